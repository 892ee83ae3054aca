"""The result of a design: optimum, characteristics, report and JSON.

Owns :class:`DesignResult`, plain data the problem's solve fills in (it keeps no
reference to the problem). It must not solve or evaluate.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
import numpy as np

from symcushion.run.output_files import atomic_write_text, jsonable
from symcushion.design.optimise.spec import Evaluation

__all__ = ["DesignResult", "NamedDesign"]

#: Number of worst violations listed in messages.
_REPORT_WORST = 5


class NamedDesign:
    """The ``design`` of a result with ``var_names`` and ``theta``, by name."""

    @property
    def design(self) -> dict:
        """{variable name: optimal value (SI)}."""
        return dict(zip(self.var_names, map(float, self.theta)))


@dataclass
class DesignResult(NamedDesign):
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
    var_names : tuple of str
        Names of the design values, in the order of ``theta``.
    p : ndarray
        Full parameter vector (the problem's ``param_names``) of the optimum.
    objective_kind : str
        ``"peak_deceleration"`` or the problem's other objective.
    record : dict
        What the problem says of the start and the optimum for the JSON file:
        bounds, named ``p``, characteristics, limits and, when the geometry is
        designed or limited, the geometry and its practical-limit rows.
    meta : dict
        The study's name and the start's scale and design.
    """

    theta: np.ndarray
    theta0: np.ndarray
    evaluation: Evaluation
    initial: Evaluation
    return_status: str
    success: bool
    iterations: int
    history: list
    timings: dict
    var_names: tuple
    p: np.ndarray
    objective_kind: str
    record: dict = field(default_factory=dict)
    meta: dict = field(default_factory=dict)

    @property
    def message(self) -> str:
        """One paragraph: status, objective and any violated constraints."""
        ev = self.evaluation
        unit = "m/s²" if self.objective_kind == "peak_deceleration" else "m"
        text = (f"Ipopt {self.return_status} after {self.iterations} iterations: "
                f"{self.objective_kind} {ev.objective:.6g} {unit} "
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
        rec = self.record
        return jsonable(dict(
            study=self.meta.get("name"),
            objective_kind=self.objective_kind,
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
            initial_design=dict(zip(self.var_names, map(float, self.theta0))),
            bounds=rec["bounds"], p=rec["p"],
            characteristic=rec["characteristic"],
            initial_characteristic=rec["initial_characteristic"],
            scenarios=self.evaluation.scenarios,
            initial_scenarios=self.initial.scenarios,
            limits=rec["limits"],
            timings=self.timings,
            history=self.history,
            **{k: rec[k] for k in ("geometry", "practical") if k in rec},
            **{k: v for k, v in self.meta.items() if k != "name"}))

    def save_json(self, path):
        """Write :meth:`to_dict` as JSON (NaN and inf written as null)."""
        path = Path(path)
        if path.parent and not path.parent.exists():
            path.parent.mkdir(parents=True)
        atomic_write_text(path, json.dumps(self.to_dict(), indent=2, ensure_ascii=False) + "\n")
        return path
