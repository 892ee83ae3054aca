"""Touchdown simulation: the contact step of §1 inside a CasADi step Function.

This module owns the time integration of a :class:`~symcushion.scene.Scene`.
It receives the physics from elsewhere: the leg force P(r) and stiffness D_p
from ``symcushion.strut``, the contact step from ``symcushion.contact`` and
the obstacle geometry from ``symcushion.obstacles``; it re-derives none of it.

Scheme (one step of length h, §3 of the paper with a velocity-Verlet body):

1. half kick with the foot forces F_j of the previous step (state):
   v ← v + h/2·(g + R ΣF_j/m), ω ← ω + h/2·I⁻¹(τ − ω × Iω);
2. drift: x' = x + h v, q' = q ⊗ exp(h ω/2) (renormalised);
3. each foot: the obstacle near it is replaced by its tangent plane (§3).
   A foot in contact starts from its stored world position r_j with the exact
   P₀ = P(ρ_j) and D_p(ρ_j) at ρ_j = Rᵀ(r_j − x) (body frame). A free foot
   whose unloaded position crosses the surface during the step starts at the
   crossing point (linear interpolation of the signed distance, projected on
   the surface) with the unloaded pose as ρ_j. The plane's displacement
   relative to the body is l_j = R'ᵀ(r_s − x') − ρ_j — the exact rigid-body
   kinematics of §3's l_j = (V₀ + ω₀ × r_j)Δt with the sign of a body moving
   past a fixed obstacle. The contact step gives δ_j, P_j; the foot moves to
   ρ_j + δ_j, is projected back onto the curved surface, or returns to its
   unloaded pose on lift-off;
4. second half kick with the new forces.

Order: velocity Verlet is second order and symplectic for smooth forces; the
contact law is non-smooth, so the measured order is stated by the tests
(``tests/test_simulate.py``) rather than assumed. The first-contact instant
inside a step is located by linear interpolation of the distance; the force
at the end of that step is exact for a plane, and the impulse over the step is
integrated by the trapezoid rule, an O(h²) local error once per touchdown.

Stability: the body update is explicit in velocity, so a stiff leg limits the
step to ω_max Δt < 2, ω_max² the largest eigenvalue of M⁻¹K (M the body's
6×6 mass matrix, K the stiffness of its pose against feet held fixed).
:func:`stable_dt` estimates that limit from D_p by AD; ``simulate(...,
adaptive=True, stability=True)`` caps every step at :data:`STABILITY_SAFETY`
of it, or at a given fraction (opt-in, added for the stiff-leg hard case,
docs/hard-cases.md; the default driver is unchanged). The paper's criterion
1 − n_k·n_{k+1} < ε says nothing about this limit.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

import casadi as ca
import numpy as np

from .contact import contact_step_call
from .obstacles import closest_obstacle
from .scene import Scene

__all__ = ["StepModel", "Trajectory", "build_model", "simulate", "initial_state",
           "equilibrium_state", "stable_dt", "MODES", "STEP_CRITERION_EPS", "STABILITY_SAFETY",
           "BODY_STATE", "LEG_STATE", "BODY_OUT", "LEG_OUT"]

#: Codes of the ``mode`` output of each leg.
MODES = {0: "free", 1: "stick", 2: "slip", 3: "lift-off"}

#: ε of the paper's step criterion 1 − n_k·n_{k+1} < ε (§3): a normal may
#: turn by about √(2ε) = 0.45° per step before the adaptive driver halves Δt.
STEP_CRITERION_EPS = 3e-5

#: Deepest halving of Δt by the adaptive driver (Δt/2¹⁰ at most).
MAX_HALVINGS = 10

#: Fraction of the explicit stability limit 2/ω_max (:func:`stable_dt`) that
#: ``simulate(adaptive=True, stability=True)`` allows per step: ω_max Δt ≤ 1,
#: where velocity Verlet keeps the stiffest mode stable with a frequency error
#: of 5 % (cos ω̃Δt = 1 − (ωΔt)²/2) instead of sitting on the edge of
#: instability (ω Δt = 2). Stable is not accurate: an impact whose energy
#: passes through that mode needs a smaller fraction (docs/hard-cases.md).
STABILITY_SAFETY = 0.5

# Layout of the state x and the per-step output y (public: the C API and the
# optimiser index them). x = [body (BODY_STATE), leg 0 (LEG_STATE), leg 1, ...],
# y = [body (BODY_OUT), leg 0 (LEG_OUT), leg 1, ...].
#: Body state: position (3), velocity (3), quaternion w, x, y, z (4), angular velocity, body axes (3).
BODY_STATE = 13
#: Leg state: foot world position (3), contact flag (1), force on the foot, body frame (3).
LEG_STATE = 7
#: Body output: acceleration of the centre of mass, world (3).
BODY_OUT = 3
#: Leg output: contact, mode, P world (3), normal (3), e_S world (3), δ_S, β, γ − γ₀.
LEG_OUT = 14


# ---------------------------------------------------------------------------
# rigid-body helpers (CasADi)
# ---------------------------------------------------------------------------
def quat_to_rot(q):
    """Rotation matrix (body → world) of a unit quaternion (w, x, y, z)."""
    w, x, y, z = q[0], q[1], q[2], q[3]
    return ca.vertcat(
        ca.horzcat(1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)),
        ca.horzcat(2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)),
        ca.horzcat(2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)))


def quat_mul(a, b):
    """Hamilton product a ⊗ b."""
    aw, av = a[0], a[1:4]
    bw, bv = b[0], b[1:4]
    return ca.vertcat(aw * bw - ca.dot(av, bv), aw * bv + bw * av + ca.cross(av, bv))


def quat_exp(theta):
    """Quaternion of the rotation vector θ (rad), safe at θ = 0."""
    angle2 = ca.dot(theta, theta)
    angle = ca.sqrt(ca.if_else(angle2 > 0, angle2, 1.0))
    # sin(a/2)/a with its Taylor series where a is tiny (no 0/0 in either branch)
    half_sinc = ca.if_else(angle2 > 1e-16, ca.sin(angle / 2) / angle, 0.5 - angle2 / 48)
    return ca.vertcat(ca.if_else(angle2 > 1e-16, ca.cos(angle / 2), 1 - angle2 / 8),
                      half_sinc * theta)


# ---------------------------------------------------------------------------
# the step Function
# ---------------------------------------------------------------------------
@dataclass
class StepModel:
    """The CasADi Functions of a scene and the layout of their vectors.

    Attributes
    ----------
    step : casadi.Function
        ``touchdown_step(x, p, dt) -> (x_next, y)``.
    scene : Scene
    nx, ny, np : int
        Sizes of the state, the per-step output and the parameter vector.
    param_names : tuple of str
        Names of ``p`` (``leg{j}.{element}.{name}``).
    """

    step: ca.Function
    scene: Scene
    nx: int
    ny: int
    np: int
    param_names: tuple
    _rollouts: dict = field(default_factory=dict)
    _body_stiffness: ca.Function | None = None

    def rollout(self, steps: int) -> ca.Function:
        """``touchdown_rollout(x0, p, dt) -> (X, Y)``: ``steps`` steps by mapaccum.

        X has the states after each step as columns (nx × steps), Y the outputs.
        One call runs a whole simulation and is differentiable end to end.
        """
        if isinstance(steps, bool) or not isinstance(steps, (int, np.integer)) or steps < 1:
            raise ValueError(f"`steps` must be a positive integer, got {steps!r}.")
        steps = int(steps)
        if steps not in self._rollouts:
            # Building costs about 2 ms per step (CasADi's sparsity analysis of the
            # repeated step); evaluating costs the same as a loop of calls without the
            # Python overhead. Built once per length and cached.
            acc = self.step.mapaccum("touchdown_rollout_acc", steps)
            x0 = ca.MX.sym("x0", self.nx)
            p = ca.MX.sym("p", self.np)
            dt = ca.MX.sym("dt")
            X, Y = acc(x0, p, dt)
            self._rollouts[steps] = ca.Function("touchdown_rollout", [x0, p, dt], [X, Y],
                                                ["x0", "p", "dt"], ["X", "Y"])
        return self._rollouts[steps]

    @property
    def n_legs(self):
        return len(self.scene.legs)

    def graph_size(self) -> dict:
        """Size of the step graph: SX instructions and nodes."""
        return {"instructions": self.step.n_instructions(), "nodes": self.step.n_nodes()}


def _leg_params(scene: Scene):
    names, offsets, start = [], [], 0
    for j, leg in enumerate(scene.legs):
        offsets.append((start, start + len(leg.param_names)))
        names += [f"leg{j}.{n}" for n in leg.param_names]
        start += len(leg.param_names)
    return tuple(names), offsets


def build_model(scene: Scene) -> StepModel:
    """Build the ``touchdown_step`` Function of a scene.

    Only what the scene needs is built: a leg's absent elements add nothing,
    μ = 0 builds the frictionless contact step, and only the scene's
    obstacles are in the graph.
    """
    legs, body = scene.legs, scene.body
    n_legs = len(legs)
    names, offsets = _leg_params(scene)
    nx = BODY_STATE + LEG_STATE * n_legs
    ny = BODY_OUT + LEG_OUT * n_legs

    X = ca.SX.sym("x", nx)
    p = ca.SX.sym("p", len(names))
    h = ca.SX.sym("dt")

    m = body.mass
    inertia = ca.DM(body.inertia)
    inertia_inv = ca.DM(np.linalg.inv(body.inertia))
    g = ca.DM(scene.gravity)
    mu = scene.mu
    friction = mu > 0

    pos, vel, quat, omega = X[0:3], X[3:6], X[6:10], X[10:13]
    feet = [X[BODY_STATE + LEG_STATE * j: BODY_STATE + LEG_STATE * (j + 1)]
            for j in range(n_legs)]
    rest = [ca.DM(leg.rest_foot) for leg in legs]

    R = quat_to_rot(quat)

    def body_frame_foot(j, foot, R_, pos_):
        in_contact = foot[3] > 0.5
        return ca.if_else(in_contact, R_.T @ (foot[0:3] - pos_), rest[j])

    # 1. half kick with the stored forces
    force = ca.DM.zeros(3)
    torque = ca.DM.zeros(3)
    for j, foot in enumerate(feet):
        rho = body_frame_foot(j, foot, R, pos)
        force = force + foot[4:7]
        torque = torque + ca.cross(rho, foot[4:7])
    acc = g + R @ force / m
    vel_h = vel + h / 2 * acc
    omega_h = omega + h / 2 * (inertia_inv @ (torque - ca.cross(omega, inertia @ omega)))

    # 2. drift
    pos1 = pos + h * vel_h
    quat1 = quat_mul(quat, quat_exp(h * omega_h))
    quat1 = quat1 / ca.norm_2(quat1)
    R1 = quat_to_rot(quat1)

    # 3. feet
    new_feet, outputs = [], []
    force1 = ca.DM.zeros(3)
    torque1 = ca.DM.zeros(3)
    for j, (leg, foot) in enumerate(zip(legs, feet)):
        fns = leg.functions()
        p_leg = p[offsets[j][0]:offsets[j][1]]
        in_contact = foot[3] > 0.5
        # free foot: where does its unloaded position cross the surface?
        free0 = pos + R @ rest[j]
        free1 = pos1 + R1 @ rest[j]
        d0, _, _ = closest_obstacle(scene.obstacles, free0)
        d1, _, _ = closest_obstacle(scene.obstacles, free1)
        crossing = d0 - d1
        tau = ca.if_else(crossing > 0, d0 / ca.if_else(crossing > 0, crossing, 1.0), 0.0)
        tau = ca.fmin(ca.fmax(tau, 0.0), 1.0)
        _, _, touch = closest_obstacle(scene.obstacles, free0 + tau * (free1 - free0))
        touches = d1 < 0
        active = ca.logic_or(in_contact, touches)

        r_s = ca.if_else(in_contact, foot[0:3], touch)        # world point of the plane
        rho_s = body_frame_foot(j, foot, R, pos)               # foot, body frame
        _, normal_w, _ = closest_obstacle(scene.obstacles, r_s)
        l = R1.T @ (r_s - pos1) - rho_s                        # §3: l_j, exact kinematics
        n_b = R1.T @ normal_w
        u0 = rho_s - rest[j]
        v_rel = l / h                                          # selects loading branches
        P0 = fns["strut_force"](rho_s, v_rel, p_leg)
        Dp = fns["strut_stiffness"](rho_s, v_rel, p_leg)
        out = contact_step_call(scene.method, P0, Dp, n_b, l, mu if friction else 0.0, u0,
                                friction=friction)
        if scene.tangent_plane == "end":
            # second pass: the tangent plane at the predicted end point, shifted along
            # its normal so that a sticking foot keeps its world point r_s
            _, _, r_pred = closest_obstacle(scene.obstacles, pos1 + R1 @ (rho_s + out["delta"]))
            _, normal_w, _ = closest_obstacle(scene.obstacles, r_pred)
            n_b = R1.T @ normal_w
            l = l + n_b * ca.dot(n_b, R1.T @ (r_pred - r_s))
            out = contact_step_call(scene.method, P0, Dp, n_b, l, mu if friction else 0.0, u0,
                                    friction=friction)
        stays = ca.logic_and(active, out["contact"] > 0.5)
        rho1 = ca.if_else(stays, rho_s + out["delta"], rest[j])
        foot_w = pos1 + R1 @ rho1
        _, _, foot_proj = closest_obstacle(scene.obstacles, foot_w)
        foot_w = ca.if_else(stays, foot_proj, foot_w)
        rho1 = ca.if_else(stays, R1.T @ (foot_w - pos1), rho1)
        P1 = ca.if_else(stays, out["P"], ca.DM.zeros(3))
        new_feet.append(ca.vertcat(foot_w, ca.if_else(stays, 1.0, 0.0), P1))
        force1 = force1 + P1
        torque1 = torque1 + ca.cross(rho1, P1)

        slipping = ca.dot(out["k"], out["k"]) > 0
        mode = ca.if_else(stays, ca.if_else(slipping, 2.0, 1.0),
                          ca.if_else(active, 3.0, 0.0))
        geo = fns["strut_geometry"](rho1)
        L_, dS, beta, gamma, e_S = geo[0], geo[1], geo[2], geo[3], geo[4]
        outputs.append(ca.vertcat(ca.if_else(stays, 1.0, 0.0), mode, R1 @ P1,
                                  ca.if_else(stays, normal_w, ca.DM.zeros(3)), R1 @ e_S,
                                  dS, beta, gamma - leg.gamma0))

    # 4. second half kick with the new forces
    acc1 = g + R1 @ force1 / m
    vel1 = vel_h + h / 2 * acc1
    omega1 = omega_h + h / 2 * (inertia_inv @ (torque1 - ca.cross(omega_h, inertia @ omega_h)))

    x_next = ca.vertcat(pos1, vel1, quat1, omega1, *new_feet)
    y = ca.vertcat(acc1, *outputs)
    step = ca.Function("touchdown_step", [X, p, h], [x_next, y], ["x", "p", "dt"],
                       ["x_next", "y"])
    return StepModel(step=step, scene=scene, nx=nx, ny=ny, np=len(names), param_names=names)


# ---------------------------------------------------------------------------
# states
# ---------------------------------------------------------------------------
def initial_state(scene: Scene) -> np.ndarray:
    """State vector of the scene's initial conditions, all feet free."""
    b = scene.body
    x = [b.position, b.velocity, b.attitude, b.angular_velocity]
    R = _rot_np(b.attitude)
    for leg in scene.legs:
        x += [b.position + R @ leg.rest_foot, [0.0], np.zeros(3)]
    return np.concatenate([np.ravel(v) for v in x]).astype(float)


def _rot_np(q):
    return np.asarray(ca.Function("R", [], [quat_to_rot(ca.DM(q))])()["o0"], dtype=float)


def _drop_point(obstacles, free, direction, iterations=20):
    """Where the line free + s·direction first meets the obstacle (Newton in s)."""
    point = ca.DM(free)
    for _ in range(iterations):
        d, n, _ = closest_obstacle(obstacles, point)
        slope = float(ca.evalf(ca.dot(n, ca.DM(direction))))
        if abs(slope) < 1e-9:
            raise ValueError("cannot drop a foot onto the obstacle: the drop direction is "
                             "tangent to it; use placement='nearest'.")
        point = point - float(ca.evalf(d)) / slope * ca.DM(direction)
    return np.asarray(point, dtype=float).ravel()


def equilibrium_state(scene: Scene, acceleration=(0.0, 0.0, 0.0), p=None,
                      solve_attitude: bool = True, placement: str = "gravity") -> np.ndarray:
    """A state at rest (or in steady translation) with every foot on the obstacle.

    Each foot is placed where its unloaded position meets the obstacle, moving
    along gravity (``placement='gravity'``, as a foot lands) or to the nearest
    surface point (``'nearest'``), and held there; the body's position and (with
    ``solve_attitude``) a small rotation of its attitude are solved by Newton's
    method so that the leg forces balance the body: ΣP_j = −m(g − a) and
    Σρ_j × P_j = 0. With ``acceleration`` the body's steady acceleration (no
    rotation), this is the state of a steadily sliding body.

    Returns
    -------
    ndarray, shape (nx,)
        Velocities zero, contact flags 1, stored forces the exact P_j.
    """
    b = scene.body
    R0 = _rot_np(b.attitude)
    a = np.asarray(acceleration, dtype=float)
    if placement not in ("gravity", "nearest"):
        raise ValueError(f"`placement` must be 'gravity' or 'nearest', got {placement!r}.")
    pts = []
    down = scene.gravity / np.linalg.norm(scene.gravity)
    for leg in scene.legs:
        free = b.position + R0 @ leg.rest_foot
        if placement == "gravity":
            pts.append(_drop_point(scene.obstacles, free, down))
        else:
            _, _, proj = closest_obstacle(scene.obstacles, ca.DM(free))
            pts.append(np.asarray(ca.evalf(proj)).ravel())
    names, offsets = _leg_params(scene)
    p = _default_p(scene) if p is None else np.asarray(p, dtype=float)
    z = ca.SX.sym("z", 6 if solve_attitude else 3)
    x = z[0:3]
    q = ca.DM(b.attitude)
    if solve_attitude:
        q = quat_mul(q, quat_exp(z[3:6]))
    R = quat_to_rot(q)
    total = ca.DM.zeros(3)
    torque = ca.DM.zeros(3)
    for j, (leg, pt) in enumerate(zip(scene.legs, pts)):
        rho = R.T @ (ca.DM(pt) - x)
        P = leg.functions()["strut_force"](rho, ca.DM.zeros(3), p[offsets[j][0]:offsets[j][1]])
        total = total + R @ P
        torque = torque + ca.cross(rho, P)
    residual = total + b.mass * (ca.DM(scene.gravity) - ca.DM(a))
    if solve_attitude:
        residual = ca.vertcat(residual, torque)
    solver = ca.rootfinder("equilibrium", "newton", ca.Function("res", [z], [residual]),
                           {"abstol": 1e-10, "max_iter": 200})
    guess = np.concatenate([b.position, np.zeros(3)]) if solve_attitude else b.position
    sol = np.asarray(solver(guess), dtype=float).ravel()
    pos = sol[0:3]
    quat = np.asarray(ca.evalf(ca.substitute(q, z, ca.DM(sol))), dtype=float).ravel()
    R = _rot_np(quat)
    state = [pos, np.zeros(3), quat, np.zeros(3)]
    for j, (leg, pt) in enumerate(zip(scene.legs, pts)):
        rho = R.T @ (pt - pos)
        P = np.asarray(leg.functions()["strut_force"](rho, np.zeros(3),
                       p[offsets[j][0]:offsets[j][1]])).ravel()
        state += [pt, [1.0], P]
    return np.concatenate([np.ravel(s) for s in state])


def _body_stiffness(model: StepModel) -> ca.Function:
    """``body_stiffness(x, p) -> K``: 6×6 stiffness of the body pose (world frame).

    K = −∂(ΣF_j, Στ_j)/∂(Δx, Δθ) at Δ = 0: the legs' force and moment on the
    body when it is displaced by Δx and turned by the small world rotation Δθ
    with every foot held where it is — a foot in contact at its stored point,
    a free foot at its unloaded position (as if it touched down there now, so
    that the estimate also covers the next touchdown). D_p enters by AD.
    """
    if model._body_stiffness is None:
        scene = model.scene
        _, offsets = _leg_params(scene)
        X = ca.SX.sym("x", model.nx)
        p = ca.SX.sym("p", model.np)
        z = ca.SX.sym("z", 6)
        pos, R = X[0:3], quat_to_rot(X[6:10])
        R_z = quat_to_rot(quat_exp(z[3:6])) @ R
        pos_z = pos + z[0:3]
        wrench = ca.SX.zeros(6)
        for j, leg in enumerate(scene.legs):
            foot = X[BODY_STATE + LEG_STATE * j: BODY_STATE + LEG_STATE * (j + 1)]
            held = ca.if_else(foot[3] > 0.5, foot[0:3], pos + R @ ca.DM(leg.rest_foot))
            rho = R_z.T @ (held - pos_z)
            P = leg.functions()["strut_force"](rho, ca.DM.zeros(3),
                                               p[offsets[j][0]:offsets[j][1]])
            wrench = wrench + ca.vertcat(R_z @ P, R_z @ ca.cross(rho, P))
        K = ca.substitute(-ca.jacobian(wrench, z), z, ca.DM.zeros(6))
        model._body_stiffness = ca.Function("body_stiffness", [X, p], [K], ["x", "p"], ["K"])
    return model._body_stiffness


def stable_dt(model: StepModel, x, p=None) -> float:
    """Explicit stability limit 2/ω_max of the body update at state ``x`` (s).

    ω_max² is the largest |eigenvalue| of M⁻¹K, with M = diag(m I, R I_b Rᵀ)
    the body's mass matrix and K its pose stiffness against feet held fixed
    (:func:`_body_stiffness`). Velocity Verlet on ẍ = −ω²x is stable for
    ω Δt < 2; a sliding foot is softer than a held one, so the estimate is
    conservative in slip. Returns ``inf`` when no leg resists (K = 0).

    Parameters
    ----------
    model : StepModel
    x : array_like, shape (nx,)
    p : array_like, optional
        Leg parameters; default the scene's values.
    """
    x = np.asarray(x, dtype=float).ravel()
    if x.shape != (model.nx,):
        raise ValueError(f"`x` must have shape ({model.nx},), got {x.shape}.")
    p = _default_p(model.scene) if p is None else np.asarray(p, dtype=float)
    K = np.asarray(_body_stiffness(model)(x, p), dtype=float)
    R = _rot_np(x[6:10] / np.linalg.norm(x[6:10]))
    body = model.scene.body
    M_inv = np.zeros((6, 6))
    M_inv[:3, :3] = np.eye(3) / body.mass
    M_inv[3:, 3:] = R @ np.linalg.inv(body.inertia) @ R.T
    omega2 = float(np.max(np.abs(np.linalg.eigvals(M_inv @ K))))
    if not np.isfinite(omega2):
        raise FloatingPointError(f"the body stiffness at this state is not finite: {K!r}.")
    return np.inf if omega2 == 0 else 2.0 / np.sqrt(omega2)


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


def simulate(scene: Scene, *, model: StepModel | None = None, x0=None, p=None,
             adaptive: bool = False, eps: float = STEP_CRITERION_EPS,
             stability: bool | float = False, progress: bool = False) -> Trajectory:
    """Simulate a scene.

    Parameters
    ----------
    scene : Scene
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


def _default_p(scene):
    vals = [leg.param_values for leg in scene.legs]
    return np.concatenate(vals) if vals else np.zeros(0)


def _normals(model, y):
    N = model.n_legs
    legs_y = np.asarray(y, float).ravel()[BODY_OUT:].reshape(N, LEG_OUT)
    return legs_y[:, 0] > 0.5, legs_y[:, 5:8]


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
