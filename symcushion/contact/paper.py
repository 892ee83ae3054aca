"""The contact step as printed: Khvostov (1976) (1.8)-(1.15) (docs/contact-spec.md §1).

This module owns ``paper_step``, the branch-free SX expressions of the
printed method with the OCR readings of docs/paper-notes.md §1, weak points
included (docs/paper-notes.md §3). It must not fix those weak points (that is
``symcushion.contact.robust``), validate inputs or build Functions (that is
``symcushion.contact``); its guarded primitives come from
``symcushion.contact.guards``.
"""
from __future__ import annotations

import casadi as ca

from symcushion.contact.guards import at_least, at_most, cone_value, safe_div, safe_sqrt, unit

__all__ = ["paper_step"]


def _cone_entry(P0, Dp, n, l, c, Dl):
    """k2 (1.11) as printed, from P2 = P0 + Dp l.

    Shapes: P0, n, l, Dl = Dp l (3, 1); Dp (3, 3); c = 1 + mu^2 (1, 1).
    Returns (k2 (1, 1), dimensionless in [0, 1]; l_tau = n x (l x n) (3, 1), m).
    """
    # k2 (1.11) with the printed P2 = P0 + Dp l (ignores k1: docs/paper-notes.md §3.2).
    l_tau = l - ca.dot(n, l) * n  # l_tau = n x (l x n) (1.8)
    P2 = P0 + Dl
    N2 = ca.dot(n, P2)
    Dl_tau = ca.mtimes(Dp, l_tau)
    A2 = ca.dot(Dl_tau, Dl_tau) - c * ca.dot(n, Dl_tau) ** 2  # (1.11)
    B2 = ca.dot(P2, Dl_tau) - c * N2 * ca.dot(n, Dl_tau)  # (1.11)
    C2 = cone_value(P2, n, c)  # (1.11)
    disc2 = B2**2 - A2 * C2
    sqrt2 = safe_sqrt(disc2)
    A2_nonzero = A2 != 0
    A2_div = ca.if_else(A2_nonzero, A2, 1.0)
    quadratic = ca.logic_and(A2_nonzero, disc2 >= 0)
    linear = ca.logic_and(ca.logic_not(A2_nonzero), B2 != 0)
    roots = [
        (quadratic, (B2 - sqrt2) / A2_div),
        (quadratic, (B2 + sqrt2) / A2_div),
        (linear, safe_div(C2, 2 * B2)),
    ]
    k2 = ca.SX(1.0)  # no root in (0, 1): k2 = 1
    for exists, lam in roots:
        counts = ca.logic_and(exists, ca.logic_and(lam > 0, lam < 1))
        k2 = ca.if_else(counts, at_most(k2, lam), k2)
    k2 = ca.if_else(ca.logic_and(C2 < 0, N2 > 0), 0.0, k2)  # (1.11)
    return k2, l_tau


def _final_slip(P0, Dp, n, l, c, k1, s, k2, l_tau):
    """k3 (1.12)-(1.15) as printed: the correction along e with (n x P3).(Dp e) = 0.

    Shapes: P0, n, l, s, l_tau (3, 1); Dp (3, 3); c, k1, k2 (1, 1).
    Returns (delta3 (3, 1), m; k3 (1, 1), m; e (3, 1), unit).
    """
    # k3 (1.12)-(1.15): correction along e with (n x P3).(Dp e) = 0.
    delta3 = l - k1 * s - k2 * l_tau  # (1.12)
    P3 = P0 + ca.mtimes(Dp, delta3)  # (1.3)
    e, _ = unit(ca.cross(n, ca.mtimes(Dp.T, ca.cross(n, P3))))  # (1.12)
    Pe = ca.mtimes(Dp, e)
    N3 = ca.dot(n, P3)
    Ne = ca.dot(n, Pe)
    A3 = ca.dot(Pe, Pe) - c * Ne**2  # (1.13)
    B3 = ca.dot(P3, Pe) - c * N3 * Ne  # (1.13)
    C3 = cone_value(P3, n, c)  # (1.13)
    H = ca.dot(P3 - N3 * n, Pe - Ne * n)  # (1.14)
    # (1.15); the max(., 0) is the one departure from print (docs/paper-notes.md §3.3).
    A3_div = ca.if_else(A3 != 0, A3, 1.0)
    k3_quadratic = (-B3 + safe_sqrt(at_least(B3**2 - A3 * C3, 0.0)) * ca.sign(H)) / A3_div
    k3_linear = safe_div(-C3, 2 * B3)  # (1.15), A3 = 0
    k3 = ca.if_else(A3 != 0, k3_quadratic, ca.if_else(B3 != 0, k3_linear, 0.0))
    k3 = ca.if_else(C3 > 0, k3, 0.0)
    return delta3, k3, e


def paper_step(P0, Dp, n, l, mu, u0):
    """The printed step (1.8)-(1.15): slip k1 (1.9)-(1.10), k2 (1.11)-(1.14), k3 (1.15).

    Arguments and returned dict as :func:`symcushion.contact.contact_step_expr`
    after its conversion: P0, n, l, u0 (3, 1), Dp (3, 3) and mu (1, 1)
    ``casadi.SX``, in N, m and N/m; ``k`` holds (k1, k2, k3) of (1.8), k1 and
    k2 dimensionless, k3 in m.
    """
    c = 1 + mu**2
    Dl = ca.mtimes(Dp, l)

    # k1: initial slip (1.9), clamped by (1.10); fires only when C0 > 0.
    N0 = ca.dot(n, P0)
    C0 = cone_value(P0, n, c)
    s = P0 - N0 * n  # s = n x (P0 x n)
    Ds = ca.mtimes(Dp, s)
    num = ca.dot(P0, Dl) - c * N0 * ca.dot(n, Dl)  # (1.9)
    den = ca.dot(P0, Ds) - c * N0 * ca.dot(n, Ds)  # (1.9)
    k1 = safe_div(num, den)
    ub = safe_div(ca.dot(s, u0), ca.dot(s, s))  # (1.10)
    k1 = at_most(at_least(k1, 0.0), at_least(ub, 0.0))  # empty interval -> 0
    k1 = ca.if_else(C0 > 0, k1, 0.0)

    k2, l_tau = _cone_entry(P0, Dp, n, l, c, Dl)
    delta3, k3, e = _final_slip(P0, Dp, n, l, c, k1, s, k2, l_tau)

    delta = delta3 + k3 * e  # (1.12)
    P = P0 + ca.mtimes(Dp, delta)  # (1.3)
    # The printed method has no separation branch (docs/paper-notes.md §3.1): P is
    # returned even when tensile; contact is a diagnostic for the simulator.
    contact = ca.if_else(ca.dot(n, P) > 0, 1.0, 0.0)
    return dict(delta=delta, P=P, k=ca.vertcat(k1, k2, k3), contact=contact)
