"""Named fields of a vector and their pack/unpack: the machinery behind every layout.

This module owns :class:`Field` (a named entry with its size, unit, meaning
and axes), the unit tokens of CSV column names (:data:`UNITS`), the axis
names :data:`XYZ` and :data:`WXYZ`, and :class:`VectorLayout` (a body block
followed by one block per leg: offsets, pack/unpack for NumPy and CasADi,
CSV columns), with the small helpers the parameter layout shares
(:func:`block_size`, :func:`is_casadi`, :func:`take_rows`). It must not name
the fields of any particular vector (``symcushion.layout.vectors`` names those of x
and y, ``symcushion.layout.params`` those of p) nor know any physics.
"""
from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

__all__ = ["Field", "VectorLayout", "UNITS", "XYZ", "WXYZ", "block_size", "is_casadi",
           "take_rows"]


#: Unit tokens of CSV column names and what each stands for.
UNITS = {"m": "m", "m_s": "m/s", "m_s2": "m/s²", "rad": "rad", "rad_s": "rad/s", "N": "N",
         "1": "dimensionless", "kg": "kg", "kg_m2": "kg·m²", "J": "J"}

XYZ = ("x", "y", "z")
WXYZ = ("w", "x", "y", "z")


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


def block_size(fields) -> int:
    """Number of entries of a block of fields."""
    return sum(f.size for f in fields)


def is_casadi(v) -> bool:
    """True for a CasADi SX, MX or DM (rows are taken as ``v[start:stop, :]``)."""
    return isinstance(v, (ca.SX, ca.MX, ca.DM))


def take_rows(v, start: int, stop: int):
    """Rows start:stop of a vector, or of a 2-D array whose columns are steps."""
    if is_casadi(v):
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
        self.body_size, self.leg_size = block_size(body_fields), block_size(leg_fields)
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
        if not is_casadi(v) and s.stop - s.start == 1:
            return v[s.start]
        return take_rows(v, s.start, s.stop)

    def legs(self, v, field: str):
        """``field`` of every leg: NumPy array (n_legs, size[, T]) or a list for CasADi.

        Scalar fields lose their size axis: (n_legs,) or (n_legs, T).
        """
        parts = [self.get(v, field, j) for j in range(self.n_legs)]
        if is_casadi(v):
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
        if any(is_casadi(p) for p in parts):
            return ca.vertcat(*[ca.vec(ca.DM(p) if not is_casadi(p) else p) for p in parts])
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
