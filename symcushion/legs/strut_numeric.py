"""NumPy evaluation of a hinged strut: validated calls of its Functions.

:class:`StrutEvaluation` is the part of :class:`~symcushion.legs.strut.HingedStrut`
that turns its CasADi Functions into checked NumPy calls —
:meth:`~StrutEvaluation.force`, :meth:`~StrutEvaluation.stiffness`,
:meth:`~StrutEvaluation.loading_set` — and the closed-form rest stiffness of
docs/paper-notes.md §2 the tests hold them against. It owns the validation of
a foot position; it must not build an expression or a Function
(``symcushion.legs.strut`` does) and is not used on its own.
"""
from __future__ import annotations

import casadi as ca
import numpy as np

from symcushion.legs import absorber
from symcushion.legs.leg_scheme import checked_params
from symcushion.validation import vector

__all__ = ["StrutEvaluation"]


class StrutEvaluation:
    """NumPy calls of a hinged strut's Functions, mixed into ``HingedStrut``.

    Reads the strut's ``hinge``, ``e0``, ``en``, ``length``, ``law``,
    ``elements``, ``geometry``, ``functions()``, ``_axial`` and ``_theta``.
    """

    def loading_set(self, r, p=None) -> float:
        """The axial set of a foot at ``r`` reached along the loading curve (A2)."""
        el = self._axial()
        delta_S = float(ca.evalf(self.geometry(ca.DM(self._check_r(r)))["delta_S"]))
        theta = self._theta(el, checked_params(self, p))
        return float(ca.evalf(absorber.set_on_loading(el.curve, delta_S, theta)))

    def _check_r(self, r):
        r = vector("r", r, (3,))
        if np.linalg.norm(r - self.hinge) < 1e-9 * self.length:
            raise ValueError(f"`r` = {r.tolist()} is at the hinge {self.hinge.tolist()}: the "
                             "strut direction is undefined; give a foot position away from it.")
        return r

    def force(self, r, v=(0.0, 0.0, 0.0), p=None) -> np.ndarray:
        """P(r) of the strut's law as a NumPy array (N); validates its inputs."""
        out = self.functions()["strut_force"](self._check_r(r), vector("v", v, (3,)),
                                              checked_params(self, p))
        return np.asarray(out, dtype=float).ravel()

    def stiffness(self, r, v=(0.0, 0.0, 0.0), p=None, *, paper=False) -> np.ndarray:
        """D_p = ∂P/∂r (3×3, N/m) by AD, or by (2.3) with ``paper=True`` (paper law only)."""
        if paper and self.law != "paper":
            raise ValueError("`paper=True` asks for the hand formula (2.3) of (2.1); this strut "
                             f"has law = {self.law!r}, whose D_p is only by AD; drop `paper`.")
        name = "strut_stiffness_paper" if paper else "strut_stiffness"
        out = self.functions()[name](self._check_r(r), vector("v", v, (3,)),
                                     checked_params(self, p))
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
