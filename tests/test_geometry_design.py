"""Leg geometry as design variables (docs/design-geometry.md).

Both design problems: the geometry entries of ``p`` and the scenarios' initial
states follow θ, the legs' own checks bound the geometry, the practical limits
are named rows, and AD agrees with central differences with geometry variables.
"""
from __future__ import annotations

import copy
import math

import numpy as np
import pytest

from symcushion.compiled.codegen import find_compiler
from symcushion.envelope.cases import initial_states
from symcushion.model.obstacles import closest_obstacle
from symcushion.design.optimise import study_from_dict
from symcushion.design.optimise.study import _place
from symcushion.design.robust import EnvelopeDesign
from symcushion.design.robust.study import robust_study_from_dict
from symcushion.model.scene import read_toml
from symcushion.scheme.touchdown import build_model, initial_state
from symcushion.layout.vectors import state_layout

from test_robust import TINY

needs_cc = pytest.mark.skipif(find_compiler() is None, reason="needs a C compiler")

GEOMETRY = [dict(quantity="hinge_radius", lower=0.4, upper=0.7),
            dict(quantity="length", lower=0.6, upper=1.0),
            dict(quantity="splay", lower_deg=10.0, upper_deg=30.0)]
PRACTICAL = dict(footprint_radius=1.0, leg_mass=3000.0, ground_clearance=0.3)


def lander(geometry=GEOMETRY, practical=PRACTICAL, duration=0.12, footpad=None, scenarios=2):
    """The lander design study, shortened: two touchdowns of 0.12 s."""
    data = read_toml("studies/optimise_lander.toml", "study")
    data["scene"]["duration"] = duration
    data["scenario"] = data["scenario"][:scenarios]
    if footpad is not None:
        data["legs"]["footpad"] = footpad
    data["design"]["geometry"] = copy.deepcopy(geometry)
    if practical:
        data["design"]["limits"] = dict(practical)
    return study_from_dict(data, "lander.toml").problem


@pytest.fixture(scope="module")
def problem():
    return lander()


def moved(pb, radius=0.6, length=0.9, splay_deg=25.0):
    theta = pb.initial.copy()
    theta[pb.var_names.index("hinge_radius")] = radius
    theta[pb.var_names.index("length")] = length
    theta[pb.var_names.index("splay")] = math.radians(splay_deg)
    return theta


def test_geometry_entries_of_p_are_those_of_the_rebuilt_legs(problem):
    theta = moved(problem)
    scene = problem.scene_at(theta, problem.scenarios[0].scene)
    rebuilt = build_model(scene).default_p
    n = problem.models[0].params.n_leg_params
    assert np.allclose(problem.step_params(0, theta)[n:], rebuilt[n:], rtol=0, atol=1e-15)
    for j, leg in enumerate(scene.legs):
        G = problem.leg_geometry(theta, j)
        start = problem.scenarios[0].scene.legs[j]
        # e₀ and e_n turn together: the hinge's γ₀ and orientation sign do not change
        assert np.dot(G["e0"], G["en"]) == pytest.approx(np.dot(start.e0, start.en), abs=1e-15)
        assert math.degrees(math.acos(-G["e0"][2])) == pytest.approx(25.0, abs=1e-12)
        assert np.hypot(*G["hinge"][:2]) == pytest.approx(0.6, abs=1e-15)
        assert leg.length == 0.9


def test_without_geometry_variables_p_and_x0_are_the_constants_they_were(problem):
    curves_only = lander(geometry=[], practical=None)
    assert not curves_only.designs_geometry
    model = curves_only.models[0]
    tail = curves_only._full_p_tail(None, model)
    assert np.array_equal(np.asarray(tail).ravel(), model.default_p[model.params.n_leg_params:])
    s = curves_only.scenarios[0]
    assert np.array_equal(np.asarray(curves_only._placed_state(s.x0, None, s.scene, 0.001, None)
                                     ).ravel(), s.x0)


@pytest.mark.parametrize("footpad", [None, 0.05])
def test_the_body_is_placed_at_the_clearance_for_every_geometry(footpad):
    geometry = GEOMETRY + ([dict(quantity="footpad", lower=0.0, upper=0.1)] if footpad else [])
    pb = lander(geometry=geometry, footpad=footpad)
    theta = moved(pb, radius=0.65, length=0.7, splay_deg=12.0)
    if footpad:
        theta[pb.var_names.index("footpad")] = 0.08
    for k, s in enumerate(pb.scenarios):
        x0 = pb.scenario_state(k, theta)
        scene = pb.scene_at(theta, s.scene)
        xl = state_layout(len(scene.legs))
        body = copy.copy(scene.body)
        body.position = xl.get(s.x0, "position")
        body.attitude = xl.get(s.x0, "attitude")
        body.velocity = xl.get(s.x0, "velocity")
        body.position = _place(scene, body, s.clearance)
        expected = initial_state(scene.with_(body=body))
        assert np.allclose(x0, expected, rtol=0, atol=1e-12)
        lowest = min(float(closest_obstacle(scene.obstacles, xl.get(x0, "foot", j),
                                            leg.footpad)[0]) for j, leg in enumerate(scene.legs))
        assert lowest == pytest.approx(s.clearance, abs=1e-12)


def test_practical_limits_are_named_rows_with_their_values(problem):
    kinds = {b.kind for b in problem.blocks}
    assert {"footprint", "leg_mass", "ground_clearance"} <= kinds
    theta = moved(problem, radius=0.7, length=1.0, splay_deg=30.0)   # foot 1.2 m out
    theta[:11] *= 1.5                                   # crush force 3600 N at 0.3 m
    _, g = problem.fg(problem.scaled(theta, t=1.0))
    rows = [b for b in problem.blocks if b.kind == "footprint"]
    G = problem.leg_geometry(theta, 0)
    foot = G["hinge"] + G["length"] * G["e0"]
    assert g[rows[0].start] * rows[0].scale == pytest.approx(np.hypot(*foot[:2]), abs=1e-14)
    clear = [b for b in problem.blocks if b.kind == "ground_clearance"][0]
    assert g[clear.start] * clear.scale == pytest.approx((1.0 - 0.25) * math.cos(math.radians(30)),
                                                         abs=1e-14)
    msgs = [v for v in problem.evaluate(theta).violations if "practical limit" in v]
    assert any("`footprint`" in m and "leg 0" in m for m in msgs)
    assert any("`leg_mass`" in m for m in msgs)          # 1.0 m × 3600 N > 3000 N·m
    assert problem.geometry_report(theta)["leg0"]["foot_radius"] == pytest.approx(
        np.hypot(*foot[:2]))


def test_gradient_with_geometry_matches_central_differences(problem):
    for theta in (problem.initial, moved(problem)):
        check = problem.check_gradient(theta)
        assert check["relative"] < 1e-7, check
        assert check["worst_row"] < 1e-5, check
        assert check["objective"] < 1e-9, check


def test_a_short_solve_moves_the_geometry_and_keeps_the_gradient():
    pb = lander(scenarios=1, duration=0.1)
    result = pb.solve(ipopt={"max_iter": 6})
    assert result.iterations >= 1
    assert not np.allclose(result.theta[-3:], pb.initial[-3:])
    check = pb.check_gradient(result.theta)
    assert check["relative"] < 1e-7, check
    out = result.to_dict()
    assert set(out["geometry"]["end"]["leg0"]) >= {"hinge_radius", "splay_deg", "foot_radius"}


@pytest.mark.parametrize("edit, words", [
    (dict(quantity="length", lower=0.2, upper=1.0), "not above the stroke limit"),
    (dict(quantity="splay", lower_deg=10.0, upper_deg=85.0), "within ±80°"),
    (dict(quantity="footpad", lower=0.0, upper=0.1), "give some leg a `footpad` > 0"),
    (dict(quantity="hinge_radius", lower=0.6, upper=0.7), "outside its bounds"),
    (dict(quantity="stance", lower=0.6, upper=0.7), "stance"),
    (dict(quantity="length", lower=0.6, upper=1.0, legs=[7]), "leg indices"),
])
def test_bad_geometry_variables_are_refused_with_the_fix(edit, words):
    with pytest.raises(ValueError, match=words.replace("(", r"\(").replace("±", "±")):
        lander(geometry=[edit], practical=None)


def test_shared_geometry_needs_equal_legs_and_splay_a_radial_rest_direction():
    data = read_toml("studies/optimise_lander.toml", "study")
    data["scene"]["duration"] = 0.05
    data["design"]["geometry"] = [dict(quantity="splay", lower_deg=0.0, upper_deg=30.0)]
    data["legs"]["e0"] = [0.3, 0.1, -0.9486832980505138]
    with pytest.raises(ValueError, match="not in the leg's radial plane"):
        study_from_dict(data, "x.toml")


# ---------------------------------------------------------------------------
# design for the envelope
# ---------------------------------------------------------------------------
CONDITIONS = dict(vertical_speed=np.array([2.0, 2.8, 1.6]),
                  horizontal_speed=np.array([0.5, 0.0, 1.0]),
                  heading_deg=np.array([0.0, 90.0, 200.0]), slope_deg=np.array([3.0, 0.0, 5.0]),
                  yaw_deg=np.zeros(3), tilt_deg=np.array([1.0, 0.0, -2.0]),
                  tilt_azimuth_deg=np.array([0.0, 45.0, 90.0]))


@pytest.fixture(scope="module")
def envelope_design(tmp_path_factory):
    d = copy.deepcopy(TINY)
    d["design"]["geometry"] = [dict(quantity="hinge_radius", lower=0.3, upper=0.6),
                               dict(quantity="splay", lower_deg=-5.0, upper_deg=20.0),
                               dict(quantity="length", lower=0.5, upper=0.8)]
    d["design"]["limits"] = dict(footprint_radius=0.8, ground_clearance=0.2)
    study = robust_study_from_dict(d, "tiny.toml")
    cache = tmp_path_factory.mktemp("build")
    with_geometry = EnvelopeDesign(study.envelope, CONDITIONS, study.variables, horizon=0.3,
                                   geometry=study.geometry, practical=study.practical,
                                   threads=2, cache_dir=cache)
    curves = EnvelopeDesign(study.envelope, CONDITIONS, study.variables, horizon=0.3,
                            threads=2, cache_dir=cache)
    return study, with_geometry, curves


@needs_cc
def test_envelope_design_with_geometry_starts_where_the_curves_only_design_does(
        envelope_design):
    _, pb, curves = envelope_design
    assert np.allclose(pb.ratios(), curves.ratios(), rtol=1e-12, atol=1e-12)


@needs_cc
def test_envelope_cases_are_placed_for_the_design_geometry(envelope_design):
    study, pb, _ = envelope_design
    import casadi as ca
    theta = pb.initial.copy()
    theta[pb.var_names.index("hinge_radius")] = 0.5
    theta[pb.var_names.index("splay")] = math.radians(12.0)
    theta[pb.var_names.index("length")] = 0.7
    scene = pb.scene_at(theta, study.envelope.scene)
    expected, _ = initial_states(study.envelope.with_(scene=scene), CONDITIONS)
    for s in range(expected.shape[1]):
        x, _ = pb._design_map(pb.x0[:, s], pb.p0[:, s], theta / pb.scale)
        assert np.allclose(np.asarray(x).ravel(), expected[:, s], rtol=0, atol=1e-12)
    # the ratios of the rebuilt scene's own cases, without any design map
    rebuilt = EnvelopeDesign(study.envelope.with_(scene=scene), CONDITIONS, study.variables,
                             horizon=0.3, threads=2, cache_dir=pb.library.parents[1])
    assert np.allclose(pb.ratios(theta), rebuilt.ratios(theta[:2]), rtol=1e-9, atol=1e-10)
    del ca


@needs_cc
def test_envelope_gradient_with_geometry_at_the_start_and_after_a_short_solve(envelope_design):
    _, pb, _ = envelope_design
    result = pb.solve(ipopt={"max_iter": 4})
    for theta in (pb.initial, result.theta):
        check = pb.check_gradient(theta)
        assert check["relative"] < 1e-6, check
    assert result.geometry["end"]["leg0"]["hinge_radius"] > 0
    assert {r["kind"] for r in result.geometry["practical"]} == {"footprint", "ground_clearance"}



@needs_cc
def test_envelope_gradient_on_the_absorbers_with_memory(tmp_path):
    """The same design on the memory law (its scene-file default dampers included):
    AD equals central differences at the start and after a short solve. An element
    riding its elastic line across the loading curve's bend kept its set only to
    round-off, which switched the step's crush-onset kick on at random: 0.216 at
    the start before its set was kept exactly (docs/optimise.md)."""
    d = copy.deepcopy(TINY)
    d["scene"]["hysteresis"] = "memory"
    d["design"]["geometry"] = [dict(quantity="hinge_radius", lower=0.3, upper=0.6),
                               dict(quantity="splay", lower_deg=-5.0, upper_deg=20.0),
                               dict(quantity="length", lower=0.5, upper=0.8)]
    d["design"]["limits"] = dict(footprint_radius=0.8, ground_clearance=0.2)
    study = robust_study_from_dict(d, "tiny.toml")
    assert study.envelope.scene.legs[0].elements[0].curve.damping > 0
    pb = EnvelopeDesign(study.envelope, CONDITIONS, study.variables, horizon=0.3,
                        geometry=study.geometry, practical=study.practical, threads=2,
                        cache_dir=tmp_path)
    result = pb.solve(ipopt={"max_iter": 4})
    for theta in (pb.initial, result.theta):
        check = pb.check_gradient(theta)
        assert check["relative"] < 1e-6, check
        assert check["nonsmooth_rows"] == 0, check


def test_per_leg_geometry_variables_and_the_study_file_fields():
    pb = lander(geometry=[dict(quantity="length", lower=0.6, upper=1.0, shared=False,
                               legs=[0, 2]),
                          dict(quantity="splay", lower_deg=10.0, upper_deg=30.0)],
                practical=None)
    assert pb.var_names[-3:] == ["leg0.length", "leg2.length", "splay"]
    assert pb.upper[-1] == pytest.approx(math.radians(30.0), abs=1e-15)
    theta = pb.initial.copy()
    theta[-3] = 0.7
    assert [pb.leg_geometry(theta, j)["length"] for j in range(4)] == [0.7, 0.8, 0.8, 0.8]
    with pytest.raises(ValueError, match=r"missing field `design.geometry\[0\].lower`"):
        lander(geometry=[dict(quantity="splay", lower_degs=10.0, upper_deg=30.0)],
               practical=None)


@needs_cc
def test_compiled_rollouts_with_a_geometry_variable_equal_the_vm(tmp_path):
    """The compiled design path (``compile = true``) takes the geometry's x0 and p
    expressions with the rollouts: f, g and the Jacobian equal the VM's."""
    import casadi as ca
    from symcushion.design.compiled_nlp import COMPILE_FLAGS

    def absorber():
        data = read_toml("studies/absorber_1d.toml", "study")
        data["scene"]["duration"] = 0.05
        data["design"]["geometry"] = [dict(quantity="length", lower=0.3, upper=0.5)]
        return study_from_dict(data, "absorber.toml").problem

    problem, vm = absorber(), absorber()
    built = problem.use_compiled(tmp_path, cflags=("-O0",) + COMPILE_FLAGS[1:])
    theta = problem.initial.copy()
    theta[-1] = 0.49                                          # the foot 1 cm above the ground
    x = problem.scaled(theta)
    f_c, g_c = problem.fg(x)
    f_v, g_v = vm.fg(x)
    assert abs(f_c - f_v) <= 1e-10 * abs(f_v)
    assert np.linalg.norm(g_c - g_v) <= 1e-10 * np.linalg.norm(g_v)
    jac = [np.asarray(ca.Function("j", [nlp["x"]], [ca.jacobian(nlp["g"], nlp["x"])])(x))
           for nlp in (built.nlp, vm.nlp)]
    assert np.linalg.norm(jac[0][:, -2]) > 0                  # the length's column
    assert np.linalg.norm(jac[0] - jac[1]) <= 1e-10 * np.linalg.norm(jac[1])
