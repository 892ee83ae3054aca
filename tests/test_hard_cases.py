"""Hard-case battery: one test per case and contact method (symcushion.studies.hard_cases).

Each test runs the study's case builder and checker and asserts (1) that the
implicit method passes every check of the case, and (2) that the run agrees
with the committed table ``figures/hard_cases.md``: where the table says a
method passes, it passes here; where it says FAIL, it fails here on the same
checks. The tolerances are the study's (named constants in
``symcushion/studies/hard_cases/checks.py``, justified there and in docs/hard-cases.md).
"""
from pathlib import Path

import numpy as np
import pytest

from symcushion.legs.characteristics import Linear
from symcushion.model.obstacles import Plane
from symcushion.model.scene import Body, Scene
from symcushion.scheme.touchdown import build_model, initial_state
from symcushion.run.driver import simulate
from symcushion.scheme.stability import stable_dt
from symcushion.legs.strut import HingedStrut
from symcushion.studies import hard_cases as hc

ROOT = Path(__file__).resolve().parents[1]

METHODS = hc.METHODS


def run_and_compare(name, method, full=True):
    """Run a case; assert implicit passes and the verdict matches the committed table."""
    with np.errstate(invalid="ignore", divide="ignore"):   # zero gravity: angles from vertical
        result = hc.run_case(name, method, full)
    verdict = hc.read_table()[(name, method)]
    assert result.stats.finite or method != "implicit", "implicit run is not finite"
    if method == "implicit":
        assert result.passed, (result.failures, result.stats)
    if verdict == "pass":
        assert result.passed, (name, method, result.failures, result.stats)
    else:
        failed = verdict[len("FAIL ("):-1].split(", ")
        assert sorted(result.failures) == sorted(failed), (verdict, result.failures, result.stats)
    return result


# -- the explicit body limit -------------------------------------------------------
def test_stable_dt_matches_closed_form_of_a_spring_under_the_centre_of_mass():
    k, m = 2e4, 10.0
    leg = HingedStrut(hinge=(0, 0, -0.1), e0=(0, 0, -1), en=(0.6, 0, -0.8), length=0.5,
                      S=Linear(k), M_beta=Linear(500.0), M_gamma=Linear(500.0))
    # a huge inertia leaves the vertical spring mode as the fastest: ω² = k/m
    body = Body(m, [1e6, 1e6, 1e6], position=[0, 0, 0.6])
    scene = Scene(body, [leg], [Plane()])
    model = build_model(scene)
    assert stable_dt(model, initial_state(scene)) == pytest.approx(2 / np.sqrt(k / m), rel=1e-9)


def test_stiff_rods_diverge_at_one_millisecond_when_the_feet_stick():
    # the reason for the stiff case's step: ω_max·1 ms ≈ 220 ≫ 2
    speed = hc.explicit_limit("implicit", steps=3)
    # impact at 0.5 m/s; the first step's stiff impulse throws the body off at km/s
    assert not np.isfinite(speed[0]) or speed[0] > 1e3, speed


def test_adaptive_stability_cap_takes_steps_below_the_limit():
    setup = hc.case_stiff_axial_stick("implicit", full=False)
    scene = setup.scene.with_(dt=1e-3, duration=2e-4)
    model = build_model(scene)
    x0 = initial_state(scene)
    limit = stable_dt(model, x0)
    traj = simulate(scene, model=model, adaptive=True, stability=hc.STIFF_FRACTION)
    # every step but the last, which is cut to end at `duration`
    assert traj.info["stability_capped"] >= traj.info["steps"] - 1
    assert traj.info["dt_min"] <= hc.STIFF_FRACTION * limit * (1 + 1e-9)
    with pytest.raises(ValueError, match="stability"):
        simulate(scene, model=model, stability=True)
    with pytest.raises(ValueError, match="stability"):
        simulate(scene, model=model, adaptive=True, stability=1.5)


# -- the cases ---------------------------------------------------------------------
@pytest.mark.parametrize("method", METHODS)
def test_stiff_axial(method):
    run_and_compare("stiff_axial", method)


@pytest.mark.parametrize("method", METHODS)
def test_stiff_axial_stick(method):
    # 0.01 s instead of the table's 0.05 s (11 000 instead of 55 000 steps): the
    # impact, the rebound and the start of the flight, where the worst values occur
    result = run_and_compare("stiff_axial_stick", method, full=False)
    assert result.dt <= hc.STIFF_FRACTION * 2 / 2.1e5       # ω_max ≈ 2.19e5 rad/s


@pytest.mark.parametrize("method", METHODS)
def test_grazing(method):
    result = run_and_compare("grazing", method)
    assert result.stats.landings >= 1                   # the foot did touch the sphere


@pytest.mark.parametrize("method", METHODS)
def test_simultaneous(method):
    run_and_compare("simultaneous", method)
    traj = simulate(hc.case_simultaneous(method).scene.with_(duration=0.005))
    first = np.argmax(traj.contact > 0.5, axis=0)
    assert np.all(first == 1)                           # all four feet in the first step


@pytest.mark.parametrize("method", METHODS)
def test_recontact(method):
    result = run_and_compare("recontact", method)
    flights = hc.recontact_flights(result.stats.t_end)
    # the step sees a flight only when a step ends inside it: some are missed
    assert 1 <= result.stats.lift_offs < flights


@pytest.mark.parametrize("method", METHODS)
def test_slope_stick(method):
    result = run_and_compare("slope_stick", method)      # the full 100 s
    assert result.stats.t_end >= 100.0
    assert result.setup.scene.mu - np.tan(hc.SLOPE) < 1e-2


@pytest.mark.parametrize("method", METHODS)
def test_high_friction(method):
    run_and_compare("high_friction", method)


@pytest.mark.parametrize("method", METHODS)
def test_near_singular(method):
    result = run_and_compare("near_singular", method)
    assert result.stats.singular < 2 * hc.NEAR_SINGULAR_MISS


@pytest.mark.parametrize("method", METHODS)
def test_tiny_step(method):
    # 0.01 s (1e4 steps of 1 µs) instead of the table's 0.02 s: the whole load-up
    run_and_compare("tiny_step", method, full=False)


@pytest.mark.parametrize("method", METHODS)
def test_large_step(method):
    run_and_compare("large_step", method)


@pytest.mark.parametrize("method", METHODS)
def test_fast_impact(method):
    run_and_compare("fast_impact", method)


@pytest.mark.parametrize("method", METHODS)
def test_long_rest(method):
    # the full 1000 s (1e5 steps) for the implicit step; 100 s for the other two,
    # whose evaluation the test budget cannot afford three times over
    result = run_and_compare("long_rest", method, full=method == "implicit")
    assert result.stats.t_end >= (1000.0 if method == "implicit" else 100.0)
