"""TOML text of a parsed scene or study: the inverse of ``read_toml`` for what they hold.

Owns turning a dict of the kinds a scene or study file is made of (tables,
arrays of tables, strings, booleans, integers, floats, arrays of these and
inline tables) into TOML text that :mod:`tomllib` parses back to an equal
dict; floats are written with ``repr`` so that every value comes back to the
last bit. Python's standard library reads TOML but does not write it, and
the subset a scene uses is small enough that a dependency would buy nothing.
It must not read files, know what a scene means or write files.
"""
from __future__ import annotations

import math
import re

__all__ = ["toml_text"]

#: A key written bare; anything else is quoted (``fullmatch``: ``$`` would let a key end
#: in a newline through).
_BARE_KEY = re.compile(r"[A-Za-z0-9_-]+")


def _key(k) -> str:
    if not isinstance(k, str):
        raise TypeError(f"TOML keys must be strings, got {k!r}.")
    return k if _BARE_KEY.fullmatch(k) else _string(k)


_ESCAPES = {"\\": "\\\\", '"': '\\"', "\n": "\\n", "\t": "\\t", "\r": "\\r"}


def _string(s: str) -> str:
    """A basic TOML string: quotes, backslashes and control characters escaped."""
    return '"' + "".join(_ESCAPES.get(c, c if c >= " " and c != "\x7f" else f"\\u{ord(c):04x}")
                         for c in s) + '"'


def _float(x: float) -> str:
    if math.isnan(x):
        return "nan"
    if math.isinf(x):
        return "inf" if x > 0 else "-inf"
    text = repr(x)
    return text if any(c in text for c in ".en") else text + ".0"


def _value(v, where: str) -> str:
    """Inline TOML of one value (no table headers)."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return _float(v)
    if isinstance(v, str):
        return _string(v)
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{_key(k)} = {_value(x, f'{where}.{k}')}"
                                for k, x in v.items()) + " }" if v else "{}"
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_value(x, f"{where}[{i}]") for i, x in enumerate(v)) + "]"
    if hasattr(v, "item") and hasattr(v, "dtype"):          # a NumPy scalar
        return _value(v.item(), where)
    raise TypeError(f"`{where}` = {v!r} has no TOML form; give a number, string, boolean, "
                    "list or table.")


def _is_table_array(v) -> bool:
    return isinstance(v, (list, tuple)) and len(v) > 0 and all(isinstance(x, dict) for x in v)


def _table(data: dict, path: tuple, lines: list):
    """Append ``data``'s plain values, then its sub-tables and arrays of tables."""
    for k, v in data.items():
        if not isinstance(v, dict) and not _is_table_array(v):
            lines.append(f"{_key(k)} = {_value(v, '.'.join(path + (k,)))}")
    for k, v in data.items():
        sub = path + (k,)
        name = ".".join(_key(s) for s in sub)
        if isinstance(v, dict):
            lines += ["", f"[{name}]"]
            _table(v, sub, lines)
        elif _is_table_array(v):
            for item in v:
                lines += ["", f"[[{name}]]"]
                _table(item, sub, lines)


def toml_text(data: dict, header: str = "") -> str:
    """TOML text of ``data``, with ``header`` as comment lines at the top.

    Parameters
    ----------
    data : dict
        Tables are dicts, arrays of tables lists of dicts; the values are
        str, bool, int, float (NaN and ±inf included) and lists of these.
    header : str
        Written first, each line as a ``#`` comment.
    """
    if not isinstance(data, dict):
        raise TypeError(f"`data` must be a dict (the top-level table), got {type(data).__name__}.")
    lines = [("# " + line).rstrip() for line in header.splitlines()]
    body = []
    _table(data, (), body)
    while body and body[0] == "":
        body.pop(0)
    if lines and body:
        lines.append("")
    return "\n".join(lines + body) + "\n"
