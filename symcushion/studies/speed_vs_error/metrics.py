"""Metrics of a run and their errors against the reference, and the CSV row of a run.

Owns the rebound speed, the peaks, the trajectory error and the errors of a
run's metrics against the reference's (defined in docs/speed-vs-error.md),
and :func:`result_row`, one CSV row of a measured run. It must not run
simulations, fit orders or write files.
"""
from __future__ import annotations

import numpy as np

from symcushion.model.scene_data import Scene

from .runs import Run


def rebound_speed(run: Run, kind: str, gravity: float = 9.81) -> tuple[float, str]:
    """Rebound speed of a run (m/s) and how it was measured.

    ``kind='ballistic'`` (Fig. 3): after the lowest point (first sample with
    upward velocity), the first sample k at or above the height of first
    contact z₀ = z(0) gives v = sqrt(v_z,k² + 2|g|(z_k − z₀)), the speed at z₀
    of the free flight through sample k (the rods are back at rest, β = 0,
    exactly at z₀). If the ball never gets back to z₀ the largest upward
    velocity is returned instead, kind ``'max_up'``.
    ``kind='max_up'``: the largest upward vertical velocity over the run.
    """
    if kind not in ("ballistic", "max_up"):
        raise ValueError(f"`kind` must be 'ballistic' or 'max_up', got {kind!r}.")
    vz, z = run.velocity[:, 2], run.position[:, 2]
    if kind == "ballistic":
        up = np.flatnonzero(vz > 0)
        if up.size:
            above = np.flatnonzero(z[up[0]:] >= z[0])
            if above.size:
                k = up[0] + above[0]
                return float(np.sqrt(max(vz[k] ** 2 + 2 * gravity * (z[k] - z[0]), 0.0))), kind
    return float(np.max(vz)), "max_up"


def metrics(run: Run, scene: Scene, kind: str) -> dict:
    """The metrics of a run: rebound speed (m/s) and how it was measured, Δy′ =
    v_reb − |ż(0)| (m/s; NaN unless measured ballistically at z₀), peak
    |a − g| (m/s²), peak hinge angle (rad) and peak stroke (m)."""
    g = float(np.linalg.norm(scene.gravity))
    v, used = rebound_speed(run, kind, g)
    return {"rebound_speed": v, "rebound_kind": used,
            # Δy′ of the paper's claim: only where the rebound is measured at z₀
            "rebound_dv": v - abs(float(run.velocity[0, 2])) if used == "ballistic"
            else float("nan"),
            "peak_decel": float(np.max(run.decel)), "peak_hinge": float(np.max(run.hinge)),
            "peak_stroke": float(np.max(run.stroke))}


def trajectory_error(run: Run, ref: Run) -> float:
    """RMS over the run's samples of |x(t_k) − x_ref(t_k)|, over the reference's travel.

    x_ref is linearly interpolated to the run's times (exact when they fall on
    the reference's samples, as every grid Δt does); the scale is
    max_t |x_ref(t) − x_ref(0)|. Samples past the reference's end are ignored.
    """
    t = run.t[run.t <= ref.t[-1] * (1 + 1e-12)]
    if t.size == 0:
        raise ValueError("`run` has no samples inside the reference's time span.")
    ref_x = np.column_stack([np.interp(t, ref.t, ref.position[:, i]) for i in range(3)])
    diff = run.position[:t.size] - ref_x
    scale = float(np.max(np.linalg.norm(ref.position - ref.position[0], axis=1)))
    if not scale > 0:
        raise ValueError("the reference's centre of mass never moves: no trajectory scale.")
    return float(np.sqrt(np.mean(np.sum(diff ** 2, axis=1))) / scale)


def errors(run_metrics: dict, ref_metrics: dict, deflection: str) -> dict:
    """Errors of a run's metrics against the reference's.

    rebound_error absolute (m/s); peak_decel_error and peak_deflection_error
    relative to the reference's value; ``deflection`` picks the hinge angle
    (``'hinge'``) or the stroke (``'stroke'``).
    """
    if deflection not in ("hinge", "stroke"):
        raise ValueError(f"`deflection` must be 'hinge' or 'stroke', got {deflection!r}.")
    key = "peak_" + deflection
    return {"rebound_error": abs(run_metrics["rebound_speed"] - ref_metrics["rebound_speed"]),
            "peak_decel_error": abs(run_metrics["peak_decel"] / ref_metrics["peak_decel"] - 1),
            "peak_deflection_error": abs(run_metrics[key] / ref_metrics[key] - 1)}



def result_row(scene_name, contact_step, backend, dt, run: Run | None, status, ref_metrics,
               ref, spec, scene, tolerance=None, build=None) -> dict:
    """One CSV row (a dict over :data:`~.grid.COLUMNS`) of a run against the reference.

    ``method`` is ``contact_step/backend`` for the VM and C backends, else
    ``contact_step``. Timing columns come from ``run.info``; metrics and
    errors are added only when ``status`` is ``'ok'``; ``run`` None gives the
    identifying columns and the status only (a failed peer run).
    """
    method = f"{contact_step}/{backend}" if backend in ("vm", "c") else contact_step
    row = {"scene": scene_name, "method": method, "contact_step": contact_step,
           "backend": backend, "dt": dt, "tolerance": tolerance, "status": status}
    if run is None:
        return row
    info = run.info
    row.update(steps_run=info["steps_run"], sim_seconds=info["sim_seconds"],
               eval_wall_seconds=info["wall"], eval_cpu_seconds=info["cpu"],
               wall_per_sim_second=info["cost"] / info["sim_seconds"],
               cpu_per_sim_second=info["cpu"] / info["sim_seconds"], passes=info["passes"],
               build_seconds=info["build"] if build is None else build)
    if status != "ok":
        return row
    m = metrics(run, scene, spec["rebound"])
    row.update(m)
    row.update(errors(m, ref_metrics, spec["deflection"]))
    row["trajectory_error"] = trajectory_error(run, ref)
    return row
