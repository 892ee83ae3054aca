"""The absorber's branch switch located inside the step (``events = "branch"``).

``symcushion.scheme.branch_switch`` weights the kick of the step in which a leg's
axial force changes between its loading and unloading branches at the
located switch time. These tests check that it does what it claims and
nothing else: second order through a clean switch (the lander on level
ground kicked down onto its crushable legs, one switch per leg, the scene
of ``studies/event_order.py``'s :func:`switch_control`) where the default
kick is first order; the step unchanged without an unloading branch (Figs.
3–4, the lander's elastic variant) and in the default graph; the option
validated; gradients through the scheme.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import symcushion.scheme.touchdown_events as touchdown
from symcushion.design.optimise import study_from_dict
from symcushion.layout.vectors import state_layout
from symcushion.model.scene import SceneError, load_scene, read_toml, scene_from_dict
from symcushion.scheme.touchdown import build_model, initial_state
from symcushion.run.driver import simulate
from symcushion.run.error_control import fitted_order

from research import event_order   # not installed: tests/conftest.py puts it on sys.path

ROOT = Path(__file__).resolve().parent.parent



#: Δt of the order fits (s): five halvings from 2 ms.
DTS = (2e-3, 1e-3, 5e-4, 2.5e-4, 1.25e-4)
#: Reference and its check (s): 12.5× and 25× below the finest fitted Δt.
REF_DT, CHECK_DT = 1e-5, 5e-6
#: The project's target order.
MIN_SECOND_ORDER = 1.8
#: The default kick through the same switch: an O(Δt) impulse error per
#: switch, measured at order 0.85 on this scene; below this bound it is not
#: second order, so the comparison shows what the scheme changes.
MAX_DEFAULT_ORDER = 1.5
#: The reference's own error (against its check) must stay below this share of
#: the smallest fitted error, so that the fit measures the run, not the reference.
REF_SHARE = 0.1



def _final_errors(events):
    scene, x0 = event_order.switch_control(events)
    model = build_model(scene)
    ref, traj = event_order.final_state(scene, model, x0, REF_DT)
    check, _ = event_order.final_state(scene, model, x0, CHECK_DT)
    errors = [np.linalg.norm(event_order.final_state(scene, model, x0, dt)[0] - ref)
              for dt in DTS]
    return np.array(errors), float(np.linalg.norm(ref - check)), traj


@pytest.fixture(scope="module")
def switch_runs():
    return {events: _final_errors(events) for events in ("none", "branch")}


def test_the_switch_control_switches_once_per_leg(switch_runs):
    _, _, traj = switch_runs["branch"]
    assert np.all(np.asarray(traj.contact)[-1] > 0.5)
    assert event_order.leg_reversals(traj) == (1, 1, 1)


def test_second_order_through_a_branch_switch(switch_runs):
    errors, ref_error, _ = switch_runs["branch"]
    assert ref_error <= REF_SHARE * errors.min(), (ref_error, errors)
    order = fitted_order(DTS, errors)
    assert order >= MIN_SECOND_ORDER, (order, errors)


def test_the_default_kick_is_not_second_order_there(switch_runs):
    errors, ref_error, _ = switch_runs["none"]
    assert ref_error <= REF_SHARE * errors.min(), (ref_error, errors)
    order = fitted_order(DTS, errors)
    assert order <= MAX_DEFAULT_ORDER, (order, errors)


def _same_step(scene):
    """The step of ``scene`` with events 'none' and 'branch': equal graphs and outputs."""
    plain, branch = build_model(scene), build_model(scene.with_(events="branch"))
    assert plain.graph_size() == branch.graph_size()
    x0, p = initial_state(scene), plain.default_p
    for h in (1e-3, 0.2):   # free fall, then a step deep into the ground
        a, b = plain.step(x0, p, h), branch.step(x0, p, h)
        assert all(np.array_equal(np.asarray(u), np.asarray(v)) for u, v in zip(a, b))


@pytest.mark.parametrize("path", ["studies/fig3.toml", "studies/fig4.toml"])
def test_figs_3_4_are_unchanged(path):
    # no unloading branch on the dome legs: nothing to locate, the Verlet step
    _same_step(load_scene(ROOT / path))


def test_without_unloading_branch_the_step_is_unchanged():
    data = event_order._variant_data(read_toml(ROOT / "studies" / "lander_slope.toml"),
                                     "elastic", "midpoint")
    _same_step(scene_from_dict(data, "elastic"))


def test_the_default_graph_does_not_contain_the_scheme(monkeypatch):
    scene = load_scene(ROOT / "studies" / "lander_slope.toml")
    assert scene.events == "none"

    def refuse(*args, **kwargs):
        raise AssertionError("branch_switch_kick called")

    monkeypatch.setattr(touchdown, "branch_switch_kick", refuse)
    build_model(scene)                                 # the default never calls it
    with pytest.raises(AssertionError, match="branch_switch_kick"):
        build_model(scene.with_(events="branch"))


def test_the_scheme_adds_to_the_graph_where_a_leg_has_a_jump():
    scene = load_scene(ROOT / "studies" / "lander_slope.toml")
    plain, branch = build_model(scene), build_model(scene.with_(events="branch"))
    assert branch.graph_size()["instructions"] > plain.graph_size()["instructions"]


def test_bad_events_is_rejected():
    scene = load_scene(ROOT / "studies" / "lander_slope.toml")
    with pytest.raises(ValueError, match="`events`.*'split'"):
        scene.with_(events="split")
    data = read_toml(ROOT / "studies" / "lander_slope.toml")
    data["scene"]["events"] = "splitt"
    with pytest.raises(SceneError, match="events"):
        scene_from_dict(data, "bad.toml")


#: The slope lander's leg 2 drops from its loading curve (2.7 kN) to its
#: unloading curve (0.56 kN) at t ≈ 48.35 ms while its foot slides: the state
#: a little before (s), the fine step around it (s) and the steps of the fit (s).
DROP_BEFORE, DROP_FINE, DROP_DTS = 0.048, 1e-6, (4e-5, 2e-5, 1e-5)
#: Leg 2's force (N) below which it is on its unloading curve (0.56 kN after the
#: drop), and above which on its loading curve (2.7 kN before it).
DROP_FORCE, LOADED_FORCE = 1000.0, 2000.0
#: Fine steps run past the first Δt of the fit: the drop comes within
#: 0.35 ms of DROP_BEFORE.
DROP_SEARCH = 400


def _drop_local_errors():
    """Errors of one step that holds leg 2's drop in its middle, against steps of
    ``DROP_FINE`` over the same time: body velocity (m/s) and leg 2's foot (m)."""
    data = read_toml(ROOT / "studies" / "lander_slope.toml")
    data["scene"].update(slip="midpoint", events="branch", duration=DROP_BEFORE, dt=1e-4)
    scene = scene_from_dict(data, "lander_slope.toml (before the drop)")
    model = build_model(scene)
    p = model.default_p
    layout = state_layout(len(scene.legs))
    states = [np.asarray(simulate(scene, model=model, monitor=False).info["final_state"],
                         dtype=float).ravel()]
    for _ in range(round(2 * max(DROP_DTS) / DROP_FINE) + DROP_SEARCH):
        states.append(np.asarray(model.step(states[-1], p, DROP_FINE)[0]).ravel())
    force = [np.linalg.norm(layout.unpack(x)["force_body"][2]) for x in states]
    drop = next(k for k, f in enumerate(force) if f < DROP_FORCE)
    assert force[drop - 1] > LOADED_FORCE                  # one jump, inside the fine step
    velocity, foot = [], []
    for dt in DROP_DTS:
        n = round(dt / DROP_FINE)
        start, ref = layout.unpack(states[drop - n // 2]), layout.unpack(states[drop - n // 2 + n])
        one = layout.unpack(np.asarray(model.step(states[drop - n // 2], p, dt)[0]).ravel())
        assert np.linalg.norm(start["force_body"][2]) > LOADED_FORCE > np.linalg.norm(
            one["force_body"][2])
        velocity.append(np.linalg.norm(np.asarray(one["velocity"]) - ref["velocity"]))
        foot.append(np.linalg.norm(np.asarray(one["foot"][2]) - ref["foot"][2]))
    return np.array(velocity), np.array(foot)


def test_a_sliding_foot_drops_onto_its_unloading_curve_at_second_order():
    """The contact step split at the switch (B2).

    As its force drops the sliding foot jumps to its equilibrium on the
    unloading curve. One contact step over the whole of Δt started that jump
    from the wrong place (the foot's position at t_n, not at t*), and located
    t* from the world point under the foot at t_n (off by a fixed share of
    the step): both O(Δt) in a step that happens once, first order. The split
    step's errors in that step are O(Δt²) or better.
    """
    velocity, foot = _drop_local_errors()
    for name, errors in (("velocity", velocity), ("foot", foot)):
        order = fitted_order(DROP_DTS, errors)
        assert order >= MIN_SECOND_ORDER, (name, order, errors)


#: The optimiser's bound on AD against central differences (tests/test_optimise.py).
GRADIENT_TOL = 1e-5
#: Simulated time of the gradient case (s): the vertical touchdown through
#: the legs' turn onto their unloading branches (at 0.104 s at the initial
#: design, every leg once).
GRADIENT_DURATION = 0.15



def test_lander_gradient_with_the_branch_switch():
    # the lander design study's vertical touchdown, shortened, with the
    # midpoint slip rule and the located branch switch: AD against central
    # differences
    data = read_toml(ROOT / "studies" / "optimise_lander.toml")
    data["scene"].update(slip="midpoint", events="branch", duration=GRADIENT_DURATION)
    data["scenario"] = [s for s in data["scenario"] if s["name"] == "vertical"]
    problem = study_from_dict(data, "optimise_lander.toml:branch",
                              base_dir=ROOT / "studies").problem
    scenario = problem.scenarios[0]
    assert scenario.scene.events == "branch"
    traj = simulate(scenario.scene, x0=scenario.x0, monitor=False)
    assert event_order.leg_reversals(traj) == (1,) * len(scenario.scene.legs)   # the switch is inside
    check = problem.check_gradient(problem.initial)
    assert check["relative"] <= GRADIENT_TOL, check
    assert check["objective"] <= GRADIENT_TOL, check
    assert check["worst_row"] <= GRADIENT_TOL, check
