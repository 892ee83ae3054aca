"""The outcome of a design for the envelope: :class:`RobustResult`.

This module owns the record :meth:`~.problem.EnvelopeDesign.solve` returns
(the optimum, the ratios before and after, the multipliers, the history) and
what it derives from it. It must not solve, evaluate or write anything.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from symcushion.design.optimise.result import NamedDesign

__all__ = ["RobustResult"]


@dataclass
class RobustResult(NamedDesign):
    """The outcome of :meth:`EnvelopeDesign.solve`.

    Attributes
    ----------
    theta : ndarray
        The optimal design (SI), in ``var_names`` order.
    var_names : list of str
    return_status : str
    iterations : int
    ratios_start, ratios : ndarray, shape (len(checks), S)
        value/limit of each check and scenario at the start and the optimum.
    checks : list of str
    scenarios : list of str
    objective_start, objective : float
        The risk measure of the losses at the start and the optimum.
    multipliers : dict
        ``scenarios``: per scenario, Ipopt's multiplier of its loss rows
        summed (how much the risk measure would gain if that scenario's
        limits were relaxed); ``checks``: the same summed per check;
        ``bounds``: design variables at a bound with their multipliers;
        ``shapes``: shape rows with a non-zero multiplier.
    history : list of dict
    timings : dict
    geometry : dict
        With geometry variables or practical limits: ``start`` and ``end``, the
        legs' geometry (:meth:`EnvelopeDesign.geometry_report`), and
        ``practical``, each practical-limit row's value at the end.
    """

    theta: np.ndarray
    var_names: list
    return_status: str
    iterations: int
    ratios_start: np.ndarray
    ratios: np.ndarray
    checks: list
    scenarios: list
    objective_start: float
    objective: float
    multipliers: dict = field(default_factory=dict)
    history: list = field(default_factory=list)
    timings: dict = field(default_factory=dict)
    geometry: dict = field(default_factory=dict)

    @property
    def success(self) -> bool:
        return self.return_status in ("Solve_Succeeded", "Solved_To_Acceptable_Level")

    def scenarios_within(self, which: str = "end") -> int:
        """How many scenarios meet every limit (all ratios ≤ 1) at the start or the end."""
        r = self.ratios if which == "end" else self.ratios_start
        return int(np.sum(np.all(r <= 1.0, axis=0)))
