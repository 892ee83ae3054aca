"""Which events limit the order of the step on the 3-D lander? The event-order study.

Question: the implicit contact step converges at second order on Figs. 3–4
but at about first order on the lander of ``studies/lander_slope.toml``.
That lander has three kinds of non-smooth event the dome scenes lack: the
crushable absorber's force jumps to its unloading branch when the stroke
rate changes sign, feet stick and slip on the slope, and single feet touch
down and lift off at different instants. This script removes each kind in
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
``symcushion.contact_midpoint``), labelled "variant (midpoint)" for the
second. The variants that keep the absorber's unloading branch (and
``elastic``, as a check that the option then changes nothing) run once more
with the midpoint rule and ``events = "branch"`` (``symcushion.branch_switch``:
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
"Events: controls" of ``docs/speed-vs-error.md``. Run from the repository
root: ``python studies/event_order.py`` (seventeen cases, 7 min on the
shared 2-core machine with other jobs running, plus gcc the first time;
builds are cached in ``build/event_order/``); ``--controls`` runs only the
control runs (about 4 min), ``--cost`` only the interleaved timing of the
located switch against its peers (:func:`cost_check`, section "Events:
cost", about 1 min), ``--only TEXT`` only the cases whose scene or variant
contains TEXT (no output written).
"""
from __future__ import annotations

import argparse
import copy
import csv
import dataclasses
import time
from pathlib import Path

import numpy as np

from symcushion import report
from symcushion.codegen import compiled_model
from symcushion.layout import state_layout
from symcushion.scene import read_toml, scene_from_dict
from symcushion.simulate import build_model, equilibrium_state, simulate
from symcushion.studies import speed_vs_error as sve
from symcushion.studies.speed_vs_error.csv_io import csv_cell

ROOT = Path(__file__).resolve().parent.parent
STUDIES = ROOT / "studies"
FIGURES = ROOT / "figures"
DOC = ROOT / "docs" / "speed-vs-error.md"
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
VARIANTS = ("all events", "elastic", "stick", "flat", "none")
#: Slip rules of the implicit contact step (``Scene.slip``): every variant runs
#: with each; a case's label is the variant, with " (midpoint)" for the second.
SLIP_RULES = ("backward", "midpoint")
#: Variants that also run with ``events = "branch"`` (midpoint slip rule):
#: those with the unloading branch, and ``elastic`` (no switch: the option
#: must change nothing).
BRANCH_VARIANTS = ("all events", "elastic", "stick", "flat")
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
    if variant in ("stick", "none"):
        data["scene"]["mu"] = STICK_MU
    if variant in ("flat", "none"):
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
    cases += [(v, "midpoint", "branch") for v in BRANCH_VARIANTS]
    out = [("lander_slope", case_label(*c), c[1],
            scene_from_dict(_variant_data(base, *c), f"lander_slope:{case_label(*c)}"))
           for c in cases]
    hop = read_toml(STUDIES / "lander_hop.toml")
    out.append(("lander_hop", "all events", "backward", scene_from_dict(hop, "lander_hop.toml")))
    for c in (("all events", "midpoint", "none"), ("all events", "midpoint", "branch")):
        out.append(("lander_hop", case_label(*c), c[1],
                    scene_from_dict(_variant_data(hop, *c), f"lander_hop.toml:{case_label(*c)}")))
    return out


def final_error(run, ref) -> float:
    """max(|x(T) − x_ref(T)| / travel, |v(T) − v_ref(T)| / |v(0)|) at the run's last sample."""
    k = int(np.argmin(np.abs(ref.t - run.t[-1])))
    travel = float(np.max(np.linalg.norm(ref.position - ref.position[0], axis=1)))
    dx = np.linalg.norm(run.position[-1] - ref.position[k]) / travel
    dv = np.linalg.norm(run.velocity[-1] - ref.velocity[k]) / np.linalg.norm(ref.velocity[0])
    return float(max(dx, dv))


def at_step(model, scene, dt):
    """``model`` for ``scene`` at step ``dt``: ``simulate`` runs the scene of its model.

    The copy shares the model's Functions and its cache of rollouts (they do
    not depend on Δt).
    """
    return dataclasses.replace(model, scene=scene.with_(dt=dt))


def slip_fraction(model, scene, dt=SLIP_DT) -> float:
    """Share of the contact samples in slip (mode 2) of a run of ``scene`` at ``dt``."""
    traj = simulate(scene.with_(dt=dt), model=at_step(model, scene, dt), monitor=False)
    contact = traj.contact[1:] > 0.5
    return float(np.sum(traj.mode[1:] == 2) / max(np.sum(contact), 1))


def leg_reversals(traj) -> tuple:
    """Per leg, the steps whose stroke change has the other sign than the previous step's,
    both in contact: one per turning point of the stroke (a branch switch)."""
    change = np.sign(np.diff(np.asarray(traj.stroke), axis=0))
    change *= np.asarray(traj.contact)[1:] > 0.5
    return tuple(int(n) for n in np.sum(change[1:] * change[:-1] < 0, axis=0))


def reversals(model, scene, dts=REVERSAL_DTS) -> list:
    """Stroke reversals of each leg in contact, at each Δt of ``dts`` (VM runs).

    A reversal is a step whose stroke change has the other sign than the
    previous step's, both in contact: one per turning point of the stroke,
    where an absorber with an unloading branch switches branch. Returns one
    tuple of per-leg counts per Δt.
    """
    out = []
    for dt in dts:
        traj = simulate(scene.with_(dt=dt), model=at_step(model, scene, dt), monitor=False)
        out.append(leg_reversals(traj))
    return out


def _errors(run, ref, ref_m, scene) -> dict:
    m = sve.metrics(run, scene, "max_up")
    return {"trajectory_error": sve.trajectory_error(run, ref),
            "rebound_error": abs(m["rebound_speed"] - ref_m["rebound_speed"]),
            "final_error": final_error(run, ref), "rebound_speed": m["rebound_speed"]}


def run_case(name, variant, scene, progress=print):
    """Rows of one case: its reference check, then every Δt of :data:`DT_GRID`."""
    model = compiled_model(scene, BUILD / scene.name, steps=CHUNK)
    started = time.perf_counter()
    ref = sve.simulate_chunked(model, scene, DT_REF, passes=1)
    check = sve.simulate_chunked(model, scene, DT_CHECK, passes=1)
    ref_m = sve.metrics(ref, scene, "max_up")
    floor = _errors(ref, check, sve.metrics(check, scene, "max_up"), scene)
    floor["rebound_speed"] = ref_m["rebound_speed"]
    slip = slip_fraction(model, scene)
    flips = " / ".join(" ".join(map(str, counts)) for counts in reversals(model, scene))
    progress(f"{name} / {variant}: reference at {DT_REF:g} checked at {DT_CHECK:g} "
             f"({time.perf_counter() - started:.0f} s): traj {floor['trajectory_error']:.1e}, "
             f"rebound {floor['rebound_error']:.1e} m/s, final {floor['final_error']:.1e}; "
             f"slip fraction {slip:.2f}; stroke reversals per leg at "
             f"{' / '.join(f'{d:g}' for d in REVERSAL_DTS)} s: {flips}")
    rows = [{"scene": name, "variant": variant, "slip": scene.slip, "events": scene.events,
             "kind": "reference check",
             "dt": DT_REF,
             "status": "ok", **floor, "slip_fraction": slip, "reversals": flips}]
    for dt in DT_GRID:
        run = sve.simulate_chunked(model, scene, dt)
        row = {"scene": name, "variant": variant, "slip": scene.slip, "events": scene.events,
               "kind": "run", "dt": dt,
               "status": "ok" if run.finite() else "non-finite",
               "cpu_per_sim_second": run.info["cpu"] / run.info["sim_seconds"]}
        if row["status"] == "ok":
            row.update(_errors(run, ref, ref_m, scene))
        rows.append(row)
        progress(f"  dt={dt:<7g} traj {row.get('trajectory_error', np.nan):.2e} "
                 f"rebound {row.get('rebound_error', np.nan):.2e} "
                 f"final {row.get('final_error', np.nan):.2e}")
    return rows


def orders(rows):
    """Fitted order (order, Δt range, points) of every (scene, variant) and error."""
    out = []
    cases = [(r["scene"], r["variant"]) for r in rows if r["kind"] == "reference check"]
    for scene, variant in cases:
        sel = [r for r in rows if (r["scene"], r["variant"]) == (scene, variant)
               and r["kind"] == "run" and r["status"] == "ok"]
        floor = next(r for r in rows if (r["scene"], r["variant"]) == (scene, variant)
                     and r["kind"] == "reference check")
        entry = {"scene": scene, "variant": variant, "slip_fraction": floor["slip_fraction"],
                 "reversals": floor["reversals"]}
        for key in ERROR_KEYS:
            if key not in floor:
                entry[key] = (float("nan"), (), 0)
                continue
            entry[key] = sve.convergence_order([r["dt"] for r in sel], [r[key] for r in sel],
                                               floor=floor[key], dt_max=max(DT_GRID))
        out.append(entry)
    return out


def _fmt(x, spec=".2e"):
    return "—" if x is None or not np.isfinite(x) else format(x, spec)


def write_csv(rows, path):
    """Write the rows (dicts) with :data:`COLUMNS` as header; missing numbers are empty."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(COLUMNS)
        for row in rows:
            writer.writerow([csv_cell(row.get(c)) for c in COLUMNS])


STYLE = {"clean switch": ("tab:purple", "P"), "all events": ("k", "o"), "elastic": ("tab:blue", "s"), "stick": ("tab:orange", "^"),
         "flat": ("tab:green", "v"), "none": ("tab:red", "D")}
#: Line style and filled marker of each rule suffix of a case label.
LINES = {"": ("-", True), " (midpoint)": ("--", False), " (midpoint, branch)": (":", True)}
PANELS = (("lander_slope", "trajectory_error", "lander, 10° slope: trajectory error (relative)"),
          ("lander_slope", "rebound_error", "lander, 10° slope: rebound error (m/s)"),
          ("lander_hop", "final_error", "lander with a hop: final-state error at 0.6 s"),
          ("switch control", "final_error",
           "clean switch (level ground, kicked down): final-state error at 0.07 s"))


def plot(rows, fits, path):
    """Trajectory and rebound error of the lander variants, final-state error of the hop."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 2, figsize=(15, 13))
    axes = axes.ravel()
    for ax, (scene, key, title) in zip(axes, PANELS):
        # guide slopes over the finest decade of the panel's grid, under the data
        finest = min((r["dt"] for r in rows if r["scene"] == scene and r["kind"] == "run"),
                     default=min(DT_GRID))
        dts = np.array([finest, 10 * finest])
        anchors = []
        for fit in (f for f in fits if f["scene"] == scene):
            sel = [r for r in rows if (r["scene"], r["variant"]) == (scene, fit["variant"])
                   and r["kind"] == "run" and r["status"] == "ok"]
            base = fit["variant"].split(" (")[0]
            colour, marker = STYLE[base]
            rule = fit["variant"][len(base):]
            line, face = LINES[rule]
            order = fit[key][0]
            label = fit["variant"] + (f" (order {order:.2f})" if np.isfinite(order) else "")
            ax.plot([r["dt"] for r in sel], [r[key] for r in sel], line, marker=marker,
                    color=colour, ms=5, lw=1.6 if rule.endswith("branch)") else 1.2,
                    mfc=colour if face else "none", label=label)
            anchors += [r[key] for r in sel if r["dt"] == finest]
        anchor = 0.3 * min(anchors, default=1.0)
        for p, ls in ((1, ":"), (2, "-.")):
            ax.plot(dts, anchor * (dts / dts[0]) ** p, ls, color="grey", lw=1.0,
                    label=f"slope {p}")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("Δt (s)")
        ax.set_title(title, fontsize=10)
        ax.grid(True, which="major", alpha=0.3)
        ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.1), ncol=2)
    fig.suptitle("Event-order study: implicit contact step, Verlet body step; each variant "
                 "removes some of the lander's events (none: all three)\n"
                 "solid: default; dashed, open markers: midpoint slip rule; dotted: midpoint "
                 "and events = 'branch' (the kick at the located branch switch)", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _fmt_order(entry):
    order, _, n = entry
    return "—" if not np.isfinite(order) else f"{order:.2f} ({n} pts)"


def cost_ratios(rows):
    """(scene, variant, ratio to the midpoint case, ratio to the default case) per branch case.

    Ratios of CPU per simulated second at equal Δt, median over :data:`DT_GRID`.
    """
    def cost(scene, variant):
        return {r["dt"]: r["cpu_per_sim_second"] for r in rows
                if (r["scene"], r["variant"]) == (scene, variant) and r["kind"] == "run"
                and r.get("cpu_per_sim_second")}

    out = []
    for scene, variant in sorted({(r["scene"], r["variant"]) for r in rows
                                  if r.get("events") == "branch" and r.get("cpu_per_sim_second")}):
        mine = cost(scene, variant)
        base = variant.split(" (")[0]
        ratios = []
        for other in (case_label(base, "midpoint"), base):
            theirs = cost(scene, other)
            common = sorted(set(mine) & set(theirs))
            ratios.append(float(np.median([mine[d] / theirs[d] for d in common]))
                          if common else float("nan"))
        out.append((scene, variant, *ratios))
    return out


def report_text(rows, fits, seconds):
    """The section "Events: measured" of the docs."""
    lines = [f"Produced by `python studies/event_order.py` in {seconds / 60:.1f} min; data in "
             "`figures/event_order.csv`, plot `figures/event_order.png`. Implicit contact step, "
             f"compiled C; Δt grid {', '.join(f'{d:g}' for d in DT_GRID)} s; reference at "
             f"Δt = {DT_REF:g} s checked against {DT_CHECK:g} s. The switch control "
             "(`switch_control()`: every leg turns once onto its unloading branch, no chatter) "
             f"runs on the VM at Δt {', '.join(f'{d:g}' for d in SWITCH_DTS)} s against "
             f"{SWITCH_REF[0]:g} s checked against {SWITCH_REF[1]:g} s.", "",
             "![event order](../figures/event_order.png)", "",
             "Fitted orders (least squares over the grid, errors above 10× the reference's "
             "own); slip: share of the contact samples in slip at "
             f"Δt = {SLIP_DT:g} s; reversals: each leg's stroke reversals in contact at "
             f"Δt = {' / '.join(f'{d:g}' for d in REVERSAL_DTS)} s (one per turning point; "
             "growing as 1/Δt where the leg chatters between its branches):", "",
             "| scene | variant | slip | trajectory | rebound | final state | reversals |",
             "|---|---|---:|---|---|---|---|"]
    for f in fits:
        lines.append(f"| {f['scene']} | {f['variant']} | {f['slip_fraction']:.0%} | "
                     f"{_fmt_order(f['trajectory_error'])} | {_fmt_order(f['rebound_error'])} | "
                     f"{_fmt_order(f['final_error'])} | {f['reversals']} |")
    lines += ["", "Cost of `events = \"branch\"` (compiled, this run): CPU per simulated second "
              "over that of the same variant with the midpoint rule alone and with the default "
              "step, median over the grid:", "",
              "| scene | variant | against midpoint | against default |", "|---|---|---:|---:|"]
    lines += [f"| {scene} | {variant} | {a:.2f} | {b:.2f} |"
              for scene, variant, a, b in cost_ratios(rows)]
    lines += ["", "Errors at each Δt (trajectory and final state relative, rebound in m/s; "
              "cost: CPU s per simulated second, compiled, measured in this one run on a "
              "shared machine):", "",
              "| scene | variant | row | Δt (s) | trajectory | rebound | final state | cost |",
              "|---|---|---|---:|---:|---:|---:|---:|"]
    for r in rows:
        lines.append(f"| {r['scene']} | {r['variant']} | {r['kind']} | {r['dt']:g} | "
                     f"{_fmt(r.get('trajectory_error'))} | {_fmt(r.get('rebound_error'))} | "
                     f"{_fmt(r.get('final_error'))} | "
                     f"{_fmt(r.get('cpu_per_sim_second'), '.3g')} |")
    lines += ["", "Reference-check rows: the errors of the reference against its check "
              "(its own error estimate)."]
    return "\n".join(lines)


#: Controls (no touchdown, no branch switch): the lander with a linear absorber
#: (1e5 N/m) on a level plane, started at rest on its feet
#: (``equilibrium_state``) with a velocity kick, run for CONTROL_DURATION on the
#: VM against a run at CONTROL_DT_REF. Name: (μ, velocity kick (m/s, world),
#: angular velocity kick (rad/s, body axes)). The first bounces and rocks:
#: its feet lift off and land one by one and slip only briefly (kicked only
#: upwards or only rocked, it converges at second order: the tests); the
#: second slides (μ = 0.1) along x, its splayed feet slipping along paths
#: that turn; the third slides and turns.
CONTROLS = {"sticks, bounces and rocks": (2.0, (0.0, 0.0, 0.2), (0.3, 0.0, 0.0)),
            "slides": (0.1, (0.3, 0.0, 0.0), (0.0, 0.0, 0.0)),
            "slides and turns": (0.1, (0.3, 0.0, 0.0), (0.0, 0.0, 1.0))}
#: Stiffness of the controls' linear absorber (N/m): the crushable curve's
#: initial slope, without its plateau and unloading branch.
CONTROL_STIFFNESS = 1e5
CONTROL_DURATION = 0.3
CONTROL_DT_REF = 1e-5
CONTROL_DTS = (2e-3, 1e-3, 5e-4, 2.5e-4, 1e-4)
#: Length of the step that settles a control's start (s; :func:`settled`):
#: at the 0.3 m/s kick the body moves 3e-10 m and its velocity changes by
#: ~1e-8 m/s, below every error measured, while each foot makes the
#: instantaneous slip that brings a force outside the friction cone onto it.
SETTLE_DT = 1e-9
#: Starts of the controls: ``equilibrium_state`` as built, and settled.
STARTS = ("as built", "settled")


def settled(model, x0, p=None):
    """The state after one step of :data:`SETTLE_DT` from ``x0``: the feet on the cone.

    ``equilibrium_state`` holds every foot where it lands with the force of a
    foot that sticks; below the legs' |P_τ|/N (0.24 at rest on level ground)
    those forces lie outside the friction cone (1.4), and the massless feet
    slip at t = 0⁺ by a finite amount. From such a start the first half kick
    of every run uses forces that its contact step then discards: an error
    h/2·ΔF/m once, first order in Δt whatever the slip rule. After this step
    the stored forces are those of the settled feet.

    Parameters
    ----------
    model : StepModel
    x0 : ndarray, shape (nx,)
    p : ndarray, shape (np,), optional
        Default the scene's values.
    """
    p = model.default_p if p is None else p
    return np.asarray(model.step(x0, p, SETTLE_DT)[0], dtype=float).ravel()


def control_scene(mu, kick_v, kick_w, duration=CONTROL_DURATION, name="control"):
    """A control: (Scene, x0) of the lander at rest on its linear legs on level ground, kicked.

    Parameters
    ----------
    mu : float
        Friction coefficient.
    kick_v : sequence of 3 float
        Velocity added to the centre of mass at rest (m/s, world).
    kick_w : sequence of 3 float
        Angular velocity added (rad/s, body axes).
    """
    data = read_toml(STUDIES / "lander_slope.toml")
    data["legs"]["S"] = {"type": "linear", "stiffness": CONTROL_STIFFNESS}
    data["obstacle"][0]["angle"] = 0.0
    data["scene"]["mu"] = float(mu)
    scene = scene_from_dict(data, f"control:{name}").with_(duration=duration)
    x0 = equilibrium_state(scene)
    xl = state_layout(len(scene.legs))
    x0[xl.slice("velocity")] += np.asarray(kick_v, dtype=float)
    x0[xl.slice("angular_velocity")] += np.asarray(kick_w, dtype=float)
    return scene, x0


#: The clean branch switch (:func:`switch_control`): the hop scene's lander on
#: level ground at rest on its feet, kicked down at 1 m/s and rocked at
#: 0.3 rad/s, μ = 2: every leg crushes, turns once (one switch to the 1.5 kN
#: spring-back, which lifts the body: no chatter) and is still in contact at
#: the end. Kick (m/s, world), rocking (rad/s, body), μ, duration (s).
SWITCH_KICK = ((0.0, 0.0, -1.0), (0.3, 0.0, 0.0), 2.0, 0.07)


def switch_control(events="none", slip="midpoint"):
    """(Scene, x0) of the clean branch switch :data:`SWITCH_KICK`, with ``events``."""
    kick_v, kick_w, mu, duration = SWITCH_KICK
    data = read_toml(STUDIES / "lander_hop.toml")
    data["obstacle"][0]["angle"] = 0.0
    data["scene"].update(mu=mu, slip=slip, events=events)
    scene = scene_from_dict(data, f"switch control:{events}").with_(duration=duration)
    x0 = equilibrium_state(scene)
    xl = state_layout(len(scene.legs))
    x0[xl.slice("velocity")] += np.asarray(kick_v, dtype=float)
    x0[xl.slice("angular_velocity")] += np.asarray(kick_w, dtype=float)
    return scene, x0


#: Δt of the switch control's fit (s), and its reference and check (VM runs).
SWITCH_DTS = (2e-3, 1e-3, 5e-4, 2.5e-4, 1.25e-4)
SWITCH_REF = (1e-5, 5e-6)


def switch_case(events, progress=print):
    """Rows of the clean switch (:func:`switch_control`) with ``events``: final-state error."""
    scene, x0 = switch_control(events)
    model = build_model(scene)
    _, ref = final_state(scene, model, x0, SWITCH_REF[0])
    _, check = final_state(scene, model, x0, SWITCH_REF[1])
    variant = case_label("clean switch", scene.slip, events)
    base = {"scene": "switch control", "variant": variant, "slip": scene.slip, "events": events}
    rows = [{**base, "kind": "reference check", "dt": SWITCH_REF[0], "status": "ok",
             "final_error": final_error(ref, check), "slip_fraction": 0.0}]
    flips = {}
    for dt in SWITCH_DTS:
        _, run = final_state(scene, model, x0, dt)
        rows.append({**base, "kind": "run", "dt": dt, "status": "ok",
                     "final_error": final_error(run, ref)})
        flips[dt] = " ".join(map(str, leg_reversals(run)))
    rows[0]["reversals"] = " / ".join(flips[dt] for dt in REVERSAL_DTS)
    progress(f"switch control / {variant}: final-state errors "
             + " ".join(f"{r['final_error']:.2e}" for r in rows[1:]))
    return rows


def final_state(scene, model, x0, dt):
    """Final centre-of-mass position and velocity (6,), m and m/s, of a VM run at ``dt``."""
    traj = simulate(scene.with_(dt=dt), model=at_step(model, scene, dt), x0=x0, monitor=False)
    return np.concatenate([traj.position[-1], traj.velocity[-1]]), traj


def controls(progress=print):
    """Final-state errors of the control runs (see :data:`CONTROLS`), VM.

    Every control runs from each start of :data:`STARTS` with each slip rule
    of :data:`SLIP_RULES`; the control that sticks has no force outside the
    cone to settle and runs from its start as built only.
    """
    rows = []
    for name, (mu, kick_v, kick_w) in CONTROLS.items():
        for rule in SLIP_RULES:
            scene, x_built = control_scene(mu, kick_v, kick_w, name=name)
            scene = scene.with_(slip=rule)
            model = build_model(scene)
            for start in STARTS if mu < STICK_MU else STARTS[:1]:
                x0 = settled(model, x_built) if start == "settled" else x_built
                ref, _ = final_state(scene, model, x0, CONTROL_DT_REF)
                errs = []
                for dt in CONTROL_DTS:
                    state, traj = final_state(scene, model, x0, dt)
                    errs.append(float(np.linalg.norm(state - ref)))
                slip = float(np.mean(traj.mode[1:] == 2))
                order = sve.convergence_order(CONTROL_DTS, errs, dt_max=max(CONTROL_DTS))[0]
                rows.append({"control": name, "mu": mu, "start": start, "rule": rule,
                             "errors": errs, "order": order, "slip": slip})
                progress(f"control {name!r}, {start}, {rule}: errors "
                         f"{['%.2e' % e for e in errs]}, order {order:.2f}, slip fraction "
                         f"{slip:.2f}")
    return rows


def controls_text(rows):
    """The section "Events: controls" of the docs."""
    lines = ["Control runs (`python studies/event_order.py --controls`): the lander with a "
             f"linear absorber ({CONTROL_STIFFNESS:g} N/m) on a level plane, started at rest on "
             f"its feet with a velocity kick, {CONTROL_DURATION:g} s on the VM; error of the "
             "final position and velocity (one 6-vector, m and m/s) against "
             f"Δt = {CONTROL_DT_REF:g} s. Start: `equilibrium_state` as built (with μ = 0.1 "
             "its stored forces lie outside the friction cone), or settled (one step of "
             f"{SETTLE_DT:g} s: the feet on the cone, `settled()`).", "",
             "| control | μ | start | slip rule | "
             + " | ".join(f"Δt = {d:g}" for d in CONTROL_DTS) + " | order | slipping samples |",
             "|---|---:|---|---|" + "---:|" * (len(CONTROL_DTS) + 2)]
    for r in rows:
        lines.append(f"| {r['control']} | {r['mu']:g} | {r['start']} | {r['rule']} | "
                     + " | ".join(f"{e:.2e}" for e in r["errors"])
                     + f" | {r['order']:.2f} | {r['slip']:.2f} |")
    return "\n".join(lines)


#: Interleaved timing of the located switch (``--cost``): Δt (s) and rounds;
#: each round runs the default, the midpoint and the midpoint + branch case of
#: a variant once, and the fastest of the rounds counts, so that the load of
#: the shared machine falls on all three alike.
COST_DT = 1e-4
COST_ROUNDS = 7


def cost_check(progress=print):
    """Best-of-rounds CPU per simulated second of each branch case and its two peers."""
    cases = {(name, label): scene for name, label, _, scene in scenes()}
    out = []
    for name, label in sorted(k for k, scene in cases.items() if scene.events == "branch"):
        base = label.split(" (")[0]
        labels = (base, case_label(base, "midpoint"), label)
        models = {lab: compiled_model(cases[(name, lab)], BUILD / cases[(name, lab)].name,
                                      steps=CHUNK) for lab in labels}
        best = dict.fromkeys(labels, float("inf"))
        for _ in range(COST_ROUNDS):
            for lab in labels:
                run = sve.simulate_chunked(models[lab], cases[(name, lab)], COST_DT, passes=1)
                best[lab] = min(best[lab], run.info["cpu"] / run.info["sim_seconds"])
        out.append((name, base, *(best[lab] for lab in labels)))
        progress(f"{name} / {base}: " + ", ".join(f"{lab} {best[lab]:.3g}" for lab in labels))
    return out


def cost_text(rows):
    """The section "Events: cost" of the docs."""
    lines = ["Interleaved timing (`python studies/event_order.py --cost`): compiled C, "
             f"Δt = {COST_DT:g} s, CPU s per simulated second, the fastest of {COST_ROUNDS} "
             "rounds, each round running the three cases of a variant one after the other. "
             "The elastic variant has no unloading branch: its midpoint and midpoint + branch "
             "steps are the same graph, and their ratio is the scatter of the timing.", "",
             "| scene | variant | default | midpoint | midpoint + branch | "
             "branch / midpoint | branch / default |", "|---|---|---:|---:|---:|---:|---:|"]
    for name, base, default, midpoint, branch in rows:
        lines.append(f"| {name} | {base} | {default:.3g} | {midpoint:.3g} | {branch:.3g} | "
                     f"{branch / midpoint:.2f} | {branch / default:.2f} |")
    return "\n".join(lines)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--only", default=None, help="run only the cases whose scene name or "
                        "variant contains this text (no output is written)")
    parser.add_argument("--controls", action="store_true",
                        help="run only the control runs and write their section")
    parser.add_argument("--cost", action="store_true",
                        help="run only the interleaved timing of the located switch and write "
                        "its section")
    args = parser.parse_args(argv)
    if args.cost:
        report.write_section(DOC, "Events: cost", cost_text(cost_check()))
        return
    if args.controls:
        report.write_section(DOC, "Events: controls", controls_text(controls()))
        return
    started = time.perf_counter()
    rows = []
    for name, variant, _, scene in scenes():
        if args.only and args.only not in name and args.only not in variant:
            continue
        rows += run_case(name, variant, scene)
    if not args.only or args.only in "switch control":
        for events in ("none", "branch"):
            rows += switch_case(events)
    fits = orders(rows)
    for f in fits:
        print(f"{f['scene']:>12} {f['variant']:>10}: traj {_fmt_order(f['trajectory_error'])}, "
              f"rebound {_fmt_order(f['rebound_error'])}, final {_fmt_order(f['final_error'])}")
    if args.only:
        return
    write_csv(rows, FIGURES / "event_order.csv")
    plot(rows, fits, FIGURES / "event_order.png")
    report.write_section(DOC, "Events: measured",
                         report_text(rows, fits, time.perf_counter() - started))


if __name__ == "__main__":
    main()
