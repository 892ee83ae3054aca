"""Force characteristics of the compliant elements: the families of resistance curves.

The curves a leg's elements are built from: :class:`Linear`,
:class:`PiecewiseLinear`, :class:`Crushable` (honeycomb), :class:`GasSpring`
(oleo-pneumatic) and :class:`TwoSided` (a different curve each way). Every
one is a :class:`~symcushion.legs.curve_base.Curve`: the loading/unloading
branches, smoothing, end stop, dampers and parameter vector they share, and
the defaults ``KINK_WIDTH``, ``RATE_WIDTH``, ``ZERO_DEFLECTION`` and
``STOP_STIFFNESS_RATIO``, live in ``symcushion.legs.curve_base`` and are
re-exported here: this module is where users import every curve from.

This module owns the families: each one's parameters, loading force, slope
and zero. It must not change what the base class does for all of them, and
knows nothing of geometry.
"""
from __future__ import annotations

import copy
from typing import Sequence

import casadi as ca
import numpy as np

# the base class and its defaults, re-exported: users import every curve from here
from symcushion.legs.curve_base import (KINK_WIDTH, RATE_WIDTH, STOP_STIFFNESS_RATIO,
    ZERO_DEFLECTION, Branch, Curve, check_real)
from symcushion.validation import vector

__all__ = [
    "Curve",
    "Linear",
    "PiecewiseLinear",
    "Crushable",
    "KINK_WIDTH",
    "RATE_WIDTH",
    "ZERO_DEFLECTION",
    "STOP_STIFFNESS_RATIO",
    "GasSpring",
    "TwoSided",
]


def _ramp(u, width):
    """max(u, 0), or its hyperbolic smoothing of width ``width`` (> 0)."""
    if width is None or width == 0:
        return ca.fmax(u, 0)
    return 0.5 * (u + ca.sqrt(u * u + width * width))


def _ramp_slope(u, width):
    """Derivative of :func:`_ramp` in u."""
    if width is None or width == 0:
        return ca.if_else(u > 0, 1.0, 0.0)
    return 0.5 * (1 + u / ca.sqrt(u * u + width * width))


class Linear(Curve):
    """Linear resistance f(x) = preload + k x.

    Parameters
    ----------
    stiffness : float
        k, N/m (axial) or N·m/rad (hinge), ≥ 0: a resistance curve restores. A
        negative k pushes the element further from rest (an unstable spring);
        a softening element is a :class:`PiecewiseLinear` curve, whose slopes
        ``symcushion.run.checks`` inspects.
    preload : float
        f(0), N or N·m. A non-zero preload loads the leg at its rest pose.
    """

    def __init__(self, stiffness, preload=0.0, **options):
        super().__init__(**options)
        stiffness = check_real("stiffness", stiffness, nonnegative=True)
        preload = check_real("preload", preload)
        self._branch = Branch(("k", "preload"), (stiffness, preload))

    def _loading(self, x, theta):
        return theta[1] + theta[0] * x

    def _loading_slope(self, x, theta):
        return theta[0] + 0 * x

    def _loading_zero(self, theta):
        # a flat curve (k = 0) has no zero: its preload puts it far to one side
        return -theta[1] / ca.fmax(theta[0], 1e-300)


class PiecewiseLinear(Curve):
    """Piecewise-linear resistance through knots (x_i, f_i).

    Outside the knots the end segments are extended. The knot positions are
    fixed; the knot values ``f0 … f{m-1}`` are the parameters (what a design
    study tunes). With ``smooth=True`` every interior corner is rounded over a
    width ``kink_width``.

    Parameters
    ----------
    x : sequence of float, shape (m,)
        Strictly increasing knot positions (m or rad), m ≥ 2.
    f : sequence of float, shape (m,)
        Values at the knots (N or N·m).
    """

    def __init__(self, x: Sequence[float], f: Sequence[float], **options):
        super().__init__(**options)
        xs = vector("x", x, (None,), what="knot positions")
        fs = vector("f", f, (None,), what="knot values")
        if xs.size < 2:
            raise ValueError(f"`x` needs at least 2 knots, got {xs.size}; give two or more.")
        if fs.size != xs.size:
            raise ValueError(f"`f` must have one value per knot ({xs.size}), got {fs.size}.")
        if not (np.all(np.isfinite(xs)) and np.all(np.isfinite(fs))):
            raise ValueError(f"`x` and `f` must be finite, got x={xs.tolist()}, "
                             f"f={fs.tolist()}; give finite knots.")
        if np.any(np.diff(xs) <= 0):
            raise ValueError(f"`x` must be strictly increasing, got {xs.tolist()}; sort the knots.")
        self.knots = xs
        self._branch = Branch(tuple(f"f{i}" for i in range(xs.size)), tuple(fs.tolist()))

    def _slopes(self, theta):
        xs = self.knots
        return [(theta[i + 1] - theta[i]) / (xs[i + 1] - xs[i]) for i in range(xs.size - 1)]

    def _loading(self, x, theta):
        xs, slopes, width = self.knots, self._slopes(theta), self._width()
        value = theta[0] + slopes[0] * (x - xs[0])
        for i in range(1, xs.size - 1):
            value = value + (slopes[i] - slopes[i - 1]) * _ramp(x - xs[i], width)
        return value

    def _loading_slope(self, x, theta):
        xs, slopes, width = self.knots, self._slopes(theta), self._width()
        value = slopes[0] + 0 * x
        for i in range(1, xs.size - 1):
            value = value + (slopes[i] - slopes[i - 1]) * _ramp_slope(x - xs[i], width)
        return value

    def _loading_zero(self, theta):
        # the last segment whose left knot is at or below zero holds the zero of an
        # increasing curve (the end segments extended); a flat segment at zero: its knot
        xs, slopes = self.knots, self._slopes(theta)
        root = xs[0] - theta[0] / ca.if_else(slopes[0] > 0, slopes[0], 1.0)
        for i in range(xs.size - 1):
            step = ca.if_else(slopes[i] > 0, xs[i] - theta[i] / ca.if_else(
                slopes[i] > 0, slopes[i], 1.0), xs[i])
            root = ca.if_else(theta[i] <= 0, step, root)
        return root


class Crushable(Curve):
    """Crushable absorber (honeycomb): elastic rise to a crush plateau.

    In compression (x < 0) the force rises with stiffness k until it reaches
    the crush force F_c, then stays on a plateau of slope ``plateau_slope``;
    in extension it is elastic with stiffness k::

        f(x) = k x                                   for x ≥ −F_c/k
        f(x) = −F_c + k_p (x + F_c/k)                for x < −F_c/k

    A small positive ``plateau_slope`` keeps the stiffness matrix regular.
    The usual unloading branch of a crushed honeycomb is nearly force-free:
    e.g. ``Crushable(2e6, 8e3, unloading=Linear(2e4))``.

    Parameters
    ----------
    stiffness : float
        Elastic stiffness k before crushing (N/m), > 0.
    crush_force : float
        Plateau force F_c (N), > 0.
    plateau_slope : float
        Slope on the plateau (N/m), ≥ 0.
    """

    crushes = True

    def __init__(self, stiffness, crush_force, plateau_slope=0.0, **options):
        super().__init__(**options)
        stiffness = check_real("stiffness", stiffness, positive=True)
        crush_force = check_real("crush_force", crush_force, positive=True)
        plateau_slope = check_real("plateau_slope", plateau_slope, nonnegative=True)
        self._branch = Branch(("k", "crush_force", "plateau_slope"),
                               (stiffness, crush_force, plateau_slope))

    def _loading(self, x, theta):
        k, f_c, k_p = theta[0], theta[1], theta[2]
        x_c = -f_c / k  # onset of crushing
        # k x plus the change of slope (k_p − k) below the onset.
        return k * x + (k - k_p) * _ramp(x_c - x, self._width())

    def _loading_slope(self, x, theta):
        k, f_c, k_p = theta[0], theta[1], theta[2]
        x_c = -f_c / k
        return k - (k - k_p) * _ramp_slope(x_c - x, self._width())

    def _loading_zero(self, theta):
        return 0 * theta[0]                     # k x: zero at zero deflection



class GasSpring(Curve):
    """The gas spring of an oleo-pneumatic strut: a polytropic gas column.

    A piston of area A compresses a gas of volume V₀ at pressure p₀ (full
    extension, x = 0); at stroke x (< 0 in compression) the force is

        f(x) = −p₀ A (V₀ / (V₀ + A x))ⁿ

    n = 1 isothermal, 1.4 adiabatic for air or nitrogen, about 1.1–1.3 for a
    strut in service. At x = 0 the strut pushes out with its preload p₀A. The
    volume left is held above :data:`MIN_GAS_FRACTION` of V₀ (the gas column
    cannot close); give the element a ``stroke_limit`` below V₀/A for the
    strut's real bottoming.

    Parameters
    ----------
    pressure : float
        p₀, Pa, > 0.
    area : float
        A, m², > 0.
    volume : float
        V₀, m³, > 0.
    exponent : float
        n, ≥ 1.
    """

    def __init__(self, pressure, area, volume, exponent=1.3, **options):
        super().__init__(**options)
        pressure = check_real("pressure", pressure, positive=True)
        area = check_real("area", area, positive=True)
        volume = check_real("volume", volume, positive=True)
        exponent = check_real("exponent", exponent, positive=True)
        if not isinstance(exponent, (ca.SX, ca.MX)) and exponent < 1:
            raise ValueError(f"`exponent` must be at least 1 (isothermal), got {exponent}; "
                             "use 1.0–1.4.")
        self._branch = Branch(("pressure", "area", "volume", "exponent"),
                               (pressure, area, volume, exponent))

    def _ratio(self, x, theta):
        p0, area, volume, n = theta[0], theta[1], theta[2], theta[3]
        left = ca.fmax(volume + area * x, MIN_GAS_FRACTION * volume)
        return p0, area, volume, n, left

    def _loading(self, x, theta):
        p0, area, volume, n, left = self._ratio(x, theta)
        return -p0 * area * (volume / left) ** n

    def _loading_slope(self, x, theta):
        p0, area, volume, n, left = self._ratio(x, theta)
        return p0 * area * area * n * (volume / left) ** n / left

    def _loading_zero(self, theta):
        raise ValueError("a gas spring pushes at every stroke: it has no unloaded deflection "
                         "and keeps no set; it is an elastic element of the memory law.")


#: Smallest gas volume a :class:`GasSpring` keeps, as a fraction of V₀: the
#: force there is 1000ⁿ times the preload, far past any stroke a strut uses.
MIN_GAS_FRACTION = 1e-3


class TwoSided(Curve):
    """An element that resists compression and tension with two different curves.

    The secondary struts of an inverted tripod crush in compression and in
    tension, at different forces. Each side is given as the curve it follows
    *in compression* (x < 0), so a crushable honeycomb serves for either; the
    tension side is its mirror image::

        f(x) = compression(x)          for x < 0
        f(x) = −tension(−x)            for x ≥ 0

    Both sides must pass through zero force at zero deflection (no preload),
    so f is continuous; its slope may jump at x = 0 (exact curves take the
    tension side's slope there). With ``smooth=True`` the switch is rounded
    over ``kink_width`` like any knot, and both sides are rounded too.

    Parameters
    ----------
    compression : Curve
        Resistance for x < 0 (N vs m), e.g. ``Crushable(2e6, 8e3)``. A plain
        curve: no unloading branch, end stop or damper of its own (give those
        to the TwoSided curve).
    tension : Curve
        Resistance in tension, written as the curve it would follow in
        compression: ``Crushable(2e6, 5e3)`` crushes at 5 kN of tension.
    **options
        As for :class:`Curve` (``unloading``, ``smooth``, ``tunable`` ...).
        Parameters are named ``compression.*`` then ``tension.*``.
    """

    def __init__(self, compression: Curve, tension: Curve, **options):
        super().__init__(**options)
        sides = dict(compression=compression, tension=tension)
        for name, side in sides.items():
            _check_side(name, side)
            if self.smooth and not side.smooth:
                side = copy.copy(side)
                side.smooth, side.kink_width = True, self.kink_width
            sides[name] = side
        self.compression, self.tension = sides["compression"], sides["tension"]
        self._n_compression = len(self.compression._branch.names)
        self._branch = Branch(
            tuple("compression." + n for n in self.compression._branch.names)
            + tuple("tension." + n for n in self.tension._branch.names),
            self.compression._branch.values + self.tension._branch.values)

    @property
    def crushes(self) -> bool:
        """True if a side crushes (a :class:`Crushable` side keeps a set)."""
        return any(isinstance(side, Crushable) for side in (self.compression, self.tension))

    def _sides(self, x, theta):
        m = self._n_compression
        return theta[:m], theta[m:]

    def _loading(self, x, theta):
        th_c, th_t = self._sides(x, theta)
        if self.smooth:       # each side sees only its own half-line, rounded at 0
            x_c, x_t = -_ramp(-x, self.kink_width), _ramp(x, self.kink_width)
            return self.compression._loading(x_c, th_c) - self.tension._loading(-x_t, th_t)
        return ca.if_else(x < 0, self.compression._loading(x, th_c),
                          -self.tension._loading(-x, th_t))

    def _loading_slope(self, x, theta):
        th_c, th_t = self._sides(x, theta)
        if self.smooth:
            w = self.kink_width
            x_c, x_t = -_ramp(-x, w), _ramp(x, w)
            return (self.compression._loading_slope(x_c, th_c) * _ramp_slope(-x, w)
                    + self.tension._loading_slope(-x_t, th_t) * _ramp_slope(x, w))
        return ca.if_else(x < 0, self.compression._loading_slope(x, th_c),
                          self.tension._loading_slope(-x, th_t))

    def _loading_zero(self, theta):
        return 0 * theta[0]                     # both sides pass through zero


#: Largest force at zero deflection (N or N·m) a side of a :class:`TwoSided`
#: curve may have: the sides must meet at zero force; 1e-9 allows round-off
#: of parameters given as sums or products without admitting a real preload.
TWO_SIDED_ZERO_FORCE = 1e-9


def _check_side(name, side):
    """A side of a TwoSided curve: a plain curve through f(0) = 0."""
    if not isinstance(side, Curve):
        raise TypeError(f"`{name}` must be a Curve such as Crushable(2e6, 8e3), got {side!r}.")
    if side.unloading is not None or side.stroke_limit is not None or side.has_damper:
        raise ValueError(f"`{name}` must be a plain curve, got {side!r} with an unloading "
                         "branch, end stop or damper; give those options to TwoSided itself.")
    th_load, _ = side._split(None)
    f0 = float(ca.evalf(side._loading(0.0, th_load)))
    if abs(f0) > TWO_SIDED_ZERO_FORCE:
        raise ValueError(f"`{name}` must give zero force at zero deflection, got f(0) = "
                         f"{f0:g}; remove its preload (the sides of TwoSided meet at zero).")
