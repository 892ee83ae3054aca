"""docs/tutorial.md: its commands and Python snippets run (short durations)."""
import re
import shlex
from pathlib import Path

import matplotlib
import numpy as np
import pytest

matplotlib.use("Agg")

from symcushion.cli import main as cli  # noqa: E402
from symcushion.model.placement import PLACEMENT_TOL, feet_clearance, place_on_obstacle  # noqa: E402
from symcushion.model.scene import load_scene  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
TUTORIAL = ROOT / "docs" / "tutorial.md"
#: Simulated time of each tutorial run in the test (s): past the first touchdown.
SHORT = "0.03"


def blocks(language):
    text = TUTORIAL.read_text()
    return re.findall(rf"```{language}\n(.*?)```", text, flags=re.S)


def commands():
    """The tutorial's shell commands, continuation lines joined."""
    out = []
    for block in blocks("bash"):
        for line in block.replace("\\\n", " ").splitlines():
            line = line.split("#")[0].strip()
            if line.startswith("symcushion "):
                out.append(shlex.split(line)[1:])
    return out


@pytest.fixture()
def workdir(tmp_path, monkeypatch):
    """A folder where the tutorial's relative paths (studies/tutorial/...) resolve."""
    (tmp_path / "studies").symlink_to(ROOT / "studies")
    (tmp_path / "docs").symlink_to(ROOT / "docs")
    monkeypatch.chdir(tmp_path)
    return tmp_path


def test_the_tutorial_lists_its_commands():
    names = [c[0] for c in commands()]
    assert names.count("simulate") == 2 and {"plot", "optimise", "envelope"} <= set(names)


def test_tutorial_commands_run(workdir, capsys):
    try:
        import plotly  # noqa: F401
        viewer = True
    except ImportError:                 # the tutorial says: with the extra viewer
        viewer = False
    for args in commands():
        command = args[0]
        if command == "view" and not viewer:
            continue
        if command == "simulate":
            args = args + ["--duration", SHORT, "--frames", "3"]
        elif command == "optimise":
            args = args + ["--max-iter", "2"]
        elif command == "envelope":
            # a short copy of the study: 4 cases of 30 ms, compiled into the test folder
            study = workdir / "envelope.toml"
            text = Path(args[1]).read_text().replace("duration = 1.0", f"duration = {SHORT}")
            study.write_text(text)
            args = ["envelope", str(study), "--out", str(workdir / "envelope"), "--n", "4",
                    "--build-dir", str(workdir / "build")]
        code = cli(args)
        assert code in ((0, 1) if command == "optimise" else (0,)), (args, code)
    result = workdir / "out" / "tutorial" / "lander"
    for name in ("trajectory.csv", "trajectory.npz", "trajectory.mat", "run.json",
                 "animation.gif"):
        assert (result / name).is_file(), name
    assert not viewer or (workdir / "out" / "tutorial" / "lander.html").is_file()
    assert (workdir / "out" / "tutorial" / "leg_design.json").is_file()
    assert (workdir / "envelope" / "cases.csv").is_file()
    assert (workdir / "envelope" / "cases.mat").is_file()
    # the Python snippets, in order, in the same folder (they load out/tutorial/lander)
    cli(["simulate", "studies/tutorial/lander.toml", "--out", "out/tutorial", "--duration",
         SHORT, "--no-plots", "--overwrite"])
    try:
        import pandas  # noqa: F401
        skip = ()
    except ImportError:                 # the tutorial says: with pandas installed
        skip = ("to_dataframe",)
    namespace = {}
    for code in blocks("python"):
        code = "\n".join(line for line in code.splitlines()
                         if not any(word in line for word in skip))
        exec(compile(code, str(TUTORIAL), "exec"), namespace)   # noqa: S102 - our own docs
    assert abs(namespace["placed"].body.position[2] - 0.9865992365179502) < 1e-9


def test_the_lander_file_is_placed_as_the_tutorial_says():
    scene = load_scene(ROOT / "studies" / "tutorial" / "lander.toml")
    np.testing.assert_allclose(feet_clearance(scene).min(), 0.001, rtol=0, atol=1e-9)
    placed = place_on_obstacle(scene, clearance=0.001)
    assert abs(placed.body.position[2] - scene.body.position[2]) < 1e-9
    assert abs(feet_clearance(placed).min() - 0.001) <= PLACEMENT_TOL


def test_tutorial_pictures_are_committed():
    for name in re.findall(r"\(\.\./(figures/[^)]+)\)", TUTORIAL.read_text()):
        assert (ROOT / name).is_file(), name
    assert "figures/tutorial/lander_frame.png" in (ROOT / "README.md").read_text()
