"""Penalty-contact peer: light feet on stiff spring-dampers, integrated by CVODES.

The usual alternative to a contact step. The body, its legs and their force
law are symcushion's own — the strut's CasADi expression P(ρ, ρ̇) of (2.1)
from ``symcushion.legs.strut``, with the same axial stiffness for 'rigid' rods
(``RIGID_AXIAL_RATIO``) — but each foot is given a small mass m_f and the
obstacle pushes it with a stiff normal spring-damper on the penetration
p = max(−d, 0) (d the signed distance of ``symcushion.model.obstacles``):

    F_n = max(k p + c ṗ, 0) n,  ṗ = −n·v_f                       (Kelvin–Voigt)
    F_t = −μ |F_n| v_t / sqrt(|v_t|² + v_s²)                   (regularised Coulomb)

The equations of motion (state: body position x, velocity v, quaternion q,
angular velocity ω in body axes; each foot's world position r_j and
velocity u_j) are one SX ODE,

    ẋ = v,  v̇ = g + R ΣP_j/m,  q̇ = ½ q ⊗ (0, ω),  ω̇ = I⁻¹(Σρ_j × P_j − ω × Iω),
    ṙ_j = u_j,  u̇_j = g + (F_c,j − R P_j)/m_f,

with ρ_j = Rᵀ(r_j − x) the foot in body axes and P_j = P(ρ_j, ρ̇_j) the
strut force (2.1) — the force on the foot from whatever holds it, so the
massless leg pushes the foot with −P_j and the body with +P_j at the moment
ρ_j × P_j, exactly as symcushion's massless foot does. The ODE is stiff
(contact and axial modes of the light foot at 10⁴ rad/s against a body
motion at 10 rad/s), so it is integrated by CVODES' BDF with a Newton
iteration on the exact Jacobian (``casadi.integrator``).

This module owns the penalty model and its integration. Argument checks,
the output record and the strut geometry used for stroke and deflection are
in ``symcushion.peers.run``.
"""
from __future__ import annotations

import time

import casadi as ca
import numpy as np

from symcushion.model.obstacles import ImplicitSurface, Plane, Sphere
from symcushion.model.scene_data import Scene
from symcushion.layout.vectors import BODY_STATE, BODY_STATE_FIELDS, state_layout
from symcushion.scheme.quaternion import quat_mul, quat_to_rot
from symcushion.layout.fields import Field, VectorLayout
from symcushion.peers.run import (PeerRun, check_scene, leg_kinematics, nonnegative, output_times,
    positive, quat_to_rot_np, state_vector)

__all__ = ["penalty_simulate", "build_penalty_ode", "default_stiffness", "FOOT_MASS_RATIO",
           "STATIC_PENETRATION", "LEG_STIFFNESS_RATIO",
           "DAMPING_RATIO", "SLIP_VELOCITY", "ATOL_LENGTH", "FOOT_STATE", "penalty_layout"]

#: Foot mass as a fraction of the body mass. Light enough that the feet carry
#: a negligible share of the momentum (four feet at 1e-4 add 0.04 % to the
#: mass of Figs. 3–4 and lose ½ m_f v² ≈ 1e-4 of the impact energy when they
#: stop on the obstacle), heavy enough that the stiffest foot mode stays near
#: ω ≈ 3·10⁴ rad/s, which BDF steps over at no cost once it is damped.
FOOT_MASS_RATIO = 1e-4

#: Default contact stiffness: the spring sinks by this much (m) under the
#: body's static weight shared equally by its legs, k = m·max(|g|, g₀)/(N·δ).
#: 0.1 mm is a thousandth of the rods' static swing in Figs. 3–4 (tens of
#: mm) and one mm of penetration at ten times the static load.
STATIC_PENETRATION = 1e-4

#: Contact stiffness over the stiffest rest stiffness of a leg (the largest
#: eigenvalue of D_p at rest, N/m). The contact spring sits in series with
#: the leg: at 100 it softens the leg's stiffest direction (the axial spring
#: of a 'rigid' rod, 3.3e6 N/m in Figs. 3–4) by 1 %. The weight rule alone
#: gives 1.2e6 N/m there, softer than the rod itself, and a rod landing along
#: its axis (a slope) then stays in contact twice as long as symcushion's.
LEG_STIFFNESS_RATIO = 100.0

#: Standard gravity (m/s²), the floor of |g| in the stiffness rule, so that a
#: scene without gravity still gets a stiff contact.
STANDARD_GRAVITY = 9.80665

#: Damping ratio ζ of a foot on its contact spring, c = 2ζ·sqrt(k·m_f).
#: Critical damping: the light foot lands without chattering (a foot that
#: bounces on a stiff spring forces thousands of tiny steps), and as the
#: body's motion is 10³ times slower than the foot mode, the dashpot sees
#: only the slow penetration rate during the stroke and dissipates almost
#: nothing of the body's energy.
DAMPING_RATIO = 1.0

#: Regularisation speed v_s of the Coulomb law (m/s): below it the friction
#: force falls linearly to zero, so a "sticking" foot creeps at
#: v_t ≈ v_s·|F_t|/(μ|F_n|). 0.1 mm/s creeps 0.1 mm per second of stick.
SLIP_VELOCITY = 1e-4

#: Length scale (m) of the absolute tolerance, atol = rtol·ATOL_LENGTH:
#: penetrations are ~1e-4 m, so positions must be resolved below that.
ATOL_LENGTH = 1e-3

#: State of one foot in the penalty model: world position (3), velocity (3).
FOOT_STATE = 6


def penalty_layout(n_legs: int) -> VectorLayout:
    """State of the penalty model: symcushion's body block, then per foot its world
    position and velocity (the feet have a small mass here)."""
    return VectorLayout(BODY_STATE_FIELDS, (
        Field("foot", "m", "foot position, world frame", ("x", "y", "z")),
        Field("foot_velocity", "m_s", "foot velocity, world frame", ("x", "y", "z"))),
        n_legs, "penalty state")


#: Largest number of CVODES steps between two output samples.
MAX_STEPS_PER_SAMPLE = 1000000


def _check_obstacles(scene: Scene):
    for i, ob in enumerate(scene.obstacles):
        if not isinstance(ob, (Plane, Sphere, ImplicitSurface)):
            raise ValueError(f"obstacle {i} of scene {scene.name!r} is a "
                             f"{type(ob).__name__}, which the penalty peer does not support; "
                             "use Plane, Sphere, ImplicitSurface or Terrain.")


def _check_legs(scene: Scene):
    for j, leg in enumerate(scene.legs):
        for el in leg.elements:
            if el.curve.unloading is not None and not el.curve.smooth:
                raise ValueError(
                    f"leg {j} `{el.name}` has an unloading branch switched exactly by the sign "
                    "of its rate: with a foot of mass that rate chatters about zero at every "
                    "stop and CVODES stalls (the right side of the ODE jumps). The penalty peer "
                    "supports hysteresis only with the smooth switch: build the curve with "
                    "smooth=True (TOML `smooth = true`), or drop `unloading`.")


def default_stiffness(scene: Scene) -> float:
    """Default contact stiffness (N/m): the larger of two rules.

    k = max(m·max(|g|, g₀)/(N·δ), r·max_j λ_max(D_p,j)), δ =
    :data:`STATIC_PENETRATION`, r = :data:`LEG_STIFFNESS_RATIO`, D_p,j the
    rest stiffness of leg j (its closed form, docs/paper-notes.md §2).
    """
    g = max(float(np.linalg.norm(scene.gravity)), STANDARD_GRAVITY)
    weight_rule = scene.body.mass * g / (len(scene.legs) * STATIC_PENETRATION)
    leg_rule = LEG_STIFFNESS_RATIO * max(
        float(np.max(np.linalg.eigvalsh(leg.rest_stiffness_closed_form()))) for leg in scene.legs)
    return max(weight_rule, leg_rule)


def build_penalty_ode(scene: Scene, *, stiffness: float, damping: float, slip_velocity: float,
                      foot_mass: float):
    """The penalty ODE of a scene as CasADi SX expressions.

    Returns
    -------
    dict
        ``x`` (SX state, 13 + 6N), ``ode`` (its derivative), and the Function
        ``penalty_outputs(x) -> (acceleration, penetration)``: the body's
        acceleration (3, world, m/s²) and each foot's deepest penetration
        (N, m; ≤ 0 when free).
    """
    legs, body = scene.legs, scene.body
    n_legs = len(legs)
    m = body.mass
    inertia = ca.DM(body.inertia)
    inertia_inv = ca.DM(np.linalg.inv(body.inertia))
    g = ca.DM(scene.gravity)
    mu = scene.mu

    xl = penalty_layout(n_legs)
    x = ca.SX.sym("x", xl.size)
    pos, vel, quat, omega = (xl.get(x, k) for k in ("position", "velocity", "attitude",
                                                     "angular_velocity"))
    R = quat_to_rot(quat / ca.norm_2(quat))

    force_body = ca.DM.zeros(3)
    torque_body = ca.DM.zeros(3)
    foot_rates, penetrations = [], []
    for j, leg in enumerate(legs):
        r_f, u_f = xl.get(x, "foot", j), xl.get(x, "foot_velocity", j)
        rho = R.T @ (r_f - pos)                                  # foot, body axes
        rho_dot = R.T @ (u_f - vel) - ca.cross(omega, rho)       # relative to the hinge
        P = leg.functions()["strut_force"](rho, rho_dot, ca.DM(leg.param_values))  # (2.1)
        force_body = force_body + P
        torque_body = torque_body + ca.cross(rho, P)

        contact = ca.DM.zeros(3)
        deepest = -ca.inf
        for ob in scene.obstacles:
            # a footpad's centre against the obstacle's offset surface (symcushion.model.obstacles)
            d = ob.distance(r_f, leg.footpad)
            n = ob.normal(r_f, leg.footpad)
            depth = ca.fmax(-d, 0.0)
            depth_rate = -ca.dot(n, u_f)
            F_n = ca.if_else(d < 0, ca.fmax(stiffness * depth + damping * depth_rate, 0.0), 0.0)
            contact = contact + F_n * n
            if mu > 0:
                v_t = u_f - ca.dot(n, u_f) * n
                contact = contact - mu * F_n * v_t / ca.sqrt(ca.dot(v_t, v_t)
                                                             + slip_velocity ** 2)
            deepest = ca.fmax(deepest, -d)
        foot_rates.append(ca.vertcat(u_f, g + (contact - R @ P) / foot_mass))
        penetrations.append(deepest)

    acc = g + R @ force_body / m
    omega_quat = ca.vertcat(0.0, omega)
    quat_dot = 0.5 * quat_mul(quat, omega_quat)
    omega_dot = inertia_inv @ (torque_body - ca.cross(omega, inertia @ omega))
    ode = ca.vertcat(vel, acc, quat_dot, omega_dot, *foot_rates)
    outputs = ca.Function("penalty_outputs", [x], [acc, ca.vertcat(*penetrations)], ["x"],
                          ["acceleration", "penetration"])
    return {"x": x, "ode": ode, "outputs": outputs}


def penalty_state(scene: Scene, x0=None) -> np.ndarray:
    """Initial state of the penalty model (13 + 6N).

    ``x0`` may be given in the penalty layout (13 + 6N: body, then each
    foot's world position and velocity) or in symcushion's layout
    (13 + 7N, e.g. :func:`symcushion.scheme.touchdown_states.initial_state` or
    ``equilibrium_state``): then each foot starts at the stored position,
    moving with the body, v + R(ω × ρ).
    """
    n_legs = len(scene.legs)
    sym_size = state_layout(n_legs).size
    own_size = penalty_layout(n_legs).size
    x0 = state_vector(scene, x0)
    if x0.size == own_size:
        return x0.copy()
    if x0.size != sym_size:
        raise ValueError(f"`x0` must have {own_size} entries (penalty layout: body "
                         f"{BODY_STATE} + {FOOT_STATE} per foot) or {sym_size} (symcushion's "
                         f"state, initial_state(scene)), got {x0.size}.")
    xl = state_layout(n_legs)
    body = x0[:xl.body_size].copy()
    pos, vel, omega = (xl.get(x0, k) for k in ("position", "velocity", "angular_velocity"))
    R = quat_to_rot_np(xl.get(x0, "attitude"))
    feet = []
    for j in range(n_legs):
        r = xl.get(x0, "foot", j)
        rho = R.T @ (r - pos)
        feet += [r, vel + R @ np.cross(omega, rho)]
    return np.concatenate([body, *feet])


def penalty_simulate(scene: Scene, *, rtol: float = 1e-8, atol: float | None = None,
                     stiffness: float | None = None, damping: float | None = None,
                     slip_velocity: float | None = None, foot_mass: float | None = None,
                     x0=None, output_dt: float | None = None) -> PeerRun:
    """Simulate a scene with penalty contact and light feet, integrated by CVODES (BDF).

    Parameters
    ----------
    scene : Scene
        Any legs symcushion accepts (the strut's own force law is used),
        except unloading branches switched exactly (``smooth=False``):
        ValueError. Plane, Sphere, ImplicitSurface and Terrain obstacles
        (a Terrain's B-spline is a call node in the ODE: ~40× slower).
    rtol : float
        CVODES relative tolerance.
    atol : float, optional
        CVODES absolute tolerance; default ``rtol·ATOL_LENGTH``.
    stiffness : float, optional
        Contact stiffness k (N/m); default :func:`default_stiffness`: at most
        δ = :data:`STATIC_PENETRATION` of sink under the static load and
        :data:`LEG_STIFFNESS_RATIO` times the stiffest leg direction.
    damping : float, optional
        Contact damping c (N·s/m); default 2ζ·sqrt(k·m_f) with ζ =
        :data:`DAMPING_RATIO` (critical for the foot on its spring).
    slip_velocity : float, optional
        v_s of the regularised Coulomb law (m/s); default :data:`SLIP_VELOCITY`.
    foot_mass : float, optional
        m_f of each foot (kg); default :data:`FOOT_MASS_RATIO`·m. The body
        keeps the scene's mass; the feet add N·m_f.
    x0 : array_like, optional
        Initial state, penalty layout (13 + 6N) or symcushion's (13 + 7N),
        see :func:`penalty_state`; default ``initial_state(scene)``.
    output_dt : float, optional
        Sample interval (s); default ``scene.dt``.

    Returns
    -------
    PeerRun
        ``info`` holds the settings and the CVODES statistics: ``steps``
        (nsteps), ``rhs_evaluations`` (nfevals), ``jacobian_evaluations``,
        ``error_test_failures``, ``newton_failures``, ``cpu_seconds`` (process
        CPU time of the integration) and the raw ``stats``.
    """
    scene = check_scene(scene)
    rtol = positive("rtol", rtol)
    if rtol >= 1e-2:
        raise ValueError(f"`rtol` = {rtol!r} is too loose for a stiff contact model; "
                         "give a value below 1e-2 (e.g. 1e-6 … 1e-10).")
    atol = positive("atol", atol, rtol * ATOL_LENGTH)
    _check_obstacles(scene)
    _check_legs(scene)
    m_f = positive("foot_mass", foot_mass, FOOT_MASS_RATIO * scene.body.mass)
    k = positive("stiffness", stiffness, default_stiffness(scene))
    c = nonnegative("damping", damping, 2 * DAMPING_RATIO * np.sqrt(k * m_f))
    v_s = positive("slip_velocity", slip_velocity, SLIP_VELOCITY)
    t = output_times(scene, output_dt)
    state0 = penalty_state(scene, x0)

    started = time.perf_counter()
    model = build_penalty_ode(scene, stiffness=k, damping=c, slip_velocity=v_s, foot_mass=m_f)
    dae = {"x": model["x"], "ode": model["ode"]}
    opts = {"abstol": atol, "reltol": rtol, "max_num_steps": MAX_STEPS_PER_SAMPLE}
    integrator = ca.integrator("penalty", "cvodes", dae, 0.0, t[1:], opts)
    build_seconds = time.perf_counter() - started

    started, cpu_started = time.perf_counter(), time.process_time()
    try:
        sol = integrator(x0=state0)
    except RuntimeError as exc:
        raise FloatingPointError(
            f"CVODES failed on scene {scene.name!r} (rtol={rtol:g}, atol={atol:g}, "
            f"stiffness={k:g}, foot_mass={m_f:g}): {exc}. Loosen `rtol`, soften `stiffness` "
            "or raise `foot_mass`.") from None
    wall_seconds = time.perf_counter() - started
    cpu_seconds = time.process_time() - cpu_started
    stats = integrator.stats()

    X = np.column_stack([state0, np.asarray(sol["xf"], dtype=float)]).T    # (T, nx)
    if not np.all(np.isfinite(X)):
        raise FloatingPointError(f"the penalty model of scene {scene.name!r} produced "
                                 "non-finite states; tighten `rtol` or soften `stiffness`.")
    n_legs = len(scene.legs)
    acc, depth = model["outputs"].map(len(t))(X.T)
    acc = np.asarray(acc, dtype=float).T
    depth = np.asarray(depth, dtype=float).T.reshape(len(t), n_legs)
    xl = penalty_layout(n_legs)
    Xc = X.T                                                    # columns are output times
    quat = xl.get(Xc, "attitude").T
    quat = quat / np.linalg.norm(quat, axis=1, keepdims=True)
    feet = np.moveaxis(xl.legs(Xc, "foot"), -1, 0)              # (T, legs, 3)
    stroke, deflection = leg_kinematics(scene, xl.get(Xc, "position").T, quat, feet)
    info = {
        "peer": "penalty", "integrator": "cvodes (BDF, Newton, dense direct)",
        "rtol": rtol, "atol": atol, "stiffness": k, "damping": c, "slip_velocity": v_s,
        "foot_mass": m_f, "output_dt": float(t[1] - t[0]) if len(t) > 1 else scene.dt,
        "steps": int(stats.get("nsteps", -1)), "rhs_evaluations": int(stats.get("nfevals", -1)),
        "jacobian_evaluations": int(stats.get("njevals", -1)) if "njevals" in stats else None,
        "error_test_failures": int(stats.get("netfails", -1)),
        "newton_failures": int(stats.get("ncfn", -1)),
        "max_penetration": float(np.max(depth)), "cpu_seconds": cpu_seconds,
        "stats": dict(stats),
        "foot_velocity": np.moveaxis(xl.legs(Xc, "foot_velocity"), -1, 0),
    }
    return PeerRun(t=t, position=xl.get(Xc, "position").T, velocity=xl.get(Xc, "velocity").T,
                   acceleration=acc, attitude=quat, foot=feet, stroke=stroke, deflection=deflection,
                   wall_seconds=wall_seconds, build_seconds=build_seconds, info=info,
                   contact=depth > 0)
