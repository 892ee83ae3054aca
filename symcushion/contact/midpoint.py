"""A second-order slip for the implicit contact step: the fitted midpoint rule.

The implicit step (``symcushion.contact.implicit``) is a backward-Euler
return mapping: the foot slips along the tangential force of the END of the
step. When the slip direction turns during the step (3-D slip: the foot's
tangential force relaxes towards the direction of the plane's motion over
the slip length s = μN/k_t, k_t the tangential stiffness) that is a first
order error in the direction, made in every slipping step.

This module owns the rule that replaces it, as an option of the touchdown
step (``Scene.slip = "midpoint"``): the slip g of the step is taken along
the weighted mean force of the slipping part of the step,

    g = γ d,   d ∥ (1 − θ) P_c,τ + θ P_τ,                          (M1)

with P = P₀ + D_p (l − g) (1.3) on the cone |P_τ| = μ n·P (1.4) at the end
of the step, P_c the force where the elastic trial path P₀ + α D_p l first
reaches the cone (P_c = P₀ for a foot that was already slipping) and
θ(z) = 1/(1 − e^(−z)) − 1/z the exponentially fitted weight of the slipping
part's relaxation number z = (1 − α_c)|(D_p l)_τ|/(μ N_c). θ = 1/2 + z/12 +
O(z³) makes (M1) a trapezoidal rule, second order, for the slow turns of a
step much shorter than the slip length; θ → 1 (backward Euler, L-stable)
when the step is much longer, so the rule does not ring where the midpoint
rule would mirror the direction about the motion every step. For a straight
leg path, isotropic K and small angles it is exact: it decays the angle φ
between the force and the motion by e^(−z) as the relaxation
dφ/dl = −sin φ/s does.

The forces P₀, P_c and P are the leg's, in body axes; the step reads the
cone and the slip in the body frame of the END of the step, while the
plane and the slip's direction are fixed in the world. A force at time t
points, in the end frame, along R₁ᵀR(t) times its body components. So the
direction of (M1) takes P_c carried into the end frame by the body's
rotation from the crossing to the end, to first order

    P_c ← P_c + (1 − α_c)(T − I) P_c,   T = R₁ᵀR₀,                       (M1)

T the body's rotation over the step (the input ``turn`` is T − I) and
α_c the crossing's place in the step. Without it the rule mixes two frames:
an O(ω Δt) error in the slip direction in every slipping step, first order
over a slide (the slope lander, docs/event-order.md, "The midpoint slip
rule mixed two frames"). ``turn`` defaults to zero (a body that does not
turn, or the rule alone).

It takes the backward-Euler step's outputs as the start of its Newton
iteration on the direction angle and falls back to them where the rule has
no solution, and keeps stick and lift-off as that step decides them. A
caller whose slip starts elsewhere than P₀ (the memory law's stored force)
gives the trial path by its forces, start and end, so that D_p is never
inverted. It must not change the backward-Euler step, validate user input,
or know about bodies and time steps (the caller passes l and the turn).
"""
from __future__ import annotations

import functools

import casadi as ca

from symcushion.contact.guards import at_least, at_most, safe_div, safe_sqrt, unit
from symcushion.contact.implicit import stick_trial

__all__ = ["MIDPOINT_NEWTON_STEPS", "MAX_TURN", "THETA_SERIES", "Z_MAX", "fitted_theta",
           "midpoint_slip", "midpoint_slip_call"]

#: Newton steps on the direction angle ψ from the backward-Euler direction: it
#: is O(z) away from the root, so two steps leave an O(z⁴) error, below the
#: rule's own O(z³); the third makes the derivative the implicit-function one.
MIDPOINT_NEWTON_STEPS = 3
#: Largest change of ψ per Newton step (rad): the start is a few degrees
#: from the root in the steps where the rule matters; the clip keeps a flat
#: residual from throwing ψ onto the opposite direction.
MAX_TURN = 0.5
#: Below this z, θ(z) is its series 1/2 + z/12 − z³/720 (error < z⁵/30240,
#: 3e-15 at the threshold): the closed form loses digits to the cancellation
#: in z − 1 + e^(−z) (relative round-off 1e-16/z²).
THETA_SERIES = 1e-2
#: z is clipped here: θ(Z_MAX) = 1 − 1/Z_MAX to round-off is backward Euler
#: for every purpose, and e^(−z) stays a normal number.
Z_MAX = 1e3


def fitted_theta(z):
    """θ(z) = 1/(1 − e^(−z)) − 1/z: the θ-method weight exact for y' = −y over a step z.

    The θ-method y₁ = y₀ − z((1 − θ)y₀ + θy₁) gives y₁ = e^(−z)y₀ with this
    θ; θ(0) = 1/2 (trapezoidal), θ(∞) = 1 (backward Euler). ``z`` ≥ 0, SX.
    """
    small = z < THETA_SERIES
    zc = ca.if_else(small, 1.0, z)  # the untaken branch divides by 1
    ez = ca.exp(-zc)
    closed = (zc - 1.0 + ez) / (zc * (1.0 - ez))
    series = 0.5 + z / 12.0 - z ** 3 / 720.0
    return ca.if_else(small, series, closed)


def _tangential(x, n):
    return x - ca.dot(n, x) * n


def _cone_quadratic(p, q, N, a, mu):
    """(A, b, C) of |p − s q|² − μ²(N − s a)² = A s² − 2 b s + C, p and q tangential."""
    A = ca.dot(q, q) - mu * mu * a * a
    b = ca.dot(p, q) - mu * mu * N * a
    C = ca.dot(p, p) - mu * mu * N * N
    return A, b, C


def _first_root(A, b, C):
    """The smaller root of A s² − 2 b s + C = 0 written C/(b + √(b² − AC)), and its flag.

    Stable when b > 0 (no cancellation); the flag is false when the roots are
    complex or the denominator is not positive.
    """
    disc = b * b - A * C
    den = b + safe_sqrt(at_least(disc, 0.0))
    ok = ca.logic_and(disc >= 0, den > 0)
    return safe_div(C, ca.if_else(ok, den, 1.0)), ok


def _crossing(P0, Dl, n, mu):
    """P_c = P₀ + α_c D_p l: where the elastic trial path first reaches the cone (1.4).

    α_c = 0 for a start force on or outside the cone (a foot already
    slipping, or round-off); else the root in (0, 1] of the cone condition
    along the path. Returns (P_c (3, 1), α_c).
    """
    N0, a = ca.dot(n, P0), ca.dot(n, Dl)
    A, b, C = _cone_quadratic(_tangential(P0, n), -_tangential(Dl, n), N0, -a, mu)
    # along +α: A α² + 2 b' α + C with b' = −b; the root through C < 0 is
    # −C/(b' + √(b'² − AC))
    alpha, ok = _first_root(A, -b, C)
    alpha = ca.if_else(ca.logic_and(C < 0, ok), at_most(at_least(-alpha, 0.0), 1.0), 0.0)
    return P0 + alpha * Dl, alpha


def _end_force(P_t, Dp, n, mu, d):
    """γ ≥ 0 and P = P_t − γ D_p d on the cone for a slip along the unit tangent d.

    Returns (γ, P (3, 1), ok); ok is false when the line misses the cone or
    its first crossing is not compressive.
    """
    q = ca.mtimes(Dp, d)
    N_t, a = ca.dot(n, P_t), ca.dot(n, q)
    A, b, C = _cone_quadratic(_tangential(P_t, n), _tangential(q, n), N_t, a, mu)
    gamma, ok = _first_root(A, b, C)
    P = P_t - gamma * q
    return gamma, P, ca.logic_and(ok, ca.logic_and(gamma >= 0, ca.dot(n, P) > 0))


def midpoint_slip(P0, Dp, n, l, mu, be, turn=None, path=None):
    """The slip of the fitted midpoint rule (M1), from a backward-Euler step's outputs.

    Parameters
    ----------
    P0 : casadi.SX, shape (3, 1)
        Force on the foot at the start of the step (N).
    Dp : casadi.SX, shape (3, 3)
        Stiffness ∂P/∂r at the start pose (N/m).
    n : casadi.SX, shape (3, 1)
        Unit normal of the plane.
    l : casadi.SX, shape (3, 1)
        Displacement of the plane relative to the body over the step (m).
    mu : casadi.SX, shape (1, 1)
        Coulomb coefficient, > 0.
    be : dict of casadi.SX
        The implicit step's outputs ``delta``, ``P``, ``k`` (the slip g, m)
        and ``contact`` for the same inputs.
    turn : casadi.SX, shape (3, 3), optional
        T − I, T = R₁ᵀR₀ the rotation from the body frame of the start of the
        step to that of its end, in which ``n`` and ``l`` are given. Default
        zero.
    path : tuple of casadi.SX, optional
        (start, Dl): the elastic trial path start + α·Dl, α ∈ [0, 1], that ends at
        the trial force P₀ + D_p l, both (3, 1), N; default (P₀, D_p l). (M1) reads
        the slip's start on it. A path given by its forces needs no D_p⁻¹: D_p may
        be singular (a leg on a flat spring-back has no axial stiffness).

    Returns
    -------
    dict of casadi.SX
        ``delta`` (3, 1), m; ``P`` (3, 1), N, on the cone; ``k`` (3, 1), the
        slip g = l − δ, m; ``contact`` (1, 1). Equal to ``be`` where that
        step sticks or lifts off, or where (M1) has no solution.
    """
    P_t, _, _, t1, _ = stick_trial(P0, Dp, n, l, mu)  # (1.3) with delta = l
    t2 = ca.cross(n, t1)
    start, Dl = (P0, ca.mtimes(Dp, l)) if path is None else path
    P_c, alpha = _crossing(start, Dl, n, mu)
    N_c = ca.dot(n, P_c)
    z = safe_div((1.0 - alpha) * ca.norm_2(_tangential(Dl, n)), mu * N_c)
    z = ca.if_else(mu * N_c > 0, at_most(at_least(z, 0.0), Z_MAX), Z_MAX)
    theta = fitted_theta(z)
    if turn is not None:
        # the start force in the end frame: the plane is fixed in the world (M1)
        P_c = P_c + (1.0 - alpha) * ca.mtimes(turn, P_c)
    P_c_tau = _tangential(P_c, n)

    psi = ca.SX.sym("psi")
    d = ca.cos(psi) * t1 + ca.sin(psi) * t2
    gamma, P1, ok = _end_force(P_t, Dp, n, mu, d)
    w, _ = unit((1.0 - theta) * P_c_tau + theta * _tangential(P1, n))
    residual = ca.dot(n, ca.cross(d, w))  # sin of the angle from d to w: 0 on (M1)
    slope = ca.jacobian(residual, psi)

    g_be = be["k"]
    psi_k = ca.atan2(ca.dot(t2, g_be), ca.dot(t1, g_be))
    for _ in range(MIDPOINT_NEWTON_STEPS):
        r, dr = ca.substitute([residual, slope], [psi], [psi_k])
        psi_k = psi_k - at_most(at_least(safe_div(r, dr), -MAX_TURN), MAX_TURN)
    gamma, P1, ok, d, w = ca.substitute([gamma, P1, ca.SX(ok), d, w], [psi], [psi_k])

    N1 = ca.dot(n, P1)
    e1, _ = unit(_tangential(P1, n))
    P1 = N1 * n + mu * N1 * e1      # on the cone to round-off, as the implicit step
    g = gamma * d
    slipping = ca.logic_and(be["contact"] > 0.5, ca.dot(g_be, g_be) > 0)
    use = ca.logic_and(ca.logic_and(slipping, ok > 0.5), ca.dot(w, d) > 0)
    return dict(delta=ca.if_else(use, l - g, be["delta"]), P=ca.if_else(use, P1, be["P"]),
                k=ca.if_else(use, g, be["k"]), contact=be["contact"])


#: Inputs: the contact step's own, its backward-Euler outputs (suffix _be), then the
#: body's turn over the step (T − I; zero, its default, for no turn); with a given
#: trial path (``path`` of :func:`midpoint_slip`), its start and force increment.
_INPUTS = ("P0", "Dp", "n", "l", "mu", "delta_be", "P_be", "k_be", "contact_be", "turn")
_PATH_INPUTS = ("start", "Dl")
_OUTPUTS = ("delta", "P", "k", "contact")


_SHAPES = dict(P0=(3, 1), Dp=(3, 3), n=(3, 1), l=(3, 1), mu=(1, 1), delta_be=(3, 1),
               P_be=(3, 1), k_be=(3, 1), contact_be=(1, 1), turn=(3, 3), start=(3, 1),
               Dl=(3, 1))


def _inputs(with_path: bool) -> tuple:
    return _INPUTS + (_PATH_INPUTS if with_path else ())


@functools.lru_cache(maxsize=None)
def _build(with_path: bool = False):
    """The SX Function ``contact_slip_midpoint`` of :func:`midpoint_slip`;
    ``contact_slip_midpoint_path`` with the trial path as inputs ``start``, ``Dl``."""
    names = _inputs(with_path)
    sym = {name: ca.SX.sym(name, *_SHAPES[name]) for name in names}
    be = {key: sym[key + "_be"] for key in _OUTPUTS}
    path = (sym["start"], sym["Dl"]) if with_path else None
    out = midpoint_slip(sym["P0"], sym["Dp"], sym["n"], sym["l"], sym["mu"], be, sym["turn"],
                        path)
    name = "contact_slip_midpoint" + ("_path" if with_path else "")
    return ca.Function(name, [sym[k] for k in names], [out[k] for k in _OUTPUTS],
                       list(names), list(_OUTPUTS), {"cse": True})


@functools.lru_cache(maxsize=None)
def _build_call(with_path: bool = False):
    """The rule evaluated only for a slipping foot, as one never-inline MX Function.

    A free, sticking or lifting foot (no slip from the backward-Euler step)
    takes the backward-Euler outputs through unchanged, without the Newton
    iteration: the rule then costs nothing in the air or in stick. Values and
    derivatives are those of :func:`_build`'s graph in either branch (its
    outputs equal the backward-Euler ones wherever the foot does not slip).
    """
    full = _build(with_path)
    names = _inputs(with_path)
    # forward-mode AD, as the contact step's conditional wrapper
    # (symcushion.contact): the same sums in the same order as the SX graph
    opts = {"ad_weight": 0, "ad_weight_sp": 0}
    sym = [ca.MX.sym(name, *_SHAPES[name]) for name in names]
    keep = ca.Function(full.name() + "_keep", sym, sym[5:9], list(names),
                       list(_OUTPUTS), opts)
    switch = ca.Function.conditional(full.name() + "_switch", [keep, full], keep, opts)
    k_be, contact_be = sym[7], sym[8]
    slipping = ca.logic_and(contact_be > 0.5, ca.dot(k_be, k_be) > 0)
    out = switch(slipping, *sym)
    # never_inline: one compiled copy serves every leg and pass of a step
    return ca.Function(full.name() + "_call", sym, out, list(names), list(_OUTPUTS),
                       dict(opts, never_inline=True))


def midpoint_slip_call(P0, Dp, n, l, mu, be, turn=None, path=None):
    """:func:`midpoint_slip` as a call node of the shared ``contact_slip_midpoint`` Function
    (``contact_slip_midpoint_path`` with a ``path``).

    Same arguments and returned dict; ``be`` is the dict of
    ``symcushion.contact.contact_step_call('implicit', ...)``.
    """
    turn = ca.DM.zeros(3, 3) if turn is None else turn
    args = [P0, Dp, n, l, mu, be["delta"], be["P"], be["k"], be["contact"], turn]
    out = _build_call(path is not None)(*args, *(() if path is None else path))
    return dict(zip(_OUTPUTS, out))
