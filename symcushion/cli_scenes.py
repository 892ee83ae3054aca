"""The scene a command runs: a scene file's, or one touchdown of a study file.

Owns telling a scene file from a study file (envelope or design) by its
tables, and building the scene of ``simulate`` and ``plot`` from either:
a study's touchdown N is :func:`symcushion.envelope.cases.case_scene`. It
must not run, write or plot anything.
"""
from __future__ import annotations

__all__ = ["STUDY_TABLES", "scene_of"]


#: Tables that make a TOML file a study (envelope or design), not a scene.
STUDY_TABLES = ("study", "sampling", "ranges", "limits", "robust", "design")


def scene_of(data: dict, source: str, case):
    """The scene of ``simulate``: a scene file's, or touchdown ``case`` of a study file's."""
    from symcushion.model.scene import scene_from_dict

    if not any(k in data for k in STUDY_TABLES):
        if case is not None:
            raise ValueError(f"`--case` = {case} needs an envelope or design study file; "
                             f"{source!r} is a scene (it has none of the tables "
                             f"{list(STUDY_TABLES)}). Drop `--case`.")
        return scene_from_dict(data, source)
    if case is None:
        raise ValueError(f"{source!r} is a study file: give `--case N` to simulate one of "
                         "its touchdowns (the row `case` of the cases.csv that `symcushion "
                         "envelope` writes).")
    from symcushion.envelope.cases import case_scene

    if "design" in data:
        from symcushion.design.robust.study import robust_study_from_dict
        study = robust_study_from_dict(data, source).envelope
    else:
        from symcushion.envelope.study import study_from_dict
        study = study_from_dict(data, source)
    return case_scene(study, case)
