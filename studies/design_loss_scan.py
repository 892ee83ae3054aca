"""Are the geometry design's scenario losses smooth where its solve stops?

Question: the memory-law geometry design (studies/design_geometry_memory.toml)
stalled before Ipopt's tolerance. Is its risk a smooth function of the design
near the stall point, or does it jump?

Method: the study's pool and scenarios are drawn as ``symcushion design``
draws them, and the compiled margins are evaluated on lines through a
design θ (``--design``, a ``result.json`` of the study; default its start):
each scaled variable moved alone over ±4e-4 in 81 steps of 1e-5. The risk
(CVaR of the scenario losses) and every scenario's loss are recorded.
``--inset 0`` takes the crush-onset kick's tangents at the step's ends, as
the step did before (``symcushion.scheme.crush_kick.TANGENT_INSET``); the
default takes them just inside. ``--study``, ``--horizon`` and ``--rest``
scan another study, over another horizon, with the at-rest check on (the
example's 0.05 m/s), e.g. a curves-only study over the envelope's 2 s.

Output: ``<out>/scan_inset_<inset>.json`` per run (read back when present)
and, with both runs there, ``figures/design_loss_scan.png``: the risk along
the variable whose risk slope spread most before.

    python studies/design_loss_scan.py --design out/design_geometry_memory/result.json [--inset 0]
    python studies/design_loss_scan.py --study studies/design_for_envelope_wide.toml \
        --horizon 2 --rest --variables 3 --out out/design_loss_scan_2s
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
STUDY = HERE / "design_geometry_memory.toml"
FIGURE = HERE.parent / "figures" / "design_loss_scan.png"
#: Step and half-width of each line, in the scaled variables (all O(1)).
STEP, HALF = 1e-5, 40


#: The at-rest check of ``--rest``: the example envelope's (m/s).
REST_SPEED = 0.05


def load(study_file: Path, horizon, rest: bool):
    """The design study, its horizon and at-rest check as asked."""
    from symcushion.design.robust.study import robust_study_from_dict
    from symcushion.model.scene import read_toml
    data = read_toml(study_file, "design study")
    if horizon is not None:
        data["robust"]["horizon"] = horizon
    if rest:
        data["limits"]["rest_speed"] = REST_SPEED
    return robust_study_from_dict(data, str(study_file))


def scan(study_file: Path, design_file, inset: float, build: Path, horizon=None,
         rest=False, variables=None) -> dict:
    """Risk and losses on the coordinate lines through the design of ``design_file``
    (None: the study's start), of the first ``variables`` variables (None: all)."""
    import symcushion.scheme.crush_kick as crush_kick
    crush_kick.TANGENT_INSET = inset          # before any Function is built
    from symcushion.design.robust.risk import saturate
    from symcushion.design.robust.margins import CHECKS
    from symcushion.design.robust.study import scenario_problem
    from symcushion.envelope.runner import run_envelope

    study = load(study_file, horizon, rest)
    pool = run_envelope(study.envelope.with_(n=study.pool, seed=study.pool_seed),
                        cache_dir=build, progress=False, plots=False)
    problem, _ = scenario_problem(study, pool, dict(threads=None, client=None, cache_dir=build,
                                                    progress=False))
    if design_file is None:
        w0 = problem.initial / problem.scale
    else:
        design = json.loads(Path(design_file).read_text())["design"]
        w0 = np.array([design[n] for n in problem.var_names]) / problem.scale
    rows = [CHECKS.index(c) for c in problem.checks]
    ts = np.arange(-HALF, HALF + 1) * STEP
    lines = {}
    for i, name in enumerate(problem.var_names[:variables]):
        losses, risk = [], []
        for t in ts:
            w = w0.copy()
            w[i] += t
            R = problem.ratios(np.clip(w * problem.scale, problem.lower, problem.upper))
            L = saturate(R[rows], problem.saturation) - 1
            if not np.all(np.isfinite(L)):
                raise RuntimeError(f"a loss is not finite on the line of {name} at {t:g}")
            losses.append(L.tolist())
            risk.append(problem.risk_of(np.max(L, axis=0))[0])
        lines[name] = dict(risk=risk, losses=losses)
    return dict(study=study.name, horizon=problem.horizon, inset=inset, t=ts.tolist(),
                scenarios=problem.names, checks=problem.checks, lines=lines)


def jumps(run: dict) -> dict:
    """Per variable: the largest change of any one loss between neighbours, and its row."""
    out = {}
    for name, line in run["lines"].items():
        L = np.asarray(line["losses"])                       # points × checks × scenarios
        step = np.abs(np.diff(L, axis=0)).max(axis=0)
        c, k = np.unravel_index(np.argmax(step), step.shape)
        out[name] = (float(step[c, k]), run["checks"][c], run["scenarios"][k])
    return out


def spread(run: dict) -> dict:
    """Per variable: the smallest and largest slope of the risk between neighbours."""
    out = {}
    for name, line in run["lines"].items():
        slope = np.diff(line["risk"]) / STEP
        out[name] = (float(slope.min()), float(slope.max()))
    return out


def draw(before: dict, after: dict, path: Path) -> Path:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from symcushion.run.output_files import replacing

    s = spread(before)
    name = max(s, key=lambda k: s[k][1] - s[k][0])
    t = np.asarray(before["t"])
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.8), sharex=True)
    for ax, run, label in ((axes[0], before, "tangents at the step's ends"),
                           (axes[1], after, "tangents just inside the step")):
        r = np.asarray(run["lines"][name]["risk"])
        ax.plot(t * 1e4, (r - r[HALF]) * 1e6, ".-", lw=0.8, ms=3)
        ax.set_title(f"{label}\nrisk slope {spread(run)[name][0]:+.3g} … "
                     f"{spread(run)[name][1]:+.3g}", fontsize=10)
        ax.set_xlabel(f"change of {name} (scaled, ×10⁻⁴)")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("risk − risk at the design (×10⁻⁶)")
    fig.suptitle("The geometry design's risk near its design, crush-onset kick before and "
                 "after", fontsize=11)
    fig.tight_layout()
    with replacing(path) as tmp:
        fig.savefig(tmp, dpi=120, format="png")
    plt.close(fig)
    return path


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--study", type=Path, default=STUDY)
    ap.add_argument("--design", type=Path, default=None,
                    help="result.json of a run of the study (default: its start)")
    ap.add_argument("--horizon", type=float, default=None, help="scenario horizon (s)")
    ap.add_argument("--rest", action="store_true", help="turn the at-rest check on")
    ap.add_argument("--variables", type=int, default=None,
                    help="scan only the first this many variables")
    ap.add_argument("--inset", type=float, default=None,
                    help="TANGENT_INSET of this run (default: the package's)")
    ap.add_argument("--out", type=Path, default=Path("out/design_loss_scan"))
    ap.add_argument("--build-dir", type=Path, default=Path("build"))
    args = ap.parse_args(argv)
    from symcushion.run.output_files import atomic_write_text
    from symcushion.scheme.crush_kick import TANGENT_INSET
    inset = TANGENT_INSET if args.inset is None else args.inset
    done = args.out / f"scan_inset_{inset:g}.json"
    if not done.is_file():
        args.out.mkdir(parents=True, exist_ok=True)
        atomic_write_text(done, json.dumps(scan(args.study, args.design, inset, args.build_dir,
                                                 args.horizon, args.rest, args.variables))
                          + "\n")
    run = json.loads(done.read_text())
    big = jumps(run)
    print(f"{run['study']}, {run['horizon']:g} s, tangent inset {inset:g}:")
    for name, (lo, hi) in spread(run).items():
        step, check, case = big[name]
        print(f"  {name:14s} risk slope {lo:+.4g} … {hi:+.4g}; largest step of one loss "
              f"{step:.3g} ({check}, {case})")
    if args.study.resolve() != STUDY:
        return
    before, after = args.out / "scan_inset_0.json", args.out / f"scan_inset_{TANGENT_INSET:g}.json"
    if before.is_file() and after.is_file():
        print("wrote", draw(json.loads(before.read_text()), json.loads(after.read_text()),
                            FIGURE))


if __name__ == "__main__":
    main()
