"""The event-order study's results text: the measured tables and the cost ratios.

Owns the Markdown of the section "Events: measured" and the head of the
tables that give a value per time; it must not run anything.
"""
from __future__ import annotations

import numpy as np

from .cases import DT_CHECK, DT_GRID, DT_REF, REVERSAL_DTS, SLIP_DT, case_label
from .controls import SWITCH_DTS, SWITCH_REF
from .runs import _fmt


def time_table_head(cells, aligns, times) -> list:
    """The two header lines of a Markdown table whose leading columns are ``cells``
    (aligned by ``aligns``, e.g. "---:") and whose further columns are ``times`` (s)."""
    if len(cells) != len(aligns):
        raise ValueError(f"`aligns` must give one alignment per cell: {len(cells)} cells, "
                         f"{len(aligns)} alignments.")
    return ["| " + " | ".join(cells) + " | " + " | ".join(f"t = {t:g} s" for t in times) + " |",
            "|" + "|".join(aligns) + "|" + "---:|" * len(times)]


def _fmt_order(entry):
    order, _, n = entry
    return "—" if not np.isfinite(order) else f"{order:.2f} ({n} pts)"


def cost_ratios(rows):
    """(scene, variant, ratio to the midpoint case, ratio to the default case) per branch case.

    Ratios of CPU per simulated second at equal Δt, median over :data:`DT_GRID`.
    """
    def cost(scene, variant):
        return {r["dt"]: r["cpu_per_sim_second"] for r in rows
                if (r["scene"], r["variant"]) == (scene, variant) and r["kind"] == "run"
                and r.get("cpu_per_sim_second")}

    out = []
    for scene, variant in sorted({(r["scene"], r["variant"]) for r in rows
                                  if r.get("events") in ("branch", "lock")
                                  and r.get("cpu_per_sim_second")}):
        mine = cost(scene, variant)
        base = variant.split(" (")[0]
        ratios = []
        for other in (case_label(base, "midpoint"), base):
            theirs = cost(scene, other)
            common = sorted(set(mine) & set(theirs))
            ratios.append(float(np.median([mine[d] / theirs[d] for d in common]))
                          if common else float("nan"))
        out.append((scene, variant, *ratios))
    return out


def report_text(rows, fits, seconds):
    """The section "Events: measured" of the results page."""
    lines = [f"Produced by `python studies/event_order.py` in {seconds / 60:.1f} min; data in "
             "`figures/event_order.csv`, plot `figures/event_order.png`. Implicit contact step, "
             f"compiled C; Δt grid {', '.join(f'{d:g}' for d in DT_GRID)} s; reference at "
             f"Δt = {DT_REF:g} s checked against {DT_CHECK:g} s. The switch control "
             "(`switch_control()`: every leg turns once onto its unloading branch, no chatter) "
             f"runs on the VM at Δt {', '.join(f'{d:g}' for d in SWITCH_DTS)} s against "
             f"{SWITCH_REF[0]:g} s checked against {SWITCH_REF[1]:g} s.", "",
             "![event order](event_order.png)", "",
             "Fitted orders (least squares over the grid, errors above 10× the reference's "
             "own); slip: share of the contact samples in slip at "
             f"Δt = {SLIP_DT:g} s; reversals: each leg's stroke reversals in contact at "
             f"Δt = {' / '.join(f'{d:g}' for d in REVERSAL_DTS)} s (one per turning point; "
             "growing as 1/Δt where the leg chatters between its branches; a held stroke, "
             "changing by less than 1e-12 m, is not a step either way):", "",
             "| scene | variant | slip | trajectory | rebound | final state | reversals |",
             "|---|---|---:|---|---|---|---|"]
    for f in fits:
        lines.append(f"| {f['scene']} | {f['variant']} | {f['slip_fraction']:.0%} | "
                     f"{_fmt_order(f['trajectory_error'])} | {_fmt_order(f['rebound_error'])} | "
                     f"{_fmt_order(f['final_error'])} | {f['reversals']} |")
    lines += ["", "Cost of `events = \"branch\"` and `\"lock\"` (compiled, this run): CPU per "
              "simulated second "
              "over that of the same variant with the midpoint rule alone and with the default "
              "step, median over the grid:", "",
              "| scene | variant | against midpoint | against default |", "|---|---|---:|---:|"]
    lines += [f"| {scene} | {variant} | {a:.2f} | {b:.2f} |"
              for scene, variant, a, b in cost_ratios(rows)]
    lines += ["", "Errors at each Δt (trajectory and final state relative, rebound in m/s; "
              "cost: CPU s per simulated second, compiled, measured in this one run on a "
              "shared machine):", "",
              "| scene | variant | row | Δt (s) | trajectory | rebound | final state | cost |",
              "|---|---|---|---:|---:|---:|---:|---:|"]
    for r in rows:
        lines.append(f"| {r['scene']} | {r['variant']} | {r['kind']} | {r['dt']:g} | "
                     f"{_fmt(r.get('trajectory_error'))} | {_fmt(r.get('rebound_error'))} | "
                     f"{_fmt(r.get('final_error'))} | "
                     f"{_fmt(r.get('cpu_per_sim_second'), '.3g')} |")
    lines += ["", "Reference-check rows: the errors of the reference against its check "
              "(its own error estimate)."]
    return "\n".join(lines)


#: Controls (no touchdown, no branch switch): the lander with a linear absorber
#: (1e5 N/m) on a level plane, started at rest on its feet
#: (``equilibrium_state``) with a velocity kick, run for CONTROL_DURATION on the
#: VM against a run at CONTROL_DT_REF. Name: (μ, velocity kick (m/s, world),
#: angular velocity kick (rad/s, body axes)). The first bounces and rocks:
#: its feet lift off and land one by one and slip only briefly (kicked only
#: upwards or only rocked, it converges at second order: the tests); the
#: second slides (μ = 0.1) along x, its splayed feet slipping along paths
#: that turn; the third slides and turns.
