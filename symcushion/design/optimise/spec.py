"""What a design problem is made of: scenarios, variables, shapes, limits.

Owns the user-facing specification types (:class:`Scenario`,
:class:`DesignVariable`, :class:`CurveShape`, :class:`Limits`), the
objectives, the result of evaluating one design (:class:`Evaluation`) and the
named blocks of constraint rows. It must not build or solve the NLP.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from symcushion.model.scene_data import Scene

__all__ = ["OBJECTIVES", "VIOLATION_TOL", "Scenario", "DesignVariable", "CurveShape", "Limits",
           "Evaluation"]

#: Objectives: the largest vertical specific force over all scenarios and steps
#: (m/s²), or the largest axial stroke |δ_S| over all legs (m).
OBJECTIVES = ("peak_deceleration", "peak_stroke")
#: A constraint counts as violated beyond this, relative to its limit
#: (Ipopt's own constr_viol_tol is 1e-4 absolute on the scaled rows).
VIOLATION_TOL = 1e-6


@dataclass
class Scenario:
    """One touchdown: a scene (legs, obstacles, time grid) and its initial state.

    Attributes
    ----------
    name : str
    scene : Scene
        Scenarios of one problem share the scene's legs (same ``param_names``).
    x0 : ndarray, shape (nx,), optional
        Initial state; default :func:`symcushion.scheme.touchdown_states.initial_state`.
    clearance : float, optional
        Height of the lowest foot above the obstacle at which ``x0`` was
        placed (m). With geometry variables the body is placed again at this
        clearance for every design (docs/design-geometry.md); None keeps
        the body where ``x0`` has it and only moves the feet to their rest poses.
    """

    name: str
    scene: Scene
    x0: np.ndarray | None = None
    clearance: float | None = None


@dataclass
class DesignVariable:
    """Design variables: the tunable parameters whose names match a pattern.

    Attributes
    ----------
    names : str or sequence of str
        ``fnmatch`` patterns. A pattern without the ``leg{j}.`` prefix (e.g.
        ``"S.f*"``) matches that parameter on every leg; with it
        (``"leg0.S.f3"``), on that leg only.
    lower, upper : float
        Bounds (SI units of the parameter).
    shared : bool
        True: one variable per parameter name, shared by all legs matched
        (a symmetric design). False: one variable per leg.
    exclude : sequence of str
        Patterns removed from the match (e.g. ``"S.f15"`` to keep f(0) = 0).
    scale : float, optional
        Typical magnitude; default the largest |initial value| of the match.
    """

    names: str | Sequence[str]
    lower: float = -math.inf
    upper: float = math.inf
    shared: bool = True
    exclude: Sequence[str] = ()
    scale: float | None = None


@dataclass
class CurveShape:
    """Shape constraints of the curves of one leg element that are being tuned.

    Attributes
    ----------
    element : {'S', 'M_beta', 'M_gamma'}
    monotone : bool
        Loading branch non-decreasing: f_L′ ≥ 0 (restoring everywhere).
    unloading_below : bool
        sign(x)·(f_L(x) − f_U(x)) ≥ 0: unloading never resists more than
        loading, so a load cycle dissipates.
    onset_slope : float, optional
        Lower bound on f_L′ next to x = 0 (N/m or N·m/rad); default
        :data:`ONSET_SLOPE_FRACTION` times the initial slope there.
    """

    element: str
    monotone: bool = True
    unloading_below: bool = True
    onset_slope: float | None = None


@dataclass
class Limits:
    """Limits checked at every step of every scenario (None: not imposed).

    Attributes
    ----------
    stroke : float
        |δ_S| ≤ stroke (m), every leg with an axial element.
    beta, gamma : float
        |β| ≤ beta, |γ − γ₀| ≤ gamma (rad), every leg.
    tilt : float
        Angle of the body z axis from the vertical ≤ tilt (rad).
    rebound_speed : float
        Upward vertical speed at the end of each scenario ≤ rebound_speed (m/s).
    sink_speed : float
        Downward vertical speed at the end ≤ sink_speed (m/s). The default 0
        makes the descent be arrested within the simulated time, so that the
        stroke constraint sees the whole stroke.
    deceleration : float
        Peak vertical specific force ≤ deceleration (m/s²).
    """

    stroke: float | None = None
    beta: float | None = None
    gamma: float | None = None
    tilt: float | None = None
    rebound_speed: float | None = None
    sink_speed: float | None = 0.0
    deceleration: float | None = None

    def __post_init__(self):
        for name in ("stroke", "beta", "gamma", "tilt", "rebound_speed", "deceleration"):
            value = getattr(self, name)
            if value is not None:
                setattr(self, name, real_number(f"limits.{name}", value, positive=True))
        if self.sink_speed is not None:
            self.sink_speed = real_number("limits.sink_speed", self.sink_speed, nonnegative=True)
        if self.tilt is not None and self.tilt >= math.pi:
            raise ValueError(f"`limits.tilt` must be below π rad, got {self.tilt!r}; "
                             "give the largest allowed tilt in radians.")


def real_number(name, value, *, positive=False, nonnegative=False):
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
        raise TypeError(f"`{name}` must be a number, got {value!r}.")
    value = float(value)
    if math.isnan(value):
        raise ValueError(f"`{name}` must be a number, got NaN.")
    if positive and not value > 0:
        raise ValueError(f"`{name}` must be positive, got {value!r}; give a value > 0.")
    if nonnegative and not value >= 0:
        raise ValueError(f"`{name}` must be non-negative, got {value!r}; give a value >= 0.")
    return value


@dataclass
class Block:
    """A block of rows of the constraint vector, for reports."""

    kind: str            # 'epigraph', 'stroke', 'beta', 'gamma', 'tilt', 'final_speed', …
    scenario: str | None
    leg: int | None
    start: int
    stop: int
    lower: float
    upper: float
    scale: float         # physical value = scaled value × scale
    unit: str
    dt: float | None = None
    label: str = ""


@dataclass
class Evaluation:
    """Objective, per-scenario measures and constraint violations of one design.

    Attributes
    ----------
    objective : float
        Peak deceleration (m/s²) or peak stroke (m) over all scenarios.
    scenarios : dict
        Per scenario: peak_deceleration (m/s²), max_stroke (m), max_beta,
        max_gamma, max_tilt (rad), final_vertical_speed (m/s), and, for
        vertical legs with a stroke limit, ideal_peak_deceleration and
        efficiency (docs/optimise.md).
    violations : list of str
        One message per violated constraint (worst first), naming the
        constraint, the scenario, the leg and the time.
    max_violation : float
        Largest violation relative to its limit (0 when feasible).
    """

    objective: float
    scenarios: dict
    violations: list
    max_violation: float

    @property
    def feasible(self) -> bool:
        return not self.violations


def leg_param_names(model) -> tuple:
    """The legs' curve parameters of a model's ``p`` (without the scene entries)."""
    return model.param_names[:model.params.n_leg_params]


def up_direction(gravity):
    norm = float(np.linalg.norm(gravity))
    return -np.asarray(gravity, dtype=float) / norm if norm > 0 else np.array([0.0, 0.0, 1.0])
