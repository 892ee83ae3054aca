"""Compiling generated C: the compiler, its flags, the build cache.

This module owns how symcushion turns generated C into a shared library or a
program: the ``casadi.CodeGenerator`` options, the gcc flags and why each is
there, the fingerprint of a build (sources, flags, compiler), the parallel
gcc runs of a build folder (``build_sources``), and the one generate-fingerprint-
compile cache (:func:`compile_cached`) that the envelope and the compiled
design share. It must not decide which Functions are generated or write
their header (``symcushion.compiled.codegen`` does), and it loads nothing.
"""
from __future__ import annotations

import hashlib
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import casadi as ca

__all__ = ["CFLAGS", "CODEGEN_OPTIONS", "WARNINGS", "LIBRARY", "MAIN", "MANIFEST", "PROGRAM",
           "TARGET_CLONES", "CachedBuild", "compile_cached", "find_compiler", "with_clones"]

MAIN = "main.c"
LIBRARY = "libsymcushion.so"
PROGRAM = "touchdown"
MANIFEST = "symcushion.json"

#: Options of ``casadi.CodeGenerator``.
CODEGEN_OPTIONS = {
    # declarations, work sizes and *_SZ_* macros, merged into symcushion.h
    "with_header": True,
    # CASADI_SYMBOL_EXPORT on the API functions: needed for a Windows DLL
    "with_export": True,
    # the precision of the CasADi VM, so that compiled results equal it to round-off
    "casadi_real": "double",
    # CasADi's own casadi_int: casadi.external reads the sparsity arrays as such
    "casadi_int": "long long int",
    # no per-operation comments: the SX code is local variables a0=..., one per line
    "verbose": False,
}

#: gcc flags of every object (docs/codegen.md, "Build"):
#: -O3 full optimisation, for every source: on the largest graph (the implicit
#: step with friction inside a 4-leg touchdown_step, ~37 000 SX instructions)
#: gcc 12 needs ~40 s of CPU at -O3; -O1 saves about a third of that and makes
#: the code about 4x slower (docs/codegen.md, "Compile-time benchmark");
#: -std=c99, the C the generated code is written in;
#: -fPIC, the objects go into a shared library (and a PIE program);
#: -fno-semantic-interposition: under -fPIC gcc may not inline a function of
#: external linkage, since another library could replace it at load time, so
#: every sq, fabs, fmin and fmax of CasADi's generated helpers was a real
#: call (91 calls of casadi_sq per implicit contact step), and each call
#: spills the live floating-point registers. No library replaces the
#: prefixed helpers; with the flag gcc inlines them. Results are the same
#: bits (the same operations), the Fig. 3 touchdown step takes 2.4 instead of
#: 2.9 µs, the implicit contact step 590 instead of 720 ns;
#: -fno-math-errno, sqrt and friends need not set errno, so gcc emits one
#: instruction instead of a call guarded for negative arguments (the results
#: are unchanged: errno is the only difference);
#: -ffp-contract=off, no fused multiply-add: a*b + c is rounded twice as in the
#: CasADi VM, so compiled and VM results agree to round-off, branch decisions
#: included. gcc already defaults to it under -std=c99; the flag keeps it so
#: under -std=gnu99 (whose default, "fast", fuses wherever the target has FMA:
#: aarch64, or x86-64 with -march=native) and documents the requirement.
#: Not used: -march=native (the library would only run on CPUs with this one's
#: instruction set, and it enables FMA), -ffast-math (breaks the IEEE
#: semantics that the guarded divisions and if_else of the contact steps need).
CFLAGS = ("-O3", "-std=c99", "-fPIC", "-fno-semantic-interposition", "-fno-math-errno",
          "-ffp-contract=off")

#: Function multiversioning of the touchdown source (docs/codegen.md, "Generate and
#: build"): gcc compiles each of its functions twice, for x86-64-v3 (AVX2) and for the baseline,
#: and the loader picks the clone the CPU runs (an ifunc). Measured on the Fig. 3 and
#: Fig. 4 steps: 7-9 % and 5 % faster, the same bits (-ffp-contract=off keeps the
#: v3 clone from fusing a*b + c; the guard below drops the clones where that is not
#: the default, outside ISO C mode), the same speed as -march=x86-64-v3 while still
#: running on any x86-64; the price is about twice gcc's time on that source. Only
#: gcc >= 11 (the name x86-64-v3) on x86-64 glibc (ifuncs) clones; elsewhere
#: SYMCUSHION_CLONES is empty and the code is the plain one.
TARGET_CLONES = """\
/* symcushion: each function also compiled for x86-64-v3, picked at load time */
#if defined(__GNUC__) && !defined(__clang__) && __GNUC__ >= 11 && defined(__x86_64__) \\
    && defined(__GLIBC__) && defined(__STRICT_ANSI__) && !defined(SYMCUSHION_NO_CLONES)
#define SYMCUSHION_CLONES __attribute__((target_clones("arch=x86-64-v3", "default")))
#else
#define SYMCUSHION_CLONES
#endif
"""

#: The definitions of CasADi's functions in its generated C (one per Function).
_DEFINITION = re.compile(r"^static int (casadi_f\d+)\((.*)\) \{$", re.M)


def with_clones(text: str) -> str:
    """CasADi's C with ``SYMCUSHION_CLONES`` on each of its function definitions, and
    the macro (:data:`TARGET_CLONES`) defined before the first."""
    first = _DEFINITION.search(text)
    if first is None:
        raise RuntimeError("no function definition found in CasADi's generated C: has "
                           "its format changed? Generate without clones.")
    # before the comment CasADi writes on the line above (the Function's signature)
    start = text.rfind("\n", 0, first.start() - 1) + 1
    start = start if text.startswith("/*", start) else first.start()
    text = text[:start] + TARGET_CLONES + "\n" + text[start:]
    return _DEFINITION.sub(r"SYMCUSHION_CLONES static int \1(\2) {", text)


#: CasADi's fmax and fmin helpers call the C library's (gcc inlines them only under
#: -ffinite-math-only, which the guarded if_else cannot have): 300 calls in the
#: envelope's step, 2 % of its time. On x86-64 glibc fmax(x, y) is maxsd, x > y ? x :
#: y, with a NaN argument giving the other one; written out so that gcc inlines it,
#: the same bits. Elsewhere (aarch64's fmaxnm orders -0 below +0) the library call.
_LIBM_MINMAX = {
    "  return fmax(x, y);": "  return y != y ? x : (x > y ? x : y);",
    "  return fmin(x, y);": "  return y != y ? x : (x < y ? x : y);",
}


def with_inline_minmax(text: str) -> str:
    """CasADi's C with ``casadi_fmax`` and ``casadi_fmin`` written out on x86-64 glibc,
    where they give the C library's bits (:data:`_LIBM_MINMAX`)."""
    for call, inline in _LIBM_MINMAX.items():
        text = text.replace(call, "#if defined(__x86_64__) && defined(__GLIBC__)\n"
                            f"{inline}\n#else\n{call}\n#endif")
    return text


#: Warnings requested on every compile; the build fails on none, the tests
#: check that gcc prints nothing.
WARNINGS = ("-Wall",)


def find_compiler() -> str | None:
    """The C compiler to use: ``$CC`` if set, else ``gcc`` on the PATH, else None."""
    cc = os.environ.get("CC") or "gcc"
    return shutil.which(cc)


def build_fingerprint(paths, flags) -> str:
    h = hashlib.sha256()
    for p in paths:
        h.update(Path(p).name.encode())
        h.update(Path(p).read_bytes())
    h.update(" ".join(flags).encode())
    h.update((find_compiler() or "").encode())
    return h.hexdigest()


def _compile_commands(cc, out_dir: Path, sources: dict, with_program: bool):
    """gcc commands: objects (in parallel), then library and program."""
    objects, cmds = [], []
    for name, src in sources.items():
        obj = out_dir / (name + ".o")
        cmds.append((name + ".o", [cc, *CFLAGS, *WARNINGS, "-c", str(src), "-o", str(obj)]))
        objects.append(str(obj))
    link = [(LIBRARY, [cc, "-shared", *objects, "-o", str(out_dir / LIBRARY), "-lm"])]
    if with_program:
        link.append((PROGRAM, [cc, *CFLAGS, *WARNINGS, "-I", str(out_dir), str(out_dir / MAIN),
                               *objects, "-o", str(out_dir / PROGRAM), "-lm"]))
    return cmds, link


def run_parallel(commands, seconds: dict, progress: bool):
    """Run (label, argv) commands concurrently; raise with gcc's output on failure.

    Records each command's wall time in ``seconds``; returns what gcc printed,
    by label, for the commands that printed anything.
    """
    def run(label, argv):
        if progress:
            print(f"  gcc: {label}", flush=True)
        start = time.perf_counter()
        done = subprocess.run(argv, capture_output=True, text=True)
        return label, argv, time.perf_counter() - start, done

    with ThreadPoolExecutor(max_workers=max(1, len(commands))) as pool:
        results = list(pool.map(lambda c: run(*c), commands))
    warnings = {}
    for label, argv, sec, done in results:
        seconds[label] = sec
        if done.returncode != 0:
            raise RuntimeError(f"compiling {label} failed ({' '.join(argv)}):\n"
                               f"{done.stderr}{done.stdout}")
        if done.stderr.strip():
            warnings[label] = done.stderr
    return warnings


def build_sources(out: Path, sources: dict, with_program: bool, fingerprint: str,
           old: dict | None, progress: bool) -> dict:
    """Compile the sources unless ``old`` records a build of the same fingerprint."""
    library, program = out / LIBRARY, out / PROGRAM
    if (old and old.get("fingerprint") == fingerprint and library.is_file()
            and (not with_program or program.is_file())):
        if progress:
            print(f"{library} is up to date", flush=True)
        return old
    for stale in (library, program):
        if stale.exists():
            stale.unlink()
    cc = find_compiler()
    cmds, link = _compile_commands(cc, out, sources, with_program)
    seconds = {}
    warnings = run_parallel(cmds, seconds, progress)
    warnings.update(run_parallel(link, seconds, progress))
    for label, err in warnings.items():
        print(f"gcc printed, compiling {label}:\n{err}", file=sys.stderr)
    if progress:
        print("built " + ", ".join(f"{k} {v:.1f} s" for k, v in seconds.items()), flush=True)
    return {"fingerprint": fingerprint, "compiler": cc, "seconds": seconds,
            "warnings": warnings, "commands": [" ".join(c) for _, c in cmds + link]}


@dataclass
class CachedBuild:
    """A library compiled by :func:`compile_cached`.

    Attributes
    ----------
    library, folder : Path
        The shared library and its cache folder.
    digest : str
        SHA-256 of the source, flags and compiler (the folder's fingerprint).
    flags : list of str
    compiler : str
    fresh : bool
        True if this call compiled it, False if it was in the cache.
    """

    library: Path
    folder: Path
    digest: str
    flags: list
    compiler: str
    fresh: bool


def compile_cached(f, source_name: str, library_name: str, cache_dir: Path,
                   stem: str, note: str | None = None, cflags=CFLAGS,
                   clones: bool = False) -> CachedBuild:
    """Generate C for ``f`` and compile it once per fingerprint into ``cache_dir``.

    ``f`` is a ``casadi.Function`` or a sequence of them, generated into the
    one source (e.g. a Function and its ``jac_`` Jacobian, the symbol
    ``casadi.external`` looks for). The source is fingerprinted with the
    flags (``cflags``, default :data:`CFLAGS`, plus :data:`WARNINGS`) and
    the compiler and built into
    ``cache_dir/<stem>-<fingerprint>/`` unless that folder already holds the
    library, so repeated runs, tests and Dask workers reuse one build and two
    different Functions never share a path (a process cannot load two
    libraries from one path). The library is written under a temporary name
    and renamed, so concurrent builders agree. ``note`` (if given) is printed
    to stderr before compiling. ``clones``: every function is compiled in the
    clones of :data:`TARGET_CLONES` (the same bits, faster where the CPU has
    AVX2, about twice gcc's time).
    """
    cc = find_compiler()
    if cc is None:
        raise FileNotFoundError("no C compiler: set $CC or install gcc; "
                                f"{library_name} runs compiled code only.")
    with tempfile.TemporaryDirectory(prefix="symcushion-cache-") as tmp:
        cg = ca.CodeGenerator(source_name, dict(CODEGEN_OPTIONS, with_header=False))
        for one in ([f] if isinstance(f, ca.Function) else f):
            cg.add(one)
        cg.generate(tmp + os.sep)
        source = (Path(tmp) / source_name).read_bytes()
    source = with_inline_minmax(source.decode()).encode()
    if clones:
        source = with_clones(source.decode()).encode()
    flags = [*cflags, *WARNINGS]
    digest = hashlib.sha256(source + " ".join(flags).encode() + cc.encode()).hexdigest()
    folder = Path(cache_dir) / f"{stem}-{digest[:16]}"
    library = folder / library_name
    if library.is_file():
        return CachedBuild(library, folder, digest, flags, cc, fresh=False)
    folder.mkdir(parents=True, exist_ok=True)
    (folder / source_name).write_bytes(source)
    if note:
        print(f"compiling {note} in {folder} ...", file=sys.stderr, flush=True)
    partial = folder / f".{library_name}.{os.getpid()}"
    argv = [cc, *flags, "-shared", str(folder / source_name), "-o", str(partial), "-lm"]
    done = subprocess.run(argv, capture_output=True, text=True)
    if done.returncode != 0:
        raise RuntimeError(f"compiling {folder / source_name} failed ({' '.join(argv)}):\n"
                           f"{done.stderr}{done.stdout}")
    if done.stderr.strip():
        print(f"gcc printed, compiling {source_name}:\n{done.stderr}", file=sys.stderr)
    os.replace(partial, library)
    return CachedBuild(library, folder, digest, flags, cc, fresh=True)
