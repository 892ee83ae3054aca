"""Command line of the speed-vs-error study: run the scenes, write CSV, figure and docs.

Owns the options, the order in which the study's parts run and where the
outputs go. It must not measure, fit or format anything itself.
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

from symcushion.run import report

from .csv_io import write_csv
from .grid import DOC, DT_GRID, DT_REF, FIGURES, QUICK_DT_GRID, QUICK_DT_REF, QUICK_OUT, SCENES
from .orders import orders_table
from .plots import plot
from .results_text import report_text
from .scene_runs import run_scene


def main(argv=None) -> None:
    from symcushion.studies import speed_vs_error  # the package: its docstring is the study's

    parser = argparse.ArgumentParser(description=speed_vs_error.__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true",
                        help="smoke run: Δt grid 3e-3..3e-4, reference at 1e-5, outputs to "
                             f"{QUICK_OUT} (docs untouched)")
    parser.add_argument("--scenes", nargs="+", choices=list(SCENES), default=list(SCENES))
    parser.add_argument("--no-vm", action="store_true", help="compiled runs only")
    parser.add_argument("--no-peers", action="store_true", help="skip symcushion.peers")
    parser.add_argument("--out", type=Path, default=None,
                        help="folder of the CSV and PNG (default figures/, or the quick folder)")
    args = parser.parse_args(argv)
    dt_grid = QUICK_DT_GRID if args.quick else DT_GRID
    dt_ref = QUICK_DT_REF if args.quick else DT_REF
    out = args.out or (QUICK_OUT if args.quick else FIGURES)
    started = time.perf_counter()
    rows, checks, floors, notes = [], [], {}, []
    for name in args.scenes:
        print(f"{name}:", flush=True)
        r, check, floor, n = run_scene(name, dt_grid, dt_ref, vm=not args.no_vm,
                                       peers=not args.no_peers,
                                       progress=lambda s: print(s, flush=True))
        rows += r
        checks.append(check)
        floors[name] = floor
        notes += n
    orders = orders_table(rows, floors)
    write_csv(rows, out / "speed_vs_error.csv")
    plot(rows, orders, out / "speed_vs_error.png", floors)
    total = time.perf_counter() - started
    shown = "figures" if out == FIGURES else str(out)
    text = report_text(rows, checks, orders, notes, dt_grid, total, shown)
    print(text)
    if not args.quick and args.out is None:
        report.write_section(DOC, "Results", text, title="# Speed versus error")
    print(f"wrote {out / 'speed_vs_error.csv'}, {out / 'speed_vs_error.png'}"
          + ("" if args.quick or args.out else f", {DOC}") + f" in {total:.0f} s", flush=True)

