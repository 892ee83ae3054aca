"""The touchdown step split at its parameters, for the compiled rollout.

This module owns :func:`hoisted_step`: ``touchdown_step(x, p, dt)`` cut by
``casadi.extract_parametric`` into what depends on ``p`` alone
(``touchdown_step_parametric``, run once per rollout) and the rest
(``touchdown_step_core``, run every step), the rest without the per-step
outputs (:func:`states_only`, ``touchdown_step_states``, run by a rollout
that is not asked for Y), and the names of the three. It must
not change what the step computes (the parts execute the step's own
operations on the same operands), write C or build anything
(``symcushion.compiled.codegen`` does).
"""
from __future__ import annotations

import casadi as ca
import numpy as np

__all__ = ["hoisted_step", "states_only", "PARAMETRIC", "CORE", "STATES", "STATES_MIN_SAVING"]

#: The step split for the rollout (:func:`hoisted_step`): what depends on p alone,
#: computed once per rollout, and the rest, called once per step.
PARAMETRIC = "touchdown_step_parametric"
CORE = "touchdown_step_core"
#: The core without its output y, called by a rollout whose caller wants X only.
STATES = "touchdown_step_states"
#: :func:`states_only` is generated only where it leaves out at least this share of the
#: core's SX instructions: it is a second copy of the step for gcc (the touchdown
#: source's compile time grows by some 60 % on Fig. 3), which pays on Figs. 3-4 and
#: lander_slope (14-15 % of the core, 5-10 % of the time per step) and not on the
#: tutorial lander (3 %: its memory law's state needs most of what y reads).
STATES_MIN_SAVING = 0.10


def hoisted_step(step: ca.Function) -> tuple[ca.Function, ca.Function, ca.Function]:
    """(step, parametric, core): ``step`` split at what depends on ``p`` alone.

    ``touchdown_step(x, p, dt)`` computes, in every step, values that depend on
    the parameters only (the inverse of the inertia, the legs' unit axes e₀ and
    e_n, their rest angle γ₀ by atan2, the rest feet): for Fig. 3 some 200 of
    its 5 400 SX instructions, 4 of its 12 atan2. ``casadi.extract_parametric``
    cuts the step's graph there: ``touchdown_step_parametric(p) -> q`` holds
    those instructions, ``touchdown_step_core(x, p, dt, q) -> (x_next, y)`` the
    rest, with q in their place. The rollout runs the first once and the
    second N times (symcushion/compiled/c/rollout.c); the returned ``touchdown_step`` is
    the two called in turn (an MX Function of the same name and arguments as
    ``step``), so that the C source holds the step's instructions once. All
    execute the step's own operations on the same operands: the results are
    the same bits.
    """
    x, p, dt = step.sx_in()
    out = step.call([x, p, dt])
    sizes = [o.numel() for o in out]
    expr, symbols, values = ca.extract_parametric(ca.vertcat(*[ca.vec(o) for o in out]), p)
    q = ca.vertcat(*[ca.vec(s) for s in symbols]) if symbols else ca.SX(0, 1)
    q_value = ca.vertcat(*[ca.vec(v) for v in values]) if values else ca.SX(0, 1)
    parametric = ca.Function(PARAMETRIC, [p], [q_value], ["p"], ["q"], {"cse": True})
    parts = ca.vertsplit(expr, list(np.cumsum([0] + sizes)))
    core = ca.Function(CORE, [x, p, dt, q], [ca.reshape(part, o.shape)
                                              for part, o in zip(parts, out)],
                       ["x", "p", "dt", "q"], step.name_out(), {"cse": True})
    args = [ca.MX.sym(name, step.sparsity_in(i)) for i, name in enumerate(step.name_in())]
    whole = ca.Function(step.name(), args, core(*args, parametric(args[1])), step.name_in(),
                        step.name_out())
    return whole, parametric, core



def states_only(core: ca.Function) -> ca.Function | None:
    """``touchdown_step_states(x, p, dt, q) -> x_next``: ``core`` without its per-step
    outputs y; None where that leaves out less than STATES_MIN_SAVING of the core.

    A rollout asked for the states alone (a null Y, as the envelope's
    classification reads them) still paid for y in every step: the legs' world
    forces, normals and axes, their angles β, γ (an atan2 and an asin per leg)
    and the works of the elements, some 14 % of the core's SX instructions on
    Fig. 3. This Function is ``core``'s graph cut at x_next: the same
    operations on the same operands for what remains, so x_next is the same
    bits.
    """
    x, p, dt, q = core.sx_in()
    x_next = core.call([x, p, dt, q])[0]
    states = ca.Function(STATES, [x, p, dt, q], [x_next], core.name_in(), [core.name_out(0)],
                         {"cse": True})
    saving = 1 - states.n_instructions() / core.n_instructions()
    return states if saving >= STATES_MIN_SAVING else None
