"""NumPy evaluation of an inverted-tripod leg: validated calls of its Functions.

:class:`TripodEvaluation` is the part of
:class:`~symcushion.legs.tripod.InvertedTripod` that turns its CasADi Functions
into checked NumPy calls — :meth:`~TripodEvaluation.force`,
:meth:`~TripodEvaluation.stiffness`, :meth:`~TripodEvaluation.strokes`,
:meth:`~TripodEvaluation.forces` — and the closed-form rest stiffness the
tests hold them against. It owns the validation of a foot position (a
parameter vector's is ``symcushion.legs.leg_scheme.checked_params``); it must not
build an expression or a Function (``symcushion.legs.tripod`` does) and is not
used on its own.
"""
from __future__ import annotations

import numpy as np

from symcushion.legs.leg_scheme import checked_params
from symcushion.legs.tripod_geometry import ZERO_LENGTH, numeric_geometry
from symcushion.validation import vector

__all__ = ["TripodEvaluation"]


class TripodEvaluation:
    """NumPy calls of an inverted tripod's Functions, mixed into ``InvertedTripod``.

    Reads the leg's ``h1``, ``h2``, ``h3``, ``foot``, ``outer_length``,
    ``length``, ``elements``, ``param_names``, ``param_values`` and
    ``functions()``.
    """


    def _check_r(self, r):
        r = vector("r", r, (3,))
        if np.linalg.norm(r - self.h1) < ZERO_LENGTH * self.length:
            raise ValueError(f"`r` = {r.tolist()} is at the hardpoint h1 {self.h1.tolist()}: "
                             "the primary's axis is undefined; give a foot position away "
                             "from it.")
        return r

    def _call(self, name, r, v, p):
        out = self.functions()[name](self._check_r(r), vector("v", v, (3,)),
                                     checked_params(self, p))
        return np.asarray(out, dtype=float)

    def force(self, r, v=(0.0, 0.0, 0.0), p=None) -> np.ndarray:
        """P(r) of (T1) as a NumPy array, shape (3,) (N); validates its inputs."""
        return self._call("tripod_force", r, v, p).ravel()

    def stiffness(self, r, v=(0.0, 0.0, 0.0), p=None) -> np.ndarray:
        """D_p = ∂P/∂r by AD, shape (3, 3) (N/m)."""
        return self._call("tripod_stiffness", r, v, p)

    def strokes(self, r) -> np.ndarray:
        """q = (δ_S, δ₂, δ₃) at foot position ``r``, shape (3,) (m)."""
        geo = self.functions()["tripod_geometry"].call(dict(r=self._check_r(r)))
        return np.concatenate([np.asarray(geo["delta_S"]).ravel(),
                               np.asarray(geo["stroke_secondary"]).ravel()])

    def forces(self, r, v=(0.0, 0.0, 0.0), p=None) -> np.ndarray:
        """f = (S, T₂, T₃) at foot position ``r``, shape (3,) (N)."""
        fn = self.functions()["tripod_element_forces"]
        out = fn.call(dict(r=self._check_r(r), v=vector("v", v, (3,)), p=checked_params(self, p)))
        return np.concatenate([np.asarray(out["S"]).ravel(), np.asarray(out["T"]).ravel()])

    def rest_stiffness_closed_form(self) -> np.ndarray:
        """D_p at the unloaded rest pose by hand, in NumPy, shape (3, 3) (N/m).

        D_p = k_P e_S e_Sᵀ + Σ_k k_k g_k g_kᵀ, g_k = (ℓ_o/L₀)(I − e_S e_Sᵀ) u_k
        (∂δ_k/∂r, docs/tripod.md), k_i the loading slopes at zero deflection.
        The geometric terms f_i ∇²q_i vanish because every f_i(0) is zero;
        a curve with a preload is refused.
        """
        L, e_S, _, spans = numeric_geometry(self.foot, self.h1, self.h2, self.h3,
                                             self.outer_length)
        across = np.eye(3) - np.outer(e_S, e_S)
        grads = [e_S] + [self.outer_length / L * across @ (s / np.linalg.norm(s))
                         for s in spans]
        out = np.zeros((3, 3))
        for el, grad in zip(self.elements, grads):
            if abs(el.curve.force(0.0)) > 0:
                raise ValueError(f"`{el.name}` carries {el.curve.force(0.0):g} N at rest: the "
                                 "closed form holds at zero load only; use `stiffness`.")
            out += el.curve.slope(0.0) * np.outer(grad, grad)
        return out
