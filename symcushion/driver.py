"""The driver: runs a scene's touchdown step and returns its trajectory.

This module owns :func:`simulate` (a fixed-step rollout in one call, or the
paper's adaptive step criterion 1 − n_k·n_{k+1} < ε of §3 by halving Δt),
the :class:`Trajectory` it returns, and writing trajectories to CSV and NPZ.
It must not build or change the step: that is :mod:`symcushion.touchdown`.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .layout import BODY_OUT, BODY_STATE, LEG_OUT, LEG_STATE, output_layout
from .scene import Scene
from .validation import real
from .touchdown import (MAX_HALVINGS, STABILITY_SAFETY, STEP_CRITERION_EPS, StepModel,
                        _default_p, _rot_np, build_model, initial_state, stable_dt)

__all__ = ["Trajectory", "trajectory_from", "simulate", "save"]


# ---------------------------------------------------------------------------
# trajectories
# ---------------------------------------------------------------------------
@dataclass
class Trajectory:
    """A simulated touchdown, one row per time point (SI units, world frame).

    Attributes
    ----------
    t : (T,) s
    position, velocity, acceleration : (T, 3) m, m/s, m/s²
    attitude : (T, 4) unit quaternion (w, x, y, z)
    angular_velocity : (T, 3) rad/s, body axes
    foot : (T, N, 3) foot positions (m)
    contact : (T, N) 1 in contact
    mode : (T, N) 0 free, 1 stick, 2 slip, 3 lift-off (:data:`MODES`)
    force : (T, N, 3) force on each foot from the obstacle (N)
    normal : (T, N, 3) unit surface normal at the contact point (0 when free)
    alpha : (T, N) angle of the surface normal from the vertical (rad, NaN when free)
    rod_angle : (T, N) angle of the strut from the downward vertical (rad)
    force_angle : (T, N) angle of the contact force from the vertical (rad, NaN when free)
    stroke, beta, gamma_deflection : (T, N) δ_S (m), hinge β and γ − γ₀ (rad)
    criterion : (T,) max over feet of 1 − n_k·n_{k+1} (§3 step criterion)
    info : dict
        dt, steps, halvings, wall_seconds, criterion_max, method, and
        ``final_state`` (the state vector after the last step, to continue a run).
    """

    t: np.ndarray
    position: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    attitude: np.ndarray
    angular_velocity: np.ndarray
    foot: np.ndarray
    contact: np.ndarray
    mode: np.ndarray
    force: np.ndarray
    normal: np.ndarray
    alpha: np.ndarray
    rod_angle: np.ndarray
    force_angle: np.ndarray
    stroke: np.ndarray
    beta: np.ndarray
    gamma_deflection: np.ndarray
    criterion: np.ndarray
    info: dict = field(default_factory=dict)

    _ARRAYS = ("t", "position", "velocity", "acceleration", "attitude", "angular_velocity",
               "foot", "contact", "mode", "force", "normal", "alpha", "rod_angle",
               "force_angle", "stroke", "beta", "gamma_deflection", "criterion")

    def save_npz(self, path):
        """Save every array (and ``info`` as a string) to an NPZ file."""
        np.savez(path, info=str(self.info), **{k: getattr(self, k) for k in self._ARRAYS})

    def save_csv(self, path):
        """Save one row per time point; per-leg columns are suffixed ``_j``."""
        cols, data = [], []

        def add(name, arr):
            arr = np.asarray(arr, dtype=float)
            if arr.ndim == 1:
                cols.append(name)
                data.append(arr)
            else:
                for idx in np.ndindex(arr.shape[1:]):
                    cols.append(name + "_" + "_".join(str(i) for i in idx))
                    data.append(arr[(slice(None),) + idx])

        for k in self._ARRAYS:
            add(k, getattr(self, k))
        table = np.column_stack(data)
        with open(path, "w") as fh:
            fh.write(",".join(cols) + "\n")
            for row in table:
                fh.write(",".join("" if np.isnan(v) else repr(float(v)) for v in row) + "\n")


def _angle_from(vectors, axis):
    norm = np.linalg.norm(vectors, axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        cos = np.einsum("...i,i->...", vectors, axis) / norm
    return np.arccos(np.clip(cos, -1.0, 1.0))


def trajectory_from(model: StepModel, x0, X, Y, t) -> Trajectory:
    """Assemble a :class:`Trajectory` from a state history and outputs."""
    scene = model.scene
    N = model.n_legs
    X = np.column_stack([np.asarray(x0, float).reshape(-1, 1), np.asarray(X, float)]).T
    Y = np.asarray(Y, float).T
    legs_x = X[:, BODY_STATE:].reshape(len(X), N, LEG_STATE)
    legs_y = Y[:, BODY_OUT:].reshape(len(Y), N, LEG_OUT)
    # the initial row has no step output: forces come from the state, geometry is NaN
    pad = lambda arr: np.concatenate([arr[:1] * np.nan, arr], axis=0)  # noqa: E731
    up = -scene.gravity / np.linalg.norm(scene.gravity)
    R0 = _rot_np(X[0, 6:10])
    acc0 = scene.gravity + R0 @ legs_x[0, :, 4:7].sum(axis=0) / scene.body.mass
    contact = np.concatenate([legs_x[:1, :, 3], legs_y[:, :, 0]])
    force = np.concatenate([np.einsum("ij,nj->ni", R0, legs_x[0, :, 4:7])[None], legs_y[:, :, 2:5]])
    normal = pad(legs_y[:, :, 5:8])
    e_S = pad(legs_y[:, :, 8:11])
    alpha = _angle_from(normal, up)
    alpha[contact < 0.5] = np.nan
    force_angle = _angle_from(force, up)
    force_angle[contact < 0.5] = np.nan
    crit = np.zeros(len(X))
    dots = np.einsum("tni,tni->tn", normal[1:-1], normal[2:])
    both = (contact[1:-1] > 0.5) & (contact[2:] > 0.5)
    crit[2:] = np.where(both, 1 - dots, 0.0).max(axis=1) if N else 0.0
    return Trajectory(
        t=np.asarray(t, float), position=X[:, 0:3], velocity=X[:, 3:6],
        acceleration=np.concatenate([acc0[None], Y[:, 0:3]]), attitude=X[:, 6:10],
        angular_velocity=X[:, 10:13], foot=legs_x[:, :, 0:3], contact=contact,
        mode=np.concatenate([legs_x[:1, :, 3], legs_y[:, :, 1]]), force=force, normal=normal,
        alpha=alpha, rod_angle=_angle_from(e_S, -up), force_angle=force_angle,
        stroke=pad(legs_y[:, :, 11]), beta=pad(legs_y[:, :, 12]),
        gamma_deflection=pad(legs_y[:, :, 13]), criterion=crit)


def simulate(scene: Scene | str | Path, *, model: StepModel | None = None, x0=None, p=None,
             adaptive: bool = False, eps: float = STEP_CRITERION_EPS,
             stability: bool | float = False, progress: bool = False) -> Trajectory:
    """Simulate a scene.

    The scene is checked first (``symcushion.checks.preflight``): a scene that
    makes no physical sense raises ``SceneError``, a doubtful one warns.

    Parameters
    ----------
    scene : Scene, or str or Path of a scene TOML file
    model : StepModel, optional
        A model built before by :func:`build_model` (reused across calls).
    x0 : array_like, shape (nx,), optional
        Initial state; default :func:`initial_state`.
    p : array_like, optional
        Leg parameters (``model.param_names``); default the scene's values.
    adaptive : bool
        False: fixed Δt, the whole run in one call of ``touchdown_rollout``;
        the largest value of the step criterion is in ``info['criterion_max']``.
        True: a Python loop that applies the paper's criterion
        1 − n_k·n_{k+1} < ``eps`` (§3) by halving Δt for a step (up to
        :data:`MAX_HALVINGS` times) where a contact normal turns too fast.
    stability : bool or float
        Adaptive runs only: also cap each step at :data:`STABILITY_SAFETY`
        (``True``) or the given fraction in (0, 1] × :func:`stable_dt` of its
        start state (stiff legs, e.g. rigid rods with a large ``axial_ratio``;
        a fraction well below 1 also resolves the stiff mode, whose energy
        error is O((ω_max Δt)²) of the energy it carries). ``info`` then has
        ``stability_capped`` (steps shortened by the cap); every adaptive run
        reports ``dt_min``, the smallest step taken (the final step, cut to
        end at ``duration``, aside).
    progress : bool
        Print a progress line (adaptive runs).
    """
    from .checks import preflight
    from .scene import load_scene

    scene = load_scene(scene) if isinstance(scene, (str, Path)) else scene
    model = model or build_model(scene)
    x0 = initial_state(scene) if x0 is None else np.asarray(x0, dtype=float)
    if x0.shape != (model.nx,):
        raise ValueError(f"`x0` must have shape ({model.nx},), got {x0.shape}.")
    p = _default_p(scene) if p is None else np.asarray(p, dtype=float)
    if p.shape != (model.np,):
        raise ValueError(f"`p` must have {model.np} entries {model.param_names}, got {p.shape}.")
    if stability is True or stability is False:
        stability = STABILITY_SAFETY if stability else 0.0
    if isinstance(stability, (bool, np.bool_)) or not isinstance(stability, (int, float)) \
            or not 0 <= stability <= 1:
        raise ValueError(f"`stability` must be True, False or a fraction in (0, 1], "
                         f"got {stability!r}.")
    if stability and not adaptive:
        raise ValueError("`stability` needs `adaptive=True` (a fixed-step run uses "
                         "scene.dt; choose it below stable_dt(model, x0) instead).")
    eps = real("eps", eps, positive=True)
    # the adaptive driver cuts its last step at `duration` and may cap steps at stable_dt
    preflight(scene, model, x0=x0, ignore=("dt_above_duration",) * bool(adaptive)
              + ("dt_unstable",) * bool(stability))
    started = time.perf_counter()
    if not adaptive:
        steps = scene.steps
        X, Y = model.rollout(steps)(x0, p, scene.dt)
        t = scene.dt * np.arange(steps + 1)
        traj = trajectory_from(model, x0, X, Y, t)
        traj.info = {"dt": scene.dt, "steps": steps, "halvings": 0,
                     "final_state": np.asarray(X, dtype=float)[:, -1]}
    else:
        traj = _simulate_adaptive(model, x0, p, eps, progress, stability)
    traj.info["criterion_max"] = float(np.nanmax(traj.criterion)) if traj.criterion.size else 0.0
    traj.info["wall_seconds"] = time.perf_counter() - started
    traj.info["method"] = scene.method
    if not np.all(np.isfinite(traj.position)):
        raise FloatingPointError("the simulation produced non-finite body positions; "
                                 "reduce `dt` or check the scene (see info).")
    return traj


def _normals(model, y):
    N = model.n_legs
    y = np.asarray(y, float).ravel()
    yl = output_layout(N)
    return yl.legs(y, "contact") > 0.5, yl.legs(y, "normal")


def _simulate_adaptive(model, x0, p, eps, progress, stability=0.0):
    scene = model.scene
    step = model.step
    t_end, dt = scene.duration, scene.dt
    t, x = 0.0, x0
    ts, xs, ys = [0.0], [], []
    last_contact, last_normal = None, None
    halvings = capped = 0
    dt_min = np.inf
    next_report = time.perf_counter() + 1.0
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
        ts.append(t)
        xs.append(x)
        ys.append(np.asarray(y, float).ravel())
        last_contact, last_normal = contact, normal
        if progress and time.perf_counter() > next_report:
            print(f"\r  t = {t:.4f} / {t_end:g} s, {len(ts) - 1} steps, {halvings} halvings",
                  end="", flush=True)
            next_report = time.perf_counter() + 1.0
    if progress:
        print()
    traj = trajectory_from(model, x0, np.column_stack(xs), np.column_stack(ys), np.array(ts))
    traj.info = {"dt": dt, "steps": len(ts) - 1, "halvings": halvings, "eps": eps,
                 "final_state": x, "dt_min": dt_min}
    if stability:
        traj.info["stability_capped"] = capped
    return traj


def save(traj: Trajectory, out_dir, stem: str):
    """Write ``stem.csv`` and ``stem.npz`` into ``out_dir``; return their paths."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    csv, npz = out / f"{stem}.csv", out / f"{stem}.npz"
    traj.save_csv(csv)
    traj.save_npz(npz)
    return csv, npz
