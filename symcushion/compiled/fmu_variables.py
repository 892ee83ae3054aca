"""What an FMU of a scene exposes: its variables and its ``modelDescription.xml``.

This module owns the FMU's interface to an importer: the parameters, inputs,
outputs and energy totals with their value references, units and meanings
(:func:`fmu_variables`, named as the columns of ``symcushion.layout.vectors``), their
table for the docs (:func:`variables_markdown`) and the FMI 2.0
Co-Simulation model description (:func:`model_description`). It must not
generate or compile code or build the archive: that is :mod:`symcushion.compiled.fmu`.
"""
from __future__ import annotations

import os
import re
import xml.etree.ElementTree as ET
from dataclasses import dataclass

import casadi as ca

from symcushion import __version__
from symcushion.layout.vectors import (BODY_OUT_FIELDS, BODY_STATE_FIELDS, MODES, output_layout,
    state_layout)
from symcushion.layout.params import (FOOTPAD_FIELD, LEG_GEOMETRY_FIELDS, SCENE_PARAM_FIELDS,
    TRIPOD_GEOMETRY_FIELDS)
from symcushion.scheme.touchdown import StepModel

__all__ = ["INPUTS", "KINDS", "ENERGY_FIELDS", "FmuVariable", "fmu_variables",
           "variables_markdown", "model_description"]

#: The inputs: a force and a torque on the body, world frame, held over a
#: communication step. Named as the columns of symcushion.layout.vectors
#: (``{owner}_{field}_{axis}_{unit}``); ``N_m`` is N·m.
INPUTS = (("external_force", "N", "external force on the body (thrust, wind, a tether), "
           "world frame, through the centre of mass, held over a communication step"),
          ("external_torque", "N_m", "external torque on the body about its centre of "
           "mass, world frame, held over a communication step"))

#: FMI unit names (Modelica's unit syntax) of the layout's unit tokens, and
#: their SI base-unit exponents for ``UnitDefinitions``; "1" has no unit.
_FMI_UNITS = {"m": ("m", dict(m=1)), "m_s": ("m/s", dict(m=1, s=-1)),
              "m_s2": ("m/s2", dict(m=1, s=-2)), "rad": ("rad", dict(rad=1)),
              "rad_s": ("rad/s", dict(rad=1, s=-1)), "N": ("N", dict(kg=1, m=1, s=-2)),
              "N_m": ("N.m", dict(kg=1, m=2, s=-2)), "kg": ("kg", dict(kg=1)),
              "kg_m2": ("kg.m2", dict(kg=1, m=2)), "N_per_m": ("N/m", dict(kg=1, s=-2)),
              "N_m_per_rad": ("N.m/rad", dict(kg=1, m=2, s=-2, rad=-1)),
              "J": ("J", dict(kg=1, m=2, s=-2))}

#: Units of the legs' tunable curve parameters (symcushion.legs.characteristics:
#: Linear k, preload; PiecewiseLinear f0, f1, ...; Crushable k, crush_force,
#: plateau_slope), by element: the axial element S is a force of a stroke (m),
#: the hinge elements M_beta, M_gamma moments of an angle (rad).
_CURVE_UNITS = {"S": {"force": "N", "slope": "N_per_m"},
                "M_beta": {"force": "N_m", "slope": "N_m_per_rad"},
                "M_gamma": {"force": "N_m", "slope": "N_m_per_rad"}}
_SLOPE_PARAMS = ("k", "plateau_slope")

#: Where a Real variable lives in the wrapper (the C enum of fmu_model.h).
KINDS = {"parameter": 0, "input": 1, "state": 2, "output": 3, "energy": 4}

#: The per-step work of each leg (symcushion.layout.vectors) that the FMU sums over its
#: run into the outputs ``leg{j}_energy_{axial,bending,friction}_J``.
ENERGY_FIELDS = ("work_axial", "work_bending", "work_friction")

#: The outputs: body fields of the state x and the output y, per-leg fields of y.
_BODY_STATE_OUT = tuple(f.name for f in BODY_STATE_FIELDS)
_BODY_Y_OUT = tuple(f.name for f in BODY_OUT_FIELDS)
_LEG_Y_OUT = ("stroke", "force", "mode")
#: Leg outputs of integer type (codes of symcushion.layout.vectors.MODES).
_INTEGER_OUT = ("mode",)
#: Meanings that say more in an FMU than the layout's: the mode's codes, and the
#: acceleration's share of the external force.
_MEANINGS = {"mode": "contact mode: " + ", ".join(f"{k} {v}" for k, v in MODES.items()),
             "acceleration": "acceleration of the centre of mass at the end of the step, world "
                             "frame (gravity and the external force included)"}


@dataclass(frozen=True)
class FmuVariable:
    """One variable of the FMU.

    Attributes
    ----------
    name : str
        The variable's name: a column of ``symcushion.layout.vectors`` for the
        outputs, an entry of ``StepModel.param_names`` for the parameters.
    type : str
        ``"Real"`` or ``"Integer"``.
    causality : str
        ``"parameter"``, ``"input"`` or ``"output"``.
    vr : int
        Value reference (per type, from 0).
    kind : str
        Where the wrapper keeps it: ``"parameter"`` (p), ``"input"``,
        ``"state"`` (x), ``"output"`` (y) or ``"energy"`` (the legs' energy
        totals the wrapper sums).
    index : int
        Its index in that vector.
    unit : str or None
        Unit token (``m_s2``, ``N_m``, ...); None for dimensionless.
    description : str
    start : float or None
        Start value of a parameter or an input.
    """

    name: str
    type: str
    causality: str
    vr: int
    kind: str
    index: int
    unit: str | None
    description: str
    start: float | None = None

    @property
    def fmi_unit(self) -> str | None:
        """The unit as written in modelDescription.xml (``m/s2``), or None."""
        return None if self.unit is None else _FMI_UNITS[self.unit][0]


# ---------------------------------------------------------------------------
# variables
# ---------------------------------------------------------------------------
def _param_unit_and_meaning(name: str):
    """Unit token and description of the entry ``name`` of ``p``."""
    scene_fields = {f.name: f for f in SCENE_PARAM_FIELDS}
    head = name.split(".")[0]
    if head in scene_fields:
        f = scene_fields[head]
        return (None if f.unit == "1" else f.unit), f.meaning
    leg, element, *rest = name.split(".")
    geometry = {f.name: f for f in LEG_GEOMETRY_FIELDS + TRIPOD_GEOMETRY_FIELDS
                + (FOOTPAD_FIELD,)}
    if element in geometry:                 # leg{j}.hinge.x, leg{j}.length, leg{j}.footpad
        f = geometry[element]
        return (None if f.unit == "1" else f.unit), f"{leg}'s {f.meaning}"
    param = rest[-1]
    units = _CURVE_UNITS.get(element, {})
    kind = "slope" if param in _SLOPE_PARAMS else "force"
    branch = "unloading" if rest[0] == "unload" else "loading"
    return units.get(kind), f"tunable parameter {param} of the {branch} curve of {leg}'s {element}"


def fmu_variables(model: StepModel) -> list:
    """The FMU's variables, in the order of modelDescription.xml.

    Parameters: every entry of ``p`` (``model.param_names``), start values
    ``model.default_p``. Inputs: ``body_external_force_{x,y,z}_N`` and
    ``body_external_torque_{x,y,z}_N_m``, start 0. Outputs: the body's
    position, velocity, attitude and angular velocity (state x), its
    acceleration (output y), and per leg the stroke, the force on the foot
    (world) and the contact mode (y), named as the CSV columns of
    ``symcushion simulate``, and the energy the leg took since the start
    (``leg{j}_energy_{axial,bending,friction}_J``, sums of the steps' work).

    Parameters
    ----------
    model : StepModel

    Returns
    -------
    list of FmuVariable
    """
    n_legs = model.n_legs
    xl, yl = state_layout(n_legs), output_layout(n_legs)
    p0 = model.default_p
    out, counters = [], {"Real": 0, "Integer": 0}

    def add(name, type_, causality, kind, index, unit, description, start=None):
        out.append(FmuVariable(name, type_, causality, counters[type_], kind, index,
                               None if unit == "1" else unit, description, start))
        counters[type_] += 1

    for k, name in enumerate(model.param_names):
        unit, meaning = _param_unit_and_meaning(name)
        add(name, "Real", "parameter", "parameter", k, unit, meaning, float(p0[k]))
    for k, (field, unit, meaning) in enumerate(INPUTS):
        for a, axis in enumerate("xyz"):
            add(f"body_{field}_{axis}_{unit}", "Real", "input", "input", 3 * k + a, unit,
                meaning, 0.0)

    def add_field(layout, kind, name, leg=None):
        at = layout.slice(name, leg)
        owner = "body" if leg is None else f"leg{leg}"
        fields = layout.body_fields if leg is None else layout.leg_fields
        f = next(f for f in fields if f.name == name)
        type_ = "Integer" if name in _INTEGER_OUT else "Real"
        meaning = _MEANINGS.get(name, f.meaning)
        for column, index in zip(f.columns(owner), range(at.start, at.stop)):
            add(column, type_, "output", kind, index, f.unit, meaning)

    for name in _BODY_STATE_OUT:
        add_field(xl, "state", name)
    for name in _BODY_Y_OUT:
        add_field(yl, "output", name)
    for j in range(n_legs):
        for name in _LEG_Y_OUT:
            add_field(yl, "output", name, j)
        for k, field in enumerate(ENERGY_FIELDS):
            what = field.replace("work_", "")
            add(f"leg{j}_energy_{what}_J", "Real", "output", "energy",
                len(ENERGY_FIELDS) * j + k, "J", f"sum since the start of the steps' "
                f"{field} (symcushion.layout.vectors): the energy the leg took "
                + ("by friction at its foot" if what == "friction" else
                   f"on its {what} element{'s' if what == 'bending' else ''}"))
    return out


def _grouped(variables):
    """Runs of variables that differ only in an axis (``gravity.x``, ``.y``, ``.z``)."""
    groups = []
    for v in variables:
        last = groups[-1][-1] if groups else None
        if last is not None and (last.causality, last.type, last.unit, last.description) == \
                (v.causality, v.type, v.unit, v.description):
            groups[-1].append(v)
        else:
            groups.append([v])
    return groups


def variables_markdown(model: StepModel) -> str:
    """The FMU's variables as a Markdown table, as docs/toolchain.md shows them.

    One row per field (``body_position_{x,y,z}_m``; start values in order);
    the legs after the first are summarised in one row.
    """
    rows = ["| variable | causality | type | unit | start | meaning |",
            "|---|---|---|---|---|---|"]
    for group in _grouped(v for v in fmu_variables(model) if not re.match(r"leg[1-9]", v.name)):
        names = [v.name for v in group]
        prefix = os.path.commonprefix(names)
        suffix = os.path.commonprefix([n[len(prefix):][::-1] for n in names])[::-1]
        middles = [n[len(prefix):len(n) - len(suffix)] for n in names]
        name = names[0] if len(group) == 1 else f"{prefix}{{{','.join(middles)}}}{suffix}"
        v = group[0]
        start = ", ".join(f"{u.start:g}" for u in group) if v.start is not None else ""
        rows.append(f"| `{name}` | {v.causality} | {v.type} | {v.fmi_unit or ''} | {start} "
                    f"| {v.description} |")
    if model.n_legs > 1:
        rows.append(f"| `leg1…` to `leg{model.n_legs - 1}…` | as leg 0 | | | | the same for "
                    "each further leg |")
    return "\n".join(rows) + "\n"


# ---------------------------------------------------------------------------
# modelDescription.xml
# ---------------------------------------------------------------------------
def _sub(parent, tag, **attrs):
    return ET.SubElement(parent, tag, {k: str(v) for k, v in attrs.items() if v is not None})


def model_description(model: StepModel, model_identifier: str, guid: str,
                      source_files=()) -> str:
    """The text of modelDescription.xml (FMI 2.0, Co-Simulation).

    Parameters
    ----------
    model : StepModel
    model_identifier : str
        C identifier: the binary's file name without suffix.
    guid : str
    source_files : sequence of str
        The C files under ``sources/`` an importer compiles to rebuild it.

    Returns
    -------
    str
        UTF-8 XML; every output is an initial unknown (``initial`` calculated),
        every parameter tunable.
    """
    scene = model.scene
    root = ET.Element("fmiModelDescription", dict(
        fmiVersion="2.0", modelName=scene.name, guid=guid,
        description=f"symcushion touchdown of scene '{scene.name}' ({model.n_legs} legs, "
                    f"method {scene.method}, dt = {scene.dt!r} s)",
        generationTool=f"symcushion {__version__} (CasADi {ca.__version__})",
        variableNamingConvention="structured", numberOfEventIndicators="0"))
    cs = _sub(root, "CoSimulation", modelIdentifier=model_identifier,
              needsExecutionTool="false", canHandleVariableCommunicationStepSize="true",
              canInterpolateInputs="false", maxOutputDerivativeOrder="0",
              canRunAsynchronuously="false", canBeInstantiatedOnlyOncePerProcess="false",
              canNotUseMemoryManagementFunctions="false", canGetAndSetFMUstate="true",
              canSerializeFMUstate="true", providesDirectionalDerivative="false")
    if source_files:
        files = _sub(cs, "SourceFiles")
        for name in source_files:
            _sub(files, "File", name=name)
    variables = fmu_variables(model)
    units = _sub(root, "UnitDefinitions")
    for token in sorted({v.unit for v in variables if v.unit is not None},
                        key=lambda t: _FMI_UNITS[t][0]):
        name, exponents = _FMI_UNITS[token]
        _sub(_sub(units, "Unit", name=name), "BaseUnit", **exponents)
    cats = _sub(root, "LogCategories")
    for name, text in (("logStatusError", "errors: a bad argument, value or step"),
                       ("logAll", "every call, with loggingOn")):
        _sub(cats, "Category", name=name, description=text)
    _sub(root, "DefaultExperiment", startTime="0.0", stopTime=repr(float(scene.duration)),
         stepSize=repr(float(scene.dt)))
    mv = _sub(root, "ModelVariables")
    for v in variables:
        attrs = dict(name=v.name, valueReference=v.vr, description=v.description,
                     causality=v.causality)
        if v.causality == "parameter":
            attrs.update(variability="tunable", initial="exact")
        elif v.type == "Integer":
            attrs.update(variability="discrete")
        else:
            attrs.update(variability="continuous")
        sv = _sub(mv, "ScalarVariable", **attrs)
        typed = dict(start=None if v.start is None else repr(float(v.start)))
        if v.type == "Real":
            typed["unit"] = v.fmi_unit
        _sub(sv, v.type, **typed)
    structure = _sub(root, "ModelStructure")
    outputs = [i + 1 for i, v in enumerate(variables) if v.causality == "output"]
    for tag in ("Outputs", "InitialUnknowns"):
        block = _sub(structure, tag)
        for index in outputs:
            _sub(block, "Unknown", index=index)
    ET.indent(root)
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, "unicode") + "\n"
