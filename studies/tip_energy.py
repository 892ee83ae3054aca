"""Does the tip-over energy margin tell the tip-overs from the landers that stay up?

Runs a pool of the design-for-envelope study's touchdowns (its own ranges
and starting legs, seed 11: the design's pool seed) through the envelope,
then evaluates the design's smooth margins on the same cases, and compares
the ``tip_energy`` ratio (1 + surplus/0.1 m, largest over the touchdown
while upright; docs/optimise.md, "Tip-over energy") with the envelope's
classes. Prints the ratio's range per class and how well thresholds
separate the tip-overs, and draws ``figures/tip_energy.png``.

    python studies/tip_energy.py [--n 400]
"""
from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib
import numpy as np

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from symcushion.envelope import run_envelope  # noqa: E402
from symcushion.run.output_files import replacing  # noqa: E402
from symcushion.design.robust import CHECKS, EnvelopeDesign  # noqa: E402
from symcushion.design.robust.study import load_robust_study  # noqa: E402

HERE = Path(__file__).resolve().parent
STUDY = HERE / "design_for_envelope.toml"
FIGURE = HERE.parent / "figures" / "tip_energy.png"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=400, help="touchdowns in the pool")
    ap.add_argument("--seed", type=int, default=11)
    args = ap.parse_args(argv)
    study = load_robust_study(STUDY)
    pool = run_envelope(study.envelope.with_(n=args.n, seed=args.seed), threads=2,
                        progress=False, plots=False)
    cls = np.asarray(pool.columns["class"]).astype(str)
    design = EnvelopeDesign(study.envelope, pool.conditions, study.variables,
                            horizon=study.horizon, threads=2, progress=False)
    ratio = design.ratios()[CHECKS.index("tip_energy")]
    if not np.all(np.isfinite(ratio)):
        raise RuntimeError("a tip-over energy ratio is not finite")
    print(f"{args.n} touchdowns (seed {args.seed}), starting design of {STUDY.name}")
    print("| class | cases | tip_energy min | median | max |")
    print("|---|---:|---:|---:|---:|")
    for c in np.unique(cls):
        r = ratio[cls == c]
        print(f"| {c} | {r.size} | {r.min():.2f} | {np.median(r):.2f} | {r.max():.2f} |")
    tipped = cls == "tip_over"
    print("\n| threshold | tip-overs at or above | other cases at or above |")
    print("|---:|---:|---:|")
    for t in (0.8, 1.0, 1.2, 1.5):
        print(f"| {t:.1f} | {np.mean(ratio[tipped] >= t):.1%} | {np.mean(ratio[~tipped] >= t):.1%} |")
    draw(ratio, cls)


def draw(ratio, cls):
    fig, ax = plt.subplots(figsize=(7, 3.6))
    bins = np.linspace(min(-0.5, ratio.min()), max(3.0, min(ratio.max(), 6.0)), 50)
    for c, colour in (("stable", "tab:green"), ("tip_over", "tab:red")):
        ax.hist(np.clip(ratio[cls == c], bins[0], bins[-1]), bins, alpha=0.6, color=colour,
                label=f"{c} ({np.sum(cls == c)})")
    other = (cls != "stable") & (cls != "tip_over")
    ax.hist(np.clip(ratio[other], bins[0], bins[-1]), bins, alpha=0.6, color="tab:gray",
            label=f"other failures ({np.sum(other)})")
    ax.axvline(1.0, color="k", lw=1, ls="--")
    ax.text(1.02, ax.get_ylim()[1] * 0.9, "energy to pass over an edge", fontsize=8)
    ax.set_xlabel("tip-over energy ratio, 1 + surplus / 0.1 m (largest while upright)")
    ax.set_ylabel("touchdowns")
    ax.set_title("Tip-over energy margin against the envelope's classes", fontsize=10)
    ax.legend(fontsize=8)
    fig.tight_layout()
    FIGURE.parent.mkdir(exist_ok=True)
    with replacing(FIGURE) as tmp:          # no half-written figure on an interrupt
        fig.savefig(tmp, dpi=110)
    print(f"wrote {FIGURE}")


if __name__ == "__main__":
    main()
