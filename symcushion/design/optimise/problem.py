"""The design problem: variables, scaling, evaluation and the Ipopt solve.

Owns :class:`DesignProblem`: its scenarios and models, scaling, evaluating a
design (objective, violated limits named by
scenario, leg and time), the feasible start and the solver call with its
iteration line. Variables and curve shapes come from :mod:`.space`, the
rows of the NLP from :mod:`.constraints`, the gradient check from
:mod:`.gradient`. It must not integrate: it receives
``touchdown_rollout`` from :mod:`symcushion.scheme.touchdown`.
"""
from __future__ import annotations

import math
import time
from typing import Callable, Sequence

import casadi as ca
import numpy as np

from symcushion.layout.vectors import state_layout
from symcushion.scheme.quaternion import quat_to_rot_np
from symcushion.model.obstacles import closest_obstacle
from symcushion.scheme.touchdown import build_model, initial_state
from symcushion.design.optimise.constraints import Constraints, design_outputs_of
from symcushion.design.optimise.gradient import GradientCheck
from symcushion.design.optimise.space import DesignSpace
from symcushion.design.optimise.progress import IterationCallback
from symcushion.design.optimise.result import DesignResult
from symcushion.design.optimise.geometry import PRACTICAL_KINDS
from symcushion.design.optimise.spec import (Block, leg_param_names, up_direction, CurveShape,
    DesignVariable, Evaluation, Limits, OBJECTIVES, Scenario, VIOLATION_TOL)

__all__ = ["IPOPT_DEFAULTS", "FEASIBLE_SCALE_MAX", "FEASIBLE_BISECTIONS", "FEASIBLE_MARGIN",
           "DesignProblem"]

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
#: Feasible start (:meth:`DesignProblem.feasible_start`): largest uniform
#: scale factor tried, bisection steps (2⁻¹² relative), and the margin added
#: so that Ipopt starts strictly inside the limits.
FEASIBLE_SCALE_MAX = 64.0
FEASIBLE_BISECTIONS = 12
FEASIBLE_MARGIN = 1e-2


class DesignProblem(DesignSpace, Constraints, GradientCheck):
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
    geometry : sequence of GeometryVariable, optional
        The legs' geometry as design variables, after the curves' in θ
        (docs/design-geometry.md).
    practical : PracticalLimits, optional
        Footprint radius, leg mass proxy and ground clearance rows.

    Notes
    -----
    Scaling: each variable is divided by its ``scale``; the epigraph variable
    by the initial design's objective; each constraint by its limit (strokes
    by ``stroke``, the epigraph rows by the initial peak), so that Ipopt sees
    O(1) numbers everywhere.
    """

    def __init__(self, scenarios: Sequence[Scenario], variables: Sequence[DesignVariable],
                 limits: Limits | None = None, objective: str = "peak_deceleration",
                 shapes: Sequence[CurveShape] = (), geometry=(), practical=None):
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
        self.param_names = leg_param_names(self.models[0])
        for s, m in zip(self.scenarios, self.models):
            if leg_param_names(m) != self.param_names:
                raise ValueError(f"scenario `{s.name}` has parameters {leg_param_names(m)}, "
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
        self._resolve_variables(list(variables), list(geometry))
        self._resolve_geometry(list(geometry), practical, self.models[0].params)
        self._shapes = self._resolve_shapes(list(shapes))
        self._build()
        self.build_seconds = time.perf_counter() - started

    # -- construction -----------------------------------------------------------
    def _model(self, scene):
        key = (tuple(map(id, scene.legs)), tuple(map(id, scene.obstacles)), scene.mu,
               scene.scheme, scene.body.mass, scene.body.inertia.tobytes(),
               scene.gravity.tobytes())
        if key not in self._models:
            self._models[key] = build_model(scene)
        return self._models[key]

    def step_params(self, k: int, theta) -> np.ndarray:
        """The ``p`` of scenario ``k``'s ``touchdown_step`` at design θ: the legs' curve
        parameters (:meth:`p_of`), then that scenario's own μ, gravity, mass and inertia."""
        model = self.models[k]
        tail = self._full_p_tail(ca.DM(np.asarray(theta, dtype=float)), model)
        return np.concatenate([self.p_of(theta), np.asarray(ca.evalf(tail), dtype=float).ravel()])

    def scenario_state(self, k: int, theta) -> np.ndarray:
        """The initial state of scenario ``k`` at design θ: its ``x0`` with the feet at the
        rest poses of θ's geometry and the body placed at the scenario's clearance."""
        s = self.scenarios[k]
        theta = ca.DM(np.asarray(theta, dtype=float))
        x0 = self._placed_state(s.x0, theta, s.scene, s.clearance, up_direction(s.scene.gravity))
        return np.asarray(ca.evalf(x0), dtype=float).ravel()

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
        y = design_outputs_of(self._outputs(w), [(s.scene.steps, model.n_legs)
                                                 for s, model in zip(self.scenarios, self.models)])
        scenarios = {}
        peaks, strokes = [], []
        for s, m, out in zip(self.scenarios, self._measure, y):
            acc, stroke, beta, gamma = out["acc"], out["strokes"], out["betas"], out["gammas"]
            tilt, v_up = out["tilt"], out["v_up"]
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
        up = up_direction(scene.gravity)
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
            d, _, _ = closest_obstacle(scene.obstacles, ca.DM(foot), leg.footpad)
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

    def _describe(self, b: Block, k: int, value: float) -> str:
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
        if b.kind in PRACTICAL_KINDS:
            side = "<" if b.lower == -math.inf else ">"
            bound = (b.upper if side == "<" else b.lower) * b.scale
            return (f"{where}{leg}: practical limit `{b.kind}` violated: {b.label} = "
                    f"{phys:.4g} {b.unit}, must be {side}= {bound:.4g} {b.unit}")
        if b.kind == "epigraph":
            return f"{where}{leg}: epigraph row violated{when} by {value:.3g} (relative)"
        limit = b.upper * b.scale
        bound = f"> limit {limit:.4g}" if b.kind == "deceleration" else f"limit ±{limit:.4g}"
        return (f"{where}{leg}: constraint `{b.kind}` violated{when}: {b.label} = {phys:.4g} "
                f"{b.unit}, {bound} {b.unit}")

    # -- solving ------------------------------------------------------------------
    def result_record(self, theta, theta0, objective: float) -> dict:
        """What a :class:`DesignResult` writes of this problem at the optimum
        ``theta`` and the start ``theta0``: bounds, named ``p``, characteristics,
        limits and, when the geometry is designed or limited, the geometry at both
        and each practical-limit row's value at the optimum."""
        record = dict(
            bounds={n: [lo, hi] for n, lo, hi in zip(self.var_names, self.lower, self.upper)},
            p={n: float(v) for n, v in zip(self.param_names, self.p_of(theta))},
            characteristic=self.characteristics(theta),
            initial_characteristic=self.characteristics(theta0),
            limits=dict(self.limits.__dict__))
        if self._frames is not None:
            _, g = self.fg(self.scaled(theta, t=objective))
            record["geometry"] = dict(start=self.geometry_report(theta0),
                                      end=self.geometry_report(theta))
            record["practical"] = [dict(kind=b.kind, leg=b.leg, label=b.label, unit=b.unit,
                                        values=(g[b.start:b.stop] * b.scale).tolist())
                                   for b in self.blocks if b.kind in PRACTICAL_KINDS]
        return record

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

        # only the curves are scaled: the geometry (hinges, lengths) stays where it starts
        curve = self._is_curve

        def scaled(c):
            return np.where(curve, c * theta, theta)

        def ok(c):
            return not self._limit_violations(scaled(c))

        if ok(1.0):
            return theta, 1.0
        with np.errstate(divide="ignore", invalid="ignore"):
            room = np.where(theta > 0, self.upper / theta,
                            np.where(theta < 0, self.lower / theta, np.inf))
        room = np.where(curve, room, np.inf)
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
        return scaled(c), c

    def _limit_violations(self, theta):
        """Violations of the limits (not of shape constraints or practical limits) at θ."""
        return [v for v in self.evaluate(theta).violations
                if "shape constraint" not in v and "practical limit" not in v]

    def solve(self, ipopt: dict | None = None, progress: bool | Callable = False,
              theta0=None, feasible_start: bool = True, compiled: bool = False,
              cache_dir=None) -> "DesignResult":
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
        compiled : bool
            Evaluate the rollouts and their Jacobian in C, built once and
            cached in ``cache_dir`` (:meth:`use_compiled`).
        cache_dir : str or Path, optional
            Folder of compiled builds (default ``build/design``).
        """
        build = self._compile_for_solve(compiled, cache_dir, progress is True)
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

        callback = IterationCallback(x0.size, self.lbg.size, on_iteration)
        nlp = self.nlp if self._compiled_nlp is None else self._compiled_nlp
        solver = ca.nlpsol("design", "ipopt", nlp,
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
            theta=theta, theta0=theta0, evaluation=evaluation,
            initial=self.evaluate(theta0), return_status=status,
            success=bool(stats.get("success", False)), iterations=int(stats.get("iter_count", 0)),
            history=history,
            timings=dict(build_seconds=self.build_seconds, solve_seconds=seconds,
                         jacobian_wall_seconds=float(stats.get("t_wall_nlp_jac_g", math.nan)),
                         jacobian_proc_seconds=float(stats.get("t_proc_nlp_jac_g", math.nan)),
                         jacobian_evaluations=int(stats.get("n_call_nlp_jac_g", 0)),
                         constraint_wall_seconds=float(stats.get("t_wall_nlp_g", math.nan)),
                         constraint_evaluations=int(stats.get("n_call_nlp_g", 0)), **build),
            var_names=tuple(self.var_names), p=self.p_of(theta),
            objective_kind=self.objective_kind,
            record=self.result_record(theta, theta0, evaluation.objective),
            meta=dict(start_scale=scale_c,
                      start_design=dict(zip(self.var_names, map(float, theta_start)))))
