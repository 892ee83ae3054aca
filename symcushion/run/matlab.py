"""MAT files for MATLAB: a table's columns as variables, its metadata as a struct.

This module owns how a table of named columns (a run's ``trajectory.csv``,
an envelope's ``cases.csv``) and its JSON metadata (``run.json``,
``summary.json``) are written for MATLAB (``scipy.io.savemat``, MAT 5):

* one variable per column, a column vector, named as the CSV's column where
  that name is a valid MATLAB identifier and otherwise as MATLAB's own
  ``matlab.lang.makeValidName`` would name it (:func:`matlab_name`);
* ``columns`` and ``variables``: the CSV's names and the variables' names, in
  the CSV's order (cell arrays of char), so a name that had to change is
  found by its position;
* optionally ``units``, a struct of each variable's unit (``units.time_s`` is
  ``'s'``);
* the metadata as a struct (:func:`to_matlab`: objects become structs, lists
  of numbers arrays, other lists cell arrays, null ``[]``) and as JSON text
  (``<name>_json``, for ``jsondecode``).

Files are written atomically, through a temporary file and ``os.replace``. It
must not run or read simulations; ``symcushion.run.results`` and the envelope
call it with their own tables. docs/toolchain.md describes the files.
"""
from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np

from symcushion.run.output_files import replacing, to_json

__all__ = ["matlab_name", "matlab_names", "to_matlab", "write_table_mat", "MATLAB_KEYWORDS",
           "NAME_LENGTH_MAX"]

#: MATLAB's ``namelengthmax``: longer names are truncated by MATLAB itself.
NAME_LENGTH_MAX = 63

#: MATLAB's reserved words (``iskeyword``): not allowed as variable or field names.
MATLAB_KEYWORDS = frozenset((
    "break", "case", "catch", "classdef", "continue", "else", "elseif", "end", "for",
    "function", "global", "if", "otherwise", "parfor", "persistent", "return", "spmd",
    "switch", "try", "while"))

_VALID = re.compile(r"[A-Za-z][A-Za-z0-9_]*\Z")


def matlab_name(name: str) -> str:
    """``name`` as a valid MATLAB identifier, as ``matlab.lang.makeValidName`` makes it.

    A valid name (a letter, then letters, digits or ``_``, at most
    :data:`NAME_LENGTH_MAX` characters, not a keyword) is kept; otherwise
    invalid characters become ``_``, a name not starting with a letter gets the
    prefix ``x``, a keyword becomes ``x`` + its capitalised self (``case`` →
    ``xCase``), and the result is cut to :data:`NAME_LENGTH_MAX` characters.
    """
    if not isinstance(name, str) or not name:
        raise ValueError(f"a MATLAB name needs a non-empty string, got {name!r}.")
    if name in MATLAB_KEYWORDS:
        return "x" + name[0].upper() + name[1:]
    valid = re.sub(r"[^A-Za-z0-9_]", "_", name)
    if not valid[0].isalpha() or not valid[0].isascii():
        valid = "x" + valid
    return valid[:NAME_LENGTH_MAX]


def matlab_names(names) -> list:
    """:func:`matlab_name` of each name, made unique by ``_1``, ``_2``, … suffixes."""
    out, seen = [], set()
    for name in names:
        candidate = base = matlab_name(name)
        k = 0
        while candidate in seen:
            k += 1
            suffix = f"_{k}"
            candidate = base[:NAME_LENGTH_MAX - len(suffix)] + suffix
        seen.add(candidate)
        out.append(candidate)
    return out


def _is_number(v) -> bool:
    return isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(
        v, (bool, np.bool_))


def _numeric_array(values):
    """A float array of a list of numbers, or of equal-length lists of numbers; else None."""
    if values and all(_is_number(v) for v in values):
        return np.asarray(values, dtype=float)
    if values and all(isinstance(v, list) for v in values):
        rows = [_numeric_array(v) for v in values]
        if all(r is not None and r.ndim == 1 and r.shape == rows[0].shape for r in rows):
            return np.vstack(rows)
    return None


def to_matlab(value):
    """A JSON-like value as ``scipy.io.savemat`` writes it for MATLAB.

    dict → struct (keys through :func:`matlab_names`); a list of numbers → a
    double row, a list of equal-length number lists → a double matrix; any
    other list → a cell array; a number → double; bool → logical; str → char;
    None → ``[]``.
    """
    if isinstance(value, dict):
        keys = list(value)
        return {name: to_matlab(value[key]) for key, name in zip(keys, matlab_names(
            [str(k) for k in keys]))}
    if isinstance(value, (list, tuple)):
        numbers = _numeric_array(list(value))
        if numbers is not None:
            return numbers
        cell = np.empty((1, len(value)), dtype=object)
        for i, item in enumerate(value):
            cell[0, i] = to_matlab(item)
        return cell
    if isinstance(value, np.ndarray):
        return to_matlab(value.tolist())
    if isinstance(value, (bool, np.bool_)):
        return np.bool_(value)
    if _is_number(value):
        return float(value)
    if value is None:
        return np.empty((0, 0))
    if isinstance(value, str):
        return value
    raise TypeError(f"cannot write a {type(value).__name__} ({value!r}) to a MAT file; "
                    "give JSON-like metadata (dict, list, str, number, bool, None).")


def _cellstr(strings) -> np.ndarray:
    cell = np.empty((len(strings), 1), dtype=object)
    cell[:, 0] = list(strings)
    return cell


def _column(values) -> np.ndarray:
    """A column as savemat writes it: numbers as double, strings as a cell array."""
    if isinstance(values, np.ndarray) and values.dtype.kind in "fiub":
        return values.astype(float, copy=False)
    if all(isinstance(v, str) for v in values):
        return _cellstr(values)
    return np.asarray(values, dtype=float)


def write_table_mat(path, columns, metadata: dict | None = None,
                    metadata_name: str = "run", units: dict | None = None,
                    extra: dict | None = None) -> Path:
    """Write a table's columns and metadata to a MAT file, atomically.

    Parameters
    ----------
    path : str or Path
        The MAT file (``.mat``), replaced whole or not at all.
    columns : mapping of str to array_like, each shape (k,)
        The columns by their CSV names, in the CSV's order: numbers (written
        as double) or strings (a cell array of char). Each is looked up,
        written and dropped in turn, so a mapping that reads its columns from
        disk keeps one column in memory.
    metadata : dict, optional
        JSON-like metadata: written as the struct ``metadata_name`` and as its
        JSON text ``metadata_name + "_json"``.
    metadata_name : str
        Name of the metadata struct (``run``, ``summary``).
    units : dict of str to str, optional
        Unit of each column by CSV name: written as the struct ``units``.
    extra : dict, optional
        Further variables by (valid) name, JSON-like (:func:`to_matlab`).

    Returns
    -------
    Path
    """
    import scipy.io

    names = list(columns)
    variables = matlab_names(names)
    extra = dict(extra or {})
    reserved = {"columns", "variables", "units", metadata_name, metadata_name + "_json", *extra}
    clash = sorted(reserved.intersection(variables))
    if clash:
        raise ValueError(f"column(s) {clash} would overwrite the MAT file's own variables "
                         f"{sorted(reserved)}; rename the column(s).")
    rest = {"columns": _cellstr(names), "variables": _cellstr(variables)}
    if units is not None:
        rest["units"] = {var: str(units[name]) for name, var in zip(names, variables)}
    rest.update({name: to_matlab(value) for name, value in extra.items()})
    if metadata is not None:
        text = to_json(metadata)
        rest[metadata_name] = to_matlab(json.loads(text))
        rest[metadata_name + "_json"] = text
    options = dict(format="5", long_field_names=True, oned_as="column", do_compression=True)
    path = Path(path)
    with replacing(path) as tmp, open(tmp, "wb") as fh:
        # savemat on an open file appends its variables (the header only at the start)
        for name, var in zip(names, variables):
            scipy.io.savemat(fh, {var: _column(columns[name])}, **options)
        scipy.io.savemat(fh, rest, **options)
    return path
