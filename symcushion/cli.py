"""Command line: ``symcushion reproduce | simulate | check | codegen | optimise | envelope``.

Each sub-command is a thin layer over the public API; it parses arguments,
reports progress and turns library errors into one-line messages.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

__all__ = ["main"]


def _cmd_reproduce(args):
    from .reproduce import reproduce

    reproduce(scene_dir=args.scenes, out_dir=args.out, duration=args.duration)
    return 0


def _cmd_simulate(args):
    from .scene import load_scene
    from .driver import save, simulate
    from .touchdown import build_model

    scene = load_scene(args.scene)
    if args.method:
        scene = scene.with_(method=args.method)
    model = build_model(scene)
    size = model.graph_size()
    print(f"{scene.name}: {len(scene.legs)} legs, method {scene.method}, μ = {scene.mu:g}, "
          f"{scene.steps} steps of {scene.dt:g} s; step graph {size['instructions']} "
          "instructions", flush=True)
    traj = simulate(scene, model=model, adaptive=args.adaptive, progress=True)
    csv, npz = save(traj, args.out, scene.name)
    print(f"wrote {csv} and {npz} ({traj.info['steps']} steps, "
          f"{traj.info['wall_seconds']:.2f} s wall, step criterion max "
          f"{traj.info['criterion_max']:.2e}, halvings {traj.info['halvings']})")
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


def _cmd_optimise(args):
    from .optimise import load_study

    study = load_study(args.study)
    if args.max_iter is not None:
        if args.max_iter < 1:
            raise ValueError(f"`--max-iter` must be a positive integer, got {args.max_iter}.")
        study.ipopt["max_iter"] = args.max_iter
    pb = study.problem
    print(f"{study.name}: {len(pb.scenarios)} scenario(s), {pb.n_variables} design variables, "
          f"{pb.lbg.size} constraints, objective {pb.objective_kind} (built in "
          f"{pb.build_seconds:.1f} s)", flush=True)
    result = study.solve(progress=True)
    out = args.out if args.out is not None else Path("out") / f"{study.name}.json"
    result.save_json(out)
    print(result.message)
    if result.efficiency is not None:
        print(f"efficiency (ideal v²/2s + g over the achieved peak): {result.efficiency:.4f}")
    print(f"wrote {out} ({result.timings['solve_seconds']:.1f} s)")
    return 0 if result.success and result.evaluation.feasible else 1


def _cmd_envelope(args):
    from .envelope import load_study, run_envelope

    study = load_study(args.study)
    changes = {k: v for k, v in (("n", args.n), ("seed", args.seed), ("batch", args.batch))
               if v is not None}
    if changes:
        study = study.with_(**changes)
    out = args.out if args.out is not None else Path("out") / study.name
    backend = ("Dask at " + args.scheduler if args.scheduler else
               f"a local Dask cluster of {args.workers} workers" if args.dask else
               f"{args.threads or 'all'} thread(s)")
    print(f"{study.name}: {study.n:,} cases ({study.method}, seed {study.seed}), "
          f"{len(study.scene.legs)} legs, method {study.scene.method}, {study.scene.steps} "
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


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="symcushion", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("reproduce", help="reproduce the paper's Figs. 3-4 into figures/")
    p.add_argument("--scenes", default="studies", help="folder with fig3.toml, fig4.toml")
    p.add_argument("--out", default="figures", help="output folder (default: figures)")
    p.add_argument("--duration", type=float, default=None, help="override duration (s)")
    p.set_defaults(func=_cmd_reproduce)

    p = sub.add_parser("simulate", help="simulate a scene TOML file, write CSV and NPZ")
    p.add_argument("scene", type=Path)
    p.add_argument("--out", default="out", help="output folder (default: out)")
    p.add_argument("--method", choices=("paper", "robust", "implicit"), default=None)
    p.add_argument("--adaptive", action="store_true",
                   help="halve dt where the paper's criterion 1 - n_k.n_k+1 < eps fails")
    p.set_defaults(func=_cmd_simulate)

    p = sub.add_parser("check", help="check a scene TOML file (fields and physics) without "
                                     "simulating (docs/checks.md)")
    p.add_argument("scene", type=Path)
    p.add_argument("--strict", action="store_true", help="exit 1 on warnings too")
    p.set_defaults(func=_cmd_check)

    p = sub.add_parser("codegen", help="generate C code of the contact steps (and a scene's "
                                       "touchdown); --build compiles it (docs/codegen.md)")
    p.add_argument("--scene", type=Path, default=None,
                   help="scene TOML file: adds its struts, touchdown_step, touchdown_rollout "
                        "and the standalone program")
    p.add_argument("--out", type=Path, required=True, help="output folder")
    p.add_argument("--steps", type=int, default=None,
                   help="N of touchdown_rollout (default: the scene's duration/dt)")
    p.add_argument("--build", action="store_true",
                   help="compile libsymcushion.so (and the program touchdown) with gcc")
    p.set_defaults(func=_cmd_codegen)

    p = sub.add_parser("optimise", help="optimise leg characteristics (a study TOML file), "
                                        "write the result as JSON")
    p.add_argument("study", type=Path)
    p.add_argument("--out", type=Path, default=None,
                   help="result JSON (default: out/<study name>.json)")
    p.add_argument("--max-iter", type=int, default=None, help="override Ipopt's max_iter")
    p.set_defaults(func=_cmd_optimise)

    p = sub.add_parser("envelope", help="Monte Carlo touchdown stability envelope of a study "
                                        "TOML file (docs/envelope.md)")
    p.add_argument("study", type=Path)
    p.add_argument("--out", type=Path, default=None,
                   help="output folder: cases.csv, summary.json, figures "
                        "(default: out/<study name>)")
    p.add_argument("--n", type=int, default=None, help="override sampling.n")
    p.add_argument("--seed", type=int, default=None, help="override sampling.seed")
    p.add_argument("--batch", type=int, default=None, help="cases per batch / Dask task")
    p.add_argument("--threads", type=int, default=None,
                   help="threads of the local run (default: every core)")
    p.add_argument("--dask", action="store_true",
                   help="run batches as Dask tasks (a local cluster unless --scheduler)")
    p.add_argument("--scheduler", default=None,
                   help="address of a Dask scheduler, e.g. tcp://host:8786 (implies --dask)")
    p.add_argument("--workers", type=int, default=2,
                   help="workers of the local Dask cluster (default: 2)")
    p.add_argument("--build-dir", type=Path, default=None,
                   help="cache of compiled Functions (default: build/envelope)")
    p.set_defaults(func=_cmd_envelope)

    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except (ValueError, TypeError, FileNotFoundError) as exc:
        print(f"symcushion {args.command}: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
