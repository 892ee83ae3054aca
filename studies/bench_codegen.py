"""What does generated C buy over the CasADi VM and over NumPy?

Question: symcushion's Functions run in CasADi's virtual machine (the SX
Function) or, generated to C by ``symcushion.compiled.codegen``, as compiled code.
How much faster is the compiled code, for one contact step and for a whole
touchdown, and is a 4-leg touchdown step fast enough for real time?

Method.
Contact steps: the three steps on BATCH random cases of the test oracle's
distribution (``tests/oracle_contact.random_cases``, all kinds), evaluated by
the NumPy oracle (``tests/oracle_contact.py``, one case per call), by the
SX Function and by the compiled library via ``casadi.external``, each from
Python one case per call and in one ``map(BATCH)`` call (serial, inputs
converted to DM beforehand), and in C by ``symcushion/compiled/c/bench_contact.c``
(a loop over the cases calling the generated function, clock_gettime).
Touchdown: the Fig. 3 drop (``studies/fig3.toml``: 4 legs, method 'paper',
μ = 0, Δt = 1 ms) run for DROP_SECONDS: a Python loop over the VM's
``touchdown_step``; the VM's ``touchdown_rollout`` (one call, mapaccum); the
compiled ``touchdown_rollout`` via ``casadi.external``; and the standalone
program ``touchdown`` (C only), timed from outside as a process (start to
exit, CSV written, nothing subtracted) and from inside with clock_gettime
over its step loop. Python-side timings are the best of BEST_OF interleaved
rounds of process CPU time; the program's, the best of BEST_OF runs of wall
time. Before anything is timed, what is timed is checked (``studies/bench_check.py``):
the compiled contact steps (``casadi.external``, mapped, and the C loop)
finite and equal to the SX Function on the VM to round-off; the Fig. 3 drop,
with the scene's own parameters (``model.default_p``), finite and equal bit
for bit to the VM rollout for the compiled rollout, both Python step loops and
the standalone program's CSV. With ``--large`` the script also builds the implicit step with
friction (Fig. 4 scene with method 'implicit', the largest graph) and
recompiles each generated source at -O3, -O2 and -O1: gcc's CPU time, and
the program's time per step built from each.

Output: Markdown tables on stdout, written to ``docs/codegen.md`` under
"## Benchmark" (and "## Compile-time benchmark" with ``--large``).
Run: ``python studies/bench_codegen.py [--large]``.
"""
from __future__ import annotations

import argparse
import importlib.util
import json
import platform
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import casadi as ca
import numpy as np

from bench_check import BITWISE, ROUNDOFF_RTOL, check_equal, check_rollout  # studies/
from symcushion.compiled import codegen
from symcushion.compiled.codegen import (CFLAGS, build_program, compiled_model, generate,
    load_compiled)
from symcushion.contact.args import METHODS
from symcushion.contact.dispatch import contact_step
from symcushion.model.scene import load_scene
from symcushion.scheme.touchdown import build_model, initial_state
from symcushion.run import report

ROOT = Path(__file__).resolve().parent.parent
DOC = ROOT / "docs" / "codegen.md"
FIG3 = ROOT / "studies" / "fig3.toml"
FIG4 = ROOT / "studies" / "fig4.toml"
#: Name of this benchmark in the messages of its checks.
BENCH = "bench_codegen"

#: Contact-step cases per batched call and per oracle loop.
BATCH = 1000
#: Timing rounds; the best is kept (the machine is shared with other jobs).
BEST_OF = 7
#: CPU time aimed at per timing round (s).
REPEAT_SECONDS = 0.2
#: Passes over all cases per method in the C loop of bench_contact.c.
C_REPEAT = 50
#: Simulated time of the Fig. 3 drop (s): 1000 steps of 1 ms.
DROP_SECONDS = 1.0
#: Loops of the standalone program's step loop per run (-r): its inner
#: time is the best loop, so one slow loop does not count.
PROGRAM_REPEAT = 20
#: Targets of the code generation, reported, not asserted.
TARGET_CONTACT_RATIO = 100.0
TARGET_STEP_US = 4.0


def load_oracle():
    """tests/oracle_contact.py, imported by path (it is a test module, not package code)."""
    path = ROOT / "tests" / "oracle_contact.py"
    spec = importlib.util.spec_from_file_location("oracle_contact", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def rel_err(a, b) -> float:
    """max |a - b| / max |b|."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    return float(np.max(np.abs(a - b))) / max(float(np.max(np.abs(b))), 1e-300)


def calibrate(call) -> int:
    """Calls of ``call`` that take about REPEAT_SECONDS of CPU time."""
    call()
    start, count = time.process_time(), 0
    while time.process_time() - start < 0.02:
        call()
        count += 1
    return max(1, int(count * REPEAT_SECONDS / (time.process_time() - start)))


def best_seconds(timers: dict) -> dict:
    """Best CPU seconds per evaluation of each ``timers[key] = (call, evals_per_call)``.

    The timers take turns (round robin), so a burst of load from other
    processes hits every variant alike.
    """
    counts = {key: calibrate(call) for key, (call, _) in timers.items()}
    best = {key: np.inf for key in timers}
    for _ in range(BEST_OF):
        for key, (call, evals) in timers.items():
            start = time.process_time()
            for _ in range(counts[key]):
                call()
            best[key] = min(best[key], (time.process_time() - start) / counts[key] / evals)
    return best


# ---------------------------------------------------------------------------
# contact steps
# ---------------------------------------------------------------------------
def reaches_newton(oracle, cases, i) -> bool:
    """Whether the oracle's implicit step runs its Newton loop on case i (a slip)."""
    path = []
    oracle.implicit_step(cases["P0"][i], cases["Dp"][i], cases["n"][i], cases["l"][i],
                         cases["mu"][i], cases["u0"][i], path=path)
    return ("no slip solution", False) in path


def native_contact(out_dir: Path, cases: dict) -> tuple[dict, np.ndarray]:
    """Seconds per evaluation of each contact step in a C loop, and its outputs (3, n, 10)."""
    n = len(cases["mu"])
    table = np.column_stack([cases["P0"], cases["Dp"].transpose(0, 2, 1).reshape(n, 9),
                             cases["n"], cases["l"], cases["mu"], cases["u0"]])
    cases_file, out_file = out_dir / "cases.bin", out_dir / "contact_out.bin"
    np.ascontiguousarray(table, dtype=np.float64).tofile(cases_file)
    program = build_program(out_dir, Path(codegen.__file__).parent / "c" / "bench_contact.c")
    # one pass first: its outputs are checked before the timed runs
    subprocess.run([str(program), str(cases_file), "1", str(out_file)], capture_output=True,
                   check=True)
    outputs = np.fromfile(out_file).reshape(3, n, 10)
    best = {}
    for _ in range(BEST_OF):
        run = subprocess.run([str(program), str(cases_file), str(C_REPEAT), str(out_file)],
                             capture_output=True, text=True, check=True)
        for line in run.stdout.splitlines():
            name, value = line.split()
            sec = float(value.split("=")[1]) * 1e-9
            best[name] = min(best.get(name, np.inf), sec)
    return best, outputs


def measure_contact(compiled: dict, oracle, out_dir: Path) -> list[dict]:
    cases = oracle.random_cases(np.random.default_rng(0), BATCH)
    # inputs as DM once: CasADi's conversion of NumPy arrays costs more than the C itself
    columns = [ca.DM(x) for x in (cases["P0"].T, np.hstack(list(cases["Dp"])), cases["n"].T,
                                  cases["l"].T, cases["mu"][None, :], cases["u0"].T)]
    one = [ca.DM(cases[key][0]) for key in ("P0", "Dp", "n", "l", "mu", "u0")]
    steps = {"paper": oracle.paper_step, "robust": oracle.robust_step,
             "implicit": oracle.implicit_step}
    native, native_out = native_contact(out_dir, cases)
    rows = []
    for k, method in enumerate(METHODS):
        vm = contact_step(method)
        ext = compiled[vm.name()]
        vm_map, ext_map = vm.map(BATCH), ext.map(BATCH)
        reference = np.vstack([np.asarray(o) for o in vm_map(*columns)]).T
        external = np.vstack([np.asarray(o) for o in ext_map(*columns)]).T
        for label, values in (("casadi.external, mapped", external),
                              ("C loop of bench_contact.c", native_out[k])):
            check_equal(BENCH, f"{vm.name()} ({label}), {BATCH} oracle cases", values,
                        reference, rtol=ROUNDOFF_RTOL, reference_name="the SX Function on the VM")
        fn = steps[method]

        def run_oracle(fn=fn):
            for i in range(BATCH):
                fn(cases["P0"][i], cases["Dp"][i], cases["n"][i], cases["l"][i],
                   cases["mu"][i], cases["u0"][i])

        # the oracle returns early (stick, lift-off); the branch-free graph never does
        full = [i for i in range(BATCH) if reaches_newton(oracle, cases, i)] \
            if method == "implicit" else list(range(BATCH))

        def run_oracle_full(fn=fn, full=full):
            for i in full:
                fn(cases["P0"][i], cases["Dp"][i], cases["n"][i], cases["l"][i],
                   cases["mu"][i], cases["u0"][i])

        timers = {
            "oracle": (run_oracle, BATCH),
            "oracle_full": (run_oracle_full, len(full)),
            "vm_call": (lambda f=vm: f(*one), 1),
            "vm_map": (lambda f=vm_map: f(*columns), BATCH),
            "ext_call": (lambda f=ext: f(*one), 1),
            "ext_map": (lambda f=ext_map: f(*columns), BATCH),
        }
        rows.append(dict(function=vm.name(), instructions=vm.n_instructions(),
                         agree=max(rel_err(external, reference),
                                   rel_err(native_out[k], reference)),
                         c_loop=native[vm.name()], full_cases=len(full),
                         **best_seconds(timers)))
    return rows


def contact_table(rows: list[dict]) -> str:
    keys = ("oracle", "vm_call", "vm_map", "ext_call", "ext_map", "c_loop")
    lines = ["| Function | SX instr. | NumPy oracle | VM, 1 call | VM, map | external, 1 call "
             "| external, map | C loop | C loop / oracle | C loop / VM map |",
             "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for r in rows:
        rates = " | ".join(f"{1 / r[k]:,.0f}" for k in keys)
        lines.append(f"| `{r['function']}` | {r['instructions']:,} | {rates} "
                     f"| {r['oracle'] / r['c_loop']:,.0f}× | {r['vm_map'] / r['c_loop']:.1f}× |")
    return "\n".join(lines)


# ---------------------------------------------------------------------------
# touchdown
# ---------------------------------------------------------------------------
def program_inner_us(program: Path, steps: int, csv: Path) -> float:
    """Best µs per step of the program's own step loop (-r PROGRAM_REPEAT), BEST_OF runs."""
    inner = np.inf
    for _ in range(BEST_OF):
        run = subprocess.run([str(program), "-n", str(steps), "-r", str(PROGRAM_REPEAT),
                              "-o", str(csv)], capture_output=True, text=True, check=True)
        report = dict(item.split("=", 1) for item in run.stderr.split()[1:])
        inner = min(inner, float(report["per_step_us"]))
    return inner


def measure_drop(scene, out_dir: Path) -> dict:
    started = time.perf_counter()
    gen = generate(out_dir, scene, build=True)
    build_seconds = time.perf_counter() - started
    compiled = compiled_model(scene, out_dir)
    model = build_model(scene)
    steps = scene.steps
    x0 = initial_state(scene)
    p = model.default_p
    vm_rollout, c_rollout = model.rollout(steps), compiled.rollout(steps)

    def vm_loop():
        x = x0
        for _ in range(steps):
            x = model.step(x, p, scene.dt)[0]
        return x

    def c_loop():
        x = x0
        for _ in range(steps):
            x = compiled.step(x, p, scene.dt)[0]
        return x

    X_c, _ = check_rollout(BENCH, f"{scene.name} compiled rollout", c_rollout, scene, x0, p,
                           scene.dt, steps, rtol=BITWISE)
    X_vm = np.asarray(vm_rollout(x0, p, scene.dt)[0])
    for label, loop in (("VM", vm_loop), ("C", c_loop)):
        check_equal(BENCH, f"{scene.name}: last state of the {label} loop over touchdown_step",
                    np.asarray(loop()).ravel(), X_vm[:, -1], rtol=BITWISE,
                    reference_name="the VM rollout")
    best = best_seconds({
        "vm_loop": (vm_loop, steps),
        "vm_rollout": (lambda: vm_rollout(x0, p, scene.dt), steps),
        "c_loop": (c_loop, steps),
        "c_rollout": (lambda: c_rollout(x0, p, scene.dt), steps),
    })
    # the program once with one loop (the process as a user runs it), checked first ...
    csv = out_dir / "bench.csv"
    subprocess.run([str(gen.program), "-o", str(csv)], capture_output=True, check=True)
    check_equal(BENCH, f"{scene.name}: states in the C program's CSV",
                np.loadtxt(csv, delimiter=",", skiprows=1)[1:, 1:], X_vm.T, rtol=BITWISE,
                reference_name="the VM rollout")
    wall = np.inf
    for _ in range(BEST_OF):
        start = time.perf_counter()
        subprocess.run([str(gen.program), "-o", str(csv)], capture_output=True, check=True)
        wall = min(wall, time.perf_counter() - start)
    # ... and with PROGRAM_REPEAT loops for its inner time
    inner = program_inner_us(gen.program, steps, csv)
    table = np.loadtxt(csv, delimiter=",", skiprows=1)
    return dict(scene=scene, gen=gen, build_seconds=build_seconds, best=best, wall=wall,
                inner_us=inner, instructions=model.step.n_instructions(),
                agree_rollout=float(np.max(np.abs(X_c - X_vm))),
                agree_program=float(np.max(np.abs(table[1:, 1:] - X_vm.T))))


def drop_table(d: dict) -> str:
    steps = d["scene"].steps
    vm_loop = d["best"]["vm_loop"]
    rows = [
        ("VM: Python loop over `touchdown_step`", vm_loop),
        ("VM: `touchdown_rollout` (mapaccum), one call", d["best"]["vm_rollout"]),
        ("C via `casadi.external`: Python loop over `touchdown_step`", d["best"]["c_loop"]),
        ("C via `casadi.external`: `touchdown_rollout`, one call", d["best"]["c_rollout"]),
        (f"C program `touchdown`, whole process (wall, start to exit, {steps + 1} CSV rows)",
         d["wall"] / steps),
        ("C program `touchdown`, its step loop (clock_gettime inside main.c)",
         d["inner_us"] * 1e-6),
    ]
    lines = ["| how | time per step (µs) | steps per second | speed-up over VM loop |",
             "|---|---:|---:|---:|"]
    for label, sec in rows:
        lines.append(f"| {label} | {sec * 1e6:,.2f} | {1 / sec:,.0f} | {vm_loop / sec:,.0f}× |")
    return "\n".join(lines)


def compile_line(gen) -> str:
    parts = [f"{name} {sec:.1f} s" for name, sec in gen.seconds.items() if name != "generate"]
    return f"generate {gen.seconds['generate']:.2f} s; gcc: " + ", ".join(parts)


def gcc_version() -> str:
    try:
        out = subprocess.run(["gcc", "--version"], capture_output=True, text=True).stdout
        return out.splitlines()[0]
    except (OSError, IndexError):
        return "gcc (version unknown)"


def cpu_name() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def summary(contact_rows, drop) -> str:
    by = {r["function"].replace("contact_step_", ""): r for r in contact_rows}
    ratios = {m: r["oracle"] / r["c_loop"] for m, r in by.items()}
    met = [m for m in ratios if ratios[m] >= TARGET_CONTACT_RATIO]
    missed = [m for m in ratios if ratios[m] < TARGET_CONTACT_RATIO]
    listing = ", ".join(f"{m} {ratios[m]:,.0f}×" for m in ratios)
    verdict = (f"the target of {TARGET_CONTACT_RATIO:.0f}× is met by "
               + (", ".join(met) or "none") + (f" and missed by {', '.join(missed)}"
                                               if missed else ""))
    imp = by["implicit"]
    implicit_note = (
        "The implicit step's graph is branch-free: it always runs its 20 safeguarded "
        "Newton iterations and evaluates both sides of every if_else, where the oracle "
        f"returns at once on a stick or a lift-off ({BATCH - imp['full_cases']} of the "
        f"{BATCH} cases); on the {imp['full_cases']} cases that reach its Newton loop the "
        f"oracle takes {imp['oracle_full'] * 1e6:.0f} µs and the compiled step is "
        f"{imp['oracle_full'] / imp['c_loop']:,.0f}× faster. ")
    vm_ratio = min(r["vm_map"] / r["c_loop"] for r in contact_rows)
    ext_ratio = min(r["oracle"] / r["ext_map"] for r in contact_rows)
    call_us = min(r["ext_call"] for r in contact_rows) * 1e6
    map_over = [(r["ext_map"] - r["c_loop"]) * 1e6 for r in contact_rows]
    inner = drop["inner_us"]
    verdict_step = "meets" if inner <= TARGET_STEP_US else "misses"
    return (
        f"Called from C, the compiled contact steps are faster per evaluation than the "
        f"NumPy oracle by {listing}: {verdict}. {implicit_note}"
        f"Against the same SX Function batched in CasADi's VM the C loop is at least "
        f"{vm_ratio:.0f}× faster. Through `casadi.external` much of the gain is lost to "
        f"calling: one call from Python costs at least {call_us:.0f} µs, VM or C alike, and a "
        f"`map` adds {min(map_over):.1f}–{max(map_over):.1f} µs per evaluation to the C "
        f"time (the map still beats the oracle by at least {ext_ratio:,.0f}×), so compiled "
        "code pays where the loop is in C: the rollout, the program, an optimiser's "
        f"callbacks. For the Fig. 3 drop the standalone program spends {inner:.2f} µs per "
        f"4-leg step in its loop, which {verdict_step} the target of {TARGET_STEP_US:g} µs; "
        "the compiled rollout via `casadi.external` is "
        f"{drop['best']['vm_rollout'] / drop['best']['c_rollout']:.1f}× faster than the VM "
        "rollout, and the whole program, process start and CSV output included, takes "
        f"{drop['wall'] * 1e3:.1f} ms for the {DROP_SECONDS:g} s drop. Compiled results "
        f"equal the VM's: the rollout to {drop['agree_rollout']:.1e} and the program's CSV "
        f"to {drop['agree_program']:.1e} (absolute, state units), the contact steps to "
        f"{max(r['agree'] for r in contact_rows):.1e} relative."
    )


def compile_cpu(argv) -> float:
    """CPU seconds (user + system) of one compiler command."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    subprocess.run(argv, check=True, capture_output=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def with_level(level: str) -> list:
    return [level if flag.startswith("-O") else flag for flag in CFLAGS]


def compile_rows(folder: Path, label: str, levels) -> list[dict]:
    """Recompile each source of a build folder at each -O level: CPU time, and µs per
    step of the program built from it (touchdown source only)."""
    info = json.loads((folder / codegen.MANIFEST).read_text())
    cc = codegen.find_compiler()
    rows = []
    for stem in info["sources"]:
        fns = {k: v for k, v in info["functions"].items()
               if (k.startswith("touchdown")) == (stem == codegen.TOUCHDOWN)}
        largest = max(fns, key=lambda k: fns[k]["instructions"])
        row = dict(source=f"{label}: `{stem}.c`", largest=largest,
                   instructions=fns[largest]["instructions"])
        for level in levels:
            obj = folder / f"{stem}{level}.o"
            row[f"cpu{level}"] = compile_cpu([cc, *with_level(level), "-c",
                                              str(folder / f"{stem}.c"), "-o", str(obj)])
            if stem == codegen.TOUCHDOWN:
                program = folder / f"touchdown{level}"
                subprocess.run([cc, *CFLAGS, "-I", str(folder), str(folder / codegen.MAIN),
                                str(folder / f"{codegen.KERNELS}.o"), str(obj), "-o",
                                str(program), "-lm"], check=True, capture_output=True)
                row[f"us{level}"] = program_inner_us(program, info["steps"],
                                                     folder / "levels.csv")
        rows.append(row)
    return rows


def compile_section(tmp: Path, fig3_folder: Path) -> str:
    """The compile-time table: Fig. 3 sources at -O3, the largest graph at -O3/-O2/-O1."""
    scene = load_scene(FIG4).with_(method="implicit", duration=DROP_SECONDS)
    folder = tmp / "fig4_implicit"
    started = time.perf_counter()
    gen = generate(folder, scene, build=True)
    build = time.perf_counter() - started
    levels = ("-O3", "-O2", "-O1")
    rows = compile_rows(fig3_folder, "Fig. 3, 'paper', μ = 0", ("-O3",))
    rows += compile_rows(folder, f"Fig. 4, 'implicit', μ = {scene.mu:g}", levels)
    lines = ["| source | largest Function | SX instr. | CPU s, -O3 | -O2 | -O1 "
             "| µs/step, -O3 | -O2 | -O1 |", "|---|---|---:|---:|---:|---:|---:|---:|---:|"]
    for r in rows:
        cells = [f"{r[f'cpu{lv}']:.1f}" if f"cpu{lv}" in r else "" for lv in levels]
        cells += [f"{r[f'us{lv}']:.1f}" if f"us{lv}" in r else "" for lv in levels]
        lines.append(f"| {r['source']} | `{r['largest']}` | {r['instructions']:,} | "
                     + " | ".join(cells) + " |")
    big = rows[-1]
    return (
        "Produced by `python studies/bench_codegen.py --large`: each generated source "
        "recompiled alone at each optimisation level (CPU time of gcc, other flags as in "
        "`CFLAGS`), and for the touchdown source the standalone program's time per step "
        "built from that object (best of "
        f"{BEST_OF} runs of {PROGRAM_REPEAT} loops). The largest graph is the Fig. 4 scene "
        f"(4 legs) with method 'implicit' and friction; its full build took {build:.0f} s "
        f"wall ({compile_line(gen)}).\n\n" + "\n".join(lines) + "\n\n"
        f"On the largest graph -O1 saves {100 * (1 - big['cpu-O1'] / big['cpu-O3']):.0f} % "
        f"of the compile time and costs a factor {big['us-O1'] / big['us-O3']:.1f} at run "
        f"time; -O2 saves {100 * (1 - big['cpu-O2'] / big['cpu-O3']):.0f} % and costs "
        f"{big['us-O2'] / big['us-O3']:.2f}. The machine is shared: CPU times spread by "
        "about ±15 % between runs."
    )


def write_section(path, heading: str, body: str) -> None:
    """Replace (or append) a section of this study's docs page."""
    report.write_section(path, heading, body, title='# Generated C code')


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--large", action="store_true",
                        help="also measure compile times, on the largest graph too "
                             "(several minutes)")
    args = parser.parse_args(argv)
    oracle = load_oracle()
    scene = load_scene(FIG3).with_(duration=DROP_SECONDS)
    with tempfile.TemporaryDirectory(prefix="symcushion-bench-") as tmp:
        tmp = Path(tmp)
        print(f"building {scene.name} ({scene.steps} steps) in {tmp} ...", flush=True)
        drop = measure_drop(scene, tmp / "fig3")
        print(compile_line(drop["gen"]), flush=True)
        compiled = load_compiled(tmp / "fig3")
        print("timing contact steps ...", flush=True)
        contact_rows = measure_contact(compiled, oracle, tmp / "fig3")
        large = compile_section(tmp, tmp / "fig3") if args.large else None

    t1, t2 = contact_table(contact_rows), drop_table(drop)
    text = summary(contact_rows, drop)
    machine = (f"{cpu_name()}, {platform.system()} {platform.machine()}, {gcc_version()}, "
               f"CasADi {ca.__version__}, CPython {platform.python_version()}")
    body = (
        "Produced by `python studies/bench_codegen.py` on " + machine + ". Flags: `"
        + " ".join(CFLAGS) + "`.\n\n"
        f"**Contact steps**, evaluations per second, {BATCH} random cases of the oracle's "
        "distribution. VM and external: CPU time from Python, one case per call or one call "
        "of `f.map(" + str(BATCH) + ")` on DM inputs; C loop: `symcushion/compiled/c/bench_contact.c` "
        "calling the generated function once per case (clock_gettime, best of "
        f"{C_REPEAT} passes); ratios are of time per evaluation.\n\n" + t1 + "\n\n"
        f"**Fig. 3 drop**, {DROP_SECONDS:g} s of simulated time ({drop['scene'].steps} steps of "
        f"{drop['scene'].dt * 1e3:g} ms, 4 legs, method '{drop['scene'].method}', "
        f"`touchdown_step` of {drop['instructions']:,} SX instructions). Build: "
        f"{compile_line(drop['gen'])} (two objects compiled in parallel; "
        f"{drop['build_seconds']:.1f} s wall in all).\n\n" + t2 + "\n\n" + text
        + "\n\nThe machine is shared with other jobs: CPU-time figures are the best of "
        f"{BEST_OF} interleaved rounds and repeated runs spread by about ±10 %; wall-clock "
        "figures (the program) by more. Rerun the script to refresh this section.")
    print()
    print(body)
    write_section(DOC, "Benchmark", body)
    if large is not None:
        print()
        print(large)
        write_section(DOC, "Compile-time benchmark", large)
    print(f"\nwritten to {DOC}")


if __name__ == "__main__":
    sys.exit(main())
