"""Design for the envelope: smooth margins, scenario selection, the NLP and the loop.

A small three-legged lander whose axial crush force is too weak for the
faster drops (stroke failures) is designed over a few scenarios with a short
horizon; its held-out Monte Carlo P(stable) must rise.
"""
from __future__ import annotations

import copy
import json
import math

import casadi as ca
import numpy as np
import pytest

from symcushion import envelope as ev
from symcushion.compiled.codegen import find_compiler
from symcushion.design.robust import CHECKS, EnvelopeDesign, saturate
from symcushion.design.robust.select import left_out, select_scenarios, worst_margin
from symcushion.design.robust.study import robust_study_from_dict, run_robust_study

needs_cc = pytest.mark.skipif(find_compiler() is None, reason="needs a C compiler")

#: A 100 kg body on three vertical legs whose crush plateau (1 kN) is too weak
#: for the faster drops: 3 legs × 1 kN × 0.2 m = 600 J against up to 450 J of
#: impact energy plus 196 J of gravity over the stroke.
TINY = {
    "study": {"name": "tiny_design"},
    "scene": {"mu": 0.5, "method": "robust", "dt": 2e-3, "duration": 1.0,
              "gravity": [0.0, 0.0, -9.81], "hysteresis": "sign"},
    "body": {"mass": 100.0, "inertia": [10.0, 10.0, 12.0]},
    "legs": {"count": 3, "radius": 0.4, "height": -0.1, "length": 0.6,
             "e0": [0.0, 0.0, -1.0], "en": [-0.5, 0.0, -0.8660254037844386],
             "S": {"type": "piecewise", "tunable": True, "x": [-0.3, -0.02, 0.0],
                   "f": [-1000.0, -1000.0, 0.0],
                   "unloading": {"type": "piecewise", "x": [-0.3, -0.01, 0.0],
                                 "f": [-300.0, -300.0, 0.0]}},
             "M_beta": {"type": "linear", "stiffness": 2e4},
             "M_gamma": {"type": "linear", "stiffness": 2e4}},
    "obstacle": [{"type": "plane"}],
    "sampling": {"n": 48, "seed": 5},
    "ranges": {"vertical_speed": [1.5, 3.0], "slope_deg": [0.0, 5.0]},
    "limits": {"stroke": 0.2, "deceleration": 80.0, "rebound_speed": 0.5,
               "rest_speed": False},
    "design": {"variables": [{"names": "S.f*", "exclude": ["S.f2"], "lower": -6000.0,
                              "upper": 0.0}]},
    "robust": {"pool": 32, "seed": 9, "scenarios": 4, "horizon": 0.5,
               "ipopt": {"max_iter": 40}},
}


# ---------------------------------------------------------------------------
# pieces
# ---------------------------------------------------------------------------
def test_saturate_is_the_identity_up_to_the_limit_and_levels_off():
    r = np.linspace(-1, 1, 11)
    assert np.array_equal(saturate(r), r)
    h = 1e-7
    slope = (saturate(1 + h, 3.0) - saturate(1 - h, 3.0)) / (2 * h)
    assert abs(slope - 1) < 1e-6                      # C¹ at r = 1
    assert saturate(1e6, 3.0) <= 3.0 and saturate(11.0, 3.0) > 2.99
    assert np.all(np.diff(saturate(np.linspace(0, 20, 200), 3.0)) > 0)



def test_an_element_off_its_bounds_keeps_its_set_exactly():
    """On the memory law the set moves only on a bound (A2), and off the bounds it is
    kept bit for bit: the step's crush-onset kick asks whether it moved, and a
    round-off move made the design's rollouts differ from their AD derivative."""
    from symcushion.legs import absorber
    from symcushion.legs.characteristics import PiecewiseLinear as Piecewise
    curve = Piecewise([-0.3, -0.02, 0.0], [-1000.0, -1000.0, 0.0], damping=10.0,
                      unloading=Piecewise([-0.3, -0.01, 0.0], [-300.0, -300.0, 0.0]))
    s = -0.0041853271
    for x in np.linspace(-0.0199, -0.011, 37):        # inside the band (A1), (A5)
        for rate in (None, (750.0, 10.0)):
            got = float(ca.evalf(absorber.next_set(curve, x, s, rate=rate)))
            assert got == s, (x, rate, got)
    crushed = float(ca.evalf(absorber.next_set(curve, -0.05, s)))
    assert crushed == pytest.approx(-0.05 + 1000.0 / 50000.0, rel=1e-12)


def test_select_scenarios_takes_failures_near_the_boundary_by_class():
    cls = np.array(["stable"] * 6 + ["tip_over"] * 4 + ["stroke"] * 2 + ["no_touchdown"])
    margins = np.array([0.5, 0.01, 0.2, 0.03, 0.9, 0.02,      # stable
                        -0.05, -3.0, -0.4, -0.2,              # tip-overs, one deep
                        -0.1, -3.0, 0.3])                     # strokes, one hopeless
    columns = {"class": cls, "margin_tip_over": margins,
               "margin_stroke": np.ones(cls.size)}
    idx = select_scenarios(columns, 5, fail_share=0.6)
    # 3 failures (2 tip-overs, 1 stroke: the counts' proportion), closest first,
    # then the 2 stable cases with the smallest margins
    assert list(idx) == [1, 5, 6, 9, 10]
    every = select_scenarios(columns, 13, fail_share=1.0)
    assert 7 in every                 # a tip-over of any depth: its energy margin can move
    assert 11 not in every            # a stroke failure 300 % over its limit: left out
    assert left_out(columns) == {"stroke": 1}
    assert np.array_equal(worst_margin(columns), np.minimum(margins, 1.0))
    with pytest.raises(ValueError, match="`n`"):
        select_scenarios(columns, 0)
    with pytest.raises(ValueError, match="`fail_share`"):
        select_scenarios(columns, 3, fail_share=1.5)


@pytest.mark.parametrize("path, value, words", [
    ("robust.seed", 5, "equals `sampling.seed`"),
    ("robust.risk", "mean", "robust.risk"),
    ("robust.alpha", 1.0, "robust.alpha"),
    ("robust.saturation", 1.0, "robust.saturation"),
    ("robust.scenario", 3, "unknown field"),
    ("design", None, "no `[design]` table"),
])
def test_bad_design_study_files_name_the_field(path, value, words):
    data = copy.deepcopy(TINY)
    head, _, key = path.rpartition(".")
    target = data[head] if head else data
    if value is None:
        del target[key]
    else:
        target[key] = value
    with pytest.raises(ValueError) as err:
        robust_study_from_dict(data, "bad.toml")
    assert words in str(err.value) and "bad.toml" in str(err.value), str(err.value)


def test_apply_design_names_unknown_parameters():
    study = robust_study_from_dict(TINY, "tiny.toml").envelope
    p = ev.case_params(study.scene, np.zeros(1), np.array([[0.0], [0.0], [-9.81]]))
    with pytest.raises(ValueError, match="`design` names 'S.k'"):
        ev.apply_design(study.scene, p, {"S.k": 1.0})
    with pytest.raises(ValueError, match="finite"):
        ev.apply_design(study.scene, p, {"S.f0": math.nan})
    q = ev.apply_design(study.scene, p, {"S.f0": -5.0, "leg1.S.f1": -7.0})
    assert np.count_nonzero(q == -5.0) == 3 and np.count_nonzero(q == -7.0) == 1


# ---------------------------------------------------------------------------
# compiled: margins, the NLP and the loop
# ---------------------------------------------------------------------------
@pytest.fixture(scope="module")
def run(tmp_path_factory):
    study = robust_study_from_dict(TINY, "tiny.toml")
    out = tmp_path_factory.mktemp("design")
    cache = tmp_path_factory.mktemp("build")
    result = run_robust_study(study, out, threads=2, check_gradient=True, cache_dir=cache,
                              progress=False)
    result["cache"] = cache                     # the libraries built, for tests that reuse them
    return result, out


@needs_cc
def test_margins_bound_the_envelope_extrema_from_above(run):
    """KS ratios lie between the running maxima and ln(K)/ρ above them."""
    run, _ = run
    problem, pool = run["problem"], run["pool"]
    R = problem.ratios()
    study = problem.study.with_(scene=problem.scene.with_(duration=problem.horizon))
    cond = {k: v[run["indices"]] for k, v in pool.conditions.items()}
    c = ev.evaluate(study, cond, cache_dir=None)
    lim = study.limits
    exact = {"stroke": c["max_stroke"] / lim.stroke,
             "deceleration": c["peak_decel"] / lim.deceleration,
             "rebound": c["rebound_speed"] / lim.rebound_speed}
    samples = problem.steps * 2 * len(problem.legs)       # steps × (±) × legs
    slack = math.log(samples) / 200.0
    for name, value in exact.items():
        r = R[CHECKS.index(name)]
        assert np.all(r >= value - 1e-9), (name, r, value)
        assert np.all(r <= value + slack), (name, r, value)


@needs_cc
def test_the_at_rest_margin_is_the_mean_motion_over_the_window(tmp_path):
    """The 'moving' ratio is the mean of (|v| + |ω|·reach)/rest_speed over the last
    REST_WINDOW of the horizon: checked against the rollout's states on the VM."""
    from symcushion.layout.vectors import state_layout
    from symcushion.design.robust.evaluate import build_margins
    from symcushion.design.robust.margins import REST_WINDOW
    from symcushion.scheme.touchdown import build_model
    import casadi as ca

    data = copy.deepcopy(TINY)
    data["limits"]["rest_speed"] = 0.05
    study = robust_study_from_dict(data, "tiny.toml").envelope
    scene = study.scene.with_(duration=0.4)
    model = build_model(scene)
    cond = {**{k: np.zeros(3) for k in ev.VARIABLES}, "mu": np.full(3, 0.5),
            "vertical_speed": np.array([1.5, 2.0, 3.0]), "slope_deg": np.array([0.0, 2.0, 5.0])}
    x0, gravity = ev.initial_states(study, cond)
    p = ev.case_params(scene, cond["mu"], gravity)
    library, _ = build_margins(model, scene.steps, {"moving": 0.05}, np.zeros((model.np, 0)),
                               sharpness=200.0, reach=ev.reach(scene), cache_dir=tmp_path,
                               name="rest")
    f = ca.external("touchdown_margins", str(library))
    xl = state_layout(len(scene.legs))
    window = int(round(REST_WINDOW / scene.dt))
    for i in range(3):
        r = np.asarray(f(x0[:, i], p[:, i], np.zeros(0), scene.dt)).ravel()
        X = np.asarray(model.rollout(scene.steps)(x0[:, i], p[:, i], scene.dt)[0])
        motion = (np.linalg.norm(xl.get(X, "velocity"), axis=0)
                  + np.linalg.norm(xl.get(X, "angular_velocity"), axis=0) * ev.reach(scene))
        expected = motion[-window:].mean() / 0.05
        assert abs(r[CHECKS.index("moving")] - expected) <= 1e-9 * max(1.0, expected)
        assert expected > 0.1                       # 0.4 s after touchdown it still moves
        assert np.all(np.delete(r, CHECKS.index("moving")) == 0)


@needs_cc
def test_the_design_converges_and_the_gradient_check_passes(run):
    run, _ = run
    res = run["result"]
    assert res.success, res.return_status
    assert res.objective < res.objective_start - 0.05
    assert res.scenarios_within() > res.scenarios_within("start")
    for where in ("start", "optimum"):
        g = run["gradient"][where]
        assert g["relative"] < 1e-5, (where, g)
        assert g["worst_row"] < 1e-4, (where, g)
        assert g["passed"] is True
    # the crush plateau rises: the start's stroke failures are bought back
    assert res.design["S.f1"] < -1000.0


@needs_cc
def test_held_out_monte_carlo_p_stable_improves(run):
    run, _ = run
    before, after = run["before"].p_stable(), run["after"].p_stable()
    assert run["before"].study.seed != run["study"].pool_seed
    assert after["stable"] > before["stable"] + 5, (before, after)
    assert run["after"].counts()["stroke"] < run["before"].counts()["stroke"]


@needs_cc
def test_the_result_directory_is_complete(run):
    run, out = run
    data = json.loads((out / "result.json").read_text())
    assert data["return_status"] == run["result"].return_status
    assert data["after"]["p_stable"]["p"] == run["after"].p_stable()["p"]
    assert set(data["multipliers"]) == {"scenarios", "checks", "bounds", "shapes"}
    rows = (out / "scenarios.csv").read_text().splitlines()
    assert len(rows) == 1 + len(run["indices"])
    for name in ("before_after.png", "curves.png", "before/cases.csv", "after/summary.json"):
        assert (out / name).is_file(), name


@needs_cc
def test_bad_design_arguments(run):
    run, _ = run
    problem = run["problem"]
    cond = {k: v[:2] for k, v in run["pool"].conditions.items()}
    with pytest.raises(ValueError, match="`risk`"):
        EnvelopeDesign(problem.study, cond, run["study"].variables, risk="mean")
    with pytest.raises(ValueError, match="`alpha`"):
        EnvelopeDesign(problem.study, cond, run["study"].variables, alpha=1.0)
    with pytest.raises(ValueError, match="one common, non-zero length"):
        EnvelopeDesign(problem.study, {"vertical_speed": [1.0, 2.0], "slope_deg": [1.0]},
                       run["study"].variables)


@needs_cc
def test_dask_evaluation_equals_threads(run):
    """The scenarios as Dask tasks (a local cluster of two worker processes) give the
    threaded path's ratios and Jacobian bit for bit, and Ipopt's first iterates."""
    distributed = pytest.importorskip("distributed")
    import casadi as ca

    run, _ = run
    problem = run["problem"]
    cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                       dashboard_address=None, silence_logs=40)
    client = distributed.Client(cluster)
    try:
        cond = {k: v[run["indices"]] for k, v in run["pool"].conditions.items()}
        on_dask = EnvelopeDesign(problem.study, cond, run["study"].variables,
                                 names=problem.names, horizon=problem.horizon, client=client,
                                 cache_dir=problem.library.parents[1])
        theta = 0.5 * (problem.initial + run["result"].theta)
        assert np.array_equal(on_dask.ratios(theta), problem.ratios(theta))
        x = problem.scaled(theta)
        jac = [np.asarray(ca.Function("j", [p.nlp["x"]],
                                      [ca.jacobian(p.nlp["g"], p.nlp["x"])])(x))
               for p in (problem, on_dask)]
        assert np.array_equal(jac[0], jac[1])
        a = problem.solve(ipopt={"max_iter": 3})
        b = on_dask.solve(ipopt={"max_iter": 3})
        assert np.allclose(a.theta, b.theta, rtol=1e-12, atol=0)
    finally:
        client.close()
        cluster.close()


def test_the_run_says_which_failures_the_scenarios_stand_for():
    from symcushion.design.robust.study import _representation
    cls = np.array(["stable", "tip_over", "tip_over", "rebound", "rebound", "no_touchdown"])
    columns = {"class": cls, "margin_tip_over": np.array([0.2, -5.0, -0.1, 0.5, 0.5, 0.0]),
               "margin_rebound": np.array([0.3, 0.5, 0.5, -0.2, -2.5, 0.0])}
    lines = _representation(columns, -1.0)
    assert lines[0] == "pool failures: rebound 2, tip_over 2"
    assert "every depth" in lines[1] and "tip_over" in lines[1]
    assert lines[2].startswith("left out (worst margin below -1") and "rebound 1" in lines[2]
    assert "robust.worst_margin" in lines[2]
    calm = {"class": np.array(["stable"]), "margin_tip_over": np.array([0.4])}
    assert "no failure" in _representation(calm, -1.0)[0]


def test_tip_energy_samples_fade_past_the_tilt_limit():
    from symcushion.design.robust.margins import TIP_FADED, tip_energy
    limits = {"tip_energy": 0.1, "tip_over": np.radians(35.0)}
    surplus = ca.DM([0.05, -0.2])
    upright = np.asarray(ca.evalf(tip_energy(surplus, 0.0, limits))).ravel()
    np.testing.assert_allclose(upright, [1.5, -1.0], rtol=1e-12)
    lying = np.asarray(ca.evalf(tip_energy(surplus, 1.0, limits))).ravel()  # 90° tilt
    np.testing.assert_allclose(lying, TIP_FADED, atol=1e-9)
    assert float(ca.evalf(tip_energy(ca.DM(0, 1), 0.0, limits))) == 0.0
    assert float(ca.evalf(tip_energy(surplus, 0.0, {"tip_over": 0.5})[0])) == 0.0


@needs_cc
def test_the_outer_loop_keeps_the_round_with_the_best_held_out_p_stable(tmp_path):
    """Rounds re-select scenarios at the last optimum; the loop stops when P stops rising."""
    data = copy.deepcopy(TINY)
    data["robust"].update(rounds=2, check=32, ipopt={"max_iter": 15})
    study = robust_study_from_dict(data, "tiny.toml")
    assert study.check_seed == 10                      # the pool's seed + 1
    run = run_robust_study(study, None, threads=2, verify=False, cache_dir=tmp_path,
                           progress=False)
    loop = run["rounds"]
    assert loop is not None and 1 <= len(loop["rounds"]) <= 2
    p = [r["held_out"]["p"] for r in loop["rounds"]]
    start = loop["start"]["p"]
    assert p[0] > start                                 # the first round helps here
    kept = max(range(len(p)), key=lambda k: p[k])
    assert run["result"].design == loop["rounds"][kept]["design"]
    if len(p) == 2 and p[1] > p[0]:
        assert run["result"].objective_start == pytest.approx(
            loop["rounds"][1]["risk_start"])            # round 2 started from round 1's optimum
    with pytest.raises(ValueError, match="check_seed"):
        robust_study_from_dict(dict(data, robust=dict(data["robust"], check_seed=9)), "x")


def test_with_the_energy_check_the_tilt_only_gates_it():
    from symcushion.design.robust.risk import design_checks
    limits = dict(tip_over=0.6, tip_energy=0.1, stroke=0.25, beta=None, gamma=None,
                  deceleration=80.0, rebound=0.5, moving=0.05)
    assert design_checks(limits) == ["tip_energy", "stroke", "deceleration", "rebound",
                                     "moving"]
    assert design_checks(dict(limits, tip_energy=None))[0] == "tip_over"


def test_a_tipped_lander_fades_every_check_but_the_energy_one():
    """Past the tilt limit the samples go to TIP_FADED; upright they are untouched."""
    from symcushion.design.robust.margins import TIP_FADED, upright
    tilt = np.radians(35.0)
    assert float(upright(0.0, tilt)) == pytest.approx(1.0, abs=1e-12)
    assert float(upright(1 - np.cos(tilt), tilt)) == pytest.approx(0.5, abs=1e-12)
    assert float(upright(1.0, tilt)) == pytest.approx(0.0, abs=1e-12)    # lying at 90°
    lying = float(upright(1.0, tilt))
    assert lying * 2.5 + (1 - lying) * TIP_FADED == pytest.approx(TIP_FADED, abs=1e-9)


@needs_cc
def test_the_design_writes_a_study_that_runs_its_optimum(run):
    """``designed.toml``: the study with the optimum written in runs the verification's
    classes and strokes again (its scene named as the study's, so the library is reused)."""
    import tomllib

    run, out = run
    data = tomllib.loads((out / "designed.toml").read_text())
    assert "design" not in data and "robust" not in data
    assert data["study"]["name"] == "tiny_design_designed"
    data["scene"]["name"] = run["after"].study.scene.name
    again = ev.run_envelope(ev.study_from_dict(data, "designed.toml"), progress=False,
                            plots=False, cache_dir=run["cache"], threads=2)
    assert list(again.columns["class"]) == list(run["after"].columns["class"])
    np.testing.assert_allclose(again.columns["max_stroke"], run["after"].columns["max_stroke"],
                               rtol=1e-12, atol=0)


@needs_cc
def test_simulate_case_runs_the_envelope_s_touchdown(run):
    """``simulate STUDY --case N`` (``case_scene``) runs case N as the envelope ran it."""
    from symcushion.envelope.cases import case_scene
    from symcushion.run.driver import simulate

    before = run[0]["before"]
    for case in (1, 4):
        scene = case_scene(before.study, case).with_(duration=before.columns["end_time"][case])
        traj = simulate(scene, estimate=False)        # the run itself, not its error
        assert np.max(np.abs(traj.stroke)) == pytest.approx(before.columns["max_stroke"][case],
                                                            rel=1e-9)
        assert np.min(traj.position[:, 2]) == pytest.approx(
            before.columns["min_height"][case], rel=1e-9)
