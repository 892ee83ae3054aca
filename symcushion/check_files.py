"""The checks of a parsed file, whatever it describes, for ``symcushion check``.

This module owns telling a scene file from an envelope, design or optimise study
file (:func:`file_kind`) and checking each scene such a file describes at the state
it starts from (:func:`check_file`): the fields first (every bad field of a scene's
tables at once), then the physics of :func:`symcushion.run.checks.check_scene`. It
sits above the studies it reads and must not check anything itself, print or exit
(the command line does).
"""
from __future__ import annotations

import numpy as np

from symcushion.run.checks import check_scene
from symcushion.model.scene import scene_from_dict
from symcushion.design.optimise.study import study_from_dict as optimise_study_from_dict
from symcushion.design.robust.study import robust_study_from_dict
from symcushion.envelope.cases import initial_states
from symcushion.envelope.study import study_from_dict as envelope_study_from_dict

__all__ = ["file_kind", "check_file"]


def file_kind(data: dict) -> str:
    """What a parsed TOML file is, from its tables: ``"scene"``, ``"envelope"``
    (``[ranges]``), ``"design"`` (``[ranges]`` and ``[design]``: design for the
    envelope) or ``"optimise"`` (``[design]`` alone)."""
    if not isinstance(data, dict):
        return "scene"
    if "ranges" in data:
        return "design" if "design" in data else "envelope"
    return "optimise" if "design" in data else "scene"


def check_file(data: dict, source: str, base_dir=".") -> tuple:
    """Check a parsed scene or study file: its fields, then the physics of its scenes.

    Parameters
    ----------
    data : dict
        The parsed TOML file.
    source : str
        Its name, for messages (``"<stdin>"`` for standard input).
    base_dir : str or Path
        Where an optimise study's ``study.scene`` file is looked up.

    Returns
    -------
    kind : str
        :func:`file_kind`.
    checked : list of (str, list of Finding)
        Per scene of the file (an optimise study's scenarios; an envelope or
        design study's scene placed for its median conditions), a label and
        its findings.

    Raises
    ------
    ValueError
        A bad field (a :class:`SceneError` lists every bad field of a scene's
        tables at once).
    """
    kind = file_kind(data)
    if kind == "scene":
        return kind, [("scene", check_scene(scene_from_dict(data, source)))]
    if kind == "optimise":
        problem = optimise_study_from_dict(data, source, base_dir=base_dir).problem
        return kind, [(f"scenario {sc.name}", check_scene(sc.scene, x0=sc.x0))
                      for sc in problem.scenarios]
    if kind == "design":
        study = robust_study_from_dict(data, source).envelope
    else:
        study = envelope_study_from_dict(data, source)
    return kind, [("median touchdown", _check_median_case(study))]


def _check_median_case(study) -> list:
    """The findings of an envelope study's scene at the median of every condition."""
    median = {name: r.transform(np.array([0.5])) for name, r in study.ranges.items()}
    x0, _ = initial_states(study, median)
    return check_scene(study.scene, x0=x0[:, 0])
