"""Compatibility module: ``symcushion.simulate`` as it was before the split.

The step lives in :mod:`symcushion.touchdown`, the driver in
:mod:`symcushion.driver` and the vector layout in :mod:`symcushion.layout`;
this module only re-exports them so that ``from symcushion.simulate import
build_model, simulate, BODY_STATE, ...`` keeps working. The package
attribute ``symcushion.simulate`` is the function :func:`simulate`, or this
module once it has been imported; the module is callable as the function, so
``symcushion.simulate(scene)`` works in both cases.
"""
import sys
import types

from .driver import Trajectory, save, simulate, trajectory_from
from .layout import BODY_OUT, BODY_STATE, LEG_OUT, LEG_STATE, MODES
from .quaternion import quat_exp, quat_mul, quat_to_rot
from .stability import STABILITY_SAFETY, stable_dt
from .stability import _body_stiffness  # noqa: F401
from .touchdown import (MAX_HALVINGS, STEP_CRITERION_EPS, StepModel, build_model,
                        equilibrium_state, initial_state)
from .touchdown import _default_p, _leg_params, _rot_np  # noqa: F401

__all__ = ["StepModel", "Trajectory", "build_model", "simulate", "initial_state",
           "equilibrium_state", "stable_dt", "trajectory_from", "save", "MODES",
           "STEP_CRITERION_EPS", "STABILITY_SAFETY", "MAX_HALVINGS", "BODY_STATE", "LEG_STATE",
           "BODY_OUT", "LEG_OUT", "quat_to_rot", "quat_mul", "quat_exp"]


class _CallableModule(types.ModuleType):
    """This module, callable as :func:`simulate`.

    Importing the submodule ``symcushion.simulate`` (as ``from
    symcushion.simulate import build_model`` does) makes Python bind the
    package attribute ``symcushion.simulate`` to this module, replacing the
    function that ``symcushion/__init__.py`` exported under that name; a
    callable module keeps ``symcushion.simulate(scene)`` working either way.
    """

    def __call__(self, *args, **kwargs):
        return simulate(*args, **kwargs)


sys.modules[__name__].__class__ = _CallableModule
