"""The event rules of the touchdown step: the second kick, the stroke lock and the switch kicks.

This module owns what ``Scene.events`` changes in the body step of
``symcushion.scheme.touchdown``, as pure functions of its :class:`StepStart`, the
drift and the feet's contact results:

* the second half kick with the feet's end forces (:func:`second_kick`),
  some legs held by given axial forces;
* ``events = "lock"``: the SHAKE of the first kick on the locked legs
  (:func:`shake_drift`), the curve a released leg takes
  (:func:`release_branch`), the legs that may lock or turn
  (:func:`lock_candidates`) and the lock's second kick (:func:`lock_phase`,
  RATTLE and the holding forces), gated to the steps that need it
  (:func:`gated_lock_phase`), with its outputs named in :data:`LOCK_LEG_OUT`;
* ``events = "branch"`` and ``"lock"``: the kick correction (B1) at the
  located loading/unloading switches, and on the memory law the kick of the
  located touchdowns, lift-offs and crush onsets (:func:`switch_kick`).

The pieces come from ``symcushion.scheme.stroke_lock`` and
``symcushion.scheme.branch_switch``. This module must not call the contact step,
drift the body or assemble the step's outputs.
"""
from __future__ import annotations

from typing import NamedTuple

import casadi as ca

from symcushion.scheme.body_step import body_acceleration, half_kick, kick_drift, legs_wrench
from symcushion.scheme.branch_switch import branch_flip, branch_switch_kick, locates_switch
from symcushion.scheme.quaternion import quat_to_rot
from symcushion.scheme.step_start import StepStart
from symcushion.scheme.stroke_lock import (any_of, axial_branches, bending_force, inside_cone,
    newton_masked, skip_unless, solve_masked, stroke_acceleration, stroke_rate)

__all__ = ["LOCK_LEG_OUT", "Kick", "second_kick", "shake_drift", "release_branch", "lock_candidates",
           "lock_phase", "gated_lock_phase", "switch_kick"]

#: What the lock's second kick gives per lockable leg: locked at the end, stuck (locked or
#: held on its stored branch), its end pose ρ and force (body axes), its branch (1 loading).
LOCK_LEG_OUT = ("locked", "stuck", "rho1", "P1", "loading")


class Kick(NamedTuple):
    """The second half kick: v, ω and a at the end of the step, the legs' ΣF and Στ (body
    axes) it took."""

    vel: object
    omega: object
    acc: object
    force: object
    torque: object


def second_kick(s: StepStart, res, vel_h, omega_h, R1, hold=None, mask=(), S=()) -> Kick:
    """The :class:`Kick` at the end of the step: the second half kick with the feet's end
    forces ``res[j]["P1"]`` at ``res[j]["rho1"]``, the lockable legs of ``mask`` held
    at ``hold[j]`` by the axial forces ``S``."""
    rho1, P1 = [], []
    for j in range(s.n_legs):
        P_j, rho_j = res[j]["P1"], res[j]["rho1"]
        if hold and j in hold:
            k = s.lockable.index(j)
            P_j = ca.if_else(mask[k], hold[j]["bend"] + S[k] * hold[j]["e_S"], P_j)
            rho_j = ca.if_else(mask[k], hold[j]["rho"], rho_j)
        rho1.append(rho_j)
        P1.append(P_j)
    force1, torque1 = legs_wrench(rho1, P1)
    acc = body_acceleration(s.body, R1, force1, torque1, omega_h)
    vel1, omega1 = half_kick(vel_h, omega_h, acc, s.h)
    return Kick(vel1, omega1, acc[0], force1, torque1)


def shake_drift(s: StepStart, rho0, ax0, force, torque, drift):
    """SHAKE: the first kick and drift with Λ e_S on the locked legs, Λ such that a locked
    leg's stroke at the end of the drift equals its stroke at the start; built only into
    a call that runs when some leg is locked. Returns the drift and that call's Function."""
    Lam = ca.SX.sym("Lam", len(s.lockable))
    for k, j in enumerate(s.lockable):
        force = force + Lam[k] * ax0[j]["e_S"]
        torque = torque + Lam[k] * ca.cross(rho0[j], ax0[j]["e_S"])
    shake = kick_drift(s.body, s.start, force, torque, s.h)
    R1_L = quat_to_rot(shake.quat1)
    held = [ca.if_else(s.locked0[j], s.fns_of[j]["strut_geometry"].call(
                dict(r=R1_L.T @ (s.feet[j]["foot"] - shake.pos1)))["delta_S"]
                - ax0[j]["delta_S"], Lam[k]) for k, j in enumerate(s.lockable)]
    Lam_value = newton_masked(ca.vertcat(*held), Lam, [s.locked0[j] for j in s.lockable])
    shake = ca.substitute(list(shake), [Lam], [Lam_value])
    args = [s.X, s.p, s.h]
    return skip_unless("touchdown_lock_shake", any_of(list(s.locked0.values())), args, args,
                       shake, list(drift))


def release_branch(s: StepStart, j: int, a):
    """A lockable leg j with its axial branches ``a`` at the start: the curve it takes if
    it is locked and is released (1 loading: the one nearer to its holding force), and
    the lock argument of its contact step (locked, e_S, the stroke rate's sign)."""
    S0 = ca.dot(s.feet[j]["force_body"], a["e_S"])
    to_load = ca.fabs(S0 - a["S_load"]) <= ca.fabs(S0 - a["S_unload"])
    # (a foot that touches down loads by the curves' own test: at zero
    # deflection they take the loading branch, characteristics.ZERO_DEFLECTION)
    rate = ca.if_else(to_load, 1.0, -1.0) * ca.dot(a["loading"], a["e_S"])
    return to_load, (s.locked0[j], a["e_S"], rate)


def lock_candidates(s: StepStart, res, rho0, release_loading):
    """Which lockable legs may lock or turn (the chord's branch test, or a switch located
    inside the step), and each one's branch at the end if it does not lock."""
    cand, end_loading = [], []
    for j in s.lockable:
        r, stored = res[j], s.stored_loading[j]
        flip, ax = branch_flip(s.fns_of[j], s.p_of[j], rho0[j], s.feet[j]["force_body"],
                               r["l_whole"], s.h, stored)
        new_loading = ax["new_loading"]
        if r["split"] is not None:
            # a switch located inside the step is a reversal as well
            flip = ca.logic_or(flip, r["split"]["use"])
            new_loading = ca.if_else(r["split"]["use"], ca.logic_not(stored), new_loading)
        end_loading.append(ca.if_else(s.locked0[j], release_loading[j],
                                      ca.if_else(r["in_contact"], new_loading, 1.0)))
        cand.append(ca.logic_and(ca.logic_and(ca.logic_not(s.locked0[j]), flip),
                                 r["in_contact"]))
    return cand, end_loading


class _Hold(NamedTuple):
    """The lock's second kick: the step, the feet's results, the drift, where each
    lockable leg would hold, and the symbols of its solves."""

    s: StepStart
    res: list
    vel_h: object
    omega_h: object
    R1: object
    hold: dict
    mu_sym: ca.SX
    lam_sym: ca.SX
    nu: ca.SX
    W: object


def _hold_poses(s: StepStart, res, pos1, R1) -> dict:
    """Where each lockable leg would hold: its foot stuck at its stored world point."""
    hold = {}
    for j in s.lockable:
        rho = R1.T @ (s.feet[j]["foot"] - pos1)
        a = axial_branches(s.fns_of[j], s.p_of[j], rho)
        hold[j] = dict(rho=rho, e_S=a["e_S"], L=a["L"], lo=a["lo"], hi=a["hi"],
                       S_load=a["S_load"], S_unload=a["S_unload"],
                       bend=bending_force(s.fns_of[j], s.p_of[j], rho, res[j]["v_rel"],
                                          a["e_S"]))
    return hold


def _kick(c: _Hold, mask, S):
    return second_kick(c.s, c.res, c.vel_h, c.omega_h, c.R1, c.hold, mask, S)


def _held_rates(c: _Hold, mask, v, w):
    return ca.vertcat(*[ca.if_else(mask[k], stroke_rate(c.hold[j]["rho"], c.hold[j]["e_S"],
                                                        v, w, c.R1), 0.0)
                        for k, j in enumerate(c.s.lockable)])


def _within(c: _Hold, j, S):
    """S between the curves and the held force in the friction cone."""
    hj = c.hold[j]
    return ca.logic_and(ca.logic_and(hj["lo"] <= S, S <= hj["hi"]),
                        inside_cone(hj["bend"] + S * hj["e_S"], c.res[j]["n_b"], c.s.mu))


def _rattle(c: _Hold, held, fixed, S_fixed):
    """v, ω, μ: the legs of ``held`` with zero stroke rate at the end (RATTLE), the legs
    of ``fixed`` stuck with the axial forces ``S_fixed``."""
    n_lk = len(c.s.lockable)
    S = [ca.if_else(fixed[k], S_fixed[k], c.mu_sym[k]) for k in range(n_lk)]
    both = [ca.logic_or(held[k], fixed[k]) for k in range(n_lk)]
    kick = _kick(c, both, S)
    v_mu, w_mu = kick.vel, kick.omega
    rate = _held_rates(c, held, v_mu, w_mu) + ca.vertcat(
        *[ca.if_else(held[k], 0.0, c.mu_sym[k]) for k in range(n_lk)])
    mu_value = newton_masked(rate, c.mu_sym, held, iterations=1)
    v1, w1 = ca.substitute([v_mu, w_mu], [c.mu_sym], [mu_value])
    return v1, w1, mu_value


def _holding(c: _Hold, held, fixed, S_fixed, v1, w1):
    """v, ω projected onto the held strokes (in the metric of M) and the forces that hold
    them (δ_S″ = 0), the legs of ``fixed`` stuck with ``S_fixed``."""
    n_lk, nu, lam = len(c.s.lockable), c.nu, c.lam_sym
    G = ca.substitute(ca.jacobian(_held_rates(c, held, nu[0:3], nu[3:6]), nu), nu,
                      ca.DM.zeros(6))                       # the rates are linear in ν
    nu1 = ca.vertcat(v1, w1)
    nu_p = nu1 - c.W @ G.T @ solve_masked(G @ c.W @ G.T, G @ nu1, held)
    v_p, w_p = nu_p[0:3], nu_p[3:6]
    S = [ca.if_else(fixed[k], S_fixed[k], lam[k]) for k in range(n_lk)]
    both = [ca.logic_or(held[k], fixed[k]) for k in range(n_lk)]
    kick = _kick(c, both, S)
    a_lam, alpha_lam = body_acceleration(c.s.body, c.R1, kick.force, kick.torque, w_p)
    dd = ca.vertcat(*[ca.if_else(held[k], stroke_acceleration(
        c.hold[j]["rho"], c.hold[j]["e_S"], c.hold[j]["L"], v_p, w_p, a_lam, alpha_lam, c.R1),
        lam[k]) for k, j in enumerate(c.s.lockable)])
    return v_p, w_p, newton_masked(dd, lam, held, iterations=1)


def _accept_or_stay(c: _Hold, cand, retry, lam1, stored_S):
    """Per lockable leg: it locks (its holding force ``lam1`` between the curves and in
    the cone), or stays stuck on its stored branch (beyond that curve)."""
    accept, stay = [], []
    for k, j in enumerate(c.s.lockable):
        hj = c.hold[j]
        accept.append(ca.logic_and(ca.logic_or(cand[k], retry[k]), _within(c, j, lam1[k])))
        outside = ca.logic_or(lam1[k] < hj["lo"], lam1[k] > hj["hi"])
        beyond_stored = ca.logic_and(outside, ca.fabs(lam1[k] - stored_S[k]) < ca.fabs(
            lam1[k] - (hj["S_load"] + hj["S_unload"] - stored_S[k])))
        stay.append(ca.logic_and(ca.logic_and(cand[k], ca.logic_not(accept[k])),
                                 ca.logic_and(beyond_stored, inside_cone(
                                     hj["bend"] + stored_S[k] * hj["e_S"],
                                     c.res[j]["n_b"], c.s.mu))))
    return accept, stay


def lock_phase(s: StepStart, drift, res, cand, end_loading):
    """The lock's second kick: v, ω, a at the end and, per lockable leg, the entries of
    :data:`LOCK_LEG_OUT` (a list: :func:`_lock_outputs`)."""
    vel_h, omega_h, pos1, quat1 = drift
    R1 = quat_to_rot(quat1)
    n_lk = len(s.lockable)
    c = _Hold(s, res, vel_h, omega_h, R1, _hold_poses(s, res, pos1, R1),
              ca.SX.sym("mu_lock", n_lk), ca.SX.sym("lam", n_lk), ca.SX.sym("nu", 6),
              ca.diagcat(ca.DM.eye(3) / s.body.m, s.body.inertia_inv))   # M⁻¹ of (v, ω)
    hold = c.hold
    off = [ca.SX(0)] * n_lk                                  # no leg; no force
    # RATTLE on the locked legs; μ off [S_u, S_l], or the held force out of the cone,
    # releases a leg onto the curve nearer to its stored force
    locked = [s.locked0[j] for j in s.lockable]
    _, _, mu1 = _rattle(c, locked, off, off)
    keep = [ca.logic_and(locked[k], _within(c, j, mu1[k])) for k, j in enumerate(s.lockable)]
    v_a, w_a, _ = _rattle(c, keep, off, off)
    # a foot in contact whose chord says its stroke reversed (``cand``): the force that
    # would hold its stroke, stuck where it was, after the velocities are projected onto
    # the held strokes (the contact step's own answer carried the wrong branch's force,
    # which may even have made it slip). Between the curves and in the cone: it locks.
    # Beyond the curve of its stored branch: the reversal was not one (a chord of O(h³)
    # after a release), it stays on that branch, stuck. Else: a direct switch.
    stored_S = [ca.if_else(s.stored_loading[j], hold[j]["S_load"], hold[j]["S_unload"])
                for j in s.lockable]
    # a leg that RATTLE released alone is tried again with the others: two legs may
    # hold together where neither holds alone
    retry = [ca.logic_and(locked[k], ca.logic_not(keep[k])) for k in range(n_lk)]
    _, _, lam1 = _holding(c, [ca.logic_or(ca.logic_or(keep[k], cand[k]), retry[k])
                              for k in range(n_lk)], off, off, v_a, w_a)
    accept, stay = _accept_or_stay(c, cand, retry, lam1, stored_S)
    v_b, w_b, mu2 = _rattle(c, keep, stay, stored_S)
    keep = [ca.logic_or(keep[k], ca.logic_and(retry[k], accept[k])) for k in range(n_lk)]
    held = [ca.logic_or(keep[k], accept[k]) for k in range(n_lk)]
    v_p, w_p, lam2 = _holding(c, held, stay, stored_S, v_b, w_b)
    entered = any_of(accept)
    vel1, omega1 = ca.if_else(entered, v_p, v_b), ca.if_else(entered, w_p, w_b)
    S_end = ca.if_else(entered, lam2, mu2)
    stuck = [ca.logic_or(held[k], stay[k]) for k in range(n_lk)]
    S1 = [ca.if_else(stay[k], stored_S[k], S_end[k]) for k in range(n_lk)]
    legs = [dict(locked=held[k], stuck=stuck[k],
                 rho1=ca.if_else(stuck[k], hold[j]["rho"], res[j]["rho1"]),
                 P1=ca.if_else(stuck[k], hold[j]["bend"] + S1[k] * hold[j]["e_S"],
                               res[j]["P1"]),
                 loading=ca.if_else(stay[k], s.stored_loading[j], end_loading[k]))
            for k, j in enumerate(s.lockable)]
    return _lock_outputs((vel1, omega1, _kick(c, stuck, S1).acc), legs)


def _lock_outputs(body, legs) -> list:
    """The gated call's outputs: v, ω, a, then each lockable leg's :data:`LOCK_LEG_OUT`."""
    return list(body) + [leg[key] for leg in legs for key in LOCK_LEG_OUT]


def _lock_results(out, lockable):
    """(v, ω, a) and {leg: {LOCK_LEG_OUT entry: value}} from the gated call's outputs."""
    n = len(LOCK_LEG_OUT)
    legs = {j: dict(zip(LOCK_LEG_OUT, out[3 + n * k: 3 + n * (k + 1)]))
            for k, j in enumerate(lockable)}
    return tuple(out[:3]), legs


def gated_lock_phase(s: StepStart, drift, res, cand, end_loading):
    """:func:`lock_phase` in a call that runs only when a leg is locked or turns; in the
    other steps its values are those of the plain second kick. Returns (v, ω, a), the
    lockable legs' :data:`LOCK_LEG_OUT` by leg, and the call's Function."""
    drift_in = [ca.SX.sym(name, n) for name, n in (("vel_h", 3), ("omega_h", 3),
                                                   ("pos1", 3), ("quat1", 4))]
    res_in = [{key: ca.SX.sym(f"{key}_{j}", 3) for key in
               (("P1", "rho1", "v_rel", "n_b") if j in s.lockable else ("P1", "rho1"))}
              for j in range(s.n_legs)]
    n_lk = len(s.lockable)
    cand_in, end_in = ca.SX.sym("cand", n_lk), ca.SX.sym("end_loading", n_lk)
    on = lock_phase(s, drift_in, res_in, ca.vertsplit(cand_in), ca.vertsplit(end_in))
    plain = second_kick(s, res_in, drift_in[0], drift_in[1], quat_to_rot(drift_in[3]))
    off = _lock_outputs((plain.vel, plain.omega, plain.acc), [dict(locked=ca.SX(0), stuck=ca.SX(0),
                                         rho1=res_in[j]["rho1"], P1=res_in[j]["P1"],
                                         loading=end_in[k])
                                    for k, j in enumerate(s.lockable)])
    out, f_on = skip_unless(
        "touchdown_lock_hold", any_of(list(s.locked0.values()) + cand),
        [s.X, s.p, s.h] + drift_in + [x for r in res_in for x in r.values()] + [cand_in, end_in],
        [s.X, s.p, s.h] + list(drift) + [res[j][key] for j, r in enumerate(res_in) for key in r]
        + [ca.vertcat(*cand), ca.vertcat(*end_loading)], on, off)
    body, legs = _lock_results(out, s.lockable)
    return body, legs, f_on


def switch_kick(s: StepStart, res, ends, R1):
    """ΣΔF, ΣΔτ (body axes): the kick correction (B1) of ``symcushion.scheme.branch_switch`` at
    each leg's located loading/unloading switch (``events`` "branch", "lock"), and the
    kick of each memory-law leg's located touchdown, lift-off and crush onset
    (``FeetStep.event_kick``). ``ends[j]``: leg j's end pose ``rho1``, force ``P1`` and
    whether (B1) applies (``b1_active``)."""
    switch_force, switch_torque = ca.DM.zeros(3), ca.DM.zeros(3)   # (B1)
    for j, leg in enumerate(s.model.legs):
        r = res[j]
        if r.get("events") is not None:
            # a touchdown or lift-off located inside the step (memory law, FeetStep.event_kick)
            switch_force, switch_torque = switch_force + r["events"][0], \
                switch_torque + r["events"][1]
        if s.scheme.events in ("branch", "lock") and locates_switch(leg):
            # the kick at the located loading/unloading switch (symcushion.scheme.branch_switch)
            dF, dT, _ = branch_switch_kick(
                s.fns_of[j], s.p_of[j],
                dict(rho0=r["rho_s"], F0=s.feet[j]["force_body"], rho1=ends[j]["rho1"],
                     F1=ends[j]["P1"], active=ends[j]["b1_active"],
                     stored_loading=s.stored_loading.get(j), split=r["split"]),
                dict(h=s.h, R=s.R, R1=R1, v=s.vel, omega=s.omega, l=r["l"]))
            switch_force, switch_torque = switch_force + dF, switch_torque + dT
    return switch_force, switch_torque
