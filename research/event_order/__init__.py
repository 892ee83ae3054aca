"""Which events limit the order of the step on the 3-D lander? The event-order study.

Question: the implicit contact step converges at second order on Figs. 3–4
but at about first order on the lander of ``studies/lander_slope.toml``.
That lander has three kinds of non-smooth event the dome scenes lack: the
crushable absorber's force jumps to its unloading branch when the stroke
rate changes sign, feet stick and slip on the slope, and single feet touch
down and lift off at different instants. The study removes each kind in
turn and fits the order of the error against Δt:

* ``all events``: the lander as committed;
* ``elastic``: the absorber without its unloading branch (the loading curve
  in both directions: no branch jump);
* ``stick``: μ = :data:`STICK_MU`, so large that hardly any foot slips (the
  CSV gives the slipping share of the contact samples);
* ``flat``: a level plane instead of the 10° slope, the feet 1 mm above it
  (all four touch down together, no tipping onto a downhill pair);
* ``none``: the three removed together;

and runs a second scene with a hop, ``studies/lander_hop.toml``, whose
final state at t = 0.6 s is compared with the reference. Every case runs
with each slip rule of the implicit step (:data:`SLIP_RULES`: backward
Euler, the default, and the second-order midpoint rule of
``symcushion.contact.midpoint``), labelled "variant (midpoint)" for the
second. The variants that keep the absorber's unloading branch (and
``elastic``, as a check that the option then changes nothing) run once more
with the midpoint rule and ``events = "branch"`` (``symcushion.scheme.branch_switch``:
the kick weighted at the located loading/unloading switch), labelled
"variant (midpoint, branch)"; :func:`reversals` counts each leg's stroke
reversals in contact, the branch switches, at two Δt.

Every run is the implicit contact step, compiled C, at Δt in :data:`DT_GRID`;
the reference is the same scene at :data:`DT_REF`, checked against a run at
:data:`DT_CHECK`. The metrics are those of ``studies/speed_vs_error.py``:
the trajectory error, RMS distance of the centre of mass from the
reference's over the run, relative to the reference's travel; the rebound
error, |max ż − max ż_ref| (m/s); and the final-state error, the larger of
|x(T) − x_ref(T)| over the reference's travel and |v(T) − v_ref(T)| over the
impact speed |v(0)|.

The control runs (``--controls``) remove every event at once: the lander on
linear legs, at rest on its feet on level ground, kicked; they separate
bouncing and rocking (no slip) from sliding, with each slip rule, from the
start as built and from a settled start (:func:`settled`).

Output: ``figures/event_order.csv`` (one row per scene, variant and Δt),
``figures/event_order.png``, and the sections "Events: measured" and
"Events: controls" of the results page ``figures/event_order.md`` (each
option below rewrites its own section there; ``docs/event-order.md`` states
the findings). The study is research, not part of the installed package;
run it from the repository root: ``python studies/event_order.py``
(seventeen cases, 7 min on the
shared 2-core machine with other jobs running, plus gcc the first time;
builds are cached in ``build/event_order/``); ``--controls`` runs only the
control runs (about 4 min), ``--cost`` only the interleaved timing of the
located switch against its peers (:func:`cost_check`, section "Events:
cost", about 1 min), ``--limits`` only the default step, the stroke lock and the
regularised branch switch on the slope lander down to Δt = 1e-6 s
(:func:`limit_runs` and :func:`oracle`, section "Events: two limits on the
slope", about 12 min), ``--held`` only what the regularised switch holds
(:func:`held_runs`, section "Events: what the regularised switch holds"),
``--reference`` only how well that reference is known, on a ladder of
widths and steps and with its initial state perturbed (:func:`ladder_runs`,
:func:`sensitivity_runs`, section "Events: how well the reference is known",
about an hour), ``--window`` only the slope lander's schemes over its first
0.2 s, where that reference is known, with their orders there
(:func:`window_runs`, section "Events: orders where the reference is known",
figure ``figures/event_order_window.png``, about 5 min), ``--smoothness``
only each scheme's run with its initial velocity nudged, to find where the
run stops being a smooth function of its initial state (:func:`smoothness_runs`,
section "Events: where each run stops being smooth", about 10 min),
``--roundoff`` only the default step, the lock and the regularised reference
with their initial velocity moved by one ulp, the floor under what each run
resolves in double precision (:func:`roundoff_runs`, section "Events: what
double precision resolves", figure ``figures/event_order_roundoff.png``,
about 8 min),
``--only TEXT`` only the cases whose scene or variant contains TEXT (no
output written).
"""
from __future__ import annotations

from .cases import (BRANCH_VARIANTS, BUILD, CHUNK, COLUMNS, DT_CHECK, DT_GRID, DT_REF,
                    ERROR_KEYS, EVENT_OPTIONS, FIGURES, FLAT_GAP, RESULTS, REVERSAL_DTS, ROOT,
                    SLIP_DT, SLIP_RULES, STICK_MU, STUDIES, VARIANTS, case_label, scenes, slope_cases)
from .cases import _variant_data  # noqa: F401 - the tests build a variant's scene data with it
from .controls import (CONTROLS, CONTROL_DTS, CONTROL_DT_REF, CONTROL_DURATION, CONTROL_STIFFNESS,
                       COST_DT, COST_ROUNDS, SETTLE_DT, STARTS, SWITCH_DTS,
                       SWITCH_KICK, SWITCH_REF, control_scene, controls,
                       controls_text, cost_check, cost_text, final_state,
                       settled, switch_case, switch_control)
from .figure import LINES, PANELS, STYLE, WINDOW_STYLE, plot, plot_roundoff, plot_window
from .held import HELD_RUNS, SIGMA_BAND, held_runs, held_text, interior_rates
from .limits import (LIMIT_DTS, LIMIT_SCHEMES, ORACLE_DT, ORACLE_DTS, ORACLE_RUNS,
                     ORACLE_SCENES, ORACLE_VARIANTS,
                     limit_runs, limits_text, oracle, oracle_text, regularized_scene,
                     slip_at_reversals)
from .main import main
from .reference import (PERTURBATION_SIZES, PERTURBED, REFERENCE_LADDER, SENSITIVITY_RUN,
                        SPREAD_TIMES, ladder_runs, perturbed_scene, reference_text,
                        sensitivity_runs, spread)
from .runs import (at_step, final_error, leg_reversals, orders, positions_at, reversal_steps,
                   reversals, run_case, slip_fraction, write_csv)
from .roundoff import (FIT_RANGE, ORDER_AIM, REGULARISED_RUNS, ROUNDOFF_DTS, ROUNDOFF_SCHEMES,
                       coarse_errors, needed_reference, needed_references, roundoff_runs,
                       roundoff_text, ulp_nudge)
from .smoothness import (LINEAR_SPREAD, NUDGES, SMOOTH_DTS, SMOOTH_SCHEMES, SMOOTH_TIMES,
                         nudged, smooth_until, smoothness_runs, smoothness_text)
from .text import cost_ratios, report_text
from .window import (WINDOW_REFERENCE, WINDOW_SCHEMES, WINDOW_TIMES, window_error, window_events,
                     window_orders, window_runs, window_text)

__all__ = [
    "BRANCH_VARIANTS", "BUILD", "CHUNK", "COLUMNS", "CONTROLS", "CONTROL_DTS", "CONTROL_DT_REF",
    "CONTROL_DURATION", "CONTROL_STIFFNESS", "COST_DT", "COST_ROUNDS", "DT_CHECK",
    "DT_GRID", "DT_REF", "ERROR_KEYS", "EVENT_OPTIONS", "FIGURES", "FLAT_GAP", "HELD_RUNS",
    "LIMIT_DTS",
    "LIMIT_SCHEMES", "LINES", "ORACLE_DT", "PERTURBATION_SIZES", "PERTURBED", "REFERENCE_LADDER",
    "SENSITIVITY_RUN", "SPREAD_TIMES", "ORACLE_DTS", "ORACLE_RUNS", "ORACLE_SCENES",
    "ORACLE_VARIANTS", "PANELS", "REVERSAL_DTS",
    "ROOT", "SETTLE_DT", "SIGMA_BAND", "SLIP_DT", "SLIP_RULES", "STARTS", "STICK_MU", "STUDIES", "STYLE",
    "SWITCH_DTS", "SWITCH_KICK", "SWITCH_REF", "VARIANTS", "at_step", "case_label",
    "control_scene", "controls", "controls_text", "cost_check", "cost_ratios", "cost_text",
    "final_error", "final_state", "held_runs", "held_text", "interior_rates", "ladder_runs", "leg_reversals", "limit_runs", "limits_text", "main", "oracle",
    "oracle_text", "orders", "perturbed_scene", "plot", "reference_text", "report_text",
    "regularized_scene", "reversal_steps", "reversals", "run_case", "scenes", "settled",
    "slip_at_reversals",
    "sensitivity_runs", "slip_fraction", "spread", "switch_case",
    "switch_control", "WINDOW_REFERENCE", "WINDOW_SCHEMES", "WINDOW_TIMES", "window_error",
    "window_events", "window_orders", "window_runs", "window_text", "WINDOW_STYLE",
    "plot_window", "write_csv", "LINEAR_SPREAD", "NUDGES", "SMOOTH_DTS", "SMOOTH_SCHEMES",
    "SMOOTH_TIMES", "nudged", "smooth_until", "smoothness_runs", "smoothness_text", "slope_cases", "positions_at",
    "REGULARISED_RUNS", "RESULTS", "ROUNDOFF_DTS", "ROUNDOFF_SCHEMES", "roundoff_runs",
    "roundoff_text", "ulp_nudge", "FIT_RANGE", "ORDER_AIM", "coarse_errors",
    "needed_reference", "needed_references", "plot_roundoff",
]
