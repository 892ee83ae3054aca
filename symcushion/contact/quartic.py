"""All real roots of a quartic, branch-free in CasADi SX, for the implicit contact step.

This module owns one numerical kernel: the real roots λ ≥ 0 of a polynomial
of degree at most four, Q(λ) = Σ_k Q_k λ^k, as a fixed list of candidates
computed by a closed form (Ferrari's resolvent cubic) and polished by Halley
steps, with no data-dependent control flow. It knows nothing about contact,
friction or forces: the caller (``symcushion.contact.implicit``) forms the
coefficients, validates each candidate against its own equation and chooses
among them. It must not decide which root is physical.

Numerics (why the steps below are as they are):

- Q is first written in t = λ/(c + λ) ∈ [0, 1), c > 0 a scale of the roots.
  λ = 0 and λ → ∞ map to t = 0 and t = 1, so neither a vanishing leading
  coefficient (a root running off to infinity: the grazing slip) nor a
  vanishing constant term (a root at λ = 0) makes the closed form divide by
  zero; the t-quartic degenerates only when −c is a root of Q, which is
  irrelevant for λ ≥ 0.
- Ferrari's closed form returns four numbers: the real roots, and for a
  complex pair re +- i im the two reals re +- im. Two close real roots can
  come out as a complex pair with a tiny imaginary part; re +- im then
  starts Newton on either side of the pair rather than at its midpoint
  (where Q' ~ 0 would throw the step far away). Every one of the four is
  polished and the caller's residual test decides.
- Each candidate is polished by POLISH_STEPS Halley steps in λ/c when
  t ≤ 1/2 and in c/λ (the reversed polynomial) when t > 1/2: both variables
  are then ≤ 1, and the iteration converges from the closed form's absolute
  error whenever the root is separated from the others by more than that
  error. A Halley step x − 2QQ'/(2Q'² − QQ'') is cubically convergent and
  costs one division, as a Newton step does: two of them reach what four
  Newton steps did, for about half the time (docs/contact.md, "Where the
  implicit step's time goes"). At a converged root (Q = 0) its derivative
  is the implicit-function derivative −∂Q/∂θ / Q'(λ), as Newton's is.
"""
from __future__ import annotations

import math

import casadi as ca

from symcushion.contact.guards import TINY, at_least, at_most, exceeds, safe_div, safe_sqrt, within

__all__ = ["POLISH_STEPS", "halley_step", "horner", "quartic_roots"]

# Halley steps per candidate after the closed form. One reaches round-off
# for a well-separated root; roots a few decades below the scale c, or with a
# close neighbour, start ~1e-4 off. With 2 Newton steps such roots were
# missed in about 1 of 2 000 random cases (tests/oracle_coulomb.py), with 4
# in none of 60 000; 2 Halley steps (order 9 together, against 16) miss none
# of those 60 000 and, like the 4 Newton steps, about 1 in 300 000.
POLISH_STEPS = 2
# The scale c is doubled when |Q(-c)| is below this fraction of sum |Q_k c^k|
# (the t-quartic then nearly loses its leading term).
SHIFT_TOL = 1e-2
# Bound of the polished variable (lam/c or c/lam, in [0, 1] at a root the
# closed form placed well): Newton steps from a start where Q is flat are
# clipped to it, so that Q(x) cannot overflow.
X_MAX = 4.0
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
    """The largest real root of z^3 + A z^2 + B z + C, closed form + 1 Halley step."""
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
    # The closed form loses digits when P ~ 0 or disc ~ 0: one Halley step
    # (as accurate as the two Newton steps it replaced, and cheaper).
    return z - halley_step(((z + A) * z + B) * z + C, (3 * z + 2 * A) * z + B, 3 * z + A)


def horner(coeffs, x):
    """(p(x), p'(x), p''(x)/2) for coefficients [a0, a1, ..., a4] (ascending powers)."""
    p, dp, hp = coeffs[-1], 0.0, 0.0
    for a in reversed(coeffs[:-1]):
        hp = hp * x + dp
        dp = dp * x + p
        p = p * x + a
    return p, dp, hp


def halley_step(f, df, hf):
    """The Halley correction f f'/(f'^2 - f f''/2): the next iterate is x minus it.

    f, df are f(x) and f'(x), hf is f''(x)/2 (as :func:`horner` returns
    them). The correction is 0 where its denominator vanishes
    (``contact_guards.safe_div``).
    """
    return _div(f * df, df * df - f * hf)


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
        Candidate roots λ_i ≥ 0. Every real root λ ≥ 0 of Q that is
        separated from the others is among them to round-off; a candidate
        may also be the real part of a complex pair or a clipped negative
        root, so the caller must check each one against its own equation.
    """
    # The t-quartic's leading coefficient is sum_k q_k (-1)^(4-k) = Q(-c): it
    # vanishes when -c is a root of Q, and the closed form then divides by
    # ~0 and loses the other roots (a near-double root at -c left a positive
    # root 6e-6 off after the polish). Such a c is moved to 2c.
    at_minus_c = (((Q[4] * c - Q[3]) * c + Q[2]) * c - Q[1]) * c + Q[0]
    size = (((ca.fabs(Q[4]) * c + ca.fabs(Q[3])) * c + ca.fabs(Q[2])) * c
            + ca.fabs(Q[1])) * c + ca.fabs(Q[0])
    c = ca.if_else(within(at_minus_c, SHIFT_TOL * size), 2 * c, c)
    c2 = c * c
    powers = (1.0, c, c2, c2 * c, c2 * c2)
    q = [Q[k] * powers[k] for k in range(5)]
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
    roots_t = []
    for sgn, const in ((1.0, alpha), (-1.0, beta)):
        disc = s * s - 4 * const
        # A complex pair re +- i im becomes the two starts re +- im: two close
        # real roots that round-off turned complex are then approached from
        # either side, not from their midpoint, where Q' ~ 0.
        root = _sqrt(ca.fabs(disc))
        roots_t += [(-sgn * s + root) / 2 - b / 4, (-sgn * s - root) / 2 - b / 4]

    rev = list(reversed(q))  # in c/lambda: sum_k q_k x^(4-k)
    out = []
    for t in roots_t:
        t = at_most(at_least(t, 0.0), 1.0)
        small = t <= 0.5
        # x = lambda/c = t/(1 - t) for t <= 1/2, x = c/lambda = (1 - t)/t else
        # t in [0, 1]: the denominator is >= 1/2 on either side, no guard needed
        x = ca.if_else(small, t, 1 - t) / ca.if_else(small, 1 - t, t)
        coeffs = [ca.if_else(small, q[k], rev[k]) for k in range(5)]
        for _ in range(POLISH_STEPS):
            # kept in [0, X_MAX]: a step thrown far by a flat Q cannot overflow
            x = at_most(at_least(x - halley_step(*horner(coeffs, x)), 0.0), X_MAX)
        out.append(c * ca.if_else(small, x, _div(1.0, x)))
    return out
