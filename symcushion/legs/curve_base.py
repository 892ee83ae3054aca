"""The resistance curve f(x) of a compliant element: the base class and its defaults.

An element of a leg (the axial absorber S, the hinge springs M_β and M_γ of
(2.1)) is described by a resistance curve f(x) of its *own* deflection x
(axial stroke δ_S in m, azimuth β in rad, polar deflection γ − γ₀ in rad).
A positive slope means restoring. The strut (``symcushion.legs.strut``) applies
the orientation signs of (2.1).

Each curve may carry a separate unloading branch, so that the element follows
P = P(δ, sign δ′) as in the paper: the loading branch is active while the
deflection grows in magnitude (x·ẋ ≥ 0), the unloading branch while it shrinks
(x·ẋ < 0). At zero deflection (|x| ≤ :data:`ZERO_DEFLECTION`) the element can
only load, whatever the sign of ẋ: a foot that touches down starts at its
unloaded pose, where the geometry's round-off leaves a deflection of order
1e-16 of either sign.

Curves evaluate on floats, on NumPy arrays (elementwise) and on CasADi SX/MX
alike. Their parameters form a
flat vector with names (``Curve.param_names``), so an optimiser can make them
symbolic: pass ``theta`` (a CasADi vector) to :meth:`Curve.force`.

This module owns :class:`Curve` (branches, smoothing, end stop, dampers,
parameter vector, evaluation), the default widths and ratios, the parameter
record :class:`Branch` and :func:`check_real`. It must not define a curve
family (they are ``symcushion.legs.characteristics``, where users import every
curve from) and knows nothing of geometry.
"""
from __future__ import annotations

import copy
from dataclasses import dataclass

import casadi as ca
import numpy as np

from symcushion.validation import boolean, real

__all__ = ["Curve", "Branch", "check_real", "KINK_WIDTH", "RATE_WIDTH", "ZERO_DEFLECTION",
           "STOP_STIFFNESS_RATIO"]

#: Default smoothing width of a knot, in units of the deflection (m or rad).
#: Used only when a curve is built with ``smooth=True``: the kink is replaced
#: by a hyperbola 0.5(u + sqrt(u² + w²)) that departs from the corner by at
#: most w/2 — 1e-4 m (0.1 mm) or 1e-4 rad is well below any stroke of
#: interest yet wide enough for Ipopt to see a continuous second derivative.
KINK_WIDTH = 1e-4

#: Default smoothing width of the loading/unloading switch, in units of x·ẋ
#: (m²/s or rad²/s), used only with ``smooth=True``: the branch weight is
#: 0.5(1 + tanh(x·ẋ / w)). Exact switching (``smooth=False``) is the paper's.
RATE_WIDTH = 1e-6

#: Deflection (m or rad) at and below which the exact branch test takes the
#: loading branch whatever the sign of the rate. The unloaded pose of a strut
#: has deflections of round-off size (1e-16) and either sign; read by x·ẋ, a
#: touching-down foot would take the unloading branch's slope for its first
#: contact step whenever that round-off has the sign of an extension, and a
#: slope that wrong for one step moves where the foot first sticks by a
#: fraction of the step (a first-order error of the whole run). 1e-12 is far
#: above round-off and far below any deflection a curve resolves.
ZERO_DEFLECTION = 1e-12

#: Default stiffness of an end stop relative to the loading curve's slope at
#: zero: 100 times stiffer bottoms an element within 1 % of its stroke limit
#: under the force that took it to its limit, and stays 10 times softer than
#: the rigid rod's axial ratio (``symcushion.legs.strut.RIGID_AXIAL_RATIO``), so the
#: stable step it asks for is a tenth of the rod's.
STOP_STIFFNESS_RATIO = 1e2


def _is_symbolic(*values) -> bool:
    return any(isinstance(v, (ca.SX, ca.MX)) for v in values)


def _is_array(*values) -> bool:
    """True if a value is an array or a sequence (evaluated elementwise)."""
    return any(isinstance(v, (np.ndarray, list, tuple)) and np.ndim(v) > 0 for v in values)


def _numeric_out(value, symbolic: bool):
    """Return a float for numeric evaluation, the expression otherwise."""
    if symbolic:
        return value
    return float(ca.DM(value))


def check_real(name, value, *, positive=False, nonnegative=False):
    """A real parameter (NumPy scalars included), or a symbolic one passed through."""
    if isinstance(value, (ca.SX, ca.MX)):
        return value
    return real(name, value, positive=positive, nonnegative=nonnegative)


@dataclass(frozen=True)
class Branch:
    """Parameters of one branch: names and default values."""

    names: tuple[str, ...]
    values: tuple[float, ...]


class Curve:
    """Base class of a resistance curve f(x) with an optional unloading branch.

    Subclasses implement :meth:`_loading` and :meth:`_loading_slope` on a
    parameter vector ``theta`` laid out as :attr:`_branch` says.

    Parameters
    ----------
    unloading : Curve, optional
        Curve used while the deflection shrinks (x·ẋ < 0). Its parameters are
        appended to this curve's, prefixed with ``unload.``.
    smooth : bool
        Replace kinks and the branch switch by smooth blends of widths
        ``kink_width`` and ``rate_width`` (for gradient-based design).
    tunable : bool
        Mark the parameters as design variables: a strut built with this curve
        exposes them in its ``p`` input instead of baking the numbers in.
    elastic_stiffness : float, optional
        k_e of the memory law (``symcushion.legs.absorber``): the slope of the
        elastic line between the loading and the unloading curve, N/m or
        N·m/rad, > 0. Default: the loading curve's slope at zero deflection.
        Unused by the printed law P(δ, sign δ′).
    damping : float
        c of a viscous damper in parallel with the element, force c·ẋ
        (N·s/m or N·m·s/rad), ≥ 0; memory law only (``symcushion.legs.absorber``).
    orifice : float
        c₂ of an orifice damper in parallel, force c₂·ẋ|ẋ| (N·s²/m²), ≥ 0;
        memory law only.
    stroke_limit : float, optional
        The compression at which the element bottoms (m or rad, > 0): an end
        stop k_stop·min(x + limit, 0) acts in parallel beyond it, and a run
        that reaches it says so (``symcushion.run.monitor``).
    stop_stiffness : float, optional
        k_stop of the end stop (N/m or N·m/rad, > 0); default
        :data:`STOP_STIFFNESS_RATIO` times the loading curve's slope at zero.
    """

    #: True for an element that keeps a set by crushing, without an unloading
    #: curve; the crushing families of ``symcushion.legs.characteristics`` say so.
    crushes = False

    def __init__(self, *, unloading: "Curve | None" = None, smooth: bool = False,
                 kink_width: float = KINK_WIDTH, rate_width: float = RATE_WIDTH,
                 tunable: bool = False, elastic_stiffness: "float | None" = None,
                 damping: float = 0.0, orifice: float = 0.0,
                 stroke_limit: "float | None" = None, stop_stiffness: "float | None" = None):
        if unloading is not None and not isinstance(unloading, Curve):
            raise TypeError(
                f"`unloading` must be a Curve (e.g. Linear(1e4)), got {unloading!r}.")
        if unloading is not None and unloading.unloading is not None:
            raise ValueError("`unloading` must not have an unloading branch of its own; "
                             "give a plain curve.")
        self.smooth = boolean("smooth", smooth)
        self.kink_width = check_real("kink_width", kink_width, positive=True)
        if unloading is not None and self.smooth and not unloading.smooth:
            # `smooth` promises no kinks: round the unloading branch's knots
            # too (on a copy; the caller's curve is left as given).
            unloading = copy.copy(unloading)
            unloading.smooth, unloading.kink_width = True, self.kink_width
        self.unloading = unloading
        self.rate_width = check_real("rate_width", rate_width, positive=True)
        self.tunable = boolean("tunable", tunable)
        self.elastic_stiffness = (None if elastic_stiffness is None else
                                  check_real("elastic_stiffness", elastic_stiffness,
                                              positive=True))
        self.damping = check_real("damping", damping, nonnegative=True)
        self.orifice = check_real("orifice", orifice, nonnegative=True)
        self.stroke_limit = (None if stroke_limit is None else
                             check_real("stroke_limit", stroke_limit, positive=True))
        if stop_stiffness is not None and stroke_limit is None:
            raise ValueError("`stop_stiffness` acts at the end stop; give `stroke_limit` too, "
                             "or remove `stop_stiffness`.")
        self.stop_stiffness = (None if stop_stiffness is None else
                               check_real("stop_stiffness", stop_stiffness, positive=True))

    @property
    def has_damper(self) -> bool:
        """True if a damper acts in parallel with the element (memory law only)."""
        return self.damping > 0 or self.orifice > 0

    @property
    def has_memory(self) -> bool:
        """True if the element keeps a set under the memory law (``symcushion.legs.absorber``):
        it has an unloading curve, or it crushes."""
        return self.unloading is not None or self.crushes

    def loading_zero(self, theta=None):
        """The deflection where the loading curve's force is zero (m or rad).

        The curve must increase through its zero (a restoring element); with
        ``smooth=True`` the zero of the unrounded curve is returned, within
        ``kink_width``/2 of the rounded one.
        """
        th_load, _ = self._split(theta)
        return self._loading_zero(th_load)

    def _loading_zero(self, theta):  # pragma: no cover - abstract
        raise NotImplementedError

    # -- parameters -------------------------------------------------------
    _branch: Branch

    @property
    def param_names(self) -> tuple[str, ...]:
        """Names of the flat parameter vector (loading, then ``unload.*``)."""
        names = self._branch.names
        if self.unloading is not None:
            names = names + tuple("unload." + s for s in self.unloading._branch.names)
        return names

    @property
    def param_values(self) -> np.ndarray:
        """Default (numeric) values of the flat parameter vector."""
        values = self._branch.values
        if self.unloading is not None:
            values = values + self.unloading._branch.values
        return np.array(values, dtype=float)

    @property
    def n_params(self) -> int:
        return len(self.param_names)

    def _split(self, theta):
        """Split a flat parameter vector into (loading, unloading) parts."""
        if theta is None:
            theta = self.param_values
        if isinstance(theta, (ca.SX, ca.MX, ca.DM)):
            count = theta.numel()
        else:
            theta = np.asarray(theta, dtype=float).ravel()
            count = theta.size
        if count != self.n_params:
            raise ValueError(
                f"`theta` of {type(self).__name__} must have {self.n_params} entries "
                f"{self.param_names}, got {count}; pass one value per parameter.")
        m = len(self._branch.names)
        return theta[:m], theta[m:]

    # -- evaluation -------------------------------------------------------
    def _width(self):
        return self.kink_width if self.smooth else None

    def _loading(self, x, theta):  # pragma: no cover - abstract
        raise NotImplementedError

    def _loading_slope(self, x, theta):  # pragma: no cover - abstract
        raise NotImplementedError

    def _weight(self, x, rate):
        """Weight of the loading branch: 1 while x·ẋ ≥ 0 (magnitude grows) or the
        deflection is zero (|x| ≤ ZERO_DEFLECTION: from there it can only grow)."""
        if self.smooth:
            return 0.5 * (1 + ca.tanh(x * rate / self.rate_width))
        return ca.if_else(ca.logic_or(x * rate >= 0, ca.fabs(x) <= ZERO_DEFLECTION), 1.0, 0.0)

    def force(self, x, rate=0.0, theta=None, branch_x=None):
        """Resistance f(x, sign ẋ) of the element.

        Parameters
        ----------
        x : float or casadi.SX/MX
            Deflection of the element (m or rad).
        rate : float or casadi.SX/MX
            Its rate ẋ (m/s or rad/s); only its sign matters (or x·ẋ over
            ``rate_width`` when smooth). Default 0: the loading branch.
        theta : array_like or casadi vector, optional
            Flat parameter vector (``param_names``); default the numbers given.
        branch_x : float or casadi.SX/MX, optional
            Deflection used in the branch test x·ẋ only (default ``x``). The
            strut passes a frozen copy so that its stiffness, the derivative
            in x, is that of the active branch (2.3) and not the derivative of
            the smooth branch weight (see ``HingedStrut.functions``).

        Returns
        -------
        float or casadi expression
            Force (N) or moment (N·m).
        """
        if _is_array(x, rate) and not _is_symbolic(x, rate, theta, branch_x):
            return self._on_array("force", x, rate, theta)
        symbolic = _is_symbolic(x, rate, theta)
        th_load, th_unload = self._split(theta)
        value = self._loading(x, th_load)
        if self.unloading is not None:
            weight = self._weight(x if branch_x is None else branch_x, rate)
            value = weight * value + (1 - weight) * self.unloading._loading(x, th_unload)
        if self.stroke_limit is not None:
            value = value + self.end_stop(x, theta)
        return _numeric_out(value, symbolic)

    def end_stop(self, x, theta=None):
        """The end stop's force k_stop·min(x + limit, 0) (0 without a ``stroke_limit``)."""
        if self.stroke_limit is None:
            return 0 * x
        return self._stop_stiffness(theta) * ca.fmin(x + self.stroke_limit, 0)

    def _stop_stiffness(self, theta):
        if self.stop_stiffness is not None:
            return self.stop_stiffness
        th_load, _ = self._split(theta)
        return STOP_STIFFNESS_RATIO * self._loading_slope(0.0, th_load)

    def slope(self, x, rate=0.0, theta=None):
        """Derivative df/dx of the active branch (N/m or N·m/rad), written by hand."""
        if _is_array(x, rate) and not _is_symbolic(x, rate, theta):
            return self._on_array("slope", x, rate, theta)
        symbolic = _is_symbolic(x, rate, theta)
        th_load, th_unload = self._split(theta)
        value = self._loading_slope(x, th_load)
        if self.unloading is not None:
            weight = self._weight(x, rate)
            value = weight * value + (1 - weight) * self.unloading._loading_slope(x, th_unload)
        if self.stroke_limit is not None:
            value = value + ca.if_else(x < -self.stroke_limit, self._stop_stiffness(theta), 0.0)
        return _numeric_out(value, symbolic)

    __call__ = force

    def _on_array(self, which, x, rate, theta):
        """Evaluate ``force`` or ``slope`` elementwise on NumPy arrays (broadcast x, rate)."""
        x = np.asarray(x, dtype=float)
        rate = np.asarray(rate, dtype=float)
        shape = np.broadcast_shapes(x.shape, rate.shape)
        theta = self.param_values if theta is None else np.asarray(theta, dtype=float).ravel()
        self._split(theta)                       # checks the number of parameters
        cache = self.__dict__.setdefault("_array_functions", {})
        if which not in cache:
            xs, rs = ca.SX.sym("x"), ca.SX.sym("rate")
            th = ca.SX.sym("theta", self.n_params)
            cache[which] = ca.Function(f"curve_{which}", [xs, rs, th],
                                       [getattr(self, which)(xs, rs, th)],
                                       ["x", "rate", "theta"], [which])
        n = int(np.prod(shape))
        if n == 0:
            return np.zeros(shape)
        # one row of n columns: CasADi evaluates the scalar Function n times
        row = lambda a: np.broadcast_to(a, shape).reshape(1, n)  # noqa: E731
        value = cache[which](row(x), row(rate), theta)
        return np.asarray(value, dtype=float).reshape(shape)

    def plot(self, x=None, ax=None, label=None):
        """Plot f(x): the loading branch and, if any, the unloading branch.

        Parameters
        ----------
        x : array_like, optional
            Deflections (m or rad); default 201 points over ±0.1.
        ax : matplotlib Axes, optional
            Default: a new figure.
        label : str, optional
            Title (default: the curve's type).

        Returns
        -------
        matplotlib Axes
        """
        import matplotlib.pyplot as plt

        x = np.linspace(-0.1, 0.1, 201) if x is None else np.asarray(x, dtype=float).ravel()
        new = ax is None
        if new:
            _, ax = plt.subplots(figsize=(5, 3.5))
        # loading: the deflection grows in magnitude (x·ẋ > 0)
        ax.plot(x, self.force(x, np.sign(x) + (x == 0)), lw=1.5, label="loading")
        if self.unloading is not None:
            ax.plot(x, self.force(x, -np.sign(x) - (x == 0)), "--", lw=1.5, label="unloading")
        ax.axhline(0, color="k", lw=0.5)
        ax.axvline(0, color="k", lw=0.5)
        ax.set_xlabel("deflection x [m or rad]")
        ax.set_ylabel("f(x) [N or N·m]")
        ax.set_title(type(self).__name__ if label is None else label, fontsize=10)
        ax.legend(fontsize=8)
        ax.grid(alpha=0.3)
        ax.ticklabel_format(axis="y", style="sci", scilimits=(-3, 4))
        ax.locator_params(axis="x", nbins=6)
        if new:
            ax.figure.tight_layout()
        return ax

    def __repr__(self):
        args = ", ".join(f"{n}={v:g}" for n, v in zip(self.param_names, self.param_values))
        return f"{type(self).__name__}({args})"
