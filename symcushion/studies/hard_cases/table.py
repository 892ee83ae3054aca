"""The Markdown table of the hard-case battery: one row per case and method; reading it back.

Owns the columns, the formatting of a result, the verdict text, the notes
of each case and where the table is written. It must not run cases or
decide verdicts (:class:`~.checks.Result` does).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from symcushion.contact.args import METHODS

from .cases import STIFF_FRACTION, recontact_flights
from .checks import Result

#: The repository root: this file is symcushion/studies/hard_cases/table.py.
ROOT = Path(__file__).resolve().parents[3]
TABLE = ROOT / "figures" / "hard_cases.md"


def notes(result: Result) -> str:
    """What the case shows beyond the pass/fail checks, in a few words."""
    s = result.stats
    case = result.case
    if case == "recontact":
        return (f"{recontact_flights(s.t_end)} flights of 6.4 ms (closed form), "
                f"{s.lift_offs} seen as a lift-off at a step end")
    if case == "near_singular":
        return f"closest strut to e_n: {s.singular:.2e} rad"
    if case == "slope_stick":
        return result.setup.note
    if case == "stiff_axial_stick":
        return f"Δt = {STIFF_FRACTION:g}·2/ω_max"
    return ""


# ---------------------------------------------------------------------------
# the table
# ---------------------------------------------------------------------------
COLUMNS = ("case", "method", "Δt (s)", "time (s)", "steps", "finite", "cone excess",
           "penetration (m)", "energy gain", "foot work", "symmetry", "creep (m)",
           "1 − n·n′ max", "adaptive driver", "landings / lift-offs", "notes", "verdict")


def _g(x, fmt=".1e"):
    return "—" if x is None or not np.isfinite(x) else format(x, fmt)


def verdict(result: Result) -> str:
    """``pass`` or ``FAIL (check, check)`` — the table's last column."""
    return "pass" if result.passed else "FAIL (" + ", ".join(result.failures) + ")"


def table_row(result: Result) -> str:
    """One Markdown row of the table."""
    s, setup = result.stats, result.setup
    a = result.adaptive
    if a:
        adaptive = (f"{a['steps']} steps in {a['duration']:g} s, {a['halvings']} halvings, "
                    f"Δt_min {a['dt_min']:.2g} s")
        if "capped" in a:
            adaptive += f", {a['capped']} capped by stability"
    else:
        adaptive = "—"
    energy = (_g(s.energy_gain / result.energy_scale) if setup.energy == "mechanical"
              else "n/a (2.1)")
    creep = "—"
    if setup.creep:
        creep = _g(s.creep_foot) + (f" / body {_g(s.creep_body)}" if setup.creep == "feet+body"
                                    else "")
    cells = [result.case, result.method, _g(result.dt, ".3g"), _g(s.t_end, ".4g"),
             str(s.steps), "yes" if s.finite else "NO", _g(s.cone), _g(s.penetration),
             energy, _g(s.work_max / result.energy_scale),
             _g(s.symmetry) if setup.symmetry else "—", creep, _g(s.criterion), adaptive,
             f"{s.landings} / {s.lift_offs}", notes(result), verdict(result)]
    return "| " + " | ".join(cells) + " |"


def table(results) -> str:
    """The Markdown table of a list of results."""
    head = "| " + " | ".join(COLUMNS) + " |\n|" + "---|" * len(COLUMNS)
    return head + "\n" + "\n".join(table_row(r) for r in results) + "\n"


def read_table(path=TABLE) -> dict:
    """Verdicts of a written table: {(case, method): 'pass' or 'FAIL (...)'}."""
    out = {}
    for line in Path(path).read_text().splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) == len(COLUMNS) and cells[1] in METHODS:
            out[(cells[0], cells[1])] = cells[-1]
    return out

