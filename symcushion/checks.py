"""Physical sanity of a valid scene, before and during a run.

A scene whose every field is well-formed (``symcushion.validation``) can still
describe nonsense: a body that starts inside the dome, feet off a terrain
grid, a surface formula that is NaN where the feet go, a step above the
explicit stability limit. This module owns those checks:

* :func:`check_scene` — every check before the run, as a list of
  :class:`Finding` (``severity`` "error" or "warning"); nothing is simulated.
* :func:`preflight` — raises :class:`~symcushion.validation.SceneError` on
  errors (and on warnings with ``strict``), else emits each warning as a
  :class:`PhysicsWarning`.
* :func:`check_file` — the checks of a parsed scene, envelope, design or
  optimise study file (``symcushion check``): its fields, then every scene
  it describes at the state it starts from.
* the checks *during* a run live in ``symcushion.monitor``
  (:class:`~symcushion.monitor.RunMonitor`, also importable from here); they
  share :class:`Finding` and the geometry helpers of this module.

It only inspects: it never changes a scene, a state or a step, and it does
not drive the simulation (``symcushion.driver`` does, and calls it).
docs/checks.md lists every check with its tolerance and its test.
"""
from __future__ import annotations

import warnings
from dataclasses import asdict, dataclass

import casadi as ca
import numpy as np

from .obstacles import ImplicitSurface, Terrain, closest_obstacle
from .scene import Scene
from .layout import state_layout
from .stability import stable_dt
from .strut import SINGULAR_ANGLE
from .touchdown import build_model, initial_state
from .validation import SceneError

__all__ = ["Finding", "PhysicsWarning", "check_scene", "preflight", "check_file", "file_kind",
           "START_TOLERANCE", "BODY_TOLERANCE", "REACH_FRACTIONS", "SAMPLE_DIRECTIONS",
           "FD_STEP", "GRADIENT_TOLERANCE", "FAST_STEP_FRACTION", "DT_ERROR_RATIO",
           "FOOTPAD_FRACTION"]

#: How far (m) a foot may start below an obstacle's surface. A scene that puts
#: the feet exactly on the surface (Figs. 3–4) computes that height in
#: decimal and lands within ~1e-16 m; 1 µm is far above that round-off and
#: far below any depth that gives a visible spring kick.
START_TOLERANCE = 1e-6

#: How deep the body centre may be below a surface, in units of the shortest
#: leg. The body has no collision shape (only the feet touch), and a flat sled
#: rests with its centre at its feet's plane (1 mm below it on 0.5 m legs in
#: tests/test_simulate.py); 5 % of a leg (3 cm on Fig. 3) separates that from
#: a body that starts in, or sinks into, the obstacle.
BODY_TOLERANCE = 0.05

#: Radii of the sample shells around each hinge, in units of the leg length:
#: a foot cannot leave the ball of radius L₀ about its hinge by more than its
#: axial stroke, so 1.25 L₀ covers the reachable region with margin.
REACH_FRACTIONS = (0.25, 0.5, 0.75, 1.0, 1.25)
#: Directions per shell (a Fibonacci sphere): 64 keeps the largest gap between
#: neighbouring samples below 0.3 rad, i.e. 0.2 m on a 0.6 m leg.
SAMPLE_DIRECTIONS = 64
#: Central-difference step for the differentiability check, in units of L₀.
#: 1e-6 L₀ balances truncation (h²) against round-off (eps/h) near 1e-10.
FD_STEP = 1e-6
#: Largest relative disagreement between ∇φ by AD and by central differences
#: at a sample before φ counts as not differentiable there; a smooth φ agrees
#: to about 1e-8, a kink or a vertical tangent (sqrt at 0) by O(1).
GRADIENT_TOLERANCE = 1e-3

#: A foot that travels more than this fraction of the shortest leg per step
#: at the initial speed crosses most of its stroke in a few steps: the
#: touchdown is under-resolved (a warning; 5 % of L₀ is 3 cm on Fig. 3 legs).
FAST_STEP_FRACTION = 0.05

#: Ratio dt/stable_dt above which the step is an error rather than a warning.
#: ``stable_dt`` holds every foot fixed; a sliding foot (above all a
#: frictionless one) resists along the normal only, which can soften the
#: stiffest mode: Fig. 3 (μ = 0) runs stably at 1.4× the estimate. Past 10×
#: (ω Δt = 20) the effective stiffness would have to be 100 times below the
#: held one for the step to be stable.
DT_ERROR_RATIO = 10.0

#: A footpad whose radius exceeds this fraction of its leg's rest length is a
#: warning: twice the Apollo LM's ratio (0.47 m pads on primaries of about
#: 3.8 m, 1/8). Beyond it what the offset-surface model neglects (the pad's
#: tilt, its contact patch, the moment of the contact point's offset) is a
#: large share of the leg's geometry (docs/footpads.md).
FOOTPAD_FRACTION = 0.25

class PhysicsWarning(UserWarning):
    """A physically doubtful scene or run (see docs/checks.md)."""


@dataclass
class Finding:
    """One result of a check.

    Attributes
    ----------
    kind : str
        Name of the check (``"foot_inside"``, ``"dt_unstable"``, ... docs/checks.md).
    message : str
        What is wrong, the value and the fix.
    severity : {'error', 'warning'}
    time : float, optional
        Simulated time of the first occurrence (s), run-time checks only.
    leg : int, optional
        Index of the leg concerned.
    value : float, optional
        The offending number (a depth in m, a ratio, ...).
    field : str, optional
        The scene field to change (``scene.dt``, ``body.position``).
    """

    kind: str
    message: str
    severity: str
    time: float | None = None
    leg: int | None = None
    value: float | None = None
    field: str | None = None

    def __post_init__(self):
        if self.severity not in ("error", "warning"):
            raise ValueError(f"`severity` must be 'error' or 'warning', got {self.severity!r}.")

    def to_dict(self) -> dict:
        """A JSON-ready dict (floats, ints, strings and None)."""
        return asdict(self)


# ---------------------------------------------------------------------------
# helpers
# ---------------------------------------------------------------------------
#: A foot's smallest rest stiffness, as a fraction of its largest, below which a
#: frictionless scene is refused (``free_direction``): 1e-9 is far below any
#: leg's ratio of bending to axial stiffness (1e-3 for a rigid rod) and far above
#: round-off of a missing element's zero.
FREE_DIRECTION_RATIO = 1e-9


def _rotations(q):
    """Rotation matrices, shape (n, 3, 3), of unit quaternions q, shape (4, n)."""
    q = q / np.linalg.norm(q, axis=0)
    w, x, y, z = q
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1)], 1)


def _distances(scene: Scene, points, pad: float = 0.0) -> np.ndarray:
    """Signed distance, shape (len(obstacles), n), of world points, shape (3, n); with
    ``pad`` a, the clearance of footpads of radius a centred there."""
    p = ca.SX.sym("p", 3)
    fn = ca.Function("obstacle_distance", [p], [ca.vertcat(*[o.distance(p, pad)
                                                              for o in scene.obstacles])],
                     ["p"], ["d"])
    return np.asarray(fn(np.asarray(points, float)), dtype=float).reshape(
        len(scene.obstacles), -1)


def _world_points(scene: Scene, X):
    """Body centre (3, n), hinges (N, 3, n) and feet (N, 3, n) of states X (nx, n)."""
    xl = state_layout(len(scene.legs))
    R = _rotations(xl.get(X, "attitude"))
    pos = xl.get(X, "position")
    hinges = np.stack([pos + np.einsum("nij,j->in", R, leg.hinge) for leg in scene.legs])
    feet = xl.legs(X, "foot")
    return pos, hinges, feet


def _where(scene, k):
    ob = scene.obstacles[k]
    return f"obstacle[{k}] ({ob.kind})"


def _fibonacci_sphere(n):
    i = np.arange(n) + 0.5
    polar = np.arccos(1 - 2 * i / n)
    azimuth = np.pi * (1 + 5 ** 0.5) * i
    return np.stack([np.cos(azimuth) * np.sin(polar), np.sin(azimuth) * np.sin(polar),
                     np.cos(polar)])


# ---------------------------------------------------------------------------
# before the run
# ---------------------------------------------------------------------------
def check_scene(scene: Scene, model=None, x0=None) -> list:
    """Every check before the run (nothing is simulated).

    Parameters
    ----------
    scene : Scene
    model : StepModel, optional
        Built by ``build_model(scene)`` if not given (needed for ``stable_dt``).
    x0 : array_like, shape (nx,), optional
        Initial state to check; default ``initial_state(scene)``.

    Returns
    -------
    list of Finding
        Errors first, then warnings. Zero gravity is valid and gives none.
    """
    if not isinstance(scene, Scene):
        raise TypeError(f"`scene` must be a Scene (load_scene('x.toml')), got "
                        f"{type(scene).__name__}.")
    x0 = initial_state(scene) if x0 is None else np.asarray(x0, dtype=float).ravel()
    findings = []
    findings += _check_start(scene, x0)
    findings += _check_footpads(scene)
    findings += _check_terrain(scene, x0)
    findings += _check_surfaces(scene, x0)
    findings += _check_curves(scene)
    findings += _check_buckling(scene)
    findings += _check_free_directions(scene, x0)
    findings += _check_damping_times(scene)
    findings += _check_time_step(scene, model, x0)
    return sorted(findings, key=lambda f: f.severity != "error")


def _check_start(scene, x0):
    out = []
    pos, hinges, feet = _world_points(scene, x0[:, None])
    d_body = _distances(scene, pos)[:, 0]
    allowed = BODY_TOLERANCE * min(leg.length for leg in scene.legs)
    for k in np.flatnonzero(d_body < -allowed):
        out.append(Finding("body_inside", f"`body.position`: the body centre starts "
                           f"{-d_body[k]:.3g} m inside {_where(scene, k)} (tolerance "
                           f"{allowed:.3g} m); move the body out of the obstacle.", "error",
                           value=float(-d_body[k]),
                           field="body.position"))
    for j, leg in enumerate(scene.legs):
        d_foot = _distances(scene, feet[j], leg.footpad)[:, 0]
        d_hinge = _distances(scene, hinges[j])[:, 0]
        k = int(np.argmin(d_foot))
        if d_foot[k] < -START_TOLERANCE:
            what = f"the footpad of leg {j}" if leg.footpad > 0 else f"foot of leg {j}"
            out.append(Finding("foot_inside", f"`body.position`: {what} starts "
                               f"{-d_foot[k]:.3g} m inside {_where(scene, k)} (tolerance "
                               f"{START_TOLERANCE:g} m); the leg would get a spring kick — raise "
                               "the body so the feet start on or above the surface.", "error",
                               leg=j, value=float(-d_foot[k]), field="body.position"))
        if np.min(d_hinge) < 0:
            k = int(np.argmin(d_hinge))
            out.append(Finding("hinge_inside", f"`body.position`: the hinge of leg {j} starts "
                               f"{-d_hinge[k]:.3g} m inside {_where(scene, k)}; move the body "
                               "out of the obstacle.", "error", leg=j,
                               value=float(-d_hinge[k]), field="body.position"))
    speed = float(np.linalg.norm(state_layout(len(scene.legs)).get(x0, "velocity")))
    shortest = min(leg.length for leg in scene.legs)
    if speed * scene.dt > FAST_STEP_FRACTION * shortest:
        out.append(Finding("fast_impact", f"`scene.dt`: at the initial speed {speed:.3g} m/s a "
                           f"foot moves {speed * scene.dt:.3g} m per step, more than "
                           f"{FAST_STEP_FRACTION:g} of the shortest leg ({shortest:g} m); the "
                           "touchdown is under-resolved — reduce `dt`.", "warning",
                           value=speed * scene.dt / shortest, field="scene.dt"))
    return out


def _check_footpads(scene):
    """A footpad larger than :data:`FOOTPAD_FRACTION` of its leg (a warning)."""
    out = []
    for j, leg in enumerate(scene.legs):
        ratio = leg.footpad / leg.length
        if ratio > FOOTPAD_FRACTION:
            out.append(Finding(
                "footpad_large", f"`legs[{j}].footpad` = {leg.footpad:g} m is {ratio:.3g} of "
                f"the leg's rest length {leg.length:g} m (more than {FOOTPAD_FRACTION:g}): the "
                "pad is modelled as a ball about the foot that does not tilt, and its contact "
                "patch and the moment of the contact point's offset are neglected — check the "
                "radius (m, not the diameter) or accept the model's limits (docs/footpads.md).",
                "warning", leg=j, value=ratio, field=f"legs[{j}].footpad"))
    return out


def _check_terrain(scene, x0):
    """Policy: a foot off a terrain's grid is an error (the height there is not data)."""
    out = []
    _, _, feet = _world_points(scene, x0[:, None])
    for k, ob in enumerate(scene.obstacles):
        if not isinstance(ob, Terrain):
            continue
        xs, ys = ob.grid
        for j in range(len(scene.legs)):
            fx, fy = feet[j, 0, 0], feet[j, 1, 0]
            if not (xs[0] <= fx <= xs[-1] and ys[0] <= fy <= ys[-1]):
                out.append(Finding(
                    "off_terrain", f"`obstacle[{k}]`: foot of leg {j} starts at (x, y) = "
                    f"({fx:.3g}, {fy:.3g}) m, off the terrain grid x ∈ [{xs[0]:g}, {xs[-1]:g}], "
                    f"y ∈ [{ys[0]:g}, {ys[-1]:g}]; extend the grid or move the body over it.",
                    "error", leg=j, field=f"obstacle[{k}]"))
    return out


def _check_surfaces(scene, x0):
    """φ and ∇φ finite, and ∇φ equal to central differences, around every hinge."""
    out = []
    _, hinges, _ = _world_points(scene, x0[:, None])
    directions = _fibonacci_sphere(SAMPLE_DIRECTIONS)
    for k, ob in enumerate(scene.obstacles):
        if not isinstance(ob, ImplicitSurface) or isinstance(ob, Terrain):
            continue
        phi, grad = ob.functions["phi"], ob.functions["grad_phi"]
        for j, leg in enumerate(scene.legs):
            shells = [hinges[j] + r * leg.length * directions for r in REACH_FRACTIONS]
            pts = np.concatenate(shells, axis=1)
            finding = _sample_surface(k, j, phi, grad, pts, FD_STEP * leg.length)
            if finding is not None:
                out.append(finding)
                break                 # one finding per surface
    return out


def _sample_surface(k, j, phi, grad, pts, h):
    with np.errstate(all="ignore"):
        values = np.asarray(phi(pts), dtype=float).ravel()
        g = np.asarray(grad(pts), dtype=float).reshape(3, -1)
        bad = ~np.isfinite(values) | ~np.all(np.isfinite(g), axis=0)
        if bad.any():
            p = pts[:, np.argmax(bad)]
            return Finding("surface_not_finite", f"`obstacle[{k}].phi` is not finite (or its "
                           f"gradient is not) at {np.round(p, 4).tolist()} m, within reach of "
                           f"leg {j}; {int(bad.sum())} of {bad.size} samples fail — use a "
                           "formula defined everywhere near the feet (e.g. sqrt(x**2 + 1e-6) "
                           "for sqrt(x)).", "error", leg=j, field=f"obstacle[{k}].phi")
        fd = np.stack([(np.asarray(phi(pts + h * e[:, None])).ravel()
                        - np.asarray(phi(pts - h * e[:, None])).ravel()) / (2 * h)
                       for e in np.eye(3)])
        err = np.linalg.norm(fd - g, axis=0) / np.maximum(np.linalg.norm(g, axis=0), 1.0)
    if np.all(np.isfinite(err)) and np.max(err) <= GRADIENT_TOLERANCE:
        return None
    i = int(np.nanargmax(np.where(np.isfinite(err), err, np.inf)))
    return Finding("surface_not_smooth", f"`obstacle[{k}].phi` is not differentiable near "
                   f"{np.round(pts[:, i], 4).tolist()} m (within reach of leg {j}): its gradient "
                   f"differs from central differences by {err[i]:.2g} (tolerance "
                   f"{GRADIENT_TOLERANCE:g}); the contact normal jumps there — smooth the "
                   "formula.", "warning", leg=j, value=float(err[i]), field=f"obstacle[{k}].phi")


#: Deflection range sampled for the slope check: ± the leg length for the
#: axial element (m), ± a quarter turn for the hinge elements (rad).
_SLOPE_SAMPLES = 81


def _check_free_directions(scene, x0):
    """At μ = 0 a foot loaded across its leg needs stiffness in every direction: the
    frictionless contact step slides the foot along the tangent plane by K⁻¹p, and a
    direction the leg does not resist (a missing or flat hinge spring) leaves it no
    solution, so the foot lifts off and the body falls through the obstacle. A leg along
    the obstacle's normal carries no load across it and is left alone."""
    if scene.mu > 0:
        return []
    out = []
    R = _rotations(state_layout(len(scene.legs)).get(x0, "attitude")[:, None])[0]
    _, _, feet = _world_points(scene, np.asarray(x0, float)[:, None])
    for j, leg in enumerate(scene.legs):
        D = leg.rest_stiffness_closed_form()
        values, vectors = np.linalg.eigh(0.5 * (D + D.T))
        _, normal, _ = closest_obstacle(scene.obstacles, ca.DM(feet[j, :, 0]))
        across = np.linalg.norm(np.cross(R @ leg.e0, np.asarray(normal, float).ravel()))
        if across > np.sin(SINGULAR_ANGLE) and \
                values[0] <= FREE_DIRECTION_RATIO * max(values[-1], 0.0):
            missing = [name for name in ("M_beta", "M_gamma")
                       if name not in {el.name for el in leg.elements}]
            why = (f"it has no {' or '.join(f'`{m}`' for m in missing)}" if missing
                   else "its hinge springs are flat at rest")
            out.append(Finding(
                "free_direction", f"leg {j}: at mu = 0 its foot has no stiffness along "
                f"{np.round(vectors[:, 0], 3).tolist()} (body axes) at rest — {why} — so the "
                "frictionless contact step cannot hold it and the body falls through the "
                "obstacle; give the leg both hinge springs (`M_beta`, `M_gamma`) or set mu > 0.",
                "error", leg=j, value=float(values[0]), field=f"legs[{j}]"))
    return out


#: Largest spread of a leg's damping times c/k (the largest over the smallest) that
#: keeps its damped foot's step stiffness close to the shape of its elastic one.
DAMPING_TIME_SPREAD = 3.0


def _check_damping_times(scene):
    """With friction, a leg whose elements are damped with very different time constants
    c/k (say the axial element alone) gives its massless foot a step stiffness of
    another shape than its elastic one; near the friction cone's edge the slip Coulomb's
    law asks for may then push the force out of the cone, and the foot hops
    (docs/absorbers.md, "Dampers on every element")."""
    if scene.mu == 0 or scene.hysteresis != "memory":
        return []
    out = []
    for j, leg in enumerate(scene.legs):
        times = {}
        for el in leg.elements:
            k = abs(float(el.curve.slope(0.0)))
            if k > 0:
                times[el.name] = el.curve.damping / k
        damped = [t for t in times.values() if t > 0]
        if not damped:
            continue
        low, high = min(times.values()), max(times.values())
        if low == 0 or high / low > DAMPING_TIME_SPREAD:
            shown = ", ".join(f"{name} {1e3 * t:.3g} ms" for name, t in times.items())
            out.append(Finding(
                "damping_times", f"leg {j}: its elements' damping times c/k differ ({shown}); "
                "a sliding foot behind dampers of unlike time constants can hop; give every "
                "element of the leg the same c/k (docs/absorbers.md, \"Dampers on every "
                "element\").", "warning", leg=j, value=high / max(low, 1e-300),
                field=f"legs[{j}]"))
    return out


def _axial_load(scene, leg) -> tuple[float, str]:
    """The axial force (N) a leg's strut is sure to carry, and what it is: the crush
    force of a crushable element S (it carries it whenever it crushes), else the
    leg's share of the weight m|g|/legs (it carries that at rest)."""
    weight = scene.body.mass * float(np.linalg.norm(scene.gravity)) / len(scene.legs)
    axial = next((el for el in leg.elements if el.name == "S"), None)
    names = getattr(axial.curve, "param_names", ()) if axial is not None else ()
    if "crush_force" in names:
        crush = float(axial.curve.param_values[names.index("crush_force")])
        if crush > weight:
            return crush, "its crush force"
    return weight, "its share of the weight"


def _check_buckling(scene):
    """The stiffness D_p of a strut (2.1) on hinge springs has, across the strut, the
    springs' k/L² less the axial force over the length, f_S/L (the turning of e_S under
    a compressive f_S; (2.3)). Where f_S/L exceeds k/L² D_p is indefinite: the straight
    leg would fold (an Euler column with a rotational spring, P·L > k), and the contact
    step, which solves P₀ + D_p δ on the plane (1.3), finds no compressive state and
    releases the foot: it lifts off with the foot inside the ground. With the memory
    law D_p keeps the loading branch's crush force after the leg unloads, so the
    refusal goes by the crush force (docs/checks.md)."""
    out = []
    for j, leg in enumerate(scene.legs):
        names = {el.name: el for el in leg.elements}
        if not {"M_beta", "M_gamma"} <= set(names):
            continue                         # a tripod: no hinge springs to fold about
        k = min(abs(float(names[n].curve.slope(0.0, 0.0))) for n in ("M_beta", "M_gamma"))
        load, what = _axial_load(scene, leg)
        if k < load * leg.length:
            out.append(Finding(
                "leg_buckles", f"leg {j}: its weaker hinge spring (k = {k:.4g} N·m/rad at "
                f"rest) gives k/L² = {k / leg.length ** 2:.4g} N/m across the strut, below "
                f"the axial force over the length, S/L = {load / leg.length:.4g} N/m ({what}, "
                f"{load:.4g} N): loaded off its axis the leg would fold, and the contact "
                "step, which cannot fold a massless leg, lifts its foot off inside the "
                f"ground instead; stiffen `M_beta` and `M_gamma` to at least "
                f"{load * leg.length:.4g} N·m/rad or lower the axial force.", "warning",
                leg=j, value=k / leg.length ** 2,
                field=f"legs[{j}].M_beta"))
    return out


def _check_curves(scene):
    """Restoring curves: slope ≥ 0 at rest (error) and over the sampled range (warning)."""
    out = []
    for j, leg in enumerate(scene.legs):
        for el in leg.elements:
            extent = leg.element_extent(el.name)
            xs = np.linspace(-extent, extent, _SLOPE_SAMPLES)
            branches = [("loading", el.curve)]
            if el.curve.unloading is not None:
                branches.append(("unloading", el.curve.unloading))
            for branch, curve in branches:
                slopes = np.array([curve.slope(float(x)) if branch == "unloading" else
                                   curve.slope(float(x), 0.0) for x in xs])
                rest = slopes[_SLOPE_SAMPLES // 2]
                where = f"legs[{j}].{el.name}"
                hinge = "hinge stiffness" if el.name != "S" else "axial stiffness"
                if rest < 0:
                    out.append(Finding("negative_stiffness", f"`{where}`: the {branch} branch "
                                       f"has negative {hinge} {rest:.4g} at rest; the element "
                                       "pushes away from rest instead of restoring — give a "
                                       "curve with a non-negative slope at 0.", "error", leg=j,
                                       value=float(rest), field=where))
                elif np.min(slopes) < 0:
                    i = int(np.argmin(slopes))
                    out.append(Finding("negative_slope", f"`{where}`: the {branch} branch has "
                                       f"slope {slopes[i]:.4g} < 0 at deflection {xs[i]:.4g}; "
                                       "the element snaps through there (D_p indefinite) — "
                                       "check the knots.", "warning", leg=j,
                                       value=float(slopes[i]), field=where))
    return out


def _check_time_step(scene, model, x0):
    out = []
    if scene.dt > scene.duration:
        out.append(Finding("dt_above_duration", f"`scene.dt` = {scene.dt:g} s is longer than "
                           f"`scene.duration` = {scene.duration:g} s: the run would be one "
                           "step of dt; reduce `dt` or raise `duration`.", "error",
                           value=scene.dt / scene.duration, field="scene.dt"))
    model = build_model(scene) if model is None else model
    try:
        limit = stable_dt(model, x0)
    except FloatingPointError as exc:
        return out + [Finding("stiffness_not_finite", f"the legs' stiffness at the start is "
                              f"not finite ({exc}); check the leg geometry.", "error")]
    if scene.dt > limit:
        ratio = scene.dt / limit
        severity = "error" if ratio > DT_ERROR_RATIO else "warning"
        out.append(Finding("dt_unstable", f"`scene.dt` = {scene.dt:g} s is {ratio:.3g} times "
                           f"the stable step 2/ω_max = {limit:.3g} s of the stiffest leg mode "
                           "(feet held): the explicit body update may diverge — use dt ≤ "
                           f"{limit / 2:.3g} s (command line: --dt {limit / 2:.3g}), or cap "
                           "each step at the limit (command line: --stability; Python: "
                           "simulate(..., adaptive=True, stability=True)).",
                           severity, value=ratio, field="scene.dt"))
    return out


def preflight(scene: Scene, model=None, strict: bool = False, *, x0=None, ignore=()) -> list:
    """Run :func:`check_scene`; raise on errors, warn on warnings.

    Parameters
    ----------
    scene, model, x0
        As :func:`check_scene`.
    strict : bool
        Treat warnings as errors.
    ignore : sequence of str
        Kinds not to report (e.g. ``("dt_unstable",)`` when the driver caps
        the step at the stability limit itself).

    Returns
    -------
    list of Finding
        The warnings (when nothing was raised).

    Raises
    ------
    SceneError
        Listing every error (and, with ``strict``, every warning).
    """
    findings = [f for f in check_scene(scene, model, x0) if f.kind not in ignore]
    fatal = [f for f in findings if strict or f.severity == "error"]
    if fatal:
        raise SceneError(f"scene {scene.name!r}", [f"{f.severity}: {f.message}" for f in fatal])
    for f in findings:
        warnings.warn(f.message, PhysicsWarning, stacklevel=2)
    return findings


def __getattr__(name):
    # RunMonitor lives in symcushion.monitor, which imports this module; it is
    # offered here too (PEP 562) so that one import serves before and during a run.
    if name == "RunMonitor":
        from .monitor import RunMonitor
        return RunMonitor
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def file_kind(data: dict) -> str:
    """What a parsed TOML file is, from its tables: ``"scene"``, ``"envelope"``
    (``[ranges]``), ``"design"`` (``[ranges]`` and ``[design]``: design for the
    envelope) or ``"optimise"`` (``[design]`` alone)."""
    if not isinstance(data, dict):
        return "scene"
    if "ranges" in data:
        return "design" if "design" in data else "envelope"
    return "optimise" if "design" in data else "scene"


def check_file(data: dict, source: str, base_dir=".") -> tuple:
    """Check a parsed scene or study file: its fields, then the physics of its scenes.

    Parameters
    ----------
    data : dict
        The parsed TOML file.
    source : str
        Its name, for messages (``"<stdin>"`` for standard input).
    base_dir : str or Path
        Where an optimise study's ``study.scene`` file is looked up.

    Returns
    -------
    kind : str
        :func:`file_kind`.
    checked : list of (str, list of Finding)
        Per scene of the file (an optimise study's scenarios; an envelope or
        design study's scene placed for its median conditions), a label and
        its findings.

    Raises
    ------
    ValueError
        A bad field (a :class:`SceneError` lists every bad field of a scene's
        tables at once).
    """
    kind = file_kind(data)
    if kind == "scene":
        from .scene import scene_from_dict

        return kind, [("scene", check_scene(scene_from_dict(data, source)))]
    if kind == "optimise":
        from .optimise.study import study_from_dict

        problem = study_from_dict(data, source, base_dir=base_dir).problem
        return kind, [(f"scenario {sc.name}", check_scene(sc.scene, x0=sc.x0))
                      for sc in problem.scenarios]
    if kind == "design":
        from .robust.study import robust_study_from_dict

        study = robust_study_from_dict(data, source).envelope
    else:
        from .envelope.study import study_from_dict

        study = study_from_dict(data, source)
    return kind, [("median touchdown", _check_median_case(study))]


def _check_median_case(study) -> list:
    """The findings of an envelope study's scene at the median of every condition."""
    from .envelope.cases import initial_states

    median = {name: r.transform(np.array([0.5])) for name, r in study.ranges.items()}
    x0, _ = initial_states(study, median)
    return check_scene(study.scene, x0=x0[:, 0])
