"""What a new user must be able to trust: exit statuses, interrupted and resumed
runs, output folders that are never silently mixed, angles in explicit units,
``symcushion check`` on every kind of file."""
import json
import re
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from symcushion import cli
from symcushion.run.results import (RUN_FILES, OutputExists, ResultWriter, claim_output,
    remove_stale)

ROOT = Path(__file__).resolve().parents[1]
FIG3 = ROOT / "studies" / "fig3.toml"
#: Seconds a subprocess may take to exit after its signal.
SIGNAL_TIMEOUT = 60


def fig3_variant(tmp_path, name="fig3", **replace) -> Path:
    """studies/fig3.toml with some lines replaced (``old=new`` pairs of text)."""
    text = FIG3.read_text()
    for old, new in replace.values():
        assert old in text, old
        text = text.replace(old, new)
    path = tmp_path / f"{name}.toml"
    path.write_text(text)
    return path


def simulate(*args):
    return cli.main(["simulate", *map(str, args), "--no-plots"])


# ---------------------------------------------------------------------------
# output folders
# ---------------------------------------------------------------------------
def test_a_second_run_into_a_folder_is_refused_without_overwrite(tmp_path, capsys):
    out = tmp_path / "out"
    assert simulate(FIG3, "--out", out, "--duration", "0.02") == 0
    before = {p.name: p.read_bytes() for p in (out / "fig3").iterdir()}
    assert simulate(FIG3, "--out", out, "--duration", "0.03") == cli.EXIT_OUTPUT_EXISTS
    err = capsys.readouterr().err
    assert "already holds the results of another run" in err and "`--overwrite`" in err
    assert {p.name: p.read_bytes() for p in (out / "fig3").iterdir()} == before


def test_two_scenes_with_one_name_do_not_overwrite_each_other(tmp_path, capsys):
    other = fig3_variant(tmp_path, "other", v=("velocity = [0.0, 0.0, -0.5]",
                                              "velocity = [0.0, 0.0, -0.4]"))
    out = tmp_path / "out"
    assert simulate(FIG3, "--out", out, "--duration", "0.02") == 0
    assert simulate(other, "--out", out, "--duration", "0.02") == cli.EXIT_OUTPUT_EXISTS
    assert "fig3" in capsys.readouterr().err
    assert json.loads((out / "fig3" / "run.json").read_text())["scene_file"] == str(FIG3)


def test_overwrite_removes_only_the_stale_files_it_owns(tmp_path):
    out = tmp_path / "out"
    assert simulate(FIG3, "--out", out, "--duration", "0.02") == 0
    folder = out / "fig3"
    (folder / "summary.png").write_text("the earlier run's figure")
    (folder / "animation.gif").write_text("the earlier run's animation")
    (folder / "notes.md").write_text("mine")
    assert simulate(FIG3, "--out", out, "--duration", "0.03", "--overwrite") == 0
    assert sorted(p.name for p in folder.iterdir()) == ["notes.md", "run.json",
                                                        "trajectory.csv", "trajectory.mat",
                                                        "trajectory.npz"]
    assert json.loads((folder / "run.json").read_text())["rows"] == 31


def test_claim_output_and_remove_stale_touch_only_their_names(tmp_path):
    assert claim_output(tmp_path, RUN_FILES) == []
    (tmp_path / "run.json").write_text("{}")
    (tmp_path / "batches").mkdir()
    (tmp_path / "batches" / "b.npz").write_text("x")
    (tmp_path / "foreign.txt").write_text("x")
    with pytest.raises(OutputExists, match=r"run\.json.*`--overwrite`"):
        claim_output(tmp_path, RUN_FILES, argument="--out")
    assert claim_output(tmp_path, RUN_FILES, overwrite=True) == [tmp_path / "run.json"]
    removed = remove_stale(tmp_path, ("run.json", "batches", "summary.png"), keep=["run.json"])
    assert removed == [tmp_path / "batches"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["foreign.txt", "run.json"]


@pytest.mark.parametrize("command, out, result", (
    (["optimise", ROOT / "studies" / "absorber_1d.toml"], "design.json", "design.json"),
    (["design", ROOT / "studies" / "design_for_envelope.toml"], "d", "d/curves.png"),
    (["reproduce", "--scenes", ROOT / "studies"], "r", "r/claims.md"),
    (["envelope", ROOT / "studies" / "envelope_lander.toml"], "e", "e/summary.json")))
def test_every_study_command_refuses_another_runs_results_before_the_work(
        tmp_path, monkeypatch, capsys, command, out, result):
    def no_work(*args, **kwargs):
        raise AssertionError("the work started before the output was checked")
    for name in ("design.robust.study.run_robust_study", "reproduce.reproduce",
                 "envelope.run_envelope"):
        monkeypatch.setattr(f"symcushion.{name}", no_work)
    (tmp_path / result).parent.mkdir(parents=True, exist_ok=True)
    (tmp_path / result).write_text("an earlier run's result")
    code = cli.main([*map(str, command), "--out", str(tmp_path / out)])
    assert code == cli.EXIT_OUTPUT_EXISTS, capsys.readouterr().err
    assert "`--overwrite`" in capsys.readouterr().err
    assert (tmp_path / result).read_text() == "an earlier run's result"


# ---------------------------------------------------------------------------
# errors and warnings of a run
# ---------------------------------------------------------------------------
def test_a_run_with_an_error_exits_non_zero_and_keeps_its_marked_results(tmp_path, capsys):
    fast = fig3_variant(tmp_path, v=("velocity = [0.0, 0.0, -0.5]",
                                     "velocity = [0.0, 0.0, -100.0]"))
    out = tmp_path / "out"
    assert simulate(fast, "--out", out, "--duration", "0.02") == cli.EXIT_ERRORS == 1
    err = capsys.readouterr().err
    assert "error: t = " in err and "passed through the obstacle" in err
    # while it runs, an error is printed as one, at the finding's own time
    live = [line for line in err.splitlines() if "passed through" in line][0]
    found_at = re.search(r"at t = ([0-9.e-]+) s", live).group(1)
    assert live.startswith(f"error: t = {float(found_at):.4g} s")
    meta = json.loads((out / "fig3" / "run.json").read_text())
    assert meta["status"] == "errors" and meta["errors"] >= 2
    assert {"pass_through", "body_inside"} <= {w["details"]["kind"] for w in meta["warnings"]
                                               if w["severity"] == "error"}
    assert (out / "fig3" / "trajectory.csv").is_file()


def test_warnings_stay_warnings_and_a_clean_run_is_complete(tmp_path, monkeypatch, capsys):
    from test_results import FakeMonitor

    monkeypatch.setattr(cli, "_run_monitor", lambda scene, model: FakeMonitor())
    assert simulate(FIG3, "--out", tmp_path / "a", "--duration", "0.02") == 0
    meta = json.loads((tmp_path / "a" / "fig3" / "run.json").read_text())
    assert meta["status"] == "complete" and meta["errors"] == 0 and meta["touched_down"]


def test_a_run_that_never_touches_down_says_so(tmp_path, capsys):
    high = fig3_variant(tmp_path, p=("position = [0.0, 0.0, 1.18]",
                                     "position = [0.0, 0.0, 11.18]"))
    assert simulate(high, "--out", tmp_path / "out", "--duration", "0.05") == 0
    assert "warning: no foot touched an obstacle in the 0.05 s" in capsys.readouterr().err
    meta = json.loads((tmp_path / "out" / "fig3" / "run.json").read_text())
    assert meta["touched_down"] is False
    assert [w["details"]["kind"] for w in meta["warnings"]] == ["no_touchdown"]
    assert simulate(high, "--out", tmp_path / "out", "--duration", "0.05", "--overwrite",
                    "--strict") == cli.EXIT_WARNINGS


# ---------------------------------------------------------------------------
# interrupts
# ---------------------------------------------------------------------------
def test_an_interrupt_inside_an_append_keeps_the_blocks_before_it(tmp_path):
    columns = ["time_s", "body_position_z_m"]
    writer = ResultWriter(tmp_path, columns)
    writer.append(np.array([[0.0, 1.0], [0.1, 0.9]]))

    def interrupted(data):
        raise KeyboardInterrupt
    writer._raw.write = interrupted             # the CSV half of the block is written
    with pytest.raises(KeyboardInterrupt):
        writer.append(np.array([[0.2, 0.8]]))
    files = writer.finish({"status": "interrupted"})
    assert files["csv"].read_text() == "time_s,body_position_z_m\n0,1\n0.10000000000000001,0.90000000000000002\n"
    with np.load(files["npz"]) as z:
        np.testing.assert_array_equal(z["data"], [[0.0, 1.0], [0.1, 0.9]])
    assert json.loads(files["json"].read_text())["rows"] == 2
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(files[k].name for k in files)


def test_keyboard_interrupt_in_any_command_is_exit_130_without_traceback(tmp_path, monkeypatch,
                                                                         capsys):
    def interrupted(args):
        raise KeyboardInterrupt
    monkeypatch.setattr(cli, "_cmd_check", interrupted)
    before = signal.getsignal(signal.SIGINT)    # default_int_handler, or SIG_IGN when the
    assert cli.main(["check", str(FIG3)]) == 130  # suite itself runs in the background
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("symcushion check: interrupted (exit 130)")
    assert signal.getsignal(signal.SIGINT) is before       # the command's handler is undone


# ---------------------------------------------------------------------------
# an envelope interrupted and resumed
# ---------------------------------------------------------------------------
#: A small, quick envelope study: the example lander with the cheap step, 600
#: cases of 2 s in batches of 10 (one thread: ~40 ms a batch, ~2.5 s in all),
#: long enough to be interrupted after its first batches.
SMALL_STUDY = {"method": 'method = "robust"', "slip": 'slip = "backward"',
               "events": 'events = "none"', "dt": "dt = 1e-3", "duration": "duration = 2.0",
               "n": "n = 600\nbatch = 10"}


def small_study(tmp_path) -> Path:
    lines = []
    for line in (ROOT / "studies" / "envelope_lander.toml").read_text().splitlines():
        key = line.split("=")[0].strip()
        if key in SMALL_STUDY and not (key == "method" and "sobol" in line):
            line = SMALL_STUDY[key]
        lines.append(line)
    path = tmp_path / "small.toml"
    path.write_text("\n".join(lines) + "\n")
    return path


def envelope(study, out, *extra):
    return cli.main(["envelope", str(study), "--out", str(out), "--threads", "1",
                     "--build-dir", str(out.parent / "build"), *map(str, extra)])


def test_an_interrupted_envelope_resumes_to_the_same_cases(tmp_path, capsys):
    study = small_study(tmp_path)
    assert envelope(study, tmp_path / "full") == 0            # also compiles the library
    part = tmp_path / "part"
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    proc = subprocess.Popen([sys.executable, "-m", "symcushion.cli", "envelope", str(study),
                             "--out", str(part), "--threads", "1",
                             "--build-dir", str(tmp_path / "build")],
                            env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    deadline = time.monotonic() + SIGNAL_TIMEOUT
    while not (part / "batches" / "batch_000001.npz").is_file():
        if time.monotonic() > deadline or proc.poll() is not None:
            proc.kill()
            pytest.fail("the envelope never finished a batch")
        time.sleep(0.01)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=SIGNAL_TIMEOUT)
    err = err.decode(errors="replace")
    assert proc.returncode == 130, err
    assert "Traceback" not in err and "--resume" in err.strip().splitlines()[-1]
    kept = sorted(p.name for p in (part / "batches").glob("batch_*.npz"))
    assert 2 <= len(kept) < 60 and not (part / "cases.csv").exists()
    # the folder is not silently taken over by a fresh run
    assert envelope(study, part) == cli.EXIT_OUTPUT_EXISTS
    assert "--resume" in capsys.readouterr().err
    # another study's batches are never combined with these
    assert envelope(study, part, "--resume", "--seed", "7") == cli.EXIT_BAD_INPUT
    assert "another study" in capsys.readouterr().err
    assert envelope(study, part, "--resume") == 0
    assert (part / "cases.csv").read_bytes() == (tmp_path / "full" / "cases.csv").read_bytes()
    assert not (part / "batches").exists()
    assert json.loads((part / "summary.json").read_text())["timings"]["resumed_cases"] \
        == 10 * len(kept)
    assert envelope(study, part, "--resume") == cli.EXIT_BAD_INPUT      # nothing to resume
    assert "complete" in capsys.readouterr().err


# ---------------------------------------------------------------------------
# angles
# ---------------------------------------------------------------------------
def _slope_scene():
    from symcushion.model.scene import read_toml

    return read_toml(ROOT / "studies" / "lander_slope.toml")


def _load(data, source="lander.toml"):
    from symcushion.model.scene import scene_from_dict

    return scene_from_dict(data, source)


def test_angle_fields_take_degrees_with_deg_bit_for_bit():
    data = _slope_scene()
    base = _load(data)
    ob, legs = data["obstacle"][0], data["legs"]
    ob["angle_deg"] = 10
    legs["azimuth0_deg"] = 45.0
    del ob["angle"], legs["azimuth0"]
    scene = _load(data)
    assert np.array_equal(scene.obstacles[0].n, base.obstacles[0].n)
    for a, b in zip(scene.legs, base.legs):
        assert np.array_equal(a.hinge, b.hinge)


@pytest.mark.parametrize("table, key, value", (("obstacle", "angle", 12.0),
                                               ("obstacle", "angle", -2),
                                               ("legs", "azimuth0", 45)))
def test_implausible_radians_name_the_field_value_and_the_deg_field(table, key, value):
    from symcushion.model.scene import SceneError

    data = _slope_scene()
    (data[table][0] if table == "obstacle" else data[table])[key] = value
    with pytest.raises(SceneError) as err:
        _load(data)
    where = f"obstacle[0].{key}" if table == "obstacle" else f"legs.{key}"
    assert f"`{where}` = {value!r}" in str(err.value)
    assert f"`{key}_deg = {value!r}`" in str(err.value) and "radians" in str(err.value)


def test_an_angle_in_both_units_is_an_error_reported_with_the_others():
    from symcushion.model.scene import SceneError

    data = _slope_scene()
    data["obstacle"][0]["angle_deg"] = 10
    data["legs"]["azimuth0"] = 90
    with pytest.raises(SceneError) as err:
        _load(data)
    assert len(err.value.problems) == 2
    assert "give either `obstacle[0].angle` (radians) or `obstacle[0].angle_deg`" in str(err.value)


def test_study_limits_take_either_unit_and_refuse_degrees_as_radians():
    import symcushion.envelope as ev
    from symcushion.model.scene import read_toml

    raw = read_toml(ROOT / "studies" / "envelope_lander.toml")
    limits = raw["limits"]
    assert ev.study_from_dict(raw, "s.toml").limits.tilt_deg == 35.0
    del limits["tilt_deg"], limits["beta"]
    limits.update(tilt=0.5, beta_deg=3.0)
    got = ev.study_from_dict(raw, "s.toml").limits
    assert got.tilt_deg == pytest.approx(np.degrees(0.5)) and got.beta == pytest.approx(np.radians(3))
    limits["tilt"] = 35.0
    with pytest.raises(ValueError, match=r"`limits.tilt` = 35.0 is not plausible in radians.*"
                                         r"`tilt_deg = 35.0`"):
        ev.study_from_dict(raw, "s.toml")


def test_the_design_tilt_limit_takes_degrees_too():
    from symcushion.design.optimise.study import study_from_dict
    from symcushion.model.scene import read_toml

    raw = read_toml(ROOT / "studies" / "absorber_1d.toml")
    raw.setdefault("limits", {})["tilt_deg"] = 30.0
    assert study_from_dict(raw, "a.toml").problem.limits.tilt == pytest.approx(np.radians(30))
    raw["limits"] = {"tilt": 30.0}
    with pytest.raises(ValueError, match="`tilt_deg = 30.0`"):
        study_from_dict(raw, "a.toml")


# ---------------------------------------------------------------------------
# symcushion check on every kind of file
# ---------------------------------------------------------------------------
@pytest.mark.parametrize("name, kind", (("envelope_lander.toml", "envelope"),
                                        ("design_for_envelope.toml", "design"),
                                        ("absorber_1d.toml", "optimise"),
                                        ("fig3.toml", "scene")))
def test_check_takes_scene_and_study_files(name, kind, capsys):
    assert cli.main(["check", str(ROOT / "studies" / name)]) == 0
    assert capsys.readouterr().out.strip().endswith(f"{kind} file, 0 error(s), 0 warning(s)")


def test_check_reports_every_bad_scene_field_of_a_study_at_once(tmp_path, capsys):
    text = (ROOT / "studies" / "envelope_lander.toml").read_text()
    text = text.replace("mass = 150.0", "mass = -150.0").replace("[legs]\n", "[legs]\nradus = 1\n")
    bad = tmp_path / "bad_study.toml"
    bad.write_text(text)
    assert cli.main(["check", str(bad)]) == cli.EXIT_ERRORS
    err = capsys.readouterr().err
    assert "2 problems" in err and "`body.mass`" in err and "did you mean 'radius'" in err


def test_check_reads_standard_input(monkeypatch, capsys):
    import io

    monkeypatch.setattr(sys, "stdin", io.StringIO(FIG3.read_text()))
    assert cli.main(["check", "-"]) == 0
    assert capsys.readouterr().out.strip() == "<stdin>: scene file, 0 error(s), 0 warning(s)"
    monkeypatch.setattr(sys, "stdin", io.StringIO("[scene]\nmu = -1\n"))
    assert cli.main(["check", "-"]) == cli.EXIT_ERRORS
    err = capsys.readouterr().err
    assert err.startswith("symcushion check: error: <stdin>: 4 problems") and "`scene.mu`" in err


# ---------------------------------------------------------------------------
# what a warning suggests is what the command line offers
# ---------------------------------------------------------------------------
def test_an_unstable_step_suggests_the_cli_options_and_stability_runs(tmp_path, capsys):
    args = ("--out", tmp_path, "--dt", "0.005", "--duration", "0.05")
    assert simulate(FIG3, *args) == 0
    err = capsys.readouterr().err
    assert "--dt 0.00143" in err and "--stability" in err
    assert simulate(FIG3, *args, "--overwrite", "--stability") == 0
    meta = json.loads((tmp_path / "fig3" / "run.json").read_text())
    assert meta["stability"] and meta["stability_capped"] > 0 and meta["warnings"] == []


def test_the_energy_growth_message_names_one_time_and_the_cli_options():
    from symcushion.layout.vectors import state_layout
    from symcushion.run.monitor import RunMonitor
    from symcushion.model.scene import load_scene
    from symcushion.scheme.touchdown import initial_state

    scene = load_scene(FIG3)
    x = initial_state(scene)
    xl = state_layout(len(scene.legs))
    X = np.column_stack([x, x])
    X[xl.slice("velocity"), 1] = [0.0, 0.0, 50.0]          # 62.5 kJ from nowhere
    found = RunMonitor(scene).check(np.array([0.001, 0.002]), X, np.zeros((0, 2)))
    (energy,) = [f for f in found if f.kind == "energy_growth"]
    assert energy.time == 0.002 and energy.message.count("t = ") == 1
    assert "--dt" in energy.message and "--stability" in energy.message
