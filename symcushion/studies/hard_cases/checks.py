"""Checks of a hard-case run: tolerances, invariants, statistics per chunk, verdicts.

Owns the tolerances (each justified in docs/hard-cases.md), the CasADi
function of the mechanical energy and the feet's distances, the worst
values of a run (:class:`Stats`) and the verdicts of a case run with one
method (:class:`Result`). It must not build scenes, run models or format
tables.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from symcushion.legs.characteristics import Linear
from symcushion.layout.vectors import state_layout
from symcushion.scheme.quaternion import quat_to_rot, quat_to_rot_np
from symcushion.model.obstacles import closest_obstacle
from symcushion.model.scene_data import Scene

from .cases import Setup

# -- tolerances of the checks (docs/hard-cases.md says why each is what it is) --
#: Cone excess (|F_τ| − μF_n)/|F| allowed on a foot in contact. The robust and
#: implicit steps project the force onto the cone (round-off, ~1e-16); 1e-9
#: leaves room for cond(D_p)·eps with D_p conditioned up to 1e7, and is still
#: far below any physical violation.
CONE_TOL = 1e-9
#: Penetration allowed, relative to the longest leg: a foot in contact is
#: projected onto the surface (round-off, ~1e-16 m), a free foot sits at its
#: unloaded pose and must be outside. 1e-9·L₀ is sub-nanometre.
PENETRATION_TOL = 1e-9
#: Energy gain allowed, relative to the case's energy scale (kinetic energy at
#: impact + m g L₀ + the initial elastic energy). Velocity Verlet conserves a
#: shadow energy; the true energy fluctuates about it by O((ωΔt)²) of the
#: energy of each mode — at most 3.1e-4 of the scale in these cases where the
#: step is right — while friction and the contact steps may only remove energy.
ENERGY_TOL = 1e-3
#: Net work of the obstacle on the feet allowed, relative to the energy scale:
#: a rigid obstacle does no work on a sticking foot and friction only takes
#: energy from a slipping one, so the cumulative work may exceed 0 by
#: round-off only (measured ≤ 2e-15 of the scale where the Coulomb law holds).
WORK_TOL = 1e-9
#: Symmetry error allowed (dimensionless, see :func:`symmetry_error`): round-off
#: grows with the steps, ~1e-12 after 1e5 steps.
SYMMETRY_TOL = 1e-8
#: Creep allowed on a sticking foot or body over the whole run (m).
CREEP_TOL = 1e-9


def _linear_energy(curve, x):
    """Energy stored in a linear element deflected by x: f₀x + ½kx² (J)."""
    if not isinstance(curve, Linear) or curve.unloading is not None:
        raise TypeError(f"the hard cases compute elastic energy for Linear curves without "
                        f"unloading only, got {curve!r}.")
    k, preload = curve.param_values
    return preload * x + 0.5 * k * x ** 2


def invariant_function(scene: Scene) -> ca.Function:
    """``hard_case_invariants(x) -> (E, d)``: mechanical energy (J) and feet's distances (m).

    E = ½m|v|² + ½ωᵀIω − m g·x + Σ elastic energy of each leg element at its
    deflection (δ_S, β, γ − γ₀), a free leg at its unloaded pose; d_j is the
    signed distance of foot j from the obstacle (positive outside).
    """
    xl = state_layout(len(scene.legs))
    x = ca.SX.sym("x", xl.size)
    body = scene.body
    pos, vel, quat, omega = (xl.get(x, k) for k in ("position", "velocity", "attitude",
                                                     "angular_velocity"))
    R = quat_to_rot(quat)
    energy = (0.5 * body.mass * ca.dot(vel, vel)
              + 0.5 * ca.dot(omega, ca.DM(body.inertia) @ omega)
              - body.mass * ca.dot(ca.DM(scene.gravity), pos))
    dists = []
    for j, leg in enumerate(scene.legs):
        foot = xl.get(x, "foot", j)
        rho = ca.if_else(xl.get(x, "contact", j) > 0.5, R.T @ (foot - pos),
                         ca.DM(leg.rest_foot))
        geo = leg.geometry(rho)
        deflection = dict(S=geo["delta_S"], M_beta=geo["beta"],
                          M_gamma=geo["gamma"] - leg.gamma0)
        for el in leg.elements:
            energy = energy + _linear_energy(el.curve, deflection[el.name])
        dists.append(closest_obstacle(scene.obstacles, foot)[0])
    return ca.Function("hard_case_invariants", [x], [energy, ca.vertcat(*dists)], ["x"],
                       ["E", "d"])


@dataclass
class Stats:
    """Worst values of the checks over a run, accumulated chunk by chunk."""

    finite: bool = True
    cone: float = -np.inf           # max (|F_τ| − μF_n)/|F| over feet in contact
    penetration: float = 0.0        # max depth of a foot below the obstacle (m)
    energy0: float = np.nan         # E at t = 0 (J)
    energy_gain: float = -np.inf    # max E(t) − E(0) (J)
    energy_end: float = np.nan
    symmetry: float = 0.0
    creep_foot: float = 0.0         # max displacement of a foot from its first contact point
    creep_body: float = 0.0
    criterion: float = 0.0          # max 1 − n_k·n_{k+1}
    landings: int = 0               # free → contact transitions of any foot
    lift_offs: int = 0
    work: float = 0.0               # work of the obstacle on the feet so far (J)
    work_max: float = 0.0           # max over t of that cumulative work (J)
    singular: float = np.inf        # min angle of a loaded strut to e_n's line or plane (rad)
    steps: int = 0
    t_end: float = 0.0

    def update(self, scene, inv, traj, first_row):
        """Fold one chunk (a Trajectory whose row 0 is the chunk's start state) in."""
        arrays = (traj.position, traj.velocity, traj.attitude, traj.angular_velocity,
                  traj.force, traj.foot)
        if not all(np.all(np.isfinite(a)) for a in arrays):
            self.finite = False
            return
        X = traj.states()
        E, d = inv.map(X.shape[1])(X)
        E, d = np.asarray(E).ravel(), np.asarray(d).reshape(-1, X.shape[1]).T
        if first_row:
            self.energy0 = E[0]
        self.energy_gain = max(self.energy_gain, float(np.max(E - self.energy0)))
        self.energy_end = float(E[-1])
        self.penetration = max(self.penetration, float(np.max(-d)))
        rows = slice(1, None)                     # rows with step outputs
        F, n, c = traj.force[rows], traj.normal[rows], traj.contact[rows] > 0.5
        Fn = np.einsum("tni,tni->tn", F, n)
        Ft = np.linalg.norm(F - Fn[..., None] * n, axis=2)
        Fabs = np.linalg.norm(F, axis=2)
        loaded = c & (Fabs > 0)
        if loaded.any():
            excess = (Ft - scene.mu * Fn)[loaded] / Fabs[loaded]
            self.cone = max(self.cone, float(np.max(excess)))
        self.criterion = max(self.criterion, float(np.max(traj.criterion)))
        contact = traj.contact > 0.5
        # obstacle's work on the feet, P_{k+1}·(r_{k+1} − r_k) over steps in contact
        # at both ends: the end force, as in the backward-Euler Coulomb step, whose
        # friction opposes the slip exactly (a trapezoid would charge the slip of a
        # stick → slip step with the large start force); a touchdown or lift-off
        # step moves a foot to or from its free pose, not along the obstacle
        both = contact[:-1] & contact[1:]
        dW = np.einsum("tni,tni->tn", traj.force[1:], np.diff(traj.foot, axis=0))
        cumulative = self.work + np.cumsum(np.where(both, dW, 0.0).sum(axis=1))
        self.work_max = max(self.work_max, float(np.max(cumulative, initial=0.0)))
        self.work = float(cumulative[-1]) if len(cumulative) else self.work
        self.singular = min(self.singular, _singular_distance(scene, traj))
        self.landings += int(np.sum(~contact[:-1] & contact[1:]))
        self.lift_offs += int(np.sum(contact[:-1] & ~contact[1:]))
        self.steps += len(traj.t) - 1
        self.t_end = float(traj.t[-1])

    def update_creep(self, traj, reference):
        """Largest displacement of feet and body from ``reference`` (foot, position)."""
        foot0, pos0 = reference
        self.creep_foot = max(self.creep_foot,
                              float(np.max(np.linalg.norm(traj.foot - foot0, axis=2))))
        self.creep_body = max(self.creep_body,
                              float(np.max(np.linalg.norm(traj.position - pos0, axis=1))))


def _singular_distance(scene, traj):
    """Smallest angle (rad) of a strut in contact to its hinge's singular sets.

    The sets of docs/paper-notes.md §2: e_S ∥ e_n (e_β undefined, D_p ~ 1/|e_S × e_n|) and
    e_S ⊥ e_n (the kink of γ); the angle is min(∠(e_S, ±e_n), |90° − ∠|).
    """
    R = quat_to_rot_np(traj.attitude, normalise=False)
    best = np.inf
    for j, leg in enumerate(scene.legs):
        c = traj.contact[:, j] > 0.5
        if not c.any():
            continue
        rho = np.einsum("tji,tj->ti", R[c], traj.foot[c, j] - traj.position[c])
        e_S = rho - leg.hinge
        e_S /= np.linalg.norm(e_S, axis=1)[:, None]
        angle = np.arccos(np.clip(np.abs(e_S @ leg.en), 0.0, 1.0))
        best = min(best, float(np.min(np.minimum(angle, np.pi / 2 - angle))))
    return best


def symmetry_error(kind, traj, length):
    """Symmetry error of a chunk (dimensionless).

    ``axial`` (symmetric about the vertical axis through the centre of mass,
    and mirror symmetric): max of |x|, |y| over L₀, the quaternion's vector
    part, and the spread of the legs' force magnitudes over the largest.
    ``c4`` (fourfold, not mirror): the same but a yaw (q_z) is allowed.
    ``mirror`` (about the xz plane): |y|/L₀, q_x, q_z.
    """
    q = traj.attitude
    if kind == "mirror":
        return float(max(np.max(np.abs(traj.position[:, 1])) / length,
                         np.max(np.abs(q[:, [1, 3]]))))
    tilt = q[:, 1:4] if kind == "axial" else q[:, 1:3]
    forces = np.linalg.norm(traj.force, axis=2)
    scale = max(float(np.max(forces)), 1e-300)
    spread = float(np.max(forces.max(axis=1) - forces.min(axis=1))) / scale
    return float(max(np.max(np.abs(traj.position[:, :2])) / length, np.max(np.abs(tilt)),
                     spread))


@dataclass
class Result:
    """One row of the table: a case run with one method."""

    case: str
    method: str
    dt: float
    stats: Stats
    energy_scale: float
    length: float
    setup: Setup
    adaptive: dict = field(default_factory=dict)
    wall: float = 0.0

    @property
    def checks(self) -> dict:
        """Each check's verdict (True = holds); a non-finite run fails every one."""
        s = self.stats
        out = {"finite": s.finite}
        if not s.finite:
            return out
        out["cone"] = s.cone <= CONE_TOL
        out["penetration"] = s.penetration <= PENETRATION_TOL * self.length
        if self.setup.energy == "mechanical":
            out["energy"] = s.energy_gain <= ENERGY_TOL * self.energy_scale
        out["foot work"] = s.work_max <= WORK_TOL * self.energy_scale
        if self.setup.symmetry:
            out["symmetry"] = s.symmetry <= SYMMETRY_TOL
        if self.setup.creep:
            body = s.creep_body if self.setup.creep == "feet+body" else 0.0
            out["creep"] = max(s.creep_foot, body) <= CREEP_TOL
        return out

    @property
    def passed(self) -> bool:
        return all(self.checks.values())

    @property
    def failures(self) -> list:
        return [k for k, ok in self.checks.items() if not ok]
