"""Where does the time of one compiled touchdown step go?

Question: for the scenes of the speed target (Fig. 3, μ = 0, its own contact
step; Fig. 4, μ = 0.05, the implicit step), which parts of the generated
``touchdown_step`` take its time: the contact calls, the strut forces and
D_p, the rest of the step body (tangent-plane pass, kicks and drift, outputs),
libm?

Method.
The scene is generated and built by ``symcushion.compiled.codegen.generate`` (the
flags of ``codegen.CFLAGS``), its standalone program ``touchdown`` runs the
scene's first SECONDS of simulated time REPEAT times, and ``perf record``
samples it. The generated C keeps every called Function in a C function of
its own (the contact steps are ``never_inline`` calls, the implicit step's
stick trial and its slip and stick branches are three), so the samples are
attributed to them by symbol; what is left in ``touchdown_step`` itself is
the step body. Inside the body the strut forces and D_p are not separate C
functions: their share of the body is estimated by their share of its SX
instructions (the legs' ``strut_force`` and ``strut_stiffness`` evaluated
together, with CSE, as the step does). ns per step = share × the program's
own per-step time (its ``clock_gettime`` loop, best of the runs).
Instruction counts are ``Function.n_instructions()`` of each part.

Needs ``perf`` (Linux) allowed to sample user space; without it only the
instruction counts are printed.

Output: one table per scene on stdout. Run:
``python studies/profile_step.py``.
"""
from __future__ import annotations

import re
import shutil
import subprocess
import tempfile
from collections import defaultdict
from pathlib import Path

import casadi as ca

from symcushion.compiled.codegen import TOUCHDOWN, generate
from symcushion.model.scene import load_scene
from symcushion.scheme.touchdown import build_model

ROOT = Path(__file__).resolve().parent.parent
SCENES = (("Fig. 3", ROOT / "studies" / "fig3.toml", None),
          ("Fig. 4", ROOT / "studies" / "fig4.toml", "implicit"))
#: Simulated time of the program's step loop (s), as in bench_touchdown.
SECONDS = 0.3
#: Loops of the program under perf: about 1 s of samples.
REPEAT = 1500
#: Runs of the program for its per-step time; the fastest is kept.
TIMING_RUNS = 5
#: libm symbols are reported together.
LIBM = "libm"


def c_names(source: Path) -> dict:
    """The generated C's static functions ``casadi_fN`` by the Function each implements."""
    text = source.read_text()
    # a definition may carry the clones macro (symcushion.compiled.cbuild.TARGET_CLONES)
    found = re.findall(r"/\* ([A-Za-z0-9_]+):\([^\n]*\*/\n(?:SYMCUSHION_CLONES )?"
                       r"static int casadi_(f\d+)\(", text)
    return {f"{TOUCHDOWN}_{fn}": name for name, fn in found}


def perf_shares(program: Path, names: dict, folder: Path) -> dict:
    """Share of perf samples by Function name (libm together, the rest under 'other')."""
    data = folder / "perf.data"
    subprocess.run(["perf", "record", "-q", "-o", str(data), str(program), "-r", str(REPEAT),
                    "-o", str(folder / "out.csv")], check=True, capture_output=True)
    report = subprocess.run(["perf", "report", "-i", str(data), "--stdio", "--sort",
                             "dso,symbol"], check=True, capture_output=True, text=True).stdout
    shares = defaultdict(float)
    for line in report.splitlines():
        hit = re.match(r"\s*([\d.]+)%\s+(\S+)\s+\[\.\]\s+(\S+)", line)
        if not hit:
            continue
        share, dso, symbol = float(hit.group(1)) / 100, hit.group(2), hit.group(3)
        base = symbol.split(".")[0]
        if base in names:
            shares[names[base]] += share
        elif dso.startswith("libm"):
            shares[LIBM] += share
        else:
            shares["other"] += share
    return dict(shares)


def per_step_us(program: Path, folder: Path) -> float:
    best = float("inf")
    for _ in range(TIMING_RUNS):
        run = subprocess.run([str(program), "-r", "50", "-o", str(folder / "out.csv")],
                             check=True, capture_output=True, text=True)
        best = min(best, float(run.stderr.split("per_step_us=")[1].split()[0]))
    return best


def strut_instructions(scene) -> int:
    """SX instructions of every leg's P and D_p evaluated together with CSE, as in the step."""
    total = 0
    for leg in scene.legs:
        fns = leg.functions()
        r, v = ca.SX.sym("r", 3), ca.SX.sym("v", 3)
        p = ca.SX.sym("p", fns["strut_force"].size1_in(2))
        both = ca.Function("strut", [r, v, p], [fns["strut_force"](r, v, p),
                                                fns["strut_stiffness"](r, v, p)], {"cse": True})
        total += both.n_instructions()
    return total


def called_functions(f: ca.Function, calls: int = 1, found=None) -> dict:
    """Every Function that ``f`` calls, directly or through other calls, by name:
    (the Function, call nodes in one call of ``f``, times ``calls``)."""
    found = {} if found is None else found
    if not (f.is_a("SXFunction") or f.is_a("MXFunction")):
        return found       # a Switch: its branches are not listed (their rows say so)
    sx = f.instructions_sx() if f.is_a("SXFunction") else None
    for k in range(f.n_instructions()):
        if f.instruction_id(k) != ca.OP_CALL:
            continue
        g = (sx[k] if sx is not None else f.instruction_MX(k)).which_function()
        old = found.get(g.name(), (g, 0))
        found[g.name()] = (g, old[1] + calls)
        called_functions(g, calls, found)
    return found


def profile(label: str, path: Path, method: str | None, folder: Path) -> list:
    scene = load_scene(path)
    if method:
        scene = scene.with_(method=method)
    scene = scene.with_(duration=SECONDS)
    gen = generate(folder, scene, build=True)
    model = build_model(scene)
    called = called_functions(model.step)
    # the step's own instructions, its call nodes excluded
    body = model.step.n_instructions() - sum(
        1 for k in range(model.step.n_instructions())
        if model.step.instruction_id(k) == ca.OP_CALL)
    strut = strut_instructions(scene)
    us = per_step_us(gen.program, folder)
    shares = perf_shares(gen.program, c_names(folder / f"{TOUCHDOWN}.c"), folder) \
        if shutil.which("perf") else {}
    # the step is compiled as its p-only part and the rest (codegen.hoisted_step),
    # called in turn by touchdown_step: together, the step body
    body_names = ("touchdown_step", "touchdown_step_parametric", "touchdown_step_core")
    body_share = sum(shares.get(name, 0.0) for name in body_names) if shares else float("nan")
    rows = [("step body: strut P and D_p (est. by SX instructions)", strut,
             body_share * strut / body),
            ("step body: the rest (tangent planes, kicks, drift, outputs)", body - strut,
             body_share * (body - strut) / body)]
    for name, share in sorted(shares.items(), key=lambda kv: -kv[1]):
        if name in body_names + ("other", LIBM):
            continue
        f, n_calls = called.get(name, (None, 0))
        if f is None:      # a branch of a Switch: run in some of the Switch's calls
            rows.append((f"{name} (a branch of a conditional call)", None, share))
        else:
            n = f.n_instructions() if f.is_a("SXFunction") or f.is_a("MXFunction") else None
            rows.append((f"{name} ({n_calls} calls)", n, share))
    rows.append(("libm (atan2, asin, pow, acos, cos)", 0, shares.get(LIBM, 0.0)))
    rows.append(("other (program, kernel)", 0, shares.get("other", 0.0)))
    return [(label, scene.method, us, rows)]


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        tables = []
        for label, path, method in SCENES:
            tables += profile(label, path, method, Path(tmp) / label.replace(". ", ""))
    for label, method, us, rows in tables:
        print(f"\n{label} ({method}): {us:.2f} µs per step (standalone program's loop)\n")
        print("| part | SX instructions | ns per step | share |")
        print("|---|---:|---:|---:|")
        for part, n, share in rows:
            count = "—" if not n else f"{n:,}"
            print(f"| {part} | {count} | {1e3 * us * share:.0f} | {100 * share:.1f} % |")


if __name__ == "__main__":
    main()
