"""The quaternion kit: unit quaternions (w, x, y, z), Hamilton convention, body → world.

This module owns the rigid-body kinematics of the body's attitude for CasADi
and NumPy alike: the rotation matrix, the product, the exponential of a
rotation vector, the axis–angle constructor, the body z axis and its tilt
from a vertical. It must not know the layout of any vector or any physics
beyond the rotation group.
"""
from __future__ import annotations

import casadi as ca
import numpy as np

__all__ = ["quat_to_rot", "quat_to_rot_np", "quat_mul", "quat_mul_np", "quat_exp", "quat_from_axis_angle_np", "body_axis", "body_axis_np", "one_minus_cos_tilt", "tilt", "tilt_np"]


def quat_to_rot(q):
    """Rotation matrix (3 × 3, body → world) of a unit quaternion, CasADi."""
    w, x, y, z = q[0], q[1], q[2], q[3]
    return ca.vertcat(
        ca.horzcat(1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)),
        ca.horzcat(2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)),
        ca.horzcat(2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)))


def quat_to_rot_np(q, normalise: bool = True) -> np.ndarray:
    """Rotation matrices (…, 3, 3) of quaternions (…, 4), NumPy.

    With ``normalise`` (default) the quaternions are scaled to unit norm first.
    """
    q = np.asarray(q, dtype=float)
    if q.shape[-1:] != (4,):
        raise ValueError(f"`q` must have 4 entries (w, x, y, z) on its last axis, got shape "
                         f"{q.shape}.")
    if normalise:
        q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    w, x, y, z = np.moveaxis(q, -1, 0)
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
    ], -2)


def quat_mul(a, b):
    """Hamilton product a ⊗ b of two quaternions, CasADi."""
    aw, av = a[0], a[1:4]
    bw, bv = b[0], b[1:4]
    return ca.vertcat(aw * bw - ca.dot(av, bv), aw * bv + bw * av + ca.cross(av, bv))


def quat_mul_np(a, b) -> np.ndarray:
    """Hamilton products a ⊗ b of quaternions (…, 4), NumPy (broadcasting)."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    aw, av = a[..., :1], a[..., 1:]
    bw, bv = b[..., :1], b[..., 1:]
    return np.concatenate([aw * bw - np.sum(av * bv, axis=-1, keepdims=True),
                           aw * bv + bw * av + np.cross(av, bv)], axis=-1)


#: Below this squared rotation angle (rad²) quat_exp uses its Taylor series:
#: cos(a/2) and sin(a/2)/a are then exact to round-off with two terms.
_EXP_SERIES_ANGLE2 = 1e-16


def quat_exp(theta):
    """Quaternion of the rotation vector θ (rad), CasADi; safe at θ = 0."""
    angle2 = ca.dot(theta, theta)
    angle = ca.sqrt(ca.if_else(angle2 > 0, angle2, 1.0))
    # sin(a/2)/a with its Taylor series where a is tiny (no 0/0 in either branch)
    small = angle2 > _EXP_SERIES_ANGLE2
    half_sinc = ca.if_else(small, ca.sin(angle / 2) / angle, 0.5 - angle2 / 48)
    return ca.vertcat(ca.if_else(small, ca.cos(angle / 2), 1 - angle2 / 8), half_sinc * theta)


def quat_from_axis_angle_np(axis, angle) -> np.ndarray:
    """Quaternions (…, 4) of rotations by ``angle`` (…) rad about unit ``axis`` (…, 3)."""
    half = 0.5 * np.asarray(angle, dtype=float)
    axis = np.asarray(axis, dtype=float)
    return np.concatenate([np.cos(half)[..., None], np.sin(half)[..., None] * axis], axis=-1)


def body_axis(q):
    """Body z axis in the world frame (third column of R), CasADi; columns of q allowed."""
    w, x, y, z = q[0, :], q[1, :], q[2, :], q[3, :]
    return ca.vertcat(2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x ** 2 + y ** 2))


def body_axis_np(q) -> np.ndarray:
    """Body z axis in the world frame (…, 3) of unit quaternions (…, 4), NumPy."""
    w, x, y, z = np.moveaxis(np.asarray(q, dtype=float), -1, 0)
    return np.stack([2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x ** 2 + y ** 2)], -1)


def one_minus_cos_tilt(q, up):
    """1 − cos(tilt) of the body z axis from ``up`` (unit), CasADi; one entry per column of q.

    Smooth at zero tilt, unlike the angle itself, so optimisers use it.
    """
    return 1 - ca.mtimes(ca.reshape(up, 1, 3), body_axis(q))


def tilt(q, up):
    """Angle (rad) of the body z axis from the unit vector ``up``, CasADi."""
    return ca.acos(ca.fmin(ca.fmax(1 - one_minus_cos_tilt(q, up), -1.0), 1.0))


def tilt_np(q, up) -> np.ndarray:
    """Angle (rad, …) of the body z axis of quaternions (…, 4) from unit ``up`` (3,)."""
    cos = body_axis_np(q) @ np.asarray(up, dtype=float)
    return np.arccos(np.clip(cos, -1.0, 1.0))
