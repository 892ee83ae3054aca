"""Which axial characteristic minimises a lander's worst-case peak deceleration?

A 150 kg lander on four legs splayed 20° (``studies/optimise_lander.toml``)
touches down at 3 m/s in four ways: straight, drifting at 1 m/s, on a 10°
slope, and rolled 6° with a diagonal drift. One piecewise-linear axial
characteristic (11 knot values), shared by the four legs, is optimised for
the largest vertical deceleration over all four touchdowns and all steps,
with the axial stroke ≤ 0.25 m, hinge deflections ≤ 0.05 rad, body tilt
≤ 15° and the descent arrested within 0.25 s (docs/optimise.md).

Output: ``out/optimise_lander.json`` (the result, as ``symcushion optimise``
writes it) and ``figures/optimise_lander.png`` (the characteristic before
and after, and the deceleration of each touchdown with the optimum).
Run: ``python studies/optimise_lander.py`` (a few minutes).
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from symcushion.optimise import load_study
from symcushion.simulate import simulate

ROOT = Path(__file__).resolve().parents[1]
STUDY = ROOT / "studies" / "optimise_lander.toml"


def deceleration_histories(result):
    """Vertical deceleration (m/s², gravity excluded) of each scenario at the optimum."""
    problem = result.problem
    out = {}
    for scenario in problem.scenarios:
        traj = simulate(scenario.scene, x0=scenario.x0, p=result.p)
        out[scenario.name] = (traj.t, traj.acceleration[:, 2] - scenario.scene.gravity[2])
    return out


def plot(result, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    data = result.to_dict()
    fig, (left, right) = plt.subplots(1, 2, figsize=(11, 4.2))
    for key, char in data["characteristic"].items():
        start = data["initial_characteristic"][key]
        x = -np.asarray(char["x"]) * 1e3
        left.plot(x, -np.asarray(start["loading"]), "o--", color="0.6", label="start (linear)")
        left.plot(x, -np.asarray(char["loading"]), "o-", label="optimum, loading")
        left.plot(x, -np.asarray(char["unloading"]), ":", label="unloading (fixed)")
    stroke = result.problem.limits.stroke * 1e3
    left.axvline(stroke, color="k", lw=0.8)
    # beyond the stroke limit the curve is never used: show the stroke only
    left.set_xlim(0, 1.1 * stroke)
    left.set_ylim(0, 1.5 * max(-min(char["loading"][1:]) for char in
                               data["characteristic"].values()))
    left.set(xlabel="axial stroke −δ_S (mm)", ylabel="axial force −S (N)",
             title="characteristic shared by the four legs")
    left.legend(fontsize=8)
    for name, (t, a) in deceleration_histories(result).items():
        right.plot(t, a, label=name)
    right.axhline(result.evaluation.objective, color="k", lw=0.8, ls="--",
                  label=f"peak {result.evaluation.objective:.1f} m/s²")
    right.set(xlabel="t (s)", ylabel="vertical deceleration (m/s²)",
              title="touchdowns with the optimum")
    right.legend(fontsize=8)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=ROOT / "out" / "optimise_lander.json")
    parser.add_argument("--figure", type=Path, default=ROOT / "figures" / "optimise_lander.png")
    parser.add_argument("--max-iter", type=int, default=None)
    args = parser.parse_args(argv)

    study = load_study(STUDY)
    if args.max_iter is not None:
        study.ipopt["max_iter"] = args.max_iter
    pb = study.problem
    print(f"{study.name}: {len(pb.scenarios)} touchdowns, {pb.n_variables} design variables, "
          f"{pb.lbg.size} constraints (built in {pb.build_seconds:.1f} s)", flush=True)
    result = study.solve(progress=True)
    result.save_json(args.out)
    print(result.message)
    print(f"{'scenario':>10} {'peak before':>12} {'peak after':>11} {'max stroke':>11} "
          f"{'max tilt':>9} {'final v_up':>10}")
    for name, after in result.evaluation.scenarios.items():
        before = result.initial.scenarios[name]
        print(f"{name:>10} {before['peak_deceleration']:10.2f}   {after['peak_deceleration']:9.2f}"
              f"   {after['max_stroke']:9.4f}  {np.degrees(after['max_tilt']):7.2f}°"
              f"  {after['final_vertical_speed']:9.3f}")
    plot(result, args.figure)
    print(f"wrote {args.out} and {args.figure}")
    return 0 if result.success else 1


if __name__ == "__main__":
    raise SystemExit(main())
