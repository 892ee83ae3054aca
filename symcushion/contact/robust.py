"""The printed contact step with its weak points fixed (docs/contact-spec.md §2).

This module owns ``robust_step``: the method of (1.8)-(1.15) with
docs/paper-notes.md §3 items 1-5 fixed (a stick trial first, tolerances on
the cone tests, the clamp (1.10) as a safeguard only, the stable root of the
k2 quadratic, the separation test and a final projection onto the cone). It
must not change the printed step (``symcushion.contact.paper``), solve the
exact Coulomb step (``symcushion.contact.implicit``), validate inputs or
build Functions (``symcushion.contact``).
"""
from __future__ import annotations

import casadi as ca

from symcushion.contact.guards import (CONE_TOL, TINY, cone_clean, cone_gap, cone_value, lift_off,
    on_cone, safe_div, safe_norm, safe_sqrt, sign_plus, unit)

__all__ = ["robust_step"]


def _initial_slip(P0, Dp, n, mu, u0, c, Dl):
    """k1 (1.9)-(1.10) of the robust step and s = n x (P0 x n) (step 2).

    Shapes: P0, n, u0 (3, 1); Dp (3, 3); mu, c = 1 + mu^2 (1, 1); Dl = Dp l
    (3, 1), N. Returns (k1 (1, 1), dimensionless; s (3, 1), N).
    """
    # 2. k1 (1.9) with a tolerance on "(1.5) violated" (item 2); clamp
    #    (1.10) as a safeguard only (item 4).
    N0 = ca.dot(n, P0)
    P0_norm = safe_norm(P0)
    s = P0 - N0 * n  # s = n x (P0 x n)
    ss = ca.dot(s, s)
    Ds = ca.mtimes(Dp, s)
    fires = ca.logic_and(
        cone_gap(P0, n, mu) >= -CONE_TOL * P0_norm,
        ca.logic_and(N0 > 0, ss > CONE_TOL * P0_norm**2),
    )
    num = ca.dot(P0, Dl) - c * N0 * ca.dot(n, Dl)  # (1.9)
    den = ca.dot(P0, Ds) - c * N0 * ca.dot(n, Ds)  # (1.9)
    k1 = ca.fmax(safe_div(num, den), 0.0)
    ub = safe_div(ca.dot(s, u0), ss)  # (1.10)
    k1 = ca.if_else(ub > 0, ca.fmin(k1, ub), k1)
    k1 = ca.if_else(fires, k1, 0.0)
    return k1, s


def _cone_entry(P0, Dp, n, l, mu, c, k1, s):
    """k2 (1.11) of the robust step: where P reaches the cone along -l_tau (step 3).

    Shapes: P0, n, l, s (3, 1); Dp (3, 3); mu, c, k1 (1, 1). Returns (k2
    (1, 1), dimensionless in [0, 1]; l_tau = n x (l x n) (3, 1), m).
    """
    # 3. k2 (1.11) from P2 = P0 + Dp (l - k1 s) (item 2), a tolerance on
    #    the cone test (item 5), stable roots of A2 lam^2 - 2 B2 lam + C2 = 0.
    l_tau = l - ca.dot(n, l) * n  # l_tau = n x (l x n) (1.8)
    Dl_tau = ca.mtimes(Dp, l_tau)
    P2 = P0 + ca.mtimes(Dp, l - k1 * s)
    N2 = ca.dot(n, P2)
    C2 = cone_value(P2, n, c)
    on_cone2 = on_cone(P2, n, mu)
    A2 = ca.dot(Dl_tau, Dl_tau) - c * ca.dot(n, Dl_tau) ** 2  # (1.11)
    B2 = ca.dot(P2, Dl_tau) - c * N2 * ca.dot(n, Dl_tau)  # (1.11)
    D2 = B2**2 - A2 * C2
    q2 = B2 + sign_plus(B2) * safe_sqrt(D2)
    n_Dl_tau = ca.dot(n, Dl_tau)
    k2 = ca.SX(1.0)  # no counting root: k2 = 1
    for denom, lam in ((A2, safe_div(q2, A2)), (q2, safe_div(C2, q2))):
        counts = ca.logic_and(
            ca.logic_and(D2 >= 0, ca.fabs(denom) > TINY),
            ca.logic_and(
                ca.logic_and(lam > 0, lam < 1),
                N2 - lam * n_Dl_tau > 0,  # n.(P2 - lam Dp l_tau) > 0
            ),
        )
        k2 = ca.if_else(counts, ca.fmin(k2, lam), k2)
    k2 = ca.if_else(on_cone2, 0.0, k2)
    return k2, l_tau


def _final_slip(P0, Dp, n, l, mu, friction, k1, s, k2, l_tau):
    """k3 (1.12)-(1.15) of the robust step along e, by closed-form roots (step 4).

    Shapes: P0, n, l, s, l_tau (3, 1); Dp (3, 3); mu, k1, k2 (1, 1).
    Returns (delta3 (3, 1), m; k3 (1, 1), m; e (3, 1), unit; no_root
    (1, 1), 1 where no admissible k3 exists off the cone).
    """
    # 4. k3 by the closed-form roots of (1.13) (item 3).
    delta3 = l - k1 * s - k2 * l_tau  # (1.12)
    P3 = P0 + ca.mtimes(Dp, delta3)  # (1.3)
    N = ca.dot(n, P3)
    t_hat, T = unit(P3 - N * n)
    e, _ = unit(ca.cross(n, ca.mtimes(Dp.T, ca.cross(n, P3))))  # (1.12)
    Pe = ca.mtimes(Dp, e)
    a = ca.dot(n, Pe)
    b = ca.dot(t_hat, Pe)  # H = T b (1.14)
    on_cone3 = on_cone(P3, n, mu)
    if friction:
        # B3^2 - A3 C3 = mu^2 (bN - aT)^2: roots without a square root.
        candidates = ((b - mu * a, safe_div(mu * N - T, b - mu * a)),
                      (b + mu * a, safe_div(-(T + mu * N), b + mu * a)))
    else:
        # mu = 0: both roots are -T/b (the cone is the ray along n).
        candidates = ((b, safe_div(-T, b)),)
    k3 = ca.SX(0.0)
    found = ca.SX(0.0)
    for denom, k in candidates:
        # the printed selection k.H < 0, and compression after the step
        counts = ca.logic_and(
            ca.fabs(denom) > TINY,
            ca.logic_and(k * b < 0, N + k * a > 0),
        )
        better = ca.logic_and(counts, ca.logic_or(ca.logic_not(found), ca.fabs(k) < ca.fabs(k3)))
        k3 = ca.if_else(better, k, k3)
        found = ca.logic_or(found, counts)
    k3 = ca.if_else(on_cone3, 0.0, k3)
    no_root = ca.logic_and(ca.logic_not(on_cone3), ca.logic_not(found))
    return delta3, k3, e, no_root


def robust_step(P0, Dp, n, l, mu, u0, friction):
    """The step of (1.8)-(1.15) with docs/paper-notes.md §3 items 1-5 fixed.

    Arguments and returned dict as :func:`symcushion.contact.contact_step_expr`
    after its conversion: P0, n, l, u0 (3, 1), Dp (3, 3) and mu (1, 1)
    ``casadi.SX``, in N, m and N/m; ``k`` holds (k1, k2, k3) of (1.8), k1 and
    k2 dimensionless, k3 in m.
    `friction` False leaves out the friction code paths (`mu` is then
    ``SX(0)``).
    """
    c = 1 + mu**2
    Dl = ca.mtimes(Dp, l)

    # 1. Stick trial: the whole of l without slip, P_t = P0 + Dp l (1.3).
    P_t = P0 + Dl
    stick = on_cone(P_t, n, mu)

    k1, s = _initial_slip(P0, Dp, n, mu, u0, c, Dl)
    k2, l_tau = _cone_entry(P0, Dp, n, l, mu, c, k1, s)
    delta3, k3, e, no_root = _final_slip(P0, Dp, n, l, mu, friction, k1, s, k2, l_tau)

    # 5. delta (1.12), P (1.3), cone clean-up.
    delta = delta3 + k3 * e
    P = cone_clean(P0 + ca.mtimes(Dp, delta), n, mu)

    # 6. Separation (item 1): tension, or no admissible k3, or, with a
    #    tensile trial force, friction along the accumulated slip
    #    g = l - delta (P_tau.g < 0): the chain then landed on the cone in no
    #    Coulomb state, and in plane-parallel motion the exact step has no
    #    compressive solution either. With a compressive trial force the
    #    exact step mostly has one in 3-D, and lifting off there is worse
    #    than the anti-Coulomb answer (docs/contact.md, "robust"). The
    #    tolerance keeps a P_tau of round-off (mu = 0) from deciding.
    P_N = ca.dot(n, P)
    slip = l - delta
    anti_coulomb = ca.logic_and(
        ca.dot(P - P_N * n, slip) < -CONE_TOL * safe_norm(P) * safe_norm(slip),
        ca.dot(n, P_t) <= 0)
    lift = ca.logic_or(ca.logic_or(P_N <= 0, no_root), anti_coulomb)
    k = ca.vertcat(k1, k2, k3)
    slip = lift_off(lift, u0, dict(delta=delta, P=P, k=k, contact=ca.SX(1.0)))
    return dict(
        delta=ca.if_else(stick, l, slip["delta"]),
        P=ca.if_else(stick, P_t, slip["P"]),
        k=ca.if_else(stick, ca.SX.zeros(3, 1), slip["k"]),
        contact=ca.if_else(stick, 1.0, slip["contact"]),
    )
