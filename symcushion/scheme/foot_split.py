"""The contact step split at a located branch switch, inside the feet's step.

With ``events = "branch"`` or ``"lock"`` (docs/scenes.md), a strut whose axial
absorber has a non-smooth unloading curve can change curves inside a step: the
force law (2.1) jumps there. This module owns the split step of such a foot, on
the stored curve up to the switch, the massless foot's jump onto the other
curve, then on to the end (:meth:`SplitAtSwitch.split_at_switch`), run in a
gated call only in the steps where a switch is possible
(:meth:`SplitAtSwitch.located_split`); :class:`~symcushion.scheme.foot_step.FeetStep`
mixes it in. It must not move the body, decide the switch time itself
(``symcushion.scheme.branch_switch`` does, (B2)) or change the contact step.
"""
from __future__ import annotations

import casadi as ca

from symcushion.model.obstacles import closest_obstacle
from symcushion.scheme.branch_switch import (branch_flip, locates_switch, stored_branch,
    switch_in_step)
from symcushion.scheme.quaternion import quat_exp, quat_mul, quat_to_rot
from symcushion.scheme.stroke_lock import axial_branches, skip_unless

__all__ = ["SplitAtSwitch"]


class SplitAtSwitch:
    """The split contact step of a foot at its axial branch switch; a mixin of
    :class:`~symcushion.scheme.foot_step.FeetStep` (it uses its poses, contact step,
    kinematics at the start and middle, gated calls and the step's inputs)."""

    def on_surface(self, rho, delta, pos_e, R_e, pad=0.0):
        """The foot ρ + δ at the pose (pos_e, R_e) put on the obstacle (its offset surface
        for a footpad of radius ``pad``): world, body."""
        _, _, w = closest_obstacle(self.model.obstacles, pos_e + R_e @ (rho + delta), pad)
        return w, R_e.T @ (w - pos_e)

    def split_at_switch(self, leg, rho_s, r_s, stored):
        """The contact step of ``leg``'s foot split at its axial branch switch: on the
        stored curve up to the switch, the foot's jump onto the other curve there,
        then on to the end. Returns the split step's (out, l, n_b, world normal,
        rate, start foot ρ of its last part) and the switch's ``use`` and θ."""
        P = self.poses
        h, fns, p_leg = P.h, leg.fns, leg.p_leg

        def on_branch(loading, rho):
            a = axial_branches(fns, p_leg, rho)
            rate = ca.if_else(loading, 1.0, -1.0) * ca.dot(a["loading"], a["e_S"])
            return lambda l_: l_ / h + (rate - ca.dot(a["e_S"], l_ / h)) * a["e_S"]

        # where the switching function crosses zero, following the sliding foot: its
        # middle position on the stored curve over the whole step
        whole, _, _, _, _ = self.contact_from(leg, rho_s, r_s, P.pos1, P.R1,
                                              on_branch(stored, rho_s), P.R)
        sw = switch_in_step(fns, rho_s, rho_s + whole["delta"] / 2, stored, self.kin_start,
                            self.kin_mid)
        theta = sw["theta"]
        pos_t = P.pos + theta * h * P.vel_h
        quat_t = quat_mul(P.quat, quat_exp(theta * h * P.omega_h))
        R_t = quat_to_rot(quat_t / ca.norm_2(quat_t))
        new = ca.logic_not(stored)
        # up to the switch on the stored curve
        before, _, _, _, _ = self.contact_from(leg, rho_s, r_s, pos_t, R_t,
                                               on_branch(stored, rho_s), P.R)
        foot_t, rho_t = self.on_surface(rho_s, before["delta"], pos_t, R_t, leg.pad)
        # at the switch the massless foot finds its equilibrium on the new curve at
        # once (l = 0: the body does not move during the jump)
        jump, _, _, _, _ = self.contact_from(leg, rho_t, foot_t, pos_t, R_t,
                                             on_branch(new, rho_t), R_t)
        foot_t, rho_t = self.on_surface(rho_t, jump["delta"], pos_t, R_t, leg.pad)
        after, l, n_b, normal_w, v_rel = self.contact_from(leg, rho_t, foot_t, P.pos1, P.R1,
                                                           on_branch(new, rho_t), R_t)
        use = ca.logic_and(ca.logic_and(sw["switches"], leg.foot["contact"] > 0.5),
                           ca.logic_and(before["contact"] > 0.5, jump["contact"] > 0.5))
        return (after, l, n_b, normal_w, v_rel, rho_t), dict(use=use, theta=theta)

    def located_split(self, j, leg, plain_step, rho_s, r_s, in_contact, release, stored):
        """Foot ``j``'s step split at its located branch switch where one is possible,
        else ``plain_step`` = (out, l, n_b, world normal, rate) as it is. Returns
        (out, (l, n_b, world normal, rate, start foot ρ of the last part), the
        switch's ``use`` and θ, or None where no switch is located)."""
        out, l, n_b, normal_w, v_rel = plain_step
        if not (self.scheme.events in ("branch", "lock") and locates_switch(leg.strut)):
            return out, (l, n_b, normal_w, v_rel, rho_s), None
        # the split step, in a call that runs only where the foot is in contact and
        # either the chord or the switching function at the unsplit step's middle
        # foot point (the split's own where the chord keeps the stored curve) says
        # the curve changes: elsewhere (B2) finds no switch and the call's value is
        # the unsplit step's
        fns, p_leg = leg.fns, leg.p_leg
        if stored is None:
            stored = stored_branch(fns, p_leg, rho_s, leg.foot["force_body"])
        flip, _ = branch_flip(fns, p_leg, rho_s, leg.foot["force_body"], l, self.poses.h,
                              stored)
        near = switch_in_step(fns, rho_s, rho_s + out["delta"] / 2, stored, self.kin_start,
                              self.kin_mid)["switches"]
        candidate = ca.logic_and(in_contact, ca.logic_or(flip, near))
        if release is not None:
            candidate = ca.logic_and(candidate, ca.logic_not(release[0]))
        keys = sorted(out)
        plain = [out[k] for k in keys] + [l, n_b, normal_w, v_rel, rho_s]
        plain_in = [ca.SX.sym(f"plain{k}", x.sparsity()) for k, x in enumerate(plain)]
        parts, sw = self.split_at_switch(leg, rho_s, r_s, stored)
        parts = [parts[0][k] for k in keys] + list(parts[1:])
        on = [ca.if_else(sw["use"], a, b) for a, b in zip(parts, plain_in)]
        got, self.gated[f"touchdown_split_{j}"] = skip_unless(
            f"touchdown_split_{j}", candidate, self.step_inputs + plain_in,
            self.step_inputs + plain,
            on + [sw["use"], ca.if_else(sw["use"], sw["theta"], 0.5)],
            plain_in + [ca.SX(0), ca.SX(0.5)])
        out = dict(zip(keys, got[:len(keys)]))
        l, n_b, normal_w, v_rel, rho_last = got[len(keys):len(keys) + 5]
        return out, (l, n_b, normal_w, v_rel, rho_last), dict(use=got[-2], theta=got[-1])
