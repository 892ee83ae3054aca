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
                 "and events = 'branch' (the located switch: its kick and the split contact step);\n"
                 "thick solid: midpoint and events = 'lock' (the switch and the stroke lock); "
                 "slope panels: the branch and lock rows only", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


#: Colour and marker of each scheme of the window figure.
WINDOW_STYLE = {"all events": ("k", "o"), "all events (midpoint)": ("tab:grey", "s"),
                "all events (midpoint, branch)": ("tab:blue", "^"),
                "all events (midpoint, lock)": ("tab:red", "D")}


def plot_window(result, fits, times, path):
    """Largest distance of the centre of mass from the scheme's own fine run (solid) and
    from the regularised reference (dashed) against Δt, one panel per window ``times``;
    ``result`` and ``fits`` are those of ``window.window_runs`` and ``window_orders``.
    The file is written atomically."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from symcushion.run.output_files import replacing

    schemes = list(dict.fromkeys(r["scheme"] for r in result["rows"]))
    order = {(f["scheme"], f["until"]): f["own"][0] for f in fits}
    ncol = 2 if len(times) > 1 else 1
    nrow = -(-len(times) // ncol)
    fig, axes = plt.subplots(nrow, ncol, figsize=(6.5 * ncol, 4.6 * nrow), squeeze=False)
    for j, (ax, until) in enumerate(zip(axes.ravel(), times)):
        for scheme in schemes:
            colour, marker = WINDOW_STYLE.get(scheme, ("tab:green", "v"))
            rows = [r for r in result["rows"] if r["scheme"] == scheme]
            dts = [r["dt"] for r in rows]
            p = order[scheme, until]
            ax.plot(dts, [1e3 * r["own"][j] for r in rows], "-", marker=marker, color=colour,
                    ms=4, label=f"{scheme} (order {p:.2f})" if np.isfinite(p) else scheme)
            ax.plot(dts, [1e3 * r["errors"][j] for r in rows], "--", marker=marker,
                    color=colour, ms=4, mfc="none", lw=0.9)
        d = np.array([min(DT_GRID), 10 * min(DT_GRID)])
        anchor = 0.3 * min(1e3 * r["own"][j] for r in result["rows"] if r["dt"] == d[0])
        ax.plot(d, anchor * (d / d[0]) ** 2, "-.", color="grey", lw=1.0)
        ax.plot(d, anchor * (d / d[0]), ":", color="grey", lw=1.0)
        spread = 1e3 * result["spread"][j]
        low = min(1e3 * min(r["own"][j], r["errors"][j]) for r in result["rows"])
        if spread > 0.1 * low:          # only where it bears on the data
            ax.axhline(spread, color="tab:purple", lw=0.8)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("Δt (s)")
        ax.set_ylabel("largest distance of the centre of mass (mm)")
        ax.set_title(f"t ≤ {until:g} s", fontsize=10)
        ax.grid(True, which="major", alpha=0.3)
        ax.legend(fontsize=7, loc="lower right", title="against its own run", title_fontsize=7)
    for ax in axes.ravel()[len(times):]:
        ax.set_visible(False)
    fig.suptitle("10° lander over its first 0.2 s, by window. Solid: distance from the "
                 "scheme's own run at Δt = 1 µs (fitted order in the legend); dashed, open: "
                 "from the regularised reference;\npurple: that reference's spread (w = 1e-6 "
                 "against 1e-7 m²/s) where it reaches the data; grey: slopes 1 (dotted) and 2 "
                 "(dash-dot)", fontsize=9)
    fig.tight_layout(rect=(0, 0, 1, 0.94))
    with replacing(path) as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)


def plot_roundoff(rows, need, path):
    """How far one ulp of the initial velocity moves each run against time (the
    ``curve`` of each row of ``roundoff.roundoff_runs``), with the reference
    accuracy each scheme's whole-run fit needs (``need``: scheme → m RMS,
    ``roundoff.needed_references``) as wide pale lines. Distances of zero are left
    out (log axis). The file is written atomically."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from symcushion.run.output_files import replacing

    fig, ax = plt.subplots(figsize=(9.5, 6))
    styles = ("-", "--", ":")
    seen, spare = {}, iter(("tab:purple", "tab:olive", "tab:cyan", "tab:pink"))
    for r in rows:
        k = seen[r["scheme"]] = seen.get(r["scheme"], -1) + 1      # the scheme's k-th Δt
        colour = WINDOW_STYLE[r["scheme"]][0] if r["scheme"] in WINDOW_STYLE else None
        if colour is None:                                       # a regularised reference
            colour, k = next(spare), 0
        um = 1e6 * np.asarray(r["curve"], float)
        step = max(1, um.size // 2000)
        t, um = np.asarray(r["curve_t"])[::step], um[::step]
        ax.plot(t[um > 0], um[um > 0], styles[k % 3], color=colour, lw=1.1,
                label=f"{r['scheme']}, Δt = {r['dt']:g} s (RMS {1e6 * r['rms']:.2g} µm)")
    for scheme, value in need.items():
        colour = WINDOW_STYLE.get(scheme, ("tab:green", "v"))[0]
        ax.axhline(1e6 * value, color=colour, lw=5, alpha=0.25,
                   label=f"reference a whole-run fit of {scheme} needs "
                         f"({1e6 * value:.2g} µm RMS)")
    ax.set_yscale("log")
    ax.set_xlabel("t (s)")
    ax.set_ylabel("distance between the run and its twin (µm)")
    ax.grid(True, which="major", alpha=0.3)
    ax.legend(fontsize=7, loc="lower right")
    nudge = rows[0]["nudge"] if rows else float("nan")
    ax.set_title("10° lander (studies/lander_slope.toml): how far the centre of mass moves when "
                 f"the initial velocity\nacross the slope changes by one ulp ({nudge:.2g} m/s), "
                 "each run against its unmoved twin", fontsize=10)
    fig.tight_layout()
    with replacing(path) as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)
