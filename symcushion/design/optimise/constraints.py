"""Objective and constraints of the design NLP (a mixin of DesignProblem).

Owns the epigraph form of the peak (one smooth row per step and scenario),
the limit rows read from ``touchdown_measures`` of every rollout step, their
scaling; the shape rows of the tuned curves come from :mod:`.space`. It
must not choose variables, call Ipopt or read study files.
"""
from __future__ import annotations

import math

import casadi as ca
import numpy as np

from symcushion.layout.vectors import state_layout
from symcushion.scheme.measures import measures_function
from symcushion.design.optimise.geometry import PRACTICAL_KINDS
from symcushion.design.optimise.spec import Block, up_direction, VIOLATION_TOL
from symcushion.design.compiled_nlp import compile_design

__all__: list = ["DESIGN_OUTPUTS", "design_outputs_of"]

#: What ``design_outputs(w)`` stacks per scenario, in this order (n steps, N legs): the
#: vertical specific force (n), each leg's stroke, hinge azimuth and polar deflection
#: (N rows of n each), 1 − cos of the tilt (n) and the final upward speed (1). Stacked by
#: :func:`_stack_design_outputs`, read back only by :func:`design_outputs_of`.
DESIGN_OUTPUTS = ("acc", "strokes", "betas", "gammas", "tilt", "v_up")


def _design_output_rows(name: str, n_legs: int):
    """How many rows of n values entry ``name`` stacks; None: one (not a list of legs)."""
    return n_legs if name in ("strokes", "betas", "gammas") else None


def _stack_design_outputs(measure: dict) -> ca.MX:
    """One scenario's :data:`DESIGN_OUTPUTS` from its measures, as one column."""
    parts = []
    for name in DESIGN_OUTPUTS:
        value = measure[name]
        parts += [ca.vec(v) for v in value] if isinstance(value, list) else [ca.vec(value)]
    return ca.vertcat(*parts)


def design_outputs_of(y, shapes) -> list:
    """The values of ``design_outputs(w)``, ``y``, split into one dict per scenario of its
    :data:`DESIGN_OUTPUTS` by name: arrays of n steps (a list of them per leg for the
    strokes and angles), the upward speed a float. ``shapes``: (n steps, N legs) of each
    scenario."""
    y = np.asarray(y, dtype=float).ravel()
    out, offset = [], 0
    for n, n_legs in shapes:
        entry = {}
        for name in DESIGN_OUTPUTS:
            rows, width = _design_output_rows(name, n_legs), 1 if name == "v_up" else n
            count = width * (1 if rows is None else rows)
            block = y[offset:offset + count]
            offset += count
            if name == "v_up":
                entry[name] = float(block[0])
            elif rows is None:
                entry[name] = block
            else:
                entry[name] = [block[i * width:(i + 1) * width] for i in range(rows)]
        out.append(entry)
    return out



class Constraints:
    """The NLP of a :class:`DesignProblem`: objective, limit and shape rows (a mixin).

    Builds ``design_fg`` from the scenarios' rollouts and the per-step
    ``touchdown_measures``; reads the problem's resolved variables, limits and
    scales, and sets ``nlp``, ``blocks``, ``lbg``/``ubg`` and the output Function.
    """

    def _build(self):
        """Assemble ``design_fg``: variables (scaled θ, epigraph t), every row, the bounds."""
        nv = len(self.var_names)
        w = ca.MX.sym("w", nv)                     # scaled design θ/scale
        t = ca.MX.sym("t")                         # scaled epigraph variable
        theta = w * ca.DM(self.scale)
        p = ca.DM(self.p_fixed) + ca.DM(self._map) @ theta
        blocks, rows = [], []
        n_rows = 0

        def add(expr, kind, scale, lower, upper, unit, scenario=None, leg=None, dt=None, label=""):
            nonlocal n_rows
            expr = ca.vec(expr if isinstance(expr, ca.MX) else ca.MX(expr))
            if kind in ("shape",) + PRACTICAL_KINDS and not ca.depends_on(expr, w):
                # fixed by parameters that are not designed: check once, add no row
                value = float(ca.Function("fixed", [w], [expr])(np.zeros(nv)))
                if not lower - VIOLATION_TOL <= value / scale <= upper + VIOLATION_TOL:
                    raise ValueError(f"shape constraint `{label}` fails ({value:.4g} {unit}) "
                                     "and no design variable can change it; make the "
                                     "parameters involved design variables or fix the curve.")
                return
            blocks.append(Block(kind, scenario, leg, n_rows, n_rows + expr.numel(), lower, upper,
                                 scale, unit, dt, label))
            rows.append(expr / scale)
            n_rows += expr.numel()

        # the initial design's peak scales the epigraph variable
        peak_exprs, stroke_exprs = self._scenario_measures(p, theta)
        ref = self._objective_scale(w, peak_exprs, stroke_exprs)
        self._add_limit_rows(add, t, ref)

        self._add_shape_constraints(theta, add)
        self._add_practical_rows(theta, add, self.limits.stroke)
        g = ca.vertcat(*rows)
        self.blocks = blocks
        self._w, self._t = w, t
        self.nlp = {"x": ca.vertcat(w, t), "f": t, "g": g}
        self.lbg = np.concatenate([np.full(b.stop - b.start, b.lower) for b in blocks])
        self.ubg = np.concatenate([np.full(b.stop - b.start, b.upper) for b in blocks])
        self._fg = ca.Function("design_fg", [self.nlp["x"]], [self.nlp["f"], g], ["x"],
                               ["f", "g"])
        self._outputs_expr = ca.vertcat(*[_stack_design_outputs(m) for m in self._measure])
        self._outputs = ca.Function("design_outputs", [w], [self._outputs_expr], ["w"], ["y"])

    def use_compiled(self, cache_dir=None, progress=False, **options):
        """Evaluate the rollouts and their Jacobian in compiled C from now on.

        Builds (or reuses from ``cache_dir``) the library of
        :func:`symcushion.design.compiled_nlp.compile_design`; ``solve``, ``fg``,
        ``evaluate`` and ``check_gradient`` then use it. ``options`` go to
        ``compile_design`` (threads, cflags, directions, client). Returns the
        :class:`~symcushion.design.compiled_nlp.CompiledDesign`.
        """
        built = compile_design(self, cache_dir, progress=progress, **options)
        self._compiled_nlp, self._fg, self._outputs = built.nlp, built.fg, built.outputs
        return built

    def _compile_for_solve(self, compiled, cache_dir, progress) -> dict:
        """:meth:`use_compiled` if ``compiled``; its timings for the result (s)."""
        if not compiled:
            return {}
        built = self.use_compiled(cache_dir, progress=progress)
        return {f"compiled_{k}_seconds": v for k, v in built.seconds.items()}

    def _scenario_measures(self, p, theta):
        """Per scenario, the measures of every rollout step as expressions of the design.

        Sets ``self._measure`` (one dict per scenario) and returns the expressions of
        the vertical specific force and of the axial strokes, which scale the objective.
        """
        self._measure = []
        self._rollout_calls = []   # (X, Y) of each scenario: compiled_nlp replaces them
        peak_exprs, stroke_exprs = [], []
        for s, model in zip(self.scenarios, self.models):
            scene = s.scene
            up = up_direction(scene.gravity)
            # the design rows of p, then this scenario's own μ, gravity and body, and the
            # legs' geometry (expressions of θ where it is designed)
            p_full = ca.vertcat(p, self._full_p_tail(theta, model))
            x0 = self._placed_state(s.x0, theta, scene, s.clearance, up)
            X, Y = model.rollout(scene.steps)(x0, p_full, scene.dt)
            self._rollout_calls.append((X, Y))
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
        return peak_exprs, stroke_exprs

    def _objective_scale(self, w, peak_exprs, stroke_exprs):
        """The initial design's objective (the scale of the epigraph variable t)."""
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
        return ref

    def _add_limit_rows(self, add, t, ref):
        """Epigraph rows of the objective and the rows of every given limit, per step."""
        lim = self.limits
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
                sc = max(abs(float(np.dot(up_direction(s.scene.gravity), v0))), 0.1)
                add(m["v_up"], "final_speed", sc, bottom / sc, top / sc, "m/s", s.name,
                    label="final vertical speed")



