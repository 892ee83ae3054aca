"""The exact backward-Euler Coulomb contact step (docs/contact-spec.md §3).

This module owns ``implicit_step`` (the return mapping for the linearised
force law (1.3), valid in 3-D, docs/paper-notes.md §3 item 6) and its
pieces: the tangent frame, the secular equation of the slip multiplier, its
quartic, the check of each candidate against the unsquared equation, and the
selection rule (docs/contact.md, "Selection rule"), with the tolerances they
use; and the step's split into its stick trial, its slip part and their
merge (``stick_trial``, ``slip_step``, ``merge_stick``), which the
conditional call of ``symcushion.contact`` reuses. It must not find polynomial roots itself (``symcushion.contact.quartic``
does, without knowing about contact), implement the printed or robust step,
validate inputs or build Functions (``symcushion.contact``).
"""
from __future__ import annotations

import casadi as ca

from symcushion.contact.guards import (CONE_TOL, TINY, at_least, at_most, exceeds, lift_off,
    safe_div, safe_sqrt, sign_plus, unit, within)
from symcushion.contact.quartic import halley_step, horner, quartic_roots

__all__ = [
    "stick_trial",
    "CANCEL_TOL",
    "DET_TOL",
    "FINAL_CLIP",
    "FINAL_STEPS",
    "POLE_TOL",
    "ROOT_SCALE_RANGE",
    "ROOT_TOL",
    "implicit_step",
    "merge_stick",
    "slip_step",
]

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
# Halley steps (contact_quartic.halley_step) of the implicit step on the
# chosen root of the quartic: a candidate accepted at ROOT_TOL (with a stiff
# normal coupling, relative to |N_t| + |a.g| rather than N) can be off by
# ~1e-3 relative; one step (cubic convergence) takes that to ~1e-9, the
# second to round-off, and its derivative is then the implicit-function
# derivative. (Three Newton steps did the same for 5 ns more.)
FINAL_STEPS = 2
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
    e1, _ = unit(ca.cross(n, axis))
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
        within(lhs - rhs, ROOT_TOL * (lhs + rhs) + CANCEL_TOL * mu * mu * N_scale * N_scale),
    )
    return valid


def _secular_slip(lam, K11, K12, K21, K22, T, K_norm):
    """g(lam) = (K + lam I)^-1 p = adj(K + lam I) p / det(K + lam I), p = (T, 0).

    Returns (g1, g2, ok), ok False at a root of det(K + lam I) (to DET_TOL).
    """
    det = lam * lam + (K11 + K22) * lam + (K11 * K22 - K12 * K21)
    ok = exceeds(det, DET_TOL * (lam + K_norm) ** 2)
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
    q = -0.5 * (tr + sign_plus(tr) * safe_sqrt(disc))
    lam_p = ca.SX(0.0)
    for r in (safe_div(det_K, q), q):
        active = ca.logic_and(
            ca.logic_and(disc >= 0, r > lam_p),
            safe_sqrt((r + K22) ** 2 + K21 * K21) > POLE_TOL * (K_norm + r),
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
        ca.logic_and(within(K21, DET_TOL * K_norm), lam > 0),
        exceeds(M11, DET_TOL * (lam + K_norm)),
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
    q = -(B + sign_plus(B) * safe_sqrt(disc))  # stable roots q/A and C/q
    out = []
    for s, s_ok in ((safe_div(q, A), exceeds(A, TINY)),
                    (safe_div(C, q), exceeds(q, TINY))):
        out.append((lam, alpha + beta * s, s, ca.logic_and(ok, s_ok)))
    return out


def _quartic(K11, K12, K21, K22, a1, a2, T, T2, N_t, mu, K_norm):
    """Coefficients [Q0..Q4] of the implicit step's quartic in lam, and its root scale c.

    Q(lam) = lam^2 |adj(K + lam I) p|^2 - mu^2 R(lam)^2 with p = (T, 0)
    (T2 = T^2, as the caller has it):
    |adj p|^2 = T^2 ((lam + K22)^2 + K21^2) and
    R(lam) = N_t det(K + lam I) - a.adj(K + lam I) p = r2 lam^2 + r1 lam + r0.
    The closed form is most accurate with the roots spread evenly around
    c: c = |Q0/Q4|^(1/4), their geometric mean, kept within
    ROOT_SCALE_RANGE of the stiffness scale |K|_F + mu |a| (Q4 or Q0 can
    vanish).
    """
    mu2 = mu * mu
    r2 = N_t
    r1 = N_t * (K11 + K22) - T * a1
    r0 = N_t * (K11 * K22 - K12 * K21) - T * (a1 * K22 - a2 * K21)
    Q = [-mu2 * r0 * r0,
         -2 * mu2 * r1 * r0,
         T2 * (K22 * K22 + K21 * K21) - mu2 * (r1 * r1 + 2 * r2 * r0),
         2 * T2 * K22 - 2 * mu2 * r2 * r1,
         T2 - mu2 * r2 * r2]
    stiff = K_norm + mu * safe_sqrt(a1 * a1 + a2 * a2)
    stiff = ca.if_else(stiff > TINY, stiff, 1.0)
    mean = safe_sqrt(safe_sqrt(safe_div(ca.fabs(Q[0]), ca.fabs(Q[4]))))
    return Q, at_most(at_least(mean, stiff / ROOT_SCALE_RANGE), stiff * ROOT_SCALE_RANGE)


def _polish_root(Q, lam):
    """FINAL_STEPS Halley steps on Q at the chosen root, each clipped to FINAL_CLIP lam.

    The candidates are accepted at ROOT_TOL; this brings lam to round-off
    (Coulomb-exact), and its derivative is then the implicit-function one.
    The clip keeps a flat Q (a double root) from moving lam far.
    """
    for _ in range(FINAL_STEPS):
        step = halley_step(*horner(Q, lam))
        lam = lam - at_most(at_least(step, -FINAL_CLIP * lam), FINAL_CLIP * lam)
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


def _trial_direction(P_t, n):
    """(N_t, T_t, t1): normal and tangential magnitudes of the trial force, and its tangent direction.

    Shapes: P_t, n (3, 1), N. Returns N_t = n.P_t (1, 1), N; T_t = |P_t,tau|
    (1, 1), N; t1 (3, 1), unit along P_t,tau (0 when T_t = 0).
    """
    N_t = ca.dot(n, P_t)
    # The tangential trial force in a fixed tangent basis (e1, e2) built from
    # n and the coordinate axis least aligned with it: e1, e2 are orthogonal
    # to n to round-off whatever P_t is, whereas P_t - N_t n is pure
    # round-off, pointing anywhere, when P_t is along n.
    e1, e2 = _tangent_basis(n)
    c1, c2 = ca.dot(e1, P_t), ca.dot(e2, P_t)
    T_t = safe_sqrt(c1 * c1 + c2 * c2)
    t1 = safe_div(c1, T_t) * e1 + safe_div(c2, T_t) * e2
    return N_t, T_t, t1


def stick_trial(P0, Dp, n, l, mu):
    """The stick trial of the implicit step: (P_t, N_t, T_t, t1, stick).

    P_t = P0 + Dp l (1.3) with delta = l, its normal part N_t = n.P_t, its
    tangential magnitude T_t and direction t1 (:func:`_trial_direction`), and
    the flag stick: P_t loads the foot and lies inside the cone (1.4).
    Shared by :func:`implicit_step` and by the conditional wrapper of
    ``symcushion.contact`` (which runs the slip part only when this flag is
    false), so that both take the same branch bit for bit.
    """
    P_t = P0 + ca.mtimes(Dp, l)  # (1.3) with delta = l
    N_t, T_t, t1 = _trial_direction(P_t, n)
    # (1.4) as T_t <= mu N_t rather than C(P_t) <= 0 (1.5): at mu = 0,
    # C = |P_tau|^2 loses any |P_tau| below 1e-8 |P_t| to round-off.
    stick = ca.logic_and(T_t <= mu * N_t, N_t > 0)
    return P_t, N_t, T_t, t1, stick


def _tangent_stiffness(Dp, n, t1):
    """The tangent frame (t1, t2 = n x t1) and Dp in it: K (2 x 2), a = n.Dp t_i, |K|_F.

    Shapes: Dp (3, 3), N/m; n, t1 (3, 1). Returns (t2 (3, 1); K11, K12,
    K21, K22, a1, a2, K_norm, each (1, 1), N/m).
    """
    t2 = ca.cross(n, t1)
    Dt1 = ca.mtimes(Dp, t1)
    Dt2 = ca.mtimes(Dp, t2)
    K11, K12 = ca.dot(t1, Dt1), ca.dot(t1, Dt2)
    K21, K22 = ca.dot(t2, Dt1), ca.dot(t2, Dt2)
    a1, a2 = ca.dot(n, Dt1), ca.dot(n, Dt2)
    K_norm = safe_sqrt(K11**2 + K12**2 + K21**2 + K22**2)
    return t2, K11, K12, K21, K22, a1, a2, K_norm


def implicit_step(P0, Dp, n, l, mu, u0, friction, slip_part=None):
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
    checked against the unsquared equation with N > 0, and the first
    solution on the branch connected to zero slip is taken (docs/contact.md,
    "Selection rule"). Stick wins when the trial force is inside the cone;
    lift-off only when no solution exists.

    Arguments and returned dict as :func:`symcushion.contact.contact_step_expr`
    after its conversion: P0, n, l, u0 (3, 1), Dp (3, 3) and mu (1, 1)
    ``casadi.SX``, in N, m and N/m; ``k`` holds the slip g (3, 1), m.
    `friction` False builds the mu = 0 step: lam = 0 only, no quartic.
    `slip_part` (default :func:`slip_step`) builds the slip part from the
    same arguments as :func:`slip_step`; ``symcushion.contact`` passes one
    that inlines the compiled slip branch of its conditional call, so that
    the full step executes exactly the branch's operations.
    """
    slip_part = slip_step if slip_part is None else slip_part
    P_t, N_t, T_t, t1, stick = stick_trial(P0, Dp, n, l, mu)
    slip = slip_part(P0, Dp, n, l, mu, u0, N_t, T_t, T_t * T_t, t1, friction)
    return merge_stick(stick, l, P_t, slip)


def merge_stick(stick, l, P_t, slip):
    """The step's outputs: the stick answer (delta = l, P = P_t) where `stick`, else `slip`.

    Shapes as :func:`implicit_step`'s outputs; `slip` is a dict of the same
    keys. Shared by the full step and the branches of the conditional
    wrapper of ``symcushion.contact``, so that both give the same bits.
    """
    zero = ca.SX.zeros(3, 1)
    return dict(
        delta=ca.if_else(stick, l, slip["delta"]),
        P=ca.if_else(stick, P_t, slip["P"]),
        k=ca.if_else(stick, zero, slip["k"]),
        contact=ca.if_else(stick, 1.0, slip["contact"]),
    )


def slip_step(P0, Dp, n, l, mu, u0, N_t, T_t, T2, t1, friction):
    """The implicit step for a foot that does not stick: slip or lift-off.

    N_t, T_t and t1 are the trial force's normal and tangential magnitudes
    (N) and its unit tangent direction (3, 1) from :func:`stick_trial`, and
    T2 (N^2) is T_t * T_t as the trial's graph computes it: the slip part
    never squares T_t itself, so that it gives the same bits whether these
    are the trial's expressions or numbers passed from a separate Function
    (in one graph CasADi simplifies the square of T_t's guarded square root
    to its argument). Returns the dict of :func:`implicit_step` for the slip
    or lift-off answer (its value where the trial sticks is unused).
    """
    # Slip in the tangent frame (t1, t2) of the trial force, p = (T_t, 0).
    t2, K11, K12, K21, K22, a1, a2, K_norm = _tangent_stiffness(Dp, n, t1)
    lams = [ca.SX(0.0)]  # the frictionless slide g = K^-1 p
    if friction:
        lams = []
        Q, c = _quartic(K11, K12, K21, K22, a1, a2, T_t, T2, N_t, mu, K_norm)
        lams += quartic_roots(Q, c)
        # lam = 0 (the frictionless slide) solves lam |g| = mu N only when
        # mu N = 0: at mu = 0 it replaces the first root (the quartic is then
        # T^2 lam^2 |w|^2, whose roots are 0 and complex).
        lams[0] = ca.if_else(mu > 0, lams[0], 0.0)
    candidates = [(lam, *_secular_slip(lam, K11, K12, K21, K22, T_t, K_norm)) for lam in lams]
    if friction:
        candidates += _family_slips(K11, K12, K21, K22, a1, a2, T_t, N_t, mu, K_norm)

    # Selection (docs/contact.md, "Selection rule"), then the polish of the
    # chosen root; family candidates keep their own g.
    found, lam_best, g1, g2, family = _select(
        candidates, len(lams), _largest_pole(K11, K12, K21, K22, K_norm),
        a1, a2, N_t, mu, CONE_TOL * safe_sqrt(N_t * N_t + T2))
    if friction:
        lam = _polish_root(Q, lam_best)
        h1, h2, ok = _secular_slip(lam, K11, K12, K21, K22, T_t, K_norm)
        polish = ca.logic_and(ok, family == 0)
        g1, g2 = ca.if_else(polish, h1, g1), ca.if_else(polish, h2, g2)

    # In contact: delta = l - g, P = P0 + Dp delta (1.3), clean-up.
    g = g1 * t1 + g2 * t2
    delta = l - g
    # On the cone, opposite the slip, by construction: P_tau = mu N g/|g|
    # with N = n.(P0 + Dp delta) (1.3). Rebuilding P_tau from (1.3) instead
    # would leave it off the cone by round-off times cond(D_p) when |g| is
    # large (a long slide of a stiff foot).
    N = ca.dot(n, P0 + ca.mtimes(Dp, delta))
    g_hat, _ = unit(g)
    P = N * n + mu * N * g_hat
    lift = ca.logic_or(ca.logic_not(found), N <= 0)
    zero = ca.SX.zeros(3, 1)
    return lift_off(lift, u0, dict(delta=delta, P=P, k=ca.if_else(lift, zero, g),
                                   contact=ca.SX(1.0)))
