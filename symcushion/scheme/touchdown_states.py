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

__all__ = ["initial_state", "equilibrium_state"]


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
    fns, p_legs, rest, pads = _legs_at(scene, p)
    for rest_j, pad in zip(rest, pads):
        free = b.position + R0 @ rest_j
        if placement == "gravity":
            pts.append(_drop_point(scene.obstacles, free, down, pad=pad))
        else:
            _, _, proj = closest_obstacle(scene.obstacles, ca.DM(free), pad)
            pts.append(np.asarray(ca.evalf(proj)).ravel())
    z = ca.SX.sym("z", 6 if solve_attitude else 3)
    x = z[0:3]
    q = ca.DM(b.attitude)
    if solve_attitude:
        q = quat_mul(q, quat_exp(z[3:6]))
    R = quat_to_rot(q)
    rho = [R.T @ (ca.DM(pt) - x) for pt in pts]
    P = [fns[j]["strut_force"](rho_j, ca.DM.zeros(3), p_legs[j]) for j, rho_j in enumerate(rho)]
    # the legs' force in world axes, their torque in body axes
    total, torque = legs_wrench(rho, P, R)[0], legs_wrench(rho, P)[1]
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
    forces = []
    for j, (leg, pt) in enumerate(zip(scene.legs, pts)):
        rho = R.T @ (pt - pos)
        forces.append(np.asarray(fns[j]["strut_force"](rho, np.zeros(3), p_legs[j])).ravel())
    return state_layout(len(scene.legs)).pack(
        position=pos, velocity=np.zeros(3), attitude=quat, angular_velocity=np.zeros(3),
        foot=pts, contact=[1.0] * len(pts), force_body=forces)

