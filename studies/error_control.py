"""What does error-controlled stepping cost against the fixed Δt that meets the
same tolerance? (docs/error-control.md)

For each lander of ``studies/error_estimate.py`` and each tolerance of
:data:`RTOLS`: the error-controlled run (``simulate(scene, rtol=...)``) and
the largest fixed Δt of 4 ms × 2⁻ᵏ whose peak loads (specific force and leg
force) are within the tolerance of the reference run; their costs as step
evaluations and wall time, and the peaks' true relative errors. Prints the
table. A few minutes on two cores.

    PYTHONPATH=. python studies/error_control.py
"""
from __future__ import annotations

import time
import warnings

from error_estimate import SCENES, reference

from symcushion import simulate
from symcushion.run.error_control import PEAKS

RTOLS = (1e-2, 1e-3)
#: Fixed steps tried, coarsest first: 4 ms × 2⁻ᵏ.
FIXED_DTS = tuple(4e-3 / 2 ** k for k in range(8))
LOADS = ("peak_specific_force", "peak_leg_force")
#: The target: an error-controlled run costs at most this many times the fixed run.
COST_TARGET = 1.5


def _errors(run, ref) -> dict:
    return {k: abs(run.info["peaks"][k] - ref[k]) / ref[k] for k in PEAKS}


def fixed_meeting(scene, model, ref, rtol):
    """The coarsest fixed Δt of :data:`FIXED_DTS` whose peak loads meet ``rtol``."""
    for dt in FIXED_DTS:
        run = simulate(scene.with_(dt=dt), model=model, monitor=False, estimate=False)
        err = _errors(run, ref)
        if max(err[k] for k in LOADS) <= rtol:
            return dt, run, err
    return None, run, err


def main():
    warnings.simplefilter("ignore")
    print("| scene | rtol | run | steps | step evaluations | wall (s) | specific force err | "
          "leg force err | stroke err | meets rtol on loads |")
    print("|---|---:|---|---:|---:|---:|---:|---:|---:|---|")
    ratios = []
    for path in SCENES:
        scene, model, ref, _ = reference(path)
        for rtol in RTOLS:
            dt, fixed, f_err = fixed_meeting(scene, model, ref, rtol)
            started = time.perf_counter()
            ctl = simulate(scene, model=model, monitor=False, rtol=rtol)
            wall = time.perf_counter() - started
            c_err = _errors(ctl, ref)
            meets = max(c_err[k] for k in LOADS) <= rtol
            label = f"fixed Δt = {dt * 1e3:g} ms" if dt else "fixed (none met)"
            for name, run, err, evals, seconds, ok in (
                    (label, fixed, f_err, fixed.info["steps"], fixed.info["rollout_seconds"],
                     dt is not None),
                    ("rtol", ctl, c_err, ctl.info["step_evaluations"], wall, meets)):
                print(f"| {scene.name} | {rtol:g} | {name} | {run.info['steps']} | {evals} | "
                      f"{seconds:.2f} | {err['peak_specific_force']:.1e} | "
                      f"{err['peak_leg_force']:.1e} | {err['peak_stroke']:.1e} | "
                      f"{'yes' if ok else 'no'} |")
            ratios.append((scene.name, rtol, ctl.info["step_evaluations"] / fixed.info["steps"],
                           wall / fixed.info["rollout_seconds"], meets))
    print(f"\ncost of the error-controlled run over the fixed run (target ≤ {COST_TARGET:g}):")
    for name, rtol, evals, wall, meets in ratios:
        print(f"  {name:14s} rtol {rtol:g}: {evals:.2f}× step evaluations, {wall:.2f}× wall; "
              f"meets rtol on the loads: {'yes' if meets else 'no'}")


if __name__ == "__main__":
    main()
