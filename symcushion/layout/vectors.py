"""Layout of the vectors of ``touchdown_step``: named fields of x, y and p.

This module owns the meaning of every entry of the state ``x`` and the
per-step output ``y`` of ``touchdown_step(x, p, dt)``: named fields with
their size, unit and meaning, and the layouts that pack/unpack them for
NumPy (1-D vectors, or 2-D arrays whose columns are steps) and for CasADi
symbols and name the CSV columns. The machinery of named fields
(:class:`Field`, :class:`VectorLayout`) is :mod:`symcushion.layout.fields`,
the parameter vector ``p`` :mod:`symcushion.layout.params`; both are
re-exported here. The quaternion kit the state's attitude needs is
:mod:`symcushion.scheme.quaternion`.

It must not build a step, integrate, or know any physics beyond the
rigid-body kinematics of a unit quaternion: every other module reads and
writes these vectors through the names defined here, never through numeric
slices.

Vector order
------------
``x = [body (BODY_STATE), leg 0 (LEG_STATE), leg 1, ...]`` and
``y = [body (BODY_OUT), leg 0 (LEG_OUT), leg 1, ...]``; the fields of each
block are listed in :data:`BODY_STATE_FIELDS`, :data:`LEG_STATE_FIELDS`,
:data:`BODY_OUT_FIELDS` and :data:`LEG_OUT_FIELDS`, in vector order.

CSV columns are named ``{owner}_{field}[_{axis}]_{unit}``: owner ``body`` or
``leg{j}`` (0-based), axis ``x``/``y``/``z`` (``w``/``x``/``y``/``z`` for the
quaternion), unit ``m``, ``m_s``, ``m_s2``, ``rad``, ``rad_s``, ``N`` or
``1`` for a dimensionless entry (e.g. ``body_position_z_m``,
``leg2_force_z_N``, ``leg0_mode_1``).
"""
from __future__ import annotations

# the parameter vector's layout, re-exported: the step and the measures read it here
from symcushion.layout.params import (FOOTPAD_FIELD, LEG_GEOMETRY_FIELDS, SCENE_PARAM_FIELDS,
    TRIPOD_GEOMETRY_FIELDS, ParamLayout, default_p, footpads, has_footpads, param_layout)
# the machinery of named fields, re-exported: Field and VectorLayout were public here
from symcushion.layout.fields import UNITS, WXYZ, XYZ, Field, VectorLayout, block_size

__all__ = ["Field", "VectorLayout", "BODY_STATE_FIELDS", "LEG_STATE_FIELDS", "BODY_OUT_FIELDS",
           "LEG_OUT_FIELDS", "BODY_STATE", "LEG_STATE", "BODY_OUT", "LEG_OUT", "MODES",
           "UNITS", "SCENE_PARAM_FIELDS", "LEG_GEOMETRY_FIELDS",
           "TRIPOD_GEOMETRY_FIELDS", "FOOTPAD_FIELD", "ParamLayout", "param_layout",
           "has_footpads", "footpads", "default_p", "state_layout", "output_layout", "state_columns",
           "output_columns"]


#: Body block of the state: 13 entries.
BODY_STATE_FIELDS = (
    Field("position", "m", "centre of mass, world frame", XYZ),
    Field("velocity", "m_s", "velocity of the centre of mass, world frame", XYZ),
    Field("attitude", "1", "unit quaternion (w, x, y, z), body → world", WXYZ),
    Field("angular_velocity", "rad_s", "angular velocity, body axes", XYZ),
)
#: Leg block of the state: 13 entries per leg.
LEG_STATE_FIELDS = (
    Field("foot", "m", "foot position, world frame (the stored contact point)", XYZ),
    Field("contact", "1", "1 while the foot is in contact, else 0; with events = 'lock', "
          "2 for a foot whose stroke is locked and 3 for one on the unloading curve "
          "(in contact: contact > 0.5)"),
    Field("force_body", "N", "force on the foot from the obstacle, body axes "
          "(the force of the last step, used by the next half kick)", XYZ),
    Field("stroke_set", "m", "set of the axial absorber under the memory law: the stroke "
          "at which its elastic line carries no force (symcushion.legs.absorber; 0 for an "
          "element that keeps no set, and under the printed law)", default=0.0),
    Field("stroke_chord", "m_s", "mean stroke rate of the last step, (x₁ − x₀)/Δt, which "
          "the axial dampers' rate (A3) of the next step reads (0 for a free foot, and "
          "under the printed law)", default=0.0),
    Field("element_set", "1", "sets of the leg's other two elements under the memory law: "
          "an inverted tripod's secondaries (m); 0 for a hinged strut, whose hinge springs "
          "keep none", ("2", "3"), default=0.0),
    Field("element_chord", "1", "mean rates of the leg's other two elements over the last "
          "step (a strut's hinge angles β, γ in rad/s; a tripod's secondaries in m/s), which "
          "their dampers' rate (A3) of the next step reads (0 for a free foot, and under the "
          "printed law)", ("2", "3"), default=0.0),
)
#: Body block of the per-step output: 3 entries.
BODY_OUT_FIELDS = (
    Field("acceleration", "m_s2", "acceleration of the centre of mass at the end of "
          "the step, world frame (gravity included)", XYZ),
)
#: Leg block of the per-step output: 19 entries per leg.
LEG_OUT_FIELDS = (
    Field("in_contact", "1", "1 if the foot is in contact at the end of the step"),
    Field("mode", "1", "contact mode code, see MODES"),
    Field("force", "N", "force on the foot from the obstacle, world frame", XYZ),
    Field("normal", "1", "unit outward obstacle normal at the contact (0 when free)", XYZ),
    Field("axis", "1", "unit strut axis e_S from hinge to foot, world frame", XYZ),
    Field("stroke", "m", "axial stroke δ_S = L − L₀"),
    Field("beta", "rad", "hinge azimuth β"),
    Field("gamma_deflection", "rad", "polar deflection γ − γ₀"),
    Field("secondary_stroke", "m", "deflections of an inverted-tripod leg's two secondary "
          "struts, extension positive (0 for a hinged strut)", ("2", "3")),
    Field("work_axial", "J", "work done on the axial element over the step, "
          "½(S₀ + S₁)(δ_S1 − δ_S0), S = P·e_S (its dampers included): what it absorbs and "
          "stores", default=0.0),
    Field("work_bending", "J", "work done on the hinge springs over the step: the work of "
          "the foot force on the foot's motion relative to the body, ½(P₀ + P₁)·(ρ₁ − ρ₀), "
          "less work_axial", default=0.0),
    Field("work_friction", "J", "energy dissipated by friction at the foot over the step, "
          "−½(P₀ + P₁)·(r₁ − r₀) in the world frame for a foot on the obstacle at the end",
          default=0.0),
)

#: Codes of the leg output ``mode``.
MODES = {0: "free", 1: "stick", 2: "slip", 3: "lift-off"}


#: Sizes of the four blocks (public since the first C API; kept as plain ints).
BODY_STATE = block_size(BODY_STATE_FIELDS)
LEG_STATE = block_size(LEG_STATE_FIELDS)
BODY_OUT = block_size(BODY_OUT_FIELDS)
LEG_OUT = block_size(LEG_OUT_FIELDS)


def state_layout(n_legs: int) -> VectorLayout:
    """Layout of the state ``x`` of a scene with ``n_legs`` legs."""
    return VectorLayout(BODY_STATE_FIELDS, LEG_STATE_FIELDS, n_legs, "state")


def output_layout(n_legs: int) -> VectorLayout:
    """Layout of the per-step output ``y`` of a scene with ``n_legs`` legs."""
    return VectorLayout(BODY_OUT_FIELDS, LEG_OUT_FIELDS, n_legs, "output")


def state_columns(n_legs: int) -> list:
    """CSV column names of the state, in vector order (``body_position_x_m``, ...)."""
    return state_layout(n_legs).columns()


def output_columns(n_legs: int) -> list:
    """CSV column names of the per-step output, in vector order."""
    return output_layout(n_legs).columns()
