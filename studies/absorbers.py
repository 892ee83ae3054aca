"""Absorbers with memory: does a lander come to rest, crush only at its crush force, converge?

Questions (docs/absorbers.md, "What it measures"):

1. The damped lander (``studies/lander_damped.toml``) and the tutorial lander
   (``studies/tutorial/lander.toml``), one-shot honeycomb cartridges with
   dampers on every element, on the memory law, after they settle,
   t > 0.5 s, at Δt = 1 and 0.5 ms: the largest step-to-step jump of a
   leg's contact force against that leg's mean force, and the standard
   deviation of the vertical acceleration (chatter would keep both large
   and independent of Δt; physics converges).
2. The 300 kg lunar lander (``studies/lunar_lander300.toml``) under the
   printed law and the memory law: the stroke crushed in steps whose axial
   force is below 2.9 kN (the crush force is 3 kN).
3. The order of the final position over Δt = 2 … 0.25 ms against a
   31.25-µs run, for the lunar lander under both laws and the damped lander.
4. The damped lander's damping time τ = c/k (the same on every element, or on
   the axial element alone): the rest spread, and how often the sliding
   downhill foot leaves the ground in the first 0.5 s.
5. The orders through touchdowns and lift-offs (docs/absorbers.md, "Located
   touchdown and lift-off") on the four landers on the memory law — the slope
   and hop landers' damped memory-law versions (``studies/lander_slope_memory.toml``,
   ``studies/lander_hop_memory.toml``), the tutorial lander and the lunar
   lander — with either slip rule: the final position and the trajectory
   (largest distance over the times every run shares), over the travel, at
   Δt = 4 … 0.125 ms against a 31.25-µs run, and their fitted orders.
6. The same final-position errors of the slope, hop and tutorial landers
   (midpoint slip) at 16 log-spaced steps from 4 to 0.125 ms instead of six
   halvings, fitted over all and over Δt ≤ 1 ms: is a fitted order of 1.4–1.6
   an error that falls slower than Δt², or a second-order error whose size
   changes with where the events fall in the step?

Output: the tables on stdout. Run: ``python studies/absorbers.py``.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from symcushion.layout.vectors import output_layout, state_layout
from symcushion.model.scene import load_scene, read_toml, scene_from_dict
from symcushion.scheme.touchdown import build_model, initial_state
from symcushion.run.error_control import fitted_order

HERE = Path(__file__).resolve().parent
DAMPED = HERE / "lander_damped.toml"
LUNAR = HERE / "lunar_lander300.toml"
TUTORIAL = HERE / "tutorial" / "lander.toml"
#: Time after which the tutorial lander is read as settled (s).
SETTLED = 0.5
#: Steps of the order fit and the reference step (s).
ORDER_STEPS = (2e-3, 1e-3, 5e-4, 2.5e-4)
REFERENCE_STEP = 3.125e-5
#: Damping times of the sweep (s).
DAMPING_TIMES = (0.0, 1e-3, 2e-3, 3.5e-3, 6e-3)
#: The four landers of the event orders (question 5): file and duration (s).
EVENT_LANDERS = (("slope", HERE / "lander_slope_memory.toml", 0.8),
                 ("hop", HERE / "lander_hop_memory.toml", 0.6),
                 ("tutorial", TUTORIAL, 1.0),
                 ("lunar", LUNAR, 2.0))
#: Steps of the event orders (s): the coarsest is the trajectory's output grid.
EVENT_STEPS = (4e-3, 2e-3, 1e-3, 5e-4, 2.5e-4, 1.25e-4)


def rollout(scene, dt):
    """States and outputs (columns are steps) of ``scene`` at step ``dt``."""
    scene = scene.with_(dt=dt)
    model = build_model(scene)
    X, Y = model.rollout(scene.steps)(initial_state(scene), model.default_p, dt)
    X, Y = np.asarray(X), np.asarray(Y)
    if not (np.all(np.isfinite(X)) and np.all(np.isfinite(Y))):
        raise RuntimeError(f"{scene.name} at dt = {dt:g} s gave a non-finite state.")
    return X, Y


def rest_measures(scene, dt):
    """(largest force jump over mean force, std of the vertical acceleration) after SETTLED."""
    _, Y = rollout(scene, dt)
    yl = output_layout(len(scene.legs))
    t = dt * np.arange(1, Y.shape[1] + 1)
    rest = t > SETTLED
    force = np.linalg.norm(yl.legs(Y, "force"), axis=1)[:, rest]
    jump = np.max(np.abs(np.diff(force, axis=1)), axis=1) / np.mean(force, axis=1)
    return float(np.max(jump)), float(np.std(yl.get(Y, "acceleration")[2, rest]))


def crushed_below(scene, dt=1e-3, below=2900.0):
    """Per leg: stroke crushed (m) in steps whose axial force is below ``below`` (N)."""
    X, Y = rollout(scene, dt)
    n = len(scene.legs)
    yl = output_layout(n)
    axial = -np.einsum("jkt,jkt->jt", yl.legs(Y, "force"), yl.legs(Y, "axis"))
    if scene.hysteresis == "memory":      # the crushed stroke is the set's inward motion
        moved = np.diff(np.c_[np.zeros(n), state_layout(n).legs(X, "stroke_set")], axis=1)
    else:                                 # the printed law has no set: the stroke's
        moved = np.diff(np.c_[np.zeros(n), yl.legs(Y, "stroke")], axis=1)
    crushing = moved < 0
    return np.sum(np.where(crushing & (axial < below), -moved, 0.0), axis=1)


def final_order(scene):
    """(errors of the final position over the travel at ORDER_STEPS, fitted order)."""
    xl = state_layout(len(scene.legs))
    final = {dt: xl.get(rollout(scene, dt)[0], "position")[:, -1]
             for dt in ORDER_STEPS + (REFERENCE_STEP,)}
    ref = final[REFERENCE_STEP]
    travel = np.linalg.norm(ref - initial_state(scene)[:3])
    errors = np.array([np.linalg.norm(final[dt] - ref) / travel for dt in ORDER_STEPS])
    return errors, fitted_order(ORDER_STEPS, errors)


def order_fit(steps, errors):
    """The slope of log error against log Δt."""
    return fitted_order(steps, errors)


def event_errors(scene, steps=EVENT_STEPS, reference=REFERENCE_STEP):
    """Errors over the travel of the final position and of the trajectory (the largest
    distance at the times of the coarsest step) against a run at ``reference``."""
    xl = state_layout(len(scene.legs))
    ref = xl.get(rollout(scene, reference)[0], "position")
    travel = np.linalg.norm(ref[:, -1] - initial_state(scene)[:3])
    every = int(round(steps[0] / reference))
    final, path = [], []
    for dt in steps:
        pos = xl.get(rollout(scene, dt)[0], "position")
        k = int(round(steps[0] / dt))
        final.append(np.linalg.norm(pos[:, -1] - ref[:, -1]) / travel)
        path.append(np.max(np.linalg.norm(pos[:, k - 1::k] - ref[:, every - 1::every], axis=0))
                    / travel)
    return np.array(final), np.array(path)


def event_orders():
    print("\nevents on the memory law: error over the travel (final | trajectory) at 1 ms,"
          " fitted order over Δt = 4 … 0.125 ms")
    print("  lander     slip       final @1ms   order   trajectory @1ms   order")
    for name, path, duration in EVENT_LANDERS:
        scene = load_scene(path).with_(hysteresis="memory", duration=duration)
        for slip in ("midpoint", "backward"):
            final, traj = event_errors(scene.with_(slip=slip))
            one = EVENT_STEPS.index(1e-3)
            print(f"  {name:9s}  {slip:9s}  {100 * final[one]:9.3f} %  "
                  f"{order_fit(EVENT_STEPS, final):6.2f}   {100 * traj[one]:12.3f} %  "
                  f"{order_fit(EVENT_STEPS, traj):6.2f}")
            print("      by Δt: " + " ".join(f"{e:.2e}" for e in final) + " | "
                  + " ".join(f"{e:.2e}" for e in traj))


def spread_orders(count=16):
    """Question 6: final-position errors at ``count`` log-spaced steps, and the fits."""
    print(f"\nfinal position at {count} log-spaced steps, 4 … 0.125 ms (midpoint slip):"
          " error over the travel, fitted order over all and over Δt ≤ 1 ms")
    for name, path, duration in EVENT_LANDERS[:3]:
        scene = load_scene(path).with_(hysteresis="memory", duration=duration,
                                       slip="midpoint")
        xl = state_layout(len(scene.legs))
        ref = xl.get(rollout(scene, REFERENCE_STEP)[0], "position")[:, -1]
        travel = np.linalg.norm(ref - initial_state(scene)[:3])
        counts = np.unique(np.round(np.geomspace(duration / 4e-3, duration / 1.25e-4, count)))
        steps = duration / counts
        errors = np.array([np.linalg.norm(xl.get(rollout(scene, dt)[0], "position")[:, -1]
                                          - ref) / travel for dt in steps])
        fine = steps <= 1.0001e-3
        print(f"  {name:9s} order {order_fit(steps, errors):5.2f} (Δt ≤ 1 ms: "
              f"{order_fit(steps[fine], errors[fine]):5.2f})")
        print("      " + " ".join(f"{1e3 * dt:.3g}:{e:.1e}" for dt, e in zip(steps, errors)))


def with_damping_time(tau, hinges=True):
    """The damped lander with every element's damping c = τ·k (the hinge springs' only
    if ``hinges``)."""
    data = read_toml(DAMPED)
    for name in ("S", "M_beta", "M_gamma"):
        element = data["legs"][name]
        element.pop("damping", None)
        if tau > 0 and (hinges or name == "S"):
            element["damping"] = tau * element["stiffness"]
    return scene_from_dict(data)


def liftoffs(scene, dt=1e-3, until=SETTLED):
    """How often each foot leaves the ground before ``until``."""
    X, _ = rollout(scene.with_(duration=until), dt)
    contact = state_layout(len(scene.legs)).legs(X, "contact") > 0.5
    return np.sum(np.diff(contact.astype(int), axis=1) < 0, axis=1)


def damping_sweep():
    print("\ndamped lander against its damping time τ = c/k, Δt = 1 ms")
    print("  τ [ms]  dampers         std after 0.5 s [m/s²]   downhill foot's lift-offs < 0.5 s")
    for tau in DAMPING_TIMES:
        for hinges in ((True, False) if tau > 0 else (True,)):
            scene = with_damping_time(tau, hinges)
            _, std = rest_measures(scene, 1e-3)
            where = "every element" if hinges else "axial only"
            where = where if tau > 0 else "none"
            print(f"  {tau * 1e3:6.1f}  {where:14s}  {std:22.4f}   {liftoffs(scene)[0]:10d}")


def main():
    damped = load_scene(DAMPED)
    for name, scene in (("damped lander", damped), ("tutorial lander", load_scene(TUTORIAL))):
        print(f"{name} after t = {SETTLED} s ({scene.hysteresis} law, slip = {scene.slip}):")
        print("  dt [ms]  largest force jump / mean force   std of vertical acceleration [m/s²]")
        for dt in (1e-3, 5e-4):
            jump, std = rest_measures(scene, dt)
            print(f"  {dt * 1e3:7.2f}  {100 * jump:31.2f} %   {std:34.4f}")
    lunar = load_scene(LUNAR)
    print("\nlunar lander: stroke crushed while the axial force is below 2.9 kN [mm], per leg")
    for law in ("sign", "memory"):
        crushed = crushed_below(lunar.with_(hysteresis=law))
        print(f"  {law:7s}" + "".join(f"{1e3 * c:9.1f}" for c in crushed))
    print("\nfinal position against a 31.25-µs run (error over the travel), slip = 'midpoint'")
    print("  scene            " + "".join(f"{dt * 1e3:>9.2f} ms" for dt in ORDER_STEPS)
          + "   order")
    for name, scene in (("lunar, memory", lunar.with_(hysteresis="memory", slip="midpoint")),
                        ("lunar, sign", lunar.with_(slip="midpoint")),
                        ("damped lander", damped)):
        errors, order = final_order(scene)
        print(f"  {name:16s} " + "".join(f"{e:12.2e}" for e in errors) + f"   {order:5.2f}")
    damping_sweep()
    event_orders()
    spread_orders()


if __name__ == "__main__":
    main()
