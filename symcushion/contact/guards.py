"""Guarded primitives and cone helpers shared by the contact steps (Khvostov 1976, §1).

This module owns the branch-free building blocks of the contact steps:
division, square root, norm and unit vector guarded so that the branch a
``casadi.if_else`` does not take can produce neither NaN nor inf, in values
or in derivatives (SX evaluates, and differentiates, both branches); the
friction cone (1.4)-(1.5) as a value, a distance and a projection; the
lift-off replacement of a step's outputs; and the comparisons and clamps
written without fabs, fmin or fmax (``within``, ``exceeds``, ``at_least``,
``at_most``), which the generated C would otherwise call as functions. It
also owns the two tolerances these use, ``TINY`` and ``CONE_TOL``.

It must not implement a contact step, choose between steps, or convert to
NumPy: ``symcushion.contact.paper``, ``contact_robust`` and
``contact_implicit`` build the steps from these pieces, and
``symcushion.contact`` is the public API (docs/contact-spec.md, "safe
division", "safe norm").
"""
from __future__ import annotations

import casadi as ca

__all__ = [
    "CONE_TOL",
    "TINY",
    "at_least",
    "at_most",
    "cone_clean",
    "cone_gap",
    "cone_value",
    "exceeds",
    "lift_off",
    "on_cone",
    "safe_div",
    "safe_norm",
    "safe_sqrt",
    "sign_plus",
    "unit",
    "within",
]

# Relative tolerance of the cone tests C(P) <= CONE_TOL*|P|^2 in the robust
# step: a force left on the cone by the previous step has C = +-round-off
# (a few 1e-16 |P|^2); 1e-12 sits well above that and far below any physical
# penetration of the cone (docs/paper-notes.md §3 items 2 and 5).
CONE_TOL = 1e-12
# A denominator with |d| <= TINY is treated as zero. 1e-300 is above the
# smallest normal double (2.2e-308), so 1/d cannot overflow.
TINY = 1e-300


# Comparisons and clamps without fabs, fmin or fmax: the generated C calls a
# helper or libm for each of those, and a call spills every live
# floating-point register, while a comparison and a select stay in registers.
def within(x, bound):
    """|x| <= bound as two comparisons: the same flag as the fabs form, NaN included."""
    return ca.logic_and(x <= bound, x >= -bound)


def exceeds(x, bound):
    """|x| > bound as two comparisons: the same flag as the fabs form, NaN included."""
    return ca.logic_or(x > bound, x < -bound)


def at_least(x, low):
    """max(x, low) for a number `low` (not NaN): x where x > low, else low.

    The value of fmax(x, low), also for a NaN x (low); only the sign of a
    zero result may differ (an SX select adds the branch to a zero).
    """
    return ca.if_else(x > low, x, low)


def at_most(x, high):
    """min(x, high) for a number `high` (not NaN): x where x < high, else high.

    The value of fmin(x, high), also for a NaN x (high); only the sign of a
    zero result may differ.
    """
    return ca.if_else(x < high, x, high)


def safe_div(a, b):
    """a/b, and 0 where |b| <= TINY; the untaken branch divides by 1."""
    ok = exceeds(b, TINY)
    return ca.if_else(ok, a / ca.if_else(ok, b, 1.0), 0.0)


def safe_sqrt(x):
    """sqrt(x), and 0 where x <= TINY: sqrt has an infinite slope at 0."""
    ok = x > TINY
    return ca.if_else(ok, ca.sqrt(ca.if_else(ok, x, 1.0)), 0.0)


def safe_norm(v):
    """|v| with the guard of :func:`safe_sqrt` on v.v."""
    return safe_sqrt(ca.dot(v, v))


def unit(v):
    """(v/|v|, |v|), with v/|v| = 0 where v.v <= TINY."""
    norm = safe_norm(v)
    ok = norm > 0  # the safe norm is 0 exactly where v.v <= TINY
    return ca.if_else(ok, v / ca.if_else(ok, norm, 1.0), ca.SX.zeros(v.shape)), norm


def sign_plus(x):
    """sign(x) with sign(0) = +1 (stable quadratic roots)."""
    return ca.if_else(x >= 0, 1.0, -1.0)


def cone_value(P, n, c):
    """C(P) = P.P - (1 + mu^2)(n.P)^2 (1.5), with c = 1 + mu^2."""
    return ca.dot(P, P) - c * ca.dot(n, P) ** 2


def cone_gap(P, n, mu):
    """gap(P) = |P_tau| - mu n.P: the cone (1.4) as a distance, <= 0 inside.

    Unlike C(P) (1.5), which is quadratic in the distance from the cone as
    mu -> 0 (C = |P_tau|^2 at mu = 0), gap is linear in it for every mu, so
    a relative tolerance on gap means the same thing at mu = 0 and mu = 2.
    """
    N = ca.dot(n, P)
    return safe_norm(P - N * n) - mu * N


def on_cone(P, n, mu):
    """Inside or on the cone up to CONE_TOL, and compressive."""
    return ca.logic_and(cone_gap(P, n, mu) <= CONE_TOL * safe_norm(P), ca.dot(n, P) > 0)


def cone_clean(P, n, mu):
    """Project P_tau onto the cone: P_tau <- P_tau min(1, mu n.P/|P_tau|).

    Round-off amplified by a stiff D_p cannot then leave C(P) > 0; P moves
    by round-off times cond(D_p) only. With mu = 0 this sets P_tau = 0.
    """
    N = ca.dot(n, P)
    P_tau = P - N * n
    T = safe_norm(P_tau)
    scale = ca.fmin(1.0, safe_div(mu * N, T))
    return N * n + scale * P_tau


def lift_off(flag, u0, out):
    """Replace `out` by lift-off (P = 0, delta = -u0, contact = 0) where flag."""
    zero = ca.SX.zeros(3, 1)
    return dict(
        delta=ca.if_else(flag, -u0, out["delta"]),
        P=ca.if_else(flag, zero, out["P"]),
        k=out["k"],
        contact=ca.if_else(flag, 0.0, out["contact"]),
    )

