"""Command line: ``symcushion reproduce | simulate | check | plot | view | codegen | optimise | envelope | design``.

Each sub-command is a thin layer over the public API; it parses arguments,
reports progress and turns library errors into one-line messages.
"""
from __future__ import annotations

import argparse
import signal
import sys
import warnings
from pathlib import Path

from . import __version__
from .animate import DEFAULT_FRAMES
from .results import check_out_dir, check_output_file

__all__ = ["main"]


def _cmd_reproduce(args):
    from .reproduce import reproduce

    if args.update_figures and args.out is not None:
        raise ValueError("give either `--out DIR` or `--update-figures` (which writes into "
                         "figures/), not both.")
    out = "figures" if args.update_figures else (args.out or Path("out") / "reproduce")
    out = check_out_dir(out, "--out")
    reproduce(scene_dir=args.scenes, out_dir=out, duration=args.duration)
    return 0


#: Exit status of a run that finished with warnings under --strict.
EXIT_WARNINGS = 3


def _scene_and_overrides(args):
    """The scene of a ``simulate`` command with its command-line overrides applied."""
    from .scene import load_scene

    scene = load_scene(args.scene)
    overrides = {k: v for k, v in (("duration", args.duration), ("dt", args.dt),
                                   ("mu", args.mu), ("method", args.method)) if v is not None}
    for key, value in overrides.items():
        if key != "method" and not value > 0 and not (key == "mu" and value == 0):
            raise ValueError(f"`--{key}` must be {'>= 0' if key == 'mu' else 'positive'}, "
                             f"got {value!r}.")
    return (scene.with_(**overrides) if overrides else scene), overrides


def _run_monitor(scene, model):
    """The run monitor of a simulation: the physical checks during the run (docs/checks.md)."""
    from .monitor import RunMonitor

    return RunMonitor(scene, model)


def _cmd_simulate(args):
    from .results import ResultWriter, result_dir, trajectory_columns, versions
    from .scene import read_toml
    from .touchdown import build_model

    scene, overrides = _scene_and_overrides(args)
    directory = result_dir(args.out, scene.name)        # checked before any work
    model = build_model(scene)
    size = model.graph_size()
    print(f"{scene.name}: {len(scene.legs)} legs, method {scene.method}, μ = {scene.mu:g}, "
          f"{scene.steps} steps of {scene.dt:g} s; step graph {size['instructions']} "
          "instructions" + (f" (+ {size['gated']} in the stroke lock's calls, run only in "
                            "the steps that need them)" if size["gated"] else ""), flush=True)
    with ResultWriter(directory, trajectory_columns(len(scene.legs))) as writer:
        traj = _simulate_reporting(scene, model, args, writer)
        meta = {"scene": read_toml(args.scene), "scene_file": str(args.scene),
                "overrides": overrides, "scene_summary": _summary(scene),
                "versions": versions(), "adaptive": args.adaptive, **traj.info}
        traj.info.update(scene_summary=meta["scene_summary"])
        files = writer.finish(meta)
    print(f"wrote {files['csv']}, {files['npz'].name}, {files['json'].name} "
          f"({traj.info['steps']} steps, {traj.info['wall_seconds']:.2f} s wall, step "
          f"criterion max {traj.info['criterion_max']:.2e}, halvings {traj.info['halvings']}, "
          f"{len(traj.info['events'])} events)")
    if not args.no_plots:
        _figures(traj, scene, directory, args.frames)
    if traj.info["warnings"]:
        print(f"{len(traj.info['warnings'])} warning(s), listed in {files['json']}",
              file=sys.stderr)
        if args.strict:
            return EXIT_WARNINGS
    return 0


def _simulate_reporting(scene, model, args, writer):
    """Run the simulation; the scene's physics warnings (``checks.preflight``) are
    printed as ``warning:`` lines and recorded with the run's own warnings."""
    from .checks import PhysicsWarning
    from .driver import simulate

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", PhysicsWarning)
        traj = simulate(scene, model=model, adaptive=args.adaptive, progress=True,
                        monitor=_run_monitor(scene, model), sink=writer)
    for w in caught:
        if not issubclass(w.category, PhysicsWarning):
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
            continue
        print(f"warning: {w.message}", file=sys.stderr)
        traj.info["warnings"].insert(0, {"time": 0.0, "kind": "warning", "severity": "warning",
                                         "message": str(w.message)})
    return traj


def _summary(scene) -> dict:
    """The effective scene parameters of a run (after overrides), for run.json."""
    return {"name": scene.name, "method": scene.method, "mu": scene.mu, "dt": scene.dt,
            "duration": scene.duration, "steps": scene.steps, "gravity": scene.gravity,
            "legs": len(scene.legs), "mass": scene.body.mass,
            "obstacles": [type(o).__name__ for o in scene.obstacles]}


def _figures(traj, scene, directory, frames):
    from .animate import animate
    from .plots import summary_figure

    summary_figure(traj, directory / "summary.png")
    print(f"wrote {directory / 'summary.png'}", flush=True)
    animate(traj, scene, directory / "animation.gif", frames=frames)
    print(f"wrote {directory / 'animation.gif'} ({frames} frames)")


def _cmd_plot(args):
    from .driver import Trajectory
    from .scene import scene_from_dict

    traj = Trajectory.load(args.result)
    meta = traj.info
    if args.no_animation or not meta.get("scene"):
        from .plots import summary_figure

        summary_figure(traj, Path(args.result) / "summary.png")
        print(f"wrote {Path(args.result) / 'summary.png'}"
              + ("" if args.no_animation else " (no scene in run.json: no animation)"))
        return 0
    scene = scene_from_dict(meta["scene"], source=str(Path(args.result) / "run.json"))
    name = (meta.get("scene_summary") or {}).get("name", scene.name)
    scene = scene.with_(name=name, **(meta.get("overrides") or {}))
    _figures(traj, scene, Path(args.result), args.frames)
    return 0


def _cmd_check(args):
    from .checks import check_scene
    from .scene import load_scene

    try:
        scene = load_scene(args.scene)
    except (ValueError, FileNotFoundError) as exc:    # SceneError lists every bad field
        print(f"symcushion check: error: {exc}", file=sys.stderr)
        return 1
    findings = check_scene(scene)
    for f in findings:
        print(f"{args.scene}: {f.severity}: {f.message}")
    errors = sum(f.severity == "error" for f in findings)
    print(f"{args.scene}: {errors} error(s), {len(findings) - errors} warning(s)")
    return 1 if errors or (args.strict and findings) else 0


def _cmd_codegen(args):
    from .codegen import generate

    try:
        gen = generate(args.out, scene=args.scene, build=args.build, steps=args.steps,
                       progress=True)
    except RuntimeError as exc:  # a failed gcc command, with its output
        print(f"symcushion codegen: error: {exc}", file=sys.stderr)
        return 1
    print(f"wrote {gen.header} and {', '.join(str(s) for s in gen.sources)}")
    for built in (gen.library, gen.program):
        if built is not None:
            print(f"built {built}")
    return 0


def _set_max_iter(ipopt: dict, value):
    """Ipopt's ``max_iter`` from ``--max-iter``, checked (None leaves the study's)."""
    if value is not None:
        if value < 1:
            raise ValueError(f"`--max-iter` must be a positive integer, got {value}.")
        ipopt["max_iter"] = value


def _cmd_optimise(args):
    from .optimise import load_study

    study = load_study(args.study)
    _set_max_iter(study.ipopt, args.max_iter)
    out = args.out if args.out is not None else Path("out") / f"{study.name}.json"
    check_output_file(out, "--out")                    # before building and solving
    pb = study.problem
    print(f"{study.name}: {len(pb.scenarios)} scenario(s), {pb.n_variables} design variables, "
          f"{pb.lbg.size} constraints, objective {pb.objective_kind} (built in "
          f"{pb.build_seconds:.1f} s)", flush=True)
    result = study.solve(progress=True)
    result.save_json(out)
    print(result.message)
    if result.efficiency is not None:
        print(f"efficiency (ideal v²/2s + g over the achieved peak): {result.efficiency:.4f}")
    print(f"wrote {out} ({result.timings['solve_seconds']:.1f} s)")
    return 0 if result.success and result.evaluation.feasible else 1


def _cmd_design(args):
    from .robust.study import load_robust_study, run_robust_study

    study = load_robust_study(args.study)
    _set_max_iter(study.ipopt, args.max_iter)
    if args.n is not None:
        if args.n < 1:
            raise ValueError(f"`--n` must be a positive integer, got {args.n}.")
        study.envelope = study.envelope.with_(n=args.n)
    out = check_out_dir(args.out if args.out is not None else Path("out") / study.name, "--out")
    client = None
    if args.scheduler:
        try:
            from distributed import Client
        except ImportError:
            raise ImportError("--scheduler needs the optional extra: pip install "
                              "'symcushion[dask]'.") from None
        client = Client(args.scheduler)
    try:
        run = run_robust_study(study, out, threads=args.threads, client=client,
                               scheduler=args.scheduler, verify=not args.no_verify,
                               check_gradient=args.check, cache_dir=args.build_dir)
    finally:
        if client is not None:
            client.close()
    res = run["result"]
    print(f"{study.name}: {res.return_status}, {res.iterations} iterations; "
          f"{run['seconds']['total']:.0f} s in all; wrote {out}")
    return 0 if res.success or res.return_status == "Maximum_Iterations_Exceeded" else 1


def _cmd_envelope(args):
    from .envelope import load_study, run_envelope

    study = load_study(args.study)
    changes = {k: v for k, v in (("n", args.n), ("seed", args.seed), ("batch", args.batch))
               if v is not None}
    if changes:
        study = study.with_(**changes)
    out = check_out_dir(args.out if args.out is not None else Path("out") / study.name, "--out")
    backend = ("Dask at " + args.scheduler if args.scheduler else
               f"a local Dask cluster of {args.workers} workers" if args.dask else
               f"{args.threads or 'all'} thread(s)")
    print(f"{study.name}: {study.n:,} cases ({study.method}, seed {study.seed}), "
          f"{len(study.scene.legs)} legs, method {study.scene.method} (slip {study.scene.slip}, "
          f"events {study.scene.events}), {study.scene.steps} "
          f"steps of {study.scene.dt:g} s; {backend}", flush=True)
    try:
        result = run_envelope(study, out, threads=args.threads, dask=args.dask,
                              scheduler=args.scheduler, workers=args.workers,
                              cache_dir=args.build_dir, progress=True)
    except RuntimeError as exc:  # a failed gcc command, with its output
        print(f"symcushion envelope: error: {exc}", file=sys.stderr)
        return 1
    ps = result.p_stable()
    counts = ", ".join(f"{k} {v}" for k, v in result.counts().items() if v)
    print(f"P(stable) = {ps['p']:.3f} [{ps['low']:.3f}, {ps['high']:.3f}] "
          f"({ps['confidence']:.0%} Wilson); {counts}")
    print(f"{result.timings['cases_per_second']:,.0f} cases/s "
          f"({result.timings['run_seconds']:.1f} s); wrote "
          + ", ".join(str(f) for f in result.files.values()))
    return 0


def _positive_int(text):
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a positive integer, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be a positive integer, got {text!r}")
    return value


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="symcushion", description="Simulate and design shock-absorbing landing legs "
        "(Khvostov 1976). Units are SI throughout: m, s, kg, N, rad.")
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    p = sub.add_parser("reproduce", help="reproduce the paper's Figs. 3-4 and print its claims "
                       "beside the measured values",
                       description="Run the Fig. 3 and Fig. 4 scenes with every contact method, "
                       "write figures, CSV files and the claims table.")
    p.add_argument("--scenes", default="studies", metavar="DIR",
                   help="folder holding fig3.toml and fig4.toml (default: %(default)s)")
    p.add_argument("--out", type=Path, default=None, metavar="DIR",
                   help="output folder (default: out/reproduce; the committed figures are "
                        "rewritten only with --update-figures)")
    p.add_argument("--update-figures", action="store_true",
                   help="write into figures/, the figures committed to the repository")
    p.add_argument("--duration", type=float, default=None, metavar="SECONDS",
                   help="simulated time of each run in s (default: the scenes' own)")
    p.set_defaults(func=_cmd_reproduce)

    p = sub.add_parser("simulate", help="simulate a scene file: trajectory, figures, animation",
                       description="Simulate a scene TOML file. Writes OUT/<scene name>/: "
                       "trajectory.csv (columns named owner_quantity_axis_unit), "
                       "trajectory.npz, trajectory.mat, run.json (scene, versions, events, warnings), "
                       "summary.png and animation.gif.")
    p.add_argument("scene", type=Path, help="scene TOML file (docs/scenes.md)")
    p.add_argument("--out", type=Path, default=Path("out"), metavar="DIR",
                   help="output folder; results go to DIR/<scene name> (default: %(default)s)")
    p.add_argument("--duration", type=float, default=None, metavar="SECONDS",
                   help="simulated time in s (default: the scene's)")
    p.add_argument("--dt", type=float, default=None, metavar="SECONDS",
                   help="time step in s (default: the scene's)")
    p.add_argument("--mu", type=float, default=None,
                   help="Coulomb friction coefficient, >= 0 (default: the scene's)")
    p.add_argument("--method", choices=("paper", "robust", "implicit"), default=None,
                   help="contact step: paper (as printed), robust, implicit (exact Coulomb) "
                        "(default: the scene's)")
    p.add_argument("--adaptive", action="store_true",
                   help="halve dt where the paper's step criterion 1 - n_k.n_k+1 < eps fails")
    p.add_argument("--no-plots", action="store_true",
                   help="write no summary.png and no animation.gif")
    p.add_argument("--frames", type=_positive_int, default=DEFAULT_FRAMES, metavar="N",
                   help="frames of animation.gif (default: %(default)s)")
    p.add_argument("--strict", action="store_true",
                   help=f"exit with status {EXIT_WARNINGS} if the run gave any warning")
    p.set_defaults(func=_cmd_simulate)

    p = sub.add_parser("check", help="check a scene file (every field and the physics) "
                       "without simulating",
                       description="Check a scene TOML file: every field, and the physical "
                       "sanity checks of docs/checks.md, without simulating. Exit status 0 when "
                       "clean, 1 on errors (and on warnings with --strict).")
    p.add_argument("scene", type=Path, help="scene TOML file (docs/scenes.md)")
    p.add_argument("--strict", action="store_true", help="exit 1 on warnings too")
    p.set_defaults(func=_cmd_check)

    p = sub.add_parser("plot", help="redraw summary.png and animation.gif of a result folder",
                       description="Redraw the figures of a run from its saved results.")
    p.add_argument("result", type=Path, metavar="RESULT_DIR",
                   help="folder written by simulate (OUT/<scene name>)")
    p.add_argument("--no-animation", action="store_true", help="redraw summary.png only")
    p.add_argument("--frames", type=_positive_int, default=DEFAULT_FRAMES, metavar="N",
                   help="frames of animation.gif (default: %(default)s)")
    p.set_defaults(func=_cmd_plot)

    _add_study_commands(sub)
    _add_design_command(sub)
    _add_view_command(sub)
    return parser


def _add_study_commands(sub):
    """The codegen, optimise and envelope sub-commands."""
    p = sub.add_parser("codegen", help="generate C code of the contact steps and a scene's "
                                       "touchdown; --build compiles it",
                       description="Generate C code (docs/codegen.md).")
    p.add_argument("--scene", type=Path, default=None,
                   help="scene TOML file: adds its struts, touchdown_step, touchdown_rollout "
                        "and the standalone program (default: contact steps only)")
    p.add_argument("--out", type=Path, required=True, metavar="DIR", help="output folder")
    p.add_argument("--steps", type=int, default=None,
                   help="N of touchdown_rollout (default: the scene's duration/dt)")
    p.add_argument("--build", action="store_true",
                   help="compile libsymcushion.so (and the program touchdown) with gcc")
    p.set_defaults(func=_cmd_codegen)

    p = sub.add_parser("optimise", help="optimise leg characteristics of a study file, write "
                                        "the result as JSON",
                       description="Ipopt design of the characteristics (docs/optimise.md).")
    p.add_argument("study", type=Path, help="study TOML file (docs/optimise.md)")
    p.add_argument("--out", type=Path, default=None, metavar="FILE",
                   help="result JSON (default: out/<study name>.json)")
    p.add_argument("--max-iter", type=int, default=None,
                   help="override Ipopt's max_iter (default: the study's)")
    p.set_defaults(func=_cmd_optimise)

    p = sub.add_parser("envelope", help="Monte Carlo touchdown stability envelope of a study "
                                        "file",
                       description="Sample touchdown conditions and classify each run "
                       "(docs/envelope.md).")
    p.add_argument("study", type=Path, help="study TOML file (docs/envelope.md)")
    p.add_argument("--out", type=Path, default=None, metavar="DIR",
                   help="output folder: cases.csv, summary.json, figures "
                        "(default: out/<study name>)")
    p.add_argument("--n", type=int, default=None, help="number of cases (default: sampling.n)")
    p.add_argument("--seed", type=int, default=None, help="seed (default: sampling.seed)")
    p.add_argument("--batch", type=int, default=None,
                   help="cases per batch or Dask task (default: the study's)")
    p.add_argument("--threads", type=int, default=None,
                   help="threads of the local run (default: every core)")
    p.add_argument("--dask", action="store_true",
                   help="run batches as Dask tasks (a local cluster unless --scheduler)")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="address of a Dask scheduler, e.g. tcp://host:8786 (implies --dask)")
    p.add_argument("--workers", type=int, default=2,
                   help="workers of the local Dask cluster (default: %(default)s)")
    p.add_argument("--build-dir", type=Path, default=None, metavar="DIR",
                   help="cache of compiled Functions (default: build/envelope)")
    p.set_defaults(func=_cmd_envelope)


def _add_design_command(sub):
    """The design sub-command (design for the envelope)."""
    p = sub.add_parser("design", help="design the legs for touchdown stability over an "
                                      "envelope: sample, select, optimise, verify",
                       description="Design for the envelope (docs/optimise.md).")
    p.add_argument("study", type=Path, help="design study TOML file (docs/optimise.md)")
    p.add_argument("--out", type=Path, default=None, metavar="DIR",
                   help="result folder (default: out/<study name>)")
    p.add_argument("--threads", type=int, default=None,
                   help="threads (default: every core)")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="run scenarios and envelopes on this Dask scheduler")
    p.add_argument("--n", type=int, default=None,
                   help="cases of the verification (default: sampling.n)")
    p.add_argument("--max-iter", type=int, default=None, help="override Ipopt's max_iter")
    p.add_argument("--no-verify", action="store_true",
                   help="skip the before/after verification envelopes")
    p.add_argument("--check", action="store_true",
                   help="gradient check at the start and at the optimum")
    p.add_argument("--build-dir", type=Path, default=None, metavar="DIR",
                   help="cache of compiled Functions (default: build/robust, build/envelope)")
    p.set_defaults(func=_cmd_design)


def _cmd_view(args):
    from .viewer import DEFAULT_VIEW_FRAMES, write_viewer

    try:
        path = write_viewer(args.result, args.out)
    except ImportError as exc:          # plotly missing: say how to install it
        print(f"symcushion view: error: {exc}", file=sys.stderr)
        return 2
    print(f"wrote {path} (at most {DEFAULT_VIEW_FRAMES} frames; opens without a network)")
    return 0


def _add_view_command(sub):
    """The view sub-command (the interactive viewer of a run, docs/tutorial.md)."""
    p = sub.add_parser("view", help="write an interactive 3-D viewer (one HTML page) of a "
                       "result folder", description="Write a self-contained HTML page of a "
                       "run: 3-D body, legs, feet, forces and obstacle, a time slider, and the "
                       "main channels (needs the extra: pip install 'symcushion[viewer]').")
    p.add_argument("result", type=Path, metavar="RESULT_DIR",
                   help="folder written by simulate (OUT/<scene name>)")
    p.add_argument("--out", type=Path, default=None, metavar="FILE.html",
                   help="the page (default: RESULT_DIR/viewer.html)")
    p.set_defaults(func=_cmd_view)


class Terminated(SystemExit):
    """Raised by the SIGTERM handler; its code is 128 + the signal number."""


#: Seconds between re-raisings of a termination that has not reached :func:`main`.
#: A C extension can swallow an exception raised while it runs Python code:
#: SWIG's overload dispatch (CasADi's ``Function.call``) tries each signature
#: and clears the errors of those that fail, so one raise could be lost and the
#: run go on to its end.
TERMINATION_REMINDER = 0.1

_pending: int | None = None     # the exit code of a SIGTERM not yet reported


def _terminate(signum, frame):
    """SIGTERM ends the run like Ctrl-C: temporary files are removed, results kept whole.

    The termination is remembered and raised again every
    :data:`TERMINATION_REMINDER` s (SIGALRM) until :func:`main` reports it.
    """
    global _pending
    _pending = 128 + signum
    signal.setitimer(signal.ITIMER_REAL, TERMINATION_REMINDER, TERMINATION_REMINDER)
    _remind(signal.SIGALRM, frame)


def _remind(signum, frame):
    """Raise the pending termination, unless an exception is being handled.

    Code in an ``except``, ``finally`` or ``__exit__`` is cleaning up (a
    propagating termination, or an error on its way to :func:`main`); it is
    never interrupted, so temporary files are always removed.
    """
    if _pending is not None and sys.exc_info()[1] is None:
        raise Terminated(_pending)


def _termination_in(exc: BaseException) -> Terminated | None:
    """The :class:`Terminated` behind ``exc``, if the signal caused it.

    A signal handler runs wherever Python next checks for signals, which may
    be inside a C extension calling back into Python (CasADi's ``DM.__array__``
    under NumPy, for one); such callers wrap the exception in a
    ``SystemError``, or replace it (SWIG's ``NotImplementedError`` for "wrong
    number or type of arguments"). A pending SIGTERM, or a termination in the
    chain of causes, means the signal caused it.
    """
    if _pending is not None:
        return Terminated(_pending)
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, Terminated):
            return exc
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return None


def main(argv=None) -> int:
    global _pending
    args = _parser().parse_args(argv)
    _pending = None
    previous = signal.signal(signal.SIGTERM, _terminate)
    previous_alarm = signal.signal(signal.SIGALRM, _remind)
    try:
        return args.func(args)
    except (ValueError, TypeError, FileNotFoundError) as exc:
        if (term := _termination_in(exc)) is not None:
            return _report_termination(args, term)
        print(f"symcushion {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except Exception as exc:
        if (term := _termination_in(exc)) is None:
            raise
        return _report_termination(args, term)
    except Terminated as term:
        return _report_termination(args, term)
    finally:
        if _pending is not None:
            signal.setitimer(signal.ITIMER_REAL, 0)
        _pending = None
        signal.signal(signal.SIGTERM, previous)
        signal.signal(signal.SIGALRM, previous_alarm)


def _report_termination(args, term: Terminated) -> int:
    print(f"symcushion {args.command}: terminated (exit {term.code}); finished results "
          "are kept, unfinished ones removed.", file=sys.stderr)
    return term.code


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
