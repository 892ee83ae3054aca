"""How reliable is the error estimate of a fixed-Δt run? (docs/error-control.md)

Every fixed-Δt ``simulate`` estimates the error of its peaks (specific force,
leg force, stroke) and of its final state by Richardson's rule from a
companion run: at 2Δt (``estimate="coarse"``, the default) or at Δt/2
(``estimate="fine"``). This study runs four landers at every Δt of
:data:`RUN_DTS`, forms both estimates for Δt = 4 … 0.25 ms from those runs
with the library's own :func:`~symcushion.run.error_control.estimate_report` (a
companion is exactly the run at 2Δt or Δt/2), and compares them with the true
error against a reference run at :data:`REFERENCE_DT`.

Prints the table and a summary, writes ``figures/error_estimate.csv`` and
``figures/error_estimate.png``. About eight minutes on two cores;
``--from-csv`` prints and plots the CSV written before, without running.

    PYTHONPATH=. python studies/error_estimate.py [--from-csv]
"""
from __future__ import annotations

import csv
import sys
import warnings
from pathlib import Path

import numpy as np

from symcushion import build_model, load_scene, simulate
from symcushion.run.error_control import COMPANIONS, PEAKS, estimate_report
from symcushion.layout.vectors import state_layout

ROOT = Path(__file__).resolve().parents[1]
SCENES = ("studies/lunar_lander300.toml", "studies/lander_slope.toml",
          "studies/lander_hop.toml", "studies/tutorial/lander.toml")
DTS = (4e-3, 2e-3, 1e-3, 5e-4, 2.5e-4)
#: Every Δt run: those studied and their companions at 2Δt and Δt/2.
RUN_DTS = (8e-3,) + DTS + (1.25e-4,)
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
    """One row per Δt and quantity: value, true error, both estimates."""
    scene, model, ref_peaks, ref_final = reference(path)
    runs = {dt: simulate(scene.with_(dt=dt), model=model, monitor=False, estimate=False)
            for dt in RUN_DTS}
    rows = []
    for dt in DTS:
        run = runs[dt]
        estimates = {}
        for name, ratio in COMPANIONS.items():
            other = runs[dt * ratio]
            estimates[name], _ = estimate_report(
                run.info["peaks"], other.info["peaks"], run.info["final_state"],
                other.info["final_state"], dt=dt, companion_dt=dt * ratio, scene=scene,
                rtol=1e-2)
        final = _final(run, len(scene.legs))
        for key in PEAKS:
            value = run.info["peaks"][key]
            rows.append(dict({"scene": scene.name, "dt_s": dt, "quantity": key, "value": value,
                              "true_error": abs(value - ref_peaks[key]),
                              "reference": ref_peaks[key]},
                             **{name: est["peaks"][key]["error"]
                                for name, est in estimates.items()}))
        for key in FINAL:
            part = key.split("_", 1)[1]
            rows.append(dict({"scene": scene.name, "dt_s": dt, "quantity": key,
                              "value": float(np.linalg.norm(final[key])),
                              "true_error": float(np.max(np.abs(final[key] - ref_final[key]))),
                              "reference": float(np.linalg.norm(ref_final[key]))},
                             **{name: est["final_state"][part]["error"]
                                for name, est in estimates.items()}))
    for row in rows:
        for name in COMPANIONS:
            row[f"{name}_ratio"] = row[name] / row["true_error"] if row["true_error"] > 0 \
                else np.inf
    return rows


def summary(rows, quantities, name, scenes=None) -> str:
    r = np.array([row[f"{name}_ratio"] for row in rows if row["quantity"] in quantities
                  and (scenes is None or row["scene"] in scenes)])
    within = np.mean((r >= 1 / FACTOR) & (r <= FACTOR))
    return (f"{len(r)} cases: {within:.0%} within a factor {FACTOR:g}, "
            f"{np.mean(r < 1 / FACTOR):.0%} underestimated, {np.mean(r > FACTOR):.0%} "
            f"overestimated by more; median ratio {np.median(r):.2f}")


#: The ratios e(2Δt)/e(Δt) of true errors that some order of convergence in
#: [0.5, 3] gives: outside them (or where the signed error of a peak changes
#: sign) a halving is not asymptotic and no companion run can track its error.
ASYMPTOTIC_RATIOS = (2 ** 0.5, 2 ** 3)


def non_asymptotic(rows) -> str:
    """How many halvings Δt → Δt/2 are not asymptotic, and how many of the fine
    companion's misses fall at one."""
    table = {(r["scene"], r["quantity"], r["dt_s"]): r for r in rows}
    lo, hi = ASYMPTOTIC_RATIOS
    halvings = bad = misses = at_bad = 0
    for (scene, quantity, dt), r in table.items():
        half = table.get((scene, quantity, dt / 2))
        if half is None:
            continue
        ratio = r["true_error"] / half["true_error"]
        flips = quantity in PEAKS and np.sign(r["value"] - r["reference"]) != np.sign(
            half["value"] - half["reference"])
        odd = flips or not lo <= ratio <= hi
        halvings, bad = halvings + 1, bad + odd
        miss = not 1 / FACTOR <= r["fine_ratio"] <= FACTOR
        misses, at_bad = misses + miss, at_bad + (miss and odd)
    return (f"{bad} of {halvings} halvings not asymptotic (true-error ratio outside "
            f"[{lo:.2f}, {hi:g}] or a sign change); {at_bad} of the fine companion's "
            f"{misses} misses there")


def figure(rows, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from symcushion.run.output_files import replacing

    fig, axes = plt.subplots(2, 2, figsize=(11, 10.5))
    markers = dict(zip(dict.fromkeys(r["scene"] for r in rows), "osD^"))
    for i, (name, ratio) in enumerate(COMPANIONS.items()):
        groups = ((axes[i, 0], list(PEAKS), "peaks (relative error)", True),
                  (axes[i, 1], list(FINAL), "final state (m, m/s)", False))
        for ax, keys, title, relative in groups:
            for key, color in zip(keys, ("C0", "C1", "C2")):
                for scene, marker in markers.items():
                    sel = [r for r in rows if r["quantity"] == key and r["scene"] == scene]
                    scale = np.array([abs(r["reference"]) if relative else 1.0 for r in sel])
                    ax.scatter(np.array([r["true_error"] for r in sel]) / scale,
                               np.array([r[name] for r in sel]) / scale, c=color,
                               marker=marker, s=28, label=f"{key}, {scene}")
            ax.set(xscale="log", yscale="log", xlabel="true error", ylabel="estimated error",
                   title=f"{title}: {name} companion ({ratio:g} Δt)")
            lo = min(ax.get_xlim()[0], ax.get_ylim()[0])
            hi = max(ax.get_xlim()[1], ax.get_ylim()[1])
            lim = np.array([lo, hi])
            ax.plot(lim, lim, "k-", lw=0.8)
            for f in (FACTOR, 1 / FACTOR):
                ax.plot(lim, f * lim, "k:", lw=0.8)
            ax.set(xlim=lim, ylim=lim)
            ax.grid(True, which="major", alpha=0.3)
    handles, labels = [], []
    for ax in axes[0]:
        h, lab = ax.get_legend_handles_labels()
        handles, labels = handles + h, labels + lab
    fig.legend(handles, labels, fontsize=7, ncol=4, loc="lower center")
    fig.suptitle(f"Richardson estimate (order 1) against the true error (reference at "
                 f"{REFERENCE_DT * 1e3:g} ms), Δt = 4 … 0.25 ms; dotted: factor {FACTOR:g}")
    fig.tight_layout(rect=(0.0, 0.11, 1.0, 1.0))
    with replacing(path) as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)


def _read_csv(path) -> list:
    """Rows of a CSV this study wrote, numbers as floats."""
    with open(path, newline="") as fh:
        return [{k: v if k in ("scene", "quantity") else float(v) for k, v in row.items()}
                for row in csv.DictReader(fh)]


def main():
    warnings.simplefilter("ignore")          # the coarse runs' own findings
    out = ROOT / "figures"
    if "--from-csv" in sys.argv[1:]:
        rows = _read_csv(out / "error_estimate.csv")
    else:
        rows = []
        for path in SCENES:
            rows += study_scene(path)
    print("| scene | Δt (ms) | quantity | true error | coarse (2Δt) | ratio | fine (Δt/2) | "
          "ratio |")
    print("|---|---:|---|---:|---:|---:|---:|---:|")
    for r in rows:
        rel = r["reference"] if r["quantity"] in PEAKS else 1.0
        print(f"| {r['scene']} | {r['dt_s'] * 1e3:g} | {r['quantity']} | "
              f"{r['true_error'] / rel:.1e} | {r['coarse'] / rel:.1e} | {r['coarse_ratio']:.2g} | "
              f"{r['fine'] / rel:.1e} | {r['fine_ratio']:.2g} |")
    others = [s for s in dict.fromkeys(r["scene"] for r in rows) if s != "lander"]
    for name in COMPANIONS:
        print(f"\n{name} companion:")
        print("  peaks:", summary(rows, PEAKS, name))
        print("  final state:", summary(rows, FINAL, name))
        print("  peaks without the tutorial lander:", summary(rows, PEAKS, name, others))
        print("  final state without it:", summary(rows, FINAL, name, others))
    print("\n" + non_asymptotic(rows))
    with open(out / "error_estimate.csv", "w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    figure(rows, out / "error_estimate.png")
    print(f"wrote {out / 'error_estimate.csv'} and {out / 'error_estimate.png'}")


if __name__ == "__main__":
    main()
