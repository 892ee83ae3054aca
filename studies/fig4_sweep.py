"""Where does the ball of Fig. 4 stick, and where does it rebound?

Khvostov (1976, §3) reports that with μ = 0.05 the ball on four rods "sticks"
to the hemisphere in a damped oscillation. The paper gives no masses, sizes or
speeds, so the claim is only as good as the scene it is tested on. This study
maps the outcome of the Fig. 4 scene (``studies/fig4.toml``) over impact
speed × hinge spring stiffness, for each contact method (the step as printed,
the robust step, the exact implicit Coulomb step), at μ = 0.05, and asks:

* for which speeds and stiffnesses does the ball stick, bounce and then
  stick, or rebound;
* does the printed step draw the boundary where the exact step does.

Why hinge stiffness and not the hinge offset: the stiffness sets how far the
rods swing and the feet slide per unit impact energy, and how strongly the
legs push the ball back, without moving the first contact point (α₀ =
asin(0.3/0.5)) or the initial height at which every foot just touches the
dome, so every run starts from the same touching pose and only the leg
compliance changes. Moving the hinge changes α₀, the lever arms and the
start height together. M_β is set equal to M_γ as in fig4.toml; the
symmetric vertical impact does not excite the sideways β swing.

Outcomes (per run, all four feet):

``sticks``
    no foot ever leaves the dome after its first contact;
``bounce then sticks``
    the ball leaves the dome on all feet at least once, lands again, and in
    its last contact phase (which lasts to the end of the run) rises to an
    apex, y′ going from > 0 to ≤ 0, with every foot still on the dome: it no
    longer has the energy to bounce, and friction only takes energy away;
``rebounds``
    it leaves the dome on all feet and is flying, or still bouncing (no apex
    on its feet since the last landing), at the end of the run;
``slides off``
    a foot slides past the dome's equator (α ≥ 90°): the legs are too soft to
    hold the ball on a hemisphere, the scene leaves its domain;
``chatters``
    some feet leave the dome but never all at once (not seen in this
    symmetric scene; kept so that nothing is misfiled).

For the runs that lift off, the first restitution is the rebound speed at
the height of first contact (rods back at β = 0) over the impact speed,
1 + Δy′/|y′₀| with Δy′ from :func:`symcushion.reproduce.measure_claims`.

Writes ``figures/fig4_sweep.csv`` (one row per run) and
``figures/fig4_sweep.png`` (one outcome map per method, the Fig. 4 scene
point marked). Run from the repository root: ``python studies/fig4_sweep.py``
(about 35 s on 2 idle cores; ``--workers`` sets the number of processes).
"""
from __future__ import annotations

import argparse
import os
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from symcushion.legs.characteristics import Linear
from symcushion.layout.vectors import state_layout
from symcushion.contact.args import METHODS
from symcushion.model.scene import load_scene, symmetric_legs
from symcushion.scheme.touchdown import build_model, initial_state
from symcushion.run.driver import simulate
from symcushion.reproduce import measure_claims

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "studies" / "fig4.toml"

#: Impact speeds (m/s): ten log-spaced values 0.08 … 5, a factor 10^(1/5)
#: apart, chosen so that the Fig. 4 speed 0.5 m/s is on the grid.
SPEEDS = 0.5 * 10.0 ** (np.arange(-4, 6) / 5)
#: Hinge spring stiffness of M_γ and M_β (N·m/rad): six values a factor
#: 2^(2/3) ≈ 1.59 apart, 476 … 4800, with the Fig. 4 value 1200 on the grid.
#: Below about 680 N·m/rad the rods cannot hold the 50 kg ball on the dome
#: even at rest (the feet slide off), so one row there is enough.
STIFFNESSES = 1200.0 * 2.0 ** (2 / 3 * np.arange(-2, 4))
#: Simulated time (s): about five periods (0.41 s) of the oscillation on the
#: dome at 1200 N·m/rad, so that a run which bounces has time to land again.
DURATION = 2.0
#: A foot at or past the dome's equator has slid off the hemisphere.
EQUATOR = np.pi / 2

OUTCOMES = ("sticks", "bounce then sticks", "rebounds", "slides off", "chatters")
COLORS = {"sticks": "#2b8cbe", "bounce then sticks": "#a6bddb", "rebounds": "#e34a33",
          "slides off": "#969696", "chatters": "#fdbb84"}
COLUMNS = ("method", "stiffness", "speed", "outcome", "restitution", "max_rod_angle",
           "flights")


def scene_with_stiffness(base, stiffness):
    """The scene ``base`` with hinge springs M_γ = M_β = ``stiffness`` (N·m/rad).

    The legs keep the geometry of ``base`` (a symmetric pattern, read back
    from its first leg), so the study follows any change to fig4.toml.
    """
    leg = base.legs[0]
    azimuth = float(np.arctan2(leg.hinge[1], leg.hinge[0]))
    radial = np.array([np.cos(azimuth), np.sin(azimuth), 0.0])
    tangential = np.array([-np.sin(azimuth), np.cos(azimuth), 0.0])
    frame = np.column_stack([radial, tangential, [0.0, 0.0, 1.0]])   # leg frame → body
    legs = symmetric_legs(len(base.legs), float(np.hypot(leg.hinge[0], leg.hinge[1])),
                          float(leg.hinge[2]), leg.length, frame.T @ leg.e0, frame.T @ leg.en,
                          M_beta=Linear(stiffness), M_gamma=Linear(stiffness),
                          azimuth0=azimuth)
    return base.with_(legs=legs)


def classify(traj):
    """Outcome of a run (:data:`OUTCOMES`) and its number of flights (all feet off).

    "slides off" takes precedence: once a foot passes the equator the run has
    left the hemisphere the scene stands for, whatever follows.
    """
    contact = traj.contact > 0.5                     # (T, N)
    if np.nanmax(traj.alpha, initial=0.0) >= EQUATOR:
        return "slides off", 0
    touched = np.maximum.accumulate(contact, axis=0)  # foot has touched by then
    left = touched & ~contact
    if not left.any():
        return "sticks", 0
    airborne = touched.any(axis=1) & ~contact.any(axis=1)
    flights = int(np.sum(airborne[1:] & ~airborne[:-1]))
    if flights == 0:
        return "chatters", 0
    on_all = contact.all(axis=1)
    if not on_all[-1]:
        return "rebounds", flights
    landed = np.where(~on_all)[0][-1] + 1          # start of the last contact phase
    vz = traj.velocity[landed:, 2]
    if np.any((vz[:-1] > 0) & (vz[1:] <= 0)):       # an apex on its feet
        return "bounce then sticks", flights
    return "rebounds", flights


def sweep_one(method, stiffness, speeds=SPEEDS, duration=DURATION):
    """All speeds for one (method, stiffness): one model, only x0 changes."""
    started = time.perf_counter()
    scene = scene_with_stiffness(load_scene(SCENE), stiffness).with_(
        method=method, mu=0.05, duration=duration)
    model = build_model(scene)
    x_touch = initial_state(scene)                    # every foot just touching the dome
    velocity = state_layout(len(scene.legs)).slice("velocity")
    rows = []
    for speed in speeds:
        x0 = x_touch.copy()
        x0[velocity] = (0.0, 0.0, -speed)             # body velocity; the step is unchanged
        traj = simulate(scene, model=model, x0=x0)
        outcome, flights = classify(traj)
        restitution = np.nan
        if outcome in ("bounce then sticks", "rebounds"):
            restitution = 1.0 + measure_claims(traj, scene).rebound_dv / speed
        rows.append(dict(method=method, stiffness=float(stiffness), speed=float(speed),
                         outcome=outcome, restitution=float(restitution),
                         max_rod_angle=float(np.nanmax(traj.rod_angle)), flights=flights))
    return rows, time.perf_counter() - started


def write_csv(rows, path):
    """One row per run, the columns of :data:`COLUMNS`; NaN restitution left empty."""
    def cell(value):
        if isinstance(value, str):
            return value
        if isinstance(value, int):
            return str(value)
        return "" if np.isnan(value) else f"{value:.6g}"

    with open(path, "w") as fh:
        fh.write(",".join(COLUMNS) + "\n")
        for row in rows:
            fh.write(",".join(cell(row[c]) for c in COLUMNS) + "\n")


def _edges(values):
    """Cell edges of a log-spaced grid (geometric midpoints, extended at the ends)."""
    logs = np.log(values)
    mid = (logs[1:] + logs[:-1]) / 2
    return np.exp(np.concatenate([[2 * logs[0] - mid[0]], mid, [2 * logs[-1] - mid[-1]]]))


def plot(rows, scene_point, path):
    """One outcome map per method over speed × stiffness.

    The first restitution is written in each cell that lifts off; the cell of
    ``scene_point`` = (speed, stiffness), which must be on the grid, is outlined.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import ListedColormap
    from matplotlib.patches import Patch, Rectangle

    speeds = np.array(sorted({r["speed"] for r in rows}))
    stiffs = np.array(sorted({r["stiffness"] for r in rows}))
    methods = [m for m in METHODS if any(r["method"] == m for r in rows)]
    cmap = ListedColormap([COLORS[o] for o in OUTCOMES])
    fig, axes = plt.subplots(1, len(methods), figsize=(4.6 * len(methods), 4.4), sharey=True)
    axes = np.atleast_1d(axes)
    for ax, method in zip(axes, methods):
        grid = np.full((len(stiffs), len(speeds)), np.nan)
        for r in (r for r in rows if r["method"] == method):
            i, j = np.searchsorted(stiffs, r["stiffness"]), np.searchsorted(speeds, r["speed"])
            grid[i, j] = OUTCOMES.index(r["outcome"])
            if np.isfinite(r["restitution"]):
                ax.text(r["speed"], r["stiffness"], f"{r['restitution']:.2f}", ha="center",
                        va="center", fontsize=6.5)
        ax.pcolormesh(_edges(speeds), _edges(stiffs), grid, cmap=cmap, vmin=-0.5,
                      vmax=len(OUTCOMES) - 0.5, edgecolors="white", linewidth=0.5)
        x_edges, y_edges = _edges(speeds), _edges(stiffs)
        i, j = np.searchsorted(stiffs, scene_point[1]), np.searchsorted(speeds, scene_point[0])
        ax.add_patch(Rectangle((x_edges[j], y_edges[i]), x_edges[j + 1] - x_edges[j],
                               y_edges[i + 1] - y_edges[i], fill=False, ec="k", lw=2.2))
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xticks(speeds, [f"{v:.2g}" for v in speeds], fontsize=7)
        ax.set_yticks(stiffs, [f"{k:.0f}" for k in stiffs], fontsize=8)
        ax.minorticks_off()
        ax.set_xlabel("impact speed [m/s]")
        ax.set_title(f"{method} method")
    axes[0].set_ylabel("hinge stiffness M_γ = M_β [N·m/rad]")
    seen = {r["outcome"] for r in rows}
    handles = [Patch(color=COLORS[o], label=o) for o in OUTCOMES if o in seen]
    handles.append(Patch(fill=False, ec="k", lw=2.2, label="Fig. 4 scene"))
    fig.legend(handles=handles, loc="lower center", ncol=len(handles), fontsize=8,
               frameon=False)
    fig.suptitle("Fig. 4 scene, μ = 0.05: outcome over impact speed × hinge stiffness "
                 "(numbers: first restitution)", fontsize=10)
    fig.tight_layout(rect=(0, 0.07, 1, 0.95))
    fig.savefig(path, dpi=110, metadata={"Software": None})
    plt.close(fig)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=str(ROOT / "figures"), help="output folder")
    parser.add_argument("--workers", type=int, default=min(2, os.cpu_count() or 1),
                        help="processes (default: 2)")
    args = parser.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)

    started = time.perf_counter()
    jobs = [(m, k) for m in METHODS for k in STIFFNESSES]
    rows = []
    with ProcessPoolExecutor(max_workers=args.workers) as pool:
        futures = {job: pool.submit(sweep_one, *job) for job in jobs}
        for (method, stiffness), future in futures.items():
            part, wall = future.result()
            rows += part
            print(f"[{time.perf_counter() - started:5.1f} s] {method:8s} "
                  f"{stiffness:6.0f} N·m/rad: {len(part)} speeds in {wall:.1f} s", flush=True)

    base = load_scene(SCENE)
    curves = {element.name: element.curve for element in base.legs[0].elements}
    scene_point = (float(np.linalg.norm(base.body.velocity)), float(curves["M_gamma"].slope(0.0)))
    write_csv(rows, out / "fig4_sweep.csv")
    plot(rows, scene_point, out / "fig4_sweep.png")
    for method in METHODS:
        print(f"{method}:")
        for stiffness in STIFFNESSES:
            line = [r for r in rows if r["method"] == method and r["stiffness"] == stiffness]
            cells = " ".join(f"{r['outcome'][:6]:6s}" for r in line)
            print(f"  {stiffness:6.0f} | {cells}")
    print(f"  speeds: {' '.join(f'{v:6.3g}' for v in SPEEDS)} m/s")
    print(f"done in {time.perf_counter() - started:.1f} s; wrote {out}/fig4_sweep.csv, "
          f"fig4_sweep.png")


if __name__ == "__main__":
    main()
