"""Fitted convergence orders and costs at equal error (Pareto fronts) of the study's rows.

Owns the least-squares order fit, the table of orders per scene, method and
metric, and the comparison of compiled methods against peers at equal
error. It reads rows (dicts, :data:`~.grid.COLUMNS`); it must not run
simulations, plot or write files.
"""
from __future__ import annotations

import math

import numpy as np


from .grid import FLOOR_FACTOR, ORDER_DT_MAX, SCENES, VARIANTS
from symcushion.run.error_control import fitted_order


def convergence_order(dts, errs, floor: float = 0.0, dt_max: float = ORDER_DT_MAX):
    """Least-squares slope of log(error) against log(Δt).

    Uses the points with Δt ≤ ``dt_max`` and error > FLOOR_FACTOR·``floor``
    (finite, positive). Returns (order, (Δt_min, Δt_max), n) with order NaN
    and an empty range when fewer than two points qualify.
    """
    dts, errs = np.asarray(dts, dtype=float), np.asarray(errs, dtype=float)
    keep = (np.isfinite(errs) & (errs > 0) & (dts <= dt_max * (1 + 1e-9))
            & (errs > FLOOR_FACTOR * floor))
    if keep.sum() < 2:
        return float("nan"), (), int(keep.sum())
    slope = fitted_order(dts[keep], errs[keep])
    return float(slope), (float(dts[keep].min()), float(dts[keep].max())), int(keep.sum())



ERROR_KEYS = ("rebound_error", "peak_decel_error", "peak_deflection_error", "trajectory_error")


def orders_table(rows, floors) -> list:
    """Fitted orders per scene, contact step and metric (compiled rows; VM rows are equal)."""
    out = []
    for scene in SCENES:
        for method in VARIANTS:
            sel = [r for r in rows if r["scene"] == scene and r["method"] == f"{method}/c"
                   and r["status"] == "ok"]
            if not sel or scene not in floors:
                continue
            entry = {"scene": scene, "method": method}
            for key in ERROR_KEYS:
                entry[key] = convergence_order([r["dt"] for r in sel],
                                               [r.get(key, np.nan) for r in sel],
                                               floors[scene][key])
            out.append(entry)
    return out


def pareto(points):
    """Points (wall, error) on the lower-left front: each cheaper one is less accurate."""
    pts = sorted((w, e) for w, e in points if np.isfinite(w) and np.isfinite(e) and e > 0)
    front, best = [], math.inf
    for w, e in pts:
        if e < best:
            front.append((w, e))
            best = e
    return front


def cost_at_error(front, error):
    """Wall per simulated second to reach ``error`` along a front, log-log interpolated.

    Returns (cost, how): how is ``'interpolated'``, ``'at most'`` (the error
    is above the front's largest: its cheapest point already reaches it) or
    ``'not reached'`` (below its smallest error; cost NaN).
    """
    if not front:
        return float("nan"), "not reached"
    walls = np.array([w for w, _ in front])
    errs = np.array([e for _, e in front])
    if error >= errs[0]:
        return float(walls[0]), "at most"
    if error < errs[-1]:
        return float("nan"), "not reached"
    # errs decreases along the front; interpolate log wall against log error
    return float(np.exp(np.interp(-np.log(error), -np.log(errs), np.log(walls)))), "interpolated"


def variants_on(rows, scene) -> list:
    """The variants with compiled rows on ``scene``, in :data:`VARIANTS` order (a variant
    that does not apply to the scene, such as the stroke lock without friction, has none)."""
    return [m for m in VARIANTS
            if any(r["scene"] == scene and r["method"] == f"{m}/c" for r in rows)]


def equal_error_comparison(rows, scene="fig3", key="rebound_error"):
    """For every peer point of a scene: the compiled methods' cost at the same error.

    Each entry's ``ours`` maps the variants run on the scene (:func:`variants_on`)
    to (cost, how) of :func:`cost_at_error`.
    """
    out = []
    fronts = {m: pareto([(r["wall_per_sim_second"], r.get(key, np.nan)) for r in rows
                         if r["scene"] == scene and r["method"] == f"{m}/c"
                         and r["status"] == "ok"]) for m in variants_on(rows, scene)}
    for r in rows:
        if r["scene"] != scene or r["backend"] != "peer" or r["status"] != "ok":
            continue
        entry = {"peer": r["method"], "dt": r["dt"], "tolerance": r["tolerance"],
                 "error": r[key], "peer_cost": r["wall_per_sim_second"], "ours": {}}
        for m in fronts:
            cost, how = cost_at_error(fronts[m], r[key])
            entry["ours"][m] = (cost, how)
        out.append(entry)
    return out

