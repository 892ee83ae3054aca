"""Touchdown stability envelope: Monte Carlo over touchdown conditions.

A subpackage split by concept; this module only re-exports:

* :mod:`.study` — the study file (schema, ranges, limits);
* :mod:`.sampling` — the seeded Sobol (or random) sample of conditions;
* :mod:`.cases` — the slope frame, the case parameters and ``envelope_case``;
* :mod:`.build` — compiling the case Function and running batches;
* :mod:`.classify` — classes and margins of each case;
* :mod:`.statistics` — P(stable) intervals and the result object;
* :mod:`.runner` — running a study on threads or Dask, writing results;
* :mod:`.plots` — the figures.

Every case is the scene's ``touchdown_step`` with its conditions in the
step's inputs (gravity and μ in ``p``), so one compiled Function serves a
whole study; no physics is derived here (docs/envelope.md).
"""
from symcushion.envelope.study import (sample_conditions, VARIABLES, MAX_SLOPE_DEG, DEFAULT_BATCH,
    DEFAULT_CLEARANCE, DEFAULT_REST_SPEED, Range, Limits, EnvelopeStudy, study_from_dict,
    load_study)
from symcushion.envelope.sampling import SOBOL_BITS, sobol, sample_unit
from symcushion.envelope.cases import (SUMMARY, DECEL_FILTER_TIME, NO_STOP, initial_states,
    envelope_function, case_params, reach, apply_design, stop_vector, study_stop)
from symcushion.envelope.build import DEFAULT_CACHE, build_envelope, run_batch
from symcushion.envelope.classify import CLASSES, classify
from symcushion.envelope.statistics import CONFIDENCE, wilson_interval, EnvelopeResult
from symcushion.envelope.runner import (PROGRESS_INTERVAL, PROGRESS_LOG_INTERVAL, run_envelope,
    evaluate, write_result)
from symcushion.envelope.plots import LOGISTIC_RIDGE, plot_envelope
from symcushion.envelope.runner import case_libraries  # noqa: F401  (tests check one library serves every μ)
from symcushion.layout.vectors import BODY_STATE, LEG_STATE  # noqa: F401  (kept importable from here)

__all__ = ["VARIABLES", "MAX_SLOPE_DEG", "DEFAULT_BATCH", "DEFAULT_CLEARANCE", "DEFAULT_REST_SPEED",
           "Range", "Limits",
           "EnvelopeStudy", "study_from_dict", "load_study", "SOBOL_BITS", "sobol", "sample_unit",
           "sample_conditions", "SUMMARY", "DECEL_FILTER_TIME", "initial_states",
           "envelope_function", "case_params", "reach", "apply_design", "NO_STOP",
           "stop_vector", "study_stop", "DEFAULT_CACHE",
           "build_envelope", "run_batch",
           "CLASSES", "classify", "CONFIDENCE", "wilson_interval", "EnvelopeResult",
           "PROGRESS_INTERVAL", "PROGRESS_LOG_INTERVAL", "run_envelope", "evaluate", "write_result", "LOGISTIC_RIDGE",
           "plot_envelope"]
