"""Design for the envelope: the legs' characteristics for touchdown stability over sampled conditions.

A study samples touchdowns from an envelope study's distribution, selects
scenarios near and beyond the stable region's boundary, optimises the legs'
tunable curves for a risk measure of the scenarios' smooth margins with exact
gradients (compiled C, threads or Dask), and checks the optimum by a fresh
Monte Carlo envelope (docs/optimise.md, "Design for the envelope").

Modules: :mod:`.margins` (the smooth value/limit of each check over a
horizon), :mod:`.evaluate` (compiled scenarios and their Jacobian),
:mod:`.problem` (the NLP and its solve), :mod:`.risk` (the loss and
its risk measures), :mod:`.result` (the outcome), :mod:`.select` (choosing
scenarios), :mod:`.study` (the study file and the sample–select–optimise–
verify loop), :mod:`.plots` (before/after figures).
"""
from symcushion.design.robust.margins import CHECKS, DEFAULT_SHARPNESS, margins_function
from symcushion.design.robust.evaluate import build_margins, ScenarioRatios
from symcushion.design.robust.problem import EnvelopeDesign
from symcushion.design.robust.result import RobustResult
from symcushion.design.robust.risk import (RISKS, DEFAULT_ALPHA, DEFAULT_SATURATION,
    DEFAULT_HORIZON, saturate)

__all__ = ["CHECKS", "DEFAULT_SHARPNESS", "margins_function", "build_margins",
           "ScenarioRatios", "RISKS", "DEFAULT_ALPHA", "DEFAULT_SATURATION", "DEFAULT_HORIZON",
           "saturate", "EnvelopeDesign", "RobustResult"]
