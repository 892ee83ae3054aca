"""The result directory of a run: self-describing columns, atomic and streamed files.

This module owns what a run leaves on disk and how it is read back:

* ``trajectory.csv``: one row per time point, columns named
  ``{owner}_{field}[_{axis}]_{unit}`` (owner ``body`` or ``leg{j}``, 0-based;
  unit ``m``, ``m_s``, ``m_s2``, ``rad``, ``rad_s``, ``N``, ``s`` or ``1`` for
  dimensionless), legs' modes as words (free, stick, slip, lift-off);
* ``trajectory.npz``: the same table as one float array ``data`` (modes as
  their codes), with ``columns``, ``units`` and ``metadata`` (a JSON string);
* ``run.json``: the scene as loaded, method, Δt, duration, versions, the run's
  events and warnings, and the column list with units;
* ``trajectory.mat``: for MATLAB, each column as a variable of the CSV's name
  (modes as codes, ``mode_names`` their words), ``units``, and run.json as the
  struct ``run`` (``symcushion.run.matlab``, docs/toolchain.md); written from a
  column-major copy of the rows, one column in memory at a time.

Every file is written through a temporary file in its own directory and moved
into place by :func:`os.replace`, so a killed run leaves the previous complete
file or none. Output paths are checked before any work (:func:`check_out_dir`,
:func:`result_dir`). Those mechanics live in ``symcushion.run.output_files`` and
are re-exported here. It must not simulate or plot: the driver
(``symcushion.run.driver``) feeds it rows, ``symcushion.viz.plots`` draws them.
"""
from __future__ import annotations

import json
import os
import zipfile
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from symcushion.layout.vectors import MODES, output_columns, state_columns
# the output files' mechanics, re-exported: users and studies import them from here
from symcushion.run.output_files import (OutputExists, atomic_write_text, check_out_dir,
    check_output_file, claim_output, jsonable, remove_stale, replacing, result_dir,
    temporary_beside, to_json, versions)
from symcushion.run.matlab import write_table_mat

__all__ = ["trajectory_columns", "column_unit", "check_out_dir", "check_output_file",
           "result_dir", "atomic_write_text", "write_csv", "jsonable", "to_json", "replacing", "ResultWriter",
           "read_result", "versions", "OutputExists", "claim_output", "remove_stale",
           "CSV_NAME", "NPZ_NAME", "JSON_NAME", "MAT_NAME", "RUN_FILES", "UNITS", "MODE_CODES"]

CSV_NAME = "trajectory.csv"
NPZ_NAME = "trajectory.npz"
JSON_NAME = "run.json"
MAT_NAME = "trajectory.mat"
#: Every file a ``simulate`` run writes into its result folder: the ones it
#: refuses to replace without ``--overwrite``, and the only ones it removes.
RUN_FILES = (CSV_NAME, NPZ_NAME, JSON_NAME, MAT_NAME, "summary.png", "animation.gif")

#: Unit suffixes of the column names, longest first so that ``_m_s2`` is not
#: read as ``_s2``; ``1`` marks a dimensionless column.
UNITS = ("m_s2", "rad_s", "m_s", "rad", "m", "N", "J", "s", "1")

#: Word of each mode code and back (the CSV writes words, the NPZ codes).
MODE_CODES = {word: code for code, word in MODES.items()}

#: Bytes copied at a time from the raw row file into the NPZ (bounded memory).
_COPY_CHUNK = 1 << 20

#: Bytes of raw rows turned into columns at a time for the MAT file (bounded
#: memory; larger blocks mean fewer, longer writes).
_TRANSPOSE_CHUNK = 8 << 20


def trajectory_columns(n_legs: int) -> list:
    """Column names of ``trajectory.csv``: ``time_s``, the state x, the output y.

    Parameters
    ----------
    n_legs : int
        Number of legs of the scene (≥ 1).

    Returns
    -------
    list of str, length 1 + nx + ny
    """
    if isinstance(n_legs, bool) or not isinstance(n_legs, (int, np.integer)) or n_legs < 1:
        raise ValueError(f"`n_legs` must be a positive integer, got {n_legs!r}.")
    return ["time_s"] + state_columns(int(n_legs)) + output_columns(int(n_legs))


def column_unit(name: str) -> str:
    """Unit suffix of a column name (``'m_s2'`` of ``'body_acceleration_z_m_s2'``)."""
    for unit in UNITS:
        if name.endswith("_" + unit):
            return unit
    raise ValueError(f"column {name!r} has no unit suffix; expected one of {UNITS}.")


def _csv_formatter(columns):
    """A function turning rows (k, C) into CSV text: %.17g, modes as words."""
    modes = [i for i, c in enumerate(columns) if c.endswith("_mode_1")]
    # %.17g round-trips every double; a mode code becomes its word
    fmt = ",".join("%s" if i in modes else "%.17g" for i in range(len(columns))) + "\n"

    def format_rows(rows):
        lines = []
        for row in rows.tolist():
            for i in modes:
                row[i] = MODES.get(int(round(row[i])), "unknown")
            lines.append(fmt % tuple(row))
        return "".join(lines)
    return format_rows


def write_csv(path, columns, rows) -> Path:
    """Write rows (k, C) under a header of ``columns`` to ``path``, atomically."""
    columns = list(columns)
    rows = np.asarray(rows, dtype=float)
    if rows.ndim != 2 or rows.shape[1] != len(columns):
        raise ValueError(f"`rows` must have shape (k, {len(columns)}), got {rows.shape}.")
    return atomic_write_text(path, ",".join(columns) + "\n" + _csv_formatter(columns)(rows))


# ---------------------------------------------------------------------------
# streamed writer
# ---------------------------------------------------------------------------
class ResultWriter:
    """Write a run's rows to ``trajectory.csv`` and ``.npz`` block by block.

    Rows go to temporary files in the result directory as they come
    (:meth:`append`), so memory does not grow with the run; :meth:`finish`
    writes ``run.json`` and ``trajectory.mat`` (one column in memory at a
    time) and moves every file into place with :func:`os.replace`;
    :meth:`abort` (or an exception inside ``with``) removes the temporary files
    and leaves the previous results untouched.

    Parameters
    ----------
    directory : Path
        The result directory (from :func:`result_dir`).
    columns : list of str
        Column names (:func:`trajectory_columns`).
    """

    def __init__(self, directory, columns):
        self.directory = Path(directory)
        self.columns = list(columns)
        self._format = _csv_formatter(self.columns)
        self._csv, self._csv_tmp = temporary_beside(self.directory / CSV_NAME, "w")
        self._raw, self._raw_tmp = temporary_beside(self.directory / NPZ_NAME, "wb")
        header = ",".join(self.columns) + "\n"
        self._csv.write(header)
        # (rows, CSV bytes, raw bytes, time of the last row) after the last
        # complete append, set in one assignment: an interrupt between the two
        # writes of a block leaves it describing the previous block
        self._mark = (0, len(header), 0, None)
        self._done = False

    @property
    def rows(self) -> int:
        """Rows appended completely so far."""
        return self._mark[0]

    @property
    def last_time(self):
        """First column (time) of the last complete row, None before any row."""
        return self._mark[3]

    def __enter__(self):
        return self

    def __exit__(self, kind, value, tb):
        if kind is not None:
            self.abort()
        return False

    def append(self, rows):
        """Append rows, shape (k, len(columns)), SI units, modes as codes."""
        rows = np.ascontiguousarray(rows, dtype=float)
        if rows.ndim != 2 or rows.shape[1] != len(self.columns):
            raise ValueError(f"`rows` must have shape (k, {len(self.columns)}), got {rows.shape}.")
        if rows.shape[0] == 0:
            return
        text, raw = self._format(rows), rows.tobytes()     # the CSV is ASCII: chars = bytes
        self._csv.write(text)
        self._raw.write(raw)
        rows_done, csv_bytes, raw_bytes, _ = self._mark
        self._mark = (rows_done + rows.shape[0], csv_bytes + len(text), raw_bytes + len(raw),
                      float(rows[-1, 0]))

    def finish(self, metadata: dict) -> dict:
        """Close the files, write ``run.json`` and ``trajectory.mat``, move everything into place.

        Only completely appended rows are kept: after an interrupt that fell
        inside :meth:`append`, the files end at the block before, so a run
        stopped early leaves whole files of the rows it finished.

        Returns
        -------
        dict
            Paths of ``csv``, ``npz``, ``mat`` and ``json``.
        """
        if self._done:
            raise ValueError("this ResultWriter was already finished or aborted; start a new "
                             "one for another run.")
        rows, csv_bytes, raw_bytes, _ = self._mark
        metadata = dict(metadata, rows=rows,
                        columns=[{"name": c, "unit": column_unit(c)} for c in self.columns])
        text = to_json(metadata)
        try:
            self._csv.close()
            self._raw.close()
            os.truncate(self._csv_tmp, csv_bytes)
            os.truncate(self._raw_tmp, raw_bytes)
            npz_fh, npz_tmp = temporary_beside(self.directory / NPZ_NAME, "wb")
            npz_fh.close()
            try:
                self._write_npz(npz_tmp, text)
                files = {"csv": self.directory / CSV_NAME, "npz": self.directory / NPZ_NAME,
                         "json": self.directory / JSON_NAME}
                os.replace(self._csv_tmp, files["csv"])
                os.replace(npz_tmp, files["npz"])
            finally:
                npz_tmp.unlink(missing_ok=True)
            files["mat"] = self._write_mat(metadata)
            atomic_write_text(files["json"], text + "\n")
        finally:
            self.abort()
        return files

    def _write_npz(self, target: Path, metadata_text: str):
        """NPZ of the raw rows, copied in chunks (no full array in memory)."""
        shape = (self.rows, len(self.columns))      # the raw file holds exactly these
        with zipfile.ZipFile(target, "w", zipfile.ZIP_STORED, allowZip64=True) as zf:
            with zf.open("data.npy", "w", force_zip64=True) as member:
                np.lib.format.write_array_header_1_0(
                    member, {"descr": np.lib.format.dtype_to_descr(np.dtype(float)),
                             "fortran_order": False, "shape": shape})
                with open(self._raw_tmp, "rb") as raw:
                    while chunk := raw.read(_COPY_CHUNK):
                        member.write(chunk)
            for key, value in (("columns", np.array(self.columns)),
                               ("units", np.array([column_unit(c) for c in self.columns])),
                               ("metadata", np.array(metadata_text))):
                with zf.open(f"{key}.npy", "w") as member:
                    np.lib.format.write_array(member, value, allow_pickle=False)

    def _write_mat(self, metadata: dict) -> Path:
        """``trajectory.mat`` from the raw rows, one column in memory at a time."""
        columns = _ColumnFile(self._raw_tmp, self.rows, self.columns,
                              self.directory / MAT_NAME)
        try:
            return write_table_mat(self.directory / MAT_NAME, columns, metadata, "run",
                                   units={c: column_unit(c) for c in self.columns},
                                   extra={"mode_names": [MODES[k] for k in sorted(MODES)]})
        finally:
            columns.path.unlink(missing_ok=True)

    def abort(self):
        """Close and remove the temporary files (previous results stay)."""
        if self._done:
            return
        self._done = True
        for fh in (self._csv, self._raw):
            fh.close()
        for tmp in (self._csv_tmp, self._raw_tmp):
            tmp.unlink(missing_ok=True)


class _ColumnFile(Mapping):
    """The columns of a raw row file (rows × columns, float64, row-major), read one at a time.

    A column-major copy is written beside ``near`` block by block
    (:data:`_TRANSPOSE_CHUNK` bytes of rows at a time), so that a column is
    one contiguous read and no more than a block and a column are ever in memory.
    """

    def __init__(self, raw: Path, rows: int, names, near: Path):
        self.names, self.rows = list(names), rows
        width = len(self.names)
        fh, self.path = temporary_beside(near, "wb")
        try:
            with fh, open(raw, "rb") as src:
                fh.truncate(rows * width * 8)
                block = max(1, _TRANSPOSE_CHUNK // (8 * width))
                for start in range(0, rows, block):
                    chunk = np.fromfile(src, dtype=float, count=block * width).reshape(-1, width)
                    for i in range(width):
                        fh.seek((i * rows + start) * 8)
                        fh.write(np.ascontiguousarray(chunk[:, i]).tobytes())
        except BaseException:
            self.path.unlink(missing_ok=True)
            raise

    def __getitem__(self, name) -> np.ndarray:
        i = self.names.index(name)
        return np.fromfile(self.path, dtype=float, count=self.rows, offset=i * self.rows * 8)

    def __iter__(self):
        return iter(self.names)

    def __len__(self) -> int:
        return len(self.names)


# ---------------------------------------------------------------------------
# reading back
# ---------------------------------------------------------------------------
def read_result(directory) -> tuple[list, np.ndarray, dict]:
    """Read a result directory: column names, rows (modes as codes), run.json.

    Reads ``trajectory.npz`` when present (exact and fast), else the CSV.

    Returns
    -------
    columns : list of str
    data : ndarray, shape (T, C)
    metadata : dict
    """
    directory = Path(directory)
    if not directory.is_dir():
        raise FileNotFoundError(f"result directory {directory} not found; give the folder a "
                                "run wrote (OUT/<scene name>).")
    json_path = directory / JSON_NAME
    metadata = json.loads(json_path.read_text()) if json_path.is_file() else {}
    npz = directory / NPZ_NAME
    if npz.is_file():
        with np.load(npz, allow_pickle=False) as z:
            return [str(c) for c in z["columns"]], np.array(z["data"]), metadata
    csv = directory / CSV_NAME
    if not csv.is_file():
        raise FileNotFoundError(f"{directory} holds neither {NPZ_NAME} nor {CSV_NAME}; give "
                                "the folder a run wrote.")
    with open(csv) as fh:
        columns = fh.readline().strip().split(",")
    modes = {i for i, c in enumerate(columns) if c.endswith("_mode_1")}
    converters = {i: (lambda s: float(MODE_CODES[s.strip()])) for i in modes}
    data = np.loadtxt(csv, delimiter=",", skiprows=1, converters=converters, ndmin=2,
                      encoding="utf-8")
    return columns, data, metadata
