"""The contact steps as expressions and cached Functions: the method dispatch.

This module owns turning a method name into a step of §1: the expressions
of a step for inlining (:func:`contact_step_expr`, (1.3)-(1.15) by
``symcushion.contact.paper``, ``contact_robust`` or ``contact_implicit``),
the cached SX Functions (:func:`contact_step`), the shared ``never_inline``
call nodes (:func:`contact_step_call`) and, for the implicit step with
friction, its split into a stick trial and two branches run through
``Function.conditional``, which gives the full step's values to the bit.
It must not build a step's expressions itself, validate NumPy data
(``symcushion.contact`` does) or know struts, bodies or time integration.
Users import its public names from ``symcushion.contact``.
"""
from __future__ import annotations

import functools

import casadi as ca

from symcushion.contact.args import (INPUT_NAMES, INPUT_SHAPES, OUTPUT_NAMES, as_sx, check_method,
    is_literal_zero)
from symcushion.contact.implicit import implicit_step, merge_stick, slip_step, stick_trial
from symcushion.contact.paper import paper_step
from symcushion.contact.robust import robust_step

__all__ = ["contact_step_expr", "contact_step", "contact_step_call", "TRIAL_NAMES"]


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
    check_method(method)
    if friction is None:
        friction = not is_literal_zero(mu)
    P0 = as_sx(P0, "P0", (3, 1))
    Dp = as_sx(Dp, "Dp", (3, 3))
    n = as_sx(n, "n", (3, 1))
    l = as_sx(l, "l", (3, 1))
    u0 = as_sx(u0, "u0", (3, 1))
    mu = as_sx(mu, "mu", (1, 1)) if friction else ca.SX(0.0)
    if method == "paper":
        out = paper_step(P0, Dp, n, l, mu, u0)
    elif method == "robust":
        out = robust_step(P0, Dp, n, l, mu, u0, friction)
    else:
        out = _implicit_expr(P0, Dp, n, l, mu, u0, friction)
    # The same operation on the same operands once (the guards and the
    # candidates build some twice); values are unchanged to the bit.
    return dict(zip(OUTPUT_NAMES, ca.cse([out[key] for key in OUTPUT_NAMES])))


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


#: Options of the Functions of the implicit step's conditional call: forward-mode
#: AD, as the SX step's own Jacobian. Reverse mode (CasADi's choice for a
#: Function with fewer outputs than inputs) sums in another order and moves
#: the Jacobian of ill-conditioned slips by up to 4e-10 relative.
_FORWARD_AD = {"ad_weight": 0, "ad_weight_sp": 0}
#: Outputs of the implicit step's stick trial that its branches take as inputs:
#: the stick flag, the trial force P_t, and what the slip part needs of the
#: trial (``contact_implicit.slip_step``: N_t, T_t, T_t^2 and the direction t1).
TRIAL_NAMES = ["stick", "P_t", "N_t", "T_t", "T2", "t1"]
_TRIAL_SHAPES = ((1, 1), (3, 1), (1, 1), (1, 1), (1, 1), (3, 1))


def _trial_outputs(P0, Dp, n, l, mu):
    """The expressions of TRIAL_NAMES (``stick_trial``), in that order."""
    P_t, N_t, T_t, t1, stick = stick_trial(P0, Dp, n, l, mu)
    return [stick, P_t, N_t, T_t, T_t * T_t, t1]


@functools.lru_cache(maxsize=None)
def _build_branches(friction):
    """The implicit step in three SX Functions: its stick trial and its two branches.

    ``..._trial`` maps the step's inputs to TRIAL_NAMES (:func:`_trial_outputs`).
    ``..._slip`` and ``..._stick`` take the step's inputs, those and
    ``other`` (zeros from the caller) and return the step's outputs. The
    slip branch is ``contact_implicit.slip_step`` on the trial's values: it
    does not compute the trial again (27 ns of about 660 per slip). The full
    step (``contact_step_implicit``) inlines this same branch on the trial's
    expressions (:func:`_implicit_expr`), so that the two execute the same
    operations and give the same bits. Derivatives through the call are
    formed by the chain rule through the trial's outputs, which sums in
    another order than one sweep over the full step: they agree with the
    full step's to the round-off of a Jacobian (up to 3.5e-10 of the
    largest entry measured, as forward and reverse mode of the full step
    differ by 2.8e-10), not to the bit. The stick branch
    returns delta = l, P = P_t from the trial, through the full step's own
    ``merge_stick`` on the symbolic flag, so that a -0.0 in `l` comes out
    +0.0 as from the full step (CasADi's ``if_else`` is a sum); its unused
    slip values are the input ``other``, which CasADi cannot simplify away.
    """
    name = "contact_step_implicit" + ("" if friction else "_frictionless")
    inputs = [ca.SX.sym(key, *shape) for key, shape in zip(INPUT_NAMES, INPUT_SHAPES)]
    P0, Dp, n, l, mu, u0 = inputs
    mu_eff = mu if friction else ca.SX(0.0)  # the frictionless step ignores mu
    test = ca.Function(f"{name}_trial", inputs, _trial_outputs(P0, Dp, n, l, mu_eff),
                       INPUT_NAMES, TRIAL_NAMES, _FORWARD_AD)
    trial = [ca.SX.sym(key, *shape) for key, shape in zip(TRIAL_NAMES, _TRIAL_SHAPES)]
    s_stick, s_P_t, N_t, T_t, T2, t1 = trial
    other = ca.SX.sym("other", 10)
    branch_in = inputs + trial + [other]
    branch_names = INPUT_NAMES + TRIAL_NAMES + ["other"]
    slip = slip_step(P0, Dp, n, l, mu_eff, u0, N_t, T_t, T2, t1, friction)
    slip_out = ca.cse([slip[key] for key in OUTPUT_NAMES])
    unused = dict(zip(OUTPUT_NAMES, (other[0:3], other[3:6], other[6:9], other[9])))
    stick_out = merge_stick(s_stick, l, s_P_t, unused)
    stick_out = ca.cse([stick_out[key] for key in OUTPUT_NAMES])
    return test, [ca.Function(f"{name}_{kind}", branch_in, out, branch_names, OUTPUT_NAMES,
                              _FORWARD_AD)
                  for kind, out in (("slip", slip_out), ("stick", stick_out))]


def _implicit_expr(P0, Dp, n, l, mu, u0, friction):
    """The full implicit step's expressions, its slip part the inlined slip branch.

    ``contact_implicit.implicit_step`` with the slip part replaced by an
    inlined call of the slip branch of :func:`_build_branches` on the
    trial's expressions: the full step then executes the branch's
    operations exactly, rather than a graph CasADi simplifies across the
    trial, so that the conditional call (:func:`_build_conditional`) gives
    the full step's values to the bit (derivatives: to round-off, see
    :func:`_build_branches`).
    """
    _, (slip_branch, _) = _build_branches(friction)

    def slip_part(P0, Dp, n, l, mu, u0, N_t, T_t, T2, t1, friction):
        # the slip branch does not use `stick`, `P_t` or `other`
        unused = ca.SX.zeros(1, 1), ca.SX.zeros(3, 1)
        args = [P0, Dp, n, l, mu, u0, *unused, N_t, T_t, T2, t1, ca.SX.zeros(10, 1)]
        return dict(zip(OUTPUT_NAMES, slip_branch.call(args, True, False)))

    return implicit_step(P0, Dp, n, l, mu, u0, friction, slip_part)


def _build_conditional(friction):
    """The implicit step that runs its slip part only when the foot does not stick.

    An MX Function with the step's inputs and outputs: it evaluates the
    stick trial of :func:`_build_branches` and then, through
    ``Function.conditional``, either the stick branch (a few dozen
    operations, on the trial force already computed) or the slip branch
    (the slip part, on the trial's values). Both branches give the full
    step's values bit for bit,
    and derivatives are those of the branch taken (the stick flag is
    piecewise constant).
    """
    f = _build("implicit", friction)
    test, (slip_branch, stick_branch) = _build_branches(friction)
    sym = [ca.MX.sym(name, f.size_in(i)) for i, name in enumerate(INPUT_NAMES)]
    opts = _FORWARD_AD
    # Branch index 0 (slip, lift-off or free): the slip branch; 1 (stick): the stick branch
    switch = ca.Function.conditional(f"{f.name()}_switch", [slip_branch, stick_branch],
                                     slip_branch, opts)
    trial = test(*sym)
    out = switch(trial[0], *sym, *trial, ca.MX.zeros(10, 1))
    return ca.Function(f"{f.name()}_call", sym, out, INPUT_NAMES, OUTPUT_NAMES,
                       dict(opts, never_inline=True))


@functools.lru_cache(maxsize=None)
def _build_call(method, friction):
    if method == "implicit" and friction:  # at mu = 0 the trial never sticks (T_t > 0)
        return _build_conditional(friction)
    f = _build(method, friction)
    sym = f.sx_in()
    # never_inline: an SX graph calling this keeps one call node per call, so
    # that a simulator calls one compiled copy instead of inlining eight
    return ca.Function(f"{f.name()}_call", sym, f.call(sym), INPUT_NAMES, OUTPUT_NAMES,
                       {"never_inline": True})


@functools.lru_cache(maxsize=None)
def _build_gated_call(method, friction):
    """The call of :func:`_build_call` run only where its input ``flag`` is set; elsewhere
    its outputs are zeros (``contact`` 0), at the cost of a copy."""
    call = _build_call(method, friction)
    sym = [ca.MX.sym(name, call.sparsity_in(i)) for i, name in enumerate(INPUT_NAMES)]
    skip = ca.Function(f"{call.name()}_skip", sym,
                       [ca.MX.zeros(call.sparsity_out(i)) for i in range(call.n_out())],
                       INPUT_NAMES, OUTPUT_NAMES, _FORWARD_AD)
    switch = ca.Function.conditional(f"{call.name()}_gate", [skip], call, _FORWARD_AD)
    flag = ca.MX.sym("flag")
    return ca.Function(f"{call.name()}_where", [flag] + sym, switch(flag, *sym),
                       ["flag"] + INPUT_NAMES, OUTPUT_NAMES,
                       dict(_FORWARD_AD, never_inline=True))


def contact_step_call(method, P0, Dp, n, l, mu, u0, *, friction=None, where=None):
    """The step of :func:`contact_step_expr` as a call node of one shared Function.

    Same arguments and returned dict as :func:`contact_step_expr`, but the
    SX graph holds a call of the ``never_inline`` Function
    ``contact_step_<method>[_frictionless]_call`` instead of the step's
    instructions: a graph with several legs and passes contains (and its
    generated C compiles) the step once. Derivatives through the call are
    CasADi's derivative Functions of the call node. For ``'implicit'`` with
    friction the called Function evaluates the slip part only when the
    trial force does not stick (:func:`_build_conditional`); its values
    equal the full step's to the bit, its Jacobian to round-off. ``where``
    (an SX flag, optional): the step runs only where it is set and returns
    zeros (``contact`` 0) elsewhere, for a caller that reads none of its
    outputs there (a foot that is nowhere near the obstacle).
    """
    check_method(method)
    if friction is None:
        friction = not is_literal_zero(mu)
    args = [as_sx(x, name, shape) for x, name, shape in
            ((P0, "P0", (3, 1)), (Dp, "Dp", (3, 3)), (n, "n", (3, 1)), (l, "l", (3, 1)),
             (mu, "mu", (1, 1)), (u0, "u0", (3, 1)))]
    if where is None:
        out = _build_call(method, bool(friction))(*args)
    else:
        out = _build_gated_call(method, bool(friction))(ca.if_else(where, 1.0, 0.0), *args)
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
    check_method(method)
    if not isinstance(friction, bool):
        raise TypeError(f"`friction` must be True or False; got {friction!r}.")
    return _build(method, friction)
