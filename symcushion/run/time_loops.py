"""The time loops of a run: fixed-step blocks, the §3 adaptive criterion, error control.

:func:`run_fixed` calls a ``mapaccum`` rollout of ``block_steps`` steps
repeatedly (the driver passes its ``BLOCK_STEPS``); :func:`run_adaptive` applies the paper's step criterion step by
step (halving where a contact normal turns too fast); :func:`run_controlled`
steps by step doubling under the standard controller of
``symcushion.run.error_control``; :func:`estimate_fixed` runs the companion of a
fixed-step run for its error estimate. Each hands its rows, in blocks, to a
:class:`~symcushion.run.recorder.Recorder`.

This module owns the stepping and the step-size bounds. It must not build
physics (``symcushion.scheme.touchdown``), check arguments or scenes
(``symcushion.run.driver``), or record events (``symcushion.run.recorder``).
"""
from __future__ import annotations

import time

import numpy as np

from symcushion.model.parts import TimeGrid
from symcushion.run.error_control import (COMPANIONS, PeakTracker, StepErrorNorm, estimate_report,
    next_step, step_pair_function)
from symcushion.layout.vectors import output_layout
from symcushion.scheme.stability import stable_dt
from symcushion.scheme.touchdown import MAX_HALVINGS
from symcushion.run.trajectory import initial_output

__all__ = ["run_fixed", "run_adaptive", "run_controlled", "estimate_fixed", "estimate_companion",
           "MIN_STEP_FRACTION", "MAX_STEP_FRACTION", "MAX_STEP_DT"]

#: Smallest step of an error-controlled run, as a fraction of the scene's Δt:
#: 2⁻²⁰ (about 1e-9 s from 1 ms) is far below any step a touchdown needs; a
#: pair still rejected there is accepted and counted (``info['floor_steps']``).
MIN_STEP_FRACTION = 2.0 ** -20

#: Largest step of an error-controlled run, as a fraction of the duration: a
#: free flight has no error to limit the step, and a touchdown must not be
#: stepped over before the estimate can see it.
MAX_STEP_FRACTION = 1e-2

#: Largest step of an error-controlled run, in units of the scene's Δt: the
#: scene's Δt is the time scale its author resolves the touchdowns with, and a
#: step doubling pair of 20 ms in the lunar lander's flight lands its second
#: touchdown 2 ms late (peak specific force 3e-3 off at rtol = 1e-3; a pair
#: of at most 4Δt: 7e-4, docs/error-control.md).
MAX_STEP_DT = 2.0


def run_fixed(model, grid: TimeGrid, x0, p, on_block, *, block_steps: int) -> dict:
    """Roll out the ``grid``'s steps in blocks of ``block_steps``, handing each block's
    times, states and outputs to ``on_block(t, X, Y)``."""
    dt, steps = grid.dt, grid.steps
    done, x = 0, x0
    while done < steps:
        block = min(block_steps, steps - done)
        X, Y = model.rollout(block)(x, p, dt)
        X, Y = np.asarray(X, float), np.asarray(Y, float)
        on_block(dt * np.arange(done + 1, done + block + 1), X, Y)
        x, done = X[:, -1], done + block
    return {"dt": dt, "steps": steps, "halvings": 0, "final_state": x,
            "step_evaluations": steps}


def estimate_companion(estimate) -> str | None:
    """The companion named by ``simulate(estimate=...)``: a key of COMPANIONS or None."""
    if estimate is True:
        return "coarse"
    if estimate is False or estimate is None:
        return None
    if isinstance(estimate, str) and estimate in COMPANIONS:
        return estimate
    raise ValueError(f"`estimate` must be True, False or one of {sorted(COMPANIONS)}, got "
                     f"{estimate!r}; give e.g. estimate='fine' (docs/error-control.md).")


def estimate_fixed(model, x0, p, info, recorder, rtol, companion="coarse", *,
                   block_steps: int):
    """The error estimate of a finished fixed-Δt run (``info['error_estimate']``): a
    companion run over the same time with half as many steps (``"coarse"``) or
    twice as many (``"fine"``), Richardson's rule on the peaks and the final
    state, a warning per peak above ``rtol``."""
    steps, dt = info["steps"], info["dt"]
    if steps < 2 and companion == "coarse":
        info["error_estimate"] = None       # one step has no coarser companion
        return
    started = time.perf_counter()
    companion_steps = round(steps / COMPANIONS[companion])
    companion_dt = steps * dt / companion_steps
    peaks = PeakTracker(model.n_legs, model.scene.gravity)
    peaks.update(initial_output(model, x0)[:, None], np.zeros(1))
    grid = TimeGrid(companion_dt, companion_steps * companion_dt)
    assert grid.steps == companion_steps
    companion = run_fixed(model, grid, x0, p, lambda t, X, Y: peaks.update(Y, t),
                          block_steps=block_steps)
    report, messages = estimate_report(
        recorder.peaks.values, peaks.values, info["final_state"], companion["final_state"],
        dt=dt, companion_dt=companion_dt, scene=model.scene, rtol=rtol)
    report["companion_seconds"] = time.perf_counter() - started
    report["overhead"] = report["companion_seconds"] / max(info["rollout_seconds"], 1e-9)
    info["error_estimate"] = report
    t_end = steps * dt
    for message in messages:
        recorder.warn({"time": t_end, "kind": "warning", "severity": "warning",
                       "message": message, "details": {"kind": "error_estimate"}}, stacklevel=4)


def _normals(model, y):
    yl = output_layout(model.n_legs)
    y = np.asarray(y, float).ravel()
    return yl.legs(y, "in_contact") > 0.5, yl.legs(y, "normal")


class _RowBuffer:
    """Rows of a variable-step run, handed to the recorder in blocks of ``block_steps``."""

    def __init__(self, recorder, block_steps):
        self.recorder, self.block_steps = recorder, block_steps
        self.ts, self.xs, self.ys = [], [], []

    def add(self, t, x, y):
        self.ts.append(t)
        self.xs.append(np.asarray(x, float).ravel())
        self.ys.append(np.asarray(y, float).ravel())
        if len(self.ts) == self.block_steps:
            self.flush()

    def flush(self):
        if self.ts:
            self.recorder.block(np.array(self.ts), np.column_stack(self.xs),
                                np.column_stack(self.ys))
            self.ts, self.xs, self.ys = [], [], []


def run_adaptive(model, grid: TimeGrid, x0, p, eps, recorder, stability=0.0, *,
                 block_steps: int) -> dict:
    """The §3 adaptive run over the ``grid``'s duration from its Δt: each step halved
    (at most ``MAX_HALVINGS`` times) while a contact normal turns too fast over it
    (1 − n·n′ ≥ ``eps``); rows at every step."""
    step = model.step
    t_end, dt = grid.duration, grid.dt
    t, x, steps = 0.0, x0, 0
    rows = _RowBuffer(recorder, block_steps)
    last_contact, last_normal = None, None
    halvings = capped = 0
    dt_min = np.inf
    while t < t_end - 1e-12 * t_end:
        h = min(dt, t_end - t)
        if stability:
            h_stable = stability * stable_dt(model, x, p)
            if h_stable < h:
                h, capped = h_stable, capped + 1
        for depth in range(MAX_HALVINGS + 1):
            x_new, y = step(x, p, h)
            contact, normal = _normals(model, y)
            if last_contact is None or depth == MAX_HALVINGS:
                break
            both = contact & last_contact
            crit = np.max(1 - np.einsum("ni,ni->n", normal, last_normal)[both], initial=0.0)
            if crit < eps:
                break
            h /= 2
            halvings += 1
        x = np.asarray(x_new, float).ravel()
        if h < t_end - t - 1e-12 * t_end:       # not the final, shortened step
            dt_min = min(dt_min, h)
        t += h
        steps += 1
        rows.add(t, x, y)
        last_contact, last_normal = contact, normal
    rows.flush()
    info = {"dt": dt, "steps": steps, "halvings": halvings, "eps": eps, "final_state": x,
            "dt_min": dt_min}
    if stability:
        info["stability_capped"] = capped
    return info


def run_controlled(model, grid: TimeGrid, x0, p, rtol, atol, recorder, stability=0.0, *,
                   block_steps: int) -> dict:
    """Error-controlled stepping over the ``grid``'s duration, its Δt the scale of the
    steps: step doubling on every pair of steps, the standard controller
    (``symcushion.run.error_control``); rows at every step."""
    pair = step_pair_function(model.step)
    norm = StepErrorNorm(model.scene, rtol, atol, x0)
    t_end = grid.duration
    h_min = MIN_STEP_FRACTION * grid.dt
    h_max = min(MAX_STEP_FRACTION * t_end, MAX_STEP_DT * grid.dt)
    h, t, x = grid.dt / 2, 0.0, np.asarray(x0, float)
    rows = _RowBuffer(recorder, block_steps)
    steps = evaluations = rejected = floor = capped = 0
    dt_min, dt_max = np.inf, 0.0
    while t < t_end - 1e-12 * t_end:
        remaining = (t_end - t) / 2
        h = min(h, h_max, remaining)
        if stability:
            h_stable = stability * stable_dt(model, x, p)
            if h_stable < h:
                h, capped = h_stable, capped + 1
        # one conversion of each output to NumPy: the error norm, the rows and the
        # next pair read them several times
        x1, y1, x2, y2, x_big, y_big = (out.full().ravel() for out in pair(x, p, h))
        evaluations += 3
        err = norm(x2, y2, x_big, y_big, h)
        if not np.isfinite(err):
            err = np.inf
        if err > 1 and h > h_min:
            rejected += 1
            h = max(h_min, next_step(h, err))
            continue
        floor += err > 1
        if h < remaining * (1 - 1e-12):       # not the final, shortened pair
            dt_min, dt_max = min(dt_min, h), max(dt_max, h)
        rows.add(t + h, x1, y1)
        t = t + 2 * h if h < remaining else t_end
        rows.add(t, x2, y2)
        x = x2
        norm.accept(x2, y2)
        steps += 2
        h = next_step(h, err)
    rows.flush()
    info = {"dt": grid.dt, "steps": steps, "halvings": 0, "rtol": rtol, "atol": atol,
            "final_state": x, "step_evaluations": evaluations, "rejected": rejected,
            "floor_steps": int(floor), "dt_min": dt_min, "dt_max": dt_max}
    if stability:
        info["stability_capped"] = capped
    return info
