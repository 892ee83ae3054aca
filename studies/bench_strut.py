"""How fast is the strut's stiffness D_p: casadi.jacobian of (2.1) or the hand formula (2.3)?

Question: the project derives D_p by automatic differentiation
(``strut_stiffness``) and keeps the paper's formula (2.3)
(``strut_stiffness_paper``) as a check. Does AD cost more to evaluate than
the hand-written formula, and does the answer depend on the CasADi symbol
type (SX scalar graphs vs MX matrix graphs)?

Method: one representative leg (crushable axial absorber with an unloading
branch, linear hinge springs, the Fig. 3 geometry). Four Functions: AD and
(2.3), each built from SX symbols (``HingedStrut.functions()``) and from MX
symbols (``force_expr``/``stiffness_paper_expr`` called on MX, AD by
``casadi.jacobian`` on the MX graph). For each: the expression size
(``n_instructions``, ``n_nodes``), and evaluations per second for single
calls from Python and for one call of ``f.map(1000)`` (serial) on 1000 poses:
the best of BEST_OF interleaved rounds, timed in process CPU time so that
other processes on a shared machine disturb the numbers less. Before
timing, each variant's D_p on the poses, with the leg's own curve parameters,
must be finite and equal to round-off to the SX AD Function's
(``studies/bench_check.py``): the AD and the hand formula are independent
derivations of one matrix.

Output: a Markdown table on stdout, also written to ``docs/strut.md`` under
"Benchmark". Run: ``python studies/bench_strut.py``.
"""
from __future__ import annotations

import platform
import time
from pathlib import Path

import casadi as ca
import numpy as np

from bench_check import ROUNDOFF_RTOL, check_equal  # studies/bench_check.py
from symcushion import Crushable, HingedStrut, Linear
from symcushion.run import report

#: Poses per batched call.
BATCH = 1000
#: Timing rounds; each variant's best round is reported (the least disturbed
#: by other processes on the machine).
BEST_OF = 15
#: Wall time aimed at per variant and round (s).
REPEAT_SECONDS = 0.05

DOC = Path(__file__).resolve().parent.parent / "docs" / "strut.md"
SECTION = "Benchmark"
#: Name of this benchmark in the messages of its checks.
BENCH = "bench_strut"


def representative_leg() -> HingedStrut:
    """The Fig. 3 leg geometry with all three elements present."""
    return HingedStrut(hinge=(0.3, 0.0, -0.18), e0=(0.0, 0.0, -1.0),
                       en=(-0.7071067811865476, 0.0, -0.7071067811865476), length=0.6,
                       S=Crushable(2e6, 8e3, 1e4, unloading=Linear(2e4)),
                       M_beta=Linear(1200.0), M_gamma=Linear(1200.0))


def mx_functions(leg: HingedStrut) -> dict[str, ca.Function]:
    """AD and (2.3) stiffness built on MX symbols (not SX Functions called on MX)."""
    r = ca.MX.sym("r", 3)
    v = ca.MX.sym("v", 3)
    p = ca.MX.sym("p", len(leg.param_names))
    P = leg.force_expr(r, v, p)
    names = (["r", "v", "p"], ["Dp"])
    return {
        "strut_stiffness": ca.Function("strut_stiffness", [r, v, p],
                                       [ca.jacobian(P, r)], *names),
        "strut_stiffness_paper": ca.Function("strut_stiffness_paper", [r, v, p],
                                             [leg.stiffness_paper_expr(r, v, p)], *names),
    }


def random_poses(leg: HingedStrut, n: int, rng) -> tuple[np.ndarray, np.ndarray]:
    """Foot positions within ~10° and ±5 % of rest, and random velocities; (3, n) each."""
    r = leg.rest_foot[:, None] + 0.06 * rng.normal(size=(3, n))
    v = rng.normal(size=(3, n))
    return r, v


def calibrate(call) -> int:
    """Calls of ``call`` that take about REPEAT_SECONDS."""
    call()                                               # warm up
    start, count = time.process_time(), 0
    while time.process_time() - start < 0.02:
        call()
        count += 1
    return max(1, int(count * REPEAT_SECONDS / 0.02))


def best_rates(timers: dict) -> dict:
    """Evaluations per CPU second of each ``timers[key] = (call, evals_per_call)``.

    The timers take turns (round robin, BEST_OF rounds) and each keeps its
    best round, so a burst of load from other processes hits all of them
    alike instead of one variant.
    """
    counts = {key: calibrate(call) for key, (call, _) in timers.items()}
    best = {key: np.inf for key in timers}
    for _ in range(BEST_OF):
        for key, (call, _) in timers.items():
            start = time.process_time()
            for _ in range(counts[key]):
                call()
            best[key] = min(best[key], (time.process_time() - start) / counts[key])
    return {key: timers[key][1] / best[key] for key in timers}


def variants(leg: HingedStrut) -> dict:
    """The four stiffness Functions by (symbols, name): AD and (2.3), on SX and on MX."""
    found = {("SX", name): f for name, f in leg.functions().items()
             if name in ("strut_stiffness", "strut_stiffness_paper")}
    found.update({("MX", name): f for name, f in mx_functions(leg).items()})
    return found


def check_variants(functions: dict, r, v, p) -> dict:
    """Each Function's D_p on the poses (r, v: (3, n)) with parameters p, checked.

    Every output must be finite and equal, to round-off, to the SX AD
    Function's (``bench_check.check_equal``); returns the outputs by key.
    """
    count = r.shape[1]
    p_batch = np.tile(np.asarray(p, dtype=float)[:, None], (1, count))
    outputs = {key: np.asarray(f.map(count)(r, v, p_batch)) for key, f in functions.items()}
    reference = outputs[("SX", "strut_stiffness")]
    for key, out in outputs.items():
        check_equal(BENCH, f"{key[0]} `{key[1]}` on {count} poses", out, reference,
                    rtol=ROUNDOFF_RTOL, reference_name="the SX `strut_stiffness` (AD of (2.1))")
    return outputs


def measure(leg: HingedStrut) -> list[dict]:
    rng = np.random.default_rng(0)
    r, v = random_poses(leg, BATCH, rng)
    p = leg.param_values
    p_batch = np.tile(p[:, None], (1, BATCH))
    functions = variants(leg)
    outputs = check_variants(functions, r, v, p)
    reference = outputs[("SX", "strut_stiffness")]
    timers, rows = {}, []
    r0, v0 = r[:, 0], v[:, 0]
    for key, f in functions.items():
        batched = f.map(BATCH)
        out = outputs[key]
        timers[key + ("single",)] = (lambda f=f: f(r0, v0, p), 1)
        timers[key + ("batch",)] = (lambda g=batched: g(r, v, p_batch), BATCH)
        rows.append(dict(symbols=key[0], function=key[1], n_instructions=f.n_instructions(),
                         n_nodes=f.n_nodes(),
                         agree=np.abs(out - reference).max() / np.abs(reference).max()))
    rates = best_rates(timers)
    for row in rows:
        row["single"] = rates[(row["symbols"], row["function"], "single")]
        row["batch"] = rates[(row["symbols"], row["function"], "batch")]
    return rows


def markdown_table(rows: list[dict]) -> str:
    lines = ["| Function | symbols | n_instructions | n_nodes | single call (evals/s) "
             f"| map({BATCH}) (evals/s) | max rel. diff. to SX AD |",
             "|---|---|---:|---:|---:|---:|---:|"]
    for row in rows:
        lines.append(f"| `{row['function']}` | {row['symbols']} | {row['n_instructions']} "
                     f"| {row['n_nodes']} | {row['single']:,.0f} | {row['batch']:,.0f} "
                     f"| {row['agree']:.1e} |")
    return "\n".join(lines)


#: Speed ratios within this factor of 1 are reported as "about as fast": twice
#: the spread of one variant between runs (measured: ±10 % in CPU time).
NOISE = 1.25


def summary(rows: list[dict]) -> str:
    """A paragraph stating what the numbers show; its verdicts follow the numbers."""
    get = {(row["symbols"], row["function"]): row for row in rows}
    ad_sx, paper_sx = get[("SX", "strut_stiffness")], get[("SX", "strut_stiffness_paper")]
    ad_mx, paper_mx = get[("MX", "strut_stiffness")], get[("MX", "strut_stiffness_paper")]

    def compare(a, b):
        ratio = a / b
        if 1 / NOISE < ratio < NOISE:
            return f"about as fast as ({ratio:.2f}×)"
        return f"{ratio:.1f}× as fast as" if ratio >= 1 else f"{1 / ratio:.1f}× slower than"

    ad_vs_paper = ad_sx["batch"] / paper_sx["batch"]
    if ad_vs_paper > 1 / NOISE:
        verdict = ("so deriving D_p by AD instead of by hand costs nothing measurable at "
                   "run time: the jacobian of the scalar graph reuses the geometry the "
                   "force already computes, and its graph is the smaller of the two")
    else:
        verdict = (f"so deriving D_p by AD costs {100 * (1 / ad_vs_paper - 1):.0f} % at run "
                   "time over the hand formula")
    mx_slower = (ad_mx["batch"] * NOISE < ad_sx["batch"]
                 and paper_mx["batch"] * NOISE < paper_sx["batch"])
    if mx_slower:
        mx_verdict = (f"the graphs are of similar size ({ad_mx['n_nodes']} and "
                      f"{paper_mx['n_nodes']} MX nodes against {ad_sx['n_nodes']} and "
                      f"{paper_sx['n_nodes']} SX nodes), but each MX node goes through "
                      "a generic, matrix-capable evaluation that costs more than an SX "
                      "scalar operation; a strut is all scalar arithmetic, so SX is the "
                      "right symbol type for it")
    else:
        mx_verdict = "MX is not clearly slower here, so either symbol type serves"
    overhead = ad_sx["batch"] / ad_sx["single"]
    singles = [row["single"] for row in rows]
    alike = ("about the same for all four variants" if max(singles) < 2 * min(singles)
             else f"between {min(singles):,.0f} and {max(singles):,.0f} for the four")
    return (
        f"Batched, the AD stiffness on SX evaluates {compare(ad_sx['batch'], paper_sx['batch'])} "
        f"the hand formula (2.3) on SX ({ad_sx['batch']:,.0f} vs {paper_sx['batch']:,.0f} "
        f"evaluations/s; {ad_sx['n_instructions']} vs {paper_sx['n_instructions']} "
        f"instructions), {verdict}. Built on MX, the AD Function runs "
        f"{compare(ad_mx['batch'], ad_sx['batch'])} its SX twin and (2.3) "
        f"{compare(paper_mx['batch'], paper_sx['batch'])} its SX twin: {mx_verdict}. "
        f"A single call from Python manages {ad_sx['single']:,.0f} evaluations/s "
        f"(SX AD), {overhead:.0f}× fewer than in a batch, and {alike}: the call overhead, "
        f"not the arithmetic, sets the cost of one evaluation, so a simulator should "
        f"evaluate its legs in one mapped call or inside a larger Function. All four agree "
        f"to {max(row['agree'] for row in rows):.0e} relative. Measured with CasADi "
        f"{ca.__version__} on {platform.machine()} ({platform.python_implementation()} "
        f"{platform.python_version()}), serial map, best of {BEST_OF} interleaved rounds "
        f"of process CPU time (the machine is shared; repeated runs spread by about "
        f"±10 %); rerun "
        f"`python studies/bench_strut.py` to refresh.")


def write_section(path, heading: str, body: str) -> None:
    """Replace (or append) a section of this study's docs page."""
    report.write_section(path, heading, body, title='# The hinged strut')


def main() -> None:
    leg = representative_leg()
    rows = measure(leg)
    table = markdown_table(rows)
    print(table)
    text = summary(rows)
    print()
    print(text)
    intro = ("Produced by `studies/bench_strut.py`: D_p of one leg (Fig. 3 geometry, "
             "crushable axial absorber with unloading branch, linear hinge springs) "
             "by `casadi.jacobian` of (2.1) (`strut_stiffness`) and by the hand formula "
             f"(2.3) (`strut_stiffness_paper`), each built on SX and on MX symbols; "
             f"single calls and one `map({BATCH})` call on {BATCH} random poses.")
    write_section(DOC, SECTION, f"{intro}\n\n{table}\n\n{text}")
    print(f"\nwritten to {DOC} under '## {SECTION}'")


if __name__ == "__main__":
    main()
