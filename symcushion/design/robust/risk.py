"""The loss a design for the envelope minimises: saturated ratios and their risk measure.

Per scenario s and check c of a design for the envelope
(:class:`~.problem.EnvelopeDesign`) the loss is L_sc = sat(r_sc) − 1, with
r_sc the smooth value/limit of :mod:`.margins` (> 0 fails) and sat the
identity up to 1 that then levels off smoothly at ``saturation``::

    sat(r) = r                                           r ≤ 1
    sat(r) = 1 + (R − 1)·tanh((r − 1)/(R − 1))           r > 1

so that a scenario far beyond a limit (a tip-over the legs cannot prevent)
stops pulling the design; it is C² at r = 1. Risk measures of the scenario
loss L_s = max_c L_sc, each exact through an epigraph (no max is formed):

* ``cvar``: the conditional value at risk at level α (Rockafellar–Uryasev),
  min η + Σ_s u_s/((1 − α)·S) with u_s ≥ L_sc − η for every c and u_s ≥ 0:
  the mean loss of the worst (1 − α) share of the scenarios;
* ``worst``: min η with η ≥ L_sc for every s and c.

This module owns the risk measures' names and defaults (``RISKS``,
``DEFAULT_ALPHA``, ``DEFAULT_SATURATION``, ``DEFAULT_TIP_ENERGY``,
``DEFAULT_HORIZON``), :func:`saturate` and :func:`design_checks`. It must not
build or solve the NLP (:mod:`.problem` does) nor evaluate scenarios.
"""
from __future__ import annotations

import casadi as ca
import numpy as np

from symcushion.design.robust.margins import CHECKS

__all__ = ["RISKS", "DEFAULT_ALPHA", "DEFAULT_SATURATION", "DEFAULT_TIP_ENERGY",
           "DEFAULT_HORIZON", "saturate", "design_checks"]

#: Risk measures of the scenario losses.
RISKS = ("cvar", "worst")
#: CVaR level: the mean loss of the worst half of the scenarios. The scenarios
#: are chosen near and beyond the boundary of the stable region, so the worse
#: half are those a design can still turn; α → 1 approaches ``worst``.
DEFAULT_ALPHA = 0.5
#: Level R at which sat(r) levels off: a ratio three times its limit is lost
#: whatever the design does; its gradient is then below 1e-3 of a ratio's
#: near the limit (sech²(5) once r is 11).
DEFAULT_SATURATION = 3.0
#: Unit of the tip-over energy margin in a study with a tilt limit (m of
#: lift of the centre of mass; ``tip_surplus`` of symcushion.scheme.measures): the
#: ``tip_energy`` ratio is 1 + surplus/unit, 1 when the body has just the
#: energy to pass over an edge of its support polygon (the rigid-pivot
#: criterion, on the safe side: the pivot legs' strokes take energy out).
#: 0.1 m spreads the example lander's stable touchdowns over ratios of about
#: 0 to 1.4 (docs/optimise.md); a study may set another with
#: ``robust.tip_energy``.
DEFAULT_TIP_ENERGY = 0.1
#: Horizon of a scenario when none is given: the envelope study's own
#: duration, so that the at-rest check is taken where the verification takes
#: it (a lander that tips goes past the 35° limit within about a second of
#: touchdown on the example study, docs/envelope.md, so any horizon from
#: ~1.5 s decides tip-overs; resting needs the full 2 s).
DEFAULT_HORIZON = None


def saturate(r, top: float = DEFAULT_SATURATION):
    """sat(r): r up to 1, then leveling off smoothly at ``top`` (NumPy or CasADi)."""
    span = top - 1.0
    if isinstance(r, (ca.MX, ca.SX, ca.DM)):
        return ca.if_else(r <= 1, r, 1 + span * ca.tanh((r - 1) / span))
    r = np.asarray(r, dtype=float)
    return np.where(r <= 1, r, 1 + span * np.tanh((r - 1) / span))


def design_checks(limits: dict) -> list:
    """The checks whose losses the design minimises, in :data:`CHECKS` order.

    Every check with a limit, except the tilt where the tip-over energy check
    is on: the tilt of a tipped lander saturates its loss whatever the design,
    and a scenario's loss is its largest over the checks, so the tilt would
    hide the energy margin's gradient. The tilt limit then only fades the
    energy samples of a lander that has tipped (:func:`.margins.tip_energy`).
    """
    energy = limits.get("tip_energy") is not None
    return [c for c in CHECKS if limits.get(c) is not None
            and not (c == "tip_over" and energy)]
