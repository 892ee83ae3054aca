"""The touchdown step: the contact step of §1 inside a CasADi step Function.

This module owns the step of a :class:`~symcushion.scene.Scene`
(``touchdown_step``, its ``mapaccum`` rollout) and its initial and
equilibrium states. The explicit stability limit of its body update lives
in :mod:`symcushion.stability`; the driver that runs the step, with the
paper's adaptive step criterion, and the trajectories it returns live in
:mod:`symcushion.driver`.
It receives the physics from elsewhere: the leg force P(r) and stiffness D_p
from ``symcushion.strut``, the feet's contact steps over a step from
``symcushion.foot_step`` (which calls ``symcushion.contact``) and the
obstacle geometry from ``symcushion.obstacles``; it re-derives none of it.

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
   at the switch located by (B2) of ``symcushion.branch_switch``: on the
   stored curve up to t*, the massless foot's jump onto the new curve at t*
   with the body held there, then on to the end (in a call that runs only
   where a switch is possible);
4. second half kick with the new forces; with ``events = "branch"`` it also
   carries the kick correction (B1) of ``symcushion.branch_switch`` for the
   legs whose axial force changed between its loading and unloading
   branches inside the step.

With ``events = "lock"`` a stuck leg whose load lies between its curves
holds its stroke (``symcushion.stroke_lock``): the first kick carries
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

from .branch_switch import branch_flip, branch_switch_kick, locates_switch
from .foot_step import FeetStep, LegInput, StepPoses
from .layout import (BODY_OUT, BODY_STATE, LEG_OUT, LEG_STATE, MODES, ParamLayout, default_p,
                     footpads, output_layout, param_layout, state_layout)
from .quaternion import quat_exp, quat_mul, quat_to_rot, quat_to_rot_np
from .obstacles import closest_obstacle
from .scene import Scene
from .validation import real
from .leg_scheme import bound_geometry
from .strut import GEOMETRY_MODES
from .stroke_lock import (LOCKED, UNLOADING, any_of, axial_branches, bending_force, inside_cone,
                          newton_masked, skip_unless, solve_masked, stroke_acceleration,
                          stroke_rate)

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
        (:class:`~symcushion.layout.ParamLayout`).
    params : ParamLayout
        The layout of ``p`` (read and write its entries by name).
    gated : dict
        The work that the step calls only in the steps that need it, by call
        name, as the SX Functions evaluated then: with ``events = "lock"``
        the stroke lock's (the SHAKE of the first kick, the RATTLE and
        holding solves of the second), with ``events = "branch"`` each
        lockable leg's contact step split at its switch
        (``touchdown_split_{j}``); empty otherwise.
    """

    step: ca.Function
    scene: Scene
    nx: int
    ny: int
    np: int
    param_names: tuple
    params: ParamLayout | None = None
    gated: dict = field(default_factory=dict)
    _rollouts: dict = field(default_factory=dict)
    _body_stiffness: ca.Function | None = None

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
        _check_geometry_entries(self.scene, self.params, p)

    @property
    def n_legs(self):
        return len(self.scene.legs)

    def graph_size(self) -> dict:
        """Size of the step graph: SX instructions and nodes, and ``gated``: the
        instructions of the gated calls (:attr:`gated`), run only in the steps that
        need them."""
        return {"instructions": self.step.n_instructions(), "nodes": self.step.n_nodes(),
                "gated": sum(f.n_instructions() for f in self.gated.values())}


def _check_geometry_entries(scene: Scene, lay: ParamLayout, p) -> None:
    """The legs' geometry blocks and footpads of a 1-D ``p`` with geometry entries."""
    for j, leg in enumerate(scene.legs):
        leg.check_geometry_block(lay.leg_geometry(p, j), where=f"`p` of leg {j}: ")
    if lay.footpads:
        for j in range(len(scene.legs)):
            real(f"leg{j}.footpad", float(lay.footpad(p, j)), nonnegative=True, unit="m")


def _leg_params(scene: Scene, geometry: bool = True):
    """Names of ``p`` and each leg's (start, stop) range of curve parameters."""
    lay = param_layout(scene, geometry)
    return lay.names, [(sl.start, sl.stop) for sl in lay._legs]


def leg_work(fns, start: dict, end: dict, stays) -> dict:
    """The energy one leg takes over a step (trapezoid rule; J): on its axial element,
    on its hinge springs, and dissipated by friction at its foot.

    ``start`` and ``end`` hold the foot in body axes ``rho``, its force ``P`` (body
    axes), the body's rotation ``R`` and the foot's world point ``foot``; ``stays``:
    the foot is on the obstacle at the end (only then did it move along it).
    """
    geo0 = fns["strut_geometry"].call(dict(r=start["rho"]))
    geo1 = fns["strut_geometry"].call(dict(r=end["rho"]))
    axial = 0.5 * (ca.dot(start["P"], geo0["e_S"]) + ca.dot(end["P"], geo1["e_S"])) * (
        geo1["delta_S"] - geo0["delta_S"])
    leg = 0.5 * ca.dot(start["P"] + end["P"], end["rho"] - start["rho"])
    slid = ca.if_else(stays, end["foot"] - start["foot"], ca.DM.zeros(3))
    friction = -0.5 * ca.dot(start["R"] @ start["P"] + end["R"] @ end["P"], slid)
    return dict(work_axial=axial, work_bending=leg - axial, work_friction=friction)


#: The state fields of the memory law (symcushion.absorber): each element's set and
#: its mean rate over the last step, the leg's own element first.
MEMORY_FIELDS = ("stroke_set", "element_set", "stroke_chord", "element_chord")


def _memory_state(res) -> dict:
    """The memory law's state fields from a foot's step result (sets and chords, 3)."""
    sets, chords = res["sets"], res["chords"]
    return dict(stroke_set=sets[0], element_set=sets[1:], stroke_chord=chords[0],
                element_chord=chords[1:])


def _memory_leg_input(leg, fns, p_leg, foot, rho0, h, pad=0.0) -> LegInput:
    """A leg on the memory law in the step: its free foot at the start is where it
    relaxed to, at the end where it relaxes to over the step (symcushion.absorber)."""
    sets = ca.vertcat(foot["stroke_set"], foot["element_set"])
    chords = ca.vertcat(foot["stroke_chord"], foot["element_chord"])
    rest = fns["strut_free_foot"](sets, p_leg, fns["strut_deflections"](rho0, p_leg), chords, h)
    return LegInput(strut=leg, fns=fns, p_leg=p_leg, rest=rest, foot=foot, rho0=rho0,
                    sets=sets, chords=chords, rest_start=rho0, pad=pad)


def build_model(scene: Scene, geometry: str = "input") -> StepModel:
    """Build the ``touchdown_step`` Function of a scene.

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
    legs = scene.legs
    n_legs = len(legs)
    inputs = geometry == "input"
    params = param_layout(scene, inputs)
    names = params.names
    xl, yl = state_layout(n_legs), output_layout(n_legs)
    nx, ny = xl.size, yl.size

    X = ca.SX.sym("x", nx)
    p = ca.SX.sym("p", params.size)
    h = ca.SX.sym("dt")

    # scene entries of p: one compiled step serves every gravity, body and μ
    m = params.get(p, "mass")
    inertia = params.inertia(p)
    inertia_inv = ca.inv(inertia)
    g = params.get(p, "gravity")
    friction = scene.mu > 0          # μ = 0 literally: the frictionless graph, no μ entry
    mu = params.get(p, "mu") if friction else 0.0

    body = xl.unpack(X)
    pos, vel, quat, omega = (body[k] for k in ("position", "velocity", "attitude",
                                                "angular_velocity"))
    feet = [{f: body[f][j] for f in ("foot", "contact", "force_body") + MEMORY_FIELDS}
            for j in range(n_legs)]
    # the legs on the memory law (symcushion.absorber): their unloaded foot is where the
    # axial element's set leaves it
    memory = [scene.hysteresis == "memory" and leg.axial_state for leg in legs]
    fns_of = [dict(leg.functions(geometry), **(leg.memory_functions(geometry) if mem else {}))
              for leg, mem in zip(legs, memory)]
    p_of = [params.leg_inputs(p, j) for j in range(n_legs)]
    if inputs:
        # each leg's geometry is its slice of p: bind it to strut_geometry(r, p), which
        # the contact code calls as strut_geometry(r)
        for fns, p_leg in zip(fns_of, p_of):
            fns["strut_geometry"] = bound_geometry(fns["strut_geometry"], p_leg)
    rest = [leg.rest_foot_expr(p_leg) if inputs else ca.DM(leg.rest_foot)
            for leg, p_leg in zip(legs, p_of)]
    pads = footpads(scene, params, p)

    R = quat_to_rot(quat)

    def body_frame_foot(j, foot, R_, pos_):
        if memory[j]:               # a free foot of the memory law is where it relaxed to
            return R_.T @ (foot["foot"] - pos_)
        in_contact = foot["contact"] > 0.5
        return ca.if_else(in_contact, R_.T @ (foot["foot"] - pos_), rest[j])

    # 1. half kick with the stored forces (+ Λ e_S on locked legs, SHAKE)
    force = ca.DM.zeros(3)
    torque = ca.DM.zeros(3)
    rho0 = []
    for j, foot in enumerate(feet):
        rho = body_frame_foot(j, foot, R, pos)
        rho0.append(rho)
        force = force + foot["force_body"]
        torque = torque + ca.cross(rho, foot["force_body"])
    lockable = [j for j, leg in enumerate(legs)
                if scene.events == "lock" and locates_switch(leg)]
    locked0 = {j: ca.fabs(feet[j]["contact"] - LOCKED) < 0.5 for j in lockable}

    def kick_drift(force, torque):
        vel_h = vel + h / 2 * (g + R @ force / m)
        omega_h = omega + h / 2 * (inertia_inv @ (torque - ca.cross(omega, inertia @ omega)))
        pos1 = pos + h * vel_h                                      # 2. drift
        quat1 = quat_mul(quat, quat_exp(h * omega_h))
        return vel_h, omega_h, pos1, quat1 / ca.norm_2(quat1)

    drift = kick_drift(force, torque)
    gated = {}                      # the gated calls, by name: the Functions they may skip
    if lockable:
        # SHAKE: a locked leg's stroke at the end of the drift equals its stroke at the
        # start; built only into the call that runs when some leg is locked
        ax0 = {j: axial_branches(fns_of[j], p_of[j], rho0[j]) for j in lockable}
        Lam = ca.SX.sym("Lam", len(lockable))
        for k, j in enumerate(lockable):
            force = force + Lam[k] * ax0[j]["e_S"]
            torque = torque + Lam[k] * ca.cross(rho0[j], ax0[j]["e_S"])
        shake = kick_drift(force, torque)
        R1_L = quat_to_rot(shake[3])
        held = [ca.if_else(locked0[j], fns_of[j]["strut_geometry"].call(
                    dict(r=R1_L.T @ (feet[j]["foot"] - shake[2])))["delta_S"]
                    - ax0[j]["delta_S"], Lam[k]) for k, j in enumerate(lockable)]
        Lam_value = newton_masked(ca.vertcat(*held), Lam, [locked0[j] for j in lockable])
        shake = ca.substitute(list(shake), [Lam], [Lam_value])
        drift, gated["touchdown_lock_shake"] = skip_unless(
            "touchdown_lock_shake", any_of(list(locked0.values())), [X, p, h], [X, p, h],
            shake, list(drift))
    vel_h, omega_h, pos1, quat1 = drift
    R1 = quat_to_rot(quat1)

    # 3. feet (symcushion.foot_step)
    feet_step = FeetStep(scene, StepPoses(h=h, pos=pos, quat=quat, R=R, vel=vel, omega=omega,
                                          vel_h=vel_h, omega_h=omega_h, pos1=pos1, R1=R1),
                         mu, [X, p, h])
    leg_in = [_memory_leg_input(legs[j], fns_of[j], p_of[j], feet[j], rho0[j], h, pads[j])
              if memory[j] else
              LegInput(strut=legs[j], fns=fns_of[j], p_leg=p_of[j], rest=rest[j], foot=feet[j],
                       rho0=rho0[j], pad=pads[j]) for j in range(n_legs)]

    res, release_loading = [], {}
    stored_loading = {j: feet[j]["contact"] < 2.5 for j in lockable}
    for j in range(n_legs):
        if j in locked0:
            # a lockable leg: if it is locked and is released, it takes the curve nearer
            # to its holding force
            a = ax0[j]
            S0 = ca.dot(feet[j]["force_body"], a["e_S"])
            to_load = ca.fabs(S0 - a["S_load"]) <= ca.fabs(S0 - a["S_unload"])
            release_loading[j] = to_load
            # (a foot that touches down loads by the curves' own test: at zero
            # deflection they take the loading branch, characteristics.ZERO_DEFLECTION)
            rate = ca.if_else(to_load, 1.0, -1.0) * ca.dot(a["loading"], a["e_S"])
            res.append(feet_step.foot(j, leg_in[j], (locked0[j], a["e_S"], rate),
                                      stored=stored_loading[j]))
        else:
            res.append(feet_step.foot(j, leg_in[j]))
    gated.update(feet_step.gated)

    def second_kick_of(res, vel_h, omega_h, R1, hold):
        """second_kick(mask, S): v, ω at the end with the legs of ``mask`` held by the
        axial forces ``S``, given the contact results ``res`` and the drift."""
        def second_kick(mask, S):
            force1, torque1 = ca.DM.zeros(3), ca.DM.zeros(3)
            for j in range(n_legs):
                P1, rho1 = res[j]["P1"], res[j]["rho1"]
                if j in hold:
                    k = lockable.index(j)
                    P1 = ca.if_else(mask[k], hold[j]["bend"] + S[k] * hold[j]["e_S"], P1)
                    rho1 = ca.if_else(mask[k], hold[j]["rho"], rho1)
                force1 = force1 + P1
                torque1 = torque1 + ca.cross(rho1, P1)
            acc1 = g + R1 @ force1 / m
            vel1 = vel_h + h / 2 * acc1
            omega1 = omega_h + h / 2 * (inertia_inv @ (torque1 - ca.cross(omega_h,
                                                                           inertia @ omega_h)))
            return vel1, omega1, acc1, force1, torque1
        return second_kick

    def lock_phase(vel_h, omega_h, pos1, quat1, res, cand, end_loading):
        """The lock's second kick: v, ω, a at the end and, per lockable leg, its lock and
        stuck flags, end pose ρ, end force and branch (1 loading)."""
        R1 = quat_to_rot(quat1)
        # where each lockable leg would hold: its foot stuck at its stored world point
        hold = {}
        for j in lockable:
            rho = R1.T @ (feet[j]["foot"] - pos1)
            a = axial_branches(fns_of[j], p_of[j], rho)
            hold[j] = dict(rho=rho, e_S=a["e_S"], L=a["L"], lo=a["lo"], hi=a["hi"],
                           S_load=a["S_load"], S_unload=a["S_unload"],
                           bend=bending_force(fns_of[j], p_of[j], rho, res[j]["v_rel"],
                                              a["e_S"]))
        second_kick = second_kick_of(res, vel_h, omega_h, R1, hold)

        def held_rates(mask, v, w):
            return ca.vertcat(*[ca.if_else(mask[k], stroke_rate(hold[j]["rho"], hold[j]["e_S"],
                                                                v, w, R1), 0.0)
                                for k, j in enumerate(lockable)])

        def within(j, S):
            """S between the curves and the held force in the friction cone."""
            return ca.logic_and(ca.logic_and(hold[j]["lo"] <= S, S <= hold[j]["hi"]),
                                inside_cone(hold[j]["bend"] + S * hold[j]["e_S"],
                                            res[j]["n_b"], mu))

        n_lk = len(lockable)
        mu_sym = ca.SX.sym("mu_lock", n_lk)
        lam_sym = ca.SX.sym("lam", n_lk)
        nu = ca.SX.sym("nu", 6)
        W = ca.diagcat(ca.DM.eye(3) / m, inertia_inv)          # M⁻¹ of (v, ω)

        def rattle(held, fixed, S_fixed):
            """v, ω, μ: the legs of ``held`` with zero stroke rate at the end (RATTLE), the
            legs of ``fixed`` stuck with the axial forces ``S_fixed``."""
            S = [ca.if_else(fixed[k], S_fixed[k], mu_sym[k]) for k in range(n_lk)]
            both = [ca.logic_or(held[k], fixed[k]) for k in range(n_lk)]
            v_mu, w_mu = second_kick(both, S)[:2]
            rate = held_rates(held, v_mu, w_mu) + ca.vertcat(
                *[ca.if_else(held[k], 0.0, mu_sym[k]) for k in range(n_lk)])
            mu_value = newton_masked(rate, mu_sym, held, iterations=1)
            v1, w1 = ca.substitute([v_mu, w_mu], [mu_sym], [mu_value])
            return v1, w1, mu_value

        def holding(held, fixed, S_fixed, v1, w1):
            """v, ω projected onto the held strokes (in the metric of M) and the forces
            that hold them (δ_S″ = 0), the legs of ``fixed`` stuck with ``S_fixed``."""
            G = ca.substitute(ca.jacobian(held_rates(held, nu[0:3], nu[3:6]), nu), nu,
                              ca.DM.zeros(6))                   # the rates are linear in ν
            nu1 = ca.vertcat(v1, w1)
            nu_p = nu1 - W @ G.T @ solve_masked(G @ W @ G.T, G @ nu1, held)
            v_p, w_p = nu_p[0:3], nu_p[3:6]
            S = [ca.if_else(fixed[k], S_fixed[k], lam_sym[k]) for k in range(n_lk)]
            both = [ca.logic_or(held[k], fixed[k]) for k in range(n_lk)]
            _, _, _, f_lam, t_lam = second_kick(both, S)
            a_lam = g + R1 @ f_lam / m
            alpha_lam = inertia_inv @ (t_lam - ca.cross(w_p, inertia @ w_p))
            dd = ca.vertcat(*[ca.if_else(held[k], stroke_acceleration(
                hold[j]["rho"], hold[j]["e_S"], hold[j]["L"], v_p, w_p, a_lam, alpha_lam, R1),
                lam_sym[k]) for k, j in enumerate(lockable)])
            return v_p, w_p, newton_masked(dd, lam_sym, held, iterations=1)

        off = [ca.SX(0)] * n_lk                                  # no leg; no force
        # RATTLE on the locked legs; μ off [S_u, S_l], or the held force out of the cone,
        # releases a leg onto the curve nearer to its stored force
        locked = [locked0[j] for j in lockable]
        _, _, mu1 = rattle(locked, off, off)
        keep = [ca.logic_and(locked[k], within(j, mu1[k])) for k, j in enumerate(lockable)]
        v_a, w_a, _ = rattle(keep, off, off)
        # a foot in contact whose chord says its stroke reversed (``cand``): the force that
        # would hold its stroke, stuck where it was, after the velocities are projected onto
        # the held strokes (the contact step's own answer carried the wrong branch's force,
        # which may even have made it slip). Between the curves and in the cone: it locks.
        # Beyond the curve of its stored branch: the reversal was not one (a chord of O(h³)
        # after a release), it stays on that branch, stuck. Else: a direct switch.
        stored_S = [ca.if_else(stored_loading[j], hold[j]["S_load"], hold[j]["S_unload"])
                    for j in lockable]
        # a leg that RATTLE released alone is tried again with the others: two legs may
        # hold together where neither holds alone
        retry = [ca.logic_and(locked[k], ca.logic_not(keep[k])) for k in range(n_lk)]
        _, _, lam1 = holding([ca.logic_or(ca.logic_or(keep[k], cand[k]), retry[k])
                              for k in range(n_lk)], off, off, v_a, w_a)
        accept, stay = [], []
        for k, j in enumerate(lockable):
            accept.append(ca.logic_and(ca.logic_or(cand[k], retry[k]), within(j, lam1[k])))
            outside = ca.logic_or(lam1[k] < hold[j]["lo"], lam1[k] > hold[j]["hi"])
            beyond_stored = ca.logic_and(outside, ca.fabs(lam1[k] - stored_S[k]) < ca.fabs(
                lam1[k] - (hold[j]["S_load"] + hold[j]["S_unload"] - stored_S[k])))
            stay.append(ca.logic_and(ca.logic_and(cand[k], ca.logic_not(accept[k])),
                                     ca.logic_and(beyond_stored, inside_cone(
                                         hold[j]["bend"] + stored_S[k] * hold[j]["e_S"],
                                         res[j]["n_b"], mu))))
        v_b, w_b, mu2 = rattle(keep, stay, stored_S)
        keep = [ca.logic_or(keep[k], ca.logic_and(retry[k], accept[k])) for k in range(n_lk)]
        held = [ca.logic_or(keep[k], accept[k]) for k in range(n_lk)]
        v_p, w_p, lam2 = holding(held, stay, stored_S, v_b, w_b)
        entered = any_of(accept)
        vel1, omega1 = ca.if_else(entered, v_p, v_b), ca.if_else(entered, w_p, w_b)
        S_end = ca.if_else(entered, lam2, mu2)
        stuck = [ca.logic_or(held[k], stay[k]) for k in range(n_lk)]
        S1 = [ca.if_else(stay[k], stored_S[k], S_end[k]) for k in range(n_lk)]
        out = [vel1, omega1, second_kick(stuck, S1)[2]]
        for k, j in enumerate(lockable):
            out += [held[k], stuck[k], ca.if_else(stuck[k], hold[j]["rho"], res[j]["rho1"]),
                    ca.if_else(stuck[k], hold[j]["bend"] + S1[k] * hold[j]["e_S"], res[j]["P1"]),
                    ca.if_else(stay[k], stored_loading[j], end_loading[k])]
        return out

    if lockable:
        # which legs may lock or turn: the chord's branch test on every lockable leg
        cand, end_loading = [], []
        for j in lockable:
            r = res[j]
            flip, ax = branch_flip(fns_of[j], p_of[j], rho0[j], feet[j]["force_body"],
                                   r["l_whole"], h, stored_loading[j])
            new_loading = ax["new_loading"]
            if r["split"] is not None:
                # a switch located inside the step is a reversal as well
                flip = ca.logic_or(flip, r["split"]["use"])
                new_loading = ca.if_else(r["split"]["use"], ca.logic_not(stored_loading[j]),
                                         new_loading)
            end_loading.append(ca.if_else(locked0[j], release_loading[j],
                                          ca.if_else(r["in_contact"], new_loading, 1.0)))
            cand.append(ca.logic_and(ca.logic_and(ca.logic_not(locked0[j]), flip),
                                     r["in_contact"]))
        # the lock's work in a call that runs it only when a leg is locked or turns; in the
        # other steps its values are those of the plain second kick
        drift_in = [ca.SX.sym(name, n) for name, n in (("vel_h", 3), ("omega_h", 3),
                                                       ("pos1", 3), ("quat1", 4))]
        res_in = [{key: ca.SX.sym(f"{key}_{j}", 3) for key in
                   (("P1", "rho1", "v_rel", "n_b") if j in lockable else ("P1", "rho1"))}
                  for j in range(n_legs)]
        cand_in, end_in = ca.SX.sym("cand", len(lockable)), ca.SX.sym("end_loading", len(lockable))
        on = lock_phase(*drift_in, res_in, ca.vertsplit(cand_in), ca.vertsplit(end_in))
        plain = second_kick_of(res_in, drift_in[0], drift_in[1], quat_to_rot(drift_in[3]), {})
        off = list(plain([], [])[:3])
        for k, j in enumerate(lockable):
            off += [ca.SX(0), ca.SX(0), res_in[j]["rho1"], res_in[j]["P1"], end_in[k]]
        out, gated["touchdown_lock_hold"] = skip_unless(
            "touchdown_lock_hold", any_of(list(locked0.values()) + cand),
            [X, p, h] + drift_in + [x for r in res_in for x in r.values()] + [cand_in, end_in],
            [X, p, h, vel_h, omega_h, pos1, quat1]
            + [res[j][key] for j, r in enumerate(res_in) for key in r]
            + [ca.vertcat(*cand), ca.vertcat(*end_loading)], on, off)
        vel1, omega1, acc1 = out[:3]
        lock_out = {j: out[3 + 5 * k: 8 + 5 * k] for k, j in enumerate(lockable)}
    else:
        vel1, omega1, acc1, _, _ = second_kick_of(res, vel_h, omega_h, R1, {})([], [])
        lock_out = {}

    new_feet, outputs = [], []
    switch_force, switch_torque = ca.DM.zeros(3), ca.DM.zeros(3)   # (B1)
    for j, leg in enumerate(legs):
        r, fns = res[j], fns_of[j]
        stays, rho1, foot_w, P1 = r["stays"], r["rho1"], r["foot_w"], r["P1"]
        contact = ca.if_else(stays, 1.0, 0.0)
        b1_active = ca.logic_and(r["in_contact"], stays)
        if j in lock_out:
            lk, st, rho1, P1, loading1 = lock_out[j]
            stays = ca.logic_or(stays, st)
            foot_w = ca.if_else(st, feet[j]["foot"], foot_w)
            contact = ca.if_else(lk, LOCKED, ca.if_else(stays, ca.if_else(loading1, 1.0,
                                                                          UNLOADING), 0.0))
            b1_active = ca.logic_and(b1_active, ca.logic_not(ca.logic_or(st, locked0[j])))
        new_feet.append(dict(foot=foot_w, contact=contact, force_body=P1,
                             **(_memory_state(r) if memory[j]
                                else {f: feet[j][f] for f in MEMORY_FIELDS})))
        if r.get("events") is not None:
            # a touchdown or lift-off located inside the step (memory law, FeetStep.event_kick)
            switch_force, switch_torque = switch_force + r["events"][0], \
                switch_torque + r["events"][1]
        if scene.events in ("branch", "lock") and locates_switch(leg):
            # the kick at the located loading/unloading switch (symcushion.branch_switch)
            dF, dT, _ = branch_switch_kick(
                fns, p_of[j], dict(rho0=r["rho_s"], F0=feet[j]["force_body"], rho1=rho1, F1=P1,
                                   active=b1_active, stored_loading=stored_loading.get(j),
                                   split=r["split"]),
                dict(h=h, R=R, R1=R1, v=vel, omega=omega, l=r["l"]))
            switch_force, switch_torque = switch_force + dF, switch_torque + dT

        slipping = ca.dot(r["out"]["k"], r["out"]["k"]) > 0
        if j in lock_out:
            slipping = ca.logic_and(slipping, ca.logic_not(lock_out[j][1]))
        mode = ca.if_else(stays, ca.if_else(slipping, 2.0, 1.0),
                          ca.if_else(r["active"], 3.0, 0.0))
        geo = fns["strut_geometry"].call(dict(r=rho1))
        outputs.append(dict(in_contact=ca.if_else(stays, 1.0, 0.0), mode=mode, force=R1 @ P1,
                            normal=ca.if_else(stays, r["normal_w"], ca.DM.zeros(3)),
                            axis=R1 @ geo["e_S"], **leg.deflection_outputs(geo),
                            **leg_work(fns, dict(rho=rho0[j], P=feet[j]["force_body"], R=R,
                                                 foot=ca.if_else(r["in_contact"],
                                                                 feet[j]["foot"], r["r_s"])),
                                       dict(rho=rho1, P=P1, R=R1, foot=foot_w), stays)))

    # 4. second half kick: the located switches' correction (B1), and the located
    # touchdowns' and lift-offs' of the legs on the memory law
    vel_plain, omega_plain = vel1, omega1
    vel1 = vel1 + h * switch_force / m
    omega1 = omega1 + h * (inertia_inv @ switch_torque)
    for j, r in enumerate(res):
        if r.get("events") is not None:
            # the located events' kick changes the body's energy by the mean velocity times
            # its impulse, exactly: the leg took that much less (its axial work)
            outputs[j]["work_axial"] = outputs[j]["work_axial"] - h * (
                ca.dot((vel_plain + vel1) / 2, r["events"][0])
                + ca.dot((omega_plain + omega1) / 2, r["events"][1]))

    x_next = xl.pack(position=pos1, velocity=vel1, attitude=quat1, angular_velocity=omega1,
                     **{f: [foot[f] for foot in new_feet]
                        for f in ("foot", "contact", "force_body") + MEMORY_FIELDS})
    y = yl.pack(acceleration=acc1, **{f.name: [o[f.name] for o in outputs]
                                       for f in yl.leg_fields})
    step = ca.Function("touchdown_step", [X, p, h], [x_next, y], ["x", "p", "dt"],
                       ["x_next", "y"], {"cse": True})
    return StepModel(step=step, scene=scene, nx=nx, ny=ny, np=params.size, param_names=names,
                     params=params, gated=gated)


# ---------------------------------------------------------------------------
# states
# ---------------------------------------------------------------------------
def initial_state(scene: Scene, p=None) -> np.ndarray:
    """State vector of the scene's initial conditions, all feet free; with ``p`` (a
    step's parameters) the feet at the rest poses of its leg geometry."""
    b = scene.body
    R = _rot_np(b.attitude)
    n = len(scene.legs)
    _, _, rest, _ = _legs_at(scene, p)
    return state_layout(n).pack(
        position=b.position, velocity=b.velocity, attitude=b.attitude,
        angular_velocity=b.angular_velocity,
        foot=[b.position + R @ r for r in rest], contact=[0.0] * n,
        force_body=[np.zeros(3)] * n)


def _legs_at(scene: Scene, p=None):
    """(Functions, p, rest foot, footpad) of every leg for a step's ``p``: with its
    geometry block when ``p`` has one, else (and for None) the scene's own geometry."""
    with_geometry = param_layout(scene, True)
    if p is None:
        p = default_p(scene, geometry=False)
    p = np.asarray(p, dtype=float).ravel()
    lay = with_geometry if p.size == with_geometry.size else param_layout(scene, False)
    if p.size != lay.size:
        raise ValueError(f"`p` must have {with_geometry.size} entries {with_geometry.names} "
                         f"(or {lay.size} without the legs' geometry), got {p.size}.")
    mode = "input" if lay.geometry else "constant"
    fns = [leg.functions(mode) for leg in scene.legs]
    p_legs = [lay.leg_inputs(p, j) for j in range(len(scene.legs))]
    if lay.geometry:
        _check_geometry_entries(scene, lay, p)
        rest = [np.asarray(ca.evalf(leg.rest_foot_expr(ca.DM(p_leg))), dtype=float).ravel()
                for leg, p_leg in zip(scene.legs, p_legs)]
    else:
        rest = [leg.rest_foot for leg in scene.legs]
    return fns, p_legs, rest, [float(a) for a in footpads(scene, lay, p)]


def _rot_np(q):
    """Rotation matrix of the quaternion ``q`` as given (not renormalised)."""
    return quat_to_rot_np(q, normalise=False)


def _drop_point(obstacles, free, direction, iterations=20, pad=0.0):
    """Where the line free + s·direction first meets the obstacle (its offset surface
    at distance ``pad``), by Newton in s."""
    point = ca.DM(free)
    for _ in range(iterations):
        d, n, _ = closest_obstacle(obstacles, point, pad)
        slope = float(ca.evalf(ca.dot(n, ca.DM(direction))))
        if abs(slope) < 1e-9:
            raise ValueError("cannot drop a foot onto the obstacle: the drop direction is "
                             "tangent to it; use placement='nearest'.")
        point = point - float(ca.evalf(d)) / slope * ca.DM(direction)
    return np.asarray(point, dtype=float).ravel()


def equilibrium_state(scene: Scene, acceleration=(0.0, 0.0, 0.0), p=None,
                      solve_attitude: bool = True, placement: str = "gravity") -> np.ndarray:
    """A state at rest (or in steady translation) with every foot on the obstacle.

    Each foot is placed where its unloaded position meets the obstacle, moving
    along gravity (``placement='gravity'``, as a foot lands) or to the nearest
    surface point (``'nearest'``), and held there; the body's position and (with
    ``solve_attitude``) a small rotation of its attitude are solved by Newton's
    method so that the leg forces balance the body: ΣP_j = −m(g − a) and
    Σρ_j × P_j = 0. With ``acceleration`` the body's steady acceleration (no
    rotation), this is the state of a steadily sliding body.

    Returns
    -------
    ndarray, shape (nx,)
        Velocities zero, contact flags 1, stored forces the exact P_j.
    """
    b = scene.body
    R0 = _rot_np(b.attitude)
    a = np.asarray(acceleration, dtype=float)
    if placement not in ("gravity", "nearest"):
        raise ValueError(f"`placement` must be 'gravity' or 'nearest', got {placement!r}.")
    pts = []
    down = scene.gravity / np.linalg.norm(scene.gravity)
    fns, p_legs, rest, pads = _legs_at(scene, p)
    for rest_j, pad in zip(rest, pads):
        free = b.position + R0 @ rest_j
        if placement == "gravity":
            pts.append(_drop_point(scene.obstacles, free, down, pad=pad))
        else:
            _, _, proj = closest_obstacle(scene.obstacles, ca.DM(free), pad)
            pts.append(np.asarray(ca.evalf(proj)).ravel())
    z = ca.SX.sym("z", 6 if solve_attitude else 3)
    x = z[0:3]
    q = ca.DM(b.attitude)
    if solve_attitude:
        q = quat_mul(q, quat_exp(z[3:6]))
    R = quat_to_rot(q)
    total = ca.DM.zeros(3)
    torque = ca.DM.zeros(3)
    for j, (leg, pt) in enumerate(zip(scene.legs, pts)):
        rho = R.T @ (ca.DM(pt) - x)
        P = fns[j]["strut_force"](rho, ca.DM.zeros(3), p_legs[j])
        total = total + R @ P
        torque = torque + ca.cross(rho, P)
    residual = total + b.mass * (ca.DM(scene.gravity) - ca.DM(a))
    if solve_attitude:
        residual = ca.vertcat(residual, torque)
    solver = ca.rootfinder("equilibrium", "newton", ca.Function("res", [z], [residual]),
                           {"abstol": 1e-10, "max_iter": 200})
    guess = np.concatenate([b.position, np.zeros(3)]) if solve_attitude else b.position
    sol = np.asarray(solver(guess), dtype=float).ravel()
    pos = sol[0:3]
    quat = np.asarray(ca.evalf(ca.substitute(q, z, ca.DM(sol))), dtype=float).ravel()
    R = _rot_np(quat)
    forces = []
    for j, (leg, pt) in enumerate(zip(scene.legs, pts)):
        rho = R.T @ (pt - pos)
        forces.append(np.asarray(fns[j]["strut_force"](rho, np.zeros(3), p_legs[j])).ravel())
    return state_layout(len(scene.legs)).pack(
        position=pos, velocity=np.zeros(3), attitude=quat, angular_velocity=np.zeros(3),
        foot=pts, contact=[1.0] * len(pts), force_body=forces)



def _default_p(scene):
    return default_p(scene)
