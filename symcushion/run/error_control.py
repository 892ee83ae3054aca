"""Error estimates of a run and the error norm of error-controlled stepping.

This module owns how a run's accuracy is judged from the step Function
alone (docs/error-control.md):

* the **peak quantities** a touchdown is designed by — the peak specific
  force on the body, the peak force on a foot and the peak stroke of a leg —
  tracked over every row of a run (:class:`PeakTracker`);
* the **estimate of a fixed-Δt run** by Richardson's rule from a companion
  run at about 2Δt or Δt/2 (:data:`COMPANIONS`): E ≈ |Q(Δt) − Q(rΔt)| /
  |r^p − 1| with r the ratio of the steps and p = :data:`ESTIMATE_ORDER`
  (:func:`richardson`,
  :func:`estimate_report`), with a warning that names the Δt that would meet
  the tolerance;
* the **error norm of step doubling** (:class:`StepErrorNorm`): one step of
  2h against two steps of h from the same state, scaled by ``atol + rtol``
  × the running size of each group, and the step-size controller
  (:func:`next_step`); :func:`step_pair_function` composes the three steps
  into one call.

It must not run the time loop (``symcushion.run.driver`` does) nor change the
step: it only calls ``touchdown_step``.
"""
from __future__ import annotations

import casadi as ca
import numpy as np

from symcushion.layout.vectors import output_layout, state_layout
from symcushion.validation import real

__all__ = ["fitted_order", "PEAKS", "ESTIMATE_ORDER", "DEFAULT_ESTIMATE_RTOL", "DT_SAFETY", "MAX_SCALED_ERROR",
           "COMPANIONS",
           "CONTROL_ORDER",
           "CONTROL_SAFETY", "FAC_MIN", "FAC_MAX", "STROKE_FLOOR", "GRAVITY_FLOOR",
           "PeakTracker", "parabola_peak", "SMOOTH_PEAK_MISFIT", "TAIL_ROWS", "StepErrorNorm",
           "ToleranceError", "check_tolerances", "peak_floors",
           "richardson", "estimate_report", "next_step", "step_pair_function"]

#: The peak quantities of a run: name → (label, unit). Loads are what a leg
#: and its payload are designed for; the stroke is what the absorber must hold.
PEAKS = {
    "peak_specific_force": ("peak specific force", "m/s²"),
    "peak_leg_force": ("peak leg force", "N"),
    "peak_stroke": ("peak stroke", "m"),
}

#: Order p of Richardson's estimate. Measured on the four landers of
#: docs/error-control.md, the peaks converge at orders 0.7–2.9 and the final
#: state at 0.3–1.5 (first order where events dominate, docs/event-order.md),
#: and the order observed from three runs is noise (−3.6 to 9.7); p = 1 is the
#: safe choice. A scheme of another order changes a coarse companion's
#: estimate by up to 1/(2^p − 1) and a fine one's by at most a factor 2
#: (:func:`estimate_report`).
ESTIMATE_ORDER = 1.0

#: The companion runs of a fixed-Δt run's estimate: name → ratio of its step
#: to the run's. "coarse" (2Δt) costs half the run again, "fine" (Δt/2) twice
#: the run; the fine one is within a factor 3 of the true error far more often
#: (docs/error-control.md, measured): a coarse companion is often not yet
#: converging at the rate of the run itself.
COMPANIONS = {"coarse": 2.0, "fine": 0.5}

#: Default tolerance on the relative error of the peak quantities of a
#: fixed-Δt run: 1 % is well inside the margins designs carry on loads
#: (factors of safety of 1.25–1.5, crush forces specified to ±5–10 %) and
#: far above the reference runs' own scatter (about 1e-4 on these peaks).
DEFAULT_ESTIMATE_RTOL = 1e-2

#: Fraction of the Δt predicted to meet the tolerance that the warning names:
#: the prediction comes from an estimate with scatter (docs/error-control.md).
DT_SAFETY = 0.5

#: Largest relative error the suggested Δt is scaled from: an estimate above
#: 1 says only that the companion run (2Δt) is far from converged — the
#: lunar lander's at 40 ms strokes 8.7 m — not how fast the error falls.
MAX_SCALED_ERROR = 1.0

#: Order p of the controller's local error (per step ~ h^(p+1)) and of its
#: Richardson factor 1/(2^p − 1): the measured global order of the landers'
#: default scheme (docs/event-order.md), the same safe value as the estimate.
CONTROL_ORDER = 1.0

#: The standard controller's safety factor and its bounds on the step ratio
#: (Hairer, Nørsett & Wanner, Solving ODEs I, §II.4): shrink at most
#: fivefold per attempt, grow at most twofold per accepted pair so that a
#: step does not leap over a touchdown it cannot yet see.
CONTROL_SAFETY = 0.9
FAC_MIN = 0.2
FAC_MAX = 2.0


class ToleranceError(ValueError, TypeError):
    """A bad tolerance. A ValueError whatever is wrong with it; also a TypeError, so
    that a caller catching what :func:`~symcushion.validation.real` raises for a
    non-number still catches it."""


def _tolerance(name, value, **rule) -> float:
    try:
        return real(name, value, **rule)
    except (TypeError, ValueError) as exc:
        raise ToleranceError(str(exc)) from None


def check_tolerances(rtol, atol, rtol_name: str = "rtol") -> tuple:
    """Validate ``rtol`` (in (0, 1)) and ``atol`` (≥ 0); return them as floats.

    ``rtol`` may be None (no error control); ``atol`` None means 0. Raises
    :class:`ToleranceError` (a ValueError) naming the argument, its value and
    the fix.
    """
    if rtol is not None:
        rtol = _tolerance(rtol_name, rtol, positive=True)
        if rtol >= 1:
            raise ToleranceError(f"`{rtol_name}` must be below 1 (a relative error), got "
                                 f"{rtol!r}; give e.g. {rtol_name}=1e-3.")
    if atol is None:
        return rtol, 0.0
    return rtol, _tolerance("atol", atol, nonnegative=True)


#: Largest misfit of the parabola through three rows at the rows two steps
#: away, in units of the middle row's rise over its lower neighbour: at a
#: smooth maximum the misfit is of order Δt³ against a rise of order Δt²; at a
#: kink (a tent: 2×) or a jump (1–2×) it is of the rise's own size, and the
#: sampled row is kept there (docs/error-control.md).
SMOOTH_PEAK_MISFIT = 0.5


def _through(t, t0, t1, t2, y0, y1, y2):
    """The parabola through (t0, y0), (t1, y1), (t2, y2), at t; and its leading coefficient."""
    s01 = (y1 - y0) / (t1 - t0)
    curv = ((y2 - y1) / (t2 - t1) - s01) / (t2 - t0)
    return y0 + s01 * (t - t0) + curv * (t - t0) * (t - t1), curv


def parabola_peak(t, y):
    """Each smooth local maximum of sampled series, refined by a parabola through three rows.

    Parameters
    ----------
    t : array_like, shape (T,)
        Sample times (s), increasing; need not be uniform.
    y : array_like, shape (C, T)
        C series of samples.

    Returns
    -------
    peak : ndarray, shape (C, T - 4)
        At a row k (2 ≤ k < T − 2) at least as high as both neighbours, where
        the parabola through rows k−1, k, k+1 also fits rows k±2 to within
        :data:`SMOOTH_PEAK_MISFIT` × the rise of row k over its lower
        neighbour, the parabola's vertex value; elsewhere the row itself.
    when : ndarray, shape (C, T - 4)
        The time of that value (s).
    """
    t = np.asarray(t, dtype=float)
    y = np.asarray(y, dtype=float)
    tm, t0, t1, t2, tp = t[:-4], t[1:-3], t[2:-2], t[3:-1], t[4:]
    ym, y0, y1, y2, yp = y[:, :-4], y[:, 1:-3], y[:, 2:-2], y[:, 3:-1], y[:, 4:]
    at_m, curv = _through(tm, t0, t1, t2, y0, y1, y2)
    at_p, _ = _through(tp, t0, t1, t2, y0, y1, y2)
    rise = y1 - np.minimum(y0, y2)
    smooth = np.maximum(np.abs(at_m - ym), np.abs(at_p - yp)) <= SMOOTH_PEAK_MISFIT * rise
    refine = (y1 >= y0) & (y1 >= y2) & (curv < 0) & smooth
    safe = np.where(refine, curv, -1.0)
    # the vertex, where the derivative s01 + curv (2τ − t0 − t1) vanishes
    s01 = (y1 - y0) / (t1 - t0)
    vertex = np.clip(0.5 * (t0 + t1) - s01 / (2.0 * safe), t0, t2)
    value, _ = _through(vertex, t0, t1, t2, y0, y1, y2)
    peak = np.where(refine, np.maximum(value, y1), y1)
    when = np.where(refine, vertex, np.broadcast_to(t1, y1.shape))
    return peak, when


#: Rows a :class:`PeakTracker` carries from one block to the next: the
#: parabola test of :func:`parabola_peak` reads five rows around a maximum.
TAIL_ROWS = 4


class PeakTracker:
    """The running peaks of :data:`PEAKS` over every row of a run.

    Each peak is read from a parabola through the three rows around a local
    maximum (:func:`parabola_peak`) rather than as the largest row: a sampled
    maximum misses the true one by an amount set by where the time grid falls
    relative to the peak's time (of order Δt² at a smooth maximum), an error
    that no order of convergence describes and that a run at another Δt
    samples differently (docs/error-control.md). ``sampled`` keeps the
    largest row itself, ``times`` the time of each peak.

    Parameters
    ----------
    n_legs : int
    gravity : array_like, shape (3,)
        m/s²; the specific force is a − g.
    """

    def __init__(self, n_legs: int, gravity):
        self._yl = output_layout(n_legs)
        self._g = np.asarray(gravity, dtype=float)
        self.values = dict.fromkeys(PEAKS, 0.0)
        self.sampled = dict.fromkeys(PEAKS, 0.0)
        self.times = dict.fromkeys(PEAKS, 0.0)
        self._tail_t = np.zeros(0)                  # the last rows seen, for the parabola
        self._tail = dict.fromkeys(PEAKS)

    def _series(self, Y) -> dict:
        acc = self._yl.get(Y, "acceleration") - self._g[:, None]
        return {"peak_specific_force": np.linalg.norm(acc, axis=0)[None, :],
                "peak_leg_force": np.linalg.norm(self._yl.legs(Y, "force"), axis=1),
                "peak_stroke": np.abs(self._yl.legs(Y, "stroke"))}

    def update(self, Y, t=None):
        """Fold outputs Y (ny, B) of B steps at times ``t`` (B,) into the peaks.

        Without ``t`` the rows are taken one time unit apart after the last
        ones (uniform steps).
        """
        Y = np.asarray(Y, dtype=float)
        if t is None:
            start = self._tail_t[-1] + 1.0 if self._tail_t.size else 0.0
            t = start + np.arange(Y.shape[1], dtype=float)
        t = np.asarray(t, dtype=float)
        times = np.concatenate([self._tail_t, t])
        for key, new in self._series(Y).items():
            if new.size:
                self.sampled[key] = max(self.sampled[key], float(np.max(new)))
            series = new if self._tail[key] is None else np.hstack([self._tail[key], new])
            if series.shape[1] >= 5:
                peak, when = parabola_peak(times, series)
                k = np.unravel_index(np.argmax(peak), peak.shape)
                if peak[k] > self.values[key]:
                    self.values[key], self.times[key] = float(peak[k]), float(when[k])
            # the last row is a peak of its own until a later row shows it is not
            last = int(np.argmax(series[:, -1])) if series.size else 0
            if series.size and series[last, -1] > self.values[key]:
                self.values[key], self.times[key] = float(series[last, -1]), float(times[-1])
            self._tail[key] = series[:, -TAIL_ROWS:]
        self._tail_t = times[-TAIL_ROWS:]


#: Floor of the stroke scale, in units of the shortest leg: 1 % of a leg
#: (14 mm on a 1.4 m leg) is smaller than any lander's crush stroke, yet a
#: stroke of a few micrometres (a body that barely loads its legs) is not
#: judged by its relative error.
STROKE_FLOOR = 1e-2

#: Floor of the gravity in the force and velocity scales (m/s²), for a scene
#: without gravity.
GRAVITY_FLOOR = 1.0


def peak_floors(scene) -> dict:
    """The smallest scale each peak is judged against (a relative error of a
    near-zero peak means nothing): |g|, the weight per leg, 1 % of the shortest leg."""
    g = max(float(np.linalg.norm(scene.gravity)), GRAVITY_FLOOR)
    return {"peak_specific_force": g, "peak_leg_force": scene.body.mass * g / len(scene.legs),
            "peak_stroke": STROKE_FLOOR * min(leg.length for leg in scene.legs)}


def fitted_order(steps, errors) -> float:
    """The order of convergence p of errors ≈ C·stepᵖ: the least-squares slope of
    log(error) against log(step) (both positive, at least two points)."""
    steps, errors = np.asarray(steps, dtype=float), np.asarray(errors, dtype=float)
    if steps.size < 2 or steps.shape != errors.shape:
        raise ValueError(f"`steps` and `errors` must be two or more values each, of one "
                         f"shape; got shapes {steps.shape} and {errors.shape}.")
    return float(np.polyfit(np.log(steps), np.log(errors), 1)[0])


def richardson(value, companion, ratio: float, order: float = ESTIMATE_ORDER):
    """Richardson's estimate of the error of ``value``: |value − companion| / |ratio^p − 1|.

    With an error C Δt^p, the runs at Δt and ``ratio`` × Δt differ by
    C Δt^p |ratio^p − 1|: a coarser companion (ratio > 1) or a finer one
    (ratio < 1) alike.

    Parameters
    ----------
    value, companion : float or array_like
        A quantity from the run at Δt and from its companion at ``ratio`` × Δt.
    ratio : float
        Ratio of the companion's step to the run's (positive, not 1).
    order : float
        p, the order of convergence assumed.

    Returns
    -------
    float
        The estimate (max-norm over the entries of an array).
    """
    if not ratio > 0 or ratio == 1:
        raise ValueError(f"`ratio` must be positive and not 1 (the companion's step over the "
                         f"run's), got {ratio!r}; give e.g. 2.0 or 0.5.")
    diff = np.abs(np.asarray(value, dtype=float) - np.asarray(companion, dtype=float))
    return float(np.max(diff, initial=0.0)) / abs(ratio ** order - 1.0)


def _final_parts(x, n_legs) -> dict:
    xl = state_layout(n_legs)
    return {"position": xl.get(x, "position"), "velocity": xl.get(x, "velocity")}


def estimate_report(peaks: dict, companion_peaks: dict, x_final, companion_final, *, dt: float,
                    companion_dt: float, scene, rtol: float,
                    order: float = ESTIMATE_ORDER) -> tuple[dict, list]:
    """The error estimate of a fixed-Δt run from its companion run.

    Parameters
    ----------
    peaks, companion_peaks : dict
        :attr:`PeakTracker.values` of the run and of the companion.
    x_final, companion_final : array_like, shape (nx,)
        Their final states (the same end time).
    dt, companion_dt : float
        Their steps (s): ``companion_dt`` about 2 ``dt`` (a coarse companion)
        or ``dt`` / 2 (a fine one, :data:`COMPANIONS`).
    scene : Scene
        The run's scene (the legs, and the floors of :func:`peak_floors`).
    rtol : float
        Tolerance on the relative error of every peak, relative to the peak
        or its floor (:func:`peak_floors`), whichever is larger.
    order : float
        p, the order the errors are taken to converge at. A fine companion
        scales the difference by 2^p / (2^p − 1), between 1 and 2 for any
        p ≥ 1, a coarse one by 1 / (2^p − 1), from 1 down to 1/7 at p = 3: the
        fine estimate barely depends on the scheme's order, the coarse one
        does (docs/error-control.md).

    Returns
    -------
    report : dict
        ``order``, ``dt``, ``companion_dt``, ``rtol``, per peak its
        ``value``, ``companion``, ``error`` and ``relative_error``; the final
        body ``position`` (m) and ``velocity`` (m/s) errors; ``within_rtol``
        and, when not, ``suggested_dt`` (s).
    messages : list of str
        One line per peak whose estimate exceeds ``rtol``.
    """
    ratio = companion_dt / dt
    report = {"method": "Richardson from a companion run", "order": order, "dt": dt,
              "companion": "fine" if ratio < 1 else "coarse",
              "companion_dt": companion_dt, "rtol": rtol, "peaks": {}, "final_state": {}}
    worst = 0.0
    over = []
    floors = peak_floors(scene)
    for key, (label, unit) in PEAKS.items():
        value = peaks[key]
        err = richardson(value, companion_peaks[key], ratio, order)
        rel = err / max(value, floors[key])
        report["peaks"][key] = {"value": value, "companion": companion_peaks[key],
                                "error": err, "relative_error": rel, "unit": unit}
        worst = max(worst, rel)
        if rel > rtol:
            over.append((label, unit, value, err, rel))
    n_legs = len(scene.legs)
    own, other = _final_parts(x_final, n_legs), _final_parts(companion_final, n_legs)
    for key, unit in (("position", "m"), ("velocity", "m/s")):
        report["final_state"][key] = {"error": richardson(own[key], other[key], ratio, order),
                                      "unit": unit}
    report["within_rtol"] = not over
    messages = []
    if over:
        # error ∝ Δt^p: the Δt that would meet rtol, with a margin for the scatter
        suggested = DT_SAFETY * dt * (rtol / min(worst, MAX_SCALED_ERROR)) ** (1.0 / order)
        report["suggested_dt"] = suggested
        for label, unit, value, err, rel in over:
            messages.append(
                f"the {label} ({value:.4g} {unit}) has an estimated relative error of {rel:.3g} "
                f"(±{err:.3g} {unit}), above rtol = {rtol:g}: Δt = {dt:g} s is too coarse for "
                f"it; use Δt ≤ {suggested:.2g} s (--dt {suggested:.2g}) or error control "
                f"(--rtol {rtol:g}); estimated from a run at {companion_dt:g} s "
                "(docs/error-control.md).")
    return report, messages


def step_pair_function(step: ca.Function) -> ca.Function:
    """``touchdown_step_pair(x, p, h)``: two steps of h and one of 2h, in one call.

    Outputs ``x1, y1`` (after the first h), ``x2, y2`` (after the second) and
    ``x_big, y_big`` (one step of 2h from x); one call from Python instead
    of three.
    """
    x = ca.MX.sym("x", step.size1_in(0))
    p = ca.MX.sym("p", step.size1_in(1))
    h = ca.MX.sym("h")
    x1, y1 = step(x, p, h)
    x2, y2 = step(x1, p, h)
    x_big, y_big = step(x, p, 2 * h)
    return ca.Function("touchdown_step_pair", [x, p, h], [x1, y1, x2, y2, x_big, y_big],
                       ["x", "p", "h"], ["x1", "y1", "x2", "y2", "x_big", "y_big"])


class StepErrorNorm:
    """The scaled local error of a step pair (step doubling), ≤ 1 to accept.

    The error of two steps of h is estimated as the difference from one step
    of 2h over (2^p − 1), p = :data:`CONTROL_ORDER`, in the quantities the
    peaks follow from: the legs' forces and strokes and the body's motion
    (the velocity of its centre and, times the longest leg, its angular
    velocity). Each group is measured against ``atol + rtol × size``, its
    size being the largest magnitude of the group so far in the run (so that
    ``rtol`` is relative to the peaks), and at least a floor from the scene:
    the floors of :func:`peak_floors` for forces and strokes, √(|g| L) for
    velocities. The norm is the largest scaled
    entry.

    An absorber's force jumps where it leaves its loading curve, and a jump
    inside a pair makes a force difference that no step reduces; forces
    therefore count only in pairs of h ≥ :attr:`force_min_step` (the
    scene's Δt × :data:`FORCE_MIN_FRACTION`), which locates such a jump to
    that step, and the continuous strokes and velocities control the rest.

    Parameters
    ----------
    scene : Scene
    rtol, atol : float
        Relative tolerance and absolute tolerance (SI units of each group:
        N, m, m/s).
    x0 : array_like, shape (nx,)
    """

    #: Shortest h (in units of the scene's Δt) at which forces count: 2⁻⁶
    #: locates a force jump to 1/64 of Δt in about three rejected pairs
    #: (the controller shrinks h at most fivefold per attempt).
    FORCE_MIN_FRACTION = 2.0 ** -2

    def __init__(self, scene, rtol: float, atol: float, x0):
        n = len(scene.legs)
        self.xl, self.yl = state_layout(n), output_layout(n)
        self.rtol, self.atol = rtol, atol
        g = max(float(np.linalg.norm(scene.gravity)), GRAVITY_FLOOR)
        self.arm = max(leg.length for leg in scene.legs)
        self.force_min_step = self.FORCE_MIN_FRACTION * scene.dt
        floors = peak_floors(scene)
        self.size = {"force": floors["peak_leg_force"], "stroke": floors["peak_stroke"],
                     "velocity": np.sqrt(g * self.arm)}
        self.factor = 1.0 / (2.0 ** CONTROL_ORDER - 1.0)
        self._fold(self._body(np.asarray(x0, dtype=float)))

    def _body(self, x) -> dict:
        """The body's velocity and its angular velocity times the longest leg, (2, 3)."""
        return {"velocity": np.stack([np.asarray(self.xl.get(x, "velocity")), self.arm
                                      * np.asarray(self.xl.get(x, "angular_velocity"))])}

    def _vectors(self, x, y) -> dict:
        """Each group's vectors, (entries, components)."""
        return dict(self._body(x), force=self.yl.legs(y, "force"),
                    stroke=self.yl.legs(y, "stroke")[:, None])

    def __call__(self, x2, y2, x_big, y_big, h: float) -> float:
        """The scaled error of the pair of steps of ``h`` ending in x2, y2."""
        fine, coarse = self._vectors(x2, y2), self._vectors(x_big, y_big)
        if h < self.force_min_step:
            del fine["force"]
        err = 0.0
        for key, value in fine.items():
            diff = np.linalg.norm(value - coarse[key], axis=1)
            scale = self.atol + self.rtol * self.size[key]
            err = max(err, float(np.max(diff)) * self.factor / scale)
        return err

    def _fold(self, vectors: dict):
        for key, value in vectors.items():
            self.size[key] = max(self.size[key], float(np.max(np.linalg.norm(value, axis=1))))

    def accept(self, x2, y2):
        """Fold an accepted pair's end into the running sizes."""
        self._fold(self._vectors(x2, y2))


def next_step(h: float, err: float) -> float:
    """The standard controller: h · min(FAC_MAX, max(FAC_MIN, safety · err^(−1/(p+1))))."""
    if err <= 0:
        return h * FAC_MAX
    factor = CONTROL_SAFETY * err ** (-1.0 / (CONTROL_ORDER + 1.0))
    return h * min(FAC_MAX, max(FAC_MIN, factor))
