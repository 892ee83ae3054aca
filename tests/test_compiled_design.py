"""The design NLP on compiled C (symcushion.design.compiled_nlp) against the VM path.

The 1-D absorber (studies/absorber_1d.toml) is the test problem: one leg,
200 steps, so that its library compiles in seconds. It is compiled at -O0
here (COMPILE_FLAGS_TEST): the optimisation level changes the speed of the
code, not its operations (-ffp-contract=off keeps every product and sum
rounded as written), and the test's budget is the compile time.
"""
from __future__ import annotations

from pathlib import Path

import casadi as ca
import numpy as np
import pytest

from symcushion.compiled.codegen import find_compiler
from symcushion.design.compiled_nlp import COMPILE_FLAGS, compile_design, scenario_function
from symcushion.design.optimise import load_study

ROOT = Path(__file__).resolve().parents[1]
ABSORBER = ROOT / "studies" / "absorber_1d.toml"

pytestmark = pytest.mark.skipif(find_compiler() is None, reason="needs a C compiler")

#: -O0 instead of -O1: same operations, quickest to compile (module docstring).
COMPILE_FLAGS_TEST = ("-O0",) + COMPILE_FLAGS[1:]
#: Compiled and VM evaluations run the same operations in the same order;
#: allow round-off of a 200-step rollout, relative.
SAME_TOL = 1e-10
#: The optimiser's bound on AD against central differences (as tests/test_optimise.py).
GRADIENT_TOL = 1e-5
#: Ipopt iterations compared between the Dask and the threaded path.
DASK_ITERATIONS = 8
#: Required efficiency of the 1-D absorber, (v²/2s)/peak (as tests/test_optimise.py).
EFFICIENCY_MIN = 0.98


@pytest.fixture(scope="module")
def compiled(tmp_path_factory):
    """The absorber's problem on compiled code, and the VM problem beside it."""
    cache = tmp_path_factory.mktemp("design_cache")
    problem = load_study(ABSORBER).problem
    built = problem.use_compiled(cache, cflags=COMPILE_FLAGS_TEST)
    vm = load_study(ABSORBER).problem
    return problem, vm, built, cache


def test_compiled_nlp_equals_vm_values_and_jacobian(compiled):
    """f, g and the Jacobian Ipopt uses agree with the VM to round-off: the
    Jacobian is the generated jac_design_scenarios, not finite differences
    (which would differ by ~1e-7)."""
    problem, vm, built, _ = compiled
    x = problem.scaled(problem.initial) * 0.9 + 0.05
    f_c, g_c = problem.fg(x)
    f_v, g_v = vm.fg(x)
    assert abs(f_c - f_v) <= SAME_TOL * abs(f_v)
    assert np.linalg.norm(g_c - g_v) <= SAME_TOL * np.linalg.norm(g_v)
    jacobians = []
    for nlp in (built.nlp, vm.nlp):
        jac = ca.Function("j", [nlp["x"]], [ca.jacobian(nlp["g"], nlp["x"])])
        jacobians.append(np.asarray(jac(x), dtype=float))
    assert np.linalg.norm(jacobians[0] - jacobians[1]) <= SAME_TOL * np.linalg.norm(jacobians[1])


def test_external_takes_jacobian_from_the_jac_symbol(compiled):
    """casadi.external finds jac_design_scenarios in the library: its
    Jacobian equals the symbolic Jacobian of design_scenarios exactly."""
    problem, _, built, _ = compiled
    f, jac = scenario_function(problem)
    assert jac.name() == "jac_" + f.name()
    ext = ca.external(f.name(), str(built.library))
    w = ca.MX.sym("w", problem.n_variables)
    ref = ca.Function("r", [w], [ca.jacobian(ca.vec(f(0, w)[0]), w)])
    got = ca.Function("c", [w], [ca.jacobian(ca.vec(ext(0, w)[0]), w)])
    w0 = problem.initial / problem.scale
    J_ref, J_got = np.asarray(ref(w0)), np.asarray(got(w0))
    assert np.linalg.norm(J_got - J_ref) <= SAME_TOL * np.linalg.norm(J_ref)


def test_second_build_is_cached(compiled):
    problem, _, built, cache = compiled
    again = compile_design(problem, cache, cflags=COMPILE_FLAGS_TEST)
    assert again.cached and again.seconds["compile"] == 0.0
    assert again.library == built.library
    other = compile_design(problem, cache, cflags=("-O0", "-std=c99", "-fPIC"))
    assert other.library != built.library     # other flags: another folder, another build


@pytest.fixture(scope="module")
def compiled_result(compiled):
    return compiled[0].solve()               # uses the compiled library (use_compiled)


def test_compiled_solve_reaches_the_vm_optimum_and_the_ideal_bound(compiled, compiled_result):
    """The compiled solve meets the absorber's bound; the VM problem agrees on
    the optimum's value and feasibility. (Same f, g and Jacobian, tested
    above, give Ipopt the same path; studies/bench_design.py solves both.)"""
    problem, vm, _, _ = compiled
    result = compiled_result
    assert result.return_status == "Solve_Succeeded", result.message
    assert result.efficiency >= EFFICIENCY_MIN, result.efficiency
    assert result.evaluation.feasible, result.evaluation.violations
    on_vm = vm.evaluate(result.theta)
    assert on_vm.feasible, on_vm.violations
    assert on_vm.objective == pytest.approx(result.evaluation.objective, rel=SAME_TOL)
    for theta in (result.theta0, result.theta):
        check = problem.check_gradient(theta)   # AD through the compiled Jacobian
        assert check["relative"] <= GRADIENT_TOL, check
        assert check["objective"] <= GRADIENT_TOL, check
        assert check["worst_row"] <= GRADIENT_TOL, check


@pytest.mark.parametrize("kwargs, match", [
    (dict(threads=0), "`threads`"),
    (dict(threads=1.5), "`threads`"),
    (dict(directions=0), "`directions`"),
])
def test_bad_options_name_the_argument(compiled, kwargs, match):
    problem, _, _, cache = compiled
    with pytest.raises(ValueError, match=match):
        compile_design(problem, cache, **kwargs)


def test_not_a_design_problem_is_refused(tmp_path):
    with pytest.raises(TypeError, match="`problem`"):
        compile_design(object(), tmp_path)


@pytest.fixture(scope="module")
def dask_problem(compiled):
    """The absorber evaluated on a local Dask cluster (two worker processes)."""
    distributed = pytest.importorskip("distributed")
    cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                       dashboard_address=None, silence_logs=40)
    client = distributed.Client(cluster)
    problem = load_study(ABSORBER).problem
    problem.use_compiled(compiled[3], cflags=COMPILE_FLAGS_TEST, client=client)
    yield problem
    client.close()
    cluster.close()


def test_dask_evaluation_equals_threads(compiled, dask_problem):
    problem, _, built, _ = compiled
    x = problem.scaled(problem.initial) * 0.9 + 0.05
    f_t, g_t = problem.fg(x)
    f_d, g_d = dask_problem.fg(x)
    assert f_d == f_t and np.array_equal(g_d, g_t)      # same library, same operations
    nlp_d = dask_problem._compiled_nlp
    jacobians = [np.asarray(ca.Function("j", [n["x"]], [ca.jacobian(n["g"], n["x"])])(x))
                 for n in (built.nlp, nlp_d)]
    assert np.array_equal(jacobians[0], jacobians[1])


def test_dask_solve_follows_the_threads_path(compiled, dask_problem):
    """Ipopt on Dask takes the threaded path's iterates, to round-off. (The
    first DASK_ITERATIONS iterations, to keep the test short: identical f, g
    and Jacobian give identical iterates all the way; a full run on Dask
    reaches the same optimum in the same number of iterations.)"""
    options = {"max_iter": DASK_ITERATIONS}
    on_dask = dask_problem.solve(ipopt=options)
    on_threads = compiled[0].solve(ipopt=options)
    assert on_dask.iterations == on_threads.iterations == DASK_ITERATIONS
    scale = np.max(np.abs(on_threads.theta))
    assert np.max(np.abs(on_dask.theta - on_threads.theta)) <= SAME_TOL * scale


def test_a_separately_started_scheduler_reaches_the_threads_optimum(compiled, compiled_result,
                                                                     dask_scheduler):
    """The absorber solved to the end with its scenarios on a ``dask scheduler`` started
    as its own process (two ``dask worker`` processes): the threaded solve's iterations
    and optimum."""
    import distributed
    problem = load_study(ABSORBER).problem
    with distributed.Client(dask_scheduler) as client:
        problem.use_compiled(compiled[3], cflags=COMPILE_FLAGS_TEST, client=client)
        remote = problem.solve()
    assert remote.return_status == compiled_result.return_status == "Solve_Succeeded"
    assert remote.iterations == compiled_result.iterations
    scale = np.max(np.abs(compiled_result.theta))
    assert np.max(np.abs(remote.theta - compiled_result.theta)) <= SAME_TOL * scale


def test_study_key_compile_selects_the_compiled_path():
    """``[solver] compile = true`` in a study file makes Study.solve compile."""
    import tomllib

    from symcushion.design.optimise import study_from_dict
    data = tomllib.loads(ABSORBER.read_text())
    assert load_study(ABSORBER).compiled is None         # unsaid: compile where gcc is found
    data["solver"]["compile"] = True
    assert study_from_dict(data, str(ABSORBER), base_dir=ABSORBER.parent).compiled is True
    data["solver"]["compile"] = "yes"
    with pytest.raises(ValueError, match="compile"):
        study_from_dict(data, str(ABSORBER), base_dir=ABSORBER.parent)


def test_a_study_that_says_nothing_compiles_where_gcc_is_found(monkeypatch):
    """``compile`` unsaid: the C path with a compiler, the VM with a message without one."""
    from symcushion.design.optimise import study as study_module
    said = []
    monkeypatch.setattr(study_module, "find_compiler", lambda: "/usr/bin/gcc")
    assert study_module.resolve_compiled(None, said.append) is True and not said
    monkeypatch.setattr(study_module, "find_compiler", lambda: None)
    assert study_module.resolve_compiled(None, said.append) is False
    assert len(said) == 1 and "no C compiler found" in said[0] and "compile = false" in said[0]
    assert study_module.resolve_compiled(False, said.append) is False
    assert study_module.resolve_compiled(True, said.append) is True and len(said) == 1
