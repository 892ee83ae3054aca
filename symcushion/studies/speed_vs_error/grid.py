"""Scenes, Δt grid, reference step, paths and CSV columns of the speed-vs-error study.

Owns the study's constants (each with a comment saying why its value) and
where the study reads and writes. It must not run, measure or write
anything: the other modules of :mod:`symcushion.studies.speed_vs_error`
import these names.
"""
from __future__ import annotations

from pathlib import Path

#: The repository root: this file is symcushion/studies/speed_vs_error/grid.py.
ROOT = Path(__file__).resolve().parents[3]
STUDIES = ROOT / "studies"
FIGURES = ROOT / "figures"
DOC = ROOT / "docs" / "speed-vs-error.md"
#: One build folder per scene and method (git-ignored ``build/``): a process
#: cannot load two different libraries from one path (symcushion.compiled.codegen).
BUILD = ROOT / "build" / "speed_vs_error"
QUICK_OUT = Path("/tmp/symcushion-sve/quick")

#: Δt of the grid (s): 1e-2 down to 1e-5, about three per decade.
DT_GRID = (1e-2, 3e-3, 1e-3, 3e-4, 1e-4, 3e-5, 1e-5)
QUICK_DT_GRID = (3e-3, 1e-3, 3e-4)
#: Δt of the reference (implicit step, compiled): 10× below the finest grid
#: point, and a divisor of every grid Δt, so its samples fall on theirs.
DT_REF = 1e-6
QUICK_DT_REF = 1e-5
#: Steps per rollout call. Building a VM rollout costs about 0.5–2 ms per step
#: (CasADi's analysis of the repeated step), so longer runs reuse this one.
CHUNK = 2000
#: Longest VM run (steps); longer points are skipped on the VM (not on C).
#: 250 000 covers the whole grid (Fig. 4 at 1e-5: 200 000 steps, ~30 s).
VM_MAX_STEPS = 250_000
#: Timing passes: a run whose first pass took less than REPEAT_BELOW seconds of
#: CPU is run again, up to BEST_OF passes, and the fastest pass is kept (the
#: machine is shared: the minimum is the least disturbed measurement).
BEST_OF = 3
REPEAT_BELOW = 1.0
#: Orders are fitted for Δt ≤ ORDER_DT_MAX (the asymptotic range: coarser steps
#: do not resolve the stiff axial mode of the rigid rods, 2/ω ≈ 3.8 ms) and to
#: errors above FLOOR_FACTOR × the reference's own error estimate.
ORDER_DT_MAX = 1e-3
FLOOR_FACTOR = 10.0
#: Peers (symcushion.peers): CVODES relative tolerances, MuJoCo time steps and
#: their output spacing, about PEER_OUTPUT_DT or one step if longer (MuJoCo: a
#: whole number of steps): fine enough for the peaks, coarse enough that
#: recording (a Python loop for MuJoCo) costs little.
PENALTY_RTOLS = (1e-4, 1e-6, 1e-8, 1e-10)
MUJOCO_TIMESTEPS = (1e-3, 3e-4, 1e-4, 3e-5, 1e-5)
PEER_OUTPUT_DT = 1e-4
#: The paper's bound on the Fig. 3 rebound, |Δy′| < 1e-2 m/s, and the aim of the study.
REBOUND_BOUND = 1e-2
REBOUND_AIM = 1e-4

#: Per scene: its file, how its rebound speed is measured and which deflection
#: the peak_deflection_error column compares.
SCENES = {
    "fig3": {"file": "fig3.toml", "rebound": "ballistic", "deflection": "hinge"},
    "fig4": {"file": "fig4.toml", "rebound": "max_up", "deflection": "hinge"},
    "lander_slope": {"file": "lander_slope.toml", "rebound": "max_up", "deflection": "stroke"},
    "lander_hop": {"file": "lander_hop.toml", "rebound": "max_up", "deflection": "stroke"},
}

#: The simulator variants the study compares, each with the scene settings it
#: sets: the three contact steps (docs/contact.md), and the exact step with the
#: second-order slip rule (docs/scenes.md, "Slip rule"; on a frictionless
#: scene it is the implicit step itself), also with the absorbers' branch
#: switch located inside the step (docs/scenes.md, "Branch switch"; without
#: an unloading branch, as on Figs. 3–4, the same graph as without it), and
#: with the stroke lock (docs/scenes.md, "Stroke lock"; a scene refuses it
#: without friction, so Fig. 3 has no such row, see :func:`applies`).
VARIANTS = {
    "paper": {"method": "paper"},
    "robust": {"method": "robust"},
    "implicit": {"method": "implicit"},
    "implicit+midpoint": {"method": "implicit", "slip": "midpoint"},
    "implicit+midpoint+branch": {"method": "implicit", "slip": "midpoint", "events": "branch"},
    "implicit+midpoint+lock": {"method": "implicit", "slip": "midpoint", "events": "lock"},
}


def applies(settings: dict, mu: float) -> bool:
    """Whether a variant's settings make sense on a scene of friction ``mu``.

    The stroke lock holds a stuck foot, so a frictionless scene refuses it
    (``Scene`` raises); every other variant runs on every scene.
    """
    return not (settings.get("events") == "lock" and mu == 0)

#: Columns of the CSV; the first five are the ones the study is built around.
REQUIRED_COLUMNS = ("scene", "method", "dt", "rebound_error", "wall_per_sim_second")
COLUMNS = REQUIRED_COLUMNS + (
    "peak_decel_error", "peak_deflection_error", "trajectory_error", "contact_step",
    "backend", "tolerance", "status", "steps_run", "sim_seconds", "eval_wall_seconds",
    "eval_cpu_seconds", "cpu_per_sim_second", "passes", "build_seconds", "rebound_speed",
    "rebound_dv", "rebound_kind", "peak_decel", "peak_hinge", "peak_stroke")

