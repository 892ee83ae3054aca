"""What double precision resolves of the slope lander: each run's round-off floor.

Owns the runs of ``--roundoff``: the lander of ``studies/lander_slope.toml``
with each scheme of :data:`ROUNDOFF_SCHEMES` at each Δt of
:data:`ROUNDOFF_DTS`, and its regularised reference at the rungs
of :data:`REGULARISED_RUNS`, each from its committed initial state and from that
state with the velocity across the slope moved by one unit in the last
place (:func:`ulp_nudge`, the smallest change a double can make), and the
distance of the nudged run's centre of mass from the unmoved run's at
:data:`smoothness.SMOOTH_TIMES` (:func:`roundoff_runs`); and the section's
text (:func:`roundoff_text`). It must not fit orders or write files
(``main`` writes its section).

Why: an order fitted over a range of Δt needs each run's error measured
against a reference that is known ten times better than the finest run's
error. One ulp of one entry of the initial state is below any error a run
can be asked to have, and below what the scene's data can mean; the
distance such a nudge moves a run is a floor under what that run says, in
double precision, about the motion. No reference of the scene is known
better than the floor of the run that serves as it.
"""
from __future__ import annotations

import numpy as np

from .cases import slope_cases
from .limits import ORACLE_RUNS, _trajectory, regularized_scene
from .runs import positions_at
from .smoothness import SMOOTH_TIMES, micrometres, nudged
from .text import time_table_head

#: The schemes whose floor is measured: the default step (whose run at 1e-6 s is
#: the order fits' reference) and the stroke lock (the envelope's scheme).
ROUNDOFF_SCHEMES = ("all events", "all events (midpoint, lock)")
#: Δt of their runs (s): the finest point of the order fits' grid, and the
#: references' range.
ROUNDOFF_DTS = (1e-4, 1e-5, 1e-6)
#: (rate_width w in m²/s, Δt in s) of the regularised references whose floor is
#: measured: the two that "--limits" compares the schemes with.
REGULARISED_RUNS = ORACLE_RUNS


def ulp_nudge(value: float) -> float:
    """The change from ``value`` to the next larger double: one unit in its last place."""
    value = float(value)
    if not np.isfinite(value):
        raise ValueError(f"`value` must be finite, got {value!r}.")
    return float(np.nextafter(value, np.inf) - value)


def _floor(scene, dt, times) -> np.ndarray:
    """Distance (m) at ``times`` between the run of ``scene`` at ``dt`` and the run
    whose v_y is one ulp larger."""
    base = _trajectory(scene, dt, keep_rows=20_000)
    moved = _trajectory(nudged(scene, "velocity", 1, ulp_nudge(scene.body.velocity[1])), dt,
                        keep_rows=20_000)
    return np.linalg.norm(positions_at(moved.t, moved.position, times)
                          - positions_at(base.t, base.position, times), axis=1)


def roundoff_runs(schemes=ROUNDOFF_SCHEMES, dts=ROUNDOFF_DTS, regularised=REGULARISED_RUNS,
                  times=SMOOTH_TIMES, progress=print) -> list:
    """One row per scheme and Δt, then one per regularised reference: ``scheme``,
    ``dt``, ``nudge`` (m/s, one ulp of v_y) and ``moved`` (m, (len(times),): the
    nudged run's distance from the unmoved run at ``times``).

    ``regularised`` holds (rate_width in m²/s, Δt in s) pairs; empty for none.
    """
    by_label = slope_cases(schemes)
    dts = np.asarray(dts, dtype=float)
    if dts.ndim != 1 or not np.all(np.isfinite(dts)) or np.any(dts <= 0):
        raise ValueError(f"`dts` must be positive finite steps (s), got {dts!r}.")
    runs = [(label, by_label[label], float(dt)) for label in schemes for dt in dts]
    runs += [(f"regularised reference (w = {w:g} m²/s)", regularized_scene("all events", w),
              float(dt)) for w, dt in regularised]
    rows = []
    for label, scene, dt in runs:
        moved = _floor(scene, dt, times)
        rows.append(dict(scheme=label, dt=dt, nudge=ulp_nudge(scene.body.velocity[1]),
                         moved=moved))
        progress(f"round-off: {label}, dt = {dt:g}: one ulp of v_y moves it "
                 f"{micrometres(moved.max())} µm")
    return rows


def roundoff_text(rows, times=SMOOTH_TIMES) -> str:
    """The section "Events: what double precision resolves" from :func:`roundoff_runs`."""
    lines = ["Produced by `python studies/event_order.py --roundoff` (compiled C, about 8 "
             "minutes): the lander of `studies/lander_slope.toml` with the default step and "
             "with the stroke lock, and its regularised references (`smooth = true`, "
             "`rate_width` w; default step), each run twice: from its committed initial state "
             "and with the velocity across the slope moved by one unit in its last place (one "
             "ulp, the smallest change a double can make). The columns give how far that "
             "moves the centre of mass (µm): a floor under what the run, computed in double "
             "precision, says about the motion.", ""]
    lines += time_table_head(("run", "Δt (s)", "nudge (m/s)"), ("---", "---:", "---:"), times)
    for r in rows:
        lines.append(f"| {r['scheme']} | {r['dt']:g} | {r['nudge']:.2g} | "
                     + " | ".join(micrometres(x) for x in r["moved"]) + " |")
    return "\n".join(lines)
