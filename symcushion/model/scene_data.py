"""Touchdown scenes as data: the scene that groups a model, a scheme and a time
grid, and the symmetric leg sets.

A :class:`Scene` is plain data, the grouping a scene file has: *what* is
simulated (:class:`~symcushion.model.parts.Model`: a rigid :class:`Body` on N
legs, obstacles, gravity, friction), *how* it is stepped
(:class:`~symcushion.model.parts.Scheme`) and *when*
(:class:`~symcushion.model.parts.TimeGrid`). The step is built from the model
and the scheme (``symcushion.scheme.touchdown``); the driver takes the grid
(``symcushion.run.driver``).

This module owns :class:`Scene`, the names of the leg schemes (``SCHEMES``) and
:func:`symmetric_legs` / :func:`symmetric_tripods`; it re-exports the body and
the scheme's choices. It must not check a part itself (the parts do), read files
or dictionaries (``symcushion.model.scene``, where users import scenes from,
loads TOML and re-exports this module's public names).
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from symcushion.legs.curve_base import Curve
from symcushion.legs.strut import HingedStrut
from symcushion.legs.tripod import InvertedTripod
from symcushion.model.body import Body
from symcushion.model.parts import (EVENT_RULES, HYSTERESIS_LAWS, LEG_SCHEMES, METHODS,
    SCHEME_OPTIONS, SLIP_RULES, TANGENT_PLANES, Model, Scheme, TimeGrid, check_scheme)
from symcushion.validation import integer, vector

__all__ = ["Body", "Scene", "Model", "Scheme", "TimeGrid", "symmetric_legs",
           "symmetric_tripods", "TANGENT_PLANES", "SLIP_RULES", "EVENT_RULES",
           "HYSTERESIS_LAWS", "SCHEMES", "LEG_SCHEMES", "METHODS"]


#: Leg schemes: ``"strut"``, the strut on a spherical hinge of (2.1)
#: (``symcushion.legs.strut``); ``"tripod"``, the inverted tripod of flown landers
#: (``symcushion.legs.tripod``, docs/tripod.md).
SCHEMES = ("strut", "tripod")


def _vec(name, value, size=3):
    return vector(name, value, (size,))


@dataclass
class Scene:
    """A touchdown as a scene file groups it: the model (body, legs, obstacles, μ,
    gravity), the scheme that steps it and its time grid, in one record.

    ``scene.model``, ``scene.scheme`` and ``scene.grid`` give the three parts
    (:mod:`symcushion.model.parts`); :meth:`from_parts` groups them again. The
    checks are the parts' own: a Scene is valid when its three parts are and the
    model takes the scheme (:func:`~symcushion.model.parts.check_scheme`).

    Attributes
    ----------
    body, legs, obstacles, mu, gravity, name
        The model's (:class:`~symcushion.model.parts.Model`).
    method, tangent_plane, slip, events, hysteresis
        The scheme's (:class:`~symcushion.model.parts.Scheme`; the choices are
        :data:`METHODS`, :data:`TANGENT_PLANES`, :data:`SLIP_RULES`,
        :data:`EVENT_RULES` and :data:`HYSTERESIS_LAWS`).
    dt, duration
        The time grid's (:class:`~symcushion.model.parts.TimeGrid`), in s.
    """

    body: Body
    legs: list
    obstacles: list
    # the defaults are the parts' own
    mu: float = Model.mu
    method: str = Scheme.method
    dt: float = TimeGrid.dt
    duration: float = TimeGrid.duration
    gravity: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, -9.81]))
    name: str = Model.name
    tangent_plane: str = Scheme.tangent_plane
    slip: str = Scheme.slip
    events: str = Scheme.events
    hysteresis: str = Scheme.hysteresis

    def __post_init__(self):
        model = Model(self.body, self.legs, self.obstacles, self.mu, self.gravity, self.name)
        scheme = Scheme(**{name: getattr(self, name) for name in SCHEME_OPTIONS})
        check_scheme(model, scheme)
        grid = TimeGrid(self.dt, self.duration)
        for part in (model, scheme, grid):
            for name in part.__dataclass_fields__:
                setattr(self, name, getattr(part, name))

    @classmethod
    def from_parts(cls, model: Model, scheme: Scheme | None = None,
                   grid: TimeGrid | None = None) -> "Scene":
        """The scene of a model, a scheme (default :class:`Scheme`'s) and a time grid
        (default :class:`TimeGrid`'s)."""
        parts = [model, Scheme() if scheme is None else scheme,
                 TimeGrid() if grid is None else grid]
        return cls(**{name: getattr(part, name) for part in parts
                      for name in part.__dataclass_fields__})

    @property
    def model(self) -> Model:
        """What is simulated: body, legs, obstacles, μ, gravity and name."""
        return Model(self.body, self.legs, self.obstacles, self.mu, self.gravity, self.name)

    @property
    def scheme(self) -> Scheme:
        """How it is stepped: method, tangent plane, slip rule, events, hysteresis."""
        return Scheme(**{name: getattr(self, name) for name in SCHEME_OPTIONS})

    @property
    def grid(self) -> TimeGrid:
        """When: Δt and the duration."""
        return TimeGrid(self.dt, self.duration)

    @property
    def steps(self) -> int:
        """Number of steps, round(duration/dt)."""
        return self.grid.steps

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
