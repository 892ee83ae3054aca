"""The Markdown of the "Results" section of docs/speed-vs-error.md.

Owns the wording and tables of the results (reference check, orders,
acceptance, per-scene tables) and the description of the machine. It reads
rows, checks and orders; it must not compute them or write files.
"""
from __future__ import annotations

import platform
from pathlib import Path

import casadi as ca
import numpy as np


from .grid import (BEST_OF, FLOOR_FACTOR, ORDER_DT_MAX, REBOUND_AIM, REBOUND_BOUND, SCENES,
                   VARIANTS)
from .orders import ERROR_KEYS, equal_error_comparison, variants_on
from .plots import TITLES


def _fmt(x, spec=".2e"):
    return "—" if x is None or not np.isfinite(x) else format(x, spec)


def _machine() -> str:
    import subprocess

    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    cc = subprocess.run(["gcc", "--version"], capture_output=True, text=True).stdout
    return (f"{cpu}, {platform.system()} {platform.machine()}, "
            f"{cc.splitlines()[0] if cc else 'gcc ?'}, CasADi {ca.__version__}, "
            f"CPython {platform.python_version()}")


def report_text(rows, checks, orders, notes, dt_grid, total_seconds,
                out: str = "figures") -> str:
    """The Markdown of the results section."""
    lines = [f"Produced by `python studies/speed_vs_error.py` in {total_seconds / 60:.1f} min "
             f"on {_machine()}; the machine has 2 cores and was shared with other jobs. "
             f"Δt grid {', '.join(f'{d:g}' for d in dt_grid)} s; the data are in "
             f"`{out}/speed_vs_error.csv`, the plot in `{out}/speed_vs_error.png`. Times "
             "are process CPU time per simulated second of the step loop (best of up to "
             f"{BEST_OF} passes; peers as described under \"Timing\").", ""]
    lines += ["![speed vs error](../figures/speed_vs_error.png)", ""]

    lines += ["### Reference and its check", "",
              "| scene | Δt_ref (s) | rebound speed (m/s) | peak \\|a − g\\| (m/s²) | "
              "peak hinge (rad) | peak stroke (m) | self-error: rebound (m/s) | peak decel "
              "(rel.) | peak deflection (rel.) | trajectory (rel.) | run time (s) |",
              "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for c in checks:
        m, s = c["ref"], c["self_error"]
        lines.append(f"| {c['scene']} | {c['dt_ref']:g} | {m['rebound_speed']:.8f} | "
                     f"{m['peak_decel']:.5f} | {m['peak_hinge']:.6f} | {m['peak_stroke']:.3e} | "
                     f"{_fmt(s['rebound_error'])} | {_fmt(s['peak_decel_error'])} | "
                     f"{_fmt(s['peak_deflection_error'])} | {_fmt(c['trajectory'])} | "
                     f"{c['wall']:.1f} |")
    vm_c = max((c.get("vm_c_max_diff", 0.0) for c in checks), default=0.0)
    lines += ["", "Self-error = |metric(2·Δt_ref) − metric(Δt_ref)|, the Richardson estimate "
              "of the reference's own error for order 1 (for order p it is that over 2^p − 1, "
              "smaller). Errors below 10× this are not used in the order fits. VM and "
              f"compiled runs agree: largest difference of any metric {vm_c:.1e}.", ""]

    lines += ["### Convergence orders", "",
              f"Slope of log(error) against log(Δt), least squares over the grid points with "
              f"Δt ≤ {ORDER_DT_MAX:g} s (the range used and the number of points in brackets) "
              f"whose error is above {FLOOR_FACTOR:g}× the reference's self-error; — where "
              "fewer than two points qualify.", "",
              "| scene | method | rebound speed | peak deceleration | peak deflection | "
              "trajectory |", "|---|---|---|---|---|---|"]
    for o in orders:
        cells = []
        for key in ERROR_KEYS:
            p, rng, n = o[key]
            cells.append("—" if not np.isfinite(p) else
                         f"{p:.2f} ({rng[0]:g}–{rng[1]:g}, {n})")
        lines.append(f"| {o['scene']} | {o['method']} | " + " | ".join(cells) + " |")

    lines += ["", "### Acceptance", ""]
    lines += _acceptance_text(rows)

    lines += _scene_tables(rows)
    if notes:
        lines += ["", "Notes of this run:", ""] + [f"* {n}" for n in notes]
    return "\n".join(lines)


def _scene_tables(rows) -> list:
    """Markdown lines of one table per scene: the C and VM rows by Δt, then the peers."""
    lines = []
    for scene in SCENES:
        sel = [r for r in rows if r["scene"] == scene]
        if not sel:
            continue
        lines += ["", f"### {TITLES[scene]}", "",
                  "Errors against the reference (rebound absolute, the others relative); "
                  "time per simulated second of the compiled rollout (C) and the VM rollout "
                  "(VM), step loop only. VM and C results are identical, so their errors are "
                  "listed once.", "",
                  "| method | Δt (s) | rebound err (m/s) | peak decel err | peak defl. err | "
                  "trajectory err | C (s/sim-s) | VM (s/sim-s) | status |",
                  "|---|---:|---:|---:|---:|---:|---:|---:|---|"]
        for method in VARIANTS:
            for r in [r for r in sel if r["method"] == f"{method}/c"]:
                vm = next((v for v in sel if v["method"] == f"{method}/vm"
                           and v["dt"] == r["dt"]), None)
                lines.append(
                    f"| {method} | {r['dt']:g} | {_fmt(r.get('rebound_error'))} | "
                    f"{_fmt(r.get('peak_decel_error'))} | {_fmt(r.get('peak_deflection_error'))} "
                    f"| {_fmt(r.get('trajectory_error'))} | {_fmt(r['wall_per_sim_second'], '.3g')}"
                    f" | {_fmt(vm['wall_per_sim_second'], '.3g') if vm else 'skipped'} | "
                    f"{r['status']} |")
        peers = [r for r in sel if r["backend"] == "peer"]
        if peers:
            lines += ["", "| peer | Δt or rtol | rebound err (m/s) | peak decel err | "
                      "peak defl. err | trajectory err | wall (s/sim-s) | status |",
                      "|---|---:|---:|---:|---:|---:|---:|---|"]
            for r in peers:
                knob = f"rtol {r['tolerance']:g}" if r.get("tolerance") is not None \
                    and np.isfinite(r["tolerance"]) else f"{r['dt']:g}"
                lines.append(
                    f"| {r['method']} | {knob} | {_fmt(r.get('rebound_error'))} | "
                    f"{_fmt(r.get('peak_decel_error'))} | {_fmt(r.get('peak_deflection_error'))} "
                    f"| {_fmt(r.get('trajectory_error'))} | "
                    f"{_fmt(r.get('wall_per_sim_second', np.nan), '.3g')} | {r['status']} |")
    return lines


def _acceptance_text(rows) -> list:
    lines = []
    comp = equal_error_comparison(rows)
    if not comp:
        lines.append("* **Compiled vs peers at equal rebound error (Fig. 3):** not measured: "
                     "no peer rows (see the notes below).")
    else:
        lines += ["* **Compiled vs peers at equal rebound error (Fig. 3).** For each peer run, "
                  "the cost of each compiled method at the same rebound-speed error, "
                  "log-log interpolated along its Pareto front (cheapest first, each point "
                  "more accurate than the last); ratio = peer cost / compiled cost, > 1 means "
                  "the compiled simulator is faster. \"≥\": the peer's error is above the "
                  "compiled method's coarsest point, whose cost is an upper bound.", "",
                  "| peer run | rebound err (m/s) | peer (s/sim-s) | " +
                  " | ".join(f"{m}/c ratio" for m in comp[0]["ours"]) + " |",
                  "|---|---:|---:|" + "---:|" * len(comp[0]["ours"])]
        for e in comp:
            # the penalty runs are named by their tolerance already
            knob = "" if e["peer"].startswith("penalty") else f" (Δt {e['dt']:g})"
            cells = []
            for m, (cost, how) in e["ours"].items():
                if how == "not reached":
                    cells.append("not reached")
                else:
                    bound = "≥ " if how == "at most" else ""
                    cells.append(f"{bound}{e['peer_cost'] / cost:.3g}")
            lines.append(f"| {e['peer']}{knob} | {e['error']:.2e} | {e['peer_cost']:.3g} | "
                         + " | ".join(cells) + " |")
        lines.append("")
    fig3 = [r for r in rows if r["scene"] == "fig3" and r["backend"] == "c"
            and r["status"] == "ok"]
    if fig3:
        lines.append("* **The paper's |Δy′| < 1e-2 m/s on Fig. 3** (Δy′ = rebound speed at the "
                     "height of first contact − impact speed, as `symcushion reproduce` "
                     "measures it; the exact value is 0, the frictionless rods being "
                     "conservative):")
        lines.append("")
        lines.append(f"| method | Δy′ at Δt = 1e-3 (m/s) | \\|Δy′\\| < {REBOUND_BOUND:g} | "
                     f"\\|Δy′\\| < {REBOUND_AIM:g} (the aim) | largest grid Δt with "
                     f"\\|Δy′\\| < {REBOUND_AIM:g} |")
        lines.append("|---|---:|---|---|---:|")
        for m in variants_on(rows, "fig3"):
            sel = [r for r in fig3 if r["contact_step"] == m and r["rebound_kind"] == "ballistic"]
            at = next((r for r in sel if abs(r["dt"] - 1e-3) < 1e-12), None)
            aim = [r["dt"] for r in sel if abs(r["rebound_dv"]) < REBOUND_AIM]
            dv = at["rebound_dv"] if at else float("nan")
            largest = f"{max(aim):g}" if aim else "none"
            lines.append(f"| {m} | {_fmt(dv)} | {'yes' if abs(dv) < REBOUND_BOUND else 'NO'} | "
                         f"{'yes' if abs(dv) < REBOUND_AIM else 'NO'} | {largest} |")
    return lines

