"""The absorber's stroke lock: a held stroke between the loading and unloading curves.

A crushable axial element follows P = P(δ_S, sign δ_S′) (2.1): the loading
curve S_l(δ_S) while the stroke grows, the lower unloading curve S_u(δ_S)
while it shrinks. When the stroke rate reaches zero with the load between
the two curves, the motion of the law's Filippov closure holds the stroke
(δ_S′ = 0) and the axial force S is whatever keeps it held, anywhere in
[S_u, S_l], until it reaches a curve. A fixed step that takes the branch
from the sign of the stroke change cannot hold: it alternates between the
branches step after step (a sliding mode), an O(h) error in the velocity.

This module owns the pieces of the lock of ``Scene.events = "lock"`` (the
touchdown step, ``symcushion.scheme.touchdown``, puts them together): a leg whose
foot sticks and whose stroke is locked is a rigid axial link, and the body
step becomes the constrained velocity-Verlet step (SHAKE/RATTLE) for it:

* first kick with the stored force plus Λ e_S, with Λ such that the stroke
  at the end of the drift equals the stroke at the start (SHAKE,
  :func:`newton_masked`);
* second kick with the bending part of the end force plus μ e_S, with μ such
  that the stroke rate at the end is zero (RATTLE, :func:`stroke_rate`,
  :func:`solve_masked`); μ outside [S_u, S_l], or the force outside the
  friction cone, releases the leg onto the curve it crossed;
* a leg that reverses its stroke with its foot stuck locks if, after the
  velocities are projected onto its held stroke (removing the impulse of the
  partly wrong branch it carried), the force that holds the stroke, from
  δ_S″ = 0 (:func:`stroke_acceleration`), lies between the curves and in the
  cone. The RATTLE μ of that step is not the holding force: it also carries
  the projection's impulse.

The lock's work runs only in the steps that need it: :func:`skip_unless`
wraps it in a call that evaluates it when some leg is locked or turns its
stroke, and otherwise the plain step's values (the same bits the lock
would give there).

Locked legs are marked in the state by ``contact`` = :data:`LOCKED`, and
legs on the unloading curve by :data:`UNLOADING` (the lock's tests need the
stored branch; 1 is the loading curve).

(2.1) takes the branch from sign(V·e_S), the hinge's approach to the foot's
point along the strut (``symcushion.legs.strut``). That is δ_S′ only while the
foot sticks, which is where this lock holds. Where the foot slides, the
closure holds V·e_S and the stroke moves with the foot (measured with a
regularised switch: docs/event-order.md, "Events: what the regularised
switch holds"). A sliding foot has no lock here: its stroke reversal keeps
the located branch switch of ``symcushion.scheme.branch_switch``
(docs/event-order.md says what that costs).

This module must not call the contact step, change the drift or decide the
order of the step's work; it returns forces, residuals and masks.
"""
from __future__ import annotations

import casadi as ca

__all__ = ["LOCKED", "UNLOADING", "SHAKE_ITERATIONS", "any_of", "axial_branches", "bending_force",
           "foot_rate", "stroke_rate", "stroke_acceleration", "newton_masked", "solve_masked",
           "inside_cone", "skip_unless"]

#: Value of the state's ``contact`` entry for a foot in contact whose stroke
#: is locked (1: in contact, 0: free; every reader tests ``contact > 0.5``).
LOCKED = 2.0
#: Value of ``contact`` for a foot in contact whose axial force is on the
#: unloading curve. With the lock the state keeps the branch: read from the
#: force, it is ambiguous where the two curves are close (near zero stroke,
#: just after a touchdown).
UNLOADING = 3.0

#: Newton iterations of the SHAKE multiplier Λ. The held stroke is affine in Λ
#: through the position and nearly so through the attitude, so the first
#: iteration leaves a residual of O(h⁴ Λ²) and the second one of round-off;
#: the third is a margin. On the lander a locked stroke holds to 1e-12 m from
#: step to step (tests/test_stroke_lock.py).
SHAKE_ITERATIONS = 3


def axial_branches(fns, p_leg, rho):
    """The axial element's two curves at the foot ``rho`` (body frame).

    Returns a dict with the strut's ``L``, ``e_S`` and ``delta_S``,
    ``loading`` (a foot velocity that selects the loading branch,
    δ_S·δ_S′ ≥ 0), ``S_load`` and ``S_unload`` (N, the axial force P·e_S on
    each branch; the bending elements do not act along e_S), and ``lo``,
    ``hi``, the smaller and larger of the two.
    """
    geo = fns["strut_geometry"].call(dict(r=rho))
    e_S, delta_S = geo["e_S"], geo["delta_S"]
    loading = ca.if_else(delta_S >= 0, 1.0, -1.0) * e_S
    S_load = ca.dot(fns["strut_force"](rho, loading, p_leg), e_S)
    S_unload = ca.dot(fns["strut_force"](rho, -loading, p_leg), e_S)
    return dict(L=geo["L"], e_S=e_S, delta_S=delta_S, loading=loading, S_load=S_load,
                S_unload=S_unload, lo=ca.fmin(S_load, S_unload), hi=ca.fmax(S_load, S_unload))


def bending_force(fns, p_leg, rho, v_rel, e_S):
    """The force of the leg's hinge springs at ``rho``: P − (P·e_S) e_S of (2.1)."""
    P = fns["strut_force"](rho, v_rel, p_leg)
    return P - ca.dot(P, e_S) * e_S


def foot_rate(rho, v, omega, R):
    """ρ′ of a foot held at a world point: −ω × ρ − Rᵀ v (body frame)."""
    return -ca.cross(omega, rho) - R.T @ v


def stroke_rate(rho, e_S, v, omega, R):
    """δ_S′ = e_S·ρ′ of a stuck foot (m/s); v world, ω body frame."""
    return ca.dot(e_S, foot_rate(rho, v, omega, R))


def stroke_acceleration(rho, e_S, L, v, omega, a, alpha, R):
    """δ_S″ of a stuck foot: e_S·ρ″ + (|ρ′|² − (e_S·ρ′)²)/L.

    ρ″ = −α × ρ − 2ω × ρ′ − ω × (ω × ρ) − Rᵀ a, with a the body's
    acceleration (world) and α its angular acceleration (body frame).
    """
    rate = foot_rate(rho, v, omega, R)
    acc = -ca.cross(alpha, rho) - 2 * ca.cross(omega, rate) \
        - ca.cross(omega, ca.cross(omega, rho)) - R.T @ a
    along = ca.dot(e_S, rate)
    return ca.dot(e_S, acc) + (ca.dot(rate, rate) - along * along) / L


#: Relative shift of the locked legs' linear solves (:func:`solve_masked`). Their matrices, −G M⁻¹ Gᵀ up to a factor (G the held
#: strokes' rates in the body's velocities), are negative definite unless
#: the held strokes are dependent: four locked legs of an exactly symmetric
#: lander, whose alternating sum of wrenches is zero, hold the body with a
#: self-stress that moves nothing and that the motion does not determine.
#: The shift −ε·max|A_ii|·I keeps such a system regular (the self-stress
#: gets 0) and changes the forces of a regular one by a relative ε.
SHIFT = 1e-10


def solve_masked(A, b, mask):
    """x with A x = b on the rows where ``mask`` is 1 and x = 0 elsewhere (branch-free).

    ``mask`` is a list of SX 0/1 entries. The masked rows and columns are
    replaced by the identity, so the system stays regular whatever the mask;
    the masked block is shifted by −ε·max|A_ii| (ε = :data:`SHIFT`).
    """
    m = ca.vertcat(*mask)
    M = ca.diag(m)
    A_m = M @ A @ M
    scale = ca.mmax(ca.fabs(ca.diag(A_m)))
    return _eliminate(A_m - SHIFT * scale * ca.diag(m) + ca.diag(1 - m), m * b)


def _eliminate(A, b):
    """A⁻¹b by Gaussian elimination without pivoting, unrolled (A small, definite).

    CasADi's symbolic ``solve`` (a QR by Gram–Schmidt) loses the near-null
    direction of a nearly dependent set of held strokes: at a condition of
    1e10 it returned a self-stress of ±2.8 kN where the exact answer has
    none. Elimination is stable for the (nearly) definite matrices here.
    """
    n = A.size1()
    a = [[A[i, j] for j in range(n)] for i in range(n)]
    r = [b[i] for i in range(n)]
    for k in range(n):
        for i in range(k + 1, n):
            f = a[i][k] / a[k][k]
            for j in range(k + 1, n):
                a[i][j] = a[i][j] - f * a[k][j]
            r[i] = r[i] - f * r[k]
    x = [None] * n
    for i in reversed(range(n)):
        x[i] = (r[i] - sum((a[i][j] * x[j] for j in range(i + 1, n)), ca.SX(0))) / a[i][i]
    return ca.vertcat(*x)


def newton_masked(residual, unknown, mask, iterations=SHAKE_ITERATIONS):
    """The root of ``residual`` (SX, affine-ish in ``unknown``) on the masked rows.

    Unmasked entries of ``unknown`` stay 0. Runs a fixed number of Newton
    iterations from 0, the Jacobian by AD; returns the iterate as an SX
    expression (no symbol ``unknown`` left in it).
    """
    J = ca.jacobian(residual, unknown)
    x = ca.SX.zeros(unknown.numel())
    for _ in range(iterations):
        r_x, J_x = ca.substitute([residual, J], [unknown], [x])
        x = x - solve_masked(J_x, r_x, mask)
    return x


def inside_cone(P, n, mu):
    """1 where the force P presses on the surface (n·P > 0) within the cone |P_t| ≤ μ n·P."""
    N = ca.dot(n, P)
    tangential = P - N * n
    return ca.logic_and(N > 0, ca.dot(tangential, tangential) <= (mu * N) ** 2)


def any_of(flags):
    """The logical or of a non-empty list of SX flags."""
    out = flags[0]
    for f in flags[1:]:
        out = ca.logic_or(out, f)
    return out


#: Options of the Functions behind :func:`skip_unless`: forward-mode AD, as the
#: SX step's own Jacobian (reverse mode sums in another order), and common
#: subexpressions merged as in the step.
_GATED_OPTS = {"ad_weight": 0, "ad_weight_sp": 0}


def skip_unless(name, flag, inputs, args, on, off):
    """The expressions ``on`` where ``flag`` is set, ``off`` elsewhere, as one call node.

    ``inputs`` are the SX symbols both lists of expressions are built on and
    ``args`` their values in the caller's graph. The call evaluates only the
    list it returns (``casadi.Function.conditional``), so the work of ``on``
    is skipped in the steps where ``flag`` is 0; ``off`` must then be the
    value ``on`` would take, for the step to give the same numbers either
    way. Derivatives are those of the list taken (the flag is piecewise
    constant). Returns the list of SX outputs and the Function of ``on``
    (its size is the work skipped).
    """
    f_on = ca.Function(f"{name}_on", inputs, on, dict(_GATED_OPTS, cse=True))
    f_off = ca.Function(f"{name}_off", inputs, off, dict(_GATED_OPTS, cse=True))
    switch = ca.Function.conditional(f"{name}_switch", [f_off], f_on, _GATED_OPTS)
    flag_sym = ca.MX.sym("flag")
    sym = [ca.MX.sym(f"in{k}", x.sparsity()) for k, x in enumerate(inputs)]
    call = ca.Function(name, [flag_sym] + sym, switch(flag_sym, *sym),
                       dict(_GATED_OPTS, never_inline=True))
    return call(ca.if_else(flag, 1.0, 0.0), *args), f_on
