"""Argument and file-field validation shared by the whole package.

This module owns the checks of *values given by a user*: Python arguments
(:func:`real`, :func:`vector`, :func:`choice`, :func:`boolean`, :func:`path`)
and the fields of TOML tables (:class:`Table`), with messages that name the
argument in backticks, show the bad value and say the fix. A file's problems
are collected and raised together as one :class:`SceneError`.

It knows nothing of physics: whether a valid scene makes physical sense
(feet inside an obstacle, a step above the stable limit) is
``symcushion.run.checks``'s business.
"""
from __future__ import annotations

import difflib
import math
import os
import re
from pathlib import Path

import numpy as np

__all__ = ["SceneError", "Problems", "Table", "INVALID", "ANGLE_FIELDS", "real", "integer", "vector",
           "direction", "choice", "boolean", "path", "did_you_mean", "show"]

#: Longest repr of a bad value quoted in a message (characters); a 10⁶-entry
#: list must not flood the terminal.
SHOW_CHARS = 80

#: Closest spellings offered for an unknown key or choice, and how close
#: (difflib ratio) a candidate must be to be offered at all: 0.6 is difflib's
#: default, which catches one or two wrong letters in a short key.
SUGGESTIONS = 1
SUGGESTION_CUTOFF = 0.6

#: The angle fields of scene and study files, by table path (list indices
#: left out) and key, with the largest magnitude plausible in radians and
#: why. Each is radians as ``key`` and degrees as ``key_deg`` (both at once is
#: an error). A radian value beyond its bound is an error that suggests the
#: degree field: ``angle = 12.0`` is far more likely 12° typed into a radian
#: field than 12 rad (687.5°, which a plane would take as a 32.5° slope).
ANGLE_FIELDS = {
    "obstacle.angle": (math.pi / 2, "a slope of at most 90°"),
    "legs.azimuth0": (2 * math.pi, "at most one turn, 360°"),
    "limits.beta": (math.pi / 2, "a hinge deflection of at most 90°"),
    "limits.gamma": (math.pi / 2, "a hinge deflection of at most 90°"),
    "limits.tilt": (math.pi / 2, "a tilt of at most 90°"),
}


class SceneError(ValueError):
    """Every problem of a scene (or study) file, raised at once.

    Attributes
    ----------
    source : str
        The file (or ``"<dict>"``).
    problems : list of str
        One message per problem, each naming the field, its value and the fix.
    """

    def __init__(self, source: str, problems):
        self.source = str(source)
        self.problems = list(problems)
        if len(self.problems) == 1:
            text = f"{self.source}: {self.problems[0]}"
        else:
            text = f"{self.source}: {len(self.problems)} problems:\n" + "\n".join(
                f"  - {p}" for p in self.problems)
        super().__init__(text)


def show(value) -> str:
    """A short repr of ``value`` for an error message."""
    text = repr(value.tolist() if isinstance(value, np.ndarray) else value)
    return text if len(text) <= SHOW_CHARS else text[:SHOW_CHARS - 5] + " ...)"


def did_you_mean(word, options) -> str:
    """``" (did you mean 'x'?)"`` for the closest of ``options``, or ``""``."""
    if not isinstance(word, str):
        return ""
    close = difflib.get_close_matches(word, [str(o) for o in options], n=SUGGESTIONS,
                                      cutoff=SUGGESTION_CUTOFF)
    return f" (did you mean {close[0]!r}?)" if close else ""


def _is_real(value) -> bool:
    """True for Python and NumPy real scalars (``np.float32(0.3)`` is a real), not bools."""
    if isinstance(value, (bool, np.bool_)):
        return False
    return isinstance(value, (int, float, np.integer, np.floating))


def real(name: str, value, *, positive=False, nonnegative=False, finite=True,
         unit: str = "") -> float:
    """``value`` as a float, or a ValueError/TypeError naming ``name``.

    Parameters
    ----------
    name : str
        Argument name shown in backticks.
    value : int, float or NumPy real scalar
    positive, nonnegative : bool
        Require > 0 or ≥ 0.
    finite : bool
        Reject ±inf (NaN is always rejected).
    unit : str
        Unit named in the fix (``"s"``, ``"N/m"``).
    """
    suffix = f" {unit}" if unit else ""
    if not _is_real(value):
        raise TypeError(f"`{name}` must be a real number{suffix}, got {show(value)} of type "
                        f"{type(value).__name__}; give a number such as 1.0.")
    value = float(value)
    if math.isnan(value) or (finite and math.isinf(value)):
        raise ValueError(f"`{name}` must be a finite number{suffix}, got {value!r}; "
                         "give a finite value.")
    if positive and not value > 0:
        raise ValueError(f"`{name}` must be positive{suffix}, got {value!r}; give a value > 0.")
    if nonnegative and not value >= 0:
        raise ValueError(f"`{name}` must be non-negative{suffix}, got {value!r}; "
                         "give a value >= 0.")
    return value


def integer(name: str, value, *, minimum: int | None = None) -> int:
    """``value`` as an int (Python or NumPy integer, not a bool), at least ``minimum``."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise TypeError(f"`{name}` must be an integer, got {show(value)} of type "
                        f"{type(value).__name__}.")
    if minimum is not None and value < minimum:
        raise ValueError(f"`{name}` must be an integer >= {minimum}, got {int(value)}.")
    return int(value)


def vector(name: str, value, shape=(3,), *, finite=True, what="numbers") -> np.ndarray:
    """``value`` as a float array of exactly ``shape``; 2-D input to a 1-D slot is an error.

    ``shape`` entries may be ``None`` (any length along that axis).
    """
    if isinstance(value, (str, bytes, dict)):
        raise TypeError(f"`{name}` must be an array of {what} of shape {_shape(shape)}, got "
                        f"{show(value)}.")
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise TypeError(f"`{name}` must be an array of {what} of shape {_shape(shape)}, got "
                        f"{show(value)}.") from None
    ok = arr.ndim == len(shape) and all(s is None or s == n for s, n in zip(shape, arr.shape))
    if not ok:
        raise ValueError(f"`{name}` must have shape {_shape(shape)}, got shape "
                         f"{arr.shape} ({show(value)}); give {_shape(shape)} {what}.")
    bad = np.isnan(arr) if not finite else ~np.isfinite(arr)
    if np.any(bad):
        raise ValueError(f"`{name}` must be {'finite' if finite else 'not NaN'}, got "
                         f"{show(arr)}; give finite {what}.")
    return arr


#: Smallest norm computed directly: below ~1e-154 the squares in the norm
#: underflow, so such a vector is scaled by its largest component first.
_NORM_UNDERFLOW = 1e-150


def direction(name: str, value, size=3) -> np.ndarray:
    """``value`` normalised to unit length; a zero or non-finite vector is an error.

    Where the norm overflows (1e300-sized components) or underflows, the
    vector is first scaled by its largest component; otherwise it is divided
    by its norm directly, bit for bit as before this check existed.
    """
    arr = vector(name, value, (size,))
    biggest = np.max(np.abs(arr))
    if not biggest > 0:
        raise ValueError(f"`{name}` must be a non-zero direction, got {arr.tolist()}; give "
                         f"{size} components of non-zero length.")
    with np.errstate(over="ignore", under="ignore"):
        norm = np.linalg.norm(arr)
    if not (np.isfinite(norm) and norm > _NORM_UNDERFLOW):
        arr = arr / biggest
        norm = np.linalg.norm(arr)
    return arr / norm


def _shape(shape) -> str:
    return "(" + ", ".join("n" if s is None else str(s) for s in shape) + \
        ("," if len(shape) == 1 else "") + ")"


def choice(name: str, value, choices):
    """``value`` if it is one of ``choices``, else a ValueError with the closest choice."""
    if not isinstance(value, str) or value not in choices:
        raise ValueError(f"`{name}` must be one of {list(choices)}, got {show(value)}"
                         f"{did_you_mean(value, choices)}.")
    return value


def boolean(name: str, value) -> bool:
    """``value`` if it is a bool (or NumPy bool); ``'yes'`` or 1 is a TypeError."""
    if not isinstance(value, (bool, np.bool_)):
        raise TypeError(f"`{name}` must be True or False, got {show(value)} of type "
                        f"{type(value).__name__}.")
    return bool(value)


def path(name: str, value, *, must_exist=False) -> Path:
    """``value`` as a Path (a str or os.PathLike); ``must_exist`` requires a file."""
    if not isinstance(value, (str, os.PathLike)):
        raise TypeError(f"`{name}` must be a file path (str or Path), got {show(value)}.")
    p = Path(value)
    if must_exist and not p.is_file():
        raise FileNotFoundError(f"`{name}`: file {str(p)!r} does not exist; check the path.")
    return p


# ---------------------------------------------------------------------------
# TOML tables
# ---------------------------------------------------------------------------
class _Invalid:
    """The value :meth:`Table.get` returns for a field that failed (collecting mode)."""

    def __repr__(self):
        return "INVALID"


#: Returned by :meth:`Table.get` for a bad field when problems are collected.
INVALID = _Invalid()


class Problems:
    """Collector of a file's problems, shared by all its :class:`Table` objects."""

    def __init__(self, source: str):
        self.source = str(source)
        self.items: list[str] = []

    def add(self, message: str):
        if message not in self.items:
            self.items.append(message)

    def raise_if_any(self):
        if self.items:
            raise SceneError(self.source, self.items)


class Table:
    """A TOML table with its path, for error messages that name the field.

    Parameters
    ----------
    data : dict
    path : str
        Dotted path of the table (``"legs.S"``; ``""`` at the top level).
    source : str
        File name shown in messages.
    problems : Problems, optional
        Collect problems instead of raising at the first one: a bad field is
        recorded and :meth:`get` returns :data:`INVALID`.

    Subclasses may point ``docs`` at their own format page and set
    ``finite_numbers = False`` to accept ±inf (e.g. unbounded limits).
    """

    docs = "docs/scenes.md"
    finite_numbers = True

    def __init__(self, data, path, source, problems: Problems | None = None):
        if not isinstance(data, dict):
            raise ValueError(f"{source}: `{path}` must be a table, got {show(data)}.")
        self.data, self.path, self.source = data, path, source
        self.problems = problems
        self.used: set = set()
        self.failed = False

    def _where(self, key):
        return f"{self.path}.{key}" if self.path else key

    def _message(self, key, value, allowed):
        return f"field `{self._where(key)}` = {show(value)} is invalid; allowed: {allowed}."

    def error(self, key, value, allowed):
        """The ValueError for a bad field (to ``raise``)."""
        return ValueError(f"{self.source}: {self._message(key, value, allowed)}")

    def fail(self, message: str):
        """Record ``message`` (collecting) or raise it; returns :data:`INVALID`."""
        self.failed = True
        if self.problems is None:
            raise ValueError(f"{self.source}: {message}")
        self.problems.add(message)
        return INVALID

    def _finite(self, value) -> bool:
        value = np.asarray(value, dtype=float)
        return bool(np.all(np.isfinite(value) if self.finite_numbers else ~np.isnan(value)))

    def get(self, key, default=..., kind="number", size=None, choices=None, positive=False,
            nonnegative=False):
        """The field ``key`` checked as ``kind``; ``default`` if absent (required without).

        ``kind`` is one of number, int, vector (``size``: an int or a tuple of
        allowed sizes), string (``choices``), bool, strings, table, tables, any.
        """
        if kind == "number" and self._angle_bound(key) is not None:
            return self.angle(key, default, positive=positive, nonnegative=nonnegative)
        self.used.add(key)
        if key not in self.data:
            if default is ...:
                return self.fail(f"missing field `{self._where(key)}` ({kind}); add it "
                                 f"(see {self.docs}).")
            return default
        value = self.data[key]
        if kind == "number":
            return self._number(key, value, positive, nonnegative)
        if kind == "int":
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                return self.fail(self._message(key, value, "a positive integer"))
            return value
        if kind == "vector":
            sizes = (size,) if isinstance(size, int) else size
            ok = isinstance(value, list) and all(_is_real(v) for v in value)
            if not ok or (sizes is not None and len(value) not in sizes) \
                    or not self._finite(value):
                count = " or ".join(str(s) for s in sizes) + " " if sizes else ""
                return self.fail(self._message(key, value, f"a list of {count}finite numbers"))
            return np.asarray(value, dtype=float)
        if kind == "string":
            if not isinstance(value, str) or (choices and value not in choices):
                allowed = f"one of {list(choices)}" if choices else "a string"
                return self.fail(self._message(key, value, allowed)[:-1]
                                 + did_you_mean(value, choices or ()) + ".")
            return value
        if kind == "bool":
            if not isinstance(value, bool):
                return self.fail(self._message(key, value, "true or false"))
            return value
        if kind == "strings":
            if isinstance(value, str):
                return [value]
            if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
                return self.fail(self._message(key, value, "a string or a list of strings"))
            return value
        if kind == "table":
            if not isinstance(value, dict):
                return self.fail(self._message(key, value, "a table ([...])"))
            return type(self)(value, self._where(key), self.source, self.problems)
        if kind == "tables":
            if not isinstance(value, list) or not all(isinstance(v, dict) for v in value):
                return self.fail(self._message(key, value, "an array of tables ([[...]])"))
            return [type(self)(v, f"{self._where(key)}[{i}]", self.source, self.problems)
                    for i, v in enumerate(value)]
        if kind == "any":
            return value
        raise AssertionError(kind)

    def _number(self, key, value, positive=False, nonnegative=False):
        ok = _is_real(value) and self._finite(value)
        if not ok or (positive and not value > 0) or (nonnegative and not value >= 0):
            return self.fail(self._message(key, value, "a positive number" if positive else
                                           "a non-negative number" if nonnegative else
                                           "a finite number"))
        return float(value)

    def _angle_bound(self, key):
        """(bound in rad, why) of an angle field (:data:`ANGLE_FIELDS`), else None."""
        return ANGLE_FIELDS.get(re.sub(r"\[\d+\]", "", self._where(key)))

    def angle(self, key, default=..., unit="rad", positive=False, nonnegative=False):
        """An angle given in radians as ``key`` or in degrees as ``key_deg``, in ``unit``.

        ``unit`` is ``"rad"`` or ``"deg"``: the value is converted only when it
        was given in the other unit, so a degree field read in degrees is
        exact. A radian value beyond the field's bound in :data:`ANGLE_FIELDS`
        is an error that suggests the degree field.
        """
        deg = key + "_deg"
        self.used.update((key, deg))
        if key in self.data and deg in self.data:
            return self.fail(f"give either `{self._where(key)}` (radians) or "
                             f"`{self._where(deg)}` (degrees), not both.")
        if deg in self.data:
            value = self._number(deg, self.data[deg], positive, nonnegative)
            return value if value is INVALID or unit == "deg" else math.radians(value)
        if key not in self.data:
            if default is ...:
                return self.fail(f"missing field `{self._where(key)}` (radians; or "
                                 f"`{self._where(deg)}` in degrees); add it (see {self.docs}).")
            return default
        value = self._number(key, self.data[key], positive, nonnegative)
        bound = self._angle_bound(key)
        if value is not INVALID and bound is not None and abs(value) > bound[0]:
            return self.fail(f"field `{self._where(key)}` = {show(self.data[key])} is not "
                             f"plausible in radians (at most {bound[0]:.4g} rad, {bound[1]}); "
                             f"if you meant degrees, write `{deg} = {show(self.data[key])}` "
                             "(docs/scenes.md, \"Angles\").")
        return value if value is INVALID or unit == "rad" else math.degrees(value)

    def has(self, key):
        return key in self.data or (self._angle_bound(key) is not None
                                    and key + "_deg" in self.data)

    def finish(self, known=()):
        """Report keys that were never read, each with the closest known key."""
        unknown = sorted(set(self.data) - self.used)
        if not unknown:
            return
        where = self.path or "the top level"
        options = self.used | set(known)
        if self.problems is None:
            hints = "".join(did_you_mean(k, options) for k in unknown)
            raise ValueError(f"{self.source}: unknown field(s) {unknown} in `{where}`{hints}; "
                             f"check the spelling against {self.docs}.")
        for key in unknown:
            self.fail(f"unknown field `{self._where(key)}`{did_you_mean(key, options)}; "
                      f"remove it or check the spelling against {self.docs}.")
