"""The result of a peer simulator and the helpers both peers share.

A peer simulator integrates the same :class:`~symcushion.model.scene.Scene` as
``symcushion.simulate`` with a different contact model (``penalty``:
a stiff spring-damper integrated by CVODES; ``mujoco_model``: MuJoCo's soft
constraints). This module owns what they have in common: the
:class:`PeerRun` record, the output grid, argument checks, the geometry that
maps a foot position back to the strut's stroke and hinge deflection, and the
rebound-speed measurement used to compare a peer with symcushion. It knows
nothing of either peer's physics.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from symcushion.scheme.quaternion import quat_to_rot_np
from symcushion.model.scene_data import Scene
from symcushion.scheme.touchdown import initial_state

__all__ = ["PeerRun", "output_times", "leg_kinematics", "trajectory_deflection",
           "rebound_speed"]

#: Time into the rebound flight (s) at which :func:`rebound_speed` samples it.
#: A peer's light foot can graze the obstacle within ~1 ms of lift-off; 5 ms
#: later the flight is surely free, and MuJoCo's Euler drift over 5 ms is
#: |g|²·h·5 ms/(2v) = 5e-5 m/s at h = 1e-4 s.
FLIGHT_SETTLE = 5e-3

#: Relative slack when deciding how many output samples fit in the duration:
#: duration/output_dt = 600.0000000001 still gives 600 intervals.
_GRID_SLACK = 1e-9


@dataclass
class PeerRun:
    """A touchdown simulated by a peer, sampled at t = k·output_dt.

    Attributes
    ----------
    t : ndarray, shape (T,)
        Sample times (s); t[0] = 0 is the initial state.
    position, velocity : ndarray, shape (T, 3)
        Body centre of mass, world (m, m/s).
    acceleration : ndarray, shape (T, 3)
        Body centre-of-mass acceleration, world (m/s²): the peer's own
        continuous-time value at the sample (for peak deceleration).
    attitude : ndarray, shape (T, 4)
        Unit quaternion (w, x, y, z), body → world.
    foot : ndarray, shape (T, N, 3)
        Foot positions, world (m). For MuJoCo the centre of the foot sphere,
        which sits on the shifted obstacle exactly where symcushion's point
        foot sits on the real one (docs/peers.md).
    stroke : ndarray, shape (T, N)
        Axial deflection δ_S = |ρ − r_h| − L₀ of each leg (m), ρ the foot in
        body axes: the same quantity as ``Trajectory.stroke``.
    deflection : ndarray, shape (T, N)
        Hinge deflection magnitude θ = ∠(e_S, e₀) (rad): the angle of the
        strut from its rest direction. To first order in the deflection
        θ = hypot(β, γ − γ₀) of ``Trajectory.beta``/``gamma_deflection``;
        :func:`trajectory_deflection` gives θ exactly from a Trajectory.
    wall_seconds : float
        Wall time of the integration alone (s).
    build_seconds : float
        Wall time to build the model (CasADi graph and integrator, or MJCF
        compilation), s.
    info : dict
        Solver statistics and every setting used (see each peer).
    contact : ndarray, shape (T, N)
        True where the foot touches an obstacle (penetration > 0).
    """

    t: np.ndarray
    position: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    attitude: np.ndarray
    foot: np.ndarray
    stroke: np.ndarray
    deflection: np.ndarray
    wall_seconds: float
    build_seconds: float
    info: dict
    contact: np.ndarray = field(default_factory=lambda: np.zeros((0, 0), dtype=bool))


# ---------------------------------------------------------------------------
# argument checks
# ---------------------------------------------------------------------------
def check_scene(scene) -> Scene:
    """``scene`` must be a :class:`Scene`."""
    if not isinstance(scene, Scene):
        raise TypeError("`scene` must be a symcushion Scene (e.g. "
                        f"load_scene('studies/fig3.toml')), got {type(scene).__name__}.")
    return scene


def state_vector(scene: Scene, x0) -> np.ndarray:
    """``x0`` as a finite float vector (default: ``initial_state(scene)``)."""
    x0 = initial_state(scene) if x0 is None else x0
    try:
        x0 = np.asarray(x0, dtype=float).ravel()
    except (TypeError, ValueError):
        raise TypeError(f"`x0` must be a vector of numbers, got {x0!r}.") from None
    if not np.all(np.isfinite(x0)):
        raise ValueError("`x0` must be finite; it holds NaN or inf.")
    return x0


def positive(name: str, value, default=None) -> float:
    """A positive finite number, or ``default`` when ``value`` is None."""
    if value is None:
        return default
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
        raise TypeError(f"`{name}` must be a positive number, got {value!r}.")
    if not (np.isfinite(value) and value > 0):
        raise ValueError(f"`{name}` must be positive and finite, got {value!r}; give a value > 0.")
    return float(value)


def nonnegative(name: str, value, default=None) -> float:
    """A finite number ≥ 0, or ``default`` when ``value`` is None."""
    if value is None:
        return default
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
        raise TypeError(f"`{name}` must be a non-negative number, got {value!r}.")
    if not (np.isfinite(value) and value >= 0):
        raise ValueError(f"`{name}` must be finite and >= 0, got {value!r}; give a value >= 0.")
    return float(value)


def output_times(scene: Scene, output_dt) -> np.ndarray:
    """Sample times k·output_dt, k = 0 … floor(duration/output_dt) (s).

    ``output_dt`` defaults to ``scene.dt`` so that a peer's samples fall on
    the time points of symcushion's fixed-step Trajectory.
    """
    dt = positive("output_dt", output_dt, scene.dt)
    if dt > scene.duration:
        raise ValueError(f"`output_dt` = {dt!r} s exceeds the scene's duration "
                         f"{scene.duration!r} s; give a smaller output step.")
    count = int(np.floor(scene.duration / dt * (1 + _GRID_SLACK)))
    return dt * np.arange(count + 1)


# ---------------------------------------------------------------------------
# geometry shared by the peers and by comparisons with symcushion
# ---------------------------------------------------------------------------
def leg_kinematics(scene: Scene, position, attitude, foot):
    """Stroke δ_S and hinge deflection θ of every leg from poses and foot positions.

    Parameters
    ----------
    scene : Scene
    position : array_like, shape (T, 3)
        Body centre of mass, world (m).
    attitude : array_like, shape (T, 4)
        Quaternions (w, x, y, z).
    foot : array_like, shape (T, N, 3)
        Foot positions, world (m).

    Returns
    -------
    stroke : ndarray, shape (T, N)
        δ_S = |ρ − r_h| − L₀ (m), ρ = Rᵀ(foot − x) the foot in body axes.
    deflection : ndarray, shape (T, N)
        θ = atan2(|e_S × e₀|, e_S·e₀) (rad), the angle of the strut from its
        rest direction (atan2 keeps full precision near θ = 0).
    """
    R = quat_to_rot_np(attitude)
    rho = np.einsum("tji,tnj->tni", R, np.asarray(foot, float)
                    - np.asarray(position, float)[:, None, :])
    hinges = np.array([leg.hinge for leg in scene.legs])
    e0 = np.array([leg.e0 for leg in scene.legs])
    lengths = np.array([leg.length for leg in scene.legs])
    d = rho - hinges[None]
    L = np.linalg.norm(d, axis=-1)
    e_S = d / L[..., None]
    stroke = L - lengths[None]
    sin = np.linalg.norm(np.cross(e_S, e0[None]), axis=-1)
    cos = np.einsum("tni,ni->tn", e_S, e0)
    return stroke, np.arctan2(sin, cos)


def trajectory_deflection(traj, scene: Scene) -> np.ndarray:
    """θ = ∠(e_S, e₀) of every leg of a symcushion Trajectory (T, N), rad.

    The quantity :attr:`PeerRun.deflection` holds, computed from the
    Trajectory's foot positions and attitude (a free foot of symcushion sits
    at its rest pose, θ = 0).
    """
    return leg_kinematics(scene, traj.position, traj.attitude, traj.foot)[1]


def rebound_speed(run, scene: Scene) -> float:
    """Speed of the body when it passes its initial height again after the first rebound.

    The same measure as ``symcushion.reproduce`` uses for the Fig. 3 claim:
    once every foot is free and the body rises after the first touchdown,
    the flight is ballistic, so the speed at the initial height h₀ follows
    from a sample k of it (:data:`FLIGHT_SETTLE` after lift-off) as
    v = sqrt(v_k² + 2|g|(h_k − h₀)), heights and velocities taken along −g.
    Works on a :class:`PeerRun` and on a symcushion Trajectory (both carry
    ``contact``, ``position``, ``velocity``). For a peer whose
    ``info`` holds ``foot_mass`` and ``foot_velocity`` the centre of mass of
    body and feet is used: its flight is exactly ballistic, the body's alone
    is shaken by the feet vibrating on their springs.

    Returns
    -------
    float
        m/s, or NaN when the body never leaves the obstacle in the run.
    """
    g = np.asarray(scene.gravity, dtype=float)
    g_norm = float(np.linalg.norm(g))
    if g_norm == 0:
        raise ValueError("`scene.gravity` is zero: a rebound speed at the initial height needs "
                         "gravity; measure the velocity directly instead.")
    up = -g / g_norm
    touching = np.asarray(run.contact, dtype=float) > 0.5
    if touching.ndim != 2 or touching.shape[0] != len(run.t):
        raise ValueError("`run.contact` must be a (T, N) array of contact flags.")
    any_touch = touching.any(axis=1)
    first = np.argmax(any_touch) if any_touch.any() else None
    if first is None:
        return float("nan")
    position = np.asarray(run.position, float)
    velocity = np.asarray(run.velocity, float)
    info = getattr(run, "info", None) or {}
    if "foot_velocity" in info and "foot_mass" in info:
        # a peer's feet have mass and vibrate on their legs in flight, shaking
        # the body by ~(m_f/m)·u; the centre of mass of body and feet is exactly
        # ballistic once every foot is free
        m, m_f = scene.body.mass, float(info["foot_mass"])
        total = m + m_f * len(scene.legs)
        position = (m * position + m_f * np.asarray(run.foot, float).sum(axis=1)) / total
        velocity = (m * velocity + m_f * np.asarray(info["foot_velocity"], float).sum(axis=1)) \
            / total
    h = position @ up
    v_up = velocity @ up
    # a light foot may leave the surface for a sample at impact while the body
    # still descends: only a free sample with the body rising is the rebound
    rebound = np.where(~any_touch[first:] & (v_up[first:] > 0))[0]
    if rebound.size == 0:
        return float("nan")
    start = first + rebound[0]
    # FLIGHT_SETTLE into that flight: a light foot may still graze the obstacle
    # between the samples right after lift-off, so those are not yet
    # ballistic; later ones are, but a first-order integrator's flight drifts
    # (semi-implicit Euler: v² + 2|g|h loses |g|²·h_step per second of flight)
    landing = np.where(any_touch[start:])[0]
    end = start + landing[0] - 1 if landing.size else len(any_touch) - 1
    t = np.asarray(run.t, float)
    k = min(int(np.searchsorted(t, t[start] + FLIGHT_SETTLE)), end)
    v = v_up[k]
    return float(np.sqrt(max(v * v + 2 * g_norm * (h[k] - h[0]), 0.0)))
