"""One envelope case: its initial state, its parameters and its CasADi Function.

Owns the slope frame (initial states and gravity of each case), the case's
step parameters ``p`` (μ and gravity per case) and ``envelope_case``: the
scene's ``touchdown_step`` folded over the duration with the running extrema
of :data:`SUMMARY` taken from ``touchdown_measures``, and the rule that stops
a case once its class is decided (:func:`study_stop`). It must not re-derive
the step's physics, compile, or classify.
"""
from __future__ import annotations

import math

import casadi as ca
import numpy as np

from symcushion.layout.vectors import output_layout, state_layout
from symcushion.layout.params import default_p, param_layout
from symcushion.scheme.quaternion import quat_from_axis_angle_np, quat_mul_np, quat_to_rot_np
from symcushion.scheme.measures import measures_function
from symcushion.model.scene_data import Body, Scene
from symcushion.scheme.touchdown import StepModel
from symcushion.envelope.study import EnvelopeStudy, sample_conditions

__all__ = ["SUMMARY", "STOP", "NO_STOP", "stop_vector", "study_stop", "DECEL_FILTER_TIME",
           "initial_states", "case_scene", "reach", "apply_design", "envelope_function",
           "case_params"]

#: Running extrema per case, the rows of ``envelope_case``'s ``summary``:
#: max |δ_S| over legs with an axial element (m), max |β| and max |γ − γ₀|
#: (rad), peak specific force |a − g| (m/s², what an accelerometer on the body
#: reads) low-pass filtered with :data:`DECEL_FILTER_TIME` and raw, max of
#: 1 − cos(tilt) against the true vertical, 1 once a foot has touched, the time of the first contact (s, −1 if none), max upward speed
#: after the first contact (m/s, ≥ 0), time with no foot on the ground after
#: the first contact (s), lowest height of the centre of mass above the ground (m),
#: the time the case ran until its class was decided (s; the duration if never).
SUMMARY = ("max_stroke", "max_beta", "max_gamma", "peak_decel", "peak_decel_raw",
           "max_one_minus_cos_tilt", "touched", "first_contact_time", "rebound_speed",
           "airborne_time", "min_height", "end_time")
_S = {name: i for i, name in enumerate(SUMMARY)}
#: The entries of ``envelope_case``'s input ``stop`` (:func:`stop_vector`).
STOP = ("one_minus_cos_tilt", "rest_speed", "rest_time")
#: Axis of the slope frame's ground normal: the ground is its plane z = 0, so the
#: body's height above the ground is its z coordinate.
_NORMAL_AXIS = 2
#: Time constant of the first-order low-pass filter on the specific force
#: whose peak is checked against ``limits.deceleration`` (s), like the filter
#: classes of crash-test accelerometry: a crushable absorber re-engages its
#: loading branch for single steps while the lander settles (the switch on the
#: sign of x·ẋ, docs/envelope.md), one-step spikes of up to 50 m/s² that carry
#: almost no impulse; 10 ms (a 16 Hz corner) passes the impact pulse (≥ 50 ms)
#: and damps a 2-ms spike about fivefold. The raw peak is kept as ``peak_decel_raw``.
DECEL_FILTER_TIME = 0.01


def initial_states(study: EnvelopeStudy, conditions: dict) -> tuple:
    """Initial states and gravity vectors of the cases, in the slope frame.

    The slope frame has the ground as its plane z = 0 and its x axis along
    the fall line; the world frame has z up and the same fall line. A world
    vector w becomes R_y(−θ) w for slope θ, so gravity is
    |g|·(sin θ, 0, −cos θ) and the true vertical (−sin θ, 0, cos θ).
    In the world frame the body has attitude q = q_tilt ⊗ q_yaw ⊗ q_scene and
    velocity (v_h cos ψ, v_h sin ψ, −v_v) for heading ψ; its position puts
    the lowest unloaded foot ``study.clearance`` above the ground. Feet are
    free, angular velocity is the scene's.

    Returns
    -------
    x0 : ndarray, shape (nx, n)
    gravity : ndarray, shape (3, n)
        Gravity in the slope frame (m/s²).
    """
    scene = study.scene
    c = conditions
    n = len(c["vertical_speed"])
    g = float(np.linalg.norm(scene.gravity))
    theta = np.radians(c["slope_deg"])
    psi = np.radians(c["heading_deg"])
    yaw = np.radians(c["yaw_deg"])
    tilt = np.radians(c["tilt_deg"])
    azim = np.radians(c["tilt_azimuth_deg"])
    zeros, ones = np.zeros(n), np.ones(n)

    v_world = np.column_stack([c["horizontal_speed"] * np.cos(psi),
                               c["horizontal_speed"] * np.sin(psi), -c["vertical_speed"]])
    q_base = np.tile(scene.body.attitude, (n, 1))
    q_yaw = quat_from_axis_angle_np(np.column_stack([zeros, zeros, ones]), yaw)
    q_tilt = quat_from_axis_angle_np(np.column_stack([-np.sin(azim), np.cos(azim), zeros]), tilt)
    q_world = quat_mul_np(q_tilt, quat_mul_np(q_yaw, q_base))
    q_slope = quat_from_axis_angle_np(np.column_stack([zeros, ones, zeros]), -theta)   # R_y(−θ)
    q = quat_mul_np(q_slope, q_world)
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    R_slope = quat_to_rot_np(q_slope, normalise=False)
    vel = np.einsum("nij,nj->ni", R_slope, v_world)
    gravity = g * np.column_stack([np.sin(theta), zeros, -np.cos(theta)])

    R = quat_to_rot_np(q, normalise=False)
    rest = np.array([leg.rest_foot for leg in scene.legs])                 # (legs, 3)
    feet_rel = np.einsum("nij,lj->nli", R, rest)                          # (n, legs, 3)
    ground = float(scene.obstacles[0].point[2])
    height = ground + study.clearance - feet_rel[:, :, 2].min(axis=1)
    pos = np.column_stack([zeros, zeros, height])
    omega = np.tile(scene.body.angular_velocity, (n, 1))
    legs = range(len(scene.legs))
    x0 = state_layout(len(scene.legs)).pack_columns(
        n, position=pos.T, velocity=vel.T, attitude=q.T, angular_velocity=omega.T,
        foot=[(pos + feet_rel[:, j]).T for j in legs], contact=[zeros for _ in legs],
        force_body=[np.zeros((3, n)) for _ in legs])
    return np.ascontiguousarray(x0), np.ascontiguousarray(gravity.T)


def case_scene(study: EnvelopeStudy, case: int) -> Scene:
    """Touchdown ``case`` of the study as a scene of its own, in the slope frame.

    The body starts where :func:`initial_states` puts it, gravity is the
    case's (tilted by its slope) and μ the case's, so that simulating the
    scene runs the case the envelope ran (``symcushion simulate STUDY
    --case N``). The scene is named ``<study>_case<N>``.
    """
    if isinstance(case, bool) or not isinstance(case, (int, np.integer)):
        raise TypeError(f"`case` must be an integer, got {case!r}.")
    if not 0 <= case < study.n:
        raise ValueError(f"`case` = {case} is not a touchdown of {study.name!r}, which samples "
                         f"{study.n:,} (cases 0 to {study.n - 1}); give one of those.")
    conditions = {k: v[case:case + 1] for k, v in sample_conditions(study).items()}
    x0, gravity = initial_states(study, conditions)
    state = state_layout(len(study.scene.legs)).unpack(x0[:, 0])
    b = study.scene.body
    body = Body(mass=b.mass, inertia=b.inertia, position=state["position"],
                attitude=state["attitude"], velocity=state["velocity"],
                angular_velocity=state["angular_velocity"])
    return study.scene.with_(body=body, gravity=gravity[:, 0], mu=float(conditions["mu"][0]),
                             name=f"{study.name}_case{case}")


def reach(scene: Scene) -> float:
    """Largest distance of a foot at rest from the centre of mass (m), 0 without legs:
    the lever arm of the at-rest check (``limits.rest_speed``)."""
    return max((float(np.linalg.norm(leg.rest_foot)) for leg in scene.legs), default=0.0)


def envelope_function(model: StepModel, steps: int | None = None) -> ca.Function:
    """``envelope_case(x0, p, dt, stop) -> (x_end, summary)``: one whole touchdown.

    The scene's ``touchdown_step`` rolled out by ``fold``, with the case's
    gravity (slope frame) and μ in its parameter vector ``p``. The running
    extrema of :data:`SUMMARY`, taken from ``touchdown_measures``
    (:mod:`symcushion.scheme.measures`), are carried as extra states, and ``fold``
    keeps only the final state, so one case returns nx + len(SUMMARY) numbers.

    A case stops stepping once its class is decided (:data:`STOP`): from then on
    each step of the fold is a branch that copies the state, so a decided case
    costs nothing more. ``stop`` = (1 − cos of the tilt at which it stops, the
    rest speed and the rest time of :func:`stop_vector`); ``NO_STOP`` runs every
    case for the whole duration.

    Parameters
    ----------
    model : StepModel
        From ``build_model(scene)`` (the SX step; it is inlined).
    steps : int, optional
        Steps per case; default ``scene.steps``.
    """
    scene = model.scene
    steps = scene.steps if steps is None else int(steps)
    nx, ns = model.nx, len(SUMMARY)
    step = _envelope_step(model, reach(scene))
    x0 = ca.MX.sym("x0", nx)
    pm = ca.MX.sym("p", model.np)
    hm = ca.MX.sym("dt")
    stop = ca.MX.sym("stop", len(STOP))
    s0 = [0.0] * ns
    xl = state_layout(model.n_legs)
    s0[_S["min_height"]] = xl.get(x0, "position")[_NORMAL_AXIS]
    xs = ca.MX.sym("xs", step.size1_in(0))
    decided = ca.logic_or(xs[nx + _S["max_one_minus_cos_tilt"]] > stop[0],
                          xs[-1] >= stop[2])
    # short-circuit: a decided case's step is a copy, not a step whose result is dropped
    xs1 = ca.if_else(decided, xs, step(xs, pm, hm, stop[1]), True)
    held = ca.Function("envelope_held_step", [xs, pm, hm, stop], [xs1],
                       ["xs", "p", "dt", "stop"], ["xs_next"])
    xs_end = held.fold(steps)(ca.vertcat(x0, *s0, ca.MX.zeros(4)), pm, hm, stop)
    summary = xs_end[nx:nx + ns]
    # cases that never touch: first contact time −1 instead of the whole duration
    summary = ca.vertcat(summary[:_S["first_contact_time"]],
                         ca.if_else(summary[_S["touched"]] > 0.5,
                                    summary[_S["first_contact_time"]], -1),
                         summary[_S["first_contact_time"] + 1:])
    return ca.Function("envelope_case", [x0, pm, hm, stop], [xs_end[:nx], summary],
                       ["x0", "p", "dt", "stop"], ["x_end", "summary"])


def _envelope_step(model: StepModel, reach_m: float) -> ca.Function:
    """``envelope_step(xs, p, dt, rest_speed) -> xs_next``: one step of a case.

    ``xs`` is the state, the running extrema of :data:`SUMMARY`, the low-pass
    filtered specific force (3) and the time the case has been at rest: its
    body's motion |v| + |ω|·reach below ``rest_speed`` on every step since."""
    scene = model.scene
    nx, ns = model.nx, len(SUMMARY)
    xl = state_layout(model.n_legs)
    x = ca.SX.sym("x", nx)
    s = ca.SX.sym("s", ns)
    a_f = ca.SX.sym("a_filtered", 3)                    # low-pass filtered specific force
    rest = ca.SX.sym("rest_time")
    p = ca.SX.sym("p", model.np)
    h = ca.SX.sym("dt")
    rest_speed = ca.SX.sym("rest_speed")

    x1, y = model.step(x, p, h)
    m = measures_function(scene).call(dict(x=x1, y=y, p=p))
    axial = [j for j, leg in enumerate(scene.legs) if not leg.rigid]
    contact_any = ca.mmax(m["contact"]) if model.n_legs else 0
    stroke = ca.mmax(ca.fabs(m["stroke"][axial])) if axial else 0
    beta = ca.mmax(ca.fabs(m["beta"])) if model.n_legs else 0
    gamma = ca.mmax(ca.fabs(m["gamma_deflection"])) if model.n_legs else 0
    specific_force = m["specific_force"]
    # first-order low-pass, exact for a force held over the step (any dt)
    a_f1 = a_f + (1 - ca.exp(-h / DECEL_FILTER_TIME)) * (specific_force - a_f)
    touched_before = s[_S["touched"]]
    touched = ca.fmax(touched_before, contact_any)
    # the step index is not in the state: the first contact time is accumulated as
    # "time elapsed while untouched", which equals it once contact has happened
    first_time = ca.if_else(touched_before < 0.5, s[_S["first_contact_time"]] + h,
                            s[_S["first_contact_time"]])
    airborne = ca.if_else(ca.logic_and(touched > 0.5, contact_any < 0.5),
                          s[_S["airborne_time"]] + h, s[_S["airborne_time"]])
    rebound = ca.if_else(touched > 0.5, ca.fmax(s[_S["rebound_speed"]], m["upward_speed"]),
                         s[_S["rebound_speed"]])
    height = xl.get(x1, "position")[_NORMAL_AXIS]
    motion = ca.norm_2(xl.get(x1, "velocity")) + ca.norm_2(xl.get(x1, "angular_velocity")) * reach_m
    # at rest: slower than rest_speed, no foot slipping (a creeping foot is not at rest,
    # however slowly it slides) and standing on at least three feet (on two a lander
    # slows to nothing at the top of a rock about them, and then falls either way)
    modes = output_layout(model.n_legs).legs(y, "mode")
    slipping = ca.mmax(ca.vertcat(*[mode == 2 for mode in modes])) if modes else 0
    standing = ca.sum1(m["contact"]) >= min(3, model.n_legs) - 0.5 if model.n_legs else 0
    still = ca.logic_and(ca.logic_and(standing, motion < rest_speed), slipping < 0.5)
    rest1 = ca.if_else(still, rest + h, 0)
    s1 = ca.vertcat(ca.fmax(s[_S["max_stroke"]], stroke), ca.fmax(s[_S["max_beta"]], beta),
                    ca.fmax(s[_S["max_gamma"]], gamma),
                    ca.fmax(s[_S["peak_decel"]], ca.norm_2(a_f1)),
                    ca.fmax(s[_S["peak_decel_raw"]], ca.norm_2(specific_force)),
                    ca.fmax(s[_S["max_one_minus_cos_tilt"]], m["one_minus_cos_tilt"]), touched,
                    first_time, rebound, airborne, ca.fmin(s[_S["min_height"]], height),
                    s[_S["end_time"]] + h)
    xs, xs1 = ca.vertcat(x, s, a_f, rest), ca.vertcat(x1, s1, a_f1, rest1)
    return ca.Function("envelope_step", [xs, p, h, rest_speed], [xs1],
                       ["xs", "p", "dt", "rest_speed"], ["xs_next"])


def stop_vector(tilt_deg: float | None, rest_speed: float | None, rest_time: float | None):
    """``stop`` of ``envelope_case``: a case stops once its tilt passes ``tilt_deg``
    (tip-over outranks every other class, so its class cannot change) or once it
    has been at rest, moving slower than ``rest_speed``, for ``rest_time`` (s).
    None leaves that stop out."""
    one_minus_cos = math.inf if tilt_deg is None else 1 - math.cos(math.radians(tilt_deg))
    if rest_speed is None or rest_time is None:
        rest_speed, rest_time = 0.0, math.inf
    return np.array([one_minus_cos, float(rest_speed), float(rest_time)])


#: ``stop`` that runs every case for the whole duration.
NO_STOP = stop_vector(None, None, None)
#: A case is at rest once it has moved slower than this share of
#: ``limits.rest_speed`` (on at least three feet, none slipping) for
#: :data:`STOP_REST_TIME`: well inside the at-rest check, so the check at the
#: end of the duration would pass too.
STOP_REST_SHARE = 0.4
#: Rest speed of the stop when the study has no at-rest check (m/s).
STOP_REST_SPEED = 0.02
#: Time a case must stay at rest before it stops (s): 50 steps at 1 ms.
STOP_REST_TIME = 0.05


def study_stop(study: EnvelopeStudy) -> np.ndarray:
    """``stop`` of a study's cases (:func:`stop_vector`): at its tip-over limit, and
    at rest (:data:`STOP_REST_SHARE`, :data:`STOP_REST_TIME`); :data:`NO_STOP`
    when ``study.stop`` is False. Why these keep every class: docs/envelope.md,
    "Stopping decided cases"."""
    if not study.stop:
        return NO_STOP
    rest = study.limits.rest_speed
    rest = STOP_REST_SPEED if rest is None else STOP_REST_SHARE * rest
    return stop_vector(study.limits.tilt_deg, rest, STOP_REST_TIME)


def apply_design(scene: Scene, p: np.ndarray, design: dict | None) -> np.ndarray:
    """``p`` (np, n) with the legs' tunable curve parameters set from ``design``.

    ``design`` maps parameter names to values: ``"S.f0"`` sets that entry of
    every leg, ``"leg2.S.f0"`` of one leg (the names of
    ``param_layout(scene).names``). The curves must be marked
    ``tunable = true`` in the scene, which makes their parameters inputs of the
    compiled case Function instead of constants.
    """
    if not design:
        return p
    names = param_layout(scene).names
    p = np.array(p, dtype=float, copy=True)
    for key, value in design.items():
        rows = [i for i, n in enumerate(names) if n == key or
                (n.startswith("leg") and n.split(".", 1)[1] == key)]
        if not rows:
            tunable = sorted({n.split(".", 1)[1] for n in names if n.startswith("leg")})
            raise ValueError(f"`design` names {key!r}, which is not a tunable parameter of the "
                             f"scene; tunable: {tunable} (mark a curve `tunable = true`).")
        value = float(value)
        if not np.isfinite(value):
            raise ValueError(f"`design[{key!r}]` must be finite, got {value!r}.")
        p[rows] = value
    return p


def case_params(scene: Scene, mu: np.ndarray, gravity: np.ndarray) -> np.ndarray:
    """Step parameters of each case (np, n): the scene's, with the cases' μ and gravity.

    Parameters
    ----------
    scene : Scene
        The compiled scene; a frictionless one (μ = 0) has no μ entry, and
        then every case's μ must be 0.
    mu : array_like, shape (n,)
    gravity : array_like, shape (3, n)
        Gravity in the slope frame (m/s²).
    """
    params = param_layout(scene)
    mu = np.asarray(mu, dtype=float)
    gravity = np.asarray(gravity, dtype=float)
    p = np.tile(default_p(scene)[:, None], (1, gravity.shape[1]))
    p[params.slice("gravity")] = gravity
    if params.friction:
        p[params.slice("mu")] = mu
    elif np.any(mu != 0):
        raise ValueError(f"`mu` has values up to {np.max(mu)!r} but the scene is frictionless "
                         "(μ = 0 builds no friction paths); build it with μ > 0.")
    return p
