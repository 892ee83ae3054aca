"""What a check finds: the finding, the warning category and the geometry checks share.

This module owns :class:`Finding` (one result of a check, before or during a
run), :class:`PhysicsWarning` and the geometry of a state that the checks
before the run (``symcushion.run.checks``) and during it (``symcushion.run.monitor``)
both read: :func:`rotations`, :func:`obstacle_distances`,
:func:`world_points`. It must not check anything itself, and it never changes
a scene, a state or a step.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass

import casadi as ca
import numpy as np

from symcushion.layout.vectors import state_layout
from symcushion.model.scene_data import Scene

__all__ = ["Finding", "PhysicsWarning", "rotations", "obstacle_distances", "world_points"]


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


def rotations(q):
    """Rotation matrices, shape (n, 3, 3), of unit quaternions q, shape (4, n)."""
    q = q / np.linalg.norm(q, axis=0)
    w, x, y, z = q
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1)], 1)


def obstacle_distances(scene: Scene, points, pad: float = 0.0) -> np.ndarray:
    """Signed distance, shape (len(obstacles), n), of world points, shape (3, n); with
    ``pad`` a, the clearance of footpads of radius a centred there."""
    p = ca.SX.sym("p", 3)
    fn = ca.Function("obstacle_distance", [p], [ca.vertcat(*[o.distance(p, pad)
                                                              for o in scene.obstacles])],
                     ["p"], ["d"])
    return np.asarray(fn(np.asarray(points, float)), dtype=float).reshape(
        len(scene.obstacles), -1)


def world_points(scene: Scene, X):
    """Body centre (3, n), hinges (N, 3, n) and feet (N, 3, n) of states X (nx, n)."""
    xl = state_layout(len(scene.legs))
    R = rotations(xl.get(X, "attitude"))
    pos = xl.get(X, "position")
    hinges = np.stack([pos + np.einsum("nij,j->in", R, leg.hinge) for leg in scene.legs])
    feet = xl.legs(X, "foot")
    return pos, hinges, feet
