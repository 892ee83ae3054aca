"""Command line: help, version, overrides, output checks before the run, killed runs."""
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from symcushion import __version__, cli
from symcushion.run import interrupts

ROOT = Path(__file__).resolve().parents[1]
FIG3 = ROOT / "studies" / "fig3.toml"
COMMANDS = ("reproduce", "simulate", "plot", "codegen", "optimise", "envelope")

#: Seconds a killed run may take to exit after SIGTERM.
KILL_TIMEOUT = 60
#: Simulated time of a run that is killed while it writes (s): 10⁶ steps of
#: Fig. 3, many seconds of writing, so that SIGTERM arrives before the run
#: ends (100 s, 10⁵ steps, sometimes finished between two polls).
KILLED_DURATION = 1000.0


def test_version(capsys):
    with pytest.raises(SystemExit) as exc:
        cli.main(["--version"])
    assert exc.value.code == 0
    assert capsys.readouterr().out.strip() == f"symcushion {__version__}"


@pytest.mark.parametrize("command", (None,) + COMMANDS)
def test_every_help_is_plain_text(command, capsys):
    with pytest.raises(SystemExit) as exc:
        cli.main(([command] if command else []) + ["--help"])
    assert exc.value.code == 0
    text = capsys.readouterr().out
    assert "usage: symcushion" in text and "`" not in text
    if command == "simulate":
        for option in ("--duration", "--dt", "--mu", "--method", "--no-plots", "--strict",
                       "--out"):
            assert option in text
        assert "(default: out)" in text


def test_simulate_overrides_apply(tmp_path, capsys):
    code = cli.main(["simulate", str(FIG3), "--out", str(tmp_path), "--duration", "0.02",
                     "--dt", "0.002", "--mu", "0.1", "--method", "robust", "--no-plots"])
    assert code == 0
    meta = json.loads((tmp_path / "fig3" / "run.json").read_text())
    summary = meta["scene_summary"]
    assert (summary["duration"], summary["dt"], summary["mu"], summary["method"]) == \
        (0.02, 0.002, 0.1, "robust")
    assert meta["steps"] == 10 and meta["rows"] == 11
    assert meta["overrides"] == {"duration": 0.02, "dt": 0.002, "mu": 0.1, "method": "robust"}
    assert meta["scene"]["body"]["mass"] == 50.0        # the scene file as loaded
    assert set(meta["versions"]) >= {"symcushion", "casadi", "numpy"}
    assert not (tmp_path / "fig3" / "summary.png").exists()


def test_simulate_writes_figures(tmp_path):
    code = cli.main(["simulate", str(FIG3), "--out", str(tmp_path), "--duration", "0.05",
                     "--frames", "5"])
    assert code == 0
    from PIL import Image

    with Image.open(tmp_path / "fig3" / "animation.gif") as gif:
        assert gif.n_frames == 5
    assert (tmp_path / "fig3" / "summary.png").stat().st_size > 10_000
    (tmp_path / "fig3" / "summary.png").unlink()
    assert cli.main(["plot", str(tmp_path / "fig3"), "--no-animation"]) == 0
    assert (tmp_path / "fig3" / "summary.png").is_file()


@pytest.mark.parametrize("where", ("file", "under_file"))
def test_bad_out_fails_before_the_run(tmp_path, monkeypatch, capsys, where):
    def no_build(*args, **kwargs):
        raise AssertionError("the model was built before the output path was checked")

    monkeypatch.setattr("symcushion.scheme.touchdown.build_model", no_build)   # what the CLI calls
    afile = tmp_path / "afile"
    afile.write_text("x")
    out = afile if where == "file" else afile / "sub"
    assert cli.main(["simulate", str(FIG3), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "`--out`" in err and "file" in err and "Traceback" not in err


def test_codegen_checks_out_first(tmp_path, capsys):
    afile = tmp_path / "afile"
    afile.write_text("x")
    assert cli.main(["codegen", "--out", str(afile / "c")]) == 2
    assert "`out_dir`" in capsys.readouterr().err


def test_scene_name_cannot_escape_out(tmp_path, capsys):
    text = FIG3.read_text().replace('name = "fig3"', 'name = "../escaped"')
    scene = tmp_path / "escape.toml"
    scene.write_text(text)
    assert cli.main(["simulate", str(scene), "--out", str(tmp_path / "out"), "--no-plots"]) == 2
    assert "plain file name" in capsys.readouterr().err
    assert not (tmp_path / "escaped").exists()


@pytest.mark.parametrize("args, field", ((["--dt", "-1"], "--dt"),
                                         (["--duration", "0"], "--duration"),
                                         (["--mu", "-0.1"], "--mu")))
def test_bad_overrides_name_the_option(tmp_path, capsys, args, field):
    assert cli.main(["simulate", str(FIG3), "--out", str(tmp_path)] + args) == 2
    assert f"`{field}`" in capsys.readouterr().err


def test_strict_turns_warnings_into_an_exit_status(tmp_path, monkeypatch, capsys):
    from test_results import FakeMonitor

    monkeypatch.setattr(cli, "_run_monitor", lambda scene, model: FakeMonitor())
    base = ["simulate", str(FIG3), "--out", str(tmp_path), "--duration", "0.02", "--no-plots"]
    assert cli.main(base) == 0
    assert "warning: t = " in capsys.readouterr().err
    assert cli.main(base + ["--strict", "--overwrite"]) == cli.EXIT_WARNINGS
    meta = json.loads((tmp_path / "fig3" / "run.json").read_text())
    assert meta["warnings"][0]["message"] == "fake finding"


def test_reproduce_writes_a_new_folder_not_figures(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    code = cli.main(["reproduce", "--scenes", str(ROOT / "studies"), "--duration", "0.01"])
    assert code == 0
    assert (tmp_path / "out" / "reproduce" / "claims.md").is_file()
    assert not (tmp_path / "figures").exists()
    assert cli.main(["reproduce", "--out", "x", "--update-figures"]) == 2


def _run_and_kill(out: Path, duration: float, sig=signal.SIGTERM, extra=()):
    """Start a long simulate in a subprocess; send ``sig`` while it writes; wait for it."""
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    proc = subprocess.Popen([sys.executable, "-m", "symcushion.cli", "simulate", str(FIG3),
                             "--out", str(out), "--duration", str(duration), "--no-plots",
                             *extra], env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    directory = out / "fig3"
    deadline = time.monotonic() + KILL_TIMEOUT
    while time.monotonic() < deadline:        # wait for rows in the temporary CSV
        tmp = [p for p in directory.glob(".trajectory.csv.*")] if directory.is_dir() else []
        if tmp and tmp[0].stat().st_size > 100_000:
            break
        time.sleep(0.05)
    else:
        proc.kill()
        pytest.fail("the run never started writing")
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=KILL_TIMEOUT)
    _run_and_kill.stderr = err.decode(errors="replace")[-2000:]   # for the failure message
    return proc.returncode, directory


def _assert_whole_interrupted_run(directory):
    """The files of an interrupted run: whole, the same rows, marked in run.json."""
    from symcushion.run.results import RUN_FILES

    assert {p.name for p in directory.iterdir()} <= set(RUN_FILES) | {"notes.txt"}
    meta = json.loads((directory / "run.json").read_text())
    assert meta["status"] == "interrupted"
    with np.load(directory / "trajectory.npz") as z:
        data = z["data"]
    lines = (directory / "trajectory.csv").read_text().splitlines()
    assert data.shape[0] == meta["rows"] == len(lines) - 1 > 1
    assert data[-1, 0] == meta["t_end"] == float(lines[-1].split(",")[0])
    assert all(e["time"] <= meta["t_end"] for e in meta["events"])
    return meta


def test_killed_run_keeps_its_finished_blocks_in_place_of_the_previous(tmp_path):
    out = tmp_path / "out"
    assert cli.main(["simulate", str(FIG3), "--out", str(out), "--duration", "0.03",
                     "--no-plots"]) == 0
    (out / "fig3" / "summary.png").write_text("a figure of the earlier run")
    (out / "fig3" / "notes.txt").write_text("the user's own file")
    code, directory = _run_and_kill(out, KILLED_DURATION, extra=["--overwrite"])
    assert code == 128 + signal.SIGTERM, _run_and_kill.stderr
    meta = _assert_whole_interrupted_run(directory)
    assert meta["rows"] > 31                              # the new run's, not the earlier one's
    assert not (directory / "summary.png").exists()       # stale: not of this run
    assert (directory / "notes.txt").read_text() == "the user's own file"


def test_ctrl_c_ends_simulate_cleanly_keeping_the_finished_blocks(tmp_path):
    code, directory = _run_and_kill(tmp_path / "out", KILLED_DURATION, sig=signal.SIGINT)
    err = _run_and_kill.stderr
    assert code == 130, err
    assert "Traceback" not in err and "KeyboardInterrupt" not in err
    last = err.strip().splitlines()[-1]
    assert last.startswith("symcushion simulate: interrupted (exit 130)") and "t = " in last
    _assert_whole_interrupted_run(directory)


def _wrapped_termination(args):
    """A termination that surfaces, as from a C extension, as a SystemError."""
    try:
        raise cli.Terminated(128 + signal.SIGTERM)
    except cli.Terminated as exc:
        raise SystemError("returned a result with an exception set") from exc


@pytest.mark.parametrize("raised", (_wrapped_termination,
                                    lambda args: interrupts.terminate(signal.SIGTERM, None)))
def test_termination_inside_a_c_extension_still_exits_with_the_signal_code(
        tmp_path, monkeypatch, capsys, raised):
    monkeypatch.setattr(cli, "_cmd_simulate", raised)
    code = cli.main(["simulate", str(FIG3), "--out", str(tmp_path / "out"), "--no-plots"])
    assert code == 128 + signal.SIGTERM
    assert "terminated" in capsys.readouterr().err


#: Seconds a run that swallowed its SIGTERM goes on before the test gives up.
SWALLOWED_RUN = 5.0


def _swallowing_run(replace_with=None):
    """A run whose SIGTERM is raised inside code that clears the error, as SWIG's
    overload dispatch does; it would go on for :data:`SWALLOWED_RUN` s."""
    def run(args):
        try:
            interrupts.terminate(signal.SIGTERM, None)
        except BaseException:
            if replace_with is not None:
                raise replace_with from None
        deadline = time.monotonic() + SWALLOWED_RUN
        while time.monotonic() < deadline:
            sum(range(1000))
        return 0
    return run


@pytest.mark.parametrize("replace_with", (None, NotImplementedError("Wrong number or type")))
def test_a_swallowed_termination_is_raised_again(tmp_path, monkeypatch, capsys, replace_with):
    monkeypatch.setattr(cli, "_cmd_simulate", _swallowing_run(replace_with))
    code = cli.main(["simulate", str(FIG3), "--out", str(tmp_path / "out"), "--no-plots"])
    assert code == 128 + signal.SIGTERM     # a lost termination would let the run return 0
    assert "terminated" in capsys.readouterr().err
    assert interrupts.pending() is None
    assert signal.getitimer(signal.ITIMER_REAL) == (0.0, 0.0)


def test_the_reminder_does_not_interrupt_cleanup(tmp_path, monkeypatch):
    cleaned = []

    def run(args):
        try:
            interrupts.terminate(signal.SIGTERM, None)
        finally:
            time.sleep(3 * interrupts.TERMINATION_REMINDER)    # reminders fall due here
            cleaned.append(True)
    monkeypatch.setattr(cli, "_cmd_simulate", run)
    code = cli.main(["simulate", str(FIG3), "--out", str(tmp_path / "out"), "--no-plots"])
    assert code == 128 + signal.SIGTERM and cleaned == [True]


def test_other_errors_from_c_extensions_are_not_taken_for_termination(tmp_path, monkeypatch):
    def broken(args):
        raise SystemError("a real bug")
    monkeypatch.setattr(cli, "_cmd_simulate", broken)
    with pytest.raises(SystemError, match="a real bug"):
        cli.main(["simulate", str(FIG3), "--out", str(tmp_path / "out"), "--no-plots"])


@pytest.mark.parametrize("command", (["optimise", str(ROOT / "studies" / "absorber_1d.toml")],
                                     ["envelope", str(ROOT / "studies" / "envelope_lander.toml")],
                                     ["design", str(ROOT / "studies" / "design_for_envelope.toml")]))
def test_study_outputs_are_checked_before_the_work(tmp_path, capsys, command):
    afile = tmp_path / "afile"
    afile.write_text("x")
    out = afile / "result.json" if command[0] == "optimise" else afile
    assert cli.main(command + ["--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "`--out`" in err and "file" in err


@pytest.mark.parametrize("flag, value", (("--max-iter", "0"), ("--n", "0")))
def test_design_rejects_bad_counts_before_the_work(tmp_path, capsys, flag, value):
    code = cli.main(["design", str(ROOT / "studies" / "design_for_envelope.toml"),
                     "--out", str(tmp_path / "out"), flag, value])
    assert code == 2
    err = capsys.readouterr().err
    assert f"`{flag}`" in err and "positive integer" in err
