"""Regression tests: every bad input a new user tried gives a clear error or a warning.

Each test is one case of the list of bad scene files and API calls (silent wrong
physics, tracebacks or hangs, API misuse); the name says which.
"""
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from symcushion.legs.characteristics import Linear, PiecewiseLinear
from symcushion.run.checks import PhysicsWarning, RunMonitor, check_scene
from symcushion.cli import main
from symcushion.model.scene import Scene, load_scene, scene_from_dict
from symcushion.run.driver import simulate
from symcushion.validation import SceneError, boolean, choice, direction, integer, real, vector
from symcushion.validation import path as validate_path

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

ROOT = Path(__file__).resolve().parents[1]
FIG3 = ROOT / "studies" / "fig3.toml"


def fig3(**scene_changes):
    """The Fig. 3 scene as a dict, 50 ms long, with ``[scene]`` fields changed."""
    data = tomllib.loads(FIG3.read_text())
    data["scene"].update({"duration": 0.05, "method": "implicit", **scene_changes})
    return data


def kinds(findings, severity=None):
    return {f.kind for f in findings if severity is None or f.severity == severity}


def load_error(data) -> str:
    with pytest.raises(SceneError) as info:
        scene_from_dict(data, "bad.toml")
    return str(info.value)


def state_matrix(traj):
    """The state columns (nx, steps) of a Trajectory, after each step."""
    return traj.states()[:, 1:]


# -- silent wrong physics ------------------------------------------------------
def test_body_centre_inside_sphere_is_an_error():
    data = fig3()
    data["body"]["position"] = [0.0, 0.0, 0.2]
    scene = scene_from_dict(data)
    assert "body_inside" in kinds(check_scene(scene), "error")
    with pytest.raises(SceneError, match="body centre starts"):
        simulate(scene)


def test_feet_starting_inside_the_obstacle_is_an_error():
    data = fig3()
    data["body"]["position"] = [0.0, 0.0, 1.18 - 0.13]
    findings = check_scene(scene_from_dict(data))
    inside = [f for f in findings if f.kind == "foot_inside"]
    assert len(inside) == 4 and all(f.severity == "error" for f in inside)
    assert all(f.field == "body.position" for f in inside)
    # 0.13 m lower, the foot at (0.3, 0, 0.27) is 0.5 − |(0.3, 0.27)| deep along the normal
    assert inside[0].value == pytest.approx(0.5 - np.hypot(0.3, 0.4 - 0.13), rel=1e-9)


def test_100_m_per_s_impact_warns_then_monitor_reports_pass_through():
    data = fig3(duration=0.02)
    data["body"]["velocity"] = [0.0, 0.0, -100.0]
    scene = scene_from_dict(data)
    assert kinds(check_scene(scene)) == {"fast_impact"}
    with pytest.warns(PhysicsWarning, match="under-resolved"):
        traj = simulate(scene)
    found = RunMonitor(scene).check(traj.t[1:], state_matrix(traj), np.zeros((0, len(traj.t) - 1)))
    assert {"pass_through", "body_inside"} <= kinds(found, "error")
    first = min(f.time for f in found)
    assert 0 < first < 0.02


def test_negative_hinge_stiffness_is_rejected_with_its_field():
    data = fig3()
    data["legs"]["M_beta"]["stiffness"] = -1200.0
    message = load_error(data)
    assert "`legs.M_beta`" in message and "-1200" in message and "non-negative" in message


def test_negative_slope_of_a_piecewise_hinge_spring_is_an_error_at_rest():
    data = fig3()
    data["legs"]["M_beta"] = {"type": "piecewise", "x": [-1.0, 1.0], "f": [1200.0, -1200.0]}
    findings = check_scene(scene_from_dict(data))
    assert "negative_stiffness" in kinds(findings, "error")


def test_feet_off_the_terrain_grid_is_an_error():
    data = fig3()
    data["obstacle"] = [{"type": "terrain", "x": [5.0, 6, 7, 8], "y": [5.0, 6, 7, 8],
                         "heights": [0.0] * 16}]
    findings = check_scene(scene_from_dict(data))
    off = [f for f in findings if f.kind == "off_terrain"]
    assert len(off) == 4 and all(f.severity == "error" for f in off)


def test_sqrt_surface_nan_on_half_the_space_is_an_error():
    data = fig3()
    data["body"]["position"] = [0.0, 0.0, 2.0]
    data["obstacle"] = [{"type": "implicit", "phi": "z - sqrt(x)"}]
    findings = check_scene(scene_from_dict(data))
    assert "surface_not_finite" in kinds(findings, "error")
    assert any(f.field == "obstacle[0].phi" for f in findings)


def test_dt_longer_than_duration_is_an_error():
    scene = scene_from_dict(fig3(dt=0.2, duration=0.05))
    found = [f for f in check_scene(scene) if f.kind == "dt_above_duration"]
    assert found and found[0].severity == "error" and found[0].field == "scene.dt"


def test_axial_ratio_1e9_far_above_the_stable_step_is_an_error():
    data = fig3()
    data["legs"]["axial_ratio"] = 1e9
    found = [f for f in check_scene(scene_from_dict(data)) if f.kind == "dt_unstable"]
    assert found and found[0].severity == "error" and found[0].value > 100


def test_zero_gravity_is_valid():
    scene = scene_from_dict(fig3(gravity=[0.0, 0.0, 0.0]))
    assert kinds(check_scene(scene), "error") == set()
    traj = simulate(scene)
    assert np.all(np.isfinite(traj.position)) and np.all(np.isfinite(traj.force))


# -- tracebacks or hangs ------------------------------------------------------------
def test_incomplete_formula_names_the_field():
    data = fig3()
    data["obstacle"] = [{"type": "implicit", "phi": "x**2 + "}]
    message = load_error(data)
    assert "`obstacle[0].phi`" in message and "'x**2 + '" in message


def test_power_tower_formula_is_rejected_at_once():
    data = fig3()
    data["obstacle"] = [{"type": "implicit", "phi": "z - 9**9**9"}]
    started = time.perf_counter()
    message = load_error(data)
    assert time.perf_counter() - started < 1.0
    assert "`obstacle[0].phi`" in message and "exponent" in message


def test_scalar_inertia_names_the_field():
    data = fig3()
    data["body"]["inertia"] = 1.25
    message = load_error(data)
    assert "`body.inertia`" in message and "1.25" in message and "3 or 9" in message


def test_wrongly_sized_terrain_heights_names_the_field():
    data = fig3()
    data["obstacle"] = [{"type": "terrain", "x": [0.0, 1, 2, 3], "y": [0.0, 1, 2, 3],
                         "heights": [0.0, 1.0]}]
    message = load_error(data)
    assert "`obstacle[0].heights`" in message and "16" in message


def test_every_problem_of_a_file_is_reported_at_once_with_did_you_mean():
    data = fig3(mu=-1.0, methd="paper")
    data["body"]["inertia"] = 1.25
    data["legs"]["M_beta"]["type"] = "linaer"
    data["obstacle"][0]["radius"] = "big"
    with pytest.raises(SceneError) as info:
        scene_from_dict(data, "bad.toml")
    problems = info.value.problems
    assert len(problems) == 5, problems
    text = str(info.value)
    for needle in ("`scene.mu`", "`scene.methd` (did you mean 'method'?)", "`body.inertia`",
                   "(did you mean 'linear'?)", "`obstacle[0].radius`"):
        assert needle in text, text


# -- API ------------------------------------------------------------------------------
def test_linear_negative_stiffness_is_rejected():
    with pytest.raises(ValueError, match="`stiffness` must be non-negative, got -5.0"):
        Linear(-5)


def test_smooth_must_be_a_bool():
    with pytest.raises(TypeError, match="`smooth` must be True or False, got 'yes'"):
        Linear(5.0, smooth="yes")


def test_adaptive_simulate_rejects_negative_eps():
    with pytest.raises(ValueError, match="`eps` must be positive"):
        simulate(scene_from_dict(fig3()), adaptive=True, eps=-1)


def test_piecewise_linear_rejects_2d_knots():
    with pytest.raises(ValueError, match=r"`x` must have shape \(n,\)"):
        PiecewiseLinear(np.zeros((2, 2)), np.ones((2, 2)))


def test_numpy_float32_mu_is_accepted():
    scene = load_scene(FIG3)
    assert Scene(scene.body, scene.legs, scene.obstacles, mu=np.float32(0.3)).mu == \
        pytest.approx(0.3, rel=1e-7)


def test_strut_force_at_the_hinge_is_a_clear_error():
    leg = load_scene(FIG3).legs[0]
    with pytest.raises(ValueError, match="`r` .* is at the hinge"):
        leg.force(leg.hinge)


def test_simulate_accepts_a_scene_path(tmp_path):
    path = tmp_path / "short.toml"
    path.write_text(FIG3.read_text().replace("duration = 0.6", "duration = 0.01"))
    traj = simulate(str(path))
    assert traj.t[-1] == pytest.approx(0.01)


# -- the check command --------------------------------------------------------------
def test_check_command_exit_codes(tmp_path, capsys):
    assert main(["check", str(FIG3)]) == 0
    bad = tmp_path / "bad.toml"
    bad.write_text(FIG3.read_text().replace("mass = 50.0", "mass = -50.0")
                   .replace("radius = 0.5 ", "radus = 0.5 "))
    assert main(["check", str(bad)]) == 1
    err = capsys.readouterr().err
    assert "`body.mass`" in err and "did you mean 'radius'" in err
    fast = tmp_path / "fast.toml"
    fast.write_text(FIG3.read_text().replace("[0.0, 0.0, -0.5]", "[0.0, 0.0, -100.0]"))
    assert main(["check", str(fast)]) == 0
    assert "warning" in capsys.readouterr().out
    assert main(["check", str(fast), "--strict"]) == 1


# -- the shared validators --------------------------------------------------------------
@pytest.mark.parametrize("call, error, needle", [
    (lambda: real("dt", "0.1"), TypeError, "`dt` must be a real number, got '0.1' of type str"),
    (lambda: real("dt", True), TypeError, "`dt` must be a real number"),
    (lambda: real("dt", float("nan")), ValueError, "`dt` must be a finite number, got nan"),
    (lambda: real("dt", 0.0, positive=True, unit="s"), ValueError,
     "`dt` must be positive s, got 0.0; give a value > 0"),
    (lambda: real("mu", -0.1, nonnegative=True), ValueError, "give a value >= 0"),
    (lambda: integer("count", 2.0), TypeError, "`count` must be an integer, got 2.0"),
    (lambda: integer("count", 0, minimum=1), ValueError, "`count` must be an integer >= 1, got 0"),
    (lambda: vector("gravity", [0, 0], (3,)), ValueError, "`gravity` must have shape (3,), got "
     "shape (2,)"),
    (lambda: vector("gravity", "down", (3,)), TypeError, "`gravity` must be an array"),
    (lambda: vector("gravity", [0, float("inf"), 0], (3,)), ValueError, "must be finite"),
    (lambda: choice("method", "implict", ("paper", "robust", "implicit")), ValueError,
     "did you mean 'implicit'?"),
    (lambda: boolean("smooth", 1), TypeError, "`smooth` must be True or False, got 1"),
    (lambda: direction("en", [0.0, 0.0, 0.0]), ValueError, "`en` must be a non-zero direction"),
    (lambda: validate_path("path", 3), TypeError, "`path` must be a file path"),
    (lambda: validate_path("path", "no/such.toml", must_exist=True), FileNotFoundError,
     "'no/such.toml' does not exist"),
])
def test_validators_name_the_argument_value_and_fix(call, error, needle):
    with pytest.raises(error) as info:
        call()
    assert needle in str(info.value), str(info.value)


def test_validators_accept_numpy_scalars_and_normalise_huge_directions():
    assert real("mu", np.float32(0.25)) == 0.25 and integer("count", np.int64(3)) == 3
    assert boolean("smooth", np.bool_(True)) is True
    np.testing.assert_allclose(direction("en", [1e300, 0.0, 1e300]),
                               [2 ** -0.5, 0.0, 2 ** -0.5], rtol=1e-15)
    assert vector("x", [[1.0, 2.0]], (1, None)).shape == (1, 2)


def _lander_slope():
    return tomllib.loads((ROOT / "studies" / "lander_slope.toml").read_text())


def test_rate_width_reaches_the_smooth_curve():
    data = _lander_slope()
    data["legs"]["S"].update(smooth=True, rate_width=1e-5, kink_width=2e-4)
    scene = scene_from_dict(data, "smooth.toml")
    S = next(el.curve for el in scene.legs[0].elements if el.name == "S")
    assert (S.smooth, S.rate_width, S.kink_width) == (True, 1e-5, 2e-4)
    assert S.unloading.smooth and S.unloading.kink_width == 2e-4


@pytest.mark.parametrize("width", ["rate_width", "kink_width"])
def test_a_width_without_smooth_is_an_error_not_ignored(width):
    data = _lander_slope()
    data["legs"]["S"][width] = 1e-5
    text = load_error(data)
    assert f"`legs.S.{width}` acts only on a smooth curve" in text and "smooth = true" in text


def test_a_non_positive_rate_width_is_rejected():
    data = _lander_slope()
    data["legs"]["S"].update(smooth=True, rate_width=0.0)
    assert "`legs.S.rate_width` = 0.0 is invalid; allowed: a positive number" in load_error(data)
