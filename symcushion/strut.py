"""A compliant strut on a spherical hinge: the force law (2.1) and its stiffness.

The strut of Khvostov (1976) §2 is fixed to the body by a spherical hinge at
r_h; a foot at r carries the contact load. The force on the foot *from the
obstacle* that holds it at r (P = −P_h, the paper's sign) is

    P = S e_S + (1/L) M_β e_β + (1/L) M_γ e_γ                          (2.1)

with L = |r − r_h|, δ_S = L − L₀, e_S = (r − r_h)/L,
e_β = e_S × e_n/|e_S × e_n|, β = −arcsin(e₀·e_β),
e_γ = e_S × (e_n × e_S)/|e_S × (e_n × e_S)|, γ = arcsin(e_n·e_γ).

This module owns the geometry of one strut and the CasADi Functions built on
it. It knows nothing of contact or of the body's motion.

Orientation of the elements (docs/paper-notes.md §2): users give every element as a
resistance curve f(x) of its own deflection x (δ_S, β, γ − γ₀) with a
positive slope meaning restoring; the strut applies
S = f_S(δ_S), M_β = f_β(β), M_γ = −sign(e₀·e_n) f_γ(γ − γ₀), for which the
rest stiffness is positive definite.

Loading/unloading branches (P = P(δ, sign δ′)): the rates of (2.1) are
sign δ_S′ = sign(V·e_S) and sign β′ = sign(V·e_β). For the polar element
the rate of the user's deflection γ − γ₀ is γ′ = −sign(e₀·e_n)(V·e_γ)/L
(e_γ points towards e_n, so moving along it closes the angle to e_n when
e₀·e_n > 0); (2.1)'s sign γ′ = sign(V·e_γ) is the rate in the direction of
the moment M_γ, the same thing seen with the paper's orientation.

Two force laws share these deflections, curves and signs (``law``):
``"paper"`` is (2.1) as printed; ``"potential"`` is
P = f_S ∇δ_S + f_β ∇β + f_γ ∇(γ − γ₀), the gradients of the deflections
by ``casadi.jacobian``. The two differ only in the β term: ∇δ_S = e_S and
∇(γ − γ₀) = −sign(e₀·e_n) e_γ/L exactly, but ∇β = c e_β/L with c = 1 only
at β = 0, γ = γ₀ (docs/strut.md, "Energy"). For elastic curves the
potential law is P = ∇U, U = Σ ∫f dx, and D_p is symmetric; (2.1) does
work around a closed loop of the foot.

The geometry (hinge, e₀, e_n, L₀) is either baked into the Functions as
constants (``functions()``, the default) or read from the last
:data:`GEOMETRY_SIZE` entries of ``p`` (``functions(geometry="input")``),
so that one compiled step serves every geometry; e₀ and e_n are then
normalised in the graph. The discrete choices stay the constructor's:
the orientation sign σ = sign(e₀·e_n) and the singularity checks, which
:meth:`HingedStrut.check_geometry` repeats for a geometry given in ``p``.

An element that is absent contributes nothing, except the axial one: a strut
given without ``S`` is an *axially rigid rod*, modelled as a stiff linear
axial spring whose stiffness is ``axial_ratio`` times the bending stiffness
scale (max hinge slope)/L₀² — see :data:`RIGID_AXIAL_RATIO`.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import casadi as ca
import numpy as np

from . import absorber
from .leg_scheme import cached_memory_functions, curve_param_names, curve_param_values
from .characteristics import Curve, Linear
from .layout import LEG_GEOMETRY_FIELDS
from .validation import direction, real, vector

__all__ = ["HingedStrut", "RIGID_AXIAL_RATIO", "SINGULAR_ANGLE", "LAWS", "DEFAULT_LAW", "GEOMETRY_MODES",
           "GEOMETRY_SIZE", "leg_geometry_expr"]

#: The force laws of a strut: ``"paper"``, (2.1) as printed; ``"potential"``,
#: the gradient of the elements' deflections weighted by their forces.
LAWS = ("paper", "potential")
#: The force law of a strut in a scene file that names none: the energy-consistent
#: ``"potential"`` law, which does no work around a closed path of the foot and
#: agrees with (2.1) at rest (docs/strut.md, "Energy"); the paper's own scenes
#: (Figs. 3–4) say ``law = "paper"``. A ``HingedStrut`` built in Python takes
#: (2.1), the paper's object, unless told otherwise.
DEFAULT_LAW = "potential"

#: How the strut's Functions take its geometry: ``"constant"`` (baked in) or
#: ``"input"`` (the last GEOMETRY_SIZE entries of ``p``).
GEOMETRY_MODES = ("constant", "input")

#: Entries of the geometry block of ``p``: hinge (3, m), e₀ (3), e_n (3), L₀ (m).
GEOMETRY_SIZE = 10

#: Axial stiffness of a "rigid" rod relative to its bending stiffness scale,
#: k_S = ratio · max(M_β′, M_γ′)/L₀². The foot is massless, so the contact
#: step itself copes with any ratio (docs/paper-notes.md §3.7: 1e8 works); what a large
#: ratio costs is the time step of the *body's* motion, which sees an axial
#: mode of frequency √(k_S/m): the explicit-in-velocity integrator is stable
#: for ω Δt < 2. At 1e3 the axial stroke is a thousandth of the bending
#: deflection under the same force, and the Figs. 3–4 scene (1200 N·m/rad,
#: 0.6 m, 50 kg, 4 legs) has ω Δt ≈ 0.5 at Δt = 1 ms. ``studies/rigid_rod.py``
#: measures the trade-off.
RIGID_AXIAL_RATIO = 1e3

#: Smallest angle (rad) allowed between the rest direction e₀ and the lines
#: where (2.1) is singular (e₀ ∥ e_n: e_β undefined; e₀ ⊥ e_n: γ has a kink,
#: docs/paper-notes.md §2). 1° keeps |e_S × e_n| and |e_S·e_n| above 0.017 at rest.
SINGULAR_ANGLE = np.deg2rad(1.0)

#: Newton steps that put a free foot where its relaxed deflections meet: it starts
#: from the foot with the hinges at rest, a few mrad away, and the map from the foot
#: to (δ_S, β, γ) is smooth there, so three steps reach round-off.
FREE_FOOT_NEWTON_STEPS = 3


def _vector(name, value, *, unit=False):
    return direction(name, value) if unit else vector(name, value, (3,))


def _unit(v):
    return v / ca.norm_2(v)


def _check_angle(e0, en, where=""):
    """cos(e₀, e_n) of unit vectors, or a ValueError if (2.1) is singular there."""
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


#: The elements of a hinged strut, in the order of their sets and rates.
_ELEMENT_ORDER = ("S", "M_beta", "M_gamma")


@dataclass(frozen=True)
class _Element:
    name: str            # 'S', 'M_beta', 'M_gamma'
    curve: Curve
    offset: int          # start of its parameters in p (tunable only)


class HingedStrut:
    """A strut on a spherical hinge with axial and bending elements (Fig. 2).

    Parameters
    ----------
    hinge : array_like, shape (3,)
        Hinge position r_h in body coordinates (m).
    e0 : array_like, shape (3,)
        Rest direction of the strut (normalised here).
    en : array_like, shape (3,)
        Polar axis e_n of the hinge (normalised here); must make an angle of
        at least :data:`SINGULAR_ANGLE` with e₀ and with the plane ⊥ e₀.
    length : float
        Rest length L₀ (m), > 0.
    S, M_beta, M_gamma : Curve, optional
        Resistance curves of the axial stroke δ_S (N vs m), of β and of
        γ − γ₀ (N·m vs rad). ``S=None`` makes an axially rigid rod.
    axial_ratio : float
        Stiffness ratio of the rigid rod's axial spring (used when S is None).
    law : {"paper", "potential"}
        ``"paper"``: (2.1) as printed. ``"potential"``: P = f_S ∇δ_S + f_β ∇β
        + f_γ ∇(γ − γ₀), the gradients by AD, the same deflections, curves and
        signs; for elastic curves P = ∇U and D_p is symmetric (docs/strut.md).
    footpad : float
        Radius a ≥ 0 of the footpad (m): the foot r is the pad's centre, which
        touches the obstacle's surface offset by a (docs/footpads.md); 0, the
        default, is a point foot. The strut's force law does not read it.

    Examples
    --------
    >>> from symcushion.characteristics import Linear
    >>> leg = HingedStrut(hinge=(0, 0, 0), e0=(0, 0, -1), en=(0, 0.5, -1),
    ...                   length=0.6, S=Linear(2e5), M_beta=Linear(3e3),
    ...                   M_gamma=Linear(3e3))
    >>> sorted(leg.functions())
    ['strut_force', 'strut_geometry', 'strut_stiffness', 'strut_stiffness_paper']
    """

    def __init__(self, hinge, e0, en, length, S: Optional[Curve] = None,
                 M_beta: Optional[Curve] = None, M_gamma: Optional[Curve] = None,
                 axial_ratio: float = RIGID_AXIAL_RATIO, law: str = "paper",
                 footpad: float = 0.0):
        if law not in LAWS:
            raise ValueError(f"`law` must be one of {LAWS}, got {law!r}; \"paper\" is (2.1) as "
                             "printed, \"potential\" its energy-consistent form.")
        self.law = law
        self.hinge = _vector("hinge", hinge)
        self.e0 = _vector("e0", e0, unit=True)
        self.en = _vector("en", en, unit=True)
        self.length = real("length", length, positive=True, unit="m")
        self.footpad = real("footpad", footpad, nonnegative=True, unit="m")
        cos0 = _check_angle(self.e0, self.en)
        for name, curve in (("S", S), ("M_beta", M_beta), ("M_gamma", M_gamma)):
            if curve is not None and not isinstance(curve, Curve):
                raise TypeError(f"`{name}` must be a characteristic curve such as Linear(1e4), "
                                f"got {curve!r}.")
        if S is None:
            axial_ratio = real("axial_ratio", axial_ratio, positive=True)
            bend = [abs(c.slope(0.0)) for c in (M_beta, M_gamma) if c is not None]
            if not bend or max(bend) == 0:
                raise ValueError("a rigid rod (`S=None`) needs a hinge element with non-zero "
                                 "stiffness to scale its axial spring; give `M_beta` or "
                                 "`M_gamma`, or give `S` explicitly.")
            S = Linear(axial_ratio * max(bend) / self.length ** 2)
            self.rigid = True
        else:
            self.rigid = False
        self.axial_ratio = float(axial_ratio)
        self.sigma = float(np.sign(cos0))  # orientation sign of M_γ, docs/paper-notes.md §2
        self.gamma0 = float(np.arctan2(np.linalg.norm(np.cross(self.e0, self.en)),
                                       abs(cos0)))  # γ(e₀), as in leg_geometry_expr
        elements, offset = [], 0
        for name, curve in (("S", S), ("M_beta", M_beta), ("M_gamma", M_gamma)):
            if curve is None:
                continue
            elements.append(_Element(name, curve, offset))
            if curve.tunable:
                offset += curve.n_params
        self.elements = tuple(elements)
        self._functions = {}            # by geometry mode
        self._memory_functions = {}
        self._gradients = {}            # strut_deflection_gradients, by size of p

    # -- parameters -----------------------------------------------------------
    @property
    def param_names(self) -> tuple[str, ...]:
        """Names of the entries of ``p`` (tunable curves only), e.g. ``S.k``."""
        return curve_param_names(self.elements)

    @property
    def param_values(self) -> np.ndarray:
        """Default values of ``p``."""
        return curve_param_values(self.elements)

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
        cos0 = _check_angle(e0, en, where)
        if np.sign(cos0) != self.sigma:
            raise ValueError(
                f"{where}`e0`·`en` = {cos0:.3g} has the opposite sign to the built strut's "
                f"({self.sigma:+g}): the orientation sign of M_γ is fixed in the compiled "
                "Functions; flip `en` (the same polar axis) or build a model for this geometry.")

    def _theta(self, el: _Element, p):
        if el.curve.tunable:
            return p[el.offset:el.offset + el.curve.n_params]
        return None

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

    # -- symbolic model ---------------------------------------------------------
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
        # gradient (module docstring), which keeps the sign.
        return dict(S=ca.dot(v, g["e_S"]),
                    M_beta=ca.dot(v, g["e_beta"]) / g["L"],
                    M_gamma=-self.sigma * ca.dot(v, g["e_gamma"]) / g["L"])

    def _deflections(self, g):
        return dict(S=g["delta_S"], M_beta=g["beta"], M_gamma=g["gamma"] - g["gamma0"])

    def curve_forces(self, g, v, p, g_branch=None):
        """f_S(δ_S), f_β(β), f_γ(γ − γ₀): the elements' curves at their deflections.

        ``g_branch`` (default ``g``): the geometry whose deflections and rates
        select the loading or unloading branch.
        """
        x = self._deflections(g)
        g_branch = g if g_branch is None else g_branch
        x_branch, rate = self._deflections(g_branch), self.rates(g_branch, v)
        out = dict(S=0.0, M_beta=0.0, M_gamma=0.0)
        for el in self.elements:
            out[el.name] = el.curve.force(x[el.name], rate[el.name], self._theta(el, p),
                                          branch_x=x_branch[el.name])
        return out

    def element_forces(self, g, v, p, g_branch=None):
        """S, M_β, M_γ of (2.1), with the orientation sign of M_γ applied.

        ``g_branch`` (default ``g``): the geometry whose deflections and rates
        select the loading or unloading branch.
        """
        out = self.curve_forces(g, v, p, g_branch)
        out["M_gamma"] = -self.sigma * out["M_gamma"]                  # docs/paper-notes.md §2
        return out

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

    def _assemble(self, g, f, r, p):
        """P from the elements' curve forces ``f`` (f_γ without the orientation sign)."""
        if self.law == "paper":
            M_gamma = -self.sigma * f["M_gamma"]                       # docs/paper-notes.md §2
            return (f["S"] * g["e_S"] + f["M_beta"] / g["L"] * g["e_beta"]
                    + M_gamma / g["L"] * g["e_gamma"])                 # (2.1)
        J = self.deflection_gradients(r, p)
        return J.T @ ca.vertcat(f["S"], f["M_beta"], f["M_gamma"])     # P = Σ f ∇x = ∇U

    def force_expr(self, r, v, p, r_branch=None):
        """P(r) of the strut's law, (2.1) or its potential form, as a CasADi expression (N).

        ``r_branch`` (default ``r``): the foot position whose deflections and
        rates select the branches; the stiffness differentiates with it held.
        A ``p`` with a geometry block after the curve parameters sets the geometry.
        """
        g = self.geometry(r, p)
        f = self.curve_forces(g, v, p, None if r_branch is None else self.geometry(r_branch, p))
        return self._assemble(g, f, r, p)

    def stiffness_paper_expr(self, r, v, p):
        """D_p from the hand formula (2.3), column by column (2.2)."""
        g = self.geometry(r, p)
        G = self._geometry_of(p)
        en, e0 = G["en"], G["e0"]
        L, e_S, e_beta, e_gamma = g["L"], g["e_S"], g["e_beta"], g["e_gamma"]
        x, rate = self._deflections(g), self.rates(g, v)
        f = self.element_forces(g, v, p)
        slope = dict(S=0.0, M_beta=0.0, M_gamma=0.0)
        for el in self.elements:
            slope[el.name] = el.curve.slope(x[el.name], rate[el.name], self._theta(el, p))
        dS = slope["S"]
        dMb = slope["M_beta"]
        dMg = -self.sigma * slope["M_gamma"]       # dM_γ/dγ with the orientation sign
        S, Mb, Mg = f["S"], f["M_beta"], f["M_gamma"]
        norm_b = ca.norm_2(ca.cross(e_S, en))                          # |e_S × e_n|
        norm_g = ca.norm_2(ca.cross(e_S, ca.cross(en, e_S)))           # |e_S × (e_n × e_S)|
        columns = []
        for i in range(3):
            e_i = ca.DM.zeros(3)
            e_i[i] = 1.0
            dL = e_S[i]                                                # ∂L/∂q_i = e_Si
            de_S = (e_i - e_S[i] * e_S) / L                            # ∂e_S/∂q_i
            u_beta = ca.cross(de_S, en) / norm_b
            de_beta = ca.cross(e_beta, ca.cross(u_beta, e_beta))       # ∂e_β/∂q_i
            d_beta = -ca.dot(e0, de_beta) / ca.sqrt(1 - ca.dot(e0, e_beta) ** 2)
            u_gamma = (ca.cross(de_S, ca.cross(en, e_S))
                       + ca.cross(e_S, ca.cross(en, de_S))) / norm_g
            de_gamma = ca.cross(e_gamma, ca.cross(u_gamma, e_gamma))   # ∂e_γ/∂q_i
            d_gamma = ca.dot(en, de_gamma) / ca.sqrt(1 - ca.dot(en, e_gamma) ** 2)
            column = (dS * dL * e_S + S * de_S                         # (2.3)
                      - (Mb * e_beta + Mg * e_gamma) * dL / L ** 2
                      + (dMb * d_beta * e_beta + Mb * de_beta) / L
                      + (dMg * d_gamma * e_gamma + Mg * de_gamma) / L)
            columns.append(column)
        return ca.horzcat(*columns)

    # -- the memory law (symcushion.absorber) ----------------------------------
    @property
    def axial_memory(self) -> bool:
        """True if the axial element keeps a set under the memory law."""
        return any(el.name == "S" and el.curve.has_memory for el in self.elements)

    @property
    def axial_state(self) -> bool:
        """True if the leg needs the memory law's state: an axial set, or a damper on
        any of its elements (whose rate (A3) reads the last step's mean rates)."""
        return any((el.name == "S" and el.curve.has_memory) or el.curve.has_damper
                   for el in self.elements)

    def deflections_expr(self, r, p=None):
        """(δ_S, β, γ − γ₀): the elements' own deflections at foot ``r`` (m, rad), with
        the geometry of ``p`` if it carries one."""
        x = self._deflections(self.geometry(r, p))
        return ca.vertcat(x["S"], x["M_beta"], x["M_gamma"])

    def _axial(self) -> _Element:
        return next(el for el in self.elements if el.name == "S")

    def memory_force_expr(self, r, sets, p, r_regime=None, rate=None):
        """P(r) of the strut's law with the elements on the memory law (A1) at ``sets``.

        ``sets`` (3): the sets of (S, M_β, M_γ); an element that keeps none
        takes its loading curve (the hinge springs, whose memory the scene
        refuses). ``r_regime`` (default ``r``): the foot position that picks each
        element's regime (``absorber.memory_force``). ``rate`` = (a, b): the
        deflection rates of the dampers are a·x + b, the affine form of (A3),
        with x = (δ_S, β, γ − γ₀) and b of length 3.
        """
        g = self.geometry(r, p)
        x = self._deflections(g)
        x_regime = None if r_regime is None else self._deflections(self.geometry(r_regime, p))
        forces = dict(S=0.0, M_beta=0.0, M_gamma=0.0)
        for el in self.elements:
            k = _ELEMENT_ORDER.index(el.name)
            forces[el.name] = absorber.element_force(
                el.curve, x[el.name], sets[k], self._theta(el, p),
                None if x_regime is None else x_regime[el.name],
                None if rate is None else (rate[0], rate[1][k]))
        return self._assemble(g, forces, r, p)

    def next_sets_expr(self, r, sets, p, rate=None):
        """The sets after the foot reached ``r`` (A2), in the order (S, M_β, M_γ);
        ``rate`` = (a, b) as in :meth:`memory_force_expr` (A5)."""
        x = self._deflections(self.geometry(r, p))
        out = [sets[k] for k in range(3)]
        for el in self.elements:
            k = _ELEMENT_ORDER.index(el.name)
            out[k] = absorber.element_next_set(el.curve, x[el.name], sets[k], self._theta(el, p),
                                               None if rate is None else (rate[0], rate[1][k]))
        return ca.vertcat(*out)

    def axial_lower_bound_expr(self, x, p):
        """lo(x) of (A1) for the axial element, the loading curve it crushes along (N),
        or None where its band has no lower bound."""
        el = self._axial()
        lo, _ = absorber.band(el.curve, x, self._theta(el, p))
        return lo

    def free_foot_expr(self, sets, p, x_start, mean_rate, dt):
        """A free foot at the end of a step (body frame): along e₀ at the axial
        element's free stroke, or relaxing towards it behind a damper (A4); a
        damped hinge spring's angle relaxes by (A4) too, an undamped one is at
        rest. With a damped hinge the foot is where the three deflections meet,
        by Newton's method from the foot with the hinges at rest."""
        el = self._axial()
        free = absorber.relaxed_deflection(el.curve, x_start[0], sets[0], mean_rate[0], dt,
                                           self._theta(el, p))
        G = self._geometry_of(p)
        foot = G["hinge"] + (G["length"] + free) * G["e0"]
        hinges = [e for e in self.elements if e.name != "S" and e.curve.has_damper]
        if not hinges:
            return foot
        # a massless foot whose hinge damper snapped it back to rest at lift-off would
        # jump by the bending deflection the damper held, often into the ground
        target = [free, 0.0, 0.0]
        for e in hinges:
            k = _ELEMENT_ORDER.index(e.name)
            target[k] = absorber.relaxed_deflection(e.curve, x_start[k], sets[k],
                                                    mean_rate[k], dt, self._theta(e, p))
        r = ca.SX.sym("r", 3)
        q = self.deflections_expr(r, p)
        newton = r - ca.solve(ca.jacobian(q, r), q - ca.vertcat(*target))
        for _ in range(FREE_FOOT_NEWTON_STEPS):
            foot = ca.substitute(newton, r, foot)
        return foot

    def memory_functions(self, geometry: str = "constant") -> dict[str, ca.Function]:
        """The named Functions of the memory law (A1)-(A4) for a leg that keeps a set
        or has a damper (``axial_state``); built once, cached. Shared by every leg
        scheme (docs/tripod.md, "Leg schemes"): ``sets``, ``rate_offset``,
        ``deflection_start`` and ``mean_rate`` have one entry per element.

        ``strut_force_memory(r, sets, p, rate_gain, rate_offset) -> P`` (the
        dampers' rates a·x + b, (A3)), ``strut_stiffness_memory(..., r_regime)
        -> Dp`` (∂P/∂r in the regime that ``r_regime`` picks, the dampers' a·c
        included), ``strut_next_set(r, sets, p, rate_gain, rate_offset) -> next_set``
        (A2), (A5),
        ``strut_free_foot(sets, p, deflection_start, mean_rate, dt) -> r`` (a
        free foot at the end of a step, body frame, (A4)) and
        ``strut_deflections(r, p) -> x`` (each element's deflection).
        ``geometry="input"``: ``p`` ends with the geometry block, as in
        :meth:`functions`.
        """
        return cached_memory_functions(self, geometry)

    def loading_set(self, r, p=None) -> float:
        """The axial set of a foot at ``r`` reached along the loading curve (A2)."""
        el = self._axial()
        delta_S = float(ca.evalf(self.geometry(ca.DM(self._check_r(r)))["delta_S"]))
        theta = self._theta(el, self._p(p))
        return float(ca.evalf(absorber.set_on_loading(el.curve, delta_S, theta)))

    # -- Functions --------------------------------------------------------------
    def _p_size(self, geometry: str) -> int:
        if geometry not in GEOMETRY_MODES:
            raise ValueError(f"`geometry` must be one of {GEOMETRY_MODES}, got {geometry!r}.")
        return len(self.param_names) + (GEOMETRY_SIZE if geometry == "input" else 0)

    def functions(self, geometry: str = "constant") -> dict[str, ca.Function]:
        """The named CasADi Functions of this strut (built once per ``geometry``, cached).

        Parameters
        ----------
        geometry : {"constant", "input"}
            ``"constant"``: the strut's geometry is baked in and ``p`` holds the
            tunable curve parameters (``param_names``), empty when all curves
            are numeric. ``"input"``: ``p`` holds those followed by the
            geometry block (:attr:`geometry_values`: hinge (m), e₀, e_n, L₀ (m);
            e₀ and e_n need not be unit), and ``strut_geometry`` takes ``p`` too.

        Returns
        -------
        dict
            ``strut_force(r, v, p) -> P``, ``strut_stiffness(r, v, p) -> Dp``
            (``casadi.jacobian``), with the paper law ``strut_stiffness_paper(r,
            v, p) -> Dp`` ((2.3) by hand, for (2.1) only), and
            ``strut_geometry(r[, p]) -> L, delta_S, beta, gamma, e_S, e_beta,
            e_gamma, gamma_deflection``. ``r``: foot position (3, m, body frame);
            ``v``: foot velocity relative to the hinge (3, m/s; selects the
            branches).

        Notes
        -----
        At the hinge (r = r_h) the strut direction e_S = (r − r_h)/L is 0/0 and
        these raw Functions return NaN; they are inner kernels and do not
        check. The Python boundary (:meth:`force`, :meth:`stiffness`) rejects
        a foot within 1e-9 L₀ of the hinge with a ValueError, and
        ``symcushion.checks.RunMonitor`` reports a non-finite state in a run.
        A geometry in ``p`` is not checked either: :meth:`check_geometry` does.
        """
        if geometry not in self._functions:
            r = ca.SX.sym("r", 3)
            v = ca.SX.sym("v", 3)
            p = ca.SX.sym("p", self._p_size(geometry))
            P = self.force_expr(r, v, p)
            # D_p = ∂P/∂r with the branches held (the active branch's slope, as
            # in (2.3)): with smooth curves the branch weight w(x·ẋ) also
            # depends on r, and its derivative ẋ/(2·rate_width)·(f_L − f_U) is
            # not a stiffness — it can make D_p indefinite at touchdown.
            r_branch = ca.SX.sym("r_branch", 3)
            Dp = ca.substitute(ca.jacobian(self.force_expr(r, v, p, r_branch), r), r_branch, r)
            g = self.geometry(r, p)
            names_in = ["r", "v", "p"]
            geo_in, geo_names = ([r], ["r"]) if geometry == "constant" else ([r, p], ["r", "p"])
            fns = {
                "strut_force": ca.Function("strut_force", [r, v, p], [P], names_in, ["P"]),
                "strut_stiffness": ca.Function("strut_stiffness", [r, v, p], [Dp],
                                               names_in, ["Dp"]),
                "strut_geometry": ca.Function(
                    "strut_geometry", geo_in,
                    [g["L"], g["delta_S"], g["beta"], g["gamma"], g["e_S"], g["e_beta"],
                     g["e_gamma"], g["gamma"] - g["gamma0"]],
                    geo_names, ["L", "delta_S", "beta", "gamma", "e_S", "e_beta", "e_gamma",
                                "gamma_deflection"]),
            }
            if self.law == "paper":
                fns["strut_stiffness_paper"] = ca.Function(
                    "strut_stiffness_paper", [r, v, p], [self.stiffness_paper_expr(r, v, p)],
                    names_in, ["Dp"])
            self._functions[geometry] = fns
        return self._functions[geometry]

    # -- the leg-scheme interface (docs/tripod.md, "Leg schemes") ---------------------
    #: The axial element: its stroke is the leg's ``stroke`` output and its curve's
    #: stroke limit the one the run's bottoming check reads.
    axial_element = "S"
    #: The fields of the strut's geometry block in ``p`` (``symcushion.layout``).
    geometry_fields = LEG_GEOMETRY_FIELDS
    @property
    def relaxes_free(self) -> tuple:
        """Which elements' deflections a free foot relaxes over a step (A4): the axial
        element's, and a hinge spring's that has a damper; the others return to rest
        at once."""
        damped = {e.name: e.curve.has_damper for e in self.elements}
        return (1.0, float(damped.get("M_beta", False)), float(damped.get("M_gamma", False)))

    def deflections(self, geo) -> dict:
        """Each element's own deflection from ``strut_geometry``'s outputs ``geo``:
        δ_S (m), β and γ − γ₀ (rad)."""
        return {"S": geo["delta_S"], "M_beta": geo["beta"], "M_gamma": geo["gamma_deflection"]}

    def deflection_outputs(self, geo) -> dict:
        """The per-leg output fields of the deflections (``symcushion.layout``)."""
        x = self.deflections(geo)
        return dict(stroke=x["S"], beta=x["M_beta"], gamma_deflection=x["M_gamma"],
                    secondary_stroke=ca.DM.zeros(2))

    def element_extent(self, name: str) -> float:
        """The range of an element's deflection worth sampling (m or rad)."""
        return self.length if name == "S" else np.pi / 2

    # -- numeric convenience ------------------------------------------------------
    def _check_r(self, r):
        r = _vector("r", r)
        if np.linalg.norm(r - self.hinge) < 1e-9 * self.length:
            raise ValueError(f"`r` = {r.tolist()} is at the hinge {self.hinge.tolist()}: the "
                             "strut direction is undefined; give a foot position away from it.")
        return r

    def _p(self, p):
        if p is None:
            return self.param_values
        p = np.asarray(p, dtype=float).ravel()
        if p.size != len(self.param_names):
            raise ValueError(f"`p` must have {len(self.param_names)} entries "
                             f"{self.param_names}, got {p.size}.")
        return p

    def force(self, r, v=(0.0, 0.0, 0.0), p=None) -> np.ndarray:
        """P(r) of the strut's law as a NumPy array (N); validates its inputs."""
        out = self.functions()["strut_force"](self._check_r(r), _vector("v", v), self._p(p))
        return np.asarray(out, dtype=float).ravel()

    def stiffness(self, r, v=(0.0, 0.0, 0.0), p=None, *, paper=False) -> np.ndarray:
        """D_p = ∂P/∂r (3×3, N/m) by AD, or by (2.3) with ``paper=True`` (paper law only)."""
        if paper and self.law != "paper":
            raise ValueError("`paper=True` asks for the hand formula (2.3) of (2.1); this strut "
                             f"has law = {self.law!r}, whose D_p is only by AD; drop `paper`.")
        name = "strut_stiffness_paper" if paper else "strut_stiffness"
        out = self.functions()[name](self._check_r(r), _vector("v", v), self._p(p))
        return np.asarray(out, dtype=float)

    def rest_stiffness_closed_form(self) -> np.ndarray:
        """D_p at the unloaded rest pose, closed form of docs/paper-notes.md §2.

        D_p = S′ e_S e_Sᵀ + (M_β′/L₀²) e_β e_βᵀ + (m′/L₀²) e_γ e_γᵀ, with the
        slopes of the loading branches at zero deflection.
        """
        e_S = self.e0
        e_beta = np.cross(e_S, self.en)
        e_beta /= np.linalg.norm(e_beta)
        e_gamma = np.cross(e_S, np.cross(self.en, e_S))
        e_gamma /= np.linalg.norm(e_gamma)
        out = np.zeros((3, 3))
        basis = dict(S=(e_S, 1.0), M_beta=(e_beta, self.length ** -2),
                     M_gamma=(e_gamma, self.length ** -2))
        for el in self.elements:
            vec, scale = basis[el.name]
            theta = el.curve.param_values
            out += el.curve.slope(0.0, 0.0, theta) * scale * np.outer(vec, vec)
        return out
