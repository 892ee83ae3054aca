"""Physical sanity of a valid scene, before and during a run.

A scene whose every field is well-formed (``symcushion.validation``) can still
describe nonsense: a body that starts inside the dome, feet off a terrain
grid, a surface formula that is NaN where the feet go, a step above the
explicit stability limit. This module owns those checks:

* :func:`check_scene` — every check before the run, as a list of
  :class:`Finding` (``severity`` "error" or "warning"); nothing is simulated.
* :func:`preflight` — raises :class:`~symcushion.validation.SceneError` on
  errors (and on warnings with ``strict``), else emits each warning as a
  :class:`PhysicsWarning`.
* the checks *during* a run live in ``symcushion.run.monitor``
  (:class:`~symcushion.run.monitor.RunMonitor`, re-exported here); they
  share :class:`Finding` and the geometry helpers of ``symcushion.run.findings``.

The checks themselves, by family, are ``symcushion.run.checks_obstacles`` (where
the body and the feet start) and ``symcushion.run.checks_legs`` (the elements and
the step); this module runs them in order and re-exports their tolerances.

It only inspects: it never changes a scene, a state or a step, and it does
not drive the simulation (``symcushion.run.driver`` does, and calls it).
docs/checks.md lists every check with its tolerance and its test.
"""
from __future__ import annotations

import warnings

import numpy as np

# the findings, checks and tolerances of the families, re-exported: users read them here
# (docs/checks.md names FREE_DIRECTION_RATIO and DAMPING_TIME_SPREAD as constants of this module)
from symcushion.run.checks_legs import (DAMPING_TIME_SPREAD, DT_ERROR_RATIO, check_buckling,
    check_curves, check_damping_times, check_time_step)
from symcushion.run.checks_obstacles import (BODY_TOLERANCE, FAST_STEP_FRACTION, FD_STEP,
    FOOTPAD_FRACTION, FREE_DIRECTION_RATIO, GRADIENT_TOLERANCE, REACH_FRACTIONS,
    SAMPLE_DIRECTIONS, START_TOLERANCE, check_footpads, check_free_directions, check_start,
    check_surfaces, check_terrain)
from symcushion.run.findings import Finding, PhysicsWarning
from symcushion.model.scene_data import Scene
from symcushion.run.monitor import RunMonitor
from symcushion.scheme.touchdown import initial_state
from symcushion.validation import SceneError

__all__ = ["Finding", "PhysicsWarning", "RunMonitor", "check_scene", "preflight",
           "START_TOLERANCE", "BODY_TOLERANCE", "REACH_FRACTIONS", "SAMPLE_DIRECTIONS",
           "FD_STEP", "GRADIENT_TOLERANCE", "FAST_STEP_FRACTION", "DT_ERROR_RATIO",
           "FOOTPAD_FRACTION"]


# ---------------------------------------------------------------------------
# before the run
# ---------------------------------------------------------------------------
def check_scene(scene: Scene, model=None, x0=None) -> list:
    """Every check before the run (nothing is simulated).

    Parameters
    ----------
    scene : Scene
    model : StepModel, optional
        Built by ``build_model(scene)`` if not given (needed for ``stable_dt``).
    x0 : array_like, shape (nx,), optional
        Initial state to check; default ``initial_state(scene)``.

    Returns
    -------
    list of Finding
        Errors first, then warnings. Zero gravity is valid and gives none.
    """
    if not isinstance(scene, Scene):
        raise TypeError(f"`scene` must be a Scene (load_scene('x.toml')), got "
                        f"{type(scene).__name__}.")
    x0 = initial_state(scene) if x0 is None else np.asarray(x0, dtype=float).ravel()
    findings = []
    findings += check_start(scene, x0)
    findings += check_footpads(scene)
    findings += check_terrain(scene, x0)
    findings += check_surfaces(scene, x0)
    findings += check_curves(scene)
    findings += check_buckling(scene)
    findings += check_free_directions(scene, x0)
    findings += check_damping_times(scene)
    findings += check_time_step(scene, model, x0)
    return sorted(findings, key=lambda f: f.severity != "error")


def preflight(scene: Scene, model=None, strict: bool = False, *, x0=None, ignore=()) -> list:
    """Run :func:`check_scene`; raise on errors, warn on warnings.

    Parameters
    ----------
    scene, model, x0
        As :func:`check_scene`.
    strict : bool
        Treat warnings as errors.
    ignore : sequence of str
        Kinds not to report (e.g. ``("dt_unstable",)`` when the driver caps
        the step at the stability limit itself).

    Returns
    -------
    list of Finding
        The warnings (when nothing was raised).

    Raises
    ------
    SceneError
        Listing every error (and, with ``strict``, every warning).
    """
    findings = [f for f in check_scene(scene, model, x0) if f.kind not in ignore]
    fatal = [f for f in findings if strict or f.severity == "error"]
    if fatal:
        raise SceneError(f"scene {scene.name!r}", [f"{f.severity}: {f.message}" for f in fatal])
    for f in findings:
        warnings.warn(f.message, PhysicsWarning, stacklevel=2)
    return findings
