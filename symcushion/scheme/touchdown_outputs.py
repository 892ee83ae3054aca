"""The end of the touchdown step: each foot's end state and the step's outputs.

This module owns how ``symcushion.scheme.touchdown`` turns the feet's contact
results (and the stroke lock's, ``symcushion.scheme.touchdown_events``) into the
state ``x_next`` and the output ``y`` of ``touchdown_step``: a leg's end pose,
force and contact flag (:func:`leg_end`), its stored state (:func:`foot_state`),
its per-step outputs with the energy it took (:func:`leg_outputs`,
:func:`leg_work`), the axial work the memory law's event kick books
(:func:`book_event_work`) and the packing of both vectors through
:mod:`symcushion.layout.vectors` (:func:`pack_step`).

It must not kick or drift the body, call the contact step or decide the
events of the scheme: it reads their results.
"""
from __future__ import annotations

import casadi as ca

from symcushion.layout.vectors import output_layout, state_layout
from symcushion.scheme.step_start import MEMORY_FIELDS, StepStart
from symcushion.scheme.stroke_lock import LOCKED, UNLOADING

__all__ = ["leg_work", "leg_end", "foot_state", "leg_outputs", "book_event_work", "pack_step"]


def leg_work(fns, start: dict, end: dict, stays) -> dict:
    """The energy one leg takes over a step (trapezoid rule; J): on its axial element,
    on its hinge springs, and dissipated by friction at its foot.

    ``start`` and ``end`` hold the foot in body axes ``rho``, its force ``P`` (body
    axes), the body's rotation ``R`` and the foot's world point ``foot``; ``stays``:
    the foot is on the obstacle at the end (only then did it move along it).
    """
    geo0 = fns["strut_geometry"].call(dict(r=start["rho"]))
    geo1 = fns["strut_geometry"].call(dict(r=end["rho"]))
    axial = 0.5 * (ca.dot(start["P"], geo0["e_S"]) + ca.dot(end["P"], geo1["e_S"])) * (
        geo1["delta_S"] - geo0["delta_S"])
    leg = 0.5 * ca.dot(start["P"] + end["P"], end["rho"] - start["rho"])
    slid = ca.if_else(stays, end["foot"] - start["foot"], ca.DM.zeros(3))
    friction = -0.5 * ca.dot(start["R"] @ start["P"] + end["R"] @ end["P"], slid)
    return dict(work_axial=axial, work_bending=leg - axial, work_friction=friction)


def leg_end(s: StepStart, j: int, r: dict, lock: dict | None) -> dict:
    """Leg j at the end of the step from its contact result ``r`` and, for a lockable
    leg, the lock's (``LOCK_LEG_OUT`` by name): on the obstacle (``stays``), pose
    ``rho1`` and force ``P1`` (body axes), world foot, contact flag, whether its switch
    kick (B1) applies, and whether it slips."""
    stays, rho1, foot_w, P1 = r["stays"], r["rho1"], r["foot_w"], r["P1"]
    contact = ca.if_else(stays, 1.0, 0.0)
    b1_active = ca.logic_and(r["in_contact"], stays)
    slipping = ca.dot(r["out"]["k"], r["out"]["k"]) > 0
    if lock is not None:
        rho1, P1 = lock["rho1"], lock["P1"]
        stays = ca.logic_or(stays, lock["stuck"])
        foot_w = ca.if_else(lock["stuck"], s.feet[j]["foot"], foot_w)
        contact = ca.if_else(lock["locked"], LOCKED, ca.if_else(
            stays, ca.if_else(lock["loading"], 1.0, UNLOADING), 0.0))
        b1_active = ca.logic_and(b1_active, ca.logic_not(ca.logic_or(lock["stuck"],
                                                                     s.locked0[j])))
        slipping = ca.logic_and(slipping, ca.logic_not(lock["stuck"]))
    return dict(stays=stays, rho1=rho1, foot_w=foot_w, P1=P1, contact=contact,
                b1_active=b1_active, slipping=slipping)


def foot_state(s: StepStart, j: int, r: dict, end: dict) -> dict:
    """Foot j's state fields at the end of the step (its memory-law fields carried over
    unless the leg is on that law)."""
    if s.memory[j]:
        sets, chords = r["sets"], r["chords"]
        memory = dict(stroke_set=sets[0], element_set=sets[1:], stroke_chord=chords[0],
                      element_chord=chords[1:])
    else:
        memory = {f: s.feet[j][f] for f in MEMORY_FIELDS}
    return dict(foot=end["foot_w"], contact=end["contact"], force_body=end["P1"], **memory)


def leg_outputs(s: StepStart, j: int, r: dict, end: dict, rho0, R1) -> dict:
    """Leg j's entries of the step's output: contact, mode, force, normal and axis
    (world), its deflections and the energy it took over the step (:func:`leg_work`)."""
    fns, foot, stays = s.fns_of[j], s.feet[j], end["stays"]
    mode = ca.if_else(stays, ca.if_else(end["slipping"], 2.0, 1.0),
                      ca.if_else(r["active"], 3.0, 0.0))
    geo = fns["strut_geometry"].call(dict(r=end["rho1"]))
    return dict(in_contact=ca.if_else(stays, 1.0, 0.0), mode=mode, force=R1 @ end["P1"],
                normal=ca.if_else(stays, r["normal_w"], ca.DM.zeros(3)),
                axis=R1 @ geo["e_S"], **s.model.legs[j].deflection_outputs(geo),
                **leg_work(fns, dict(rho=rho0, P=foot["force_body"], R=s.R,
                                     foot=ca.if_else(r["in_contact"], foot["foot"], r["r_s"])),
                           dict(rho=end["rho1"], P=end["P1"], R=R1, foot=end["foot_w"]),
                           stays))


def book_event_work(s: StepStart, res, outputs, plain, kicked) -> None:
    """The located events' kick changes the body's energy by the mean velocity times its
    impulse, exactly: the leg took that much less (its axial work). ``plain`` and
    ``kicked``: (v, ω) before and after that kick; changes ``outputs`` in place."""
    for j, r in enumerate(res):
        if r.get("events") is not None:
            outputs[j]["work_axial"] = outputs[j]["work_axial"] - s.h * (
                ca.dot((plain[0] + kicked[0]) / 2, r["events"][0])
                + ca.dot((plain[1] + kicked[1]) / 2, r["events"][1]))


def pack_step(s: StepStart, body: dict, feet: list, acc1, outputs: list):
    """``x_next`` and ``y`` of the step: the body's end ``position``, ``velocity``,
    ``attitude``, ``angular_velocity``, the feet's state fields, the acceleration and
    the legs' outputs."""
    xl, yl = state_layout(s.n_legs), output_layout(s.n_legs)
    x_next = xl.pack(**body, **{f: [foot[f] for foot in feet]
                                for f in ("foot", "contact", "force_body") + MEMORY_FIELDS})
    y = yl.pack(acceleration=acc1, **{f.name: [o[f.name] for o in outputs]
                                       for f in yl.leg_fields})
    return x_next, y
