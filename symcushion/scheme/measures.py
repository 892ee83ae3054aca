"""What a touchdown is judged by: the named Function ``touchdown_measures``.

This module owns the quantities that the reproduction, the envelope, the
optimiser, the peers' comparisons and the studies read from one step of
``touchdown_step``: the specific force on the body, the legs' strokes and
hinge angles, the tilt of the body axis, the upward speed, the contact flags
and the feet's penetration of the obstacle. They are computed once here, as
one CasADi Function of ``(x, y, p)``, and read by name.

It must not integrate, keep running extrema or apply limits: callers fold,
map or classify these per-step values themselves. It reads the vectors only
through :mod:`symcushion.layout.vectors`.
"""
from __future__ import annotations

import math

import casadi as ca

from symcushion.layout.vectors import footpads, output_layout, param_layout, state_layout
from symcushion.scheme.quaternion import one_minus_cos_tilt, quat_to_rot
from symcushion.model.obstacles import closest_obstacle

__all__ = ["MEASURES", "measures_function", "support_edges", "tip_surplus"]

#: Outputs of ``touchdown_measures`` and their meaning (N = number of legs).
MEASURES = {
    "specific_force": "(3,) m/s², a − g, world: the legs' force over the mass "
                      "(what an accelerometer on the body reads)",
    "stroke": "(N,) m, axial stroke δ_S of every leg",
    "beta": "(N,) rad, hinge azimuth β of every leg",
    "gamma_deflection": "(N,) rad, polar deflection γ − γ₀ of every leg",
    "one_minus_cos_tilt": "(1,) 1 − cos of the angle of the body z axis from the "
                          "vertical −g/|g| (world z without gravity; smooth at zero tilt)",
    "upward_speed": "(1,) m/s, velocity of the centre of mass along −g/|g|",
    "contact": "(N,) 1 for a foot in contact at the end of the step",
    "penetration": "(N,) m, depth of each foot below the obstacle surface (≥ 0; a footpad's "
                   "below the surface offset by its radius)",
    "tip_surplus": "(E,) m, per edge of the support polygon (E = N for N ≥ 3 legs, else 0): "
                   "the body's energy in the rotation about that edge less the energy that "
                   "lifts the centre of mass over it, in metres of lift (≥ 0: enough to tip "
                   "over that edge; docs/optimise.md, \"Tip-over energy\")",
}


def measures_function(scene) -> ca.Function:
    """``touchdown_measures(x, y, p) -> (specific_force, stroke, ...)`` of a scene.

    Parameters
    ----------
    scene : Scene
        Gives the number of legs, the obstacles and the layout of ``p``.

    Returns
    -------
    casadi.Function
        Inputs ``x`` (state after a step, nx), ``y`` (that step's output,
        ny), ``p`` (the step's parameters, np); outputs named as in
        :data:`MEASURES`. Built in SX; ``map`` it over the columns of a
        rollout's ``X, Y``.
    """
    n_legs = len(scene.legs)
    xl, yl, pl = state_layout(n_legs), output_layout(n_legs), param_layout(scene)
    x = ca.SX.sym("x", xl.size)
    y = ca.SX.sym("y", yl.size)
    p = ca.SX.sym("p", pl.size)
    g = pl.get(p, "gravity")
    g_norm = ca.norm_2(g)
    # without gravity (a drop in free space) "up" is the world z axis
    up = ca.if_else(g_norm > 0, -g / ca.if_else(g_norm > 0, g_norm, 1.0), ca.DM([0, 0, 1]))
    specific_force = yl.get(y, "acceleration") - g
    tilt = one_minus_cos_tilt(xl.get(x, "attitude"), up)
    v_up = ca.dot(up, xl.get(x, "velocity"))
    depth = []
    pads = footpads(scene, pl, p)
    for j in range(n_legs):
        d, _, _ = closest_obstacle(scene.obstacles, xl.get(x, "foot", j), pads[j])
        depth.append(ca.fmax(-d, 0.0))

    def legs(field):
        return ca.vertcat(*yl.legs(y, field)) if n_legs else ca.SX(0, 1)

    feet = [xl.get(x, "foot", j) for j in range(n_legs)]
    surplus = tip_surplus(xl, x, pl.get(p, "mass"), pl.inertia(p), g, feet,
                          support_edges(scene))
    outputs = [specific_force, legs("stroke"), legs("beta"), legs("gamma_deflection"), tilt,
               v_up, legs("in_contact"), ca.vertcat(*depth) if n_legs else ca.SX(0, 1),
               surplus]
    return ca.Function("touchdown_measures", [x, y, p], outputs, ["x", "y", "p"],
                       list(MEASURES))


def support_edges(scene) -> list:
    """Edges (j, k) of the support polygon: the legs in the order of their azimuth.

    The polygon of the feet of N ≥ 3 legs, taken around the body axis in the
    order of each leg's hinge (or a tripod's primary joint) azimuth in body
    axes, so that consecutive legs make an edge. A lander with fewer than
    three legs has no polygon and no edges.
    """
    legs = scene.legs
    if len(legs) < 3:
        return []
    azimuth = [math.atan2(leg.hinge[1], leg.hinge[0]) for leg in legs]
    order = sorted(range(len(legs)), key=lambda j: azimuth[j])
    return [(order[i], order[(i + 1) % len(order)]) for i in range(len(order))]


def tip_surplus(xl, x, mass, inertia, g, feet, edges):
    """Tip-over energy surplus about each support edge, in m of lift (CasADi, (len(edges), 1)).

    For the edge through feet a and b (u the unit vector from a to b), let d
    be the perpendicular from the edge to the centre of mass c (r = |d|) and
    ẑ = −g/|g| the vertical. The body pivoting on the edge has the moment of
    inertia I_e = m r² + uᵀ R I Rᵀ u about it and the angular momentum
    L_e = u·(d × m v + R I ω). Turning about the edge, the centre of mass
    rises at most to r·s above it, s = √(1 − (u·ẑ)²); it is d·ẑ above it now.
    The surplus

        L_e²/(2 I_e m |g|) [while that rotation lifts c]  −  (r s − d·ẑ)

    is the height the body's energy in that rotation could lift its centre
    of mass beyond the point above the edge: below 0 it cannot pass over the
    edge, at 0 and above it can. This is the energy criterion of landing
    stability; the pivot legs' strokes take energy out, so it errs on the
    safe side. The kinetic term counts only while the rotation lifts c; it
    is C¹ in the state except where c is right above the edge (surplus ≥ 0
    there anyway).
    """
    if not edges:
        return ca.SX(0, 1)
    c = xl.get(x, "position")
    v = xl.get(x, "velocity")
    R = quat_to_rot(xl.get(x, "attitude"))
    omega = R @ xl.get(x, "angular_velocity")
    I_w = R @ inertia @ R.T
    g_norm = ca.norm_2(g)
    z = -g / ca.if_else(g_norm > 0, g_norm, 1.0)
    weight = mass * ca.if_else(g_norm > 0, g_norm, 1.0)
    out = []
    for a, b in edges:
        edge = feet[b] - feet[a]
        u = edge / ca.norm_2(edge)
        rel = c - feet[a]
        d = rel - ca.dot(rel, u) * u
        r2 = ca.dot(d, d)
        I_e = mass * r2 + ca.dot(u, I_w @ u)
        L_e = ca.dot(u, mass * ca.cross(d, v) + I_w @ omega)
        rising = L_e * ca.dot(ca.cross(u, d), z) > 0
        lift = ca.if_else(rising, L_e ** 2 / (2 * I_e * weight), 0.0)
        top = ca.sqrt(r2 * (1 - ca.dot(u, z) ** 2))
        out.append(lift - (top - ca.dot(d, z)))
    return ca.vertcat(*out)
