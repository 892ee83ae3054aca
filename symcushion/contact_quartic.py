"""All real roots of a quartic, branch-free in CasADi SX, for the implicit contact step.

This module owns one numerical kernel: the real roots λ ≥ 0 of a polynomial
of degree at most four, Q(λ) = Σ_k Q_k λ^k, as a fixed list of candidates
computed by a closed form (Ferrari's resolvent cubic) whose two quadratic
factors are refined by a Newton step, with no data-dependent control flow.
It knows nothing about contact, friction or forces: the caller
(``symcushion.contact_implicit``) forms the coefficients, validates each
candidate against its own equation, chooses among them and polishes the
chosen one. It must not decide which root is physical.

Numerics (why the steps below are as they are):

- Q is first written in t = λ/(c + λ) ∈ [0, 1), c > 0 a scale of the roots.
  λ = 0 and λ → ∞ map to t = 0 and t = 1, so neither a vanishing leading
  coefficient (a root running off to infinity: the grazing slip) nor a
  vanishing constant term (a root at λ = 0) makes the closed form divide by
  zero; the t-quartic degenerates only when −c is a root of Q, which is
  irrelevant for λ ≥ 0.
- Ferrari's closed form factors the depressed quartic (t shifted by b/4)
  into two quadratics. When the roots sit in two clusters (two close roots
  near t = 0, two near t = 1) the shift is large against the spread within
  a cluster and the depressed coefficients lose the digits that separate
  the close roots (a root 28 % off was seen). One Newton step on the four
  equations of the factorisation, with residuals from the undepressed
  coefficients, restores the factors to round-off (FACTOR_STEPS); each
  factor's roots then come from the stable quadratic formula. The
  candidates are accurate enough for the caller's residual test without a
  Newton polish of their own (four steps per root before the refinement).
- A complex pair re +- i im becomes the two reals re +- im. Two close real
  roots can come out as a complex pair with a tiny imaginary part; the
  caller's test then sees two numbers on either side of the pair rather
  than its midpoint, and its own polish starts from the one it keeps.
"""
from __future__ import annotations

import math

import casadi as ca

from .contact_guards import TINY, at_least, at_most, exceeds, safe_div, safe_sqrt

__all__ = ["FACTOR_STEPS", "quartic_roots"]

# Newton steps on the two quadratic factors of the quartic after Ferrari's
# closed form (see _refine_factors). One brings the factors from the
# depressed quartic's lost digits back to round-off: with it the candidates
# need no Newton polish of their own (none of the 60 000 random cases of
# tests/test_contact_exact.py goes wrong). Without it each candidate needed
# 4 Newton steps: with 2, 3 of those cases took another solution or lifted
# off (close roots far below c).
FACTOR_STEPS = 1
# The guarded division and square root are those of the contact step
# (contact_guards: |x| <= TINY is taken as 0, the untaken branch is finite).
_TINY = TINY
_div = safe_div
_sqrt = safe_sqrt


def _cbrt(x):
    """Real cube root, sign(x) |x|^(1/3), guarded at 0."""
    ok = exceeds(x, _TINY)
    mag = ca.power(ca.if_else(ok, ca.fabs(x), 1.0), 1.0 / 3.0)
    return ca.if_else(ok, ca.sign(x) * mag, 0.0)


def _largest_cubic_root(A, B, C):
    """The largest real root of z^3 + A z^2 + B z + C, closed form + 2 Newton steps."""
    P = B - A * A / 3
    Qc = 2 * A**3 / 27 - A * B / 3 + C
    disc = Qc * Qc / 4 + P**3 / 27
    # one real root (disc > 0): Cardano in the cancellation-free form
    u = _cbrt(-Qc / 2 - ca.if_else(Qc >= 0, 1.0, -1.0) * _sqrt(disc))
    w_one = u - _div(P, 3 * u)
    # three real roots (disc <= 0, P <= 0): the largest, trigonometric form
    m = _sqrt(-P / 3)
    arg = _div(-Qc, 2 * m**3)
    # acos has an infinite slope at +-1: evaluate it strictly inside, and
    # take its limits 0 and pi outside (SX differentiates untaken branches).
    inside = ca.logic_and(arg < 1, arg > -1)  # |arg| < 1
    angle = ca.if_else(inside, ca.acos(ca.if_else(inside, arg, 0.0)), ca.if_else(arg > 0, 0.0, ca.pi))
    w_three = 2 * m * ca.cos(angle / 3)
    z = ca.if_else(disc > 0, w_one, w_three) - A / 3
    for _ in range(2):  # the closed form loses digits when P ~ 0 or disc ~ 0
        f = ((z + A) * z + B) * z + C
        df = (3 * z + 2 * A) * z + B
        z = z - _div(f, df)
    return z


def _factor_residual(factors, b, cc, d, e):
    """How far (t^2 + A1 t + B1)(t^2 + A2 t + B2) is from t^4 + b t^3 + cc t^2 + d t + e."""
    A1, B1, A2, B2 = factors
    return A1 + A2 - b, B1 + B2 + A1 * A2 - cc, A1 * B2 + A2 * B1 - d, B1 * B2 - e


def _refine_factors(factors, b, cc, d, e):
    """One Newton step on the factorisation t^4 + b t^3 + cc t^2 + d t + e = (t^2 + A1 t + B1)(t^2 + A2 t + B2).

    Ferrari's factors come from the depressed quartic, which loses the
    digits of d and e when the roots sit in two clusters (the shift b/4 is
    large against the spread within a cluster: two close roots at t ~ 0, two
    at t ~ 1). The residual of the four coefficient equations uses d and e
    themselves, so one step restores the factors to round-off, and the close
    roots with them. The 4 x 4 Newton system is solved by elimination of
    dA2 and Cramer's rule on the rest; its determinant is the resultant of
    the two factors, zero when they share a root. The step is kept only
    where it lowers the residual (a shared root, or a factor far off).
    """
    A1, B1, A2, B2 = factors
    F1, F2, F3, F4 = _factor_residual(factors, b, cc, d, e)
    R2 = A1 * F1 - F2
    R3 = B1 * F1 - F3
    dA, dB = A2 - A1, B2 - B1
    w = A2 * B1 - A1 * B2
    det = dA * w + dB * dB
    inv = _div(1.0, det)
    dA1 = (R2 * w + R3 * dB + F4 * dA) * inv
    dB1 = (dA * (R3 * B1 + F4 * A1) - (R2 * B1 + F4) * dB) * inv
    dB2 = ((R2 * B2 + F4) * dB - dA * (F4 * A2 + R3 * B2)) * inv
    new = (A1 + dA1, B1 + dB1, A2 - F1 - dA1, B2 + dB2)
    old_res = sum(r * r for r in (F1, F2, F3, F4))
    new_res = sum(r * r for r in _factor_residual(new, b, cc, d, e))
    better = new_res < old_res
    return tuple(ca.if_else(better, x_new, x_old) for x_new, x_old in zip(new, factors))


def _quadratic_roots(A, B):
    """Two starts for the roots of t^2 + A t + B: the real roots, or re +- im of a complex pair.

    Real roots by the stable formula: the larger in magnitude
    -(A + sign(A) sqrt(disc))/2 and the other B over it, neither a
    difference of nearly equal numbers. A complex pair re +- i im becomes
    the two starts re +- im: two close real roots that round-off turned
    complex are then approached from either side, not from their midpoint,
    where Q' ~ 0.
    """
    disc = A * A - 4 * B
    root = _sqrt(ca.fabs(disc))
    big = -(A + ca.if_else(A >= 0, root, -root)) / 2
    real = disc >= 0
    return [ca.if_else(real, big, (root - A) / 2),
            ca.if_else(real, _div(B, big), -(A + root) / 2)]


def quartic_roots(Q, c):
    """Candidates for the real roots λ ≥ 0 of Q(λ) = Q[0] + Q[1] λ + ... + Q[4] λ^4.

    Parameters
    ----------
    Q : sequence of 5 casadi.SX
        Coefficients in ascending powers of λ; any of them may vanish.
    c : casadi.SX
        A positive scale of the roots (units of λ); the closed form is most
        accurate for roots within a few decades of it.

    Returns
    -------
    list of 4 casadi.SX
        Candidate roots λ_i ≥ 0, not polished. Every real root λ ≥ 0 of Q
        that is separated from the others is among them to round-off of the
        refined factors (a double root to about the square root of it); a
        candidate
        may also be the real part of a complex pair or a clipped negative
        root, so the caller must check each one against its own equation.
    """
    q = [Q[k] * c**k for k in range(5)]
    # Q(c t/(1 - t)) (1 - t)^4 = sum_k q_k t^k (1 - t)^(4 - k)
    t_coef = [sum(q[k] * math.comb(4 - k, j - k) * (-1) ** (j - k) for k in range(j + 1))
              for j in range(5)]
    lead = t_coef[4]
    # monic t^4 + b t^3 + cc t^2 + d t + e
    b, cc, d, e = (_div(t_coef[k], lead) for k in (3, 2, 1, 0))
    # depressed y^4 + p y^2 + r1 y + r0, t = y - b/4
    p = cc - 3 * b * b / 8
    r1 = d - b * cc / 2 + b**3 / 8
    r0 = e - b * d / 4 + b * b * cc / 16 - 3 * b**4 / 256
    # resolvent z^3 + 2p z^2 + (p^2 - 4 r0) z - r1^2 = 0 has a root z >= 0
    z = at_least(_largest_cubic_root(2 * p, p * p - 4 * r0, -r1 * r1), 0.0)
    s = _sqrt(z)
    # (y^2 + s y + alpha)(y^2 - s y + beta), alpha + beta = p + z,
    # beta - alpha = r1/s = sign(r1) sqrt((p + z)^2 - 4 r0) (no division by s)
    m = ca.if_else(r1 >= 0, 1.0, -1.0) * _sqrt((p + z) ** 2 - 4 * r0)
    alpha = (p + z - m) / 2
    beta = (p + z + m) / 2
    # The two factors in t (y = t + b/4): t^2 + A1 t + B1 and t^2 + A2 t + B2.
    factors = (b / 2 + s, b * b / 16 + s * b / 4 + alpha,
               b / 2 - s, b * b / 16 - s * b / 4 + beta)
    for _ in range(FACTOR_STEPS):
        factors = _refine_factors(factors, b, cc, d, e)
    roots_t = []
    for A, B in (factors[:2], factors[2:]):
        roots_t += _quadratic_roots(A, B)

    # lambda = c t/(1 - t); t = 1 (a root at infinity) gives 0, as a
    # guarded division, and the caller's check rejects it.
    return [c * _div(t, 1 - t) for t in (at_most(at_least(t, 0.0), 1.0) for t in roots_t)]
