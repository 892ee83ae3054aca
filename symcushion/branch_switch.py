"""The absorber's branch switch inside a step: a located, time-weighted kick.

A crushable axial element follows P = P(δ_S, sign δ_S′) (2.1): its force
jumps from the loading to the unloading curve when the stroke rate changes
sign, and back when the leg is compressed again. The velocity-Verlet body
step integrates the leg force by the trapezoid rule over each step,
h/2·(F_n + F_{n+1}), with each node force on the branch of the step that
computed it. Across a switch that puts the force jump in the middle of the
step whatever the switch time t* = t_n + θh: an impulse error h(θ − ½)ΔF,
O(h) once per switch, first order overall.

This module owns the correction, a scene option (``Scene.events =
"branch"``): in the step whose node force changes branch, the kick is the
time-weighted mean of the two branches' forces at the located switch,

    h[θ F_n + (1 − θ) F_{n+1}] = h/2·(F_n + F_{n+1}) + h(θ − ½)(F_n − F_{n+1}),   (B1)

and likewise for the moments ρ × F. θ is the zero of the switching function
s(t) = e_S·ρ̇ (the stroke rate of the world point under the foot, the rate
that selects the branch in the touchdown step), interpolated linearly
through its exact value at the start of the step, s₀ = e_S·(−ω × ρ − Rᵀv),
and its value at the middle, the chord l/h of the step projected on the
strut axis at the middle foot point ρ + l/2 (exact to O(h²)):
θ = s₀ / (2(s₀ − s_½)). The node forces switch branch between the middle
of the previous step and the middle of this one, so θ lies in [−½, ½]; a
negative θ returns the part of the jump the previous step's kick missed.
With θ right to O(h) the impulse is right to O(h²), a local error made
once per switch: second order. The drift of the switching step keeps the
start force (its error is O(h²) once per switch).

The node force F_n's branch is read from the force itself (the branch whose
axial force at the foot is nearer to F_n·e_S), so no state is added.
Only the axial element's switch is located; a leg whose axial curve has no
unloading branch, or a smooth one (no jump), gets nothing, and the step is
then the velocity-Verlet step unchanged.

This module must not change the contact step, the drift or the forces; it
returns the kick's correction only.
"""
from __future__ import annotations

import casadi as ca

from .contact_guards import at_least, at_most
from .stroke_lock import axial_branches

__all__ = ["locates_switch", "branch_flip", "branch_switch_kick"]

#: Smallest |2(s₀ − s_½)| (m/s) that θ divides by: a stroke rate that does
#: not change over the step has no zero in it, and the quotient is clipped
#: to [−½, ½] anyway; the floor only keeps the division finite (and its
#: derivative) where the branches of the node forces differ all the same.
RATE_FLOOR = 1e-12


def locates_switch(leg) -> bool:
    """True if the leg's axial curve has a non-smooth unloading branch (a force jump)."""
    axial = [el.curve for el in leg.elements if el.name == "S"]
    return bool(axial) and axial[0].unloading is not None and not axial[0].smooth


def _axial_loading(delta_S, rate):
    """1 where the axial element is on its loading branch (x·ẋ ≥ 0, as the curve tests)."""
    return ca.if_else(delta_S * rate >= 0, 1.0, 0.0)


def branch_flip(strut_fns, p_leg, rho0, F0, l, h, stored_loading=None):
    """1 where this step's end force is on the other axial branch than the stored force.

    The end force's branch is the touchdown step's own test on the chord
    l/h; the stored force's is ``stored_loading`` where the state keeps it
    (``events = "lock"``), else the curve whose axial force at ``rho0`` is
    nearer to F0·e_S. Returns the flag and ``axial_branches`` at ``rho0``,
    with ``stored_loading`` and ``new_loading`` (1 on the loading curve).
    """
    ax = axial_branches(strut_fns, p_leg, rho0)
    e_S = ax["e_S"]
    new_loading = _axial_loading(ax["delta_S"], ca.dot(e_S, l / h))
    if stored_loading is None:
        S0 = ca.dot(F0, e_S)
        stored_loading = ca.if_else(ca.fabs(S0 - ax["S_load"]) <= ca.fabs(S0 - ax["S_unload"]),
                                    1.0, 0.0)
    return (new_loading != stored_loading,
            dict(ax, stored_loading=stored_loading, new_loading=new_loading))


def branch_switch_kick(strut_fns, p_leg, foot, step):
    """Correction (B1) of one leg's kick for a branch switch inside the step.

    Parameters
    ----------
    strut_fns : dict of casadi.Function
        The leg's ``strut_force`` and ``strut_geometry``
        (``HingedStrut.functions``).
    p_leg : casadi.SX, shape (n_p,)
        The leg's curve parameters.
    foot : dict
        ``rho0`` (3, m, body frame, start of the step), ``F0`` (3, N, body
        frame, the stored force of the first half kick), ``rho1`` and ``F1``
        (the same at the end), ``active`` (1 where the foot was in contact at
        the start and stays in contact at the end), optionally
        ``stored_loading`` (1 where the stored force is on the loading curve,
        when the state keeps the branch; else it is read from the force).
    step : dict
        ``h`` (s), ``R`` and ``R1`` (3×3, attitude at start and end), ``v``
        (3, m/s, world) and ``omega`` (3, rad/s, body) at the start, ``l``
        (3, m, body: the displacement of the plane's point over the step,
        §3).

    Returns
    -------
    dforce : casadi.SX, shape (3,)
        (θ − ½)(R F0 − R1 F1) (N, world): the second half kick of the
        velocity gains h·dforce/m.
    dtorque : casadi.SX, shape (3,)
        (θ − ½)(ρ0 × F0 − ρ1 × F1) (N·m, body frame): the angular velocity
        gains h·I⁻¹·dtorque.
    theta : casadi.SX
        The located switch time (t* − t_n)/h where a switch is flagged, else ½.
    """
    rho0, F0 = foot["rho0"], foot["F0"]
    h, l = step["h"], step["l"]
    flip, ax = branch_flip(strut_fns, p_leg, rho0, F0, l, h, foot.get("stored_loading"))
    e_S = ax["e_S"]
    switched = ca.logic_and(foot["active"], flip)
    # the zero of s(t) through s₀ (exact) and s_½ (chord at the middle foot point)
    s0 = ca.dot(e_S, -ca.cross(step["omega"], rho0) - step["R"].T @ step["v"])
    e_mid = strut_fns["strut_geometry"].call(dict(r=rho0 + l / 2))["e_S"]
    s_half = ca.dot(e_mid, l / h)
    gap = 2 * (s0 - s_half)
    safe = ca.if_else(ca.fabs(gap) > RATE_FLOOR, gap, RATE_FLOOR)
    theta = at_most(at_least(s0 / safe, -0.5), 0.5)
    weight = ca.if_else(switched, theta - 0.5, 0.0)                         # (B1)
    dforce = weight * (step["R"] @ F0 - step["R1"] @ foot["F1"])
    dtorque = weight * (ca.cross(rho0, F0) - ca.cross(foot["rho1"], foot["F1"]))
    return dforce, dtorque, ca.if_else(switched, theta, 0.5)
