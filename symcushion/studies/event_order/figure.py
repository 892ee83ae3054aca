"""The event-order study's figure: errors against Δt per scene, variant and scheme.

Owns the figure's styles, panels and layout; it reads rows and fitted
orders and must not compute them.
"""
from __future__ import annotations

import numpy as np

from .cases import DT_GRID


STYLE = {"clean switch": ("tab:purple", "P"), "all events": ("k", "o"), "elastic": ("tab:blue", "s"), "stick": ("tab:orange", "^"),
         "flat": ("tab:green", "v"), "stick, flat": ("tab:brown", "P"),
         "none": ("tab:red", "D")}
#: Line style and filled marker of each rule suffix of a case label.
LINES = {"": ("-", True), " (midpoint)": ("--", False), " (midpoint, branch)": (":", True),
         " (midpoint, lock)": ("-", True)}
PANELS = (("lander_slope", "trajectory_error", "lander, 10° slope: trajectory error (relative)"),
          ("lander_slope", "rebound_error", "lander, 10° slope: rebound error (m/s)"),
          ("lander_hop", "final_error", "lander with a hop: final-state error at 0.6 s"),
          ("switch control", "final_error",
           "clean switch (level ground, kicked down): final-state error at 0.07 s"))


def plot(rows, fits, path):
    """Trajectory and rebound error of the lander variants, final-state error of the hop."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 2, figsize=(15, 13))
    axes = axes.ravel()
    for ax, (scene, key, title) in zip(axes, PANELS):
        # guide slopes over the finest decade of the panel's grid, under the data
        finest = min((r["dt"] for r in rows if r["scene"] == scene and r["kind"] == "run"),
                     default=min(DT_GRID))
        dts = np.array([finest, 10 * finest])
        anchors = []
        for fit in (f for f in fits if f["scene"] == scene):
            sel = [r for r in rows if (r["scene"], r["variant"]) == (scene, fit["variant"])
                   and r["kind"] == "run" and r["status"] == "ok"]
            base = fit["variant"].split(" (")[0]
            colour, marker = STYLE[base]
            rule = fit["variant"][len(base):]
            if scene == "lander_slope" and rule in ("", " (midpoint)"):
                continue        # the slope panels: the event schemes (the CSV has every row)
            line, face = LINES[rule]
            order = fit[key][0]
            label = fit["variant"] + (f" (order {order:.2f})" if np.isfinite(order) else "")
            ax.plot([r["dt"] for r in sel], [r[key] for r in sel], line, marker=marker,
                    color=colour, ms=5, lw=2.2 if rule.endswith("lock)") else 1.2,
                    mfc=colour if face else "none", label=label)
            anchors += [r[key] for r in sel if r["dt"] == finest]
        anchor = 0.3 * min(anchors, default=1.0)
        for p, ls in ((1, ":"), (2, "-.")):
            ax.plot(dts, anchor * (dts / dts[0]) ** p, ls, color="grey", lw=1.0,
                    label=f"slope {p}")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("Δt (s)")
        ax.set_title(title, fontsize=10)
        ax.grid(True, which="major", alpha=0.3)
        ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.1), ncol=2)
    fig.suptitle("Event-order study: implicit contact step, Verlet body step; each variant "
                 "removes some of the lander's events (none: all three)\n"
                 "thin solid: default; dashed, open markers: midpoint slip rule; dotted: midpoint "
                 "and events = 'branch' (the kick at the located branch switch); thick solid: "
                 "midpoint and events = 'lock' (the switch and the stroke lock)\n"
                 "slope panels: the branch and lock rows only", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
