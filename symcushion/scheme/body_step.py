"""The rigid body's part of the touchdown step: the legs' wrench, the kicks, the drift.

This module owns the velocity-Verlet update of the body of §3 as small pure
CasADi expressions: the force and torque of all legs on the body about its
centre of mass (:func:`legs_wrench`, also read by ``symcushion.scheme.stability``),
the body's accelerations under a wrench (:func:`body_acceleration`), a half
kick (:func:`half_kick`) and the drift of position and attitude
(:func:`drift`). The body's mass, inertia and gravity come as one
:class:`BodyParams`, read from the step's ``p``.

It must not know about feet, contact, the absorbers' curves or the events
of the scheme (``symcushion.scheme.touchdown`` puts the step together), nor build
Functions: it returns expressions.
"""
from __future__ import annotations

from typing import NamedTuple

import casadi as ca

from symcushion.scheme.quaternion import quat_exp, quat_mul

__all__ = ["BodyParams", "legs_wrench", "body_acceleration", "half_kick", "drift", "Drift", "kick_drift"]


class BodyParams(NamedTuple):
    """The body of a step: mass m, inertia I (body axes), its inverse and gravity g."""

    m: object
    inertia: object
    inertia_inv: object
    g: object


def legs_wrench(rho, P, R=None):
    """(ΣF, Στ): the force and torque of all legs on the body, about the centre of mass.

    ``rho[j]`` is leg j's foot and ``P[j]`` its force on the body, both in body
    axes; the torque of a leg is ρ_j × P_j. Body axes by default; with the
    body's rotation ``R`` each leg's force and torque are turned into world
    axes before they are summed (ΣR P_j, ΣR(ρ_j × P_j)).
    """
    force, torque = ca.DM.zeros(3), ca.DM.zeros(3)
    for rho_j, P_j in zip(rho, P):
        if R is None:
            force = force + P_j
            torque = torque + ca.cross(rho_j, P_j)
        else:
            force = force + R @ P_j
            torque = torque + R @ ca.cross(rho_j, P_j)
    return force, torque


def body_acceleration(body: BodyParams, R, force, torque, omega):
    """(a, α): the body's linear acceleration g + R F/m (world) and angular acceleration
    I⁻¹(τ − ω × Iω) (body axes) under the legs' force F and torque τ (body axes)."""
    return (body.g + R @ force / body.m,
            body.inertia_inv @ (torque - ca.cross(omega, body.inertia @ omega)))


def half_kick(vel, omega, acc, h):
    """v + h/2·a, ω + h/2·α: a half kick of velocity Verlet with ``acc`` = (a, α)."""
    return vel + h / 2 * acc[0], omega + h / 2 * acc[1]


def drift(pos, quat, vel_h, omega_h, h):
    """x' = x + h v, q' = q ⊗ exp(h ω/2), renormalised: the drift over the step."""
    pos1 = pos + h * vel_h
    quat1 = quat_mul(quat, quat_exp(h * omega_h))
    return pos1, quat1 / ca.norm_2(quat1)


class Drift(NamedTuple):
    """The body after the first half kick and the drift: v_h, ω_h, x', q'."""

    vel_h: object
    omega_h: object
    pos1: object
    quat1: object


def kick_drift(body: BodyParams, start, force, torque, h) -> Drift:
    """The first half kick with the wrench (F, τ) from ``start`` = (x, v, q, ω, R), then
    the drift."""
    pos, vel, quat, omega, R = start
    vel_h, omega_h = half_kick(vel, omega, body_acceleration(body, R, force, torque, omega), h)
    return Drift(vel_h, omega_h, *drift(pos, quat, vel_h, omega_h, h))
