"""The event-order study's control runs: the lander on linear legs, kicked, and the clean switch.

Owns the control scenes (at rest on level ground, kicked; the settled start),
the clean branch-switch control, their runs and the interleaved cost check,
and the text of their sections. It must not run the lander variants.
"""
from __future__ import annotations

import numpy as np

from symcushion.compiled.codegen import compiled_model
from symcushion.layout.vectors import state_layout
from symcushion.model.scene import read_toml, scene_from_dict
from symcushion.scheme.touchdown import build_model, equilibrium_state
from symcushion.run.driver import simulate
from symcushion.studies import speed_vs_error as sve

from .cases import BUILD, CHUNK, REVERSAL_DTS, SLIP_RULES, STICK_MU, STUDIES, case_label, scenes
from .runs import at_step, final_error, leg_reversals


CONTROLS = {"sticks, bounces and rocks": (2.0, (0.0, 0.0, 0.2), (0.3, 0.0, 0.0)),
            "slides": (0.1, (0.3, 0.0, 0.0), (0.0, 0.0, 0.0)),
            "slides and turns": (0.1, (0.3, 0.0, 0.0), (0.0, 0.0, 1.0))}
#: Stiffness of the controls' linear absorber (N/m): the crushable curve's
#: initial slope, without its plateau and unloading branch.
CONTROL_STIFFNESS = 1e5
CONTROL_DURATION = 0.3
CONTROL_DT_REF = 1e-5
CONTROL_DTS = (2e-3, 1e-3, 5e-4, 2.5e-4, 1e-4)
#: Length of the step that settles a control's start (s; :func:`settled`):
#: at the 0.3 m/s kick the body moves 3e-10 m and its velocity changes by
#: ~1e-8 m/s, below every error measured, while each foot makes the
#: instantaneous slip that brings a force outside the friction cone onto it.
SETTLE_DT = 1e-9
#: Starts of the controls: ``equilibrium_state(cone=False)`` as built (feet held), and settled.
STARTS = ("as built", "settled")


def settled(model, x0, p=None):
    """The state after one step of :data:`SETTLE_DT` from ``x0``: the feet on the cone.

    ``equilibrium_state(cone=False)`` holds every foot where it lands with the
    force of a foot that sticks (by default it solves for the feet on their cones
    instead); below the legs' |P_τ|/N (0.24 at rest on level ground)
    those forces lie outside the friction cone (1.4), and the massless feet
    slip at t = 0⁺ by a finite amount. From such a start the first half kick
    of every run uses forces that its contact step then discards: an error
    h/2·ΔF/m once, first order in Δt whatever the slip rule. After this step
    the stored forces are those of the settled feet.

    Parameters
    ----------
    model : StepModel
    x0 : ndarray, shape (nx,)
    p : ndarray, shape (np,), optional
        Default the scene's values.
    """
    p = model.default_p if p is None else p
    return np.asarray(model.step(x0, p, SETTLE_DT)[0], dtype=float).ravel()


def control_scene(mu, kick_v, kick_w, duration=CONTROL_DURATION, name="control"):
    """A control: (Scene, x0) of the lander at rest on its linear legs on level ground, kicked.

    Parameters
    ----------
    mu : float
        Friction coefficient.
    kick_v : sequence of 3 float
        Velocity added to the centre of mass at rest (m/s, world).
    kick_w : sequence of 3 float
        Angular velocity added (rad/s, body axes).
    """
    data = read_toml(STUDIES / "lander_slope.toml")
    data["legs"]["S"] = {"type": "linear", "stiffness": CONTROL_STIFFNESS}
    data["obstacle"][0]["angle"] = 0.0
    data["scene"]["mu"] = float(mu)
    scene = scene_from_dict(data, f"control:{name}").with_(duration=duration)
    return scene, _kicked(scene, kick_v, kick_w)


def _kicked(scene, kick_v, kick_w):
    """The scene's state at rest on its feet with the velocity kick_v (m/s, world) and
    angular velocity kick_w (rad/s, body axes) added."""
    x0 = equilibrium_state(scene, cone=False)   # held where they land: the start "as built"
    xl = state_layout(len(scene.legs))
    x0[xl.slice("velocity")] += np.asarray(kick_v, dtype=float)
    x0[xl.slice("angular_velocity")] += np.asarray(kick_w, dtype=float)
    return x0


#: The clean branch switch (:func:`switch_control`): the hop scene's lander on
#: level ground at rest on its feet, kicked down at 1 m/s and rocked at
#: 0.3 rad/s, μ = 2: every leg crushes, turns once (one switch to the 1.5 kN
#: spring-back, which lifts the body: no chatter) and is still in contact at
#: the end. Kick (m/s, world), rocking (rad/s, body), μ, duration (s).
SWITCH_KICK = ((0.0, 0.0, -1.0), (0.3, 0.0, 0.0), 2.0, 0.07)


def switch_control(events="none", slip="midpoint"):
    """(Scene, x0) of the clean branch switch :data:`SWITCH_KICK`, with ``events``."""
    kick_v, kick_w, mu, duration = SWITCH_KICK
    data = read_toml(STUDIES / "lander_hop.toml")
    data["obstacle"][0]["angle"] = 0.0
    data["scene"].update(mu=mu, slip=slip, events=events)
    scene = scene_from_dict(data, f"switch control:{events}").with_(duration=duration)
    return scene, _kicked(scene, kick_v, kick_w)


#: Δt of the switch control's fit (s), and its reference and check (VM runs).
SWITCH_DTS = (2e-3, 1e-3, 5e-4, 2.5e-4, 1.25e-4)
SWITCH_REF = (1e-5, 5e-6)


def switch_case(events, progress=print):
    """Rows of the clean switch (:func:`switch_control`) with ``events``: final-state error."""
    scene, x0 = switch_control(events)
    model = build_model(scene)
    _, ref = final_state(scene, model, x0, SWITCH_REF[0])
    _, check = final_state(scene, model, x0, SWITCH_REF[1])
    variant = case_label("clean switch", scene.slip, events)
    base = {"scene": "switch control", "variant": variant, "slip": scene.slip, "events": events}
    rows = [{**base, "kind": "reference check", "dt": SWITCH_REF[0], "status": "ok",
             "final_error": final_error(ref, check), "slip_fraction": 0.0}]
    flips = {}
    for dt in SWITCH_DTS:
        _, run = final_state(scene, model, x0, dt)
        rows.append({**base, "kind": "run", "dt": dt, "status": "ok",
                     "final_error": final_error(run, ref)})
        flips[dt] = " ".join(map(str, leg_reversals(run)))
    rows[0]["reversals"] = " / ".join(flips[dt] for dt in REVERSAL_DTS)
    progress(f"switch control / {variant}: final-state errors "
             + " ".join(f"{r['final_error']:.2e}" for r in rows[1:]))
    return rows


def final_state(scene, model, x0, dt):
    """Final centre-of-mass position and velocity (6,), m and m/s, of a VM run at ``dt``."""
    traj = simulate(scene.with_(dt=dt), model=at_step(model, scene, dt), x0=x0, monitor=False)
    return np.concatenate([traj.position[-1], traj.velocity[-1]]), traj


def controls(progress=print):
    """Final-state errors of the control runs (see :data:`CONTROLS`), VM.

    Every control runs from each start of :data:`STARTS` with each slip rule
    of :data:`SLIP_RULES`; the control that sticks has no force outside the
    cone to settle and runs from its start as built only.
    """
    rows = []
    for name, (mu, kick_v, kick_w) in CONTROLS.items():
        for rule in SLIP_RULES:
            scene, x_built = control_scene(mu, kick_v, kick_w, name=name)
            scene = scene.with_(slip=rule)
            model = build_model(scene)
            for start in STARTS if mu < STICK_MU else STARTS[:1]:
                x0 = settled(model, x_built) if start == "settled" else x_built
                ref, _ = final_state(scene, model, x0, CONTROL_DT_REF)
                errs = []
                for dt in CONTROL_DTS:
                    state, traj = final_state(scene, model, x0, dt)
                    errs.append(float(np.linalg.norm(state - ref)))
                slip = float(np.mean(traj.mode[1:] == 2))
                order = sve.convergence_order(CONTROL_DTS, errs, dt_max=max(CONTROL_DTS))[0]
                rows.append({"control": name, "mu": mu, "start": start, "rule": rule,
                             "errors": errs, "order": order, "slip": slip})
                progress(f"control {name!r}, {start}, {rule}: errors "
                         f"{['%.2e' % e for e in errs]}, order {order:.2f}, slip fraction "
                         f"{slip:.2f}")
    return rows


def controls_text(rows):
    """The section "Events: controls" of the results page."""
    lines = ["Control runs (`python studies/event_order.py --controls`): the lander with a "
             f"linear absorber ({CONTROL_STIFFNESS:g} N/m) on a level plane, started at rest on "
             f"its feet with a velocity kick, {CONTROL_DURATION:g} s on the VM; error of the "
             "final position and velocity (one 6-vector, m and m/s) against "
             f"Δt = {CONTROL_DT_REF:g} s. Start: `equilibrium_state` as built (with μ = 0.1 "
             "its stored forces lie outside the friction cone), or settled (one step of "
             f"{SETTLE_DT:g} s: the feet on the cone, `settled()`).", "",
             "| control | μ | start | slip rule | "
             + " | ".join(f"Δt = {d:g}" for d in CONTROL_DTS) + " | order | slipping samples |",
             "|---|---:|---|---|" + "---:|" * (len(CONTROL_DTS) + 2)]
    for r in rows:
        lines.append(f"| {r['control']} | {r['mu']:g} | {r['start']} | {r['rule']} | "
                     + " | ".join(f"{e:.2e}" for e in r["errors"])
                     + f" | {r['order']:.2f} | {r['slip']:.2f} |")
    return "\n".join(lines)


#: Interleaved timing of the located switch and the lock (``--cost``): Δt (s)
#: and rounds; each round runs the default, the midpoint, the midpoint + branch
#: and the midpoint + lock case of a variant once, and the fastest of the
#: rounds counts, so that the load of the shared machine falls on all alike.
COST_DT = 1e-4
COST_ROUNDS = 7


def cost_check(progress=print):
    """Best-of-rounds CPU per simulated second of each branch case and its two peers."""
    cases = {(name, label): scene for name, label, _, scene in scenes()}
    out = []
    for name, label in sorted(k for k, scene in cases.items() if scene.events == "branch"):
        base = label.split(" (")[0]
        labels = (base, case_label(base, "midpoint"), label,
                  case_label(base, "midpoint", "lock"))
        models = {lab: compiled_model(cases[(name, lab)], BUILD / cases[(name, lab)].name,
                                      steps=CHUNK) for lab in labels}
        best = dict.fromkeys(labels, float("inf"))
        for _ in range(COST_ROUNDS):
            for lab in labels:
                run = sve.simulate_chunked(models[lab], cases[(name, lab)], COST_DT, passes=1)
                best[lab] = min(best[lab], run.info["cpu"] / run.info["sim_seconds"])
        out.append((name, base, *(best[lab] for lab in labels)))
        progress(f"{name} / {base}: " + ", ".join(f"{lab} {best[lab]:.3g}" for lab in labels))
    return out


def cost_text(rows):
    """The section "Events: cost" of the results page."""
    lines = ["Interleaved timing (`python studies/event_order.py --cost`): compiled C, "
             f"Δt = {COST_DT:g} s, CPU s per simulated second, the fastest of {COST_ROUNDS} "
             "rounds, each round running the four cases of a variant one after the other. "
             "The elastic variant has no unloading branch: its midpoint, midpoint + branch and "
             "midpoint + lock steps are the same graph, and their ratios are the scatter of "
             "the timing.", "",
             "| scene | variant | default | midpoint | midpoint + branch | midpoint + lock | "
             "branch / midpoint | lock / midpoint | lock / default |",
             "|---|---|---:|---:|---:|---:|---:|---:|---:|"]
    for name, base, default, midpoint, branch, lock in rows:
        lines.append(f"| {name} | {base} | {default:.3g} | {midpoint:.3g} | {branch:.3g} | "
                     f"{lock:.3g} | {branch / midpoint:.2f} | {lock / midpoint:.2f} | "
                     f"{lock / default:.2f} |")
    return "\n".join(lines)
