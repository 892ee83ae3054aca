"""Placing a body at touchdown: its lowest foot just touches the obstacle.

This module owns :func:`place_on_obstacle`, which moves a scene's body along
the vertical (−gravity, +z without gravity) so that, at a given attitude and
with every leg at its unloaded pose, the foot nearest the obstacle is at a
given signed distance from it. It returns a new scene; it must not simulate
and does not change velocities, legs or obstacles.
"""
from __future__ import annotations

from dataclasses import replace

import casadi as ca
import numpy as np

from symcushion.model.obstacles import closest_obstacle
from symcushion.model.scene_data import Scene

__all__ = ["place_on_obstacle", "feet_clearance", "PLACEMENT_TOL"]

#: Tolerance on the placed clearance (m): far below any stroke, far above the
#: round-off of the distance functions at metre scale.
PLACEMENT_TOL = 1e-10

#: Bisection steps: halving a bracket of at most a few hundred metres this
#: often reaches PLACEMENT_TOL.
_BISECTIONS = 80

#: Steps of the search (upward doubling, then tracing down): a grazing foot
#: closes the gap by a factor 1 − cos α per step, α its slope from level.
_MAX_STEPS = 400


def _up(scene: Scene) -> np.ndarray:
    norm = np.linalg.norm(scene.gravity)
    return -scene.gravity / norm if norm > 0 else np.array([0.0, 0.0, 1.0])


def _rotation(q) -> np.ndarray:
    w, x, y, z = np.asarray(q, dtype=float) / np.linalg.norm(q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def _distance(scene: Scene, pad: float = 0.0) -> ca.Function:
    p = ca.SX.sym("p", 3)
    return ca.Function("foot_distance", [p], [closest_obstacle(scene.obstacles, p, pad)[0]],
                       ["p"], ["d"])


def _distances(scene: Scene) -> dict:
    """``foot_distance`` of each footpad radius of the scene's legs, by radius."""
    return {pad: _distance(scene, pad) for pad in sorted({leg.footpad for leg in scene.legs})}


def feet_clearance(scene: Scene, _dist: dict | None = None) -> np.ndarray:
    """Signed distance (m) of each unloaded foot from the nearest obstacle, shape (N,).

    Positive outside the obstacle, negative inside; the body at its scene
    position and attitude. A foot with a footpad of radius a gives the pad's
    clearance: its centre's distance less a (docs/footpads.md).
    """
    R = _rotation(scene.body.attitude)
    dist = _distances(scene) if _dist is None else _dist
    feet = scene.body.position + np.array([R @ leg.rest_foot for leg in scene.legs])
    out = np.empty(len(feet))
    for pad, fn in dist.items():
        legs = [j for j, leg in enumerate(scene.legs) if leg.footpad == pad]
        out[legs] = np.asarray(fn.map(len(legs))(feet[legs].T), dtype=float).ravel()
    return out


def place_on_obstacle(scene: Scene, attitude=None, clearance: float = 0.0) -> Scene:
    """A copy of ``scene`` whose body is moved vertically so its lowest foot touches.

    The body keeps its horizontal position; its height along the vertical is
    set so that the smallest signed distance of the unloaded feet from the
    obstacles equals ``clearance`` (to :data:`PLACEMENT_TOL`).

    Parameters
    ----------
    scene : Scene
    attitude : array_like, shape (4,), optional
        Unit quaternion (w, x, y, z), body → world, to place the body at;
        default the scene's.
    clearance : float
        Gap (m) between the lowest foot and the obstacle, ≥ 0; 0 is touching.

    Returns
    -------
    Scene
    """
    if not isinstance(scene, Scene):
        raise TypeError(f"`scene` must be a Scene, got {type(scene).__name__}.")
    if isinstance(clearance, bool) or not isinstance(clearance, (int, float, np.floating)) \
            or not np.isfinite(clearance) or clearance < 0:
        raise ValueError(f"`clearance` must be a finite number >= 0 (m), got {clearance!r}; "
                         "0 places the lowest foot on the obstacle.")
    body = scene.body if attitude is None else replace(scene.body, attitude=attitude)
    up = _up(scene)
    base = replace(scene, body=body)
    dist = _distances(scene)

    def gap(s):
        moved = replace(base, body=replace(body, position=body.position + s * up))
        return float(np.min(feet_clearance(moved, dist))) - clearance

    s, g, step = 0.0, gap(0.0), 1.0
    for _ in range(_MAX_STEPS):          # start above the obstacle
        if g >= 0:
            break
        s, step = s + step, 2 * step
        g = gap(s)
    else:
        raise ValueError("cannot place the body: moving it up never lifts every foot out of "
                         "the obstacle; check the obstacle and the legs.")
    # sphere tracing: no surface is nearer than the signed distance, so a step
    # down by the gap cannot pass through the obstacle
    for _ in range(_MAX_STEPS):
        if g <= PLACEMENT_TOL:
            break
        above, g_above, s = s, g, s - g
        g = gap(s)
        if g > g_above:
            raise ValueError("cannot place the body: the feet move away from the obstacle "
                             "as the body goes down (they are below it); start the body "
                             "above the obstacle.")
        if g < 0:                       # an approximate distance overshot: bisect
            below = s
            for _ in range(_BISECTIONS):
                s = (above + below) / 2
                g = gap(s)
                if abs(g) <= PLACEMENT_TOL:
                    break
                above, below = (s, below) if g > 0 else (above, s)
            break
    else:
        raise ValueError("cannot place the body: no obstacle below the legs along the "
                         "vertical; check the obstacles' positions.")
    return replace(base, body=replace(body, position=body.position + s * up))
