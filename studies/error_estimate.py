"""How reliable is the error estimate of a fixed-Δt run? (docs/error-control.md)

Every fixed-Δt ``simulate`` estimates the error of its peaks (specific force,
leg force, stroke) and of its final state by Richardson's rule from a
companion run at 2Δt (``info['error_estimate']``). This study compares that
estimate with the true error, measured against a reference run at
:data:`REFERENCE_DT` (Δt/16 of the finest Δt), on four landers at Δt = 4, 2,
1, 0.5 and 0.25 ms, and fits the order at which each quantity converges.

Prints the table and a summary, writes ``figures/error_estimate.csv`` and
``figures/error_estimate.png`` (estimated against true error). About a minute
on two cores.

    PYTHONPATH=. python studies/error_estimate.py
"""
from __future__ import annotations

import csv
import warnings
from pathlib import Path

import numpy as np

from symcushion import build_model, load_scene, simulate
from symcushion.error_control import PEAKS
from symcushion.layout import state_layout

ROOT = Path(__file__).resolve().parents[1]
SCENES = ("studies/lunar_lander300.toml", "studies/lander_slope.toml",
          "studies/lander_hop.toml", "studies/tutorial/lander.toml")
DTS = (4e-3, 2e-3, 1e-3, 5e-4, 2.5e-4)
#: Δt of the reference runs: 1/16 of the finest Δt studied.
REFERENCE_DT = DTS[-1] / 16
#: The target of the estimate: within this factor of the true error.
FACTOR = 3.0
FINAL = {"final_position": "m", "final_velocity": "m/s"}


def _final(traj, n_legs) -> dict:
    xl = state_layout(n_legs)
    x = traj.info["final_state"]
    return {"final_position": xl.get(x, "position"), "final_velocity": xl.get(x, "velocity")}


def reference(path):
    """The scene, its model and its reference run's peaks and final state."""
    scene = load_scene(ROOT / path)
    model = build_model(scene)
    run = simulate(scene.with_(dt=REFERENCE_DT), model=model, monitor=False, estimate=False)
    return scene, model, dict(run.info["peaks"]), _final(run, len(scene.legs))


def study_scene(path) -> list:
    """One row per Δt and quantity: value, estimated and true error."""
    scene, model, ref_peaks, ref_final = reference(path)
    rows = []
    for dt in DTS:
        run = simulate(scene.with_(dt=dt), model=model, monitor=False)
        est = run.info["error_estimate"]
        final = _final(run, len(scene.legs))
        for key in PEAKS:
            value = run.info["peaks"][key]
            rows.append({"scene": scene.name, "dt_s": dt, "quantity": key, "value": value,
                         "estimated_error": est["peaks"][key]["error"],
                         "true_error": abs(value - ref_peaks[key]),
                         "reference": ref_peaks[key]})
        for key in FINAL:
            rows.append({"scene": scene.name, "dt_s": dt, "quantity": key,
                         "value": float(np.linalg.norm(final[key])),
                         "estimated_error": est["final_state"][key.split("_", 1)[1]]["error"],
                         "true_error": float(np.max(np.abs(final[key] - ref_final[key]))),
                         "reference": float(np.linalg.norm(ref_final[key]))})
    for row in rows:
        row["ratio"] = row["estimated_error"] / row["true_error"] if row["true_error"] > 0 \
            else np.inf
    return rows


def orders(rows) -> dict:
    """Least-squares order of the true error in Δt, per scene and quantity."""
    out = {}
    for scene in dict.fromkeys(r["scene"] for r in rows):
        for key in dict.fromkeys(r["quantity"] for r in rows):
            sel = [r for r in rows if r["scene"] == scene and r["quantity"] == key
                   and r["true_error"] > 0]
            dt = np.log([r["dt_s"] for r in sel])
            err = np.log([r["true_error"] for r in sel])
            out[scene, key] = float(np.polyfit(dt, err, 1)[0])
    return out


def summary(rows, quantities) -> str:
    r = np.array([row["ratio"] for row in rows if row["quantity"] in quantities])
    within = np.mean((r >= 1 / FACTOR) & (r <= FACTOR))
    return (f"{len(r)} cases: {within:.0%} within a factor {FACTOR:g}, "
            f"{np.mean(r < 1 / FACTOR):.0%} underestimated, {np.mean(r > FACTOR):.0%} "
            f"overestimated by more; median ratio {np.median(r):.2f}, "
            f"range {r.min():.2g}–{r.max():.2g}")


def figure(rows, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from symcushion.results import replacing

    fig, axes = plt.subplots(1, 2, figsize=(11, 5))
    markers = dict(zip(dict.fromkeys(r["scene"] for r in rows), "osD^"))
    groups = ((axes[0], list(PEAKS), "peaks (relative error)", True),
              (axes[1], list(FINAL), "final state (m, m/s)", False))
    for ax, keys, title, relative in groups:
        for key, color in zip(keys, ("C0", "C1", "C2")):
            for scene, marker in markers.items():
                sel = [r for r in rows if r["quantity"] == key and r["scene"] == scene]
                scale = np.array([abs(r["reference"]) if relative else 1.0 for r in sel])
                ax.scatter(np.array([r["true_error"] for r in sel]) / scale,
                           np.array([r["estimated_error"] for r in sel]) / scale,
                           c=color, marker=marker, s=28,
                           label=f"{key}, {scene}" if relative or key == keys[0] else None)
        lo, hi = ax.get_xlim()[0], ax.get_xlim()[1]
        lim = np.array([min(lo, ax.get_ylim()[0]), max(hi, ax.get_ylim()[1])])
        ax.set(xscale="log", yscale="log", xlabel="true error", ylabel="estimated error",
               title=title)
        ax.plot(lim, lim, "k-", lw=0.8)
        for f in (FACTOR, 1 / FACTOR):
            ax.plot(lim, f * lim, "k:", lw=0.8)
        ax.grid(True, which="major", alpha=0.3)
    axes[0].legend(fontsize=6, ncol=1, loc="upper left")
    fig.suptitle(f"Richardson estimate from a run at 2Δt (order 1) against a reference at "
                 f"{REFERENCE_DT * 1e3:g} ms; dotted: factor {FACTOR:g}")
    fig.tight_layout()
    with replacing(path) as tmp:
        fig.savefig(tmp, dpi=120, format="png")
    plt.close(fig)


def main():
    warnings.simplefilter("ignore")          # the coarse runs' own estimate warnings
    rows = []
    for path in SCENES:
        rows += study_scene(path)
    print("| scene | Δt (ms) | quantity | value | estimated error | true error | ratio |")
    print("|---|---:|---|---:|---:|---:|---:|")
    for r in rows:
        print(f"| {r['scene']} | {r['dt_s'] * 1e3:g} | {r['quantity']} | {r['value']:.5g} | "
              f"{r['estimated_error']:.2e} | {r['true_error']:.2e} | {r['ratio']:.2f} |")
    print("\npeaks:", summary(rows, PEAKS))
    print("final state:", summary(rows, FINAL))
    print("\nmeasured order of the true error (least squares over Δt = 4 … 0.25 ms):")
    for (scene, key), p in orders(rows).items():
        print(f"  {scene:14s} {key:22s} {p:5.2f}")
    out = ROOT / "figures"
    with open(out / "error_estimate.csv", "w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    figure(rows, out / "error_estimate.png")
    print(f"wrote {out / 'error_estimate.csv'} and {out / 'error_estimate.png'}")


if __name__ == "__main__":
    main()
