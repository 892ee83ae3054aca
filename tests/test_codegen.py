"""C code generation (symcushion.compiled.codegen): compiled code against the SX Functions.

One build of the Fig. 3 scene (4 legs, shortened to SHORT_DURATION) serves
all tests: the generated sources must compile without a word from gcc under
-Wall; every compiled Function, loaded with casadi.external, must equal the
SX Function it was generated from to REL_TOL on random inputs; the
standalone program's trajectory must equal the Python rollout to TRAJ_TOL.
Skipped, with the reason, only when no C compiler is found.
"""
from __future__ import annotations

import json
import subprocess
from pathlib import Path

import casadi as ca
import numpy as np
import pytest

from symcushion.compiled import codegen
from symcushion.cli import main as cli_main
from symcushion.contact.dispatch import contact_step
from symcushion.model.scene import load_scene
from symcushion.scheme.touchdown import build_model, initial_state
from symcushion.run.driver import simulate


ROOT = Path(__file__).resolve().parent.parent
FIG3 = ROOT / "studies" / "fig3.toml"

#: Relative agreement of compiled and SX (VM) results. Both evaluate the same
#: operations in the same order in IEEE double without fused multiply-add
#: (-ffp-contract=off), so they differ at most by the libm of each.
REL_TOL = 1e-12
#: Agreement of the standalone program's trajectory with the Python rollout.
TRAJ_TOL = 1e-10
#: Fig. 3 shortened: impact at t = 0, the deepest compression near 0.1 s,
#: rebound under way at 0.3 s; 300 steps keep the test fast.
SHORT_DURATION = 0.3
#: Random cases per contact step (oracle_contact.random_cases, every kind).
CONTACT_CASES = 400
#: Random poses per strut Function and states per touchdown_step.
STRUT_CASES = 200
STEP_CASES = 100

pytestmark = pytest.mark.skipif(codegen.find_compiler() is None,
                                reason="no C compiler found (set $CC or install gcc)")


@pytest.fixture(scope="module")
def scene():
    return load_scene(FIG3).with_(duration=SHORT_DURATION)


@pytest.fixture(scope="module")
def built(scene, tmp_path_factory):
    out = tmp_path_factory.mktemp("codegen_fig3")
    gen = codegen.generate(out, scene, build=True)
    return gen, codegen.load_compiled(out)


def _rel_err(a, b):
    a, b = np.asarray(a, float), np.asarray(b, float)
    scale = max(np.max(np.abs(b), initial=0.0), np.finfo(float).tiny)
    return float(np.max(np.abs(a - b), initial=0.0)) / scale


def _assert_same(compiled, reference, args, label):
    got = compiled.call(args)
    want = reference.call(args)
    assert set(got) == set(want)
    for name in want:
        err = _rel_err(got[name], want[name])
        assert np.all(np.isfinite(np.asarray(got[name]))) == \
            np.all(np.isfinite(np.asarray(want[name]))), f"{label}: {name} finiteness"
        assert err <= REL_TOL, f"{label}: output {name} differs by {err:.2e} relative"


# ---------------------------------------------------------------------------
# build
# ---------------------------------------------------------------------------
def test_compiles_without_warnings(built):
    gen, _ = built
    assert gen.warnings == {}, f"gcc printed: {gen.warnings}"
    assert "-Wall" in codegen.WARNINGS
    assert gen.library.is_file() and gen.program.is_file()
    manifest = json.loads((gen.out_dir / codegen.MANIFEST).read_text())
    assert all("-Wall" in flags for flags in manifest["cflags"].values())


def test_one_header_documents_every_function(built):
    gen, fns = built
    header = gen.header.read_text()
    assert sorted(p.name for p in gen.out_dir.glob("*.h")) == ["scene_data.h", "symcushion.h"]
    expected = {"contact_step_paper", "contact_step_robust", "contact_step_implicit",
                "touchdown_step", "touchdown_rollout"}
    expected |= {f"leg{j}_{b}" for j in range(4) for b in ("strut_force", "strut_stiffness")}
    assert set(gen.functions) == expected == set(fns)
    for name, f in fns.items():
        signature = f"{name}({', '.join(f.name_in())}) -> ({', '.join(f.name_out())})"
        assert signature in header, signature
        assert f"int {name}(const casadi_real** arg" in header
    assert "touchdown_step(x, p, dt) -> (x_next, y)" in header
    assert "[65x300]" in header  # X of the rollout (13 + 13 per leg), N = scene.steps


def test_cached_build_is_not_recompiled(built, scene):
    gen, _ = built
    mtime = gen.library.stat().st_mtime_ns
    again = codegen.generate(gen.out_dir, scene, build=True)
    assert again.library.stat().st_mtime_ns == mtime
    assert again.warnings == {}


# ---------------------------------------------------------------------------
# compiled == SX
# ---------------------------------------------------------------------------
@pytest.mark.parametrize("method", ["paper", "robust", "implicit"])
def test_contact_steps_equal_sx(built, method, random_contact_cases):
    _, fns = built
    cases = random_contact_cases(6, CONTACT_CASES)
    reference = contact_step(method)
    compiled = fns[reference.name()]
    for i in range(CONTACT_CASES):
        args = {"P0": cases["P0"][i], "Dp": cases["Dp"][i], "n": cases["n"][i],
                "l": cases["l"][i], "mu": cases["mu"][i], "u0": cases["u0"][i]}
        _assert_same(compiled, reference, args, f"{reference.name()} case {i}")


def test_strut_functions_equal_sx(built, scene):
    _, fns = built
    rng = np.random.default_rng(7)
    for j, leg in enumerate(scene.legs):
        for base in ("strut_force", "strut_stiffness"):
            reference = leg.functions()[base]
            for i in range(STRUT_CASES):
                args = {"r": leg.rest_foot + 0.05 * rng.standard_normal(3),
                        "v": rng.standard_normal(3), "p": leg.param_values}
                _assert_same(fns[f"leg{j}_{base}"], reference, args, f"leg{j}_{base} case {i}")


def test_touchdown_step_and_rollout_equal_sx(built, scene):
    _, fns = built
    model = build_model(scene)
    x0 = initial_state(scene)
    X, _ = model.rollout(scene.steps)(x0, model.default_p, scene.dt)
    states = np.asarray(X).T
    rng = np.random.default_rng(8)
    for i in range(STEP_CASES):
        # states of the drop (feet free, landing, in contact), perturbed
        x = states[rng.integers(len(states))] * (1 + 1e-3 * rng.standard_normal(model.nx))
        args = {"x": x, "p": model.default_p, "dt": scene.dt * rng.uniform(0.5, 2.0)}
        _assert_same(fns["touchdown_step"], model.step, args, f"touchdown_step case {i}")
    args = {"x0": x0, "p": model.default_p, "dt": scene.dt}
    _assert_same(fns["touchdown_rollout"], model.rollout(scene.steps), args, "touchdown_rollout")


def test_hoisted_step_is_the_step(scene):
    """The step split at its parameters (p-only part once, the rest per step) gives the
    step's bits on the VM, with p changed too (mass, inertia, a leg's geometry)."""
    model = build_model(scene)
    whole, parametric, core = codegen.hoisted_step(model.step)
    assert parametric.nnz_out(0) > 0 and core.n_instructions() < model.step.n_instructions()
    x0 = initial_state(scene)
    X, _ = model.rollout(20)(x0, model.default_p, scene.dt)
    rng = np.random.default_rng(3)
    for i in range(STEP_CASES):
        x = np.asarray(X)[:, rng.integers(20)]
        p = model.pack_params(mass=50.0 * rng.uniform(0.8, 1.2),
                              **{"leg0.length": 0.6 * rng.uniform(0.95, 1.05)})
        ref = model.step(x, p, scene.dt)
        q = parametric(p)
        for got in (whole(x, p, scene.dt), core(x, p, scene.dt, q)):
            for a, b in zip(got, ref):
                assert np.array_equal(np.asarray(a), np.asarray(b)), f"case {i}"
        x_next = codegen.states_only(core)(x, p, scene.dt, q)
        assert np.array_equal(np.asarray(x_next), np.asarray(ref[0])), f"states, case {i}"


def test_rollout_without_outputs_gives_the_same_states(built, scene):
    """The compiled rollout called with a null Y runs the step without its outputs
    (touchdown_step_states): the same X, bit for bit."""
    _, fns = built
    rollout = fns["touchdown_rollout"]
    model = build_model(scene)
    inputs = [np.asarray(initial_state(scene), dtype=float),
              np.asarray(model.default_p, dtype=float), np.array([scene.dt])]
    X, _ = rollout(*inputs)
    buffer, evaluate = rollout.buffer()
    X_only = np.zeros(rollout.nnz_out(0))
    for i, a in enumerate(inputs):
        buffer.set_arg(i, memoryview(a))
    buffer.set_res(0, memoryview(X_only))           # Y left a null pointer
    evaluate()
    assert np.array_equal(X_only, np.asarray(X).ravel(order="F"))


def test_compiled_model_simulates_like_the_vm(built, scene):
    gen, _ = built
    compiled = codegen.compiled_model(scene, gen.out_dir)
    assert isinstance(compiled.step, ca.Function) and compiled.library == gen.library
    fast, slow = simulate(scene, model=compiled), simulate(scene)
    assert _rel_err(fast.position, slow.position) <= TRAJ_TOL
    # another N: the compiled step rolled out by mapaccum
    X_c, _ = compiled.rollout(7)(initial_state(scene), compiled.default_p, scene.dt)
    X_v, _ = build_model(scene).rollout(7)(initial_state(scene), compiled.default_p, scene.dt)
    assert _rel_err(X_c, X_v) <= REL_TOL


# ---------------------------------------------------------------------------
# the standalone program
# ---------------------------------------------------------------------------
def test_standalone_program_equals_python_rollout(built, scene, tmp_path):
    gen, _ = built
    csv = tmp_path / "traj.csv"
    run = subprocess.run([str(gen.program), "-o", str(csv)], capture_output=True, text=True,
                         timeout=60)
    assert run.returncode == 0, run.stderr
    report = dict(item.split("=", 1) for item in run.stderr.split()[1:])
    assert int(report["steps"]) == scene.steps and float(report["per_step_us"]) > 0
    header = csv.read_text().splitlines()[0].split(",")
    assert header[:4] == ["t", "body_position_x_m", "body_position_y_m", "body_position_z_m"]
    assert len(header) == 1 + 13 + 13 * 4      # t, body, four legs
    table = np.loadtxt(csv, delimiter=",", skiprows=1)
    model = build_model(scene)
    x0 = initial_state(scene)
    X, _ = model.rollout(scene.steps)(x0, model.default_p, scene.dt)
    expected = np.column_stack([x0, np.asarray(X)]).T
    assert table.shape == (scene.steps + 1, 1 + model.nx)
    np.testing.assert_allclose(table[:, 0], scene.dt * np.arange(scene.steps + 1), rtol=0,
                               atol=1e-15)
    assert np.max(np.abs(table[:, 1:] - expected)) <= TRAJ_TOL
    assert expected[:, 16].max() == 1.0, "the run must include contact"


def test_standalone_program_options(built, tmp_path):
    gen, _ = built
    csv = tmp_path / "short.csv"
    run = subprocess.run([str(gen.program), "-n", "5", "-d", "2e-3", "-r", "3", "-o", str(csv)],
                         capture_output=True, text=True, timeout=60)
    assert run.returncode == 0, run.stderr
    assert len(csv.read_text().splitlines()) == 1 + 6
    bad = subprocess.run([str(gen.program), "-n", "zero"], capture_output=True, text=True)
    assert bad.returncode == 2 and "`-n` must be a positive integer" in bad.stderr


def test_own_c_program_calls_the_contact_steps(built, tmp_path, random_contact_cases):
    """build_program links a C file (here bench_contact.c) with the generated objects."""
    gen, _ = built
    source = Path(codegen.__file__).parent / "c" / "bench_contact.c"
    program = codegen.build_program(gen.out_dir, source)
    cases = random_contact_cases(9, 50)
    n = len(cases["mu"])
    table = np.column_stack([cases["P0"], cases["Dp"].transpose(0, 2, 1).reshape(n, 9),
                             cases["n"], cases["l"], cases["mu"], cases["u0"]])
    np.ascontiguousarray(table).tofile(tmp_path / "cases.bin")
    run = subprocess.run([str(program), str(tmp_path / "cases.bin"), "1",
                          str(tmp_path / "out.bin")], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    out = np.fromfile(tmp_path / "out.bin").reshape(3, n, 10)
    for k, method in enumerate(["paper", "robust", "implicit"]):
        f = contact_step(method)
        for i in range(n):
            want = np.concatenate([np.asarray(v).ravel() for v in f(
                cases["P0"][i], cases["Dp"][i], cases["n"][i], cases["l"][i], cases["mu"][i],
                cases["u0"][i])])
            assert _rel_err(out[k, i], want) <= REL_TOL, f"{method} case {i}"


# ---------------------------------------------------------------------------
# API and command line
# ---------------------------------------------------------------------------
def test_contact_steps_only_without_scene(tmp_path, capsys):
    assert cli_main(["codegen", "--out", str(tmp_path)]) == 0
    assert (tmp_path / "symcushion.h").is_file()
    assert not (tmp_path / "scene_data.h").exists()
    info = json.loads((tmp_path / "symcushion.json").read_text())
    assert set(info["functions"]) == {"contact_step_paper", "contact_step_robust",
                                      "contact_step_implicit"}
    assert info["functions"]["contact_step_paper"]["in"]["Dp"] == "3x3"
    with pytest.raises(FileNotFoundError, match="--build"):
        codegen.load_compiled(tmp_path)


def test_invalid_arguments(tmp_path):
    with pytest.raises(ValueError, match="`steps` must be a positive integer"):
        codegen.generate(tmp_path, FIG3, steps=0)
    with pytest.raises(ValueError, match="needs a `scene`"):
        codegen.generate(tmp_path, steps=10)
    with pytest.raises(TypeError, match="`scene` must be"):
        codegen.generate(tmp_path, scene=3.0)


def test_tunable_scene_generates_clean_c(tmp_path):
    """With leg parameters p grows by the curve parameters; the generated C compiles cleanly."""
    toml = FIG3.read_text().replace('type = "linear"', 'type = "linear"\ntunable = true')
    path = tmp_path / "fig3_tunable.toml"
    path.write_text(toml)
    scene = load_scene(path)
    gen = codegen.generate(tmp_path / "out", scene)
    info = json.loads((gen.out_dir / codegen.MANIFEST).read_text())
    # 16 curve parameters of the legs, then gravity (3), mass (1) and inertia (6): μ = 0;
    # then the 4 legs' geometry (10 each)
    assert info["np"] == 16 + 10 + 40 \
        and info["functions"]["touchdown_rollout"]["in"]["p"] == "66"
    assert info["param_names"][16:26] == ["gravity.x", "gravity.y", "gravity.z", "mass",
                                          "inertia.xx", "inertia.yy", "inertia.zz",
                                          "inertia.xy", "inertia.xz", "inertia.yz"]
    assert info["param_names"][26:30] == ["leg0.hinge.x", "leg0.hinge.y", "leg0.hinge.z",
                                          "leg0.e0.x"]
    for source in [*gen.sources, gen.out_dir / "main.c"]:
        # the front end's warnings (the ones CasADi's code could trigger) without optimising
        run = subprocess.run([codegen.find_compiler(), "-std=c99", *codegen.WARNINGS,
                              "-fsyntax-only", "-I", str(gen.out_dir), str(source)],
                             capture_output=True, text=True)
        assert run.returncode == 0 and run.stderr == "", run.stderr
