"""The summary figure of a run: body and legs against time, events marked.

This module owns the static figure every ``symcushion simulate`` writes
(``summary.png``) and ``symcushion plot`` redraws. It reads a
:class:`~symcushion.run.driver.Trajectory` and nothing else: it must not simulate,
and it writes files only through ``symcushion.run.results.replacing`` (atomic).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
from symcushion.run.output_files import replacing

__all__ = ["summary_figure", "EVENT_STYLES", "MAX_EVENT_LINES"]

#: Line style of each kind of event marked across the panels.
EVENT_STYLES = {"touchdown": dict(color="tab:green", ls=":", lw=1.0),
                "lift-off": dict(color="tab:red", ls=":", lw=1.0),
                "warning": dict(color="tab:orange", ls="-", lw=1.2)}

#: At most this many lines per kind of event: a chattering contact would
#: otherwise hide the curves under hundreds of lines (the rest are counted).
MAX_EVENT_LINES = 12

#: Dots per inch of saved figures: readable on screen, small in git.
DPI = 110


def _event_lines(events):
    """(time, kind) to draw, one per instant and kind, capped; and the capped counts."""
    lines, dropped = {}, {}
    for e in events:
        kind = e.get("kind")
        if kind not in EVENT_STYLES or e.get("time") is None:
            continue
        times = lines.setdefault(kind, [])
        t = float(e["time"])
        if any(abs(t - s) < 1e-12 for s in times):
            continue
        if len(times) < MAX_EVENT_LINES:
            times.append(t)
        else:
            dropped[kind] = dropped.get(kind, 0) + 1
    return lines, dropped


#: Line styles cycled over the legs: legs that move alike (a symmetric lander)
#: draw on top of each other, and dashes keep each of them visible.
LEG_DASHES = ("-", "--", "-.", ":")


def _leg_style(j, colors):
    return dict(color=colors[j % len(colors)], ls=LEG_DASHES[j % len(LEG_DASHES)],
                lw=1.6 if j % len(LEG_DASHES) == 0 else 1.2)


def _mark_events(axes, events) -> list:
    """Vertical lines at the events on every panel; legend handles of the kinds drawn."""
    from matplotlib.lines import Line2D

    lines, dropped = _event_lines(events)
    handles = []
    for kind, times in lines.items():
        style = EVENT_STYLES[kind]
        for ax in axes:
            for s in times:
                ax.axvline(s, **style)
        more = f" (+{dropped[kind]} more)" if kind in dropped else ""
        handles.append(Line2D([], [], label=kind + more, **style))
    return handles


def summary_figure(traj, path=None, title: str | None = None):
    """Draw the summary of a run: body height, vertical velocity and acceleration;
    per leg contact-force magnitude, stroke, hinge angles β and γ − γ₀, and mode.

    Touchdowns, lift-offs and monitor warnings (``traj.info['events']``) are
    vertical lines on every panel.

    Parameters
    ----------
    traj : Trajectory
    path : str or Path, optional
        Where to save the PNG (atomically); the figure is returned either way.
    title : str, optional
        Default: the scene name and method from ``traj.info``.

    Returns
    -------
    matplotlib.figure.Figure
    """
    import matplotlib

    if path is not None:
        matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t, N = traj.t, traj.n_legs
    force = np.linalg.norm(traj.force, axis=-1)
    panels_body = [("body height z [m]", traj.position[:, 2]),
                   ("vertical velocity [m/s]", traj.velocity[:, 2]),
                   ("vertical acceleration [m/s²]", traj.acceleration[:, 2]),
                   ("contact force |P| [N]", force)]
    panels_leg = [("stroke δ_S [mm]", 1e3 * traj.stroke),
                  ("hinge angle β [deg]", np.degrees(traj.beta)),
                  ("hinge angle γ − γ₀ [deg]", np.degrees(traj.gamma_deflection)),
                  ("mode", traj.mode)]
    fig, axes = plt.subplots(4, 2, figsize=(11, 8.5), sharex=True)
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    leg_handles = []
    for ax, (label, y) in zip(axes[:, 0], panels_body):
        if y.ndim == 1:
            ax.plot(t, y, color="k", lw=1.2)
        else:
            for j in range(N):
                ax.plot(t, y[:, j], **_leg_style(j, colors))
        ax.set_ylabel(label, fontsize=9)
    for ax, (label, y) in zip(axes[:, 1], panels_leg):
        for j in range(N):
            drawn = ax.plot(t, y[:, j], drawstyle="steps-post" if label == "mode" else "default",
                            label=f"leg {j}", **_leg_style(j, colors))
            if label == "mode":
                leg_handles.append(drawn[0])
        ax.set_ylabel(label, fontsize=9)
        ax.yaxis.set_label_position("right")
    mode_ax = axes[-1, 1]
    mode_ax.set_yticks([0, 1, 2, 3], ["free", "stick", "slip", "lift-off"], fontsize=8)
    mode_ax.set_ylim(-0.4, 3.4)
    event_handles = _mark_events(axes.ravel(), traj.info.get("events", []))
    for ax in axes.ravel():
        ax.grid(alpha=0.3)
        ax.tick_params(labelsize=8)
    for ax in axes[-1]:
        ax.set_xlabel("t [s]")
    fig.legend(handles=leg_handles + event_handles, loc="upper center",
               ncol=min(len(leg_handles) + len(event_handles), 8), fontsize=8, frameon=False,
               bbox_to_anchor=(0.5, 0.955))
    info = traj.info
    if title is None:
        name = info.get("name") or (info.get("scene_summary") or {}).get("name", "run")
        title = f"{name}: {info.get('method', '')} method, Δt = {info.get('dt', float('nan')):g} s"
        if info.get("stride", 1) > 1:
            title += f" (every {info['stride']}th row drawn)"
    fig.suptitle(title, fontsize=11)
    fig.tight_layout(rect=(0, 0, 1, 0.93))
    if path is not None:
        with replacing(Path(path)) as tmp:
            fig.savefig(tmp, dpi=DPI, format="png", metadata={"Software": None})
    return fig
