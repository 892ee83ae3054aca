"""Which axial characteristic minimises a lander's worst-case peak deceleration?

A 150 kg lander on four legs splayed 20° (``studies/optimise_lander.toml``)
touches down at 3 m/s in four ways: straight, drifting at 1 m/s, on a 10°
slope, and rolled 6° with a diagonal drift. One piecewise-linear axial
characteristic (11 knot values), shared by the four legs, is optimised for
the largest vertical deceleration over all four touchdowns and all steps,
with the axial stroke ≤ 0.25 m, hinge deflections ≤ 0.05 rad, body tilt
≤ 15° and the descent arrested within 0.25 s (docs/optimise.md).

Output: ``figures/optimise_lander.json`` (the result, as ``symcushion
optimise`` writes it; ``tests/test_optimise.py`` checks the gradient at its
optimum), ``figures/optimise_lander.md`` (the table: peaks before and after,
the margin of every limit in every touchdown, iterations and time) and
``figures/optimise_lander.png`` (the characteristic before and after, and
the deceleration and stroke histories of each touchdown with the optimum).
Run: ``python studies/optimise_lander.py`` (a few minutes).
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from symcushion.design.optimise import load_study
from symcushion.run.driver import simulate

ROOT = Path(__file__).resolve().parents[1]
STUDY = ROOT / "studies" / "optimise_lander.toml"


def histories(problem, result):
    """Vertical deceleration (m/s², gravity excluded) and the largest axial
    stroke over the legs (m) of each scenario of ``problem`` at the optimum."""
    out = {}
    for k, scenario in enumerate(problem.scenarios):
        traj = simulate(scenario.scene, x0=scenario.x0, p=problem.step_params(k, result.theta))
        stroke = np.nan_to_num(-traj.stroke).max(axis=1)
        out[scenario.name] = (traj.t, traj.acceleration[:, 2] - scenario.scene.gravity[2], stroke)
    return out


def margins(limits, result) -> list[dict]:
    """Per scenario: peaks before and after, and each limit's margin at the optimum."""
    rows = []
    for name, after in result.evaluation.scenarios.items():
        v_up = after["final_vertical_speed"]
        rows.append(dict(
            scenario=name,
            peak_hand=result.initial.scenarios[name]["peak_deceleration"],
            peak_optimum=after["peak_deceleration"],
            stroke=after["max_stroke"], stroke_margin=limits.stroke - after["max_stroke"],
            hinge_margin=min(limits.beta - after["max_beta"], limits.gamma - after["max_gamma"]),
            tilt=after["max_tilt"], tilt_margin=limits.tilt - after["max_tilt"],
            v_up=v_up, rebound_margin=limits.rebound_speed - v_up,
            sink_margin=limits.sink_speed + v_up))
    return rows


def _m(value, digits):
    """A margin rounded to ``digits``, without a sign on a rounded zero."""
    return f"{round(value, digits) + 0.0:.{digits}f}"


def table(problem, result) -> str:
    """The Markdown table of :func:`margins`, with status, iterations and time."""
    d = result.to_dict()
    lines = [f"Ipopt {result.return_status} after {result.iterations} iterations, "
             f"{d['seconds']:.0f} s (build {result.timings['build_seconds']:.1f} s); "
             f"worst-case peak {result.initial.objective:.2f} → "
             f"{result.evaluation.objective:.2f} m/s²; every limit met: "
             f"{'yes' if result.evaluation.feasible else 'NO'}.", "",
             "| touchdown | peak, hand design (m/s²) | peak, optimum (m/s²) | max stroke (m) "
             "| stroke margin (m) | hinge margin (rad) | max tilt | tilt margin "
             "| final v_up (m/s) | rebound margin (m/s) | sink margin (m/s) |",
             "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for r in margins(problem.limits, result):
        lines.append(f"| {r['scenario']} | {r['peak_hand']:.2f} | {r['peak_optimum']:.2f} "
                     f"| {r['stroke']:.4f} | {_m(r['stroke_margin'], 4)} | {_m(r['hinge_margin'], 4)} "
                     f"| {np.degrees(r['tilt']):.1f}° | {np.degrees(r['tilt_margin']):.1f}° "
                     f"| {r['v_up']:.3f} | {_m(r['rebound_margin'], 3)} | {_m(r['sink_margin'], 3)} |")
    return "\n".join(lines) + "\n"


def plot(problem, result, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    data = result.to_dict()
    fig, (left, mid, right) = plt.subplots(1, 3, figsize=(15, 4.2))
    for key, char in data["characteristic"].items():
        start = data["initial_characteristic"][key]
        x = -np.asarray(char["x"]) * 1e3
        left.plot(x, -np.asarray(start["loading"]), "o--", color="0.6", label="start (linear)")
        left.plot(x, -np.asarray(char["loading"]), "o-", label="optimum, loading")
        left.plot(x, -np.asarray(char["unloading"]), ":", label="unloading (fixed)")
    stroke = problem.limits.stroke * 1e3
    left.axvline(stroke, color="k", lw=0.8)
    # beyond the stroke limit the curve is never used: show the stroke only
    left.set_xlim(0, 1.1 * stroke)
    left.set_ylim(0, 1.5 * max(-min(char["loading"][1:]) for char in
                               data["characteristic"].values()))
    left.set(xlabel="axial stroke −δ_S (mm)", ylabel="axial force −S (N)",
             title="characteristic shared by the four legs")
    left.legend(fontsize=8)
    for name, (t, a, s) in histories(problem, result).items():
        mid.plot(t, a, label=name)
        right.plot(t, s * 1e3, label=name)
    mid.axhline(result.evaluation.objective, color="k", lw=0.8, ls="--",
                label=f"peak {result.evaluation.objective:.1f} m/s²")
    mid.set(xlabel="t (s)", ylabel="vertical deceleration (m/s²)",
            title="touchdowns with the optimum")
    mid.legend(fontsize=8)
    right.axhline(stroke, color="k", lw=0.8, ls="--", label="stroke limit")
    right.set(xlabel="t (s)", ylabel="largest axial stroke over the legs (mm)",
              title="strokes with the optimum")
    right.legend(fontsize=8)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=ROOT / "figures" / "optimise_lander.json")
    parser.add_argument("--table", type=Path, default=ROOT / "figures" / "optimise_lander.md")
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
    text = table(pb, result)
    print(text)
    args.table.parent.mkdir(parents=True, exist_ok=True)
    args.table.write_text(text)
    plot(pb, result, args.figure)
    print(f"wrote {args.out}, {args.table} and {args.figure}")
    return 0 if result.success else 1


if __name__ == "__main__":
    raise SystemExit(main())
