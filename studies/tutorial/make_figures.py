"""The pictures of docs/tutorial.md ("Your first lander"), into figures/tutorial/.

Runs the tutorial's commands (simulate, optimise, envelope) into
``out/tutorial`` and copies or draws what the tutorial shows:
``lander_summary.png``, ``lander_frame.png`` (one frame of the animation,
also in the README), ``lander.gif``, ``leg_design.png`` (the designed
absorber against its start), ``lander_envelope.png`` and ``conventions.png``
(the obstacles' geometry and signs). About two minutes, most of it compiling
the envelope's C code.

Usage: ``python studies/tutorial/make_figures.py [--out DIR] [--figures DIR]``.
"""
from __future__ import annotations

import argparse
import json
import shutil
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from symcushion.viz.animate import draw_frame  # noqa: E402
from symcushion.legs.characteristics import PiecewiseLinear  # noqa: E402
from symcushion.cli import main as cli  # noqa: E402
from symcushion.run.driver import Trajectory  # noqa: E402
from symcushion.model.scene import load_scene, read_toml  # noqa: E402

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]

#: Frames of the committed GIF: fewer than a run's default, to keep git small.
GIF_FRAMES = 40


def design_figure(result_json: Path, path: Path):
    """The designed axial characteristic against the start."""
    knots = read_toml(HERE / "leg_design.toml")["leg"][0]["S"]["x"]
    result = json.loads(result_json.read_text())
    fig, ax = plt.subplots(figsize=(6, 3.8))
    for key, label in (("initial_design", "start"), ("design", "optimised")):
        values = dict(result[key])
        f = [values.get(f"S.f{i}", 0.0) for i in range(len(knots))]
        x = np.linspace(knots[0], 0.0, 301)
        # a curve evaluates on a NumPy array; rate −1 with x < 0: compressing (loading)
        ax.plot(x, PiecewiseLinear(knots, f)(x, -1.0), lw=1.6, label=label)
    ideal = 33.3 * 2.0 ** 2 / (2 * 0.15)
    ax.axhline(-ideal, color="0.4", ls="--", lw=1, label=f"ideal: {ideal:.0f} N over 0.15 m")
    ax.set_xlabel("stroke δ_S [m] (compression negative)")
    ax.set_ylabel("axial force f(δ_S) [N]")
    ax.set_ylim(-2.2e3, 100)
    ax.grid(alpha=0.3)
    ax.set_title("leg_design: the axial absorber's loading branch", fontsize=10)
    ax.legend(fontsize=8, loc="lower right")
    fig.tight_layout()
    fig.savefig(path, dpi=110, metadata={"Software": None})
    plt.close(fig)


def conventions_figure(path: Path):
    """Side views (x-z) of the plane, sphere and implicit/terrain obstacles with their signs."""
    fig, axes = plt.subplots(1, 3, figsize=(12, 4.0))
    arrow = dict(arrowstyle="->", lw=1.5, color="tab:purple")
    # plane: angle θ turns the normal from +z towards +x (a right-handed turn about +y)
    ax = axes[0]
    theta = np.radians(20)
    x = np.linspace(-1, 1, 2)
    ax.fill_between(x, -np.tan(theta) * x, -1.2, color="wheat")
    ax.plot(x, -np.tan(theta) * x, color="tan")
    ax.plot(x, 0 * x, color="0.5", ls=":", lw=1)
    n = np.array([np.sin(theta), np.cos(theta)])
    ax.annotate("", (0.6 * n[0], 0.6 * n[1]), (0, 0), arrowprops=arrow)
    ax.text(0.6 * n[0] + 0.03, 0.6 * n[1], "n = (sin θ, 0, cos θ)", fontsize=8)
    ax.text(0.55, -0.12, "θ", fontsize=10)
    ax.set_title('plane: angle = θ (rad)\nturned about +y; falls along +x for θ > 0', fontsize=9)
    # sphere
    ax = axes[1]
    t = np.linspace(0, np.pi, 100)
    ax.fill(np.cos(t) * 0.7, np.sin(t) * 0.7 - 0.5, color="wheat")
    ax.plot(np.cos(t) * 0.7, np.sin(t) * 0.7 - 0.5, color="tan")
    ax.plot([0], [-0.5], "k.", ms=6)
    ax.text(0.03, -0.62, "center", fontsize=8)
    ax.annotate("", (0.7 * np.cos(1.0), 0.7 * np.sin(1.0) - 0.5), (0, -0.5),
                arrowprops=dict(arrowstyle="-", color="0.3"))
    ax.text(-0.05, -0.12, "radius", fontsize=8, rotation=55, ha="right")
    p = np.array([0.7 * np.cos(1.0), 0.7 * np.sin(1.0) - 0.5])
    ax.annotate("", p + 0.45 * np.array([np.cos(1.0), np.sin(1.0)]), p, arrowprops=arrow)
    ax.text(*(p + 0.47 * np.array([np.cos(1.0), np.sin(1.0)])), "n, out of the sphere",
            fontsize=8)
    ax.set_title("sphere: center, radius (m)", fontsize=9)
    # implicit and terrain
    ax = axes[2]
    x = np.linspace(-1, 1, 200)
    h = 0.15 * np.sin(3 * x) - 0.2
    ax.fill_between(x, h, -1.2, color="wheat")
    ax.plot(x, h, color="tan")
    ax.text(-0.6, -0.8, "φ < 0 (inside)", fontsize=9)
    ax.text(-0.6, 0.5, "φ > 0 (outside)", fontsize=9)
    k = 120
    g = np.array([-0.45 * np.cos(3 * x[k]), 1.0])
    g /= np.linalg.norm(g)
    ax.annotate("", (x[k] + 0.45 * g[0], h[k] + 0.45 * g[1]), (x[k], h[k]), arrowprops=arrow)
    ax.text(x[k] + 0.45 * g[0] + 0.03, h[k] + 0.45 * g[1], "n = ∇φ/|∇φ|", fontsize=8)
    ax.set_title('implicit: phi = "z - h(x, y)",\n'
                 "solid where φ ≤ 0; terrain: h from a grid", fontsize=9)
    for ax in axes:
        ax.set_xlim(-1, 1)
        ax.set_ylim(-1.2, 1.0)
        ax.set_aspect("equal")
        ax.set_xlabel("x [m]")
        ax.annotate("", (-0.85, 0.35), (-0.85, 0.8), arrowprops=dict(arrowstyle="->", lw=1.2))
        ax.text(-0.8, 0.55, "g", fontsize=9)
    axes[0].set_ylabel("z [m] (up)")
    fig.suptitle("Obstacles (world frame, z up; the obstacle is the shaded side, n points out "
                 "of it; a foot in contact feels P with n·P > 0)", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110, metadata={"Software": None})
    plt.close(fig)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=ROOT / "out" / "tutorial",
                        help="where the commands write (default: out/tutorial)")
    parser.add_argument("--figures", type=Path, default=ROOT / "figures" / "tutorial",
                        help="where the pictures go (default: figures/tutorial)")
    args = parser.parse_args(argv)
    out, figs = args.out, args.figures
    figs.mkdir(parents=True, exist_ok=True)
    conventions_figure(figs / "conventions.png")
    lander = HERE / "lander.toml"
    assert cli(["simulate", str(lander), "--out", str(out), "--frames", str(GIF_FRAMES),
                "--overwrite"]) == 0
    shutil.copyfile(out / "lander" / "summary.png", figs / "lander_summary.png")
    shutil.copyfile(out / "lander" / "animation.gif", figs / "lander.gif")
    traj = Trajectory.load(out / "lander")
    draw_frame(traj, load_scene(lander), figs / "lander_frame.png", time=0.06)
    design = out / "leg_design.json"
    assert cli(["optimise", str(HERE / "leg_design.toml"), "--out", str(design),
                "--overwrite"]) == 0
    design_figure(design, figs / "leg_design.png")
    envelope = out / "envelope"
    assert cli(["envelope", str(HERE / "lander_envelope.toml"), "--out", str(envelope),
                "--overwrite"]) == 0
    shutil.copyfile(envelope / "lander_envelope.png", figs / "lander_envelope.png")
    print(f"wrote the tutorial's pictures into {figs}")


if __name__ == "__main__":
    main()
