"""Design optimisation of landing legs through the differentiable touchdown.

A *design problem* is a set of touchdown scenarios (a scene and its initial
conditions) sharing one set of legs, a selection of the legs' tunable
parameters as design variables (``model.param_names`` entries, with bounds),
shape constraints on the tuned curves, an objective and limits:

    minimise    t                                    (epigraph of the peak)
    subject to  a_k^(s) ≤ t                    every step k, scenario s
                |δ_S,jk^(s)| ≤ s_max,  |β_jk| ≤ β_max,  |γ_jk − γ₀| ≤ γ_max
                1 − cos(tilt_k^(s)) ≤ 1 − cos(tilt_max)
                −v_sink ≤ v_up^(s)(T) ≤ v_rebound
                f_L′ ≥ 0 (monotone), f_L′ ≥ k_onset near x = 0,
                sign(x)(f_L(x) − f_U(x)) ≥ 0 (unloading below loading)
                lower ≤ θ ≤ upper

with a_k = (ÿ_k − g)·e_up the vertical *specific force* of the body (leg
forces over mass, gravity excluded: what an accelerometer on the body reads).
The peak is never written as a non-smooth max: t is a variable and every
step contributes a smooth constraint. The rollout is ``touchdown_rollout``
(one MX Function per scenario), so Ipopt gets exact first derivatives by AD
through the whole simulation; the Hessian is approximated by L-BFGS
(:data:`IPOPT_DEFAULTS`). ``docs/optimise.md`` explains how the problem is kept
solvable despite contact onset and branch switching.

This module owns the problem statement, its scaling, the solver call, the
gradient check and the study files (TOML). It does not integrate anything
itself: it receives ``touchdown_rollout`` from ``symcushion.simulate``.

References
----------
V. F. Khvostov (1976), Izv. AN SSSR MTT, §2 (the leg force law (2.1) whose
curves are tuned here) and §3 (the touchdown simulation differentiated here).
"""
from __future__ import annotations

import dataclasses
import fnmatch
import json
import math
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Sequence

import casadi as ca
import numpy as np

from .characteristics import Curve, PiecewiseLinear
from .obstacles import closest_obstacle
from .scene import Scene, _Table, read_toml, scene_from_dict
from .layout import quat_to_rot_np, state_layout
from .measures import measures_function
from .touchdown import build_model, initial_state

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

__all__ = [
    "CurveShape",
    "DesignProblem",
    "DesignResult",
    "DesignVariable",
    "Evaluation",
    "Limits",
    "Scenario",
    "Study",
    "FD_STEP",
    "ROW_FLOOR",
    "FD_AGREEMENT",
    "IPOPT_DEFAULTS",
    "OBJECTIVES",
    "ONSET_SLOPE_FRACTION",
    "load_study",
    "run_study",
    "study_from_dict",
]

#: Objectives: the largest vertical specific force over all scenarios and steps
#: (m/s²), or the largest axial stroke |δ_S| over all legs (m).
OBJECTIVES = ("peak_deceleration", "peak_stroke")

#: Ipopt options used unless a study overrides them (docs/optimise.md has the
#: measurements behind each choice).
#:
#: * L-BFGS: an exact Hessian needs second-order AD through every step of
#:   every rollout; on the 1-D absorber it took 199 iterations and 133 s
#:   against 65 iterations and 10 s with L-BFGS, to the same optimum.
#: * A monotone barrier from μ₀ = 1e-4: the problem has one row per step,
#:   scenario and limit (10³–10⁴ rows), and at barrier parameter μ the
#:   central path keeps each row about μ/(its multiplier) inside its limit, so
#:   the epigraph variable sits ~N·μ above the peak. Under L-BFGS Ipopt's
#:   default is the adaptive strategy, which chose μ ≈ 0.2 here: t drifted to
#:   10²–10³ times the peak and the design to stiff curves where it stalled
#:   (the lander study and the tripod test problem). From μ₀ = 1e-4 both
#:   converge; the 1-D absorber converges either way.
#: * tol 1e-8 on the scaled problem (variables, objective and rows all O(1));
#:   print_level 0 because the driver prints its own line per iteration.
IPOPT_DEFAULTS = {
    "hessian_approximation": "limited-memory",
    "mu_strategy": "monotone",
    "mu_init": 1e-4,
    "tol": 1e-8,
    "acceptable_tol": 1e-6,
    "max_iter": 300,
    "print_level": 0,
    "sb": "yes",
}

#: Default lower bound on the slope of a tuned loading curve next to zero
#: deflection, as a fraction of the initial curve's slope there. A curve that
#: is flat at zero force lets the foot of a massless leg sink without any
#: force, which the contact step reads as lift-off: the body falls through
#: and every output jumps (docs/optimise.md, "contact onset"). A tenth of the
#: starting stiffness keeps well away from that edge and is not active at the
#: optima measured here.
ONSET_SLOPE_FRACTION = 0.1

#: Number of check points per side of zero for shape constraints of curves
#: without knots (linear, crushable), on [−range, range].
SHAPE_GRID = 8

#: x·ẋ used to select a single branch of a curve when evaluating its shape,
#: in units of the curve's ``rate_width``: tanh(50) = 1 to double precision,
#: so a smooth curve then returns exactly its loading or unloading branch.
_BRANCH_SELECT = 50.0

#: Central-difference step on the *scaled* design variables (all O(1)):
#: truncation ≈ h²·f‴ ≈ 1e-10, round-off ≈ ε·|f|/h ≈ 1e-11 relative.
FD_STEP = 1e-5

#: Rows of the Jacobian whose norm is below this fraction of the largest are
#: left out of ``worst_row`` in :meth:`DesignProblem.check_gradient`: central
#: differences carry a round-off of about eps/FD_STEP ≈ 2e-11 per unit of the
#: (O(1), scaled) row values, so a relative accuracy of 1e-5 cannot be resolved
#: on rows much smaller than 1e-5. Measured on the lander: the worst error of
#: such rows grows as 1/step (1e-4, 2e-3, 2e-2 at steps 1e-5, 1e-6, 1e-7), the
#: signature of round-off, not of a wrong derivative.
ROW_FLOOR = 1e-4

#: Two central differences of a row, at FD_STEP and FD_STEP/10, agreeing to
#: this fraction of the row's norm mark it smooth within FD_STEP of the design
#: (``check_gradient``); far stricter than any jump, which gives O(1/step).
FD_AGREEMENT = 1e-6

#: Iterations of the vertical placement of a scenario's body (``clearance``):
#: exact in one for planes, a few for curved obstacles.
_PLACEMENT_ITERS = 20

#: Feasible start (:meth:`DesignProblem.feasible_start`): largest uniform
#: scale factor tried, bisection steps (2⁻¹² relative), and the margin added
#: so that Ipopt starts strictly inside the limits.
FEASIBLE_SCALE_MAX = 64.0
FEASIBLE_BISECTIONS = 12
FEASIBLE_MARGIN = 1e-2

#: A constraint counts as violated beyond this, relative to its limit
#: (Ipopt's own constr_viol_tol is 1e-4 absolute on the scaled rows).
VIOLATION_TOL = 1e-6

#: Number of worst violations listed in messages.
_REPORT_WORST = 5


# ---------------------------------------------------------------------------
# problem statement
# ---------------------------------------------------------------------------
@dataclass
class Scenario:
    """One touchdown: a scene (legs, obstacles, time grid) and its initial state.

    Attributes
    ----------
    name : str
    scene : Scene
        Scenarios of one problem share the scene's legs (same ``param_names``).
    x0 : ndarray, shape (nx,), optional
        Initial state; default :func:`symcushion.simulate.initial_state`.
    """

    name: str
    scene: Scene
    x0: np.ndarray | None = None


@dataclass
class DesignVariable:
    """Design variables: the tunable parameters whose names match a pattern.

    Attributes
    ----------
    names : str or sequence of str
        ``fnmatch`` patterns. A pattern without the ``leg{j}.`` prefix (e.g.
        ``"S.f*"``) matches that parameter on every leg; with it
        (``"leg0.S.f3"``), on that leg only.
    lower, upper : float
        Bounds (SI units of the parameter).
    shared : bool
        True: one variable per parameter name, shared by all legs matched
        (a symmetric design). False: one variable per leg.
    exclude : sequence of str
        Patterns removed from the match (e.g. ``"S.f15"`` to keep f(0) = 0).
    scale : float, optional
        Typical magnitude; default the largest |initial value| of the match.
    """

    names: str | Sequence[str]
    lower: float = -math.inf
    upper: float = math.inf
    shared: bool = True
    exclude: Sequence[str] = ()
    scale: float | None = None


@dataclass
class CurveShape:
    """Shape constraints of the curves of one leg element that are being tuned.

    Attributes
    ----------
    element : {'S', 'M_beta', 'M_gamma'}
    monotone : bool
        Loading branch non-decreasing: f_L′ ≥ 0 (restoring everywhere).
    unloading_below : bool
        sign(x)·(f_L(x) − f_U(x)) ≥ 0: unloading never resists more than
        loading, so a load cycle dissipates.
    onset_slope : float, optional
        Lower bound on f_L′ next to x = 0 (N/m or N·m/rad); default
        :data:`ONSET_SLOPE_FRACTION` times the initial slope there.
    """

    element: str
    monotone: bool = True
    unloading_below: bool = True
    onset_slope: float | None = None


@dataclass
class Limits:
    """Limits checked at every step of every scenario (None: not imposed).

    Attributes
    ----------
    stroke : float
        |δ_S| ≤ stroke (m), every leg with an axial element.
    beta, gamma : float
        |β| ≤ beta, |γ − γ₀| ≤ gamma (rad), every leg.
    tilt : float
        Angle of the body z axis from the vertical ≤ tilt (rad).
    rebound_speed : float
        Upward vertical speed at the end of each scenario ≤ rebound_speed (m/s).
    sink_speed : float
        Downward vertical speed at the end ≤ sink_speed (m/s). The default 0
        makes the descent be arrested within the simulated time, so that the
        stroke constraint sees the whole stroke.
    deceleration : float
        Peak vertical specific force ≤ deceleration (m/s²).
    """

    stroke: float | None = None
    beta: float | None = None
    gamma: float | None = None
    tilt: float | None = None
    rebound_speed: float | None = None
    sink_speed: float | None = 0.0
    deceleration: float | None = None

    def __post_init__(self):
        for name in ("stroke", "beta", "gamma", "tilt", "rebound_speed", "deceleration"):
            value = getattr(self, name)
            if value is not None:
                setattr(self, name, _real(f"limits.{name}", value, positive=True))
        if self.sink_speed is not None:
            self.sink_speed = _real("limits.sink_speed", self.sink_speed, nonnegative=True)
        if self.tilt is not None and self.tilt >= math.pi:
            raise ValueError(f"`limits.tilt` must be below π rad, got {self.tilt!r}; "
                             "give the largest allowed tilt in radians.")


def _real(name, value, *, positive=False, nonnegative=False):
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
        raise TypeError(f"`{name}` must be a number, got {value!r}.")
    value = float(value)
    if math.isnan(value):
        raise ValueError(f"`{name}` must be a number, got NaN.")
    if positive and not value > 0:
        raise ValueError(f"`{name}` must be positive, got {value!r}; give a value > 0.")
    if nonnegative and not value >= 0:
        raise ValueError(f"`{name}` must be non-negative, got {value!r}; give a value >= 0.")
    return value


@dataclass
class _Block:
    """A block of rows of the constraint vector, for reports."""

    kind: str            # 'epigraph', 'stroke', 'beta', 'gamma', 'tilt', 'final_speed', …
    scenario: str | None
    leg: int | None
    start: int
    stop: int
    lower: float
    upper: float
    scale: float         # physical value = scaled value × scale
    unit: str
    dt: float | None = None
    label: str = ""


@dataclass
class Evaluation:
    """Objective, per-scenario measures and constraint violations of one design.

    Attributes
    ----------
    objective : float
        Peak deceleration (m/s²) or peak stroke (m) over all scenarios.
    scenarios : dict
        Per scenario: peak_deceleration (m/s²), max_stroke (m), max_beta,
        max_gamma, max_tilt (rad), final_vertical_speed (m/s), and, for
        vertical legs with a stroke limit, ideal_peak_deceleration and
        efficiency (docs/optimise.md).
    violations : list of str
        One message per violated constraint (worst first), naming the
        constraint, the scenario, the leg and the time.
    max_violation : float
        Largest violation relative to its limit (0 when feasible).
    """

    objective: float
    scenarios: dict
    violations: list
    max_violation: float

    @property
    def feasible(self) -> bool:
        return not self.violations


class DesignProblem:
    """The design NLP over a set of scenarios.

    Parameters
    ----------
    scenarios : sequence of Scenario
    variables : sequence of DesignVariable
    limits : Limits
    objective : {'peak_deceleration', 'peak_stroke'}
    shapes : sequence of CurveShape, optional
        Default: monotone and unloading-below for every element with a design
        variable. An element not listed gets the default.

    Notes
    -----
    Scaling: each variable is divided by its ``scale``; the epigraph variable
    by the initial design's objective; each constraint by its limit (strokes
    by ``stroke``, the epigraph rows by the initial peak), so that Ipopt sees
    O(1) numbers everywhere.
    """

    def __init__(self, scenarios: Sequence[Scenario], variables: Sequence[DesignVariable],
                 limits: Limits | None = None, objective: str = "peak_deceleration",
                 shapes: Sequence[CurveShape] = ()):
        started = time.perf_counter()
        self.scenarios = list(scenarios)
        if not self.scenarios or not all(isinstance(s, Scenario) for s in self.scenarios):
            raise ValueError("`scenarios` must be a non-empty list of Scenario.")
        names = [s.name for s in self.scenarios]
        if len(set(names)) != len(names):
            raise ValueError(f"scenario names must be unique, got {names}.")
        if objective not in OBJECTIVES:
            raise ValueError(f"`objective` must be one of {OBJECTIVES}, got {objective!r}.")
        self.objective_kind = objective
        self.limits = limits if limits is not None else Limits()
        if not isinstance(self.limits, Limits):
            raise TypeError(f"`limits` must be a Limits, got {type(self.limits).__name__}.")
        if objective == "peak_stroke" and self.limits.stroke is not None:
            raise ValueError("`limits.stroke` is meaningless with objective 'peak_stroke' "
                             "(the stroke is minimised); remove it or change the objective.")

        self._models = {}
        self.models = [self._model(s.scene) for s in self.scenarios]
        # design variables are the legs' curve parameters, the head of every model's p;
        # the scene entries after them (μ, gravity, body) stay each scenario's own
        self.param_names = _leg_param_names(self.models[0])
        for s, m in zip(self.scenarios, self.models):
            if _leg_param_names(m) != self.param_names:
                raise ValueError(f"scenario `{s.name}` has parameters {_leg_param_names(m)}, "
                                 f"the first scenario {self.param_names}; scenarios must share "
                                 "legs.")
            if s.x0 is None:
                s.x0 = initial_state(s.scene)
            s.x0 = np.asarray(s.x0, dtype=float).ravel()
            if s.x0.shape != (m.nx,):
                raise ValueError(f"scenario `{s.name}`: `x0` must have {m.nx} entries, "
                                 f"got {s.x0.size}.")
        self.legs = self.scenarios[0].scene.legs
        self.p_default = np.concatenate([leg.param_values for leg in self.legs]) \
            if self.param_names else np.zeros(0)
        self._resolve_variables(list(variables))
        self._shapes = self._resolve_shapes(list(shapes))
        self._build()
        self.build_seconds = time.perf_counter() - started

    # -- construction -----------------------------------------------------------
    def _model(self, scene):
        key = (tuple(map(id, scene.legs)), tuple(map(id, scene.obstacles)), scene.mu,
               scene.method, scene.tangent_plane, scene.body.mass, scene.body.inertia.tobytes(),
               scene.gravity.tobytes())
        if key not in self._models:
            self._models[key] = build_model(scene)
        return self._models[key]

    def _resolve_variables(self, specs):
        if not specs:
            raise ValueError("no design variables; give at least one (e.g. names = \"S.f*\") "
                             "and mark the curve `tunable = true`.")
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
            lo = _real(f"variables[{i}].lower", spec.lower)
            hi = _real(f"variables[{i}].upper", spec.upper)
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
                sc = _real(f"variables[{i}].scale", spec.scale, positive=True)
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

    def _build(self):
        lim = self.limits
        nv = len(self.var_names)
        w = ca.MX.sym("w", nv)                     # scaled design θ/scale
        t = ca.MX.sym("t")                         # scaled epigraph variable
        theta = w * ca.DM(self.scale)
        p = ca.DM(self.p_fixed) + ca.DM(self._map) @ theta
        blocks, rows = [], []
        n_rows = 0

        def add(expr, kind, scale, lower, upper, unit, scenario=None, leg=None, dt=None, label=""):
            nonlocal n_rows
            expr = ca.vec(expr)
            if kind == "shape" and not ca.depends_on(expr, w):
                # fixed by parameters that are not designed: check once, add no row
                value = float(ca.Function("fixed", [w], [expr])(np.zeros(nv)))
                if not lower - VIOLATION_TOL <= value / scale <= upper + VIOLATION_TOL:
                    raise ValueError(f"shape constraint `{label}` fails ({value:.4g} {unit}) "
                                     "and no design variable can change it; make the "
                                     "parameters involved design variables or fix the curve.")
                return
            blocks.append(_Block(kind, scenario, leg, n_rows, n_rows + expr.numel(), lower, upper,
                                 scale, unit, dt, label))
            rows.append(expr / scale)
            n_rows += expr.numel()

        # the initial design's peak scales the epigraph variable
        self._measure = []
        peak_exprs, stroke_exprs = [], []
        for s, model in zip(self.scenarios, self.models):
            scene = s.scene
            up = _up(scene.gravity)
            # the design rows of p, then this scenario's own μ, gravity and body
            p_full = ca.vertcat(p, ca.DM(model.default_p[model.params.n_leg_params:]))
            X, Y = model.rollout(scene.steps)(ca.DM(s.x0), p_full, scene.dt)
            per_step = measures_function(scene).map(scene.steps).call(
                dict(x=X, y=Y, p=ca.repmat(p_full, 1, scene.steps)))
            acc = ca.mtimes(ca.DM(up).T, per_step["specific_force"])
            strokes = [per_step["stroke"][j, :] for j in range(model.n_legs)]
            betas = [per_step["beta"][j, :] for j in range(model.n_legs)]
            gammas = [per_step["gamma_deflection"][j, :] for j in range(model.n_legs)]
            one_minus_cos_tilt = per_step["one_minus_cos_tilt"]
            v_up = per_step["upward_speed"][-1]
            axial = [j for j, leg in enumerate(scene.legs) if not leg.rigid]
            self._measure.append(dict(acc=acc, strokes=strokes, betas=betas, gammas=gammas,
                                      tilt=one_minus_cos_tilt, v_up=v_up, axial=axial))
            peak_exprs.append(acc)
            stroke_exprs += [strokes[j] for j in axial]

        w0 = self.initial / self.scale
        if self.objective_kind == "peak_deceleration":
            ref = max(float(np.max(np.concatenate([
                np.asarray(ca.Function("a", [w], [a])(w0)).ravel() for a in peak_exprs]))), 1e-12)
            if ref <= 1e-9:
                raise ValueError("the initial design gives no deceleration in any scenario: "
                                 "no foot touches the obstacle within the simulated time; "
                                 "lower the body (`clearance`) or lengthen `duration`.")
        else:
            if not stroke_exprs:
                raise ValueError("objective 'peak_stroke' needs legs with an axial element `S`.")
            ref = max(float(np.max(np.abs(np.concatenate([
                np.asarray(ca.Function("d", [w], [d])(w0)).ravel() for d in stroke_exprs])))),
                1e-12)
        self.objective_scale = ref

        for s, model, m in zip(self.scenarios, self.models, self._measure):
            dt = s.scene.dt
            if self.objective_kind == "peak_deceleration":
                add(m["acc"] - t * ref, "epigraph", ref, -math.inf, 0.0, "m/s²", s.name, dt=dt,
                    label="vertical deceleration ≤ t")
            if lim.deceleration is not None:
                add(m["acc"], "deceleration", lim.deceleration, -math.inf, 1.0, "m/s²", s.name,
                    dt=dt, label="vertical deceleration")
            for j in m["axial"]:
                if self.objective_kind == "peak_stroke":
                    add(ca.vertcat(m["strokes"][j] - t * ref, -m["strokes"][j] - t * ref),
                        "epigraph", ref, -math.inf, 0.0, "m", s.name, j, dt, "|δ_S| ≤ t")
                if lim.stroke is not None:
                    add(m["strokes"][j], "stroke", lim.stroke, -1.0, 1.0, "m", s.name, j, dt,
                        "axial stroke δ_S")
            for j in range(model.n_legs):
                if lim.beta is not None:
                    add(m["betas"][j], "beta", lim.beta, -1.0, 1.0, "rad", s.name, j, dt,
                        "hinge azimuth β")
                if lim.gamma is not None:
                    add(m["gammas"][j], "gamma", lim.gamma, -1.0, 1.0, "rad", s.name, j, dt,
                        "hinge polar deflection γ − γ₀")
            if lim.tilt is not None:
                add(m["tilt"], "tilt", 1 - math.cos(lim.tilt), -math.inf, 1.0, "", s.name,
                    dt=dt, label="body tilt (1 − cos)")
            if lim.rebound_speed is not None or lim.sink_speed is not None:
                top = lim.rebound_speed if lim.rebound_speed is not None else math.inf
                bottom = -lim.sink_speed if lim.sink_speed is not None else -math.inf
                v0 = state_layout(model.n_legs).get(s.x0, "velocity")
                sc = max(abs(float(np.dot(_up(s.scene.gravity), v0))), 0.1)
                add(m["v_up"], "final_speed", sc, bottom / sc, top / sc, "m/s", s.name,
                    label="final vertical speed")

        self._add_shape_constraints(theta, add)
        g = ca.vertcat(*rows)
        self.blocks = blocks
        self._w, self._t = w, t
        self.nlp = {"x": ca.vertcat(w, t), "f": t, "g": g}
        self.lbg = np.concatenate([np.full(b.stop - b.start, b.lower) for b in blocks])
        self.ubg = np.concatenate([np.full(b.stop - b.start, b.upper) for b in blocks])
        self._fg = ca.Function("design_fg", [self.nlp["x"]], [self.nlp["f"], g], ["x"],
                               ["f", "g"])
        self._outputs = ca.Function(
            "design_outputs", [w], [ca.vertcat(*[ca.vertcat(
                ca.vec(m["acc"]), *[ca.vec(d) for d in m["strokes"]],
                *[ca.vec(b) for b in m["betas"]], *[ca.vec(c) for c in m["gammas"]],
                ca.vec(m["tilt"]), m["v_up"]) for m in self._measure])], ["w"], ["y"])

    def _add_shape_constraints(self, theta, add):
        """Monotone loading, onset slope and unloading-below rows, in terms of θ."""
        p = ca.DM(self.p_fixed) + ca.DM(self._map) @ theta
        lim = self.limits
        ranges = dict(S=lim.stroke, M_beta=lim.beta, M_gamma=lim.gamma)
        for j, name, curve, idx, shape in self._shapes:
            th = ca.vertcat(*[p[k] for k in idx])
            th0 = self.p_of(self.initial)[idx]
            where = f"leg{j}.{name}"
            points = _check_points(curve, ranges.get(name))
            force_scale = max(float(np.max(np.abs([curve.force(x, _rate(curve, x, True), th0)
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
                    gap = np.sign(x) * (curve.force(x, _rate(curve, x, True), th)
                                        - curve.force(x, _rate(curve, x, False), th))
                    add(gap, "shape", force_scale, 0.0, math.inf,
                        "N" if name == "S" else "N·m",
                        label=f"{where} unloading below loading at x = {x:.4g}")

    # -- evaluation -------------------------------------------------------------
    @property
    def n_variables(self) -> int:
        return len(self.var_names)

    def scaled(self, theta, t=None):
        """NLP vector (θ/scale, t/t_ref) of design values θ (and epigraph t, SI)."""
        w = np.asarray(theta, dtype=float) / self.scale
        if t is None:
            t = self.evaluate(theta).objective
        return np.concatenate([w, [t / self.objective_scale]])

    def fg(self, x):
        """Scaled objective and constraint vector at the NLP vector x."""
        f, g = self._fg(x)
        return float(f), np.asarray(g, dtype=float).ravel()

    def evaluate(self, theta=None) -> Evaluation:
        """Simulate every scenario at design θ (SI; default the initial design).

        Returns
        -------
        Evaluation
            The objective and the violated limits and shape constraints, each
            named with its scenario, leg and time.
        """
        theta = self.initial if theta is None else np.asarray(theta, dtype=float).ravel()
        if theta.shape != (self.n_variables,):
            raise ValueError(f"`theta` must have {self.n_variables} entries {self.var_names}, "
                             f"got {theta.size}.")
        w = theta / self.scale
        y = np.asarray(self._outputs(w), dtype=float).ravel()
        scenarios, offset = {}, 0
        peaks, strokes = [], []
        for s, model, m in zip(self.scenarios, self.models, self._measure):
            n, nl = s.scene.steps, model.n_legs
            acc = y[offset:offset + n]
            offset += n
            parts = [y[offset + i * n: offset + (i + 1) * n] for i in range(3 * nl)]
            offset += 3 * nl * n
            stroke, beta, gamma = parts[:nl], parts[nl:2 * nl], parts[2 * nl:]
            tilt = y[offset:offset + n]
            v_up = float(y[offset + n])
            offset += n + 1
            info = dict(
                peak_deceleration=float(np.max(acc)),
                max_stroke=float(max((np.max(np.abs(stroke[j])) for j in m["axial"]),
                                     default=0.0)),
                max_beta=float(max(np.max(np.abs(b)) for b in beta)),
                max_gamma=float(max(np.max(np.abs(c)) for c in gamma)),
                max_tilt=float(np.arccos(np.clip(1 - np.max(tilt), -1.0, 1.0))),
                final_vertical_speed=v_up,
            )
            info.update(self._efficiency(s, info["peak_deceleration"]))
            scenarios[s.name] = info
            peaks.append(info["peak_deceleration"])
            strokes.append(info["max_stroke"])
        objective = max(peaks) if self.objective_kind == "peak_deceleration" else max(strokes)
        x = np.concatenate([w, [objective / self.objective_scale]])
        _, g = self.fg(x)
        violations, worst = self._violations(g)
        return Evaluation(objective=objective, scenarios=scenarios, violations=violations,
                          max_violation=worst)

    def _efficiency(self, s: Scenario, peak):
        """Ideal-absorber efficiency (v²/2s + g)/peak for vertical legs (else empty)."""
        scene = s.scene
        up = _up(scene.gravity)
        if self.limits.stroke is None or self.objective_kind != "peak_deceleration":
            return {}
        xl = state_layout(len(scene.legs))
        R = quat_to_rot_np(xl.get(s.x0, "attitude"))
        if not all(abs(float(np.dot(R @ leg.e0, up)) + 1) < 1e-9 for leg in scene.legs):
            return {}
        # vertical speed at touchdown from the initial speed and the height of the
        # lowest foot (energy; the legs are free until then)
        heights = []
        for j, leg in enumerate(scene.legs):
            foot = xl.get(s.x0, "foot", j)
            d, _, _ = closest_obstacle(scene.obstacles, ca.DM(foot))
            heights.append(float(d))
        g = float(np.linalg.norm(scene.gravity))
        v0 = float(np.dot(up, xl.get(s.x0, "velocity")))
        v_td2 = v0 ** 2 + 2 * g * max(min(heights), 0.0)
        ideal = v_td2 / (2 * self.limits.stroke) + g
        return dict(ideal_peak_deceleration=ideal, efficiency=ideal / peak if peak > 0 else None)

    def _violations(self, g):
        found = []
        for b in self.blocks:
            vals = g[b.start:b.stop]
            excess = np.maximum(vals - b.upper, b.lower - vals)
            excess = np.where(np.isfinite(excess), excess, 0.0)
            k = int(np.argmax(excess)) if excess.size else 0
            if excess.size and excess[k] > VIOLATION_TOL:
                found.append((float(excess[k]), self._describe(b, k, vals[k])))
        found.sort(key=lambda item: -item[0])
        return [msg for _, msg in found], (found[0][0] if found else 0.0)

    def _describe(self, b: _Block, k: int, value: float) -> str:
        where = f"scenario `{b.scenario}`" if b.scenario else "design"
        leg = f", leg {b.leg}" if b.leg is not None else ""
        when = f" at t = {(k + 1) * b.dt:.4g} s (step {k + 1})" if b.dt else ""
        phys = value * b.scale
        if b.kind == "tilt":
            limit = math.degrees(self.limits.tilt)
            angle = math.degrees(math.acos(max(-1.0, 1 - phys)))
            return (f"{where}: constraint `tilt` violated{when}: body tilt {angle:.3g}° > "
                    f"limit {limit:.3g}°")
        if b.kind == "final_speed":
            lo, hi = b.lower * b.scale, b.upper * b.scale
            which = "rebound_speed" if phys > hi else "sink_speed"
            return (f"{where}: constraint `{which}` violated: final vertical speed {phys:.4g} "
                    f"m/s outside [{lo:.4g}, {hi:.4g}] m/s")
        if b.kind == "shape":
            return f"{where}: shape constraint violated: {b.label} (value {phys:.4g} {b.unit})"
        if b.kind == "epigraph":
            return f"{where}{leg}: epigraph row violated{when} by {value:.3g} (relative)"
        limit = b.upper * b.scale
        bound = f"> limit {limit:.4g}" if b.kind == "deceleration" else f"limit ±{limit:.4g}"
        return (f"{where}{leg}: constraint `{b.kind}` violated{when}: {b.label} = {phys:.4g} "
                f"{b.unit}, {bound} {b.unit}")

    # -- derivatives --------------------------------------------------------------
    def check_gradient(self, theta=None, step: float = FD_STEP) -> dict:
        """Compare the AD Jacobian of (f, g) in the design with central differences.

        Differences are taken on the scaled variables x = (θ/scale, t/t_ref),
        with step ``step`` and, to tell where differences are valid, again
        with ``step/10``. A row whose two difference quotients disagree is not
        smooth within ``step`` of θ (a contact, stick/slip or branch switch
        jumps inside the interval: the quotient then grows like 1/step); such
        rows are counted and named, not compared with AD. The smoothness test
        does not involve AD, so it cannot hide a wrong derivative.

        Returns
        -------
        dict
            ``relative``: ‖J_AD − J_FD‖_F/‖J_AD‖_F over the smooth rows;
            ``relative_all``: the same over all rows;
            ``worst_row``: the largest ‖row_AD − row_FD‖/‖row_AD‖ over smooth
            rows whose AD norm is at least :data:`ROW_FLOOR` of the largest;
            ``worst_row_all``: the same over every row above 1e-8 of the largest;
            ``objective``: the relative error of the objective row;
            ``rows``, ``columns``, ``rows_below_floor``, ``nonsmooth_rows``
            (how many), ``nonsmooth`` (a description of the first 5) and
            ``nonsmooth_scenarios`` (the scenarios they belong to).
        """
        theta = self.initial if theta is None else np.asarray(theta, dtype=float)
        x = self.scaled(theta)
        jac = ca.Function("design_jac", [self.nlp["x"]],
                          [ca.jacobian(ca.vertcat(self.nlp["f"], self.nlp["g"]), self.nlp["x"])])
        J = np.asarray(jac(x), dtype=float)

        def differences(h):
            out = np.zeros_like(J)
            for i in range(x.size):
                e = np.zeros(x.size)
                e[i] = h
                f1, g1 = self.fg(x + e)
                f0, g0 = self.fg(x - e)
                out[:, i] = (np.concatenate([[f1], g1]) - np.concatenate([[f0], g0])) / (2 * h)
            return out

        J_fd, J_fine = differences(step), differences(step / 10)
        norm = np.linalg.norm(J, axis=1)
        top = max(norm.max(), 1e-300)
        # two valid quotients differ by truncation (≤ h²·|f‴|) and round-off
        # (≈ eps·|f|/h at the finer step, rows O(1)); a jump inside the
        # interval makes them differ by O(jump/h)
        spread = np.linalg.norm(J_fd - J_fine, axis=1)
        smooth = spread <= FD_AGREEMENT * np.maximum(norm, ROW_FLOOR * top) \
            + 100 * np.finfo(float).eps * 10 / step
        diff = np.linalg.norm(J - J_fd, axis=1)
        big = norm > 1e-8 * top
        row_rel = np.where(big, diff / np.where(big, norm, 1.0), 0.0)
        kept = smooth & (norm >= ROW_FLOOR * top)
        described, where = [], set()
        for k in np.flatnonzero(~smooth):
            if k == 0:
                described.append("objective")
                continue
            b = next(b for b in self.blocks if b.start <= k - 1 < b.stop)
            where.add(b.scenario or "design")
            if len(described) < 5:
                when = f", t = {(k - b.start) * b.dt:.4g} s" if b.dt else ""
                leg = f", leg {b.leg}" if b.leg is not None else ""
                described.append(f"{b.scenario or 'design'}{leg}: {b.label}{when}")
        rel = lambda D, rows: float(np.linalg.norm(D[rows])  # noqa: E731
                                    / max(np.linalg.norm(J[rows]), 1e-300))
        return dict(relative=rel(J - J_fd, smooth), relative_all=rel(J - J_fd, slice(None)),
                    worst_row=float(row_rel[kept].max(initial=0.0)),
                    worst_row_all=float(row_rel.max()), objective=float(row_rel[0]),
                    rows=int(J.shape[0]), columns=int(J.shape[1]),
                    rows_below_floor=int(np.count_nonzero(big & (norm < ROW_FLOOR * top))),
                    nonsmooth_rows=int(np.count_nonzero(~smooth)), nonsmooth=described,
                    nonsmooth_scenarios=sorted(where))

    # -- solving ------------------------------------------------------------------
    def feasible_start(self, theta=None, progress=False):
        """The design c·θ with the smallest c ≥ 1 that meets every limit.

        A one-parameter homotopy: all design variables scaled together (for
        force curves, the same shape made uniformly stiffer), c found by
        doubling and bisection on :meth:`evaluate`. Returns θ unchanged if it
        is feasible, or if no c up to the variables' bounds helps.

        Returns
        -------
        theta : ndarray
        c : float
        """
        theta = self.initial if theta is None else np.asarray(theta, dtype=float)

        def ok(c):
            return not self._limit_violations(c * theta)

        if ok(1.0):
            return theta, 1.0
        with np.errstate(divide="ignore", invalid="ignore"):
            room = np.where(theta > 0, self.upper / theta,
                            np.where(theta < 0, self.lower / theta, np.inf))
        c_max = float(np.min(room))
        c_hi = 1.0
        while not ok(c_hi):
            if c_hi >= c_max or c_hi >= FEASIBLE_SCALE_MAX:
                return theta, 1.0
            c_hi = min(2 * c_hi, c_max, FEASIBLE_SCALE_MAX)
        c_lo = c_hi / 2 if c_hi > 1 else 1.0
        for _ in range(FEASIBLE_BISECTIONS):
            mid = 0.5 * (c_lo + c_hi)
            c_lo, c_hi = (c_lo, mid) if ok(mid) else (mid, c_hi)
        c = c_hi * (1 + FEASIBLE_MARGIN)
        c = c if ok(c) and c <= c_max else c_hi
        if progress is True:
            print(f"  feasible start: design scaled by c = {c:.4g}", flush=True)
        return c * theta, c

    def _limit_violations(self, theta):
        """Violations of the limits (not of shape constraints) at θ."""
        return [v for v in self.evaluate(theta).violations if "shape constraint" not in v]

    def solve(self, ipopt: dict | None = None, progress: bool | Callable = False,
              theta0=None, feasible_start: bool = True) -> "DesignResult":
        """Solve the design NLP with Ipopt (``casadi.nlpsol``).

        Parameters
        ----------
        ipopt : dict, optional
            Ipopt options over :data:`IPOPT_DEFAULTS`.
        progress : bool or callable
            True prints one line per iteration; a callable receives a dict
            (iteration, objective in SI, max_violation, seconds).
        theta0 : array_like, optional
            Starting design (SI); default the scene's values.
        feasible_start : bool
            If the start violates a limit, first scale it by
            :meth:`feasible_start` (docs/optimise.md: Ipopt started outside
            the limits takes large restoring steps into stiff designs where
            it stalls).
        """
        options = dict(IPOPT_DEFAULTS)
        options.update(ipopt or {})
        theta0 = self.initial if theta0 is None else np.asarray(theta0, dtype=float)
        started = time.perf_counter()
        theta_start, scale_c = theta0, 1.0
        if feasible_start:
            theta_start, scale_c = self.feasible_start(theta0, progress=progress)
        x0 = self.scaled(theta_start)
        history = []
        unit = "m/s²" if self.objective_kind == "peak_deceleration" else "m"

        epigraph = np.concatenate([np.arange(b.start, b.stop) for b in self.blocks
                                   if b.kind == "epigraph"])

        def on_iteration(x, f, g):
            viol = float(np.max(np.maximum(g - self.ubg, self.lbg - g), initial=0.0))
            # a_k = t_ref·(g_k + t) on the epigraph rows: the peak itself, not t
            peak = float(np.max(g[epigraph]) + f) * self.objective_scale
            entry = dict(iteration=len(history), objective=peak,
                         t=float(f) * self.objective_scale, max_violation=max(viol, 0.0),
                         seconds=time.perf_counter() - started)
            history.append(entry)
            if progress is True:
                print(f"  iter {entry['iteration']:4d}  {self.objective_kind} "
                      f"{peak:.6g} {unit} (t {entry['t']:.6g})  max violation "
                      f"{entry['max_violation']:.2e}  {entry['seconds']:.1f} s", flush=True)
            elif callable(progress):
                progress(entry)

        callback = _IterationCallback(x0.size, self.lbg.size, on_iteration)
        solver = ca.nlpsol("design", "ipopt", self.nlp,
                           {"ipopt": options, "print_time": False,
                            "iteration_callback": callback})
        lbx = np.concatenate([self.lower / self.scale, [0.0]])   # peaks are ≥ 0
        ubx = np.concatenate([self.upper / self.scale, [math.inf]])
        sol = solver(x0=x0, lbx=lbx, ubx=ubx, lbg=self.lbg, ubg=self.ubg)
        seconds = time.perf_counter() - started
        stats = solver.stats()
        x = np.asarray(sol["x"], dtype=float).ravel()
        theta = x[:-1] * self.scale
        evaluation = self.evaluate(theta)
        iters = stats.get("iterations", {})
        for key in ("inf_pr", "inf_du", "mu"):
            for entry, value in zip(history, iters.get(key, [])):
                entry[key] = float(value)
        status = stats.get("return_status", "unknown")
        return DesignResult(
            problem=self, theta=theta, theta0=theta0, evaluation=evaluation,
            initial=self.evaluate(theta0), return_status=status,
            success=bool(stats.get("success", False)), iterations=int(stats.get("iter_count", 0)),
            history=history,
            timings=dict(build_seconds=self.build_seconds, solve_seconds=seconds,
                         jacobian_wall_seconds=float(stats.get("t_wall_nlp_jac_g", math.nan)),
                         jacobian_proc_seconds=float(stats.get("t_proc_nlp_jac_g", math.nan)),
                         jacobian_evaluations=int(stats.get("n_call_nlp_jac_g", 0)),
                         constraint_wall_seconds=float(stats.get("t_wall_nlp_g", math.nan)),
                         constraint_evaluations=int(stats.get("n_call_nlp_g", 0))),
            meta=dict(start_scale=scale_c,
                      start_design=dict(zip(self.var_names, map(float, theta_start)))))

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
            points = [float(x) for x in _check_points(curve, ranges.get(name))]
            entry = dict(element=name, legs=legs, type=type(curve).__name__,
                         parameters={n: float(v) for n, v in zip(curve.param_names, th)},
                         x=points,
                         loading=[float(curve.force(x, _rate(curve, x, True), th))
                                  for x in points])
            if curve.unloading is not None:
                entry["unloading"] = [float(curve.force(x, _rate(curve, x, False), th))
                                      for x in points]
            out[f"leg{j}.{name}"] = entry
        return out


class _IterationCallback(ca.Callback):
    """Ipopt's intermediate callback: hands (x, f, g) to a Python function."""

    def __init__(self, nx, ng, handler):
        ca.Callback.__init__(self)
        self.nx, self.ng, self.handler = nx, ng, handler
        self.construct("design_iteration", {})

    def get_n_in(self):
        return ca.nlpsol_n_out()

    def get_n_out(self):
        return 1

    def get_name_in(self, i):
        return ca.nlpsol_out(i)

    def get_name_out(self, i):
        return "ret"

    def get_sparsity_in(self, i):
        name = ca.nlpsol_out(i)
        if name == "f":
            return ca.Sparsity.scalar()
        if name in ("x", "lam_x"):
            return ca.Sparsity.dense(self.nx)
        if name in ("g", "lam_g"):
            return ca.Sparsity.dense(self.ng)
        return ca.Sparsity(0, 0)

    def eval(self, arg):
        names = [ca.nlpsol_out(i) for i in range(ca.nlpsol_n_out())]
        values = dict(zip(names, arg))
        self.handler(np.asarray(values["x"], dtype=float).ravel(), float(values["f"]),
                     np.asarray(values["g"], dtype=float).ravel())
        return [0]


def _leg_param_names(model) -> tuple:
    """The legs' curve parameters of a model's ``p`` (without the scene entries)."""
    return model.param_names[:model.params.n_leg_params]


def _up(gravity):
    norm = float(np.linalg.norm(gravity))
    return -np.asarray(gravity, dtype=float) / norm if norm > 0 else np.array([0.0, 0.0, 1.0])


def _rate(curve: Curve, x: float, loading: bool):
    """A rate that selects one branch of ``curve`` exactly at x ≠ 0."""
    if x == 0:
        return 0.0
    magnitude = _BRANCH_SELECT * curve.rate_width / abs(x)
    return float(np.sign(x)) * magnitude * (1.0 if loading else -1.0)


def _check_points(curve: Curve, extent) -> np.ndarray:
    """Where shape constraints are checked: knots, or a grid on [−extent, extent]."""
    pts = []
    for c in (curve, curve.unloading):
        if isinstance(c, PiecewiseLinear):
            pts += list(c.knots)
    if not pts:
        extent = 1.0 if extent is None else extent
        pts = list(np.linspace(-extent, extent, 2 * SHAPE_GRID + 1))
    return np.unique(np.asarray(pts, dtype=float))


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
    slopes = [curve.slope(x, _rate(curve, x, True), th) for x in pts]
    pts = np.asarray(pts)
    onset = np.zeros(pts.size, dtype=bool)
    for side in (pts < 0, pts > 0):
        if side.any():
            onset[np.flatnonzero(side)[np.argmin(np.abs(pts[side]))]] = True
    return slopes, pts, onset


# ---------------------------------------------------------------------------
# results
# ---------------------------------------------------------------------------
@dataclass
class DesignResult:
    """Outcome of :meth:`DesignProblem.solve`.

    Attributes
    ----------
    theta, theta0 : ndarray, shape (n,)
        Optimal and starting design values (SI), named ``problem.var_names``.
    evaluation, initial : Evaluation
        The optimal and the starting design simulated.
    return_status : str
        Ipopt's, e.g. ``"Solve_Succeeded"``.
    success : bool
    iterations : int
    history : list of dict
        Per iteration: objective (SI), max_violation (scaled), seconds, and
        Ipopt's inf_pr, inf_du, mu.
    timings : dict
        build_seconds, solve_seconds, Ipopt's wall time and Jacobian time.
    """

    problem: DesignProblem
    theta: np.ndarray
    theta0: np.ndarray
    evaluation: Evaluation
    initial: Evaluation
    return_status: str
    success: bool
    iterations: int
    history: list
    timings: dict
    meta: dict = field(default_factory=dict)

    @property
    def design(self) -> dict:
        return dict(zip(self.problem.var_names, map(float, self.theta)))

    @property
    def p(self) -> np.ndarray:
        """Full parameter vector (``problem.param_names``) of the optimum."""
        return self.problem.p_of(self.theta)

    @property
    def message(self) -> str:
        """One paragraph: status, objective and any violated constraints."""
        ev = self.evaluation
        unit = "m/s²" if self.problem.objective_kind == "peak_deceleration" else "m"
        text = (f"Ipopt {self.return_status} after {self.iterations} iterations: "
                f"{self.problem.objective_kind} {ev.objective:.6g} {unit} "
                f"(initial {self.initial.objective:.6g} {unit})")
        if ev.violations:
            text += "; the design is infeasible:\n  " + "\n  ".join(ev.violations[:_REPORT_WORST])
            if len(ev.violations) > _REPORT_WORST:
                text += f"\n  … and {len(ev.violations) - _REPORT_WORST} more"
        return text

    @property
    def efficiency(self):
        """Smallest ideal-absorber efficiency over the scenarios (None if undefined)."""
        values = [s["efficiency"] for s in self.evaluation.scenarios.values()
                  if s.get("efficiency") is not None]
        return min(values) if values else None

    def to_dict(self) -> dict:
        pb = self.problem
        return _jsonable(dict(
            study=self.meta.get("name"),
            objective_kind=pb.objective_kind,
            objective=self.evaluation.objective,
            initial_objective=self.initial.objective,
            efficiency=self.efficiency,
            return_status=self.return_status,
            success=self.success,
            iterations=self.iterations,
            seconds=self.timings["build_seconds"] + self.timings["solve_seconds"],
            feasible=self.evaluation.feasible,
            violations=self.evaluation.violations,
            design=self.design,
            initial_design=dict(zip(pb.var_names, map(float, self.theta0))),
            bounds={n: [lo, hi] for n, lo, hi in zip(pb.var_names, pb.lower, pb.upper)},
            p={n: float(v) for n, v in zip(pb.param_names, self.p)},
            characteristic=pb.characteristics(self.theta),
            initial_characteristic=pb.characteristics(self.theta0),
            scenarios=self.evaluation.scenarios,
            initial_scenarios=self.initial.scenarios,
            limits=pb.limits.__dict__,
            timings=self.timings,
            history=self.history,
            **{k: v for k, v in self.meta.items() if k != "name"}))

    def save_json(self, path):
        """Write :meth:`to_dict` as JSON (NaN and inf written as null)."""
        path = Path(path)
        if path.parent and not path.parent.exists():
            path.parent.mkdir(parents=True)
        path.write_text(json.dumps(self.to_dict(), indent=2, ensure_ascii=False) + "\n")
        return path


def _jsonable(obj):
    if isinstance(obj, dict):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _jsonable(obj.tolist())
    if isinstance(obj, (np.floating, float)):
        value = float(obj)
        return value if math.isfinite(value) else None
    if isinstance(obj, (np.integer,)):
        return int(obj)
    return obj


# ---------------------------------------------------------------------------
# study files
# ---------------------------------------------------------------------------
class _Fields(_Table):
    """A study-file table: the scene files' field checker, with ±inf allowed."""

    docs = "docs/optimise.md"
    finite_numbers = False


_SCENE_KEYS = ("scene", "body", "legs", "leg", "obstacle")
#: Body initial conditions a scenario may override (no new model needed).
_INITIAL = ("position", "velocity", "attitude", "angular_velocity")


@dataclass
class Study:
    """A study file: the design problem plus solver options and metadata."""

    name: str
    problem: DesignProblem
    ipopt: dict
    source: str = ""
    description: str = ""

    def solve(self, progress=False) -> DesignResult:
        result = self.problem.solve(ipopt=self.ipopt, progress=progress)
        result.meta.update(name=self.name, source=self.source, description=self.description)
        return result


def load_study(path) -> Study:
    """Load a design study from a TOML file (format: docs/optimise.md)."""
    path = Path(path)
    return study_from_dict(read_toml(path, "study"), str(path), base_dir=path.parent)


def study_from_dict(data: dict, source: str = "<dict>", base_dir=".") -> Study:
    """Build a :class:`Study` from the parsed contents of a study TOML file."""
    top = _Fields(data, "", source)
    st = top.get("study", kind="table")
    name = st.get("name", Path(source).stem, kind="string")
    description = st.get("description", "", kind="string")
    objective = st.get("objective", "peak_deceleration", kind="string", choices=OBJECTIVES)
    scene_raw = {k: data[k] for k in _SCENE_KEYS if k in data}
    top.used.update(_SCENE_KEYS)
    if st.has("scene"):
        if scene_raw:
            raise ValueError(f"{source}: give the scene either as `study.scene` (a file) or as "
                             f"tables {sorted(scene_raw)} in this file, not both.")
        scene_path = Path(base_dir) / st.get("scene", kind="string")
        if not scene_path.is_file():
            raise FileNotFoundError(f"{source}: `study.scene` = {str(scene_path)!r} does not "
                                    "exist.")
        try:
            scene_raw = tomllib.loads(scene_path.read_text())
        except tomllib.TOMLDecodeError as exc:
            raise ValueError(f"{scene_path}: not valid TOML: {exc}") from None
        scene_source = str(scene_path)
    else:
        if not scene_raw:
            raise ValueError(f"{source}: no scene; give `study.scene` = \"file.toml\" or the "
                             "scene tables ([scene], [body], [legs] or [[leg]], [[obstacle]]).")
        scene_source = source
    st.finish()
    base = scene_from_dict(scene_raw, scene_source)

    if top.has("smoothing"):
        sm = top.get("smoothing", kind="table")
        _smooth_tunable(base, sm.get("kink_width", None, positive=True),
                        sm.get("rate_width", None, positive=True))
        sm.finish()

    scenarios = [_scenario(t, base, scene_raw, scene_source)
                 for t in (top.get("scenario", kind="tables") if top.has("scenario") else [])]
    top.used.add("scenario")
    if not scenarios:
        scenarios = [Scenario("nominal", base)]

    dz = top.get("design", kind="table")
    variables = []
    for t in dz.get("variables", kind="tables"):
        variables.append(DesignVariable(
            names=t.get("names", kind="strings"), lower=t.get("lower", -math.inf),
            upper=t.get("upper", math.inf), shared=t.get("shared", True, kind="bool"),
            exclude=t.get("exclude", [], kind="strings"),
            scale=t.get("scale", None, positive=True)))
        t.finish()
    shapes = []
    for t in (dz.get("shape", kind="tables") if dz.has("shape") else []):
        shapes.append(CurveShape(
            element=t.get("element", kind="string", choices=("S", "M_beta", "M_gamma")),
            monotone=t.get("monotone", True, kind="bool"),
            unloading_below=t.get("unloading_below", True, kind="bool"),
            onset_slope=t.get("onset_slope", None, nonnegative=True)))
        t.finish()
    dz.used.add("shape")
    dz.finish()

    lim = top.get("limits", kind="table") if top.has("limits") else _Fields({}, "limits", source)
    top.used.add("limits")
    sink = lim.data.get("sink_speed", 0.0)
    lim.used.add("sink_speed")
    if sink is not False:
        sink = lim.get("sink_speed", 0.0, nonnegative=True)
    limits = Limits(stroke=lim.get("stroke", None, positive=True),
                    beta=lim.get("beta", None, positive=True),
                    gamma=lim.get("gamma", None, positive=True),
                    tilt=lim.get("tilt", None, positive=True),
                    rebound_speed=lim.get("rebound_speed", None, positive=True),
                    sink_speed=None if sink is False else sink,
                    deceleration=lim.get("deceleration", None, positive=True))
    lim.finish()

    ipopt = {}
    if top.has("solver"):
        so = top.get("solver", kind="table")
        if so.has("max_iter"):
            ipopt["max_iter"] = so.get("max_iter", kind="int")
        if so.has("tol"):
            ipopt["tol"] = so.get("tol", positive=True)
        if so.has("hessian"):
            ipopt["hessian_approximation"] = so.get(
                "hessian", kind="string", choices=("limited-memory", "exact"))
        if so.has("ipopt"):
            extra = so.get("ipopt", kind="any")
            if not isinstance(extra, dict):
                raise so.error("ipopt", extra, "a table of Ipopt options")
            ipopt.update(extra)
        so.finish()
    top.used.add("solver")
    top.finish()
    try:
        problem = DesignProblem(scenarios, variables, limits, objective, shapes)
    except (ValueError, TypeError) as exc:
        raise ValueError(f"{source}: {exc}") from None
    return Study(name=name, problem=problem, ipopt=ipopt, source=source, description=description)


def _smooth_tunable(scene: Scene, kink_width, rate_width):
    """Turn on smoothing of the tuned curves with the given widths (in place)."""
    for leg in scene.legs:
        for el in leg.elements:
            if not el.curve.tunable:
                continue
            for c in (el.curve, el.curve.unloading):
                if c is None:
                    continue
                c.smooth = True
                if kink_width is not None:
                    c.kink_width = kink_width
                if rate_width is not None:
                    c.rate_width = rate_width


def _scenario(t: _Fields, base: Scene, scene_raw: dict, scene_source: str) -> Scenario:
    name = t.get("name", kind="string")
    scene = base
    changes = {}
    if t.has("duration"):
        changes["duration"] = t.get("duration", positive=True)
    if t.has("mu"):
        changes["mu"] = t.get("mu", nonnegative=True)
    if t.has("obstacle"):
        raw = dict(scene_raw, obstacle=t.get("obstacle", kind="any"))
        try:
            other = scene_from_dict(raw, f"{t.source} (scenario `{name}`)")
        except ValueError as exc:
            raise ValueError(f"{t.source}: `{t.path}`: {exc}") from None
        changes["obstacles"] = other.obstacles
    if changes:
        scene = base.with_(**changes)
    initial = {}
    for key in _INITIAL:
        if t.has(key):
            size = 4 if key == "attitude" else 3
            value = t.get(key, kind="vector")
            if value.size != size or not np.all(np.isfinite(value)):
                raise t.error(key, value.tolist(), f"a list of {size} finite numbers")
            initial[key] = value
    try:
        body = dataclasses.replace(base.body, **initial)
    except ValueError as exc:
        raise ValueError(f"{t.source}: `{t.path}`: {exc}") from None
    if t.has("clearance"):
        body.position = _place(scene, body, t.get("clearance", nonnegative=True))
    t.finish()
    x0 = initial_state(scene.with_(body=body))
    return Scenario(name, scene, x0)


def _place(scene: Scene, body, clearance: float) -> np.ndarray:
    """Body position, moved along the vertical, whose lowest free foot is ``clearance`` up."""
    up = _up(scene.gravity)
    R = quat_to_rot_np(body.attitude)
    pos = np.array(body.position, dtype=float)
    for _ in range(_PLACEMENT_ITERS):
        best = None
        for leg in scene.legs:
            d, n, _ = closest_obstacle(scene.obstacles, ca.DM(pos + R @ leg.rest_foot))
            d, n = float(d), np.asarray(n, dtype=float).ravel()
            if best is None or d < best[0]:
                best = (d, n)
        d, n = best
        rate = float(np.dot(n, up))
        if rate < 0.1:
            raise ValueError(f"cannot place the body by `clearance`: the lowest foot faces a "
                             f"surface whose normal is {math.degrees(math.acos(rate)):.0f}° from "
                             "the vertical; give `position` instead.")
        pos = pos - (d - clearance) / rate * up
        if abs(d - clearance) < 1e-12:
            break
    return pos


def run_study(path, out=None, progress=True) -> DesignResult:
    """Load, solve and (with ``out``) save a study; return the result."""
    study = load_study(path)
    pb = study.problem
    if progress:
        print(f"{study.name}: {len(pb.scenarios)} scenario(s), {pb.n_variables} design "
              f"variables, {pb.lbg.size} constraints, objective {pb.objective_kind} "
              f"(built in {pb.build_seconds:.1f} s)", flush=True)
    result = study.solve(progress=progress)
    if out is not None:
        result.save_json(out)
    return result
