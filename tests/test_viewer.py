"""The interactive viewer (symcushion view): a self-contained page whose frames follow the run,
the scene's obstacle drawn, clear errors; and, in a real headless Chromium, screenshots at
three times that differ where the run moves."""
import json
import re
import shutil
import sys

import numpy as np
import pytest

from symcushion.cli import main as cli
from symcushion.model.obstacles import Plane, Sphere, Terrain

plotly = pytest.importorskip("plotly", reason="the viewer needs the optional extra "
                                              "symcushion[viewer] (plotly)")

from symcushion.viz import viewer  # noqa: E402
from symcushion.viz.chromium import browser  # noqa: E402

#: Screenshot window of the browser test (px): smaller than the default, quicker to draw.
TEST_SIZE = (1100, 700)

#: Times of the three screenshots (s): before leg 0 touches down, the crush, the hop.
SHOT_TIMES = (0.01, 0.06, 0.2)

#: A non-blank screenshot has at least this many distinct colours and this spread of grey.
MIN_COLOURS, MIN_GREY_STD = 200, 20.0

#: Two frames of a moving run differ in at least this fraction of the 3-D view's pixels.
MIN_CHANGED = 0.002


@pytest.fixture(scope="module")
def run(tutorial_result):
    return viewer.load_run(tutorial_result)


@pytest.fixture(scope="module")
def page(tutorial_result, tmp_path_factory):
    out = tmp_path_factory.mktemp("viewer") / "lander.html"
    assert cli(["view", str(tutorial_result), "--out", str(out)]) == 0
    return out


def trace_named(fig, name):
    return [t for t in fig.data if t.name == name]


def test_page_is_self_contained_with_the_time_hook(page, run, capsys):
    html = page.read_text()
    assert len(html) > 3_000_000                             # plotly.js itself is inside
    assert not re.search(r"<script[^>]+src=", html)          # nothing loaded from a network
    assert "Plotly.addFrames" in html and "hashchange" in html and "data-frame" in html
    traj, _ = run
    times = json.loads(re.search(r"var times = (\[[^\]]*\]);", html).group(1))
    assert len(times) == min(viewer.DEFAULT_VIEW_FRAMES, len(traj.t))
    assert times[0] == traj.t[0] and times[-1] == traj.t[-1]


def test_default_page_goes_into_the_result_folder(tutorial_result, capsys):
    assert cli(["view", str(tutorial_result)]) == 0
    assert (tutorial_result / viewer.VIEWER_NAME).stat().st_size > 3_000_000
    assert "200 frames" in capsys.readouterr().out


def test_frames_follow_the_run(run):
    traj, scene = run
    fig = viewer.viewer_figure(traj, scene, frames=7)
    rows = fig.layout.meta["rows"]
    assert len(fig.frames) == 7 == len(fig.layout.sliders[0].steps) and rows[-1] == len(traj.t) - 1
    colours = viewer._mode_colors()
    for frame, k in zip(fig.frames, rows):
        legs, body, centre, feet, shafts, heads = frame.data[:6]
        np.testing.assert_allclose(np.c_[feet.x, feet.y, feet.z], traj.foot[k])
        np.testing.assert_allclose([centre.x[0], centre.y[0], centre.z[0]], traj.position[k])
        assert list(feet.marker.color) == [colours[int(m)] for m in traj.mode[k]]
        loaded = np.linalg.norm(traj.force[k], axis=1) > 0
        assert len(heads.x) == loaded.sum() and len(shafts.x) == 3 * loaded.sum()
        for marker in frame.data[6:]:                        # one per 2-D plot
            assert marker.x == (traj.t[k], traj.t[k])
        assert f"t = {traj.t[k]:.3f} s" in frame.layout.title.text
    assert len(frame.data) == 6 + 4
    # the arrows point along the force on the foot
    k = int(np.argmax(np.linalg.norm(traj.force, axis=-1).sum(axis=1)))
    heads = viewer._Geometry(traj, scene).traces(plotly.graph_objects, k)[5]
    P = traj.force[k][np.linalg.norm(traj.force[k], axis=1) > 0]
    np.testing.assert_allclose(np.c_[heads.u, heads.v, heads.w],
                               P / np.linalg.norm(P, axis=1)[:, None])


def test_long_runs_plot_every_kth_row(run, monkeypatch):
    traj, scene = run
    monkeypatch.setattr(viewer, "MAX_PLOT_POINTS", 50)
    fig = viewer.viewer_figure(traj, scene, frames=2)
    (height,) = trace_named(fig, "body z")
    stride = -(-len(traj.t) // 50)                           # 301 rows: every 7th
    np.testing.assert_array_equal(height.x, traj.t[::stride])
    np.testing.assert_array_equal(height.y, traj.position[::stride, 2])
    assert len(height.x) <= 50
    # a plot of one line is named by its axis; the strokes' legs are in the legend
    assert height.showlegend is False
    assert [t.name for t in fig.data if t.showlegend] == ["leg 0", "leg 1", "leg 2"]


@pytest.mark.parametrize("obstacle, height", [
    (Plane.inclined(0.0873), lambda x, y: -np.tan(0.0873) * x),
    (Sphere(center=(0.0, 0.0, -1.0), radius=1.2),
     lambda x, y: -1.0 + np.sqrt(np.where(x ** 2 + y ** 2 < 1.44, 1.44 - x ** 2 - y ** 2, np.nan))),
    (Terrain(np.linspace(-3, 3, 7), np.linspace(-3, 3, 7),
             0.05 * np.add.outer(np.linspace(-3, 3, 7), np.zeros(7))), lambda x, y: 0.05 * x),
], ids=["plane", "sphere", "terrain"])
def test_the_obstacle_is_drawn(run, obstacle, height):
    traj, scene = run
    fig = viewer.viewer_figure(traj, scene.with_(obstacles=[obstacle]), frames=2)
    (surface,) = trace_named(fig, "obstacle")
    X, Y, Z = (np.asarray(a, dtype=float) for a in (surface.x, surface.y, surface.z))
    expected = height(X, Y)
    drawn = np.isfinite(Z)
    assert drawn.mean() > 0.5
    np.testing.assert_allclose(Z[drawn], expected[drawn], atol=1e-6)


def test_not_a_result_folder_is_named(tmp_path, tutorial_result, capsys):
    assert cli(["view", str(tmp_path / "missing")]) == 2
    assert not (tmp_path / "missing").exists()               # nothing made for --out
    assert cli(["view", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "`RESULT_DIR`" in err and "missing" in err and "not a result folder (no run.json)" in err
    # a run whose run.json records no scene: nothing to draw the geometry from
    shutil.copy(tutorial_result / "trajectory.npz", tmp_path)
    meta = json.loads((tutorial_result / "run.json").read_text())
    del meta["scene"]
    (tmp_path / "run.json").write_text(json.dumps(meta))
    assert cli(["view", str(tmp_path)]) == 2
    assert "records no scene" in capsys.readouterr().err


def test_bad_out_is_named(tutorial_result, tmp_path, capsys):
    assert cli(["view", str(tutorial_result), "--out", str(tmp_path / "page.png")]) == 2
    assert "`--out`" in capsys.readouterr().err
    assert cli(["view", str(tutorial_result), "--out", str(tmp_path)]) == 2
    assert "is a directory" in capsys.readouterr().err
    with pytest.raises(ValueError, match="`frames` must be a positive integer"):
        viewer.viewer_figure(*viewer.load_run(tutorial_result), frames=0)


def test_missing_plotly_says_how_to_install_it(tutorial_result, monkeypatch, capsys):
    for name in ("plotly", "plotly.graph_objects", "plotly.subplots"):
        monkeypatch.setitem(sys.modules, name, None)
    assert cli(["view", str(tutorial_result)]) == 2
    assert "pip install 'symcushion[viewer]'" in capsys.readouterr().err


def test_screenshot_arguments_are_checked(page, tmp_path, monkeypatch):
    with pytest.raises(FileNotFoundError, match="`page` .*nowhere.html.* does not exist"):
        viewer.screenshots(tmp_path / "nowhere.html", [0.1], [tmp_path / "a.png"])
    with pytest.raises(ValueError, match="`times` and `pngs` must have the same length, got 2 "
                                         "and 1; give one file per time"):
        viewer.screenshots(page, [0.1, 0.2], [tmp_path / "a.png"])
    monkeypatch.setattr(viewer, "browser", lambda: None)
    with pytest.raises(FileNotFoundError, match="no Chromium found .*apt-get install chromium"):
        viewer.screenshots(page, [0.1], [tmp_path / "a.png"])
    assert not (tmp_path / "a.png").exists()


@pytest.mark.skipif(browser() is None,
                    reason="no Chromium on the PATH (apt-get install chromium)")
def test_screenshots_in_headless_chromium_step_the_slider(page, run, tmp_path):
    from PIL import Image

    traj, _ = run
    pngs = [tmp_path / f"t{t}.png" for t in SHOT_TIMES]
    frames = viewer.screenshots(page, SHOT_TIMES, pngs, size=TEST_SIZE)
    times = traj.t[viewer.frame_indices(len(traj.t), viewer.DEFAULT_VIEW_FRAMES)]
    assert frames == [int(np.argmin(np.abs(times - t))) for t in SHOT_TIMES]
    images = [np.asarray(Image.open(p).convert("RGB"), dtype=float) for p in pngs]
    marker_x = []
    for image in images:
        assert image.shape == (TEST_SIZE[1], TEST_SIZE[0], 3)
        assert len(np.unique(image.reshape(-1, 3), axis=0)) > MIN_COLOURS
        assert image.mean(axis=2).std() > MIN_GREY_STD
        right = image[:, TEST_SIZE[0] // 2:]
        # the plots' time marker (#d62728, dotted and antialiased): red columns, no curve's
        red = (right[..., 0] > 170) & (right[..., 1] < 110) & (right[..., 2] < 110)
        columns = np.nonzero(red.sum(axis=0) > 0.1 * TEST_SIZE[1])[0]
        assert columns.size, "no time marker in the plots"
        marker_x.append(columns.mean())
    assert marker_x[0] < marker_x[1] < marker_x[2]           # the marker moves with the slider
    scene_view = (slice(60, TEST_SIZE[1] - 80), slice(0, int(TEST_SIZE[0] * 0.55)))
    for a, b in ((0, 1), (1, 2), (0, 2)):
        changed = np.abs(images[a][scene_view] - images[b][scene_view]).sum(axis=2) > 30
        assert changed.mean() > MIN_CHANGED, (SHOT_TIMES[a], SHOT_TIMES[b])


@pytest.mark.skipif(browser() is None,
                    reason="no Chromium on the PATH (apt-get install chromium)")
def test_chromium_runs_javascript_and_reports_failures(tmp_path):
    from symcushion.viz.chromium import Chromium

    page = tmp_path / "page.html"
    page.write_text("<html><body><p id='p'>hello</p></body></html>")
    with Chromium(browser(), page.as_uri(), (400, 300), timeout=60) as chrome:
        assert chrome.evaluate("document.getElementById('p').textContent") == "hello"
        assert chrome.evaluate("new Promise(r => setTimeout(() => r(6 * 7), 10))") == 42
        with pytest.raises(RuntimeError, match="the page raised: ReferenceError: undefinedName"):
            chrome.evaluate("undefinedName.field")
        with pytest.raises(RuntimeError, match="the browser refused No.such"):
            chrome.send("No.such")
        process = chrome.process
    assert process.poll() is not None                       # ended on leaving the block
