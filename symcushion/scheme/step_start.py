"""The start of the touchdown step: its symbols and what the step reads from ``x`` and ``p``.

This module owns :class:`StepStart`, the data every part of the touchdown
step (``symcushion.scheme.touchdown``) starts from: the symbols ``x``, ``p``, ``dt``
of ``touchdown_step``, the body's state and parameters, each foot's stored
state, each leg's Functions, curve parameters, rest foot and footpad, and
which legs are on the memory law or may lock; and :func:`start_foot`, a
foot's position in body axes at the start of the step. It reads the vectors
only through :mod:`symcushion.layout.vectors`.

It must not compute forces, kicks or contact steps, nor build Functions.
"""
from __future__ import annotations

from dataclasses import dataclass

import casadi as ca

from symcushion.scheme.body_step import BodyParams
from symcushion.scheme.branch_switch import locates_switch
from symcushion.layout.vectors import footpads, param_layout, state_layout
from symcushion.legs.leg_scheme import bound_geometry
from symcushion.scheme.quaternion import quat_to_rot
from symcushion.model.parts import Model, Scheme
from symcushion.scheme.stroke_lock import LOCKED

__all__ = ["MEMORY_FIELDS", "StepStart", "step_start", "start_foot"]

#: The state fields of the memory law (symcushion.legs.absorber): each element's set and
#: its mean rate over the last step, the leg's own element first.
MEMORY_FIELDS = ("stroke_set", "element_set", "stroke_chord", "element_chord")

#: A foot's stored state fields.
FOOT_FIELDS = ("foot", "contact", "force_body") + MEMORY_FIELDS


@dataclass
class StepStart:
    """The symbols of ``touchdown_step(x, p, dt)`` and what the step reads from them.

    ``feet[j]`` holds foot j's stored state fields (:data:`FOOT_FIELDS`);
    ``fns_of[j]``, ``p_of[j]``, ``rest[j]`` and ``pads[j]`` leg j's Functions
    (geometry bound to ``p``), curve parameters, unloaded foot (body axes) and
    footpad radius; ``memory[j]``: leg j is on the memory law; ``lockable``:
    the legs whose stroke may lock (``events = "lock"``), and ``locked0[j]``
    whether it is locked at the start, ``stored_loading[j]`` whether its
    stored branch is the loading curve (``contact`` not
    :data:`~symcushion.scheme.stroke_lock.UNLOADING`).
    """

    model: Model
    scheme: Scheme
    X: ca.SX
    p: ca.SX
    h: ca.SX
    params: object
    body: BodyParams
    mu: object
    pos: ca.SX
    vel: ca.SX
    quat: ca.SX
    omega: ca.SX
    R: ca.SX
    feet: list
    memory: list
    fns_of: list
    p_of: list
    rest: list
    pads: list
    lockable: list
    locked0: dict
    stored_loading: dict

    @property
    def n_legs(self) -> int:
        return len(self.feet)

    @property
    def start(self):
        """(x, v, q, ω, R) at the start of the step."""
        return self.pos, self.vel, self.quat, self.omega, self.R


def step_start(model: Model, scheme: Scheme, geometry: str = "input") -> StepStart:
    """The symbols of the step of ``model`` under ``scheme`` and the quantities read
    from them."""
    legs = model.legs
    n_legs = len(legs)
    inputs = geometry == "input"
    params = param_layout(model, inputs)
    xl = state_layout(n_legs)
    X = ca.SX.sym("x", xl.size)
    p = ca.SX.sym("p", params.size)
    h = ca.SX.sym("dt")

    # scene entries of p: one compiled step serves every gravity, body and μ
    inertia = params.inertia(p)
    body = BodyParams(m=params.get(p, "mass"), inertia=inertia, inertia_inv=ca.inv(inertia),
                      g=params.get(p, "gravity"))
    friction = model.mu > 0          # μ = 0 literally: the frictionless graph, no μ entry
    mu = params.get(p, "mu") if friction else 0.0

    state = xl.unpack(X)
    feet = [{f: state[f][j] for f in FOOT_FIELDS} for j in range(n_legs)]
    # the legs on the memory law (symcushion.legs.absorber): their unloaded foot is where the
    # axial element's set leaves it
    memory = [scheme.hysteresis == "memory" and leg.axial_state for leg in legs]
    fns_of = [dict(leg.functions(geometry), **(leg.memory_functions(geometry) if mem else {}))
              for leg, mem in zip(legs, memory)]
    p_of = [params.leg_inputs(p, j) for j in range(n_legs)]
    if inputs:
        # each leg's geometry is its slice of p: bind it to strut_geometry(r, p), which
        # the contact code calls as strut_geometry(r)
        for fns, p_leg in zip(fns_of, p_of):
            fns["strut_geometry"] = bound_geometry(fns["strut_geometry"], p_leg)
    rest = [leg.rest_foot_expr(p_leg) if inputs else ca.DM(leg.rest_foot)
            for leg, p_leg in zip(legs, p_of)]
    lockable = [j for j, leg in enumerate(legs)
                if scheme.events == "lock" and locates_switch(leg)]
    return StepStart(model=model, scheme=scheme, X=X, p=p, h=h, params=params, body=body, mu=mu,
                     pos=state["position"], vel=state["velocity"], quat=state["attitude"],
                     omega=state["angular_velocity"], R=quat_to_rot(state["attitude"]),
                     feet=feet, memory=memory, fns_of=fns_of, p_of=p_of, rest=rest,
                     pads=footpads(model, params, p), lockable=lockable,
                     locked0={j: ca.fabs(feet[j]["contact"] - LOCKED) < 0.5 for j in lockable},
                     stored_loading={j: feet[j]["contact"] < 2.5 for j in lockable})


def start_foot(s: StepStart, j: int, R, pos):
    """Foot j in body axes for the body at (R, pos): a foot in contact (or of the memory
    law, whose free foot is where it relaxed to) at its stored world point, a free foot
    at its unloaded pose."""
    foot = s.feet[j]
    if s.memory[j]:
        return R.T @ (foot["foot"] - pos)
    in_contact = foot["contact"] > 0.5
    return ca.if_else(in_contact, R.T @ (foot["foot"] - pos), s.rest[j])

