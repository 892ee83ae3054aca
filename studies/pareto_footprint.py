"""How much stability does another 10 cm of stance buy? P(stable) against the footprint limit.

Question: for the example lander (studies/envelope_lander.toml: its body,
touchdown ranges, absorbers with memory and limits), what P(stable) can a
design of the legs reach when every foot at rest must lie within R of the
body axis, for R from 0.7 to 1.1 m?

Method: for each R, the design study studies/design_geometry_memory.toml
(crush curve, spring-back, hinge stiffnesses, and the shared hinge radius,
L₀ and splay, designed over the 0.7-s tipping phase; docs/design-geometry.md,
"Run 5") is solved with ``design.limits.footprint_radius = R`` and a box wide
enough that the footprint, not the box, bounds the stance: hinge radius
0.4–1.1 m, L₀ 0.55–1.0 m, splay 0–30° (the hinge clearance at full stroke,
0.3 m, keeps L₀ above about 0.55 m). Each optimum is written as its own
study file (``designed.toml``) and verified by Monte Carlo on the example's
10,000 held-out touchdowns (seed 2024; the design's pool has seed 11) with
the example's limits and at-rest check, 2 s per touchdown: P(stable) with
its 95 % Wilson interval. The example lander itself is the reference point.

Output: figures/pareto_footprint.png and figures/pareto_footprint.csv (one
row per R: the limit, the feet's radius at rest, the geometry, Ipopt's
status and iterations, the risk, P(stable) [low, high] and the cases per
class); each point's design directory under ``--out``. A point whose
``verified.json`` exists is read back, not solved again, so an interrupted
study resumes where it stopped.

    python studies/pareto_footprint.py [--limits 0.7 0.75 0.8 0.9 1.0 1.1] [--out out/pareto_footprint]
"""
from __future__ import annotations

import argparse
import copy
import json
import math
import time
from pathlib import Path

import numpy as np

from symcushion.design.robust.study import robust_study_from_dict, run_robust_study
from symcushion.envelope import CLASSES, run_envelope
from symcushion.envelope.statistics import wilson_interval
from symcushion.envelope.study import study_from_dict as envelope_from_dict
from symcushion.model.scene import read_toml
from symcushion.run.output_files import atomic_write_text, replacing

HERE = Path(__file__).resolve().parent
DESIGN = HERE / "design_geometry_memory.toml"
EXAMPLE = HERE / "envelope_lander.toml"
FIGURES = HERE.parent / "figures"
LIMITS = (0.7, 0.75, 0.8, 0.9, 1.0, 1.1)
#: The geometry's box: wide enough that the footprint limit bounds the stance.
BOX = {"hinge_radius": dict(lower=0.4, upper=1.1), "length": dict(lower=0.55, upper=1.0),
       "splay": dict(lower_deg=0.0, upper_deg=30.0)}
#: Ipopt iterations per design; None: the design's own limit (200), each solve runs
#: to Ipopt's tolerance (docs/optimise.md, "Convergence").
MAX_ITER = None


def design_data(limit: float, max_iter: int | None = MAX_ITER) -> dict:
    """The design study with footprint ``limit`` and the wide box."""
    data = read_toml(DESIGN, "design study")    # its name kept: one margins library serves all
    data["design"]["limits"]["footprint_radius"] = limit
    for g in data["design"]["geometry"]:
        for key in ("lower", "upper", "lower_deg", "upper_deg"):
            g.pop(key, None)
        g.update(BOX[g["quantity"]])
    if max_iter is not None:
        data["robust"]["ipopt"] = dict(data["robust"].get("ipopt", {}), max_iter=max_iter)
    return data


def with_example_rules(designed: dict, example: dict, n: int | None = None) -> dict:
    """A designed study judged by the example's rules: its limits, duration, sampling."""
    out = copy.deepcopy(designed)
    out["limits"] = copy.deepcopy(example["limits"])
    out["sampling"] = copy.deepcopy(example["sampling"])
    if n is not None:
        out["sampling"]["n"] = n
    out["scene"]["duration"] = example["scene"]["duration"]
    return out


def verify(data: dict, source: str, cache) -> dict:
    """P(stable) of a study on its own touchdowns: the summary ``symcushion envelope`` prints."""
    result = run_envelope(envelope_from_dict(data, source), cache_dir=cache, progress=True,
                          plots=False)
    ps = result.p_stable()
    return dict(p=ps["p"], low=ps["low"], high=ps["high"], cases=result.n,
                counts={c: int(n) for c, n in result.counts().items()})


def solve_point(limit: float, out: Path, example: dict, cache, max_iter: int | None = MAX_ITER,
                n: int | None = None) -> dict:
    """Design for one footprint limit and verify it; read back if already done."""
    folder = out / f"R_{limit:.2f}"
    done = folder / "verified.json"
    if done.is_file():
        return json.loads(done.read_text())
    started = time.perf_counter()
    # one source for every point: the pool's scene keeps its name, so its library is built once
    study = robust_study_from_dict(design_data(limit, max_iter), str(DESIGN))
    run = run_robust_study(study, folder, verify=False, cache_dir=cache)
    res = run["result"]
    geo = res.geometry["end"]
    designed = read_toml(folder / "designed.toml", "designed study")
    row = dict(limit=limit, return_status=res.return_status, iterations=res.iterations,
               risk_start=res.objective_start, risk=res.objective,
               design=dict(zip(res.var_names, map(float, res.theta))),
               foot_radius=max(leg["foot_radius"] for leg in geo.values()),
               verified=verify(with_example_rules(designed, example, n),
                               str(folder / "designed.toml"), cache),
               seconds=None)
    row["seconds"] = time.perf_counter() - started
    atomic_write_text(done, json.dumps(row, indent=2) + "\n")
    return row


def without_rest(verified: dict) -> tuple:
    """P(stable) [low, high] if the at-rest check were left out: the ``moving`` cases
    (within every limit, not at rest at 2 s) counted stable, as the design's own
    0.7-s rules count them."""
    k = verified["counts"].get("stable", 0) + verified["counts"].get("moving", 0)
    return tuple(float(v) for v in wilson_interval(k, verified["cases"]))


def csv_text(rows: list, reference: dict) -> str:
    head = ["footprint_limit_m", "foot_radius_m", "hinge_radius_m", "length_m", "splay_deg",
            "return_status", "iterations", "risk_start", "risk", "p_stable", "low", "high",
            "p_without_rest", "low_without_rest", "high_without_rest"] + \
        [f"n_{c}" for c in CLASSES]
    lines = [",".join(head)]
    ref = reference["verified"]
    lines.append(",".join(["example", f"{reference['foot_radius']:.4f}", "0.5", "0.8", "20.0",
                           "", "", "", "", f"{ref['p']:.4f}", f"{ref['low']:.4f}",
                           f"{ref['high']:.4f}"] + [f"{v:.4f}" for v in without_rest(ref)]
                          + [str(ref["counts"].get(c, 0)) for c in CLASSES]))
    for r in rows:
        d, v = r["design"], r["verified"]
        lines.append(",".join([f"{r['limit']:.2f}", f"{r['foot_radius']:.4f}",
                               f"{d['hinge_radius']:.4f}", f"{d['length']:.4f}",
                               f"{math.degrees(d['splay']):.2f}", r["return_status"],
                               str(r["iterations"]), f"{r['risk_start']:.5f}",
                               f"{r['risk']:.5f}", f"{v['p']:.4f}", f"{v['low']:.4f}",
                               f"{v['high']:.4f}"] + [f"{x:.4f}" for x in without_rest(v)]
                              + [str(v["counts"].get(c, 0)) for c in CLASSES]))
    return "\n".join(lines) + "\n"


def plot(rows: list, reference: dict, path: Path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax, bx, cx) = plt.subplots(1, 3, figsize=(15, 4.2), constrained_layout=True)
    R = np.array([r["limit"] for r in rows])
    feet = np.array([r["foot_radius"] for r in rows])
    p = np.array([r["verified"]["p"] for r in rows])
    lo = np.array([r["verified"]["low"] for r in rows])
    hi = np.array([r["verified"]["high"] for r in rows])
    ax.errorbar(R, p, yerr=[p - lo, hi - p], fmt="o-", capsize=4, color="C0",
                label="designed legs, the example's rules (95 % interval)")
    free = np.array([without_rest(r["verified"]) for r in rows])
    ax.errorbar(R, free[:, 0], yerr=[free[:, 0] - free[:, 1], free[:, 2] - free[:, 0]],
                fmt="^--", capsize=3, color="C2", alpha=0.8,
                label="the same without the at-rest check\n(the design's own 0.7-s rules)")
    ref = reference["verified"]
    ax.errorbar([reference["foot_radius"]], [ref["p"]],
                yerr=[[ref["p"] - ref["low"]], [ref["high"] - ref["p"]]], fmt="s", capsize=4,
                color="C3", label="the example lander (at its feet's radius)")
    ax.set_xlabel("footprint limit R: every foot at rest within R of the axis (m)")
    ax.set_ylabel("P(stable), 10,000 held-out touchdowns")
    ax.set_ylim(0.4, 1.0)
    ax.grid(alpha=0.3)
    ax.legend(loc="center right", fontsize=8)
    ax.set_title("stability bought by stance")
    bx.plot(R, feet, "o-", label="feet at rest (m)")
    bx.plot(R, [r["design"]["hinge_radius"] for r in rows], "s-", label="hinge radius ρ (m)")
    bx.plot(R, [r["design"]["length"] for r in rows], "^-", label="rest length L₀ (m)")
    bx.plot(R, R, "k:", lw=1, label="the limit R")
    twin = bx.twinx()
    twin.plot(R, [math.degrees(r["design"]["splay"]) for r in rows], "d--", color="C4",
              label="splay (°, right)")
    twin.set_ylabel("splay (°)")
    twin.set_ylim(-1, 31)
    bx.set_xlabel("footprint limit R (m)")
    bx.set_ylabel("m")
    bx.grid(alpha=0.3)
    handles = bx.get_legend_handles_labels()
    extra = twin.get_legend_handles_labels()
    bx.legend(handles[0] + extra[0], handles[1] + extra[1], fontsize=8, loc="upper left")
    bx.set_title("the designed geometry")
    _plot_failures(cx, rows, reference)
    with replacing(path) as tmp:
        fig.savefig(tmp, dpi=120, format="png")
    plt.close(fig)
    return path


def _plot_failures(ax, rows: list, reference: dict):
    """What still fails: cases per failure class, the example first."""
    labels = ["example"] + [f"{r['limit']:g}" for r in rows]
    counts = [reference["verified"]["counts"]] + [r["verified"]["counts"] for r in rows]
    bottom = np.zeros(len(labels))
    for k, c in enumerate(c for c in CLASSES if c != "stable"):
        n = np.array([cnt.get(c, 0) for cnt in counts], dtype=float)
        if n.any():
            ax.bar(labels, n, bottom=bottom, label=c.replace("_", "-"), color=f"C{k}")
            bottom += n
    ax.set_xlabel("footprint limit R (m)")
    ax.set_ylabel("failed touchdowns of 10,000")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3, axis="y")
    ax.set_title("what still fails")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--limits", type=float, nargs="+", default=list(LIMITS))
    ap.add_argument("--out", type=Path, default=Path("out/pareto_footprint"))
    ap.add_argument("--build-dir", type=Path, default=Path("build"))
    ap.add_argument("--max-iter", type=int, default=MAX_ITER,
                    help="Ipopt iterations per design (default: the study's, 200)")
    ap.add_argument("--n", type=int, default=None,
                    help="touchdowns of each verification (default the example's 10,000)")
    ap.add_argument("--figures", type=Path, default=FIGURES, help="where the figure and CSV go")
    args = ap.parse_args(argv)
    example = read_toml(EXAMPLE, "envelope study")
    if args.n is not None:
        example["sampling"]["n"] = args.n
    started = time.perf_counter()
    ref_file = args.out / "example_verified.json"
    if ref_file.is_file():
        reference = json.loads(ref_file.read_text())
    else:
        study = envelope_from_dict(example, str(EXAMPLE))
        feet = max(math.hypot(*leg.rest_foot[:2]) for leg in study.scene.legs)
        reference = dict(foot_radius=feet, verified=verify(example, str(EXAMPLE),
                                                           args.build_dir))
        args.out.mkdir(parents=True, exist_ok=True)
        atomic_write_text(ref_file, json.dumps(reference, indent=2) + "\n")
    rows = []
    for limit in sorted(args.limits):
        print(f"--- footprint limit {limit:g} m", flush=True)
        rows.append(solve_point(limit, args.out, example, args.build_dir, args.max_iter,
                                args.n))
        v = rows[-1]["verified"]
        print(f"R = {limit:g} m: feet at {rows[-1]['foot_radius']:.3f} m, "
              f"{rows[-1]['return_status']} ({rows[-1]['iterations']} iterations), "
              f"P(stable) = {v['p']:.3f} [{v['low']:.3f}, {v['high']:.3f}]", flush=True)
    args.figures.mkdir(parents=True, exist_ok=True)
    table = atomic_write_text(args.figures / "pareto_footprint.csv", csv_text(rows, reference))
    figure = plot(rows, reference, args.figures / "pareto_footprint.png")
    print(f"wrote {table} and {figure} ({(time.perf_counter() - started) / 60:.1f} min)")


if __name__ == "__main__":
    main()
