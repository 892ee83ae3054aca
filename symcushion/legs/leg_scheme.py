"""The leg-scheme interface: what every leg scheme shares with the touchdown step.

A leg scheme (the hinged strut of (2.1), ``symcushion.legs.strut``; the inverted
tripod, ``symcushion.legs.tripod``) is a massless compliant mechanism with a foot. The
step calls it only through ``functions()`` (``strut_force``, ``strut_stiffness``,
``strut_geometry``), the memory law's Functions built here from the scheme's
``memory_force_expr``, ``next_sets_expr``, ``free_foot_expr`` and
``deflections_expr`` and, for an axial element that keeps a set,
``axial_lower_bound_expr``, ``axial_elastic_line_expr`` and
``axial_band_force_expr`` (docs/tripod.md,
"Interface"; docs/absorbers.md), its
deflection outputs and its geometry block in ``p``.

This module owns the pieces both schemes build the same way: the names and
values of a leg's tunable curve parameters, the check of a ``p`` given to
a leg's NumPy calls, the memory law's named Functions, and a geometry
Function bound to a leg's slice of ``p``. It knows no scheme's geometry and nothing of contact or the body.
"""
from __future__ import annotations

import casadi as ca
import numpy as np

from symcushion.legs import absorber

__all__ = ["CurveParams", "checked_params", "cached_memory_functions",
           "memory_functions_of", "elastic_line", "band_part", "bound_geometry"]


class CurveParams:
    """The curve parameters of a leg scheme with ``elements`` (a mixin of both schemes):
    the entries of ``p`` its tunable curves own."""

    @property
    def param_names(self) -> tuple[str, ...]:
        """``element.parameter`` names of the tunable curves, in the order of ``p``
        (e.g. ``S.k``)."""
        return tuple(f"{el.name}.{n}" for el in self.elements if el.curve.tunable
                     for n in el.curve.param_names)

    @property
    def param_values(self) -> np.ndarray:
        """Default values of ``p``."""
        vals = [el.curve.param_values for el in self.elements if el.curve.tunable]
        return np.concatenate(vals) if vals else np.zeros(0)


def checked_params(leg, p) -> np.ndarray:
    """The ``p`` of a leg's NumPy calls: ``leg.param_values`` when ``p`` is None, else
    ``p`` as a flat float array, refused unless it has one entry per ``leg.param_names``."""
    if p is None:
        return leg.param_values
    p = np.asarray(p, dtype=float).ravel()
    if p.size != len(leg.param_names):
        raise ValueError(f"`p` must have {len(leg.param_names)} entries "
                         f"{leg.param_names}, got {p.size}.")
    return p


def cached_memory_functions(leg, geometry: str) -> dict[str, ca.Function]:
    """``leg``'s memory Functions for ``geometry``, built once into ``leg._memory_functions``;
    a leg whose elements keep no state is refused."""
    if not leg.axial_state:
        raise ValueError("this leg's elements keep no state (a crushable element, "
                         "one with an unloading curve, or a damped one does); use "
                         "`functions()`.")
    if geometry not in leg._memory_functions:
        leg._memory_functions[geometry] = memory_functions_of(leg, geometry)
    return leg._memory_functions[geometry]


def memory_functions_of(leg, geometry: str = "constant") -> dict[str, ca.Function]:
    """The memory law's named Functions of any leg scheme with ``memory_force_expr``,
    ``next_sets_expr``, ``free_foot_expr``, ``deflections_expr`` and ``_p_size``;
    ``geometry="input"``: ``p`` ends with the leg's geometry block.

    A scheme whose axial element keeps a set (``axial_memory``) and that has
    ``axial_lower_bound_expr``, ``axial_elastic_line_expr`` and
    ``axial_band_force_expr`` also gets
    ``strut_crush_curve(x, p) -> (f, slope)``, the lower bound lo(x) of (A1) that
    the element crushes along, and ``strut_elastic_line(x, set, rate, p) -> (f,
    slope)``, its elastic line k_e(x − s) + c·ė through the set s (A1), (A5), with
    ė the elastic deflection's rate and slope k_e, and (from
    ``axial_band_force_expr``) ``strut_band_force(r, P, rate, p) -> f``, the
    element's force (A1), (A5) that the foot force P at foot r carries, less its end
    stop and its orifice at ``rate`` (:func:`band_part`).
    """
    r, r_regime = ca.SX.sym("r", 3), ca.SX.sym("r_regime", 3)
    sets = ca.SX.sym("sets", 3)
    p = ca.SX.sym("p", leg._p_size(geometry))
    rate = ca.SX.sym("rate_gain"), ca.SX.sym("rate_offset", 3)
    P = leg.memory_force_expr(r, sets, p, rate=rate)
    Dp = ca.jacobian(leg.memory_force_expr(r, sets, p, r_regime, rate), r)
    x0, rate0, dt = ca.SX.sym("deflection_start", 3), ca.SX.sym("mean_rate", 3), ca.SX.sym("dt")
    names = ["r", "sets", "p", "rate_gain", "rate_offset"]
    fns = {
        "strut_force_memory": ca.Function("strut_force_memory", [r, sets, p, *rate], [P],
                                          names, ["P"]),
        "strut_stiffness_memory": ca.Function("strut_stiffness_memory",
                                              [r, sets, p, *rate, r_regime], [Dp],
                                              names + ["r_regime"], ["Dp"]),
        "strut_next_set": ca.Function("strut_next_set", [r, sets, p, *rate],
                                      [leg.next_sets_expr(r, sets, p, rate)],
                                      names, ["next_set"]),
        "strut_deflections": ca.Function("strut_deflections", [r, p],
                                         [leg.deflections_expr(r, p)], ["r", "p"], ["x"]),
        "strut_free_foot": ca.Function(
            "strut_free_foot", [sets, p, x0, rate0, dt],
            [leg.free_foot_expr(sets, p, x0, rate0, dt)],
            ["sets", "p", "deflection_start", "mean_rate", "dt"], ["r"]),
    }
    lower = getattr(leg, "axial_lower_bound_expr", None)
    x = ca.SX.sym("x")
    lo = lower(x, p) if lower is not None and leg.axial_memory else None
    if lo is not None:
        # the axial element's force law along a step, for the kinks inside it
        # (symcushion.scheme.foot_step.FeetStep.kink_kick): the loading curve it crushes along
        # and the elastic line of its set (A1), (A5), which it reloads along
        fns["strut_crush_curve"] = ca.Function(
            "strut_crush_curve", [x, p], [lo, ca.jacobian(lo, x)], ["x", "p"], ["f", "slope"])
        s, rate = ca.SX.sym("set"), ca.SX.sym("rate")
        line = leg.axial_elastic_line_expr(x, s, rate, p)
        fns["strut_elastic_line"] = ca.Function(
            "strut_elastic_line", [x, s, rate, p], [line, ca.jacobian(line, x)],
            ["x", "set", "rate", "p"], ["f", "slope"])
        force = ca.SX.sym("P", 3)
        fns["strut_band_force"] = ca.Function(
            "strut_band_force", [r, force, rate, p],
            [leg.axial_band_force_expr(r, force, rate, p)], ["r", "P", "rate", "p"], ["f"])
    return fns


def elastic_line(curve, x, s, rate, theta=None):
    """An element's elastic line through its set ``s`` at deflection ``x``: k_e (x − s)
    + c·ė (N or N·m), the trial force of (A1) with the viscous damper on the elastic
    line (A5), ė = ``rate`` the elastic deflection's rate; k_e from ``theta``'s curve
    parameters (``absorber.elastic_stiffness``)."""
    return absorber.elastic_stiffness(curve, theta) * (x - s) + curve.damping * rate


def band_part(curve, x, force, rate, theta=None):
    """The part of an element's force ``force`` at deflection ``x`` that is (A1) with its
    elastic line's damper (A5): less its end stop and its orifice damper, which act in
    parallel (``absorber.element_force``), the orifice at the rate ``rate``."""
    return (force - curve.end_stop(x, theta)
            - curve.orifice * rate * ca.fabs(rate))


class bound_geometry:
    """``strut_geometry(r, p)`` with its ``p`` bound: called, like the constant-geometry
    Function, as ``f(r)`` or ``f.call(dict(r=...))``; the step binds each leg's slice
    of its ``p`` (symcushion.scheme.touchdown)."""

    def __init__(self, function: ca.Function, p):
        self.function, self.p = function, p

    def __call__(self, r):
        return tuple(self.function(r, self.p))

    def call(self, args: dict) -> dict:
        return self.function.call(dict(args, p=self.p))
