"""What the command line accepts: the parser of ``symcushion`` and its sub-commands.

This module owns every sub-command's arguments, defaults and help texts. It
must not run anything: :mod:`symcushion.cli` hands it the function of each
sub-command and runs what the arguments name.
"""
from __future__ import annotations

import argparse
from pathlib import Path

from symcushion import __version__
from symcushion.viz.animate import DEFAULT_FRAMES
from symcushion.run.interrupts import EXIT_OUTPUT_EXISTS, EXIT_WARNINGS

__all__ = ["build_parser"]


def _positive_int(text):
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a positive integer, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be a positive integer, got {text!r}")
    return value


def build_parser(commands: dict) -> argparse.ArgumentParser:
    """The argument parser of ``symcushion``; ``commands`` maps each sub-command to its function."""
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
    _add_overwrite(p)
    p.set_defaults(func=commands["reproduce"])

    p = sub.add_parser("simulate", help="simulate a scene file: trajectory, figures, animation",
                       description="Simulate a scene TOML file. Writes OUT/<scene name>/: "
                       "trajectory.csv (columns named owner_quantity_axis_unit), "
                       "trajectory.npz, trajectory.mat, run.json (scene, versions, events, warnings), "
                       "summary.png and animation.gif.")
    p.add_argument("scene", type=Path, help="scene TOML file (docs/scenes.md), or an envelope "
                   "or design study file with --case")
    p.add_argument("--out", type=Path, default=Path("out"), metavar="DIR",
                   help="output folder; results go to DIR/<scene name> (default: %(default)s)")
    p.add_argument("--case", type=int, default=None, metavar="N",
                   help="with an envelope or design study file: simulate its touchdown N "
                        "(the row 'case' of its cases.csv), as the envelope ran it")
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
    p.add_argument("--stability", action="store_true",
                   help="cap each step at the explicit stability limit of the legs (implies "
                        "--adaptive; for a dt above the stable step)")
    p.add_argument("--rtol", type=float, default=None, metavar="RTOL",
                   help="error control: choose every step by step doubling so that the local "
                        "error of the strokes and the body's velocity stays below "
                        "atol + RTOL x their size, e.g. 1e-3 (docs/error-control.md); rows "
                        "then come at variable times")
    p.add_argument("--atol", type=float, default=None, metavar="ATOL",
                   help="absolute tolerance of --rtol in SI units (m, m/s; default 0)")
    p.add_argument("--no-estimate", action="store_true",
                   help="fixed-dt runs: skip the error estimate (a companion run at 2 dt, "
                        "half the cost again)")
    p.add_argument("--fine-estimate", action="store_true",
                   help="fixed-dt runs: estimate the error from a companion run at dt/2 "
                        "(twice the cost; within a factor 3 of the true error far more "
                        "often, docs/error-control.md)")
    p.add_argument("--estimate-rtol", type=float, default=None, metavar="RTOL",
                   help="fixed-dt runs: warn when a peak's estimated relative error exceeds "
                        "this (default: 1e-2)")
    p.add_argument("--no-plots", action="store_true",
                   help="write no summary.png and no animation.gif")
    p.add_argument("--frames", type=_positive_int, default=DEFAULT_FRAMES, metavar="N",
                   help="frames of animation.gif (default: %(default)s)")
    p.add_argument("--strict", action="store_true",
                   help=f"exit with status {EXIT_WARNINGS} if the run gave any warning")
    _add_overwrite(p)
    p.set_defaults(func=commands["simulate"])

    p = sub.add_parser("check", help="check a scene or study file (every field and the "
                       "physics) without simulating",
                       description="Check a scene, envelope, design or optimise study TOML "
                       "file: every field, and the physical sanity checks of docs/checks.md "
                       "for every scene it describes, without simulating. Exit status 0 when "
                       "clean, 1 on errors (and on warnings with --strict).")
    p.add_argument("scene", type=Path, metavar="FILE",
                   help="scene (docs/scenes.md) or study TOML file (docs/envelope.md, "
                        "docs/optimise.md); - reads standard input")
    p.add_argument("--strict", action="store_true", help="exit 1 on warnings too")
    p.set_defaults(func=commands["check"])

    p = sub.add_parser("plot", help="redraw summary.png and animation.gif of a result folder",
                       description="Redraw the figures of a run from its saved results.")
    p.add_argument("result", type=Path, metavar="RESULT_DIR",
                   help="folder written by simulate (OUT/<scene name>)")
    p.add_argument("--no-animation", action="store_true", help="redraw summary.png only")
    p.add_argument("--frames", type=_positive_int, default=DEFAULT_FRAMES, metavar="N",
                   help="frames of animation.gif (default: %(default)s)")
    p.set_defaults(func=commands["plot"])

    _add_study_commands(sub, commands)
    _add_design_command(sub, commands)
    _add_view_command(sub, commands)
    return parser


def _add_overwrite(p):
    p.add_argument("--overwrite", action="store_true",
                   help="replace the results of an earlier run at the output path (its stale "
                        f"files are removed; without this the command stops with status "
                        f"{EXIT_OUTPUT_EXISTS})")


def _add_study_commands(sub, commands):
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
    p.set_defaults(func=commands["codegen"])
    p = sub.add_parser("fmu", help="an FMI 2.0 Co-Simulation FMU of a scene's touchdown step "
                       "(docs/toolchain.md)", description="Build an FMU for Simulink/Modelica.")
    p.add_argument("scene", type=Path, help="scene TOML file")
    p.add_argument("--out", type=Path, required=True, metavar="FILE.fmu", help="the FMU")
    p.set_defaults(func=commands["fmu"])

    p = sub.add_parser("optimise", help="optimise leg characteristics of a study file, write "
                                        "the result as JSON",
                       description="Ipopt design of the characteristics (docs/optimise.md).")
    p.add_argument("study", type=Path, help="study TOML file (docs/optimise.md)")
    p.add_argument("--out", type=Path, default=None, metavar="FILE",
                   help="result JSON (default: out/<study name>.json)")
    p.add_argument("--max-iter", type=int, default=None,
                   help="override Ipopt's max_iter (default: the study's)")
    _add_overwrite(p)
    p.set_defaults(func=commands["optimise"])

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
    p.add_argument("--resume", action="store_true",
                   help="continue an interrupted study in its output folder from its finished "
                        "batches (same study file and options); the results equal an "
                        "uninterrupted run's")
    _add_overwrite(p)
    p.set_defaults(func=commands["envelope"])


def _add_design_command(sub, commands):
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
    _add_overwrite(p)
    p.set_defaults(func=commands["design"])


def _add_view_command(sub, commands):
    """The view sub-command (the interactive viewer of a run, docs/tutorial.md)."""
    p = sub.add_parser("view", help="write an interactive 3-D viewer (one HTML page) of a "
                       "result folder", description="Write a self-contained HTML page of a "
                       "run: 3-D body, legs, feet, forces and obstacle, a time slider, and the "
                       "main channels (needs the extra: pip install 'symcushion[viewer]').")
    p.add_argument("result", type=Path, metavar="RESULT_DIR",
                   help="folder written by simulate (OUT/<scene name>)")
    p.add_argument("--out", type=Path, default=None, metavar="FILE.html",
                   help="the page (default: RESULT_DIR/viewer.html)")
    p.set_defaults(func=commands["view"])
