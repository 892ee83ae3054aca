"""The hinge's geometry: the deflections of (2.1) of a foot position, and their rates.

The strut of Khvostov (1976) §2 is fixed to the body by a spherical hinge at
r_h; a foot at r gives

    L = |r − r_h|, δ_S = L − L₀, e_S = (r − r_h)/L,
    e_β = e_S × e_n/|e_S × e_n|, β = −arcsin(e₀·e_β),
    e_γ = e_S × (e_n × e_S)/|e_S × (e_n × e_S)|, γ = arcsin(e_n·e_γ)   (2.1)

This module owns those expressions (:func:`leg_geometry_expr`), the checks
that keep them away from their singular lines (:data:`SINGULAR_ANGLE`,
:func:`check_angle`), the strut's geometry block in ``p``
(:data:`GEOMETRY_SIZE`) and :class:`HingeGeometry`, the part of
:class:`~symcushion.legs.strut.HingedStrut` that reads its geometry (its own, or
the block of ``p``) and gives the elements' deflections, their rates and
gradients. It must not know the elements' curves, the forces of (2.1), the
memory law, contact or the body.
"""
from __future__ import annotations

import casadi as ca
import numpy as np

from symcushion.validation import direction, real, vector

__all__ = ["HingeGeometry", "SINGULAR_ANGLE", "GEOMETRY_SIZE", "check_angle", "leg_geometry_expr"]

#: Entries of the geometry block of ``p``: hinge (3, m), e₀ (3), e_n (3), L₀ (m).
GEOMETRY_SIZE = 10

#: Smallest angle (rad) allowed between the rest direction e₀ and the lines
#: where (2.1) is singular (e₀ ∥ e_n: e_β undefined; e₀ ⊥ e_n: γ has a kink,
#: docs/paper-notes.md §2). 1° keeps |e_S × e_n| and |e_S·e_n| above 0.017 at rest.
SINGULAR_ANGLE = np.deg2rad(1.0)


def _unit(v):
    return v / ca.norm_2(v)


def check_angle(e0, en, where=""):
    """cos(e₀, e_n) of unit vectors, or a ValueError if (2.1) is singular there
    (within :data:`SINGULAR_ANGLE` of e_n or of the plane ⊥ e_n); ``where``
    prefixes the message."""
    cos0 = float(e0 @ en)
    angle = np.arccos(np.clip(abs(cos0), 0.0, 1.0))
    if angle < SINGULAR_ANGLE:
        raise ValueError(
            f"{where}`e0` is parallel to `en` (angle {np.rad2deg(angle):.3g}° < "
            f"{np.rad2deg(SINGULAR_ANGLE):g}°): e_β of (2.1) is undefined there; "
            "tilt `en` away from the strut.")
    if np.pi / 2 - angle < SINGULAR_ANGLE:
        raise ValueError(
            f"{where}`e0` is perpendicular to `en` (angle {np.rad2deg(angle):.4g}° from the "
            "axis line): γ of (2.1) has a kink there (docs/paper-notes.md §2); tilt `en` so "
            "that the strut makes an angle strictly between 0° and 90° with it.")
    return cos0


def leg_geometry_expr(r, r_h, e0, en):
    """Geometry of (2.1) as CasADi expressions of the foot position ``r``.

    Returns a dict with L, e_S, e_beta, e_gamma, beta, gamma.
    """
    d = r - r_h
    L = ca.norm_2(d)
    e_S = d / L
    e_beta = _unit(ca.cross(e_S, en))                                  # (2.1)
    e_gamma = _unit(ca.cross(e_S, ca.cross(en, e_S)))                  # (2.1)
    beta = -ca.asin(ca.dot(e0, e_beta))                                # (2.1)
    # (2.1), docs/paper-notes.md §1: γ = arcsin(e_n·e_γ) = arcsin|e_S × e_n|, evaluated as
    # atan2(|e_S × e_n|, |e_S·e_n|): the same angle, but arcsin near 1 loses
    # digits like eps/(90° − γ)² in its derivative within 1° of e_S ⊥ e_n.
    gamma = ca.atan2(ca.norm_2(ca.cross(e_S, en)), ca.fabs(ca.dot(e_S, en)))
    return dict(L=L, e_S=e_S, e_beta=e_beta, e_gamma=e_gamma, beta=beta, gamma=gamma)


class HingeGeometry:
    """The geometry of a hinged strut, mixed into ``HingedStrut``.

    Reads the strut's ``hinge``, ``e0``, ``en``, ``length``, ``gamma0``,
    ``sigma``, ``param_names`` and its cache ``_gradients``.
    """

    @property
    def geometry_values(self) -> np.ndarray:
        """The geometry block of ``p`` (shape (GEOMETRY_SIZE,)): hinge (m), e₀, e_n, L₀ (m)."""
        return np.concatenate([self.hinge, self.e0, self.en, [self.length]])

    @property
    def rest_foot(self) -> np.ndarray:
        """Foot position at the unloaded rest pose, r_h + L₀ e₀ (m)."""
        return self.hinge + self.length * self.e0

    def rest_foot_expr(self, p):
        """r_h + L₀ e₀ as a CasADi expression of ``p`` (constants without a geometry block)."""
        G = self._geometry_of(p)
        return G["hinge"] + G["length"] * G["e0"]

    def check_geometry_block(self, block, where=""):
        """:meth:`check_geometry` of the geometry block of ``p`` (hinge, e0, en, length)."""
        block = np.asarray(block, dtype=float).ravel()
        self.check_geometry(block[0:3], block[3:6], block[6:9], block[9], where=where)

    def check_geometry(self, hinge, e0, en, length, where=""):
        """Refuse a geometry (as the block of ``p`` holds it) this strut's Functions cannot take.

        The constructor's checks (a positive length, e₀ at least
        :data:`SINGULAR_ANGLE` from e_n and from the plane ⊥ e_n), and the
        orientation sign: σ = sign(e₀·e_n) is fixed when the Functions are
        built, so a geometry that flips it is refused. ``where`` prefixes
        the message (e.g. ``"leg 2: "``).
        """
        vector(f"{where}hinge", hinge, (3,))
        e0 = direction(f"{where}e0", e0)
        en = direction(f"{where}en", en)
        real(f"{where}length", length, positive=True, unit="m")
        cos0 = check_angle(e0, en, where)
        if np.sign(cos0) != self.sigma:
            raise ValueError(
                f"{where}`e0`·`en` = {cos0:.3g} has the opposite sign to the built strut's "
                f"({self.sigma:+g}): the orientation sign of M_γ is fixed in the compiled "
                "Functions; flip `en` (the same polar axis) or build a model for this geometry.")

    def _geometry_of(self, p=None) -> dict:
        """hinge, e0, en, length and γ₀: the strut's numbers, or, when ``p`` carries a
        geometry block after the curve parameters, expressions of it (e₀, e_n normalised)."""
        n = len(self.param_names)
        if p is None or p.shape[0] == n:
            return dict(hinge=ca.DM(self.hinge), e0=ca.DM(self.e0), en=ca.DM(self.en),
                        length=self.length, gamma0=self.gamma0)
        if p.shape[0] != n + GEOMETRY_SIZE:
            raise ValueError(f"`p` must have {n} entries (curve parameters) or "
                             f"{n + GEOMETRY_SIZE} (and the geometry), got {p.shape[0]}.")
        e0, en = _unit(p[n + 3:n + 6]), _unit(p[n + 6:n + 9])
        # γ(e₀), as in leg_geometry_expr
        gamma0 = ca.atan2(ca.norm_2(ca.cross(e0, en)), ca.fabs(ca.dot(e0, en)))
        return dict(hinge=p[n:n + 3], e0=e0, en=en, length=p[n + 9], gamma0=gamma0)

    def geometry(self, r, p=None):
        """Geometry of (2.1) at foot position ``r`` (CasADi expression); the strut's own
        geometry, or the one in ``p``'s geometry block."""
        G = self._geometry_of(p)
        g = leg_geometry_expr(r, G["hinge"], G["e0"], G["en"])
        g["delta_S"] = g["L"] - G["length"]
        g["gamma0"] = G["gamma0"]
        return g

    def rates(self, g, v):
        """Deflection rates of (S, M_β, M_γ) whose signs select the branches (2.1)."""
        # β′ ≈ (V·e_β)/L, so that x·ẋ is in rad²/s like RATE_WIDTH says. The potential law
        # uses the same rates: its exact β′ = ∇β·V differs by the factor c > 0 of its
        # gradient (``symcushion.legs.strut``'s docstring), which keeps the sign.
        return dict(S=ca.dot(v, g["e_S"]),
                    M_beta=ca.dot(v, g["e_beta"]) / g["L"],
                    M_gamma=-self.sigma * ca.dot(v, g["e_gamma"]) / g["L"])

    def _deflections(self, g):
        return dict(S=g["delta_S"], M_beta=g["beta"], M_gamma=g["gamma"] - g["gamma0"])

    def deflection_gradients(self, r, p=None):
        """∇δ_S, ∇β, ∇(γ − γ₀) at ``r`` (the rows of a 3×3 expression, 1/m or rad/m), by
        ``casadi.jacobian`` of the deflections of (2.1)."""
        n_p = 0 if p is None else p.shape[0]
        if n_p not in self._gradients:
            r_sym = ca.SX.sym("r", 3)
            p_sym = ca.SX.sym("p", n_p)
            x = self._deflections(self.geometry(r_sym, None if p is None else p_sym))
            J = ca.jacobian(ca.vertcat(x["S"], x["M_beta"], x["M_gamma"]), r_sym)
            self._gradients[n_p] = ca.Function("strut_deflection_gradients", [r_sym, p_sym],
                                               [J], ["r", "p"], ["J"])
        return self._gradients[n_p](r, ca.DM.zeros(0) if p is None else p)
