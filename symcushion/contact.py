"""Contact step of one massless foot on a rigid plane (Khvostov 1976, §1).

Given the force on the foot P₀ and the stiffness matrix D_p = ∂P/∂r at the
start of a time step, and the displacement l of the plane relative to the
body over the step, a contact step returns the foot's displacement δ, the
force P = P₀ + D_p δ (1.3) at the end of the step, and whether the foot is
still in compressive contact, under Coulomb friction with coefficient μ.

This module owns three such steps, built as branch-free CasADi SX graphs with
identical signatures, and specified exactly in ``docs/contact-spec.md``:

``contact_step_paper``
    (1.8)-(1.15) as printed, with the OCR readings of docs/paper-notes.md §1.
``contact_step_robust``
    the same method with the weak points of docs/paper-notes.md §3 items 1-5 fixed.
``contact_step_implicit``
    the exact backward-Euler Coulomb step (return mapping) for the same
    linearised force law, valid in 3-D (docs/paper-notes.md §3 item 6).

It knows nothing about struts, bodies or time integration: the stiffness
matrix comes from the caller, and the simulator either calls a Function from
:func:`contact_step` or inlines the expressions of :func:`contact_step_expr`
in its own graph. Only :func:`solve_contact` converts to NumPy.

Every division and square root is guarded (``_safe_div``, ``_safe_sqrt``) so
that the branch an ``if_else`` does not take can produce neither NaN nor inf,
in values or in derivatives: SX evaluates, and differentiates, both branches.

References
----------
V. F. Khvostov, "On the dynamic interaction of shock-absorbing supports with a
rigid obstacle", Izv. AN SSSR, Mekhanika Tverdogo Tela, 1976, §1,
equations (1.3)-(1.15); the project's reading in ``docs/paper-notes.md``.
"""
from __future__ import annotations

import dataclasses
import functools
import numbers

import casadi as ca
import numpy as np

from .contact_quartic import quartic_roots

__all__ = [
    "CONE_TOL",
    "DET_TOL",
    "ContactResult",
    "INPUT_NAMES",
    "METHODS",
    "OUTPUT_NAMES",
    "POLE_TOL",
    "ROOT_TOL",
    "TINY",
    "UNIT_TOL",
    "contact_step",
    "contact_step_call",
    "contact_step_expr",
    "solve_contact",
    "stack_inputs",
]

# Relative tolerance of the cone tests C(P) <= CONE_TOL*|P|^2 in the robust
# step: a force left on the cone by the previous step has C = +-round-off
# (a few 1e-16 |P|^2); 1e-12 sits well above that and far below any physical
# penetration of the cone (docs/paper-notes.md §3 items 2 and 5).
CONE_TOL = 1e-12
# A denominator with |d| <= TINY is treated as zero. 1e-300 is above the
# smallest normal double (2.2e-308), so 1/d cannot overflow.
TINY = 1e-300
# A candidate lam of the implicit step is a root of det(K + lam I) -- g(lam)
# unbounded, or not unique when adj(K + lam I) p = 0 too -- when
# |det(K + lam I)| <= DET_TOL (|K|_F + lam)^2: round-off leaves det at
# ~1e-16 of that scale at a true root, and 1e-12 sits well above it.
DET_TOL = 1e-12
# A polished candidate solves lam |g| = mu N when the two sides agree to
# ROOT_TOL relative. Simple roots are polished to ~1e-15; a double root (the
# secular function touching zero) only to ~1e-8, so 1e-6 keeps those, and
# rejects the squared equation's roots of lam |g| = -mu N (relative residual
# 2) and the real parts of complex pairs more than ~1e-3 off the real axis.
ROOT_TOL = 1e-6
# Newton steps of the implicit step on the chosen root of the quartic: a
# candidate accepted at ROOT_TOL (with a stiff normal coupling, relative to
# |N_t| + |a.g| rather than N) can be off by ~1e-3 relative; two steps reach
# round-off, the third makes the derivative of the last step the
# implicit-function derivative.
FINAL_STEPS = 3
# Each of those steps moves lam by at most FINAL_CLIP lam, so that a flat Q
# (a double root) cannot throw it onto another root.
FINAL_CLIP = 1e-2
# A root r of det(K + lam I) is a pole of the implicit step's g(lam) only if
# |adj(K + r I) p| > POLE_TOL (|K|_F + r) |p|: the residue is exactly 0 when
# p is an eigenvector of K (plane-parallel motion) and round-off leaves it at
# ~1e-16 relative; 1e-12 sits well above that.
POLE_TOL = 1e-12
# Round-off of N = N_t - a.g relative to |N_t| + |a.g| that the check of a
# candidate tolerates on top of ROOT_TOL: with a stiff normal coupling (an
# axially rigid rod, cond(D_p) ~ 1e8) N is a small difference of large terms;
# the hard case `stiff_axial` needs 1e-14 (lifts off spuriously with 0).
CANCEL_TOL = 1e-12
# The implicit step's root scale c stays within this factor of the
# tangential stiffness |K|_F + mu |a|: slips of interest have lam = mu N/|g|
# within a few decades of it, and the guard keeps c finite when the quartic
# loses its leading or constant term.
ROOT_SCALE_RANGE = 1e3
# |n| must equal 1 to this tolerance at the Python boundary: the cone test
# (1.5) is homogeneous in P but not in n, so a non-unit n changes mu.
UNIT_TOL = 1e-9

METHODS = ("paper", "robust", "implicit")
INPUT_NAMES = ["P0", "Dp", "n", "l", "mu", "u0"]
OUTPUT_NAMES = ["delta", "P", "k", "contact"]


# ---------------------------------------------------------------------------
# Guarded primitives (docs/contact-spec.md, "safe division", "safe norm")
# ---------------------------------------------------------------------------
def _safe_div(a, b):
    """a/b, and 0 where |b| <= TINY; the untaken branch divides by 1."""
    ok = ca.fabs(b) > TINY
    return ca.if_else(ok, a / ca.if_else(ok, b, 1.0), 0.0)


def _safe_sqrt(x):
    """sqrt(x), and 0 where x <= TINY: sqrt has an infinite slope at 0."""
    ok = x > TINY
    return ca.if_else(ok, ca.sqrt(ca.if_else(ok, x, 1.0)), 0.0)


def _safe_norm(v):
    """|v| with the guard of :func:`_safe_sqrt` on v.v."""
    return _safe_sqrt(ca.dot(v, v))


def _unit(v):
    """(v/|v|, |v|), with v/|v| = 0 where v.v <= TINY."""
    norm = _safe_norm(v)
    ok = norm > 0  # the safe norm is 0 exactly where v.v <= TINY
    return ca.if_else(ok, v / ca.if_else(ok, norm, 1.0), ca.SX.zeros(v.shape)), norm


def _sign_plus(x):
    """sign(x) with sign(0) = +1 (stable quadratic roots)."""
    return ca.if_else(x >= 0, 1.0, -1.0)


def _cone(P, n, c):
    """C(P) = P.P - (1 + mu^2)(n.P)^2 (1.5), with c = 1 + mu^2."""
    return ca.dot(P, P) - c * ca.dot(n, P) ** 2


def _cone_gap(P, n, mu):
    """gap(P) = |P_tau| - mu n.P: the cone (1.4) as a distance, <= 0 inside.

    Unlike C(P) (1.5), which is quadratic in the distance from the cone as
    mu -> 0 (C = |P_tau|^2 at mu = 0), gap is linear in it for every mu, so
    a relative tolerance on gap means the same thing at mu = 0 and mu = 2.
    """
    N = ca.dot(n, P)
    return _safe_norm(P - N * n) - mu * N


def _on_cone(P, n, mu):
    """Inside or on the cone up to CONE_TOL, and compressive."""
    return ca.logic_and(_cone_gap(P, n, mu) <= CONE_TOL * _safe_norm(P), ca.dot(n, P) > 0)


def _cone_clean(P, n, mu):
    """Project P_tau onto the cone: P_tau <- P_tau min(1, mu n.P/|P_tau|).

    Round-off amplified by a stiff D_p cannot then leave C(P) > 0; P moves
    by round-off times cond(D_p) only. With mu = 0 this sets P_tau = 0.
    """
    N = ca.dot(n, P)
    P_tau = P - N * n
    T = _safe_norm(P_tau)
    scale = ca.fmin(1.0, _safe_div(mu * N, T))
    return N * n + scale * P_tau


def _lift_off(flag, u0, out):
    """Replace `out` by lift-off (P = 0, delta = -u0, contact = 0) where flag."""
    zero = ca.SX.zeros(3, 1)
    return dict(
        delta=ca.if_else(flag, -u0, out["delta"]),
        P=ca.if_else(flag, zero, out["P"]),
        k=out["k"],
        contact=ca.if_else(flag, 0.0, out["contact"]),
    )


# ---------------------------------------------------------------------------
# contact_step_paper: (1.8)-(1.15) as printed (docs/contact-spec.md §1)
# ---------------------------------------------------------------------------
def _paper(P0, Dp, n, l, mu, u0):
    c = 1 + mu**2
    Dl = ca.mtimes(Dp, l)

    # k1: initial slip (1.9), clamped by (1.10); fires only when C0 > 0.
    N0 = ca.dot(n, P0)
    C0 = _cone(P0, n, c)
    s = P0 - N0 * n  # s = n x (P0 x n)
    Ds = ca.mtimes(Dp, s)
    num = ca.dot(P0, Dl) - c * N0 * ca.dot(n, Dl)  # (1.9)
    den = ca.dot(P0, Ds) - c * N0 * ca.dot(n, Ds)  # (1.9)
    k1 = _safe_div(num, den)
    ub = _safe_div(ca.dot(s, u0), ca.dot(s, s))  # (1.10)
    k1 = ca.fmin(ca.fmax(k1, 0.0), ca.fmax(ub, 0.0))  # empty interval -> 0
    k1 = ca.if_else(C0 > 0, k1, 0.0)

    # k2 (1.11) with the printed P2 = P0 + Dp l (ignores k1: docs/paper-notes.md §3.2).
    l_tau = l - ca.dot(n, l) * n  # l_tau = n x (l x n) (1.8)
    P2 = P0 + Dl
    N2 = ca.dot(n, P2)
    Dl_tau = ca.mtimes(Dp, l_tau)
    A2 = ca.dot(Dl_tau, Dl_tau) - c * ca.dot(n, Dl_tau) ** 2  # (1.11)
    B2 = ca.dot(P2, Dl_tau) - c * N2 * ca.dot(n, Dl_tau)  # (1.11)
    C2 = _cone(P2, n, c)  # (1.11)
    disc2 = B2**2 - A2 * C2
    sqrt2 = _safe_sqrt(disc2)
    A2_nonzero = A2 != 0
    A2_div = ca.if_else(A2_nonzero, A2, 1.0)
    quadratic = ca.logic_and(A2_nonzero, disc2 >= 0)
    linear = ca.logic_and(ca.logic_not(A2_nonzero), B2 != 0)
    roots = [
        (quadratic, (B2 - sqrt2) / A2_div),
        (quadratic, (B2 + sqrt2) / A2_div),
        (linear, _safe_div(C2, 2 * B2)),
    ]
    k2 = ca.SX(1.0)  # no root in (0, 1): k2 = 1
    for exists, lam in roots:
        counts = ca.logic_and(exists, ca.logic_and(lam > 0, lam < 1))
        k2 = ca.if_else(counts, ca.fmin(k2, lam), k2)
    k2 = ca.if_else(ca.logic_and(C2 < 0, N2 > 0), 0.0, k2)  # (1.11)

    # k3 (1.12)-(1.15): correction along e with (n x P3).(Dp e) = 0.
    delta3 = l - k1 * s - k2 * l_tau  # (1.12)
    P3 = P0 + ca.mtimes(Dp, delta3)  # (1.3)
    e, _ = _unit(ca.cross(n, ca.mtimes(Dp.T, ca.cross(n, P3))))  # (1.12)
    Pe = ca.mtimes(Dp, e)
    N3 = ca.dot(n, P3)
    Ne = ca.dot(n, Pe)
    A3 = ca.dot(Pe, Pe) - c * Ne**2  # (1.13)
    B3 = ca.dot(P3, Pe) - c * N3 * Ne  # (1.13)
    C3 = _cone(P3, n, c)  # (1.13)
    H = ca.dot(P3 - N3 * n, Pe - Ne * n)  # (1.14)
    # (1.15); the max(., 0) is the one departure from print (docs/paper-notes.md §3.3).
    A3_div = ca.if_else(A3 != 0, A3, 1.0)
    k3_quadratic = (-B3 + _safe_sqrt(ca.fmax(B3**2 - A3 * C3, 0.0)) * ca.sign(H)) / A3_div
    k3_linear = _safe_div(-C3, 2 * B3)  # (1.15), A3 = 0
    k3 = ca.if_else(A3 != 0, k3_quadratic, ca.if_else(B3 != 0, k3_linear, 0.0))
    k3 = ca.if_else(C3 > 0, k3, 0.0)

    delta = delta3 + k3 * e  # (1.12)
    P = P0 + ca.mtimes(Dp, delta)  # (1.3)
    # The printed method has no separation branch (docs/paper-notes.md §3.1): P is
    # returned even when tensile; contact is a diagnostic for the simulator.
    contact = ca.if_else(ca.dot(n, P) > 0, 1.0, 0.0)
    return dict(delta=delta, P=P, k=ca.vertcat(k1, k2, k3), contact=contact)


# ---------------------------------------------------------------------------
# contact_step_robust: docs/paper-notes.md §3 items 1-5 fixed (docs/contact-spec.md §2)
# ---------------------------------------------------------------------------
def _robust(P0, Dp, n, l, mu, u0, friction):
    c = 1 + mu**2
    Dl = ca.mtimes(Dp, l)

    # 1. Stick trial: the whole of l without slip, P_t = P0 + Dp l (1.3).
    P_t = P0 + Dl
    stick = _on_cone(P_t, n, mu)

    # 2. k1 (1.9) with a tolerance on "(1.5) violated" (item 2); clamp
    #    (1.10) as a safeguard only (item 4).
    N0 = ca.dot(n, P0)
    P0_norm = _safe_norm(P0)
    s = P0 - N0 * n  # s = n x (P0 x n)
    ss = ca.dot(s, s)
    Ds = ca.mtimes(Dp, s)
    fires = ca.logic_and(
        _cone_gap(P0, n, mu) >= -CONE_TOL * P0_norm,
        ca.logic_and(N0 > 0, ss > CONE_TOL * P0_norm**2),
    )
    num = ca.dot(P0, Dl) - c * N0 * ca.dot(n, Dl)  # (1.9)
    den = ca.dot(P0, Ds) - c * N0 * ca.dot(n, Ds)  # (1.9)
    k1 = ca.fmax(_safe_div(num, den), 0.0)
    ub = _safe_div(ca.dot(s, u0), ss)  # (1.10)
    k1 = ca.if_else(ub > 0, ca.fmin(k1, ub), k1)
    k1 = ca.if_else(fires, k1, 0.0)

    # 3. k2 (1.11) from P2 = P0 + Dp (l - k1 s) (item 2), a tolerance on
    #    the cone test (item 5), stable roots of A2 lam^2 - 2 B2 lam + C2 = 0.
    l_tau = l - ca.dot(n, l) * n  # l_tau = n x (l x n) (1.8)
    Dl_tau = ca.mtimes(Dp, l_tau)
    P2 = P0 + ca.mtimes(Dp, l - k1 * s)
    N2 = ca.dot(n, P2)
    C2 = _cone(P2, n, c)
    on_cone2 = _on_cone(P2, n, mu)
    A2 = ca.dot(Dl_tau, Dl_tau) - c * ca.dot(n, Dl_tau) ** 2  # (1.11)
    B2 = ca.dot(P2, Dl_tau) - c * N2 * ca.dot(n, Dl_tau)  # (1.11)
    D2 = B2**2 - A2 * C2
    q2 = B2 + _sign_plus(B2) * _safe_sqrt(D2)
    n_Dl_tau = ca.dot(n, Dl_tau)
    k2 = ca.SX(1.0)  # no counting root: k2 = 1
    for denom, lam in ((A2, _safe_div(q2, A2)), (q2, _safe_div(C2, q2))):
        counts = ca.logic_and(
            ca.logic_and(D2 >= 0, ca.fabs(denom) > TINY),
            ca.logic_and(
                ca.logic_and(lam > 0, lam < 1),
                N2 - lam * n_Dl_tau > 0,  # n.(P2 - lam Dp l_tau) > 0
            ),
        )
        k2 = ca.if_else(counts, ca.fmin(k2, lam), k2)
    k2 = ca.if_else(on_cone2, 0.0, k2)

    # 4. k3 by the closed-form roots of (1.13) (item 3).
    delta3 = l - k1 * s - k2 * l_tau  # (1.12)
    P3 = P0 + ca.mtimes(Dp, delta3)  # (1.3)
    N = ca.dot(n, P3)
    t_hat, T = _unit(P3 - N * n)
    e, _ = _unit(ca.cross(n, ca.mtimes(Dp.T, ca.cross(n, P3))))  # (1.12)
    Pe = ca.mtimes(Dp, e)
    a = ca.dot(n, Pe)
    b = ca.dot(t_hat, Pe)  # H = T b (1.14)
    on_cone3 = _on_cone(P3, n, mu)
    if friction:
        # B3^2 - A3 C3 = mu^2 (bN - aT)^2: roots without a square root.
        candidates = ((b - mu * a, _safe_div(mu * N - T, b - mu * a)),
                      (b + mu * a, _safe_div(-(T + mu * N), b + mu * a)))
    else:
        # mu = 0: both roots are -T/b (the cone is the ray along n).
        candidates = ((b, _safe_div(-T, b)),)
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

    # 5. delta (1.12), P (1.3), cone clean-up.
    delta = delta3 + k3 * e
    P = _cone_clean(P0 + ca.mtimes(Dp, delta), n, mu)

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
        ca.dot(P - P_N * n, slip) < -CONE_TOL * _safe_norm(P) * _safe_norm(slip),
        ca.dot(n, P_t) <= 0)
    lift = ca.logic_or(ca.logic_or(P_N <= 0, no_root), anti_coulomb)
    k = ca.vertcat(k1, k2, k3)
    slip = _lift_off(lift, u0, dict(delta=delta, P=P, k=k, contact=ca.SX(1.0)))
    return dict(
        delta=ca.if_else(stick, l, slip["delta"]),
        P=ca.if_else(stick, P_t, slip["P"]),
        k=ca.if_else(stick, ca.SX.zeros(3, 1), slip["k"]),
        contact=ca.if_else(stick, 1.0, slip["contact"]),
    )


# ---------------------------------------------------------------------------
# contact_step_implicit: backward-Euler Coulomb step (docs/contact-spec.md §3)
# ---------------------------------------------------------------------------
def _tangent_basis(n):
    """(e1, e2): orthonormal, orthogonal to n, from the axis least aligned with n.

    The axis is x, y or z, whichever has the smallest |n_i| (the first on a
    tie); |n x axis| >= sqrt(2/3) for a unit n, so e1 = n x axis/|n x axis|
    is orthogonal to n to round-off. e2 = n x e1.
    """
    ax, ay, az = ca.fabs(n[0]), ca.fabs(n[1]), ca.fabs(n[2])
    use_x = ca.logic_and(ax <= ay, ax <= az)
    use_y = ca.logic_and(ca.logic_not(use_x), ay <= az)
    axis = ca.vertcat(ca.if_else(use_x, 1.0, 0.0), ca.if_else(use_y, 1.0, 0.0),
                      ca.if_else(ca.logic_or(use_x, use_y), 0.0, 1.0))
    e1, _ = _unit(ca.cross(n, axis))
    return e1, ca.cross(n, e1)


def _coulomb_check(lam, g1, g2, ok, a1, a2, N_t, mu, N_min):
    """Whether slip (g1, g2) with multiplier lam is a compressive Coulomb solution.

    It is when `ok` (the slip is well defined), the normal force
    N = N_t - a.g exceeds N_min (compressive beyond round-off) and the
    secular equation lam |g| = mu N holds to ROOT_TOL (the squared quartic
    also has the roots of lam |g| = -mu N, removed here by N > 0).
    """
    gg = g1 * g1 + g2 * g2
    N = N_t - (a1 * g1 + a2 * g2)
    # lam |g| = mu N with both sides >= 0, compared squared (no square root):
    # |A - B| <= ROOT_TOL (A + B) for A, B >= 0 is within a factor 2 of the
    # relative test on lam |g| - mu N.
    # The tolerance scales with |N_t| + |a.g|, not N: with a stiff normal
    # coupling N is a difference of large terms and carries their round-off.
    lhs, rhs = lam * lam * gg, mu * mu * N * N
    N_scale = ca.fabs(N_t) + ca.fabs(a1 * g1) + ca.fabs(a2 * g2)
    valid = ca.logic_and(
        ca.logic_and(ok, N > N_min),
        ca.fabs(lhs - rhs) <= ROOT_TOL * (lhs + rhs) + CANCEL_TOL * mu * mu * N_scale * N_scale,
    )
    return valid


def _secular_slip(lam, K11, K12, K21, K22, T, K_norm):
    """g(lam) = (K + lam I)^-1 p = adj(K + lam I) p / det(K + lam I), p = (T, 0).

    Returns (g1, g2, ok), ok False at a root of det(K + lam I) (to DET_TOL).
    """
    det = lam * lam + (K11 + K22) * lam + (K11 * K22 - K12 * K21)
    ok = ca.fabs(det) > DET_TOL * (lam + K_norm) ** 2
    inv = 1.0 / ca.if_else(ok, det, 1.0)
    return (lam + K22) * T * inv, -K21 * T * inv, ok


def _largest_pole(K11, K12, K21, K22, K_norm):
    """The largest lam > 0 where g(lam) = (K + lam I)^-1 p, p = (T, 0), has a pole; 0 if none.

    det(K + lam I) = lam^2 + tr lam + det K has real roots when
    tr^2 - 4 det K >= 0. A positive root r is a pole of g only if the residue
    adj(K + r I) p = T (r + K22, -K21) is not zero (to POLE_TOL): it vanishes
    when p is an eigenvector of K, and g then passes r smoothly.
    """
    tr = K11 + K22
    det_K = K11 * K22 - K12 * K21
    disc = tr * tr - 4 * det_K
    q = -0.5 * (tr + _sign_plus(tr) * _safe_sqrt(disc))
    lam_p = ca.SX(0.0)
    for r in (_safe_div(det_K, q), q):
        active = ca.logic_and(
            ca.logic_and(disc >= 0, r > lam_p),
            _safe_sqrt((r + K22) ** 2 + K21 * K21) > POLE_TOL * (K_norm + r),
        )
        lam_p = ca.if_else(active, r, lam_p)
    return lam_p


def _family_slips(K11, K12, K21, K22, a1, a2, T, N_t, mu, K_norm):
    """The slips at lam = -K22 when K21 = 0: det(K + lam I) = 0 and g not unique.

    With K21 = 0 (t1 an eigenvector of K) and lam* = -K22 > 0, every
    g = (alpha + beta s, s), alpha = T/(K11 + lam*), beta = -K12/(K11 + lam*),
    solves (K + lam* I) g = p; lam* |g| = mu N, N = N0 - gamma s with
    N0 = N_t - a1 alpha and gamma = a1 beta + a2, then fixes s by the quadratic
    A s^2 + 2 B s + C = 0 below. Returns two (lam*, g1, g2, ok).
    """
    lam = -K22
    M11 = K11 + lam
    ok = ca.logic_and(
        ca.logic_and(ca.fabs(K21) <= DET_TOL * K_norm, lam > 0),
        ca.fabs(M11) > DET_TOL * (lam + K_norm),
    )
    inv = 1.0 / ca.if_else(ok, M11, 1.0)
    alpha, beta = T * inv, -K12 * inv
    N0 = N_t - a1 * alpha
    gamma = a1 * beta + a2
    lam2, mu2 = lam * lam, mu * mu
    A = lam2 * (beta * beta + 1) - mu2 * gamma * gamma
    B = lam2 * alpha * beta + mu2 * N0 * gamma
    C = lam2 * alpha * alpha - mu2 * N0 * N0
    disc = B * B - A * C
    ok = ca.logic_and(ok, disc >= 0)
    q = -(B + _sign_plus(B) * _safe_sqrt(disc))  # stable roots q/A and C/q
    out = []
    for s, s_ok in ((_safe_div(q, A), ca.fabs(A) > TINY), (_safe_div(C, q), ca.fabs(q) > TINY)):
        out.append((lam, alpha + beta * s, s, ca.logic_and(ok, s_ok)))
    return out


def _quartic(K11, K12, K21, K22, a1, a2, T, N_t, mu, K_norm):
    """Coefficients [Q0..Q4] of the implicit step's quartic in lam, and its root scale c.

    Q(lam) = lam^2 |adj(K + lam I) p|^2 - mu^2 R(lam)^2 with p = (T, 0):
    |adj p|^2 = T^2 ((lam + K22)^2 + K21^2) and
    R(lam) = N_t det(K + lam I) - a.adj(K + lam I) p = r2 lam^2 + r1 lam + r0.
    The closed form is most accurate with the roots spread evenly around
    c: c = |Q0/Q4|^(1/4), their geometric mean, kept within
    ROOT_SCALE_RANGE of the stiffness scale |K|_F + mu |a| (Q4 or Q0 can
    vanish).
    """
    T2, mu2 = T * T, mu * mu
    r2 = N_t
    r1 = N_t * (K11 + K22) - T * a1
    r0 = N_t * (K11 * K22 - K12 * K21) - T * (a1 * K22 - a2 * K21)
    Q = [-mu2 * r0 * r0,
         -2 * mu2 * r1 * r0,
         T2 * (K22 * K22 + K21 * K21) - mu2 * (r1 * r1 + 2 * r2 * r0),
         2 * T2 * K22 - 2 * mu2 * r2 * r1,
         T2 - mu2 * r2 * r2]
    stiff = K_norm + mu * _safe_sqrt(a1 * a1 + a2 * a2)
    stiff = ca.if_else(stiff > TINY, stiff, 1.0)
    mean = _safe_sqrt(_safe_sqrt(_safe_div(ca.fabs(Q[0]), ca.fabs(Q[4]))))
    return Q, ca.fmin(ca.fmax(mean, stiff / ROOT_SCALE_RANGE), stiff * ROOT_SCALE_RANGE)


def _polish_root(Q, lam):
    """FINAL_STEPS Newton steps on Q at the chosen root, each clipped to FINAL_CLIP lam.

    The candidates are accepted at ROOT_TOL; this brings lam to round-off
    (Coulomb-exact), and its derivative is then the implicit-function one.
    The clip keeps a flat Q (a double root) from moving lam far.
    """
    for _ in range(FINAL_STEPS):
        f = (((Q[4] * lam + Q[3]) * lam + Q[2]) * lam + Q[1]) * lam + Q[0]
        df = ((4 * Q[4] * lam + 3 * Q[3]) * lam + 2 * Q[2]) * lam + Q[1]
        lam = lam - ca.fmin(ca.fmax(_safe_div(f, df), -FINAL_CLIP * lam), FINAL_CLIP * lam)
    return lam


def _select(candidates, n_secular, lam_p, a1, a2, N_t, mu, N_min):
    """The rule: of the valid candidates on the branch, the one of largest lam.

    The branch is lam > lam_p (lam_p the largest pole of g(lam), 0 if none):
    below it the foot would slide through infinity (snap-through). The largest
    lam is the first solution met as the slip grows from zero along g(lam).
    A slip ending at N <= N_min (round-off: the foot slides off its load) is
    not contact. Candidates from index `n_secular` on are family slips.
    Returns (found, lam, g1, g2, family).
    """
    found = ca.SX(0)
    lam_best = g1 = g2 = family = ca.SX(0.0)
    for i, (lam, h1, h2, ok) in enumerate(candidates):
        on_branch = ca.logic_or(lam > lam_p, lam_p <= 0)
        valid = _coulomb_check(lam, h1, h2, ca.logic_and(ok, on_branch), a1, a2, N_t, mu, N_min)
        better = ca.logic_and(valid, ca.logic_or(ca.logic_not(found), lam > lam_best))
        lam_best = ca.if_else(better, lam, lam_best)
        g1, g2 = ca.if_else(better, h1, g1), ca.if_else(better, h2, g2)
        family = ca.if_else(better, 1.0 if i >= n_secular else 0.0, family)
        found = ca.logic_or(found, valid)
    return found, lam_best, g1, g2, family


def _implicit(P0, Dp, n, l, mu, u0, friction):
    r"""Find the tangential slip g with P = P0 + Dp (l - g) on the cone.

    Coulomb's law for the slip g (n.g = 0, the foot slides by -g relative to
    the plane): |P_tau| <= mu n.P, and P_tau = mu (n.P) g/|g| when g != 0.
    In the tangent frame (t1, t2) of the trial force, P_tau(g) = p - K g,
    p = (T_t, 0), and N(g) = N_t - a.g. With lam = mu N/|g| >= 0 this is
    (K + lam I) g = p and lam |g| = mu N; multiplied by det(K + lam I)
    and squared, every slip solution is a real root lam >= 0 of the quartic

        lam^2 |adj(K + lam I) p|^2 = mu^2 (N_t det(K + lam I) - a.adj(K + lam I) p)^2.

    All its roots are found (``contact_quartic.quartic_roots``), plus
    lam = 0 (the frictionless slide, a solution only when mu N = 0); each is
    checked against the unsquared equation with N > 0, and the solution of
    least slip |g| is taken (docs/contact.md, "Selection rule"). Stick wins
    when the trial force is inside the cone; lift-off only when no
    solution exists.
    """
    # 1. Stick trial.
    P_t = P0 + ca.mtimes(Dp, l)  # (1.3) with delta = l
    N_t = ca.dot(n, P_t)
    # The tangential trial force in a fixed tangent basis (e1, e2) built from
    # n and the coordinate axis least aligned with it: e1, e2 are orthogonal
    # to n to round-off whatever P_t is, whereas P_t - N_t n is pure
    # round-off, pointing anywhere, when P_t is along n.
    e1, e2 = _tangent_basis(n)
    c1, c2 = ca.dot(e1, P_t), ca.dot(e2, P_t)
    T_t = _safe_sqrt(c1 * c1 + c2 * c2)
    t1 = _safe_div(c1, T_t) * e1 + _safe_div(c2, T_t) * e2
    # (1.4) as T_t <= mu N_t rather than C(P_t) <= 0 (1.5): at mu = 0,
    # C = |P_tau|^2 loses any |P_tau| below 1e-8 |P_t| to round-off.
    stick = ca.logic_and(T_t <= mu * N_t, N_t > 0)

    # 2. Slip in the tangent frame (t1, t2) of the trial force, p = (T_t, 0).
    t2 = ca.cross(n, t1)
    Dt1 = ca.mtimes(Dp, t1)
    Dt2 = ca.mtimes(Dp, t2)
    K11, K12 = ca.dot(t1, Dt1), ca.dot(t1, Dt2)
    K21, K22 = ca.dot(t2, Dt1), ca.dot(t2, Dt2)
    a1, a2 = ca.dot(n, Dt1), ca.dot(n, Dt2)
    K_norm = _safe_sqrt(K11**2 + K12**2 + K21**2 + K22**2)
    lams = [ca.SX(0.0)]  # the frictionless slide g = K^-1 p
    if friction:
        lams = []
        Q, c = _quartic(K11, K12, K21, K22, a1, a2, T_t, N_t, mu, K_norm)
        lams += quartic_roots(Q, c)
        # lam = 0 (the frictionless slide) solves lam |g| = mu N only when
        # mu N = 0: at mu = 0 it replaces the first root (the quartic is then
        # T^2 lam^2 |w|^2, whose roots are 0 and complex).
        lams[0] = ca.if_else(mu > 0, lams[0], 0.0)
    candidates = [(lam, *_secular_slip(lam, K11, K12, K21, K22, T_t, K_norm)) for lam in lams]
    if friction:
        candidates += _family_slips(K11, K12, K21, K22, a1, a2, T_t, N_t, mu, K_norm)

    # 3. Selection (docs/contact.md, "Selection rule"), then the polish of
    #    the chosen root; family candidates keep their own g.
    found, lam_best, g1, g2, family = _select(
        candidates, len(lams), _largest_pole(K11, K12, K21, K22, K_norm),
        a1, a2, N_t, mu, CONE_TOL * _safe_sqrt(N_t * N_t + T_t * T_t))
    if friction:
        lam = _polish_root(Q, lam_best)
        h1, h2, ok = _secular_slip(lam, K11, K12, K21, K22, T_t, K_norm)
        polish = ca.logic_and(ok, family == 0)
        g1, g2 = ca.if_else(polish, h1, g1), ca.if_else(polish, h2, g2)

    # 4. In contact: delta = l - g, P = P0 + Dp delta (1.3), clean-up.
    g = g1 * t1 + g2 * t2
    delta = l - g
    # On the cone, opposite the slip, by construction: P_tau = mu N g/|g|
    # with N = n.(P0 + Dp delta) (1.3). Rebuilding P_tau from (1.3) instead
    # would leave it off the cone by round-off times cond(D_p) when |g| is
    # large (a long slide of a stiff foot).
    N = ca.dot(n, P0 + ca.mtimes(Dp, delta))
    g_hat, _ = _unit(g)
    P = N * n + mu * N * g_hat
    lift = ca.logic_or(ca.logic_not(found), N <= 0)
    zero = ca.SX.zeros(3, 1)
    slip = _lift_off(lift, u0, dict(delta=delta, P=P, k=ca.if_else(lift, zero, g), contact=ca.SX(1.0)))
    return dict(
        delta=ca.if_else(stick, l, slip["delta"]),
        P=ca.if_else(stick, P_t, slip["P"]),
        k=ca.if_else(stick, zero, slip["k"]),
        contact=ca.if_else(stick, 1.0, slip["contact"]),
    )


# ---------------------------------------------------------------------------
# Public API
# ---------------------------------------------------------------------------
def _check_method(method):
    if method not in METHODS:
        raise ValueError(
            f"`method` must be one of {', '.join(repr(m) for m in METHODS)}; "
            f"got {method!r}."
        )


def _is_literal_zero(mu):
    """True when mu is a plain number (not a symbol) equal to 0."""
    if isinstance(mu, numbers.Real):
        return float(mu) == 0.0
    if isinstance(mu, np.ndarray) and mu.size == 1 and np.isrealobj(mu):
        return float(mu.reshape(())) == 0.0
    return False


def _as_sx(x, name, shape):
    x = ca.SX(x)
    if x.shape != shape:
        if shape[1] == 1 and x.shape == (1, shape[0]):
            x = x.T
        else:
            raise ValueError(f"`{name}` must have shape {shape}; got {x.shape}.")
    return x


def contact_step_expr(method, P0, Dp, n, l, mu, u0, *, friction=None):
    """Build the expressions of one contact step, for inlining in a graph.

    Implements (1.3)-(1.15) of Khvostov (1976) as fixed by
    ``docs/contact-spec.md`` §1 (``'paper'``), §2 (``'robust'``) or §3
    (``'implicit'``): the displacement δ of the foot over the step and the
    force P = P₀ + D_p δ (1.3) satisfying the friction cone (1.5).

    Parameters
    ----------
    method : {'paper', 'robust', 'implicit'}
        Which step.
    P0 : casadi.SX or array_like, shape (3,) or (3, 1)
        Force on the foot from the plane at time t (N).
    Dp : casadi.SX or array_like, shape (3, 3)
        Stiffness matrix ∂P/∂r at the start pose (N/m), any sign pattern.
    n : casadi.SX or array_like, shape (3,)
        Unit normal of the plane, out of the obstacle (dimensionless). Not
        checked here: pass a unit vector.
    l : casadi.SX or array_like, shape (3,)
        Displacement of the plane relative to the body over the step (m);
        n·l > 0 is landing.
    mu : casadi.SX or float
        Coulomb coefficient, ≥ 0 (dimensionless).
    u0 : casadi.SX or array_like, shape (3,)
        Elastic displacement of the foot at t, r₀ − r_free (m); the clamp
        (1.10) and the lift-off pose δ = −u₀ use it.
    friction : bool or None, optional
        ``False`` builds a smaller graph for μ = 0, where the cone is the ray
        along n (P_τ = 0 in contact): no friction code paths, no Newton loop
        in the implicit step (the slip is the frictionless slide
        g = K⁻¹p in one solve), and `mu` is ignored. ``None`` (default)
        means ``False`` when `mu` is the literal number 0 and ``True``
        otherwise. The μ = 0 results equal those of the full graph.

    Returns
    -------
    dict of casadi.SX
        ``delta`` (3, 1), m; ``P`` (3, 1), N; ``k`` (3, 1): (k₁, k₂, k₃)
        for 'paper' and 'robust' (k₁ dimensionless, k₂ dimensionless, k₃ m),
        the slip vector g (m) for 'implicit'; ``contact`` (1, 1): 1 in
        compressive contact, 0 after lift-off.

    References
    ----------
    Khvostov (1976), §1, (1.3)-(1.15); docs/paper-notes.md §3 for the fixes of 'robust'.
    """
    _check_method(method)
    if friction is None:
        friction = not _is_literal_zero(mu)
    P0 = _as_sx(P0, "P0", (3, 1))
    Dp = _as_sx(Dp, "Dp", (3, 3))
    n = _as_sx(n, "n", (3, 1))
    l = _as_sx(l, "l", (3, 1))
    u0 = _as_sx(u0, "u0", (3, 1))
    mu = _as_sx(mu, "mu", (1, 1)) if friction else ca.SX(0.0)
    if method == "paper":
        return _paper(P0, Dp, n, l, mu, u0)
    if method == "robust":
        return _robust(P0, Dp, n, l, mu, u0, friction)
    return _implicit(P0, Dp, n, l, mu, u0, friction)


@functools.lru_cache(maxsize=None)
def _build(method, friction):
    P0 = ca.SX.sym("P0", 3)
    Dp = ca.SX.sym("Dp", 3, 3)
    n = ca.SX.sym("n", 3)
    l = ca.SX.sym("l", 3)
    mu = ca.SX.sym("mu")
    u0 = ca.SX.sym("u0", 3)
    out = contact_step_expr(method, P0, Dp, n, l, mu, u0, friction=friction)
    name = f"contact_step_{method}" + ("" if friction else "_frictionless")
    return ca.Function(
        name,
        [P0, Dp, n, l, mu, u0],
        [out[key] for key in OUTPUT_NAMES],
        INPUT_NAMES,
        OUTPUT_NAMES,
    )


@functools.lru_cache(maxsize=None)
def _build_call(method, friction):
    f = _build(method, friction)
    sym = f.sx_in()
    # never_inline: an SX graph calling this keeps one call node per call, so
    # that a simulator calls one compiled copy instead of inlining eight
    return ca.Function(f"{f.name()}_call", sym, f.call(sym), INPUT_NAMES, OUTPUT_NAMES,
                       {"never_inline": True})


def contact_step_call(method, P0, Dp, n, l, mu, u0, *, friction=None):
    """The step of :func:`contact_step_expr` as a call node of one shared Function.

    Same arguments and returned dict as :func:`contact_step_expr`, but the
    SX graph holds a call of the ``never_inline`` Function
    ``contact_step_<method>[_frictionless]_call`` instead of the step's
    instructions: a graph with several legs and passes contains (and its
    generated C compiles) the step once. Derivatives through the call are
    CasADi's derivative Functions of the call node.
    """
    _check_method(method)
    if friction is None:
        friction = not _is_literal_zero(mu)
    args = [_as_sx(x, name, shape) for x, name, shape in
            ((P0, "P0", (3, 1)), (Dp, "Dp", (3, 3)), (n, "n", (3, 1)), (l, "l", (3, 1)),
             (mu, "mu", (1, 1)), (u0, "u0", (3, 1)))]
    out = _build_call(method, bool(friction))(*args)
    return dict(zip(OUTPUT_NAMES, out))


def contact_step(method, friction=True):
    """The cached ``casadi.Function`` of one contact step.

    Named ``contact_step_paper``, ``contact_step_robust`` or
    ``contact_step_implicit`` (suffix ``_frictionless`` with
    ``friction=False``), with inputs ``P0`` (3), ``Dp`` (3×3), ``n`` (3),
    ``l`` (3), ``mu`` (1), ``u0`` (3) and outputs ``delta`` (3), ``P`` (3),
    ``k`` (3), ``contact`` (1), units and meaning as in
    :func:`contact_step_expr`. The graph is SX, branch-free
    (``casadi.if_else``) and differentiable everywhere except on the
    stick/slip/lift-off switches.

    Parameters
    ----------
    method : {'paper', 'robust', 'implicit'}
        Which step (``docs/contact-spec.md`` §1, §2, §3).
    friction : bool, optional
        ``False`` builds the μ = 0 graph; the ``mu`` input is then ignored.

    Returns
    -------
    casadi.Function

    References
    ----------
    Khvostov (1976), §1, (1.3)-(1.15).
    """
    _check_method(method)
    if not isinstance(friction, bool):
        raise TypeError(f"`friction` must be True or False; got {friction!r}.")
    return _build(method, friction)


@dataclasses.dataclass(frozen=True)
class ContactResult:
    """Result of one contact step (read-only arrays).

    Attributes
    ----------
    delta : numpy.ndarray, shape (3,)
        Displacement of the foot relative to the body over the step (m).
    P : numpy.ndarray, shape (3,)
        Force on the foot from the plane at t + Δt (N).
    k : numpy.ndarray, shape (3,)
        (k₁, k₂, k₃) of (1.8) for 'paper' and 'robust'; the slip vector g
        (m) for 'implicit' (the foot slides by −g relative to the plane).
    contact : bool
        True in compressive contact, False after lift-off.
    """

    delta: np.ndarray
    P: np.ndarray
    k: np.ndarray
    contact: bool


def _show(x):
    """A one-line repr of a bad value for an error message."""
    if isinstance(x, np.ndarray):
        return np.array2string(x, separator=", ", threshold=20).replace("\n", "")
    return repr(x)


def _validate_vector(x, name, shape, hint):
    if isinstance(x, (str, bytes)) or x is None:
        raise TypeError(f"`{name}` must be a real array of shape {shape}; got {x!r}. {hint}")
    try:
        arr = np.asarray(x)
    except Exception as exc:  # ragged sequences and the like
        raise TypeError(f"`{name}` must be a real array of shape {shape}; got {x!r}. {hint}") from exc
    if arr.dtype == bool or not (np.issubdtype(arr.dtype, np.integer) or np.issubdtype(arr.dtype, np.floating)):
        raise TypeError(
            f"`{name}` must be a real array of shape {shape}; got dtype {arr.dtype} ({_show(arr)}). {hint}"
        )
    if arr.shape != shape:
        raise ValueError(f"`{name}` must have shape {shape}; got shape {arr.shape} ({_show(arr)}). {hint}")
    arr = arr.astype(float)
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"`{name}` must be finite; got {_show(arr)}. Replace the NaN/inf entries.")
    return arr


def solve_contact(method, P0, Dp, n, l, mu, u0=None):
    """Evaluate one contact step on NumPy data, validating the inputs.

    Computes δ and P = P₀ + D_p δ (1.3) of the step `method` (see
    :func:`contact_step_expr`), with P inside the friction cone (1.5) for
    'robust' and 'implicit'.

    Parameters
    ----------
    method : {'paper', 'robust', 'implicit'}
        Which step.
    P0 : array_like, shape (3,)
        Force on the foot from the plane at time t (N).
    Dp : array_like, shape (3, 3)
        Stiffness matrix ∂P/∂r at the start pose (N/m).
    n : array_like, shape (3,)
        Unit normal of the plane, out of the obstacle; |n| = 1 within
        ``UNIT_TOL``.
    l : array_like, shape (3,)
        Displacement of the plane relative to the body over the step (m).
    mu : float
        Coulomb coefficient, finite and ≥ 0.
    u0 : array_like, shape (3,), optional
        Elastic displacement of the foot at t (m); default zero.

    Returns
    -------
    ContactResult

    Raises
    ------
    TypeError
        An argument is not a real number or array.
    ValueError
        Wrong shape, non-finite entry, |n| ≠ 1, μ < 0, or unknown method.
    """
    _check_method(method)
    P0 = _validate_vector(P0, "P0", (3,), "Pass the force as a 3-vector in N.")
    Dp = _validate_vector(Dp, "Dp", (3, 3), "Pass the stiffness matrix dP/dr as a 3x3 array in N/m.")
    n = _validate_vector(n, "n", (3,), "Pass the plane normal as a 3-vector.")
    norm_n = float(np.linalg.norm(n))
    if abs(norm_n - 1.0) > UNIT_TOL:
        raise ValueError(
            f"`n` must be a unit vector (|n| = 1 within {UNIT_TOL:g}); got |n| = {norm_n!r} "
            f"for n = {_show(n)}. Pass n / np.linalg.norm(n)."
        )
    l = _validate_vector(l, "l", (3,), "Pass the plane displacement as a 3-vector in m.")
    if isinstance(mu, (bool, np.bool_)) or not isinstance(mu, (numbers.Real, np.ndarray)):
        raise TypeError(f"`mu` must be a real number; got {mu!r}. Pass a float such as 0.3.")
    mu_arr = np.asarray(mu)
    if mu_arr.shape != () or not np.isrealobj(mu_arr) or mu_arr.dtype == bool:
        raise TypeError(f"`mu` must be a real scalar; got {mu!r}. Pass a float such as 0.3.")
    mu = float(mu_arr)
    if not np.isfinite(mu) or mu < 0:
        raise ValueError(f"`mu` must be finite and >= 0; got {mu!r}. Pass a Coulomb coefficient such as 0.3.")
    if u0 is None:
        u0 = np.zeros(3)
    u0 = _validate_vector(u0, "u0", (3,), "Pass the elastic displacement r0 - r_free as a 3-vector in m, or None.")

    out = contact_step(method)(P0=P0, Dp=Dp, n=n, l=l, mu=mu, u0=u0)
    arrays = {}
    for key in ("delta", "P", "k"):
        arr = np.array(out[key]).reshape(3)
        arr.flags.writeable = False
        arrays[key] = arr
    return ContactResult(contact=bool(float(out["contact"]) > 0.5), **arrays)


def stack_inputs(cases):
    """Arguments of ``contact_step(method).map(len(cases))`` from a list of cases.

    Parameters
    ----------
    cases : sequence of (P0, Dp, n, l, mu, u0)
        Per case: P0 (3,), Dp (3, 3), n (3,), l (3,), mu scalar, u0 (3,).

    Returns
    -------
    list of ndarray
        P0, n, l, u0 as (3, N); Dp as (3, 3N); mu as (1, N).
    """
    return [
        np.array([c[0] for c in cases], dtype=float).T,
        np.hstack([np.asarray(c[1], dtype=float) for c in cases]),
        np.array([c[2] for c in cases], dtype=float).T,
        np.array([c[3] for c in cases], dtype=float).T,
        np.array([[c[4] for c in cases]], dtype=float),
        np.array([c[5] for c in cases], dtype=float).T,
    ]
