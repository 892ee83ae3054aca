"""Running a hard case: rollout chunks fed back, checks folded in, the adaptive driver.

Owns :func:`run_case` (one case with one contact method, checked) and
:func:`run_adaptive` (what the adaptive driver does on it). It must not
define cases, tolerances or the table.
"""
from __future__ import annotations

import time

import numpy as np

from symcushion.contact.args import METHODS
from symcushion.layout.vectors import state_layout
from symcushion.scheme.touchdown import build_model, initial_state
from symcushion.run.driver import simulate, trajectory_from

from .cases import CASES
from .checks import Result, Stats, invariant_function, symmetry_error

#: Steps per rollout chunk of a long run: building mapaccum costs 1–3 ms per
#: step, so one chunk of 1000 is built once per run and fed back its state.
CHUNK = 1000


def _chunks(model, x0, p, dt, steps):
    """Yield the Trajectory of each chunk of ``steps`` steps (rollout chunks, fed back)."""
    chunk = min(steps, CHUNK)
    rollout = model.rollout(chunk)
    x, t0 = x0, 0.0
    for _ in range(-(-steps // chunk)):
        X, Y = rollout(x, p, dt)
        traj = trajectory_from(model, x, X, Y, t0 + dt * np.arange(chunk + 1))
        yield traj
        x = np.asarray(X, dtype=float)[:, -1]
        t0 += chunk * dt
        if not np.all(np.isfinite(x)):
            return


def run_case(name, method, full=True) -> Result:
    """Run one case with one contact method and check it (see the module docstring)."""
    if name not in CASES:
        raise ValueError(f"`name` must be one of {sorted(CASES)}, got {name!r}.")
    if method not in METHODS:
        raise ValueError(f"`method` must be one of {METHODS}, got {method!r}.")
    started = time.perf_counter()
    setup = CASES[name](method, full)
    scene = setup.scene
    model = build_model(scene)
    x0 = initial_state(scene) if setup.x0 is None else setup.x0
    p = model.default_p
    inv = invariant_function(scene)
    length = max(leg.length for leg in scene.legs)
    stats = Stats()
    reference = None
    for k, traj in enumerate(_chunks(model, x0, p, scene.dt, scene.steps)):
        stats.update(scene, inv, traj, k == 0)
        if not stats.finite:
            break
        if setup.symmetry:
            stats.symmetry = max(stats.symmetry, symmetry_error(setup.symmetry, traj, length))
        if setup.creep:
            if reference is None:
                reference = (traj.foot[0].copy(), traj.position[0].copy())
            stats.update_creep(traj, reference)
    xl = state_layout(len(scene.legs))
    v0 = xl.get(x0, "velocity")
    E_el0 = float(inv(x0)[0]) - 0.5 * scene.body.mass * float(v0 @ v0) \
        + scene.body.mass * float(scene.gravity @ xl.get(x0, "position"))
    energy_scale = (0.5 * scene.body.mass * float(v0 @ v0)
                    + scene.body.mass * float(np.linalg.norm(scene.gravity)) * length
                    + abs(E_el0))
    result = Result(name, method, scene.dt, stats, energy_scale, length, setup)
    if setup.adaptive:
        result.adaptive = run_adaptive(setup, model, x0)
    result.wall = time.perf_counter() - started
    return result


#: Simulated time of the adaptive run of a case with the stability cap (s):
#: the cap takes Δt to about a µs, and the adaptive driver is a Python loop.
STABILITY_RUN = 0.002


def run_adaptive(setup, model, x0) -> dict:
    """What the adaptive driver does on the case: halvings, smallest step, capped steps."""
    scene = setup.scene
    if setup.stability:
        scene = scene.with_(dt=1e-3, duration=STABILITY_RUN)
        model = build_model(scene)
    traj = simulate(scene, model=model, x0=x0, adaptive=True, stability=setup.stability)
    info = traj.info
    out = {"steps": info["steps"], "halvings": info["halvings"], "dt_min": info["dt_min"],
           "criterion_max": info["criterion_max"], "duration": scene.duration,
           "finite": bool(np.all(np.isfinite(traj.position)))}
    if setup.stability:
        out["capped"] = info["stability_capped"]
    return out
