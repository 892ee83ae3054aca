"""Touchdown stability envelope: Monte Carlo over touchdown conditions.

This module owns the envelope study: sampling touchdown conditions
(vertical and horizontal speed, heading, slope, yaw, attitude error) by a
seeded scrambled Sobol sequence or pseudo-random numbers, running each case
through one compiled C Function on all cores (``casadi.Function.map(...,
"thread", n)``) or as batches on a Dask cluster, classifying every outcome
against limits (tip-over, stroke, hinge deflection, deceleration, rebound)
with its margins, and writing cases, summary and plots.

It derives no physics: every case is the scene's ``touchdown_step``
(``symcushion.simulate``) rolled out by ``fold``, with the case's conditions
in its inputs, so one compiled Function serves the whole study:

* **the slope**, by simulating in the *slope frame*, where the ground stays
  the plane z = 0 of the scene and gravity, an entry of the step's parameter
  vector ``p``, is rotated by the slope angle;
* **μ**, another entry of ``p``, sampled continuously or from levels (cases
  with μ = 0 exactly run on the scene's frictionless graph, a second library);
* **the initial state**: attitude, velocity and a position with the lowest
  foot at ``clearance`` above the ground.

Per case the compiled Function returns the final state and a short vector of
running extrema (strokes, deflections, peak deceleration, tilt, rebound
speed, ...), never the trajectory, so a batch of 10,000 cases needs
kilobytes. It must not re-implement the step, and it classifies only from
those numbers.
"""
from __future__ import annotations

import csv
import dataclasses
import hashlib
import io
import json
import math
import os
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import casadi as ca
import numpy as np

from .codegen import CFLAGS, CODEGEN_OPTIONS, WARNINGS, find_compiler
from .obstacles import Plane
from .scene import Scene, _Table, read_toml, scene_from_dict
from .layout import (BODY_OUT, BODY_STATE, LEG_OUT, LEG_STATE, body_axis_np, default_p,
                     param_layout, quat_from_axis_angle_np, quat_mul_np, quat_to_rot_np,
                     state_layout)
from .measures import measures_function
from .touchdown import StepModel, build_model

__all__ = ["VARIABLES", "SUMMARY", "CLASSES", "Range", "Limits", "EnvelopeStudy",
           "EnvelopeResult", "load_study", "study_from_dict", "sample_unit", "sobol",
           "sample_conditions", "initial_states", "envelope_function", "build_envelope",
           "run_batch", "case_params", "evaluate", "classify", "wilson_interval", "run_envelope", "plot_envelope"]

#: Sampled touchdown conditions, in the order they take dimensions of the
#: sequence (only those given as a range or distribution take one). Angles in
#: degrees. Heading is the direction of the horizontal velocity and yaw the
#: azimuth of the body's x axis, both measured from the fall line (0 =
#: downhill); tilt is the attitude error, a rotation of the body by tilt_deg
#: about the horizontal axis perpendicular to tilt_azimuth_deg.
VARIABLES = {
    "vertical_speed": ("m/s", "downwards"),
    "horizontal_speed": ("m/s", ""),
    "heading_deg": ("deg", "from the fall line"),
    "slope_deg": ("deg", ""),
    "yaw_deg": ("deg", "leg 0 from the fall line"),
    "tilt_deg": ("deg", "attitude error"),
    "tilt_azimuth_deg": ("deg", "direction the body axis leans to"),
    "mu": ("", "Coulomb coefficient"),
}
_DEFAULTS = {"horizontal_speed": 0.0, "heading_deg": 0.0, "slope_deg": 0.0, "yaw_deg": 0.0,
             "tilt_deg": 0.0, "tilt_azimuth_deg": 0.0}
#: Slopes above this are refused: the lowest-foot placement and the legs'
#: geometry are not meant for cliffs (and gravity would pull along the ground).
MAX_SLOPE_DEG = 60.0

#: Running extrema per case, the rows of ``envelope_case``'s ``summary``:
#: max |δ_S| over legs with an axial element (m), max |β| and max |γ − γ₀|
#: (rad), peak specific force |a − g| (m/s², what an accelerometer on the body
#: reads) low-pass filtered with :data:`DECEL_FILTER_TIME` and raw, max of
#: 1 − cos(tilt) against the true vertical, 1 once a foot has touched, the time of the first contact (s, −1 if none), max upward speed
#: after the first contact (m/s, ≥ 0), time with no foot on the ground after
#: the first contact (s), lowest height of the centre of mass above the ground (m).
SUMMARY = ("max_stroke", "max_beta", "max_gamma", "peak_decel", "peak_decel_raw",
           "max_one_minus_cos_tilt", "touched", "first_contact_time", "rebound_speed",
           "airborne_time", "min_height")
_S = {name: i for i, name in enumerate(SUMMARY)}
#: Axis of the slope frame's ground normal: the ground is its plane z = 0, so the
#: body's height above the ground is its z coordinate.
_NORMAL_AXIS = 2

#: Time constant of the first-order low-pass filter on the specific force
#: whose peak is checked against ``limits.deceleration`` (s), like the filter
#: classes of crash-test accelerometry: a crushable absorber re-engages its
#: loading branch for single steps while the lander settles (the switch on the
#: sign of x·ẋ, docs/envelope.md), one-step spikes of up to 50 m/s² that carry
#: almost no impulse; 10 ms (a 16 Hz corner) passes the impact pulse (≥ 50 ms)
#: and damps a 2-ms spike about fivefold. The raw peak is kept as ``peak_decel_raw``.
DECEL_FILTER_TIME = 0.01

#: Outcome classes, in the order of precedence when a case fails several checks.
CLASSES = ("stable", "tip_over", "stroke", "deflection", "deceleration", "rebound",
           "no_touchdown")

#: Cases per batch (one ``map`` call or one Dask task): at ~5 ms per 2-s
#: case a batch takes about half a second, long against a task's overhead
#: (~1 ms) and short enough for a smooth progress line.
DEFAULT_BATCH = 100
#: Default lowest-foot clearance at t = 0 (m): touchdown within a few ms.
DEFAULT_CLEARANCE = 1e-3
#: Bits of the Sobol digits: 2^31 points per dimension before it repeats.
SOBOL_BITS = 31
#: Confidence level of the Wilson interval on P(stable).
CONFIDENCE = 0.95
#: Ridge penalty of the logistic boundary fit (standardised features): keeps
#: the fit finite when a panel's classes are separable.
LOGISTIC_RIDGE = 1e-2
#: Seconds between progress lines.
PROGRESS_INTERVAL = 0.5

# Joe & Kuo (2008) primitive polynomials and initial direction numbers
# (new-joe-kuo-6.21201), dimensions 2..13: (degree s, coefficients a, m_1..m_s).
_JOE_KUO = (
    (1, 0, (1,)), (2, 1, (1, 3)), (3, 1, (1, 3, 1)), (3, 2, (1, 1, 1)),
    (4, 1, (1, 1, 3, 3)), (4, 4, (1, 3, 5, 13)), (5, 2, (1, 1, 5, 5, 17)),
    (5, 4, (1, 1, 5, 5, 5)), (5, 7, (1, 1, 7, 11, 19)), (5, 11, (1, 1, 5, 1, 1)),
    (5, 13, (1, 1, 1, 3, 11)), (5, 14, (1, 3, 5, 5, 31)))


# ---------------------------------------------------------------------------
# sampling
# ---------------------------------------------------------------------------
def _direction_numbers(dim: int) -> np.ndarray:
    """Sobol direction numbers v_k (k = 1..SOBOL_BITS) as integers, one row per dimension."""
    if dim > len(_JOE_KUO) + 1:
        raise ValueError(f"`dim` = {dim}: the built-in Sobol table has {len(_JOE_KUO) + 1} "
                         "dimensions; use method = \"random\".")
    bits = SOBOL_BITS
    v = np.zeros((dim, bits), dtype=np.int64)
    for d in range(dim):
        if d == 0:
            m = [1] * bits                      # van der Corput: m_k = 1
        else:
            s, a, m0 = _JOE_KUO[d - 1]
            m = list(m0)
            for k in range(s, bits):            # m_k = 2a₁m_{k−1} ⊕ … ⊕ 2^s m_{k−s} ⊕ m_{k−s}
                new = m[k - s] ^ (m[k - s] << s)
                for i in range(1, s):
                    if (a >> (s - 1 - i)) & 1:
                        new ^= m[k - i] << i
                m.append(new)
        for k in range(bits):
            v[d, k] = m[k] << (bits - 1 - k)
    return v


def _parity(x: np.ndarray) -> np.ndarray:
    x = x.copy()
    for shift in (32, 16, 8, 4, 2, 1):
        x ^= x >> shift
    return x & 1


def sobol(n: int, dim: int, seed: int | None = 0, scramble: bool = True) -> np.ndarray:
    """Points of the Sobol sequence in [0, 1)^dim, optionally scrambled.

    Scrambling is Matoušek's linear matrix scramble plus a random digital
    shift (the scheme of SciPy's ``qmc.Sobol``): each dimension's direction
    numbers are multiplied by a random lower-triangular unit matrix over
    GF(2), then every point is XOR-ed with a random digit vector. Both keep
    the net property: the first 2^m points put exactly one point in each of
    the 2^m equal intervals of every coordinate. Points are the centres of
    their 2^−31 cells, never exactly 0 or 1.

    Parameters
    ----------
    n : int
        Number of points (balance is best when n is a power of two).
    dim : int
        Dimensions, ≤ 13.
    seed : int or None
        Seed of the scramble (NumPy ``default_rng``); ignored without scrambling.

    Returns
    -------
    ndarray, shape (n, dim)

    References
    ----------
    S. Joe, F. Y. Kuo (2008), Constructing Sobol sequences with better
    two-dimensional projections, SIAM J. Sci. Comput. 30, 2635–2654.
    J. Matoušek (1998), On the L2-discrepancy for anchored boxes, J. Complexity 14.
    """
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 0:
        raise ValueError(f"`n` must be a non-negative integer, got {n!r}.")
    if n > 2 ** SOBOL_BITS:
        raise ValueError(f"`n` = {n} exceeds the 2^{SOBOL_BITS} points of the sequence.")
    bits = SOBOL_BITS
    v = _direction_numbers(dim)
    shift = np.zeros(dim, dtype=np.int64)
    if scramble and dim:
        rng = np.random.default_rng(seed)
        # lower-triangular unit matrix L: output bit r (MSB first) = input bit r ⊕ a
        # random combination of the more significant input bits
        for d in range(dim):
            rows = []
            for r in range(bits):
                above = int(rng.integers(0, 2 ** r)) if r else 0
                rows.append((above << (bits - r)) | (1 << (bits - 1 - r)))
            rows = np.array(rows, dtype=np.int64)
            scr = np.zeros(bits, dtype=np.int64)
            for r in range(bits):
                scr |= _parity(v[d][None, :] & rows[r]).ravel() << (bits - 1 - r)
            v[d] = scr
        shift = rng.integers(0, 2 ** bits, size=dim, dtype=np.int64)
    index = np.arange(n, dtype=np.int64)
    points = np.zeros((n, dim), dtype=np.int64)
    for k in range(max(1, int(n - 1).bit_length()) if n > 1 else 0):
        on = ((index >> k) & 1).astype(bool)
        points[on] ^= v[:, k]
    points ^= shift
    return (points.astype(np.float64) + 0.5) / 2.0 ** bits


@dataclass(frozen=True)
class Range:
    """How one touchdown condition is sampled.

    ``kind`` is ``'fixed'`` (``value``), ``'uniform'`` on [low, high],
    ``'normal'`` (mean, std, optionally truncated to [low, high]) or
    ``'levels'`` (equally likely discrete values, for μ).
    """

    kind: str
    value: float = 0.0
    low: float = -math.inf
    high: float = math.inf
    mean: float = 0.0
    std: float = 0.0
    levels: tuple = ()

    @property
    def random(self) -> bool:
        """True when the condition takes a dimension of the sequence."""
        return self.kind != "fixed"

    def transform(self, u: np.ndarray) -> np.ndarray:
        """Map uniform numbers u ∈ (0, 1) to samples (inverse CDF)."""
        u = np.asarray(u, dtype=float)
        if self.kind == "fixed":
            return np.full(u.shape, self.value)
        if self.kind == "uniform":
            return self.low + u * (self.high - self.low)
        if self.kind == "levels":
            idx = np.minimum((u * len(self.levels)).astype(int), len(self.levels) - 1)
            return np.asarray(self.levels, dtype=float)[idx]
        dist = statistics.NormalDist(self.mean, self.std)
        lo = dist.cdf(self.low) if np.isfinite(self.low) else 0.0
        hi = dist.cdf(self.high) if np.isfinite(self.high) else 1.0
        return np.array([dist.inv_cdf(lo + x * (hi - lo)) for x in u.ravel()]).reshape(u.shape)

    def bounds(self) -> tuple:
        """Smallest and largest value that can be sampled."""
        if self.kind == "fixed":
            return self.value, self.value
        if self.kind == "levels":
            return min(self.levels), max(self.levels)
        return self.low, self.high

    def describe(self) -> str:
        if self.kind == "fixed":
            return f"{self.value:g}"
        if self.kind == "uniform":
            return f"uniform [{self.low:g}, {self.high:g}]"
        if self.kind == "levels":
            return "levels " + ", ".join(f"{v:g}" for v in self.levels)
        cut = "" if not (np.isfinite(self.low) or np.isfinite(self.high)) else \
            f" on [{self.low:g}, {self.high:g}]"
        return f"normal({self.mean:g}, {self.std:g}){cut}"


@dataclass(frozen=True)
class Limits:
    """Limits of a stable touchdown; None leaves a check out.

    Attributes
    ----------
    stroke : float
        Largest axial stroke |δ_S| of any leg (m).
    beta, gamma : float
        Largest hinge azimuth |β| and polar deflection |γ − γ₀| (rad).
    tilt_deg : float
        Tip-over: the body z axis more than this from the true vertical at
        any time (deg). Choose it beyond the largest slope plus the static
        tip-over margin you accept.
    deceleration : float
        Peak specific force |a − g| (m/s²).
    rebound_speed : float
        Upward speed after the first contact (m/s).
    """

    stroke: float | None = None
    beta: float | None = None
    gamma: float | None = None
    tilt_deg: float | None = None
    deceleration: float | None = None
    rebound_speed: float | None = None

    def __post_init__(self):
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if value is not None and not (isinstance(value, (int, float))
                                          and not isinstance(value, bool)
                                          and math.isfinite(value) and value > 0):
                raise ValueError(f"`limits.{f.name}` must be a positive number or None, "
                                 f"got {value!r}.")
        if self.tilt_deg is not None and self.tilt_deg >= 180:
            raise ValueError(f"`limits.tilt_deg` must be below 180°, got {self.tilt_deg!r}.")
        if all(getattr(self, f.name) is None for f in dataclasses.fields(self)):
            raise ValueError("`limits`: give at least one limit (stroke, beta, gamma, tilt_deg, "
                             "deceleration, rebound_speed); without any every case is stable.")


@dataclass
class EnvelopeStudy:
    """An envelope study: base scene, sampling, ranges and limits.

    Attributes
    ----------
    name, description : str
    scene : Scene
        The base scene: legs, body mass and inertia, μ, method, Δt, duration.
        The ground must be one plane with normal +z (the slope frame).
    n : int
        Cases.
    seed : int
    method : {'sobol', 'random'}
    ranges : dict of str to Range
        One per name of :data:`VARIABLES`.
    limits : Limits
    clearance : float
        Lowest foot above the ground at t = 0 (m).
    batch : int
        Cases per batch.
    source : str
    scene_data : dict, optional
        The scene tables as read from the file, for Dask workers that build
        the compiled Function themselves.
    """

    name: str
    scene: Scene
    n: int
    seed: int
    method: str
    ranges: dict
    limits: Limits
    clearance: float = DEFAULT_CLEARANCE
    batch: int = DEFAULT_BATCH
    description: str = ""
    source: str = ""
    scene_data: dict | None = None

    def with_(self, **changes) -> "EnvelopeStudy":
        """A copy with some fields replaced, e.g. ``study.with_(n=200, seed=1)``."""
        new = dataclasses.replace(self, **changes)
        _check_counts(new)
        return new


def _check_counts(study):
    for name in ("n", "batch"):
        value = getattr(study, name)
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
            raise ValueError(f"`{name}` must be a positive integer, got {value!r}.")
    if isinstance(study.seed, bool) or not isinstance(study.seed, (int, np.integer)) \
            or study.seed < 0:
        raise ValueError(f"`seed` must be a non-negative integer, got {study.seed!r}.")
    if study.method not in ("sobol", "random"):
        raise ValueError(f"`method` must be 'sobol' or 'random', got {study.method!r}.")


def sample_unit(study: EnvelopeStudy) -> np.ndarray:
    """Uniform numbers in (0, 1), shape (n, d), one column per random condition."""
    dim = sum(r.random for r in study.ranges.values())
    if study.method == "sobol":
        return sobol(study.n, dim, seed=study.seed)
    return np.random.default_rng(study.seed).random((study.n, dim))


def sample_conditions(study: EnvelopeStudy) -> dict:
    """The sampled touchdown conditions: a dict of arrays of shape (n,), by :data:`VARIABLES`."""
    u = sample_unit(study)
    out, col = {}, 0
    for name in VARIABLES:
        r = study.ranges[name]
        if r.random:
            out[name] = r.transform(u[:, col])
            col += 1
        else:
            out[name] = r.transform(np.zeros(study.n))
    return out


# ---------------------------------------------------------------------------
# study files
# ---------------------------------------------------------------------------
class _Fields(_Table):
    """An envelope study table: the scene files' field checker."""

    docs = "docs/envelope.md"


_SCENE_KEYS = ("scene", "body", "legs", "leg", "obstacle")


def _range(t: _Fields, name: str) -> Range:
    value = t.data[name]
    t.used.add(name)
    where = f"{t.path}.{name}" if t.path else name
    allowed = ("a number, [low, high], {distribution = \"normal\", mean, std (, low, high)}"
               + (" or {levels = [...]}" if name == "mu" else ""))
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        if not math.isfinite(value):
            raise t.error(name, value, allowed)
        return Range("fixed", value=float(value))
    if isinstance(value, list):
        ok = len(value) == 2 and all(isinstance(v, (int, float)) and not isinstance(v, bool)
                                     and math.isfinite(v) for v in value)
        if not ok or value[0] > value[1]:
            raise t.error(name, value, "[low, high] with low ≤ high (" + allowed + ")")
        if value[0] == value[1]:
            return Range("fixed", value=float(value[0]))
        return Range("uniform", low=float(value[0]), high=float(value[1]))
    if isinstance(value, dict):
        sub = _Fields(value, where, t.source)
        if name == "mu" and sub.has("levels"):
            levels = sub.get("levels", kind="vector")
            sub.finish()
            if levels.size < 1 or np.any(levels < 0):
                raise sub.error("levels", levels.tolist(), "a non-empty list of numbers ≥ 0")
            if levels.size == 1:
                return Range("fixed", value=float(levels[0]))
            return Range("levels", levels=tuple(sorted(set(levels.tolist()))))
        kind = sub.get("distribution", kind="string", choices=("normal", "uniform"))
        if kind == "uniform":
            low, high = sub.get("low"), sub.get("high")
            if low > high:
                raise sub.error("high", high, f"a number ≥ low = {low:g}")
            sub.finish()
            return Range("uniform", low=low, high=high) if low < high else \
                Range("fixed", value=low)
        mean, std = sub.get("mean"), sub.get("std", nonnegative=True)
        low, high = sub.get("low", -math.inf), sub.get("high", math.inf)
        sub.finish()
        if not low < high or not low <= mean <= high:
            raise sub.error("low", low, f"low < high with low ≤ mean ≤ high (mean {mean:g}, "
                                        f"high {high:g})")
        if std == 0:
            return Range("fixed", value=mean)
        return Range("normal", low=low, high=high, mean=mean, std=std)
    raise t.error(name, value, allowed)


def _check_range(name: str, r: Range, source: str):
    lo, hi = r.bounds()
    problem = None
    if name in ("vertical_speed", "horizontal_speed", "mu") and lo < 0:
        problem = ("must not be negative" + ("; truncate the normal distribution with "
                                             "`low = 0`" if r.kind == "normal" else ""))
    if name == "slope_deg" and not (0 <= lo and hi < MAX_SLOPE_DEG):
        problem = (f"must lie in [0°, {MAX_SLOPE_DEG:g}°) (a negative slope is the same slope "
                   "with heading and yaw turned by 180°)")
    if problem:
        raise ValueError(f"{source}: field `ranges.{name}` = {r.describe()} {problem}; see "
                         "docs/envelope.md.")


def study_from_dict(data: dict, source: str = "<dict>") -> EnvelopeStudy:
    """Build an :class:`EnvelopeStudy` from the parsed contents of a study TOML file."""
    top = _Fields(data, "", source)
    st = top.get("study", kind="table") if top.has("study") else _Fields({}, "study", source)
    top.used.add("study")
    name = st.get("name", Path(source).stem, kind="string")
    description = st.get("description", "", kind="string")
    clearance = st.get("clearance", DEFAULT_CLEARANCE, nonnegative=True)
    st.finish()
    scene_raw = {k: data[k] for k in _SCENE_KEYS if k in data}
    top.used.update(_SCENE_KEYS)
    if not scene_raw:
        raise ValueError(f"{source}: no scene; give the scene tables ([scene], [body], [legs] "
                         "or [[leg]], [[obstacle]]) as in a scene file (docs/scenes.md).")
    scene = scene_from_dict(scene_raw, source)
    _check_scene(scene, source)

    sa = top.get("sampling", kind="table") if top.has("sampling") else \
        _Fields({}, "sampling", source)
    top.used.add("sampling")
    n = sa.get("n", kind="int")
    seed = sa.data.get("seed", 0)
    sa.used.add("seed")
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise sa.error("seed", seed, "an integer ≥ 0")
    method = sa.get("method", "sobol", kind="string", choices=("sobol", "random"))
    batch = sa.get("batch", DEFAULT_BATCH, kind="int")
    sa.finish()

    ra = top.get("ranges", kind="table")
    ranges = {}
    for var in VARIABLES:
        if ra.has(var):
            ranges[var] = _range(ra, var)
        elif var == "vertical_speed":
            raise ValueError(f"{source}: missing field `ranges.vertical_speed` (m/s downwards: "
                             "a number, [low, high] or a distribution).")
        elif var == "mu":
            ranges[var] = Range("fixed", value=scene.mu)
        else:
            ranges[var] = Range("fixed", value=_DEFAULTS[var])
        _check_range(var, ranges[var], source)
    ra.finish()

    li = top.get("limits", kind="table")
    try:
        limits = Limits(**{k: li.get(k, None, positive=True) for k in
                           ("stroke", "beta", "gamma", "tilt_deg", "deceleration",
                            "rebound_speed")})
    except ValueError as exc:
        raise ValueError(f"{source}: {exc}") from None
    li.finish()
    top.finish()
    study = EnvelopeStudy(name=name, scene=scene, n=n, seed=seed, method=method, ranges=ranges,
                          limits=limits, clearance=clearance, batch=batch,
                          description=description, source=source,
                          scene_data=json.loads(json.dumps(scene_raw)))
    dim = sum(r.random for r in ranges.values())
    if method == "sobol" and dim > len(_JOE_KUO) + 1:
        raise ValueError(f"{source}: {dim} random conditions exceed the Sobol table; "
                         "use `sampling.method = \"random\"`.")
    return study


def _check_scene(scene: Scene, source: str):
    obs = scene.obstacles
    if len(obs) != 1 or not isinstance(obs[0], Plane) or not np.allclose(obs[0].n, [0, 0, 1]):
        raise ValueError(f"{source}: an envelope study needs exactly one `[[obstacle]]` of "
                         "type \"plane\" with normal [0, 0, 1]: the ground of the slope frame "
                         "(slopes come from `ranges.slope_deg`, which rotates gravity).")
    g = np.asarray(scene.gravity, dtype=float)
    if np.linalg.norm(g[:2]) > 1e-12 * np.linalg.norm(g) or g[2] >= 0:
        raise ValueError(f"{source}: `scene.gravity` = {g.tolist()} must point along −z; "
                         "slopes come from `ranges.slope_deg`.")


def load_study(path) -> EnvelopeStudy:
    """Load an envelope study from a TOML file (format: docs/envelope.md)."""
    return study_from_dict(read_toml(path, "envelope study"), str(path))


# ---------------------------------------------------------------------------
# initial states in the slope frame
# ---------------------------------------------------------------------------
def initial_states(study: EnvelopeStudy, conditions: dict) -> tuple:
    """Initial states and gravity vectors of the cases, in the slope frame.

    The slope frame has the ground as its plane z = 0 and its x axis along
    the fall line; the world frame has z up and the same fall line. A world
    vector w becomes R_y(−θ) w for slope θ, so gravity is
    |g|·(sin θ, 0, −cos θ) and the true vertical (−sin θ, 0, cos θ).
    In the world frame the body has attitude q = q_tilt ⊗ q_yaw ⊗ q_scene and
    velocity (v_h cos ψ, v_h sin ψ, −v_v) for heading ψ; its position puts
    the lowest unloaded foot ``study.clearance`` above the ground. Feet are
    free, angular velocity is the scene's.

    Returns
    -------
    x0 : ndarray, shape (nx, n)
    gravity : ndarray, shape (3, n)
        Gravity in the slope frame (m/s²).
    """
    scene = study.scene
    c = conditions
    n = len(c["vertical_speed"])
    g = float(np.linalg.norm(scene.gravity))
    theta = np.radians(c["slope_deg"])
    psi = np.radians(c["heading_deg"])
    yaw = np.radians(c["yaw_deg"])
    tilt = np.radians(c["tilt_deg"])
    azim = np.radians(c["tilt_azimuth_deg"])
    zeros, ones = np.zeros(n), np.ones(n)

    v_world = np.column_stack([c["horizontal_speed"] * np.cos(psi),
                               c["horizontal_speed"] * np.sin(psi), -c["vertical_speed"]])
    q_base = np.tile(scene.body.attitude, (n, 1))
    q_yaw = quat_from_axis_angle_np(np.column_stack([zeros, zeros, ones]), yaw)
    q_tilt = quat_from_axis_angle_np(np.column_stack([-np.sin(azim), np.cos(azim), zeros]), tilt)
    q_world = quat_mul_np(q_tilt, quat_mul_np(q_yaw, q_base))
    q_slope = quat_from_axis_angle_np(np.column_stack([zeros, ones, zeros]), -theta)   # R_y(−θ)
    q = quat_mul_np(q_slope, q_world)
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    R_slope = quat_to_rot_np(q_slope, normalise=False)
    vel = np.einsum("nij,nj->ni", R_slope, v_world)
    gravity = g * np.column_stack([np.sin(theta), zeros, -np.cos(theta)])

    R = quat_to_rot_np(q, normalise=False)
    rest = np.array([leg.rest_foot for leg in scene.legs])                 # (legs, 3)
    feet_rel = np.einsum("nij,lj->nli", R, rest)                          # (n, legs, 3)
    ground = float(scene.obstacles[0].point[2])
    height = ground + study.clearance - feet_rel[:, :, 2].min(axis=1)
    pos = np.column_stack([zeros, zeros, height])
    omega = np.tile(scene.body.angular_velocity, (n, 1))
    legs = range(len(scene.legs))
    x0 = state_layout(len(scene.legs)).pack_columns(
        n, position=pos.T, velocity=vel.T, attitude=q.T, angular_velocity=omega.T,
        foot=[(pos + feet_rel[:, j]).T for j in legs], contact=[zeros for _ in legs],
        force_body=[np.zeros((3, n)) for _ in legs])
    return np.ascontiguousarray(x0), np.ascontiguousarray(gravity.T)


# ---------------------------------------------------------------------------
# the compiled case Function
# ---------------------------------------------------------------------------
def envelope_function(model: StepModel, steps: int | None = None) -> ca.Function:
    """``envelope_case(x0, p, dt) -> (x_end, summary)``: one whole touchdown.

    The scene's ``touchdown_step`` rolled out by ``fold``, with the case's
    gravity (slope frame) and μ in its parameter vector ``p``. The running
    extrema of :data:`SUMMARY`, taken from ``touchdown_measures``
    (:mod:`symcushion.measures`), are carried as extra states, and ``fold``
    keeps only the final state, so one case returns nx + 11 numbers.

    Parameters
    ----------
    model : StepModel
        From ``build_model(scene)`` (the SX step; it is inlined).
    steps : int, optional
        Steps per case; default ``scene.steps``.
    """
    scene = model.scene
    steps = scene.steps if steps is None else int(steps)
    nx, ns = model.nx, len(SUMMARY)
    xl = state_layout(model.n_legs)
    x = ca.SX.sym("x", nx)
    s = ca.SX.sym("s", ns)
    a_f = ca.SX.sym("a_filtered", 3)                    # low-pass filtered specific force
    p = ca.SX.sym("p", model.np)
    h = ca.SX.sym("dt")

    x1, y = model.step(x, p, h)
    m = measures_function(scene).call(dict(x=x1, y=y, p=p))
    axial = [j for j, leg in enumerate(scene.legs) if not leg.rigid]
    contact_any = ca.mmax(m["contact"]) if model.n_legs else 0
    stroke = ca.mmax(ca.fabs(m["stroke"][axial])) if axial else 0
    beta = ca.mmax(ca.fabs(m["beta"])) if model.n_legs else 0
    gamma = ca.mmax(ca.fabs(m["gamma_deflection"])) if model.n_legs else 0
    specific_force = m["specific_force"]
    # first-order low-pass, exact for a force held over the step (any dt)
    a_f1 = a_f + (1 - ca.exp(-h / DECEL_FILTER_TIME)) * (specific_force - a_f)
    touched_before = s[_S["touched"]]
    touched = ca.fmax(touched_before, contact_any)
    # the step index is not in the state: the first contact time is accumulated as
    # "time elapsed while untouched", which equals it once contact has happened
    first_time = ca.if_else(touched_before < 0.5, s[_S["first_contact_time"]] + h,
                            s[_S["first_contact_time"]])
    airborne = ca.if_else(ca.logic_and(touched > 0.5, contact_any < 0.5),
                          s[_S["airborne_time"]] + h, s[_S["airborne_time"]])
    rebound = ca.if_else(touched > 0.5, ca.fmax(s[_S["rebound_speed"]], m["upward_speed"]),
                         s[_S["rebound_speed"]])
    height = xl.get(x1, "position")[_NORMAL_AXIS]
    s1 = ca.vertcat(ca.fmax(s[_S["max_stroke"]], stroke), ca.fmax(s[_S["max_beta"]], beta),
                    ca.fmax(s[_S["max_gamma"]], gamma),
                    ca.fmax(s[_S["peak_decel"]], ca.norm_2(a_f1)),
                    ca.fmax(s[_S["peak_decel_raw"]], ca.norm_2(specific_force)),
                    ca.fmax(s[_S["max_one_minus_cos_tilt"]], m["one_minus_cos_tilt"]), touched,
                    first_time, rebound, airborne, ca.fmin(s[_S["min_height"]], height))
    x0 = ca.MX.sym("x0", nx)
    pm = ca.MX.sym("p", model.np)
    hm = ca.MX.sym("dt")
    s0 = ca.vertcat(ca.MX.zeros(_S["min_height"]), xl.get(x0, "position")[_NORMAL_AXIS],
                    ca.MX.zeros(3))
    xs, xs1 = ca.vertcat(x, s, a_f), ca.vertcat(x1, s1, a_f1)
    step = ca.Function("envelope_step", [xs, p, h], [xs1], ["xs", "p", "dt"], ["xs_next"])
    xs_end = step.fold(steps)(ca.vertcat(x0, s0), pm, hm)
    summary = xs_end[nx:nx + ns]
    # cases that never touch: first contact time −1 instead of the whole duration
    summary = ca.vertcat(summary[:_S["first_contact_time"]],
                         ca.if_else(summary[_S["touched"]] > 0.5,
                                    summary[_S["first_contact_time"]], -1),
                         summary[_S["first_contact_time"] + 1:])
    return ca.Function("envelope_case", [x0, pm, hm], [xs_end[:nx], summary],
                       ["x0", "p", "dt"], ["x_end", "summary"])


#: Default folder of the compiled case Functions, one sub-folder per source
#: fingerprint (git-ignored: ``build/`` is in .gitignore).
DEFAULT_CACHE = Path("build") / "envelope"
_SOURCE = "envelope_case.c"
_LIBRARY = "libenvelope_case.so"
_MANIFEST = "envelope.json"


def build_envelope(scene: Scene, cache_dir=None, *, steps: int | None = None,
                   progress: bool = False) -> Path:
    """Generate and compile ``envelope_case`` for a scene; return the library's path.

    The C source is generated (a second or two), fingerprinted with the flags
    and compiler, and compiled into ``cache_dir/<scene name>-<fingerprint>/``
    unless that folder already holds the library, so repeated studies, tests
    and Dask workers reuse one build and different scenes (or μ) never share
    a path (a process cannot load two libraries from one path). Flags are
    those of ``symcushion.codegen`` (:data:`~symcushion.codegen.CFLAGS`).

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
    cc = find_compiler()
    if cc is None:
        raise FileNotFoundError("no C compiler: set $CC or install gcc; the envelope runs "
                                "compiled code only.")
    started = time.perf_counter()
    model = build_model(scene)
    f = envelope_function(model, steps)
    with tempfile.TemporaryDirectory(prefix="symcushion-envelope-") as tmp:
        cg = ca.CodeGenerator(_SOURCE, dict(CODEGEN_OPTIONS, with_header=False))
        cg.add(f)
        cg.generate(tmp + os.sep)
        source = (Path(tmp) / _SOURCE).read_bytes()
    flags = [*CFLAGS, *WARNINGS]
    digest = hashlib.sha256(source + " ".join(flags).encode() + cc.encode()).hexdigest()
    folder = Path(DEFAULT_CACHE if cache_dir is None else cache_dir) / \
        f"{_safe(scene.name)}-{digest[:16]}"
    library = folder / _LIBRARY
    if library.is_file():
        return library
    folder.mkdir(parents=True, exist_ok=True)
    (folder / _SOURCE).write_bytes(source)
    if progress:
        print(f"compiling envelope_case for '{scene.name}' (method {scene.method}, "
              f"{'μ an input' if scene.mu > 0 else 'frictionless'}, "
              f"{scene.steps if steps is None else steps} steps) in "
              f"{folder} ...", file=sys.stderr, flush=True)
    partial = folder / f".{_LIBRARY}.{os.getpid()}"
    argv = [cc, *flags, "-shared", str(folder / _SOURCE), "-o", str(partial), "-lm"]
    done = subprocess.run(argv, capture_output=True, text=True)
    if done.returncode != 0:
        raise RuntimeError(f"compiling {folder / _SOURCE} failed ({' '.join(argv)}):\n"
                           f"{done.stderr}{done.stdout}")
    if done.stderr.strip():
        print(f"gcc printed, compiling {_SOURCE}:\n{done.stderr}", file=sys.stderr)
    os.replace(partial, library)                 # atomic: concurrent builders agree
    (folder / _MANIFEST).write_text(json.dumps({
        "scene": scene.name, "method": scene.method, "friction": scene.mu > 0, "dt": scene.dt,
        "steps": scene.steps if steps is None else steps, "nx": model.nx, "np": model.np,
        "summary": list(SUMMARY), "instructions": model.step.n_instructions(),
        "cflags": flags, "compiler": cc, "fingerprint": digest, "casadi": ca.__version__,
        "seconds": time.perf_counter() - started}, indent=1))
    return library


def _safe(name: str) -> str:
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


def run_batch(library, x0, p, dt, threads: int = 1) -> tuple:
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
    threads = max(1, min(int(threads), count))
    key = (id(f), count, threads)
    if key not in _MAPS:
        _MAPS[key] = f.map(count, "thread", threads) if threads > 1 else f.map(count, "serial")
    x_end, summary = _MAPS[key](x0, p, float(dt))
    return np.asarray(x_end, dtype=float), np.asarray(summary, dtype=float)


def case_params(scene: Scene, mu: np.ndarray, gravity: np.ndarray) -> np.ndarray:
    """Step parameters of each case (np, n): the scene's, with the cases' μ and gravity.

    Parameters
    ----------
    scene : Scene
        The compiled scene; a frictionless one (μ = 0) has no μ entry, and
        then every case's μ must be 0.
    mu : array_like, shape (n,)
    gravity : array_like, shape (3, n)
        Gravity in the slope frame (m/s²).
    """
    params = param_layout(scene)
    mu = np.asarray(mu, dtype=float)
    gravity = np.asarray(gravity, dtype=float)
    p = np.tile(default_p(scene)[:, None], (1, gravity.shape[1]))
    p[params.slice("gravity")] = gravity
    if params.friction:
        p[params.slice("mu")] = mu
    elif np.any(mu != 0):
        raise ValueError(f"`mu` has values up to {np.max(mu)!r} but the scene is frictionless "
                         "(μ = 0 builds no friction paths); build it with μ > 0.")
    return p


def _dask_batch(library, scene_data, source, cache_dir, x0, p, dt):
    """A Dask task: one batch; builds the library on the worker if it cannot see it."""
    if not Path(library).is_file():
        if scene_data is None:
            raise FileNotFoundError(f"this worker cannot see {library!r} and has no scene to "
                                    "build it from: put `cache_dir` on a shared filesystem or "
                                    "load the study from a file (docs/envelope.md).")
        scene = scene_from_dict(scene_data, source)
        library = build_envelope(scene, cache_dir)
    return run_batch(library, x0, p, dt, threads=1)


# ---------------------------------------------------------------------------
# classification
# ---------------------------------------------------------------------------
def wilson_interval(k, n, confidence: float = CONFIDENCE) -> tuple:
    """Wilson score interval of a binomial proportion k/n.

    Returns (estimate, low, high); (nan, 0, 1) for n = 0.
    """
    k, n = np.asarray(k, dtype=float), np.asarray(n, dtype=float)
    z = statistics.NormalDist().inv_cdf(0.5 + confidence / 2)
    with np.errstate(invalid="ignore", divide="ignore"):
        phat = k / n
        denom = 1 + z * z / n
        centre = (phat + z * z / (2 * n)) / denom
        half = z / denom * np.sqrt(phat * (1 - phat) / n + z * z / (4 * n * n))
    empty = n == 0
    return (np.where(empty, np.nan, phat), np.where(empty, 0.0, centre - half),
            np.where(empty, 1.0, centre + half))


def classify(summary: np.ndarray, x_end: np.ndarray, gravity: np.ndarray, x0: np.ndarray,
             limits: Limits, n_legs: int) -> dict:
    """Measures, margins and the class of every case.

    A case is ``stable`` when it passes every given limit; otherwise its class
    is the first failed check in the order of :data:`CLASSES` (tip-over first:
    it ends the mission whatever else happened). ``no_touchdown`` marks a case
    whose feet never touched (raise ``duration`` or lower ``clearance``).
    Margins are 1 − value/limit: positive passes, 0 is on the limit.

    Returns
    -------
    dict of str to ndarray
        Measure and margin columns, plus ``class`` (str) and ``stable`` (bool).
    """
    S = {name: summary[i] for i, name in enumerate(SUMMARY)}
    up = -gravity / np.linalg.norm(gravity, axis=0, keepdims=True)
    xl = state_layout(n_legs)
    body_z = body_axis_np(xl.get(x_end, "attitude").T).T
    final_tilt = np.degrees(np.arccos(np.clip(np.sum(up * body_z, axis=0), -1, 1)))
    contacts = xl.legs(x_end, "contact")
    out = {
        "max_stroke": S["max_stroke"], "max_beta": S["max_beta"], "max_gamma": S["max_gamma"],
        "peak_decel": S["peak_decel"], "peak_decel_raw": S["peak_decel_raw"],
        "max_tilt_deg": np.degrees(np.arccos(np.clip(1 - S["max_one_minus_cos_tilt"], -1, 1))),
        "final_tilt_deg": final_tilt, "rebound_speed": S["rebound_speed"],
        "airborne_time": S["airborne_time"], "first_contact_time": S["first_contact_time"],
        "min_height": S["min_height"],
        "final_speed": np.linalg.norm(xl.get(x_end, "velocity"), axis=0),
        # along the ground: the slope frame's x and y
        "slide": np.linalg.norm((xl.get(x_end, "position") - xl.get(x0, "position"))[:2], axis=0),
        "feet_down": np.sum(contacts > 0.5, axis=0).astype(float),
    }
    n = summary.shape[1]
    failed = {}
    checks = (("tip_over", "max_tilt_deg", limits.tilt_deg),
              ("stroke", "max_stroke", limits.stroke),
              ("deflection", "max_beta", limits.beta),
              ("deflection", "max_gamma", limits.gamma),
              ("deceleration", "peak_decel", limits.deceleration),
              ("rebound", "rebound_speed", limits.rebound_speed))
    for check, measure, limit in checks:
        if limit is None:
            continue
        margin = 1 - out[measure] / limit
        key = f"margin_{check}"
        out[key] = np.minimum(out[key], margin) if key in out else margin
        failed[check] = failed.get(check, np.zeros(n, bool)) | (out[measure] > limit)
    if not all(np.all(np.isfinite(v)) for v in out.values()):
        bad = [k for k, v in out.items() if not np.all(np.isfinite(v))]
        raise FloatingPointError(f"non-finite results in {bad}: a case diverged; reduce "
                                 "`scene.dt` or check the legs (docs/envelope.md).")
    cls = np.full(n, "stable", dtype=object)
    for check in reversed(CLASSES[1:-1]):
        if check in failed:
            cls[failed[check]] = check
    cls[S["touched"] < 0.5] = "no_touchdown"
    out["class"] = cls
    out["stable"] = cls == "stable"
    return out


# ---------------------------------------------------------------------------
# running a study
# ---------------------------------------------------------------------------
class _Progress:
    """One stderr line: cases done, cases per second, estimated time left."""

    def __init__(self, total: int, enabled: bool, label: str):
        self.total, self.enabled, self.label = total, enabled, label
        self.done = 0
        self.started = time.perf_counter()
        self.last = -math.inf

    def update(self, count: int):
        self.done += count
        now = time.perf_counter()
        if self.enabled and (now - self.last >= PROGRESS_INTERVAL or self.done >= self.total):
            self.last = now
            elapsed = max(now - self.started, 1e-9)
            rate = self.done / elapsed
            left = (self.total - self.done) / rate if rate > 0 else math.inf
            print(f"\r  {self.label}: {self.done:,}/{self.total:,} cases, {rate:,.0f} cases/s, "
                  f"{elapsed:.0f} s elapsed, about {left:.0f} s left   ", end="",
                  file=sys.stderr, flush=True)
            if self.done >= self.total:
                print(file=sys.stderr, flush=True)


@dataclass
class EnvelopeResult:
    """Cases of an envelope study and what was measured.

    Attributes
    ----------
    study : EnvelopeStudy
    conditions : dict of str to ndarray, shape (n,)
        The sampled conditions (:data:`VARIABLES`).
    columns : dict of str to ndarray, shape (n,)
        Measures, margins, ``class`` and ``stable`` (:func:`classify`).
    timings : dict
        ``build_seconds``, ``run_seconds``, ``cases_per_second``, backend details.
    files : dict of str to Path
        What :func:`run_envelope` wrote.
    """

    study: EnvelopeStudy
    conditions: dict
    columns: dict
    timings: dict = field(default_factory=dict)
    files: dict = field(default_factory=dict)

    @property
    def n(self) -> int:
        return len(self.columns["class"])

    def counts(self) -> dict:
        """Cases per class (every class of :data:`CLASSES`, zeros included)."""
        cls = self.columns["class"]
        return {c: int(np.sum(cls == c)) for c in CLASSES}

    def p_stable(self) -> dict:
        """P(stable) with its Wilson interval at :data:`CONFIDENCE`."""
        k = int(np.sum(self.columns["stable"]))
        est, lo, hi = wilson_interval(k, self.n)
        return {"stable": k, "cases": self.n, "p": float(est), "low": float(lo),
                "high": float(hi), "confidence": CONFIDENCE}

    def csv_text(self) -> str:
        """Every case as CSV: index, conditions, measures, margins, class.

        Numbers are written with ``repr`` (shortest round-trip form), so equal
        results give equal bytes.
        """
        names = list(VARIABLES) + [k for k in self.columns if k not in ("class", "stable")]
        data = [self.conditions[k] for k in VARIABLES] + [self.columns[k] for k in names[
            len(VARIABLES):]]
        buf = io.StringIO()
        writer = csv.writer(buf, lineterminator="\n")
        writer.writerow(["case"] + names + ["class"])
        for i in range(self.n):
            writer.writerow([i] + [repr(float(col[i])) for col in data]
                            + [self.columns["class"][i]])
        return buf.getvalue()

    def summary(self) -> dict:
        """The summary JSON: study, counts, P(stable) overall and per slope bin, timings."""
        st = self.study
        slope = self.conditions["slope_deg"]
        bins = _slope_bins(slope)
        per_bin = []
        for lo, hi in bins:
            sel = (slope >= lo) & (slope <= hi) if hi == bins[-1][1] else \
                (slope >= lo) & (slope < hi)
            k, n = int(np.sum(self.columns["stable"][sel])), int(np.sum(sel))
            est, low, high = wilson_interval(k, n)
            per_bin.append({"slope_deg": [lo, hi], "cases": n, "stable": k,
                            "p": None if n == 0 else float(est), "low": float(low),
                            "high": float(high)})
        return {
            "study": st.name, "description": st.description, "source": st.source,
            "cases": self.n, "seed": st.seed, "sampling": st.method,
            "scene": {"method": st.scene.method, "dt": st.scene.dt,
                      "duration": st.scene.duration, "legs": len(st.scene.legs),
                      "mass": st.scene.body.mass},
            "ranges": {k: r.describe() for k, r in st.ranges.items()},
            "limits": {k: v for k, v in dataclasses.asdict(st.limits).items() if v is not None},
            "clearance": st.clearance,
            "counts": self.counts(), "p_stable": self.p_stable(), "p_stable_by_slope": per_bin,
            "timings": self.timings,
        }


def _slope_bins(slope: np.ndarray, count: int = 3) -> list:
    lo, hi = float(np.min(slope)), float(np.max(slope))
    if hi - lo < 1e-9:
        return [(lo, hi)]
    edges = np.linspace(lo, hi, count + 1)
    return [(float(a), float(b)) for a, b in zip(edges[:-1], edges[1:])]


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


def _libraries(study: EnvelopeStudy, mu: np.ndarray, cache_dir, progress: bool) -> dict:
    """One compiled library per kind of case present (frictionless, friction)."""
    return {friction: build_envelope(_level_scene(study.scene, friction, mu), cache_dir,
                                     progress=progress)
            for friction in sorted({bool(v > 0) for v in mu})}


def _all_params(study: EnvelopeStudy, mu: np.ndarray, gravity: np.ndarray) -> dict:
    """Each kind's parameter columns (np, n), indexed by case."""
    return {friction: case_params(_level_scene(study.scene, friction, mu),
                                  np.where(mu > 0, mu, 0.0) if friction else np.zeros_like(mu),
                                  gravity)
            for friction in sorted({bool(v > 0) for v in mu})}


def _scene_data(study: EnvelopeStudy, friction: bool, mu: np.ndarray) -> dict | None:
    if study.scene_data is None:
        return None
    raw = json.loads(json.dumps(study.scene_data))
    raw.setdefault("scene", {})["mu"] = _level_scene(study.scene, friction, mu).mu
    return raw


def run_envelope(study: EnvelopeStudy, out_dir=None, *, threads: int | None = None,
                 dask: bool = False, scheduler: str | None = None, workers: int = 2,
                 cache_dir=None, progress: bool = True, plots: bool = True) -> EnvelopeResult:
    """Sample, run, classify and (with ``out_dir``) write an envelope study.

    Parameters
    ----------
    study : EnvelopeStudy
    out_dir : str or Path, optional
        Writes ``cases.csv``, ``summary.json`` and, with ``plots``, the figures
        (:func:`plot_envelope`).
    threads : int, optional
        Threads of the local run (``map(batch, "thread", threads)``); default
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
    _check_counts(study)
    conditions = sample_conditions(study)
    x0, gravity = initial_states(study, conditions)
    scene = study.scene
    started = time.perf_counter()
    libraries = _libraries(study, conditions["mu"], cache_dir, progress)
    p = _all_params(study, conditions["mu"], gravity)
    build_seconds = time.perf_counter() - started
    tasks = _tasks(conditions, study.batch)
    x_end = np.zeros_like(x0)
    summary = np.zeros((len(SUMMARY), study.n))
    backend = "dask" if dask else "threads"
    bar = _Progress(study.n, progress, f"{study.name} ({backend})")
    started = time.perf_counter()
    info = {}
    if not dask:
        for friction, idx in tasks:
            xe, sm = run_batch(libraries[friction], x0[:, idx], p[friction][:, idx], scene.dt,
                               threads)
            x_end[:, idx], summary[:, idx] = xe, sm
            bar.update(len(idx))
        info = {"threads": threads}
    else:
        # run_seconds leaves out the cluster's start (reported as startup_seconds)
        info = _run_dask(study, tasks, libraries, x0, conditions["mu"], p, x_end, summary, bar,
                         scheduler, workers, cache_dir)
    run_seconds = info.pop("compute_seconds", time.perf_counter() - started)
    columns = classify(summary, x_end, gravity, x0, study.limits, len(scene.legs))
    timings = {"backend": backend, **info, "batch": study.batch,
               "build_seconds": round(build_seconds, 3), "run_seconds": round(run_seconds, 3),
               "cases_per_second": round(study.n / run_seconds, 1),
               "steps_per_case": scene.steps, "dt": scene.dt}
    result = EnvelopeResult(study, conditions, columns, timings)
    if out_dir is not None:
        write_result(result, out_dir, plots=plots)
    return result


def evaluate(study: EnvelopeStudy, conditions: dict, *, threads: int = 1, cache_dir=None,
             progress: bool = False) -> dict:
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
                (study.scene.mu if name == "mu" else _DEFAULTS[name])
            full[name] = np.full(n, value)
    x0, gravity = initial_states(study, full)
    libraries = _libraries(study, full["mu"], cache_dir, progress)
    p = _all_params(study, full["mu"], gravity)
    x_end = np.zeros_like(x0)
    summary = np.zeros((len(SUMMARY), n))
    for friction, idx in _tasks(full, study.batch):
        x_end[:, idx], summary[:, idx] = run_batch(libraries[friction], x0[:, idx],
                                                   p[friction][:, idx], study.scene.dt, threads)
    return classify(summary, x_end, gravity, x0, study.limits, len(study.scene.legs))


def _run_dask(study, tasks, libraries, x0, mu, p, x_end, summary, bar, scheduler,
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
        for k, (friction, idx) in enumerate(tasks):
            fut = client.submit(_dask_batch, str(Path(libraries[friction]).resolve()),
                                _scene_data(study, friction, mu), study.source, cache,
                                x0[:, idx], p[friction][:, idx], study.scene.dt,
                                key=f"envelope-{study.name}-{study.seed}-{k}-{os.getpid()}-"
                                    f"{time.monotonic_ns()}")
            futures[fut] = idx
        for fut in as_completed(futures):
            idx = futures[fut]
            xe, sm = fut.result()
            x_end[:, idx], summary[:, idx] = xe, sm
            bar.update(len(idx))
        compute = time.perf_counter() - bar.started
        n_workers = len(client.scheduler_info().get("workers", {}))
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
    return {"scheduler": scheduler or "LocalCluster", "workers": n_workers,
            "startup_seconds": round(startup, 3), "compute_seconds": compute}


def write_result(result: EnvelopeResult, out_dir, plots: bool = True) -> dict:
    """Write ``cases.csv``, ``summary.json`` and (with ``plots``) the figures into ``out_dir``."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    files = {"cases": out / "cases.csv", "summary": out / "summary.json"}
    files["cases"].write_text(result.csv_text())
    if plots:
        files.update(plot_envelope(result, out))
    result.files = files
    files["summary"].write_text(json.dumps(result.summary(), indent=1))
    return files


# ---------------------------------------------------------------------------
# plots
# ---------------------------------------------------------------------------
#: Colours of the outcome classes in the plots.
_COLOURS = {"stable": "#b8c4cc", "tip_over": "#d62728", "stroke": "#ff7f0e",
            "deflection": "#9467bd", "deceleration": "#1f77b4", "rebound": "#2ca02c",
            "no_touchdown": "#000000"}
#: Heading bins of the boundary plot: direction of travel against the fall line (deg).
_HEADINGS = (("downhill", 0.0, 45.0), ("across", 45.0, 135.0), ("uphill", 135.0, 180.0))


def _logistic_fit(a, b, y, ridge=LOGISTIC_RIDGE, iterations=50):
    """Quadratic logistic regression of y on (a, b) by Newton's method with a ridge.

    Returns a function P(a, b), or None when the classes are too few to fit.
    """
    if min(np.sum(y), np.sum(~y)) < 5:
        return None
    ma, sa = a.mean(), a.std() or 1.0
    mb, sb = b.mean(), b.std() or 1.0

    def features(a_, b_):
        u, v = (a_ - ma) / sa, (b_ - mb) / sb
        return np.column_stack([np.ones_like(u), u, v, u * u, v * v, u * v])

    X = features(a, b)
    w = np.zeros(X.shape[1])
    penalty = ridge * len(y) * np.diag([0.0] + [1.0] * (X.shape[1] - 1))
    for _ in range(iterations):
        prob = 1 / (1 + np.exp(-np.clip(X @ w, -30, 30)))
        grad = X.T @ (prob - y) + penalty @ w
        hess = X.T @ (X * (prob * (1 - prob))[:, None]) + penalty
        step = np.linalg.solve(hess, grad)
        w -= step
        if np.max(np.abs(step)) < 1e-10:
            break
    return lambda a_, b_: 1 / (1 + np.exp(-np.clip(features(a_, b_) @ w, -30, 30)))


def _heading_from_fall_line(heading_deg):
    """|heading| folded to [0°, 180°]: 0 downhill, 180 uphill."""
    return np.abs((np.asarray(heading_deg) + 180.0) % 360.0 - 180.0)


def plot_envelope(result: EnvelopeResult, out_dir) -> dict:
    """Write the envelope figures; return their paths by kind.

    * ``<name>.png``: the stability boundary in the (horizontal speed,
      vertical speed) plane, one panel per slope bin (columns) and heading
      bin (rows: travelling downhill, across, uphill). Cases are dots coloured
      by class; the line is P(stable) = 0.5 of a quadratic logistic
      regression fitted to the panel's cases (with a small ridge,
      :data:`LOGISTIC_RIDGE`), drawn where both outcomes occur.
    * ``<name>_pstable.png``: P(stable) against slope with Wilson intervals
      (:data:`CONFIDENCE`), overall and per heading bin.
    * ``<name>_distributions.png``: histograms of peak deceleration, largest
      stroke and largest tilt, with the limits.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    st = result.study
    c, col = result.conditions, result.columns
    name = _safe(st.name)
    files = {}
    cls = col["class"]
    stable = col["stable"]
    vh, vv = c["horizontal_speed"], c["vertical_speed"]
    slope = c["slope_deg"]
    heading = _heading_from_fall_line(c["heading_deg"])
    slope_bins = _slope_bins(slope)
    heading_bins = _HEADINGS if np.ptp(heading) > 0 and np.ptp(vh) > 0 else (("all", 0, 180),)

    # 1. boundary panels
    nr, nc = len(heading_bins), len(slope_bins)
    fig, axes = plt.subplots(nr, nc, figsize=(3.6 * nc + 1.2, 3.0 * nr + 0.8), squeeze=False,
                             sharex=True, sharey=True)
    for r, (hname, h_lo, h_hi) in enumerate(heading_bins):
        for k, (s_lo, s_hi) in enumerate(slope_bins):
            ax = axes[r, k]
            sel = (heading >= h_lo) & (heading <= h_hi) & (slope >= s_lo) & (slope <= s_hi)
            for label in CLASSES:
                m = sel & (cls == label)
                if np.any(m):
                    ax.scatter(vh[m], vv[m], s=4 if label == "stable" else 7,
                               c=_COLOURS[label], lw=0, label=label.replace("_", "-"))
            fit = _logistic_fit(vh[sel], vv[sel], stable[sel]) if np.sum(sel) > 20 else None
            if fit is not None:
                ga, gb = np.meshgrid(np.linspace(vh.min(), vh.max(), 120),
                                     np.linspace(vv.min(), vv.max(), 120))
                prob = fit(ga.ravel(), gb.ravel()).reshape(ga.shape)
                if prob.min() < 0.5 < prob.max():
                    ax.contour(ga, gb, prob, levels=[0.5], colors="k", linewidths=1.2)
            k_s, n_s = int(np.sum(stable[sel])), int(np.sum(sel))
            est, lo, hi = wilson_interval(k_s, n_s)
            title = f"slope {s_lo:.0f}–{s_hi:.0f}°" if nc > 1 or s_hi > s_lo else \
                f"slope {s_lo:.0f}°"
            if len(heading_bins) > 1:
                title += f", {hname}"
            ax.set_title(f"{title}\nP(stable) = {est:.2f} [{lo:.2f}, {hi:.2f}], n = {n_s}",
                         fontsize=8)
            if r == nr - 1:
                ax.set_xlabel("horizontal speed (m/s)")
            if k == 0:
                ax.set_ylabel("vertical speed (m/s)")
    handles = {}
    for ax in axes.ravel():
        for h, lab in zip(*ax.get_legend_handles_labels()):
            handles.setdefault(lab, h)
    fig.legend(list(handles.values()), list(handles.keys()), loc="lower center",
               ncol=len(handles), fontsize=8, markerscale=2, frameon=False)
    fig.suptitle(f"{st.name}: outcome of {result.n:,} touchdowns; line: P(stable) = 0.5 "
                 "(quadratic logistic fit)", fontsize=10)
    fig.tight_layout(rect=(0, 0.05, 1, 0.96))
    files["boundary"] = out / f"{name}.png"
    fig.savefig(files["boundary"], dpi=110)
    plt.close(fig)

    # 2. P(stable) against slope
    fig, ax = plt.subplots(figsize=(6, 4))
    edges = np.linspace(slope.min(), slope.max(), 7) if np.ptp(slope) > 0 else \
        np.array([slope.min() - 0.5, slope.max() + 0.5])
    centres = 0.5 * (edges[:-1] + edges[1:])
    groups = [("all headings", np.ones_like(stable, bool))]
    if len(heading_bins) > 1:
        groups += [(hname, (heading >= lo) & (heading <= hi)) for hname, lo, hi in heading_bins]
    rows = []
    for g_i, (gname, gsel) in enumerate(groups):
        idx = np.clip(np.digitize(slope, edges[1:-1]), 0, len(centres) - 1)
        k = np.array([np.sum(stable[gsel & (idx == b)]) for b in range(len(centres))])
        n = np.array([np.sum(gsel & (idx == b)) for b in range(len(centres))])
        est, lo, hi = wilson_interval(k, n)
        offset = (g_i - (len(groups) - 1) / 2) * 0.08 * (edges[1] - edges[0])
        ax.errorbar(centres + offset, est, yerr=[est - lo, hi - est], marker="o", ms=4,
                    capsize=3, lw=2 if g_i == 0 else 1, label=gname)
        rows += [(gname, float(a), float(b), int(kk), int(nn), float(e), float(lw), float(hg))
                 for a, b, kk, nn, e, lw, hg in zip(edges[:-1], edges[1:], k, n, est, lo, hi)]
    ax.set_xlabel("slope (deg)")
    ax.set_ylabel(f"P(stable), {CONFIDENCE:.0%} Wilson interval")
    ax.set_ylim(-0.02, 1.02)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title(f"{st.name}: P(stable) by slope", fontsize=10)
    fig.tight_layout()
    files["pstable"] = out / f"{name}_pstable.png"
    fig.savefig(files["pstable"], dpi=110)
    plt.close(fig)
    table = ["heading,slope_lo_deg,slope_hi_deg,stable,cases,p,low,high"]
    table += [f"{g},{a:.4g},{b:.4g},{k},{n},{e:.4f},{lw:.4f},{hg:.4f}"
              for g, a, b, k, n, e, lw, hg in rows]
    files["pstable_csv"] = out / f"{name}_pstable.csv"
    files["pstable_csv"].write_text("\n".join(table) + "\n")

    # 3. distributions
    lim = st.limits
    panels = (("peak_decel", "peak deceleration |a − g| (m/s²)", lim.deceleration),
              ("max_stroke", "largest axial stroke (m)", lim.stroke),
              ("max_tilt_deg", "largest tilt from the vertical (deg)", lim.tilt_deg))
    fig, axes = plt.subplots(1, 3, figsize=(13, 3.6))
    for ax, (key, label, limit) in zip(axes, panels):
        values = col[key]
        bins = np.linspace(values.min(), values.max(), 50) if np.ptp(values) > 0 else 10
        ax.hist(values[stable], bins=bins, color=_COLOURS["stable"], label="stable")
        ax.hist(values[~stable], bins=bins, color="#d62728", alpha=0.6, label="not stable")
        if limit is not None:
            ax.axvline(limit, color="k", ls="--", lw=1, label="limit")
        ax.set_xlabel(label)
        ax.set_ylabel("cases")
        ax.legend(fontsize=8)
    fig.suptitle(f"{st.name}: distributions over {result.n:,} cases", fontsize=10)
    fig.tight_layout()
    files["distributions"] = out / f"{name}_distributions.png"
    fig.savefig(files["distributions"], dpi=110)
    plt.close(fig)
    return files
