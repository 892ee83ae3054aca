"""The event-order study's cases: paths, Δt grid, variants and the scenes they build.

Owns the study's constants (each with a comment saying why its value), the
labels of its cases, how a variant changes the lander's scene data and the
slope lander's cases by label. It must not run, measure or write anything.
"""
from __future__ import annotations

import copy
from pathlib import Path

from symcushion.model.scene import read_toml, scene_from_dict


#: The repository root: this file is research/event_order/cases.py.
ROOT = Path(__file__).resolve().parents[2]
STUDIES = ROOT / "studies"
FIGURES = ROOT / "figures"
#: The study's generated tables, one section per option; docs/event-order.md
#: states the findings and quotes these numbers.
RESULTS = FIGURES / "event_order.md"
BUILD = ROOT / "build" / "event_order"

#: Δt of the fits (s): 1e-2 to 1e-4, about three per decade; each divides the
#: scenes' durations (0.8 s, 0.6 s) and is a multiple of DT_REF, so that a
#: run's samples, its last one included, fall on the reference's.
DT_GRID = (1e-2, 5e-3, 2e-3, 1e-3, 5e-4, 2e-4, 1e-4)
#: Reference and its check (s): 50× below the finest grid point; the check at
#: half of it estimates the reference's own error (for an order ≥ 1 the
#: difference bounds the reference's error).
DT_REF = 2e-6
DT_CHECK = 1e-6
#: μ at which (almost) no foot of the lander slips: five times the slope's
#: tan 10° and well above the |P_t|/P_n of a crushing leg.
STICK_MU = 2.0
#: Height of the lowest foot above the level plane of the ``flat`` variant (m).
FLAT_GAP = 1e-3
#: Steps per compiled rollout call.
CHUNK = 2000
#: Δt at which the slipping share of the contact samples is counted (s).
SLIP_DT = 1e-4
#: The lander's variants: each removes some of its events. "stick, flat" keeps
#: only the absorbers' branch switches and locks (level ground, μ = STICK_MU):
#: the feet that lock stick, the case the stroke lock (``events = "lock"``)
#: is built for.
VARIANTS = ("all events", "elastic", "stick", "flat", "stick, flat", "none")
#: Slip rules of the implicit contact step (``Scene.slip``): every variant runs
#: with each; a case's label is the variant, with " (midpoint)" for the second.
SLIP_RULES = ("backward", "midpoint")
#: Variants that also run with ``events = "branch"`` (midpoint slip rule):
#: those with the unloading branch, and ``elastic`` (no switch: the option
#: must change nothing).
BRANCH_VARIANTS = ("all events", "elastic", "stick", "flat", "stick, flat")
#: Event rules beyond "none" that run on :data:`BRANCH_VARIANTS` and on the hop
#: scene (midpoint slip rule): the located switch, and the switch with the lock.
EVENT_OPTIONS = ("branch", "lock")
#: Δt at which :func:`reversals` counts the stroke reversals (s): if a leg
#: reverses once per turning point the counts are equal; if it chatters
#: between its branches they grow as 1/Δt.
REVERSAL_DTS = (1e-3, 2.5e-4)
COLUMNS = ("scene", "variant", "slip", "events", "kind", "dt", "status", "trajectory_error", "rebound_error",
           "final_error", "rebound_speed", "cpu_per_sim_second", "slip_fraction", "reversals")
ERROR_KEYS = ("trajectory_error", "rebound_error", "final_error")


def case_label(variant: str, slip: str, events: str = "none") -> str:
    """The label of a case: the variant, with " (midpoint)" for the midpoint slip rule
    and " (midpoint, branch)" with ``events = "branch"`` as well."""
    options = [o for o, default in ((slip, "backward"), (events, "none")) if o != default]
    return f"{variant} ({', '.join(options)})" if options else variant


def _variant_data(data: dict, variant: str, slip: str = "backward", events: str = "none") -> dict:
    """The lander's TOML contents with the events of ``variant`` removed, slip rule ``slip``
    and event rule ``events``."""
    if variant not in VARIANTS:
        raise ValueError(f"`variant` must be one of {VARIANTS}, got {variant!r}.")
    if slip not in SLIP_RULES:
        raise ValueError(f"`slip` must be one of {SLIP_RULES}, got {slip!r}.")
    data = copy.deepcopy(data)
    if slip != "backward":
        data["scene"]["slip"] = slip
    if events != "none":
        data["scene"]["events"] = events
    if variant in ("elastic", "none"):
        data["legs"]["S"].pop("unloading")
    if variant in ("stick", "stick, flat", "none"):
        data["scene"]["mu"] = STICK_MU
    if variant in ("flat", "stick, flat", "none"):
        data["obstacle"][0]["angle"] = 0.0
        scene = scene_from_dict(data, "<variant>")
        lowest = max(-float(leg.rest_foot[2]) for leg in scene.legs)
        data["body"]["position"][2] = FLAT_GAP + lowest
    label = (case_label(variant, slip, events).replace(" (", "-").replace(")", "")
             .replace(", ", "-").replace(" ", "_"))
    data["scene"]["name"] = f"{data['scene']['name']}-{label}"
    return data


def scenes():
    """(scene name, case label, slip rule, Scene) of every case of the study."""
    base = read_toml(STUDIES / "lander_slope.toml")
    cases = [(v, r, "none") for r in SLIP_RULES for v in VARIANTS]
    cases += [(v, "midpoint", e) for e in EVENT_OPTIONS for v in BRANCH_VARIANTS]
    out = [("lander_slope", case_label(*c), c[1],
            scene_from_dict(_variant_data(base, *c), f"lander_slope:{case_label(*c)}"))
           for c in cases]
    hop = read_toml(STUDIES / "lander_hop.toml")
    out.append(("lander_hop", "all events", "backward", scene_from_dict(hop, "lander_hop.toml")))
    for c in [("all events", "midpoint", e) for e in ("none",) + EVENT_OPTIONS]:
        out.append(("lander_hop", case_label(*c), c[1],
                    scene_from_dict(_variant_data(hop, *c), f"lander_hop.toml:{case_label(*c)}")))
    return out


def slope_cases(labels) -> dict:
    """The slope lander's cases of ``labels`` (case labels of :func:`scenes`), by label;
    a ValueError naming the unknown ones and the known labels otherwise."""
    by_label = {label: scene for name, label, _, scene in scenes() if name == "lander_slope"}
    unknown = [label for label in labels if label not in by_label]
    if unknown:
        raise ValueError(f"`schemes` holds {unknown!r}, not cases of the slope lander; use "
                         f"some of {sorted(by_label)}.")
    return {label: by_label[label] for label in labels}
