"""Where a scheme's run of the slope lander stops being a smooth function of its initial state.

Owns the runs of ``--smoothness``: the lander of ``studies/lander_slope.toml``
with each scheme of :data:`SMOOTH_SCHEMES` at each Δt of :data:`SMOOTH_DTS`,
from the committed initial state and from that state with the velocity
across the slope moved by each ε of :data:`NUDGES`, and the distance of each
nudged run's centre of mass from the unmoved run's at :data:`SMOOTH_TIMES`
(:func:`smoothness_runs`); the time up to which those distances grow
linearly in ε (:func:`smooth_until`); and the section's text
(:func:`smoothness_text`). It must not fit orders or write files (``main``
writes its section).

Why: a fitted order says how a run's error falls with Δt. It presumes that
the run at a fixed Δt is a smooth function of the scene's data, so that
its error is a smooth function of Δt. A step that decides per step which
legs stick, lock or change branch is piecewise smooth: where one decision
flips, the run jumps. A jump that shrinks like Δt² leaves the order intact;
one that does not caps every fit over a range of Δt. Nudging the initial
velocity by far less than any step's error finds the jumps: on a smooth
piece the distance moved is linear in ε (the same gain |Δx|/ε for every
ε), across a jump it is not.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from .cases import slope_cases
from .limits import _trajectory
from .runs import positions_at
from .text import time_table_head

#: The schemes nudged (case labels of ``cases.scenes()`` on the slope lander).
SMOOTH_SCHEMES = ("all events", "all events (midpoint)", "all events (midpoint, branch)",
                  "all events (midpoint, lock)")
#: Δt of the runs (s): the finest point of the order fits' grid and a decade below it.
SMOOTH_DTS = (1e-4, 1e-5)
#: Nudges of the initial velocity across the slope, v_y (m/s): from far below
#: any step's error (a smooth run then moves by ε times a gain below 1 s) to
#: the size at which the regularised reference was perturbed.
NUDGES = (1e-9, 1e-8, 1e-7, 1e-6, 1e-5)
#: Times (s) at which the nudged runs are compared with the unmoved one.
SMOOTH_TIMES = (0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.8)
#: Gains |Δx|/ε that agree within this factor over all ε count as linear.
LINEAR_SPREAD = 2.0


def nudged(scene, field: str, index: int, size: float):
    """``scene`` with ``body[field][index]`` of its initial state moved by ``size``.

    ``field`` is "position" or "velocity"; ``index`` 0, 1 or 2. The name is
    kept, so a compiled build of ``scene`` serves (the initial state is not
    in the step).
    """
    if field not in ("position", "velocity"):
        raise ValueError(f"`field` must be 'position' or 'velocity', got {field!r}.")
    if index not in (0, 1, 2):
        raise ValueError(f"`index` must be 0, 1 or 2, got {index!r}.")
    if not np.isfinite(size):
        raise ValueError(f"`size` must be finite, got {size!r}.")
    entry = np.array(getattr(scene.body, field), dtype=float)
    entry[index] += size
    return scene.with_(body=replace(scene.body, **{field: entry}))


def _position_at(traj, times) -> np.ndarray:
    return positions_at(traj.t, traj.position, times)


def smoothness_runs(schemes=SMOOTH_SCHEMES, dts=SMOOTH_DTS, nudges=NUDGES,
                    times=SMOOTH_TIMES, progress=print) -> list:
    """One row per scheme and Δt: ``scheme``, ``dt``, ``nudges`` (m/s, (k,)) and
    ``moved`` (m, (k, len(times)): each nudged run's distance from the unmoved
    run at ``times``)."""
    by_label = slope_cases(schemes)
    nudges = np.asarray(nudges, dtype=float)
    if nudges.ndim != 1 or nudges.size == 0 or not np.all(np.isfinite(nudges)) \
            or np.any(nudges <= 0):
        raise ValueError(f"`nudges` must be positive finite velocities (m/s), got {nudges!r}.")
    rows = []
    for scheme in schemes:
        scene = by_label[scheme]
        for dt in dts:
            base = _position_at(_trajectory(scene, dt), times)
            moved = np.array([np.linalg.norm(
                _position_at(_trajectory(nudged(scene, "velocity", 1, eps), dt), times) - base,
                axis=1) for eps in nudges])
            rows.append(dict(scheme=scheme, dt=dt, nudges=nudges, moved=moved))
            progress(f"smoothness: {scheme}, dt = {dt:g}: smooth until "
                     f"{smooth_until(nudges, moved, times)} s")
    return rows


def smooth_until(nudges, moved, times=SMOOTH_TIMES, spread=LINEAR_SPREAD):
    """The last of ``times`` up to which the gains |Δx|/ε of every nudge agree within
    the factor ``spread`` (the run is linear in ε there); None if not at the first.

    ``moved`` is (len(nudges), len(times)), m. A gain of zero (a run that did
    not move at all) counts as not linear.
    """
    gain = np.asarray(moved, float) / np.asarray(nudges, float)[:, None]
    if gain.shape[1] != len(times):
        raise ValueError(f"`moved` has {gain.shape[1]} columns for {len(times)} times.")
    last = None
    for i, T in enumerate(times):
        g = gain[:, i]
        if not (np.all(g > 0) and g.max() <= spread * g.min()):
            break
        last = T
    return last


def _micrometres(x: float) -> str:
    """``x`` (m) in µm to three significant digits, without an exponent."""
    um = 1e6 * x
    return f"{um:,.0f}" if um >= 1000 else f"{um:.3g}"


def smoothness_text(rows, times=SMOOTH_TIMES) -> str:
    """The section "Events: where each run stops being smooth" from :func:`smoothness_runs`."""
    nudges = rows[0]["nudges"] if rows else np.asarray(NUDGES)
    lines = ["Produced by `python studies/event_order.py --smoothness` (compiled C, about "
             "10 minutes): the lander of `studies/lander_slope.toml` with each scheme, at two Δt, "
             "from its committed initial state and from that state with the velocity across "
             "the slope moved by ε = "
             + ", ".join(f"{e:g}" for e in nudges) + " m/s. \"Linear until\" is the last "
             f"time at which the distance moved grows linearly with ε (the gains |Δx|/ε of "
             f"every ε within a factor {LINEAR_SPREAD:g}): up to there the run is a smooth "
             "function of its initial state. The other columns give the largest distance "
             "any nudge moved the centre of mass (µm); a smooth run moves at most ε times a "
             "gain below 1 s, under 10 µm for the largest ε.", ""]
    lines += time_table_head(("scheme", "Δt (s)", "linear until (s)"), ("---", "---:", "---:"),
                             times)
    for r in rows:
        until = smooth_until(r["nudges"], r["moved"], times)
        lines.append(f"| {r['scheme']} | {r['dt']:g} | "
                     + ("before " + f"{times[0]:g}" if until is None else f"{until:g}") + " | "
                     + " | ".join(_micrometres(x) for x in np.max(r["moved"], axis=0)) + " |")
    return "\n".join(lines)
