"""How well the slope lander's reference is known: its ladder in width and Δt, and its sensitivity.

Owns the runs of ``--reference``: the lander of ``studies/lander_slope.toml``
with its absorbers' branch switch regularised (``limits.regularized_scene``)
on a ladder of widths w and steps Δt (:data:`REFERENCE_LADDER`), each run's
final centre of mass and its distance from the ladder's last run over time
(:func:`ladder_runs`), and the final state's response to tiny changes of the
initial state at the ladder's first rung (:func:`sensitivity_runs`). It must
not fit orders or write files (``main`` writes its section).

Why: the error of a scheme on this lander is measured against a regularised
run, and a fitted order means something only down to the error of that run.
The ladder says how far the reference still moves with w and Δt, and where
in time the runs part; the sensitivity says how rough the final state is
as a function of the initial one, a floor below which no two runs of this
scene can be told apart.
"""
from __future__ import annotations

import numpy as np

from symcushion.compiled.codegen import compiled_model
from symcushion.run.driver import simulate

from .cases import BUILD, CHUNK
from .limits import regularized_scene
from .runs import at_step, positions_at
from .smoothness import nudged
from .text import time_table_head

#: (rate_width w in m²/s, Δt in s) of the ladder, coarse to fine; the last is the
#: ladder's reference. w = 1e-7 at 1e-8 s is 8e7 steps, about half an hour.
REFERENCE_LADDER = ((1e-5, 1e-6), (1e-6, 3e-7), (1e-6, 1e-7), (1e-6, 3e-8),
                    (1e-7, 3e-8), (1e-7, 1e-8))
#: Times (s) at which each run's centre of mass is compared with the last run's.
SPREAD_TIMES = (0.1, 0.2, 0.3, 0.4, 0.45, 0.5, 0.6, 0.8)
#: Rows kept of each ladder run (``simulate(keep_rows=...)``).
KEEP_ROWS = 20_000
#: The rung whose initial state is perturbed: cheap and resolved.
SENSITIVITY_RUN = (1e-5, 1e-6)
#: Perturbed entries of the initial state: (label, body field, index).
PERTURBED = (("z", "position", 2), ("v_x", "velocity", 0), ("v_y", "velocity", 1))
#: Sizes of the perturbations (m or m/s).
PERTURBATION_SIZES = (1e-6, 1e-4)


def perturbed_scene(rate_width: float, field: str, index: int, size: float):
    """The regularised lander (``limits.regularized_scene``, all events) with
    ``body[field][index]`` of its initial state moved by ``size``
    (``smoothness.nudged``: ``field`` "position" or "velocity", ``index`` 0–2)."""
    return nudged(regularized_scene("all events", rate_width), field, index, size)


def _model(scene):
    return compiled_model(scene, BUILD / scene.name, steps=CHUNK)


def _run(scene, dt, model=None):
    model = _model(scene) if model is None else model
    return simulate(scene.with_(dt=dt), model=at_step(model, scene, dt), monitor=False,
                    keep_rows=KEEP_ROWS)


def spread(rows, times=SPREAD_TIMES) -> np.ndarray:
    """Distance (m) of each row's centre of mass from the last row's at ``times``:
    shape (len(rows), len(times)). Rows carry ``t`` and ``position`` (thinned runs:
    each is read at its first kept row at or after the time)."""
    last = positions_at(rows[-1]["t"], rows[-1]["position"], times)
    return np.array([np.linalg.norm(positions_at(r["t"], r["position"], times) - last, axis=1)
                     for r in rows])


def ladder_runs(runs=REFERENCE_LADDER, progress=print) -> list:
    """One row per (w, Δt) of ``runs``: ``rate_width``, ``dt``, ``final`` (m, (3,)),
    ``t`` and ``position`` (the thinned run)."""
    rows = []
    for w, dt in runs:
        traj = _run(regularized_scene("all events", w), dt)
        rows.append(dict(rate_width=w, dt=dt, final=np.asarray(traj.position[-1], dtype=float),
                         t=np.asarray(traj.t), position=np.asarray(traj.position)))
        progress(f"reference ladder: w = {w:g}, dt = {dt:g}: final x {rows[-1]['final'][0]:.5f} m")
    return rows


def sensitivity_runs(run=SENSITIVITY_RUN, perturbed=PERTURBED, sizes=PERTURBATION_SIZES,
                     progress=print) -> list:
    """The final centre of mass of the rung ``run`` with each entry of ``perturbed``
    moved by each of ``sizes``: rows of ``label``, ``size`` and ``moved`` (m, the
    distance of the final centre of mass from the unperturbed run's)."""
    w, dt = run
    scene = regularized_scene("all events", w)
    model = _model(scene)           # the perturbed scenes share it: x0 is not in the step
    base = np.asarray(_run(scene, dt, model).position[-1])
    rows = []
    for label, field, index in perturbed:
        for size in sizes:
            final = np.asarray(_run(perturbed_scene(w, field, index, size), dt,
                                     model).position[-1])
            rows.append(dict(label=label, size=size, moved=float(np.linalg.norm(final - base))))
            progress(f"sensitivity: {label} + {size:g}: final centre of mass moves "
                     f"{1e3 * rows[-1]['moved']:.3f} mm")
    return rows


def reference_text(ladder, sensitivity, run=SENSITIVITY_RUN, times=SPREAD_TIMES) -> str:
    """The section "Events: how well the reference is known" from :func:`ladder_runs`
    and :func:`sensitivity_runs`."""
    d = spread(ladder, times)
    lines = ["Produced by `python studies/event_order.py --reference` (compiled C, about an "
             "hour): the lander of `studies/lander_slope.toml` with its absorbers' branch "
             "switch regularised (`smooth = true`, `rate_width` w; default step) on a ladder "
             "of widths and steps. The last columns are the distance of each run's centre of "
             "mass from the last run's at the times given (mm).", ""]
    lines += time_table_head(("w (m²/s)", "Δt (s)", "final centre of mass (m)"),
                             ("---:", "---:", "---"), times)
    for r, row in zip(ladder, d):
        lines.append(f"| {r['rate_width']:g} | {r['dt']:g} | "
                     f"({', '.join(f'{x:.5f}' for x in r['final'])}) | "
                     + " | ".join(f"{1e3 * x:.2f}" for x in row) + " |")
    lines += ["", f"The final centre of mass of the run at w = {run[0]:g}, Δt = {run[1]:g} s "
              "when one entry of the initial state is moved (distance from the unperturbed "
              "run's, mm):", "",
              "| entry moved | by | final centre of mass moves (mm) |", "|---|---:|---:|"]
    for r in sensitivity:
        unit = "m" if r["label"] == "z" else "m/s"
        lines.append(f"| {r['label']} | {r['size']:g} {unit} | {1e3 * r['moved']:.3f} |")
    return "\n".join(lines)
