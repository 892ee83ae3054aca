"""What the lander design costs on compiled C and on the CasADi VM, in one run.

Solves ``studies/optimise_lander.toml`` (4 legs, 4 touchdowns, 11 design
variables, implicit step) twice: with the rollouts and their Jacobian in a
compiled library (``symcushion.design.compiled_nlp``, built once and cached), and on
the VM as before. Prints for each: total wall time, CPU time of the process,
the build (C generation, gcc cold and cached, loading), the time Ipopt
spends in the constraint Jacobian and in the rest, iterations, and the
result (worst-case peak deceleration, every limit met); then how far the two
optima are apart, and the machine's load (the benchmark is meant for a quiet
two-core machine; on a shared one, compare the CPU times).

Run: ``python studies/bench_design.py`` (add ``--no-vm`` to skip the VM
solve, ``--cold`` to rebuild the library in a fresh folder, ``--check`` for
the gradient check at the start and at the optimum on the compiled path,
``--opt-level -O0`` for other gcc flags). ``--opt-levels STUDY`` instead
measures, for a study, gcc's time and one Jacobian evaluation at -O0..-O3.

Before the compiled solve, the compiled NLP's objective and constraints at
the initial design (every scenario with its own μ, gravity, mass and inertia)
must be finite and equal to round-off to the same NLP on the CasADi VM
(``studies/bench_check.py``); the check's time is left out of the timings.
"""
from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

import casadi as ca
import numpy as np

from bench_check import ROUNDOFF_RTOL, check_equal  # studies/bench_check.py
from symcushion.design.compiled_nlp import COMPILE_FLAGS, DEFAULT_CACHE, SCENARIOS, compile_design
from symcushion.design.optimise import load_study

ROOT = Path(__file__).resolve().parents[1]
STUDY = ROOT / "studies" / "optimise_lander.toml"
#: Name of this benchmark in the messages of its checks.
BENCH = "bench_design"


def vm_reference(problem) -> tuple:
    """(x, f, g): the NLP vector of the initial design and (f, g) there on the VM.

    Call before ``use_compiled``, which makes ``fg`` evaluate the library."""
    x = problem.scaled(problem.initial)
    f, g = problem.fg(x)
    return x, f, g


def check_compiled(problem, reference) -> None:
    """Raise unless ``problem.fg`` (compiled) at the reference's x equals the VM's (f, g)."""
    x, f_vm, g_vm = reference
    f, g = problem.fg(x)
    name = "the same NLP on the CasADi VM"
    check_equal(BENCH, "compiled objective at the initial design", [f], [f_vm],
                rtol=ROUNDOFF_RTOL, reference_name=name)
    check_equal(BENCH, "compiled constraints at the initial design", g, g_vm,
                rtol=ROUNDOFF_RTOL, reference_name=name)


def opt_levels(study_path, levels=("-O0", "-O1", "-O2", "-O3"), repeats=5):
    """Per gcc level: cold compile wall time, and wall/CPU of one constraint Jacobian."""
    for level in levels:
        problem = load_study(study_path).problem
        built = compile_design(problem, tempfile.mkdtemp(prefix=SCENARIOS),
                               cflags=(level,) + COMPILE_FLAGS[1:])
        nlp = built.nlp
        jac = ca.Function("jac_g", [nlp["x"]], [ca.jacobian(nlp["g"], nlp["x"])])
        x = problem.scaled(problem.initial)
        jac(x)
        wall0, cpu0 = time.perf_counter(), time.process_time()
        for _ in range(repeats):
            jac(x)
        print(f"{level}: gcc {built.seconds['compile']:.1f} s wall; Jacobian "
              f"{(time.perf_counter() - wall0) / repeats:.3f} s wall, "
              f"{(time.process_time() - cpu0) / repeats:.3f} s CPU per evaluation", flush=True)


def run(compiled: bool, cache_dir, cflags=COMPILE_FLAGS, study_path=STUDY) -> dict:
    """Build and solve a study (default the lander) once; return the measured figures."""
    wall0, cpu0 = time.perf_counter(), time.process_time()
    study = load_study(study_path)
    problem = study.problem
    row = dict(path="compiled C" if compiled else "CasADi VM",
               problem_seconds=problem.build_seconds)
    if compiled:
        check0, check_cpu0 = time.perf_counter(), time.process_time()
        reference = vm_reference(problem)
        check_seconds = (time.perf_counter() - check0, time.process_time() - check_cpu0)
        built = problem.use_compiled(cache_dir, progress=True, cflags=cflags)
        check0, check_cpu0 = time.perf_counter(), time.process_time()
        check_compiled(problem, reference)
        # the checks are not part of what is timed
        wall0 += check_seconds[0] + time.perf_counter() - check0
        cpu0 += check_seconds[1] + time.process_time() - check_cpu0
        row.update(generate=built.seconds["generate"], gcc=built.seconds["compile"],
                   load=built.seconds["load"], cached=built.cached, threads=built.threads)
        # the same build again: what a second run of the study pays (a cache hit)
        warm0 = time.perf_counter()
        problem.use_compiled(cache_dir, cflags=cflags)
        row["warm_build"] = time.perf_counter() - warm0
    result = problem.solve(ipopt=study.ipopt)
    t = result.timings
    row.update(wall=time.perf_counter() - wall0, cpu=time.process_time() - cpu0,
               solve=t["solve_seconds"], jacobian=t["jacobian_wall_seconds"],
               jacobian_calls=t["jacobian_evaluations"],
               rest=t["solve_seconds"] - t["jacobian_wall_seconds"],
               iterations=result.iterations, status=result.return_status,
               peak=result.evaluation.objective, feasible=result.evaluation.feasible,
               theta=result.theta, result=result, problem=problem)
    return row


def _print(row):
    print(f"\n{row['path']}: {row['status']} after {row['iterations']} iterations")
    print(f"  total wall {row['wall']:.1f} s, CPU {row['cpu']:.1f} s "
          f"(problem statement {row['problem_seconds']:.1f} s)")
    if "gcc" in row:
        state = "cached" if row["cached"] else "cold"
        print(f"  build: Functions {row['generate']:.1f} s, C and gcc {row['gcc']:.1f} s "
              f"({state}), load {row['load']:.2f} s; from the warm cache {row['warm_build']:.1f} s "
              f"in all; {row['threads']} thread(s)")
    print(f"  solve {row['solve']:.1f} s: Jacobian {row['jacobian']:.1f} s "
          f"({row['jacobian_calls']} calls), rest {row['rest']:.1f} s")
    print(f"  worst-case peak deceleration {row['peak']:.4f} m/s², every limit met: "
          f"{'yes' if row['feasible'] else 'NO'}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--no-vm", action="store_true", help="skip the VM solve")
    ap.add_argument("--cold", action="store_true", help="build the library in a fresh folder")
    ap.add_argument("--check", action="store_true",
                    help="gradient check at the start and the optimum (compiled path)")
    ap.add_argument("--cache-dir", default=str(ROOT / DEFAULT_CACHE))
    ap.add_argument("--opt-level", default=COMPILE_FLAGS[0], choices=["-O0", "-O1", "-O2", "-O3"])
    ap.add_argument("--opt-levels", metavar="STUDY", help="measure gcc levels on STUDY, then stop")
    ap.add_argument("--study", default=str(STUDY), help="another design study file")
    args = ap.parse_args(argv)
    if args.opt_levels:
        opt_levels(args.opt_levels)
        return
    cflags = (args.opt_level,) + COMPILE_FLAGS[1:]
    cache = tempfile.mkdtemp(prefix=SCENARIOS) if args.cold else args.cache_dir
    print(f"{Path(args.study).name}; load average at start: {os.getloadavg()[0]:.2f} on "
          f"{os.cpu_count()} cores")
    rows = [run(True, cache, cflags, args.study)]
    _print(rows[0])
    if args.check:
        problem, result = rows[0]["problem"], rows[0]["result"]
        for label, theta in (("start", result.theta0), ("optimum", result.theta)):
            c = problem.check_gradient(theta)
            print(f"  gradient check at the {label}: relative {c['relative']:.2e}, objective "
                  f"{c['objective']:.2e}, worst row {c['worst_row']:.2e}, "
                  f"{c['nonsmooth_rows']} rows across a switch {c['nonsmooth_scenarios']}")
    if not args.no_vm:
        rows.append(run(False, cache, study_path=args.study))
        _print(rows[1])
        a, b = rows
        gap = np.max(np.abs(a["theta"] - b["theta"])) / np.max(np.abs(b["theta"]))
        print(f"\noptima apart by {gap:.2e} (max |Δθ| / max |θ|), peaks "
              f"{a['peak']:.6f} and {b['peak']:.6f} m/s²; wall ratio VM/compiled "
              f"{b['wall'] / a['wall']:.2f}, CPU ratio {b['cpu'] / a['cpu']:.2f}, "
              f"Jacobian ratio {b['jacobian'] / a['jacobian']:.2f}")
    print(f"load average at end: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
