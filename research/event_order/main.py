"""Command line of the event-order study: run the cases, write CSV, figures and the results page.

Owns the argument parsing and the order of the work; it must not measure
anything itself.
"""
from __future__ import annotations

import argparse
import importlib
import time

from symcushion.run import report

from .cases import FIGURES, RESULTS, scenes
from .controls import controls, controls_text, cost_check, cost_text, switch_case
from .figure import plot, plot_roundoff, plot_window
from .held import held_runs, held_text
from .limits import limit_runs, limits_text, oracle, oracle_text
from .reference import ladder_runs, reference_text, sensitivity_runs
from .runs import orders, run_case, write_csv
from .roundoff import coarse_errors, needed_references, roundoff_runs, roundoff_text
from .smoothness import smoothness_runs, smoothness_text
from .text import _fmt_order, report_text
from .window import WINDOW_TIMES, window_orders, window_runs, window_text


#: First line of a new results page.
TITLE = "# Event order: results"


def _write(heading: str, body: str) -> None:
    """Replace (or append) the section ``heading`` of the results page."""
    report.write_section(RESULTS, heading, body, title=TITLE)


def main(argv=None):
    study = importlib.import_module(__package__)    # its docstring is the study's

    parser = argparse.ArgumentParser(description=study.__doc__.split("\n")[0])
    parser.add_argument("--only", default=None, help="run only the cases whose scene name or "
                        "variant contains this text (no output is written)")
    parser.add_argument("--controls", action="store_true",
                        help="run only the control runs and write their section")
    parser.add_argument("--cost", action="store_true",
                        help="run only the interleaved timing of the located switch and write "
                        "its section")
    parser.add_argument("--limits", action="store_true",
                        help="run only the default step, the stroke lock and the regularised branch "
                        "switch down to 1e-6 s and write their section")
    parser.add_argument("--held", action="store_true",
                        help="run only the regularised branch switch at several widths and write "
                        "what it holds where a foot slides (its section)")
    parser.add_argument("--reference", action="store_true",
                        help="run only the regularised reference on a ladder of widths and steps "
                        "and with its initial state perturbed, and write how well it is known "
                        "(its section; about an hour)")
    parser.add_argument("--window", action="store_true",
                        help="run only the slope lander's schemes over its first 0.2 s, where the "
                        "regularised reference is known, and write their orders (its section)")
    parser.add_argument("--smoothness", action="store_true",
                        help="run only each scheme on the slope lander with its initial velocity "
                        "nudged by tiny amounts, and write up to when its run is a smooth "
                        "function of its initial state (its section; about 10 min)")
    parser.add_argument("--roundoff", action="store_true",
                        help="run only the default step, the stroke lock and the regularised "
                        "reference with the initial velocity moved by one ulp, and write how far "
                        "that moves each run (its section; about 8 min)")
    args = parser.parse_args(argv)
    if args.roundoff:
        coarse = coarse_errors(FIGURES / "event_order.csv")     # before the runs: fail early
        rows = roundoff_runs()
        need = needed_references(rows, coarse)
        plot_roundoff(rows, need, FIGURES / "event_order_roundoff.png")
        _write("Events: what double precision resolves", roundoff_text(rows, need, coarse))
        return
    if args.smoothness:
        _write("Events: where each run stops being smooth", smoothness_text(smoothness_runs()))
        return
    if args.window:
        result = window_runs()
        plot_window(result, window_orders(result), WINDOW_TIMES,
                    FIGURES / "event_order_window.png")
        _write("Events: orders where the reference is known", window_text(result))
        return
    if args.reference:
        _write("Events: how well the reference is known",
               reference_text(ladder_runs(), sensitivity_runs()))
        return
    if args.held:
        _write("Events: what the regularised switch holds", held_text(held_runs()))
        return
    if args.limits:
        text = limits_text(limit_runs()) + "\n\n" + oracle_text(oracle())
        _write("Events: two limits on the slope", text)
        return
    if args.cost:
        _write("Events: cost", cost_text(cost_check()))
        return
    if args.controls:
        _write("Events: controls", controls_text(controls()))
        return
    started = time.perf_counter()
    rows = []
    for name, variant, _, scene in scenes():
        if args.only and args.only not in name and args.only not in variant:
            continue
        rows += run_case(name, variant, scene)
    if not args.only or args.only in "switch control":
        for events in ("none", "branch"):
            rows += switch_case(events)
    fits = orders(rows)
    for f in fits:
        print(f"{f['scene']:>12} {f['variant']:>10}: traj {_fmt_order(f['trajectory_error'])}, "
              f"rebound {_fmt_order(f['rebound_error'])}, final {_fmt_order(f['final_error'])}")
    if args.only:
        return
    write_csv(rows, FIGURES / "event_order.csv")
    plot(rows, fits, FIGURES / "event_order.png")
    _write("Events: measured", report_text(rows, fits, time.perf_counter() - started))
