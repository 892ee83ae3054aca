"""Compiling ``envelope_case`` and running batches of cases through it.

Owns the generated-and-compiled library of a scene's case Function (through
:func:`symcushion.compiled.codegen.compile_cached`, the one build-and-cache of the
package), loading it once per process, and the threaded ``map`` over a batch
(and the Dask task wrapping it). It must not sample or classify.
"""
from __future__ import annotations

import hashlib
import json
import os
import pickle
import time
from pathlib import Path

import casadi as ca
import numpy as np

from symcushion.compiled.cbuild import CFLAGS, WARNINGS
from symcushion.compiled.codegen import compile_cached, find_compiler
from symcushion.model.scene import scene_from_dict
from symcushion.model.scene_data import Scene
from symcushion.scheme.touchdown import build_model
from symcushion.envelope.cases import envelope_function, NO_STOP, STOP, SUMMARY

__all__ = ["DEFAULT_CACHE", "batch_map", "build_envelope", "run_batch"]

#: Default folder of the compiled case Functions, one sub-folder per source
#: fingerprint (git-ignored: ``build/`` is in .gitignore).
DEFAULT_CACHE = Path("build") / "envelope"
_SOURCE = "envelope_case.c"
_LIBRARY = "libenvelope_case.so"
_MANIFEST = "envelope.json"
#: Sub-folder of the cache that maps what a library was built from (the scene,
#: the steps, symcushion's source, CasADi, flags, compiler) to its folder, so
#: that a study whose library is built already skips building the step's graph
#: and generating its C (1–3 s of every start, docs/envelope.md, "Throughput").
_INDEX = "index"
_PACKAGE = Path(__file__).resolve().parents[1]
_PACKAGE_DIGEST: list = []


def _package_digest() -> bytes:
    """Digest of every Python source of symcushion (once per process): the code that
    turns a scene into C."""
    if not _PACKAGE_DIGEST:
        digest = hashlib.sha256()
        for path in sorted(_PACKAGE.rglob("*.py")):
            digest.update(str(path.relative_to(_PACKAGE)).encode() + b"\0" + path.read_bytes())
        _PACKAGE_DIGEST.append(digest.digest())
    return _PACKAGE_DIGEST[0]


def _input_key(scene: Scene, steps: int) -> str | None:
    """Key of everything the generated C of ``envelope_case`` depends on, or None when
    the scene cannot be pickled (then the C is generated and fingerprinted as usual).

    A key that differs for the same C only costs a generation; one that matched for
    different C would load a wrong library, so it holds the whole scene (pickled),
    the steps, the package's source, CasADi's version, the flags and the compiler."""
    try:
        blob = pickle.dumps((scene, int(steps)), protocol=4)
    except Exception:   # noqa: BLE001 (an unpicklable scene only loses the shortcut)
        return None
    digest = hashlib.sha256(blob)
    digest.update(_package_digest())
    digest.update(" ".join([ca.__version__, *CFLAGS, *WARNINGS, str(find_compiler())]).encode())
    return digest.hexdigest()


def build_envelope(scene: Scene, cache_dir=None, *, steps: int | None = None,
                   progress: bool = False) -> Path:
    """Generate and compile ``envelope_case`` for a scene; return the library's path.

    The C source is generated (a second or two), fingerprinted with the flags
    and compiler, and compiled into ``cache_dir/<scene name>-<fingerprint>/``
    unless that folder already holds the library (a scene built before is
    found without generating its C, by the key of :func:`_input_key` in
    ``cache_dir/index/``), so repeated studies, tests
    and Dask workers reuse one build and different scenes (or μ) never share
    a path (a process cannot load two libraries from one path). Flags are
    those of ``symcushion.compiled.codegen`` (:data:`~symcushion.compiled.codegen.CFLAGS`).

    Parameters
    ----------
    scene : Scene
    cache_dir : str or Path, optional
        Default :data:`DEFAULT_CACHE`.
    steps : int, optional
        Steps per case; default ``scene.steps``.

    Returns
    -------
    Path
        ``libenvelope_case.so``, for ``casadi.external("envelope_case", path)``.
    """
    started = time.perf_counter()
    n_steps = scene.steps if steps is None else steps
    cache = Path(DEFAULT_CACHE if cache_dir is None else cache_dir)
    key = _input_key(scene, n_steps)
    entry = None if key is None else cache / _INDEX / f"{safe_file_name(scene.name)}-{key[:32]}.json"
    if entry is not None and entry.is_file():
        try:
            library = cache / json.loads(entry.read_text())["library"]
        except (ValueError, KeyError, OSError):
            library = None
        if library is not None and library.is_file():
            return library
    model = build_model(scene)
    note = (f"envelope_case for '{scene.name}' (method {scene.method}, "
            f"{'μ an input' if scene.mu > 0 else 'frictionless'}, {n_steps} steps)")
    built = compile_cached(envelope_function(model, steps), _SOURCE, _LIBRARY, cache,
                           safe_file_name(scene.name), note=note if progress else None,
                           clones=True)
    if built.fresh:
        (built.folder / _MANIFEST).write_text(json.dumps({
            "scene": scene.name, "method": scene.method, "friction": scene.mu > 0,
            "dt": scene.dt, "steps": n_steps, "nx": model.nx, "np": model.np,
            "summary": list(SUMMARY), "instructions": model.step.n_instructions(),
            "cflags": built.flags, "compiler": built.compiler, "fingerprint": built.digest,
            "casadi": ca.__version__, "seconds": time.perf_counter() - started}, indent=1))
    if entry is not None:
        entry.parent.mkdir(parents=True, exist_ok=True)
        partial = entry.with_name(f".{entry.name}.{os.getpid()}")
        partial.write_text(json.dumps({"library": str(built.library.relative_to(cache))}))
        os.replace(partial, entry)
    return built.library


def safe_file_name(name: str) -> str:
    return "".join(ch if ch.isalnum() or ch in "-_" else "_" for ch in name) or "scene"


_LOADED: dict = {}
_MAPS: dict = {}


def _case_function(library) -> ca.Function:
    """``envelope_case`` from a library, loaded once per process."""
    key = str(Path(library).resolve())
    if key not in _LOADED:
        if not Path(key).is_file():
            raise FileNotFoundError(f"compiled envelope library {key!r} does not exist; "
                                    "build it with `build_envelope(scene, cache_dir)`.")
        _LOADED[key] = ca.external("envelope_case", key)
    return _LOADED[key]


def batch_map(library, count: int, threads: int = 1) -> ca.Function:
    """``map`` of a library's ``envelope_case`` over ``count`` cases on ``threads``
    threads (serial for 1), made once per process."""
    f = _case_function(library)
    threads = max(1, min(int(threads), count))
    key = (id(f), count, threads)
    if key not in _MAPS:
        _MAPS[key] = f.map(count, "thread", threads) if threads > 1 else f.map(count, "serial")
    return _MAPS[key]


def run_batch(library, x0, p, dt, threads: int = 1, stop=NO_STOP) -> tuple:
    """Run a batch of cases through a compiled ``envelope_case``.

    Parameters
    ----------
    library : str or Path
        From :func:`build_envelope`.
    x0 : array_like, shape (nx, B)
    p : array_like, shape (np, B)
        Each case's step parameters (:func:`case_params`: the legs' curves,
        μ, the slope frame's gravity, mass, inertia).
    dt : float
    threads : int
        Threads of ``map(B, "thread", threads)``; 1 runs serially.
    stop : array_like, shape (3,)
        When a case stops (:func:`~symcushion.envelope.cases.stop_vector`); default
        never: every case runs the whole duration.

    Returns
    -------
    x_end : ndarray, shape (nx, B)
    summary : ndarray, shape (len(SUMMARY), B)
    """
    f = _case_function(library)
    x0 = np.asarray(x0, dtype=float)
    p = np.asarray(p, dtype=float)
    count = x0.shape[1]
    if x0.shape[0] != f.size1_in(0) or p.shape != (f.size1_in(1), count):
        raise ValueError(f"`x0` must be ({f.size1_in(0)}, B) and `p` ({f.size1_in(1)}, B), got "
                         f"{x0.shape} and {p.shape}.")
    stop = np.asarray(stop, dtype=float)
    if stop.shape != (len(STOP),) or np.isnan(stop).any():
        raise ValueError(f"`stop` must be {len(STOP)} numbers ({', '.join(STOP)}), got {stop!r}.")
    x_end, summary = batch_map(library, count, threads)(x0, p, float(dt), stop)
    return np.asarray(x_end, dtype=float), np.asarray(summary, dtype=float)


def dask_batch(library, scene_data, source, cache_dir, x0, p, dt, stop=NO_STOP):
    """A Dask task: one batch; builds the library on the worker if it cannot see it."""
    if not Path(library).is_file():
        if scene_data is None:
            raise FileNotFoundError(f"this worker cannot see {library!r} and has no scene to "
                                    "build it from: put `cache_dir` on a shared filesystem or "
                                    "load the study from a file (docs/envelope.md).")
        scene = scene_from_dict(scene_data, source)
        library = build_envelope(scene, cache_dir)
    return run_batch(library, x0, p, dt, threads=1, stop=stop)
