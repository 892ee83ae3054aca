"""What does an inverted-tripod leg cost per step, against a hinged strut?

Question (docs/tripod.md, "An Apollo-class example"): per step of the
compiled touchdown rollout, the four-tripod lander of
``studies/apollo_lander.toml`` against a lander of hinged struts (2.1) that
differs only in its legs. Target: tripod/strut ≤ 1.5.

The strut lander. Same body, mass, inertia, obstacle, μ, scheme, Δt and
initial state; each strut runs from the tripod's primary joint h₁ to the
same rest foot (so the feet start at the same points), its axial curve is
the tripod's primary curve (crush force, damper and end stop included), and
its hinge springs are linear, stiff as the tripod is across its primary at
rest (the two eigenvalues of the closed-form rest stiffness across e_S,
times L₀²), damped with the same time constant as the elements
(``APOLLO_TAU``). The polar axis leans ``POLAR_TILT`` inwards from the
downward vertical (as the example landers of ``studies/``).

Method, as ``studies/bench_touchdown.py``: ``symcushion.compiled.codegen.compiled_model``
builds each scene's C; its ``touchdown_rollout`` over ``SECONDS`` of the
scene's own start (the design-limit touchdown: first contact, stroke, the
downhill legs landing) runs with the scene's own parameters
(``default_p``), evaluated into NumPy arrays allocated once through
``Function.buffer()``. Before timing, each compiled rollout's states and
outputs must be finite and equal bit for bit to the uncompiled model's, and
its last state equal (to round-off) to ``symcushion.simulate`` of the same
scene. Then the two rollouts are called alternately, BEST_OF times, and the
best time of each is kept; µs per step = time / N.

Output: a table on stdout. Run: ``python studies/bench_tripod.py``.
"""
from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np

from bench_check import (BITWISE, ROUNDOFF_RTOL, buffered, check_equal,  # studies/
                         check_rollout)
from symcushion import simulate
from symcushion.legs.characteristics import Linear
from symcushion.compiled.codegen import compiled_model
from symcushion.model.scene import load_scene
from symcushion.scheme.touchdown import build_model, initial_state
from symcushion.legs.strut import HingedStrut

ROOT = Path(__file__).resolve().parent.parent
BENCH = "bench_tripod"
APOLLO = ROOT / "studies" / "apollo_lander.toml"
#: Timed calls per rollout, alternated; the best is kept (bench_touchdown.py says why).
BEST_OF = 30
#: Simulated time per timed call (s): the uphill foot's contact, the flight to the
#: downhill legs (about 0.35 s) and their stroke.
SECONDS = 0.6
#: Damping time c/k of the example's elements (s), given to the struts' hinge springs.
APOLLO_TAU = 1e-3
#: Polar axis of the struts' hinges, from the downward vertical towards the axis (rad):
#: any axis well away from the strut serves; the strut leans 44° outwards.
POLAR_TILT = np.deg2rad(25.0)
#: The target of the tripod's cost per step, in strut steps.
TARGET = 1.5


def strut_of(tripod) -> HingedStrut:
    """A hinged strut from the tripod's h₁ to its rest foot, with comparable curves."""
    e0 = (tripod.rest_foot - tripod.hinge) / tripod.length
    radial = np.array([e0[0], e0[1], 0.0]) / np.hypot(e0[0], e0[1])
    en = -np.sin(POLAR_TILT) * radial - np.cos(POLAR_TILT) * np.array([0.0, 0.0, 1.0])
    K = tripod.rest_stiffness_closed_form()
    across = np.eye(3) - np.outer(e0, e0)
    k_across = np.sort(np.linalg.eigvalsh(across @ K @ across))[1:]     # drop e_S's 0
    k_beta, k_gamma = k_across * tripod.length ** 2                      # N·m/rad
    primary = tripod.elements[0].curve
    return HingedStrut(tripod.hinge, e0, en, tripod.length, S=primary,
                       M_beta=Linear(k_beta, damping=APOLLO_TAU * k_beta),
                       M_gamma=Linear(k_gamma, damping=APOLLO_TAU * k_gamma))


def timer_of(scene, folder: Path):
    """(timer, steps): ``timer()`` runs the checked compiled rollout once into
    preallocated arrays and returns its seconds."""
    steps = int(round(SECONDS / scene.dt))
    model = compiled_model(scene, folder, steps=steps)
    rollout = model.rollout(steps)
    x0, p = initial_state(scene), build_model(scene).default_p
    X, Y = check_rollout(BENCH, f"{scene.name} compiled rollout", rollout, scene, x0, p,
                         scene.dt, steps, rtol=BITWISE)
    traj = simulate(scene.with_(duration=steps * scene.dt), estimate=False)
    check_equal(BENCH, f"{scene.name} last state", X[:, -1], traj.info["final_state"],
                rtol=ROUNDOFF_RTOL, reference_name="symcushion.simulate of the same scene")
    evaluate, outputs = buffered(rollout, x0, p, scene.dt)
    evaluate()
    check_equal(BENCH, f"{scene.name} rollout evaluated into buffers: X", outputs[0],
                X.ravel(order="F"), rtol=BITWISE, reference_name="the checked rollout")

    def timer(_keep=outputs) -> float:
        # the buffers hold raw pointers: their arrays must live as long as the timer
        start = time.perf_counter()
        evaluate()
        return time.perf_counter() - start

    return timer, steps


def main() -> None:
    tripods = load_scene(APOLLO)
    struts = tripods.with_(legs=[strut_of(leg) for leg in tripods.legs], name="apollo_struts")
    for a, b in zip(tripods.legs, struts.legs):
        assert np.allclose(a.rest_foot, b.rest_foot, atol=1e-12), "feet must start together"
    with tempfile.TemporaryDirectory() as tmp:
        timers = {name: timer_of(scene, Path(tmp) / name)
                  for name, scene in (("tripod", tripods), ("strut", struts))}
        best = dict.fromkeys(timers, np.inf)
        for _ in range(BEST_OF):
            for name, (timer, _) in timers.items():
                best[name] = min(best[name], timer())
    us = {name: 1e6 * best[name] / timers[name][1] for name in timers}
    instr = {name: build_model(scene).step.n_instructions()
             for name, scene in (("tripod", tripods), ("strut", struts))}
    print(f"Apollo-class lander, {SECONDS} s of its design-limit touchdown at Δt = "
          f"{tripods.dt:g} s, best of {BEST_OF} interleaved calls:\n")
    print("| legs | SX instr. (step) | µs/step |")
    print("|---|---:|---:|")
    for name in ("tripod", "strut"):
        print(f"| four {name}s | {instr[name]:,} | {us[name]:.2f} |")
    ratio = us["tripod"] / us["strut"]
    print(f"\ntripod/strut per step: {ratio:.2f} (target ≤ {TARGET:g})")


if __name__ == "__main__":
    main()
