"""Design optimisation of landing legs through the differentiable touchdown.

A *design problem* is a set of touchdown scenarios (a scene and its initial
conditions) sharing one set of legs, a selection of the legs' tunable
parameters as design variables (``model.param_names`` entries, with bounds),
shape constraints on the tuned curves, an objective and limits:

    minimise    t                                    (epigraph of the peak)
    subject to  a_k^(s) ≤ t                    every step k, scenario s
                |δ_S,jk^(s)| ≤ s_max,  |β_jk| ≤ β_max,  |γ_jk − γ₀| ≤ γ_max
                1 − cos(tilt_k^(s)) ≤ 1 − cos(tilt_max)
                −v_sink ≤ v_up^(s)(T) ≤ v_rebound
                f_L′ ≥ 0 (monotone), f_L′ ≥ k_onset near x = 0,
                sign(x)(f_L(x) − f_U(x)) ≥ 0 (unloading below loading)
                lower ≤ θ ≤ upper

with a_k = (ÿ_k − g)·e_up the vertical *specific force* of the body (leg
forces over mass, gravity excluded: what an accelerometer on the body reads).
The peak is never written as a non-smooth max: t is a variable and every
step contributes a smooth constraint. The rollout is ``touchdown_rollout``
(one MX Function per scenario), so Ipopt gets exact first derivatives by AD
through the whole simulation; the Hessian is approximated by L-BFGS
(:data:`IPOPT_DEFAULTS`). ``docs/optimise.md`` explains how the problem is kept
solvable despite contact onset and branch switching.

A subpackage split by concept; this module only re-exports:
:mod:`.spec` (scenarios, variables, shapes, limits), :mod:`.constraints`
(objective and constraint rows), :mod:`.gradient` (AD against central
differences), :mod:`.problem` (variables, scaling, evaluation, Ipopt) with
:mod:`.progress` (its per-iteration callback),
:mod:`.result` and :mod:`.study` (TOML files). Nothing here integrates: the
rollout is ``touchdown_rollout`` of :mod:`symcushion.scheme.touchdown`.

References
----------
V. F. Khvostov (1976), Izv. AN SSSR MTT, §2 (the leg force law (2.1) whose
curves are tuned here) and §3 (the touchdown simulation differentiated here).
"""
from symcushion.design.optimise.spec import (OBJECTIVES, VIOLATION_TOL, Scenario, DesignVariable,
    CurveShape, Limits, Evaluation)
from symcushion.design.optimise.space import ONSET_SLOPE_FRACTION
from symcushion.design.optimise.shape_points import SHAPE_GRID
from symcushion.design.optimise.gradient import FD_STEP, ROW_FLOOR, FD_AGREEMENT
from symcushion.design.optimise.problem import (IPOPT_DEFAULTS, FEASIBLE_SCALE_MAX,
    FEASIBLE_BISECTIONS, FEASIBLE_MARGIN, DesignProblem)
from symcushion.design.optimise.result import DesignResult
from symcushion.design.optimise.study import Study, load_study, study_from_dict, run_study

__all__ = ["OBJECTIVES", "VIOLATION_TOL", "Scenario", "DesignVariable", "CurveShape", "Limits",
           "Evaluation", "ONSET_SLOPE_FRACTION", "SHAPE_GRID", "FD_STEP", "ROW_FLOOR",
           "FD_AGREEMENT", "IPOPT_DEFAULTS", "FEASIBLE_SCALE_MAX", "FEASIBLE_BISECTIONS",
           "FEASIBLE_MARGIN", "DesignProblem", "DesignResult", "Study", "load_study",
           "study_from_dict", "run_study"]
