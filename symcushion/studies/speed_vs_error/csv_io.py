"""The study's CSV file: writing rows with the fixed columns and reading them back.

Owns the CSV format (:data:`~.grid.COLUMNS` as header, non-finite numbers as
empty cells). It must not compute any row.
"""
from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from .grid import COLUMNS


def csv_cell(value):
    """One CSV cell: empty for None or a non-finite number, 12 digits otherwise."""
    if value is None:
        return ""
    if isinstance(value, (float, np.floating)):
        return "" if not np.isfinite(value) else f"{float(value):.12g}"
    return str(value)


def write_csv(rows, path) -> None:
    """Write the study's rows (dicts) with :data:`COLUMNS` as header.

    Missing or non-finite numbers are written as empty cells; ``status``
    says why (e.g. ``non-finite``).
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(COLUMNS)
        for row in rows:
            unknown = set(row) - set(COLUMNS)
            if unknown:
                raise ValueError(f"row has unknown column(s) {sorted(unknown)}; add them to "
                                 "COLUMNS.")
            writer.writerow([csv_cell(row.get(c)) for c in COLUMNS])


def read_csv(path) -> list:
    """Rows of a CSV written by :func:`write_csv`, numbers as floats."""
    rows = []
    with open(path, newline="") as fh:
        for row in csv.DictReader(fh):
            out = {}
            for k, v in row.items():
                try:
                    out[k] = float(v) if v != "" else float("nan")
                except ValueError:
                    out[k] = v
            rows.append(out)
    return rows

