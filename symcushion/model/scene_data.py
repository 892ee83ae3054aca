"""Touchdown scenes as data: the body, the scene, the symmetric leg sets.

A :class:`Scene` is plain data: it says *what* is simulated — a rigid body
(:class:`Body`) on N legs, obstacles, gravity, friction, method and step.
How it is integrated lives in ``symcushion.simulate``.

Frames: the body frame has its origin at the centre of mass; legs are given in
body coordinates. The attitude is a unit quaternion (w, x, y, z) mapping body
to world coordinates.

This module owns the dataclasses, the names of the step's options
(``TANGENT_PLANES``, ``SLIP_RULES``, ``EVENT_RULES``, ``HYSTERESIS_LAWS``,
``SCHEMES``) and :func:`symmetric_legs` / :func:`symmetric_tripods`. It must
not read files or dictionaries (``symcushion.model.scene``, where users import
scenes from, loads TOML and re-exports this module's public names).
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from symcushion.contact.args import METHODS
from symcushion.legs.curve_base import Curve
from symcushion.model.obstacles import Obstacle
from symcushion.legs.strut import HingedStrut
from symcushion.legs.tripod import InvertedTripod
from symcushion.validation import choice, direction, integer, real, show, vector

__all__ = ["Body", "Scene", "symmetric_legs", "symmetric_tripods", "TANGENT_PLANES",
           "SLIP_RULES", "EVENT_RULES", "HYSTERESIS_LAWS", "SCHEMES", "LEG_SCHEMES"]


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

#: Leg schemes: ``"strut"``, the strut on a spherical hinge of (2.1)
#: (``symcushion.legs.strut``); ``"tripod"``, the inverted tripod of flown landers
#: (``symcushion.legs.tripod``, docs/tripod.md).
SCHEMES = ("strut", "tripod")
LEG_SCHEMES = (HingedStrut, InvertedTripod)


def _vec(name, value, size=3):
    return vector(name, value, (size,))


def _positive(name, value, unit=""):
    return real(name, value, positive=True, unit=unit)


@dataclass
class Body:
    """The rigid body and its initial state.

    Attributes
    ----------
    mass : float
        kg, > 0.
    inertia : ndarray, shape (3, 3)
        Inertia tensor about the centre of mass, body axes (kg·m²); a 3-vector
        is taken as the diagonal.
    position : ndarray, shape (3,)
        Initial centre of mass, world (m).
    attitude : ndarray, shape (4,)
        Initial unit quaternion (w, x, y, z), body → world.
    velocity : ndarray, shape (3,)
        Initial velocity, world (m/s).
    angular_velocity : ndarray, shape (3,)
        Initial angular velocity in body axes (rad/s).
    """

    mass: float
    inertia: np.ndarray
    position: np.ndarray = field(default_factory=lambda: np.zeros(3))
    attitude: np.ndarray = field(default_factory=lambda: np.array([1.0, 0, 0, 0]))
    velocity: np.ndarray = field(default_factory=lambda: np.zeros(3))
    angular_velocity: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def __post_init__(self):
        self.mass = _positive("body.mass", self.mass, "kg")
        try:
            inertia = vector("body.inertia", self.inertia, (3,))
            inertia = np.diag(inertia)
        except (TypeError, ValueError):
            try:
                inertia = vector("body.inertia", self.inertia, (3, 3))
            except (TypeError, ValueError):
                raise ValueError(f"`body.inertia` must be 3 numbers (the diagonal) or a 3×3 "
                                 f"matrix in kg·m², got {show(self.inertia)}.") from None
        if not np.allclose(inertia, inertia.T) or np.any(np.linalg.eigvalsh(inertia) <= 0):
            raise ValueError(f"`body.inertia` must be symmetric positive definite, got "
                             f"{inertia.tolist()}; give the principal moments (kg·m²).")
        self.inertia = inertia
        self.position = _vec("body.position", self.position)
        self.attitude = direction("body.attitude", self.attitude, 4)
        self.velocity = _vec("body.velocity", self.velocity)
        self.angular_velocity = _vec("body.angular_velocity", self.angular_velocity)


@dataclass
class Scene:
    """A touchdown: body, legs, obstacles, gravity, friction and time grid.

    Attributes
    ----------
    body : Body
    legs : list of HingedStrut
        Legs in body coordinates.
    obstacles : list of Obstacle
    mu : float
        Coulomb coefficient between every foot and every obstacle, ≥ 0. With
        μ = 0 the simulator builds no friction code.
    method : {'paper', 'robust', 'implicit'}
        Contact step (``symcushion.contact``).
    dt : float
        Time step (s).
    duration : float
        Simulated time (s).
    gravity : ndarray, shape (3,)
        m/s², world.
    name : str
    tangent_plane : {'end', 'start'}
        Where the obstacle is replaced by its tangent plane (:data:`TANGENT_PLANES`).
    slip : {'backward', 'midpoint'}
        The slip rule of the implicit contact step (:data:`SLIP_RULES`);
        ``'midpoint'`` needs ``method='implicit'``.
    events : {'none', 'branch', 'lock'}
        What the body step does at the absorbers' branch switches inside a
        step (:data:`EVENT_RULES`); ``'lock'`` needs ``mu > 0``.
    hysteresis : {'sign', 'memory'}
        The absorbers' law between their curves (:data:`HYSTERESIS_LAWS`);
        ``'memory'`` needs ``events = 'none'`` (its force does not jump).
    """

    body: Body
    legs: list
    obstacles: list
    mu: float = 0.0
    method: str = "implicit"
    dt: float = 1e-3
    duration: float = 1.0
    gravity: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, -9.81]))
    name: str = "scene"
    tangent_plane: str = "end"
    slip: str = "backward"
    events: str = "none"
    hysteresis: str = "sign"

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
        self.method = choice("method", self.method, METHODS)
        self.tangent_plane = choice("tangent_plane", self.tangent_plane, TANGENT_PLANES)
        self.slip = choice("slip", self.slip, SLIP_RULES)
        self.events = choice("events", self.events, EVENT_RULES)
        if self.events == "lock" and self.mu == 0:
            raise ValueError("`events` = 'lock' holds the stroke of a leg whose foot sticks, and "
                             "with mu = 0 no foot sticks. Set mu > 0 or events = 'branch'.")
        if self.slip != "backward" and self.method != "implicit":
            raise ValueError(f"`slip` = {self.slip!r} corrects the implicit contact step's slip; "
                             f"`method` is {self.method!r}. Set method = 'implicit' or "
                             "slip = 'backward'.")
        self.hysteresis = choice("hysteresis", self.hysteresis, HYSTERESIS_LAWS)
        self._check_dampers()
        self._check_tripods()
        if self.hysteresis == "memory":
            self._check_memory()
        self.dt = _positive("dt", self.dt, "s")
        self.duration = _positive("duration", self.duration, "s")
        self.gravity = _vec("gravity", self.gravity)
        if not isinstance(self.name, str):
            raise TypeError(f"`name` must be a string, got {show(self.name)}.")

    def _check_dampers(self):
        """Dampers act under the memory law, on any element."""
        for j, leg in enumerate(self.legs):
            for el in leg.elements:
                if el.curve.has_damper and self.hysteresis != "memory":
                    raise ValueError(f"leg {j}: `{el.name}` has a damper, which the printed "
                                     "law P(δ, sign δ′) does not have; set hysteresis = "
                                     "'memory'.")

    def _check_tripods(self):
        """An inverted tripod takes no event rule: those locate a strut's switches."""
        tripods = [j for j, leg in enumerate(self.legs) if isinstance(leg, InvertedTripod)]
        if tripods and self.events != "none":
            raise ValueError(f"legs {tripods} are inverted tripods; `events` = "
                             f"{self.events!r} locates the switches of a strut's axial element "
                             "only. Set events = 'none'.")

    def _check_memory(self):
        """The memory law's conditions: no event rule, no hinge spring with memory."""
        if self.events != "none":
            raise ValueError(f"`events` = {self.events!r} locates the jumps of the printed law; "
                             "`hysteresis` = 'memory' has a continuous force and needs none. "
                             "Set events = 'none' (or hysteresis = 'sign').")
        for j, leg in enumerate(self.legs):
            for el in leg.elements:
                if el.name != "S" and el.curve.unloading is not None:
                    raise ValueError(
                        f"leg {j}: `{el.name}` has an unloading curve; `hysteresis` = 'memory' "
                        "keeps a set for the axial absorber only. Remove the hinge spring's "
                        "unloading curve or set hysteresis = 'sign'.")

    @property
    def steps(self) -> int:
        """Number of steps, round(duration/dt)."""
        return max(1, int(round(self.duration / self.dt)))

    def with_(self, **changes) -> "Scene":
        """A copy with some fields replaced (``scene.with_(method='paper')``). A new
        ``method`` other than ``'implicit'`` takes the backward slip rule unless ``slip``
        is given too: the slip rule belongs to the implicit step."""
        if changes.get("method", "implicit") != "implicit" and "slip" not in changes:
            changes["slip"] = "backward"
        return replace(self, **changes)


def symmetric_legs(count: int, radius: float, height: float, length: float, e0_local,
                   en_local, S: Curve | None = None, M_beta: Curve | None = None,
                   M_gamma: Curve | None = None, azimuth0: float = 0.0,
                   axial_ratio: float | None = None, law: str = "paper",
                   footpad: float = 0.0) -> list:
    """``count`` identical legs spaced evenly about the body's z axis.

    Leg i has its hinge at azimuth φ_i = azimuth0 + 2πi/count, at ``radius``
    from the axis and ``height`` along z. Its rest direction and polar axis
    are given in the leg's local frame (radial, tangential, z), e.g.
    ``e0_local=(0, 0, -1)`` for a rod hanging straight down. ``law``: the
    force law of every leg (``HingedStrut``'s, ``"paper"`` or ``"potential"``);
    ``footpad``: every leg's footpad radius (m, 0 for point feet).

    Returns
    -------
    list of HingedStrut
    """
    count = integer("count", count, minimum=1)
    e0_local = _vec("e0_local", e0_local)
    en_local = _vec("en_local", en_local)
    legs = []
    for i in range(count):
        phi = azimuth0 + 2 * np.pi * i / count
        radial = np.array([np.cos(phi), np.sin(phi), 0.0])
        tangential = np.array([-np.sin(phi), np.cos(phi), 0.0])
        up = np.array([0.0, 0.0, 1.0])
        frame = np.column_stack([radial, tangential, up])
        kwargs = {} if axial_ratio is None else {"axial_ratio": axial_ratio}
        legs.append(HingedStrut(hinge=radius * radial + height * up, e0=frame @ e0_local,
                                en=frame @ en_local, length=length, S=S, M_beta=M_beta,
                                M_gamma=M_gamma, law=law, footpad=footpad, **kwargs))
    return legs


def symmetric_tripods(count: int, h1, h2, h3, foot, outer_length: float, primary: Curve,
                      secondary2: Curve, secondary3: Curve, azimuth0: float = 0.0,
                      footpad: float = 0.0) -> list:
    """``count`` identical inverted-tripod legs evenly spaced about the body's z axis.

    Leg 0's hardpoints ``h1``, ``h2``, ``h3`` and rest ``foot`` are given in
    body axes at azimuth 0 (its plane of symmetry is usually x–z); leg i is
    leg 0 turned about z by φ_i = azimuth0 + 2πi/count; ``footpad``: every leg's
    footpad radius (m, 0 for point feet).

    Returns
    -------
    list of InvertedTripod
    """
    count = integer("count", count, minimum=1)
    points = [np.asarray(v, dtype=float) for v in (h1, h2, h3, foot)]
    legs = []
    for i in range(count):
        phi = azimuth0 + 2 * np.pi * i / count
        c, s = np.cos(phi), np.sin(phi)
        turn = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        legs.append(InvertedTripod(*(turn @ v for v in points), outer_length=outer_length,
                                   primary=primary, secondary2=secondary2,
                                   secondary3=secondary3, footpad=footpad))
    return legs
