"""Touchdown stability envelope (symcushion.envelope).

One compiled build of the example lander, shortened to SHORT_DURATION,
serves every test that runs cases (module-scoped cache folder): the sampler
is reproducible, in range and stratified; the threaded and the Dask paths
write identical CSV bytes; the slope frame (gravity rotated, ground z = 0)
equals a scene whose gravity is rotated; hand-built touchdowns fall in the
class the physics demands; bad study files name the bad field.
"""
from __future__ import annotations

import copy
import json
import math

import numpy as np
import pytest

from symcushion import envelope as ev
from symcushion.compiled.codegen import find_compiler
from symcushion.envelope.cases import STOP_REST_SHARE
from symcushion.model.scene import read_toml
from symcushion.scheme.touchdown import build_model

from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
LANDER = ROOT / "studies" / "envelope_lander.toml"
#: Simulated time per case in the tests (s): the impact and the first swing of
#: a tip-over are over by then; 500 steps of 2 ms keep a 200-case run at ~1 s.
SHORT_DURATION = 1.0
#: Cases of the threaded-vs-Dask comparison.
CASES = 200
#: Agreement (relative, and absolute near zero) of the slope frame with a
#: rotated-gravity scene: the same arithmetic except the order of the gravity
#: terms in the two half kicks, i.e. round-off carried over 40 steps.
FRAME_TOL = 1e-9

needs_cc = pytest.mark.skipif(find_compiler() is None,
                              reason="no C compiler found (set $CC or install gcc)")


@pytest.fixture(scope="module")
def raw():
    return read_toml(LANDER)


@pytest.fixture(scope="module")
def study(raw):
    data = copy.deepcopy(raw)
    data["scene"]["duration"] = SHORT_DURATION
    # the machinery under test is the same for every contact step: the tests
    # use the cheap one (compiles in seconds) rather than the example's
    # implicit step with the midpoint slip at 1 ms (docs/envelope.md,
    # "Method and Δt"); the absorbers with memory and their dampers are the
    # example's
    data["scene"].update(method="robust", dt=2e-3, tangent_plane="start", slip="backward",
                         events="none")
    data["sampling"]["n"] = CASES
    return ev.study_from_dict(data, str(LANDER))


@pytest.fixture(scope="module")
def cache(tmp_path_factory):
    return tmp_path_factory.mktemp("envelope_cache")


@pytest.fixture(scope="module")
def library(study, cache):
    if find_compiler() is None:
        pytest.skip("no C compiler found (set $CC or install gcc)")
    return ev.build_envelope(study.scene, cache)


# ---------------------------------------------------------------------------
# sampling
# ---------------------------------------------------------------------------
def test_sobol_unscrambled_is_the_sobol_sequence():
    u = ev.sobol(8, 3, scramble=False)
    cell = 2.0 ** -ev.SOBOL_BITS / 2          # points are the centres of their cells
    expected = np.array([[0, 0, 0], [.5, .5, .5], [.25, .75, .75], [.75, .25, .25],
                         [.125, .625, .375], [.625, .125, .875], [.375, .375, .625],
                         [.875, .875, .125]])
    assert np.allclose(u, expected + cell, atol=0, rtol=1e-12)


@pytest.mark.parametrize("seed", [0, 7])
def test_scrambled_sobol_is_a_net(seed):
    """Scrambling keeps the net property: the first 2^m points stratify every axis
    into 2^m intervals, and the (vertical, horizontal speed) pair is a (0, m, 2)-net:
    one point in each of the 16 × 16 squares for m = 8."""
    u = ev.sobol(256, 8, seed=seed)
    assert np.all((u > 0) & (u < 1))
    for d in range(8):
        assert len(np.unique(np.floor(u[:, d] * 256))) == 256
    squares = np.floor(u[:, 0] * 16) * 16 + np.floor(u[:, 1] * 16)
    assert len(np.unique(squares)) == 256
    rng = np.random.default_rng(seed).random((256, 2))
    random_squares = np.floor(rng[:, 0] * 16) * 16 + np.floor(rng[:, 1] * 16)
    assert len(np.unique(random_squares)) < 256  # pseudo-random points leave gaps


def test_sampling_is_reproducible_and_in_range(study):
    a, b = ev.sample_conditions(study), ev.sample_conditions(study)
    other = ev.sample_conditions(study.with_(seed=study.seed + 1))
    for name in ev.VARIABLES:
        assert np.array_equal(a[name], b[name]), name
        lo, hi = study.ranges[name].bounds()
        assert np.all((a[name] >= lo) & (a[name] <= hi)), name
    assert not np.array_equal(a["vertical_speed"], other["vertical_speed"])
    tilt = study.ranges["tilt_deg"]
    assert tilt.kind == "normal"
    assert abs(np.mean(a["tilt_deg"]) - tilt.mean) < 4 * tilt.std / math.sqrt(study.n)
    rnd = ev.sample_conditions(study.with_(method="random"))
    assert not np.array_equal(rnd["vertical_speed"], a["vertical_speed"])


def test_truncated_normal_stays_in_its_bounds():
    r = ev.Range("normal", mean=2.0, std=1.0, low=1.5, high=2.2)
    x = r.transform(np.linspace(1e-6, 1 - 1e-6, 1001))
    assert x.min() >= 1.5 - 1e-12 and x.max() <= 2.2 + 1e-12
    assert np.all(np.diff(x) > 0)


def test_initial_states_put_the_lowest_foot_at_the_clearance(study):
    c = ev.sample_conditions(study.with_(n=64))
    x0, g = ev.initial_states(study, c)
    n_legs = len(study.scene.legs)
    feet_z = x0[[ev.BODY_STATE + ev.LEG_STATE * j + 2 for j in range(n_legs)]]
    assert np.allclose(feet_z.min(axis=0), study.clearance, atol=1e-12)
    # gravity keeps its magnitude; the true vertical is the slope angle from the normal
    assert np.allclose(np.linalg.norm(g, axis=0), np.linalg.norm(study.scene.gravity))
    slope = np.degrees(np.arccos(-g[2] / np.linalg.norm(g, axis=0)))
    assert np.allclose(slope, c["slope_deg"], atol=1e-9)
    # the velocity has the sampled vertical and horizontal parts against the true vertical
    up = -g / np.linalg.norm(g, axis=0)
    v = x0[3:6]
    assert np.allclose(-np.sum(v * up, axis=0), c["vertical_speed"], atol=1e-12)
    horizontal = np.linalg.norm(v + c["vertical_speed"] * up, axis=0)
    assert np.allclose(horizontal, c["horizontal_speed"], atol=1e-12)


# ---------------------------------------------------------------------------
# the slope frame and the compiled runs
# ---------------------------------------------------------------------------
def test_slope_frame_equals_a_scene_with_rotated_gravity(study):
    """envelope_case with the slope frame's gravity in p equals a scene built with it."""
    steps = 40                                   # 80 ms: touchdown and the first stroke
    cond = {k: np.array([v]) for k, v in dict(
        vertical_speed=2.0, horizontal_speed=1.0, heading_deg=30.0, slope_deg=12.0,
        yaw_deg=20.0, tilt_deg=3.0, tilt_azimuth_deg=100.0, mu=study.scene.mu).items()}
    x0, g = ev.initial_states(study, cond)
    f = ev.envelope_function(build_model(study.scene), steps)
    p = ev.case_params(study.scene, cond["mu"], g)[:, 0]
    x_end, summary = f(x0[:, 0], p, study.scene.dt, ev.NO_STOP)
    rotated = build_model(study.scene.with_(gravity=g[:, 0]))
    X, _ = rotated.rollout(steps)(x0[:, 0], rotated.default_p, study.scene.dt)
    reference = np.asarray(X)[:, -1]
    assert float(summary[ev.SUMMARY.index("touched")]) == 1.0
    # relative per entry: the state mixes metres with feet forces of ~1e3 N
    assert np.allclose(np.asarray(x_end).ravel(), reference, rtol=FRAME_TOL, atol=FRAME_TOL)


@needs_cc
def test_threaded_and_dask_csv_are_identical(study, library, cache, tmp_path):
    pytest.importorskip("distributed", reason="the Dask path needs the optional extra "
                                              "symcushion[dask] (dask[distributed])")
    threaded = ev.run_envelope(study, tmp_path / "threads", threads=2, cache_dir=cache,
                               progress=False, plots=False)
    serial = ev.run_envelope(study.with_(batch=64), tmp_path / "serial", threads=1,
                             cache_dir=cache, progress=False, plots=False)
    dask = ev.run_envelope(study, tmp_path / "dask", dask=True, workers=2, cache_dir=cache,
                           progress=False, plots=False)
    a = (tmp_path / "threads" / "cases.csv").read_bytes()
    assert a == (tmp_path / "serial" / "cases.csv").read_bytes()
    assert a == (tmp_path / "dask" / "cases.csv").read_bytes()
    assert a.count(b"\n") == CASES + 1
    assert threaded.counts() == dask.counts() == serial.counts()
    assert sum(threaded.counts().values()) == CASES
    assert dask.timings["workers"] == 2


@needs_cc
def test_a_separately_started_scheduler_gives_the_same_csv(study, library, cache, tmp_path,
                                                           dask_scheduler):
    threaded = ev.run_envelope(study, tmp_path / "threads", threads=2, cache_dir=cache,
                               progress=False, plots=False)
    remote = ev.run_envelope(study, tmp_path / "remote", scheduler=dask_scheduler,
                             cache_dir=cache, progress=False, plots=False)
    a = (tmp_path / "threads" / "cases.csv").read_bytes()
    assert a == (tmp_path / "remote" / "cases.csv").read_bytes()
    assert remote.counts() == threaded.counts()
    assert remote.timings["workers"] == 2


@needs_cc
def test_threaded_run_writes_every_case_and_the_figures(study, library, cache, tmp_path):
    small = study.with_(n=64)
    result = ev.run_envelope(small, tmp_path, cache_dir=cache, progress=False)
    header = (tmp_path / "cases.csv").read_text().splitlines()[0].split(",")
    assert header[0] == "case" and header[-1] == "class"
    for name in list(ev.VARIABLES) + ["max_stroke", "peak_decel", "max_tilt_deg",
                                      "margin_tip_over", "margin_stroke"]:
        assert name in header
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert "p_stable" in summary
    # the scheme of the step is recorded with the results it gave
    assert {k: summary["scene"][k] for k in ("method", "slip", "events", "dt")} == dict(
        method="robust", slip="backward", events="none", dt=2e-3)
    ps = result.p_stable()
    assert ps["low"] <= ps["p"] <= ps["high"]
    for kind in ("boundary", "pstable", "distributions"):
        assert result.files[kind].stat().st_size > 10_000


# ---------------------------------------------------------------------------
# classification
# ---------------------------------------------------------------------------
@needs_cc
def test_hand_built_touchdowns_are_classified_by_the_physics(study, library, cache):
    """Flat ground at 1 m/s stays upright; a vertical drop on a 40° slope (above the
    friction angle atan 0.5 = 27° and the static tip-over angle) tips over; a 6 m/s
    vertical drop needs more stroke than 0.25 m (the plateau absorbs about
    4 · 2.2 kN · 0.25 m ≈ 2.2 kJ against 2.7 kJ of kinetic energy)."""
    c = ev.evaluate(study, {"vertical_speed": [1.0, 2.0, 6.0],
                            "horizontal_speed": [0.5, 0.0, 0.0],
                            "slope_deg": [0.0, 40.0, 0.0], "yaw_deg": [0.0, 45.0, 0.0],
                            "tilt_deg": 0.0}, cache_dir=cache)
    assert list(c["class"]) == ["stable", "tip_over", "stroke"]
    # the tipping case stops once its tilt passes the limit; run on, it falls over
    assert c["max_tilt_deg"][0] < 5 and study.limits.tilt_deg < c["max_tilt_deg"][1] < 40
    assert c["end_time"][1] < study.scene.duration
    full = ev.evaluate(study.with_(stop=False), {"vertical_speed": 2.0, "slope_deg": 40.0,
                                                 "yaw_deg": 45.0}, cache_dir=cache)
    assert list(full["class"]) == ["tip_over"] and full["max_tilt_deg"][0] > 90
    assert c["margin_tip_over"][1] < 0 < c["margin_tip_over"][0]
    assert c["max_stroke"][2] > study.limits.stroke > c["max_stroke"][0]
    assert np.all(c["first_contact_time"] > 0)


@needs_cc
def test_stopping_decided_cases_keeps_every_class(study, library, cache):
    """A case stops once it has tipped over or come to rest on three feet; every
    class and every case that did not stop is as in the full run, and a case at
    rest stops well inside the at-rest limit."""
    stopped = ev.run_envelope(study, cache_dir=cache, progress=False, plots=False).columns
    full = ev.run_envelope(study.with_(stop=False), cache_dir=cache, progress=False,
                           plots=False).columns
    assert list(stopped["class"]) == list(full["class"])
    early = stopped["end_time"] < study.scene.duration - study.scene.dt / 2
    assert 0.3 < early.mean() < 1          # the stop is used, and not on every case
    tipped = early & (stopped["class"] == "tip_over")
    assert np.all(stopped["max_tilt_deg"][tipped] > study.limits.tilt_deg)
    rest = early & ~tipped
    assert rest.any() and np.all(stopped["final_motion"][rest]
                                 < STOP_REST_SHARE * study.limits.rest_speed)
    for name in ("max_stroke", "peak_decel", "rebound_speed", "final_speed"):
        assert np.array_equal(stopped[name][~early], full[name][~early]), name
    assert np.all(full["end_time"] > study.scene.duration - study.scene.dt / 2)


@needs_cc
def test_an_elastic_lander_rebounds(tmp_path):
    """Linear axial springs and no friction give back most of the impact speed."""
    data = {
        "scene": {"mu": 0.0, "method": "robust", "dt": 2e-3, "duration": 0.6},
        "body": {"mass": 100.0, "inertia": [10.0, 10.0, 12.0]},
        "legs": {"count": 4, "radius": 0.4, "height": -0.1, "length": 0.6,
                 "e0": [0.0, 0.0, -1.0], "en": [-0.5, 0.0, -0.8660254037844386],
                 "S": {"type": "linear", "stiffness": 2e4},
                 "M_beta": {"type": "linear", "stiffness": 1e4},
                 "M_gamma": {"type": "linear", "stiffness": 1e4}},
        "obstacle": [{"type": "plane"}],
        "sampling": {"n": 2},
        "ranges": {"vertical_speed": [1.0, 2.0]},
        "limits": {"rebound_speed": 0.5, "stroke": 0.3},
    }
    study = ev.study_from_dict(data, "elastic")
    c = ev.evaluate(study, {"vertical_speed": [2.0, 0.3]}, cache_dir=tmp_path)
    assert c["class"][0] == "rebound" and c["rebound_speed"][0] > 1.0
    assert c["airborne_time"][0] > 0
    # the slow drop stays within every limit, but undamped springs without
    # friction never bring it to rest: not stable unless the rest check is off
    assert c["class"][1] == "moving" and c["final_motion"][1] > ev.DEFAULT_REST_SPEED
    data["limits"]["rest_speed"] = False
    c = ev.evaluate(ev.study_from_dict(data, "elastic"), {"vertical_speed": [0.3]},
                    cache_dir=tmp_path)
    assert c["class"][0] == "stable"


def test_classify_precedence_and_margins():
    n_legs = 1
    summary = np.zeros((len(ev.SUMMARY), 4))
    row = {name: i for i, name in enumerate(ev.SUMMARY)}
    summary[row["touched"]] = [1, 1, 1, 0]
    summary[row["max_stroke"]] = [0.1, 0.3, 0.3, 0.0]
    summary[row["peak_decel"]] = [10.0, 10.0, 90.0, 0.0]
    one_minus_cos = 1 - math.cos(math.radians(40))
    summary[row["max_one_minus_cos_tilt"]] = [0.0, 0.0, one_minus_cos, 0.0]
    x_end = np.zeros((ev.BODY_STATE + ev.LEG_STATE * n_legs, 4))
    x_end[6] = 1.0                                       # upright quaternion
    x0 = np.zeros_like(x_end)
    gravity = np.tile([[0.0], [0.0], [-9.81]], (1, 4))
    limits = ev.Limits(stroke=0.2, tilt_deg=35.0, deceleration=80.0)
    c = ev.classify(summary, x_end, gravity, x0, limits, n_legs)
    assert list(c["class"]) == ["stable", "stroke", "tip_over", "no_touchdown"]
    assert np.isclose(c["margin_stroke"][0], 0.5) and np.isclose(c["margin_stroke"][1], -0.5)
    assert np.isclose(c["max_tilt_deg"][2], 40.0)
    assert np.isclose(c["margin_deceleration"][2], 1 - 90 / 80)


def test_classify_at_rest_counts_rotation_at_the_reach():
    """A case within every limit is stable only when |v| + |ω|·reach ≤ rest_speed."""
    n_legs = 1
    summary = np.zeros((len(ev.SUMMARY), 3))
    summary[list(ev.SUMMARY).index("touched")] = 1
    x_end = np.zeros((ev.BODY_STATE + ev.LEG_STATE * n_legs, 3))
    x_end[6] = 1.0                                       # upright quaternion
    x_end[3] = [0.0, 0.04, 0.0]                          # centre-of-mass speed (m/s)
    x_end[10] = [0.0, 0.0, 0.02]                         # body rate (rad/s)
    gravity = np.tile([[0.0], [0.0], [-9.81]], (1, 3))
    limits = ev.Limits(stroke=0.2, rest_speed=0.05)
    c = ev.classify(summary, x_end, gravity, np.zeros_like(x_end), limits, n_legs, reach=2.0)
    assert list(c["class"]) == ["stable", "stable", "stable"]
    assert np.allclose(c["final_motion"], [0.0, 0.04, 0.04])
    assert np.isclose(c["margin_moving"][2], 1 - 0.04 / 0.05)
    c = ev.classify(summary, x_end, gravity, np.zeros_like(x_end), limits, n_legs, reach=3.0)
    assert list(c["class"]) == ["stable", "stable", "moving"]
    assert np.isclose(c["final_motion"][2], 0.06)
    c = ev.classify(summary, x_end, gravity, np.zeros_like(x_end),
                    ev.Limits(stroke=0.2, rest_speed=None), n_legs, reach=3.0)
    assert list(c["class"]) == ["stable"] * 3


def test_wilson_interval():
    p, lo, hi = ev.wilson_interval(50, 100)
    assert p == 0.5 and np.isclose(lo, 1 - hi) and 0.40 < lo < 0.41
    p, lo, hi = ev.wilson_interval(0, 20)
    assert p == 0 and lo == 0 and 0 < hi < 0.2      # never an empty interval at 0


# ---------------------------------------------------------------------------
# bad study files
# ---------------------------------------------------------------------------
def _edit(raw, path, value):
    data = copy.deepcopy(raw)
    *keys, last = path.split(".")
    node = data
    for k in keys:
        node = node.setdefault(k, {})
    if value is ...:
        del node[last]
    else:
        node[last] = value
    return data


@pytest.mark.parametrize("path, value, words", [
    ("ranges.vertical_speed", ..., "ranges.vertical_speed"),
    ("ranges.vertical_speed", [4.0, 1.0], "ranges.vertical_speed"),
    ("ranges.vertical_speed", {"distribution": "normal", "mean": 2.0, "std": 1.0},
     "low = 0"),
    ("ranges.slope_deg", [0.0, 75.0], "ranges.slope_deg"),
    ("ranges.heading", [0.0, 90.0], "unknown field(s) ['heading']"),
    ("ranges.tilt_deg", {"distribution": "gauss", "mean": 0.0, "std": 1.0},
     "ranges.tilt_deg.distribution"),
    ("ranges.mu", [-0.1, 0.7], "ranges.mu"),
    ("sampling.method", "halton", "sampling.method"),
    ("sampling.n", 0, "sampling.n"),
    ("sampling.seed", -1, "sampling.seed"),
    ("limits.stroke", -0.1, "limits.stroke"),
    ("limits", {}, "at least one limit"),
    ("limits.rest_speed", -0.05, "limits.rest_speed"),
    ("limits.rest_speed", "slow", "limits.rest_speed"),
    ("limits", {"rest_speed": 0.05}, "at least one limit"),
    ("obstacle", [{"type": "sphere", "center": [0, 0, -1], "radius": 1.0}],
     "type \"plane\""),
    ("study.clearence", 0.01, "unknown field(s) ['clearence']"),
])
def test_bad_study_files_name_the_field(raw, path, value, words):
    with pytest.raises(ValueError, match=None) as err:
        ev.study_from_dict(_edit(raw, path, value), "bad.toml")
    assert words in str(err.value), str(err.value)
    assert "bad.toml" in str(err.value)


def test_mu_levels_are_accepted(raw):
    study = ev.study_from_dict(_edit(raw, "ranges.mu", {"levels": [0.3, 0.7]}), "mu.toml")
    assert study.ranges["mu"].kind == "levels"
    mu = ev.sample_conditions(study.with_(n=64))["mu"]
    assert set(mu) == {0.3, 0.7} and 20 < np.sum(mu == 0.3) < 44


def test_missing_study_file_is_reported(tmp_path):
    with pytest.raises(FileNotFoundError, match="nope.toml"):
        ev.load_study(tmp_path / "nope.toml")


@needs_cc
def test_a_built_study_is_found_by_its_index_without_generating_c(study, library, cache,
                                                                  monkeypatch):
    """A study whose library was built is found from the index of what it was built from
    (as a new process reads its file) without building the step's graph; another Δt
    is not."""
    from symcushion.envelope import build as eb
    from symcushion.model.scene import scene_from_dict

    def scene():                                # a fresh Scene, as a new process reads it
        return scene_from_dict(study.scene_data, study.source).with_(
            **{k: getattr(study.scene, k) for k in ("method", "dt", "duration",
                                                    "tangent_plane", "slip", "events")})
    first = ev.build_envelope(scene(), cache)
    assert first.resolve() == Path(library).resolve()
    assert list((Path(cache) / eb._INDEX).glob("*.json"))

    def no_graph(*args, **kwargs):
        raise AssertionError("the step's graph was built for a library in the index")
    monkeypatch.setattr(eb, "build_model", no_graph)
    assert ev.build_envelope(scene(), cache) == first
    with pytest.raises(AssertionError, match="graph was built"):
        ev.build_envelope(scene().with_(dt=study.scene.dt / 2), cache)


@needs_cc
def test_mu_sampled_continuously_from_one_library(raw, study, cache):
    """A uniform μ range runs on one compiled library, μ entering through p; each
    case equals the same touchdown evaluated alone with its μ."""
    data = copy.deepcopy(raw)
    data["scene"].update(duration=0.3, method="robust", dt=2e-3, tangent_plane="start",
                         slip="backward", events="none")
    data["sampling"]["n"] = 16
    data["ranges"]["mu"] = [0.1, 0.9]
    continuous = ev.study_from_dict(data, "mu_uniform.toml")
    assert continuous.ranges["mu"].kind == "uniform"
    mu = ev.sample_conditions(continuous)["mu"]
    assert len(np.unique(mu)) == 16 and np.all((mu >= 0.1) & (mu <= 0.9))
    libraries = ev.case_libraries(continuous, mu, cache, progress=False)
    assert list(libraries) == [True]                   # one friction library for every μ
    result = ev.run_envelope(continuous, threads=1, cache_dir=cache, progress=False)
    cond = result.conditions
    alone = ev.evaluate(continuous, {k: cond[k][[3, 11]] for k in ev.VARIABLES},
                        cache_dir=cache)
    for name in ("max_stroke", "peak_decel", "slide", "max_tilt_deg"):
        np.testing.assert_array_equal(alone[name], result.columns[name][[3, 11]])


def test_wilson_interval_is_the_closed_form():
    """SciPy's Wilson interval equals the score formula (centre ± half-width) to round-off."""
    z = 1.959963984540054                               # the 97.5 % normal quantile
    for k, n in ((0, 1), (3, 7), (6380, 10000), (10000, 10000)):
        phat = k / n
        denom = 1 + z * z / n
        centre = (phat + z * z / (2 * n)) / denom
        half = z / denom * math.sqrt(phat * (1 - phat) / n + z * z / (4 * n * n))
        p, lo, hi = ev.wilson_interval(k, n)
        assert abs(lo - (centre - half)) < 1e-14 and abs(hi - (centre + half)) < 1e-14
    with pytest.raises(ValueError, match="`k` and `n`"):
        ev.wilson_interval(5, 3)
    with pytest.raises(ValueError, match="`confidence`"):
        ev.wilson_interval(1, 3, confidence=95)


def test_progress_off_a_terminal_is_plain_lines(monkeypatch):
    """Off a terminal (a log, CI) progress comes as whole lines, one per interval and
    one at the end; on a terminal tqdm draws its bar instead."""
    import io
    from symcushion.envelope import runner

    stream = io.StringIO()                        # not a terminal
    monkeypatch.setattr(runner, "PROGRESS_LOG_INTERVAL", 0.0)
    bar = runner._Progress(300, True, "demo", stream=stream)
    for _ in range(3):
        bar.update(100)
    lines = stream.getvalue().splitlines()
    assert len(lines) == 3 and "\r" not in stream.getvalue()
    assert lines[-1].startswith("  demo: 300/300 cases,") and lines[-1].endswith("0.0 min left")

    quiet = io.StringIO()
    bar = runner._Progress(300, False, "demo", stream=quiet)
    bar.update(300)
    assert quiet.getvalue() == ""


def test_progress_on_a_terminal_is_the_bar_only(monkeypatch):
    import io
    from symcushion.envelope import runner

    class Terminal(io.StringIO):
        def isatty(self):
            return True

    stream = Terminal()
    monkeypatch.setattr(runner, "PROGRESS_LOG_INTERVAL", 0.0)
    bar = runner._Progress(200, True, "demo", stream=stream)
    bar.update(200)
    assert "200/200" in stream.getvalue() and "cases/s," not in stream.getvalue()


def test_the_designed_lander_is_the_example_with_its_legs_within_the_footprint():
    """studies/envelope_lander_designed.toml (docs/design-geometry.md, "Run 5") differs from
    the example only in the legs the design set, and its feet rest within the design's
    1.0-m footprint, farther out than the example's."""
    example = ev.load_study(LANDER)
    designed = ev.load_study(ROOT / "studies" / "envelope_lander_designed.toml")
    assert designed.ranges == example.ranges and designed.limits == example.limits
    assert (designed.n, designed.seed, designed.scene.dt, designed.scene.duration) == (
        example.n, example.seed, example.scene.dt, example.scene.duration)
    assert designed.scene.body.mass == example.scene.body.mass
    assert np.array_equal(designed.scene.body.inertia, example.scene.body.inertia)
    def footprint(scene):        # farthest foot at rest from the body axis (m)
        return max(float(np.linalg.norm(leg.rest_foot[:2])) for leg in scene.legs)
    assert footprint(example.scene) == pytest.approx(0.774, abs=1e-3)
    assert footprint(example.scene) < footprint(designed.scene) <= 1.0
