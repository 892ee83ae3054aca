"""Design study files (TOML): scenarios, variables, limits and the solve.

Owns the study schema, its checks (file, field path, bad value, what is
allowed), the placement of each scenario's body above the obstacle and
:func:`run_study`. It must not build the NLP itself.
"""
from __future__ import annotations

import copy
import dataclasses
import math
import sys
from dataclasses import dataclass, field
from pathlib import Path

import casadi as ca
import numpy as np

from symcushion.compiled.cbuild import find_compiler
from symcushion.scheme.quaternion import quat_to_rot_np
from symcushion.model.obstacles import closest_obstacle
from symcushion.model.scene import read_toml, scene_from_dict
from symcushion.validation import Table
from symcushion.model.scene_data import Scene
from symcushion.scheme.touchdown import initial_state
from symcushion.design.optimise.geometry import (GEOMETRY_QUANTITIES, GeometryVariable,
    PracticalLimits)
from symcushion.design.optimise.problem import DesignProblem
from symcushion.design.optimise.result import DesignResult
from symcushion.design.optimise.spec import (up_direction, CurveShape, DesignVariable, Limits, OBJECTIVES,
    Scenario)

__all__ = ["Study", "load_study", "study_from_dict", "read_design_table", "run_study"]

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib
#: Iterations of the vertical placement of a scenario's body (``clearance``):
#: exact in one for planes, a few for curved obstacles.
_PLACEMENT_ITERS = 20


class StudyFields(Table):
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
    compiled: bool | None = None
    scene_data: dict = field(default_factory=dict, repr=False)   # the scene's tables, as parsed

    def solve(self, progress=False) -> DesignResult:
        """Solve the design; ``compiled`` None (the default) compiles where gcc is found."""
        compiled = resolve_compiled(self.compiled, say=print if progress else None)
        result = self.problem.solve(ipopt=self.ipopt, progress=progress, compiled=compiled)
        result.meta.update(name=self.name, source=self.source, description=self.description)
        return result


def resolve_compiled(compiled: bool | None, say=None) -> bool:
    """Whether to evaluate the rollouts in compiled C: ``compiled``, or if None, gcc's presence.

    The compiled path is about ten times faster on the lander design
    (docs/compiled-design.md), so a study that
    says nothing uses it wherever a C compiler is found (``$CC`` or gcc);
    without one it runs on CasADi's VM and ``say`` (e.g. print) is told why.
    """
    if compiled is not None:
        return bool(compiled)
    if find_compiler() is not None:
        return True
    if say is not None:
        say("no C compiler found (install gcc or set $CC): the rollouts run on CasADi's "
            "VM, about ten times slower; `compile = false` under [solver] says so and "
            "silences this.")
    return False


def load_study(path) -> Study:
    """Load a design study from a TOML file (format: docs/optimise.md)."""
    path = Path(path)
    return study_from_dict(read_toml(path, "study"), str(path), base_dir=path.parent)


def study_from_dict(data: dict, source: str = "<dict>", base_dir=".") -> Study:
    """Build a :class:`Study` from the parsed contents of a study TOML file."""
    top = StudyFields(data, "", source)
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

    variables, shapes, geometry, practical = read_design_table(top.get("design", kind="table"))

    lim = top.get("limits", kind="table") if top.has("limits") else StudyFields({}, "limits", source)
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

    ipopt, compiled = {}, None                                 # None: compile where gcc is found
    if top.has("solver"):
        so = top.get("solver", kind="table")
        compiled = so.get("compile", None, kind="bool")    # C rollouts (compiled_nlp)
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
        problem = DesignProblem(scenarios, variables, limits, objective, shapes, geometry,
                                practical)
    except (ValueError, TypeError) as exc:
        raise ValueError(f"{source}: {exc}") from None
    return Study(name=name, problem=problem, ipopt=ipopt, source=source, description=description,
                 compiled=compiled, scene_data=copy.deepcopy(scene_raw))


def read_design_table(dz) -> tuple:
    """``[[design.variables]]``, ``[[design.shape]]``, ``[[design.geometry]]`` and
    ``[design.limits]`` of a study's ``[design]`` table.

    Returns
    -------
    variables : list of DesignVariable
    shapes : list of CurveShape
    geometry : list of GeometryVariable
    practical : PracticalLimits
    """
    variables = []
    for t in (dz.get("variables", kind="tables") if dz.has("variables") else []):
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
    geometry = [_geometry_variable(t) for t in
                (dz.get("geometry", kind="tables") if dz.has("geometry") else [])]
    dz.used.add("geometry")
    practical = PracticalLimits()
    if dz.has("limits"):
        lt = dz.get("limits", kind="table")
        practical = PracticalLimits(
            footprint_radius=lt.get("footprint_radius", None, positive=True),
            leg_mass=lt.get("leg_mass", None, positive=True),
            ground_clearance=lt.get("ground_clearance", None, positive=True))
        lt.finish()
    dz.used.add("limits")
    dz.finish()
    if not variables and not geometry:
        raise dz.error("variables", None, "at least one `[[design.variables]]` (curve "
                       "parameters) or `[[design.geometry]]` table")
    return variables, shapes, geometry, practical


def _geometry_variable(t) -> GeometryVariable:
    """One ``[[design.geometry]]`` table: the splay's bounds in radians or degrees
    (``lower_deg``), the others' in metres (``lower``, ``upper``)."""
    quantity = t.get("quantity", kind="string", choices=tuple(GEOMETRY_QUANTITIES))
    if quantity == "splay":        # radians, or degrees as `lower_deg` (docs/scenes.md, "Angles")
        lower, upper = t.angle("lower"), t.angle("upper")
        scale = t.angle("scale", None, positive=True)
    else:
        lower, upper = t.get("lower"), t.get("upper")
        scale = t.get("scale", None, positive=True)
    legs = t.get("legs", None, kind="any")
    if legs is not None and not (isinstance(legs, list) and all(
            isinstance(j, int) and not isinstance(j, bool) for j in legs)):
        raise t.error("legs", legs, "a list of leg indices, e.g. [0, 2]")
    out = GeometryVariable(quantity, lower, upper, legs=legs,
                           shared=t.get("shared", True, kind="bool"), scale=scale)
    t.finish()
    return out


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


def _scenario(t: StudyFields, base: Scene, scene_raw: dict, scene_source: str) -> Scenario:
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
    clearance = None
    if t.has("clearance"):
        clearance = t.get("clearance", nonnegative=True)
        body.position = _place(scene, body, clearance)
    t.finish()
    x0 = initial_state(scene.with_(body=body))
    return Scenario(name, scene, x0, clearance)


def _place(scene: Scene, body, clearance: float) -> np.ndarray:
    """Body position, moved along the vertical, whose lowest free foot is ``clearance`` up."""
    up = up_direction(scene.gravity)
    R = quat_to_rot_np(body.attitude)
    pos = np.array(body.position, dtype=float)
    for _ in range(_PLACEMENT_ITERS):
        best = None
        for leg in scene.legs:
            d, n, _ = closest_obstacle(scene.obstacles, ca.DM(pos + R @ leg.rest_foot),
                                       leg.footpad)
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
