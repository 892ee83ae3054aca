"""A compliant strut on a spherical hinge: the force law (2.1) and its stiffness.

The strut of Khvostov (1976) §2 is fixed to the body by a spherical hinge at
r_h; a foot at r carries the contact load. The force on the foot *from the
obstacle* that holds it at r (P = −P_h, the paper's sign) is

    P = S e_S + (1/L) M_β e_β + (1/L) M_γ e_γ                          (2.1)

with L = |r − r_h|, δ_S = L − L₀, e_S = (r − r_h)/L,
e_β = e_S × e_n/|e_S × e_n|, β = −arcsin(e₀·e_β),
e_γ = e_S × (e_n × e_S)/|e_S × (e_n × e_S)|, γ = arcsin(e_n·e_γ).

This module owns the force law of one strut, its stiffness and the CasADi
Functions built on them; the geometry of (2.1) is
``symcushion.legs.strut_geometry``'s, the memory law's expressions and Functions
``symcushion.legs.strut_memory``'s, the validated NumPy calls
``symcushion.legs.strut_numeric``'s (mixed into :class:`HingedStrut`). It knows
nothing of contact or of the body's motion.

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
``symcushion.legs.strut_geometry.GEOMETRY_SIZE`` entries of ``p``
(``functions(geometry="input")``), so that one compiled step serves every
geometry; e₀ and e_n are then
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

from symcushion.legs.leg_scheme import CurveParams
from symcushion.legs.characteristics import Curve, Linear
from symcushion.layout.vectors import LEG_GEOMETRY_FIELDS
from symcushion.legs.strut_geometry import GEOMETRY_SIZE, HingeGeometry, check_angle
from symcushion.legs.strut_memory import StrutMemory
from symcushion.legs.strut_numeric import StrutEvaluation
from symcushion.validation import direction, real, vector

__all__ = ["HingedStrut", "RIGID_AXIAL_RATIO", "LAWS", "DEFAULT_LAW", "GEOMETRY_MODES"]

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


def _vector(name, value, *, unit=False):
    return direction(name, value) if unit else vector(name, value, (3,))


@dataclass(frozen=True)
class _Element:
    name: str            # 'S', 'M_beta', 'M_gamma'
    curve: Curve
    offset: int          # start of its parameters in p (tunable only)


class HingedStrut(CurveParams, HingeGeometry, StrutMemory, StrutEvaluation):
    """A strut on a spherical hinge with axial and bending elements (Fig. 2).

    Parameters
    ----------
    hinge : array_like, shape (3,)
        Hinge position r_h in body coordinates (m).
    e0 : array_like, shape (3,)
        Rest direction of the strut (normalised here).
    en : array_like, shape (3,)
        Polar axis e_n of the hinge (normalised here); must make an angle of
        at least ``symcushion.legs.strut_geometry.SINGULAR_ANGLE`` with e₀ and with
        the plane ⊥ e₀.
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
    >>> from symcushion.legs.characteristics import Linear
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
        cos0 = check_angle(self.e0, self.en)
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

    # -- parameters (param_names, param_values: CurveParams) ------------------
    def _theta(self, el: _Element, p):
        if el.curve.tunable:
            return p[el.offset:el.offset + el.curve.n_params]
        return None

    # -- symbolic model ---------------------------------------------------------
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
        ``symcushion.run.checks.RunMonitor`` reports a non-finite state in a run.
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
    #: The fields of the strut's geometry block in ``p`` (``symcushion.layout.vectors``).
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
        """The per-leg output fields of the deflections (``symcushion.layout.vectors``)."""
        x = self.deflections(geo)
        return dict(stroke=x["S"], beta=x["M_beta"], gamma_deflection=x["M_gamma"],
                    secondary_stroke=ca.DM.zeros(2))

    def element_extent(self, name: str) -> float:
        """The range of an element's deflection worth sampling (m or rad)."""
        return self.length if name == "S" else np.pi / 2

