"""Design for the envelope: the legs' curves that keep many touchdowns within their limits.

Owns :class:`EnvelopeDesign`: the scenario NLP over the legs' tunable curve
parameters with a risk measure of the scenarios' losses as objective, its
scaling, start, Ipopt solve and multipliers. The scenario loss
L_sc = sat(r_sc) − 1 of each scenario s and check c, with r_sc the smooth
value/limit of :mod:`.margins`, and its risk measures (``cvar``, ``worst``),
each exact through an epigraph, are set out in :mod:`.risk`; the result
record is :mod:`.result`.

The scenarios' ratios and their Jacobian run in compiled C on threads or
Dask (:mod:`.evaluate`); variables and curve shapes come from
:mod:`symcushion.design.optimise.space`, the gradient check from
:mod:`symcushion.design.optimise.gradient`. It must not choose scenarios, sample,
classify or write files.
"""
from __future__ import annotations

import math
import os
import time

import casadi as ca
import numpy as np

from symcushion.envelope.cases import case_params, initial_states, reach
from symcushion.envelope.study import EnvelopeStudy
from symcushion.design.optimise.gradient import GradientCheck
from symcushion.design.optimise.problem import IPOPT_DEFAULTS
from symcushion.design.optimise.progress import IterationCallback
from symcushion.design.optimise.space import DesignSpace
from symcushion.design.optimise.spec import Block, leg_param_names, Limits, VIOLATION_TOL
from symcushion.scheme.touchdown import build_model
from symcushion.design.optimise.geometry import PRACTICAL_KINDS
from symcushion.design.robust.evaluate import build_margins, design_margins, ScenarioRatios
from symcushion.design.robust.margins import CHECKS, DEFAULT_SHARPNESS
from symcushion.design.robust.result import RobustResult
from symcushion.design.robust.risk import (DEFAULT_ALPHA, DEFAULT_HORIZON, DEFAULT_SATURATION,
    DEFAULT_TIP_ENERGY, RISKS, design_checks, saturate)

__all__ = ["EnvelopeDesign"]

#: A bound or shape row counts as active within this distance (scaled units)
#: and with a multiplier above it: an interior point keeps every multiplier
#: small but non-zero.
_ACTIVE = 1e-6
#: Ipopt options of the envelope design: the design package's defaults, Ipopt's
#: own tolerance 1e-8 among them, with at most 200 iterations. On the absorbers
#: with memory the shipped designs end in Solve_Succeeded in 80-100
#: (docs/optimise.md, "Convergence").
_IPOPT = {**IPOPT_DEFAULTS, "max_iter": 200}


class EnvelopeDesign(DesignSpace, GradientCheck):
    """The scenario NLP of a design for the envelope.

    Parameters
    ----------
    study : EnvelopeStudy
        Scene (its tuned curves marked ``tunable = true``), limits and the
        slope frame of the cases.
    conditions : dict of str to ndarray
        The scenarios: touchdown conditions by name of the envelope's
        variables (each an array of length S), e.g. from
        :func:`~symcushion.design.robust.select.select_scenarios`.
    variables : sequence of DesignVariable
    names : sequence of str, optional
        Scenario names for reports (default ``s0 … s{S-1}``).
    horizon : float, optional
        Simulated time per scenario (s); default the study's duration.
    risk : {'cvar', 'worst'}
    alpha : float
        CVaR level in [0, 1).
    saturation : float
        R of :func:`saturate`, > 1.
    sharpness : float
        ρ of the KS aggregates (:mod:`.margins`).
    shapes : sequence of CurveShape
        Default: monotone loading and unloading below loading for every
        element with a design variable.
    threads : int, optional
        Threads evaluating the scenarios (default: every core).
    client : distributed.Client, optional
        Evaluate the scenarios as Dask tasks instead.
    cache_dir : str or Path, optional
        Folder of the compiled library (:data:`~symcushion.design.robust.evaluate.DEFAULT_CACHE`).
    progress : bool
    """

    def __init__(self, study: EnvelopeStudy, conditions: dict, variables, *, names=None,
                 horizon: float | None = DEFAULT_HORIZON, risk: str = "cvar",
                 alpha: float = DEFAULT_ALPHA, saturation: float = DEFAULT_SATURATION,
                 sharpness: float = DEFAULT_SHARPNESS, shapes=(), geometry=(),
                 practical=None, threads: int | None = None, client=None, cache_dir=None,
                 progress: bool = False, tip_energy: float | None = DEFAULT_TIP_ENERGY):
        started = time.perf_counter()
        if not isinstance(study, EnvelopeStudy):
            raise TypeError(f"`study` must be an EnvelopeStudy, got {type(study).__name__}.")
        if risk not in RISKS:
            raise ValueError(f"`risk` must be one of {RISKS}, got {risk!r}.")
        if not (isinstance(alpha, (int, float)) and 0 <= alpha < 1):
            raise ValueError(f"`alpha` must be in [0, 1), got {alpha!r}; e.g. {DEFAULT_ALPHA}.")
        if not (isinstance(saturation, (int, float)) and saturation > 1):
            raise ValueError(f"`saturation` must be > 1, got {saturation!r}; e.g. "
                             f"{DEFAULT_SATURATION}.")
        horizon = study.scene.duration if horizon is None else horizon
        if not (isinstance(horizon, (int, float)) and horizon > 0 and math.isfinite(horizon)):
            raise ValueError(f"`horizon` must be a positive time in s, got {horizon!r}.")
        threads = (os.cpu_count() or 1) if threads is None else threads
        if isinstance(threads, bool) or not isinstance(threads, int) or threads < 1:
            raise ValueError(f"`threads` must be a positive integer, got {threads!r}.")
        self.study, self.risk, self.alpha, self.saturation = study, risk, float(alpha), \
            float(saturation)
        scene = study.scene
        self.scene = scene
        self.steps = max(1, int(round(horizon / scene.dt)))
        self.horizon = self.steps * scene.dt
        model = build_model(scene)
        self.model = model
        self.param_names = leg_param_names(model)
        self.legs = scene.legs
        self.p_default = np.concatenate([leg.param_values for leg in self.legs]) \
            if self.param_names else np.zeros(0)
        if not self.param_names and not geometry:
            raise ValueError("the study's legs have no tunable parameters; mark the curves to "
                             "design `tunable = true` (docs/optimise.md).")
        lim = study.limits
        self.limits = Limits(stroke=lim.stroke, beta=lim.beta, gamma=lim.gamma,
                             tilt=None if lim.tilt_deg is None else math.radians(lim.tilt_deg),
                             rebound_speed=lim.rebound_speed, deceleration=lim.deceleration,
                             sink_speed=None)
        self._limits = dict(tip_over=self.limits.tilt,
                            tip_energy=None if self.limits.tilt is None else tip_energy,
                            stroke=lim.stroke, beta=lim.beta,
                            gamma=lim.gamma, deceleration=lim.deceleration,
                            rebound=lim.rebound_speed, moving=lim.rest_speed)
        self.checks = design_checks(self._limits)
        self._resolve_variables(list(variables), list(geometry))
        self._resolve_geometry(list(geometry), practical, model.params)
        self._shapes = self._resolve_shapes(list(shapes))
        self._set_scenarios(conditions, names)
        nv, n_leg = len(self.var_names), len(self.param_names)
        design = np.zeros((model.np, nv))
        design[:n_leg] = self._map * self.scale          # p = p0 + design·w, w = θ/scale
        self._design, self._sharpness = design, sharpness
        self._design_map = self._geometry_map(design) if self.designs_geometry else None
        self.library, compile_seconds = build_margins(
            model, self.steps, self._limits, design, sharpness=sharpness, reach=reach(scene),
            cache_dir=cache_dir,
            name=f"{study.name}-{self.steps}", progress=progress, design_map=self._design_map)
        self._ratios = ScenarioRatios(self.library, self.x0, self.p0, scene.dt, threads, client)
        self.threads = threads
        self._build()
        self.timings = dict(compile_seconds=compile_seconds,
                            build_seconds=time.perf_counter() - started)

    # -- construction -----------------------------------------------------------
    def _set_scenarios(self, conditions, names):
        arrays = {k: np.atleast_1d(np.asarray(v, dtype=float)) for k, v in conditions.items()}
        sizes = {v.size for v in arrays.values()}
        if len(sizes) != 1 or 0 in sizes:
            raise ValueError("`conditions` must hold arrays of one common, non-zero length "
                             f"(one entry per scenario), got lengths {sorted(sizes)}.")
        self.conditions = arrays
        S = sizes.pop()
        self.names = [f"s{i}" for i in range(S)] if names is None else list(names)
        if len(self.names) != S:
            raise ValueError(f"`names` must have one entry per scenario ({S}), got "
                             f"{len(self.names)}.")
        x0, gravity = initial_states(self.study, arrays)
        mu = arrays.get("mu", np.full(S, self.scene.mu))
        p = case_params(self.scene, mu, gravity)
        p[:len(self.param_names)] = self.p_fixed[:, None]     # designed entries come from w
        self.x0, self.p0 = x0, p

    def _geometry_map(self, design) -> ca.Function:
        """``(x0, p0, w) -> (x0, p)`` of a design with geometry variables: the curves'
        entries p0 + design·w, the legs' geometry blocks of θ = w·scale, and each case's
        body moved so that its lowest foot keeps the envelope's clearance."""
        model = self.model
        x0, p0 = ca.MX.sym("x0", model.nx), ca.MX.sym("p0", model.np)
        w = ca.MX.sym("w", design.shape[1])
        theta = w * ca.DM(self.scale)
        n = model.params.n_leg_params
        p = p0 + ca.DM(design) @ w
        p = ca.vertcat(p[:n], self._full_p_tail(theta, model, tail=p[n:]))
        return ca.Function("design_map", [x0, p0, w],
                           [self._placed_state_on_ground(x0, theta), p],
                           ["x0", "p0", "w"], ["x0_design", "p_design"])

    def _build(self):
        nv, S, C = len(self.var_names), len(self.names), len(self.checks)
        w = ca.MX.sym("w", nv)
        eta = ca.MX.sym("eta")
        u = ca.MX.sym("u", S if self.risk == "cvar" else 0)
        R = self._ratios(w)
        rows_idx = [CHECKS.index(c) for c in self.checks]
        loss = saturate(R[rows_idx, :], self.saturation) - 1          # C × S
        blocks, rows = [], []

        def add(expr, kind, scale, lower, upper, unit, scenario=None, leg=None, dt=None,
                label=""):
            expr = ca.vec(expr if isinstance(expr, ca.MX) else ca.MX(expr))
            if kind in ("shape",) + PRACTICAL_KINDS and not ca.depends_on(expr, w):
                value = float(ca.Function("fixed", [w], [expr])(np.zeros(nv)))
                if not lower - VIOLATION_TOL <= value / scale <= upper + VIOLATION_TOL:
                    raise ValueError(f"shape constraint `{label}` fails ({value:.4g} {unit}) "
                                     "and no design variable can change it.")
                return
            start = sum(r.numel() for r in rows)
            blocks.append(Block(kind, scenario, leg, start, start + expr.numel(), lower,
                                 upper, scale, unit, dt, label))
            rows.append(expr / scale)

        for s, name in enumerate(self.names):
            top = eta + (u[s] if self.risk == "cvar" else 0)
            add(top - loss[:, s], "risk", 1.0, 0.0, math.inf, "", name,
                label="η + u_s ≥ loss of " + ", ".join(self.checks))
        self._add_shape_constraints(w * ca.DM(self.scale), add)
        self._add_practical_rows(w * ca.DM(self.scale), add, self.limits.stroke)
        f = eta + (ca.sum1(u) / ((1 - self.alpha) * S) if self.risk == "cvar" else 0)
        self.blocks, self._w, self._C = blocks, w, C
        x = ca.vertcat(w, eta, u)
        self.nlp = {"x": x, "f": f, "g": ca.vertcat(*rows)}
        self.lbg = np.concatenate([np.full(b.stop - b.start, b.lower) for b in blocks])
        self.ubg = np.concatenate([np.full(b.stop - b.start, b.upper) for b in blocks])
        self._fg = ca.Function("robust_fg", [x], [f, self.nlp["g"]], ["x"], ["f", "g"])
        self._R = ca.Function("robust_ratios", [w], [R], ["w"], ["R"])

    # -- evaluation -------------------------------------------------------------
    @property
    def n_variables(self) -> int:
        return len(self.var_names)

    def ratios(self, theta=None) -> np.ndarray:
        """value/limit of every check (rows: :data:`CHECKS`) and scenario (columns) at θ."""
        theta = self.initial if theta is None else np.asarray(theta, dtype=float)
        return np.asarray(self._R(theta / self.scale), dtype=float)

    def reference_ratios(self, theta=None) -> np.ndarray:
        """:meth:`ratios` on the CasADi VM, without the compiled library.

        The same ``touchdown_margins`` graph evaluated uncompiled, scenario by
        scenario: the reference the compiled evaluation is checked against (one
        whole rollout per scenario on the VM, so much slower than :meth:`ratios`).
        """
        theta = self.initial if theta is None else np.asarray(theta, dtype=float)
        f = design_margins(self.model, self.steps, self._limits, self._design,
                           sharpness=self._sharpness, reach=reach(self.scene),
                           design_map=self._design_map)
        w = theta / self.scale
        return np.column_stack([np.asarray(f(self.x0[:, s], self.p0[:, s], w, self.scene.dt),
                                           dtype=float).ravel()
                                for s in range(self.x0.shape[1])])

    def losses(self, theta=None) -> np.ndarray:
        """L_s = max over checks of sat(r) − 1, per scenario, at θ."""
        R = self.ratios(theta)[[CHECKS.index(c) for c in self.checks]]
        return np.max(saturate(R, self.saturation) - 1, axis=0)

    def risk_of(self, losses) -> tuple:
        """(risk measure, η, u) of scenario losses: the epigraph variables at their optimum."""
        L = np.asarray(losses, dtype=float)
        if self.risk == "worst":
            return float(L.max()), float(L.max()), np.zeros(0)
        # Rockafellar–Uryasev: η at the α-quantile (any point of the flat optimum)
        eta = float(np.quantile(L, self.alpha, method="inverted_cdf"))
        u = np.maximum(L - eta, 0.0)
        return eta + float(u.sum()) / ((1 - self.alpha) * L.size), eta, u

    def scaled(self, theta, t=None):
        """NLP vector (θ/scale, η, u) with the epigraph variables at their optimum for θ."""
        theta = np.asarray(theta, dtype=float)
        _, eta, u = self.risk_of(self.losses(theta))
        return np.concatenate([theta / self.scale, [eta], u])

    def fg(self, x):
        """(f, g) of the NLP at x (NumPy)."""
        f, g = self._fg(x)
        return float(f), np.asarray(g, dtype=float).ravel()

    # -- solve ------------------------------------------------------------------
    def solve(self, ipopt: dict | None = None, progress=False, theta0=None) -> RobustResult:
        """Solve the scenario NLP with Ipopt from the study's curves (or ``theta0``).

        Parameters
        ----------
        ipopt : dict, optional
            Ipopt options over the defaults (limited-memory Hessian, monotone
            barrier from 1e-4, tol 1e-8, at most 200 iterations).
        progress : bool or callable
            True prints one line per iteration; a callable receives each
            iteration's dict (iteration, risk, scenarios within, seconds).
        theta0 : array_like, shape (n_variables,), optional
            Start here instead of the study's design (an earlier round's
            optimum); within the bounds.
        """
        started = time.perf_counter()
        start = self._start(theta0)
        x0 = self.scaled(start)
        nv = self.n_variables
        lbx = np.concatenate([self.lower / self.scale, [-1.0],
                              np.zeros(x0.size - nv - 1)])
        ubx = np.concatenate([self.upper / self.scale, [self.saturation],
                              np.full(x0.size - nv - 1, np.inf)])
        history = []
        R0 = self.ratios(start)
        best = dict(risk=self.risk_of(self.losses(start))[0], theta=start.copy(), iteration=-1)

        # shape and practical-limit rows: a design must meet them to be kept
        shape_rows = np.concatenate([np.arange(b.start, b.stop) for b in self.blocks
                                     if b.kind != "risk"] + [np.zeros(0, int)]).astype(int)

        def on_iteration(x, f, g):
            theta = np.clip(x[:nv] * self.scale, self.lower, self.upper)
            # only designs that meet the curve shapes (rows scaled to O(1)) may be kept
            admissible = bool(np.all(g[shape_rows] >= self.lbg[shape_rows] - VIOLATION_TOL))
            R = self.ratios(theta)
            active = R[[CHECKS.index(c) for c in self.checks]]
            risk = self.risk_of(np.max(saturate(active, self.saturation) - 1, axis=0))[0]
            row = dict(iteration=len(history), objective=f, risk=risk, shapes_met=admissible,
                       seconds=time.perf_counter() - started,
                       within=int(np.sum(np.all(active <= 1.0, axis=0))))
            history.append(row)
            if admissible and risk < best["risk"]:
                best.update(risk=risk, theta=theta, iteration=row["iteration"])
            if callable(progress):
                progress(row)
            elif progress:
                print(f"  iteration {row['iteration']:3d}: risk {risk:+.5f} (Ipopt's objective "
                      f"{f:+.5f}), scenarios within every limit {row['within']}/"
                      f"{len(self.names)}, {row['seconds']:.1f} s", flush=True)

        options = dict(_IPOPT, **(ipopt or {}))
        opts = {"ipopt": options, "print_time": False,
                "iteration_callback": IterationCallback(x0.size, self.lbg.size, on_iteration)}
        solver = ca.nlpsol("robust_design", "ipopt", self.nlp, opts)
        sol = solver(x0=x0, lbx=lbx, ubx=ubx, lbg=self.lbg, ubg=self.ubg)
        stats = solver.stats()
        x = np.asarray(sol["x"], dtype=float).ravel()
        final = np.clip(x[:nv] * self.scale, self.lower, self.upper)
        final_risk = self.risk_of(self.losses(final))[0]
        g_final = np.asarray(sol["g"], dtype=float).ravel()
        if not np.all(g_final[shape_rows] >= self.lbg[shape_rows] - VIOLATION_TOL):
            final_risk = math.inf                         # not an admissible design
        # the rollouts are only piecewise smooth (contacts, stick–slip, branch switches):
        # Ipopt's filter may accept a step that lowers the rows' violation at the cost of
        # the risk, so the best admissible design it visited is kept, not only its last one
        theta, objective = (final, final_risk) if final_risk <= best["risk"] else \
            (best["theta"], best["risk"])
        chosen = "final" if theta is final else f"iteration {best['iteration']}"
        return RobustResult(
            theta=theta, var_names=list(self.var_names), return_status=stats["return_status"],
            iterations=int(stats.get("iter_count", 0)), ratios_start=R0,
            ratios=self.ratios(theta), checks=list(CHECKS), scenarios=list(self.names),
            objective_start=self.risk_of(self.losses(start))[0], objective=objective,
            multipliers=self._multipliers(np.asarray(sol["lam_g"], dtype=float).ravel(),
                                          np.asarray(sol["lam_x"], dtype=float).ravel(), x,
                                          np.asarray(sol["g"], dtype=float).ravel()),
            history=history,
            timings=dict(self.timings, solve_seconds=time.perf_counter() - started,
                         ratio_calls=self._ratios.calls,
                         ratio_seconds=self._ratios.seconds,
                         jacobian_calls=self._ratios.jacobian_calls[0],
                         jacobian_seconds=self._ratios.jacobian_calls[1],
                         threads=self.threads, design_taken=chosen,
                         final_risk=final_risk),
            geometry=self._geometry_summary(theta))

    def _geometry_summary(self, theta) -> dict:
        """The legs' geometry at the start and at θ, and the practical rows at θ."""
        if self._frames is None:
            return {}
        g = self.fg(self.scaled(theta))[1]
        rows = [dict(kind=b.kind, leg=b.leg, label=b.label,
                     values=(g[b.start:b.stop] * b.scale).tolist(), unit=b.unit)
                for b in self.blocks if b.kind in PRACTICAL_KINDS]
        return dict(start=self.geometry_report(self.initial), end=self.geometry_report(theta),
                    practical=rows)

    def _start(self, theta0) -> np.ndarray:
        """The design to start from: ``theta0`` checked against the bounds, or the study's."""
        if theta0 is None:
            return self.initial
        theta = np.asarray(theta0, dtype=float).ravel()
        if theta.shape != self.initial.shape or not np.all(np.isfinite(theta)):
            raise ValueError(f"`theta0` must hold {self.initial.size} finite values (one per "
                             f"design variable {self.var_names}), got {theta0!r}.")
        outside = (theta < self.lower) | (theta > self.upper)
        if np.any(outside):
            names = [n for n, o in zip(self.var_names, outside) if o]
            raise ValueError(f"`theta0` is outside the bounds of {names}; start within them.")
        return theta

    def _multipliers(self, lam_g, lam_x, x, g) -> dict:
        """Which scenarios, checks, bounds and shapes bind at Ipopt's last iterate.

        Scenario and check entries sum the multipliers of the loss rows
        (∂ risk/∂ relaxing that limit, per unit of the ratio); bounds and
        shape rows are listed only when active (within :data:`_ACTIVE` of the
        bound, scaled) with a multiplier above it.
        """
        per_scenario, per_check = {}, {c: 0.0 for c in self.checks}
        shapes = []
        for b in self.blocks:
            lam = -lam_g[b.start:b.stop]          # ≥ 0 for a binding lower bound
            if b.kind == "risk":
                per_scenario[b.scenario] = float(lam.sum())
                for c, value in zip(self.checks, lam):
                    per_check[c] += float(value)
                continue
            active = np.abs(g[b.start:b.stop] - b.lower) <= _ACTIVE
            if np.any(active & (np.abs(lam) > _ACTIVE)):
                shapes.append(dict(label=b.label, multiplier=float(np.abs(lam[active]).max())))
        bounds = []
        for i, name in enumerate(self.var_names):
            value = x[i] * self.scale[i]
            for side, limit in (("lower", self.lower[i]), ("upper", self.upper[i])):
                if abs(value - limit) <= _ACTIVE * self.scale[i] and abs(lam_x[i]) > _ACTIVE:
                    bounds.append(dict(variable=name, bound=side, value=float(value),
                                       multiplier=float(lam_x[i])))
        return dict(scenarios=per_scenario, checks=per_check, bounds=bounds, shapes=shapes)
