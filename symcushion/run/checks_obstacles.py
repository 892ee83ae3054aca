"""The checks before a run of where the body and its feet start: obstacles, footpads, reach.

A foot or a hinge that starts inside an obstacle, feet off a terrain grid, a
surface formula that is NaN or not smooth where the feet can go, an
oversized footpad, a frictionless leg with a direction of no stiffness: each
family of findings of :func:`~symcushion.run.checks.check_scene` that looks at the
scene's geometry at its first state is here, with its tolerance.

This module owns those checks and their named tolerances (re-exported by
``symcushion.run.checks``, where users read them; docs/checks.md lists each). It
must not run them in order or raise (``symcushion.run.checks`` does), and it
never changes a scene, a state or a step.
"""
from __future__ import annotations

import casadi as ca
import numpy as np

from symcushion.run.findings import Finding, obstacle_distances, rotations, world_points
from symcushion.layout.vectors import state_layout
from symcushion.model.obstacles import ImplicitSurface, Terrain, closest_obstacle
from symcushion.legs.strut_geometry import SINGULAR_ANGLE

__all__ = ["check_start", "check_footpads", "check_terrain", "check_surfaces",
           "check_free_directions", "START_TOLERANCE", "BODY_TOLERANCE", "REACH_FRACTIONS",
           "SAMPLE_DIRECTIONS", "FD_STEP", "GRADIENT_TOLERANCE", "FAST_STEP_FRACTION",
           "FOOTPAD_FRACTION", "FREE_DIRECTION_RATIO"]


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

#: A footpad whose radius exceeds this fraction of its leg's rest length is a
#: warning: twice the Apollo LM's ratio (0.47 m pads on primaries of about
#: 3.8 m, 1/8). Beyond it what the offset-surface model neglects (the pad's
#: tilt, its contact patch, the moment of the contact point's offset) is a
#: large share of the leg's geometry (docs/footpads.md).
FOOTPAD_FRACTION = 0.25

#: A foot's smallest rest stiffness, as a fraction of its largest, below which a
#: frictionless scene is refused (``free_direction``): 1e-9 is far below any
#: leg's ratio of bending to axial stiffness (1e-3 for a rigid rod) and far above
#: round-off of a missing element's zero.
FREE_DIRECTION_RATIO = 1e-9


def _where(scene, k):
    ob = scene.obstacles[k]
    return f"obstacle[{k}] ({ob.kind})"


def _fibonacci_sphere(n):
    i = np.arange(n) + 0.5
    polar = np.arccos(1 - 2 * i / n)
    azimuth = np.pi * (1 + 5 ** 0.5) * i
    return np.stack([np.cos(azimuth) * np.sin(polar), np.sin(azimuth) * np.sin(polar),
                     np.cos(polar)])


def check_start(scene, x0):
    """The body, the hinges and the feet at the first state: none inside an obstacle,
    no foot far off the surface or fast to cross its stroke."""
    out = []
    pos, hinges, feet = world_points(scene, x0[:, None])
    d_body = obstacle_distances(scene, pos)[:, 0]
    allowed = BODY_TOLERANCE * min(leg.length for leg in scene.legs)
    for k in np.flatnonzero(d_body < -allowed):
        out.append(Finding("body_inside", f"`body.position`: the body centre starts "
                           f"{-d_body[k]:.3g} m inside {_where(scene, k)} (tolerance "
                           f"{allowed:.3g} m); move the body out of the obstacle.", "error",
                           value=float(-d_body[k]),
                           field="body.position"))
    for j, leg in enumerate(scene.legs):
        d_foot = obstacle_distances(scene, feet[j], leg.footpad)[:, 0]
        d_hinge = obstacle_distances(scene, hinges[j])[:, 0]
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


def check_footpads(scene):
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


def check_terrain(scene, x0):
    """Policy: a foot off a terrain's grid is an error (the height there is not data)."""
    out = []
    _, _, feet = world_points(scene, x0[:, None])
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


def check_surfaces(scene, x0):
    """φ and ∇φ finite, and ∇φ equal to central differences, around every hinge."""
    out = []
    _, hinges, _ = world_points(scene, x0[:, None])
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


def check_free_directions(scene, x0):
    """At μ = 0 a foot loaded across its leg needs stiffness in every direction: the
    frictionless contact step slides the foot along the tangent plane by K⁻¹p, and a
    direction the leg does not resist (a missing or flat hinge spring) leaves it no
    solution, so the foot lifts off and the body falls through the obstacle. A leg along
    the obstacle's normal carries no load across it and is left alone."""
    if scene.mu > 0:
        return []
    out = []
    R = rotations(state_layout(len(scene.legs)).get(x0, "attitude")[:, None])[0]
    _, _, feet = world_points(scene, np.asarray(x0, float)[:, None])
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
