"""The design's own file: the study file with the optimum's geometry and curves written in.

Owns turning a design θ back into the TOML a user runs: the parsed study
file with its ``[design]`` and ``[robust]`` tables dropped, each designed
curve parameter written into its element table (``S.f3`` into ``f[3]``,
``M_beta.k`` into ``stiffness``, ``S.unload.f0`` into ``unloading.f[0]``) and
each leg's designed hinge, e₀, e_n, L₀ and footpad into ``[legs]`` (when the
design keeps the legs a symmetric pattern) or into one ``[[leg]]`` table per
leg. What it writes is loaded back and compared, leg by leg, with the
design before the file is kept: a file that would run another lander is
refused, never written. An envelope design's file is an envelope study
(``symcushion envelope`` runs it; ``symcushion simulate --case`` runs one
of its touchdowns). It must not solve, simulate or choose a design.
"""
from __future__ import annotations

import copy
from pathlib import Path

import numpy as np

from symcushion.model.scene_data import symmetric_legs
from symcushion.model.toml_text import toml_text
from symcushion.run.output_files import atomic_write_text

__all__ = ["designed_data", "write_designed_file", "write_optimised_scene", "DESIGN_TABLES",
           "MATCH_TOL"]

#: Tables of a study file that only the design reads.
DESIGN_TABLES = ("design", "robust")

#: Largest relative difference between the design and the lander the written
#: file builds: round-off of the [legs] pattern's sines and cosines, far
#: below any physical tolerance.
MATCH_TOL = 1e-12

#: Element-table field of each curve parameter name, by curve type; a
#: piecewise curve's ``f{i}`` is entry i of its ``f``.
_FIELDS = {"linear": {"k": "stiffness", "preload": "preload"},
           "crushable": {"k": "stiffness", "crush_force": "crush_force",
                         "plateau_slope": "plateau_slope"},
           "gas": {"pressure": "pressure", "area": "area", "volume": "volume",
                   "exponent": "exponent"}}


def _set_param(table: dict, name: str, value: float, where: str):
    """Write curve parameter ``name`` into its element ``table`` (in place)."""
    if name.startswith("unload."):
        if "unloading" not in table:
            raise ValueError(f"`{where}` has no `unloading` table for parameter {name!r}.")
        return _set_param(table["unloading"], name[len("unload."):], value,
                          where + ".unloading")
    kind = table.get("type")
    if kind == "piecewise" and name[:1] == "f" and name[1:].isdigit():
        f = [float(v) for v in table["f"]]
        f[int(name[1:])] = value
        table["f"] = f
    elif name in _FIELDS.get(kind, {}):
        table[_FIELDS[kind][name]] = value
    else:
        raise ValueError(f"parameter {name!r} of `{where}` (type {kind!r}) has no field in a "
                         "scene file; write this design with the Python API instead.")


def _leg_values(problem, theta) -> list:
    """Per leg: {element: {parameter: value}} of the designed curves at θ."""
    p = problem.p_of(theta)
    out = []
    for j, leg in enumerate(problem.legs):
        curves = {}
        for el in leg.elements:
            if el.curve.tunable:
                curves[el.name] = {n: float(p[problem.param_names.index(f"leg{j}.{el.name}.{n}")])
                                   for n in el.curve.param_names}
        out.append(curves)
    return out


def _leg_geometry(problem, theta) -> list:
    return [problem.leg_geometry(theta, j) if problem.designs_geometry else None
            for j in range(len(problem.legs))]


def _pattern(table: dict, geometry: list, legs: list):
    """The ``[legs]`` fields of the designed geometry, or None if it is no longer a pattern."""
    if geometry[0] is None:
        return {}
    a0 = float(table.get("azimuth0", 0.0))
    frame = np.array([[np.cos(a0), -np.sin(a0), 0.0], [np.sin(a0), np.cos(a0), 0.0],
                      [0.0, 0.0, 1.0]])                  # columns: radial, tangential, up
    G = geometry[0]
    local = frame.T @ G["hinge"]
    if abs(local[1]) > MATCH_TOL * max(1.0, abs(local[0])):
        return None                                      # a hinge off its radial line
    fields = dict(radius=float(local[0]), height=float(local[2]), length=float(G["length"]),
                  e0=[float(v) for v in frame.T @ G["e0"]],
                  en=[float(v) for v in frame.T @ G["en"]])
    curves = {el.name: el.curve for el in legs[0].elements}
    pattern = symmetric_legs(int(table["count"]), fields["radius"], fields["height"],
                             fields["length"], fields["e0"], fields["en"],
                             S=None if legs[0].rigid else curves.get("S"),
                             M_beta=curves.get("M_beta"), M_gamma=curves.get("M_gamma"),
                             axial_ratio=legs[0].axial_ratio, azimuth0=a0)
    if len(pattern) != len(geometry):
        return None
    for leg, g in zip(pattern, geometry):
        if not (_close(leg.hinge, g["hinge"]) and _close(leg.e0, g["e0"])
                and _close(leg.en, g["en"]) and _close(leg.length, g["length"])
                and _close(g["footpad"], geometry[0]["footpad"])):
            return None
    if geometry[0]["footpad"] > 0 or "footpad" in table:
        fields["footpad"] = float(geometry[0]["footpad"])
    return fields


def _close(a, b) -> bool:
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return bool(np.all(np.abs(a - b) <= MATCH_TOL * np.maximum(1.0, np.abs(b))))


def _explicit_legs(data: dict, problem, geometry: list) -> list:
    """One ``[[leg]]`` table per leg of the design, elements copied from the file."""
    pattern = data.get("legs", {})
    own = list(data.get("leg", []))
    first = int(pattern["count"]) if pattern else 0
    out = []
    for j, leg in enumerate(problem.legs):
        src = pattern if j < first else own[j - first]
        t = {k: copy.deepcopy(v) for k, v in src.items()
             if k in ("S", "M_beta", "M_gamma", "axial_ratio", "law", "footpad")}
        G = geometry[j] if geometry[j] is not None else dict(
            hinge=leg.hinge, e0=leg.e0, en=leg.en, length=leg.length, footpad=leg.footpad)
        t.update(hinge=[float(v) for v in G["hinge"]], e0=[float(v) for v in G["e0"]],
                 en=[float(v) for v in G["en"]], length=float(G["length"]))
        if G["footpad"] > 0 or "footpad" in t:
            t["footpad"] = float(G["footpad"])
        out.append(t)
    return out


def designed_data(data: dict, problem, theta) -> dict:
    """The parsed study file ``data`` with design θ of ``problem`` written in.

    Parameters
    ----------
    data : dict
        The study file as ``read_toml`` parses it.
    problem : DesignProblem or EnvelopeDesign
        The design problem θ belongs to (its legs, parameter names and geometry map).
    theta : array_like, shape (n_variables,)
        The design (SI), in ``problem.var_names`` order.
    """
    if any(t.get("scheme") == "tripod" for t in [data.get("legs", {})] + data.get("leg", [])):
        raise ValueError("a scene of inverted tripods cannot be written back with its design "
                         "yet; write the design with the Python API.")
    out = {k: copy.deepcopy(v) for k, v in data.items() if k not in DESIGN_TABLES}
    values, geometry = _leg_values(problem, theta), _leg_geometry(problem, theta)
    same = all(v == values[0] for v in values)
    fields = (_pattern(out["legs"], geometry, problem.legs) if "legs" in out and "leg" not in out
              else None)
    if fields is not None and same:
        out["legs"].update(fields)
        for element, params in values[0].items():
            for name, value in params.items():
                _set_param(out["legs"][element], name, value, f"legs.{element}")
        return out
    legs = _explicit_legs(out, problem, geometry)
    for j, (t, curves) in enumerate(zip(legs, values)):
        for element, params in curves.items():
            for name, value in params.items():
                _set_param(t[element], name, value, f"leg[{j}].{element}")
    out.pop("legs", None)
    out["leg"] = legs
    return out


def _check_built(scene, problem, values, geometry):
    """Refuse a file whose lander is not the design's (a :class:`ValueError` naming the leg)."""
    if len(scene.legs) != len(problem.legs):
        raise ValueError(f"the written file has {len(scene.legs)} legs, the design "
                         f"{len(problem.legs)}.")
    for j, leg in enumerate(scene.legs):
        for el in leg.elements:
            want = values[j].get(el.name)
            if want is not None and not _close(el.curve.param_values, list(want.values())):
                raise ValueError(f"leg {j}'s `{el.name}` in the written file is not the "
                                 "design's; the file was not kept.")
        G = geometry[j]
        if G is not None and not (_close(leg.hinge, G["hinge"]) and _close(leg.e0, G["e0"])
                                  and _close(leg.en, G["en"])
                                  and _close(leg.length, G["length"])):
            raise ValueError(f"leg {j}'s geometry in the written file is not the design's; "
                             "the file was not kept.")


def write_designed_file(path, data: dict, problem, theta, load, header: str = ""):
    """Write ``data`` with design θ to ``path`` (atomically), checked by loading it back.

    ``load(dict) -> Scene`` builds the lander of the written file (the study's
    own loader); the file is kept only if that lander's legs are the design's
    to :data:`MATCH_TOL`.
    """
    import tomllib

    out = designed_data(data, problem, theta)
    text = toml_text(out, header)
    scene = load(tomllib.loads(text))
    _check_built(scene, problem, _leg_values(problem, theta), _leg_geometry(problem, theta))
    return atomic_write_text(path, text)


def write_optimised_scene(study, result, out) -> Path:
    """``<out>_designed.toml`` beside ``out`` (the JSON of ``symcushion optimise``):
    the design study's scene with the optimum written in, named ``<study>_designed``."""
    from symcushion.model.scene import scene_from_dict

    path = Path(out).with_name(Path(out).stem + "_designed.toml")
    data = dict(study.scene_data)
    data["scene"] = dict(data.get("scene", {}), name=f"{study.name}_designed")
    header = (f"The scene of {study.source} with the design of `symcushion optimise` written "
              f"in:\n{result.message}\n\n  symcushion simulate {path.name} --out OUT")
    return write_designed_file(path, data, study.problem, result.theta,
                               lambda d: scene_from_dict(d, str(path)), header=header)
