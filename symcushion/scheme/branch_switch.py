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
That θ is the stroke lock's (``events = "lock"``), for its direct switches;
with ``events = "branch"`` every located switch takes θ of (B2) below.
With θ right to O(h) the impulse is right to O(h²), a local error made
once per switch: second order. The drift of the switching step keeps the
start force (its error is O(h²) once per switch).

The node force F_n's branch is read from the force itself (the branch whose
axial force at the foot is nearer to F_n·e_S), so no state is added.
Only the axial element's switch is located; a leg whose axial curve has no
unloading branch, or a smooth one (no jump), gets nothing, and the step is
then the velocity-Verlet step unchanged.

With ``events = "branch"`` the touchdown step also splits the CONTACT step
of a leg at its switch. (B1) puts the impulse right, but a foot that
slides while its force drops (the slope lander: the force of an uphill
leg falls from 2.7 kN to 0.56 kN as its foot slides) then jumps, being
massless, to its equilibrium on the new curve: where it lands depends on
where it started, so one contact step over the whole of Δt puts it O(Δt)
wrong, and that error stays in the foot's position. The split step runs
the contact step on the stored curve up to t* (the body at its drift
position there), the jump at t* with the body held (l = 0), and the rest of
the step on the new curve from where the foot landed. θ is then located
inside the step, θ ∈ [0, 1] (:func:`switch_in_step`):

    θ = s₀ / (s₀ − s₁),   s₁ = 2 s_½ − s₀,                          (B2)

s₀ as above and s_½ the switching function at the middle of the step, at
the middle of the foot's path on the stored curve (a contact step over the
whole step on that curve) with the drift's middle velocities, which are
exact to O(Δt²) in velocity Verlet. s follows the sliding foot: with the
foot held at its start point instead, θ is off by a fixed fraction of the
step (1 % on the slope lander), an O(Δt) error in t*. The step splits when
the branch of s₁ differs from the stored one, and (B1) then uses θ of
(B2).

This module must not change the contact step, the drift or the forces; it
returns the kick's correction and the switch's location only.
"""
from __future__ import annotations

import casadi as ca

from symcushion.legs.curve_base import ZERO_DEFLECTION
from symcushion.contact.guards import at_least, at_most
from symcushion.scheme.stroke_lock import axial_branches, stroke_rate

__all__ = ["locates_switch", "stored_branch", "switch_in_step", "branch_flip",
           "branch_switch_kick"]

#: Smallest |2(s₀ − s_½)| and |s₀ − s₁| (m/s) that θ divides by, its sign kept:
#: a stroke rate that does not change over the step has no zero in it, and the
#: quotient is clipped to [−½, ½] (B1) or [0, 1] (B2) anyway; the floor only
#: keeps the division finite (and its derivative) where the branches of the
#: node forces differ all the same.
RATE_FLOOR = 1e-12


def locates_switch(leg) -> bool:
    """True if the leg's axial curve has a non-smooth unloading branch (a force jump)."""
    axial = [el.curve for el in leg.elements if el.name == "S"]
    return bool(axial) and axial[0].unloading is not None and not axial[0].smooth


def _axial_loading(delta_S, rate):
    """1 where the axial element is on its loading branch (x·ẋ ≥ 0, as the curve tests)."""
    return ca.if_else(delta_S * rate >= 0, 1.0, 0.0)


def stored_branch(strut_fns, p_leg, rho, F):
    """1 where the force ``F`` (body frame) is on the loading curve at ``rho``: the
    curve whose axial force is nearer to F·e_S."""
    ax = axial_branches(strut_fns, p_leg, rho)
    S = ca.dot(F, ax["e_S"])
    return ca.if_else(ca.fabs(S - ax["S_load"]) <= ca.fabs(S - ax["S_unload"]), 1.0, 0.0)


def _floored(gap):
    """``gap`` with its magnitude at least :data:`RATE_FLOOR`, its sign kept."""
    return ca.if_else(ca.fabs(gap) > RATE_FLOOR, gap,
                      ca.if_else(gap >= 0, RATE_FLOOR, -RATE_FLOOR))


def _rate_at(strut_fns, rho, kin):
    """The switching function s = e_S·ρ̇ of the world point under the foot ``rho``,
    with the body's ``R``, ``v`` (world) and ``omega`` (body) of ``kin``: the rate
    whose sign selects the branch in (2.1)."""
    e_S = strut_fns["strut_geometry"].call(dict(r=rho))["e_S"]
    return stroke_rate(rho, e_S, kin["v"], kin["omega"], kin["R"])        # (2.1)


def switch_in_step(strut_fns, rho0, rho_mid, stored_loading, start, mid):
    """Whether the axial element switches branch inside the step, and when (B2).

    Parameters
    ----------
    strut_fns : dict of casadi.Function
        The leg's ``strut_geometry``.
    rho0, rho_mid : casadi.SX, shape (3,)
        The foot at the start of the step and in its middle (body frame, m).
    stored_loading : casadi.SX
        1 where the force at the start is on the loading curve.
    start, mid : dict
        The body's ``R`` (3×3), ``v`` (m/s, world) and ``omega`` (rad/s, body)
        at the start and in the middle of the step.

    Returns
    -------
    dict
        ``switches`` (1 where s₁ = 2 s_½ − s₀ selects the other curve than the
        stored one), ``theta`` ((t* − t_n)/h in [0, 1]), ``s0`` and ``s1`` (m/s).
    """
    s0 = _rate_at(strut_fns, rho0, start)
    s1 = 2 * _rate_at(strut_fns, rho_mid, mid) - s0
    delta_S = strut_fns["strut_geometry"].call(dict(r=rho0))["delta_S"]
    # the curves' own test x·ẋ ≥ 0, loading at zero deflection (characteristics)
    end_loading = ca.logic_or(ca.fabs(delta_S) <= ZERO_DEFLECTION, delta_S * s1 >= 0)
    theta = s0 / _floored(s0 - s1)                                          # (B2)
    return dict(switches=end_loading != stored_loading,
                theta=at_most(at_least(theta, 0.0), 1.0), s0=s0, s1=s1)


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
        stored_loading = stored_branch(strut_fns, p_leg, rho0, F0)
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
        when the state keeps the branch; else it is read from the force),
        optionally ``split`` (a dict with ``use`` and ``theta``: the contact
        step was split at the switch located by (B2); (B1) then takes that θ
        where ``use`` is set, and nothing elsewhere).
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
    if foot.get("split") is not None:
        # the contact step was split at the switch of (B2): its θ, in [0, 1]
        switched = ca.logic_and(foot["active"], foot["split"]["use"])
        theta = foot["split"]["theta"]
    else:
        flip, ax = branch_flip(strut_fns, p_leg, rho0, F0, l, h, foot.get("stored_loading"))
        switched = ca.logic_and(foot["active"], flip)
        # the zero of s(t) through s₀ (exact) and s_½ (chord at the middle foot point)
        s0 = _rate_at(strut_fns, rho0, dict(R=step["R"], v=step["v"], omega=step["omega"]))
        e_mid = strut_fns["strut_geometry"].call(dict(r=rho0 + l / 2))["e_S"]
        s_half = ca.dot(e_mid, l / h)
        theta = at_most(at_least(s0 / _floored(2 * (s0 - s_half)), -0.5), 0.5)
    weight = ca.if_else(switched, theta - 0.5, 0.0)                         # (B1)
    dforce = weight * (step["R"] @ F0 - step["R1"] @ foot["F1"])
    dtorque = weight * (ca.cross(rho0, F0) - ca.cross(foot["rho1"], foot["F1"]))
    return dforce, dtorque, ca.if_else(switched, theta, 0.5)
