"""Command line: ``symcushion reproduce | simulate``.

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
    from .simulate import build_model, save, simulate

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

    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except (ValueError, TypeError, FileNotFoundError) as exc:
        print(f"symcushion {args.command}: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
