"""Physical sanity checks: check_scene, preflight and the run monitor."""
import json
import tomllib
import warnings
from pathlib import Path

import numpy as np
import pytest

from symcushion.run.checks import (BODY_TOLERANCE, START_TOLERANCE, Finding, PhysicsWarning,
    RunMonitor, check_scene, preflight)
from symcushion.run.monitor import DEFAULT_TOLERANCES
from symcushion.model.scene import load_scene, scene_from_dict
from symcushion.layout.vectors import BODY_STATE, LEG_STATE
from symcushion.scheme.touchdown import build_model, initial_state
from symcushion.run.driver import simulate
from symcushion.validation import SceneError

ROOT = Path(__file__).resolve().parents[1]
SCENES = ("fig3.toml", "fig4.toml", "lander_slope.toml")


def fig3(duration=0.1):
    return load_scene(ROOT / "studies" / "fig3.toml").with_(method="implicit",
                                                            duration=duration)


def rollout(scene):
    """States X (nx, steps) and outputs Y (ny, steps) of the scene's fixed-step run."""
    model = build_model(scene)
    X, Y = model.rollout(scene.steps)(initial_state(scene), model.default_p, scene.dt)
    return model, np.asarray(X), np.asarray(Y), scene.dt * np.arange(1, scene.steps + 1)


@pytest.mark.parametrize("name", SCENES)
def test_study_scenes_are_clean(name):
    assert check_scene(load_scene(ROOT / "studies" / name)) == []


def test_finding_to_dict_is_json_ready_and_severity_checked():
    f = Finding("foot_inside", "deep", "error", leg=2, value=0.1, field="body.position")
    assert json.loads(json.dumps(f.to_dict())) == {
        "kind": "foot_inside", "message": "deep", "severity": "error", "time": None, "leg": 2,
        "value": 0.1, "field": "body.position"}
    with pytest.raises(ValueError, match="`severity`"):
        Finding("x", "y", "fatal")


def test_feet_just_within_the_start_tolerance_pass():
    scene = fig3()
    assert check_scene(scene.with_(body=_moved(scene, -0.5 * START_TOLERANCE))) == []
    below = check_scene(scene.with_(body=_moved(scene, -2 * START_TOLERANCE)))
    assert {f.kind for f in below} == {"foot_inside"}


def _moved(scene, dz):
    from dataclasses import replace
    return replace(scene.body, position=scene.body.position + np.array([0.0, 0.0, dz]))


def test_body_far_inside_puts_hinges_inside_too():
    found = check_scene(fig3().with_(body=_moved(fig3(), -0.75)))   # centre 7 cm deep
    assert {"body_inside", "hinge_inside", "foot_inside"} <= {f.kind for f in found}


def test_preflight_raises_on_errors_warns_on_warnings_and_strict_raises_both():
    scene = fig3()
    fast = scene.with_(body=_velocity(scene, -100.0))
    with pytest.warns(PhysicsWarning, match="under-resolved"):
        assert [f.kind for f in preflight(fast)] == ["fast_impact"]
    with pytest.raises(SceneError, match="warning: .*under-resolved"):
        preflight(fast, strict=True)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert preflight(scene) == []
    assert preflight(fast.with_(dt=1e-4)) == []       # 1 cm per step: resolved
    with pytest.raises(SceneError, match="dt_above|longer than"):
        preflight(scene.with_(dt=0.2, duration=0.05))


def _velocity(scene, vz):
    from dataclasses import replace
    return replace(scene.body, velocity=np.array([0.0, 0.0, vz]))


def test_zero_gravity_scene_has_no_findings():
    assert check_scene(fig3().with_(gravity=[0.0, 0.0, 0.0])) == []


def test_rippled_surface_is_not_smooth():
    data = {"scene": {"duration": 0.1}, "body": {"mass": 50.0, "inertia": [1.25] * 3,
                                                 "position": [0, 0, 1.0]},
            "legs": {"count": 4, "radius": 0.3, "height": -0.18, "length": 0.6,
                     "e0": [0, 0, -1], "en": [-0.7, 0, -0.7],
                     "M_beta": {"type": "linear", "stiffness": 1200.0},
                     "M_gamma": {"type": "linear", "stiffness": 1200.0}},
            # ripples of 6 µm wavelength: the central difference at h = 0.6 µm
            # misses their slope by 6 %, far above the 1e-3 tolerance
            "obstacle": [{"type": "implicit", "phi": "z - 1e-6*sin(1e6*x)"}]}
    found = check_scene(scene_from_dict(data))
    assert [(f.kind, f.severity) for f in found] == [("surface_not_smooth", "warning")]
    data["obstacle"][0]["phi"] = "z - 0.1*sin(x)"
    assert check_scene(scene_from_dict(data)) == []


def test_monitor_is_silent_on_a_clean_run_fed_in_blocks():
    scene = fig3(duration=0.3)
    model, X, Y, t = rollout(scene)
    monitor = RunMonitor(scene, model)
    for block in np.array_split(np.arange(t.size), 7):
        assert monitor.check(t[block], X[:, block], Y[:, block]) == []


def test_monitor_reports_each_kind_once_per_leg_with_its_first_time():
    scene = fig3()
    model, X, Y, t = rollout(scene)
    X = X.copy()
    tol = DEFAULT_TOLERANCES["penetration"]
    foot1 = BODY_STATE + LEG_STATE * 1
    X[foot1 + 2, 40:] -= 3 * tol                      # foot 1 pushed 3 mm into the dome
    monitor = RunMonitor(scene, model)
    first = monitor.check(t[:60], X[:, :60], Y[:, :60])
    assert [(f.kind, f.leg) for f in first] == [("penetration", 1)]
    assert first[0].time == pytest.approx(t[40]) and first[0].severity == "warning"
    assert monitor.check(t[60:], X[:, 60:], Y[:, 60:]) == []          # reported once


def test_monitor_non_finite_body_inside_and_energy_growth():
    scene = fig3()
    model, X, Y, t = rollout(scene)
    bad = X.copy()
    bad[3:6, 10:] *= 3.0                               # kinetic energy × 9 from step 10
    found = RunMonitor(scene, model).check(t, bad, Y)
    assert [f.kind for f in found] == ["energy_growth"] and found[0].time == pytest.approx(t[10])
    sunk = X.copy()
    depth = 1.18 - 0.5 + BODY_TOLERANCE * 0.6 + 0.01   # centre 1 cm past the allowed depth
    sunk[2, 20:] -= depth
    kinds = {f.kind for f in RunMonitor(scene, model).check(t, sunk, Y)}
    assert "body_inside" in kinds and "pass_through" in kinds
    nan = X.copy()
    nan[0, 30] = np.nan
    found = RunMonitor(scene, model).check(t, nan, Y)
    assert [(f.kind, f.severity) for f in found] == [("non_finite", "error")]
    assert found[0].time == pytest.approx(t[30])


def test_monitor_validates_its_arguments():
    scene = fig3()
    with pytest.raises(ValueError, match="did you mean 'penetration'"):
        RunMonitor(scene, tolerances={"penetraton": 1e-3})
    with pytest.raises(ValueError, match="positive"):
        RunMonitor(scene, tolerances={"energy": -1.0})
    monitor = RunMonitor(scene)
    with pytest.raises(ValueError, match="`X` must have shape"):
        monitor.check(np.zeros(3), np.zeros((5, 3)), np.zeros((2, 3)))


def test_simulate_runs_preflight():
    scene = fig3()
    with pytest.raises(SceneError, match="body centre starts"):
        simulate(scene.with_(body=_moved(scene, -1.0)))


def test_negative_slope_away_from_rest_is_a_warning():
    scene = fig3()
    data = {"type": "piecewise", "x": [-1.0, 0.0, 0.5, 1.0], "f": [-1200.0, 0.0, 600.0, 300.0]}
    from symcushion.model.scene import _curve
    from symcushion.validation import Table
    curve = _curve(Table(data, "legs.M_beta", "test"))
    legs = [type(leg)(leg.hinge, leg.e0, leg.en, leg.length, M_beta=curve,
                      M_gamma=leg.elements[-1].curve) for leg in scene.legs]
    found = check_scene(scene.with_(legs=legs))
    assert [(f.kind, f.severity) for f in found] == [("negative_slope", "warning")] * 4
    assert found[0].value == pytest.approx(-600.0, rel=1e-12)     # (300 − 600)/0.5


def test_dt_a_little_above_the_stable_step_is_a_warning():
    found = check_scene(fig3().with_(dt=4e-3))
    assert [(f.kind, f.severity) for f in found] == [("dt_unstable", "warning")]
    assert 1 < found[0].value < 10


def test_monitor_reports_a_foot_in_contact_off_the_terrain_grid():
    from symcushion.model.obstacles import Terrain
    scene = fig3().with_(obstacles=[Terrain.crater()])      # grid ±3 m
    x = initial_state(scene)
    foot0 = BODY_STATE
    x[foot0:foot0 + 4] = [3.5, 0.0, 0.0, 1.0]                # in contact at x = 3.5 m
    found = RunMonitor(scene).check(np.array([0.01]), x[:, None], np.zeros((1, 1)))
    assert [(f.kind, f.leg, f.severity) for f in found] == [("off_terrain", 0, "error")]


def test_a_frictionless_leg_without_a_hinge_spring_is_refused_before_it_falls_through():
    """μ = 0 and legs tilted 20° with no M_beta: no foot could take load (the contact step
    finds no slide along the free direction), so check reports it and simulate refuses."""
    from symcushion.legs.characteristics import Linear as _Linear
    from symcushion.legs.strut import HingedStrut
    lander = load_scene(ROOT / "studies" / "tutorial" / "lander.toml")
    legs = [HingedStrut(hinge=leg.hinge, e0=leg.e0, en=leg.en, length=leg.length,
                        S=_Linear(1e5), M_gamma=_Linear(2e4)) for leg in lander.legs]
    scene = lander.with_(legs=legs, mu=0.0)
    found = [f for f in check_scene(scene) if f.kind == "free_direction"]
    assert [f.leg for f in found] == [0, 1, 2] and all(f.severity == "error" for f in found)
    assert "M_beta" in found[0].message and "mu > 0" in found[0].message
    with pytest.raises(ValueError, match="falls through"):
        simulate(scene)
    # with friction, or with both hinge springs, the same legs are accepted
    assert not [f for f in check_scene(scene.with_(mu=0.5)) if f.kind == "free_direction"]
    assert not [f for f in check_scene(lander.with_(mu=0.0)) if f.kind == "free_direction"]


def test_a_leg_damped_on_its_axis_alone_is_warned():
    """Dampers of one time constant on every element pass; an axial damper alone is
    warned about, naming the leg and the time constants (docs/absorbers.md)."""
    from symcushion.run.checks import check_scene
    from symcushion.model.scene import read_toml
    studies = Path(__file__).resolve().parents[1] / "studies"
    data = read_toml(studies / "lander_damped.toml")
    assert not [f for f in check_scene(scene_from_dict(data)) if f.kind == "damping_times"]
    for name in ("M_beta", "M_gamma"):
        del data["legs"][name]["damping"]
    found = [f for f in check_scene(scene_from_dict(data)) if f.kind == "damping_times"]
    assert len(found) == 3 and found[0].severity == "warning"
    assert "S 3.5 ms" in found[0].message and "same c/k" in found[0].message


def _tutorial_with_hinge_stiffness(k):
    """The tutorial lander (crush force 2 kN, legs of 0.8 m) with both hinge springs at k
    N·m/rad, their dampers keeping the elements' common damping time."""
    data = tomllib.loads((ROOT / "studies" / "tutorial" / "lander.toml").read_text())
    for name in ("M_beta", "M_gamma"):
        spring = data["legs"][name]
        spring["damping"] *= k / spring["stiffness"]
        spring["stiffness"] = k
    return scene_from_dict(data)


def test_a_leg_whose_hinge_springs_cannot_hold_its_crush_force_is_warned():
    # k/L² = 1000/0.64 = 1562 N/m below S/L = 2000/0.8 = 2500 N/m; the bound is 1600 N·m/rad
    weak = _tutorial_with_hinge_stiffness(1000.0)
    found = [f for f in check_scene(weak) if f.kind == "leg_buckles"]
    assert [f.leg for f in found] == [0, 1, 2]
    assert all(f.severity == "warning" and f.field == f"legs[{f.leg}].M_beta" for f in found)
    assert "1600 N·m/rad" in found[0].message and "crush force" in found[0].message
    with pytest.warns(PhysicsWarning, match="would fold"):
        preflight(weak)
    with pytest.raises(SceneError, match="would fold"):          # `symcushion check --strict`
        preflight(weak, strict=True)
    stiff = _tutorial_with_hinge_stiffness(1700.0)
    assert not [f for f in check_scene(stiff) if f.kind == "leg_buckles"]


def test_the_warned_leg_is_released_at_the_ground_not_inside_it():
    # what the warning is about: the contact step finds no compressive state for the
    # straight leg and releases the downhill foot. Before lift-offs were located in the
    # step (docs/absorbers.md) it did so 1.7 mm inside the slope; now the release is at
    # the ground, and no step ends with a foot inside an obstacle
    weak = _tutorial_with_hinge_stiffness(1000.0).with_(duration=0.15)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        run = simulate(weak, estimate=False)
    lift = [e["time"] for e in run.info["events"] if e["kind"] == "lift-off" and e["leg"] == 0]
    inside = [w for w in run.info["warnings"] if "inside an obstacle" in w["message"]]
    assert lift == [pytest.approx(0.121)] and not inside
