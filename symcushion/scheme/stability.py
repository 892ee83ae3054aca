"""The explicit stability limit of the touchdown step's body update.

This module owns the pose stiffness of the body against its feet held fixed
(``body_stiffness``, D_p by AD), the limit 2/ω_max that it sets on Δt
(:func:`stable_dt`) and the fraction of that limit the adaptive driver
allows (:data:`STABILITY_SAFETY`). It must not build or run the step
(``symcushion.scheme.touchdown``, ``symcushion.run.driver``); it reads a built
:class:`~symcushion.scheme.touchdown.StepModel` and keeps its Function there, as
the model's derived Function ``body_stiffness``
(:meth:`~symcushion.scheme.touchdown.StepModel.derived_function`). The legs'
wrench is the step's own (``symcushion.scheme.body_step.legs_wrench``).
"""
from __future__ import annotations

import casadi as ca
import numpy as np

from symcushion.scheme.body_step import legs_wrench
from symcushion.layout.vectors import param_layout, state_layout
from symcushion.scheme.quaternion import quat_exp, quat_to_rot, quat_to_rot_np
from symcushion.scheme.touchdown import StepModel

__all__ = ["STABILITY_SAFETY", "stable_dt", "body_stiffness"]

#: Fraction of the explicit stability limit 2/ω_max (:func:`stable_dt`) that
#: ``simulate(adaptive=True, stability=True)`` allows per step: ω_max Δt ≤ 1,
#: where velocity Verlet keeps the stiffest mode stable with a frequency error
#: of 5 % (cos ω̃Δt = 1 − (ωΔt)²/2) instead of sitting on the edge of
#: instability (ω Δt = 2). Stable is not accurate: an impact whose energy
#: passes through that mode needs a smaller fraction (docs/hard-cases.md).
STABILITY_SAFETY = 0.5


def body_stiffness(model: StepModel) -> ca.Function:
    """``body_stiffness(x, p) -> K``: 6×6 stiffness of the body pose (world frame).

    K = −∂(ΣF_j, Στ_j)/∂(Δx, Δθ) at Δ = 0: the legs' force and moment on the
    body when it is displaced by Δx and turned by the small world rotation Δθ
    with every foot held where it is — a foot in contact at its stored point,
    a free foot at its unloaded position (as if it touched down there now, so
    that the estimate also covers the next touchdown). D_p enters by AD.
    Built once per model (``model.derived_function("body_stiffness", …)``).
    """
    return model.derived_function("body_stiffness", _build_body_stiffness)


#: The name this module's stiffness Function had before it was public.
_body_stiffness = body_stiffness


def _build_body_stiffness(model: StepModel) -> ca.Function:
    scene = model.scene
    params = param_layout(scene)
    X = ca.SX.sym("x", model.nx)
    p = ca.SX.sym("p", model.np)
    z = ca.SX.sym("z", 6)
    xl = state_layout(model.n_legs)
    pos, R = xl.get(X, "position"), quat_to_rot(xl.get(X, "attitude"))
    R_z = quat_to_rot(quat_exp(z[3:6])) @ R
    pos_z = pos + z[0:3]
    rho, P = [], []
    for j, leg in enumerate(scene.legs):
        held = ca.if_else(xl.get(X, "contact", j) > 0.5, xl.get(X, "foot", j),
                          pos + R @ ca.DM(leg.rest_foot))
        rho.append(R_z.T @ (held - pos_z))
        P.append(leg.functions()["strut_force"](rho[-1], ca.DM.zeros(3), params.leg(p, j)))
    wrench = ca.vertcat(*legs_wrench(rho, P, R_z))         # world axes
    K = ca.substitute(-ca.jacobian(wrench, z), z, ca.DM.zeros(6))
    return ca.Function("body_stiffness", [X, p], [K], ["x", "p"], ["K"])


def stable_dt(model: StepModel, x, p=None) -> float:
    """Explicit stability limit 2/ω_max of the body update at state ``x`` (s).

    ω_max² is the largest |eigenvalue| of M⁻¹K, with M = diag(m I, R I_b Rᵀ)
    the body's mass matrix and K its pose stiffness against feet held fixed
    (:func:`body_stiffness`). Velocity Verlet on ẍ = −ω²x is stable for
    ω Δt < 2; a sliding foot is softer than a held one, so the estimate is
    conservative in slip. Returns ``inf`` when no leg resists (K = 0).

    Parameters
    ----------
    model : StepModel
    x : array_like, shape (nx,)
    p : array_like, optional
        Leg parameters; default the scene's values.
    """
    x = np.asarray(x, dtype=float).ravel()
    if x.shape != (model.nx,):
        raise ValueError(f"`x` must have shape ({model.nx},), got {x.shape}.")
    p = model.default_p if p is None else np.asarray(p, dtype=float)
    K = np.asarray(body_stiffness(model)(x, p), dtype=float)
    R = quat_to_rot_np(state_layout(model.n_legs).get(x, "attitude"))
    body = model.scene.body
    M_inv = np.zeros((6, 6))
    M_inv[:3, :3] = np.eye(3) / body.mass
    M_inv[3:, 3:] = R @ np.linalg.inv(body.inertia) @ R.T
    omega2 = float(np.max(np.abs(np.linalg.eigvals(M_inv @ K))))
    if not np.isfinite(omega2):
        raise FloatingPointError(f"the body stiffness at this state is not finite: {K!r}.")
    return np.inf if omega2 == 0 else 2.0 / np.sqrt(omega2)
