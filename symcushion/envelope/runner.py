"""Running an envelope study: locally on threads or as Dask tasks.

Owns :func:`run_envelope` (sample, build, run in batches, classify, write),
:func:`evaluate` (given conditions), the grouping of cases into batches by
library (frictionless or with friction), the finished batches kept on disk
while a study runs (so an interrupted study resumes from them), progress
lines and writing the results. It must not define the case Function or the
classification.
"""
from __future__ import annotations

import hashlib
import json
import os
import shutil
import sys
import time
from concurrent.futures import ThreadPoolExecutor, as_completed
from pathlib import Path

import numpy as np

from symcushion.run.matlab import write_table_mat
from symcushion.run.output_files import atomic_write_text, replacing
from symcushion.model.scene_data import Scene
from symcushion.envelope.build import (batch_map, dask_batch, safe_file_name, build_envelope,
    DEFAULT_CACHE, run_batch)
from symcushion.envelope.cases import (apply_design, case_params, initial_states, reach,
    study_stop, SUMMARY)
from symcushion.envelope.classify import classify
from symcushion.envelope.plots import plot_envelope
from symcushion.envelope.statistics import EnvelopeResult
from symcushion.envelope.study import (check_counts, CONDITION_DEFAULTS, EnvelopeStudy, VARIABLES,
    sample_conditions)

__all__ = ["PROGRESS_INTERVAL", "PROGRESS_LOG_INTERVAL", "BATCH_DIR", "run_envelope", "evaluate",
           "dask_client", "write_result", "output_names"]

#: Seconds between updates of the progress bar on a terminal.
PROGRESS_INTERVAL = 0.5
#: Seconds between plain progress lines when stderr is not a terminal (a log
#: file, CI): the example study runs for minutes, and a bar that tqdm hides
#: there would leave its log silent until the end.
PROGRESS_LOG_INTERVAL = 30.0
#: Folder, inside a study's output folder, of the batches finished so far: each
#: is written as it finishes, so an interrupted study keeps them and
#: ``run_envelope(..., resume=True)`` runs only the others. Removed once
#: cases.csv and summary.json are written.
BATCH_DIR = "batches"
_BATCH_MANIFEST = "study.json"


class _Progress:
    """Progress on stderr: cases done, cases per second, time left.

    On a terminal a tqdm bar (well kept, estimates the rate and the time
    left); elsewhere a plain line every :data:`PROGRESS_LOG_INTERVAL` seconds
    and one at the end, which a log keeps one per line.
    """

    def __init__(self, total: int, enabled: bool, label: str, stream=None):
        from tqdm.auto import tqdm

        self.stream = sys.stderr if stream is None else stream
        self.total, self.done, self.label = total, 0, label
        self.started = self.last_line = time.perf_counter()
        terminal = bool(getattr(self.stream, "isatty", lambda: False)())
        self.lines = enabled and not terminal
        self.bar = tqdm(total=total, unit="case", desc=f"  {label}", file=self.stream,
                        mininterval=PROGRESS_INTERVAL, leave=True,
                        disable=not (enabled and terminal))

    def update(self, count: int):
        self.done += count
        self.bar.update(count)
        now = time.perf_counter()
        finished = self.done >= self.total
        if self.lines and (finished or now - self.last_line >= PROGRESS_LOG_INTERVAL):
            self.last_line = now
            rate = self.done / max(now - self.started, 1e-9)
            left = (self.total - self.done) / rate if rate > 0 else float("inf")
            print(f"  {self.label}: {self.done:,}/{self.total:,} cases, {rate:.1f} cases/s, "
                  f"{left / 60:.1f} min left", file=self.stream, flush=True)
        if finished:
            self.bar.close()


def _tasks(conditions: dict, batch: int) -> list:
    """(friction, indices) per batch: frictionless cases (μ = 0) run on the smaller
    graph without friction paths, every other μ on one friction library."""
    friction = conditions["mu"] > 0
    tasks = []
    for key in (False, True):
        idx = np.flatnonzero(friction == key)
        tasks += [(key, idx[i:i + batch]) for i in range(0, len(idx), batch)]
    return tasks


def _level_scene(scene: Scene, friction: bool, mu: np.ndarray) -> Scene:
    """The scene whose graph runs the cases: frictionless, or with friction (μ an input)."""
    if not friction:
        return scene.with_(mu=0.0)
    return scene if scene.mu > 0 else scene.with_(mu=float(np.max(mu)))


def case_libraries(study: EnvelopeStudy, mu: np.ndarray, cache_dir, progress: bool) -> dict:
    """One compiled library per kind of case present (frictionless, friction)."""
    return {friction: build_envelope(_level_scene(study.scene, friction, mu), cache_dir,
                                     progress=progress)
            for friction in sorted({bool(v > 0) for v in mu})}


def _all_params(study: EnvelopeStudy, mu: np.ndarray, gravity: np.ndarray,
                design: dict | None = None) -> dict:
    """Each kind's parameter columns (np, n), indexed by case, with ``design`` applied."""
    out = {}
    for friction in sorted({bool(v > 0) for v in mu}):
        scene = _level_scene(study.scene, friction, mu)
        p = case_params(scene, np.where(mu > 0, mu, 0.0) if friction else np.zeros_like(mu),
                        gravity)
        out[friction] = apply_design(scene, p, design)
    return out


def _scene_data(study: EnvelopeStudy, friction: bool, mu: np.ndarray) -> dict | None:
    if study.scene_data is None:
        return None
    raw = json.loads(json.dumps(study.scene_data))
    raw.setdefault("scene", {})["mu"] = _level_scene(study.scene, friction, mu).mu
    return raw


def _fingerprint(x0, p: dict, tasks: list, libraries: dict, dt: float, stop) -> str:
    """What the batches' results depend on: every case's initial state and
    parameters, the grouping into batches, Δt, when cases stop and the compiled libraries (their
    folder names carry the fingerprint of the generated source)."""
    digest = hashlib.sha256()
    digest.update(np.ascontiguousarray(x0, dtype=float).tobytes())
    for friction in sorted(p):
        digest.update(np.ascontiguousarray(p[friction], dtype=float).tobytes())
        digest.update(Path(libraries[friction]).parent.name.encode())
    for friction, idx in tasks:
        digest.update(bytes([friction]) + np.asarray(idx, dtype=np.int64).tobytes())
    digest.update(repr(float(dt)).encode())
    digest.update(np.asarray(stop, dtype=float).tobytes())
    return digest.hexdigest()


class _Batches:
    """The finished batches of a study in ``out_dir/batches``, one NPZ each.

    A fresh run starts the folder with a manifest holding the study's
    fingerprint (:func:`_fingerprint`); a resumed run requires the same
    fingerprint, so batches are only ever combined with those of the same
    cases. Each batch is written atomically as it finishes.
    """

    def __init__(self, out_dir, fingerprint: str, total: int, resume: bool):
        self.folder = Path(out_dir) / BATCH_DIR
        manifest = self.folder / _BATCH_MANIFEST
        if resume:
            if not manifest.is_file():
                raise ValueError(f"`resume`: {Path(out_dir)} holds no finished batches of an "
                                 f"interrupted study ({BATCH_DIR}/{_BATCH_MANIFEST} is missing); "
                                 "run the study without --resume.")
            saved = json.loads(manifest.read_text())
            if saved.get("fingerprint") != fingerprint:
                raise ValueError(f"`resume`: the finished batches in {self.folder} belong to "
                                 "another study (other cases, scene, batch size or design); "
                                 "resume with the same study file and options, or start again "
                                 "with --overwrite.")
            return
        if self.folder.exists():
            shutil.rmtree(self.folder)
        self.folder.mkdir(parents=True)
        atomic_write_text(manifest, json.dumps({"fingerprint": fingerprint, "tasks": total}))

    def _path(self, k: int) -> Path:
        return self.folder / f"batch_{k:06d}.npz"

    def load(self, tasks: list) -> dict:
        """The finished batches by task number: (x_end, summary) of their cases."""
        done = {}
        for k, (_, idx) in enumerate(tasks):
            if self._path(k).is_file():
                with np.load(self._path(k), allow_pickle=False) as z:
                    if np.array_equal(z["index"], idx):
                        done[k] = (z["x_end"], z["summary"])
        return done

    def save(self, k: int, idx, x_end, summary):
        with replacing(self._path(k)) as tmp:
            np.savez(tmp, index=np.asarray(idx), x_end=x_end, summary=summary)

    def remove(self):
        shutil.rmtree(self.folder, ignore_errors=True)


def output_names(study: EnvelopeStudy) -> tuple:
    """Names of every file and folder a study writes into its output folder."""
    name = safe_file_name(study.name)                # as the figures name their files
    return ("cases.csv", "cases.mat", "summary.json", f"{name}.png", f"{name}_pstable.png",
            f"{name}_pstable.csv", f"{name}_distributions.png", BATCH_DIR)


def run_envelope(study: EnvelopeStudy, out_dir=None, *, threads: int | None = None,
                 dask: bool = False, scheduler: str | None = None, workers: int = 2,
                 cache_dir=None, progress: bool = True, plots: bool = True,
                 design: dict | None = None, resume: bool = False) -> EnvelopeResult:
    """Sample, run, classify and (with ``out_dir``) write an envelope study.

    Parameters
    ----------
    study : EnvelopeStudy
    out_dir : str or Path, optional
        Writes ``cases.csv``, ``summary.json`` and, with ``plots``, the figures
        (:func:`plot_envelope`). While the study runs, each finished batch is
        kept in ``out_dir/batches`` (:data:`BATCH_DIR`), removed at the end.
    threads : int, optional
        Worker threads of the local run, each running whole batches; default
        every core (``os.cpu_count()``).
    dask : bool
        Run the batches as Dask tasks: on ``scheduler`` (an address such as
        ``tcp://host:8786``) or, without one, on an in-process
        ``LocalCluster`` of ``workers`` single-threaded worker processes.
        Results equal the local run's bit for bit.
    workers : int
        Workers of the local Dask cluster.
    cache_dir : str or Path, optional
        Where compiled Functions are kept (:func:`build_envelope`); on a real
        cluster put it on a filesystem the workers share, or let each worker
        build its own copy.
    progress : bool
        A progress line on stderr.
    design : dict, optional
        Values of the legs' tunable curve parameters by name
        (:func:`~symcushion.envelope.cases.apply_design`), e.g. an optimised
        design; default the scene's own. One compiled library serves every
        design.

    Returns
    -------
    EnvelopeResult
    """
    if scheduler is not None:
        dask = True
    threads = (os.cpu_count() or 1) if threads is None else threads
    if isinstance(threads, bool) or not isinstance(threads, int) or threads < 1:
        raise ValueError(f"`threads` must be a positive integer, got {threads!r}.")
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ValueError(f"`workers` must be a positive integer, got {workers!r}.")
    check_counts(study)
    started = time.perf_counter()
    conditions = sample_conditions(study)
    x0, gravity = initial_states(study, conditions)
    prepare_seconds = time.perf_counter() - started
    scene = study.scene
    started = time.perf_counter()
    libraries = case_libraries(study, conditions["mu"], cache_dir, progress)
    p = _all_params(study, conditions["mu"], gravity, design)
    build_seconds = time.perf_counter() - started
    tasks = _tasks(conditions, study.batch)
    if resume and out_dir is None:
        raise ValueError("`resume` continues a study from the batches in its `out_dir`; give "
                         "`out_dir`.")
    batches = None if out_dir is None else _Batches(
        out_dir, _fingerprint(x0, p, tasks, libraries, scene.dt, study_stop(study)), len(tasks),
        resume)
    finished = {} if batches is None else batches.load(tasks)
    x_end = np.zeros_like(x0)
    summary = np.zeros((len(SUMMARY), study.n))
    backend = "dask" if dask else "threads"
    bar = _Progress(study.n, progress, f"{study.name} ({backend})")
    for k, (xe, sm) in finished.items():
        idx = tasks[k][1]
        x_end[:, idx], summary[:, idx] = xe, sm
        bar.update(len(idx))

    def done(k, xe, sm):
        idx = tasks[k][1]
        x_end[:, idx], summary[:, idx] = xe, sm
        if batches is not None:
            batches.save(k, idx, xe, sm)
        bar.update(len(idx))

    todo = [k for k in range(len(tasks)) if k not in finished]
    started = time.perf_counter()
    info = {}
    if not dask:
        _run_local(tasks, todo, libraries, x0, p, scene.dt, study_stop(study), threads, done)
        info = {"threads": threads}
    else:
        # run_seconds leaves out the cluster's start (reported as startup_seconds)
        info = _run_dask(study, tasks, todo, libraries, x0, conditions["mu"], p, done, bar,
                         scheduler, workers, cache_dir)
    if finished:
        info["resumed_cases"] = int(sum(len(tasks[k][1]) for k in finished))
    run_seconds = info.pop("compute_seconds", time.perf_counter() - started)
    started = time.perf_counter()
    columns = classify(summary, x_end, gravity, x0, study.limits, len(scene.legs),
                       reach(scene))
    classify_seconds = time.perf_counter() - started
    timings = {"backend": backend, **info, "batch": study.batch,
               "prepare_seconds": round(prepare_seconds, 3),
               "build_seconds": round(build_seconds, 3), "run_seconds": round(run_seconds, 3),
               "classify_seconds": round(classify_seconds, 3),
               "cases_per_second": round((study.n - info.get("resumed_cases", 0))
                                         / max(run_seconds, 1e-9), 1),
               "steps_per_case": scene.steps, "dt": scene.dt,
               # a case stops once its class is decided (study_stop): the steps it ran
               "mean_steps_run": round(float(np.mean(columns["end_time"])) / scene.dt, 1)}
    result = EnvelopeResult(study, conditions, columns, timings)
    if out_dir is not None:
        write_result(result, out_dir, plots=plots)
        batches.remove()
    return result


def evaluate(study: EnvelopeStudy, conditions: dict, *, threads: int = 1, cache_dir=None,
             progress: bool = False, design: dict | None = None) -> dict:
    """Run and classify given touchdown conditions (not sampled), e.g. hand-built cases.

    Parameters
    ----------
    study : EnvelopeStudy
        Scene and limits (its sampling is not used).
    conditions : dict
        Values or arrays by name of :data:`VARIABLES`; missing names take the
        study's fixed value or the default (0; μ the scene's).

    Returns
    -------
    dict of str to ndarray
        The columns of :func:`classify`.
    """
    unknown = sorted(set(conditions) - set(VARIABLES))
    if unknown:
        raise ValueError(f"`conditions`: unknown name(s) {unknown}; allowed: {list(VARIABLES)}.")
    arrays = {k: np.atleast_1d(np.asarray(v, dtype=float)) for k, v in conditions.items()}
    n = max(len(v) for v in arrays.values()) if arrays else 1
    full = {}
    for name in VARIABLES:
        if name in arrays:
            full[name] = np.broadcast_to(arrays[name], (n,)).copy()
        else:
            r = study.ranges.get(name)
            value = r.value if r is not None and r.kind == "fixed" else \
                (study.scene.mu if name == "mu" else CONDITION_DEFAULTS[name])
            full[name] = np.full(n, value)
    x0, gravity = initial_states(study, full)
    libraries = case_libraries(study, full["mu"], cache_dir, progress)
    p = _all_params(study, full["mu"], gravity, design)
    x_end = np.zeros_like(x0)
    summary = np.zeros((len(SUMMARY), n))
    for friction, idx in _tasks(full, study.batch):
        x_end[:, idx], summary[:, idx] = run_batch(libraries[friction], x0[:, idx],
                                                   p[friction][:, idx], study.scene.dt, threads,
                                                   study_stop(study))
    return classify(summary, x_end, gravity, x0, study.limits, len(study.scene.legs),
                    reach(study.scene))


def _run_local(tasks, todo, libraries, x0, p, dt, stop, threads: int, done):
    """The batches on ``threads`` worker threads, each batch serial on one of them.

    A worker takes the next batch when it finishes one (CasADi releases the GIL
    while compiled code runs), so cases that stop early leave no thread idle:
    a ``map`` over one batch on several threads splits it into equal parts and
    waits for the slowest. ``done`` runs in this thread, in the order batches
    finish; an interrupt cancels the batches not started."""
    if threads == 1:
        for k in todo:
            friction, idx = tasks[k]
            done(k, *run_batch(libraries[friction], x0[:, idx], p[friction][:, idx], dt, 1, stop))
        return
    for k in todo:       # build each map once, here, before the threads use it
        friction, idx = tasks[k]
        batch_map(libraries[friction], len(idx), 1)
    pool = ThreadPoolExecutor(max_workers=threads)
    try:
        futures = {pool.submit(run_batch, libraries[tasks[k][0]], x0[:, tasks[k][1]],
                               p[tasks[k][0]][:, tasks[k][1]], dt, 1, stop): k for k in todo}
        for fut in as_completed(futures):
            done(futures[fut], *fut.result())
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


def dask_client(address: str):
    """A ``distributed.Client`` on the scheduler at ``address`` (the optional extra)."""
    try:
        from distributed import Client
    except ImportError:
        raise ImportError("--scheduler needs the optional extra: pip install "
                          "'symcushion[dask]'.") from None
    return Client(address)


def _run_dask(study, tasks, todo, libraries, x0, mu, p, done, bar, scheduler,
              workers, cache_dir) -> dict:
    try:
        from distributed import Client, LocalCluster, as_completed
    except ImportError:
        raise ImportError("the Dask backend needs the optional extra: pip install "
                          "'symcushion[dask]' (dask[distributed]).") from None
    cluster = None
    started = time.perf_counter()
    if scheduler is None:
        cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                               dashboard_address=None, silence_logs=40)
        client = Client(cluster)
    else:
        client = Client(scheduler)
    cache = str(Path(DEFAULT_CACHE if cache_dir is None else cache_dir).resolve())
    startup = time.perf_counter() - started
    bar.started = time.perf_counter()
    try:
        futures = {}
        for k in todo:
            friction, idx = tasks[k]
            fut = client.submit(dask_batch, str(Path(libraries[friction]).resolve()),
                                _scene_data(study, friction, mu), study.source, cache,
                                x0[:, idx], p[friction][:, idx], study.scene.dt,
                                study_stop(study),
                                key=f"envelope-{study.name}-{study.seed}-{k}-{os.getpid()}-"
                                    f"{time.monotonic_ns()}")
            futures[fut] = k
        for fut in as_completed(futures):
            done(futures[fut], *fut.result())
        compute = time.perf_counter() - bar.started
        n_workers = len(client.scheduler_info().get("workers", {}))
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
    return {"scheduler": scheduler or "LocalCluster", "workers": n_workers,
            "startup_seconds": round(startup, 3), "compute_seconds": compute}


def write_result(result: EnvelopeResult, out_dir, plots: bool = True) -> dict:
    """Write ``cases.csv``, ``cases.mat`` (for MATLAB, with the summary as the struct
    ``summary``), ``summary.json`` and (with ``plots``) the figures into ``out_dir``,
    each atomically."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    files = {"cases": out / "cases.csv", "cases_mat": out / "cases.mat",
             "summary": out / "summary.json"}
    started = time.perf_counter()
    atomic_write_text(files["cases"], result.csv_text())
    if plots:
        files.update(plot_envelope(result, out))
    result.files = files
    # the MAT file and summary.json carry the time of writing the CSV and the figures
    result.timings["write_seconds"] = round(time.perf_counter() - started, 3)
    summary = result.summary()
    write_table_mat(files["cases_mat"], result.table(), summary, "summary")
    atomic_write_text(files["summary"], json.dumps(summary, indent=1))
    return files
