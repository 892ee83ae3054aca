"""What a touchdown is judged by: the named Function ``touchdown_measures``.

This module owns the quantities that the reproduction, the envelope, the
optimiser, the peers' comparisons and the studies read from one step of
``touchdown_step``: the specific force on the body, the legs' strokes and
hinge angles, the tilt of the body axis, the upward speed, the contact flags
and the feet's penetration of the obstacle. They are computed once here, as
one CasADi Function of ``(x, y, p)``, and read by name.

It must not integrate, keep running extrema or apply limits: callers fold,
map or classify these per-step values themselves. It reads the vectors only
through :mod:`symcushion.layout`.
"""
from __future__ import annotations

import casadi as ca

from .layout import footpads, one_minus_cos_tilt, output_layout, param_layout, state_layout
from .obstacles import closest_obstacle

__all__ = ["MEASURES", "measures_function"]

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

    outputs = [specific_force, legs("stroke"), legs("beta"), legs("gamma_deflection"), tilt,
               v_up, legs("in_contact"), ca.vertcat(*depth) if n_legs else ca.SX(0, 1)]
    return ca.Function("touchdown_measures", [x, y, p], outputs, ["x", "y", "p"],
                       list(MEASURES))
