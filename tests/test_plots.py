"""Figures of a run, curves on arrays, placing a body on the obstacle."""
from dataclasses import replace
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from PIL import Image  # noqa: E402

from symcushion.viz.animate import animate, draw_frame, frame_indices  # noqa: E402
from symcushion.legs.characteristics import Crushable, Linear, PiecewiseLinear  # noqa: E402
from symcushion.model.placement import PLACEMENT_TOL, feet_clearance, place_on_obstacle  # noqa: E402
from symcushion.viz.plots import summary_figure  # noqa: E402
from symcushion.model.scene import load_scene  # noqa: E402
from symcushion.run.driver import simulate  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def fig3():
    scene = load_scene(ROOT / "studies" / "fig3.toml").with_(duration=0.1)
    return scene, simulate(scene)


def test_summary_figure_has_every_panel_and_the_events(fig3, tmp_path):
    scene, traj = fig3
    fig = summary_figure(traj, tmp_path / "summary.png")
    assert len(fig.axes) == 8
    labels = [ax.get_ylabel() for ax in fig.axes]
    for word in ("height", "velocity", "acceleration", "|P|", "stroke", "β", "γ", "mode"):
        assert any(word in label for label in labels), word
    for ax in fig.axes:
        assert ax.lines, ax.get_ylabel()           # no empty panel
    touchdown = [e["time"] for e in traj.events if e["kind"] == "touchdown"][0]
    xs = [line.get_xdata()[0] for line in fig.axes[0].lines if len(line.get_xdata()) == 2]
    assert touchdown in xs                          # the touchdown is marked
    plt.close(fig)
    assert Image.open(tmp_path / "summary.png").size[0] > 800


def test_animation_has_the_requested_frames(fig3, tmp_path):
    scene, traj = fig3
    path = animate(traj, scene, tmp_path / "animation.gif", frames=7)
    with Image.open(path) as gif:
        assert gif.n_frames == 7
    assert not list(tmp_path.glob(".*"))            # no temporary file left
    assert draw_frame(traj, scene, tmp_path / "frame.png").stat().st_size > 10_000


def test_frame_indices():
    np.testing.assert_array_equal(frame_indices(101, 5), [0, 25, 50, 75, 100])
    np.testing.assert_array_equal(frame_indices(3, 10), [0, 1, 2])
    with pytest.raises(ValueError, match="`frames`"):
        frame_indices(10, 0)


def test_animation_rejects_another_scene(fig3, tmp_path):
    scene, traj = fig3
    with pytest.raises(ValueError, match="legs"):
        animate(traj, scene.with_(legs=scene.legs[:2]), tmp_path / "a.gif")


@pytest.mark.parametrize("curve", (Linear(1e4, preload=5.0), PiecewiseLinear([0, 0.1, 0.2],
                                                                             [0, 100, 400]),
                                   Crushable(2e6, 8e3, unloading=Linear(2e4))))
def test_curves_evaluate_on_arrays_like_on_floats(curve):
    x = np.linspace(-0.05, 0.25, 13)
    for rate in (1.0, -1.0):
        values = curve(x, rate)
        assert values.shape == x.shape
        np.testing.assert_allclose(values, [curve(float(v), rate) for v in x], rtol=0, atol=1e-9)
        np.testing.assert_allclose(curve.slope(x, rate),
                                   [curve.slope(float(v), rate) for v in x], rtol=0, atol=1e-9)
    grid = curve(x.reshape(13, 1), np.array([1.0, -1.0]))        # broadcasting
    assert grid.shape == (13, 2)
    ax = curve.plot(x)
    assert len(ax.lines) >= 1 and ax.get_xlabel().startswith("deflection")
    plt.close(ax.figure)


def test_linear_on_an_array():
    np.testing.assert_allclose(Linear(1e4)(np.array([-0.1, 0.0, 0.2])), [-1e3, 0.0, 2e3],
                               rtol=0, atol=1e-12)


def test_place_on_obstacle_touches_the_dome():
    scene = load_scene(ROOT / "studies" / "fig3.toml")
    high = scene.with_(body=replace(scene.body, position=[0.0, 0.0, 3.0]))
    placed = place_on_obstacle(high)
    # the file's own position: feet exactly on the dome, z = 0.5 cos(asin 0.6) + 0.78
    assert abs(placed.body.position[2] - 1.18) < 1e-9
    assert abs(feet_clearance(placed).min()) <= PLACEMENT_TOL
    tilt = np.array([np.cos(0.1), np.sin(0.1), 0.0, 0.0])
    tilted = place_on_obstacle(high, attitude=tilt, clearance=0.02)
    assert abs(feet_clearance(tilted).min() - 0.02) <= PLACEMENT_TOL
    np.testing.assert_allclose(tilted.body.attitude, tilt, rtol=0, atol=1e-15)
    assert tilted.body.position[:2].tolist() == [0.0, 0.0]


def test_place_on_obstacle_rejects_bad_input():
    scene = load_scene(ROOT / "studies" / "fig3.toml")
    with pytest.raises(ValueError, match="`clearance`"):
        place_on_obstacle(scene, clearance=-1.0)
    below = scene.with_(body=replace(scene.body, position=[0.0, 0.0, 0.2]))
    with pytest.raises(ValueError, match="below it"):
        place_on_obstacle(below)
