"""Hard-case battery: does each contact method survive the cases that break simulators?

Twelve cases, each run with the three contact steps (the step as printed,
the robust step, the exact implicit Coulomb step):

``stiff_axial``
    axially rigid rods with stiffness ratio 1e8 against bending, sliding on
    the Fig. 4 dome (μ = 0.05), Δt = 1 ms.
``stiff_axial_stick``
    the same rods with μ = 1: the feet stick and hold the stiff direction, so
    the explicit body update needs Δt below 2/ω_max (``stable_dt``); the case
    runs at STIFF_FRACTION·stable_dt and records that Δt = 1 ms diverges.
``grazing``
    a foot skimming a sphere along a line tangent to it (zero gravity).
``simultaneous``
    four feet crossing a plane inside the same step (vertical drop).
``recontact``
    a body bouncing on one leg with flights shorter than Δt = 10 ms: the
    foot leaves the plane and lands again inside one step.
``slope_stick``
    a sled on a 35° slope with μ just above the feet's T/N ≈ tan θ, 100 s:
    no creep.
``high_friction``
    an oblique landing with μ = 2.
``near_singular``
    legs whose struts pass within ~1e-3 rad of their hinge's polar axis
    (e_S ∥ e_n, docs/paper-notes.md §2), where D_p grows like 1/|e_S × e_n|.
``tiny_step`` / ``large_step``
    a compliant lander on a dome with Δt = 1e-6 and Δt = 1e-2.
``fast_impact``
    a stiff lander hitting a large dome at 10 m/s.
``long_rest``
    1000 s of resting contact on a dome at Δt = 1e-2.

For every run the checker reports (definitions in ``docs/hard-cases.md``):
finite results; the worst friction-cone excess (|F_τ| − μF_n)/|F| of a foot
in contact; the worst signed distance of a foot below the obstacle; the
largest gain of the mechanical energy (kinetic + gravity + elastic energy of
the legs' elements, ½kx² + f₀x per linear element) over its initial value,
relative to the case's energy scale; a symmetry error where the scene is
symmetric; the paper's step criterion 1 − n_k·n_{k+1} (max over the run) and,
where the case asks for it, what the adaptive driver did (halvings, smallest
step, steps capped by the stability limit). Long runs use one
``model.rollout(CHUNK)`` fed back chunk by chunk, keeping only these summaries.

Writes ``figures/hard_cases.md`` (the table) and the "Results" section of
``docs/hard-cases.md``. Run from the repository root:
``python studies/hard_cases.py`` (several minutes; ``--cases a,b`` runs some).
"""
from __future__ import annotations

import argparse
import time
from dataclasses import dataclass, field
from pathlib import Path

import casadi as ca
import numpy as np

from symcushion import report
from symcushion.characteristics import Linear
from symcushion.contact import METHODS
from symcushion.obstacles import Plane, Sphere, closest_obstacle
from symcushion.scene import Body, Scene, symmetric_legs
from symcushion.layout import quat_to_rot, quat_to_rot_np, state_layout
from symcushion.simulate import (build_model, equilibrium_state, initial_state, simulate,
                                 stable_dt, trajectory_from)
from symcushion.strut import HingedStrut

ROOT = Path(__file__).resolve().parents[2]
TABLE = ROOT / "figures" / "hard_cases.md"
DOC = ROOT / "docs" / "hard-cases.md"
SECTION = "Results"
G = 9.81

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
#: Symmetry error allowed (dimensionless, see :func:`_symmetry`): round-off
#: grows with the steps, ~1e-12 after 1e5 steps.
SYMMETRY_TOL = 1e-8
#: Creep allowed on a sticking foot or body over the whole run (m).
CREEP_TOL = 1e-9
#: Steps per rollout chunk of a long run: building mapaccum costs 1–3 ms per
#: step, so one chunk of 1000 is built once per run and fed back its state.
CHUNK = 1000


# ---------------------------------------------------------------------------
# scenes
# ---------------------------------------------------------------------------
def _rod_legs(ratio):
    """The four rods of Figs. 3–4 (studies/fig4.toml) with a chosen axial ratio."""
    return symmetric_legs(4, 0.3, -0.18, 0.6, (0.0, 0.0, -1.0),
                          (-np.sqrt(0.5), 0.0, -np.sqrt(0.5)), M_beta=Linear(1200.0),
                          M_gamma=Linear(1200.0), axial_ratio=ratio)


def _lander_legs(count=4, k_axial=2e4, k_hinge=1200.0, splay=np.deg2rad(20), azimuth0=0.0):
    """Compliant legs splayed outward; e_n 45° from the rest direction, in the swing plane."""
    e0 = (np.sin(splay), 0.0, -np.cos(splay))
    tilt = splay - np.pi / 4          # e_n rotated 45° towards the axis, radial plane
    en = (np.sin(tilt), 0.0, -np.cos(tilt))
    return symmetric_legs(count, 0.3, -0.18, 0.6, e0, en, S=Linear(k_axial),
                          M_beta=Linear(k_hinge), M_gamma=Linear(k_hinge), azimuth0=azimuth0)


def _height_on(obstacle_top, legs, gap=0.0):
    """Body height at which the lowest unloaded foot is ``gap`` above ``obstacle_top``."""
    return obstacle_top - min(leg.rest_foot[2] for leg in legs) + gap


@dataclass
class Setup:
    """One runnable case: the scene, its initial state and how to run and check it."""

    scene: Scene
    x0: np.ndarray | None = None
    symmetry: str | None = None          # None, "axial", "c4" or "mirror"
    creep: str = ""                      # "", "feet" or "feet+body": check they do not move
    adaptive: bool = False               # also run the adaptive driver (step criterion)
    stability: float = 0.0               # ... with its stability cap (fraction of 2/ω_max)
    energy: str = "mechanical"           # energy check: "mechanical" or "work" (see Result)
    note: str = ""


def _stiff_scene(method, mu, duration, name):
    legs = _rod_legs(STIFF_RATIO)
    body = Body(50.0, [1.25, 1.25, 1.25], position=[0, 0, 1.18], velocity=[0, 0, -0.5])
    return Scene(body, legs, [Sphere((0, 0, 0), 0.5)], mu=mu, method=method, dt=1e-3,
                 duration=duration, name=name)


#: Axial stiffness of the stiff rods relative to their bending stiffness scale.
STIFF_RATIO = 1e8
#: Step of the sticking stiff case as a fraction of the stability limit
#: 2/ω_max: the energy error of the impact is O((ω_max Δt)²) of the impact
#: energy (measured: 1.0 J of 6.25 J at 0.5, 0.22 J at 0.25, 0.035 J at 0.1,
#: 0.0087 J at 0.05 — second order), 0.1 keeps it at 1e-4 of the energy scale.
STIFF_FRACTION = 0.1


def case_stiff_axial(method, full=True):
    """Rods of axial ratio 1e8 sliding on the Fig. 4 dome (μ = 0.05), Δt = 1 ms.

    The feet slide, so the stiff axial direction is not held and the explicit
    body update stays stable at the paper's step; the contact step sees
    cond(D_p) ≈ 1e8 (docs/paper-notes.md §3.7).
    """
    return Setup(_stiff_scene(method, 0.05, 0.3, "stiff_axial"), symmetry="axial")


def case_stiff_axial_stick(method, full=True):
    """The same rods with μ = 1: the feet stick and hold the stiff direction.

    Velocity Verlet is then stable only for ω_max Δt < 2 (ω_max of the axial
    and rocking modes, 2/ω_max = 9.1 µs), and the impact's whole kinetic
    energy passes through the stiff mode in ~20 µs, so the step must also
    resolve it: Δt = STIFF_FRACTION·stable_dt (ω_max Δt = 0.2). At Δt = 1 ms
    the first step throws the body off at kilometres per second
    (:func:`explicit_limit`).
    """
    scene = _stiff_scene(method, 1.0, 0.05 if full else 0.01, "stiff_axial_stick")
    dt = STIFF_FRACTION * stable_dt(build_model(scene), initial_state(scene))
    return Setup(scene.with_(dt=dt), symmetry="axial", adaptive=full,
                 stability=STIFF_FRACTION)


def explicit_limit(method, dt=1e-3, steps=20):
    """Body speed (m/s) after each of ``steps`` steps of the sticking stiff case at ``dt``."""
    scene = case_stiff_axial_stick(method, full=False).scene.with_(dt=dt)
    model = build_model(scene)
    X, _ = model.rollout(steps)(initial_state(scene), model.default_p, dt)
    return np.linalg.norm(state_layout(model.n_legs).get(np.asarray(X, dtype=float), "velocity"),
                          axis=0)


#: Interference of the grazing foot's path with the sphere (m): the line of
#: its unloaded position passes this far below the top, so the foot touches
#: for about 2√(2Rd)/v ≈ 1.5 ms, one or two steps, with a force of ~k·d.
GRAZE_DEPTH = 1e-6


def case_grazing(method, full=True):
    """A foot moving along a line tangent to a sphere's top (no gravity), μ = 0.3."""
    leg = HingedStrut(hinge=(0, 0, -0.1), e0=(0, 0, -1), en=(0.6, 0, -0.8), length=0.5,
                      S=Linear(2e4), M_beta=Linear(500.0), M_gamma=Linear(500.0))
    radius = 0.3
    z = _height_on(radius, [leg], gap=-GRAZE_DEPTH)
    body = Body(10.0, [0.5, 0.5, 0.5], position=[0.2, 0, z], velocity=[-1.0, 0, 0])
    scene = Scene(body, [leg], [Sphere((0, 0, 0), radius)], mu=0.3, method=method,
                  dt=1e-3, duration=0.4, gravity=[0, 0, 0], name="grazing")
    return Setup(scene, symmetry="mirror", adaptive=True)


def case_simultaneous(method, full=True):
    """Four feet crossing a plane in the same step, inside it (vertical drop at 2 m/s)."""
    legs = _lander_legs(k_axial=5e4)
    # feet 0.37 mm above the plane: they cross at t = 0.185 ms, inside the first step
    body = Body(50.0, [2.0, 2.0, 2.0], position=[0, 0, _height_on(0.0, legs, 3.7e-4)],
                velocity=[0, 0, -2.0])
    scene = Scene(body, legs, [Plane()], mu=0.5, method=method, dt=1e-3, duration=0.5,
                  name="simultaneous")
    return Setup(scene, symmetry="axial")


#: Drop height of the re-contact case (m): flights last 2√(2h/g) = 6.4 ms,
#: less than one step of 10 ms.
RECONTACT_DROP = 5e-5


def case_recontact(method, full=True):
    """A body bouncing on one leg with flights shorter than a step (Δt = 10 ms)."""
    leg = HingedStrut(hinge=(0, 0, -0.1), e0=(0, 0, -1), en=(0.6, 0, -0.8), length=0.5,
                      S=Linear(2e4), M_beta=Linear(500.0), M_gamma=Linear(500.0))
    body = Body(10.0, [0.5, 0.5, 0.5], position=[0, 0, _height_on(0.0, [leg], RECONTACT_DROP)])
    scene = Scene(body, [leg], [Plane()], mu=0.5, method=method, dt=1e-2, duration=2.0,
                  name="recontact")
    return Setup(scene, symmetry="mirror")


#: Slope of the sticking case and the margin of μ over tan θ.
SLOPE = np.deg2rad(35.0)
SLOPE_MARGIN = 1e-3


def case_slope_stick(method, full=True):
    """A sled at rest on a 35° slope with μ = tan θ + 1e-3 for 100 s (Δt = 10 ms)."""
    # four vertical legs whose feet are level with the centre of mass: each foot
    # carries −mg/4, T/N = tan θ, 1e-3 inside the cone (as in tests/test_simulate.py)
    legs = symmetric_legs(4, 0.4, 0.5, 0.5, (0, 0, -1), (-0.6, 0, -0.8), S=Linear(2e4),
                          M_beta=Linear(3e3), M_gamma=Linear(3e3), azimuth0=np.pi / 4)
    attitude = [np.cos(SLOPE / 2), 0, np.sin(SLOPE / 2), 0]
    body = Body(40.0, [2.0, 2.0, 2.0], position=[0, 0, 0.01], attitude=attitude)
    scene = Scene(body, legs, [Plane.inclined(SLOPE)], mu=float(np.tan(SLOPE)),
                  method=method, dt=1e-2, duration=100.0, name="slope_stick")
    x0 = equilibrium_state(scene, placement="nearest")
    # the legs' 5 mm compression lowers the feet below the centre of mass, so the
    # friction forces tilt the load and the feet's T/N differ from tan θ by ~0.5 %:
    # μ is set just above the largest one at the equilibrium
    n = scene.obstacles[0].n
    xl = state_layout(len(scene.legs))
    forces = xl.legs(x0, "force_body") @ quat_to_rot_np(xl.get(x0, "attitude"), normalise=False).T
    normal = forces @ n
    ratio = np.linalg.norm(forces - np.outer(normal, n), axis=1) / normal
    return Setup(scene.with_(mu=float(ratio.max()) + SLOPE_MARGIN), x0=x0, creep="feet+body",
                 note=f"μ − tan θ = {ratio.max() + SLOPE_MARGIN - np.tan(SLOPE):.2g}")


def case_high_friction(method, full=True):
    """An oblique landing (1.5 m/s across, 2 m/s down) with μ = 2."""
    legs = _lander_legs(k_axial=5e4)
    body = Body(50.0, [2.0, 2.0, 2.0], position=[0, 0, _height_on(0.0, legs, 1e-3)],
                velocity=[1.5, 0, -2.0])
    scene = Scene(body, legs, [Plane()], mu=2.0, method=method, dt=1e-3, duration=0.6,
                  name="high_friction")
    return Setup(scene, symmetry="mirror")


#: Angle between each strut's rest direction and its hinge's polar axis e_n
#: (rad), and the out-of-plane tilt of e_n: the strut swings outward in its
#: radial plane through the projection of e_n and passes the e_n line at
#: about NEAR_SINGULAR_MISS.
NEAR_SINGULAR_GAMMA0 = np.deg2rad(1.5)
NEAR_SINGULAR_MISS = 1e-3
#: Impact speed of the near-singular case (m/s): enough for the struts to
#: swing past e_n (a swing of more than NEAR_SINGULAR_GAMMA0).
NEAR_SINGULAR_SPEED = 2.0


def case_near_singular(method, full=True):
    """Struts that swing past their hinge's polar axis within ~1e-3 rad (docs/paper-notes.md §2)."""
    splay = np.deg2rad(30)
    e0 = np.array([np.sin(splay), 0.0, -np.cos(splay)])
    outward = splay + NEAR_SINGULAR_GAMMA0
    en = np.array([np.sin(outward) * np.cos(NEAR_SINGULAR_MISS), np.sin(NEAR_SINGULAR_MISS),
                   -np.cos(outward) * np.cos(NEAR_SINGULAR_MISS)])
    legs = symmetric_legs(4, 0.3, -0.18, 0.6, e0, en, S=Linear(5e4), M_beta=Linear(300.0),
                          M_gamma=Linear(300.0))
    body = Body(50.0, [2.0, 2.0, 2.0], position=[0, 0, _height_on(0.0, legs, 1e-3)],
                velocity=[0, 0, -NEAR_SINGULAR_SPEED])
    scene = Scene(body, legs, [Plane()], mu=1.0, method=method, dt=1e-3, duration=0.5,
                  name="near_singular")
    # (2.1) is not conservative near e_n (the β element works off e_β), so the
    # energy check is the obstacle's work on the feet (docs/hard-cases.md)
    return Setup(scene, symmetry="c4", adaptive=True, energy="work")


def _dome_lander(method, dt, duration, name, radius=1.0, speed=1.0, k_axial=2e4,
                 k_hinge=1200.0, mu=0.3, count=4):
    legs = _lander_legs(count=count, k_axial=k_axial, k_hinge=k_hinge)
    foot_r = np.hypot(*legs[0].rest_foot[:2])
    top = np.sqrt(radius ** 2 - foot_r ** 2)        # height of the dome under the feet
    body = Body(50.0, [2.0, 2.0, 2.0], position=[0, 0, _height_on(top, legs, 1e-4)],
                velocity=[0, 0, -speed])
    return Scene(body, legs, [Sphere((0, 0, 0), radius)], mu=mu, method=method, dt=dt,
                 duration=duration, name=name)


def case_tiny_step(method, full=True):
    """The compliant lander landing on a dome at 1 m/s with Δt = 1e-6 (impact only)."""
    scene = _dome_lander(method, 1e-6, 0.02 if full else 0.01, "tiny_step")
    return Setup(scene, symmetry="axial")


def case_large_step(method, full=True):
    """The compliant lander landing on a dome at 1 m/s with Δt = 1e-2."""
    scene = _dome_lander(method, 1e-2, 2.0, "large_step")
    # the feet slide on the dome fast enough for 1 − n·n′ to exceed ε at 10 ms
    return Setup(scene, symmetry="axial", adaptive=True)


def case_fast_impact(method, full=True):
    """A stiff lander hitting a dome of radius 3 m at 10 m/s."""
    scene = _dome_lander(method, 1e-3, 0.3, "fast_impact", radius=3.0, speed=10.0,
                         k_axial=2e5, k_hinge=2e4)
    return Setup(scene, symmetry="axial", adaptive=True)


#: Vertical velocity given to the resting lander (m/s): it sets an undamped
#: oscillation of the legs that must neither grow nor make a foot creep.
REST_KICK = 1e-3


def case_long_rest(method, full=True):
    """A three-legged lander resting on a dome (radius 2 m) for 1000 s (Δt = 10 ms)."""
    # three legs, the fewest that stand, to keep 1e5 steps × 3 methods in the test budget;
    # μ = 1 holds the splayed feet (their force is 35° off the dome normal)
    scene = _dome_lander(method, 1e-2, 1000.0 if full else 100.0, "long_rest", radius=2.0,
                         mu=1.0, count=3)
    x0 = equilibrium_state(scene)
    x0[state_layout(len(scene.legs)).slice("velocity")] = (0.0, 0.0, -REST_KICK)
    # the kick makes the body oscillate by ~25 µm for ever: only the feet must not move
    return Setup(scene, x0=x0, symmetry="axial", creep="feet")


CASES = {
    "stiff_axial": case_stiff_axial,
    "stiff_axial_stick": case_stiff_axial_stick,
    "grazing": case_grazing,
    "simultaneous": case_simultaneous,
    "recontact": case_recontact,
    "slope_stick": case_slope_stick,
    "high_friction": case_high_friction,
    "near_singular": case_near_singular,
    "tiny_step": case_tiny_step,
    "large_step": case_large_step,
    "fast_impact": case_fast_impact,
    "long_rest": case_long_rest,
}


# ---------------------------------------------------------------------------
# checks
# ---------------------------------------------------------------------------
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
        X = np.column_stack([traj.position, traj.velocity, traj.attitude,
                             traj.angular_velocity] + [
            np.column_stack([traj.foot[:, j], traj.contact[:, j], traj.force[:, j]])
            for j in range(traj.foot.shape[1])]).T
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


def _symmetry(kind, traj, length):
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


def _chunks(model, x0, p, dt, steps):
    """Yield the Trajectory of each chunk of ``steps`` steps (rollout chunks, fed back)."""
    chunk = min(steps, CHUNK)
    rollout = model.rollout(chunk)
    x, t0 = x0, 0.0
    for _ in range(-(-steps // chunk)):
        X, Y = rollout(x, p, dt)
        traj = trajectory_from(model, x, X, Y, t0 + dt * np.arange(chunk + 1))
        yield traj
        x = np.asarray(X, dtype=float)[:, -1]
        t0 += chunk * dt
        if not np.all(np.isfinite(x)):
            return


def run_case(name, method, full=True) -> Result:
    """Run one case with one contact method and check it (see the module docstring)."""
    if name not in CASES:
        raise ValueError(f"`name` must be one of {sorted(CASES)}, got {name!r}.")
    if method not in METHODS:
        raise ValueError(f"`method` must be one of {METHODS}, got {method!r}.")
    started = time.perf_counter()
    setup = CASES[name](method, full)
    scene = setup.scene
    model = build_model(scene)
    x0 = initial_state(scene) if setup.x0 is None else setup.x0
    p = model.default_p
    inv = invariant_function(scene)
    length = max(leg.length for leg in scene.legs)
    stats = Stats()
    reference = None
    for k, traj in enumerate(_chunks(model, x0, p, scene.dt, scene.steps)):
        stats.update(scene, inv, traj, k == 0)
        if not stats.finite:
            break
        if setup.symmetry:
            stats.symmetry = max(stats.symmetry, _symmetry(setup.symmetry, traj, length))
        if setup.creep:
            if reference is None:
                reference = (traj.foot[0].copy(), traj.position[0].copy())
            stats.update_creep(traj, reference)
    xl = state_layout(len(scene.legs))
    v0 = xl.get(x0, "velocity")
    E_el0 = float(inv(x0)[0]) - 0.5 * scene.body.mass * float(v0 @ v0) \
        + scene.body.mass * float(scene.gravity @ xl.get(x0, "position"))
    energy_scale = (0.5 * scene.body.mass * float(v0 @ v0)
                    + scene.body.mass * float(np.linalg.norm(scene.gravity)) * length
                    + abs(E_el0))
    result = Result(name, method, scene.dt, stats, energy_scale, length, setup)
    if setup.adaptive:
        result.adaptive = run_adaptive(setup, model, x0)
    result.wall = time.perf_counter() - started
    return result


#: Simulated time of the adaptive run of a case with the stability cap (s):
#: the cap takes Δt to about a µs, and the adaptive driver is a Python loop.
STABILITY_RUN = 0.002


def run_adaptive(setup, model, x0) -> dict:
    """What the adaptive driver does on the case: halvings, smallest step, capped steps."""
    scene = setup.scene
    if setup.stability:
        scene = scene.with_(dt=1e-3, duration=STABILITY_RUN)
        model = build_model(scene)
    traj = simulate(scene, model=model, x0=x0, adaptive=True, stability=setup.stability)
    info = traj.info
    out = {"steps": info["steps"], "halvings": info["halvings"], "dt_min": info["dt_min"],
           "criterion_max": info["criterion_max"], "duration": scene.duration,
           "finite": bool(np.all(np.isfinite(traj.position)))}
    if setup.stability:
        out["capped"] = info["stability_capped"]
    return out


# ---------------------------------------------------------------------------
# case-specific observations
# ---------------------------------------------------------------------------
def recontact_flights(duration) -> int:
    """Flights of the re-contact case in ``duration`` s, closed form of a mass on a spring.

    The body lands at v = √(2gh), rides the leg's spring k for
    (2π − 2 atan(v/(ω δ)))/ω (δ = mg/k the static deflection, ω = √(k/m)),
    and flies for 2v/g.
    """
    setup = case_recontact("implicit")
    scene = setup.scene
    leg = scene.legs[0]
    k = leg.elements[0].curve.param_values[0]
    m = scene.body.mass
    v = np.sqrt(2 * G * RECONTACT_DROP)
    omega = np.sqrt(k / m)
    contact = (2 * np.pi - 2 * np.arctan(v / (omega * m * G / k))) / omega
    flight = 2 * v / G
    first = np.sqrt(2 * RECONTACT_DROP / G)              # the drop before the first landing
    return int(np.floor((duration - first - contact) / (contact + flight))) + 1


def notes(result: Result) -> str:
    """What the case shows beyond the pass/fail checks, in a few words."""
    s = result.stats
    case = result.case
    if case == "recontact":
        return (f"{recontact_flights(s.t_end)} flights of 6.4 ms (closed form), "
                f"{s.lift_offs} seen as a lift-off at a step end")
    if case == "near_singular":
        return f"closest strut to e_n: {s.singular:.2e} rad"
    if case == "slope_stick":
        return result.setup.note
    if case == "stiff_axial_stick":
        return f"Δt = {STIFF_FRACTION:g}·2/ω_max"
    return ""


# ---------------------------------------------------------------------------
# the table
# ---------------------------------------------------------------------------
COLUMNS = ("case", "method", "Δt (s)", "time (s)", "steps", "finite", "cone excess",
           "penetration (m)", "energy gain", "foot work", "symmetry", "creep (m)",
           "1 − n·n′ max", "adaptive driver", "landings / lift-offs", "notes", "verdict")


def _g(x, fmt=".1e"):
    return "—" if x is None or not np.isfinite(x) else format(x, fmt)


def verdict(result: Result) -> str:
    """``pass`` or ``FAIL (check, check)`` — the table's last column."""
    return "pass" if result.passed else "FAIL (" + ", ".join(result.failures) + ")"


def table_row(result: Result) -> str:
    """One Markdown row of the table."""
    s, setup = result.stats, result.setup
    a = result.adaptive
    if a:
        adaptive = (f"{a['steps']} steps in {a['duration']:g} s, {a['halvings']} halvings, "
                    f"Δt_min {a['dt_min']:.2g} s")
        if "capped" in a:
            adaptive += f", {a['capped']} capped by stability"
    else:
        adaptive = "—"
    energy = (_g(s.energy_gain / result.energy_scale) if setup.energy == "mechanical"
              else "n/a (2.1)")
    creep = "—"
    if setup.creep:
        creep = _g(s.creep_foot) + (f" / body {_g(s.creep_body)}" if setup.creep == "feet+body"
                                    else "")
    cells = [result.case, result.method, _g(result.dt, ".3g"), _g(s.t_end, ".4g"),
             str(s.steps), "yes" if s.finite else "NO", _g(s.cone), _g(s.penetration),
             energy, _g(s.work_max / result.energy_scale),
             _g(s.symmetry) if setup.symmetry else "—", creep, _g(s.criterion), adaptive,
             f"{s.landings} / {s.lift_offs}", notes(result), verdict(result)]
    return "| " + " | ".join(cells) + " |"


def table(results) -> str:
    """The Markdown table of a list of results."""
    head = "| " + " | ".join(COLUMNS) + " |\n|" + "---|" * len(COLUMNS)
    return head + "\n" + "\n".join(table_row(r) for r in results) + "\n"


def read_table(path=TABLE) -> dict:
    """Verdicts of a written table: {(case, method): 'pass' or 'FAIL (...)'}."""
    out = {}
    for line in Path(path).read_text().splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) == len(COLUMNS) and cells[1] in METHODS:
            out[(cells[0], cells[1])] = cells[-1]
    return out


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", default=",".join(CASES),
                        help="comma-separated case names (default: all)")
    args = parser.parse_args(argv)
    names = [n for n in args.cases.split(",") if n]
    results = []
    started = time.perf_counter()
    for name in names:
        for method in METHODS:
            with np.errstate(invalid="ignore", divide="ignore"):
                result = run_case(name, method)
            results.append(result)
            print(f"{name:18s} {method:8s} {verdict(result):30s} {result.wall:6.1f} s", flush=True)
    speeds = {m: explicit_limit(m) for m in METHODS}
    text = table(results)
    TABLE.parent.mkdir(parents=True, exist_ok=True)
    header = ("# Hard-case battery\n\nWritten by `python studies/hard_cases.py`; columns and "
              "tolerances in docs/hard-cases.md.\n\n")
    TABLE.write_text(header + text)
    body = (text + "\n"
            + "Explicit limit, `stiff_axial_stick` at Δt = 1 ms (body speed after steps 1–3, "
              "m/s): "
            + "; ".join(f"{m} " + ", ".join(f"{v:.3g}" for v in speeds[m][:3]) for m in METHODS)
            + ".\n\n"
            + f"Tolerances: cone {CONE_TOL:g} of |F|, penetration {PENETRATION_TOL:g}·L₀, "
              f"energy gain {ENERGY_TOL:g} and foot work {WORK_TOL:g} of the energy scale, "
              f"symmetry {SYMMETRY_TOL:g}, creep {CREEP_TOL:g} m. "
            + f"Whole battery: {time.perf_counter() - started:.0f} s of wall time on a shared "
              "2-core machine.\n")
    report.write_section(DOC, SECTION, body, title="# Hard cases")
    print(f"wrote {TABLE} and the '{SECTION}' section of {DOC}")


if __name__ == "__main__":
    main()
