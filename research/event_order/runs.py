"""The event-order study's runs: the reference, the grid of Δt, errors, orders and the CSV.

Owns running one case (compiled C, the reference and its check), reading a
run's positions at given times, the errors of a run against the reference,
the stroke reversals of a leg, the fitted orders and the CSV. It must not plot or write the results page.
"""
from __future__ import annotations

import csv
import dataclasses
import time

import numpy as np

from symcushion.compiled.codegen import compiled_model
from symcushion.run.driver import simulate
from symcushion.studies import speed_vs_error as sve
from symcushion.studies.speed_vs_error.csv_io import csv_cell

from .cases import (BUILD, CHUNK, COLUMNS, DT_CHECK, DT_GRID, DT_REF, ERROR_KEYS, REVERSAL_DTS,
                    SLIP_DT)


def final_error(run, ref) -> float:
    """max(|x(T) − x_ref(T)| / travel, |v(T) − v_ref(T)| / |v(0)|) at the run's last sample."""
    k = int(np.argmin(np.abs(ref.t - run.t[-1])))
    travel = float(np.max(np.linalg.norm(ref.position - ref.position[0], axis=1)))
    dx = np.linalg.norm(run.position[-1] - ref.position[k]) / travel
    dv = np.linalg.norm(run.velocity[-1] - ref.velocity[k]) / np.linalg.norm(ref.velocity[0])
    return float(max(dx, dv))


def positions_at(t, position, times) -> np.ndarray:
    """Rows of ``position`` (one per sample time of ``t``) at ``times``: each the
    first sample at or after the time, the last sample past the end."""
    t = np.asarray(t)
    rows = [min(np.searchsorted(t, T - 1e-12), len(t) - 1) for T in times]
    return np.asarray(position)[rows]


def at_step(model, scene, dt):
    """``model`` for ``scene`` at step ``dt``: ``simulate`` runs the scene of its model.

    The copy shares the model's Functions and its cache of rollouts (they do
    not depend on Δt).
    """
    return dataclasses.replace(model, scene=scene.with_(dt=dt))


def slip_fraction(model, scene, dt=SLIP_DT) -> float:
    """Share of the contact samples in slip (mode 2) of a run of ``scene`` at ``dt``."""
    traj = simulate(scene.with_(dt=dt), model=at_step(model, scene, dt), monitor=False)
    contact = traj.contact[1:] > 0.5
    return float(np.sum(traj.mode[1:] == 2) / max(np.sum(contact), 1))


#: A stroke change below this (m) is a held stroke (``events = "lock"`` holds
#: it to round-off), not a step in either direction.
HELD_STROKE = 1e-12


def reversal_steps(traj) -> np.ndarray:
    """Which stroke changes are reversals: bool (steps, legs), entry k for the change
    from sample k to k + 1.

    A reversal is a stroke change with the other sign than the leg's previous
    change in the same contact: one per turning point of the stroke (a branch
    switch or a lock). Changes below :data:`HELD_STROKE` (a locked stroke) are
    skipped, so that a lock followed by a release the other way counts once;
    a new contact starts afresh.
    """
    stroke = np.asarray(traj.stroke)
    contact = np.asarray(traj.contact) > 0.5
    change = np.diff(stroke, axis=0)
    out = np.zeros(change.shape, dtype=bool)
    for j in range(stroke.shape[1]):
        last = 0.0
        for k in range(change.shape[0]):
            if not (contact[k, j] and contact[k + 1, j]):
                last = 0.0                      # a new contact starts afresh
                continue
            if abs(change[k, j]) <= HELD_STROKE:
                continue
            sign = np.sign(change[k, j])
            out[k, j] = bool(last and sign != last)
            last = sign
    return out


def leg_reversals(traj) -> tuple:
    """Per leg, the number of :func:`reversal_steps`: one per turning point of the stroke."""
    return tuple(int(n) for n in reversal_steps(traj).sum(axis=0))


def reversals(model, scene, dts=REVERSAL_DTS) -> list:
    """Stroke reversals of each leg in contact, at each Δt of ``dts`` (VM runs).

    A reversal is a step whose stroke change has the other sign than the
    previous step's, both in contact: one per turning point of the stroke,
    where an absorber with an unloading branch switches branch. Returns one
    tuple of per-leg counts per Δt.
    """
    out = []
    for dt in dts:
        traj = simulate(scene.with_(dt=dt), model=at_step(model, scene, dt), monitor=False)
        out.append(leg_reversals(traj))
    return out


def _errors(run, ref, ref_m, scene) -> dict:
    m = sve.metrics(run, scene, "max_up")
    return {"trajectory_error": sve.trajectory_error(run, ref),
            "rebound_error": abs(m["rebound_speed"] - ref_m["rebound_speed"]),
            "final_error": final_error(run, ref), "rebound_speed": m["rebound_speed"]}


def run_case(name, variant, scene, progress=print):
    """Rows of one case: its reference check, then every Δt of :data:`DT_GRID`."""
    model = compiled_model(scene, BUILD / scene.name, steps=CHUNK)
    started = time.perf_counter()
    ref = sve.simulate_chunked(model, scene, DT_REF, passes=1)
    check = sve.simulate_chunked(model, scene, DT_CHECK, passes=1)
    ref_m = sve.metrics(ref, scene, "max_up")
    floor = _errors(ref, check, sve.metrics(check, scene, "max_up"), scene)
    floor["rebound_speed"] = ref_m["rebound_speed"]
    slip = slip_fraction(model, scene)
    flips = " / ".join(" ".join(map(str, counts)) for counts in reversals(model, scene))
    progress(f"{name} / {variant}: reference at {DT_REF:g} checked at {DT_CHECK:g} "
             f"({time.perf_counter() - started:.0f} s): traj {floor['trajectory_error']:.1e}, "
             f"rebound {floor['rebound_error']:.1e} m/s, final {floor['final_error']:.1e}; "
             f"slip fraction {slip:.2f}; stroke reversals per leg at "
             f"{' / '.join(f'{d:g}' for d in REVERSAL_DTS)} s: {flips}")
    rows = [{"scene": name, "variant": variant, "slip": scene.slip, "events": scene.events,
             "kind": "reference check",
             "dt": DT_REF,
             "status": "ok", **floor, "slip_fraction": slip, "reversals": flips}]
    for dt in DT_GRID:
        run = sve.simulate_chunked(model, scene, dt)
        row = {"scene": name, "variant": variant, "slip": scene.slip, "events": scene.events,
               "kind": "run", "dt": dt,
               "status": "ok" if run.finite() else "non-finite",
               "cpu_per_sim_second": run.info["cpu"] / run.info["sim_seconds"]}
        if row["status"] == "ok":
            row.update(_errors(run, ref, ref_m, scene))
        rows.append(row)
        progress(f"  dt={dt:<7g} traj {row.get('trajectory_error', np.nan):.2e} "
                 f"rebound {row.get('rebound_error', np.nan):.2e} "
                 f"final {row.get('final_error', np.nan):.2e}")
    return rows


def orders(rows):
    """Fitted order (order, Δt range, points) of every (scene, variant) and error."""
    out = []
    cases = [(r["scene"], r["variant"]) for r in rows if r["kind"] == "reference check"]
    for scene, variant in cases:
        sel = [r for r in rows if (r["scene"], r["variant"]) == (scene, variant)
               and r["kind"] == "run" and r["status"] == "ok"]
        floor = next(r for r in rows if (r["scene"], r["variant"]) == (scene, variant)
                     and r["kind"] == "reference check")
        entry = {"scene": scene, "variant": variant, "slip_fraction": floor["slip_fraction"],
                 "reversals": floor["reversals"]}
        for key in ERROR_KEYS:
            if key not in floor:
                entry[key] = (float("nan"), (), 0)
                continue
            entry[key] = sve.convergence_order([r["dt"] for r in sel], [r[key] for r in sel],
                                               floor=floor[key], dt_max=max(DT_GRID))
        out.append(entry)
    return out


def _fmt(x, spec=".2e"):
    return "—" if x is None or not np.isfinite(x) else format(x, spec)


def write_csv(rows, path):
    """Write the rows (dicts) with :data:`COLUMNS` as header; missing numbers are empty."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(COLUMNS)
        for row in rows:
            writer.writerow([csv_cell(row.get(c)) for c in COLUMNS])
