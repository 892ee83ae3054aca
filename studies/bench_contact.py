"""How close are the printed and the robust contact steps to the exact one, and what do they cost?

Question: the printed step (1.8)-(1.15) (``contact_step_paper``), the same
step with docs/paper-notes.md §3 items 1-5 fixed (``contact_step_robust``) and the exact
backward-Euler Coulomb step (``contact_step_implicit``) all map
(P0, D_p, n, l, mu, u0) to the force P at the end of a step. How far is each
from the implicit one, in plane-parallel motion (the case the paper derives)
and in 3-D; how large is each graph and how fast does it evaluate, from
Python and compiled?

Method:

- Plane-parallel cases: n, l and P0 in one plane; D_p symmetric positive
  definite with that plane invariant (a rotated 2x2 block, cond up to 1e3,
  plus an out-of-plane stiffness); P0 on the cone (half the cases, as a
  sliding step leaves it) or inside; mu in [0.05, 2], and a tenth of the
  cases with mu = 0.
- 3-D cases: n, l random; D_p symmetric positive definite (cond up to 1e4),
  half of them with a skew part (non-symmetric, positive-definite symmetric
  part); P0 on or inside the cone.
- Error of a method: |P - P_implicit| / |P_implicit - P0|, the error relative
  to the force increment of the step. "Both in contact" restricts to cases
  where both steps keep contact; "contact differs" counts the cases where one
  lifts off and the other does not.
- Cost: ``n_instructions``, ``n_nodes``; evaluations per second for a single
  call from Python and for one call of ``f.map(BATCH)`` (serial), best of
  BEST_OF repeats.
- Compiled cost: the steps generated into one C library at -O3 and timed
  in one C harness (``symcushion/compiled/c/bench_contact.c``) on the same cases:
  ns per evaluation and the implicit/robust ratio; also the steps as the
  simulator calls them (``contact_step_call``: the implicit step skips its
  slip part for a sticking foot), in a second library timed by the same
  harness. Before the C timing, one pass of each harness over the cases
  must give finite outputs equal (to round-off, ``bench_check``) to the
  same steps evaluated on the CasADi VM; before the Python timing, each
  timed Function's outputs must be finite and its single call equal to its
  mapped call on the same case.

Output: Markdown tables on stdout, also written to ``docs/contact.md`` under
"Benchmark". Run: ``python studies/bench_contact.py``.
"""
from __future__ import annotations

import os
import platform
import subprocess
import tempfile
import time
from pathlib import Path

import casadi as ca
import numpy as np

from bench_check import (BITWISE, ROUNDOFF_RTOL, BenchmarkCheckError, check_equal,  # studies/
                         check_finite)
from symcushion.compiled import codegen
from symcushion.run import report
from symcushion.contact import (INPUT_NAMES, METHODS, OUTPUT_NAMES, contact_step,
    contact_step_call, stack_inputs)
from symcushion.contact.args import INPUT_SHAPES

#: Random cases per family.
CASES = 20000
#: Cases per batched call in the timing.
BATCH = 10000
#: Timing repeats; the best is reported (the least disturbed by the machine).
BEST_OF = 5
#: Wall time aimed at per timing repeat (s).
REPEAT_SECONDS = 0.2
#: Cases of the compiled C timing, and passes over them per run.
NATIVE_CASES = 2000
C_REPEAT = 20

DOC = Path(__file__).resolve().parent.parent / "docs" / "contact.md"
#: The C timing loop (symcushion/compiled/c/bench_contact.c).
HARNESS = Path(codegen.__file__).parent / "c" / "bench_contact.c"
SECTION = "Benchmark"
#: Name of this benchmark in the messages of its checks.
BENCH = "bench_contact"
#: Columns of each output in a row of the harness's output file (OUT_SIZE = 10
#: doubles per case and step, in OUTPUT_NAMES order: delta, P, k, contact).
HARNESS_COLUMNS = {"delta": slice(0, 3), "P": slice(3, 6), "k": slice(6, 9),
                   "contact": slice(9, 10)}
HARNESS_WIDTH = 10


# ---------------------------------------------------------------------------
# random cases, as (6, ...) argument lists for a mapped Function
# ---------------------------------------------------------------------------
def _rotation(rng):
    Q, R = np.linalg.qr(rng.normal(size=(3, 3)))
    return Q * np.sign(np.diag(R))


def _unit(v):
    return v / np.linalg.norm(v)


def plane_parallel_cases(rng, count, mu_zero=None):
    """n, l, P0 in one plane; SPD D_p with that plane invariant. ``mu_zero``: None,
    μ = 0 in a tenth of the cases (drawn); True, in all; False, in none (the tests'
    cases, tests/test_contact.py)."""
    cases = []
    for _ in range(count):
        n = _unit(rng.normal(size=3))
        x = _unit(np.cross(n, rng.normal(size=3)))
        y = np.cross(n, x)
        E = np.stack([x, n], 1)
        th = rng.uniform(0, np.pi)
        R2 = np.array([[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]])
        B = R2 @ np.diag([1, 10 ** rng.uniform(0, 3)]) @ R2.T * 10 ** rng.uniform(0, 3)
        Dp = E @ B @ E.T + rng.uniform(0.1, 10) * B.max() * np.outer(y, y)
        if mu_zero is None:
            mu = 0.0 if rng.random() < 0.1 else rng.uniform(0.05, 2)
        else:
            mu = 0.0 if mu_zero else rng.uniform(0.05, 2)
        N0 = abs(rng.normal()) + 0.1
        fraction = rng.choice([-1.0, 1.0]) if rng.random() < 0.5 else rng.uniform(-1, 1)
        P0 = N0 * (n + fraction * mu * x)
        l = E @ rng.normal(size=2) * 0.01 * 10 ** rng.uniform(-2, 1)
        cases.append((P0, Dp, n, l, mu, np.linalg.solve(Dp, P0)))
    return cases


def spatial_cases(rng, count, max_log_cond=4.0, kind="mixed"):
    """Random 3-D cases, mu in [0.05, 2].

    kind: 'mixed' (half SPD, half SPD + skew), 'spd', 'skew' (SPD + skew,
    positive-definite symmetric part), 'indefinite' (SPD + a general
    perturbation of 30 % of its norm).
    """
    cases = []
    for _ in range(count):
        n = _unit(rng.normal(size=3))
        ev = 10 ** rng.uniform(0, max_log_cond, 3)
        ev[0], ev[1] = 1.0, 10**max_log_cond
        Q = _rotation(rng)
        Dp = Q @ np.diag(ev) @ Q.T * 10 ** rng.uniform(0, 3)
        norm = np.linalg.norm(Dp, 2)
        this = kind if kind != "mixed" else ("spd" if rng.random() < 0.5 else "skew")
        if this == "skew":
            W = rng.normal(size=(3, 3))
            Dp = Dp + 0.3 * (W - W.T) * norm
        elif this == "indefinite":
            Dp = Dp + 0.3 * rng.normal(size=(3, 3)) * norm
        mu = rng.uniform(0.05, 2)
        t = _unit(np.cross(n, rng.normal(size=3)))
        N0 = 10 ** rng.uniform(-1, 2)
        fraction = 1.0 if rng.random() < 0.5 else rng.uniform(0, 1)
        P0 = N0 * (n + fraction * mu * t)
        l = rng.normal(size=3) * N0 / norm * 10 ** rng.uniform(-2, 1)
        u0 = np.linalg.lstsq(Dp, P0, rcond=None)[0]
        cases.append((P0, Dp, n, l, mu, u0))
    return cases


def stack(cases):
    """Arguments of a mapped contact-step Function."""
    return stack_inputs(cases)


def evaluate(f, cases):
    out = f.map(len(cases))(*stack(cases))
    return {key: np.array(value) for key, value in zip(OUTPUT_NAMES, out)}


# ---------------------------------------------------------------------------
# measurements
# ---------------------------------------------------------------------------
def agreement(cases):
    """Per method: errors relative to the force increment, and contact mismatches.

    Split by what the implicit step does: stick (P_implicit = P0 + D_p l),
    slip in contact, or lift-off.
    """
    P0 = stack(cases)[0]
    ref = evaluate(contact_step("implicit"), cases)
    increment = np.linalg.norm(ref["P"] - P0, axis=0)
    in_contact = ref["contact"][0] == 1
    slip = in_contact & (np.linalg.norm(ref["k"], axis=0) > 0)
    stick = in_contact & ~slip
    rows = {}
    for method in METHODS:
        out = evaluate(contact_step(method), cases)
        error = np.linalg.norm(out["P"] - ref["P"], axis=0) / np.where(increment > 0, increment, 1)
        both = slip & (out["contact"][0] == 1)
        rows[method] = dict(
            stick_max=error[stick].max(),
            slip_count=int(slip.sum()),
            slip_median=np.median(error[slip]),
            slip_p99=np.percentile(error[slip], 99),
            slip_max_both=error[both].max(),
            differs=int((out["contact"][0] != ref["contact"][0]).sum()),
            count=len(cases),
        )
    return rows


def robust_breakdown(cases):
    """Where robust and implicit disagree in the plane-parallel cases, and why."""
    out = evaluate(contact_step("robust"), cases)
    ref = evaluate(contact_step("implicit"), cases)
    P0, _, n, l, mu, _ = stack(cases)
    mu = mu[0]
    increment = np.linalg.norm(ref["P"] - P0, axis=0)
    error = np.linalg.norm(out["P"] - ref["P"], axis=0) / np.where(increment > 0, increment, 1)
    both = (out["contact"][0] == 1) & (ref["contact"][0] == 1)
    only_robust = (out["contact"][0] == 1) & (ref["contact"][0] == 0)
    # friction against the slip in the robust answer: P_tau . g < 0
    g = l - out["delta"]
    g = g - np.sum(g * n, 0) * n
    P_tau = out["P"] - np.sum(out["P"] * n, 0) * n
    anti = np.sum(P_tau * g, 0) < 0
    N_t = np.sum((P0 + np.einsum("ijk,jk->ik", stack_matrices(cases), l)) * n, 0)
    worst_small_mu = np.argmax(np.where(both & (mu > 0), error, -1))
    return dict(
        both_mu_pos_max=error[both & (mu > 0)].max(),
        both_mu_pos_p99=np.percentile(error[both & (mu > 0)], 99),
        worst_mu=mu[worst_small_mu],
        both_mu0_max=error[both & (mu == 0)].max(),
        only_robust=int(only_robust.sum()),
        only_robust_anti=int((only_robust & anti).sum()),
        only_robust_tension=int((only_robust & (N_t <= 0)).sum()),
        only_implicit=int(((out["contact"][0] == 0) & (ref["contact"][0] == 1)).sum()),
        both_anti=int((both & (mu > 0) & anti).sum()),
        count=len(cases),
    )


def stack_matrices(cases):
    """D_p of every case, shape (3, 3, N)."""
    return np.stack([c[1] for c in cases], axis=2)


def called_program(out: Path) -> Path:
    """The C harness on the three steps as the simulator calls them.

    Each ``contact_step_<method>`` of this library is an SX Function holding
    one call of ``contact_step_call(method, ...)``: for the implicit step the
    stick test and then, through ``Function.conditional``, either the stick
    branch or the full step; for the paper and robust steps the full step
    (they have no such shortcut). Generated with ``codegen.CODEGEN_OPTIONS``
    and compiled with ``codegen.CFLAGS``, as the kernels.
    """
    functions = []
    for method in METHODS:
        args = [ca.SX.sym(name, *shape) for name, shape in zip(INPUT_NAMES, INPUT_SHAPES)]
        step = contact_step_call(method, *args, friction=True)
        functions.append(ca.Function(f"contact_step_{method}", args,
                                     [step[key] for key in OUTPUT_NAMES], INPUT_NAMES,
                                     OUTPUT_NAMES))
    generator = ca.CodeGenerator("symcushion_kernels.c", dict(codegen.CODEGEN_OPTIONS))
    for f in functions:
        generator.add(f)
    generator.generate(str(out) + os.sep)
    (out / "symcushion.h").write_text('#include "symcushion_kernels.h"\n')
    program = out / "bench_contact"
    subprocess.run([codegen.find_compiler(), *codegen.CFLAGS, "-I", str(out), str(HARNESS),
                    str(out / "symcushion_kernels.c"), "-o", str(program), "-lm"],
                   check=True, capture_output=True)
    return program


def native_ratio(cases, called=False):
    """ns per evaluation of the three steps in one C harness (-O3), same cases.

    The three steps are generated into one library by ``symcushion.compiled.codegen``
    (``CFLAGS``: -O3) and timed by ``symcushion/compiled/c/bench_contact.c`` (a loop
    over the cases calling each generated function, clock_gettime), in one
    process run per repeat, best of BEST_OF runs. With ``called``, the steps
    as the simulator calls them (:func:`called_program`). Returns the best ns
    per evaluation by Function name, and under ``"outputs"`` the bytes the
    harness wrote (every step's outputs on every case).
    """
    P0, Dp, n, l, mu, u0 = stack(cases)
    count = P0.shape[1]
    Dp = stack_matrices(cases)  # (3, 3, N)
    table = np.column_stack([P0.T, Dp.transpose(2, 1, 0).reshape(count, 9), n.T, l.T,
                             mu.T, u0.T])
    best = {}
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp)
        np.ascontiguousarray(table, dtype=np.float64).tofile(out / "cases.bin")
        if called:
            program = called_program(out)
        else:
            codegen.generate(out, build=True)
            program = codegen.build_program(out, HARNESS)
        arguments = [str(program), str(out / "cases.bin"), "1", str(out / "out.bin")]
        subprocess.run(arguments, capture_output=True, check=True)
        outputs = (out / "out.bin").read_bytes()
        check_native(outputs, cases, called)
        arguments[2] = str(C_REPEAT)
        for _ in range(BEST_OF):
            run = subprocess.run(arguments, capture_output=True, text=True, check=True)
            for line in run.stdout.splitlines():
                name, value = line.split()
                best[name] = min(best.get(name, np.inf), float(value.split("=")[1]))
        best["outputs"] = outputs
    return best


def check_native(outputs: bytes, cases, called: bool) -> None:
    """Raise unless the harness's outputs equal the steps on the CasADi VM.

    ``outputs`` is what ``symcushion/compiled/c/bench_contact.c`` wrote: for each step of
    METHODS and each case, the outputs of OUTPUT_NAMES (HARNESS_COLUMNS). Each
    must be finite and equal, to round-off (ROUNDOFF_RTOL), to
    ``contact_step(method)`` mapped over the same cases on the VM.
    """
    got = np.frombuffer(outputs, dtype=np.float64)
    shape = (len(METHODS), len(cases), HARNESS_WIDTH)
    if got.size != np.prod(shape):
        raise BenchmarkCheckError(f"{BENCH}: the harness wrote {got.size} doubles, expected "
                                  f"{np.prod(shape)} (steps × cases × outputs = {shape}).")
    got = got.reshape(shape)
    how = "as the simulator calls it" if called else "branch-free graph"
    for k, method in enumerate(METHODS):
        reference = evaluate(contact_step(method), cases)
        for name in OUTPUT_NAMES:
            check_equal(BENCH, f"compiled contact_step_{method} ({how}) output `{name}`",
                        got[k][:, HARNESS_COLUMNS[name]], reference[name].T,
                        rtol=ROUNDOFF_RTOL, reference_name="contact_step on the CasADi VM")


def check_cost(f, batched, one, args) -> None:
    """Raise unless the Functions :func:`cost` times give finite, consistent outputs:
    ``batched(*args)`` finite, and ``f(*one)`` equal, bit for bit, to its first case."""
    many = [np.asarray(o, dtype=float) for o in batched(*args)]
    single = [np.asarray(o, dtype=float) for o in f(*one)]
    for name, column, value in zip(OUTPUT_NAMES, many, single):
        check_finite(BENCH, f"`{f.name()}` mapped output `{name}`", column)
        check_equal(BENCH, f"`{f.name()}` single-call output `{name}`", value.ravel(),
                    column[:, 0], rtol=BITWISE, reference_name="its mapped call's first case")


def stick_share(cases):
    """A sentence: how many of the cases stick, slip and lift off in the implicit step."""
    out = evaluate(contact_step("implicit"), cases)
    contact = out["contact"][0] == 1
    slip = contact & (np.linalg.norm(out["k"], axis=0) > 0)
    return (f"Of the {len(cases)} cases the implicit step sticks in {int((contact & ~slip).sum())}, "
            f"slips in {int(slip.sum())} and lifts off in {int((~contact).sum())}.")


def evals_per_second(call, evals_per_call):
    """Best-of-BEST_OF rate of ``call()``, in evaluations per second."""
    call()
    start = time.perf_counter()
    count = 0
    while time.perf_counter() - start < 0.05:
        call()
        count += 1
    per_repeat = max(1, int(count * REPEAT_SECONDS / 0.05))
    best = np.inf
    for _ in range(BEST_OF):
        start = time.perf_counter()
        for _ in range(per_repeat):
            call()
        best = min(best, (time.perf_counter() - start) / per_repeat)
    return evals_per_call / best


def cost(cases):
    args = stack(cases[:BATCH])
    one = [a[:, 0] if a.shape[1] == BATCH else a[:, :3] for a in args]
    one[4] = float(args[4][0, 0])
    rows = []
    for method in METHODS:
        for friction in (True, False):
            f = contact_step(method, friction)
            batched = f.map(BATCH)
            check_cost(f, batched, one, args)
            rows.append(dict(
                function=f.name(), n_instructions=f.n_instructions(), n_nodes=f.n_nodes(),
                single=evals_per_second(lambda: f(*one), 1),
                batch=evals_per_second(lambda: batched(*args), BATCH)))
    return rows


# ---------------------------------------------------------------------------
# output
# ---------------------------------------------------------------------------
def agreement_table(plane, spatial):
    lines = ["| method | cases | implicit sticks: max | implicit slips: cases | median | p99 "
             "| max, both in contact | contact differs |",
             "|---|---|---:|---:|---:|---:|---:|---:|"]
    for family, rows in (("plane-parallel", plane), ("3-D", spatial)):
        for method in METHODS:
            a = rows[method]
            lines.append(
                f"| `{method}` | {family} | {a['stick_max']:.1e} | {a['slip_count']} | "
                f"{a['slip_median']:.1e} | {a['slip_p99']:.1e} | {a['slip_max_both']:.1e} | "
                f"{a['differs']} / {a['count']} |")
    return "\n".join(lines)


def cost_table(rows):
    lines = ["| Function | n_instructions | n_nodes | single call (evals/s) "
             f"| map({BATCH}) (evals/s) |", "|---|---:|---:|---:|---:|"]
    for row in rows:
        lines.append(f"| `{row['function']}` | {row['n_instructions']} | {row['n_nodes']} "
                     f"| {row['single']:,.0f} | {row['batch']:,.0f} |")
    return "\n".join(lines)


def native_table(ns, called):
    rows = ["| Function (C, -O3) | branch-free graph: ns per evaluation "
            "| as the simulator calls it: ns per evaluation |", "|---|---:|---:|"]
    rows += [f"| `{name}` | {value:.0f} | {called[name]:.0f} |" for name, value in ns.items()]
    ratio = ns["contact_step_implicit"] / ns["contact_step_robust"]
    ratio_called = called["contact_step_implicit"] / called["contact_step_robust"]
    return "\n".join(rows) + (
        f"\n\nimplicit / robust per evaluation, as the simulator calls them: "
        f"**{ratio_called:.2f}** (target ≤ 1.5); branch-free graphs: {ratio:.2f}.")


def breakdown_text(b):
    return (
        f"Robust vs implicit, plane-parallel cases ({b['count']}): where both keep contact "
        f"and mu > 0 the worst error is {b['both_mu_pos_max']:.1e} of the force increment "
        f"(p99 {b['both_mu_pos_p99']:.1e}; the worst case has mu = {b['worst_mu']:.3f}); "
        f"with mu = 0 the worst is {b['both_mu0_max']:.1e}. The robust step keeps contact "
        f"where the implicit one lifts off in {b['only_robust']} cases, all of them with "
        f"friction along the slip in the robust answer (P_tau·g < 0: "
        f"{b['only_robust_anti']} of {b['only_robust']}), {b['only_robust_tension']} of them "
        f"with a tensile trial force n·P_t ≤ 0; the opposite happens in "
        f"{b['only_implicit']} cases. Where both keep contact (mu > 0), "
        f"{b['both_anti']} robust answers have P_tau·g < 0.")


def write_section(path, heading: str, body: str) -> None:
    """Replace (or append) a section of this study's docs page."""
    report.write_section(path, heading, body, title='# The contact step')


def main() -> None:
    rng = np.random.default_rng(2024)
    plane = plane_parallel_cases(rng, CASES)
    spatial = spatial_cases(rng, CASES)
    table_a = agreement_table(agreement(plane), agreement(spatial))
    breakdown = breakdown_text(robust_breakdown(plane))
    table_b = cost_table(cost(spatial))
    ns = native_ratio(spatial[:NATIVE_CASES])
    called = native_ratio(spatial[:NATIVE_CASES], called=True)
    same = ns.pop("outputs") == called.pop("outputs")
    environment = (f"CasADi {ca.__version__} on {platform.machine()} "
                   f"({platform.python_implementation()} {platform.python_version()}), "
                   f"serial map, best of {BEST_OF} repeats.")
    body = "\n\n".join([
        "Produced by `studies/bench_contact.py` (rerun to refresh). Error = "
        "|P − P_implicit| / |P_implicit − P0|, the error relative to the force increment "
        f"of the step, over {CASES} random plane-parallel and {CASES} random 3-D cases "
        "(P0 on or inside the cone).",
        "### Agreement with the implicit step", table_a, breakdown,
        "### Size and speed", table_b, environment,
        "### Compiled, one C harness",
        f"The three steps compiled at -O3 into one library and timed in one C loop over "
        f"the same {NATIVE_CASES} random 3-D cases, best of {BEST_OF} runs "
        f"({C_REPEAT} passes each; a loaded 2-core machine: ratios from one run). "
        "The second column times the steps as `symcushion.simulate` calls them "
        "(`contact_step_call`): the implicit step runs its stick test first and the "
        "slip part only when the trial force does not stick (`Function.conditional`); "
        "the paper and robust calls have no such shortcut. "
        f"{stick_share(spatial[:NATIVE_CASES])} The two libraries' outputs are "
        f"{'the same bits' if same else 'NOT the same bits'}.",
        native_table(ns, called),
    ])
    print(body)
    write_section(DOC, SECTION, body)
    print(f"\nwritten to {DOC} under '## {SECTION}'")


if __name__ == "__main__":
    main()
