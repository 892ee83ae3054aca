"""symcushion: differentiable simulation and design of shock-absorbing landing legs.

Implements and extends V. F. Khvostov (1976), "On the dynamic interaction of
shock-absorbing supports with a rigid obstacle" (Izv. AN SSSR, MTT).
This module only re-exports the public API (docs/architecture.md maps the
modules behind it). ``symcushion.simulate`` is the function
:func:`~symcushion.run.driver.simulate`.
"""
from symcushion import envelope
from symcushion.design import optimise
from symcushion.legs.characteristics import Crushable, Linear, PiecewiseLinear, TwoSided
from symcushion.legs.curve_base import Curve
from symcushion.contact.solve import solve_contact
from symcushion.contact.args import METHODS
from symcushion.contact.dispatch import contact_step
from symcushion.run.driver import Trajectory, save, simulate
from symcushion.layout.vectors import MODES, output_columns, state_columns
from symcushion.scheme.measures import measures_function
from symcushion.model.obstacles import ImplicitSurface, Plane, Sphere, Terrain
from symcushion.model.scene import load_scene, scene_from_dict
from symcushion.model.parts import Model, Scheme, TimeGrid
from symcushion.model.scene_data import Body, Scene, symmetric_legs
from symcushion.legs.strut import HingedStrut
from symcushion.legs.tripod import InvertedTripod
from symcushion.scheme.stability import stable_dt
from symcushion.scheme.touchdown import StepModel, build_model, equilibrium_state, initial_state

__all__ = ["Crushable", "Curve", "Linear", "PiecewiseLinear", "TwoSided", "HingedStrut",
           "InvertedTripod",
           "METHODS", "contact_step", "solve_contact",
           "Plane", "Sphere", "ImplicitSurface", "Terrain",
           "Body", "Scene", "Model", "Scheme", "TimeGrid", "load_scene", "scene_from_dict", "symmetric_legs",
           "StepModel", "build_model", "initial_state", "equilibrium_state", "stable_dt",
           "Trajectory", "simulate", "save", "MODES", "state_columns", "output_columns",
           "measures_function", "envelope", "optimise"]
__version__ = "0.1.0"
