"""Contact step of one massless foot on a rigid plane (Khvostov 1976, §1): the public API.

Given the force on the foot P₀ and the stiffness matrix D_p = ∂P/∂r at the
start of a time step, and the displacement l of the plane relative to the
body over the step, a contact step returns the foot's displacement δ, the
force P = P₀ + D_p δ (1.3) at the end of the step, and whether the foot is
still in compressive contact, under Coulomb friction with coefficient μ.

Three such steps exist, built as branch-free CasADi SX graphs with identical
signatures, and specified exactly in ``docs/contact-spec.md``:

``contact_step_paper``
    (1.8)-(1.15) as printed, with the OCR readings of docs/paper-notes.md §1
    (``symcushion.contact_paper``).
``contact_step_robust``
    the same method with the weak points of docs/paper-notes.md §3 items 1-5
    fixed (``symcushion.contact_robust``).
``contact_step_implicit``
    the exact backward-Euler Coulomb step (return mapping) for the same
    linearised force law, valid in 3-D (docs/paper-notes.md §3 item 6;
    ``symcushion.contact_implicit``, roots from ``symcushion.contact_quartic``).

Their guarded divisions and square roots live in ``symcushion.contact_guards``.
This module owns the public API: the method names, the input/output names,
the expressions of a step for inlining (:func:`contact_step_expr`), the
cached Functions (:func:`contact_step`, :func:`contact_step_call`), the
validated NumPy evaluation (:func:`solve_contact`, :class:`ContactResult`,
``UNIT_TOL``) and :func:`stack_inputs`; it re-exports the tolerances of the
step modules. It must not build a step's expressions itself, and knows
nothing about struts, bodies or time integration: the stiffness matrix comes
from the caller. Only :func:`solve_contact` converts to NumPy.

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

# The tolerances live with the step that uses them and are re-exported here,
# where they have always been read (contact.CONE_TOL, contact.FINAL_STEPS, ...).
from .contact_guards import CONE_TOL, TINY
from .contact_implicit import (  # noqa: F401 (CANCEL_TOL, FINAL_*, ROOT_SCALE_RANGE: re-exports)
    CANCEL_TOL,
    DET_TOL,
    FINAL_CLIP,
    FINAL_STEPS,
    POLE_TOL,
    ROOT_SCALE_RANGE,
    ROOT_TOL,
    implicit_step,
    merge_stick,
    slip_step,
    stick_trial,
)
from .contact_paper import paper_step
from .contact_robust import robust_step

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

# |n| must equal 1 to this tolerance at the Python boundary: the cone test
# (1.5) is homogeneous in P but not in n, so a non-unit n changes mu.
UNIT_TOL = 1e-9

METHODS = ("paper", "robust", "implicit")
INPUT_NAMES = ["P0", "Dp", "n", "l", "mu", "u0"]
OUTPUT_NAMES = ["delta", "P", "k", "contact"]
#: Shapes of the inputs, in INPUT_NAMES order.
INPUT_SHAPES = ((3, 1), (3, 3), (3, 1), (3, 1), (1, 1), (3, 1))


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


def contact_step_call(method, P0, Dp, n, l, mu, u0, *, friction=None):
    """The step of :func:`contact_step_expr` as a call node of one shared Function.

    Same arguments and returned dict as :func:`contact_step_expr`, but the
    SX graph holds a call of the ``never_inline`` Function
    ``contact_step_<method>[_frictionless]_call`` instead of the step's
    instructions: a graph with several legs and passes contains (and its
    generated C compiles) the step once. Derivatives through the call are
    CasADi's derivative Functions of the call node. For ``'implicit'`` with
    friction the called Function evaluates the slip part only when the
    trial force does not stick (:func:`_build_conditional`); its values
    equal the full step's to the bit, its Jacobian to round-off.
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
