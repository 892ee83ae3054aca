"""Tests of the speed-vs-error study's measurements (symcushion.studies.speed_vs_error).

The study itself (timings, the full Δt grid, compiled code, peers) is a script
whose numbers are reported, never asserted. These tests check what its
conclusions rest on: the chunked rollout is the same simulation as one
rollout, the metrics read the trajectory as ``symcushion.simulate`` and
``symcushion.reproduce`` define it, errors vanish against the reference
itself and shrink with Δt on the Fig. 3 scene, the order fit and the
equal-error interpolation recover known answers, and the CSV has the columns
the study promises. Short VM runs only (a few seconds in all).
"""
from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest

from symcushion.reproduce import measure_claims
from symcushion.model.scene import load_scene
from symcushion.scheme.touchdown import build_model
from symcushion.run.driver import simulate
from symcushion.studies import speed_vs_error as sve

ROOT = Path(__file__).resolve().parent.parent
FIG3 = ROOT / "studies" / "fig3.toml"



#: Fig. 3 up to just after the rebound (contact ends at 0.364 s, the second
#: landing is at 0.466 s): the runs stay short.
DURATION = 0.45
#: Δt of the short runs and of the test's own reference (the stiff axial mode
#: of the rods is stable below 3.8 ms, so 2 ms is the coarsest sensible step).
COARSE, FINE, REFERENCE = 2e-3, 1e-3, 2.5e-4


@pytest.fixture(scope="module")
def fig3():
    scene = load_scene(FIG3).with_(method="implicit", duration=DURATION)
    return scene, build_model(scene)


@pytest.fixture(scope="module")
def runs(fig3):
    scene, model = fig3
    return {dt: sve.simulate_chunked(model, scene, dt, chunk=400, passes=1)
            for dt in (COARSE, FINE, REFERENCE)}


def test_chunked_rollout_is_one_rollout(fig3, runs):
    """Chunks of 400 steps continue each other exactly: the same states as one rollout."""
    scene, model = fig3
    traj = simulate(scene.with_(dt=FINE), model=model)
    run = runs[FINE]
    assert run.info["steps"] == len(traj.t) - 1
    assert run.info["steps_run"] >= run.info["steps"]
    np.testing.assert_array_equal(run.t, traj.t)
    np.testing.assert_array_equal(run.position, traj.position)
    np.testing.assert_array_equal(run.velocity, traj.velocity)


def test_reduced_quantities_match_the_trajectory(fig3, runs):
    """|a − g|, stroke and hinge angle from the state equal the simulator's outputs."""
    scene, model = fig3
    traj = simulate(scene.with_(dt=FINE), model=model)
    run = runs[FINE]
    decel = np.linalg.norm(traj.acceleration - scene.gravity, axis=1)
    np.testing.assert_allclose(run.decel, decel, rtol=1e-12, atol=1e-9)
    stroke = np.nanmax(np.abs(traj.stroke[1:]), axis=1)
    np.testing.assert_allclose(run.stroke[1:], stroke, rtol=1e-9, atol=1e-12)
    # the angle from e0 is hypot(β, γ − γ0) to first order (β sin γ exactly for small β)
    hinge = np.nanmax(np.hypot(traj.beta[1:], traj.gamma_deflection[1:]), axis=1)
    np.testing.assert_allclose(run.hinge[1:], hinge, rtol=1e-6, atol=1e-9)
    assert run.hinge.max() > 0.1  # the rods do swing (0.14 rad)


def test_rebound_speed_is_reproduce_delta_y(fig3, runs):
    """The ballistic rebound speed gives the Δy′ that `symcushion reproduce` reports."""
    scene, model = fig3
    traj = simulate(scene.with_(dt=FINE), model=model)
    m = sve.metrics(runs[FINE], scene, "ballistic")
    assert m["rebound_kind"] == "ballistic"
    assert m["rebound_dv"] == pytest.approx(measure_claims(traj, scene).rebound_dv, abs=1e-12)


def test_errors_of_the_reference_against_itself_are_zero(fig3, runs):
    scene, _ = fig3
    ref = runs[REFERENCE]
    m = sve.metrics(ref, scene, "ballistic")
    for deflection in ("hinge", "stroke"):
        assert all(v == 0 for v in sve.errors(m, m, deflection).values())
    assert sve.trajectory_error(ref, ref) == 0


def test_errors_shrink_with_dt_on_fig3(fig3, runs):
    """Implicit step on Fig. 3: every error is smaller at 1 ms than at 2 ms."""
    scene, _ = fig3
    ref = runs[REFERENCE]
    ref_m = sve.metrics(ref, scene, "ballistic")
    errs = {}
    for dt in (COARSE, FINE):
        m = sve.metrics(runs[dt], scene, "ballistic")
        errs[dt] = dict(sve.errors(m, ref_m, "hinge"),
                        trajectory_error=sve.trajectory_error(runs[dt], ref))
    for key in errs[FINE]:
        assert 0 < errs[FINE][key] < errs[COARSE][key], key


def test_max_up_rebound_is_the_largest_upward_velocity(runs):
    run = runs[COARSE]
    v, kind = sve.rebound_speed(run, "max_up")
    assert kind == "max_up" and v == run.velocity[:, 2].max() and v > 0.4


def test_rebound_speed_rejects_an_unknown_kind(runs):
    with pytest.raises(ValueError, match="`kind`"):
        sve.rebound_speed(runs[COARSE], "apex")


def test_run_checks_shapes():
    t = np.linspace(0, 1, 5)
    with pytest.raises(ValueError, match="`position`"):
        sve.Run(t=t, position=np.zeros((4, 3)), velocity=np.zeros((5, 3)), decel=np.zeros(5),
                hinge=np.zeros(5), stroke=np.zeros(5))


def test_convergence_order_recovers_a_known_slope():
    dts = np.array([1e-2, 3e-3, 1e-3, 3e-4, 1e-4, 3e-5])
    errs = 5.0 * dts ** 2
    errs[-1] = 1e-12                            # at the reference's floor: must be left out
    order, rng, n = sve.convergence_order(dts, errs, floor=1e-12, dt_max=1e-3)
    assert order == pytest.approx(2.0, abs=1e-9)
    assert rng == (1e-4, 1e-3) and n == 3
    order, rng, n = sve.convergence_order(dts, np.full(6, np.nan))
    assert np.isnan(order) and rng == () and n == 0


def test_cost_at_error_interpolates_along_the_front():
    # cost ∝ error^(-1/2) (a second-order method): the front is a line in log-log
    walls = np.array([1.0, 10.0, 100.0])
    points = [(w, 1e-2 * (w / 1.0) ** -2) for w in walls] + [(50.0, 1e-2)]  # last: dominated
    front = sve.pareto(points)
    assert front == [(w, 1e-2 * w ** -2) for w in walls]
    cost, how = sve.cost_at_error(front, 1e-5)
    assert how == "interpolated" and cost == pytest.approx(10 ** 1.5, rel=1e-12)
    assert sve.cost_at_error(front, 1.0) == (1.0, "at most")
    cost, how = sve.cost_at_error(front, 1e-9)
    assert how == "not reached" and np.isnan(cost)


def test_csv_has_the_required_columns(tmp_path):
    rows = [{"scene": "fig3", "method": "implicit/c", "contact_step": "implicit", "backend": "c",
             "dt": 1e-3, "rebound_error": 2.2e-5, "wall_per_sim_second": 0.01,
             "trajectory_error": float("nan"), "status": "ok"}]
    path = tmp_path / "out.csv"
    sve.write_csv(rows, path)
    with open(path, newline="") as fh:
        table = list(csv.DictReader(fh))
    assert set(sve.REQUIRED_COLUMNS) <= set(table[0])
    assert table[0]["method"] == "implicit/c" and float(table[0]["dt"]) == 1e-3
    assert table[0]["trajectory_error"] == ""   # NaN is an empty cell, never "nan"
    back = sve.read_csv(path)
    assert back[0]["rebound_error"] == pytest.approx(2.2e-5)
    with pytest.raises(ValueError, match="unknown column"):
        sve.write_csv([{"scene": "fig3", "speed": 1.0}], tmp_path / "bad.csv")


def test_the_lock_variant_runs_only_with_friction():
    lock = sve.VARIANTS["implicit+midpoint+lock"]
    fig3, fig4 = (load_scene(sve.STUDIES / f) for f in ("fig3.toml", "fig4.toml"))
    assert not sve.applies(lock, fig3.mu)            # μ = 0: the scene refuses the lock
    with pytest.raises(ValueError, match="events"):
        fig3.with_(**lock)
    assert sve.applies(lock, fig4.mu)
    fig4.with_(**lock)                               # builds its scene without complaint
    assert all(sve.applies(s, 0.0) for m, s in sve.VARIANTS.items() if m != "implicit+midpoint+lock")


def test_tables_list_only_the_variants_run_on_a_scene():
    def row(method, wall, err, backend="c"):
        return {"scene": "fig3", "method": method, "backend": backend, "dt": 1e-3,
                "status": "ok", "wall_per_sim_second": wall, "rebound_error": err,
                "tolerance": 1e-6}

    rows = [row("implicit/c", 0.01, 1e-5), row("paper/c", 0.02, 1e-5), row("paper/c", 0.2, 1e-7),
            row("penalty-cvodes/rtol=1e-06", 2.0, 1e-6, backend="peer")]
    assert sve.variants_on(rows, "fig3") == ["paper", "implicit"]   # VARIANTS order
    assert sve.variants_on(rows, "fig4") == []
    (entry,) = sve.equal_error_comparison(rows)
    assert list(entry["ours"]) == ["paper", "implicit"]
    cost, how = entry["ours"]["paper"]                # halfway in log error: halfway in log cost
    assert how == "interpolated" and cost == pytest.approx((0.02 * 0.2) ** 0.5, rel=1e-12)
    assert entry["ours"]["implicit"][1] == "not reached"      # its only error is larger
