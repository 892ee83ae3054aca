"""The states of a scene's touchdown step: its initial state and its states at rest.

This module owns :func:`initial_state` (the scene's initial conditions, all
feet free, at the rest poses of a step's leg geometry) and
:func:`equilibrium_state` (every foot on the obstacle, the legs' wrench
balancing the body, solved by Newton), and the check of the legs' geometry
entries of a ``p`` that both they and ``StepModel.check_params`` apply. It
reads the vectors only through :mod:`symcushion.layout.vectors`.

It must not build or run the step (``symcushion.scheme.touchdown``,
``symcushion.run.driver``).
"""
from __future__ import annotations

import casadi as ca
import numpy as np

from symcushion.scheme.body_step import legs_wrench
from symcushion.layout.vectors import ParamLayout, default_p, footpads, param_layout, state_layout
from symcushion.model.obstacles import closest_obstacle
from symcushion.scheme.quaternion import quat_exp, quat_mul, quat_to_rot, quat_to_rot_np
from symcushion.model.scene import Scene
from symcushion.validation import real

__all__ = ["initial_state", "equilibrium_state", "CONE_SLACK"]

#: Relative slack of the friction-cone test of a held foot: a force on the cone
#: to round-off (|P_τ| = μN(1 + ε)) is inside.
CONE_SLACK = 1e-9


def check_geometry_entries(scene: Scene, lay: ParamLayout, p) -> None:
    """The legs' geometry blocks and footpads of a 1-D ``p`` with geometry entries."""
    for j, leg in enumerate(scene.legs):
        leg.check_geometry_block(lay.leg_geometry(p, j), where=f"`p` of leg {j}: ")
    if lay.footpads:
        for j in range(len(scene.legs)):
            real(f"leg{j}.footpad", float(lay.footpad(p, j)), nonnegative=True, unit="m")



def initial_state(scene: Scene, p=None) -> np.ndarray:
    """State vector of the scene's initial conditions, all feet free; with ``p`` (a
    step's parameters) the feet at the rest poses of its leg geometry."""
    b = scene.body
    R = _rot_np(b.attitude)
    n = len(scene.legs)
    _, _, rest, _ = _legs_at(scene, p)
    return state_layout(n).pack(
        position=b.position, velocity=b.velocity, attitude=b.attitude,
        angular_velocity=b.angular_velocity,
        foot=[b.position + R @ r for r in rest], contact=[0.0] * n,
        force_body=[np.zeros(3)] * n)


def _legs_at(scene: Scene, p=None):
    """(Functions, p, rest foot, footpad) of every leg for a step's ``p``: with its
    geometry block when ``p`` has one, else (and for None) the scene's own geometry."""
    with_geometry = param_layout(scene, True)
    if p is None:
        p = default_p(scene, geometry=False)
    p = np.asarray(p, dtype=float).ravel()
    lay = with_geometry if p.size == with_geometry.size else param_layout(scene, False)
    if p.size != lay.size:
        raise ValueError(f"`p` must have {with_geometry.size} entries {with_geometry.names} "
                         f"(or {lay.size} without the legs' geometry), got {p.size}.")
    mode = "input" if lay.geometry else "constant"
    fns = [leg.functions(mode) for leg in scene.legs]
    p_legs = [lay.leg_inputs(p, j) for j in range(len(scene.legs))]
    if lay.geometry:
        check_geometry_entries(scene, lay, p)
        rest = [np.asarray(ca.evalf(leg.rest_foot_expr(ca.DM(p_leg))), dtype=float).ravel()
                for leg, p_leg in zip(scene.legs, p_legs)]
    else:
        rest = [leg.rest_foot for leg in scene.legs]
    return fns, p_legs, rest, [float(a) for a in footpads(scene, lay, p)]


def _rot_np(q):
    """Rotation matrix of the quaternion ``q`` as given (not renormalised)."""
    return quat_to_rot_np(q, normalise=False)


def _drop_point(obstacles, free, direction, iterations=20, pad=0.0):
    """Where the line free + s·direction first meets the obstacle (its offset surface
    at distance ``pad``), by Newton in s."""
    point = ca.DM(free)
    for _ in range(iterations):
        d, n, _ = closest_obstacle(obstacles, point, pad)
        slope = float(ca.evalf(ca.dot(n, ca.DM(direction))))
        if abs(slope) < 1e-9:
            raise ValueError("cannot drop a foot onto the obstacle: the drop direction is "
                             "tangent to it; use placement='nearest'.")
        point = point - float(ca.evalf(d)) / slope * ca.DM(direction)
    return np.asarray(point, dtype=float).ravel()


def equilibrium_state(scene: Scene, acceleration=(0.0, 0.0, 0.0), p=None,
                      solve_attitude: bool = True, placement: str = "gravity",
                      cone: bool = True) -> np.ndarray:
    """A state at rest (or in steady translation) with every foot on the obstacle and
    every foot force inside the friction cone (1.4).

    Each foot is placed where its unloaded position meets the obstacle, moving
    along gravity (``placement='gravity'``, as a foot lands) or to the nearest
    surface point (``'nearest'``); the body's position and (with
    ``solve_attitude``) a small rotation of its attitude are solved by Newton's
    method so that the leg forces balance the body: ΣP_j = −m(g − a) and
    Σρ_j × P_j = 0. A foot whose force would lie outside the cone |P_τ| ≤ μN
    slides on the obstacle, the way the leg pushes it, to where its force is on
    the cone, as a massless foot does at once on touching (the slides are solved
    with the pose, and feet are added to them until every force is inside). With
    ``acceleration`` the body's steady acceleration (no rotation), this is the state
    of a steadily sliding body: its feet slide too, and keep where they land.
    ``cone=False`` holds every foot where it lands, whatever its force (a start
    whose feet slip at t = 0⁺ by a finite amount).

    Returns
    -------
    ndarray, shape (nx,)
        Velocities zero, contact flags 1, stored forces the exact P_j.

    Raises
    ------
    ValueError
        When no such state exists (legs that splay further as their feet slide
        out, with no bending stiffness to stop them).
    """
    a = np.asarray(acceleration, dtype=float)
    if placement not in ("gravity", "nearest"):
        raise ValueError(f"`placement` must be 'gravity' or 'nearest', got {placement!r}.")
    fns, p_legs, rest, pads = _legs_at(scene, p)
    pts = _landing_points(scene, rest, pads, placement)
    mu = _friction(scene, p)
    slides = {}
    steady = bool(np.any(a)) or not cone
    for _ in range(len(pts) + 1):
        pos, quat, feet, forces = _balance(scene, fns, p_legs, pads, pts, slides, a,
                                           solve_attitude)
        outside = {} if steady else _outside_cone(scene, feet, forces, quat, pads, mu, slides)
        if not outside:
            break
        slides.update(outside)
    else:  # pragma: no cover - every foot slides after len(pts) rounds
        raise ValueError("no state at rest with every foot force inside the friction cone.")
    return state_layout(len(scene.legs)).pack(
        position=pos, velocity=np.zeros(3), attitude=quat, angular_velocity=np.zeros(3),
        foot=feet, contact=[1.0] * len(feet), force_body=forces)


def _landing_points(scene: Scene, rest, pads, placement: str) -> list:
    """Where each foot meets the obstacle: along gravity from its unloaded position, or
    the nearest surface point."""
    b = scene.body
    R0 = _rot_np(b.attitude)
    down = scene.gravity / np.linalg.norm(scene.gravity)
    pts = []
    for rest_j, pad in zip(rest, pads):
        free = b.position + R0 @ rest_j
        if placement == "gravity":
            pts.append(_drop_point(scene.obstacles, free, down, pad=pad))
        else:
            _, _, proj = closest_obstacle(scene.obstacles, ca.DM(free), pad)
            pts.append(np.asarray(ca.evalf(proj)).ravel())
    return pts


def _friction(scene: Scene, p) -> float:
    """μ of the scene, or of ``p`` where it has an entry."""
    if p is None or scene.mu == 0:
        return float(scene.mu)
    p = np.asarray(p, dtype=float).ravel()
    lay = param_layout(scene, p.size == param_layout(scene, True).size)
    return float(lay.get(p, "mu"))


def _balance(scene, fns, p_legs, pads, pts, slides, a, solve_attitude):
    """Newton on the pose (and on each sliding foot's slide s_j, its force on the cone
    (1.4)): the legs' wrench balancing the body. Returns position, attitude, the feet
    (world) and their forces (body axes)."""
    b = scene.body
    n_pose = 6 if solve_attitude else 3
    z = ca.SX.sym("z", n_pose + len(slides))
    q = ca.DM(b.attitude)
    if solve_attitude:
        q = quat_mul(q, quat_exp(z[3:6]))
    R = quat_to_rot(q)
    feet = [ca.DM(pt) for pt in pts]
    for k, (j, (u, mu)) in enumerate(slides.items()):
        _, _, feet[j] = closest_obstacle(scene.obstacles, feet[j] + z[n_pose + k] * ca.DM(u),
                                         pads[j])
    rho = [R.T @ (foot - z[0:3]) for foot in feet]
    P = [fns[j]["strut_force"](rho_j, ca.DM.zeros(3), p_legs[j]) for j, rho_j in enumerate(rho)]
    # the legs' force in world axes, their torque in body axes
    total, torque = legs_wrench(rho, P, R)[0], legs_wrench(rho, P)[1]
    residual = [total + b.mass * (ca.DM(scene.gravity) - ca.DM(a))]
    if solve_attitude:
        residual.append(torque)
    for j, (u, mu) in slides.items():
        _, normal, _ = closest_obstacle(scene.obstacles, feet[j], pads[j])
        F = R @ P[j]
        N = ca.dot(normal, F)
        residual.append(ca.norm_2(F - N * normal) - mu * N)        # on the cone (1.4)
    solver = ca.rootfinder("equilibrium", "newton",
                           ca.Function("res", [z], [ca.vertcat(*residual)]),
                           {"abstol": 1e-10, "max_iter": 200, "error_on_fail": True})
    guess = np.concatenate([b.position, np.zeros(n_pose - 3), np.zeros(len(slides))])
    try:
        sol = np.asarray(solver(guess), dtype=float).ravel()
    except RuntimeError:
        raise ValueError(f"no state at rest with the feet of legs {sorted(slides)} sliding to "
                         "their friction cones: the legs splay further as the feet slide "
                         "out. Give the legs bending stiffness (M_beta), raise mu, start from "
                         "initial_state, or hold the feet where they land with cone=False.") from None
    out = ca.Function("at", [z], [q, ca.horzcat(*feet), ca.horzcat(*P)])(sol)
    quat = np.asarray(out[0], dtype=float).ravel()
    feet_w = [np.asarray(out[1][:, j], dtype=float).ravel() for j in range(len(pts))]
    forces = [np.asarray(out[2][:, j], dtype=float).ravel() for j in range(len(pts))]
    return sol[0:3], quat, feet_w, forces


def _outside_cone(scene, feet, forces, quat, pads, mu, slides) -> dict:
    """{leg: (slide direction, μ)} of the feet not sliding yet whose force lies outside
    the cone |P_τ| ≤ μN (1.4); a foot slides against its friction, along −P_τ."""
    R = _rot_np(quat)
    out = {}
    for j, (foot, force) in enumerate(zip(feet, forces)):
        if j in slides:
            continue
        _, normal, _ = closest_obstacle(scene.obstacles, ca.DM(foot), pads[j])
        n = np.asarray(normal, dtype=float).ravel()
        F = R @ force
        N = float(n @ F)
        tangential = F - N * n
        size = float(np.linalg.norm(tangential))
        if size > mu * N * (1 + CONE_SLACK) and size > 0:
            out[j] = (-tangential / size, mu)
    return out
