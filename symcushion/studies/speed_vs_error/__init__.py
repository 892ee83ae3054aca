"""How much accuracy does a second of computing buy? The speed-vs-error study.

Question: for the Fig. 3 scene (μ = 0), the Fig. 4 scene (μ = 0.05), a
four-legged lander on a 10° slope (``studies/lander_slope.toml``) and a
three-legged lander that hops (``studies/lander_hop.toml``), how does the
error of each variant (:data:`~.grid.VARIANTS`: the contact steps paper,
robust and implicit, and the implicit step with the midpoint slip rule, alone,
with the located branch switch and with the stroke lock)
fall with the time step Δt, at what orders, and what does each error level
cost per simulated second, in CasADi's virtual machine (``VARIANT/vm``) and
as compiled C (``VARIANT/c``)? The peers of ``symcushion.peers``, a penalty contact model
integrated by CVODES (``penalty-cvodes/rtol=...``) and MuJoCo (``mujoco``),
are measured the same way when that module is importable.

Reference: the implicit step, compiled, at Δt = DT_REF (1e-6 s), far below
the grid; its own error is estimated by running it again at 2·DT_REF and
taking the difference of every metric (a Richardson estimate of order 1, an
upper bound for any order ≥ 1). Errors below FLOOR_FACTOR times that
estimate are not used to fit orders.

Metrics of a run (docs/speed-vs-error.md defines them with formulas):

* rebound speed: Fig. 3, the vertical speed with which the ball passes the
  height of first contact on the way up, from the first sample above it by
  ballistic extrapolation (as ``symcushion.reproduce`` measures Δy′);
  Fig. 4 and the lander, which need not leave the ground, the largest upward
  vertical velocity of the centre of mass over the run;
* peak deceleration: max over the run of |a − g|, the contact force per
  unit mass (m/s²);
* peak deflection: max over the run and the legs of the hinge deflection
  (angle between the strut and its rest direction, rad) and of the axial
  stroke |δ_S| (m); the error column uses the hinge angle for Figs. 3–4
  (rigid rods) and the stroke for the lander;
* trajectory: RMS over the run's samples of the distance between its centre
  of mass and the reference's (interpolated to the same times), over the
  largest distance the reference's centre of mass travels from its start.

Errors: rebound speed absolute (m/s); peaks and trajectory relative.
Timing: the step loop only (the compiled or VM rollout calls), best of up to
BEST_OF passes when a pass is short. The machine is shared, so the cost
column ``wall_per_sim_second`` is process CPU time per simulated second (for
this single-threaded loop the wall time of an idle core); the wall clock is
kept in ``eval_wall_seconds``. Peers: see :func:`run_from_peer`. Build and
compile times have their own column.
The VM runs a rollout of at most CHUNK steps (``mapaccum``) again and again,
from the last state of the previous call, so that no rollout longer than
CHUNK is ever built; the compiled model runs its compiled CHUNK-step rollout
the same way (the last call runs past the end; wall per simulated second
divides by the steps actually run).

Output: ``figures/speed_vs_error.csv`` (one row per scene, method, backend
and Δt or tolerance), ``figures/speed_vs_error.png``, and the section
"Results" of ``docs/speed-vs-error.md``. Run from the repository root:
``python studies/speed_vs_error.py`` (10–20 min on 2 shared cores, most of
it the VM at small Δt and the references, plus about 5 min of gcc the first
time), or ``--quick`` for a smoke run (a few
Δt, reference at 1e-5, outputs to /tmp/symcushion-sve/quick, docs untouched).

The package holds the study's code, one module per concept; this file only
re-exports their names (the tests and ``studies/speed_vs_error.py`` import
them from here) and must not define any:

* ``grid``: scenes, Δt grid, reference step, paths, CSV columns;
* ``runs``: :class:`Run`, state reduction, the timed chunked rollout;
* ``metrics``: rebound speed, peaks, trajectory error, errors, a CSV row;
* ``orders``: order fits, Pareto fronts, cost at equal error;
* ``scene_runs``: a scene's reference and its VM and compiled runs;
* ``peer_runs``: the rows of symcushion.peers;
* ``csv_io``, ``plots``, ``results_text``: the CSV, the figure, the docs text;
* ``main``: the command line.
"""
from __future__ import annotations

from .csv_io import read_csv, write_csv
from .grid import (BEST_OF, applies, BUILD, CHUNK, COLUMNS, DOC, DT_GRID, DT_REF, FIGURES, FLOOR_FACTOR,
                   MUJOCO_TIMESTEPS, ORDER_DT_MAX, PEER_OUTPUT_DT, PENALTY_RTOLS,
                   QUICK_DT_GRID, QUICK_DT_REF, QUICK_OUT, REBOUND_AIM, REBOUND_BOUND,
                   REPEAT_BELOW, REQUIRED_COLUMNS, ROOT, SCENES, STUDIES, VARIANTS,
                   VM_MAX_STEPS)
from .main import main
from .metrics import errors, metrics, rebound_speed, result_row, trajectory_error
from .orders import (ERROR_KEYS, convergence_order, cost_at_error, equal_error_comparison,
                     orders_table, pareto, variants_on)
from .peer_runs import peer_rows, run_from_peer
from .plots import COLOURS, PEER_STYLE, PLOT_FLOOR, TITLES, plot
from .results_text import report_text
from .runs import Run, reduce_states, simulate_chunked
from .scene_runs import reference, run_scene

__all__ = [
    "BEST_OF", "BUILD", "CHUNK", "COLOURS", "COLUMNS", "DOC", "DT_GRID", "DT_REF",
    "ERROR_KEYS", "FIGURES", "FLOOR_FACTOR", "MUJOCO_TIMESTEPS", "ORDER_DT_MAX",
    "PEER_OUTPUT_DT", "PEER_STYLE", "PENALTY_RTOLS", "PLOT_FLOOR", "QUICK_DT_GRID",
    "QUICK_DT_REF", "QUICK_OUT", "REBOUND_AIM", "REBOUND_BOUND", "REPEAT_BELOW",
    "REQUIRED_COLUMNS", "ROOT", "Run", "SCENES", "STUDIES", "TITLES", "VARIANTS", "VM_MAX_STEPS",
    "applies", "convergence_order", "cost_at_error", "equal_error_comparison", "errors", "main",
    "metrics", "orders_table", "pareto", "peer_rows", "plot", "read_csv", "rebound_speed",
    "reduce_states", "reference", "report_text", "result_row", "run_from_peer", "run_scene",
    "simulate_chunked", "trajectory_error", "variants_on", "write_csv",
]
