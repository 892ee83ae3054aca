"""The study's figure: rebound error against cost per simulated second, and errors against Δt.

Owns the figure's colours, titles and layout. It reads rows and fitted
orders; it must not compute them.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np


from .grid import SCENES, VARIANTS


COLOURS = {"paper": "tab:blue", "robust": "tab:orange", "implicit": "tab:green",
           "implicit+midpoint": "tab:olive", "implicit+midpoint+branch": "tab:brown",
           "implicit+midpoint+lock": "black"}
PEER_STYLE = {"penalty-cvodes": ("tab:red", "s"), "mujoco": ("tab:purple", "D")}
TITLES = {"fig3": "Fig. 3 (μ = 0)", "fig4": "Fig. 4 (μ = 0.05)",
          "lander_slope": "lander, 10° slope (μ = 0.4)",
          "lander_hop": "3-leg lander with a hop, 5° slope (μ = 0.4)"}
#: Errors are drawn at no less than this (a log axis has no 0).
PLOT_FLOOR = 1e-14


def plot(rows, orders, path, floors=None) -> None:
    """Two rows of panels: rebound error vs wall per simulated second; errors vs Δt."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import matplotlib.ticker

    scenes = [s for s in SCENES if any(r["scene"] == s for r in rows)]
    fig, axes = plt.subplots(2, len(scenes), figsize=(5.2 * len(scenes), 9.0), squeeze=False)
    for col, scene in enumerate(scenes):
        ax = axes[0, col]
        for method in VARIANTS:
            for backend, style in (("c", "-o"), ("vm", "--^")):
                sel = [r for r in rows if r["scene"] == scene and r["method"] ==
                       f"{method}/{backend}" and r["status"] == "ok"]
                if sel:
                    ax.plot([r["wall_per_sim_second"] for r in sel],
                            [max(r["rebound_error"], PLOT_FLOOR) for r in sel], style,
                            color=COLOURS[method], ms=4, lw=1.2,
                            mfc="none" if backend == "vm" else COLOURS[method],
                            label=f"{method}/{backend}")
        for peer, (colour, marker) in PEER_STYLE.items():
            sel = [r for r in rows if r["scene"] == scene and r["backend"] == "peer"
                   and r["method"].startswith(peer) and r["status"] == "ok"]
            if sel:
                ax.plot([r["wall_per_sim_second"] for r in sel],
                        [max(r["rebound_error"], PLOT_FLOOR) for r in sel], ":" + marker,
                        color=colour, ms=6, lw=1, label=peer)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("time per simulated second (s/s)")
        ax.set_ylabel("rebound-speed error (m/s)")
        ax.set_title(TITLES[scene])
        ax.grid(True, which="major", alpha=0.3)
        if col == 0:
            ax.legend(fontsize=7, ncol=2, loc="lower left")
        ax = axes[1, col]
        for method in VARIANTS:
            sel = [r for r in rows if r["scene"] == scene and r["method"] == f"{method}/c"
                   and r["status"] == "ok"]
            if not sel:
                continue
            entry = next((o for o in orders if o["scene"] == scene and o["method"] == method),
                         None)
            for key, style in (("rebound_error", "-o"), ("trajectory_error", "--s")):
                p = entry[key][0] if entry else float("nan")
                label = f"{method}, {'rebound' if key == 'rebound_error' else 'trajectory'}"
                label += f" (order {p:.1f})" if np.isfinite(p) else " (no order)"
                ax.plot([r["dt"] for r in sel], [max(r[key], PLOT_FLOOR) for r in sel], style,
                        color=COLOURS[method], ms=4, lw=1.2,
                        mfc="none" if key == "trajectory_error" else COLOURS[method],
                        label=label)
        if floors and scene in floors:
            ax.axhline(max(floors[scene]["rebound_error"], PLOT_FLOOR), color="grey", lw=0.8,
                       ls=":", label="reference's own rebound error")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("Δt (s)")
        ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
        ax.set_ylabel("rebound error (m/s) / trajectory error (rel.)")
        ax.grid(True, which="major", alpha=0.3)
        ax.legend(fontsize=6.5)
    fig.suptitle("Speed vs error: compiled C (filled, solid) and CasADi VM (open, dashed); "
                 "peers dotted", fontsize=10)
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
