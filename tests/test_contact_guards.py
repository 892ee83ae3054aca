"""The call-free comparisons and clamps of contact_guards against the fabs/fmin/fmax forms.

``within``, ``exceeds``, ``at_least`` and ``at_most`` replace ``fabs(x) <= b``,
``fabs(x) > b``, ``fmax(x, low)`` and ``fmin(x, high)`` in the contact steps
(the generated C calls a helper or libm for each of those). These tests
hold them to the forms they replace on the special values of IEEE doubles,
in the CasADi VM and in the generated C, and the steps to the same outputs.
"""
from __future__ import annotations

import itertools

import casadi as ca
import numpy as np
import pytest

from symcushion.compiled import codegen
from symcushion.contact.guards import at_least, at_most, exceeds, within

#: x of every comparison: signed zeros, infinities, NaN, the guard scale
#: TINY and the smallest subnormal.
X_VALUES = (0.0, -0.0, 1.0, -1.0, 2.0, np.inf, -np.inf, np.nan, 1e-300, -1e-300, 5e-324)
#: Bounds (numbers, never NaN: the clamps are documented for numbers only).
BOUNDS = (0.0, -0.0, 1.0, -1.0, 1e-300, np.inf)


def _pairs():
    x, b = ca.SX.sym("x"), ca.SX.sym("b")
    new = [within(x, b), exceeds(x, b), at_least(x, b), at_most(x, b)]
    old = [ca.fabs(x) <= b, ca.fabs(x) > b, ca.fmax(x, b), ca.fmin(x, b)]
    return ca.Function("guards", [x, b], new + old, ["x", "b"],
                       ["within", "exceeds", "at_least", "at_most",
                        "within_ref", "exceeds_ref", "at_least_ref", "at_most_ref"])


def _check(outputs, x, b):
    new, old = outputs[:4], outputs[4:]
    # the flags: the same bits, NaN included
    for got, want in zip(new[:2], old[:2]):
        assert np.float64(got).tobytes() == np.float64(want).tobytes(), (x, b)
    # the clamps: the same value (== or both NaN); a zero may change sign
    for got, want in zip(new[2:], old[2:]):
        assert got == want or (np.isnan(got) and np.isnan(want)), (x, b, got, want)


def test_guards_equal_fabs_fmin_fmax_in_the_vm():
    f = _pairs()
    for x, b in itertools.product(X_VALUES, BOUNDS):
        _check([float(v) for v in f(x, b)], x, b)


def test_guards_equal_fabs_fmin_fmax_compiled(tmp_path):
    if codegen.find_compiler() is None:
        pytest.skip("no C compiler")
    f = _pairs()
    built = codegen.compile_cached(f, "guards.c", "libguards.so", tmp_path, "guards")
    g = ca.external("guards", str(built.library))
    for x, b in itertools.product(X_VALUES, BOUNDS):
        _check([float(v) for v in g(x, b)], x, b)
