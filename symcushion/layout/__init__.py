"""The named vectors of a step: the parameter vector p, the state x and the
output y, field by field, with their units and CSV columns.

This folder owns every slicing of those vectors (:mod:`.fields` the machinery,
:mod:`.params` the fields of p, :mod:`.vectors` those of x and y); no other
module decodes a vector by position. It must not know physics. This module
re-exports :mod:`.vectors`, so ``from symcushion.layout import state_layout``
reads as the one place the layouts come from.
"""
from symcushion.layout.vectors import *  # noqa: F401,F403
from symcushion.layout.vectors import __all__  # noqa: F401
