"""The driver: runs a scene's step Function in blocks and records what happened.

This module owns the time loop around ``touchdown_step`` (built by
``symcushion.scheme.touchdown.build_model``): fixed-step runs call a ``mapaccum``
rollout of :data:`BLOCK_STEPS` steps repeatedly, adaptive runs apply the
paper's step criterion step by step; both hand each block of rows to a
recorder that detects the legs' events (touchdown, lift-off, stick/slip),
calls an optional run monitor, streams the rows to a
:class:`~symcushion.run.results.ResultWriter` and shows progress; the result is a
:class:`~symcushion.run.trajectory.Trajectory`. It must not build physics (that
is ``symcushion.scheme.touchdown``) nor format files (``symcushion.run.results``).

Here are :func:`simulate` (arguments checked, the scene preflighted, a loop
chosen) and :func:`save`; the loops themselves are ``symcushion.run.time_loops``,
the recorder ``symcushion.run.recorder``, and their public constants are
re-exported here.
"""
from __future__ import annotations

import dataclasses
import time
from pathlib import Path

import numpy as np

from symcushion.run.error_control import DEFAULT_ESTIMATE_RTOL, ToleranceError, check_tolerances
# RunWarning and MAX_EVENTS re-exported: users catch the one and read the other here
from symcushion.run.recorder import MAX_EVENTS, Recorder, RunWarning
from symcushion.scheme.stability import STABILITY_SAFETY
# the step-size bounds re-exported: users read them here
from symcushion.run.time_loops import (MAX_STEP_DT, MAX_STEP_FRACTION, MIN_STEP_FRACTION,
    estimate_companion, estimate_fixed, run_adaptive, run_controlled, run_fixed)
from symcushion.scheme.touchdown import STEP_CRITERION_EPS, StepModel, build_model, initial_state
from symcushion.validation import real
from symcushion.run.trajectory import Trajectory, initial_output, trajectory_from
from symcushion.run.checks import preflight
from symcushion.model.scene import Scene, load_scene
from symcushion.run.monitor import RunMonitor
from symcushion.run.results import ResultWriter, result_dir, trajectory_columns

__all__ = ["Trajectory", "trajectory_from", "initial_output", "simulate", "save", "RunWarning",
           "BLOCK_STEPS", "KEEP_ROWS", "MAX_EVENTS", "MIN_STEP_FRACTION", "MAX_STEP_FRACTION",
           "MAX_STEP_DT"]

#: Rows a streamed run (one writing to a ResultWriter) keeps in memory for its
#: figures: every k-th row, k doubling as the run grows, at most 2× this many
#: (about 16 MB with 4 legs); the files hold every row.
KEEP_ROWS = 20_000

#: Steps per rollout call: building a 500-step mapaccum takes about 0.1 s and
#: a block's rows take 0.4 MB (4 legs), so progress updates several times a
#: second while memory stays small whatever the duration.
BLOCK_STEPS = 500


def _check_arguments(scene, model, x0, p, adaptive, eps, stability, monitor, sink, keep_rows):
    """Validate :func:`simulate`'s arguments and check the scene (``checks.preflight``);
    return scene, model, x0, p, stability, monitor, keep_rows. ``adaptive`` is true
    for every variable-step run (the §3 criterion or error control)."""
    if isinstance(scene, (str, Path)):
        scene = load_scene(scene)
    if not isinstance(scene, Scene):
        raise TypeError(f"`scene` must be a Scene, got {type(scene).__name__} {scene!r}; load a "
                        "file with symcushion.model.scene.load_scene(path).")
    model = model or build_model(scene)
    if model.scene is not scene:
        # the run's Δt and duration are the given scene's, not those of the scene
        # the model was built from (they do not enter the step's graph)
        model = dataclasses.replace(model, scene=scene)
    x0 = initial_state(scene) if x0 is None else np.asarray(x0, dtype=float)
    if x0.shape != (model.nx,):
        raise ValueError(f"`x0` must have shape ({model.nx},), got {x0.shape}.")
    p = model.default_p if p is None else np.asarray(p, dtype=float)
    if p.shape != (model.np,):
        raise ValueError(f"`p` must have {model.np} entries {model.param_names}, got {p.shape}.")
    model.check_params(p)           # a leg geometry the built step cannot take
    if stability is True or stability is False:
        stability = STABILITY_SAFETY if stability else 0.0
    if isinstance(stability, (bool, np.bool_)) or not isinstance(stability, (int, float)) \
            or not 0 <= stability <= 1:
        raise ValueError(f"`stability` must be True, False or a fraction in (0, 1], "
                         f"got {stability!r}.")
    if stability and not adaptive:
        raise ValueError("`stability` needs `adaptive=True` (a fixed-step run uses "
                         "scene.dt; choose it below stable_dt(model, x0) instead).")
    eps = real("eps", eps, positive=True)
    # the adaptive driver cuts its last step at `duration` and may cap steps at stable_dt
    preflight(scene, model, x0=x0, ignore=("dt_above_duration",) * bool(adaptive)
              + ("dt_unstable",) * bool(stability))
    if monitor is True:
        monitor = RunMonitor(scene, model, x0=x0)
    elif monitor is False:
        monitor = None
    if monitor is not None and not callable(getattr(monitor, "check", None)):
        raise TypeError(f"`monitor` must have a check(t, X, Y) method, got {monitor!r}.")
    if keep_rows is None and sink is not None:
        keep_rows = KEEP_ROWS
    if keep_rows is not None and (not isinstance(keep_rows, (int, np.integer)) or keep_rows < 1):
        raise ValueError(f"`keep_rows` must be a positive integer, got {keep_rows!r}.")
    return scene, model, x0, p, stability, monitor, keep_rows


def simulate(scene, *, model: StepModel | None = None, x0=None, p=None,
             adaptive: bool = False, eps: float = STEP_CRITERION_EPS,
             stability: bool | float = False, rtol: float | None = None,
             atol: float | None = None, estimate: bool | str = True,
             estimate_rtol: float = DEFAULT_ESTIMATE_RTOL, progress: bool = False,
             monitor=True, sink=None, keep_rows: int | None = None) -> Trajectory:
    """Simulate a scene.

    Parameters
    ----------
    scene : Scene
    model : StepModel, optional
        A model built before by :func:`~symcushion.scheme.touchdown.build_model`.
    x0 : array_like, shape (nx,), optional
        Initial state; default :func:`~symcushion.scheme.touchdown.initial_state`.
    p : array_like, optional
        Step parameters (``model.param_names``: curve parameters, μ, gravity, mass,
        inertia); default ``model.default_p``, the scene's values.
    adaptive : bool
        False: fixed Δt, rolled out in blocks of :data:`BLOCK_STEPS` steps by
        ``touchdown_rollout`` (bit-identical to one rollout of the whole run).
        True: a Python loop that applies the paper's criterion
        1 − n_k·n_{k+1} < ``eps`` (§3) by halving Δt for a step (up to
        :data:`MAX_HALVINGS` times) where a contact normal turns too fast.
    stability : bool or float
        Adaptive and error-controlled runs only: also cap each step at
        :data:`STABILITY_SAFETY` (``True``) or the given fraction in (0, 1] ×
        ``stable_dt`` of its start state. ``info`` then has
        ``stability_capped``; every adaptive run reports ``dt_min``, the
        smallest step taken (the final step aside).
    rtol, atol : float, optional
        Error control (docs/error-control.md): steps chosen by step doubling
        (two steps of h against one of 2h, every pair) so that the local
        error of the legs' forces and strokes and of the body's velocity
        stays below ``atol + rtol`` × their largest size so far (``rtol`` in
        (0, 1); ``atol`` ≥ 0 in the groups' SI units N, m, m/s, default 0).
        The scene's Δt is the first pair's 2h; rows come at the variable
        times of the steps. ``info`` reports ``steps``, ``step_evaluations``,
        ``rejected``, ``dt_min``, ``dt_max``. Ignores ``adaptive`` and ``eps``.
    estimate : bool or str
        Fixed-Δt runs: estimate the error of the peaks (specific force, leg
        force, stroke) and of the final state by Richardson's rule from a
        companion run, reported in ``info['error_estimate']``; a peak whose
        estimated relative error exceeds ``estimate_rtol`` gives a warning
        that names a Δt to use. ``True`` or ``"coarse"``: a companion at about
        2Δt (half the run's cost again); ``"fine"``: at Δt/2 (twice the
        run's cost, far more often within a factor 3 of the true error,
        docs/error-control.md); ``False``: none.
    estimate_rtol : float
        Tolerance of that warning, in (0, 1) (default
        :data:`~symcushion.run.error_control.DEFAULT_ESTIMATE_RTOL`).
    progress : bool
        Show a progress bar on the terminal (tqdm; silent when not a TTY) and
        print monitor findings as ``warning:`` lines instead of raising
        :class:`RunWarning` through :mod:`warnings`.
    monitor : bool or object, optional
        ``True`` (default): :class:`symcushion.run.monitor.RunMonitor` checks every
        block (penetration, pass-through, non-finite state, energy growth;
        docs/checks.md); ``False``: no checks. Or an object that
        has ``check(t, X, Y) -> list`` of findings (objects with ``.to_dict()``,
        ``.severity``, ``.message``), called once per block with t (B,) s and
        the states X (nx, B) and outputs Y (ny, B) after each step. Findings
        are recorded in ``info['warnings']`` and ``info['events']``.
    sink : symcushion.run.results.ResultWriter, optional
        Receives every row as it is computed. The returned trajectory then
        keeps at most about 2 × ``keep_rows`` rows (every ``info['stride']``-th).
    keep_rows : int, optional
        Default :data:`KEEP_ROWS` with a sink, all rows without one.
    """
    rtol, atol = check_tolerances(rtol, atol)
    if estimate_rtol is None:
        raise ToleranceError("`estimate_rtol` must be a number in (0, 1), got None; give e.g. "
                             f"estimate_rtol={DEFAULT_ESTIMATE_RTOL:g}, or estimate=False.")
    estimate_rtol, _ = check_tolerances(estimate_rtol, None, "estimate_rtol")
    companion = estimate_companion(estimate)
    scene, model, x0, p, stability, monitor, keep_rows = _check_arguments(
        scene, model, x0, p, adaptive or rtol is not None, eps, stability, monitor, sink,
        keep_rows)
    started = time.perf_counter()
    recorder = Recorder(model, x0, sink, monitor, progress, keep_rows)
    grid = scene.grid                 # when: the step itself has Δt as an input
    try:
        if rtol is not None:
            info = run_controlled(model, grid, x0, p, rtol, atol, recorder, stability,
                                  block_steps=BLOCK_STEPS)
        elif not adaptive:
            info = run_fixed(model, grid, x0, p, recorder.block, block_steps=BLOCK_STEPS)
            info["rollout_seconds"] = time.perf_counter() - started
            if companion:
                estimate_fixed(model, x0, p, info, recorder, estimate_rtol, companion,
                               block_steps=BLOCK_STEPS)
        else:
            info = run_adaptive(model, grid, x0, p, eps, recorder, stability,
                                block_steps=BLOCK_STEPS)
    except BaseException as exc:
        # an interrupt (Ctrl-C, a termination) keeps what is complete: the
        # events and warnings of the blocks recorded so far go with the
        # exception, for a caller that keeps the rows its sink received
        exc.run_so_far = {"events": list(recorder.events), "warnings": list(recorder.warnings),
                          "events_dropped": recorder.dropped}
        raise
    finally:
        recorder.bar.close()
    traj = recorder.finish(scene.gravity)
    traj.info.update(info)
    traj.info["criterion_max"] = float(np.nanmax(traj.criterion)) if traj.criterion.size else 0.0
    traj.info["wall_seconds"] = time.perf_counter() - started
    traj.info["method"] = scene.method
    traj.info["gravity"] = scene.gravity      # the vertical of the angles, for Trajectory.load
    traj.info["name"] = scene.name
    traj.info["peaks"] = dict(recorder.peaks.values)
    traj.info["peaks_sampled"] = dict(recorder.peaks.sampled)
    traj.info["peak_times"] = dict(recorder.peaks.times)
    return traj


def save(traj: Trajectory, out_dir, name: str, metadata: dict | None = None) -> dict:
    """Write a trajectory held in memory to the result directory ``out_dir/name``.

    Writes ``trajectory.csv``, ``trajectory.npz`` and ``run.json`` atomically
    (``symcushion.run.results``); a long run streams instead (``simulate(...,
    sink=ResultWriter(...))``). Returns the paths as a dict.
    """
    directory = result_dir(out_dir, name, "out_dir")
    with ResultWriter(directory, trajectory_columns(traj.n_legs)) as writer:
        writer.append(traj.rows)
        return writer.finish(dict(traj.info, **(metadata or {})))
