"""Design optimisation: the ideal absorber, exact gradients, clear errors."""
import json
from pathlib import Path

import numpy as np
import pytest

from symcushion.legs.characteristics import Linear, PiecewiseLinear
from symcushion.cli import main
from symcushion.model.obstacles import Plane
from symcushion.design.optimise import (DesignProblem, DesignVariable, Limits, Scenario,
    load_study, study_from_dict)
from symcushion.model.scene import Body, Scene, load_scene, symmetric_legs

ROOT = Path(__file__).resolve().parents[1]
ABSORBER = ROOT / "studies" / "absorber_1d.toml"
LANDER = ROOT / "studies" / "optimise_lander.toml"
#: The lander study's committed result (``python studies/optimise_lander.py``).
LANDER_RESULT = ROOT / "figures" / "optimise_lander.json"

#: The brief's bound on AD against central differences, relative.
GRADIENT_TOL = 1e-5
#: Required efficiency of the 1-D absorber, (v²/2s)/peak.
EFFICIENCY_MIN = 0.98


# ---------------------------------------------------------------------------
# canonical problems
# ---------------------------------------------------------------------------
def tripod_problem(duration=0.13):
    """Three legs splayed 15°, two drops (straight, and rolled with drift), no gravity.

    Frictionless and without gravity so that the body never rests on the
    legs: every output is a smooth function of the design between knots.
    """
    splay = np.deg2rad(15)
    xs = np.array([-0.2, -0.12, -0.06, -0.02, -0.005, 0.0])
    S = PiecewiseLinear(xs, 6000.0 * xs, unloading=Linear(100.0), tunable=True)
    legs = symmetric_legs(3, 0.3, -0.1, 0.5, (np.sin(splay), 0, -np.cos(splay)),
                          (-np.sin(np.deg2rad(30)), 0, -np.cos(np.deg2rad(30))),
                          S=S, M_beta=Linear(5e4), M_gamma=Linear(5e4))
    height = 0.1 + 0.5 * np.cos(splay) + 0.002
    scenarios = []
    roll = (np.cos(0.04), np.sin(0.04), 0, 0)           # 4.6° about x
    for name, velocity, attitude in [("straight", (0, 0, -2.0), (1, 0, 0, 0)),
                                     ("rolled", (0.3, 0, -2.0), roll)]:
        body = Body(mass=60.0, inertia=[3.0, 3.0, 4.0], position=[0, 0, height],
                    velocity=velocity, attitude=attitude)
        scene = Scene(body, legs, [Plane()], mu=0.0, dt=1e-3, duration=duration,
                      gravity=[0, 0, 0])
        scenarios.append(Scenario(name, scene))
    return DesignProblem(scenarios, [DesignVariable("S.f*", lower=-5e3, upper=0.0,
                                                    exclude=["S.f5"])],
                         Limits(stroke=0.1, beta=0.05, gamma=0.05, tilt=0.3, rebound_speed=0.5))


@pytest.fixture(scope="module")
def absorber():
    study = load_study(ABSORBER)
    return study, study.solve()


@pytest.fixture(scope="module")
def tripod():
    problem = tripod_problem()
    return problem, problem.solve()


# ---------------------------------------------------------------------------
# validation against the ideal absorber
# ---------------------------------------------------------------------------
def test_absorber_reaches_ideal_efficiency(absorber):
    study, result = absorber
    assert result.return_status == "Solve_Succeeded", result.message
    nominal = result.evaluation.scenarios["nominal"]
    # gravity is off in the study, so the ideal constant force gives v²/(2s) exactly
    assert nominal["ideal_peak_deceleration"] == pytest.approx(3.0 ** 2 / (2 * 0.25))
    assert result.efficiency >= EFFICIENCY_MIN, result.efficiency
    assert result.evaluation.feasible, result.evaluation.violations
    assert nominal["max_stroke"] <= 0.25 * (1 + 1e-6)
    assert 0.0 <= nominal["final_vertical_speed"] <= 0.1
    # the optimum is a plateau: every knot inside the stroke at the same force
    char = result.to_dict()["characteristic"]["leg0.S"]
    inside = [f for x, f in zip(char["x"], char["loading"]) if -0.25 <= x < 0]
    assert np.ptp(inside) < 1e-3 * abs(np.mean(inside))


@pytest.mark.parametrize("which", ["initial", "final"])
def test_absorber_gradient_matches_central_differences(absorber, which):
    study, result = absorber
    theta = result.theta0 if which == "initial" else result.theta
    check = study.problem.check_gradient(theta)
    assert check["relative"] <= GRADIENT_TOL, check
    assert check["objective"] <= GRADIENT_TOL, check
    assert check["worst_row"] <= GRADIENT_TOL, check


def test_tripod_optimum_and_gradients(tripod):
    problem, result = tripod
    assert result.success, result.message
    assert result.evaluation.feasible, result.evaluation.violations
    assert result.evaluation.objective < 0.9 * result.initial.objective
    # the worst case binds: the rolled drop uses the whole stroke
    assert result.evaluation.scenarios["rolled"]["max_stroke"] == pytest.approx(0.1, rel=1e-4)
    for theta in (result.theta0, result.theta):
        check = problem.check_gradient(theta)
        assert check["relative"] <= GRADIENT_TOL, check
        assert check["objective"] <= GRADIENT_TOL, check


@pytest.fixture(scope="module")
def lander():
    return load_study(LANDER).problem, json.loads(LANDER_RESULT.read_text())


@pytest.mark.parametrize("which", ["initial_design", "design"])
def test_lander_gradient_matches_central_differences(lander, which):
    """The full lander problem (4 legs, 4 touchdowns with μ = 0.5, 14 027
    rows) at Ipopt's starting design and at the committed optimum."""
    problem, result = lander
    theta = np.array([result[which][name] for name in problem.var_names])
    check = problem.check_gradient(theta)
    assert check["rows"] == problem.lbg.size + 1
    assert check["relative"] <= GRADIENT_TOL, check
    assert check["objective"] <= GRADIENT_TOL, check
    assert check["worst_row"] <= GRADIENT_TOL, check
    if which == "initial_design":
        assert check["nonsmooth_rows"] == 0, check
    else:
        # Ipopt's optimum sits within 1e-7 (scaled) of branch switches: at the
        # stop of the drift touchdown (its rows from t = 0.172 s on) and, with
        # the exact step from the quartic, in the vertical touchdown from
        # t = 0.046 s (where a foot changes branch); those rows jump inside the
        # difference interval and are left out above. The vertical switch is
        # within 1e-12 of the optimum (below), so whether a step of 1e-5
        # crosses it depends on the rollout's round-off, which differs between
        # builds of the libraries (a clean CI install did not cross it): the
        # drift rows always jump, the vertical ones may.
        assert "drift" in check["nonsmooth_scenarios"], check
        assert set(check["nonsmooth_scenarios"]) <= {"drift", "vertical"}, check
        # At a step of 1e-9 the drift touchdown's switch is out of reach and
        # its rows match AD. The vertical touchdown's switch is not: the
        # optimum sits on it to within 1e-12 along three of the twelve axes
        # (measured: its deceleration rows jump by 8.1 for a step of +1e-12
        # in the fifth scaled variable), so those rows jump at every step and
        # are left out;
        # the smooth rows match (5.8e-6 measured; at 1e-10 round-off reaches
        # 5.9e-5). Which side of a switch a 1e-9 step lands on depends on
        # the rollout's round-off.
        fine = problem.check_gradient(theta, step=1e-9)
        assert fine["relative"] <= GRADIENT_TOL, fine
        assert set(fine["nonsmooth_scenarios"]) <= {"vertical"}, fine


def test_lander_result_meets_every_limit_and_lowers_the_peak(lander):
    """The committed optimum, re-simulated now, still meets every limit in
    every touchdown and beats the hand design (guards the committed table)."""
    problem, result = lander
    theta = np.array([result["design"][name] for name in problem.var_names])
    ev = problem.evaluate(theta)
    assert ev.feasible, ev.violations
    assert ev.objective == pytest.approx(result["objective"], rel=1e-9)
    assert ev.objective < 0.8 * problem.evaluate(problem.initial).objective
    assert result["return_status"] == "Solve_Succeeded"


def test_result_json_has_the_reported_fields(absorber, tmp_path):
    _, result = absorber
    data = json.loads(result.save_json(tmp_path / "r.json").read_text())
    for key in ("efficiency", "return_status", "iterations", "seconds", "characteristic",
                "design", "history", "timings", "scenarios"):
        assert key in data, key
    assert data["iterations"] == len(data["history"]) - 1
    assert data["characteristic"]["leg0.S"]["x"][-1] == 0.0


def test_cli_optimise_writes_json(tmp_path, capsys):
    out = tmp_path / "cli.json"
    code = main(["optimise", str(ABSORBER), "--out", str(out), "--max-iter", "3"])
    text = capsys.readouterr().out
    assert "iter    3" in text and "wrote" in text
    assert code == 1                      # stopped early: not a success
    data = json.loads(out.read_text())
    assert data["return_status"] == "Maximum_Iterations_Exceeded"
    assert data["iterations"] == 3
    # the scene with the last design written in, which simulate takes as it stands
    scene = load_scene(tmp_path / "cli_designed.toml")
    assert scene.name == "absorber_1d_designed"
    curves = {el.name: el.curve for el in scene.legs[0].elements}
    for name, value in data["design"].items():
        element, param = name.split(".", 1)
        curve = curves[element]
        assert curve.param_values[curve.param_names.index(param)] == value, name
    assert main(["simulate", str(tmp_path / "cli_designed.toml"), "--out", str(tmp_path),
                 "--no-plots", "--no-estimate"]) == 0


# ---------------------------------------------------------------------------
# errors
# ---------------------------------------------------------------------------
def absorber_dict():
    import tomllib

    return tomllib.loads(ABSORBER.read_text())


@pytest.mark.parametrize("edit, expected", [
    (lambda d: d.update(desing={}), "unknown field(s) ['desing']"),
    (lambda d: d["study"].update(objective="min_force"), "`study.objective` = 'min_force'"),
    (lambda d: d["design"]["variables"][0].update(names="S.g*"), "match no tunable parameter"),
    (lambda d: d["design"]["variables"][0].update(lower=1.0), "`lower` = 1 > `upper` = 0"),
    (lambda d: d["design"]["variables"][0].update(upper=-6000.0), "outside its bounds"),
    (lambda d: d["limits"].update(stroke=-0.1), "`limits.stroke` = -0.1"),
    (lambda d: d.pop("design"), "missing field `design`"),
    (lambda d: d.update(scenario=[{"name": "a", "veloctiy": [0, 0, -1]}]),
     "unknown field(s) ['veloctiy'] in `scenario[0]`"),
    (lambda d: d["leg"][0]["S"].update(tunable=False), "mark a curve `tunable = true`"),
])
def test_bad_study_files_name_the_field(edit, expected):
    data = absorber_dict()
    edit(data)
    with pytest.raises(ValueError) as info:
        study_from_dict(data, "bad.toml")
    assert expected in str(info.value)
    assert str(info.value).startswith("bad.toml")


def test_cli_reports_bad_files_in_one_line(tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text(ABSORBER.read_text().replace("[limits]", "[limits]\nstrok = 0.2"))
    assert main(["optimise", str(bad)]) == 2
    err = capsys.readouterr().err
    assert "unknown field(s) ['strok'] in `limits`" in err
    assert main(["optimise", str(tmp_path / "missing.toml")]) == 2


def test_infeasible_design_names_constraint_and_scenario():
    study = load_study(ABSORBER)
    problem = study.problem
    soft = problem.initial * 0.5                  # half as stiff: runs out of stroke
    evaluation = problem.evaluate(soft)
    assert not evaluation.feasible
    assert any("scenario `nominal`" in v and "constraint `stroke`" in v and "limit ±0.25 m" in v
               for v in evaluation.violations), evaluation.violations
    steep = problem.initial.copy()
    steep[-1] = steep[-2] * 1.5                   # f14 below f13: loading curve falls
    messages = problem.evaluate(steep).violations
    assert any("leg0.S loading slope" in v for v in messages), messages


def test_infeasible_problem_is_reported_with_the_binding_constraint():
    data = absorber_dict()
    # 3 m/s in 1 cm of stroke needs 45 kN; the bounds allow 20 kN
    data["limits"]["stroke"] = 0.01
    data["solver"]["max_iter"] = 25
    study = study_from_dict(data, "tight.toml")
    result = study.solve()
    assert not result.success
    assert not result.evaluation.feasible
    text = result.message
    assert "infeasible" in text and "scenario `nominal`" in text
    assert "constraint `stroke`" in text or "constraint `sink_speed`" in text
