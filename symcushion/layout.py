"""Layout of the vectors of ``touchdown_step``: named fields of x, y and p.

This module owns the meaning of every entry of the state ``x``, the per-step
output ``y`` and the parameter vector ``p`` of ``touchdown_step(x, p, dt)``:
named fields with their size, unit and meaning, pack/unpack for NumPy
(1-D vectors, or 2-D arrays whose columns are steps) and for CasADi
symbols, and the CSV column names. The quaternion kit the state's attitude needs is
:mod:`symcushion.quaternion`.

It must not build a step, integrate, or know any physics beyond the
rigid-body kinematics of a unit quaternion: every other module reads and
writes these vectors through the names defined here, never through numeric
slices.

Vector order
------------
``x = [body (BODY_STATE), leg 0 (LEG_STATE), leg 1, ...]`` and
``y = [body (BODY_OUT), leg 0 (LEG_OUT), leg 1, ...]``; the fields of each
block are listed in :data:`BODY_STATE_FIELDS`, :data:`LEG_STATE_FIELDS`,
:data:`BODY_OUT_FIELDS` and :data:`LEG_OUT_FIELDS`, in vector order.

CSV columns are named ``{owner}_{field}[_{axis}]_{unit}``: owner ``body`` or
``leg{j}`` (0-based), axis ``x``/``y``/``z`` (``w``/``x``/``y``/``z`` for the
quaternion), unit ``m``, ``m_s``, ``m_s2``, ``rad``, ``rad_s``, ``N`` or
``1`` for a dimensionless entry (e.g. ``body_position_z_m``,
``leg2_force_z_N``, ``leg0_mode_1``).
"""
from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

__all__ = ["Field", "VectorLayout", "BODY_STATE_FIELDS", "LEG_STATE_FIELDS", "BODY_OUT_FIELDS",
           "LEG_OUT_FIELDS", "BODY_STATE", "LEG_STATE", "BODY_OUT", "LEG_OUT", "MODES",
           "UNITS", "SCENE_PARAM_FIELDS", "LEG_GEOMETRY_FIELDS",
           "TRIPOD_GEOMETRY_FIELDS", "FOOTPAD_FIELD", "ParamLayout", "param_layout",
           "has_footpads", "footpads", "default_p", "state_layout", "output_layout", "state_columns",
           "output_columns"]

#: Unit tokens of CSV column names and what each stands for.
UNITS = {"m": "m", "m_s": "m/s", "m_s2": "m/s²", "rad": "rad", "rad_s": "rad/s", "N": "N",
         "1": "dimensionless", "kg": "kg", "kg_m2": "kg·m²", "J": "J"}

_XYZ = ("x", "y", "z")
_WXYZ = ("w", "x", "y", "z")


@dataclass(frozen=True)
class Field:
    """One named entry (scalar or vector) of a state, output or parameter block.

    Attributes
    ----------
    name : str
        Field name, a valid Python identifier (``position``, ``stroke``).
    unit : str
        Unit token of :data:`UNITS` (``m_s2``, ``1``, ...).
    meaning : str
        What the entry is, with its frame.
    axes : tuple of str
        Component names (``("x", "y", "z")``); empty for a scalar.
    default : float, optional
        The value ``pack`` gives the field when it is not passed (None: the
        field is required).
    """

    name: str
    unit: str
    meaning: str
    axes: tuple = ()
    default: float | None = None

    def __post_init__(self):
        if self.unit not in UNITS:
            raise ValueError(f"`unit` must be one of {sorted(UNITS)}, got {self.unit!r}.")

    @property
    def size(self) -> int:
        """Number of entries (1 for a scalar)."""
        return max(len(self.axes), 1)

    def columns(self, owner: str) -> list:
        """CSV column names ``{owner}_{name}[_{axis}]_{unit}`` of this field."""
        if not self.axes:
            return [f"{owner}_{self.name}_{self.unit}"]
        return [f"{owner}_{self.name}_{a}_{self.unit}" for a in self.axes]


#: Body block of the state: 13 entries.
BODY_STATE_FIELDS = (
    Field("position", "m", "centre of mass, world frame", _XYZ),
    Field("velocity", "m_s", "velocity of the centre of mass, world frame", _XYZ),
    Field("attitude", "1", "unit quaternion (w, x, y, z), body → world", _WXYZ),
    Field("angular_velocity", "rad_s", "angular velocity, body axes", _XYZ),
)
#: Leg block of the state: 13 entries per leg.
LEG_STATE_FIELDS = (
    Field("foot", "m", "foot position, world frame (the stored contact point)", _XYZ),
    Field("contact", "1", "1 while the foot is in contact, else 0; with events = 'lock', "
          "2 for a foot whose stroke is locked and 3 for one on the unloading curve "
          "(in contact: contact > 0.5)"),
    Field("force_body", "N", "force on the foot from the obstacle, body axes "
          "(the force of the last step, used by the next half kick)", _XYZ),
    Field("stroke_set", "m", "set of the axial absorber under the memory law: the stroke "
          "at which its elastic line carries no force (symcushion.absorber; 0 for an "
          "element that keeps no set, and under the printed law)", default=0.0),
    Field("stroke_chord", "m_s", "mean stroke rate of the last step, (x₁ − x₀)/Δt, which "
          "the axial dampers' rate (A3) of the next step reads (0 for a free foot, and "
          "under the printed law)", default=0.0),
    Field("element_set", "1", "sets of the leg's other two elements under the memory law: "
          "an inverted tripod's secondaries (m); 0 for a hinged strut, whose hinge springs "
          "keep none", ("2", "3"), default=0.0),
    Field("element_chord", "1", "mean rates of the leg's other two elements over the last "
          "step (a strut's hinge angles β, γ in rad/s; a tripod's secondaries in m/s), which "
          "their dampers' rate (A3) of the next step reads (0 for a free foot, and under the "
          "printed law)", ("2", "3"), default=0.0),
)
#: Body block of the per-step output: 3 entries.
BODY_OUT_FIELDS = (
    Field("acceleration", "m_s2", "acceleration of the centre of mass at the end of "
          "the step, world frame (gravity included)", _XYZ),
)
#: Leg block of the per-step output: 19 entries per leg.
LEG_OUT_FIELDS = (
    Field("in_contact", "1", "1 if the foot is in contact at the end of the step"),
    Field("mode", "1", "contact mode code, see MODES"),
    Field("force", "N", "force on the foot from the obstacle, world frame", _XYZ),
    Field("normal", "1", "unit outward obstacle normal at the contact (0 when free)", _XYZ),
    Field("axis", "1", "unit strut axis e_S from hinge to foot, world frame", _XYZ),
    Field("stroke", "m", "axial stroke δ_S = L − L₀"),
    Field("beta", "rad", "hinge azimuth β"),
    Field("gamma_deflection", "rad", "polar deflection γ − γ₀"),
    Field("secondary_stroke", "m", "deflections of an inverted-tripod leg's two secondary "
          "struts, extension positive (0 for a hinged strut)", ("2", "3")),
    Field("work_axial", "J", "work done on the axial element over the step, "
          "½(S₀ + S₁)(δ_S1 − δ_S0), S = P·e_S (its dampers included): what it absorbs and "
          "stores", default=0.0),
    Field("work_bending", "J", "work done on the hinge springs over the step: the work of "
          "the foot force on the foot's motion relative to the body, ½(P₀ + P₁)·(ρ₁ − ρ₀), "
          "less work_axial", default=0.0),
    Field("work_friction", "J", "energy dissipated by friction at the foot over the step, "
          "−½(P₀ + P₁)·(r₁ − r₀) in the world frame for a foot on the obstacle at the end",
          default=0.0),
)

#: Codes of the leg output ``mode``.
MODES = {0: "free", 1: "stick", 2: "slip", 3: "lift-off"}


def _block_size(fields) -> int:
    return sum(f.size for f in fields)


#: Sizes of the four blocks (public since the first C API; kept as plain ints).
BODY_STATE = _block_size(BODY_STATE_FIELDS)
LEG_STATE = _block_size(LEG_STATE_FIELDS)
BODY_OUT = _block_size(BODY_OUT_FIELDS)
LEG_OUT = _block_size(LEG_OUT_FIELDS)


def _is_casadi(v) -> bool:
    return isinstance(v, (ca.SX, ca.MX, ca.DM))


def _rows(v, start: int, stop: int):
    """Rows start:stop of a vector, or of a 2-D array whose columns are steps."""
    if _is_casadi(v):
        return v[start:stop, :]
    return v[start:stop]


class VectorLayout:
    """A body block followed by one block per leg.

    Parameters
    ----------
    body_fields, leg_fields : tuple of Field
    n_legs : int
        Number of legs (≥ 0).
    name : str
        ``"state"`` or ``"output"``, used in messages.
    """

    def __init__(self, body_fields, leg_fields, n_legs: int, name: str):
        if isinstance(n_legs, bool) or not isinstance(n_legs, (int, np.integer)) or n_legs < 0:
            raise ValueError(f"`n_legs` must be a non-negative integer, got {n_legs!r}.")
        self.body_fields, self.leg_fields = tuple(body_fields), tuple(leg_fields)
        self.n_legs, self.name = int(n_legs), name
        self.body_size, self.leg_size = _block_size(body_fields), _block_size(leg_fields)
        self.size = self.body_size + self.leg_size * self.n_legs
        self._body_at, self._leg_at = self._offsets(body_fields), self._offsets(leg_fields)

    @staticmethod
    def _offsets(fields) -> dict:
        at, start = {}, 0
        for f in fields:
            at[f.name] = (start, f)
            start += f.size
        return at

    # -- indices --------------------------------------------------------------
    def slice(self, field: str, leg: int | None = None) -> slice:
        """Index range of ``field`` of the body (``leg=None``) or of leg ``leg``."""
        if leg is None:
            if field not in self._body_at:
                raise KeyError(f"the body {self.name} has no field {field!r}; fields: "
                               f"{[f.name for f in self.body_fields]}.")
            start, f = self._body_at[field]
            return slice(start, start + f.size)
        if field not in self._leg_at:
            raise KeyError(f"a leg's {self.name} has no field {field!r}; fields: "
                           f"{[f.name for f in self.leg_fields]}.")
        if isinstance(leg, bool) or not isinstance(leg, (int, np.integer)) \
                or not 0 <= leg < self.n_legs:
            raise IndexError(f"`leg` must be an integer in [0, {self.n_legs}), got {leg!r}.")
        start, f = self._leg_at[field]
        start += self.body_size + self.leg_size * int(leg)
        return slice(start, start + f.size)

    def index(self, field: str, leg: int | None = None) -> int:
        """Index of a scalar field (``contact``, ``mode``, ``stroke``, ...)."""
        s = self.slice(field, leg)
        if s.stop - s.start != 1:
            raise ValueError(f"`{field}` has {s.stop - s.start} entries; use `slice`.")
        return s.start

    def leg_block(self, leg: int) -> slice:
        """Index range of the whole block of leg ``leg``."""
        first = self.leg_fields[0].name
        start = self.slice(first, leg).start
        return slice(start, start + self.leg_size)

    # -- reading ----------------------------------------------------------------
    def get(self, v, field: str, leg: int | None = None):
        """Rows of ``field`` in ``v`` (NumPy 1-D/2-D, or CasADi SX/MX/DM).

        For a 2-D ``v`` (columns are steps) the result keeps the columns. A
        scalar field of a 1-D NumPy vector is returned as a float-like 0-d
        entry, of a 2-D array as a row of shape (T,).
        """
        self._check(v)
        s = self.slice(field, leg)
        if not _is_casadi(v) and s.stop - s.start == 1:
            return v[s.start]
        return _rows(v, s.start, s.stop)

    def legs(self, v, field: str):
        """``field`` of every leg: NumPy array (n_legs, size[, T]) or a list for CasADi.

        Scalar fields lose their size axis: (n_legs,) or (n_legs, T).
        """
        parts = [self.get(v, field, j) for j in range(self.n_legs)]
        if _is_casadi(v):
            return parts
        v = np.asarray(v)
        size = self._leg_at[field][1].size
        tail = (size,) if size > 1 else ()
        tail += v.shape[1:]
        return np.array(parts).reshape((self.n_legs,) + tail)

    def unpack(self, v) -> dict:
        """Every field by name: body fields as ``get`` gives them, leg fields as ``legs``."""
        out = {f.name: self.get(v, f.name) for f in self.body_fields}
        out.update({f.name: self.legs(v, f.name) for f in self.leg_fields})
        return out

    # -- writing ----------------------------------------------------------------
    def pack(self, **fields):
        """Assemble a vector from named fields (every field required).

        Body fields are given as vectors of their size; leg fields as a
        sequence over the legs (or a NumPy array (n_legs, size)); a field with
        a ``default`` may be left out. If any
        value is a CasADi symbol the result is ``ca.vertcat`` of the parts,
        else a NumPy float vector of shape (size,).
        """
        fields = self._with_defaults(fields)
        expected = [f.name for f in self.body_fields] + [f.name for f in self.leg_fields]
        missing = [n for n in expected if n not in fields]
        extra = [n for n in fields if n not in expected]
        if missing or extra:
            raise ValueError(f"`pack` of the {self.name} needs exactly the fields {expected}; "
                             f"missing {missing}, unknown {extra}.")
        parts = [fields[f.name] for f in self.body_fields]
        for j in range(self.n_legs):
            parts += [fields[f.name][j] for f in self.leg_fields]
        if any(_is_casadi(p) for p in parts):
            return ca.vertcat(*[ca.vec(ca.DM(p) if not _is_casadi(p) else p) for p in parts])
        out = np.concatenate([np.ravel(np.asarray(p, dtype=float)) for p in parts])
        if out.shape != (self.size,):
            raise ValueError(f"the packed {self.name} has {out.size} entries, expected "
                             f"{self.size}; check the sizes of the fields.")
        return out

    def pack_columns(self, n: int, **fields) -> np.ndarray:
        """Assemble ``n`` vectors as the columns of an array (size, n), NumPy.

        Each field is given as (field size, n) (a scalar field as (n,));
        leg fields as a sequence over the legs of such arrays.
        """
        fields = self._with_defaults(fields, n)
        expected = [f.name for f in self.body_fields] + [f.name for f in self.leg_fields]
        if sorted(fields) != sorted(expected):
            raise ValueError(f"`pack_columns` of the {self.name} needs exactly the fields "
                             f"{expected}, got {sorted(fields)}.")
        parts = [(f, fields[f.name]) for f in self.body_fields]
        for j in range(self.n_legs):
            parts += [(f, fields[f.name][j]) for f in self.leg_fields]
        rows = []
        for f, value in parts:
            value = np.asarray(value, dtype=float)
            if value.size != f.size * n:
                raise ValueError(f"`{f.name}` must have shape ({f.size}, {n}), got "
                                 f"{value.shape}.")
            rows.append(value.reshape(f.size, n))
        return np.vstack(rows) if rows else np.zeros((0, n))

    def _with_defaults(self, fields: dict, n: int | None = None) -> dict:
        """``fields`` with every left-out field that has a default filled in
        (``n`` columns of it for ``pack_columns``)."""
        out = dict(fields)
        for f in self.body_fields + self.leg_fields:
            if f.name in out or f.default is None:
                continue
            value = np.full((f.size,) if n is None else (f.size, n), f.default)
            out[f.name] = value if f in self.body_fields else [value] * self.n_legs
        return out

    def columns(self) -> list:
        """CSV column names in vector order."""
        cols = [c for f in self.body_fields for c in f.columns("body")]
        for j in range(self.n_legs):
            cols += [c for f in self.leg_fields for c in f.columns(f"leg{j}")]
        return cols

    def _check(self, v):
        rows = v.shape[0] if hasattr(v, "shape") else len(v)
        if rows != self.size:
            raise ValueError(f"the {self.name} vector must have {self.size} rows "
                             f"({self.n_legs} legs), got {rows}.")


def state_layout(n_legs: int) -> VectorLayout:
    """Layout of the state ``x`` of a scene with ``n_legs`` legs."""
    return VectorLayout(BODY_STATE_FIELDS, LEG_STATE_FIELDS, n_legs, "state")


def output_layout(n_legs: int) -> VectorLayout:
    """Layout of the per-step output ``y`` of a scene with ``n_legs`` legs."""
    return VectorLayout(BODY_OUT_FIELDS, LEG_OUT_FIELDS, n_legs, "output")


def state_columns(n_legs: int) -> list:
    """CSV column names of the state, in vector order (``body_position_x_m``, ...)."""
    return state_layout(n_legs).columns()


def output_columns(n_legs: int) -> list:
    """CSV column names of the per-step output, in vector order."""
    return output_layout(n_legs).columns()


# ---------------------------------------------------------------------------
# the parameter vector p
# ---------------------------------------------------------------------------
#: Scene entries of ``p``, after the legs' parameters. ``mu`` is present only
#: when the scene has friction (μ > 0): a frictionless scene builds the
#: smaller graph without friction paths and has no μ to vary.
SCENE_PARAM_FIELDS = (
    Field("mu", "1", "Coulomb friction coefficient of every contact (friction scenes only)"),
    Field("gravity", "m_s2", "acceleration of gravity, world frame", _XYZ),
    Field("mass", "kg", "body mass"),
    Field("inertia", "kg_m2", "body inertia about the centre of mass, body axes "
          "(xx, yy, zz, xy, xz, yz of the symmetric tensor)", ("xx", "yy", "zz", "xy", "xz", "yz")),
)
#: Geometry entries of ``p``, one block per leg after the scene entries, in the
#: order the strut's Functions take them (``HingedStrut.geometry_values``).
LEG_GEOMETRY_FIELDS = (
    Field("hinge", "m", "hinge position r_h, body axes", _XYZ),
    Field("e0", "1", "rest direction e₀ of the strut, body axes (normalised in the step)",
          _XYZ),
    Field("en", "1", "polar axis e_n of the hinge, body axes (normalised in the step; "
          "sign(e₀·e_n) must stay the built scene's)", _XYZ),
    Field("length", "m", "rest length L₀ of the strut"),
)
#: Geometry entries of an inverted-tripod leg's block (``InvertedTripod.geometry_values``).
TRIPOD_GEOMETRY_FIELDS = (
    Field("h1", "m", "the primary's joint h₁, body axes", _XYZ),
    Field("h2", "m", "hardpoint h₂ of the first secondary, body axes", _XYZ),
    Field("h3", "m", "hardpoint h₃ of the second secondary, body axes", _XYZ),
    Field("foot", "m", "the foot at rest, body axes (sets the rest lengths)", _XYZ),
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
        return _rows(p, s.start, s.stop)

    def leg_geometry(self, p, j: int):
        """Rows of leg ``j``'s geometry block in ``p`` (a strut's hinge, e0, en, length;
        a tripod's h1, h2, h3, foot, outer_length)."""
        fields = self.geometry_fields[j]
        s = self.slice(f"leg{j}.{fields[0].name}")
        return _rows(p, s.start, s.start + _block_size(fields))

    def footpad(self, p, j: int):
        """Leg ``j``'s footpad radius in ``p`` (m; a float of a 1-D NumPy ``p``)."""
        return self.get(p, f"leg{j}.{FOOTPAD_FIELD.name}")

    def leg_inputs(self, p, j: int):
        """The ``p`` of leg ``j``'s strut Functions: its curve parameters, then (with
        ``geometry``) its geometry block (NumPy or CasADi)."""
        curve = self.leg(p, j)
        if not self.geometry:
            return curve
        if _is_casadi(p):
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
        if not _is_casadi(p) and s.stop - s.start == 1:
            return p[s.start]
        return _rows(p, s.start, s.stop)

    def inertia(self, p):
        """Inertia tensor (3 × 3, kg·m²) from a 1-D ``p`` (NumPy or CasADi)."""
        entries = self.get(p, "inertia")
        if _is_casadi(p):
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
