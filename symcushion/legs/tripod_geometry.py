"""The inverted tripod's geometry: element lengths, directions and deflections of a foot position.

The gear of Apollo LM, Surveyor and Chang'e-3: a primary strut on a
spherical joint at the hardpoint h₁ runs to the foot r; its outer cylinder,
of fixed length ℓ_o, carries at Q = h₁ + ℓ_o e_S the pin of two secondary
struts from the hardpoints h₂, h₃. With L = |r − h₁|, e_S = (r − h₁)/L,
l_k = |Q − h_k| and u_k = (Q − h_k)/l_k, the generalised deflections are

    q = (δ_S, δ₂, δ₃) = (L − L₀, l₂ − l₂₀, l₃ − l₃₀)

(extension positive, compression negative, as δ_S of ``symcushion.legs.strut``),
each element resists with its curve f_i(q_i) and, by virtual work, the force
on the foot *from the obstacle* that holds it at r (the paper's sign, as in
(2.1)) is

    P = Σᵢ f_i(q_i) ∇_r q_i = J(r)ᵀ f,          J = ∂q/∂r            (T1)

the equilibrium of the massless primary about h₁ (docs/tripod.md). J comes
from ``casadi.jacobian`` and D_p = ∂P/∂r from another, with the
loading/unloading branches held as ``HingedStrut`` holds them. An element's
branch is selected by the sign of q_i·q̇_i with q̇ = J v (v: the foot's
velocity relative to the body).

This module owns those expressions (CasADi, so that the hardpoints and
lengths may become symbols), their NumPy twin for checks, and the block
size and zero-length threshold they imply. It must not know the elements'
curves, contact, the body or scenes: :class:`~symcushion.legs.tripod.InvertedTripod`
builds its forces and Functions on it.
"""
from __future__ import annotations

import casadi as ca
import numpy as np

__all__ = ["tripod_geometry_expr", "tripod_rest_lengths", "tripod_deflections",
           "angle_from_parallel", "numeric_geometry", "GEOMETRY_SIZE", "ZERO_LENGTH"]

#: Entries of a tripod's geometry block in ``p``: h₁, h₂, h₃, the rest foot, ℓ_o.
GEOMETRY_SIZE = 13

#: A secondary shorter than this fraction of the primary's rest length counts
#: as of zero length: its direction u_k is then round-off.
ZERO_LENGTH = 1e-9


def tripod_geometry_expr(r, h1, h2, h3, outer_length):
    """Lengths and directions of the tripod's elements at foot position ``r``.

    Parameters
    ----------
    r, h1, h2, h3 : casadi.SX, MX or DM, shape (3,)
        Foot position and hardpoints, body frame (m).
    outer_length : float or casadi scalar
        ℓ_o, length of the primary's outer cylinder from h₁ to the pin Q (m).

    Returns
    -------
    dict
        ``L`` (primary length), ``e_S`` (primary axis), ``Q`` (pin),
        ``l`` (list of the two secondary lengths), ``u`` (their unit vectors
        from h_k towards Q).
    """
    d = r - h1
    L = ca.norm_2(d)
    e_S = d / L
    Q = h1 + outer_length * e_S
    spans = [Q - h2, Q - h3]
    lengths = [ca.norm_2(s) for s in spans]
    units = [s / length for s, length in zip(spans, lengths)]
    return dict(L=L, e_S=e_S, Q=Q, l=lengths, u=units)


def tripod_rest_lengths(foot, h1, h2, h3, outer_length):
    """Rest lengths (L₀, l₂₀, l₃₀) of the three elements with the foot at ``foot`` (m)."""
    g = tripod_geometry_expr(foot, h1, h2, h3, outer_length)
    return ca.vertcat(g["L"], *g["l"])


def tripod_deflections(g, rest_lengths):
    """q = (δ_S, δ₂, δ₃): element lengths minus rest lengths (m), extension positive."""
    return ca.vertcat(g["L"], *g["l"]) - rest_lengths

def angle_from_parallel(a, b):
    """Angle (rad, 0 to π/2) between the lines of a and b; 0 if either is zero."""
    cross, dot = np.linalg.norm(np.cross(a, b)), abs(float(a @ b))
    return float(np.arctan2(cross, dot)) if cross + dot > 0 else 0.0


def numeric_geometry(r, h1, h2, h3, outer_length):
    """The geometry of :func:`tripod_geometry_expr` in NumPy (for checks)."""
    d = r - h1
    L = np.linalg.norm(d)
    e_S = d / L
    Q = h1 + outer_length * e_S
    spans = [Q - h2, Q - h3]
    return L, e_S, Q, spans
