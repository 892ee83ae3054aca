"""How the envelope design's scenario evaluation scales with threads and Dask workers.

Question: for ``studies/design_for_envelope.toml`` (its scenarios, horizon and
design variables), how long does one evaluation of every scenario's
ratios, and one of their Jacobian (what Ipopt calls once per iteration),
take on one and two threads, and on a local Dask cluster of one and two
single-threaded worker processes? All in one run, on the same scenarios and
the same compiled library; the ratio to one thread is printed, and the
Jacobians are checked equal bit for bit across the backends.

Method: the study's pool (its size and seed), the study's scenario selection,
then ``EnvelopeDesign`` built once per backend; best of ``REPEATS`` calls.
Before timing, the compiled ratios at the study's initial design (the
scenarios' own parameters: μ, slope gravity, mass, inertia, the curves) must
be finite and equal to round-off to the same graph on the CasADi VM
(``EnvelopeDesign.reference_ratios``), and every backend's ratios and
Jacobian finite and equal, bit for bit, to one thread's
(``studies/bench_check.py``).

Run: ``PYTHONPATH=. python studies/bench_design_envelope.py [--pool N]``.
"""
from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

import casadi as ca
import numpy as np

from bench_check import BITWISE, ROUNDOFF_RTOL, check_equal, check_finite  # studies/
from symcushion.envelope import run_envelope
from symcushion.design.robust import EnvelopeDesign
from symcushion.design.robust.select import select_scenarios
from symcushion.design.robust.study import load_robust_study

ROOT = Path(__file__).resolve().parents[1]
STUDY = ROOT / "studies" / "design_for_envelope.toml"
#: Timed calls per backend (the best is kept: a shared machine only adds time).
REPEATS = 3
#: Name of this benchmark in the messages of its checks.
BENCH = "bench_design_envelope"


def check_reference(problem) -> None:
    """Raise unless the compiled ratios at the initial design equal the VM's (to round-off)."""
    check_equal(BENCH, f"compiled ratios of {problem.x0.shape[1]} scenarios at the initial "
                "design", problem.ratios(), problem.reference_ratios(), rtol=ROUNDOFF_RTOL,
                reference_name="touchdown_margins on the CasADi VM")


def check_backend(name: str, problem, x, reference=None) -> tuple:
    """(ratios, Jacobian) of one backend at x, checked: finite, and bit for bit equal
    to ``reference`` (one thread's pair) when given."""
    jac = ca.Function("j", [problem.nlp["x"]], [ca.jacobian(problem.nlp["g"], problem.nlp["x"])])
    theta = x[:problem.n_variables] * problem.scale
    got = (check_finite(BENCH, f"{name}: ratios", problem.ratios(theta)),
           check_finite(BENCH, f"{name}: constraint Jacobian", np.asarray(jac(x))))
    if reference is not None:
        for label, value, ref in zip(("ratios", "constraint Jacobian"), got, reference):
            check_equal(BENCH, f"{name}: {label}", value, ref, rtol=BITWISE,
                        reference_name="one thread's")
    return got


def _time(problem, x):
    jac = ca.Function("j", [problem.nlp["x"]], [ca.jacobian(problem.nlp["g"], problem.nlp["x"])])
    theta = x[:problem.n_variables] * problem.scale
    best_r = best_j = np.inf
    for _ in range(REPEATS):
        t0 = time.perf_counter()
        problem.ratios(theta)
        best_r = min(best_r, time.perf_counter() - t0)
        t0 = time.perf_counter()
        J = np.asarray(jac(x))
        best_j = min(best_j, time.perf_counter() - t0)
    return best_r, best_j, J


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pool", type=int, default=None, help="pool size (default: the study's)")
    args = parser.parse_args()
    study = load_robust_study(STUDY)
    pool = run_envelope(study.envelope.with_(n=args.pool or study.pool, seed=study.pool_seed),
                        progress=False, plots=False)
    idx = select_scenarios(pool.columns, study.scenarios, fail_share=study.fail_share,
                           worst=study.worst_margin)
    cond = {k: v[idx] for k, v in pool.conditions.items()}
    common = dict(horizon=study.horizon, risk=study.risk, alpha=study.alpha)
    print(f"{STUDY.name}: {idx.size} scenarios of {study.horizon:g} s, "
          f"{len(study.variables)} variable groups; load {os.getloadavg()[0]:.2f} on "
          f"{os.cpu_count()} cores; best of {REPEATS}")
    rows, reference = [], None
    for threads in (1, 2):
        problem = EnvelopeDesign(study.envelope, cond, study.variables, threads=threads,
                                 **common)
        x = problem.scaled(problem.initial)
        if reference is None:
            check_reference(problem)
        checked = check_backend(f"threads {threads}", problem, x, reference)
        reference = checked if reference is None else reference
        r, j, J = _time(problem, x)
        rows.append((f"threads {threads}", r, j, np.array_equal(J, reference[1])))
    try:
        import distributed
    except ImportError:
        distributed = None
        print("(Dask rows skipped: pip install 'symcushion[dask]')")
    for workers in ((1, 2) if distributed else ()):
        cluster = distributed.LocalCluster(n_workers=workers, threads_per_worker=1,
                                           processes=True, dashboard_address=None,
                                           silence_logs=40)
        client = distributed.Client(cluster)
        try:
            problem = EnvelopeDesign(study.envelope, cond, study.variables, client=client,
                                     **common)
            problem.ratios(problem.initial)          # workers load the library once
            check_backend(f"Dask, {workers} worker(s)", problem, x, reference)
            r, j, J = _time(problem, x)
            rows.append((f"Dask, {workers} worker(s)", r, j, np.array_equal(J, reference[1])))
        finally:
            client.close()
            cluster.close()
    base_r, base_j = rows[0][1], rows[0][2]
    print(f"{'backend':22s} {'ratios (s)':>11s} {'×':>6s} {'Jacobian (s)':>13s} {'×':>6s}  "
          "same Jacobian")
    for name, r, j, same in rows:
        print(f"{name:22s} {r:11.3f} {base_r / r:6.2f} {j:13.3f} {base_j / j:6.2f}  {same}")


if __name__ == "__main__":
    main()
