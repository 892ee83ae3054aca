"""Reproduction of the paper's Figs. 3–4 (``symcushion reproduce``).

Runs the scenes ``studies/fig3.toml`` (μ = 0) and ``studies/fig4.toml``
(μ = 0.05) with each contact method, checks the paper's claims, and writes
figures and CSV files. The paper's quantities (§3): y′ and y″ the vertical
velocity and acceleration of the ball, α the angle of the surface normal at a
foot's contact point, β the rod's deflection and γ the angle of the contact
force, all from the vertical. The γ of the figures is not the hinge angle γ
of (2.1); in code it is ``force_angle``.
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from symcushion.run.output_files import atomic_write_text, check_out_dir, replacing
from symcushion.model.scene import load_scene
from symcushion.contact.args import METHODS
from symcushion.run.driver import Trajectory, simulate
from symcushion.scheme.touchdown import build_model

__all__ = ["Claims", "measure_claims", "reproduce", "METHODS_ORDER"]

METHODS_ORDER = METHODS

#: The paper's bounds for Fig. 3 (μ = 0).
ALIGN_BOUND = 1e-4      # |α − γ| (rad)
REBOUND_BOUND = 1e-2    # |Δy′| (m/s)


@dataclass
class Claims:
    """Measured counterparts of the paper's claims for one run."""

    scene: str
    method: str
    max_align: float          # max |α − γ| over the contact phase, foot 0 (rad)
    rebound_dv: float         # |y′ at first lift-off| − |y′ at impact| (m/s), NaN if none
    lifted_off: bool          # did foot 0 ever leave the dome?
    ends_in_contact: bool     # is foot 0 on the dome at the end?
    slide_excess: float       # max(|α − γ| − atan μ) while a foot slides (rad)
    decay: float              # ratio of the last to the first swing of y′ (sticking runs)
    wall: float               # seconds

    def rows(self, mu: float):
        """(claim, measured, holds) rows for the printed table."""
        if mu == 0:
            return [
                ("|α − γ| < 1e-4 rad", f"{self.max_align:.2e}", self.max_align < ALIGN_BOUND),
                ("|Δy′| < 1e-2 m/s at rebound (β = 0)", f"{self.rebound_dv:.2e}",
                 bool(np.isfinite(self.rebound_dv) and abs(self.rebound_dv) < REBOUND_BOUND)),
            ]
        if not self.lifted_off:
            outcome = "sticks"
        elif self.ends_in_contact:
            outcome = "bounces, then sticks"
        else:
            outcome = "rebounds"
        return [
            ("sticks (no lift-off)", outcome, not self.lifted_off),
            ("damped oscillation of y′ (last/first swing)", f"{self.decay:.2f}",
             bool(self.decay < 1)),
            ("|α − γ| ≤ atan μ while sliding", f"excess {self.slide_excess:.1e}",
             self.slide_excess <= 1e-6),
        ]


def _swings(v):
    """Peak-to-peak swings of a signal between successive extrema."""
    d = np.diff(v)
    turns = np.where(np.sign(d[1:]) != np.sign(d[:-1]))[0] + 1
    ext = v[turns]
    return np.abs(np.diff(ext))


def measure_claims(traj: Trajectory, scene) -> Claims:
    """Measure the paper's claims on a trajectory (foot 0; the scene is symmetric)."""
    c = traj.contact[:, 0] > 0.5
    align = np.abs(traj.alpha[:, 0] - traj.force_angle[:, 0])
    max_align = float(np.nanmax(align[c])) if c.any() else np.nan
    v = traj.velocity[:, 2]
    v_impact = v[0]
    off = np.where(c[:-1] & ~c[1:])[0]
    lifted = bool(off.size)
    rebound_dv = np.nan
    if lifted:
        # The rods are back at β = 0 when the ball passes the height of first contact
        # again. Between steps the flight is ballistic, so the speed there follows
        # exactly from the first sample k with every foot free:
        # y′² = y′_k² + 2|g|(y_k − y₀).
        free = np.where(np.all(traj.contact[off[0] + 1:] < 0.5, axis=1))[0]
        if free.size:
            k = off[0] + 1 + free[0]
            g = np.linalg.norm(scene.gravity)
            z0 = traj.position[0, 2]
            v_reb = np.sqrt(max(v[k] ** 2 + 2 * g * (traj.position[k, 2] - z0), 0.0))
            rebound_dv = float(v_reb - abs(v_impact))
    slide = traj.mode[:, 0] == 2
    if scene.mu > 0 and slide.any():
        excess = float(np.nanmax(align[slide] - np.arctan(scene.mu)))
    else:
        excess = -np.inf
    # swings of y′ during the last contact phase only (not across a flight)
    start = off[-1] + 1 if lifted else 0
    landing = np.where(~c[start:-1] & c[start + 1:])[0]
    last_phase = v[start + landing[-1] + 1:] if (lifted and landing.size) else v[c]
    contact_v = last_phase if lifted else v[c]
    sw = _swings(contact_v) if contact_v.size > 3 else np.array([])
    decay = float(sw[-1] / sw[0]) if sw.size >= 2 and sw[0] > 0 else np.nan
    return Claims(scene.name, scene.method, max_align, rebound_dv, lifted, bool(c[-1]), excess,
                  decay,
                  float(traj.info.get("wall_seconds", np.nan)))


def _write_csv(traj: Trajectory, path: Path):
    """Columns t, vy, ay, alpha, beta, gamma (foot 0), SI and rad; α, γ empty when free."""
    cols = dict(t=traj.t, vy=traj.velocity[:, 2], ay=traj.acceleration[:, 2],
                alpha=traj.alpha[:, 0], beta=traj.rod_angle[:, 0], gamma=traj.force_angle[:, 0])
    # rod angle on the first row is the rest pose
    cols["beta"] = np.where(np.isnan(cols["beta"]), 0.0, cols["beta"])
    lines = [",".join(cols)]
    lines += [",".join("" if np.isnan(x) else f"{x:.10g}" for x in row)
              for row in zip(*cols.values())]
    atomic_write_text(path, "\n".join(lines) + "\n")     # a killed run leaves no half file


def _plot_paper_style(traj: Trajectory, title: str, path: Path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = traj.t
    beta = np.where(np.isnan(traj.rod_angle[:, 0]), 0.0, traj.rod_angle[:, 0])
    curves = [
        ("1", "y′ [m/s]", traj.velocity[:, 2]),
        ("2", "y″/10 [m/s²]", traj.acceleration[:, 2] / 10),
        ("3", "α [rad]", traj.alpha[:, 0]),
        ("4", "β [rad]", beta),
        ("5", "γ [rad]", traj.force_angle[:, 0]),
    ]
    fig, ax = plt.subplots(figsize=(7.5, 4.5))
    for number, label, y in curves:
        (line,) = ax.plot(t, y, lw=1.2, label=f"{number}: {label}")
        finite = np.where(np.isfinite(y))[0]
        if finite.size:
            k = finite[int(0.15 * finite.size)]
            ax.annotate(number, (t[k], y[k]), textcoords="offset points", xytext=(3, 4),
                        color=line.get_color(), fontsize=10, fontweight="bold")
    ax.axhline(0, color="k", lw=0.5)
    ax.set_xlabel("t [s]")
    ax.set_title(title)
    ax.legend(loc="best", fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    with replacing(path) as tmp:
        fig.savefig(tmp, dpi=110, format="png", metadata={"Software": None})
    plt.close(fig)


def _plot_methods(trajs: dict, title: str, path: Path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    panels = [
        ("y′ [m/s]", lambda tr: tr.velocity[:, 2]),
        ("y″ [m/s²]", lambda tr: tr.acceleration[:, 2]),
        ("β, rod from vertical [rad]", lambda tr: tr.rod_angle[:, 0]),
        ("α − γ [rad]", lambda tr: tr.alpha[:, 0] - tr.force_angle[:, 0]),
    ]
    fig, axes = plt.subplots(len(panels), 1, figsize=(7.5, 8), sharex=True)
    styles = {"paper": "-", "robust": "--", "implicit": ":"}
    for ax, (label, getter) in zip(axes, panels):
        for method, tr in trajs.items():
            ax.plot(tr.t, getter(tr), styles.get(method, "-"), lw=1.2, label=method)
        ax.set_ylabel(label, fontsize=9)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8)
    axes[0].set_title(title)
    axes[-1].set_xlabel("t [s]")
    fig.tight_layout()
    with replacing(path) as tmp:
        fig.savefig(tmp, dpi=110, format="png", metadata={"Software": None})
    plt.close(fig)


def reproduce(scene_dir="studies", out_dir="out/reproduce", methods=METHODS_ORDER,
              duration=None, verbose=True) -> list:
    """Run Figs. 3–4 with every method, write figures/CSVs, print the claims table.

    Parameters
    ----------
    scene_dir : path
        Folder holding ``fig3.toml`` and ``fig4.toml``.
    out_dir : path
        Where figures and CSV files go (checked before the runs); the
        committed figures are ``figures/`` (``symcushion reproduce
        --update-figures``).
    methods : sequence of str
    duration : float, optional
        Override the scenes' durations (fast checks).

    Returns
    -------
    list of Claims
    """
    scene_dir, out = Path(scene_dir), check_out_dir(out_dir, "out_dir")
    for name in ("fig3", "fig4"):
        if not (scene_dir / f"{name}.toml").is_file():
            raise FileNotFoundError(
                f"{scene_dir / (name + '.toml')} not found; run from the repository root or "
                "pass --scenes DIR.")
    results = []
    started = time.perf_counter()
    for name, paper_fig in (("fig3", "Fig. 3, μ = 0"), ("fig4", "Fig. 4, μ = 0.05")):
        base = load_scene(scene_dir / f"{name}.toml")
        if duration is not None:
            base = base.with_(duration=duration)
        trajs = {}
        for method in methods:
            scene = base.with_(method=method)
            if verbose:
                print(f"[{time.perf_counter() - started:5.1f} s] {name}: {method} method, "
                      f"{scene.steps} steps of {scene.dt:g} s ...", flush=True)
            traj = simulate(scene, model=build_model(scene))
            trajs[method] = traj
            results.append(measure_claims(traj, scene))
            suffix = "" if method == "paper" else f"_{method}"
            _write_csv(traj, out / f"{name}{suffix}.csv")
        main_method = "paper" if "paper" in trajs else next(iter(trajs))
        _plot_paper_style(trajs[main_method], f"{paper_fig} ({main_method} method)",
                          out / f"{name}.png")
        _plot_methods(trajs, f"{paper_fig}: contact methods compared", out / f"{name}_methods.png")
    table = claims_table(results, {"fig3": 0.0, "fig4": 0.05})
    atomic_write_text(out / "claims.md", table + "\n")
    if verbose:
        print(table)
        print(f"done in {time.perf_counter() - started:.1f} s; wrote {out}/fig3.png, "
              f"fig4.png, *_methods.png, *.csv, claims.md")
    return results


def claims_table(results, mus) -> str:
    """Markdown table: each claim of the paper beside the measured value, per method."""
    lines = ["| figure | method | claim | measured | holds |", "|---|---|---|---|---|"]
    for c in results:
        for claim, value, ok in c.rows(mus[c.scene]):
            claim = claim.replace("|", "\\|")   # literal bars inside a table cell
            lines.append(f"| {c.scene} | {c.method} | {claim} | {value} | "
                         f"{'yes' if ok else 'NO'} |")
    return "\n".join(lines)
