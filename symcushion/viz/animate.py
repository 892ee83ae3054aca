"""The animation of a run: body, legs, feet, obstacle surface and contact forces in 3-D.

This module owns ``animation.gif`` (matplotlib's ``PillowWriter``) and single
frames as PNG. The camera is fixed: it frames every position the body, hinges
and feet take during the run, with equal scales on the three axes. It reads a
:class:`~symcushion.run.driver.Trajectory` and its :class:`~symcushion.model.scene.Scene`
(for the hinges and the obstacles); it must not simulate.
"""
from __future__ import annotations

from pathlib import Path

import casadi as ca
import numpy as np

from symcushion.model.obstacles import Sphere, closest_obstacle
from symcushion.run.output_files import replacing

__all__ = ["animate", "draw_frame", "frame_indices", "DEFAULT_FRAMES", "DEFAULT_FPS"]

#: Frames of the GIF: 60 at 20 frames/s is a 3-s clip of any run, about
#: 1-2 MB, and takes a few seconds to draw.
DEFAULT_FRAMES = 60
DEFAULT_FPS = 20

#: Length of the largest contact-force arrow, as a fraction of the scene's size.
ARROW_FRACTION = 0.25

#: Grid points per side of the drawn obstacle surface.
SURFACE_GRID = 25

#: Levels scanned from the top of the view down for the surface.
SURFACE_SCAN = 60

#: Bisection steps locating the surface height over each grid point (2⁻³⁰ of
#: the search interval: far below a pixel).
SURFACE_BISECTIONS = 30

#: Colour of a foot by mode code (free, stick, slip, lift-off).
MODE_COLORS = ("0.5", "tab:green", "tab:orange", "tab:red")


def frame_indices(n_rows: int, frames: int) -> np.ndarray:
    """Row indices of ``frames`` frames spread evenly over ``n_rows`` rows (first and last kept)."""
    if isinstance(frames, bool) or not isinstance(frames, (int, np.integer)) or frames < 1:
        raise ValueError(f"`frames` must be a positive integer, got {frames!r}; e.g. 60.")
    return np.unique(np.linspace(0, n_rows - 1, min(frames, n_rows)).round().astype(int))


def _quat_rot(q):
    w, x, y, z = q / np.linalg.norm(q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def hinge_positions(traj, scene):
    """World positions of the hinges, shape (T, N, 3)."""
    H = np.array([leg.hinge for leg in scene.legs])
    R = np.array([_quat_rot(q) for q in traj.attitude])
    return traj.position[:, None, :] + np.einsum("tij,nj->tni", R, H)


def scene_bounds(traj, hinges):
    pts = np.concatenate([traj.position, hinges.reshape(-1, 3), traj.foot.reshape(-1, 3)])
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    centre, half = (lo + hi) / 2, max(float(np.max(hi - lo)) / 2, 0.2) * 1.15
    return centre, half


def surface_heights(scene, centre, half):
    """Height z(x, y) of the obstacle surface over a grid around the scene (NaN: none)."""
    p = ca.SX.sym("p", 3)
    dist = ca.Function("surface_distance", [p], [closest_obstacle(scene.obstacles, p)[0]],
                       ["p"], ["d"])
    if all(isinstance(ob, Sphere) for ob in scene.obstacles):
        # a polar grid about the scene's axis: a dome's rim is then a clean circle
        radius, angle = np.meshgrid(np.linspace(0, half, SURFACE_GRID),
                                    np.linspace(0, 2 * np.pi, 2 * SURFACE_GRID))
        X, Y = centre[0] + radius * np.cos(angle), centre[1] + radius * np.sin(angle)
    else:
        # a square grid filling the view: ground under every foot
        X, Y = np.meshgrid(centre[0] + np.linspace(-half, half, SURFACE_GRID),
                           centre[1] + np.linspace(-half, half, SURFACE_GRID))
    n = X.size
    mapped = dist.map(n)
    points = np.vstack([X.ravel(), Y.ravel(), np.zeros(n)])

    def d(z):
        points[2] = z
        return np.asarray(mapped(points), float).ravel()

    # scan down from the top of the box for the first level inside the obstacle,
    # then bisect between it and the level above (the topmost surface)
    levels = np.linspace(centre[2] + half, centre[2] - 3 * half, SURFACE_SCAN)
    inside = np.array([d(np.full(n, z)) < 0 for z in levels])
    found = inside.any(axis=0) & ~inside[0]
    first = np.argmax(inside, axis=0)
    lo = levels[first]
    hi = levels[np.maximum(first - 1, 0)]
    for _ in range(SURFACE_BISECTIONS):
        mid = (lo + hi) / 2
        below = d(mid) < 0
        lo, hi = np.where(below, mid, lo), np.where(below, hi, mid)
    Z = np.where(found, (lo + hi) / 2, np.nan).reshape(X.shape)
    return X, Y, Z


class _Scene3D:
    """The axes and the artists updated per frame."""

    def __init__(self, traj, scene, fig=None):
        import matplotlib.pyplot as plt

        self.traj, self.scene = traj, scene
        self.hinges = hinge_positions(traj, scene)
        self.centre, self.half = scene_bounds(traj, self.hinges)
        self.fig = fig or plt.figure(figsize=(6.4, 5.6))
        ax = self.ax = self.fig.add_subplot(projection="3d", computed_zorder=False)
        # drawn in zorder: surface first, then the lander over it (feet behind the
        # obstacle stay visible rather than vanishing into it)
        X, Y, Z = surface_heights(scene, self.centre, self.half)
        if np.isfinite(Z).any():
            # flat colour: a GIF has 256 colours per frame, and a shaded, translucent
            # surface would use them up and shift the colours of the feet
            ax.plot_surface(X, Y, Z, color="wheat", shade=False, linewidth=0.3,
                            edgecolor="tan", rstride=2, cstride=2, zorder=1)
        c, h = self.centre, self.half
        ax.set_xlim(c[0] - h, c[0] + h)
        ax.set_ylim(c[1] - h, c[1] + h)
        z_low = min(c[2] - h, float(np.nanmin(Z))) if np.isfinite(Z).any() else c[2] - h
        ax.set_zlim(z_low, z_low + 2 * h)
        ax.set_box_aspect((1, 1, 1))
        ax.set_xlabel("x [m]", fontsize=8)
        ax.set_ylabel("y [m]", fontsize=8)
        ax.set_zlabel("z [m]", fontsize=8)
        ax.tick_params(labelsize=7)
        ax.view_init(elev=18, azim=-60)
        force = np.linalg.norm(traj.force, axis=-1)
        peak = float(np.max(force)) if force.size else 0.0
        self.arrow_scale = ARROW_FRACTION * 2 * h / peak if peak > 0 else 0.0
        N = len(scene.legs)
        self.frame_lines = [ax.plot([], [], [], color="0.2", lw=1.5, zorder=3)[0] for _ in range(N)]
        self.legs = [ax.plot([], [], [], color="tab:blue", lw=2.2, zorder=3)[0] for _ in range(N)]
        self.body = ax.plot([], [], [], "o", color="tab:blue", ms=12, mec="k", zorder=4)[0]
        self.feet = ax.scatter([], [], [], s=36, depthshade=False, zorder=5)
        self.arrows = None
        self.title = ax.set_title("", fontsize=10)
        from matplotlib.lines import Line2D

        handles = [Line2D([], [], marker="o", ls="", color=col, label=word)
                   for col, word in zip(MODE_COLORS, ("free", "stick", "slip", "lift-off"))]
        handles.append(Line2D([], [], color="tab:purple", label="force on foot"))
        ax.legend(handles=handles, loc="upper left", fontsize=7, frameon=False)

    def draw(self, k: int):
        traj, c = self.traj, self.traj.position[k]
        hinges, feet = self.hinges[k], self.traj.foot[k]
        for line, hinge, foot in zip(self.legs, hinges, feet):
            line.set_data_3d([hinge[0], foot[0]], [hinge[1], foot[1]], [hinge[2], foot[2]])
        for line, hinge in zip(self.frame_lines, hinges):
            line.set_data_3d([c[0], hinge[0]], [c[1], hinge[1]], [c[2], hinge[2]])
        self.body.set_data_3d([c[0]], [c[1]], [c[2]])
        self.feet._offsets3d = (feet[:, 0], feet[:, 1], feet[:, 2])
        modes = np.clip(np.rint(traj.mode[k]).astype(int), 0, 3)
        self.feet.set_color([MODE_COLORS[m] for m in modes])
        if self.arrows is not None:
            self.arrows.remove()
        P = traj.force[k] * self.arrow_scale
        self.arrows = self.ax.quiver(feet[:, 0], feet[:, 1], feet[:, 2], P[:, 0], P[:, 1],
                                     P[:, 2], color="tab:purple", lw=1.8, arrow_length_ratio=0.2, zorder=6)
        peak = float(np.max(np.linalg.norm(traj.force[k], axis=-1)))
        self.title.set_text(f"{self.scene.name}   t = {traj.t[k]:.3f} s   "
                            f"max |P| = {peak:,.0f} N")
        return []


def animate(traj, scene, path, frames: int = DEFAULT_FRAMES, fps: int = DEFAULT_FPS) -> Path:
    """Write a GIF of the run: ``frames`` frames spread evenly over it.

    Parameters
    ----------
    traj : Trajectory
    scene : Scene
        The scene simulated (its legs' hinges and its obstacles are drawn).
    path : str or Path
        The GIF (written atomically).
    frames : int
        Number of frames (at most the number of rows).
    fps : int
        Frames per second of the GIF.

    Returns
    -------
    Path
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.animation import FuncAnimation, PillowWriter

    if isinstance(fps, bool) or not isinstance(fps, (int, np.integer)) or fps < 1:
        raise ValueError(f"`fps` must be a positive integer, got {fps!r}; e.g. 20.")
    if len(scene.legs) != traj.n_legs:
        raise ValueError(f"`scene` has {len(scene.legs)} legs but the trajectory {traj.n_legs}; "
                         "give the scene that was simulated.")
    rows = frame_indices(len(traj.t), frames)
    view = _Scene3D(traj, scene)
    anim = FuncAnimation(view.fig, view.draw, frames=list(rows), blit=False)
    path = Path(path)
    with replacing(path) as tmp:
        anim.save(tmp, writer=PillowWriter(fps=fps))
    plt.close(view.fig)
    return path


def draw_frame(traj, scene, path, time: float | None = None) -> Path:
    """Save one frame of the animation as a PNG: the row nearest ``time`` (default: peak force)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    if time is None:
        k = int(np.argmax(np.linalg.norm(traj.force, axis=-1).sum(axis=1)))
    else:
        k = int(np.argmin(np.abs(traj.t - float(time))))
    view = _Scene3D(traj, scene)
    view.draw(k)
    path = Path(path)
    with replacing(path) as tmp:
        view.fig.savefig(tmp, dpi=110, format="png", metadata={"Software": None})
    plt.close(view.fig)
    return path
