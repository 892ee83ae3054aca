"""Command line of the hard-case battery: run the cases, write the table and the docs section.

Owns the options and the text around the table in docs/hard-cases.md. It
must not run or check a case itself.
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from symcushion.run import report
from symcushion.contact.args import METHODS

from .cases import CASES, explicit_limit
from .checks import CONE_TOL, CREEP_TOL, ENERGY_TOL, PENETRATION_TOL, SYMMETRY_TOL, WORK_TOL
from .runner import run_case
from .table import ROOT, TABLE, table, verdict

DOC = ROOT / "docs" / "hard-cases.md"
SECTION = "Results"


def main(argv=None):
    from symcushion.studies import hard_cases  # the package: its docstring is the battery's

    parser = argparse.ArgumentParser(description=hard_cases.__doc__.splitlines()[0])
    parser.add_argument("--cases", default=",".join(CASES),
                        help="comma-separated case names (default: all)")
    args = parser.parse_args(argv)
    names = [n for n in args.cases.split(",") if n]
    results = []
    started = time.perf_counter()
    for name in names:
        for method in METHODS:
            with np.errstate(invalid="ignore", divide="ignore"):
                result = run_case(name, method)
            results.append(result)
            print(f"{name:18s} {method:8s} {verdict(result):30s} {result.wall:6.1f} s", flush=True)
    speeds = {m: explicit_limit(m) for m in METHODS}
    text = table(results)
    TABLE.parent.mkdir(parents=True, exist_ok=True)
    header = ("# Hard-case battery\n\nWritten by `python studies/hard_cases.py`; columns and "
              "tolerances in docs/hard-cases.md.\n\n")
    TABLE.write_text(header + text)
    body = (text + "\n"
            + "Explicit limit, `stiff_axial_stick` at Δt = 1 ms (body speed after steps 1–3, "
              "m/s): "
            + "; ".join(f"{m} " + ", ".join(f"{v:.3g}" for v in speeds[m][:3]) for m in METHODS)
            + ".\n\n"
            + f"Tolerances: cone {CONE_TOL:g} of |F|, penetration {PENETRATION_TOL:g}·L₀, "
              f"energy gain {ENERGY_TOL:g} and foot work {WORK_TOL:g} of the energy scale, "
              f"symmetry {SYMMETRY_TOL:g}, creep {CREEP_TOL:g} m. "
            + f"Whole battery: {time.perf_counter() - started:.0f} s of wall time on a shared "
              "2-core machine.\n")
    report.write_section(DOC, SECTION, body, title="# Hard cases")
    print(f"wrote {TABLE} and the '{SECTION}' section of {DOC}")
