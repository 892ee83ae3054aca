"""The feet's contact steps inside one touchdown step.

This module owns what happens to each foot over one body step whose poses
are given (§1, §3 of the paper): where a free foot's unloaded position
crosses the obstacle, the contact step of ``symcushion.contact`` on the
tangent plane (and its second pass at the predicted end point; a foot
with a pad of radius a is the pad's centre, on the obstacle's surface offset
by a, ``symcushion.model.obstacles``), the
midpoint slip rule of ``symcushion.contact.midpoint`` with the start force
carried into the frame of the end of the step, and, with ``events =
"branch"`` or ``"lock"`` (a leg that is not locked), the contact step split
at a located branch switch of the axial absorber (``symcushion.scheme.branch_switch``)
in a call that runs only where a switch is possible. On the memory law
(``symcushion.legs.absorber``) it locates a touchdown, a lift-off and a crush
onset inside the step and returns the kick's correction for each
(docs/absorbers.md, "Located touchdown and lift-off"). It returns each
foot's end pose, end force and what the touchdown step needs to kick the
body.

It must not move the body (the kicks, the drift and the stroke lock's
solves are ``symcushion.scheme.touchdown``'s), change the contact step or the force
law (2.1), or validate user input.
"""
from __future__ import annotations

from dataclasses import dataclass

import casadi as ca

from symcushion.contact.dispatch import contact_step_call
from symcushion.contact.guards import at_least, at_most
from symcushion.contact.midpoint import midpoint_slip_call
from symcushion.scheme.quaternion import quat_exp, quat_mul, quat_to_rot
from symcushion.model.obstacles import Plane, closest_obstacle
from symcushion.scheme.crush_kick import crush_kick
from symcushion.scheme.foot_split import SplitAtSwitch

__all__ = ["StepPoses", "LegInput", "FeetStep", "MIN_CONTACT_FRACTION"]

#: The shortest part of a step over which a foot that touches down inside it is
#: taken to be in contact (of Δt), for the dampers' rate over that part: it keeps
#: the damper's step stiffness c/((1 − θ)Δt) finite when the foot touches at the
#: very end of a step; 1e-3 keeps it below 1e3 times the whole step's, far from
#: round-off, and is reached only by feet that touch in the step's last 0.1 %.
MIN_CONTACT_FRACTION = 1e-3


def turned(v, a, b):
    """``v`` turned by the smallest rotation that takes the unit vector ``a`` to ``b``
    (Rodrigues; a and b closer than 90°, as two normals of one step are)."""
    axis = ca.cross(a, b)
    return v + ca.cross(axis, v) + ca.cross(axis, ca.cross(axis, v)) / (1 + ca.dot(a, b))


@dataclass(frozen=True)
class StepPoses:
    """The body over one step of length ``h`` (CasADi expressions): at the start
    ``pos``, ``quat``, ``R`` (world), ``vel`` (m/s, world), ``omega`` (rad/s,
    body); the drift's velocities ``vel_h``, ``omega_h`` (those of the middle of
    the step); at the end ``pos1``, ``R1``."""

    h: ca.SX
    pos: ca.SX
    quat: ca.SX
    R: ca.SX
    vel: ca.SX
    omega: ca.SX
    vel_h: ca.SX
    omega_h: ca.SX
    pos1: ca.SX
    R1: ca.SX


@dataclass(frozen=True)
class LegInput:
    """One leg in the step: its ``strut`` (:class:`~symcushion.legs.strut.HingedStrut`),
    its Functions ``fns`` and curve parameters ``p_leg``, its unloaded foot
    ``rest`` (body frame), its state entries ``foot`` (``foot``, ``contact``,
    ``force_body``) and its foot at the start ``rho0`` (body frame); under
    the memory law (``symcushion.legs.absorber``) its elements' sets at the start
    ``sets`` (3) and their mean rates over the previous step ``chords`` (3)
    (else None), with ``fns`` holding the leg's ``memory_functions`` too; then
    ``rest`` is the free foot at the end of the step and ``rest_start`` the
    free foot at its start (a damped foot relaxes over the step), and ``free`` the
    :class:`~symcushion.scheme.free_foot.FreeFoot` that evaluates ``rest`` only where a
    step reads it (``rest`` is its value before the contact passes). ``pad``: its
    footpad radius a (m; a float, or the entry of ``p``), the foot being the pad's
    centre on the obstacle's surface offset by a (0.0 builds a point foot's step)."""

    strut: object
    fns: dict
    p_leg: ca.SX
    rest: ca.DM
    foot: dict
    rho0: ca.SX
    sets: ca.SX | None = None
    chords: ca.SX | None = None
    rest_start: ca.SX | None = None
    pad: ca.SX | float = 0.0
    free: object | None = None


class FeetStep(SplitAtSwitch):
    """The contact steps of the feet of one body step.

    Parameters
    ----------
    model : Model
        Its obstacles and μ (:class:`~symcushion.model.parts.Model`).
    scheme : Scheme
        The contact ``method``, ``tangent_plane``, ``slip`` and ``events``
        (:class:`~symcushion.model.parts.Scheme`).
    poses : StepPoses
    mu : casadi.SX or float
        The Coulomb coefficient (0.0 for a frictionless scene).
    step_inputs : list of casadi.SX
        The symbols of the step Function's inputs (x, p, dt), on which the
        gated calls are built.

    Attributes
    ----------
    gated : dict
        The gated calls built so far, by name (``touchdown_split_{j}``), as the
        SX Functions they run.
    """

    def __init__(self, model, scheme, poses: StepPoses, mu, step_inputs):
        self.model, self.scheme, self.poses, self.mu = model, scheme, poses, mu
        self.friction = model.mu > 0
        # a curved obstacle turns the tangent plane between a step's predicted and final
        # foot points
        self.curved = not all(isinstance(o, Plane) for o in model.obstacles)
        self.step_inputs = list(step_inputs)
        self.gated = {}
        P = poses
        quat_mid = quat_mul(P.quat, quat_exp(P.h / 2 * P.omega_h))
        self.kin_start = dict(R=P.R, v=P.vel, omega=P.omega)            # exact at the start
        self.kin_mid = dict(R=quat_to_rot(quat_mid / ca.norm_2(quat_mid)), v=P.vel_h,
                            omega=P.omega_h)

    def contact_from(self, leg: LegInput, rho_s, r_s, pos_e, R_e, rate_of, R_s, span=None,
                     where=None):
        """The contact step of ``leg``'s foot from ``rho_s`` (body frame) at the world
        point ``r_s``, the body going from attitude ``R_s`` to the pose (``pos_e``,
        ``R_e``); ``rate_of(l)`` is the rate that selects the branches; ``span``: the
        dampers' rate over a touchdown's part of the step (:meth:`damper_rate`); ``where``:
        the passes run only where it is set (``contact_step_call``). Returns the step's outputs, l, n_b, the world normal and the rate."""
        model, scheme, mu, friction = self.model, self.scheme, self.mu, self.friction
        fns, p_leg = leg.fns, leg.p_leg
        pad = leg.pad
        _, normal_w, _ = closest_obstacle(model.obstacles, r_s, pad)
        l = R_e.T @ (r_s - pos_e) - rho_s                      # §3: l_j, exact kinematics
        n_b = R_e.T @ normal_w
        # a leg with a gated free foot: u₀ = 0, a lift-off's δ = −u₀ set after each pass
        u0 = rho_s - leg.rest if leg.free is None else ca.DM.zeros(3)
        v_rel = rate_of(l)
        if leg.sets is None:
            P0 = fns["strut_force"](rho_s, v_rel, p_leg)
            Dp = fns["strut_stiffness"](rho_s, v_rel, p_leg)
        else:
            rate = self.damper_rate(leg, rho_s, span)
            P0, Dp = self.memory_linearisation(leg, rho_s, l, rate)
        out = self.lifted(leg, rho_s, contact_step_call(scheme.method, P0, Dp, n_b, l, mu, u0,
                                                        friction=friction, where=where))
        if scheme.tangent_plane == "end" or leg.sets is not None:
            # second pass: the tangent plane at the predicted end point, shifted along
            # its normal so that a sticking foot keeps its world point r_s; on the memory
            # law, the force law linearised there too, in the regime the foot reaches
            # (a slipping foot may leave the band where a sticking one would enter it)
            if scheme.tangent_plane == "end":
                _, _, r_pred = closest_obstacle(model.obstacles,
                                                pos_e + R_e @ (rho_s + out["delta"]), pad)
                _, normal_w, _ = closest_obstacle(model.obstacles, r_pred, pad)
                n_b = R_e.T @ normal_w
                l = l + n_b * ca.dot(n_b, R_e.T @ (r_pred - r_s))
            if leg.sets is not None:
                P0, Dp = self.memory_linearisation(leg, rho_s, out["delta"], rate)
            out = self.lifted(leg, rho_s, contact_step_call(scheme.method, P0, Dp, n_b, l, mu,
                                                            u0, friction=friction, where=where))
        if scheme.slip == "midpoint" and friction:
            # second-order slip direction (symcushion.contact.midpoint); μ = 0 has none.
            # The start force turns with the body into the frame of the end.
            turn = R_e.T @ R_s - ca.DM.eye(3)
            if leg.sets is None:
                out = midpoint_slip_call(P0, Dp, n_b, l, mu, out, turn)
            else:
                out = self.memory_midpoint(leg, P0, Dp, n_b, l, out, turn)
        return out, l, n_b, normal_w, v_rel

    @staticmethod
    def lifted(leg: LegInput, rho_s, out):
        return out if leg.free is None else leg.free.lifted(rho_s, out)

    def memory_midpoint(self, leg: LegInput, P0, Dp, n_b, l, out, turn):
        """The midpoint slip rule (M1) of a leg on the memory law, its trial path
        started at the foot's own start force.

        The rule weighs the slip direction between the force at the start of the
        slip and the end force, and takes the start from its trial path P₀ + α D_p l
        at α = 0. On the memory law P₀ is the offset of the law linearised about the
        end foot with the dampers' end rate (A3), not the start force: they differ by
        the dampers' c(ẋ₁ − ẋ₀), and a sliding damped foot slipped along an
        O(1)-wrong mean direction. A foot in contact at the start has its stored
        force F₀: its path is F₀ + α(P_t − F₀), P_t = P₀ + D_p l the backward-Euler
        trial force, so that step's outputs are kept. Given by its forces, the path
        needs no D_p⁻¹, which on a flat stretch of the spring-back (constant force,
        no axial stiffness) turned round-off into the step's values and derivatives
        (docs/design-geometry.md, "A wrong derivative at the start").
        """
        F0 = leg.foot["force_body"]
        in_contact = leg.foot["contact"] > 0.5
        Dl = ca.mtimes(Dp, l)
        path = (ca.if_else(in_contact, F0, P0),
                ca.if_else(in_contact, (P0 + Dl) - F0, Dl))           # (1.3): P_t − F₀
        got = midpoint_slip_call(P0, Dp, n_b, l, self.mu, out, turn, path)
        got["delta"] = ca.if_else(got["contact"] > 0.5, l - got["k"], got["delta"])
        return got

    def damper_rate(self, leg: LegInput, rho_s, span=None):
        """(a, b) of the dampers' end rate a·x + b by (A3), from the foot ρ_s at the
        start of the step and the previous step's mean rate.

        ``span`` = (touching, h_c): where ``touching`` is set the foot touched down
        inside the step and has been in contact for h_c only; its rate is then the
        mean rate over that part, (x − x₀)/h_c. The two-step difference (A3) would
        spread the contact's motion over the whole step and the previous free
        step's rate, and carry an O(1) error into the end force at every touchdown
        behind a damper (docs/absorbers.md, "Located touchdown and lift-off").
        """
        x0 = leg.fns["strut_deflections"](rho_s, leg.p_leg)    # δ_S, β, γ − γ₀ at the start
        h = self.poses.h
        a, b = 1.5 / h, -1.5 * x0 / h - 0.5 * leg.chords               # (A3)
        if span is None:
            return a, b
        touching, h_c = span
        return ca.if_else(touching, 1 / h_c, a), ca.if_else(touching, -x0 / h_c, b)

    @staticmethod
    def memory_linearisation(leg: LegInput, rho_s, d, rate):
        """P₀ and D_p of (1.3) for a leg on the memory law: the force law linearised
        about the foot ρ_s + d, in the regime it reaches there.

        The law (A1) has kinks where the element starts or stops crushing; the
        tangent at the start would carry the start's regime through the whole
        step. The first pass linearises about the foot that sticks (d = l), the
        second about the first pass's end foot: a sticking foot's end force is
        then the law's to round-off whatever regime it enters, and a slipping
        foot's differs by the curvature over the second correction only.
        """
        fns, s0, p_leg = leg.fns, leg.sets, leg.p_leg
        rho_d = rho_s + d
        Dp = fns["strut_stiffness_memory"](rho_d, s0, p_leg, *rate, rho_d)
        return fns["strut_force_memory"](rho_d, s0, p_leg, *rate) - Dp @ d, Dp

    def event_kick(self, leg: LegInput, at: dict):
        """The kick's correction for a foot on the memory law that touches down or
        lifts off inside the step (docs/absorbers.md, "Located touchdown and
        lift-off"): (force, torque), N in world axes and N·m in body axes, whose
        impulse h·force the second half kick adds.

        Velocity Verlet takes the impulse of a leg's force over a step as
        h(F₀ + F₁)/2. A foot that touches at θ (``at["theta"]``, from its free
        gap) carries no force before θh, and behind a damper its force jumps at θh
        to F*, the force of the end rates with the foot where it touched; the
        impulse is (1 − θ)h(F* + F₁)/2. A foot that lifts off carries its force to
        zero at θ_off = N₀/(N₀ − N₁), N₁ the normal force it would have at the
        end held where it was (its end force, exact on the law at the stuck foot);
        the impulse is θ_off h F₀/2. Where the force jumps (behind a damper) these
        differ from Verlet's by O(h) once per event, first order; where it does not,
        by O(h²) with a constant that changes with θ. A crush onset inside the step
        adds :meth:`kink_kick`.
        """
        P, fns, p_leg = self.poses, leg.fns, leg.p_leg
        rho_s, n_b, stays = at["rho_s"], at["n_b"], at["stays"]
        theta, (touching, _) = at["theta"], at["span"]
        F0 = leg.foot["force_body"]
        # touchdown: the force jumps to F* at θ; F* has the end rates at the touch foot
        a, b = self.damper_rate(leg, rho_s, at["span"])
        rate_end = a * fns["strut_deflections"](at["rho1"], p_leg) + b
        F_star = self.in_cone(fns["strut_force_memory"](rho_s, leg.sets, p_leg, 0.0, rate_end),
                              n_b)
        down = ca.logic_and(touching, stays)
        w_star = ca.if_else(down, (1 - theta) / 2, 0.0)
        w_end = ca.if_else(down, -theta / 2, 0.0)
        # lift-off: the normal force held at the stuck foot crosses zero at θ_off
        stuck = fns["strut_force_memory"](rho_s + at["l"], leg.sets, p_leg,
                                          *self.damper_rate(leg, rho_s))
        N0, N1 = ca.dot(n_b, F0), ca.dot(n_b, stuck)
        crosses = N0 * N1 < 0
        theta_off = ca.if_else(crosses, N0 / ca.if_else(crosses, N0 - N1, 1.0), 1.0)
        off = ca.logic_and(leg.foot["contact"] > 0.5, ca.logic_not(stays))
        w_start = ca.if_else(off, -(1 - theta_off) / 2, 0.0)
        end = w_star * F_star + w_end * at["P1"]
        if "strut_crush_curve" in fns:
            end = end + self.kink_kick(leg, at)
        force = P.R1 @ end + w_start * (P.R @ F0)
        torque = ca.cross(at["rho1"], end) + w_start * ca.cross(rho_s, F0)
        return force, torque

    def in_cone(self, F, n):
        """``F`` with its tangential part cut to the friction cone μ·max(n·F, 0) (1.4):
        the force a foot can carry at the instant it touches, sliding where a damper
        asks for more (at that instant its normal force is the elastic one's, zero
        for a foot that lands on a crushable's elastic rise)."""
        N = ca.fmax(ca.dot(n, F), 0.0)
        tangential = F - ca.dot(n, F) * n
        size = ca.norm_2(tangential)
        bound = self.mu * N
        scale = ca.if_else(size > bound, bound / ca.if_else(size > 0, size, 1.0), 1.0)
        return N * n + scale * tangential

    def kink_kick(self, leg: LegInput, at: dict):
        """The kick's correction for the bends of the axial force law inside the step
        (N, body axes of the end, times h): :func:`~symcushion.scheme.crush_kick.crush_kick`."""
        return crush_kick(self, leg, at)

    def crossing(self, leg: LegInput, in_contact):
        """Where the free foot's unloaded position crosses the obstacle over the step:
        (θ of the crossing, the world point there, whether the foot is in contact at
        some time of the step, and on the memory law the part of the step in contact,
        ``(touching, h_c)``, else None)."""
        model, P, h = self.model, self.poses, self.poses.h
        free0 = P.pos + P.R @ (leg.rest if leg.rest_start is None else leg.rest_start)
        free1 = P.pos1 + P.R1 @ leg.rest
        d0, _, _ = closest_obstacle(model.obstacles, free0, leg.pad)
        d1, _, _ = closest_obstacle(model.obstacles, free1, leg.pad)
        crossing = d0 - d1
        tau = ca.if_else(crossing > 0, d0 / ca.if_else(crossing > 0, crossing, 1.0), 0.0)
        tau = at_most(at_least(tau, 0.0), 1.0)
        _, _, touch = closest_obstacle(model.obstacles, free0 + tau * (free1 - free0), leg.pad)
        touches = d1 < 0
        active = ca.logic_or(in_contact, touches)
        span = None
        if leg.sets is not None:
            # a touchdown at θ = tau: in contact over the step's last (1 − θ)h only
            touching = ca.logic_and(ca.logic_not(in_contact), touches)
            span = (touching, h * ca.fmax(1 - tau, MIN_CONTACT_FRACTION))
        return tau, touch, active, span

    def end_pose(self, leg: LegInput, out, n_b, normal_w, rho_last, stays):
        """Where foot and force end the step: the foot (body frame and world) put on the
        obstacle where it stays in contact, else at rest; the normal there; the end
        force, turned onto that normal on a curved obstacle."""
        model, P = self.model, self.poses
        rest = leg.rest if leg.free is None else leg.free.value   # after the contact passes
        rho1 = ca.if_else(stays, rho_last + out["delta"], rest)
        foot_w = P.pos1 + P.R1 @ rho1
        _, _, foot_proj = closest_obstacle(model.obstacles, foot_w, leg.pad)
        foot_w = ca.if_else(stays, foot_proj, foot_w)
        if self.curved:
            _, normal_end, _ = closest_obstacle(model.obstacles, foot_proj, leg.pad)
        else:                       # on planes the predicted normal is the final one
            normal_end = normal_w
        rho1 = ca.if_else(stays, P.R1.T @ (foot_w - P.pos1), rho1)
        # the force found with the tangent plane at the predicted end point, turned with
        # that plane onto the plane at the foot's final point: a frictionless force is then
        # normal where the foot is, and on a curved obstacle does no work on its slide
        P_end = turned(out["P"], n_b, P.R1.T @ normal_end) if self.curved else out["P"]
        return rho1, foot_w, normal_end, ca.if_else(stays, P_end, ca.DM.zeros(3))

    def foot(self, j, leg: LegInput, release=None, stored=None) -> dict:
        """The contact step of foot ``j``. ``release`` = (flag, e_S, rate): where the
        flag is set, the axial component of the chord's rate l/h (which picks the
        branch) is replaced by ``rate``, and the step is not split. ``stored``: the
        stored force's curve (1 loading) where the state keeps it, else read from
        the force."""
        P = self.poses
        h, foot = P.h, leg.foot
        in_contact = foot["contact"] > 0.5
        tau, touch, active, span = self.crossing(leg, in_contact)
        r_s = ca.if_else(in_contact, foot["foot"], touch)        # world point of the plane
        rho_s = leg.rho0                                         # foot, body frame

        def chord_rate(l):
            v_rel = l / h                                      # selects loading branches
            if release is not None:
                flag, e_S, rate = release
                v_rel = ca.if_else(flag, v_rel + (rate - ca.dot(e_S, v_rel)) * e_S, v_rel)
            return v_rel

        # on the memory law a foot that is not active (free, not touching down) reads
        # nothing of its contact passes (it ends at its free foot, with no force)
        out, l, n_b, normal_w, v_rel = self.contact_from(
            leg, rho_s, r_s, P.pos1, P.R1, chord_rate, P.R, span,
            where=active if leg.sets is not None else None)
        l_whole = l
        out, (l, n_b, normal_w, v_rel, rho_last), split = self.located_split(
            j, leg, (out, l, n_b, normal_w, v_rel), rho_s, r_s, in_contact, release, stored)
        stays = ca.logic_and(active, out["contact"] > 0.5)
        rho1, foot_w, normal_end, P1 = self.end_pose(leg, out, n_b, normal_w, rho_last, stays)
        sets, chords = leg.sets, leg.chords
        if sets is not None:
            # the end force and sets of the memory law at the end foot (A1)-(A3): a stroke
            # grows only at its loading curve's force, whatever the foot did
            fns, rate = leg.fns, self.damper_rate(leg, rho_s, span)
            P1 = ca.if_else(stays, fns["strut_force_memory"](rho1, sets, leg.p_leg, *rate),
                            ca.DM.zeros(3))
            sets_end = fns["strut_next_set"](rho1, sets, leg.p_leg, *rate)
            events = self.event_kick(leg, dict(rho_s=rho_s, l=l, n_b=n_b, rho1=rho1, P1=P1,
                                               stays=stays, theta=tau, span=span,
                                               sets_end=sets_end))
            # the mean rates of the elastic deflections x − s, which (A3) of the next step
            # reads (for an element that keeps no set, of x); after a touchdown, over
            # the part of the step in contact
            moved = ((fns["strut_deflections"](rho1, leg.p_leg) - sets_end)
                     - (fns["strut_deflections"](rho_s, leg.p_leg) - sets)) / ca.if_else(
                         span[0], span[1], h)
            sets = sets_end
            # a free foot's elements that do not relax (a strut's hinge angles) return to
            # rest at once: no rate to carry
            chords = ca.if_else(stays, moved, moved * ca.DM(leg.strut.relaxes_free))
        return dict(in_contact=in_contact, active=active, stays=stays, rho_s=rho_s, r_s=r_s,
                    l=l, n_b=n_b, v_rel=v_rel, normal_w=normal_end, out=out, rho1=rho1,
                    foot_w=foot_w, P1=P1, locked=ca.SX(0), split=split, l_whole=l_whole,
                    sets=sets, chords=chords, events=events if leg.sets is not None else None)
