"""The contact step's signature: its methods, argument names and shapes, and their checks.

This module owns what every contact step of §1 shares at its boundary: the
method names (:data:`METHODS`), the names and shapes of the inputs
(P₀, D_p, n, l, μ, u₀) and outputs (δ, P, k, contact), and the helpers that
check a method, tell a literal μ = 0 from a symbol and cast an argument to
an SX column of the right shape. It must not build a step
(``symcushion.contact.dispatch`` does) or evaluate one on NumPy data
(``symcushion.contact``).
"""
from __future__ import annotations

import numbers

import casadi as ca
import numpy as np

__all__ = ["METHODS", "INPUT_NAMES", "OUTPUT_NAMES", "INPUT_SHAPES", "check_method",
           "is_literal_zero", "as_sx"]

METHODS = ("paper", "robust", "implicit")
INPUT_NAMES = ["P0", "Dp", "n", "l", "mu", "u0"]
OUTPUT_NAMES = ["delta", "P", "k", "contact"]
#: Shapes of the inputs, in INPUT_NAMES order.
INPUT_SHAPES = ((3, 1), (3, 3), (3, 1), (3, 1), (1, 1), (3, 1))


def check_method(method):
    """Refuse a method that is not one of :data:`METHODS`."""
    if method not in METHODS:
        raise ValueError(
            f"`method` must be one of {', '.join(repr(m) for m in METHODS)}; "
            f"got {method!r}."
        )


def is_literal_zero(mu):
    """True when mu is a plain number (not a symbol) equal to 0."""
    if isinstance(mu, numbers.Real):
        return float(mu) == 0.0
    if isinstance(mu, np.ndarray) and mu.size == 1 and np.isrealobj(mu):
        return float(mu.reshape(())) == 0.0
    return False


def as_sx(x, name, shape):
    """``x`` as a ``casadi.SX`` of ``shape`` (a row given for a column is transposed);
    a ValueError names ``name`` otherwise."""
    x = ca.SX(x)
    if x.shape != shape:
        if shape[1] == 1 and x.shape == (1, shape[0]):
            x = x.T
        else:
            raise ValueError(f"`{name}` must have shape {shape}; got {x.shape}.")
    return x
