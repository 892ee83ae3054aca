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

import numpy as np

from .characteristics import Crushable, GasSpring, Linear, PiecewiseLinear, TwoSided
from .curve_base import KINK_WIDTH, RATE_WIDTH, Curve
from .contact import METHODS  # re-exported: scenes name their contact step
from .obstacles import ImplicitSurface, Obstacle, Plane, Sphere, Terrain
from .strut import DEFAULT_LAW, LAWS, HingedStrut
from .tripod import ELEMENTS as TRIPOD_ELEMENTS
from .tripod import InvertedTripod
from .formula import Formula, FormulaError
from .validation import (INVALID, Problems, SceneError, Table, choice, direction, integer,
                         real, show, vector)
from .validation import path as validate_path

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

__all__ = ["Body", "Scene", "SceneError", "symmetric_legs", "load_scene", "scene_from_dict",
           "METHODS"]


#: Where a step replaces the obstacle by its tangent plane (§3): ``"start"``,
#: at the foot's contact point at the start of the step (the literal reading,
#: first order on curved obstacles: the force lags the normal by half a step);
#: ``"end"``, a second contact step on the plane tangent at the end point the
#: first predicted (second order, twice the contact cost).
TANGENT_PLANES = ("start", "end")

#: How the implicit contact step turns a sliding foot's slip direction over a
#: step (``symcushion.contact_midpoint``): ``"backward"``, along the force of
#: the end of the step (backward Euler: first order when the direction turns);
#: ``"midpoint"``, along the fitted mean of the start and end forces (second
#: order, a Newton correction after the backward-Euler step).
SLIP_RULES = ("backward", "midpoint")

#: What the touchdown step does at the events inside a step
#: (``symcushion.branch_switch``): ``"none"``, the velocity-Verlet kick;
#: ``"branch"``, the kick weighted at the located switch of each leg's axial
#: loading/unloading branch (second order through the force jump);
#: ``"lock"``, that and the stroke lock of ``symcushion.stroke_lock``: a leg
#: whose foot sticks holds its stroke between the curves (SHAKE/RATTLE).
EVENT_RULES = ("none", "branch", "lock")

#: The absorbers' law between their loading and unloading curves:
#: ``"sign"``, the printed P = P(δ, sign δ′) of (2.1) (the force jumps between
#: the curves when the rate changes sign); ``"memory"``, the elastic band of
#: ``symcushion.absorber`` (a set per absorber in the state, a continuous force,
#: crushing only at the loading curve's force; docs/absorbers.md).
HYSTERESIS_LAWS = ("sign", "memory")

#: Leg schemes: ``"strut"``, the strut on a spherical hinge of (2.1)
#: (``symcushion.strut``); ``"tripod"``, the inverted tripod of flown landers
#: (``symcushion.tripod``, docs/tripod.md).
SCHEMES = ("strut", "tripod")
LEG_SCHEMES = (HingedStrut, InvertedTripod)


def _vec(name, value, size=3):
    return vector(name, value, (size,))


def _positive(name, value, unit=""):
    return real(name, value, positive=True, unit=unit)


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
        self.mass = _positive("body.mass", self.mass, "kg")
        try:
            inertia = vector("body.inertia", self.inertia, (3,))
            inertia = np.diag(inertia)
        except (TypeError, ValueError):
            try:
                inertia = vector("body.inertia", self.inertia, (3, 3))
            except (TypeError, ValueError):
                raise ValueError(f"`body.inertia` must be 3 numbers (the diagonal) or a 3×3 "
                                 f"matrix in kg·m², got {show(self.inertia)}.") from None
        if not np.allclose(inertia, inertia.T) or np.any(np.linalg.eigvalsh(inertia) <= 0):
            raise ValueError(f"`body.inertia` must be symmetric positive definite, got "
                             f"{inertia.tolist()}; give the principal moments (kg·m²).")
        self.inertia = inertia
        self.position = _vec("body.position", self.position)
        self.attitude = direction("body.attitude", self.attitude, 4)
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
    slip : {'backward', 'midpoint'}
        The slip rule of the implicit contact step (:data:`SLIP_RULES`);
        ``'midpoint'`` needs ``method='implicit'``.
    events : {'none', 'branch', 'lock'}
        What the body step does at the absorbers' branch switches inside a
        step (:data:`EVENT_RULES`); ``'lock'`` needs ``mu > 0``.
    hysteresis : {'sign', 'memory'}
        The absorbers' law between their curves (:data:`HYSTERESIS_LAWS`);
        ``'memory'`` needs ``events = 'none'`` (its force does not jump).
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
    slip: str = "backward"
    events: str = "none"
    hysteresis: str = "sign"

    def __post_init__(self):
        if not isinstance(self.body, Body):
            raise TypeError(f"`body` must be a Body, got {type(self.body).__name__}.")
        self.legs = list(self.legs)
        if not self.legs or not all(isinstance(leg, LEG_SCHEMES) for leg in self.legs):
            raise ValueError("`legs` must be a non-empty list of legs (HingedStrut or "
                             "InvertedTripod).")
        self.obstacles = list(self.obstacles)
        if not self.obstacles or not all(isinstance(o, Obstacle) for o in self.obstacles):
            raise ValueError("`obstacles` must be a non-empty list of Obstacle.")
        self.mu = real("mu", self.mu, nonnegative=True)
        self.method = choice("method", self.method, METHODS)
        self.tangent_plane = choice("tangent_plane", self.tangent_plane, TANGENT_PLANES)
        self.slip = choice("slip", self.slip, SLIP_RULES)
        self.events = choice("events", self.events, EVENT_RULES)
        if self.events == "lock" and self.mu == 0:
            raise ValueError("`events` = 'lock' holds the stroke of a leg whose foot sticks, and "
                             "with mu = 0 no foot sticks. Set mu > 0 or events = 'branch'.")
        if self.slip != "backward" and self.method != "implicit":
            raise ValueError(f"`slip` = {self.slip!r} corrects the implicit contact step's slip; "
                             f"`method` is {self.method!r}. Set method = 'implicit' or "
                             "slip = 'backward'.")
        self.hysteresis = choice("hysteresis", self.hysteresis, HYSTERESIS_LAWS)
        self._check_dampers()
        self._check_tripods()
        if self.hysteresis == "memory":
            self._check_memory()
        self.dt = _positive("dt", self.dt, "s")
        self.duration = _positive("duration", self.duration, "s")
        self.gravity = _vec("gravity", self.gravity)
        if not isinstance(self.name, str):
            raise TypeError(f"`name` must be a string, got {show(self.name)}.")

    def _check_dampers(self):
        """Dampers act under the memory law, on any element."""
        for j, leg in enumerate(self.legs):
            for el in leg.elements:
                if el.curve.has_damper and self.hysteresis != "memory":
                    raise ValueError(f"leg {j}: `{el.name}` has a damper, which the printed "
                                     "law P(δ, sign δ′) does not have; set hysteresis = "
                                     "'memory'.")

    def _check_tripods(self):
        """An inverted tripod takes no event rule: those locate a strut's switches."""
        tripods = [j for j, leg in enumerate(self.legs) if isinstance(leg, InvertedTripod)]
        if tripods and self.events != "none":
            raise ValueError(f"legs {tripods} are inverted tripods; `events` = "
                             f"{self.events!r} locates the switches of a strut's axial element "
                             "only. Set events = 'none'.")

    def _check_memory(self):
        """The memory law's conditions: no event rule, no hinge spring with memory."""
        if self.events != "none":
            raise ValueError(f"`events` = {self.events!r} locates the jumps of the printed law; "
                             "`hysteresis` = 'memory' has a continuous force and needs none. "
                             "Set events = 'none' (or hysteresis = 'sign').")
        for j, leg in enumerate(self.legs):
            for el in leg.elements:
                if el.name != "S" and el.curve.unloading is not None:
                    raise ValueError(
                        f"leg {j}: `{el.name}` has an unloading curve; `hysteresis` = 'memory' "
                        "keeps a set for the axial absorber only. Remove the hinge spring's "
                        "unloading curve or set hysteresis = 'sign'.")

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
                   axial_ratio: float | None = None, law: str = "paper",
                   footpad: float = 0.0) -> list:
    """``count`` identical legs spaced evenly about the body's z axis.

    Leg i has its hinge at azimuth φ_i = azimuth0 + 2πi/count, at ``radius``
    from the axis and ``height`` along z. Its rest direction and polar axis
    are given in the leg's local frame (radial, tangential, z), e.g.
    ``e0_local=(0, 0, -1)`` for a rod hanging straight down. ``law``: the
    force law of every leg (``HingedStrut``'s, ``"paper"`` or ``"potential"``);
    ``footpad``: every leg's footpad radius (m, 0 for point feet).

    Returns
    -------
    list of HingedStrut
    """
    count = integer("count", count, minimum=1)
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
                                M_gamma=M_gamma, law=law, footpad=footpad, **kwargs))
    return legs


# ---------------------------------------------------------------------------
# TOML
# ---------------------------------------------------------------------------
#: Kept for the study loaders that subclass it (the TOML checker now lives in
#: ``symcushion.validation``).
_Table = Table

_CURVES = ("linear", "piecewise", "crushable", "gas", "two_sided")
#: Every key of an element table, for "did you mean" on a misspelt one.
_CURVE_KEYS = ("type", "smooth", "tunable", "unloading", "stiffness", "preload", "x", "f",
               "crush_force", "plateau_slope", "kink_width", "rate_width",
               "elastic_stiffness", "damping", "orifice", "stroke_limit", "stop_stiffness",
               "pressure", "area", "volume", "exponent", "compression", "tension")


def symmetric_tripods(count: int, h1, h2, h3, foot, outer_length: float, primary: Curve,
                      secondary2: Curve, secondary3: Curve, azimuth0: float = 0.0,
                      footpad: float = 0.0) -> list:
    """``count`` identical inverted-tripod legs evenly spaced about the body's z axis.

    Leg 0's hardpoints ``h1``, ``h2``, ``h3`` and rest ``foot`` are given in
    body axes at azimuth 0 (its plane of symmetry is usually x–z); leg i is
    leg 0 turned about z by φ_i = azimuth0 + 2πi/count; ``footpad``: every leg's
    footpad radius (m, 0 for point feet).

    Returns
    -------
    list of InvertedTripod
    """
    count = integer("count", count, minimum=1)
    points = [np.asarray(v, dtype=float) for v in (h1, h2, h3, foot)]
    legs = []
    for i in range(count):
        phi = azimuth0 + 2 * np.pi * i / count
        c, s = np.cos(phi), np.sin(phi)
        turn = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        legs.append(InvertedTripod(*(turn @ v for v in points), outer_length=outer_length,
                                   primary=primary, secondary2=secondary2,
                                   secondary3=secondary3, footpad=footpad))
    return legs


def _build(t: Table, build, *args, **kwargs):
    """``build(*args, **kwargs)`` unless a field of ``t`` failed (then INVALID).

    A ValueError/TypeError of the constructor is recorded with the table's path,
    so that e.g. ``Linear(-5)`` from ``[legs.M_beta]`` names `legs.M_beta`.
    """
    if t.failed or any(a is INVALID for a in (*args, *kwargs.values())):
        t.failed = True
        return INVALID
    try:
        return build(*args, **kwargs)
    except (ValueError, TypeError) as exc:
        return t.fail(f"`{t.path or 'scene'}`: {exc}")


def _curve(table, allow_unloading=True) -> Curve:
    if table is INVALID:
        return INVALID
    kind = table.get("type", kind="string", choices=_CURVES)
    options = dict(smooth=table.get("smooth", False, kind="bool"),
                   tunable=table.get("tunable", False, kind="bool"))
    for width, default in (("kink_width", KINK_WIDTH), ("rate_width", RATE_WIDTH)):
        # the widths of the rounding act only on a smooth curve: said, not ignored
        if table.has(width) and options["smooth"] is False:
            table.fail(f"`{table.path}.{width}` acts only on a smooth curve; add "
                       f"`smooth = true` to `{table.path}` or remove `{width}`.")
        options[width] = table.get(width, default, positive=True)
    if table.has("elastic_stiffness"):
        options["elastic_stiffness"] = table.get("elastic_stiffness", positive=True)
    for damper in ("damping", "orifice"):
        if table.has(damper):
            options[damper] = table.get(damper, nonnegative=True)
    for stop in ("stroke_limit", "stop_stiffness"):
        if table.has(stop):
            options[stop] = table.get(stop, positive=True)
    if allow_unloading and table.has("unloading"):
        options["unloading"] = _curve(table.get("unloading", kind="table"), allow_unloading=False)
    if kind == "linear":
        build, args = Linear, (table.get("stiffness"), table.get("preload", 0.0))
    elif kind == "piecewise":
        build, args = PiecewiseLinear, (table.get("x", kind="vector"),
                                        table.get("f", kind="vector"))
    elif kind == "crushable":
        build, args = Crushable, (table.get("stiffness", positive=True),
                                  table.get("crush_force", positive=True),
                                  table.get("plateau_slope", 0.0))
    elif kind == "gas":
        build, args = GasSpring, (table.get("pressure", positive=True),
                                  table.get("area", positive=True),
                                  table.get("volume", positive=True),
                                  table.get("exponent", 1.3, positive=True))
    elif kind == "two_sided":   # each side written as the curve it follows in compression
        build, args = TwoSided, tuple(_curve(table.get(side, kind="table"),
                                             allow_unloading=False)
                                      for side in ("compression", "tension"))
    else:                       # a bad type, already reported: its fields are not unknown
        build, args = None, ()
        table.used.update(_CURVE_KEYS)
    table.finish(known=_CURVE_KEYS)
    return _build(table, build, *args, **options)


def _elements(table: Table):
    out = {}
    for name in ("S", "M_beta", "M_gamma"):
        if table.has(name):
            out[name] = _curve(table.get(name, kind="table"))
        else:
            table.used.add(name)
    return out


_LEGS_KEYS = ("scheme", "count", "radius", "height", "length", "e0", "en", "azimuth0",
              "axial_ratio", "law", "footpad", "S", "M_beta", "M_gamma")


def _legs(top: Table) -> list:
    legs = []
    if top.has("legs"):
        t = top.get("legs", kind="table")
        if t is not INVALID and t.get("scheme", "strut", kind="string",
                                      choices=SCHEMES) == "tripod":
            legs.append(_tripods(t))
        elif t is not INVALID:
            els = _elements(t)
            if t.has("axial_ratio"):
                els["axial_ratio"] = t.get("axial_ratio", positive=True)
            args = (t.get("count", kind="int"), t.get("radius", positive=True), t.get("height"),
                    t.get("length", positive=True), t.get("e0", kind="vector", size=3),
                    t.get("en", kind="vector", size=3))
            els["azimuth0"] = t.get("azimuth0", 0.0)
            els["law"] = t.get("law", DEFAULT_LAW, kind="string", choices=LAWS)
            els["footpad"] = t.get("footpad", 0.0, nonnegative=True)
            t.finish(known=_LEGS_KEYS)
            legs.append(_build(t, symmetric_legs, *args, **els))
    if top.has("leg"):
        tables = top.get("leg", kind="tables")
        for t in ([] if tables is INVALID else tables):
            if t.get("scheme", "strut", kind="string", choices=SCHEMES) == "tripod":
                leg = _tripod(t)
                legs.append(leg if leg is INVALID else [leg])
                continue
            els = _elements(t)
            if t.has("axial_ratio"):
                els["axial_ratio"] = t.get("axial_ratio", positive=True)
            els["law"] = t.get("law", DEFAULT_LAW, kind="string", choices=LAWS)
            els["footpad"] = t.get("footpad", 0.0, nonnegative=True)
            args = (t.get("hinge", kind="vector", size=3), t.get("e0", kind="vector", size=3),
                    t.get("en", kind="vector", size=3), t.get("length", positive=True))
            t.finish(known=("scheme", "hinge", "e0", "en", "length", "axial_ratio", "law",
                            "footpad", "S", "M_beta", "M_gamma"))
            leg = _build(t, HingedStrut, *args, **els)
            legs.append(leg if leg is INVALID else [leg])
    top.used.update(("legs", "leg"))
    if not legs:
        return top.fail("no legs; give a `[legs]` table (a symmetric pattern) or `[[leg]]` "
                        "tables (docs/scenes.md).")
    if any(group is INVALID for group in legs):
        return INVALID
    return [leg for group in legs for leg in group]


def _tripods(t: Table):
    """A ``[legs]`` table with ``scheme = "tripod"``: a symmetric set of tripods."""
    curves = {name: _curve(t.get(name, kind="table")) for name in TRIPOD_ELEMENTS}
    args = (t.get("count", kind="int"),)
    args += tuple(t.get(k, kind="vector", size=3) for k in ("h1", "h2", "h3", "foot"))
    args += (t.get("outer_length", positive=True),)
    azimuth0 = t.get("azimuth0", 0.0)
    footpad = t.get("footpad", 0.0, nonnegative=True)
    t.finish(known=("scheme", "count", "h1", "h2", "h3", "foot", "outer_length", "azimuth0",
                    "footpad") + TRIPOD_ELEMENTS)
    if any(c is INVALID for c in curves.values()):
        return INVALID
    return _build(t, symmetric_tripods, *args, azimuth0=azimuth0, footpad=footpad, **curves)


def _tripod(t: Table):
    """An ``[[leg]]`` table with ``scheme = "tripod"``: an inverted-tripod leg."""
    curves = {name: _curve(t.get(name, kind="table")) for name in TRIPOD_ELEMENTS}
    args = tuple(t.get(k, kind="vector", size=3) for k in ("h1", "h2", "h3", "foot"))
    args += (t.get("outer_length", positive=True),)
    footpad = t.get("footpad", 0.0, nonnegative=True)
    t.finish(known=("scheme", "h1", "h2", "h3", "foot", "outer_length", "footpad")
             + TRIPOD_ELEMENTS)
    if any(c is INVALID for c in curves.values()):
        return INVALID
    return _build(t, InvertedTripod, *args, footpad=footpad, **curves)


_OBSTACLES = ("plane", "sphere", "implicit", "terrain")
_OBSTACLE_KEYS = ("type", "point", "normal", "angle", "center", "radius", "phi", "preset",
                  "depth", "rim", "x", "y", "heights")


def _obstacle(t: Table) -> Obstacle:
    kind = t.get("type", kind="string", choices=_OBSTACLES)
    build, args = None, ()
    if kind == "plane":
        point = t.get("point", (0.0, 0.0, 0.0), kind="vector", size=3)
        if t.has("angle"):
            build, args = Plane.inclined, (t.get("angle"), point)
        else:
            build, args = Plane, (point, t.get("normal", (0.0, 0.0, 1.0), kind="vector", size=3))
    elif kind == "sphere":
        build, args = Sphere, (t.get("center", kind="vector", size=3),
                               t.get("radius", positive=True))
    elif kind == "implicit":
        text = t.get("phi", kind="string")
        if text is not INVALID:
            try:
                build, args = ImplicitSurface, (Formula(text, t._where("phi")),)
            except FormulaError as exc:
                t.fail(str(exc))
    elif kind == "terrain":
        build, args = _terrain(t)
    else:                       # a bad type, already reported: its fields are not unknown
        t.used.update(_OBSTACLE_KEYS)
    t.finish(known=_OBSTACLE_KEYS)
    return _build(t, build, *args)


def _terrain(t: Table):
    preset = t.get("preset", "grid", kind="string", choices=("grid", "crater", "slope_with_rocks"))
    if preset == "crater":
        return Terrain.crater, (t.get("radius", 2.0, positive=True), t.get("depth", 0.3),
                                t.get("rim", 0.1))
    if preset == "slope_with_rocks":
        return Terrain.slope_with_rocks, (t.get("angle", 0.1),)
    x, y = t.get("x", kind="vector"), t.get("y", kind="vector")
    heights = t.get("heights", kind="vector")
    if any(v is INVALID for v in (x, y, heights)):
        return None, ()
    if heights.size != x.size * y.size:
        t.fail(f"field `{t._where('heights')}` has {heights.size} values; it needs "
               f"len(x)·len(y) = {x.size}·{y.size} = {x.size * y.size} (row-major: heights at "
               "(x[0], y[0]), (x[0], y[1]), ...).")
        return None, ()
    return Terrain, (x, y, heights.reshape(x.size, y.size))


_SCENE_KEYS = ("name", "mu", "method", "dt", "duration", "gravity", "tangent_plane", "slip",
               "events", "hysteresis")
_BODY_KEYS = ("mass", "inertia", "position", "attitude", "velocity", "angular_velocity")


def _body(top: Table):
    b = top.get("body", kind="table")
    if b is INVALID:
        return INVALID
    inertia = b.get("inertia", kind="vector", size=(3, 9))
    if inertia is not INVALID and inertia.size == 9:
        inertia = inertia.reshape(3, 3)
    fields = dict(mass=b.get("mass", positive=True), inertia=inertia,
                  position=b.get("position", (0.0, 0.0, 0.0), kind="vector", size=3),
                  attitude=b.get("attitude", (1.0, 0.0, 0.0, 0.0), kind="vector", size=4),
                  velocity=b.get("velocity", (0.0, 0.0, 0.0), kind="vector", size=3),
                  angular_velocity=b.get("angular_velocity", (0.0, 0.0, 0.0), kind="vector",
                                         size=3))
    b.finish(known=_BODY_KEYS)
    return _build(b, Body, **fields)


def scene_from_dict(data: dict, source: str = "<dict>") -> Scene:
    """Build a :class:`Scene` from the parsed contents of a scene TOML file.

    Every field is checked before anything is built, and all problems are
    reported together.

    Raises
    ------
    SceneError
        (a ValueError) listing every bad, missing or unknown field with its
        path, its value and the fix.
    """
    problems = Problems(source)
    if not isinstance(data, dict):
        raise SceneError(source, [f"a scene must be a table of tables, got {show(data)}."])
    top = Table(data, "", source, problems)
    s = top.get("scene", kind="table") if top.has("scene") else Table({}, "scene", source,
                                                                       problems)
    top.used.add("scene")
    body = _body(top)
    legs = _legs(top)
    obstacles = top.get("obstacle", kind="tables")
    obstacles = INVALID if obstacles is INVALID else [_obstacle(t) for t in obstacles]
    if s is INVALID:
        settings = INVALID
    else:
        settings = dict(mu=s.get("mu", 0.0, nonnegative=True),
                        method=s.get("method", "implicit", kind="string", choices=METHODS),
                        dt=s.get("dt", 1e-3, positive=True),
                        duration=s.get("duration", 1.0, positive=True),
                        gravity=s.get("gravity", (0.0, 0.0, -9.81), kind="vector", size=3),
                        name=s.get("name", Path(source).stem, kind="string"),
                        tangent_plane=s.get("tangent_plane", "end", kind="string",
                                            choices=TANGENT_PLANES),
                        slip=s.get("slip", "backward", kind="string", choices=SLIP_RULES),
                        events=s.get("events", "none", kind="string", choices=EVENT_RULES),
                        hysteresis=s.get("hysteresis", "sign", kind="string",
                                         choices=HYSTERESIS_LAWS))
        s.finish(known=_SCENE_KEYS)
    top.finish(known=("scene", "body", "legs", "leg", "obstacle"))
    problems.raise_if_any()
    try:
        return Scene(body=body, legs=legs, obstacles=obstacles, **settings)
    except (ValueError, TypeError) as exc:
        raise SceneError(source, [str(exc)]) from None


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
    """Load a scene from a TOML file (format: docs/scenes.md).

    Raises
    ------
    SceneError
        Every problem of the file at once (see :func:`scene_from_dict`).
    FileNotFoundError
        The file does not exist.
    """
    path = validate_path("path", path)
    return scene_from_dict(read_toml(path, "scene"), str(path))
