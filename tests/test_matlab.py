"""MAT files for MATLAB (symcushion.run.matlab): trajectory.mat beside every run's CSV, cases.mat
beside an envelope's cases.csv; every column equal to the CSV's to the last bit, the
metadata struct equal to its JSON, names valid in MATLAB, atomic writes."""
import csv
import json
from pathlib import Path

import numpy as np
import pytest
import scipy.io

from symcushion import envelope as ev
from symcushion.run.matlab import (MATLAB_KEYWORDS, NAME_LENGTH_MAX, matlab_name, matlab_names,
    to_matlab, write_table_mat)
from symcushion.run.results import MAT_NAME, MODE_CODES, ResultWriter, column_unit, result_dir

ROOT = Path(__file__).resolve().parents[1]

#: A MATLAB identifier (``isvarname``, keywords apart).
VALID = r"[A-Za-z][A-Za-z0-9_]{0,62}"


def read_csv(path):
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    return rows[0], rows[1:]


def load(path):
    return scipy.io.loadmat(path, simplify_cells=True)


def assert_same(json_value, mat_value, where="run"):
    """A JSON value equals its MATLAB form as loadmat returns it: numbers as doubles, a
    list of numbers as an array, null as [], a one-element list as its element (MATLAB
    does not tell a 1×1 array from a scalar)."""
    if isinstance(json_value, dict):
        assert isinstance(mat_value, dict), where
        assert list(mat_value) == matlab_names(list(json_value)), where
        for (key, value), name in zip(json_value.items(), mat_value):
            assert_same(value, mat_value[name], f"{where}.{key}")
    elif json_value is None:
        assert np.size(mat_value) == 0, where
    elif isinstance(json_value, bool):
        assert bool(mat_value) is json_value, where
    elif isinstance(json_value, (int, float)):
        assert float(mat_value) == json_value, where
    elif isinstance(json_value, str):
        assert mat_value == json_value, where
    elif all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in json_value) \
            and json_value:
        np.testing.assert_array_equal(np.ravel(mat_value), json_value, err_msg=where)
    elif len(json_value) == 1 and not isinstance(mat_value, (list, np.ndarray)):
        assert_same(json_value[0], mat_value, where)
    else:
        items = list(mat_value) if np.size(mat_value) else []
        assert len(items) == len(json_value), where
        for i, (a, b) in enumerate(zip(json_value, items)):
            assert_same(a, b, f"{where}[{i}]")


def test_trajectory_mat_holds_every_csv_column_to_the_last_bit(tutorial_result):
    header, rows = read_csv(tutorial_result / "trajectory.csv")
    mat = load(tutorial_result / MAT_NAME)
    assert list(mat["columns"]) == header and list(mat["variables"]) == header  # all valid
    modes = list(mat["mode_names"])
    for i, name in enumerate(header):
        text = [row[i] for row in rows]
        if name.endswith("_mode_1"):
            expected = np.array([MODE_CODES[word] for word in text], dtype=float)
            assert [modes[int(code)] for code in mat[name]] == text
        else:
            expected = np.array([float(x) for x in text])     # %.17g: every double exactly
        assert mat[name].shape == (len(rows),), name
        np.testing.assert_array_equal(mat[name], expected, err_msg=name)
        assert mat["units"][name] == column_unit(name)


def test_run_struct_round_trips_run_json(tutorial_result):
    text = (tutorial_result / "run.json").read_text()
    mat = load(tutorial_result / MAT_NAME)
    assert mat["run_json"] == text.rstrip("\n")                   # verbatim, for jsondecode
    meta = json.loads(text)
    assert_same(meta, mat["run"])
    assert mat["run"]["scene"]["legs"]["e0"].shape == (3,)        # a vector stays numeric
    assert mat["run"]["events"][0]["kind"] == "touchdown"         # a list of objects: a cell


def test_an_empty_run_writes_an_empty_mat(tmp_path):
    directory = result_dir(tmp_path, "empty")
    with ResultWriter(directory, ["time_s", "body_position_z_m"]) as writer:
        files = writer.finish({"note": None})
    mat = load(files["mat"])
    assert mat["time_s"].size == 0 and mat["units"]["body_position_z_m"] == "m"
    assert np.size(mat["run"]["note"]) == 0


def test_names_follow_matlab_rules():
    assert matlab_name("leg0_force_z_N") == "leg0_force_z_N"
    assert matlab_name("case") == "xCase" and matlab_name("end") == "xEnd"
    assert matlab_name("0th") == "x0th" and matlab_name("_x") == "x_x"
    assert matlab_name("max |P| (N)") == "max__P___N_"
    long = "a" * 80
    assert matlab_name(long) == "a" * NAME_LENGTH_MAX
    assert matlab_names([long, long + "b", "x", "x"]) == [
        "a" * 63, "a" * 61 + "_1", "x", "x_1"]
    import re
    for name in matlab_names(list(MATLAB_KEYWORDS) + ["é", "1", "a-b", long]):
        assert re.fullmatch(VALID, name) and name not in MATLAB_KEYWORDS, name
    with pytest.raises(ValueError, match="non-empty string"):
        matlab_name("")


def test_metadata_conversion():
    converted = to_matlab({"a b": [1, 2.5], "m": [[1, 2], [3, 4]], "s": ["x", "yy"],
                           "mixed": [1, None], "flag": True, "none": None, "n": 3})
    assert list(converted) == ["a_b", "m", "s", "mixed", "flag", "none", "n"]
    np.testing.assert_array_equal(converted["a_b"], [1.0, 2.5])
    assert converted["m"].shape == (2, 2) and converted["s"].dtype == object
    assert converted["mixed"].dtype == object and converted["flag"].dtype == bool
    assert converted["none"].shape == (0, 0) and converted["n"] == 3.0
    with pytest.raises(TypeError, match=r"cannot write a set .* give JSON-like"):
        to_matlab({"bad": {1, 2}})


def test_a_column_may_not_overwrite_the_files_own_variables(tmp_path):
    with pytest.raises(ValueError, match=r"\['units'\] would overwrite .* rename"):
        write_table_mat(tmp_path / "t.mat", {"time_s": np.zeros(2), "units": np.zeros(2)},
                        units={"time_s": "s", "units": "1"})


def test_failed_mat_write_keeps_the_previous_file(tmp_path, monkeypatch):
    path = write_table_mat(tmp_path / "t.mat", {"x": np.arange(3.0)})
    before = path.read_bytes()

    def broken(stream, *args, **kwargs):
        stream.write(b"half a file")
        raise OSError("disk full")

    monkeypatch.setattr(scipy.io, "savemat", broken)
    with pytest.raises(OSError, match="disk full"):
        write_table_mat(path, {"x": np.arange(5.0)})
    assert path.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == ["t.mat"]      # no temporary left


def test_cases_mat_holds_every_column_of_cases_csv(tmp_path):
    study = ev.load_study(ROOT / "studies" / "envelope_lander.toml").with_(n=7)
    rng = np.random.default_rng(3)
    conditions = {k: rng.uniform(0, 10, 7) for k in ev.VARIABLES}
    classes = np.array(["stable", "tip_over", "stable", "stroke", "rebound", "stable",
                        "deceleration"])
    columns = {"max_stroke": rng.uniform(0, 0.3, 7), "margin_tip_over": rng.normal(size=7),
               "class": classes, "stable": classes == "stable"}
    result = ev.EnvelopeResult(study, conditions, columns, timings={"run_seconds": 0.5})
    files = ev.write_result(result, tmp_path, plots=False)
    assert files["cases_mat"] == tmp_path / "cases.mat"
    header, rows = read_csv(tmp_path / "cases.csv")
    mat = load(tmp_path / "cases.mat")
    assert list(mat["columns"]) == header
    assert list(mat["variables"]) == ["xCase"] + header[1:]      # `case` is a MATLAB keyword
    for i, (name, variable) in enumerate(zip(header, mat["variables"])):
        text = [row[i] for row in rows]
        if name == "class":
            assert list(mat[variable]) == text
        else:
            np.testing.assert_array_equal(mat[variable], [float(x) for x in text], err_msg=name)
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert_same(summary, mat["summary"], "summary")
    assert json.loads(mat["summary_json"]) == summary


def test_columns_are_transposed_block_by_block(tutorial_result, tmp_path, monkeypatch):
    """The MAT file is written from a column-major copy made a block of rows at a time;
    blocks of 8 rows (the last one short) give the same columns as the NPZ."""
    from symcushion.run import results

    with np.load(tutorial_result / "trajectory.npz") as z:
        columns, data = [str(c) for c in z["columns"]], z["data"]
    monkeypatch.setattr(results, "_TRANSPOSE_CHUNK", 8 * len(columns) * 8)
    assert len(data) % 8
    directory = result_dir(tmp_path, "again")
    with ResultWriter(directory, columns) as writer:
        for start in range(0, len(data), 50):
            writer.append(data[start:start + 50])
        files = writer.finish({})
    mat = load(files["mat"])
    for i, name in enumerate(columns):
        np.testing.assert_array_equal(mat[name], data[:, i], err_msg=name)
    assert sorted(p.name for p in directory.iterdir()) == sorted(
        ["trajectory.csv", "trajectory.npz", MAT_NAME, "run.json"])    # no copy left
