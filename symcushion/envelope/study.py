"""The envelope study file: its schema, checks and the study objects.

Owns :data:`VARIABLES` (the touchdown conditions a study may sample), the
:class:`Range` of each, the :class:`Limits` a case is judged against and
:class:`EnvelopeStudy`, read from TOML by :func:`load_study` with every field
checked (file, field path, bad value, what is allowed). It must not sample,
simulate or classify.
"""
from __future__ import annotations

import dataclasses
import json
import math
import statistics
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from symcushion.model.obstacles import Plane
from symcushion.model.scene import read_toml, scene_from_dict
from symcushion.validation import Table
from symcushion.model.scene_data import Scene
from symcushion.envelope.sampling import MAX_SOBOL_DIMENSIONS, sample_unit

__all__ = ["VARIABLES", "MAX_SLOPE_DEG", "DEFAULT_BATCH", "DEFAULT_CLEARANCE", "DEFAULT_REST_SPEED",
           "Range", "Limits",
           "EnvelopeStudy", "study_from_dict", "load_study", "sample_conditions"]

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
CONDITION_DEFAULTS = {"horizontal_speed": 0.0, "heading_deg": 0.0, "slope_deg": 0.0, "yaw_deg": 0.0,
             "tilt_deg": 0.0, "tilt_azimuth_deg": 0.0}
#: Slopes above this are refused: the lowest-foot placement and the legs'
#: geometry are not meant for cliffs (and gravity would pull along the ground).
MAX_SLOPE_DEG = 60.0
#: Cases per batch (one ``map`` call or one Dask task): at ~5 ms per 2-s
#: case a batch takes about half a second, long against a task's overhead
#: (~1 ms) and short enough for a smooth progress line.
DEFAULT_BATCH = 100
#: Default lowest-foot clearance at t = 0 (m): touchdown within a few ms.
DEFAULT_CLEARANCE = 1e-3
#: Default `limits.rest_speed` (m/s): a case that is upright and within every
#: limit but whose body still moves this fast at the end has not come to rest
#: and is not counted as stable (class ``moving``). 5 cm/s: a settled lander
#: creeps by far less (its feet stick), a rocking or sliding one by far more.
DEFAULT_REST_SPEED = 0.05


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
    rest_speed : float
        At rest at the end: no point of the body within reach of its feet
        moves faster than this, |v| + |ω|·reach ≤ ``rest_speed`` (m/s), where
        reach is the largest distance of a foot at rest from the centre of
        mass. Default :data:`DEFAULT_REST_SPEED`; None leaves the check out.
    """

    stroke: float | None = None
    beta: float | None = None
    gamma: float | None = None
    tilt_deg: float | None = None
    deceleration: float | None = None
    rebound_speed: float | None = None
    rest_speed: float | None = None

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
        if all(getattr(self, f.name) is None for f in dataclasses.fields(self)
               if f.name != "rest_speed"):
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
    stop : bool
        Stop each case once its class is decided: tipped over, or at rest
        (:func:`~symcushion.envelope.cases.study_stop`); False runs every case
        for the whole duration. Classes are the same either way; the measures
        of a stopped case are those up to its stop (``end_time``).
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
    stop: bool = True
    description: str = ""
    source: str = ""
    scene_data: dict | None = None

    def with_(self, **changes) -> "EnvelopeStudy":
        """A copy with some fields replaced, e.g. ``study.with_(n=200, seed=1)``."""
        new = dataclasses.replace(self, **changes)
        check_counts(new)
        return new


def sample_conditions(study: EnvelopeStudy) -> dict:
    """The sampled touchdown conditions: a dict of arrays of shape (n,), by
    :data:`VARIABLES`; each random range takes the next column of the study's
    points in the unit cube, a fixed one its value."""
    dim = sum(r.random for r in study.ranges.values())
    u = sample_unit(study.method, study.n, dim, study.seed)
    out, col = {}, 0
    for name in VARIABLES:
        r = study.ranges[name]
        if r.random:
            out[name] = r.transform(u[:, col])
            col += 1
        else:
            out[name] = r.transform(np.zeros(study.n))
    return out


def check_counts(study):
    for name in ("n", "batch"):
        value = getattr(study, name)
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
            raise ValueError(f"`{name}` must be a positive integer, got {value!r}.")
    if isinstance(study.seed, bool) or not isinstance(study.seed, (int, np.integer)) \
            or study.seed < 0:
        raise ValueError(f"`seed` must be a non-negative integer, got {study.seed!r}.")
    if study.method not in ("sobol", "random"):
        raise ValueError(f"`method` must be 'sobol' or 'random', got {study.method!r}.")


class _Fields(Table):
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
    stop = st.data.get("stop_decided", True)
    st.used.add("stop_decided")
    if not isinstance(stop, bool):
        raise st.error("stop_decided", stop, "true (stop each case once its class is decided) "
                       "or false (run every case for the whole duration)")
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
            ranges[var] = Range("fixed", value=CONDITION_DEFAULTS[var])
        _check_range(var, ranges[var], source)
    ra.finish()

    li = top.get("limits", kind="table")
    try:
        rest = li.data.get("rest_speed", DEFAULT_REST_SPEED)
        li.used.add("rest_speed")
        if rest is False:
            rest = None
        elif isinstance(rest, bool) or not isinstance(rest, (int, float)) or not rest > 0:
            raise li.error("rest_speed", rest, "a speed > 0 in m/s, or false to leave the "
                           "at-rest check out")
        limits = Limits(**{k: li.get(k, None, positive=True) for k in
                           ("stroke", "beta", "gamma", "deceleration", "rebound_speed")},
                        tilt_deg=li.angle("tilt", None, unit="deg", positive=True),
                        rest_speed=rest)
    except ValueError as exc:
        message = str(exc)      # a field's own message names the file already
        raise ValueError(message if message.startswith(f"{source}: ")
                         else f"{source}: {message}") from None
    li.finish()
    top.finish()
    study = EnvelopeStudy(name=name, scene=scene, n=n, seed=seed, method=method, ranges=ranges,
                          limits=limits, clearance=clearance, batch=batch, stop=stop,
                          description=description, source=source,
                          scene_data=json.loads(json.dumps(scene_raw)))
    dim = sum(r.random for r in ranges.values())
    if method == "sobol" and dim > MAX_SOBOL_DIMENSIONS:
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
