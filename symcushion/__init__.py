"""symcushion: differentiable simulation and design of shock-absorbing landing legs.

Implements and extends V. F. Khvostov (1976), "On the dynamic interaction of
shock-absorbing supports with a rigid obstacle" (Izv. AN SSSR, MTT).
This module only re-exports the public API (docs/architecture.md maps the
modules behind it). ``symcushion.simulate`` is the function
:func:`~symcushion.driver.simulate`; ``from symcushion.simulate import ...``
still reads the compatibility module of the same name.
"""
from . import envelope, optimise
from .characteristics import Crushable, Linear, PiecewiseLinear, TwoSided
from .curve_base import Curve
from .contact import solve_contact
from .contact_args import METHODS
from .contact_dispatch import contact_step
from .driver import Trajectory, save, simulate
from .layout import MODES, output_columns, state_columns
from .measures import measures_function
from .obstacles import ImplicitSurface, Plane, Sphere, Terrain
from .scene import load_scene, scene_from_dict
from .scene_data import Body, Scene, symmetric_legs
from .strut import HingedStrut
from .tripod import InvertedTripod
from .stability import stable_dt
from .touchdown import StepModel, build_model, equilibrium_state, initial_state

__all__ = ["Crushable", "Curve", "Linear", "PiecewiseLinear", "TwoSided", "HingedStrut",
           "InvertedTripod",
           "METHODS", "contact_step", "solve_contact",
           "Plane", "Sphere", "ImplicitSurface", "Terrain",
           "Body", "Scene", "load_scene", "scene_from_dict", "symmetric_legs",
           "StepModel", "build_model", "initial_state", "equilibrium_state", "stable_dt",
           "Trajectory", "simulate", "save", "MODES", "state_columns", "output_columns",
           "measures_function", "envelope", "optimise"]
__version__ = "0.1.0"
