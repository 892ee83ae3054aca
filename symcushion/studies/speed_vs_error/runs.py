"""Runs of the speed-vs-error study: a touchdown reduced to what the metrics read.

Owns :class:`Run`, the reduction of symcushion.simulate's state columns to
it (:func:`reduce_states`) and the timed, chunked rollout of a VM or
compiled model (:func:`simulate_chunked`). It must not compute metrics or
errors, run peers, or write files.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from symcushion.compiled.codegen import CompiledModel
from symcushion.layout.vectors import state_layout
from symcushion.layout.params import default_p
from symcushion.scheme.quaternion import quat_to_rot_np
from symcushion.model.scene_data import Scene
from symcushion.scheme.touchdown import initial_state

from .grid import BEST_OF, CHUNK, REPEAT_BELOW


@dataclass
class Run:
    """A touchdown reduced to the quantities the metrics read (SI, world frame).

    Attributes
    ----------
    t : ndarray, shape (T,)
        Sample times (s), t[0] = 0 the initial state.
    position, velocity : ndarray, shape (T, 3)
        Centre of mass (m, m/s).
    decel : ndarray, shape (T,)
        |a − g| (m/s²): the legs' total force over the mass.
    hinge : ndarray, shape (T,)
        Largest hinge deflection over the legs: angle between the strut and
        its rest direction e₀, body frame (rad).
    stroke : ndarray, shape (T,)
        Largest axial stroke |δ_S| = |L − L₀| over the legs (m).
    info : dict
        Timing (``wall``, ``cpu``, ``passes``, ``steps_run``, ``build``) and
        the backend's notes.
    """

    t: np.ndarray
    position: np.ndarray
    velocity: np.ndarray
    decel: np.ndarray
    hinge: np.ndarray
    stroke: np.ndarray
    info: dict = field(default_factory=dict)

    def __post_init__(self):
        T = len(self.t)
        for name in ("position", "velocity"):
            if np.shape(getattr(self, name)) != (T, 3):
                raise ValueError(f"`{name}` must have shape ({T}, 3), got "
                                 f"{np.shape(getattr(self, name))}.")
        for name in ("decel", "hinge", "stroke"):
            if np.shape(getattr(self, name)) != (T,):
                raise ValueError(f"`{name}` must have shape ({T},), got "
                                 f"{np.shape(getattr(self, name))}.")

    def finite(self) -> bool:
        """True when every sampled quantity is finite."""
        return bool(all(np.all(np.isfinite(getattr(self, k)))
                        for k in ("position", "velocity", "decel", "hinge", "stroke")))


def reduce_states(scene: Scene, X) -> dict:
    """The Run quantities of state columns X (nx × K), symcushion.simulate's layout.

    The state holds each leg's foot (world), contact flag and force on the
    foot (body axes), so |a − g| = |Σ_j P_j| / m and the strut vector is
    ρ_j − r_h with ρ_j = Rᵀ(foot_j − x); a free foot is stored at its rest
    pose, deflection zero.
    """
    X = np.asarray(X, dtype=float)
    xl = state_layout(len(scene.legs))
    pos, vel = xl.get(X, "position").T, xl.get(X, "velocity").T
    R = quat_to_rot_np(xl.get(X, "attitude").T, normalise=False)
    force = np.zeros((X.shape[1], 3))
    hinge = np.zeros(X.shape[1])
    stroke = np.zeros(X.shape[1])
    for j, leg in enumerate(scene.legs):
        force += xl.get(X, "force_body", j).T
        rho = np.einsum("tki,tk->ti", R, xl.get(X, "foot", j).T - pos)
        strut = rho - leg.hinge
        length = np.linalg.norm(strut, axis=1)
        e_S = strut / length[:, None]
        angle = np.arctan2(np.linalg.norm(np.cross(e_S, leg.e0), axis=1), e_S @ leg.e0)
        hinge = np.maximum(hinge, angle)
        stroke = np.maximum(stroke, np.abs(length - leg.length))
    return {"position": pos, "velocity": vel,
            "decel": np.linalg.norm(force, axis=1) / scene.body.mass,
            "hinge": hinge, "stroke": stroke}


def simulate_chunked(model, scene: Scene, dt: float, *, chunk: int = CHUNK,
                     passes: int = BEST_OF, repeat_below: float = REPEAT_BELOW) -> Run:
    """Simulate ``scene`` at step ``dt`` by repeated rollout calls; time the calls.

    Parameters
    ----------
    model : StepModel or CompiledModel
        A VM model (``build_model``) or a compiled one (``compiled_model``).
        A compiled model runs its compiled rollout (``compiled_steps`` steps
        per call); a VM model a rollout of min(chunk, steps) steps, built here
        and cached by the model.
    scene : Scene
        Its duration sets the steps, round(duration/dt).
    dt : float
        Time step (s).
    chunk : int
        Steps per VM rollout call.
    passes : int
        Most timing passes; a pass is repeated only while the first took less
        than ``repeat_below`` s of CPU.

    Returns
    -------
    Run
        Samples 0..steps; ``info`` has ``wall`` and ``cpu`` (fastest pass, s),
        ``passes``, ``steps_run`` (steps evaluated, ≥ steps), ``build`` (s,
        rollout construction) and ``sim_seconds`` (steps_run·dt).
    """
    if not (isinstance(dt, (float, int)) and np.isfinite(dt) and dt > 0):
        raise ValueError(f"`dt` must be a positive number of seconds, got {dt!r}.")
    if isinstance(chunk, bool) or not isinstance(chunk, int) or chunk < 1:
        raise ValueError(f"`chunk` must be a positive integer, got {chunk!r}.")
    steps = max(1, int(round(scene.duration / dt)))
    started = time.perf_counter()
    if isinstance(model, CompiledModel):
        length = model.compiled_steps
    else:
        length = min(chunk, steps)
    rollout = model.rollout(length)
    build = time.perf_counter() - started
    calls = -(-steps // length)
    x0 = initial_state(scene)
    p = default_p(scene)

    def one_pass(keep):
        # only the rollout calls are timed; each chunk is reduced as it comes
        # (a reference run has millions of steps: the states would not fit)
        x, wall, cpu = x0, 0.0, 0.0
        parts = [reduce_states(scene, x0[:, None])] if keep else None
        for _ in range(calls):
            w0, c0 = time.perf_counter(), time.process_time()
            X, _ = rollout(x, p, dt)
            wall += time.perf_counter() - w0
            cpu += time.process_time() - c0
            X = np.asarray(X, dtype=float)
            x = X[:, -1]
            if keep:
                parts.append(reduce_states(scene, X))
        return wall, cpu, parts

    wall, cpu, reduced = one_pass(keep=True)
    n_pass = 1
    while n_pass < passes and cpu < repeat_below:
        w, c, _ = one_pass(keep=False)
        wall, cpu = min(wall, w), min(cpu, c)
        n_pass += 1
    arrays = {k: np.concatenate([r[k] for r in reduced])[:steps + 1] for k in reduced[0]}
    return Run(t=dt * np.arange(steps + 1), **arrays,
               info={"wall": wall, "cpu": cpu, "cost": cpu, "passes": n_pass,
                     "steps_run": calls * length,
                     "sim_seconds": calls * length * dt, "build": build, "steps": steps})
