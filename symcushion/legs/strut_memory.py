"""The hinged strut on the memory law: its expressions and named Functions.

:class:`StrutMemory` is the part of :class:`~symcushion.legs.strut.HingedStrut`
whose elements keep a set or have a damper (``symcushion.legs.absorber``,
docs/absorbers.md): the force of the strut's law with the elements on the
memory law (A1) at given sets, the sets after a step (A2), (A5), the crush
curve of the axial element, a free foot relaxing behind its dampers (A4), and
the named Functions of (A1)-(A4) the step calls (built by
``symcushion.legs.leg_scheme``). It must not build the memoryless Functions, hold
the geometry of (2.1) (``symcushion.legs.strut_geometry``) or know contact or the
body, and is not used on its own.
"""
from __future__ import annotations

import casadi as ca

from symcushion.legs import absorber
from symcushion.legs.leg_scheme import band_part, cached_memory_functions, elastic_line

__all__ = ["StrutMemory", "FREE_FOOT_NEWTON_STEPS"]

#: Newton steps that put a free foot where its relaxed deflections meet: it starts
#: from the foot with the hinges at rest, a few mrad away, and the map from the foot
#: to (δ_S, β, γ) is smooth there, so three steps reach round-off.
FREE_FOOT_NEWTON_STEPS = 3

#: The elements of a hinged strut, in the order of their sets and rates.
_ELEMENT_ORDER = ("S", "M_beta", "M_gamma")


class StrutMemory:
    """The memory law's expressions and Functions of a hinged strut, mixed into
    ``HingedStrut``.

    Reads the strut's ``elements``, ``geometry``, ``_deflections``,
    ``_geometry_of``, ``_theta`` and ``_assemble``; ``symcushion.legs.leg_scheme``
    reads its ``_p_size`` and cache ``_memory_functions``.
    """

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

    def _axial(self):
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

    def axial_elastic_line_expr(self, x, s, rate, p):
        """The axial element's elastic line through its set ``s`` at deflection ``x`` (N):
        k_e (x − s) + c·ė, the trial force of (A1) with its damper (A5), ė the elastic
        deflection's rate ``rate`` (m/s); what the element carries between its bounds."""
        el = self._axial()
        return elastic_line(el.curve, x, s, rate, self._theta(el, p))

    def axial_band_force_expr(self, r, P, rate, p):
        """The axial element's force (A1), (A5) that the foot force ``P`` (N, body axes)
        carries at foot ``r``: S of P = S e_S + (M_β/L) e_β + (M_γ/L) e_γ (2.1), or of
        P = Jᵀ f (the potential law), less its end stop and its orifice damper at the
        elastic deflection's rate ``rate`` (N)."""
        g = self.geometry(r, p)
        if self.law == "paper":
            A = ca.horzcat(g["e_S"], g["e_beta"] / g["L"], g["e_gamma"] / g["L"])   # (2.1)
        else:
            A = self.deflection_gradients(r, p).T
        el = self._axial()
        return band_part(el.curve, self._deflections(g)["S"], ca.solve(A, P)[0], rate,
                         self._theta(el, p))

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
