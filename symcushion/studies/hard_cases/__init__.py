"""Hard-case battery: does each contact method survive the cases that break simulators?

Twelve cases, each run with the three contact steps (the step as printed,
the robust step, the exact implicit Coulomb step):

``stiff_axial``
    axially rigid rods with stiffness ratio 1e8 against bending, sliding on
    the Fig. 4 dome (μ = 0.05), Δt = 1 ms.
``stiff_axial_stick``
    the same rods with μ = 1: the feet stick and hold the stiff direction, so
    the explicit body update needs Δt below 2/ω_max (``stable_dt``); the case
    runs at STIFF_FRACTION·stable_dt and records that Δt = 1 ms diverges.
``grazing``
    a foot skimming a sphere along a line tangent to it (zero gravity).
``simultaneous``
    four feet crossing a plane inside the same step (vertical drop).
``recontact``
    a body bouncing on one leg with flights shorter than Δt = 10 ms: the
    foot leaves the plane and lands again inside one step.
``slope_stick``
    a sled on a 35° slope with μ just above the feet's T/N ≈ tan θ, 100 s:
    no creep.
``high_friction``
    an oblique landing with μ = 2.
``near_singular``
    legs whose struts pass within ~1e-3 rad of their hinge's polar axis
    (e_S ∥ e_n, docs/paper-notes.md §2), where D_p grows like 1/|e_S × e_n|.
``tiny_step`` / ``large_step``
    a compliant lander on a dome with Δt = 1e-6 and Δt = 1e-2.
``fast_impact``
    a stiff lander hitting a large dome at 10 m/s.
``long_rest``
    1000 s of resting contact on a dome at Δt = 1e-2.

For every run the checker reports (definitions in ``docs/hard-cases.md``):
finite results; the worst friction-cone excess (|F_τ| − μF_n)/|F| of a foot
in contact; the worst signed distance of a foot below the obstacle; the
largest gain of the mechanical energy (kinetic + gravity + elastic energy of
the legs' elements, ½kx² + f₀x per linear element) over its initial value,
relative to the case's energy scale; a symmetry error where the scene is
symmetric; the paper's step criterion 1 − n_k·n_{k+1} (max over the run) and,
where the case asks for it, what the adaptive driver did (halvings, smallest
step, steps capped by the stability limit). Long runs use one
``model.rollout(CHUNK)`` fed back chunk by chunk, keeping only these summaries.

Writes ``figures/hard_cases.md`` (the table) and the "Results" section of
``docs/hard-cases.md``. Run from the repository root:
``python studies/hard_cases.py`` (several minutes; ``--cases a,b`` runs some).

The package holds the battery's code, one module per concept; this file
only re-exports their names (the tests and ``studies/hard_cases.py`` import
them from here) and must not define any: ``cases`` (the twelve scenes and
their closed forms), ``checks`` (tolerances, invariants, accumulated
statistics, verdicts), ``runner`` (running a case chunk by chunk and the
adaptive driver), ``table`` (the Markdown table and reading it back) and
``main`` (the command line).
"""
from __future__ import annotations

from symcushion.contact.args import METHODS

from .cases import (CASES, G, GRAZE_DEPTH, NEAR_SINGULAR_GAMMA0, NEAR_SINGULAR_MISS,
                    NEAR_SINGULAR_SPEED, RECONTACT_DROP, REST_KICK, SLOPE, SLOPE_MARGIN,
                    STIFF_FRACTION, STIFF_RATIO, Setup, case_fast_impact, case_grazing,
                    case_high_friction, case_large_step, case_long_rest, case_near_singular,
                    case_recontact, case_simultaneous, case_slope_stick, case_stiff_axial,
                    case_stiff_axial_stick, case_tiny_step, explicit_limit, recontact_flights)
from .checks import (CONE_TOL, CREEP_TOL, ENERGY_TOL, PENETRATION_TOL, SYMMETRY_TOL, WORK_TOL,
                     Result, Stats, invariant_function)
from .main import DOC, SECTION, main
from .runner import CHUNK, STABILITY_RUN, run_adaptive, run_case
from .table import COLUMNS, ROOT, TABLE, notes, read_table, table, table_row, verdict

__all__ = [
    "CASES", "CHUNK", "COLUMNS", "CONE_TOL", "CREEP_TOL", "DOC", "ENERGY_TOL", "G",
    "GRAZE_DEPTH", "METHODS", "NEAR_SINGULAR_GAMMA0", "NEAR_SINGULAR_MISS",
    "NEAR_SINGULAR_SPEED", "PENETRATION_TOL", "RECONTACT_DROP", "REST_KICK", "ROOT",
    "Result", "SECTION", "SLOPE", "SLOPE_MARGIN", "STABILITY_RUN", "STIFF_FRACTION",
    "STIFF_RATIO", "SYMMETRY_TOL", "Setup", "Stats", "TABLE", "WORK_TOL", "case_fast_impact",
    "case_grazing", "case_high_friction", "case_large_step", "case_long_rest",
    "case_near_singular", "case_recontact", "case_simultaneous", "case_slope_stick",
    "case_stiff_axial", "case_stiff_axial_stick", "case_tiny_step", "explicit_limit",
    "invariant_function", "main", "notes", "read_table", "recontact_flights", "run_adaptive",
    "run_case", "table", "table_row", "verdict",
]
