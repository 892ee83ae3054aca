"""The touchdown step: the contact step of §1 inside a CasADi step Function.

This module owns the step of a :class:`~symcushion.model.scene.Scene`
(``touchdown_step``, its ``mapaccum`` rollout, :class:`StepModel`) as a
short composition, :func:`build_model`, of small pure parts that live
elsewhere: what the step reads from ``x`` and ``p``
(:mod:`symcushion.scheme.step_start`), the body's kicks, drift and the legs'
wrench (:mod:`symcushion.scheme.body_step`), the event rules of the scheme, the
second kick with the stroke lock and the switch kicks
(:mod:`symcushion.scheme.touchdown_events`), and the end state and outputs
(:mod:`symcushion.scheme.touchdown_outputs`); here is the feet's contact pass
that joins them to ``symcushion.scheme.foot_step``. The initial and equilibrium
states live in :mod:`symcushion.scheme.touchdown_states` (re-exported here). The
explicit stability limit of its body update lives in
:mod:`symcushion.scheme.stability`; the driver that runs the step, with the
paper's adaptive step criterion, and the trajectories it returns live in
:mod:`symcushion.run.driver`. It must not run simulations, nor compute the
body's update, the event rules or the outputs itself.

It receives the physics from elsewhere: the leg force P(r) and stiffness D_p
from ``symcushion.legs.strut``, the feet's contact steps over a step from
``symcushion.scheme.foot_step`` (which calls ``symcushion.contact``) and the
obstacle geometry from ``symcushion.model.obstacles``; it re-derives none of it.

Scheme (one step of length h, §3 of the paper with a velocity-Verlet body):

1. half kick with the foot forces F_j of the previous step (state):
   v ← v + h/2·(g + R ΣF_j/m), ω ← ω + h/2·I⁻¹(τ − ω × Iω);
2. drift: x' = x + h v, q' = q ⊗ exp(h ω/2) (renormalised);
3. each foot: the obstacle near it is replaced by its tangent plane (§3).
   A foot in contact starts from its stored world position r_j with the exact
   P₀ = P(ρ_j) and D_p(ρ_j) at ρ_j = Rᵀ(r_j − x) (body frame). A free foot
   whose unloaded position crosses the surface during the step starts at the
   crossing point (linear interpolation of the signed distance, projected on
   the surface) with the unloaded pose as ρ_j. The plane's displacement
   relative to the body is l_j = R'ᵀ(r_s − x') − ρ_j — the exact rigid-body
   kinematics of §3's l_j = (V₀ + ω₀ × r_j)Δt with the sign of a body moving
   past a fixed obstacle. The contact step gives δ_j, P_j; the foot moves to
   ρ_j + δ_j, is projected back onto the curved surface, or returns to its
   unloaded pose on lift-off.
   With ``events = "branch"`` a leg whose axial force changes between its
   loading and unloading curves inside the step has its contact step split
   at the switch located by (B2) of ``symcushion.scheme.branch_switch``: on the
   stored curve up to t*, the massless foot's jump onto the new curve at t*
   with the body held there, then on to the end (in a call that runs only
   where a switch is possible);
4. second half kick with the new forces; with ``events = "branch"`` it also
   carries the kick correction (B1) of ``symcushion.scheme.branch_switch`` for the
   legs whose axial force changed between its loading and unloading
   branches inside the step.

With ``events = "lock"`` a stuck leg whose load lies between its curves
holds its stroke (``symcushion.scheme.stroke_lock``): the first kick carries
Λ e_S on the locked legs with the stroke at the end of the drift equal to
the stroke at the start (SHAKE), the second μ e_S with the stroke rate at
the end zero (RATTLE); the locked foot stays at its world point. A leg in
contact whose chord turns is tested for the lock by the force that holds
its stroke after the velocities are projected onto the held strokes; the
ones that do not lock keep the located switch, their contact step split at
it as with ``"branch"`` (a switch the split locates is tried for the lock as
well). The state's
``contact`` entry marks a locked foot (2) and a foot on the unloading
curve (3). The lock's work sits in two calls (``stroke_lock.skip_unless``)
that run only in the steps where a leg is locked (SHAKE) or is locked or
turns its stroke in contact (RATTLE and holding solves); the other steps
take the plain kicks, the same numbers the lock's work gives there.

Order: velocity Verlet is second order and symplectic for smooth forces; the
contact law is non-smooth, so the measured order is stated by the tests
(``tests/test_simulate.py``) rather than assumed. The first-contact instant
inside a step is located by linear interpolation of the distance; the force
at the end of that step is exact for a plane, and the impulse over the step is
integrated by the trapezoid rule, an O(h²) local error once per touchdown.
On the memory law the second half kick also carries each leg's located
touchdown, lift-off and crush onset (``FeetStep.event_kick``), and the leg's
axial work output books that kick's work.

Stability: the body update is explicit in velocity, so a stiff leg limits the
step to ω_max Δt < 2, ω_max² the largest eigenvalue of M⁻¹K (M the body's
6×6 mass matrix, K the stiffness of its pose against feet held fixed).
``stability.stable_dt`` estimates that limit from D_p by AD; ``simulate(...,
adaptive=True, stability=True)`` caps every step at ``stability.STABILITY_SAFETY``
of it, or at a given fraction (opt-in, added for the stiff-leg hard case,
docs/hard-cases.md; the default driver is unchanged). The paper's criterion
1 − n_k·n_{k+1} < ε says nothing about this limit.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from symcushion.scheme.body_step import kick_drift, legs_wrench
from symcushion.scheme.foot_step import FeetStep, LegInput, StepPoses
from symcushion.scheme.free_foot import FreeFoot
from symcushion.layout.vectors import (BODY_OUT, BODY_STATE, LEG_OUT, LEG_STATE, MODES,
    ParamLayout, default_p)
from symcushion.scheme.quaternion import quat_to_rot
from symcushion.model.parts import Model, Scheme
from symcushion.model.scene import Scene
from symcushion.scheme.step_start import StepStart, start_foot, step_start
from symcushion.legs.strut import GEOMETRY_MODES
from symcushion.scheme.stroke_lock import axial_branches
from symcushion.scheme.touchdown_events import (gated_lock_phase, lock_candidates, release_branch,
    second_kick, shake_drift, switch_kick)
from symcushion.scheme.touchdown_outputs import (book_event_work, foot_state, leg_end,
    leg_outputs, pack_step)
from symcushion.scheme.touchdown_states import (check_geometry_entries, equilibrium_state,
    initial_state)

__all__ = ["StepModel", "build_model", "initial_state", "equilibrium_state",
           "MODES", "STEP_CRITERION_EPS", "MAX_HALVINGS",
           "BODY_STATE", "LEG_STATE", "BODY_OUT", "LEG_OUT"]

#: ε of the paper's step criterion 1 − n_k·n_{k+1} < ε (§3): a normal may
#: turn by about √(2ε) = 0.45° per step before the adaptive driver halves Δt.
STEP_CRITERION_EPS = 3e-5

#: Deepest halving of Δt by the adaptive driver (Δt/2¹⁰ at most).
MAX_HALVINGS = 10


# ---------------------------------------------------------------------------
# the step Function
# ---------------------------------------------------------------------------
@dataclass
class StepModel:
    """The CasADi Functions of a scene and the layout of their vectors.

    Attributes
    ----------
    step : casadi.Function
        ``touchdown_step(x, p, dt) -> (x_next, y)``.
    scene : Scene
    nx, ny, np : int
        Sizes of the state, the per-step output and the parameter vector.
    param_names : tuple of str
        Names of ``p``: ``leg{j}.{element}.{name}`` for the legs' curve
        parameters, then the scene's ``mu`` (friction scenes only),
        ``gravity.x/y/z``, ``mass`` and ``inertia.xx/yy/zz/xy/xz/yz``, then
        (geometry as inputs, the default) each leg's ``leg{j}.hinge.x/y/z``,
        ``leg{j}.e0.x/y/z``, ``leg{j}.en.x/y/z`` and ``leg{j}.length``, and, in a
        scene where some leg has a footpad, each leg's ``leg{j}.footpad``
        (:class:`~symcushion.layout.vectors.ParamLayout`).
    params : ParamLayout
        The layout of ``p`` (read and write its entries by name).
    gated : dict
        The work that the step calls only in the steps that need it, by call
        name, as the SX Functions evaluated then: with ``events = "lock"``
        the stroke lock's (the SHAKE of the first kick, the RATTLE and
        holding solves of the second), with ``events = "branch"`` each
        lockable leg's contact step split at its switch
        (``touchdown_split_{j}``); empty otherwise.
    derived : dict
        Functions derived from the step by other modules, by name, built once
        per model (:meth:`derived_function`), e.g. ``body_stiffness`` of
        :mod:`symcushion.scheme.stability`.
    """

    step: ca.Function
    scene: Scene
    nx: int
    ny: int
    np: int
    param_names: tuple
    params: ParamLayout | None = None
    gated: dict = field(default_factory=dict)
    derived: dict = field(default_factory=dict)
    _rollouts: dict = field(default_factory=dict)

    def rollout(self, steps: int) -> ca.Function:
        """``touchdown_rollout(x0, p, dt) -> (X, Y)``: ``steps`` steps by mapaccum.

        X has the states after each step as columns (nx × steps), Y the outputs.
        One call runs a whole simulation and is differentiable end to end.
        """
        if isinstance(steps, bool) or not isinstance(steps, (int, np.integer)) or steps < 1:
            raise ValueError(f"`steps` must be a positive integer, got {steps!r}.")
        steps = int(steps)
        if steps not in self._rollouts:
            # Building costs about 2 ms per step (CasADi's sparsity analysis of the
            # repeated step); evaluating costs the same as a loop of calls without the
            # Python overhead. Built once per length and cached.
            acc = self.step.mapaccum("touchdown_rollout_acc", steps)
            x0 = ca.MX.sym("x0", self.nx)
            p = ca.MX.sym("p", self.np)
            dt = ca.MX.sym("dt")
            X, Y = acc(x0, p, dt)
            self._rollouts[steps] = ca.Function("touchdown_rollout", [x0, p, dt], [X, Y],
                                                ["x0", "p", "dt"], ["X", "Y"])
        return self._rollouts[steps]

    def derived_function(self, name: str, build) -> ca.Function:
        """The Function ``name`` derived from this model: ``build(model)`` on first use,
        then kept in :attr:`derived` (a cache; the model itself does not change)."""
        if name not in self.derived:
            self.derived[name] = build(self)
        return self.derived[name]

    @property
    def default_p(self) -> np.ndarray:
        """The scene's values of ``p`` (shape (np,))."""
        return default_p(self.scene, self.params is None or self.params.geometry)

    def pack_params(self, base=None, **overrides) -> np.ndarray:
        """``p`` with named entries replaced: the scene's (``mu=``, ``gravity=``,
        ``mass=``, ``inertia=``) and the legs' geometry (``**{"leg0.hinge": (…),
        "leg0.e0": (…), "leg0.en": (…), "leg0.length": …}``); ``base`` defaults to
        :attr:`default_p`. A frictionless scene has no ``mu`` entry and refuses
        one; a geometry the legs' built Functions cannot take is refused
        (:meth:`check_params`)."""
        p = self.params.pack(self.default_p if base is None else base, **overrides)
        self.check_params(p)
        return p

    def check_params(self, p) -> None:
        """Refuse a ``p`` whose leg geometry the built step cannot take: a length ≤ 0,
        a zero direction, e₀ within 1° of e_n or of the plane ⊥ e_n, or a flipped
        sign(e₀·e_n) (``HingedStrut.check_geometry``), or a negative footpad radius.
        Nothing to check when the geometry is baked in."""
        if self.params is None or not self.params.geometry:
            return
        p = np.asarray(p, dtype=float).ravel()
        check_geometry_entries(self.scene, self.params, p)

    @property
    def n_legs(self):
        return len(self.scene.legs)

    def graph_size(self) -> dict:
        """Size of the step graph: SX instructions and nodes, and ``gated``: the
        instructions of the gated calls (:attr:`gated`), run only in the steps that
        need them."""
        return {"instructions": self.step.n_instructions(), "nodes": self.step.n_nodes(),
                "gated": sum(f.n_instructions() for f in self.gated.values())}


# ---------------------------------------------------------------------------
# the step's composition
# ---------------------------------------------------------------------------
def _leg_input(s: StepStart, j: int, rho0) -> LegInput:
    """Leg j in the feet's contact pass; a leg on the memory law with its free foot at the
    start where it relaxed to, at the end where it relaxes to over the step
    (symcushion.legs.absorber)."""
    leg, fns, p_leg, foot, pad = s.model.legs[j], s.fns_of[j], s.p_of[j], s.feet[j], s.pads[j]
    if not s.memory[j]:
        return LegInput(strut=leg, fns=fns, p_leg=p_leg, rest=s.rest[j], foot=foot, rho0=rho0,
                        pad=pad)
    sets = ca.vertcat(foot["stroke_set"], foot["element_set"])
    chords = ca.vertcat(foot["stroke_chord"], foot["element_chord"])
    # the free foot (A4), evaluated only in the steps that read it (symcushion.scheme.free_foot)
    free = FreeFoot(f"touchdown_free_foot_{j}",
                    fns["strut_free_foot"](sets, p_leg, fns["strut_deflections"](rho0, p_leg),
                                           chords, s.h),
                    ca.logic_not(foot["contact"] > 0.5))
    return LegInput(strut=leg, fns=fns, p_leg=p_leg, rest=free.value, foot=foot, rho0=rho0,
                    sets=sets, chords=chords, rest_start=rho0, pad=pad, free=free)


def contact_pass(s: StepStart, rho0, ax0, drift, R1):
    """3. The feet's contact steps over the step (symcushion.scheme.foot_step), in leg order: a
    lockable leg with its lock and the curve it takes if released. Returns the results,
    those curves by leg, and the gated calls of the split contact steps."""
    vel_h, omega_h, pos1, _ = drift
    feet_step = FeetStep(s.model, s.scheme, StepPoses(h=s.h, pos=s.pos, quat=s.quat, R=s.R, vel=s.vel,
                                            omega=s.omega, vel_h=vel_h, omega_h=omega_h,
                                            pos1=pos1, R1=R1), s.mu, [s.X, s.p, s.h])
    res, release_loading = [], {}
    for j in range(s.n_legs):
        leg_in = _leg_input(s, j, rho0[j])
        if leg_in.free is not None:
            feet_step.gated[f"touchdown_free_foot_{j}"] = leg_in.free.work
        if j in s.locked0:
            release_loading[j], lock = release_branch(s, j, ax0[j])
            res.append(feet_step.foot(j, leg_in, lock, stored=s.stored_loading[j]))
        else:
            res.append(feet_step.foot(j, leg_in))
    return res, release_loading, feet_step.gated


def _scene_of(scene, scheme) -> Scene:
    """The scene a step is built for: ``scene`` itself, or a model and a scheme grouped."""
    if isinstance(scene, Model):
        scheme = Scheme() if scheme is None else scheme
        if not isinstance(scheme, Scheme):
            raise TypeError(f"`scheme` must be a Scheme, got {type(scheme).__name__}.")
        return Scene.from_parts(scene, scheme)
    if not isinstance(scene, Scene):
        raise TypeError(f"`scene` must be a Scene or a Model, got {type(scene).__name__}; "
                        "load a file with symcushion.load_scene(path).")
    if scheme is not None:
        raise ValueError("`scheme` is given with a Scene, which has its own; pass "
                         "scene.model with the scheme, or scene.with_(...) instead.")
    return scene


def build_model(scene: Scene | Model, geometry: str = "input", *,
                scheme: Scheme | None = None) -> StepModel:
    """Build the ``touchdown_step`` Function of a scene: of its model under its scheme
    (:mod:`symcushion.model.parts`), or of a :class:`Model` under ``scheme`` (default
    :class:`Scheme`'s choices). The step has Δt as an input: no time grid enters it.

    Only what the scene needs is built: a leg's absent elements add nothing,
    μ = 0 builds the frictionless contact step, and only the scene's
    obstacles are in the graph. ``geometry="input"`` (default): the legs'
    hinges, rest directions, polar axes and lengths are entries of ``p``
    (the scene's as defaults), so one step serves every geometry with the
    same discrete choices (the scene's orientation signs sign(e₀·e_n), which
    :meth:`StepModel.check_params` enforces); ``"constant"``: they are baked
    into the graph. So are the legs' footpad radii: entries of ``p`` in a
    scene where some leg has a pad (a point foot's is then 0), constants
    otherwise; a scene of point feet has no pad terms in its graph.
    """
    if geometry not in GEOMETRY_MODES:
        raise ValueError(f"`geometry` must be one of {GEOMETRY_MODES}, got {geometry!r}.")
    scene = _scene_of(scene, scheme)
    s = step_start(scene.model, scene.scheme, geometry)
    legs = range(s.n_legs)
    # 1. half kick with the stored forces (+ Λ e_S on locked legs, SHAKE), 2. drift
    rho0 = [start_foot(s, j, s.R, s.pos) for j in legs]
    force, torque = legs_wrench(rho0, [foot["force_body"] for foot in s.feet])
    drift = kick_drift(s.body, s.start, force, torque, s.h)
    ax0 = {j: axial_branches(s.fns_of[j], s.p_of[j], rho0[j]) for j in s.lockable}
    gated = {}                      # the gated calls, by name: the Functions they may skip
    if s.lockable:
        drift, gated["touchdown_lock_shake"] = shake_drift(s, rho0, ax0, force, torque, drift)
    vel_h, omega_h, pos1, quat1 = drift
    R1 = quat_to_rot(quat1)

    # 3. feet (symcushion.scheme.foot_step)
    res, release_loading, feet_gated = contact_pass(s, rho0, ax0, drift, R1)
    gated.update(feet_gated)

    # 4. second half kick: with the stroke lock's RATTLE and holding solves, gated
    if s.lockable:
        cand, end_loading = lock_candidates(s, res, rho0, release_loading)
        (vel1, omega1, acc1), lock_out, gated["touchdown_lock_hold"] = gated_lock_phase(
            s, drift, res, cand, end_loading)
    else:
        kick, lock_out = second_kick(s, res, vel_h, omega_h, R1), {}
        vel1, omega1, acc1 = kick.vel, kick.omega, kick.acc
    ends = [leg_end(s, j, res[j], lock_out.get(j)) for j in legs]
    new_feet = [foot_state(s, j, res[j], ends[j]) for j in legs]
    outputs = [leg_outputs(s, j, res[j], ends[j], rho0[j], R1) for j in legs]

    # the located switches' correction (B1), and the located touchdowns' and lift-offs'
    # of the legs on the memory law
    switch_force, switch_torque = switch_kick(s, res, ends, R1)
    vel2 = vel1 + s.h * switch_force / s.body.m
    omega2 = omega1 + s.h * (s.body.inertia_inv @ switch_torque)
    book_event_work(s, res, outputs, (vel1, omega1), (vel2, omega2))

    x_next, y = pack_step(s, dict(position=pos1, velocity=vel2, attitude=quat1,
                                  angular_velocity=omega2), new_feet, acc1, outputs)
    step = ca.Function("touchdown_step", [s.X, s.p, s.h], [x_next, y], ["x", "p", "dt"],
                       ["x_next", "y"], {"cse": True})
    return StepModel(step=step, scene=scene, nx=s.X.numel(), ny=y.numel(), np=s.params.size,
                     param_names=s.params.names, params=s.params, gated=gated)
