"""Loading compiled code: the Functions of a build folder, and programs linked to it.

This module owns reading a build folder that :func:`symcushion.compiled.codegen.generate`
wrote and built: :func:`load_compiled` (its library's Functions through
``casadi.external``, refused when the build is stale) and
:func:`build_program` (your own C program compiled and linked against its
objects with the flags of ``symcushion.compiled.cbuild``). It must not generate or
rebuild the folder's sources.
"""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import casadi as ca

from symcushion.compiled.cbuild import CFLAGS, LIBRARY, MANIFEST, WARNINGS, find_compiler

__all__ = ["load_compiled", "build_program"]


def load_compiled(path) -> dict:
    """The compiled Functions of a build folder, by name, via ``casadi.external``.

    Parameters
    ----------
    path : str or Path
        The folder given to :func:`generate` with ``build=True``, or its
        ``libsymcushion.so``.

    Returns
    -------
    dict of str to casadi.Function
        ``{'contact_step_paper': ..., 'touchdown_step': ..., ...}``, the
        functions listed in the folder's ``symcushion.json``, with the same
        named inputs and outputs as the SX Functions they were generated from.
        They evaluate numerically only (no derivatives are generated).
    """
    path = Path(path)
    folder = path.parent if path.suffix == ".so" else path
    library = path if path.suffix == ".so" else folder / LIBRARY
    manifest = folder / MANIFEST
    if not library.is_file() or not manifest.is_file():
        raise FileNotFoundError(f"no compiled symcushion library in {str(folder)!r}: run "
                                f"`symcushion codegen --out {folder} --build` first.")
    info = json.loads(manifest.read_text())
    if (info.get("build") or {}).get("fingerprint") != info["fingerprint"]:
        raise FileNotFoundError(f"{library} was built from other sources than those now in "
                                f"{str(folder)!r}: rebuild with `symcushion codegen --out "
                                f"{folder} --build` (add --scene as before).")
    return {name: ca.external(name, str(library.resolve())) for name in info["functions"]}


def build_program(out_dir, source, name: str | None = None) -> Path:
    """Compile your own C program against a build folder's generated code.

    ``source`` includes ``symcushion.h`` and calls the generated Functions; it
    is compiled with :data:`CFLAGS` and :data:`WARNINGS`, ``-I out_dir``, and
    linked with the folder's objects (the build of :func:`generate` with
    ``build=True``) into ``out_dir/name``.

    Parameters
    ----------
    out_dir : str or Path
    source : str or Path
        A C file.
    name : str, optional
        The program's file name; default the source's stem.

    Returns
    -------
    Path
        The program.
    """
    out = Path(out_dir)
    source = Path(source)
    manifest = out / MANIFEST
    info = json.loads(manifest.read_text()) if manifest.is_file() else {}
    objects = [out / (stem + ".o") for stem in info.get("sources", {})]
    if not objects or not all(o.is_file() for o in objects):
        raise FileNotFoundError(f"no compiled symcushion objects in {str(out)!r}: run "
                                f"`symcushion codegen --out {out} --build` first.")
    if not source.is_file():
        raise FileNotFoundError(f"C source {str(source)!r} does not exist.")
    program = out / (name or source.stem)
    argv = [find_compiler(), *CFLAGS, *WARNINGS, "-I", str(out), str(source),
            *map(str, objects), "-o", str(program), "-lm"]
    run = subprocess.run(argv, capture_output=True, text=True)
    if run.returncode != 0:
        raise RuntimeError(f"compiling {source} failed ({' '.join(argv)}):\n{run.stderr}")
    if run.stderr.strip():
        print(f"gcc printed, compiling {source.name}:\n{run.stderr}", file=sys.stderr)
    return program
