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
    (``symcushion.contact.paper``).
``contact_step_robust``
    the same method with the weak points of docs/paper-notes.md §3 items 1-5
    fixed (``symcushion.contact.robust``).
``contact_step_implicit``
    the exact backward-Euler Coulomb step (return mapping) for the same
    linearised force law, valid in 3-D (docs/paper-notes.md §3 item 6;
    ``symcushion.contact.implicit``, roots from ``symcushion.contact.quartic``).

Their guarded divisions and square roots live in ``symcushion.contact.guards``,
the method dispatch and the cached Functions in ``symcushion.contact.dispatch``,
the names and shapes of the arguments in ``symcushion.contact.args``.
This module is the public API: it re-exports the method names, the
input/output names, the expressions of a step for inlining
(:func:`contact_step_expr`), the cached Functions (:func:`contact_step`,
:func:`contact_step_call`) and the tolerances of the step modules, where
users have always read them, and owns the validated NumPy evaluation
(:func:`solve_contact`, :class:`ContactResult`, ``UNIT_TOL``) and
:func:`stack_inputs`. It must not build a step's expressions itself, and knows
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
import numbers

import numpy as np

# The tolerances live with the step that uses them and are re-exported here,
# where they have always been read (contact.CONE_TOL, contact.FINAL_STEPS, ...);
# so are the names and Functions of the steps (docs/contact.md: the public API).
from symcushion.contact.args import INPUT_NAMES, METHODS, OUTPUT_NAMES, check_method  # noqa: F401
from symcushion.contact.dispatch import contact_step, contact_step_call, contact_step_expr  # noqa: F401
from symcushion.contact.guards import CONE_TOL, TINY
from symcushion.contact.implicit import (CANCEL_TOL, DET_TOL, FINAL_CLIP, FINAL_STEPS, POLE_TOL,
    ROOT_SCALE_RANGE, ROOT_TOL)

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
    check_method(method)
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
