"""Where a design checks the shape of a tuned curve: the check points and the rate
that selects one branch of a curve exactly.

This module owns the points at which shape constraints and practical limits read
a curve (its knots, or a grid) and the branch-selecting rate. It must not build
constraints or know about legs and scenes.
"""
from __future__ import annotations

import numpy as np

from symcushion.legs.characteristics import PiecewiseLinear
from symcushion.legs.curve_base import Curve

__all__ = ["SHAPE_GRID", "BRANCH_SELECT", "branch_rate", "shape_points"]

#: Number of check points per side of zero for shape constraints of curves
#: without knots (linear, crushable), on [−range, range].
SHAPE_GRID = 8
#: x·ẋ used to select a single branch of a curve when evaluating its shape,
#: in units of the curve's ``rate_width``: tanh(50) = 1 to double precision,
#: so a smooth curve then returns exactly its loading or unloading branch.
BRANCH_SELECT = 50.0


def branch_rate(curve: Curve, x: float, loading: bool):
    """A rate that selects one branch of ``curve`` exactly at x ≠ 0."""
    if x == 0:
        return 0.0
    magnitude = BRANCH_SELECT * curve.rate_width / abs(x)
    return float(np.sign(x)) * magnitude * (1.0 if loading else -1.0)


def shape_points(curve: Curve, extent) -> np.ndarray:
    """Where shape constraints are checked: knots, or a grid on [−extent, extent]."""
    pts = []
    for c in (curve, curve.unloading):
        if isinstance(c, PiecewiseLinear):
            pts += list(c.knots)
    if not pts:
        extent = 1.0 if extent is None else extent
        pts = list(np.linspace(-extent, extent, 2 * SHAPE_GRID + 1))
    return np.unique(np.asarray(pts, dtype=float))
