"""Layout of the parameter vector ``p`` of ``touchdown_step(x, p, dt)``.

``p = [leg 0 params, leg 1 params, ..., (mu), gravity (3), mass, inertia (6),
(leg 0 geometry, leg 1 geometry, ..., (leg 0 footpad, leg 1 footpad, ...))]``:
the legs' tunable curve parameters, the scene entries, then (with
``geometry``) every leg's geometry and footpads.

This module owns the fields of p (:data:`SCENE_PARAM_FIELDS`,
:data:`LEG_GEOMETRY_FIELDS`, :data:`TRIPOD_GEOMETRY_FIELDS`,
:data:`FOOTPAD_FIELD`), :class:`ParamLayout`, :func:`param_layout` and
:func:`default_p`, all re-exported by ``symcushion.layout.vectors``. It must not
build a step or know the physics the entries feed; the state and output
vectors are ``symcushion.layout.vectors``'s.
"""
from __future__ import annotations

import casadi as ca
import numpy as np

from symcushion.layout.fields import XYZ, Field, block_size, is_casadi, take_rows

__all__ = ["SCENE_PARAM_FIELDS", "LEG_GEOMETRY_FIELDS", "TRIPOD_GEOMETRY_FIELDS",
           "FOOTPAD_FIELD", "ParamLayout", "param_layout", "has_footpads", "footpads",
           "default_p"]

#: Scene entries of ``p``, after the legs' parameters. ``mu`` is present only
#: when the scene has friction (μ > 0): a frictionless scene builds the
#: smaller graph without friction paths and has no μ to vary.
SCENE_PARAM_FIELDS = (
    Field("mu", "1", "Coulomb friction coefficient of every contact (friction scenes only)"),
    Field("gravity", "m_s2", "acceleration of gravity, world frame", XYZ),
    Field("mass", "kg", "body mass"),
    Field("inertia", "kg_m2", "body inertia about the centre of mass, body axes "
          "(xx, yy, zz, xy, xz, yz of the symmetric tensor)", ("xx", "yy", "zz", "xy", "xz", "yz")),
)
#: Geometry entries of ``p``, one block per leg after the scene entries, in the
#: order the strut's Functions take them (``HingedStrut.geometry_values``).
LEG_GEOMETRY_FIELDS = (
    Field("hinge", "m", "hinge position r_h, body axes", XYZ),
    Field("e0", "1", "rest direction e₀ of the strut, body axes (normalised in the step)",
          XYZ),
    Field("en", "1", "polar axis e_n of the hinge, body axes (normalised in the step; "
          "sign(e₀·e_n) must stay the built scene's)", XYZ),
    Field("length", "m", "rest length L₀ of the strut"),
)
#: Geometry entries of an inverted-tripod leg's block (``InvertedTripod.geometry_values``).
TRIPOD_GEOMETRY_FIELDS = (
    Field("h1", "m", "the primary's joint h₁, body axes", XYZ),
    Field("h2", "m", "hardpoint h₂ of the first secondary, body axes", XYZ),
    Field("h3", "m", "hardpoint h₃ of the second secondary, body axes", XYZ),
    Field("foot", "m", "the foot at rest, body axes (sets the rest lengths)", XYZ),
    Field("outer_length", "m", "from h₁ to the secondaries' pin Q on the primary"),
)
#: The footpad entry of ``p``, one per leg after the geometry blocks, present in a
#: scene where some leg has a pad (a scene of point feet builds the graph without
#: pad terms and has no entry to vary, as a frictionless scene has no μ).
FOOTPAD_FIELD = Field("footpad", "m", "footpad radius a: the foot is the pad's centre, on "
                      "the obstacle's surface offset by a (0: a point foot)")
#: Where each entry of the inertia field goes in the 3 × 3 tensor.
_INERTIA_ENTRIES = ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2))


class ParamLayout:
    """Layout of ``p``: every leg's tunable curve parameters, the scene entries, then
    (with ``geometry``) every leg's geometry.

    ``p = [leg 0 params, leg 1 params, ..., (mu), gravity (3), mass, inertia (6),
    (leg 0 geometry (10), leg 1 geometry, ..., (leg 0 footpad, leg 1 footpad, ...))]``;
    names are ``leg{j}.{element}.{name}`` for the legs' curve parameters, ``mu``,
    ``gravity.x``, ``mass``, ``inertia.xx``, ... for the scene, and
    ``leg{j}.hinge.x``, ``leg{j}.e0.x``, ``leg{j}.en.x``, ``leg{j}.length`` for
    the geometry (:data:`LEG_GEOMETRY_FIELDS`), then ``leg{j}.footpad``
    (:data:`FOOTPAD_FIELD`). The geometry comes last, and the footpads after
    it, so that the entries before them keep the indices they had without them.

    Parameters
    ----------
    leg_param_names : sequence of tuple of str
        Each leg's ``param_names`` (possibly empty).
    friction : bool
        Whether ``mu`` is an entry.
    geometry : bool
        Whether the legs' geometry are entries (default False).
    geometry_fields : sequence of tuple of Field, optional
        Each leg's geometry block (its scheme's ``geometry_fields``); default
        :data:`LEG_GEOMETRY_FIELDS` for every leg.
    footpads : bool
        Whether every leg's footpad radius is an entry (default False; only
        with ``geometry``).
    """

    def __init__(self, leg_param_names, friction: bool, geometry: bool = False,
                 geometry_fields=None, footpads: bool = False):
        self.friction = bool(friction)
        self.geometry = bool(geometry)
        self.footpads = bool(footpads) and self.geometry
        leg_param_names = list(leg_param_names)
        self.geometry_fields = (tuple(geometry_fields) if geometry_fields is not None
                                else (LEG_GEOMETRY_FIELDS,) * len(leg_param_names))
        names, self._legs, start = [], [], 0
        for j, leg_names in enumerate(leg_param_names):
            names += [f"leg{j}.{n}" for n in leg_names]
            self._legs.append(slice(start, start + len(leg_names)))
            start += len(leg_names)
        self.n_leg_params = start
        self.scene_fields = tuple(f for f in SCENE_PARAM_FIELDS if f.name != "mu" or friction)
        self._scene = {}
        for f in self.scene_fields:
            self._scene[f.name] = slice(start, start + f.size)
            names += [f.name] if not f.axes else [f"{f.name}.{a}" for a in f.axes]
            start += f.size
        self._geometry = {}                 # "leg{j}.{field}" -> slice
        for j in range(len(self._legs) if self.geometry else 0):
            for f in self.geometry_fields[j]:
                key = f"leg{j}.{f.name}"
                self._geometry[key] = slice(start, start + f.size)
                names += [key] if not f.axes else [f"{key}.{a}" for a in f.axes]
                start += f.size
        for j in range(len(self._legs) if self.footpads else 0):
            key = f"leg{j}.{FOOTPAD_FIELD.name}"
            self._geometry[key] = slice(start, start + 1)
            names.append(key)
            start += 1
        self.names, self.size = tuple(names), start

    def leg(self, p, j: int):
        """Rows of leg ``j``'s curve parameters in ``p`` (NumPy or CasADi)."""
        s = self._legs[j]
        return take_rows(p, s.start, s.stop)

    def leg_geometry(self, p, j: int):
        """Rows of leg ``j``'s geometry block in ``p`` (a strut's hinge, e0, en, length;
        a tripod's h1, h2, h3, foot, outer_length)."""
        fields = self.geometry_fields[j]
        s = self.slice(f"leg{j}.{fields[0].name}")
        return take_rows(p, s.start, s.start + block_size(fields))

    def footpad(self, p, j: int):
        """Leg ``j``'s footpad radius in ``p`` (m; a float of a 1-D NumPy ``p``)."""
        return self.get(p, f"leg{j}.{FOOTPAD_FIELD.name}")

    def leg_inputs(self, p, j: int):
        """The ``p`` of leg ``j``'s strut Functions: its curve parameters, then (with
        ``geometry``) its geometry block (NumPy or CasADi)."""
        curve = self.leg(p, j)
        if not self.geometry:
            return curve
        if is_casadi(p):
            return ca.vertcat(curve, self.leg_geometry(p, j))
        return np.concatenate([curve, self.leg_geometry(p, j)])

    def slice(self, field: str) -> slice:
        """Index range of a scene field (``mu``, ``gravity``, ``mass``, ``inertia``) or of a
        leg's geometry field (``leg0.hinge``, ``leg0.e0``, ``leg0.en``, ``leg0.length``,
        ``leg0.footpad``)."""
        if field in self._geometry:
            return self._geometry[field]
        if field not in self._scene:
            extra = " (the scene is frictionless: μ = 0 builds no friction paths; give the " \
                "scene a μ > 0 to vary it)" if field == "mu" else ""
            if field.startswith("leg") and not self.geometry:
                extra = " (this model bakes the legs' geometry in: build it with geometry " \
                    "= 'input' to vary it)"
            elif field.endswith(f".{FOOTPAD_FIELD.name}"):
                extra = " (the scene's feet are points: a scene without pads builds no pad " \
                    "terms; give a leg a `footpad` > 0 to vary it)"
            raise KeyError(f"`p` has no field {field!r}{extra}; fields: "
                           f"{list(self._scene) + list(self._geometry)}.")
        return self._scene[field]

    def get(self, p, field: str):
        """Rows of a scene field in ``p``; scalars of a 1-D NumPy ``p`` as floats."""
        s = self.slice(field)
        if not is_casadi(p) and s.stop - s.start == 1:
            return p[s.start]
        return take_rows(p, s.start, s.stop)

    def inertia(self, p):
        """Inertia tensor (3 × 3, kg·m²) from a 1-D ``p`` (NumPy or CasADi)."""
        entries = self.get(p, "inertia")
        if is_casadi(p):
            rows = [[None] * 3 for _ in range(3)]
            for k, (a, b) in enumerate(_INERTIA_ENTRIES):
                rows[a][b] = rows[b][a] = entries[k]
            return ca.vertcat(*[ca.horzcat(*r) for r in rows])
        out = np.zeros((3, 3))
        for k, (a, b) in enumerate(_INERTIA_ENTRIES):
            out[a, b] = out[b, a] = entries[k]
        return out

    def pack(self, base, **overrides) -> np.ndarray:
        """A copy of ``base`` (shape (size,)) with named scene entries replaced.

        ``overrides`` take the scene fields (``mu=0.4``, ``gravity=(0, 0, -1.62)``,
        ``mass=…``, ``inertia=`` a 3 × 3 symmetric tensor) and, with ``geometry``,
        the legs' geometry fields by name (``**{"leg0.hinge": (0.5, 0, -0.2),
        "leg0.length": 0.9}``); leg curve parameters are set by name through
        :meth:`index`. Only sizes and finiteness are checked here; whether a
        geometry suits the strut is the strut's to say (``HingedStrut.check_geometry``).
        """
        p = np.array(base, dtype=float).ravel()
        if p.shape != (self.size,):
            raise ValueError(f"`base` must have {self.size} entries {self.names}, got {p.shape}.")
        for name, value in overrides.items():
            s = self.slice(name)
            value = np.asarray(value, dtype=float)
            if name == "inertia":
                if value.shape != (3, 3) or not np.allclose(value, value.T):
                    raise ValueError(f"`inertia` must be a symmetric 3 × 3 tensor (kg·m²), got "
                                     f"{value.tolist()}.")
                value = np.array([value[a, b] for a, b in _INERTIA_ENTRIES])
            if value.size != s.stop - s.start or not np.all(np.isfinite(value)):
                raise ValueError(f"`{name}` must be {s.stop - s.start} finite number(s), got "
                                 f"{value.tolist()}.")
            p[s] = value.ravel()
        return p

    def index(self, name: str) -> int:
        """Index of the entry called ``name`` (e.g. ``'leg0.S.k'`` or ``'gravity.z'``)."""
        try:
            return self.names.index(name)
        except ValueError:
            raise KeyError(f"`p` has no entry {name!r}; entries: {list(self.names)}.") from None


def has_footpads(scene) -> bool:
    """True if some leg of ``scene`` has a footpad (radius > 0)."""
    return any(leg.footpad > 0 for leg in scene.legs)


def footpads(scene, lay: ParamLayout, p) -> list:
    """Each leg's footpad radius (m): its entry of ``p`` where ``lay`` has one, else the
    leg's own (a Python float, 0.0 for a point foot, whose expressions then carry no
    pad term)."""
    if lay.footpads:
        return [lay.footpad(p, j) for j in range(len(scene.legs))]
    return [leg.footpad for leg in scene.legs]


def param_layout(scene, geometry: bool = True) -> ParamLayout:
    """The :class:`ParamLayout` of a scene (μ an entry only when ``scene.mu > 0``; the
    legs' geometry entries unless ``geometry`` is False, and their footpads when some
    leg has one)."""
    return ParamLayout([leg.param_names for leg in scene.legs], scene.mu > 0, geometry,
                       [leg.geometry_fields for leg in scene.legs], has_footpads(scene))


def default_p(scene, geometry: bool = True) -> np.ndarray:
    """The scene's own values of ``p``: curve parameters, (μ), gravity, mass, inertia and
    (unless ``geometry`` is False) the legs' geometry."""
    lay = param_layout(scene, geometry)
    legs = [np.asarray(leg.param_values, dtype=float) for leg in scene.legs]
    base = np.concatenate(legs + [np.zeros(lay.size - lay.n_leg_params)])
    overrides = dict(gravity=scene.gravity, mass=scene.body.mass, inertia=scene.body.inertia)
    if lay.friction:
        overrides["mu"] = scene.mu
    if lay.geometry:
        for j, leg in enumerate(scene.legs):
            values = np.asarray(leg.geometry_values, dtype=float)
            start = 0
            for f in leg.geometry_fields:
                block = values[start:start + f.size]
                overrides[f"leg{j}.{f.name}"] = block if f.axes else float(block[0])
                start += f.size
    if lay.footpads:
        for j, leg in enumerate(scene.legs):
            overrides[f"leg{j}.{FOOTPAD_FIELD.name}"] = leg.footpad
    return lay.pack(base, **overrides)
