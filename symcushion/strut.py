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
from .characteristics import Curve, Linear
from .validation import direction, real, vector

__all__ = ["HingedStrut", "RIGID_AXIAL_RATIO", "SINGULAR_ANGLE", "leg_geometry_expr"]

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


def _vector(name, value, *, unit=False):
    return direction(name, value) if unit else vector(name, value, (3,))


def _unit(v):
    return v / ca.norm_2(v)


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


def memory_functions_of(leg) -> dict[str, ca.Function]:
    """The memory law's named Functions of any leg scheme with ``memory_force_expr``,
    ``next_sets_expr``, ``free_foot_expr``, ``deflections_expr`` and ``param_names``."""
    r, r_regime = ca.SX.sym("r", 3), ca.SX.sym("r_regime", 3)
    sets = ca.SX.sym("sets", 3)
    p = ca.SX.sym("p", len(leg.param_names))
    rate = ca.SX.sym("rate_gain"), ca.SX.sym("rate_offset", 3)
    P = leg.memory_force_expr(r, sets, p, rate=rate)
    Dp = ca.jacobian(leg.memory_force_expr(r, sets, p, r_regime, rate), r)
    x0, rate0, dt = ca.SX.sym("deflection_start", 3), ca.SX.sym("mean_rate", 3), ca.SX.sym("dt")
    names = ["r", "sets", "p", "rate_gain", "rate_offset"]
    return {
        "strut_force_memory": ca.Function("strut_force_memory", [r, sets, p, *rate], [P],
                                          names, ["P"]),
        "strut_stiffness_memory": ca.Function("strut_stiffness_memory",
                                              [r, sets, p, *rate, r_regime], [Dp],
                                              names + ["r_regime"], ["Dp"]),
        "strut_next_set": ca.Function("strut_next_set", [r, sets, p],
                                      [leg.next_sets_expr(r, sets, p)],
                                      ["r", "sets", "p"], ["next_set"]),
        "strut_deflections": ca.Function("strut_deflections", [r], [leg.deflections_expr(r)],
                                         ["r"], ["x"]),
        "strut_free_foot": ca.Function(
            "strut_free_foot", [sets, p, x0, rate0, dt],
            [leg.free_foot_expr(sets, p, x0, rate0, dt)],
            ["sets", "p", "deflection_start", "mean_rate", "dt"], ["r"]),
    }


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
                 axial_ratio: float = RIGID_AXIAL_RATIO):
        self.hinge = _vector("hinge", hinge)
        self.e0 = _vector("e0", e0, unit=True)
        self.en = _vector("en", en, unit=True)
        self.length = real("length", length, positive=True, unit="m")
        cos0 = float(self.e0 @ self.en)
        angle = np.arccos(np.clip(abs(cos0), 0.0, 1.0))
        if angle < SINGULAR_ANGLE:
            raise ValueError(
                f"`e0` is parallel to `en` (angle {np.rad2deg(angle):.3g}° < "
                f"{np.rad2deg(SINGULAR_ANGLE):g}°): e_β of (2.1) is undefined there; "
                "tilt `en` away from the strut.")
        if np.pi / 2 - angle < SINGULAR_ANGLE:
            raise ValueError(
                f"`e0` is perpendicular to `en` (angle {np.rad2deg(angle):.4g}° from the "
                "axis line): γ of (2.1) has a kink there (docs/paper-notes.md §2); tilt `en` so that the "
                "strut makes an angle strictly between 0° and 90° with it.")
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
        self._functions = None
        self._memory_functions = None

    # -- parameters -----------------------------------------------------------
    @property
    def param_names(self) -> tuple[str, ...]:
        """Names of the entries of ``p`` (tunable curves only), e.g. ``S.k``."""
        return tuple(f"{el.name}.{n}" for el in self.elements if el.curve.tunable
                     for n in el.curve.param_names)

    @property
    def param_values(self) -> np.ndarray:
        """Default values of ``p``."""
        vals = [el.curve.param_values for el in self.elements if el.curve.tunable]
        return np.concatenate(vals) if vals else np.zeros(0)

    @property
    def rest_foot(self) -> np.ndarray:
        """Foot position at the unloaded rest pose, r_h + L₀ e₀ (m)."""
        return self.hinge + self.length * self.e0

    def _theta(self, el: _Element, p):
        if el.curve.tunable:
            return p[el.offset:el.offset + el.curve.n_params]
        return None

    # -- symbolic model ---------------------------------------------------------
    def geometry(self, r):
        """Geometry of (2.1) at foot position ``r`` (CasADi expression)."""
        g = leg_geometry_expr(r, ca.DM(self.hinge), ca.DM(self.e0), ca.DM(self.en))
        g["delta_S"] = g["L"] - self.length
        return g

    def rates(self, g, v):
        """Deflection rates of (S, M_β, M_γ) whose signs select the branches (2.1)."""
        # β′ ≈ (V·e_β)/L, so that x·ẋ is in rad²/s like RATE_WIDTH says.
        return dict(S=ca.dot(v, g["e_S"]),
                    M_beta=ca.dot(v, g["e_beta"]) / g["L"],
                    M_gamma=-self.sigma * ca.dot(v, g["e_gamma"]) / g["L"])

    def _deflections(self, g):
        return dict(S=g["delta_S"], M_beta=g["beta"], M_gamma=g["gamma"] - self.gamma0)

    def element_forces(self, g, v, p, g_branch=None):
        """S, M_β, M_γ of (2.1), with the orientation sign of M_γ applied.

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
        out["M_gamma"] = -self.sigma * out["M_gamma"]                  # docs/paper-notes.md §2
        return out

    def force_expr(self, r, v, p, r_branch=None):
        """P(r) of (2.1) as a CasADi expression (N).

        ``r_branch`` (default ``r``): the foot position whose deflections and
        rates select the branches; the stiffness differentiates with it held.
        """
        g = self.geometry(r)
        f = self.element_forces(g, v, p, None if r_branch is None else self.geometry(r_branch))
        return (f["S"] * g["e_S"] + f["M_beta"] / g["L"] * g["e_beta"]
                + f["M_gamma"] / g["L"] * g["e_gamma"])                # (2.1)

    def stiffness_paper_expr(self, r, v, p):
        """D_p from the hand formula (2.3), column by column (2.2)."""
        g = self.geometry(r)
        en, e0 = ca.DM(self.en), ca.DM(self.e0)
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

    def deflections_expr(self, r):
        """(δ_S, β, γ − γ₀): the elements' own deflections at foot ``r`` (m, rad)."""
        x = self._deflections(self.geometry(r))
        return ca.vertcat(x["S"], x["M_beta"], x["M_gamma"])

    def _axial(self) -> _Element:
        return next(el for el in self.elements if el.name == "S")

    def memory_force_expr(self, r, sets, p, r_regime=None, rate=None):
        """P(r) of (2.1) with the elements on the memory law (A1) at ``sets``.

        ``sets`` (3): the sets of (S, M_β, M_γ); an element that keeps none
        takes its loading curve (the hinge springs, whose memory the scene
        refuses). ``r_regime`` (default ``r``): the foot position that picks each
        element's regime (``absorber.memory_force``). ``rate`` = (a, b): the
        deflection rates of the dampers are a·x + b, the affine form of (A3),
        with x = (δ_S, β, γ − γ₀) and b of length 3.
        """
        g = self.geometry(r)
        x = self._deflections(g)
        x_regime = None if r_regime is None else self._deflections(self.geometry(r_regime))
        forces = dict(S=0.0, M_beta=0.0, M_gamma=0.0)
        for el in self.elements:
            k = _ELEMENT_ORDER.index(el.name)
            forces[el.name] = absorber.element_force(
                el.curve, x[el.name], sets[k], self._theta(el, p),
                None if x_regime is None else x_regime[el.name],
                None if rate is None else rate[0] * x[el.name] + rate[1][k])
        forces["M_gamma"] = -self.sigma * forces["M_gamma"]            # docs/paper-notes.md §2
        return (forces["S"] * g["e_S"] + forces["M_beta"] / g["L"] * g["e_beta"]
                + forces["M_gamma"] / g["L"] * g["e_gamma"])           # (2.1)

    def next_sets_expr(self, r, sets, p):
        """The sets after the foot reached ``r`` (A2), in the order (S, M_β, M_γ)."""
        x = self._deflections(self.geometry(r))
        out = [sets[k] for k in range(3)]
        for el in self.elements:
            k = _ELEMENT_ORDER.index(el.name)
            out[k] = absorber.element_next_set(el.curve, x[el.name], sets[k], self._theta(el, p))
        return ca.vertcat(*out)

    def free_foot_expr(self, sets, p, x_start, mean_rate, dt):
        """A free foot at the end of a step (body frame): along e₀ at the axial
        element's free stroke, or relaxing towards it behind a damper (A4); the
        hinge angles at rest."""
        el = self._axial()
        free = absorber.relaxed_deflection(el.curve, x_start[0], sets[0], mean_rate[0], dt,
                                           self._theta(el, p))
        return ca.DM(self.hinge) + (self.length + free) * ca.DM(self.e0)

    def memory_functions(self) -> dict[str, ca.Function]:
        """The named Functions of the memory law (A1)-(A4) for a leg that keeps a set
        or has a damper (``axial_state``); built once, cached. Shared by every leg
        scheme (docs/tripod.md, "Leg schemes"): ``sets``, ``rate_offset``,
        ``deflection_start`` and ``mean_rate`` have one entry per element.

        ``strut_force_memory(r, sets, p, rate_gain, rate_offset) -> P`` (the
        dampers' rates a·x + b, (A3)), ``strut_stiffness_memory(..., r_regime)
        -> Dp`` (∂P/∂r in the regime that ``r_regime`` picks, the dampers' a·c
        included), ``strut_next_set(r, sets, p) -> next_set`` (A2),
        ``strut_free_foot(sets, p, deflection_start, mean_rate, dt) -> r`` (a
        free foot at the end of a step, body frame, (A4)) and
        ``strut_deflections(r) -> x`` (each element's deflection).
        """
        if not self.axial_state:
            raise ValueError("this leg's elements keep no state (a crushable element, "
                             "one with an unloading curve, or a damped one does); use "
                             "`functions()`.")
        if self._memory_functions is None:
            self._memory_functions = memory_functions_of(self)
        return self._memory_functions

    def loading_set(self, r, p=None) -> float:
        """The axial set of a foot at ``r`` reached along the loading curve (A2)."""
        el = self._axial()
        delta_S = float(ca.evalf(self.geometry(ca.DM(self._check_r(r)))["delta_S"]))
        theta = self._theta(el, self._p(p))
        return float(ca.evalf(absorber.set_on_loading(el.curve, delta_S, theta)))

    # -- Functions --------------------------------------------------------------
    def functions(self) -> dict[str, ca.Function]:
        """The named CasADi Functions of this strut (built once, cached).

        Returns
        -------
        dict
            ``strut_force(r, v, p) -> P``, ``strut_stiffness(r, v, p) -> Dp``
            (``casadi.jacobian``), ``strut_stiffness_paper(r, v, p) -> Dp``
            ((2.3) by hand) and ``strut_geometry(r) -> L, delta_S, beta, gamma,
            e_S, e_beta, e_gamma``. ``r``: foot position (3, m, body frame);
            ``v``: foot velocity relative to the hinge (3, m/s; selects the
            branches); ``p``: tunable parameters (``param_names``), empty when
            all curves are numeric.

        Notes
        -----
        At the hinge (r = r_h) the strut direction e_S = (r − r_h)/L is 0/0 and
        these raw Functions return NaN; they are inner kernels and do not
        check. The Python boundary (:meth:`force`, :meth:`stiffness`) rejects
        a foot within 1e-9 L₀ of the hinge with a ValueError, and
        ``symcushion.checks.RunMonitor`` reports a non-finite state in a run.
        """
        if self._functions is None:
            r = ca.SX.sym("r", 3)
            v = ca.SX.sym("v", 3)
            p = ca.SX.sym("p", len(self.param_names))
            P = self.force_expr(r, v, p)
            # D_p = ∂P/∂r with the branches held (the active branch's slope, as
            # in (2.3)): with smooth curves the branch weight w(x·ẋ) also
            # depends on r, and its derivative ẋ/(2·rate_width)·(f_L − f_U) is
            # not a stiffness — it can make D_p indefinite at touchdown.
            r_branch = ca.SX.sym("r_branch", 3)
            Dp = ca.substitute(ca.jacobian(self.force_expr(r, v, p, r_branch), r), r_branch, r)
            Dp_paper = self.stiffness_paper_expr(r, v, p)
            g = self.geometry(r)
            names_in = ["r", "v", "p"]
            self._functions = {
                "strut_force": ca.Function("strut_force", [r, v, p], [P], names_in, ["P"]),
                "strut_stiffness": ca.Function("strut_stiffness", [r, v, p], [Dp],
                                               names_in, ["Dp"]),
                "strut_stiffness_paper": ca.Function("strut_stiffness_paper", [r, v, p],
                                                     [Dp_paper], names_in, ["Dp"]),
                "strut_geometry": ca.Function(
                    "strut_geometry", [r],
                    [g["L"], g["delta_S"], g["beta"], g["gamma"], g["e_S"], g["e_beta"],
                     g["e_gamma"]],
                    ["r"], ["L", "delta_S", "beta", "gamma", "e_S", "e_beta", "e_gamma"]),
            }
        return self._functions

    # -- the leg-scheme interface (docs/tripod.md, "Leg schemes") ---------------------
    #: The axial element: its stroke is the leg's ``stroke`` output and its curve's
    #: stroke limit the one the run's bottoming check reads.
    axial_element = "S"
    #: Which elements' deflections a free foot relaxes over a step (A4); the hinge
    #: angles return to rest at once.
    relaxes_free = (1.0, 0.0, 0.0)

    def deflections(self, geo) -> dict:
        """Each element's own deflection from ``strut_geometry``'s outputs ``geo``:
        δ_S (m), β and γ − γ₀ (rad)."""
        return {"S": geo["delta_S"], "M_beta": geo["beta"], "M_gamma": geo["gamma"] - self.gamma0}

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
        """P(r) of (2.1) as a NumPy array (N); validates its inputs."""
        out = self.functions()["strut_force"](self._check_r(r), _vector("v", v), self._p(p))
        return np.asarray(out, dtype=float).ravel()

    def stiffness(self, r, v=(0.0, 0.0, 0.0), p=None, *, paper=False) -> np.ndarray:
        """D_p = ∂P/∂r (3×3, N/m) by AD, or by (2.3) with ``paper=True``."""
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
