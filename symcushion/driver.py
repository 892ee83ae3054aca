"""The driver: runs a scene's step Function in blocks and records what happened.

This module owns the time loop around ``touchdown_step`` (built by
``symcushion.touchdown.build_model``): fixed-step runs call a ``mapaccum``
rollout of :data:`BLOCK_STEPS` steps repeatedly, adaptive runs apply the
paper's step criterion step by step; both hand each block of rows to a
recorder that detects the legs' events (touchdown, lift-off, stick/slip),
calls an optional run monitor, streams the rows to a
:class:`~symcushion.results.ResultWriter` and shows progress; the result is a
:class:`~symcushion.trajectory.Trajectory`. It must not build physics (that
is ``symcushion.touchdown``) nor format files (``symcushion.results``).
"""
from __future__ import annotations

import dataclasses
import sys
import time
import warnings
from pathlib import Path

import numpy as np

from .error_control import (COMPANIONS, DEFAULT_ESTIMATE_RTOL, PeakTracker, StepErrorNorm,
                            ToleranceError, check_tolerances, estimate_report, next_step,
                            step_pair_function)
from .layout import MODES, output_layout, state_layout
from .stability import STABILITY_SAFETY, stable_dt
from .touchdown import (MAX_HALVINGS, STEP_CRITERION_EPS, StepModel, build_model,
                        initial_state)
from .validation import real
from .trajectory import Trajectory, _assemble, initial_output, trajectory_from

__all__ = ["Trajectory", "trajectory_from", "initial_output", "simulate", "save", "RunWarning",
           "BLOCK_STEPS", "KEEP_ROWS", "MAX_EVENTS", "MIN_STEP_FRACTION", "MAX_STEP_FRACTION",
           "MAX_STEP_DT"]

#: Steps per rollout call: building a 500-step mapaccum takes about 0.1 s and
#: a block's rows take 0.4 MB (4 legs), so progress updates several times a
#: second while memory stays small whatever the duration.
BLOCK_STEPS = 500

#: Rows a streamed run (one writing to a ResultWriter) keeps in memory for its
#: figures: every k-th row, k doubling as the run grows, at most 2× this many
#: (about 16 MB with 4 legs); the files hold every row.
KEEP_ROWS = 20_000

#: Events (touchdowns, lift-offs, stick/slip switches) recorded in full; a
#: chattering run beyond this counts the rest in ``info['events_dropped']``.
MAX_EVENTS = 10_000

#: The per-step work outputs summed into run.json's ``energy`` totals.
ENERGY_FIELDS = ("work_axial", "work_bending", "work_friction")

#: Smallest step of an error-controlled run, as a fraction of the scene's Δt:
#: 2⁻²⁰ (about 1e-9 s from 1 ms) is far below any step a touchdown needs; a
#: pair still rejected there is accepted and counted (``info['floor_steps']``).
MIN_STEP_FRACTION = 2.0 ** -20

#: Largest step of an error-controlled run, as a fraction of the duration: a
#: free flight has no error to limit the step, and a touchdown must not be
#: stepped over before the estimate can see it.
MAX_STEP_FRACTION = 1e-2

#: Largest step of an error-controlled run, in units of the scene's Δt: the
#: scene's Δt is the time scale its author resolves the touchdowns with, and a
#: step doubling pair of 20 ms in the lunar lander's flight lands its second
#: touchdown 2 ms late (peak specific force 3e-3 off at rtol = 1e-3; a pair
#: of at most 4Δt: 7e-4, docs/error-control.md).
MAX_STEP_DT = 2.0

class RunWarning(UserWarning):
    """A finding of a run monitor, raised through :mod:`warnings` by the API."""


class _Recorder:
    """Receives blocks of rows: events, monitor, streaming, thinning, progress."""

    def __init__(self, model, x0, sink, monitor, progress, keep_rows):
        self.model, self.sink, self.monitor = model, sink, monitor
        self.keep_rows = keep_rows
        self.events, self.warnings, self.dropped = [], [], 0
        self.energy = None
        self.kept, self.kept_idx, self.stride, self.count = [], [], 1, 0
        self.last_row = None
        self.peaks = PeakTracker(model.n_legs, model.scene.gravity)
        from tqdm.auto import tqdm

        self.bar = tqdm(total=model.scene.duration, unit="s", file=sys.stderr, leave=False,
                        disable=None if progress else True, desc=model.scene.name,
                        bar_format="{desc}: {percentage:3.0f}%|{bar}| t = {n:.3f}/{total:g} s "
                                   "[{elapsed}<{remaining}]")
        self.progress = progress
        y0 = initial_output(model, x0)
        self._rows(np.zeros(1), x0[:, None], y0[:, None])

    def _leg_flags(self, Y):
        yl = output_layout(self.model.n_legs)
        return yl.legs(Y, "in_contact") > 0.5, np.rint(yl.legs(Y, "mode")).astype(int)

    def _events(self, t, Y):
        contact, mode = self._leg_flags(Y)
        if self.count:
            contact = np.column_stack([self.prev[0], contact])
            mode = np.column_stack([self.prev[1], mode])
            t = np.concatenate([[np.nan], t])
        self.prev = (contact[:, -1], mode[:, -1])
        found = []
        for j in range(contact.shape[0]):
            c, m = contact[j], mode[j]
            for k in np.nonzero(c[1:] != c[:-1])[0] + 1:
                found.append((t[k], "touchdown" if c[k] else "lift-off", j))
            stays = c[1:] & c[:-1]
            for k in np.nonzero(stays & (m[1:] != m[:-1]) & (m[1:] > 0) & (m[:-1] > 0))[0] + 1:
                found.append((t[k], MODES.get(int(m[k]), "unknown"), j))
        for time_, kind, leg in sorted(found):
            if len(self.events) < MAX_EVENTS:
                self.events.append({"time": float(time_), "kind": kind, "leg": int(leg)})
            else:
                self.dropped += 1

    def _monitor(self, t, X, Y):
        for finding in self.monitor.check(t, X, Y) or []:
            when = getattr(finding, "time", None)      # the finding's own time, not the block's
            self.warn({"time": float(t[-1] if when is None else when), "kind": "warning",
                       "severity": str(getattr(finding, "severity", "warning")),
                       "message": str(finding.message), "details": finding.to_dict()})

    def warn(self, entry: dict, stacklevel: int = 5):
        """Record a warning of the run (a dict with ``time`` and ``message``) and show it."""
        self.warnings.append(entry)
        if len(self.events) < MAX_EVENTS:
            self.events.append(entry)
        text = f"t = {entry['time']:.4g} s: {entry['message']}"
        if self.progress:
            label = "error" if entry.get("severity") == "error" else "warning"
            self.bar.write(f"{label}: {text}", file=sys.stderr)
        else:
            warnings.warn(text, RunWarning, stacklevel=stacklevel)

    def _energy(self, Y):
        """Add the block's per-leg work (axial, bending, friction; J) to the run's totals."""
        yl = output_layout(self.model.n_legs)
        block = np.array([yl.legs(Y, f).sum(axis=-1) for f in ENERGY_FIELDS])
        self.energy = block if self.energy is None else self.energy + block

    def energy_totals(self) -> dict:
        """The run's energy per leg (J): on its axial element, on its hinge springs,
        dissipated by friction (``layout.LEG_OUT_FIELDS``); sums of the steps' work."""
        totals = np.zeros((len(ENERGY_FIELDS), self.model.n_legs)) if self.energy is None \
            else self.energy
        return {f"leg{j}": {f.replace("work_", "") + "_J": float(totals[i, j])
                            for i, f in enumerate(ENERGY_FIELDS)}
                for j in range(self.model.n_legs)}

    def _rows(self, t, X, Y):
        rows = np.column_stack([t, X.T, Y.T])
        self._energy(Y)
        if not np.all(np.isfinite(state_layout(self.model.n_legs).get(X, "position"))):
            raise FloatingPointError(
                f"the simulation produced non-finite body positions near t = {t[0]:.4g} s; "
                "reduce `dt` or check the scene.")
        self._events(t, Y)
        self.peaks.update(Y, t)
        if self.monitor is not None and self.count:
            self._monitor(t, X, Y)
        if self.sink is not None:
            self.sink.append(rows)
        idx = self.count + np.arange(len(rows))
        self.count += len(rows)
        self.last_row = rows[-1]
        if self.keep_rows is None:
            self.kept.append(rows)
            return
        mask = idx % self.stride == 0
        self.kept.append(rows[mask])
        self.kept_idx.append(idx[mask])
        if sum(len(k) for k in self.kept) > 2 * self.keep_rows:
            self.stride *= 2
            rows, idx = np.concatenate(self.kept), np.concatenate(self.kept_idx)
            mask = idx % self.stride == 0
            self.kept, self.kept_idx = [rows[mask]], [idx[mask]]

    def block(self, t, X, Y):
        """Record steps: t (B,) s, X (nx, B) states and Y (ny, B) outputs after each step."""
        self._rows(np.asarray(t, float), np.asarray(X, float), np.asarray(Y, float))
        self.bar.update(float(t[-1]) - self.bar.n)

    def finish(self, gravity) -> Trajectory:
        self.bar.close()
        rows = np.concatenate(self.kept)
        # a thinned run always ends on its last row, even where the last block kept none
        # (row 0 is always kept, so some block holds a kept index)
        if self.keep_rows is not None and np.concatenate(self.kept_idx)[-1] != self.count - 1:
            rows = np.vstack([rows, self.last_row])
        traj = _assemble(rows, self.model.n_legs, gravity)
        traj.info = {"events": self.events, "warnings": self.warnings,
                     "events_dropped": self.dropped, "rows": self.count,
                     "energy": self.energy_totals()}
        if self.keep_rows is not None:
            traj.info["stride"] = self.stride
        return traj


def _check_arguments(scene, model, x0, p, adaptive, eps, stability, monitor, sink, keep_rows):
    """Validate :func:`simulate`'s arguments and check the scene (``checks.preflight``);
    return scene, model, x0, p, stability, monitor, keep_rows. ``adaptive`` is true
    for every variable-step run (the §3 criterion or error control)."""
    from .checks import preflight
    from .scene import Scene, load_scene

    if isinstance(scene, (str, Path)):
        scene = load_scene(scene)
    if not isinstance(scene, Scene):
        raise TypeError(f"`scene` must be a Scene, got {type(scene).__name__} {scene!r}; load a "
                        "file with symcushion.scene.load_scene(path).")
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
        from .monitor import RunMonitor

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
        A model built before by :func:`~symcushion.touchdown.build_model`.
    x0 : array_like, shape (nx,), optional
        Initial state; default :func:`~symcushion.touchdown.initial_state`.
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
        :data:`~symcushion.error_control.DEFAULT_ESTIMATE_RTOL`).
    progress : bool
        Show a progress bar on the terminal (tqdm; silent when not a TTY) and
        print monitor findings as ``warning:`` lines instead of raising
        :class:`RunWarning` through :mod:`warnings`.
    monitor : bool or object, optional
        ``True`` (default): :class:`symcushion.monitor.RunMonitor` checks every
        block (penetration, pass-through, non-finite state, energy growth;
        docs/checks.md); ``False``: no checks. Or an object that
        has ``check(t, X, Y) -> list`` of findings (objects with ``.to_dict()``,
        ``.severity``, ``.message``), called once per block with t (B,) s and
        the states X (nx, B) and outputs Y (ny, B) after each step. Findings
        are recorded in ``info['warnings']`` and ``info['events']``.
    sink : symcushion.results.ResultWriter, optional
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
    companion = _companion(estimate)
    scene, model, x0, p, stability, monitor, keep_rows = _check_arguments(
        scene, model, x0, p, adaptive or rtol is not None, eps, stability, monitor, sink,
        keep_rows)
    started = time.perf_counter()
    recorder = _Recorder(model, x0, sink, monitor, progress, keep_rows)
    try:
        if rtol is not None:
            info = _run_controlled(model, x0, p, rtol, atol, recorder, stability)
        elif not adaptive:
            info = _run_fixed(model, x0, p, recorder.block)
            info["rollout_seconds"] = time.perf_counter() - started
            if companion:
                _estimate_fixed(model, x0, p, info, recorder, estimate_rtol, companion)
        else:
            info = _run_adaptive(model, x0, p, eps, recorder, stability)
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


def _run_fixed(model, x0, p, on_block, dt=None, steps=None) -> dict:
    """Roll out ``steps`` steps of ``dt`` (default the scene's) in blocks, handing
    each block's times, states and outputs to ``on_block(t, X, Y)``."""
    scene = model.scene
    dt = scene.dt if dt is None else dt
    steps = scene.steps if steps is None else steps
    done, x = 0, x0
    while done < steps:
        block = min(BLOCK_STEPS, steps - done)
        X, Y = model.rollout(block)(x, p, dt)
        X, Y = np.asarray(X, float), np.asarray(Y, float)
        on_block(dt * np.arange(done + 1, done + block + 1), X, Y)
        x, done = X[:, -1], done + block
    return {"dt": dt, "steps": steps, "halvings": 0, "final_state": x,
            "step_evaluations": steps}


def _companion(estimate) -> str | None:
    """The companion named by ``simulate(estimate=...)``: a key of COMPANIONS or None."""
    if estimate is True:
        return "coarse"
    if estimate is False or estimate is None:
        return None
    if isinstance(estimate, str) and estimate in COMPANIONS:
        return estimate
    raise ValueError(f"`estimate` must be True, False or one of {sorted(COMPANIONS)}, got "
                     f"{estimate!r}; give e.g. estimate='fine' (docs/error-control.md).")


def _estimate_fixed(model, x0, p, info, recorder, rtol, companion="coarse"):
    """The error estimate of a finished fixed-Δt run (``info['error_estimate']``): a
    companion run over the same time with half as many steps (``"coarse"``) or
    twice as many (``"fine"``), Richardson's rule on the peaks and the final
    state, a warning per peak above ``rtol``."""
    steps, dt = info["steps"], info["dt"]
    if steps < 2 and companion == "coarse":
        info["error_estimate"] = None       # one step has no coarser companion
        return
    started = time.perf_counter()
    companion_steps = round(steps / COMPANIONS[companion])
    companion_dt = steps * dt / companion_steps
    peaks = PeakTracker(model.n_legs, model.scene.gravity)
    peaks.update(initial_output(model, x0)[:, None], np.zeros(1))
    companion = _run_fixed(model, x0, p, lambda t, X, Y: peaks.update(Y, t), companion_dt,
                           companion_steps)
    report, messages = estimate_report(
        recorder.peaks.values, peaks.values, info["final_state"], companion["final_state"],
        dt=dt, companion_dt=companion_dt, scene=model.scene, rtol=rtol)
    report["companion_seconds"] = time.perf_counter() - started
    report["overhead"] = report["companion_seconds"] / max(info["rollout_seconds"], 1e-9)
    info["error_estimate"] = report
    t_end = steps * dt
    for message in messages:
        recorder.warn({"time": t_end, "kind": "warning", "severity": "warning",
                       "message": message, "details": {"kind": "error_estimate"}}, stacklevel=4)


def _normals(model, y):
    yl = output_layout(model.n_legs)
    y = np.asarray(y, float).ravel()
    return yl.legs(y, "in_contact") > 0.5, yl.legs(y, "normal")


class _RowBuffer:
    """Rows of a variable-step run, handed to the recorder in blocks of :data:`BLOCK_STEPS`."""

    def __init__(self, recorder):
        self.recorder = recorder
        self.ts, self.xs, self.ys = [], [], []

    def add(self, t, x, y):
        self.ts.append(t)
        self.xs.append(np.asarray(x, float).ravel())
        self.ys.append(np.asarray(y, float).ravel())
        if len(self.ts) == BLOCK_STEPS:
            self.flush()

    def flush(self):
        if self.ts:
            self.recorder.block(np.array(self.ts), np.column_stack(self.xs),
                                np.column_stack(self.ys))
            self.ts, self.xs, self.ys = [], [], []


def _run_adaptive(model, x0, p, eps, recorder, stability=0.0) -> dict:
    scene, step = model.scene, model.step
    t_end, dt = scene.duration, scene.dt
    t, x, steps = 0.0, x0, 0
    rows = _RowBuffer(recorder)
    last_contact, last_normal = None, None
    halvings = capped = 0
    dt_min = np.inf
    while t < t_end - 1e-12 * t_end:
        h = min(dt, t_end - t)
        if stability:
            h_stable = stability * stable_dt(model, x, p)
            if h_stable < h:
                h, capped = h_stable, capped + 1
        for depth in range(MAX_HALVINGS + 1):
            x_new, y = step(x, p, h)
            contact, normal = _normals(model, y)
            if last_contact is None or depth == MAX_HALVINGS:
                break
            both = contact & last_contact
            crit = np.max(1 - np.einsum("ni,ni->n", normal, last_normal)[both], initial=0.0)
            if crit < eps:
                break
            h /= 2
            halvings += 1
        x = np.asarray(x_new, float).ravel()
        if h < t_end - t - 1e-12 * t_end:       # not the final, shortened step
            dt_min = min(dt_min, h)
        t += h
        steps += 1
        rows.add(t, x, y)
        last_contact, last_normal = contact, normal
    rows.flush()
    info = {"dt": dt, "steps": steps, "halvings": halvings, "eps": eps, "final_state": x,
            "dt_min": dt_min}
    if stability:
        info["stability_capped"] = capped
    return info


def _run_controlled(model, x0, p, rtol, atol, recorder, stability=0.0) -> dict:
    """Error-controlled stepping: step doubling on every pair of steps, the
    standard controller (``symcushion.error_control``); rows at every step."""
    scene = model.scene
    pair = step_pair_function(model.step)
    norm = StepErrorNorm(scene, rtol, atol, x0)
    t_end = scene.duration
    h_min = MIN_STEP_FRACTION * scene.dt
    h_max = min(MAX_STEP_FRACTION * t_end, MAX_STEP_DT * scene.dt)
    h, t, x = scene.dt / 2, 0.0, np.asarray(x0, float)
    rows = _RowBuffer(recorder)
    steps = evaluations = rejected = floor = capped = 0
    dt_min, dt_max = np.inf, 0.0
    while t < t_end - 1e-12 * t_end:
        remaining = (t_end - t) / 2
        h = min(h, h_max, remaining)
        if stability:
            h_stable = stability * stable_dt(model, x, p)
            if h_stable < h:
                h, capped = h_stable, capped + 1
        # one conversion of each output to NumPy: the error norm, the rows and the
        # next pair read them several times
        x1, y1, x2, y2, x_big, y_big = (out.full().ravel() for out in pair(x, p, h))
        evaluations += 3
        err = norm(x2, y2, x_big, y_big, h)
        if not np.isfinite(err):
            err = np.inf
        if err > 1 and h > h_min:
            rejected += 1
            h = max(h_min, next_step(h, err))
            continue
        floor += err > 1
        if h < remaining * (1 - 1e-12):       # not the final, shortened pair
            dt_min, dt_max = min(dt_min, h), max(dt_max, h)
        rows.add(t + h, x1, y1)
        t = t + 2 * h if h < remaining else t_end
        rows.add(t, x2, y2)
        x = x2
        norm.accept(x2, y2)
        steps += 2
        h = next_step(h, err)
    rows.flush()
    info = {"dt": scene.dt, "steps": steps, "halvings": 0, "rtol": rtol, "atol": atol,
            "final_state": x, "step_evaluations": evaluations, "rejected": rejected,
            "floor_steps": int(floor), "dt_min": dt_min, "dt_max": dt_max}
    if stability:
        info["stability_capped"] = capped
    return info


def save(traj: Trajectory, out_dir, name: str, metadata: dict | None = None) -> dict:
    """Write a trajectory held in memory to the result directory ``out_dir/name``.

    Writes ``trajectory.csv``, ``trajectory.npz`` and ``run.json`` atomically
    (``symcushion.results``); a long run streams instead (``simulate(...,
    sink=ResultWriter(...))``). Returns the paths as a dict.
    """
    from .results import ResultWriter, result_dir, trajectory_columns

    directory = result_dir(out_dir, name, "out_dir")
    with ResultWriter(directory, trajectory_columns(traj.n_legs)) as writer:
        writer.append(traj.rows)
        return writer.finish(dict(traj.info, **(metadata or {})))
