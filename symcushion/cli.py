"""Command line: ``symcushion reproduce | simulate | check | plot | view | codegen | fmu | optimise | envelope | design``.

Each sub-command is a thin layer over the public API; it parses arguments,
reports progress and turns library errors into one-line messages.
"""
from __future__ import annotations

import sys
import warnings
from pathlib import Path

from symcushion.run.interrupts import (EXIT_BAD_INPUT, EXIT_ERRORS, EXIT_INTERRUPTED,
    EXIT_OUTPUT_EXISTS, EXIT_WARNINGS, Terminated, interrupt_code, signals_handled)
from symcushion.cli_parser import build_parser
from symcushion.cli_scenes import scene_of
from symcushion.run.output_files import check_out_dir, check_output_file, claim_output

__all__ = ["main"]


#: The files ``reproduce`` writes (every one is rewritten by each run).
REPRODUCE_FILES = tuple(f"{fig}{suffix}" for fig in ("fig3", "fig4")
                        for suffix in (".png", "_methods.png", ".csv", "_robust.csv",
                                       "_implicit.csv")) + ("claims.md",)


def _cmd_reproduce(args):
    from symcushion.reproduce import reproduce

    if args.update_figures and args.out is not None:
        raise ValueError("give either `--out DIR` or `--update-figures` (which writes into "
                         "figures/), not both.")
    out = "figures" if args.update_figures else (args.out or Path("out") / "reproduce")
    out = check_out_dir(out, "--out")
    # --update-figures exists to rewrite the committed figures
    claim_output(out, REPRODUCE_FILES, overwrite=args.overwrite or args.update_figures)
    reproduce(scene_dir=args.scenes, out_dir=out, duration=args.duration)
    return 0




def _scene_and_overrides(args):
    """The scene of a ``simulate`` command with its command-line overrides applied."""
    from symcushion.model.scene import read_toml

    scene = scene_of(read_toml(args.scene), str(args.scene), getattr(args, "case", None))
    overrides = {k: v for k, v in (("duration", args.duration), ("dt", args.dt),
                                   ("mu", args.mu), ("method", args.method)) if v is not None}
    for key, value in overrides.items():
        if key != "method" and not value > 0 and not (key == "mu" and value == 0):
            raise ValueError(f"`--{key}` must be {'>= 0' if key == 'mu' else 'positive'}, "
                             f"got {value!r}.")
    return (scene.with_(**overrides) if overrides else scene), overrides


def _run_monitor(scene, model):
    """The run monitor of a simulation: the physical checks during the run (docs/checks.md)."""
    from symcushion.run.monitor import RunMonitor

    return RunMonitor(scene, model)


def _cmd_simulate(args):
    from symcushion.run.results import (RUN_FILES, ResultWriter, claim_output, remove_stale,
        result_dir, trajectory_columns, versions)
    from symcushion.model.scene import read_toml
    from symcushion.scheme.touchdown import build_model

    scene, overrides = _scene_and_overrides(args)
    directory = result_dir(args.out, scene.name)        # checked before any work
    claim_output(directory, RUN_FILES, overwrite=args.overwrite)
    model = build_model(scene)
    size = model.graph_size()
    print(f"{scene.name}: {len(scene.legs)} legs, method {scene.method}, μ = {scene.mu:g}, "
          f"{scene.steps} steps of {scene.dt:g} s; step graph {size['instructions']} "
          "instructions" + (f" (+ {size['gated']} in the stroke lock's calls, run only in "
                            "the steps that need them)" if size["gated"] else ""), flush=True)
    meta = {"scene": read_toml(args.scene), "scene_file": str(args.scene), "case": args.case,
            "overrides": overrides, "scene_summary": _summary(scene),
            "versions": versions(), "adaptive": args.adaptive or args.stability,
            "stability": args.stability, "rtol": args.rtol, "atol": args.atol}
    with ResultWriter(directory, trajectory_columns(len(scene.legs))) as writer:
        try:
            traj = _simulate_reporting(scene, model, args, writer)
        except BaseException as exc:
            if interrupt_code(exc) is not None:
                args.kept = _keep_interrupted(writer, meta, exc)
            raise
        _note_no_touchdown(traj)
        errors = _errors(traj.info["warnings"])
        meta.update(traj.info, status="errors" if errors else "complete", errors=len(errors))
        traj.info.update(scene_summary=meta["scene_summary"])
        files = writer.finish(meta)
    remove_stale(directory, RUN_FILES, keep=files.values())
    print(f"wrote {files['csv']}, {files['npz'].name}, {files['json'].name} "
          f"({traj.info['steps']} steps, {traj.info['wall_seconds']:.2f} s wall, step "
          f"criterion max {traj.info['criterion_max']:.2e}, halvings {traj.info['halvings']}, "
          f"{len(traj.info['events'])} events)")
    print(_accuracy_line(traj.info))
    if not args.no_plots:
        _figures(traj, scene, directory, args.frames)
    return _run_status(traj.info["warnings"], files["json"], args.strict)


def _accuracy_line(info) -> str:
    """One line on the run's accuracy: its error control or its error estimate."""
    if info.get("rtol") is not None:
        return (f"error control rtol {info['rtol']:g}, atol {info['atol']:g}: "
                f"{info['step_evaluations']} step evaluations, {info['rejected']} rejected "
                f"pairs, dt {info['dt_min']:.3g} to {info['dt_max']:.3g} s")
    est = info.get("error_estimate")
    if not est:
        return "no error estimate (--no-estimate, an adaptive run, or a single step)"
    parts = ", ".join(f"{key.replace('peak_', '').replace('_', ' ')} {p['relative_error']:.1e}"
                      for key, p in est["peaks"].items())
    verdict = "within" if est["within_rtol"] else "ABOVE"
    return (f"estimated relative error of the peaks (Richardson, run at "
            f"{est['companion_dt']:g} s, {est['overhead']:.2g}× the run's time): {parts}; "
            f"{verdict} rtol {est['rtol']:g}")


def _errors(findings) -> list:
    return [w for w in findings if w.get("severity") == "error"]


def _run_status(findings, where, strict) -> int:
    """Report a finished run's findings; its exit status (errors beat warnings)."""
    errors = _errors(findings)
    for e in errors:                       # the run printed them as it went; the verdict last
        print(f"error: t = {e['time']:.4g} s: {e['message']}", file=sys.stderr)
    if findings:
        print(f"{len(errors)} error(s), {len(findings) - len(errors)} warning(s), listed in "
              f"{where}", file=sys.stderr)
    if errors:
        print(f"the run gave {len(errors)} error(s): its results are kept, marked "
              f"\"status\": \"errors\" in {where}; exit status {EXIT_ERRORS}.", file=sys.stderr)
        return EXIT_ERRORS
    return EXIT_WARNINGS if findings and strict else 0


def _note_no_touchdown(traj):
    """A run that never touched down says so: a warning line and a run.json entry."""
    from symcushion.run.monitor import no_touchdown

    finding = no_touchdown(traj)
    if finding is not None:
        print(f"warning: {finding.message}", file=sys.stderr)
        traj.info["warnings"].append({"time": finding.time, "kind": "warning",
                                      "severity": finding.severity, "message": finding.message,
                                      "details": finding.to_dict()})
    traj.info["touched_down"] = finding is None


def _keep_interrupted(writer, meta, exc) -> str | None:
    """Write the rows of the finished blocks of an interrupted run, marked in run.json.

    Returns a note of what was kept for the one-line exit message (None if
    no block had finished: the writer's exit then removes its temporary files).
    """
    from symcushion.run.results import RUN_FILES, remove_stale

    if writer.rows < 2:                         # the initial row only
        return None
    so_far = getattr(exc, "run_so_far", {})
    t_end = writer.last_time
    done = [e for e in so_far.get("events", []) if e["time"] <= t_end]
    findings = [w for w in so_far.get("warnings", []) if w["time"] <= t_end]
    files = writer.finish(dict(meta, status="interrupted", t_end=t_end, events=done,
                               warnings=findings, errors=len(_errors(findings)),
                               events_dropped=so_far.get("events_dropped", 0)))
    remove_stale(writer.directory, RUN_FILES, keep=files.values())
    return (f"the run up to t = {t_end:.6g} s is kept in {writer.directory} "
            "(run.json: \"status\": \"interrupted\")")


def _simulate_reporting(scene, model, args, writer):
    """Run the simulation; the scene's physics warnings (``checks.preflight``) are
    printed as ``warning:`` lines and recorded with the run's own warnings."""
    from symcushion.run.checks import PhysicsWarning
    from symcushion.run.driver import simulate

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", PhysicsWarning)
        traj = simulate(scene, model=model, adaptive=args.adaptive or args.stability,
                        stability=args.stability, rtol=args.rtol, atol=args.atol,
                        estimate=False if args.no_estimate
                        else "fine" if args.fine_estimate else "coarse", progress=True,
                        monitor=_run_monitor(scene, model), sink=writer,
                        **({} if args.estimate_rtol is None
                           else {"estimate_rtol": args.estimate_rtol}))
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
    from symcushion.viz.animate import animate
    from symcushion.viz.plots import summary_figure

    summary_figure(traj, directory / "summary.png")
    print(f"wrote {directory / 'summary.png'}", flush=True)
    animate(traj, scene, directory / "animation.gif", frames=frames)
    print(f"wrote {directory / 'animation.gif'} ({frames} frames)")


def _cmd_plot(args):
    from symcushion.run.driver import Trajectory

    traj = Trajectory.load(args.result)
    meta = traj.info
    if args.no_animation or not meta.get("scene"):
        from symcushion.viz.plots import summary_figure

        summary_figure(traj, Path(args.result) / "summary.png")
        print(f"wrote {Path(args.result) / 'summary.png'}"
              + ("" if args.no_animation else " (no scene in run.json: no animation)"))
        return 0
    scene = scene_of(meta["scene"], str(Path(args.result) / "run.json"), meta.get("case"))
    name = (meta.get("scene_summary") or {}).get("name", scene.name)
    scene = scene.with_(name=name, **(meta.get("overrides") or {}))
    _figures(traj, scene, Path(args.result), args.frames)
    return 0


def _cmd_check(args):
    from symcushion.check_files import check_file
    from symcushion.model.scene import read_toml

    stdin = str(args.scene) == "-"
    name = "<stdin>" if stdin else str(args.scene)
    try:
        data = _read_stdin_toml() if stdin else read_toml(args.scene, "scene or study")
        kind, checked = check_file(data, name, base_dir="." if stdin else args.scene.parent)
    except (ValueError, FileNotFoundError) as exc:    # SceneError lists every bad field
        print(f"symcushion check: error: {exc}", file=sys.stderr)
        return EXIT_ERRORS
    findings = []
    for label, found in checked:
        where = name if len(checked) == 1 else f"{name} ({label})"
        for f in found:
            print(f"{where}: {f.severity}: {f.message}")
        findings += found
    errors = sum(f.severity == "error" for f in findings)
    print(f"{name}: {kind} file, {errors} error(s), {len(findings) - errors} warning(s)")
    return EXIT_ERRORS if errors or (args.strict and findings) else 0


def _read_stdin_toml() -> dict:
    from symcushion.model.scene import tomllib

    try:
        return tomllib.loads(sys.stdin.read())
    except tomllib.TOMLDecodeError as exc:
        raise ValueError(f"<stdin>: not valid TOML: {exc}") from None


def _cmd_codegen(args):
    from symcushion.compiled.codegen import generate

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


def _cmd_fmu(args):
    from symcushion.compiled.fmu import build_fmu

    try:
        build_fmu(args.scene, args.out, progress=True)
    except RuntimeError as exc:  # a failed gcc command, with its output
        print(f"symcushion fmu: error: {exc}", file=sys.stderr)
        return 1
    return 0


def _set_max_iter(ipopt: dict, value):
    """Ipopt's ``max_iter`` from ``--max-iter``, checked (None leaves the study's)."""
    if value is not None:
        if value < 1:
            raise ValueError(f"`--max-iter` must be a positive integer, got {value}.")
        ipopt["max_iter"] = value


def _cmd_optimise(args):
    from symcushion.design.optimise import load_study
    from symcushion.design.scene_file import write_optimised_scene

    study = load_study(args.study)
    _set_max_iter(study.ipopt, args.max_iter)
    out = args.out if args.out is not None else Path("out") / f"{study.name}.json"
    check_output_file(out, "--out")                    # before building and solving
    claim_output(Path(out).parent, [Path(out).name, Path(out).stem + "_designed.toml"],
                 overwrite=args.overwrite)
    pb = study.problem
    print(f"{study.name}: {len(pb.scenarios)} scenario(s), {pb.n_variables} design variables, "
          f"{pb.lbg.size} constraints, objective {pb.objective_kind} (built in "
          f"{pb.build_seconds:.1f} s)", flush=True)
    result = study.solve(progress=True)
    result.save_json(out)
    scene_file = write_optimised_scene(study, result, out)
    print(result.message)
    if result.efficiency is not None:
        print(f"efficiency (ideal v²/2s + g over the achieved peak): {result.efficiency:.4f}")
    print(f"wrote {out} and {scene_file} ({result.timings['solve_seconds']:.1f} s)")
    return 0 if result.success and result.evaluation.feasible else 1


#: What ``design`` writes into its folder (``symcushion.design.robust.report``).
DESIGN_FILES = ("result.json", "scenarios.csv", "before", "after", "before_after.png",
                "curves.png", "designed.toml", "geometry.json")


def _cmd_design(args):
    from symcushion.run.output_files import remove_stale
    from symcushion.design.robust.study import load_robust_study, run_robust_study
    from symcushion.envelope.runner import dask_client

    study = load_robust_study(args.study)
    _set_max_iter(study.ipopt, args.max_iter)
    if args.n is not None:
        if args.n < 1:
            raise ValueError(f"`--n` must be a positive integer, got {args.n}.")
        study.envelope = study.envelope.with_(n=args.n)
    out = check_out_dir(args.out if args.out is not None else Path("out") / study.name, "--out")
    if claim_output(out, DESIGN_FILES, overwrite=args.overwrite):
        remove_stale(out, DESIGN_FILES)        # a design takes minutes: no stale file meanwhile
    client = dask_client(args.scheduler) if args.scheduler else None
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
    if not all(c.get("passed", True) for c in (run.get("gradient") or {}).values()):
        return 1                       # a gradient check failed: its verdict line says where
    return 0 if res.success or res.return_status == "Maximum_Iterations_Exceeded" else 1


def _finished_batches(out) -> int:
    from symcushion.envelope.runner import BATCH_DIR

    return len(list((out / BATCH_DIR).glob("batch_*.npz"))) if (out / BATCH_DIR).is_dir() else 0


def _kept_batches(out, study) -> str:
    """What an interrupted envelope keeps, and how to go on."""
    from symcushion.envelope.runner import BATCH_DIR

    kept = _finished_batches(out)
    if not kept:
        return "no batch had finished"
    return (f"{kept} finished batch(es) are kept in {out / BATCH_DIR}; continue with "
            f"`symcushion envelope {study} --resume` and the same options")


def _claim_study_folder(out, owned, args):
    """The output folder of an envelope study: new, resumed, or overwritten (checked first)."""
    from symcushion.envelope.runner import BATCH_DIR
    from symcushion.run.output_files import OutputExists, claim_output, remove_stale

    interrupted = (out / BATCH_DIR).is_dir()
    if args.resume and args.overwrite:
        raise ValueError("give either `--resume` (continue the interrupted study in "
                         f"{out}) or `--overwrite` (start it again), not both.")
    if args.resume and not interrupted:
        done = " (its cases.csv is complete)" if (out / "cases.csv").is_file() else ""
        raise ValueError(f"`--resume`: {out} holds no interrupted study{done}; run without "
                         "--resume (with --overwrite to run it again).")
    if interrupted and not (args.resume or args.overwrite):
        raise OutputExists(f"`--out` {out} holds an interrupted study "
                           f"({_finished_batches(out)} finished batch(es)); continue it with "
                           "`--resume`, or start again with `--overwrite`.")
    if not args.resume and claim_output(out, owned, overwrite=args.overwrite):
        remove_stale(out, owned)            # a study takes minutes: no stale file meanwhile


def _cmd_envelope(args):
    from symcushion.envelope import load_study, run_envelope
    from symcushion.envelope.runner import output_names

    study = load_study(args.study)
    changes = {k: v for k, v in (("n", args.n), ("seed", args.seed), ("batch", args.batch))
               if v is not None}
    if changes:
        study = study.with_(**changes)
    out = check_out_dir(args.out if args.out is not None else Path("out") / study.name, "--out")
    _claim_study_folder(out, output_names(study), args)
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
                              cache_dir=args.build_dir, progress=True, resume=args.resume)
    except BaseException as exc:
        if interrupt_code(exc) is not None:
            args.kept = _kept_batches(out, args.study)
        elif isinstance(exc, RuntimeError):   # a failed gcc command, with its output
            print(f"symcushion envelope: error: {exc}", file=sys.stderr)
            return 1
        raise
    ps = result.p_stable()
    counts = ", ".join(f"{k} {v}" for k, v in result.counts().items() if v)
    print(f"P(stable) = {ps['p']:.3f} [{ps['low']:.3f}, {ps['high']:.3f}] "
          f"({ps['confidence']:.0%} Wilson); {counts}")
    print(f"{result.timings['cases_per_second']:,.0f} cases/s "
          f"({result.timings['run_seconds']:.1f} s); wrote "
          + ", ".join(str(f) for f in result.files.values()))
    return 0


def _cmd_view(args):
    from symcushion.viz.viewer import DEFAULT_VIEW_FRAMES, write_viewer

    try:
        path = write_viewer(args.result, args.out)
    except ImportError as exc:          # plotly missing: say how to install it
        print(f"symcushion view: error: {exc}", file=sys.stderr)
        return 2
    print(f"wrote {path} (at most {DEFAULT_VIEW_FRAMES} frames; opens without a network)")
    return 0


def _parser():
    """The parser, each sub-command bound to its function here (looked up at each call)."""
    return build_parser(dict(
        reproduce=_cmd_reproduce, simulate=_cmd_simulate, check=_cmd_check, plot=_cmd_plot,
        view=_cmd_view, codegen=_cmd_codegen, fmu=_cmd_fmu, optimise=_cmd_optimise,
        envelope=_cmd_envelope, design=_cmd_design))


def main(argv=None) -> int:
    args = _parser().parse_args(argv)
    args.kept = None        # a command that keeps part of its work says what, for the message
    with signals_handled():
        try:
            return args.func(args)
        except (ValueError, TypeError, FileNotFoundError) as exc:
            if (code := interrupt_code(exc)) is not None:
                return _report_termination(args, code)
            print(f"symcushion {args.command}: error: {exc}", file=sys.stderr)
            return _error_status(exc)
        except Exception as exc:
            if (code := interrupt_code(exc)) is None:
                raise
            return _report_termination(args, code)
        except (Terminated, KeyboardInterrupt) as exc:
            return _report_termination(args, interrupt_code(exc))


def _error_status(exc) -> int:
    from symcushion.run.output_files import OutputExists

    return EXIT_OUTPUT_EXISTS if isinstance(exc, OutputExists) else EXIT_BAD_INPUT


def _report_termination(args, code: int) -> int:
    what = "interrupted" if code == EXIT_INTERRUPTED else "terminated"
    kept = args.kept or "finished results are kept, unfinished ones removed"
    print(f"symcushion {args.command}: {what} (exit {code}); {kept}.", file=sys.stderr)
    return code


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
