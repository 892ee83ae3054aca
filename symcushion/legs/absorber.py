"""Absorbers with memory: the elastic band between an element's curves.

The printed law of Khvostov (1976), P = P(δ, sign δ′) of (2.1), puts an
element on its loading curve while its deflection grows and on its
unloading curve while it shrinks, so the force jumps between the curves
whenever the rate changes sign. A real absorber does not jump: a crushed
honeycomb unloads elastically from where it stopped crushing, and reloads
elastically up to its crush force before it crushes further. This module
owns that law (``Scene.hysteresis = "memory"``, docs/absorbers.md):

    f(x, s) = clip(k_e (x − s), lo(x), hi(x))                        (A1)
    s⁺      = x − f(x, s)/k_e                                         (A2)

x the element's deflection (m or rad), s its *set* — the deflection at
which its elastic line carries no force, the one internal state the
element remembers — k_e the slope of the elastic line
(``Curve.elastic_stiffness``, by default the loading curve's slope at zero),
and [lo, hi] the band between the loading curve f_L and the unloading curve
f_U: lo = min(f_L, f_U), hi = max(f_L, f_U). A crushable element without an
unloading curve has lo = f_L and no upper bound: it crushes in compression
only and unloads along its elastic line, keeping its crushed stroke. The set
changes only where the force is on a bound (A2), so a stroke grows only at
the loading curve's force; the force is continuous in x and s; as k_e → ∞
the band's elastic line turns vertical and (A1) tends to the printed law
with the stroke held between the curves.

A free element (a foot in the air) rests where its force is zero,
x₀(s) = clip(s, min(z_L, z_U), max(z_L, z_U)), z the zeros of the curves:
the elastic line's zero s while the band holds zero force there, else the
zero of the bound that pushes it out (a spring-back curve).

Dampers in parallel with the element add c·ẋ + c₂·ẋ|ẋ| (viscous and
orifice, ``Curve.damping`` and ``Curve.orifice``). A massless foot's damper
force belongs to the end of the step; its rate there is taken by the
two-step backward difference (BDF2)

    ẋ₁ = (3/2)(x₁ − x₀)/Δt − (1/2) c₀,                              (A3)

c₀ the mean rate of the previous step ((x₀ − x₋₁)/Δt, kept in the state):
second order, and L-stable, so a stiff damper behind a massless foot
neither rings nor limits the step. (A3) is affine in x₁, so the contact
step sees the damper as the stiffness (3/2)c/Δt along the strut. A free
damped element relaxes towards x₀(s) instead of jumping there: its end
deflection solves

    f(x₁, s) + c ẋ₁ + c₂ ẋ₁|ẋ₁| = 0,   ẋ₁ of (A3).                    (A4)

On an element that keeps a set, the viscous damper acts on its elastic line
(a Kelvin–Voigt element in series with the crushing):

    f(x, s) = clip(k_e (x − s) + c ė, lo(x), hi(x)),                 (A5)

ė the rate of the elastic deflection x − s, whose (A3) over a step with s
held is that of x. Crushing stays rate-independent, as a honeycomb's is,
and the force never leaves the band. Where the force is on a bound the set
moves so that the damped elastic line carries it: s⁺ = x − e₁, with
(k_e + (3/2)c/Δt) e₁ = f + c((3/2)e₀/Δt + (1/2)ė₀). The orifice damper
stays in parallel, as a hydraulic strut's is, and so do both dampers on
an element that keeps no set.

It must not know about struts, legs or contact: the strut
(``symcushion.legs.strut``) applies (A1) to its axial deflection, and the step
(``symcushion.scheme.touchdown``) carries s in the state.
"""
from __future__ import annotations

import casadi as ca

from symcushion.legs.characteristics import Crushable, TwoSided
from symcushion.legs.curve_base import Curve

__all__ = ["elastic_stiffness", "default_damping_time", "DEFAULT_DAMPING_RATIO", "band", "memory_force", "band_force", "next_set",
           "free_deflection", "set_on_loading", "damper_force", "end_rate", "relaxed_deflection",
           "RELAX_NEWTON_STEPS"]

#: Newton steps of a free damped element's relaxation over a step (A4). Its
#: residual is piecewise linear and increasing (viscous damper) or smooth
#: (orifice): each step lands on the solution of the segment it starts on, so
#: four cross three kinks of the band; a free foot's error is no contact force.
RELAX_NEWTON_STEPS = 4


#: Damping ratio ζ that a scene file gives the axial mode of a leg on the memory law
#: when none of the leg's elements names a damper (docs/absorbers.md, "Default
#: damping"): the loss of a leg's structure and its absorber's sliding parts, not of
#: a hydraulic damper.
DEFAULT_DAMPING_RATIO = 0.05


def default_damping_time(axial: Curve, mass_share: float, ratio: float) -> float:
    """τ = c/k = 2ζ/ω of a leg's axial mode, ω = √(k_e/m), k_e the axial element's
    elastic stiffness (A1) and m the body's mass share per leg (s)."""
    k_e = float(elastic_stiffness(axial))
    return 2.0 * ratio * (mass_share / k_e) ** 0.5


def elastic_stiffness(curve: Curve, theta=None):
    """k_e of (A1): the curve's ``elastic_stiffness``, else its loading slope at zero."""
    if curve.elastic_stiffness is not None:
        return curve.elastic_stiffness
    th_load, _ = curve._split(theta)
    return curve._loading_slope(0.0, th_load)


def _crush_line(side: Curve, x, theta):
    """The crushing line of a crushable side, extended over every ``x`` (None for a
    side that does not crush)."""
    if not isinstance(side, Crushable):
        return None
    k, f_c, k_p = theta[0], theta[1], theta[2]
    return -f_c + k_p * (x + f_c / k)


def band(curve: Curve, x, theta=None):
    """(lo, hi) of (A1) at deflection ``x``; None where there is no bound.

    A two-sided element (:class:`~symcushion.legs.characteristics.TwoSided`) is bounded
    by its sides' crushing lines: below by the compression side's, above by the
    mirror of the tension side's; a side that does not crush leaves that side open.
    """
    th_load, th_unload = curve._split(theta)
    if isinstance(curve, TwoSided) and curve.unloading is None:
        th_c, th_t = curve._sides(x, th_load)
        hi = _crush_line(curve.tension, -x, th_t)
        return _crush_line(curve.compression, x, th_c), None if hi is None else -hi
    f_load = curve._loading(x, th_load)
    if curve.unloading is None:
        return f_load, None
    f_unload = curve.unloading._loading(x, th_unload)
    return ca.fmin(f_load, f_unload), ca.fmax(f_load, f_unload)


def memory_force(curve: Curve, x, s, theta=None, x_regime=None, rate=None):
    """f(x, s) of (A1) and the element's end stop in parallel, N or N·m.

    ``x_regime`` (default ``x``): the deflection whose place in the band picks
    the regime (on the lower bound, elastic, on the upper bound); the force is
    then that regime's expression at ``x``, so that its derivative in ``x`` is
    the tangent stiffness of the regime the step is heading for. ``rate`` =
    (a, b): the viscous damper's rate a·x + b (A3) on the elastic line (A5).
    """
    return band_force(curve, x, s, theta, x_regime, rate) + curve.end_stop(x, theta)


def _band_damper(curve: Curve, rate):
    """(c, a, b) of the viscous damper on the elastic line (A5), or None."""
    if rate is None or curve.damping == 0:
        return None
    return curve.damping, rate[0], rate[1]


def band_force(curve: Curve, x, s, theta=None, x_regime=None, rate=None):
    """f(x, s) of (A1) with the elastic line's damper (A5), alone (see
    :func:`memory_force`)."""
    k_e = elastic_stiffness(curve, theta)
    lo, hi = band(curve, x, theta)
    damper = _band_damper(curve, rate)

    def trial_at(z):
        t = k_e * (z - s)                                              # (A1)
        if damper is not None:
            c, a, b = damper
            t = t + c * (a * z + b)                                    # (A5)
        return t

    trial = trial_at(x)
    if x_regime is None:
        f = trial if lo is None else ca.fmax(trial, lo)
        return f if hi is None else ca.fmin(f, hi)
    lo_r, hi_r = band(curve, x_regime, theta)
    trial_r = trial_at(x_regime)
    f = trial if lo is None else ca.if_else(trial_r < lo_r, lo, trial)
    if hi is not None:
        f = ca.if_else(trial_r > hi_r, hi, f)
    return f


def next_set(curve: Curve, x, s, theta=None, rate=None):
    """s⁺ of (A2): the set after the element reached ``x`` from set ``s``; with the
    elastic line's damper (A5), the set whose damped elastic line carries the force."""
    k_e = elastic_stiffness(curve, theta)
    f = band_force(curve, x, s, theta, rate=rate)
    damper = _band_damper(curve, rate)
    if damper is None:
        moved = x - f / k_e                                            # (A2)
    else:
        c, a, b = damper
        moved = x - (f - c * (b + a * s)) / (k_e + a * c)              # (A2), (A5)
    # off the bounds (A2) gives s back, but only to round-off: x − k_e(x − s)/k_e.
    # Keep s exactly there, so that "the set moved" is a fact of the law and not of
    # rounding (the crush-onset kick of symcushion.scheme.foot_step tests it: a round-off
    # move switched that kick on at random for an element riding its elastic line
    # across the loading curve's bend, and central differences then disagreed with
    # AD by a few per cent on the design problems; docs/optimise.md). Continuous:
    # on a bound's edge both give s.
    lo, hi = band(curve, x, theta)
    trial = k_e * (x - s) + (0.0 if damper is None else c * (a * x + b))
    clipped = None if lo is None else trial < lo
    if hi is not None:
        above = trial > hi
        clipped = above if clipped is None else ca.logic_or(clipped, above)
    return moved if clipped is None else ca.if_else(clipped, moved, s)


def free_deflection(curve: Curve, s, theta=None):
    """x₀(s): where a free element with set ``s`` carries no force."""
    z_load = curve.loading_zero(theta)
    if isinstance(curve, TwoSided) and curve.unloading is None:
        return s                                # the elastic line's zero, either way
    if curve.unloading is None:
        return ca.fmin(s, z_load)
    _, th_unload = curve._split(theta)
    z_unload = curve.unloading._loading_zero(th_unload)
    return ca.fmin(ca.fmax(s, ca.fmin(z_load, z_unload)), ca.fmax(z_load, z_unload))


def set_on_loading(curve: Curve, x, theta=None):
    """The set of an element that reached ``x`` along its loading curve."""
    th_load, _ = curve._split(theta)
    return x - curve._loading(x, th_load) / elastic_stiffness(curve, theta)


def element_force(curve: Curve, x, s, theta=None, x_regime=None, rate=None):
    """An element's force on the memory law, ``rate`` = (a, b) its dampers' rate
    a·x + b (A3). An element that keeps a set: (A1) with its end stop, its viscous
    damper on the elastic line (A5) and its orifice in parallel. One that keeps
    none: its loading curve with both dampers in parallel."""
    value = None if rate is None else rate[0] * x + rate[1]
    if curve.has_memory:
        f = memory_force(curve, x, s, theta, x_regime, rate)
        if curve.orifice > 0 and value is not None:
            f = f + curve.orifice * value * ca.fabs(value)
        return f
    f = curve.force(x, 0.0, theta)
    if curve.has_damper and value is not None:
        f = f + damper_force(curve, value)
    return f


def element_next_set(curve: Curve, x, s, theta=None, rate=None):
    """s⁺ of (A2) for an element that keeps a set; ``s`` unchanged for one that does not."""
    return next_set(curve, x, s, theta, rate) if curve.has_memory else s


def damper_force(curve: Curve, rate):
    """c·ẋ + c₂·ẋ|ẋ| of the dampers in parallel with the element (N or N·m)."""
    return curve.damping * rate + curve.orifice * rate * ca.fabs(rate)


def end_rate(x1, x0, mean_rate0, dt):
    """ẋ at the end of a step by (A3): ``x1``, ``x0`` the deflections at its end and
    start, ``mean_rate0`` the previous step's mean rate, ``dt`` the step."""
    return 1.5 * (x1 - x0) / dt - 0.5 * mean_rate0                     # (A3)


def relaxed_deflection(curve: Curve, x0, s, mean_rate0, dt, theta=None):
    """x₁ of a free element over a step: x₀(s) at once without a damper, else (A4)
    by Newton's method from the start deflection ``x0``."""
    if not curve.has_damper:
        return free_deflection(curve, s, theta)
    x = ca.SX.sym("x")
    th_load, _ = curve._split(theta)
    elastic = (memory_force(curve, x, s, theta) if curve.has_memory
               else curve._loading(x, th_load) + curve.end_stop(x, theta))
    residual = elastic + damper_force(
        curve, end_rate(x, x0, mean_rate0, dt))                        # (A4)
    slope = ca.jacobian(residual, x)
    # a pure orifice damper has no slope where it carries no force: stay there
    newton = x - ca.if_else(slope > 0, residual / ca.if_else(slope > 0, slope, 1.0), 0.0)
    x1 = x0
    for _ in range(RELAX_NEWTON_STEPS):
        x1 = ca.substitute(newton, x, x1)
    return x1
