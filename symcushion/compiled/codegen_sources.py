"""The text of the generated C: sources, the documented header, the scene's data.

This module owns what :func:`symcushion.compiled.codegen.generate` writes around the
C that ``casadi.CodeGenerator`` produces: each source (with the touchdown
step's functions compiled in clones and the rollout loop
``symcushion/compiled/c/rollout.c`` appended, sized by :func:`rollout_source`), the
one header ``symcushion.h`` with a documentation block per Function
(:class:`Signature`, :func:`write_header`), ``scene_data.h`` for the
standalone program and the manifest's entry of a Function. It must not
choose which Functions are generated or what their arguments mean
(``symcushion.compiled.codegen`` does), compile anything (``symcushion.compiled.cbuild``) or
load compiled code (``symcushion.compiled.codegen_load``).
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import casadi as ca
import numpy as np

from symcushion.compiled.cbuild import CODEGEN_OPTIONS, with_clones
from symcushion.compiled.codegen_hoist import CORE, PARAMETRIC, STATES
from symcushion.layout.vectors import default_p, state_columns
from symcushion.model.scene import Scene
from symcushion.scheme.touchdown import StepModel, initial_state

__all__ = ["Signature", "loop_rollout", "manifest_entry", "c_string", "generate_source",
           "rollout_source", "write_header", "write_scene_data", "HEADER", "ROLLOUT",
           "ROLLOUT_SOURCE", "SCENE_DATA"]

HEADER = "symcushion.h"
#: The C loop over the step that the touchdown source ends with (symcushion/compiled/c/rollout.c).
ROLLOUT = "touchdown_rollout"
ROLLOUT_SOURCE = "rollout.c"
SCENE_DATA = "scene_data.h"


def _shape(sp: ca.Sparsity) -> str:
    r, c = sp.shape
    return f"{r}" if c == 1 else f"{r}x{c}"


@dataclass(frozen=True)
class Signature:
    """A generated C function as the header and the manifest describe it: its name,
    inputs and outputs (name, shape text) and what its work line says."""

    name: str
    inputs: tuple
    outputs: tuple
    work: str
    instructions: int

    @classmethod
    def of(cls, f: ca.Function) -> "Signature":
        kind = "SX" if f.is_a("SXFunction") else "MX"
        return cls(f.name(),
                   tuple((n, _shape(f.sparsity_in(i))) for i, n in enumerate(f.name_in())),
                   tuple((n, _shape(f.sparsity_out(i))) for i, n in enumerate(f.name_out())),
                   f"{f.n_instructions()} {kind} instructions", f.n_instructions())


def loop_rollout(model: StepModel, steps: int) -> Signature:
    """``touchdown_rollout``: ``symcushion/compiled/c/rollout.c``, N calls of the step in a C loop."""
    return Signature(ROLLOUT, (("x0", f"{model.nx}"), ("p", f"{model.np}"), ("dt", "1")),
                      (("X", f"{model.nx}x{steps}"), ("Y", f"{model.ny}x{steps}")),
                      f"{steps} calls of touchdown_step in a C loop", 0)


def _doc_block(sig: Signature, summary: str, meanings: dict) -> str:
    """The comment documenting one Function in symcushion.h."""
    lines = [f"{sig.name}({', '.join(n for n, _ in sig.inputs)}) -> "
             f"({', '.join(n for n, _ in sig.outputs)})"]
    lines += ["  " + s for s in summary.splitlines()]
    for label, args in (("in ", sig.inputs), ("out", sig.outputs)):
        for i, (name, shape) in enumerate(args):
            text = meanings.get(name, "").splitlines() or [""]
            lines.append(f"  {label} {i}  {name:<8}[{shape:>6}]  {text[0]}")
            lines += [" " * 27 + t for t in text[1:]]
    lines.append(f"  work sizes: {sig.name}_work(); {sig.work}")
    return "\n".join(" * " + s if s else " *" for s in lines)


def manifest_entry(sig: Signature) -> dict:
    """Inputs and outputs of a generated function with their shapes, for the manifest."""
    return {"in": dict(sig.inputs), "out": dict(sig.outputs), "instructions": sig.instructions}


def c_string(text: str) -> str:
    """``text`` as a C string literal, quotes and backslashes escaped."""
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"') + '"'


def _c_doubles(values) -> str:
    vals = [repr(float(v)) for v in np.ravel(values)] or ["0.0"]
    rows = [", ".join(vals[i:i + 4]) for i in range(0, len(vals), 4)]
    return "{\n    " + ",\n    ".join(rows) + "\n}"


def generate_source(name: str, functions, out_dir: Path, tail: str = "",
                     declarations: str = "", clones: bool = False) -> tuple[Path, str]:
    """Write ``name.c``, with ``tail`` appended to CasADi's code; return it and the text
    of the header CasADi wrote (deleted), with ``declarations`` appended. ``clones``:
    every function CasADi wrote is compiled in the clones of ``cbuild.TARGET_CLONES``."""
    cg = ca.CodeGenerator(name + ".c", CODEGEN_OPTIONS)
    for f in functions:
        cg.add(f)
    cg.generate(str(out_dir) + os.sep)
    source = out_dir / (name + ".c")
    text = source.read_text()
    if clones:
        text = with_clones(text)
    if tail:
        text = _before_closing(text, tail)
    source.write_text(text)
    header = out_dir / (name + ".h")
    text = header.read_text()
    header.unlink()
    if declarations:
        text = _before_closing(text, declarations)
    return source, text


def rollout_source(model: StepModel, steps: int, nq: int,
                   states: bool = False) -> tuple[str, str]:
    """(C code, declarations) of ``touchdown_rollout``: symcushion/compiled/c/rollout.c with the
    sizes of this step, ``nq`` values of p alone (:func:`hoisted_step`) and N = ``steps``;
    ``states``: the source also holds ``touchdown_step_states`` (:func:`states_only`),
    which the loop runs when Y is not wanted."""
    sizes = (f"#define ROLLOUT_NX {model.nx}\n#define ROLLOUT_NY {model.ny}\n"
             f"#define ROLLOUT_NP {model.np}\n#define ROLLOUT_NQ {nq}\n"
             f"#define ROLLOUT_STEPS {steps}\n#define ROLLOUT_STATES {int(states)}\n")
    # the work of the Functions the loop calls
    called = (CORE, STATES, PARAMETRIC) if states else (CORE, PARAMETRIC)

    def largest(k):
        most = f"{called[-1]}_SZ_{k}"
        for name in called[:-1]:
            most = f"{ROLLOUT}_MAX({name}_SZ_{k}, {most})"
        return most
    code = (Path(__file__).parent / "c" / ROLLOUT_SOURCE).read_text()
    args = ("(const casadi_real** arg, casadi_real** res, casadi_int* iw, casadi_real* w, "
            "int mem)")
    work = "(casadi_int *sz_arg, casadi_int* sz_res, casadi_int *sz_iw, casadi_int *sz_w)"
    declarations = "\n".join([
        f"int {ROLLOUT}{args};", f"int {ROLLOUT}_checkout(void);",
        f"void {ROLLOUT}_release(int mem);", f"void {ROLLOUT}_incref(void);",
        f"void {ROLLOUT}_decref(void);", f"casadi_int {ROLLOUT}_n_in(void);",
        f"casadi_int {ROLLOUT}_n_out(void);", f"casadi_real {ROLLOUT}_default_in(casadi_int i);",
        f"const char* {ROLLOUT}_name_in(casadi_int i);",
        f"const char* {ROLLOUT}_name_out(casadi_int i);",
        f"const casadi_int* {ROLLOUT}_sparsity_in(casadi_int i);",
        f"const casadi_int* {ROLLOUT}_sparsity_out(casadi_int i);",
        f"int {ROLLOUT}_work{work};", f"int {ROLLOUT}_work_bytes{work};",
        f"#define {ROLLOUT}_MAX(a, b) ((a) > (b) ? (a) : (b))",
        *(f"#define {ROLLOUT}_STEP_SZ_{k} {largest(k)}" for k in ("ARG", "RES", "IW", "W")),
        f"#define {ROLLOUT}_SZ_ARG (3 + {ROLLOUT}_STEP_SZ_ARG)",
        f"#define {ROLLOUT}_SZ_RES (2 + {ROLLOUT}_STEP_SZ_RES)",
        f"#define {ROLLOUT}_SZ_IW {ROLLOUT}_STEP_SZ_IW",
        f"#define {ROLLOUT}_SZ_W (2 * {model.nx} + {nq} + {ROLLOUT}_STEP_SZ_W)"]) + "\n"
    return "\n" + sizes + code, declarations


_OPEN_C = '#ifdef __cplusplus\nextern "C" {\n#endif\n'
_CLOSE_C = '#ifdef __cplusplus\n} /* extern "C" */\n#endif\n'


def _before_closing(text: str, insert: str) -> str:
    """``text``, a generated source or header, with ``insert`` before its closing
    ``extern "C"`` block."""
    if not text.endswith(_CLOSE_C):
        raise RuntimeError("unexpected layout of CasADi-generated code: it does not end with "
                           "the extern \"C\" block; update "
                           "symcushion.compiled.codegen_sources._before_closing.")
    return text[:-len(_CLOSE_C)] + insert + "\n" + _CLOSE_C


def _strip_linkage(text: str) -> str:
    """The declarations of a generated header, without its banner and extern "C" wrapper."""
    if _OPEN_C not in text or _CLOSE_C not in text:
        raise RuntimeError("unexpected layout of a CasADi-generated header: no extern \"C\" "
                           "block; update symcushion.compiled.codegen_sources._strip_linkage.")
    body = text.split(_OPEN_C, 1)[1].rsplit(_CLOSE_C, 1)[0]
    return body.strip() + "\n"


def write_header(out_dir: Path, parts, signatures, docs, scene) -> Path:
    """Write ``symcushion.h``: the documentation block of every ``Signature`` (``docs``:
    summary and argument meanings by name), then the declarations of the headers
    CasADi wrote (``parts``)."""
    blocks = "\n *\n".join(_doc_block(sig, *docs[sig.name]) for sig in signatures)
    about = (f"scene '{scene.name}'" if scene is not None else "no scene (contact steps only)")
    text = f"""/*
 * symcushion.h -- C API of the symcushion Functions generated by symcushion.compiled.codegen
 * (CasADi {ca.__version__}) for {about}. Do not edit: regenerate with
 * `symcushion codegen`. docs/codegen.md explains how to build and call it.
 *
 * Calling convention (CasADi's): every Function F has
 *   int F(const casadi_real** arg, casadi_real** res, casadi_int* iw, casadi_real* w, int mem);
 * arg[i] points to input i, res[i] to output i (a null pointer: input taken as 0,
 * output not written), both dense, matrices column-major. Get the sizes of the work
 * arrays arg, res, iw, w from F_work(&sz_arg, &sz_res, &sz_iw, &sz_w) (arg and res
 * must hold at least sz_arg, sz_res pointers: the first n_in / n_out are yours, the
 * rest scratch); call F_incref() once, mem = F_checkout(), F(...) as often as needed,
 * F_release(mem), F_decref(). F returns 0 on success. Inputs and outputs must not
 * overlap. casadi_real is double, casadi_int long long int.
 *
 * Functions (argument [shape], meaning and unit):
 *
{blocks}
 */
#ifndef SYMCUSHION_H
#define SYMCUSHION_H

#ifdef __cplusplus
extern "C" {{
#endif

""" + "\n".join(_strip_linkage(t) for t in parts) + """
#ifdef __cplusplus
} /* extern "C" */
#endif

#endif /* SYMCUSHION_H */
"""
    path = out_dir / HEADER
    path.write_text(text)
    return path


def write_scene_data(out_dir: Path, scene: Scene, model: StepModel, steps: int) -> Path:
    """Write ``scene_data.h``, the scene's x0, p, dt, N and state names for ``main.c``."""
    # the standalone program's CSV columns: the names of symcushion.layout.vectors, as in
    # the trajectory.csv of `symcushion simulate`
    names = state_columns(len(scene.legs))
    x0 = initial_state(scene)
    p = default_p(scene)
    name_rows = ",\n    ".join(c_string(n) for n in names)
    text = f"""/*
 * scene_data.h -- scene '{scene.name}' for the standalone program touchdown (main.c).
 * Generated by symcushion.compiled.codegen; do not edit. x0 is the scene's initial state
 * (all feet free), p the default leg parameters, dt and STEPS the scene's time grid.
 */
#ifndef SYMCUSHION_SCENE_DATA_H
#define SYMCUSHION_SCENE_DATA_H

#define SCENE_NAME {c_string(scene.name)}
#define SCENE_NX {model.nx}
#define SCENE_NP {model.np}
#define SCENE_STEPS {steps}
#define SCENE_DT {scene.dt!r}

static const double scene_x0[SCENE_NX] = {_c_doubles(x0)};

/* one element more than needed when SCENE_NP is 0: C has no empty arrays */
static const double scene_p[SCENE_NP > 0 ? SCENE_NP : 1] = {_c_doubles(p)};

static const char *const scene_state_names[SCENE_NX] = {{
    {name_rows}
}};

#endif /* SYMCUSHION_SCENE_DATA_H */
"""
    path = out_dir / SCENE_DATA
    path.write_text(text)
    return path
