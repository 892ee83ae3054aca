"""Orders where the reference is known: the slope lander over its first fifth of a second.

Owns the runs of ``--window``: the regularised reference of the lander of
``studies/lander_slope.toml`` and its check (two widths, :data:`WINDOW_REFERENCE`)
run up to the last of :data:`WINDOW_TIMES`; each scheme of
:data:`WINDOW_SCHEMES` on the study's Δt grid up to the same time, and once
more at :data:`OWN_DT`; each run's largest distance of the centre of mass from
the reference's, and from the scheme's own run at ``OWN_DT``, over t ≤ T for
each T (:func:`window_error`); the orders fitted over the points above ten
times the reference's spread (or the own run's distance from its check at
half the step); and the events of
the reference inside each window (:func:`window_events`). It must not write
files (``main`` writes its section).

Two references, because each is sharp where the other is not: the
regularised run is the right limit of the holds (section "Events: two
limits on the slope") but carries its width's own error from the start
(about 1e-7 m); the scheme's own fine run is sharp (its check differs by
1e-10 m) but converges to the scheme's own limit, which after the first
holds is not the regularised one. Against the first a scheme shows whether
it goes to the right motion, against the second at what order it goes to
its own.

Why: over the whole run the reference is known only to about 5 mm (section
"Events: how well the reference is known"), which caps any fitted order on
this scene. Over its first 0.05–0.2 s the widths agree to 0.0001–0.14 mm,
so there an order can be measured, and the events inside that window say
which of them the step fails to carry at second order.
"""
from __future__ import annotations

import numpy as np

from symcushion.run.driver import MAX_EVENTS
from symcushion.studies.speed_vs_error import convergence_order

from .cases import DT_GRID, slope_cases
from .limits import _trajectory, regularized_scene
from .runs import reversal_steps

#: Ends of the windows (s): the uphill feet's touchdown, both stuck, strokes growing
#: (to 0.035 s); their first slips and stroke turns (to 0.05 s); the downhill legs'
#: touchdowns (to 0.1 s); the tipping onto the downhill pair (to 0.2 s). The
#: reference widths part after 0.2 s.
WINDOW_TIMES = (0.035, 0.05, 0.1, 0.2)
#: (rate_width w in m²/s, Δt in s) of the reference and of its check: the finest
#: rungs of the two widths on the ladder of ``--reference`` at equal Δt.
WINDOW_REFERENCE = ((1e-6, 3e-8), (1e-7, 3e-8))
#: The schemes measured (case labels of ``cases.scenes()`` on the slope lander).
WINDOW_SCHEMES = ("all events", "all events (midpoint)", "all events (midpoint, branch)",
                  "all events (midpoint, lock)")
#: Δt of each scheme's own fine run (s): 100× below the finest grid point; its
#: check runs at half of it.
OWN_DT = 1e-6
#: Rows kept of each reference run (``simulate(keep_rows=...)``): 1e-5 s apart over 0.2 s.
KEEP_ROWS = 20_000


def _run(scene, dt, keep_rows=None):
    """A compiled run of ``scene`` up to the last window (``limits._trajectory``)."""
    return _trajectory(scene.with_(duration=max(WINDOW_TIMES)), dt, keep_rows)


def window_error(t, position, ref_t, ref_position, until: float) -> float:
    """Largest distance (m) of ``position`` (rows at times ``t``) from the reference's
    centre of mass over ``t`` ≤ ``until``.

    The reference (rows at ``ref_t``, much finer) is interpolated linearly to
    the run's own times, so that the run is read where its step put it.
    """
    t, position = np.asarray(t, float), np.asarray(position, float)
    ref_t, ref_position = np.asarray(ref_t, float), np.asarray(ref_position, float)
    if not np.isfinite(until) or until <= 0:
        raise ValueError(f"`until` must be a positive time (s), got {until!r}.")
    if until > ref_t[-1] + 1e-12:
        raise ValueError(f"`until` = {until:g} s lies beyond the reference's end, "
                         f"{ref_t[-1]:g} s; run the reference longer or shorten the window.")
    keep = t <= until + 1e-12
    ref = np.column_stack([np.interp(t[keep], ref_t, ref_position[:, i]) for i in range(3)])
    return float(np.max(np.linalg.norm(position[keep] - ref, axis=1)))


def window_events(events, turns, until: float) -> dict:
    """Counts of the reference's events at t ≤ ``until``: touchdowns, lift-offs,
    stick → slip (``slip``), slip → stick (``stick``), from ``events`` (the run's
    event dicts), and stroke turns, from ``turns`` (their times, s)."""
    counts = {kind: 0 for kind in ("touchdown", "lift-off", "slip", "stick")}
    for e in events:
        if e.get("kind") in counts and e["time"] <= until + 1e-12:
            counts[e["kind"]] += 1
    counts["stroke turn"] = int(np.sum(np.asarray(turns, float) <= until + 1e-12))
    return counts


def _turn_times(traj) -> np.ndarray:
    steps = reversal_steps(traj)
    return np.asarray(traj.t)[1:][steps.any(axis=1)]


def window_runs(schemes=WINDOW_SCHEMES, dts=DT_GRID, progress=print) -> dict:
    """The reference, its check and every scheme on ``dts`` over the windows.

    Returns a dict: ``spread`` (m, per window: the check's distance from the
    reference), ``events`` (per window: :func:`window_events` of the
    reference), ``events_complete_until`` (s: the time of the last event the
    reference kept, if it dropped any; inf otherwise), ``first`` (the
    reference's events up to the first window, as
    (time, kind, leg)), ``own_spread`` (per scheme, m per window: its own run's
    distance from its check at half the step) and ``rows`` (one per scheme and Δt: ``scheme``,
    ``dt``, ``errors`` and ``own`` in m per window, from the reference and
    from the scheme's own run at :data:`OWN_DT`).
    """
    by_label = slope_cases(schemes)
    (w, dt), (w_check, dt_check) = WINDOW_REFERENCE
    ref = _run(regularized_scene("all events", w), dt, KEEP_ROWS)
    progress(f"window reference: w = {w:g}, dt = {dt:g} s")
    check = _run(regularized_scene("all events", w_check), dt_check, KEEP_ROWS)
    progress(f"window check: w = {w_check:g}, dt = {dt_check:g} s")
    ref_t, ref_x = np.asarray(ref.t), np.asarray(ref.position)
    spread = [window_error(check.t, check.position, ref_t, ref_x, T) for T in WINDOW_TIMES]
    turns = _turn_times(ref)
    # the run keeps its first MAX_EVENTS events: counts past the last kept one are lower bounds
    complete = (float(ref.events[-1]["time"]) if ref.info.get("events_dropped", 0)
                else float("inf"))
    out = dict(spread=spread, events_complete_until=complete,
               events=[window_events(ref.events, turns, T) for T in WINDOW_TIMES],
               first=sorted([(e["time"], e["kind"], e.get("leg")) for e in ref.events
                             if "kind" in e and e["time"] <= WINDOW_TIMES[0]]
                            + [(float(t), "stroke turn", None)
                               for t in turns[turns <= WINDOW_TIMES[0]]], key=lambda e: e[0]),
               rows=[], own_spread={})
    for scheme in schemes:
        own = _run(by_label[scheme], OWN_DT, KEEP_ROWS)
        own_t, own_x = np.asarray(own.t), np.asarray(own.position)
        own_check = _run(by_label[scheme], OWN_DT / 2, KEEP_ROWS)
        out["own_spread"][scheme] = [window_error(own.t, own.position, np.asarray(own_check.t),
                                                  np.asarray(own_check.position), T)
                                     for T in WINDOW_TIMES]
        for step in dts:
            traj = _run(by_label[scheme], step)
            errors = [window_error(traj.t, traj.position, ref_t, ref_x, T) for T in WINDOW_TIMES]
            own_errors = [window_error(traj.t, traj.position, own_t, own_x, T)
                          for T in WINDOW_TIMES]
            out["rows"].append(dict(scheme=scheme, dt=step, errors=errors, own=own_errors))
            progress(f"window: {scheme}, dt = {step:g}: "
                     + ", ".join(f"{1e3 * e:.2e}" for e in errors) + " mm from the reference, "
                     + ", ".join(f"{1e3 * e:.2e}" for e in own_errors) + " mm from its own")
    return out


def window_orders(result) -> list:
    """Fitted orders per scheme and window of :func:`window_runs`' result: rows of
    ``scheme``, ``until``, ``fit`` (order, Δt range, points) against the reference,
    over the points above ten times its spread in that window, and ``own``, the
    same against the scheme's own fine run over the points above ten times that
    run's distance from its check."""
    fits = []
    for scheme in dict.fromkeys(r["scheme"] for r in result["rows"]):
        rows = [r for r in result["rows"] if r["scheme"] == scheme]
        dts = [r["dt"] for r in rows]
        for j, until in enumerate(WINDOW_TIMES):
            fits.append(dict(
                scheme=scheme, until=until,
                fit=convergence_order(dts, [r["errors"][j] for r in rows],
                                      floor=result["spread"][j], dt_max=max(DT_GRID)),
                own=convergence_order(dts, [r["own"][j] for r in rows],
                                      floor=result["own_spread"][scheme][j],
                                      dt_max=max(DT_GRID))))
    return fits


def _order(fit):
    order, span, n = fit
    if not np.isfinite(order):
        return "—"
    return f"{order:.2f} ({span[0]:g}–{span[1]:g}, {n})"


def window_text(result) -> str:
    """The section "Events: orders where the reference is known"."""
    (w, dt), (w_check, dt_check) = WINDOW_REFERENCE
    dts = list(dict.fromkeys(r["dt"] for r in result["rows"]))
    lines = [
        "Produced by `python studies/event_order.py --window` (compiled C): the lander of "
        f"`studies/lander_slope.toml` up to t = {max(WINDOW_TIMES):g} s, each scheme's largest "
        "distance of the centre of mass from the reference's over t ≤ T (read at the scheme's "
        f"own steps). Reference: the regularised switch at w = {w:g} m²/s, Δt = {dt:g} s; its "
        f"check: w = {w_check:g} m²/s, Δt = {dt_check:g} s. Plot: "
        "`figures/event_order_window.png`.", "",
        "![event order by window](event_order_window.png)", "",
        "The reference's spread (the check's distance from it over the window) and its "
        "events inside the window (stick and slip count each switch of a foot; a stroke turn "
        "is a reversal of a leg's stroke in contact, a branch switch or a hold):", "",
        "| window | spread (mm) | touchdowns | lift-offs | stick → slip | slip → stick "
        "| stroke turns |",
        "|---|---:|---:|---:|---:|---:|---:|"]
    complete = result.get("events_complete_until", float("inf"))
    for until, spread, ev in zip(WINDOW_TIMES, result["spread"], result["events"]):
        at_least = "≥ " if until > complete else ""
        lines.append(f"| t ≤ {until:g} s | {1e3 * spread:.4f} | "
                     + " | ".join(f"{at_least}{ev[k]}" for k in ("touchdown", "lift-off", "slip",
                                                                 "stick"))
                     + f" | {ev['stroke turn']} |")
    if np.isfinite(complete):
        lines += ["", f"The reference keeps its first {MAX_EVENTS:,} events (up to "
                  f"t = {complete:.4f} s); \"≥\" marks counts over windows past that."]
    first = "; ".join(f"{1e3 * t:.1f} ms {kind}" + (f" (leg {leg})" if leg is not None else "")
                      for t, kind, leg in result["first"])
    lines += ["", f"Events up to t = {WINDOW_TIMES[0]:g} s: {first}.", "",
              "Largest distance of the centre of mass over the window (mm) from the reference "
              f"and, below it, from the scheme's own run at Δt = {OWN_DT:g} s; each order is "
              "fitted over the points above ten times that reference's own error (the spread "
              f"above; the own run's distance from its check at {OWN_DT / 2:g} s, the last "
              "column) (Δt range and points in brackets):",
              "", "| scheme | window | from | " + " | ".join(f"{d:g}" for d in dts)
              + " | order | reference's error |", "|---|---|---|" + "---:|" * len(dts)
              + "---|---:|"]
    fits = {(f["scheme"], f["until"]): f for f in window_orders(result)}
    for scheme in dict.fromkeys(r["scheme"] for r in result["rows"]):
        rows = {r["dt"]: r for r in result["rows"] if r["scheme"] == scheme}
        for j, until in enumerate(WINDOW_TIMES):
            floors = (result["spread"][j], result["own_spread"][scheme][j])
            for (key, label, fit), floor in zip((("errors", "reference", "fit"),
                                                 ("own", "own run", "own")), floors):
                lines.append(f"| {scheme} | t ≤ {until:g} s | {label} | "
                             + " | ".join(f"{1e3 * rows[d][key][j]:.2e}" for d in dts)
                             + f" | {_order(fits[scheme, until][fit])} | {1e3 * floor:.1e} |")
    return "\n".join(lines)
