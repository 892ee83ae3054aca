"""The touchdown step split at its parameters, for the compiled rollout.

This module owns :func:`hoisted_step`: ``touchdown_step(x, p, dt)`` cut by
``casadi.extract_parametric`` into what depends on ``p`` alone
(``touchdown_step_parametric``, run once per rollout) and the rest
(``touchdown_step_core``, run every step), and the names of the two. It must
not change what the step computes (the parts execute the step's own
operations on the same operands), write C or build anything
(``symcushion.compiled.codegen`` does).
"""
from __future__ import annotations

import casadi as ca
import numpy as np

__all__ = ["hoisted_step", "PARAMETRIC", "CORE"]

#: The step split for the rollout (:func:`hoisted_step`): what depends on p alone,
#: computed once per rollout, and the rest, called once per step.
PARAMETRIC = "touchdown_step_parametric"
CORE = "touchdown_step_core"


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

