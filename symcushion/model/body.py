"""The rigid body a touchdown moves: its mass, inertia and initial state.

Frames: the body frame has its origin at the centre of mass; legs are given in
body coordinates. The attitude is a unit quaternion (w, x, y, z) mapping body
to world coordinates. This module owns :class:`Body` and its checks. It must not
know legs, obstacles or schemes.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from symcushion.validation import direction, real, show, vector

__all__ = ["Body"]


def _vec(name, value, size=3):
    return vector(name, value, (size,))


def _positive(name, value, unit=""):
    return real(name, value, positive=True, unit=unit)


@dataclass
class Body:
    """The rigid body and its initial state.

    Attributes
    ----------
    mass : float
        kg, > 0.
    inertia : ndarray, shape (3, 3)
        Inertia tensor about the centre of mass, body axes (kg·m²); a 3-vector
        is taken as the diagonal.
    position : ndarray, shape (3,)
        Initial centre of mass, world (m).
    attitude : ndarray, shape (4,)
        Initial unit quaternion (w, x, y, z), body → world.
    velocity : ndarray, shape (3,)
        Initial velocity, world (m/s).
    angular_velocity : ndarray, shape (3,)
        Initial angular velocity in body axes (rad/s).
    """

    mass: float
    inertia: np.ndarray
    position: np.ndarray = field(default_factory=lambda: np.zeros(3))
    attitude: np.ndarray = field(default_factory=lambda: np.array([1.0, 0, 0, 0]))
    velocity: np.ndarray = field(default_factory=lambda: np.zeros(3))
    angular_velocity: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def __post_init__(self):
        self.mass = _positive("body.mass", self.mass, "kg")
        try:
            inertia = vector("body.inertia", self.inertia, (3,))
            inertia = np.diag(inertia)
        except (TypeError, ValueError):
            try:
                inertia = vector("body.inertia", self.inertia, (3, 3))
            except (TypeError, ValueError):
                raise ValueError(f"`body.inertia` must be 3 numbers (the diagonal) or a 3×3 "
                                 f"matrix in kg·m², got {show(self.inertia)}.") from None
        if not np.allclose(inertia, inertia.T) or np.any(np.linalg.eigvalsh(inertia) <= 0):
            raise ValueError(f"`body.inertia` must be symmetric positive definite, got "
                             f"{inertia.tolist()}; give the principal moments (kg·m²).")
        self.inertia = inertia
        self.position = _vec("body.position", self.position)
        self.attitude = direction("body.attitude", self.attitude, 4)
        self.velocity = _vec("body.velocity", self.velocity)
        self.angular_velocity = _vec("body.angular_velocity", self.angular_velocity)
