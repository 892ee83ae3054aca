"""Result directories: self-describing columns, round trip, atomic and streamed writing."""
import json
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

from symcushion.run import driver
from symcushion.legs.characteristics import Linear
from symcushion.run.driver import RunWarning, Trajectory, save, simulate
from symcushion.model.obstacles import Plane
from symcushion.run.results import (JSON_NAME, UNITS, ResultWriter, check_out_dir, column_unit,
    result_dir, trajectory_columns)
from symcushion.model.scene import Body, Scene, load_scene
from symcushion.layout.vectors import BODY_OUT, BODY_STATE, LEG_OUT, LEG_STATE
from symcushion.scheme.touchdown import build_model
from symcushion.legs.strut import HingedStrut

ROOT = Path(__file__).resolve().parents[1]


def drop_scene(duration=0.25, gravity=(0.0, 0.0, -9.81), dt=1e-3):
    """One vertical leg dropped on a plane at 1 m/s: touchdown then lift-off."""
    leg = HingedStrut(hinge=(0, 0, -0.1), e0=(0, 0, -1), en=(0, 0.6, -0.8), length=0.5,
                      S=Linear(2e4), M_beta=Linear(500.0), M_gamma=Linear(500.0))
    body = Body(mass=10.0, inertia=[0.5, 0.5, 0.5], position=[0, 0, 0.62],
                velocity=[0, 0, -1.0])
    return Scene(body, [leg], [Plane()], dt=dt, duration=duration, gravity=gravity,
                 name="drop")


class FakeFinding:
    severity = "warning"

    def __init__(self, message):
        self.message = message

    def to_dict(self):
        return {"check": "fake", "message": self.message}


class FakeMonitor:
    """Reports one finding in the first block it sees, and records its calls."""

    def __init__(self):
        self.calls = []

    def check(self, t, X, Y):
        self.calls.append((np.array(t), np.shape(X), np.shape(Y)))
        return [FakeFinding("fake finding")] if len(self.calls) == 1 else []


def test_every_column_has_a_unit_and_names_are_unique():
    cols = trajectory_columns(3)
    assert len(cols) == 1 + BODY_STATE + 3 * LEG_STATE + BODY_OUT + 3 * LEG_OUT
    assert len(set(cols)) == len(cols)
    for c in cols:
        assert column_unit(c) in UNITS
        assert c == "time_s" or c.startswith(("body_", "leg0_", "leg1_", "leg2_"))
    assert "leg2_force_z_N" in cols and "body_position_z_m" in cols
    assert "body_acceleration_z_m_s2" in cols and "leg1_beta_rad" in cols


def test_round_trip_through_npz_and_csv(tmp_path):
    scene = drop_scene()
    traj = simulate(scene)
    files = save(traj, tmp_path, "drop", {"scene_summary": {"gravity": scene.gravity}})
    back = Trajectory.load(tmp_path / "drop")
    np.testing.assert_array_equal(back.rows, traj.rows)
    np.testing.assert_array_equal(back.force, traj.force)
    np.testing.assert_array_equal(back.alpha, traj.alpha)
    files["npz"].unlink()                  # the CSV alone: %.17g round-trips every double
    back = Trajectory.load(tmp_path / "drop")
    np.testing.assert_array_equal(back.rows, traj.rows)
    header = files["csv"].read_text().splitlines()[0].split(",")
    assert header == trajectory_columns(1)
    modes = {line.split(",")[header.index("leg0_mode_1")]
             for line in files["csv"].read_text().splitlines()[1:]}
    assert modes <= {"free", "stick", "slip", "lift-off"} and "stick" in modes


def test_run_json_and_npz_metadata_parse(tmp_path):
    scene = drop_scene(0.05)
    traj = simulate(scene)
    files = save(traj, tmp_path, "drop", {"scene": {"body": {"mass": 10.0}}})
    meta = json.loads(files["json"].read_text())
    assert meta["scene"] == {"body": {"mass": 10.0}}
    assert meta["rows"] == len(traj.t) and meta["method"] == scene.method
    assert [c["name"] for c in meta["columns"]] == trajectory_columns(1)
    assert all(c["unit"] == column_unit(c["name"]) for c in meta["columns"])
    with np.load(files["npz"], allow_pickle=False) as z:
        assert json.loads(str(z["metadata"]))["rows"] == len(traj.t)
        assert list(z["units"]) == [column_unit(c) for c in trajectory_columns(1)]


def test_events_match_the_contact_history():
    traj = simulate(drop_scene())
    c = traj.contact[:, 0] > 0.5
    downs = traj.t[1:][~c[:-1] & c[1:]]
    ups = traj.t[1:][c[:-1] & ~c[1:]]
    assert downs.size == 1 and ups.size == 1
    kinds = {(e["kind"], e["time"]) for e in traj.events}
    assert ("touchdown", downs[0]) in kinds and ("lift-off", ups[0]) in kinds


def test_blocks_are_bit_identical_to_one_rollout(monkeypatch):
    scene = drop_scene(0.1)
    model = build_model(scene)
    whole = simulate(scene, model=model)        # 100 steps: one block
    monkeypatch.setattr(driver, "BLOCK_STEPS", 17)
    blocks = simulate(scene, model=model)       # 5 blocks of 17 and one of 15
    np.testing.assert_array_equal(blocks.rows, whole.rows)


def test_streamed_run_writes_every_row_and_keeps_few(tmp_path, monkeypatch):
    monkeypatch.setattr(driver, "BLOCK_STEPS", 40)
    scene = drop_scene(0.25)
    full = simulate(scene)
    directory = result_dir(tmp_path, "drop")
    with ResultWriter(directory, trajectory_columns(1)) as writer:
        kept = simulate(scene, sink=writer, keep_rows=30)
        writer.finish(kept.info)
    assert len(kept.t) <= 2 * 30 + 1 and kept.info["stride"] > 1
    assert kept.t[-1] == full.t[-1]              # the last row is always kept
    back = Trajectory.load(directory)
    np.testing.assert_array_equal(back.rows, full.rows)


def test_thinned_run_ends_on_its_last_row_when_the_last_block_keeps_none(monkeypatch):
    # blocks of 7 steps against a stride that grows past 7: some blocks, the last
    # among them, hold no kept row; the run must still end on its final state
    monkeypatch.setattr(driver, "BLOCK_STEPS", 7)
    scene = drop_scene(0.25)
    full = simulate(scene)
    kept = simulate(scene, keep_rows=3)
    assert kept.info["stride"] > driver.BLOCK_STEPS
    last_block = np.arange(len(full.t) - 1)[-((len(full.t) - 1) % 7 or 7):]
    assert not np.any(last_block % kept.info["stride"] == 0)   # the case this test is for
    assert kept.t[-1] == full.t[-1]
    np.testing.assert_array_equal(kept.rows[-1], full.rows[-1])
    assert np.isin(kept.t, full.t).all()


def test_zero_gravity_writes_finite_columns(tmp_path):
    scene = drop_scene(0.2, gravity=(0.0, 0.0, 0.0))
    traj = simulate(scene)
    files = save(traj, tmp_path, "drop")
    data = np.load(files["npz"])["data"]
    assert np.all(np.isfinite(data))
    text = files["csv"].read_text()
    assert "nan" not in text.lower() and "inf" not in text.lower()
    assert np.isfinite(traj.rod_angle).all()
    back = Trajectory.load(tmp_path / "drop")     # the vertical (+z) comes back with it
    np.testing.assert_array_equal(back.rod_angle, traj.rod_angle)


def test_monitor_findings_become_events_and_warnings(tmp_path):
    monitor = FakeMonitor()
    scene = drop_scene(0.05)
    with pytest.warns(RunWarning, match="fake finding"):
        traj = simulate(scene, monitor=monitor)
    t, x_shape, y_shape = monitor.calls[0]
    model = build_model(scene)
    assert x_shape == (model.nx, len(t)) and y_shape == (model.ny, len(t))
    assert [w["message"] for w in traj.info["warnings"]] == ["fake finding"]
    assert any(e["kind"] == "warning" for e in traj.events)
    files = save(traj, tmp_path, "drop")
    meta = json.loads(files["json"].read_text())
    assert meta["warnings"][0]["details"] == {"check": "fake", "message": "fake finding"}


def test_monitor_without_check_is_rejected():
    with pytest.raises(TypeError, match="`monitor`"):
        simulate(drop_scene(0.01), monitor=object())


def test_simulate_loads_a_path_and_names_a_missing_file_or_a_wrong_type():
    with pytest.raises(FileNotFoundError, match="x.toml"):
        simulate("x.toml")
    with pytest.raises(TypeError, match="`scene` must be a Scene"):
        simulate(42)
    traj = simulate(str(ROOT / "studies" / "fig3.toml"), monitor=False)
    assert traj.info["name"] == "fig3"


def test_out_paths_are_checked(tmp_path):
    afile = tmp_path / "afile"
    afile.write_text("x")
    with pytest.raises(ValueError, match="is a file"):
        check_out_dir(afile)
    with pytest.raises(ValueError, match="lies under .*afile"):
        check_out_dir(afile / "sub")
    for bad in ("../escaped", "/abs", "..", "a/b", ""):
        with pytest.raises(ValueError, match="name"):
            result_dir(tmp_path / "out", bad)
    assert not (tmp_path / "escaped").exists()
    assert result_dir(tmp_path / "out", "ok") == tmp_path / "out" / "ok"


def test_failed_write_keeps_the_previous_files(tmp_path):
    traj = simulate(drop_scene(0.05))
    files = save(traj, tmp_path, "drop")
    before = {k: p.read_bytes() for k, p in files.items()}
    with pytest.raises(RuntimeError):
        with ResultWriter(tmp_path / "drop", trajectory_columns(1)) as writer:
            writer.append(traj.rows[:3])
            raise RuntimeError("killed while writing")
    assert {k: p.read_bytes() for k, p in files.items()} == before
    assert sorted(p.name for p in (tmp_path / "drop").iterdir()) == sorted(
        ["trajectory.csv", "trajectory.npz", "trajectory.mat", JSON_NAME])


def test_to_dataframe_says_how_to_get_pandas(monkeypatch):
    traj = simulate(drop_scene(0.01))
    monkeypatch.setitem(sys.modules, "pandas", None)
    with pytest.raises(ImportError, match="pip install pandas"):
        traj.to_dataframe()


def test_fig3_stream_matches_the_paper_scene_rows(tmp_path):
    """A whole Fig. 3 run through the writer equals the in-memory run, with finite rows."""
    scene = load_scene(ROOT / "studies" / "fig3.toml").with_(duration=0.05)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        traj = simulate(scene)
    files = save(traj, tmp_path, scene.name)
    back = Trajectory.load(files["csv"].parent)
    np.testing.assert_array_equal(back.rows, traj.rows)
    assert np.all(np.isfinite(back.rows))
