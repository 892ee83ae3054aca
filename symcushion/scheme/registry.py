"""The scheme registry: each choice of a :class:`~symcushion.model.parts.Scheme`
mapped to the parts of the step that carry it out, as SciPy's ``solve_ivp`` maps
each name of its ``METHODS`` to a solver.

A choice is validated once, by :class:`~symcushion.model.parts.Scheme` (alone)
and :func:`~symcushion.model.parts.check_scheme` (against a model); the step reads
it from the scheme it is built with. This module owns :data:`SCHEME_PARTS` (what
each choice changes in the step, and where) and :func:`valid_schemes` (every
scheme a model takes, which the tests build and step once each). It must not
build or run a step.
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass

from symcushion.contact.implicit import implicit_step
from symcushion.contact.midpoint import midpoint_slip
from symcushion.contact.paper import paper_step
from symcushion.contact.robust import robust_step
from symcushion.legs import absorber
from symcushion.model.parts import SCHEME_OPTIONS, Model, Scheme, check_scheme
from symcushion.scheme import branch_switch, foot_step, stroke_lock, touchdown_events

__all__ = ["Part", "SCHEME_PARTS", "valid_schemes"]


@dataclass(frozen=True)
class Part:
    """What one choice does in the step (``summary``) and the functions that do it."""

    summary: str
    functions: tuple = ()


#: Every option of :data:`~symcushion.model.parts.SCHEME_OPTIONS`, each choice
#: with its part of the step.
SCHEME_PARTS = {
    "method": {
        "paper": Part("the contact step as printed, (1.8)-(1.15)", (paper_step,)),
        "robust": Part("the printed step with its weak points fixed (docs/contact.md)",
                       (robust_step,)),
        "implicit": Part("the exact backward-Euler Coulomb step (docs/contact.md)",
                         (implicit_step,)),
    },
    "tangent_plane": {
        "start": Part("one contact step on the plane tangent at the foot's start point",
                      (foot_step.FeetStep.contact_from,)),
        "end": Part("a second contact step on the plane tangent where the first ends",
                    (foot_step.FeetStep.contact_from,)),
    },
    "slip": {
        "backward": Part("the slip direction of the end force (backward Euler)"),
        "midpoint": Part("the slip direction of the fitted mean force, a Newton correction "
                         "after the implicit step", (midpoint_slip,
                                                     foot_step.FeetStep.memory_midpoint)),
    },
    "events": {
        "none": Part("velocity Verlet's kick, the legs' forces at the step's ends",
                     (touchdown_events.second_kick,)),
        "branch": Part("the kick corrected at each axial absorber's located branch switch "
                       "(B1)-(B2)", (branch_switch.branch_switch_kick,
                                     foot_step.FeetStep.split_at_switch,
                                     touchdown_events.switch_kick)),
        "lock": Part("the branch switches and the stroke lock of a stuck foot "
                     "(SHAKE/RATTLE)", (touchdown_events.shake_drift,
                                        touchdown_events.lock_candidates,
                                        touchdown_events.gated_lock_phase,
                                        stroke_lock.newton_masked)),
    },
    "hysteresis": {
        "sign": Part("the printed law P(δ, sign δ′) of (2.1)"),
        "memory": Part("the absorbers with memory (A1)-(A5): a set per absorber, a "
                       "continuous force, the located touchdowns and lift-offs",
                       (absorber.memory_force, absorber.next_set,
                        foot_step.FeetStep.event_kick, foot_step.FeetStep.kink_kick)),
    },
}


def valid_schemes(model: Model) -> list:
    """Every :class:`Scheme` the model takes, in the order of the choices."""
    out = []
    for values in itertools.product(*SCHEME_OPTIONS.values()):
        try:
            scheme = Scheme(**dict(zip(SCHEME_OPTIONS, values)))
            check_scheme(model, scheme)
        except ValueError:
            continue
        out.append(scheme)
    return out
