"""symcushion: differentiable simulation and design of shock-absorbing landing legs.

Implements and extends V. F. Khvostov (1976), "On the dynamic interaction of
shock-absorbing supports with a rigid obstacle" (Izv. AN SSSR, MTT).
This module only re-exports the public API.
"""
from .characteristics import Crushable, Curve, Linear, PiecewiseLinear
from .strut import HingedStrut

__all__ = ["Crushable", "Curve", "Linear", "PiecewiseLinear", "HingedStrut"]
__version__ = "0.1.0"
