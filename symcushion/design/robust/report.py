"""The result directory of a design-for-the-envelope study, and its figures.

Owns what :func:`~.study.run_robust_study` writes: ``result.json`` (design,
solver status, risk before and after, Ipopt's multipliers, P(stable) before
and after with Wilson intervals overall, per slope band and per class,
timings), ``scenarios.csv`` (each scenario's conditions and value/limit of
every check at the start and the optimum), the two verification envelopes
(``before/`` and ``after/``, as ``symcushion envelope`` writes them),
``before_after.png`` (P(stable) per slope band and cases per class, side by
side), ``curves.png`` (the tuned characteristics before and after) and
``designed.toml`` (the study file with the optimum written in, an envelope
study of its own: :mod:`symcushion.design.scene_file`). Every file is
written atomically. It must not run anything.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from symcushion.envelope.classify import CLASSES
from symcushion.envelope.runner import write_result
from symcushion.envelope.study import VARIABLES
from symcushion.run.output_files import (atomic_write_text, check_out_dir, jsonable, replacing,
    to_json, versions)
from symcushion.design.robust.margins import CHECKS
from symcushion.design.scene_file import write_designed_file

__all__ = ["write_report", "write_designed", "plot_before_after", "plot_curves", "DESIGNED_FILE"]

#: The design's own study file in the result directory.
DESIGNED_FILE = "designed.toml"


def _envelope_block(result) -> dict:
    if result is None:
        return None
    s = result.summary()
    return dict(p_stable=s["p_stable"], by_slope=s["p_stable_by_slope"], counts=s["counts"],
                cases=s["cases"], seed=s["seed"], run_seconds=result.timings["run_seconds"])


def write_report(run: dict, out_dir) -> dict:
    """Write the result directory of a study run; return {what: path}."""
    out = check_out_dir(out_dir, "out_dir")
    study, res, problem = run["study"], run["result"], run["problem"]
    files = {}
    summary = dict(
        study=study.name, description=study.description, source=study.source,
        design=res.design, start=dict(zip(problem.var_names, map(float, problem.initial))),
        bounds={n: [float(lo), float(hi)] for n, lo, hi in
                zip(problem.var_names, problem.lower, problem.upper)},
        return_status=res.return_status, iterations=res.iterations,
        risk=dict(measure=study.risk, alpha=study.alpha, start=res.objective_start,
                  optimum=res.objective, saturation=study.saturation,
                  sharpness=study.sharpness, horizon=problem.horizon),
        scenarios=dict(count=len(res.scenarios), pool=study.pool, pool_seed=study.pool_seed,
                       within_start=res.scenarios_within("start"),
                       within_optimum=res.scenarios_within()),
        multipliers=res.multipliers, gradient=run.get("gradient", {}),
        before=_envelope_block(run.get("before")), after=_envelope_block(run.get("after")),
        characteristics=dict(start=problem.characteristics(problem.initial),
                             optimum=problem.characteristics(res.theta)),
        outer_loop=run.get("rounds"),
        seconds=run["seconds"], timings=res.timings, history=res.history,
        versions=versions())
    files["result"] = atomic_write_text(out / "result.json", to_json(jsonable(summary)))
    files["scenarios"] = atomic_write_text(out / "scenarios.csv", _scenarios_csv(run))
    for label in ("before", "after"):
        if run.get(label) is not None:
            write_result(run[label], out / label, plots=True)
            files[label] = out / label
    if run.get("before") is not None and run.get("after") is not None:
        files["before_after"] = plot_before_after(run["before"], run["after"],
                                                  out / "before_after.png", study.name)
    files["curves"] = plot_curves(problem, res.theta, out / "curves.png")
    if study.data:
        files["designed"] = write_designed(run, out / DESIGNED_FILE)
    return files


def write_designed(run: dict, path) -> Path:
    """The study file with the kept design written in: an envelope study named
    ``<study>_designed`` that ``symcushion envelope`` runs as it stands."""
    from symcushion.envelope.study import study_from_dict

    study, res, problem = run["study"], run["result"], run["problem"]
    data = dict(study.data)
    table = dict(data.get("study", {}))
    table["name"] = f"{study.name}_designed"
    table["description"] = (f"{study.description} (designed)" if study.description
                            else f"{study.name}, designed")
    data["study"] = table
    lines = [f"The design of {study.source}, written by `symcushion design`:",
             f"Ipopt {res.return_status} after {res.iterations} iterations; risk "
             f"({study.risk}) {res.objective_start:.4g} -> {res.objective:.4g} on "
             f"{len(res.scenarios)} scenarios of {problem.horizon:g} s."]
    after = run.get("after")
    if after is not None:
        ps = after.p_stable()
        lines.append(f"P(stable) on {after.n:,} touchdowns (seed {study.envelope.seed}): "
                     f"{ps['p']:.3f} [{ps['low']:.3f}, {ps['high']:.3f}], 95 % interval.")
    lines += ["Design variables at the optimum: " + ", ".join(
        f"{n} = {v:.6g}" for n, v in zip(res.var_names, res.theta)),
              "", f"  symcushion envelope {DESIGNED_FILE} --out OUT",
              f"  symcushion simulate {DESIGNED_FILE} --case N   (touchdown N of the study)"]
    return write_designed_file(path, data, problem, res.theta,
                               lambda d: study_from_dict(d, str(path)).scene,
                               header="\n".join(lines))


def _scenarios_csv(run) -> str:
    res, pool, idx = run["result"], run["pool"], run["indices"]
    head = ["scenario", "pool_case", "class_start"] + list(VARIABLES) + \
        [f"{c}_start" for c in CHECKS] + [f"{c}_optimum" for c in CHECKS]
    lines = [",".join(head)]
    for s, i in enumerate(idx):
        row = [res.scenarios[s], str(int(i)), str(pool.columns["class"][i])]
        row += [repr(float(pool.conditions[k][i])) for k in VARIABLES]
        row += [repr(float(v)) for v in res.ratios_start[:, s]]
        row += [repr(float(v)) for v in res.ratios[:, s]]
        lines.append(",".join(row))
    return "\n".join(lines) + "\n"


def _save(fig, path):
    import matplotlib.pyplot as plt

    with replacing(path) as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)
    return Path(path)


def plot_before_after(before, after, path, title: str = "") -> Path:
    """P(stable) per slope band (Wilson intervals) and cases per class, before and after."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4.2))
    width = 0.38
    for k, (label, r, colour) in enumerate((("starting design", before, "#9aa7b1"),
                                            ("optimum", after, "#1f77b4"))):
        bins = r.summary()["p_stable_by_slope"]
        x = np.arange(len(bins)) + (k - 0.5) * width
        p = np.array([b["p"] if b["p"] is not None else np.nan for b in bins])
        err = np.array([[b["p"] - b["low"], b["high"] - b["p"]] if b["p"] is not None
                        else [0, 0] for b in bins]).T
        ps = r.p_stable()
        ax1.bar(x, p, width, yerr=err, capsize=3, color=colour,
                label=f"{label}: P(stable) = {ps['p']:.3f} [{ps['low']:.3f}, {ps['high']:.3f}]")
        counts = r.counts()
        shown = [c for c in CLASSES if c != "no_touchdown" or counts[c]]
        ax2.bar(np.arange(len(shown)) + (k - 0.5) * width, [counts[c] for c in shown], width,
                color=colour, label=label)
    ax1.set_xticks(range(len(bins)))
    ax1.set_xticklabels([f"{b['slope_deg'][0]:.0f}–{b['slope_deg'][1]:.0f}°" for b in bins])
    ax1.set_xlabel("slope band")
    ax1.set_ylabel("P(stable), 95 % Wilson interval")
    ax1.set_ylim(0, 1.05)
    ax1.axhline(0.8, color="k", lw=0.8, ls=":")
    ax1.legend(loc="lower left", fontsize=8)
    ax2.set_xticks(range(len(shown)))
    ax2.set_xticklabels([c.replace("_", "-") for c in shown], rotation=20)
    ax2.set_ylabel(f"cases of {before.n:,}")
    ax2.legend(fontsize=8)
    fig.suptitle(f"{title}: the same {before.n:,} touchdowns (seed {before.study.seed}) "
                 "on the starting design and the optimum", fontsize=10)
    fig.tight_layout()
    return _save(fig, path)


def plot_curves(problem, theta, path) -> Path:
    """The tuned characteristics at the start (grey) and the optimum (blue)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    start, end = problem.characteristics(problem.initial), problem.characteristics(theta)
    keys = list(end)
    fig, axes = plt.subplots(1, len(keys), figsize=(4.2 * len(keys), 3.6), squeeze=False)
    for ax, key in zip(axes[0], keys):
        for data, colour, label in ((start[key], "#9aa7b1", "start"),
                                    (end[key], "#1f77b4", "optimum")):
            ax.plot(data["x"], data["loading"], "-o", ms=3, color=colour,
                    label=f"{label}, loading")
            if "unloading" in data:
                ax.plot(data["x"], data["unloading"], "--", color=colour,
                        label=f"{label}, unloading")
        unit = ("m", "N") if data["element"] == "S" else ("rad", "N·m")
        ax.set_xlabel(f"deflection ({unit[0]})")
        ax.set_ylabel(f"force ({unit[1]})")
        ax.set_title(f"{key} (legs {', '.join(map(str, data['legs']))})", fontsize=9)
        ax.grid(alpha=0.3)
    axes[0][0].legend(fontsize=7)
    fig.tight_layout()
    return _save(fig, path)
