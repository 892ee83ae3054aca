"""The result of a design: optimum, characteristics, report and JSON.

Owns :class:`DesignResult`. It must not solve or evaluate.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from symcushion.run.output_files import atomic_write_text, jsonable
from symcushion.design.optimise.geometry import PRACTICAL_KINDS
from symcushion.design.optimise.spec import Evaluation

if TYPE_CHECKING:  # the problem module imports this one
    from symcushion.design.optimise.problem import DesignProblem

__all__ = ["DesignResult"]

#: Number of worst violations listed in messages.
_REPORT_WORST = 5


@dataclass
class DesignResult:
    """Outcome of :meth:`DesignProblem.solve`.

    Attributes
    ----------
    theta, theta0 : ndarray, shape (n,)
        Optimal and starting design values (SI), named ``problem.var_names``.
    evaluation, initial : Evaluation
        The optimal and the starting design simulated.
    return_status : str
        Ipopt's, e.g. ``"Solve_Succeeded"``.
    success : bool
    iterations : int
    history : list of dict
        Per iteration: objective (SI), max_violation (scaled), seconds, and
        Ipopt's inf_pr, inf_du, mu.
    timings : dict
        build_seconds, solve_seconds, Ipopt's wall time and Jacobian time.
    """

    problem: DesignProblem
    theta: np.ndarray
    theta0: np.ndarray
    evaluation: Evaluation
    initial: Evaluation
    return_status: str
    success: bool
    iterations: int
    history: list
    timings: dict
    meta: dict = field(default_factory=dict)

    @property
    def design(self) -> dict:
        return dict(zip(self.problem.var_names, map(float, self.theta)))

    @property
    def p(self) -> np.ndarray:
        """Full parameter vector (``problem.param_names``) of the optimum."""
        return self.problem.p_of(self.theta)

    @property
    def message(self) -> str:
        """One paragraph: status, objective and any violated constraints."""
        ev = self.evaluation
        unit = "m/s²" if self.problem.objective_kind == "peak_deceleration" else "m"
        text = (f"Ipopt {self.return_status} after {self.iterations} iterations: "
                f"{self.problem.objective_kind} {ev.objective:.6g} {unit} "
                f"(initial {self.initial.objective:.6g} {unit})")
        if ev.violations:
            text += "; the design is infeasible:\n  " + "\n  ".join(ev.violations[:_REPORT_WORST])
            if len(ev.violations) > _REPORT_WORST:
                text += f"\n  … and {len(ev.violations) - _REPORT_WORST} more"
        return text

    @property
    def efficiency(self):
        """Smallest ideal-absorber efficiency over the scenarios (None if undefined)."""
        values = [s["efficiency"] for s in self.evaluation.scenarios.values()
                  if s.get("efficiency") is not None]
        return min(values) if values else None

    def to_dict(self) -> dict:
        pb = self.problem
        return jsonable(dict(
            study=self.meta.get("name"),
            objective_kind=pb.objective_kind,
            objective=self.evaluation.objective,
            initial_objective=self.initial.objective,
            efficiency=self.efficiency,
            return_status=self.return_status,
            success=self.success,
            iterations=self.iterations,
            seconds=self.timings["build_seconds"] + self.timings["solve_seconds"],
            feasible=self.evaluation.feasible,
            violations=self.evaluation.violations,
            design=self.design,
            initial_design=dict(zip(pb.var_names, map(float, self.theta0))),
            bounds={n: [lo, hi] for n, lo, hi in zip(pb.var_names, pb.lower, pb.upper)},
            p={n: float(v) for n, v in zip(pb.param_names, self.p)},
            characteristic=pb.characteristics(self.theta),
            initial_characteristic=pb.characteristics(self.theta0),
            scenarios=self.evaluation.scenarios,
            initial_scenarios=self.initial.scenarios,
            limits=pb.limits.__dict__,
            timings=self.timings,
            history=self.history,
            **self._geometry(),
            **{k: v for k, v in self.meta.items() if k != "name"}))

    def _geometry(self) -> dict:
        """``geometry`` (the legs' geometry at the start and the optimum) and
        ``practical`` (each practical-limit row's value there), when designed or limited."""
        pb = self.problem
        if getattr(pb, "_frames", None) is None:
            return {}
        _, g = pb.fg(pb.scaled(self.theta, t=self.evaluation.objective))
        rows = [dict(kind=b.kind, leg=b.leg, label=b.label, unit=b.unit,
                     values=(g[b.start:b.stop] * b.scale).tolist())
                for b in pb.blocks if b.kind in PRACTICAL_KINDS]
        return dict(geometry=dict(start=pb.geometry_report(self.theta0),
                                  end=pb.geometry_report(self.theta)), practical=rows)

    def save_json(self, path):
        """Write :meth:`to_dict` as JSON (NaN and inf written as null)."""
        path = Path(path)
        if path.parent and not path.parent.exists():
            path.parent.mkdir(parents=True)
        atomic_write_text(path, json.dumps(self.to_dict(), indent=2, ensure_ascii=False) + "\n")
        return path
