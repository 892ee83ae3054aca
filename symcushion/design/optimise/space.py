"""The design space: named variables over the legs' curve parameters, and curve shapes.

Owns resolving design variables from parameter-name patterns (shared by
symmetric legs, bounds, scales, the map p = p_fixed + M θ of the curves'
parameters; geometry variables, nonlinear in θ, come from :mod:`.geometry`), the tuned curves
and their shape rows (monotone loading, onset slope, unloading below
loading), and the curves' values at a design. A mixin of every design
problem (:class:`~symcushion.design.optimise.DesignProblem` and the envelope
design of :mod:`symcushion.design.robust`): it reads ``param_names``,
``p_default``, ``legs`` and ``limits`` (stroke, beta, gamma: the ranges of
the shape checks) from its host. It must not simulate, state objectives or
call a solver.
"""
from __future__ import annotations

import fnmatch
import math

import casadi as ca
import numpy as np

from symcushion.legs.characteristics import PiecewiseLinear
from symcushion.legs.curve_base import Curve
from symcushion.design.optimise.geometry import GeometryDesign
from symcushion.design.optimise.shape_points import branch_rate, shape_points
from symcushion.design.optimise.spec import real_number, CurveShape, DesignVariable

__all__ = ["ONSET_SLOPE_FRACTION"]

#: Default lower bound on the slope of a tuned loading curve next to zero
#: deflection, as a fraction of the initial curve's slope there. A curve that
#: is flat at zero force lets the foot of a massless leg sink without any
#: force, which the contact step reads as lift-off: the body falls through
#: and every output jumps (docs/optimise.md, "contact onset"). A tenth of the
#: starting stiffness keeps well away from that edge and is not active at the
#: optima measured here.
ONSET_SLOPE_FRACTION = 0.1


class DesignSpace(GeometryDesign):
    """Design variables, curve shapes and (through :class:`GeometryDesign`) the legs'
    geometry of a design problem (a mixin)."""

    def _resolve_variables(self, specs, geometry=()):
        """Curve variables from ``specs``; ``geometry`` (GeometryVariable) may stand alone."""
        if not specs and not geometry:
            raise ValueError("no design variables; give at least one (e.g. names = \"S.f*\") "
                             "and mark the curve `tunable = true`, or a geometry variable.")
        if not specs:
            self.var_names, self.var_index = [], []
            self.lower = self.upper = self.scale = self.initial = np.zeros(0)
            self._map = np.zeros((len(self.param_names), 0))
            self.p_fixed = np.asarray(self.p_default, dtype=float)
            return
        if not self.param_names:
            raise ValueError("the legs have no tunable parameters; mark a curve "
                             "`tunable = true` to make its parameters design variables.")
        short = [n.split(".", 1)[1] for n in self.param_names]
        taken = {}
        self.var_names, self.var_index, lower, upper, scale = [], [], [], [], []
        for i, spec in enumerate(specs):
            if not isinstance(spec, DesignVariable):
                raise TypeError(f"`variables[{i}]` must be a DesignVariable, got {spec!r}.")
            patterns = [spec.names] if isinstance(spec.names, str) else list(spec.names)
            excluded = [spec.exclude] if isinstance(spec.exclude, str) else list(spec.exclude)
            lo = real_number(f"variables[{i}].lower", spec.lower)
            hi = real_number(f"variables[{i}].upper", spec.upper)
            if lo > hi:
                raise ValueError(f"design variables {patterns}: `lower` = {lo:g} > `upper` = "
                                 f"{hi:g}; swap the bounds.")
            groups = {}
            for k, (full, sh) in enumerate(zip(self.param_names, short)):
                hit = any(fnmatch.fnmatchcase(full if pat.startswith("leg") else sh, pat)
                          for pat in patterns)
                out = any(fnmatch.fnmatchcase(full if pat.startswith("leg") else sh, pat)
                          for pat in excluded)
                if hit and not out:
                    key = sh if spec.shared else full
                    groups.setdefault(key, []).append(k)
            if not groups:
                raise ValueError(
                    f"design variables {patterns} match no tunable parameter; the tunable "
                    f"parameters are {list(self.param_names)} (patterns without `leg<j>.` "
                    "match every leg).")
            start = len(self.var_names)
            for key, idx in groups.items():
                for k in idx:
                    if k in taken:
                        raise ValueError(f"parameter `{self.param_names[k]}` is matched by "
                                         f"design variables {taken[k]} and {patterns}; "
                                         "match each parameter once.")
                    taken[k] = patterns
                values = self.p_default[idx]
                if np.ptp(values) > 0:
                    raise ValueError(f"design variable `{key}` is shared by legs whose initial "
                                     f"values differ ({values.tolist()}); give the legs equal "
                                     "values or set `shared = false`.")
                if not lo <= values[0] <= hi:
                    raise ValueError(f"design variable `{key}` starts at {values[0]:g}, outside "
                                     f"its bounds [{lo:g}, {hi:g}]; widen the bounds or change "
                                     "the scene's curve.")
                self.var_names.append(key)
                self.var_index.append(idx)
                lower.append(lo)
                upper.append(hi)
            if spec.scale is not None:
                sc = real_number(f"variables[{i}].scale", spec.scale, positive=True)
            else:
                sc = float(np.max(np.abs(self.p_default[sum(groups.values(), [])])))
                sc = sc if sc > 0 else 1.0
            scale += [sc] * (len(self.var_names) - start)
        self.lower, self.upper = np.array(lower), np.array(upper)
        self.scale = np.array(scale)
        n = len(self.var_names)
        self._map = np.zeros((len(self.param_names), n))     # p = p_fixed + M θ
        for j, idx in enumerate(self.var_index):
            self._map[idx, j] = 1.0
        self.p_fixed = np.where(self._map.any(axis=1), 0.0, self.p_default)
        self.initial = np.array([self.p_default[idx[0]] for idx in self.var_index])

    def _element_params(self):
        """(leg j, element, curve, indices of its parameters in p) of tuned curves."""
        out, seen = [], set()
        for j, leg in enumerate(self.legs):
            for el in leg.elements:
                if not el.curve.tunable:
                    continue
                idx = [self.param_names.index(f"leg{j}.{el.name}.{n}")
                       for n in el.curve.param_names]
                if not self._map[idx].any():
                    continue                        # nothing of this curve is designed
                key = (id(el.curve), self._map[idx].tobytes(), self.p_fixed[idx].tobytes())
                if key in seen:
                    continue                        # same curve, same variables (symmetric legs)
                seen.add(key)
                out.append((j, el.name, el.curve, idx))
        return out

    def _resolve_shapes(self, shapes):
        by_element = {}
        for s in shapes:
            if not isinstance(s, CurveShape):
                raise TypeError(f"`shapes` entries must be CurveShape, got {s!r}.")
            if s.element not in ("S", "M_beta", "M_gamma"):
                raise ValueError(f"`shape.element` must be 'S', 'M_beta' or 'M_gamma', got "
                                 f"{s.element!r}.")
            by_element[s.element] = s
        out = []
        for j, name, curve, idx in self._element_params():
            out.append((j, name, curve, idx, by_element.get(name, CurveShape(name))))
        return out

    def p_of(self, theta):
        """Full parameter vector p (``param_names``) of design values θ (SI)."""
        return self.p_fixed + self._map @ np.asarray(theta, dtype=float)

    def _add_shape_constraints(self, theta, add):
        """Monotone loading, onset slope and unloading-below rows, in terms of θ."""
        p = ca.DM(self.p_fixed) + ca.DM(self._map) @ theta
        lim = self.limits
        ranges = dict(S=lim.stroke, M_beta=lim.beta, M_gamma=lim.gamma)
        for j, name, curve, idx, shape in self._shapes:
            th = ca.vertcat(*[p[k] for k in idx])
            th0 = self.p_of(self.initial)[idx]
            where = f"leg{j}.{name}"
            points = shape_points(curve, ranges.get(name))
            force_scale = max(float(np.max(np.abs([curve.force(x, branch_rate(curve, x, True), th0)
                                                   for x in points]))), 1e-12)
            slopes, mids, onset = _loading_slopes(curve, th, points)
            if shape.monotone and slopes is not None:
                slope0 = np.array([float(v) for v in _loading_slopes(curve, th0, points)[0]])
                k_onset = shape.onset_slope
                if k_onset is None:
                    k_onset = ONSET_SLOPE_FRACTION * float(np.min(slope0[onset])) \
                        if np.any(onset) else 0.0
                    if np.any(onset) and k_onset <= 0:
                        raise ValueError(
                            f"{where}: the initial loading curve is not rising at zero "
                            f"deflection (slope {np.min(slope0[onset]):g}); start from a "
                            "rising curve or give `onset_slope` explicitly.")
                minimum = np.where(onset, k_onset, 0.0)
                slope_scale = max(float(np.max(np.abs(slope0))), 1e-12)
                for i in range(len(slopes)):
                    add(slopes[i] - minimum[i], "shape", slope_scale, 0.0, math.inf,
                        "N/m" if name == "S" else "N·m/rad", label=(
                            f"{where} loading slope at x = {mids[i]:.4g} ≥ {minimum[i]:.4g}"))
            if shape.unloading_below and curve.unloading is not None:
                for x in points:
                    if x == 0:
                        continue
                    gap = np.sign(x) * (curve.force(x, branch_rate(curve, x, True), th)
                                        - curve.force(x, branch_rate(curve, x, False), th))
                    add(gap, "shape", force_scale, 0.0, math.inf,
                        "N" if name == "S" else "N·m",
                        label=f"{where} unloading below loading at x = {x:.4g}")

    def characteristics(self, theta) -> dict:
        """Loading and unloading values of each tuned curve at its check points."""
        out = {}
        theta = np.asarray(theta, dtype=float)
        p = self.p_of(theta)
        ranges = dict(S=self.limits.stroke, M_beta=self.limits.beta, M_gamma=self.limits.gamma)
        for j, name, curve, idx, _ in self._shapes:
            th = p[idx]
            legs = [i for i, leg in enumerate(self.legs)
                    if any(el.curve is curve for el in leg.elements)]
            points = [float(x) for x in shape_points(curve, ranges.get(name))]
            entry = dict(element=name, legs=legs, type=type(curve).__name__,
                         parameters={n: float(v) for n, v in zip(curve.param_names, th)},
                         x=points,
                         loading=[float(curve.force(x, branch_rate(curve, x, True), th))
                                  for x in points])
            if curve.unloading is not None:
                entry["unloading"] = [float(curve.force(x, branch_rate(curve, x, False), th))
                                      for x in points]
            out[f"leg{j}.{name}"] = entry
        return out


def _loading_slopes(curve: Curve, th, points):
    """Slopes of the loading branch, where, and which are next to x = 0.

    For a piecewise-linear curve the slopes of its segments, from the knot
    values (exact; a smoothed curve's slope blends neighbouring segments, so
    it is monotone when they are); otherwise the slope at the check points.
    """
    if isinstance(curve, PiecewiseLinear):
        xs = curve.knots
        m = xs.size
        slopes = [(th[i + 1] - th[i]) / (xs[i + 1] - xs[i]) for i in range(m - 1)]
        mids = 0.5 * (xs[1:] + xs[:-1])
        onset = (xs[:-1] <= 0) & (xs[1:] >= 0)
        if not onset.any():                          # zero outside the knots: end segment
            onset[0 if xs[0] > 0 else -1] = True
        return slopes, mids, onset
    pts = [x for x in points if x != 0]
    if not pts:
        return None, None, None
    slopes = [curve.slope(x, branch_rate(curve, x, True), th) for x in pts]
    pts = np.asarray(pts)
    onset = np.zeros(pts.size, dtype=bool)
    for side in (pts < 0, pts > 0):
        if side.any():
            onset[np.flatnonzero(side)[np.argmin(np.abs(pts[side]))]] = True
    return slopes, pts, onset
