"""What does it cost to take the legs' geometry from p instead of baking it in?

Question: ``build_model(scene)`` reads each leg's hinge, e₀, e_n and L₀ from
the parameter vector p (``geometry="input"``), so one compiled step serves
every geometry; ``geometry="constant"`` bakes them into the graph as
constants, which CasADi folds. How much slower is the compiled step with
the geometry as inputs, and are its numbers the constant build's?

Method: for each scene, both builds' ``touchdown_rollout`` of STEPS steps
are generated to C and compiled with ``symcushion.compiled.cbuild.CFLAGS`` (-O3),
then called on the scene's initial state and default p, interleaved, best
of BEST_OF rounds of process CPU time; µs per step = time / STEPS. Printed:
SX instructions of the step, µs per step, the ratio input/constant, and the
largest difference of the rolled-out states.

Run: ``python studies/bench_geometry_inputs.py`` (compiles four libraries
into ``build/bench_geometry``; a few minutes on two cores).
"""
from __future__ import annotations

import time
from pathlib import Path

import casadi as ca
import numpy as np

from symcushion.compiled.cbuild import compile_cached
from symcushion.model.scene import load_scene
from symcushion.scheme.touchdown import build_model, initial_state

ROOT = Path(__file__).resolve().parents[1]
SCENES = ("studies/fig4.toml", "studies/lander_slope.toml")
#: Steps of one timed rollout call: long enough that the call overhead is noise.
STEPS = 300
#: Rounds of the interleaved timing; the best is kept (the machine is shared).
BEST_OF = 15
CACHE = ROOT / "build" / "bench_geometry"


def compiled_rollout(model, tag: str) -> ca.Function:
    rollout = model.rollout(STEPS)
    build = compile_cached(rollout, f"rollout_{tag}.c", f"librollout_{tag}.so", CACHE,
                           f"rollout_{tag}", note=f"the {tag} rollout")
    return ca.external("touchdown_rollout", str(build.library))


def cpu_seconds(f, args) -> float:
    start = time.process_time()
    f(*args)
    return time.process_time() - start


def measure(path: str) -> dict:
    scene = load_scene(ROOT / path)
    x0 = initial_state(scene)
    out = {"scene": scene.name}
    runs, states = {}, {}
    for mode in ("input", "constant"):
        model = build_model(scene, geometry=mode)
        out[f"instructions_{mode}"] = model.step.n_instructions()
        f = compiled_rollout(model, f"{scene.name}_{mode}")
        args = (x0, model.default_p, scene.dt)
        states[mode] = np.asarray(f(*args)[0])
        runs[mode] = (f, args)
    best = {mode: np.inf for mode in runs}
    for _ in range(BEST_OF):
        for mode, (f, args) in runs.items():
            best[mode] = min(best[mode], cpu_seconds(f, args))
    for mode in runs:
        out[f"us_{mode}"] = 1e6 * best[mode] / STEPS
    out["ratio"] = best["input"] / best["constant"]
    out["max_state_diff"] = float(np.max(np.abs(states["input"] - states["constant"])))
    return out


def main() -> None:
    print("| scene | SX instructions, input / constant | µs per step, input | µs per step, "
          "constant | ratio | max |Δx| over the rollout |")
    print("|---|---:|---:|---:|---:|---:|")
    for path in SCENES:
        r = measure(path)
        print(f"| {r['scene']} | {r['instructions_input']} / {r['instructions_constant']} | "
              f"{r['us_input']:.2f} | {r['us_constant']:.2f} | {r['ratio']:.3f} | "
              f"{r['max_state_diff']:.1e} |", flush=True)


if __name__ == "__main__":
    main()
