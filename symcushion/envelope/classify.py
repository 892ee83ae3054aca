"""Classifying envelope cases from their summaries.

Owns :data:`CLASSES` and the rule that turns a case's running extrema and
final state into measures, margins (1 − value/limit) and a class. It must not
run anything: it reads numbers only.
"""
from __future__ import annotations

import numpy as np

from symcushion.layout.vectors import state_layout
from symcushion.scheme.quaternion import body_axis_np
from symcushion.envelope.cases import SUMMARY
from symcushion.envelope.study import Limits

__all__ = ["CLASSES", "classify"]

#: Outcome classes, in the order of precedence when a case fails several checks.
CLASSES = ("stable", "tip_over", "stroke", "deflection", "deceleration", "rebound",
           "moving", "no_touchdown")


def classify(summary: np.ndarray, x_end: np.ndarray, gravity: np.ndarray, x0: np.ndarray,
             limits: Limits, n_legs: int, reach: float = 0.0) -> dict:
    """Measures, margins and the class of every case.

    A case is ``stable`` when it passes every given limit; otherwise its class
    is the first failed check in the order of :data:`CLASSES` (tip-over first:
    it ends the mission whatever else happened). ``no_touchdown`` marks a case
    whose feet never touched (raise ``duration`` or lower ``clearance``).
    Margins are 1 − value/limit: positive passes, 0 is on the limit.
    ``moving`` marks a case that passes every other check but has not come to
    rest: |v| + |ω|·``reach`` at the end exceeds ``limits.rest_speed``.

    Parameters
    ----------
    reach : float
        Largest distance of a foot at rest from the centre of mass (m): the
        end motion |v| + |ω|·reach bounds the speed of every point of the
        body within that distance.

    Returns
    -------
    dict of str to ndarray
        Measure and margin columns, plus ``class`` (str) and ``stable`` (bool).
    """
    S = {name: summary[i] for i, name in enumerate(SUMMARY)}
    up = -gravity / np.linalg.norm(gravity, axis=0, keepdims=True)
    xl = state_layout(n_legs)
    body_z = body_axis_np(xl.get(x_end, "attitude").T).T
    final_tilt = np.degrees(np.arccos(np.clip(np.sum(up * body_z, axis=0), -1, 1)))
    contacts = xl.legs(x_end, "contact")
    out = {
        "max_stroke": S["max_stroke"], "max_beta": S["max_beta"], "max_gamma": S["max_gamma"],
        "peak_decel": S["peak_decel"], "peak_decel_raw": S["peak_decel_raw"],
        "max_tilt_deg": np.degrees(np.arccos(np.clip(1 - S["max_one_minus_cos_tilt"], -1, 1))),
        "final_tilt_deg": final_tilt, "rebound_speed": S["rebound_speed"],
        "airborne_time": S["airborne_time"], "first_contact_time": S["first_contact_time"],
        "min_height": S["min_height"], "end_time": S["end_time"],
        "final_speed": np.linalg.norm(xl.get(x_end, "velocity"), axis=0),
        "final_rate": np.linalg.norm(xl.get(x_end, "angular_velocity"), axis=0),
        # along the ground: the slope frame's x and y
        "slide": np.linalg.norm((xl.get(x_end, "position") - xl.get(x0, "position"))[:2], axis=0),
        "feet_down": np.sum(contacts > 0.5, axis=0).astype(float),
    }
    n = summary.shape[1]
    failed = {}
    checks = (("tip_over", "max_tilt_deg", limits.tilt_deg),
              ("stroke", "max_stroke", limits.stroke),
              ("deflection", "max_beta", limits.beta),
              ("deflection", "max_gamma", limits.gamma),
              ("deceleration", "peak_decel", limits.deceleration),
              ("rebound", "rebound_speed", limits.rebound_speed),
              ("moving", "final_motion", limits.rest_speed))
    out["final_motion"] = out["final_speed"] + out["final_rate"] * float(reach)
    for check, measure, limit in checks:
        if limit is None:
            continue
        margin = 1 - out[measure] / limit
        key = f"margin_{check}"
        out[key] = np.minimum(out[key], margin) if key in out else margin
        failed[check] = failed.get(check, np.zeros(n, bool)) | (out[measure] > limit)
    if not all(np.all(np.isfinite(v)) for v in out.values()):
        bad = [k for k, v in out.items() if not np.all(np.isfinite(v))]
        raise FloatingPointError(f"non-finite results in {bad}: a case diverged; reduce "
                                 "`scene.dt` or check the legs (docs/envelope.md).")
    cls = np.full(n, "stable", dtype=object)
    for check in reversed(CLASSES[1:-1]):
        if check in failed:
            cls[failed[check]] = check
    cls[S["touched"] < 0.5] = "no_touchdown"
    out["class"] = cls
    out["stable"] = cls == "stable"
    return out
