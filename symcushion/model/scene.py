"""Touchdown scenes from TOML: the reader and checker of scene files.

A scene (``symcushion.model.scene_data``: :class:`Scene`, :class:`Body`,
:func:`symmetric_legs`, re-exported here) is built from Python or loaded
from TOML (:func:`load_scene`); every field of a TOML file is checked and an
invalid one is reported with its path, its value and what is allowed.

This module owns the reading: :func:`read_toml`, :func:`scene_from_dict`,
:func:`load_scene` and the tables of keys, curve types and obstacle types;
it is where users import scenes from. It must not define what a scene is
(``symcushion.model.scene_data``) nor how it is integrated (``symcushion.run.driver``).
"""
from __future__ import annotations

import copy
import dataclasses
import sys
from pathlib import Path

from symcushion.legs.absorber import DEFAULT_DAMPING_RATIO, default_damping_time, elastic_stiffness
from symcushion.legs.characteristics import Crushable, GasSpring, Linear, PiecewiseLinear, TwoSided
from symcushion.legs.curve_base import KINK_WIDTH, RATE_WIDTH, Curve
from symcushion.contact.args import METHODS  # re-exported: scenes name their contact step
from symcushion.model.obstacles import ImplicitSurface, Obstacle, Plane, Sphere, Terrain
from symcushion.legs.strut import DEFAULT_LAW, LAWS, HingedStrut
from symcushion.legs.tripod import ELEMENTS as TRIPOD_ELEMENTS
from symcushion.legs.tripod import InvertedTripod
from symcushion.model.formula import Formula, FormulaError
# the scene's data, re-exported: users import scenes from here
from symcushion.model.scene_data import (EVENT_RULES, HYSTERESIS_LAWS, SCHEMES, SLIP_RULES,
    TANGENT_PLANES, Body, Scene, symmetric_legs, symmetric_tripods)
from symcushion.validation import INVALID, Problems, SceneError, Table, show
from symcushion.validation import path as validate_path

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

__all__ = ["Body", "Scene", "SceneError", "symmetric_legs", "load_scene", "scene_from_dict",
           "METHODS"]


# ---------------------------------------------------------------------------
# TOML
# ---------------------------------------------------------------------------
_CURVES = ("linear", "piecewise", "crushable", "gas", "two_sided")
#: Every key of an element table, for "did you mean" on a misspelt one.
_CURVE_KEYS = ("type", "smooth", "tunable", "unloading", "stiffness", "preload", "x", "f",
               "crush_force", "plateau_slope", "kink_width", "rate_width",
               "elastic_stiffness", "damping", "orifice", "stroke_limit", "stop_stiffness",
               "pressure", "area", "volume", "exponent", "compression", "tension")


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
               "events", "hysteresis", "damping_ratio")
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


def _settings(s: Table, name: str) -> dict:
    """The [scene] table's settings. A file's scheme defaults to the second-order
    one of docs/scenes.md ("Defaults"): the midpoint slip rule on the implicit step,
    and the memory law (with DEFAULT_DAMPING_RATIO) where no event rule is named."""
    method = s.get("method", "implicit", kind="string", choices=METHODS)
    events = s.get("events", "none", kind="string", choices=EVENT_RULES)
    hysteresis = s.get("hysteresis", "memory" if events == "none" else "sign",
                       kind="string", choices=HYSTERESIS_LAWS)
    if s.has("damping_ratio") and hysteresis != "memory":
        s.fail("`scene.damping_ratio` gives dampers to the memory law's elements, and "
               f"`hysteresis` is {hysteresis!r}; set hysteresis = \"memory\" or remove "
               "`damping_ratio`.")
    return dict(mu=s.get("mu", 0.0, nonnegative=True), method=method,
                dt=s.get("dt", 1e-3, positive=True),
                duration=s.get("duration", 1.0, positive=True),
                gravity=s.get("gravity", (0.0, 0.0, -9.81), kind="vector", size=3),
                name=s.get("name", name, kind="string"),
                tangent_plane=s.get("tangent_plane", "end", kind="string",
                                    choices=TANGENT_PLANES),
                slip=s.get("slip", "midpoint" if method == "implicit" else "backward",
                           kind="string", choices=SLIP_RULES),
                events=events, hysteresis=hysteresis,
                damping_ratio=s.get("damping_ratio", DEFAULT_DAMPING_RATIO, nonnegative=True))


def _damped_by_default(leg, mass_share: float, ratio: float):
    """``leg`` with a viscous damper of one damping time τ (``default_damping_time`` of
    its axial element) on every element, c = τ k_e, unless an element names a damper."""
    if any(el.curve.has_damper for el in leg.elements):
        return leg
    tau = default_damping_time(leg.elements[0].curve, mass_share, ratio)
    damped = []
    for el in leg.elements:
        curve = copy.copy(el.curve)
        curve.damping = tau * float(elastic_stiffness(curve))
        damped.append(dataclasses.replace(el, curve=curve))
    leg.elements = tuple(damped)
    return leg


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
        settings = _settings(s, Path(source).stem)
        s.finish(known=_SCENE_KEYS)
    top.finish(known=("scene", "body", "legs", "leg", "obstacle"))
    problems.raise_if_any()
    ratio = settings.pop("damping_ratio")
    if settings["hysteresis"] == "memory" and ratio > 0 and legs:
        legs = [_damped_by_default(leg, body.mass / len(legs), ratio) for leg in legs]
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
