"""The free foot of a leg on the memory law, evaluated only in the steps that read it.

A leg on the memory law (``symcushion.legs.absorber``) with dampers on its
hinges relaxes its free foot over a step by Newton's method on the three
deflections of (2.1) (``strut_free_foot``, (A4)): about 1,100 SX instructions
per leg, with their arcsines and arctangents, a quarter of the envelope's
step. A step reads that foot only where the foot is free at its start (the
crossing of the obstacle, the end pose of a foot that stays free) or where a
contact pass lifts it off (the pass's δ = −u₀ = −(ρ_s − ρ_free), and the end
pose). In the other steps, a foot that stays in contact, every read of it is
multiplied out by CasADi's ``if_else`` (its untaken side is zeroed, not
summed). So the foot is a gated call (``Function.conditional``, as
``stroke_lock.skip_unless``, on the step's own symbols so that it runs the
step's operations) that runs the Newton iteration only where a read is
coming, and the contact passes of such a leg are called with u₀ = 0
and get a lift-off's δ back afterwards, by the same operations as inside the
contact step: the step's values are the same bits as with the foot evaluated
in every step.

This module owns that gated call and the lift-off's δ. It must not change
the free foot's law, the contact step, or decide which passes a foot runs
(``symcushion.scheme.foot_step`` does).
"""
from __future__ import annotations

import casadi as ca

__all__ = ["FreeFoot", "gated_call"]

#: Forward-mode AD through the conditional, as the other gated calls.
_GATED_OPTS = {"ad_weight": 0, "ad_weight_sp": 0}


def gated_call(name: str, on) -> tuple:
    """``name(flag, inputs, fallback) -> r``: the expression ``on`` where ``flag`` is
    set, ``fallback`` (copied) elsewhere, as one ``never_inline`` Function; its
    ``inputs`` are the symbols ``on`` reads (:func:`casadi.symvar`, e.g. the entries
    of the step's x, p and dt), so that its constants fold as they do inlined in
    the step and it runs the step's operations, and a call copies only those.
    Returns the Function, those symbols (the value of ``inputs`` in the caller's
    graph) and the Function of ``on`` (the work it may skip)."""
    used = ca.vertcat(*ca.symvar(on))
    fallback = ca.SX.sym("fallback", on.sparsity())
    f_on = ca.Function(f"{name}_on", [used, fallback], [on], dict(_GATED_OPTS, cse=True))
    f_off = ca.Function(f"{name}_off", [used, fallback], [fallback], _GATED_OPTS)
    switch = ca.Function.conditional(f"{name}_switch", [f_off], f_on, _GATED_OPTS)
    flag = ca.MX.sym("flag")
    sym = [ca.MX.sym("inputs", used.sparsity()), ca.MX.sym("fallback", on.sparsity())]
    call = ca.Function(name, [flag] + sym, [switch(flag, *sym)],
                       ["flag", "inputs", "fallback"], ["r"], dict(_GATED_OPTS, never_inline=True))
    return call, used, f_on


class FreeFoot:
    """A leg's free foot at the end of one step (body frame), evaluated where it is read.

    ``value`` holds the foot (A4) wherever ``known`` is set, and zeros or an
    earlier value elsewhere, where no read of it is taken; :meth:`where` extends
    it to where a flag is set, evaluating the foot only where it was not yet.

    Parameters
    ----------
    name : str
        Of the gated call (``touchdown_free_foot_{j}``).
    foot : casadi.SX
        The free foot (3, 1), an expression of the step's inputs.
    needed : casadi.SX
        Where the foot is read before any contact pass (a foot free at the start).

    Attributes
    ----------
    work : casadi.Function
        The foot's Function, the work the gated calls skip.
    """

    def __init__(self, name: str, foot, needed):
        self._call, self._args, self.work = gated_call(name, foot)
        self.known = needed
        self.value = self._call(ca.if_else(needed, 1.0, 0.0), self._args, ca.DM.zeros(3))

    def where(self, flag):
        """The foot, now also evaluated where ``flag`` is set."""
        new = ca.logic_and(flag, ca.logic_not(self.known))
        self.value = self._call(ca.if_else(new, 1.0, 0.0), self._args, self.value)
        self.known = ca.logic_or(self.known, flag)
        return self.value

    def lifted(self, rho_s, out: dict) -> dict:
        """A contact pass's outputs ``out``, called with u₀ = 0, with δ = −u₀ where it
        lifts the foot off (``contact.guards.lift_off``; ``contact`` is 0 there and
        only there), u₀ = ρ_s − ρ_free: the operations of the contact step, so the
        same bits as a pass given u₀."""
        lift = out["contact"] < 0.5
        u0 = rho_s - self.where(lift)
        return dict(out, delta=ca.if_else(lift, -u0, out["delta"]))
