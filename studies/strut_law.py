"""Does the paper's force law (2.1) create energy, and does it matter for the landers?

Question: (2.1) is not the gradient of a potential, so an elastic leg does
work around a closed loop of its foot. How much energy does that put into
the studies' landers while their feet stick, and how different are their
runs under the energy-consistent law ``law = "potential"`` (P = Σ f ∇x,
the same deflections, curves and signs)?

Method. Loop: the work ∮P·dr of one lander leg (hinge springs 2e4 N·m/rad,
axial 1e5 N/m) around a 2 cm circle about a foot deflected by (3, −2, 4) cm,
periodic trapezoid rule on 256 and 512 nodes. Landers: each scene is run
under both laws with the same fixed Δt (``StepModel.rollout``). The hinge
springs are linear in every scene, so their stored energy U = ½k_β β² +
½k_γ (γ − γ₀)² is known at every step; a step's *gain* is ΔU − W_b, with W_b
the work the foot force did on them (the step output ``work_bending``):
zero for a law that stores what it is given, up to the trapezoid rule's
O(Δt²). Summed over the steps in which a leg sticks at both ends. The
elastic lander (axial springs 1e5 N/m instead of crushing absorbers, on a
10° slope at μ = 1) also gets its total mechanical energy (kinetic,
gravity, every spring) from touchdown over at most 60 ms, until a foot
first slips or lifts off (the two uphill feet stick, the others are
free), at Δt and Δt/2. Final states: body position and attitude of the two laws at
the end of each run.

Output: the numbers on stdout and ``figures/strut_law.png`` (the elastic
lander's energy drift under both laws while its feet stick; the landers' body separation
between the laws over time). Run: ``python studies/strut_law.py`` (about two
minutes on two cores).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from symcushion import HingedStrut, Linear
from symcushion.envelope.cases import case_params, initial_states
from symcushion.envelope.study import load_study
from symcushion.layout.vectors import output_layout, state_layout
from symcushion.scheme.quaternion import tilt_np
from symcushion.model.obstacles import Plane
from symcushion.model.scene import Scene, load_scene, symmetric_legs
from symcushion.scheme.touchdown import build_model, initial_state

ROOT = Path(__file__).resolve().parents[1]
FIGURE = ROOT / "figures" / "strut_law.png"
LAWS = ("paper", "potential")
#: The loop of the closed-path check (m): centre offset from the rest foot and radius.
LOOP_CENTRE, LOOP_RADIUS = np.array([0.03, -0.02, 0.04]), 0.02
#: Window of the elastic lander's energy drift after all four feet stick (s).
STICK_WINDOW = 0.06
#: The envelope study's run is cut to this (s): touchdown and settling.
ENVELOPE_DURATION = 0.6


def with_law(scene: Scene, law: str) -> Scene:
    """The scene with every leg rebuilt under ``law``."""
    legs = []
    for leg in scene.legs:
        curves = {el.name: el.curve for el in leg.elements}
        if leg.rigid:
            curves.pop("S")
        legs.append(HingedStrut(leg.hinge, leg.e0, leg.en, leg.length, **curves,
                                axial_ratio=leg.axial_ratio, law=law))
    return scene.with_(legs=legs)


def elastic_lander(law: str = "paper") -> Scene:
    """lander_slope's body and legs with linear axial springs, on 10° at μ = 1."""
    base = load_scene(ROOT / "studies" / "lander_slope.toml")
    leg = base.legs[0]
    legs = symmetric_legs(4, 0.5, -0.2, 0.8, (np.sin(np.deg2rad(20)), 0, -np.cos(np.deg2rad(20))),
                          (-np.sin(np.deg2rad(25)), 0, -np.cos(np.deg2rad(25))),
                          S=Linear(1e5), M_beta=Linear(2e4), M_gamma=Linear(2e4),
                          azimuth0=np.pi / 4, law=law)
    assert np.allclose(legs[0].rest_foot, leg.rest_foot)
    return Scene(base.body, legs, [Plane.inclined(np.deg2rad(10))], mu=1.0, dt=1e-3,
                 duration=0.5, name="elastic_lander")


def loop_work(leg: HingedStrut, n: int) -> float:
    a, b = np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.6, 0.8])
    work = 0.0
    for t in 2 * np.pi * np.arange(n) / n:
        r = leg.rest_foot + LOOP_CENTRE + LOOP_RADIUS * (np.cos(t) * a + np.sin(t) * b)
        work += leg.force(r) @ (LOOP_RADIUS * (-np.sin(t) * a + np.cos(t) * b) * 2 * np.pi / n)
    return work


def hinge_springs(leg) -> tuple:
    """(k_β, k_γ) of a leg's linear hinge springs (N·m/rad; 0 where absent)."""
    k = {"M_beta": 0.0, "M_gamma": 0.0}
    for el in leg.elements:
        if el.name in k:
            if not isinstance(el.curve, Linear) or el.curve.param_values[1] != 0:
                raise ValueError(f"{el.name} must be a linear spring without preload.")
            k[el.name] = float(el.curve.param_values[0])
    return k["M_beta"], k["M_gamma"]


def run(scene: Scene, x0=None, p=None, dt=None, steps=None) -> dict:
    model = build_model(scene)
    x0 = initial_state(scene) if x0 is None else x0
    p = model.default_p if p is None else p
    dt = scene.dt if dt is None else dt
    steps = scene.steps if steps is None else steps
    X, Y = model.rollout(steps)(x0, p, dt)
    X = np.column_stack([x0, np.asarray(X)])
    return dict(scene=scene, X=X, Y=np.asarray(Y), dt=dt, p=p, model=model)


def stick_gain(r: dict) -> tuple:
    """(gain summed over sticking steps (J), per-step gain of all legs (J))."""
    scene, Y = r["scene"], r["Y"]
    yl = output_layout(len(scene.legs))
    mode = yl.legs(Y, "mode")
    gain_total, per_step = 0.0, np.zeros(Y.shape[1])
    for j, leg in enumerate(scene.legs):
        kb, kg = hinge_springs(leg)
        U = 0.5 * kb * yl.get(Y, "beta", j) ** 2 + 0.5 * kg * yl.get(Y, "gamma_deflection", j) ** 2
        U = np.concatenate([[0.0], U])          # free at the start: no deflection
        gain = np.diff(U) - yl.get(Y, "work_bending", j)
        stuck = (mode[j] == 1) & np.concatenate([[False], mode[j][:-1] == 1])
        gain_total += gain[stuck].sum()
        per_step += np.where(stuck, gain, 0.0)
    return gain_total, per_step


def mechanical_energy(r: dict) -> np.ndarray:
    """Kinetic + gravity + springs of the elastic lander at every state (J)."""
    scene, X, Y = r["scene"], r["X"], r["Y"]
    xl, yl = state_layout(len(scene.legs)), output_layout(len(scene.legs))
    b = scene.body
    v, w = xl.get(X, "velocity"), xl.get(X, "angular_velocity")
    kinetic = 0.5 * b.mass * np.sum(v ** 2, axis=0) + 0.5 * np.einsum("it,ij,jt->t", w,
                                                                        b.inertia, w)
    gravity = -b.mass * (scene.gravity @ xl.get(X, "position"))
    springs = np.zeros(X.shape[1])
    for j, leg in enumerate(scene.legs):
        kb, kg = hinge_springs(leg)
        kS = float(leg.elements[0].curve.param_values[0])
        springs[1:] += 0.5 * (kS * yl.get(Y, "stroke", j) ** 2 + kb * yl.get(Y, "beta", j) ** 2
                              + kg * yl.get(Y, "gamma_deflection", j) ** 2)
    return kinetic + gravity + springs


def touchdown_energy(r: dict) -> float:
    b, x0 = r["scene"].body, r["X"][:, 0]
    v = state_layout(len(r["scene"].legs)).get(x0, "velocity")
    return 0.5 * b.mass * float(v @ v)


def final_difference(a: dict, b: dict) -> tuple:
    """(|Δ body position| (m), |Δ tilt| (deg)) at the end of two runs."""
    xl = state_layout(len(a["scene"].legs))
    pa, pb = xl.get(a["X"][:, -1], "position"), xl.get(b["X"][:, -1], "position")
    up = -a["scene"].gravity / np.linalg.norm(a["scene"].gravity)
    ta, tb = (tilt_np(xl.get(r["X"][:, -1], "attitude"), up) for r in (a, b))
    return float(np.linalg.norm(pa - pb)), float(np.rad2deg(abs(ta - tb)))


def envelope_median(law: str) -> dict:
    study = load_study(ROOT / "studies" / "envelope_lander.toml")
    scene = with_law(study.scene, law)
    median = {name: rng.transform(np.array([0.5])) for name, rng in study.ranges.items()}
    x0, gravity = initial_states(study, median)
    p = case_params(scene, np.array([scene.mu]), gravity)[:, 0]
    steps = int(round(ENVELOPE_DURATION / scene.dt))
    return run(scene.with_(name="envelope_lander (median case)"), x0[:, 0], p, steps=steps)


def elastic_window(law: str, dt: float) -> tuple:
    """(hinge gain over the stick window, mechanical energy drift in it (J), touchdown
    energy (J), start of the window (s), the run, its mechanical energy)."""
    r = run(elastic_lander(law), dt=dt, steps=int(round(0.5 / dt)))
    mode = output_layout(4).legs(r["Y"], "mode")
    start = np.flatnonzero(np.any(mode == 1, axis=0))[0]
    slips = np.flatnonzero(np.any(mode[:, start:] > 1.5, axis=0))      # slip or lift-off
    stop = start + min(int(round(STICK_WINDOW / dt)), slips[0] if slips.size else mode.shape[1])
    E = mechanical_energy(r)
    _, per_step = stick_gain(r)
    return (per_step[start:stop].sum(), E[stop] - E[start], touchdown_energy(r),
            (start, stop), r, E)


def main() -> None:
    leg_kw = dict(hinge=(0.35, 0.35, -0.2), e0=(0.242, 0.242, -0.94), en=(-0.3, -0.3, -0.906),
                  length=0.8, S=Linear(1e5), M_beta=Linear(2e4), M_gamma=Linear(2e4))
    print("work of the foot force around a 2 cm loop (J), 256 / 512 nodes:")
    for law in LAWS:
        leg = HingedStrut(**leg_kw, law=law)
        print(f"  {law:9s} {loop_work(leg, 256): .6e} / {loop_work(leg, 512): .6e}")

    print("\nelastic lander (10°, μ = 1): over the first "
          f"{1e3 * STICK_WINDOW:.0f} ms of sticking after touchdown")
    elastic = {}
    for law in LAWS:
        for dt in (1e-3, 5e-4):
            gain, drift, e0, (k0, k1), r, E = elastic_window(law, dt)
            elastic[(law, dt)] = (r, E[:k1 + 1])
            print(f"  {law:9s} Δt = {1e3 * dt:g} ms: t = {1e3 * k0 * dt:.1f}-{1e3 * k1 * dt:.1f} ms, hinge "
                  f"gain {gain:+.3f} J, mechanical energy {drift:+.3f} J "
                  f"({100 * drift / e0:+.2f} % of the touchdown energy {e0:.0f} J)")

    print("\nlanders: hinge-spring gain while sticking (J, and % of the touchdown energy), "
          "final-state difference between the laws")
    runs = {}
    for path in ("studies/lander_slope.toml", "studies/lander_hop.toml",
                 "studies/tutorial/lander.toml"):
        base = load_scene(ROOT / path)
        runs[base.name] = {law: run(with_law(base, law)) for law in LAWS}
    runs["envelope_lander (median)"] = {law: envelope_median(law) for law in LAWS}
    runs["elastic_lander"] = {law: elastic[(law, 1e-3)][0] for law in LAWS}
    print("| scene | gain, paper | gain, potential | Δ final position (mm) | Δ final tilt (°) |")
    print("|---|---:|---:|---:|---:|")
    for name, pair in runs.items():
        e0 = touchdown_energy(pair["paper"])
        gains = [stick_gain(pair[law])[0] for law in LAWS]
        dpos, dtilt = final_difference(pair["paper"], pair["potential"])
        print(f"| {name} | {gains[0]:+.3f} J ({100 * gains[0] / e0:+.2f} %) | {gains[1]:+.4f} J "
              f"({100 * gains[1] / e0:+.3f} %) | {1e3 * dpos:.2f} | {dtilt:.3f} |")
    plot(elastic, runs)
    print(f"\nwrote {FIGURE.relative_to(ROOT)}")


def plot(elastic: dict, runs: dict) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4))
    for (law, dt), (r, E) in elastic.items():
        t = np.arange(E.size) * dt              # E: up to the first slip or lift-off
        ax1.plot(1e3 * t, E - E[0], label=f"{law}, Δt = {1e3 * dt:g} ms",
                 ls="-" if dt == 1e-3 else "--")
    ax1.set_xlabel("t (ms)")
    ax1.set_ylabel("mechanical energy − touchdown value (J)")
    ax1.set_title("elastic lander, 10° slope, μ = 1: while its feet stick")
    ax1.legend(fontsize=8)
    for name, pair in runs.items():
        a, b = pair["paper"], pair["potential"]
        xl = state_layout(len(a["scene"].legs))
        d = np.linalg.norm(xl.get(a["X"], "position") - xl.get(b["X"], "position"), axis=0)
        ax2.semilogy(1e3 * np.arange(d.size) * a["dt"], np.maximum(1e3 * d, 1e-9), label=name)
    ax2.set_xlabel("t (ms)")
    ax2.set_ylabel("|body position, paper − potential| (mm)")
    ax2.set_title("separation of the two laws' runs")
    ax2.legend(fontsize=8)
    fig.tight_layout()
    FIGURE.parent.mkdir(exist_ok=True)
    fig.savefig(FIGURE, dpi=120)


if __name__ == "__main__":
    main()
