"""The interactive viewer of a run: one self-contained HTML page (plotly).

This module owns ``symcushion view``: a page with the body, legs (hinge to
foot), feet coloured by contact mode and the contact forces as arrows in 3-D
over the scene's obstacle surface, a time slider with a play button, and the
main channels (height, vertical velocity and acceleration, strokes) as 2-D
plots whose time marker follows the slider. plotly.js is embedded, so the
page opens without a network. The page honours a URL fragment ``#t=0.12``
(seconds): it shows the frame nearest that time, at load and whenever the
fragment changes (:data:`TIME_HOOK`), which lets a headless browser take a
screenshot at a chosen time (:func:`screenshots`, through ``symcushion.viz.chromium``).

It reads a result folder (``trajectory.npz`` or ``.csv`` and ``run.json``,
whose scene gives the hinges and the obstacles) and draws the geometry
with ``symcushion.viz.animate``'s helpers; it must not simulate.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from symcushion.viz.animate import (ARROW_FRACTION, MODE_COLORS, scene_bounds, hinge_positions, surface_heights,
    frame_indices)
from symcushion.viz.chromium import BROWSERS, Chromium, browser
from symcushion.run.output_files import atomic_write_text, check_output_file, replacing
from symcushion.run.results import JSON_NAME
from symcushion.run.driver import Trajectory
from symcushion.model.scene import scene_from_dict

__all__ = ["load_run", "viewer_figure", "write_viewer", "screenshots",
           "DEFAULT_VIEW_FRAMES", "MAX_PLOT_POINTS", "VIEWER_NAME", "TIME_HOOK", "INSTALL_HINT"]

#: Frames of the slider: every frame holds the 3-D traces' data, and 200 keep
#: the page's data near 1 MB and a slider step visible, whatever the run's length.
DEFAULT_VIEW_FRAMES = 200

#: Points per 2-D channel at most (every k-th row beyond): a 10⁶-step run stays a small page.
MAX_PLOT_POINTS = 5000

#: File name of the page in the result folder when ``--out`` is not given.
VIEWER_NAME = "viewer.html"

#: What to run when plotly is missing.
INSTALL_HINT = "pip install 'symcushion[viewer]'"

#: Length of a force arrow's cone, as a fraction of the scene's size.
CONE_FRACTION = 0.04

#: Colour of the force arrows and the time markers.
FORCE_COLOR = "#9467bd"
MARKER_COLOR = "#d62728"

#: Camera of the 3-D view: elevation 18°, azimuth −60° as the GIF (``animate``).
CAMERA_EYE = dict(x=0.95, y=-1.65, z=0.62)

#: Browser window of a screenshot (px): the 3-D view and four plots side by side.
SCREENSHOT_SIZE = (1400, 800)

#: JavaScript run after the plot is drawn: ``#t=SECONDS`` shows the frame nearest that
#: time and moves the slider there; the div's ``data-frame`` attribute then holds the
#: frame's index (a headless browser's ``--dump-dom`` can read it).
TIME_HOOK = """
var gd = document.getElementById('{plot_id}');
var times = %s;
function showTime() {
    var m = /[#&]t=([-+0-9.eE]+)/.exec(window.location.hash);
    if (!m) { gd.setAttribute('data-frame', '0'); return; }
    var t = parseFloat(m[1]), k = 0;
    for (var i = 1; i < times.length; i++) {
        if (Math.abs(times[i] - t) < Math.abs(times[k] - t)) { k = i; }
    }
    return Plotly.animate(gd, [String(k)], {frame: {duration: 0, redraw: true},
                                            transition: {duration: 0}, mode: 'immediate'})
        .then(function () { return Plotly.relayout(gd, {'sliders[0].active': k}); })
        .then(function () { gd.setAttribute('data-frame', String(k)); });
}
window.addEventListener('hashchange', showTime);
return showTime();
"""


def _plotly():
    try:
        import plotly.graph_objects as go
        from plotly.subplots import make_subplots
    except ImportError:
        raise ImportError(f"the viewer needs plotly, which is not installed: {INSTALL_HINT} "
                          "(or pip install 'plotly>=5').") from None
    return go, make_subplots


def _check_result_dir(result_dir) -> Path:
    """``result_dir`` as a Path, if it is a folder holding a run's ``run.json``."""
    directory = Path(result_dir)
    if not directory.is_dir():
        raise FileNotFoundError(f"`RESULT_DIR` {str(directory)!r} is not a folder; give the "
                                "folder a run wrote, OUT/<scene name> of `symcushion simulate`.")
    if not (directory / JSON_NAME).is_file():
        raise FileNotFoundError(f"`RESULT_DIR` {str(directory)!r} is not a result folder (no "
                                f"{JSON_NAME}); give the folder a run wrote, OUT/<scene name> "
                                "of `symcushion simulate`.")
    return directory


def load_run(result_dir):
    """The :class:`~symcushion.run.driver.Trajectory` and :class:`~symcushion.model.scene.Scene` of a result folder.

    Parameters
    ----------
    result_dir : str or Path
        A folder written by ``symcushion simulate`` (``OUT/<scene name>``).

    Raises
    ------
    FileNotFoundError
        The folder does not exist or holds no run (``run.json`` and a trajectory).
    ValueError
        Its run.json records no scene (the hinges and obstacles to draw).
    """
    directory = _check_result_dir(result_dir)
    traj = Trajectory.load(directory)
    if not traj.info.get("scene"):
        raise ValueError(f"`RESULT_DIR` {str(directory)!r}: {JSON_NAME} records no scene, so "
                         "there are no hinges and obstacles to draw; rerun the scene with "
                         "`symcushion simulate`.")
    scene = scene_from_dict(traj.info["scene"], source=str(directory / JSON_NAME))
    if len(scene.legs) != traj.n_legs:
        raise ValueError(f"`RESULT_DIR` {str(directory)!r}: the scene in {JSON_NAME} has "
                         f"{len(scene.legs)} legs but the trajectory {traj.n_legs}; rerun the "
                         "scene.")
    return traj, scene


def _segments(starts, ends):
    """x, y, z lists of line segments start→end, separated by None (one plotly trace)."""
    out = ([], [], [])
    for a, b in zip(starts, ends):
        for axis in range(3):
            out[axis].extend([a[axis], b[axis], None])
    return out


def _mode_colors():
    from matplotlib.colors import to_hex

    return [to_hex(c) for c in MODE_COLORS]


class _Geometry:
    """What moves in the 3-D view, per row: the traces of :func:`viewer_figure`."""

    def __init__(self, traj, scene):
        self.traj = traj
        self.hinges = hinge_positions(traj, scene)
        self.centre, self.half = scene_bounds(traj, self.hinges)
        peak = float(np.max(np.linalg.norm(traj.force, axis=-1), initial=0.0))
        self.arrow_scale = ARROW_FRACTION * 2 * self.half / peak if peak > 0 else 0.0
        self.colors = _mode_colors()

    def traces(self, go, k: int) -> list:
        """The moving traces at row ``k``: legs, body frame, centre, feet, force shafts, heads."""
        traj, hinges, feet = self.traj, self.hinges[k], self.traj.foot[k]
        centre = traj.position[k]
        ring = np.vstack([hinges, hinges[:1]])
        frame = _segments([centre] * len(hinges), hinges)
        modes = np.clip(np.rint(traj.mode[k]).astype(int), 0, 3)
        P = traj.force[k] * self.arrow_scale
        loaded = np.linalg.norm(P, axis=1) > 0
        tips = feet + P
        unit = P[loaded] / np.linalg.norm(P[loaded], axis=1)[:, None] if loaded.any() else P[:0]
        legs, shafts = _segments(hinges, feet), _segments(feet[loaded], tips[loaded])
        return [
            go.Scatter3d(x=legs[0], y=legs[1], z=legs[2], mode="lines", name="legs",
                         line=dict(color="#1f77b4", width=7), showlegend=False),
            go.Scatter3d(x=frame[0] + ring[:, 0].tolist(), y=frame[1] + ring[:, 1].tolist(),
                         z=frame[2] + ring[:, 2].tolist(), mode="lines", name="body",
                         line=dict(color="#333333", width=4), showlegend=False),
            go.Scatter3d(x=[centre[0]], y=[centre[1]], z=[centre[2]], mode="markers",
                         name="centre of mass", showlegend=False,
                         marker=dict(size=9, color="#1f77b4", line=dict(color="black", width=1))),
            go.Scatter3d(x=feet[:, 0], y=feet[:, 1], z=feet[:, 2], mode="markers", name="feet",
                         showlegend=False, text=[f"leg {j}" for j in range(len(feet))],
                         marker=dict(size=8, color=[self.colors[m] for m in modes],
                                     line=dict(color="black", width=1))),
            go.Scatter3d(x=shafts[0], y=shafts[1], z=shafts[2], mode="lines",
                         name="force on foot", showlegend=False,
                         line=dict(color=FORCE_COLOR, width=5)),
            go.Cone(x=tips[loaded, 0], y=tips[loaded, 1], z=tips[loaded, 2], u=unit[:, 0],
                    v=unit[:, 1], w=unit[:, 2], anchor="tip", sizemode="absolute",
                    sizeref=CONE_FRACTION * 2 * self.half, showscale=False, name="force",
                    colorscale=[[0, FORCE_COLOR], [1, FORCE_COLOR]], hoverinfo="skip"),
        ]

    def title(self, k: int, name: str) -> str:
        peak = float(np.max(np.linalg.norm(self.traj.force[k], axis=-1)))
        return f"{name}   t = {self.traj.t[k]:.3f} s   max |P| = {peak:,.0f} N"


def _channels(traj) -> list:
    """The 2-D plots: (axis title, [(label, values (T,))])."""
    return [("height z [m]", [("body z", traj.position[:, 2])]),
            ("vertical velocity [m/s]", [("body v_z", traj.velocity[:, 2])]),
            ("vertical acceleration [m/s²]", [("body a_z", traj.acceleration[:, 2])]),
            ("stroke δ_S [m]", [(f"leg {j}", traj.stroke[:, j]) for j in range(traj.n_legs)])]


def viewer_figure(traj, scene, frames: int = DEFAULT_VIEW_FRAMES, name: str | None = None):
    """The viewer's plotly figure: 3-D scene, channels, slider, play button and frames.

    Parameters
    ----------
    traj : Trajectory
    scene : Scene
        The scene simulated (its hinges and obstacles are drawn).
    frames : int
        Frames of the slider, spread evenly over the run (first and last kept;
        at most the number of rows).
    name : str, optional
        The run's name in the title (default: the scene's).

    Returns
    -------
    plotly.graph_objects.Figure
        ``fig.layout.meta`` holds ``times``, the frames' times (s), and ``rows``,
        their row indices.
    """
    go, make_subplots = _plotly()
    if len(scene.legs) != traj.n_legs:
        raise ValueError(f"`scene` has {len(scene.legs)} legs but the trajectory {traj.n_legs}; "
                         "give the scene that was simulated.")
    rows = frame_indices(len(traj.t), frames)
    name = name or scene.name
    geo = _Geometry(traj, scene)
    channels = _channels(traj)
    fig = make_subplots(rows=len(channels), cols=2, column_widths=[0.58, 0.42],
                        specs=[[{"type": "scene", "rowspan": len(channels)}, {"type": "xy"}]]
                        + [[None, {"type": "xy"}]] * (len(channels) - 1),
                        shared_xaxes=True, vertical_spacing=0.04, horizontal_spacing=0.06)
    moving = geo.traces(go, rows[0])
    for trace in moving:
        fig.add_trace(trace, row=1, col=1)
    X, Y, Z = surface_heights(scene, geo.centre, geo.half)
    if np.isfinite(Z).any():
        fig.add_trace(go.Surface(x=X, y=Y, z=Z, showscale=False, opacity=0.85, name="obstacle",
                                 colorscale=[[0, "#f5deb3"], [1, "#d2b48c"]], hoverinfo="skip"),
                      row=1, col=1)
    stride = max(1, -(-len(traj.t) // MAX_PLOT_POINTS))
    palette = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#8c564b", "#e377c2", "#7f7f7f"]
    markers, limits = [], []
    for i, (title, lines) in enumerate(channels, start=1):
        for j, (label, values) in enumerate(lines):
            fig.add_trace(go.Scatter(x=traj.t[::stride], y=values[::stride], mode="lines",
                                     name=label, showlegend=len(lines) > 1,
                                     line=dict(width=1.4, color=palette[j % len(palette)])),
                          row=i, col=2)
        both = np.concatenate([v for _, v in lines])
        lo, hi = float(np.nanmin(both)), float(np.nanmax(both))
        pad = 0.05 * (hi - lo) or 0.05 * max(abs(hi), 1e-3)
        limits.append((lo - pad, hi + pad))
        fig.update_yaxes(title_text=title, title_font_size=11, range=limits[-1], row=i, col=2)
        markers.append(len(fig.data))
        fig.add_trace(go.Scatter(x=[traj.t[rows[0]]] * 2, y=list(limits[-1]), mode="lines",
                                 line=dict(color=MARKER_COLOR, width=1.5, dash="dot"),
                                 showlegend=False, hoverinfo="skip"), row=i, col=2)
    fig.update_xaxes(title_text="t [s]", row=len(channels), col=2)
    for word, colour in zip(("free", "stick", "slip", "lift-off"), geo.colors):
        fig.add_trace(go.Scatter(x=[None], y=[None], mode="markers", name=f"foot: {word}",
                                 marker=dict(size=9, color=colour)), row=1, col=2)
    fig.add_trace(go.Scatter(x=[None], y=[None], mode="lines", name="force on foot",
                             line=dict(color=FORCE_COLOR, width=4)), row=1, col=2)
    moving_ids = list(range(len(moving))) + markers
    fig.frames = [go.Frame(name=str(i), traces=moving_ids,
                           data=geo.traces(go, k) + [go.Scatter(x=[traj.t[k]] * 2, y=list(lim))
                                                    for lim in limits],
                           layout=dict(title_text=geo.title(k, name)))
                  for i, k in enumerate(rows)]
    c, h = geo.centre, geo.half
    z_low = min(c[2] - h, float(np.nanmin(Z))) if np.isfinite(Z).any() else c[2] - h
    play = dict(frame=dict(duration=60, redraw=True), fromcurrent=True,
                transition=dict(duration=0), mode="immediate")
    still = dict(frame=dict(duration=0, redraw=True), transition=dict(duration=0),
                 mode="immediate")
    fig.update_layout(
        title=dict(text=geo.title(rows[0], name), x=0.02, font_size=15),
        margin=dict(l=10, r=10, t=60, b=10),
        meta=dict(times=traj.t[rows].tolist(), rows=rows.tolist()), uirevision="view",
        legend=dict(font_size=10, x=0.0, y=1.0, xanchor="left", yanchor="top",
                     bgcolor="rgba(255,255,255,0.7)"),
        scene=dict(xaxis=dict(range=[c[0] - h, c[0] + h], title="x [m]"),
                   yaxis=dict(range=[c[1] - h, c[1] + h], title="y [m]"),
                   zaxis=dict(range=[z_low, z_low + 2 * h], title="z [m]"),
                   aspectmode="cube", camera=dict(eye=CAMERA_EYE)),
        updatemenus=[dict(type="buttons", direction="left", x=0.0, y=-0.02, xanchor="left",
                          yanchor="top", showactive=False, pad=dict(t=0, r=6),
                          buttons=[dict(label="▶ play", method="animate", args=[None, play]),
                                   dict(label="❚❚ pause", method="animate",
                                        args=[[None], still])])],
        sliders=[dict(active=0, x=0.12, y=-0.02, len=0.44, xanchor="left", yanchor="top",
                      pad=dict(t=0), currentvalue=dict(prefix="t = ", suffix=" s",
                                                       font=dict(size=12, color="black")),
                      # 200 step labels cannot be read side by side: the current one is shown
                      font=dict(color="rgba(0,0,0,0)"),
                      steps=[dict(label=f"{traj.t[k]:.3f}", method="animate",
                                  args=[[str(i)], still]) for i, k in enumerate(rows)])])
    return fig


def write_viewer(result_dir, out=None, frames: int = DEFAULT_VIEW_FRAMES) -> Path:
    """Write the viewer page of a result folder (``symcushion view``), atomically.

    Parameters
    ----------
    result_dir : str or Path
        A folder written by ``symcushion simulate``.
    out : str or Path, optional
        The HTML file (default: ``result_dir/viewer.html``).
    frames : int
        Frames of the slider (:data:`DEFAULT_VIEW_FRAMES`).

    Returns
    -------
    Path
    """
    _plotly()                               # before any work: say how to install it
    _check_result_dir(result_dir)           # before --out's default is made in it
    out = check_output_file(Path(result_dir) / VIEWER_NAME if out is None else out, "--out")
    if out.suffix.lower() not in (".html", ".htm"):
        raise ValueError(f"`--out` {str(out)!r} must end in .html (a web page); e.g. "
                         f"{out.with_suffix('.html').name}.")
    traj, scene = load_run(result_dir)
    name = (traj.info.get("scene_summary") or {}).get("name", scene.name)
    fig = viewer_figure(traj, scene, frames, name=name)
    html = fig.to_html(include_plotlyjs=True, full_html=True, auto_play=False,
                       post_script=TIME_HOOK % json.dumps(fig.layout.meta["times"]),
                       config=dict(responsive=True, displaylogo=False),
                       default_height="100vh")
    # the page is the plot: no margin around it, so it fills the window without scrolling
    html = html.replace("<body>", '<body style="margin: 0">', 1)
    return atomic_write_text(out, html)


#: JavaScript: resolves with the frame the page shows once the time hook has set it,
#: after two animation frames (the WebGL scene is drawn).
_SHOWN = """new Promise(function (done) {
    function poll() {
        var gd = document.querySelector('.plotly-graph-div');
        var k = gd && gd.getAttribute('data-frame');
        if (k === null || k === undefined) { setTimeout(poll, 50); return; }
        requestAnimationFrame(function () { requestAnimationFrame(function () {
            done(parseInt(k)); }); });
    }
    poll();
})"""


def screenshots(page, times, pngs, size=SCREENSHOT_SIZE, timeout: float = 120.0) -> list:
    """PNGs of a viewer page at given times (s), taken by one headless Chromium.

    The browser loads the page once, then for each time sets the URL fragment
    ``#t=TIME`` (:data:`TIME_HOOK`: the slider moves to the nearest frame) and
    captures the window. WebGL runs on the CPU (SwiftShader): no GPU or display
    is needed.

    Parameters
    ----------
    page : str or Path
        A page written by :func:`write_viewer`.
    times : sequence of float
        Times of the frames shown (s).
    pngs : sequence of str or Path, same length
        The screenshots (each written atomically).
    size : (int, int)
        Window width and height (px).
    timeout : float
        Seconds to wait for each answer of the browser.

    Returns
    -------
    list of int
        The frame (slider step) shown in each screenshot.
    """
    import base64

    page = Path(page).resolve()
    if not page.is_file():
        raise FileNotFoundError(f"`page` {str(page)!r} does not exist; write it with "
                                "`symcushion view`.")
    times, pngs = [float(t) for t in times], [check_output_file(p, "pngs") for p in pngs]
    if len(times) != len(pngs):
        raise ValueError(f"`times` and `pngs` must have the same length, got {len(times)} "
                         f"and {len(pngs)}; give one file per time.")
    exe = browser()
    if exe is None:
        raise FileNotFoundError(f"no Chromium found on the PATH (looked for "
                                f"{', '.join(BROWSERS)}); install one, e.g. "
                                "apt-get install chromium.")
    with Chromium(exe, page.as_uri(), size, timeout) as chrome:
        chrome.evaluate(_SHOWN)                 # loaded and drawn
        frames = []
        for t, png in zip(times, pngs):
            frames.append(chrome.evaluate(
                "document.querySelector('.plotly-graph-div').removeAttribute('data-frame');"
                f"window.location.hash = 't={t!r}'; {_SHOWN}"))
            shot = chrome.send("Page.captureScreenshot", chrome.session, format="png")
            with replacing(png) as tmp:
                tmp.write_bytes(base64.b64decode(shot["data"]))
    return frames
