"""Touchdown scenes: a rigid body on N legs, obstacles, gravity, friction, method.

A :class:`Scene` is plain data: it says *what* is simulated. How it is
integrated lives in ``symcushion.simulate``. Scenes are built from Python or
loaded from TOML (:func:`load_scene`); every field of a TOML file is checked
and an invalid one is reported with its path, its value and what is allowed.

Frames: the body frame has its origin at the centre of mass; legs are given in
body coordinates. The attitude is a unit quaternion (w, x, y, z) mapping body
to world coordinates.
"""
from __future__ import annotations

import sys
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Sequence

import numpy as np

from .characteristics import Crushable, Curve, Linear, PiecewiseLinear
from .contact import METHODS  # re-exported: scenes name their contact step
from .obstacles import ImplicitSurface, Obstacle, Plane, Sphere, Terrain
from .strut import HingedStrut

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

__all__ = ["Body", "Scene", "symmetric_legs", "load_scene", "scene_from_dict", "METHODS"]


#: Where a step replaces the obstacle by its tangent plane (§3): ``"start"``,
#: at the foot's contact point at the start of the step (the literal reading,
#: first order on curved obstacles: the force lags the normal by half a step);
#: ``"end"``, a second contact step on the plane tangent at the end point the
#: first predicted (second order, twice the contact cost).
TANGENT_PLANES = ("start", "end")


def _vec(name, value, size=3):
    try:
        arr = np.asarray(value, dtype=float).ravel()
    except (TypeError, ValueError):
        raise TypeError(f"`{name}` must be {size} numbers, got {value!r}.") from None
    if arr.size != size or not np.all(np.isfinite(arr)):
        raise ValueError(f"`{name}` must be {size} finite numbers, got {value!r}.")
    return arr


def _positive(name, value):
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
        raise TypeError(f"`{name}` must be a number, got {value!r}.")
    if not (np.isfinite(value) and value > 0):
        raise ValueError(f"`{name}` must be positive and finite, got {value!r}.")
    return float(value)


@dataclass
class Body:
    """The rigid body and its initial state.

    Attributes
    ----------
    mass : float
        kg, > 0.
    inertia : ndarray, shape (3, 3)
        Inertia tensor about the centre of mass, body axes (kg·m²); a 3-vector
        is taken as the diagonal.
    position : ndarray, shape (3,)
        Initial centre of mass, world (m).
    attitude : ndarray, shape (4,)
        Initial unit quaternion (w, x, y, z), body → world.
    velocity : ndarray, shape (3,)
        Initial velocity, world (m/s).
    angular_velocity : ndarray, shape (3,)
        Initial angular velocity in body axes (rad/s).
    """

    mass: float
    inertia: np.ndarray
    position: np.ndarray = field(default_factory=lambda: np.zeros(3))
    attitude: np.ndarray = field(default_factory=lambda: np.array([1.0, 0, 0, 0]))
    velocity: np.ndarray = field(default_factory=lambda: np.zeros(3))
    angular_velocity: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def __post_init__(self):
        self.mass = _positive("body.mass", self.mass)
        inertia = np.asarray(self.inertia, dtype=float)
        if inertia.shape == (3,):
            inertia = np.diag(inertia)
        if inertia.shape != (3, 3) or not np.all(np.isfinite(inertia)):
            raise ValueError(f"`body.inertia` must be 3 numbers or a 3×3 matrix, got {self.inertia!r}.")
        if not np.allclose(inertia, inertia.T) or np.any(np.linalg.eigvalsh(inertia) <= 0):
            raise ValueError(f"`body.inertia` must be symmetric positive definite, got {inertia.tolist()}.")
        self.inertia = inertia
        self.position = _vec("body.position", self.position)
        q = _vec("body.attitude", self.attitude, 4)
        if np.linalg.norm(q) < 1e-12:
            raise ValueError(f"`body.attitude` must be a non-zero quaternion, got {q.tolist()}.")
        self.attitude = q / np.linalg.norm(q)
        self.velocity = _vec("body.velocity", self.velocity)
        self.angular_velocity = _vec("body.angular_velocity", self.angular_velocity)


@dataclass
class Scene:
    """A touchdown: body, legs, obstacles, gravity, friction and time grid.

    Attributes
    ----------
    body : Body
    legs : list of HingedStrut
        Legs in body coordinates.
    obstacles : list of Obstacle
    mu : float
        Coulomb coefficient between every foot and every obstacle, ≥ 0. With
        μ = 0 the simulator builds no friction code.
    method : {'paper', 'robust', 'implicit'}
        Contact step (``symcushion.contact``).
    dt : float
        Time step (s).
    duration : float
        Simulated time (s).
    gravity : ndarray, shape (3,)
        m/s², world.
    name : str
    tangent_plane : {'end', 'start'}
        Where the obstacle is replaced by its tangent plane (:data:`TANGENT_PLANES`).
    """

    body: Body
    legs: list
    obstacles: list
    mu: float = 0.0
    method: str = "implicit"
    dt: float = 1e-3
    duration: float = 1.0
    gravity: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, -9.81]))
    name: str = "scene"
    tangent_plane: str = "end"

    def __post_init__(self):
        if not isinstance(self.body, Body):
            raise TypeError(f"`body` must be a Body, got {type(self.body).__name__}.")
        self.legs = list(self.legs)
        if not self.legs or not all(isinstance(leg, HingedStrut) for leg in self.legs):
            raise ValueError("`legs` must be a non-empty list of HingedStrut.")
        self.obstacles = list(self.obstacles)
        if not self.obstacles or not all(isinstance(o, Obstacle) for o in self.obstacles):
            raise ValueError("`obstacles` must be a non-empty list of Obstacle.")
        if isinstance(self.mu, bool) or not isinstance(self.mu, (int, float)) \
                or not np.isfinite(self.mu) or self.mu < 0:
            raise ValueError(f"`mu` must be a finite number >= 0, got {self.mu!r}.")
        self.mu = float(self.mu)
        if self.method not in METHODS:
            raise ValueError(f"`method` must be one of {METHODS}, got {self.method!r}.")
        if self.tangent_plane not in TANGENT_PLANES:
            raise ValueError(f"`tangent_plane` must be one of {TANGENT_PLANES}, "
                             f"got {self.tangent_plane!r}.")
        self.dt = _positive("dt", self.dt)
        self.duration = _positive("duration", self.duration)
        self.gravity = _vec("gravity", self.gravity)

    @property
    def steps(self) -> int:
        """Number of steps, round(duration/dt)."""
        return max(1, int(round(self.duration / self.dt)))

    def with_(self, **changes) -> "Scene":
        """A copy with some fields replaced (``scene.with_(method='paper')``)."""
        return replace(self, **changes)


def symmetric_legs(count: int, radius: float, height: float, length: float, e0_local,
                   en_local, S: Curve | None = None, M_beta: Curve | None = None,
                   M_gamma: Curve | None = None, azimuth0: float = 0.0,
                   axial_ratio: float | None = None) -> list:
    """``count`` identical legs spaced evenly about the body's z axis.

    Leg i has its hinge at azimuth φ_i = azimuth0 + 2πi/count, at ``radius``
    from the axis and ``height`` along z. Its rest direction and polar axis
    are given in the leg's local frame (radial, tangential, z), e.g.
    ``e0_local=(0, 0, -1)`` for a rod hanging straight down.

    Returns
    -------
    list of HingedStrut
    """
    if isinstance(count, bool) or not isinstance(count, (int, np.integer)) or count < 1:
        raise ValueError(f"`count` must be a positive integer, got {count!r}.")
    e0_local = _vec("e0_local", e0_local)
    en_local = _vec("en_local", en_local)
    legs = []
    for i in range(count):
        phi = azimuth0 + 2 * np.pi * i / count
        radial = np.array([np.cos(phi), np.sin(phi), 0.0])
        tangential = np.array([-np.sin(phi), np.cos(phi), 0.0])
        up = np.array([0.0, 0.0, 1.0])
        frame = np.column_stack([radial, tangential, up])
        kwargs = {} if axial_ratio is None else {"axial_ratio": axial_ratio}
        legs.append(HingedStrut(hinge=radius * radial + height * up, e0=frame @ e0_local,
                                en=frame @ en_local, length=length, S=S, M_beta=M_beta,
                                M_gamma=M_gamma, **kwargs))
    return legs


# ---------------------------------------------------------------------------
# TOML
# ---------------------------------------------------------------------------
class _Table:
    """A TOML table with its path, for error messages that name the field.

    Subclasses may point ``docs`` at their own format page and set
    ``finite_numbers = False`` to accept ±inf (e.g. unbounded limits).
    """

    docs = "docs/scenes.md"
    finite_numbers = True

    def __init__(self, data, path, source):
        if not isinstance(data, dict):
            raise ValueError(f"{source}: `{path}` must be a table, got {data!r}.")
        self.data, self.path, self.source = data, path, source
        self.used = set()

    def _where(self, key):
        return f"{self.path}.{key}" if self.path else key

    def error(self, key, value, allowed):
        return ValueError(f"{self.source}: field `{self._where(key)}` = {value!r} is invalid; "
                          f"allowed: {allowed}.")

    def _finite(self, value) -> bool:
        value = np.asarray(value, dtype=float)
        return bool(np.all(np.isfinite(value) if self.finite_numbers else ~np.isnan(value)))

    def get(self, key, default=..., kind="number", size=None, choices=None, positive=False,
            nonnegative=False):
        self.used.add(key)
        if key not in self.data:
            if default is ...:
                raise ValueError(f"{self.source}: missing field `{self._where(key)}` ({kind}).")
            return default
        value = self.data[key]
        if kind == "number":
            ok = not isinstance(value, bool) and isinstance(value, (int, float)) \
                and self._finite(value)
            if not ok or (positive and not value > 0) or (nonnegative and not value >= 0):
                raise self.error(key, value, "a positive number" if positive else
                                 "a non-negative number" if nonnegative else "a finite number")
            return float(value)
        if kind == "int":
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise self.error(key, value, "a positive integer")
            return value
        if kind == "vector":
            ok = isinstance(value, list) and all(
                isinstance(v, (int, float)) and not isinstance(v, bool) for v in value)
            if not ok or (size is not None and len(value) != size) or not self._finite(value):
                raise self.error(key, value, f"a list of {size} finite numbers")
            return np.asarray(value, dtype=float)
        if kind == "string":
            if not isinstance(value, str) or (choices and value not in choices):
                raise self.error(key, value, f"one of {list(choices)}" if choices else "a string")
            return value
        if kind == "bool":
            if not isinstance(value, bool):
                raise self.error(key, value, "true or false")
            return value
        if kind == "strings":
            if isinstance(value, str):
                return [value]
            if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
                raise self.error(key, value, "a string or a list of strings")
            return value
        if kind == "table":
            return type(self)(value, self._where(key), self.source)
        if kind == "tables":
            if not isinstance(value, list):
                raise self.error(key, value, "an array of tables ([[...]])")
            return [type(self)(v, f"{self._where(key)}[{i}]", self.source)
                    for i, v in enumerate(value)]
        if kind == "any":
            return value
        raise AssertionError(kind)

    def has(self, key):
        return key in self.data

    def finish(self):
        unknown = sorted(set(self.data) - self.used)
        if unknown:
            where = self.path or "the top level"
            raise ValueError(f"{self.source}: unknown field(s) {unknown} in `{where}`; "
                             f"check the spelling against {self.docs}.")


_CURVES = ("linear", "piecewise", "crushable")


def _curve(table: _Table, allow_unloading=True) -> Curve:
    kind = table.get("type", kind="string", choices=_CURVES)
    options = dict(smooth=table.get("smooth", False, kind="bool"),
                   tunable=table.get("tunable", False, kind="bool"))
    if allow_unloading and table.has("unloading"):
        options["unloading"] = _curve(table.get("unloading", kind="table"), allow_unloading=False)
    try:
        if kind == "linear":
            curve = Linear(table.get("stiffness"), table.get("preload", 0.0), **options)
        elif kind == "piecewise":
            curve = PiecewiseLinear(table.get("x", kind="vector"), table.get("f", kind="vector"),
                                    **options)
        else:
            curve = Crushable(table.get("stiffness", positive=True),
                              table.get("crush_force", positive=True),
                              table.get("plateau_slope", 0.0), **options)
    except (ValueError, TypeError) as exc:
        raise ValueError(f"{table.source}: `{table.path}`: {exc}") from None
    table.finish()
    return curve


def _elements(table: _Table):
    out = {}
    for name in ("S", "M_beta", "M_gamma"):
        if table.has(name):
            out[name] = _curve(table.get(name, kind="table"))
        else:
            table.used.add(name)
    return out


def _legs(top: _Table) -> list:
    legs = []
    if top.has("legs"):
        t = top.get("legs", kind="table")
        els = _elements(t)
        kwargs = {}
        if t.has("axial_ratio"):
            kwargs["axial_ratio"] = t.get("axial_ratio", positive=True)
        try:
            legs += symmetric_legs(
                t.get("count", kind="int"), t.get("radius", positive=True), t.get("height"),
                t.get("length", positive=True), t.get("e0", kind="vector", size=3),
                t.get("en", kind="vector", size=3), azimuth0=t.get("azimuth0", 0.0),
                **els, **kwargs)
        except (ValueError, TypeError) as exc:
            raise ValueError(f"{t.source}: `legs`: {exc}") from None
        t.finish()
    if top.has("leg"):
        for t in top.get("leg", kind="tables"):
            els = _elements(t)
            kwargs = {}
            if t.has("axial_ratio"):
                kwargs["axial_ratio"] = t.get("axial_ratio", positive=True)
            try:
                legs.append(HingedStrut(t.get("hinge", kind="vector", size=3),
                                        t.get("e0", kind="vector", size=3),
                                        t.get("en", kind="vector", size=3),
                                        t.get("length", positive=True), **els, **kwargs))
            except (ValueError, TypeError) as exc:
                raise ValueError(f"{t.source}: `{t.path}`: {exc}") from None
            t.finish()
    if not legs:
        raise ValueError(f"{top.source}: no legs; give a `[legs]` table (a symmetric pattern) "
                         "or `[[leg]]` tables.")
    return legs


_OBSTACLES = ("plane", "sphere", "implicit", "terrain")


def _obstacle(t: _Table) -> Obstacle:
    kind = t.get("type", kind="string", choices=_OBSTACLES)
    try:
        if kind == "plane":
            if t.has("angle"):
                ob = Plane.inclined(t.get("angle"), t.get("point", (0.0, 0.0, 0.0), kind="vector",
                                                          size=3))
            else:
                ob = Plane(t.get("point", (0.0, 0.0, 0.0), kind="vector", size=3),
                           t.get("normal", (0.0, 0.0, 1.0), kind="vector", size=3))
        elif kind == "sphere":
            ob = Sphere(t.get("center", kind="vector", size=3), t.get("radius", positive=True))
        elif kind == "implicit":
            ob = _implicit_from_string(t.get("phi", kind="string"), t)
        else:
            preset = t.get("preset", "grid", kind="string",
                           choices=("grid", "crater", "slope_with_rocks"))
            if preset == "crater":
                ob = Terrain.crater(t.get("radius", 2.0, positive=True), t.get("depth", 0.3),
                                    t.get("rim", 0.1))
            elif preset == "slope_with_rocks":
                ob = Terrain.slope_with_rocks(t.get("angle", 0.1))
            else:
                ob = Terrain(t.get("x", kind="vector"), t.get("y", kind="vector"),
                             np.asarray(t.get("heights", kind="vector")).reshape(
                                 len(t.data["x"]), len(t.data["y"])))
    except (ValueError, TypeError) as exc:
        if str(exc).startswith(t.source):
            raise
        raise ValueError(f"{t.source}: `{t.path}`: {exc}") from None
    t.finish()
    return ob


def _implicit_from_string(text: str, t: _Table) -> ImplicitSurface:
    """φ(x, y, z) from a formula in a TOML file, e.g. ``"x**2 + y**2 + z**2 - 1"``.

    Only arithmetic and the CasADi functions named below may appear.
    """
    import ast

    allowed_funcs = {"sin", "cos", "tan", "exp", "log", "sqrt", "tanh", "fabs"}
    tree = ast.parse(text, mode="eval")
    for node in ast.walk(tree):
        if isinstance(node, ast.Name) and node.id not in {"x", "y", "z"} | allowed_funcs:
            raise t.error("phi", text, f"a formula in x, y, z using {sorted(allowed_funcs)}")
        if isinstance(node, (ast.Attribute, ast.Subscript, ast.Lambda)):
            raise t.error("phi", text, "plain arithmetic in x, y, z")
    code = compile(tree, "<phi>", "eval")

    import casadi as ca

    def phi(p):
        env = {name: getattr(ca, name) for name in allowed_funcs}
        env.update(x=p[0], y=p[1], z=p[2])
        return eval(code, {"__builtins__": {}}, env)  # noqa: S307 - names checked above

    return ImplicitSurface(phi)


def scene_from_dict(data: dict, source: str = "<dict>") -> Scene:
    """Build a :class:`Scene` from the parsed contents of a scene TOML file."""
    top = _Table(data, "", source)
    s = top.get("scene", {}, kind="table") if top.has("scene") else _Table({}, "scene", source)
    top.used.add("scene")
    b = top.get("body", kind="table")
    body = Body(mass=b.get("mass", positive=True),
                inertia=np.asarray(b.get("inertia", kind="vector")).reshape(-1, 3)
                if len(b.data.get("inertia", [])) == 9 else b.get("inertia", kind="vector", size=3),
                position=b.get("position", (0.0, 0.0, 0.0), kind="vector", size=3),
                attitude=b.get("attitude", (1.0, 0.0, 0.0, 0.0), kind="vector", size=4),
                velocity=b.get("velocity", (0.0, 0.0, 0.0), kind="vector", size=3),
                angular_velocity=b.get("angular_velocity", (0.0, 0.0, 0.0), kind="vector", size=3))
    b.finish()
    legs = _legs(top)
    obstacles = [_obstacle(t) for t in top.get("obstacle", kind="tables")]
    scene = Scene(body=body, legs=legs, obstacles=obstacles,
                  mu=s.get("mu", 0.0), method=s.get("method", "implicit", kind="string",
                                                    choices=METHODS),
                  dt=s.get("dt", 1e-3, positive=True), duration=s.get("duration", 1.0, positive=True),
                  gravity=s.get("gravity", (0.0, 0.0, -9.81), kind="vector", size=3),
                  name=s.get("name", Path(source).stem, kind="string"),
                  tangent_plane=s.get("tangent_plane", "end", kind="string",
                                      choices=TANGENT_PLANES))
    if scene.mu < 0:
        raise s.error("mu", scene.mu, "a number >= 0")
    s.finish()
    top.finish()
    return scene


def read_toml(path, what: str = "scene") -> dict:
    """Parse a TOML file; a missing file or bad TOML gets a message naming it."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{what} file {str(path)!r} does not exist.")
    try:
        return tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as exc:
        raise ValueError(f"{path}: not valid TOML: {exc}") from None


def load_scene(path) -> Scene:
    """Load a scene from a TOML file (format: docs/scenes.md)."""
    return scene_from_dict(read_toml(path, "scene"), str(path))
