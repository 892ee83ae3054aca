"""The crush-onset kick: the trapezoid rule's missed impulse at the bends of an axial law.

This module owns :func:`crush_kick`, the correction that
``symcushion.scheme.foot_step.FeetStep`` adds to the kick of a foot on the
memory law (docs/absorbers.md, "Located touchdown and lift-off") for the
bends of its axial element's force inside a step: the crush onset, where the
elastic line (A1), (A5) meets the loading curve, and a bend of the loading
curve it crushes along; and :data:`TANGENT_INSET`, where the loading curve's
tangents are taken. It must not run the contact step, move the body or
change the force law: it integrates the law it is given.
"""
from __future__ import annotations

import casadi as ca

__all__ = ["TANGENT_INSET", "crush_kick"]

#: Where the loading curve's tangents of :func:`crush_kick` are taken: this
#: fraction of the step inside it, at x₀ + ι(x₁ − x₀) and x₁ − ι(x₁ − x₀),
#: so each is the one-sided slope towards the other end. At the ends
#: themselves a bend of the loading curve exactly there has two slopes, and
#: which one AD returns is decided by rounding: every touchdown starts at
#: x₀ = 0, where an element's loading and unloading curves meet and the lower
#: bound lo = min(loading, unloading) of (A1) bends. Its slope there came out
#: as the loading curve's (10⁶ N/m on the example lander) or the unloading
#: curve's (3.8·10³ N/m) by the last bit of lo(0), which every knot value
#: moves, so a touchdown's kick jumped by 0.28 N·s (277 N over the 1-ms step)
#: when a design moved the knot at 5 cm, beyond that step's stroke, by 5e-7 of
#: its scale. A bend closer to an end than ι of the step is taken as at the
#: end: its share of the kick, θ(1 − θ)|k₀ − k₁||x₁ − x₀|/2 per unit h, is
#: then below 5e-7 × 10⁶ N/m × 3 mm ≈ 1.5e-3 N (1.5e-6 N·s per 1-ms step) on
#: that lander.
TANGENT_INSET = 1e-6


def crush_kick(feet, leg, at: dict):
    """The kick's correction (N, body axes of the end, times h) for the bends of the
    axial element's force law inside the step: the crush onset, where its elastic
    line meets its loading curve, and a bend of the loading curve it crushes along
    (docs/absorbers.md, "Located touchdown and lift-off").

    Along a step the stroke x runs from x₀ to x₁ (x = x₀ + τ(x₁ − x₀), τ ∈ [0, 1])
    with the set s₀ of the start held until the force reaches a bound, so the force
    follows (A1) at s₀: g(τ) = max(E(τ), ℓ(τ)). E is the element's elastic line
    through s₀ (A1), (A5): slope k_e from the element's force at the start (its
    own slope, so that a bend moving from one step into the next is seen alike
    from both sides); ℓ the loading curve, its tangents just inside x₀ and x₁
    (:data:`TANGENT_INSET`) meeting at θ_K (the chord where they do not meet inside the step). A step that starts on the loading
    curve follows ℓ (E leaves it inwards), one that reloads elastically from a kept
    set follows E to where it meets ℓ. The trapezoid rule's impulse h(g(0) +
    g(1))/2 misses ∫g − (g(0) + g(1))/2 (per unit h): θ(1 − θ)(k₀ − k₁)(x₁ − x₀)/2
    at one bend of slopes k₀, k₁ at θ, O(h²) once but with the honeycomb's k·v in
    it (7e-3 m/s at Δt = 1 ms on the tutorial's 33 kg leg share), and changing
    with where the bend falls in the step. g is piecewise linear with its bends
    among θ_K and the meeting points of E with the tangents and the chord, so the
    trapezoid rule over those points is its exact integral; the kick is
    continuous in the stroke, the set and the curve parameters, including
    where E meets ℓ at the step's start (a crush that goes on).

    E starts at the element's force in the foot's stored force F₀
    (``strut_band_force``), which is the loading curve's where the crush goes on,
    so that no bend is seen there; a foot that touches down inside the step starts,
    as F* of ``FeetStep.event_kick``, on the elastic line with the end rate. Where the
    foot touched down, the part in contact h_c takes the kick.
    """
    fns, p_leg = leg.fns, leg.p_leg
    touching, h_c = at["span"]
    h = feet.poses.h
    x0 = fns["strut_deflections"](at["rho_s"], p_leg)[0]
    x1 = fns["strut_deflections"](at["rho1"], p_leg)[0]
    s0, s1 = leg.sets[0], at["sets_end"][0]
    dx = x1 - x0
    # the loading curve: its values at x₀ and x₁, and its tangents there taken just
    # inside the step (TANGENT_INSET), which meet at θ_K
    f0, f1 = fns["strut_crush_curve"](x0, p_leg)[0], fns["strut_crush_curve"](x1, p_leg)[0]
    k0 = fns["strut_crush_curve"](x0 + TANGENT_INSET * dx, p_leg)[1]
    k1 = fns["strut_crush_curve"](x1 - TANGENT_INSET * dx, p_leg)[1]
    dk = k0 - k1
    bends = ca.logic_and(ca.fabs(dk) > 0, ca.fabs(dx) > 0)
    theta_k = (f1 - f0 - k1 * dx) / ca.if_else(bends, dk * dx, 1.0)
    inside = ca.logic_and(ca.logic_and(bends, theta_k > 0), theta_k < 1)

    def loading(tau):
        """ℓ(τ): the tangent at x₀ up to θ_K, then the one at x₁; else the chord."""
        bent = ca.if_else(tau < theta_k, f0 + k0 * dx * tau, f1 + k1 * dx * (tau - 1))
        return ca.if_else(inside, bent, f0 + (f1 - f0) * tau)

    # the elastic line through the start set (A1), (A5); a touching foot's starts with
    # the step's own end rate (A3), as F* does; the orifice's rate at the start (it
    # acts in parallel and is taken out of the start force) from the mean rates
    a, b = feet.damper_rate(leg, at["rho_s"], at["span"])
    rate1 = a * x1 + b[0]
    h_part = ca.if_else(touching, h_c, h)
    rate0 = (leg.chords[0] + ((x1 - s1) - (x0 - s0)) / h_part) / 2
    # at the start the force the foot carried (on the loading curve where the crush
    # goes on, exactly: E leaves it inwards); a foot that touches down, F*'s
    line0, k_e = fns["strut_elastic_line"](x0, s0, rate1, p_leg)
    e0 = ca.if_else(touching, line0,
                    fns["strut_band_force"](at["rho_s"], leg.foot["force_body"], rate0,
                                            p_leg))
    # E: slope k_e (A1), the element's own, so that a bend that moves from one step
    # into the next is seen alike from both sides
    e1 = e0 + k_e * dx

    def force(tau):
        return ca.fmax(e0 + (e1 - e0) * tau, loading(tau))        # (A1) at s₀

    def meets(c0, c1):
        """Where E meets the line from c0 (τ = 0) to c1 (τ = 1), in [0, 1]."""
        den = (e1 - e0) - (c1 - c0)
        tau = (c0 - e0) / ca.if_else(den != 0, den, 1.0)
        return ca.fmin(ca.fmax(ca.if_else(den != 0, tau, 0.0), 0.0), 1.0)

    points = [ca.if_else(inside, theta_k, 0.0), meets(f0, f0 + k0 * dx),
              meets(f1 - k1 * dx, f1), meets(f0, f1)]
    # sorted (a network of min/max), then the trapezoid rule over g's bends
    for i, j in ((0, 1), (2, 3), (0, 2), (1, 3), (1, 2)):
        points[i], points[j] = ca.fmin(points[i], points[j]), ca.fmax(points[i], points[j])
    taus = [ca.DM(0.0)] + points + [ca.DM(1.0)]
    values = [force(t) for t in taus]
    integral = sum((taus[i + 1] - taus[i]) * (values[i] + values[i + 1]) / 2
                   for i in range(len(taus) - 1))
    missed = integral - (values[0] + values[-1]) / 2
    held = ca.logic_and(at["stays"], ca.logic_or(leg.foot["contact"] > 0.5, touching))
    share = h_part / h
    e_S = fns["strut_geometry"].call(dict(r=at["rho1"]))["e_S"]
    return ca.if_else(held, share * missed, 0.0) * e_S
