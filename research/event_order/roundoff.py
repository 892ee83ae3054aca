"""What double precision resolves of the slope lander: each run's round-off floor.

Owns the runs of ``--roundoff``: the lander of ``studies/lander_slope.toml``
with each scheme of :data:`ROUNDOFF_SCHEMES` at each Δt of
:data:`ROUNDOFF_DTS`, and its regularised reference at the rungs
of :data:`REGULARISED_RUNS`, each from its committed initial state and from that
state with the velocity across the slope moved by one unit in the last
place (:func:`ulp_nudge`, the smallest change a double can make), and the
distance of the nudged run's centre of mass from the unmoved run's, over
the whole run, at :data:`smoothness.SMOOTH_TIMES` and as a root mean square
over the run's samples (:func:`roundoff_runs`); how well a
reference must be known for the whole-run order fit the floor is set
against (:func:`needed_reference`, :func:`needed_references`, from the
errors the study's grid run measured: :func:`coarse_errors`); and the
section's text
(:func:`roundoff_text`). It must not fit orders or write files (``main``
writes its section and figure).

Why: an order fitted over a range of Δt needs each run's error measured
against a reference that is known ten times better than the finest run's
error. One ulp of one entry of the initial state is below any error a run
can be asked to have, and below what the scene's data can mean; the
distance such a nudge moves a run is a floor under what that run says, in
double precision, about the motion. No reference of the scene is known
better than the floor of the run that serves as it.
"""
from __future__ import annotations

import csv

import numpy as np

from .cases import slope_cases
from .limits import ORACLE_RUNS, _trajectory, regularized_scene
from .runs import positions_at
from .smoothness import SMOOTH_TIMES, nudged
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
#: The fit the floor is set against: this order over the Δt range FIT_RANGE (s),
#: the study's grid, with the reference known to REFERENCE_SHARE of the finest
#: run's error (the study leaves out errors below ten times the reference's).
ORDER_AIM = 1.8
FIT_RANGE = (1e-2, 1e-4)
REFERENCE_SHARE = 0.1
#: Rows kept of each run (``simulate(keep_rows=...)``): the nudged run and its
#: twin are thinned alike, so their rows fall at the same times.
KEEP_ROWS = 20_000


def ulp_nudge(value: float) -> float:
    """The step from ``value`` to the next larger double (one ulp of ``value``; for a
    negative power of two, the ulp of the doubles just above it)."""
    value = float(value)
    if not np.isfinite(value):
        raise ValueError(f"`value` must be finite, got {value!r}.")
    return float(np.nextafter(value, np.inf) - value)


def needed_reference(coarse_error: float, travel: float, order: float = ORDER_AIM,
                     dts=FIT_RANGE, share: float = REFERENCE_SHARE) -> float:
    """Distance (m) to which a reference must be known for a fit of ``order`` over
    ``dts`` = (coarsest, finest) that starts from the relative trajectory error
    ``coarse_error`` at the coarsest Δt: ``share`` of the error the finest run
    must then have, ``coarse_error``·(finest/coarsest)^order of ``travel`` (m)."""
    for name, value in (("coarse_error", coarse_error), ("travel", travel), ("order", order),
                        ("share", share)):
        if not (np.isfinite(value) and value > 0):
            raise ValueError(f"`{name}` must be positive and finite, got {value!r}.")
    coarsest, finest = dts
    if not 0 < finest < coarsest:
        raise ValueError(f"`dts` must be (coarsest, finest) with 0 < finest < coarsest, "
                         f"got {dts!r}.")
    return share * coarse_error * travel * (finest / coarsest) ** order


def coarse_errors(path, schemes=ROUNDOFF_SCHEMES, dt=FIT_RANGE[0]) -> dict:
    """The slope lander's trajectory error at ``dt`` of each of ``schemes`` (case
    labels) in the study's CSV at ``path`` (``python studies/event_order.py``);
    a ValueError if the file is missing, lacks a scheme or holds one twice."""
    try:
        with open(path, newline="") as fh:
            table = list(csv.DictReader(fh))
    except FileNotFoundError:
        raise ValueError(f"{path} does not exist; run `python studies/event_order.py` "
                         "first.") from None
    found = {}
    for row in table:
        if (row["scene"] == "lander_slope" and row["variant"] in schemes
                and row["kind"] == "run" and row["trajectory_error"]
                and np.isclose(float(row["dt"]), dt, rtol=1e-9, atol=0.0)):
            if row["variant"] in found:
                raise ValueError(f"{path} holds two runs of {row['variant']!r} at dt = "
                                 f"{dt:g} s; write it anew with `python studies/event_order.py`.")
            found[row["variant"]] = float(row["trajectory_error"])
    missing = [s for s in schemes if s not in found]
    if missing:
        raise ValueError(f"{path} has no trajectory error at dt = {dt:g} s for {missing!r}; "
                         "run `python studies/event_order.py` first.")
    return found


def _floor(scene, dt, times) -> dict:
    """The run of ``scene`` at ``dt`` against its twin whose v_y is one ulp larger:
    ``moved`` (m, the distance at ``times``), ``rms`` (m, over the kept rows),
    ``curve_t`` and ``curve`` (s, m: the distance at every kept row) and ``travel``
    (m, the unmoved run's largest distance from where it starts)."""
    base = _trajectory(scene, dt, keep_rows=KEEP_ROWS)
    twin = _trajectory(nudged(scene, "velocity", 1, ulp_nudge(scene.body.velocity[1])), dt,
                       keep_rows=KEEP_ROWS)
    t, x, y = np.asarray(base.t), np.asarray(base.position), np.asarray(twin.position)
    if not (len(twin.t) == len(t) and np.allclose(twin.t, t, rtol=0.0, atol=1e-12)):
        raise RuntimeError(f"the nudged run of {scene.name} kept other rows than its twin.")
    curve = np.linalg.norm(y - x, axis=1)
    return dict(moved=np.linalg.norm(positions_at(t, y, times) - positions_at(t, x, times),
                                     axis=1),
                rms=float(np.sqrt(np.mean(curve ** 2))), curve_t=t, curve=curve,
                travel=float(np.max(np.linalg.norm(x - x[0], axis=1))))


def roundoff_runs(schemes=ROUNDOFF_SCHEMES, dts=ROUNDOFF_DTS, regularised=REGULARISED_RUNS,
                  times=SMOOTH_TIMES, progress=print) -> list:
    """One row per scheme and Δt, then one per regularised reference: ``scheme``,
    ``dt``, ``nudge`` (m/s, one ulp of v_y) and what :func:`_floor` measures:
    ``moved`` (m, (len(times),)), ``rms``, ``curve_t``, ``curve`` and ``travel``.

    ``regularised`` holds (rate_width in m²/s, Δt in s) pairs; empty for none.
    Every argument is checked before the first run.
    """
    by_label = slope_cases(schemes)
    dts = np.asarray(dts, dtype=float)
    if dts.ndim != 1 or not np.all(np.isfinite(dts)) or np.any(dts <= 0):
        raise ValueError(f"`dts` must be positive finite steps (s), got {dts!r}.")
    pairs = np.asarray(regularised, dtype=float).reshape(-1, 2) if len(regularised) else \
        np.zeros((0, 2))
    if not (np.all(np.isfinite(pairs)) and np.all(pairs > 0)):
        raise ValueError("`regularised` must hold positive (rate_width, dt) pairs, got "
                         f"{regularised!r}.")
    times = np.asarray(times, dtype=float)
    if times.ndim != 1 or times.size == 0 or np.any(times <= 0) or np.any(np.diff(times) <= 0):
        raise ValueError(f"`times` must be positive and increasing (s), got {times!r}.")
    runs = [(label, by_label[label], float(dt)) for label in schemes for dt in dts]
    runs += [(f"regularised reference (w = {w:g} m²/s)", regularized_scene("all events", w),
              float(dt)) for w, dt in pairs]
    late = [label for label, scene, _ in runs if times[-1] > scene.duration]
    if late:
        raise ValueError(f"`times` end at {times[-1]:g} s, after the runs of {late!r} end.")
    rows = []
    for label, scene, dt in runs:
        floor = _floor(scene, dt, times)
        rows.append(dict(scheme=label, dt=dt, nudge=ulp_nudge(scene.body.velocity[1]), **floor))
        progress(f"round-off: {label}, dt = {dt:g}: one ulp of v_y moves it up to "
                 f"{1e6 * floor['curve'].max():.3g} µm, {1e6 * floor['rms']:.3g} µm RMS")
    return rows


def needed_references(rows, coarse) -> dict:
    """:func:`needed_reference` (m) of each scheme of ``coarse`` (its trajectory error
    at the coarsest Δt of the fit, :func:`coarse_errors`), with the travel of that
    scheme's finest run among ``rows``."""
    out = {}
    for scheme, error in coarse.items():
        runs = [r for r in rows if r["scheme"] == scheme]
        if not runs:
            raise ValueError(f"`rows` hold no run of {scheme!r}.")
        out[scheme] = needed_reference(error, min(runs, key=lambda r: r["dt"])["travel"])
    return out


def _um(x: float) -> str:
    return f"{1e6 * x:.2e}"


def roundoff_text(rows, need=None, coarse=None, times=SMOOTH_TIMES) -> str:
    """The section "Events: what double precision resolves" from :func:`roundoff_runs`,
    with the reference accuracy each scheme's whole-run fit needs (``need``, from
    :func:`needed_references`, and ``coarse``, the errors it starts from) when given."""
    if (need is None) != (coarse is None):
        raise ValueError("`need` and `coarse` go together: pass both (needed_references() "
                         "and coarse_errors()) or neither.")
    lines = ["Produced by `python studies/event_order.py --roundoff` (compiled C, about 8 "
             "minutes): the lander of `studies/lander_slope.toml` with the default step and "
             "with the stroke lock, and its regularised references (`smooth = true`, "
             "`rate_width` w; default step), each run twice: from its committed initial state "
             "and with the velocity across the slope moved by one unit in its last place (one "
             "ulp, the smallest change a double can make). The columns give how far that "
             "moves the centre of mass (µm), at the times given and as a root mean square "
             "over the run's samples: a floor under what the run, computed in double "
             "precision, says about the motion.", ""]
    lines += time_table_head(("run", "Δt (s)", "nudge (m/s)"), ("---", "---:", "---:"), times)
    lines[-2] = lines[-2] + " RMS over the run |"
    lines[-1] = lines[-1] + "---:|"
    for r in rows:
        lines.append(f"| {r['scheme']} | {r['dt']:g} | {r['nudge']:.2g} | "
                     + " | ".join(_um(x) for x in r["moved"]) + f" | {_um(r['rms'])} |")
    if need:
        lo, hi = FIT_RANGE
        lines += ["", f"What a whole-run fit needs: an order of {ORDER_AIM:g} over Δt = "
                  f"{lo:g} … {hi:g} s, starting from the scheme's trajectory error at {lo:g} s "
                  "(`figures/event_order.csv`; a root mean square over the run, relative to "
                  f"the travel), asks for an error of that times ({hi:g}/{lo:g})^{ORDER_AIM:g} "
                  f"at {hi:g} s, and a reference known to {REFERENCE_SHARE:g} of that (in the "
                  "same root mean square, against the RMS column above):", "",
                  "| scheme | trajectory error at the coarsest Δt | travel (m) | "
                  "reference needed (µm RMS) |", "|---|---:|---:|---:|"]
        for s in need:
            travel = min((r for r in rows if r["scheme"] == s), key=lambda r: r["dt"])["travel"]
            lines.append(f"| {s} | {coarse[s]:.2e} | {travel:.3f} | {_um(need[s])} |")
        lines += ["", "![round-off floor](event_order_roundoff.png)"]
    return "\n".join(lines)
