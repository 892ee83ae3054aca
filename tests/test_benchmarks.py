"""Each benchmark's check on a short case, and the check against the old bug.

Every ``studies/bench_*.py`` checks, before it times, that what it times is
finite and equal to the reference computation of the same scene
(``studies/bench_check.py``). These tests run those checks on small cases (a
few steps, short horizons, cheap variants of the scenes) so that a benchmark
that stops timing the real computation fails here; and they show that the
check rejects the old benchmark's rollout with every parameter zero (no
gravity, no mass, no inertia, μ = 0), which ends in NaN.
"""
import sys
import tempfile
from pathlib import Path

import numpy as np
import pytest

from symcushion.compiled.codegen import compiled_model
from symcushion.envelope import load_study, sample_conditions
from symcushion.design.optimise import load_study as load_design_study
from symcushion.design.robust import EnvelopeDesign
from symcushion.design.robust.study import load_robust_study
from symcushion.scheme.touchdown import initial_state

STUDIES = Path(__file__).resolve().parents[1] / "studies"
sys.path.insert(0, str(STUDIES))       # the benchmarks import each other as scripts

import bench_check  # noqa: E402
import bench_codegen  # noqa: E402
import bench_contact  # noqa: E402
import bench_design  # noqa: E402
import bench_design_envelope  # noqa: E402
import bench_envelope  # noqa: E402
import bench_long_run  # noqa: E402
import bench_strut  # noqa: E402
import bench_touchdown  # noqa: E402

#: Steps of the short rollouts: past the touchdown of Figs. 3-4 (their feet
#: touch at the start), where wrong parameters turn every state NaN.
STEPS = 20
#: Contact cases of the short harness runs.
CONTACT_CASES = 50
#: A cheap step for the envelope scenes: the exact step's midpoint rule and
#: stroke lock compile for tens of seconds; the checks are the same.
QUICK_STEP = dict(method="robust", slip="backward", events="none", dt=1e-3, duration=0.05)


@pytest.fixture(scope="module")
def fig3_compiled(fig3_scene):
    """The Fig. 3 scene cut to STEPS steps and its compiled model."""
    scene = fig3_scene.with_(duration=STEPS * fig3_scene.dt)
    with tempfile.TemporaryDirectory() as folder:
        yield scene, compiled_model(scene, folder, steps=STEPS)


def test_touchdown_check_passes_on_the_scene_parameters(fig3_compiled):
    scene, model = fig3_compiled
    p = bench_touchdown.check_symcushion(scene, model.rollout(STEPS), STEPS)
    np.testing.assert_array_equal(p, model.default_p)


def test_check_rejects_the_rollout_with_zero_parameters(fig3_compiled):
    """The old bench_touchdown: p = zeros (μ, gravity, mass, inertia 0) ends in NaN."""
    scene, model = fig3_compiled
    with pytest.raises(bench_check.BenchmarkCheckError,
                       match=r"bench_touchdown: .*states X has \d+ non-finite"):
        bench_check.check_rollout("bench_touchdown", "zero-parameter rollout",
                                  model.rollout(STEPS), scene, initial_state(scene),
                                  np.zeros(model.np), scene.dt, STEPS)


def test_check_rejects_a_different_rollout(fig3_compiled):
    """Finite but not the scene's: another gravity is caught by the comparison."""
    scene, model = fig3_compiled
    p = model.pack_params(gravity=[0.0, 0.0, -1.62])
    rollout = model.rollout(STEPS)

    def moon(x0, _, dt):
        return rollout(x0, p, dt)

    with pytest.raises(bench_check.BenchmarkCheckError, match="differs from the uncompiled"):
        bench_check.check_rollout("bench_touchdown", "rollout", moon, scene,
                                  initial_state(scene), model.default_p, scene.dt, STEPS)


def test_check_equal_names_the_difference():
    with pytest.raises(bench_check.BenchmarkCheckError,
                       match=r"bench_x: y differs .* 1 of 3 entries by up to 0.001"):
        bench_check.check_equal("bench_x", "y", [1.0, 2.0, 3.001], [1.0, 2.0, 3.0])
    assert bench_check.check_equal("bench_x", "y", [1.0, 2.0], [1.0, 2.0 + 1e-15]) > 0
    with pytest.raises(bench_check.BenchmarkCheckError, match="the same bits"):
        bench_check.check_equal("bench_x", "y", [1.0, 2.0], [1.0, 2.0 + 4.5e-16],
                                rtol=bench_check.BITWISE)
    with pytest.raises(ValueError, match="`rtol` must be"):
        bench_check.check_equal("bench_x", "y", [1.0], [1.0], rtol=-1.0)


def test_touchdown_mujoco_check(fig3_scene):
    pytest.importorskip("mujoco", reason="the MuJoCo peer needs the optional extra "
                                         "symcushion[peers]")
    bench_touchdown.check_mujoco(fig3_scene, STEPS)


@pytest.mark.parametrize("path", ["lander_slope.toml", "tutorial/lander.toml"])
def test_touchdown_mujoco_check_nonlinear_legs(path):
    """The landers' absorbers are non-linear: MuJoCo is timed on the same lander with
    linear springs of their slopes at rest (bench_touchdown.mujoco_scene), checked the same way."""
    pytest.importorskip("mujoco", reason="the MuJoCo peer needs the optional extra "
                                         "symcushion[peers]")
    from symcushion.legs.characteristics import Linear
    from symcushion.model.scene import load_scene
    scene = load_scene(STUDIES / path)
    linear = bench_touchdown.mujoco_scene(scene)
    assert linear is not scene and all(isinstance(el.curve, Linear) for leg in linear.legs
                                       for el in leg.elements)
    assert len(linear.legs) == len(scene.legs) and linear.mu == scene.mu
    bench_touchdown.check_mujoco(linear, STEPS)


def test_contact_checks(tmp_path):
    cases = bench_contact.spatial_cases(np.random.default_rng(1), CONTACT_CASES)
    for called in (False, True):
        ns = bench_contact.native_ratio(cases, called=called)
        assert set(ns) >= {"contact_step_implicit", "contact_step_robust", "outputs"}
    args = bench_contact.stack(cases)
    one = [a[:, 0] if a.shape[1] == CONTACT_CASES else a[:, :3] for a in args]
    one[4] = float(args[4][0, 0])
    f = bench_contact.contact_step("implicit")
    bench_contact.check_cost(f, f.map(CONTACT_CASES), one, args)


def test_contact_check_rejects_wrong_outputs():
    cases = bench_contact.spatial_cases(np.random.default_rng(1), 4)
    wrong = np.zeros(3 * 4 * bench_contact.HARNESS_WIDTH)
    with pytest.raises(bench_check.BenchmarkCheckError, match="bench_contact: compiled"):
        bench_contact.check_native(wrong.tobytes(), cases, called=False)


def test_codegen_drop_check(fig3_scene, tmp_path, monkeypatch):
    """measure_drop checks the compiled rollout, both step loops and the program's CSV."""
    monkeypatch.setattr(bench_codegen, "BEST_OF", 1)
    monkeypatch.setattr(bench_codegen, "REPEAT_SECONDS", 1e-3)
    monkeypatch.setattr(bench_codegen, "PROGRAM_REPEAT", 1)
    drop = bench_codegen.measure_drop(fig3_scene.with_(duration=STEPS * fig3_scene.dt),
                                      tmp_path / "fig3")
    assert drop["agree_rollout"] == 0.0 and drop["agree_program"] == 0.0


def test_strut_check():
    leg = bench_strut.representative_leg()
    r, v = bench_strut.random_poses(leg, 10, np.random.default_rng(0))
    outputs = bench_strut.check_variants(bench_strut.variants(leg), r, v, leg.param_values)
    assert len(outputs) == 4


def test_envelope_check(tmp_path):
    study = load_study(bench_envelope.STUDY)
    study = study.with_(scene=study.scene.with_(**QUICK_STEP))
    bench_envelope.check_cases(study, tmp_path)


def test_design_check(tmp_path):
    problem = load_design_study(STUDIES / "absorber_1d.toml").problem
    reference = bench_design.vm_reference(problem)
    problem.use_compiled(tmp_path)
    bench_design.check_compiled(problem, reference)


def test_design_envelope_check(tmp_path):
    study = load_robust_study(bench_design_envelope.STUDY)
    envelope = study.envelope.with_(scene=study.envelope.scene.with_(**QUICK_STEP))
    conditions = sample_conditions(envelope.with_(n=2))
    problem = EnvelopeDesign(envelope, conditions, study.variables[:1], horizon=0.05, threads=1,
                             cache_dir=tmp_path)
    bench_design_envelope.check_reference(problem)
    x = problem.scaled(problem.initial)
    reference = bench_design_envelope.check_backend("threads 1", problem, x)
    bench_design_envelope.check_backend("threads 1, again", problem, x, reference)


def test_long_run_check(tmp_path):
    bench_long_run.check_run(tmp_path, duration=0.05)
