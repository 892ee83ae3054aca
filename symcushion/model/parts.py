"""The three parts a scene groups: what is simulated, how it is stepped, when.

* :class:`Model` — *what*: the body, its legs, the obstacles, μ and gravity. No
  time step and no numerical choice.
* :class:`Scheme` — *how*: the contact step of §1 (``method``), the slip rule,
  where the tangent plane is taken, the event rule and the absorbers' law between
  their curves. Each choice is checked here, once; the conditions a choice puts on
  the model (a stroke lock needs friction, dampers need the memory law, ...) are
  :func:`check_scheme`. ``symcushion.scheme.registry`` maps each choice to the
  parts of the step that implement it.
* :class:`TimeGrid` — *when*: Δt and the duration, which the driver takes; the step
  Function itself has Δt as an input and never depends on the grid.

:class:`~symcushion.model.scene_data.Scene` is the user-facing grouping of the three
(a scene file's tables); ``scene.model``, ``scene.scheme`` and ``scene.grid`` give
them back. This module owns the three dataclasses, the names of the scheme's
choices and their checks. It must not build Functions, read files or run anything.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from symcushion.contact.args import METHODS
from symcushion.legs.strut import HingedStrut
from symcushion.legs.tripod import InvertedTripod
from symcushion.model.body import Body
from symcushion.model.obstacles import Obstacle
from symcushion.validation import choice, real, show, vector

__all__ = ["Model", "Scheme", "TimeGrid", "check_scheme", "SCHEME_OPTIONS", "METHODS",
           "TANGENT_PLANES", "SLIP_RULES", "EVENT_RULES", "HYSTERESIS_LAWS", "LEG_SCHEMES"]

#: Where a step replaces the obstacle by its tangent plane (§3): ``"start"``,
#: at the foot's contact point at the start of the step (the literal reading,
#: first order on curved obstacles: the force lags the normal by half a step);
#: ``"end"``, a second contact step on the plane tangent at the end point the
#: first predicted (second order, twice the contact cost).
TANGENT_PLANES = ("start", "end")

#: How the implicit contact step turns a sliding foot's slip direction over a
#: step (``symcushion.contact.midpoint``): ``"backward"``, along the force of
#: the end of the step (backward Euler: first order when the direction turns);
#: ``"midpoint"``, along the fitted mean of the start and end forces (second
#: order, a Newton correction after the backward-Euler step).
SLIP_RULES = ("backward", "midpoint")

#: What the touchdown step does at the events inside a step
#: (``symcushion.scheme.branch_switch``): ``"none"``, the velocity-Verlet kick;
#: ``"branch"``, the kick weighted at the located switch of each leg's axial
#: loading/unloading branch (second order through the force jump);
#: ``"lock"``, that and the stroke lock of ``symcushion.scheme.stroke_lock``: a leg
#: whose foot sticks holds its stroke between the curves (SHAKE/RATTLE).
EVENT_RULES = ("none", "branch", "lock")

#: The absorbers' law between their loading and unloading curves:
#: ``"sign"``, the printed P = P(δ, sign δ′) of (2.1) (the force jumps between
#: the curves when the rate changes sign); ``"memory"``, the elastic band of
#: ``symcushion.legs.absorber`` (a set per absorber in the state, a continuous force,
#: crushing only at the loading curve's force; docs/absorbers.md).
HYSTERESIS_LAWS = ("sign", "memory")

#: Every option of a scheme and its choices, in the order :class:`Scheme` takes them.
SCHEME_OPTIONS = {"method": METHODS, "tangent_plane": TANGENT_PLANES, "slip": SLIP_RULES,
                  "events": EVENT_RULES, "hysteresis": HYSTERESIS_LAWS}

LEG_SCHEMES = (HingedStrut, InvertedTripod)


@dataclass
class Model:
    """What is simulated: a rigid body on legs against obstacles.

    Attributes
    ----------
    body : Body
    legs : list of HingedStrut or InvertedTripod
        Legs in body coordinates.
    obstacles : list of Obstacle
    mu : float
        Coulomb coefficient between every foot and every obstacle, ≥ 0. With
        μ = 0 the simulator builds no friction code.
    gravity : ndarray, shape (3,)
        m/s², world.
    name : str
    """

    body: Body
    legs: list
    obstacles: list
    mu: float = 0.0
    gravity: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, -9.81]))
    name: str = "scene"

    def __post_init__(self):
        if not isinstance(self.body, Body):
            raise TypeError(f"`body` must be a Body, got {type(self.body).__name__}.")
        self.legs = list(self.legs)
        if not self.legs or not all(isinstance(leg, LEG_SCHEMES) for leg in self.legs):
            raise ValueError("`legs` must be a non-empty list of legs (HingedStrut or "
                             "InvertedTripod).")
        self.obstacles = list(self.obstacles)
        if not self.obstacles or not all(isinstance(o, Obstacle) for o in self.obstacles):
            raise ValueError("`obstacles` must be a non-empty list of Obstacle.")
        self.mu = real("mu", self.mu, nonnegative=True)
        self.gravity = vector("gravity", self.gravity, (3,))
        if not isinstance(self.name, str):
            raise TypeError(f"`name` must be a string, got {show(self.name)}.")


@dataclass(frozen=True)
class Scheme:
    """How a touchdown is stepped: one choice per option of :data:`SCHEME_OPTIONS`.

    The defaults are the printed method's reading with the exact Coulomb step; a
    scene file's defaults are the second-order scheme of docs/scenes.md. A choice
    that needs another (the midpoint slip rule needs the implicit step) is refused
    here; one that needs something of the model, by :func:`check_scheme`.
    """

    method: str = "implicit"
    tangent_plane: str = "end"
    slip: str = "backward"
    events: str = "none"
    hysteresis: str = "sign"

    def __post_init__(self):
        for name, choices in SCHEME_OPTIONS.items():
            object.__setattr__(self, name, choice(name, getattr(self, name), choices))
        if self.slip != "backward" and self.method != "implicit":
            raise ValueError(f"`slip` = {self.slip!r} corrects the implicit contact step's slip; "
                             f"`method` is {self.method!r}. Set method = 'implicit' or "
                             "slip = 'backward'.")
        if self.hysteresis == "memory" and self.events != "none":
            raise ValueError(f"`events` = {self.events!r} locates the jumps of the printed law; "
                             "`hysteresis` = 'memory' has a continuous force and needs none. "
                             "Set events = 'none' (or hysteresis = 'sign').")


@dataclass(frozen=True)
class TimeGrid:
    """When: the fixed step Δt and the simulated time, both in s and > 0."""

    dt: float = 1e-3
    duration: float = 1.0

    def __post_init__(self):
        object.__setattr__(self, "dt", real("dt", self.dt, positive=True, unit="s"))
        object.__setattr__(self, "duration",
                           real("duration", self.duration, positive=True, unit="s"))

    @property
    def steps(self) -> int:
        """Number of steps, round(duration/dt)."""
        return max(1, int(round(self.duration / self.dt)))


def check_scheme(model: Model, scheme: Scheme) -> None:
    """Refuse a scheme that the model cannot take, with the reason and the fix."""
    if scheme.events == "lock" and model.mu == 0:
        raise ValueError("`events` = 'lock' holds the stroke of a leg whose foot sticks, and "
                         "with mu = 0 no foot sticks. Set mu > 0 or events = 'branch'.")
    for j, leg in enumerate(model.legs):
        for el in leg.elements:
            if el.curve.has_damper and scheme.hysteresis != "memory":
                raise ValueError(f"leg {j}: `{el.name}` has a damper, which the printed "
                                 "law P(δ, sign δ′) does not have; set hysteresis = "
                                 "'memory'.")
    tripods = [j for j, leg in enumerate(model.legs) if isinstance(leg, InvertedTripod)]
    if tripods and scheme.events != "none":
        raise ValueError(f"legs {tripods} are inverted tripods; `events` = "
                         f"{scheme.events!r} locates the switches of a strut's axial element "
                         "only. Set events = 'none'.")
    if scheme.hysteresis == "memory":
        for j, leg in enumerate(model.legs):
            for el in leg.elements:
                if el.name != "S" and el.curve.unloading is not None:
                    raise ValueError(
                        f"leg {j}: `{el.name}` has an unloading curve; `hysteresis` = 'memory' "
                        "keeps a set for the axial absorber only. Remove the hinge spring's "
                        "unloading curve or set hysteresis = 'sign'.")
