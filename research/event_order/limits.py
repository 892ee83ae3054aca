"""The limits of the slope lander as Δt → 0: the default step, the stroke lock and a reference.

Owns the runs of ``--limits``: the lander of ``studies/lander_slope.toml``
with the default step and with the midpoint rule and the stroke lock, at
Δt from :data:`LIMIT_DTS` down to 1e-6 s, and what each run says about
where it converges: the final position of the centre of mass, the slipping
share of the contact samples, the share of the stroke reversals at which
the foot slips, and each foot's sliding path (:func:`limit_runs`); and the
reference both are compared with, the same lander with its absorbers'
branch switch regularised and resolved (:func:`oracle`; also for the
three-legged lander that hops, whose held leg meets the friction cone).
It must not fit orders or write files (``main`` writes its section).

Why: the two schemes converge to final positions a centimetre apart. The
default step takes the branch of each step from the sign of its stroke
change, so a leg whose absorber the model holds between its curves
alternates between them step after step (docs/event-order.md, "The
stroke lock on the lander"); its foot then sees a force that jumps by the
gap between the curves at every step, however small the step, and
Coulomb's law responds to each half of that alternation rather than to its
mean. The lock holds such a leg only while its foot sticks. The
regularised switch (``smooth = true`` with a small ``rate_width``), once its
step resolves the blend, holds the rate whose sign (2.1) takes, sliding foot
or not: as the width falls it should tend to the Filippov closure of (2.1),
the motion both schemes approximate (on the 10° lander successive widths
still move it by a few mm down to 1e-7 m²/s: ``held``; how well it is known,
width by width and step by step: ``reference``). Where the foot
sticks that rate is the stroke's; where it slides the stroke moves with the
foot.
"""
from __future__ import annotations

import numpy as np

from symcushion.compiled.codegen import compiled_model
from symcushion.model.scene import read_toml, scene_from_dict
from symcushion.run.driver import simulate

from .cases import BUILD, CHUNK, STUDIES, _variant_data, case_label, scenes
from .runs import at_step, reversal_steps

#: Δt of the limit runs (s): two decades below the study's grid and down to
#: its reference's check (1e-6 s: 800,000 steps, about 30 s compiled).
LIMIT_DTS = (1e-4, 1e-5, 1e-6)
#: (slip rule, event rule) of the two schemes compared: the default step and
#: the scheme with the stroke lock.
LIMIT_SCHEMES = (("backward", "none"), ("midpoint", "lock"))
#: The mode of a sliding foot in a trajectory (``Trajectory.mode``).
SLIP_MODE = 2
#: The reference for the held rate of (2.1): the absorber's branch switch regularised
#: (``smooth = true``, the blend 0.5(1 + tanh(x·ẋ/w)) of its two curves) with
#: these (rate_width w in m²/s, Δt in s). As w → 0 the blend holds the rate
#: of (2.1) at any force between the curves, the Filippov closure, with or
#: without a sliding foot; each w needs a Δt that resolves its blend (the
#: rate's scale w/|x| against the leg's force gap and mass).
ORACLE_RUNS = ((1e-5, 1e-6), (1e-6, 3e-7))
#: Variants compared with that reference: the slope lander's feet that stick,
#: some sliding feet (level ground, μ = 0.4), and the 10° slope; and the
#: three-legged lander that hops (``studies/lander_hop.toml``), whose held leg
#: meets the friction cone three times at about 0.1 s.
ORACLE_VARIANTS = ("stick, flat", "flat", "all events", "hop")
#: The scene file and the lander variant (``cases.VARIANTS``) of each compared variant.
ORACLE_SCENES = {"stick, flat": ("lander_slope", "stick, flat"),
                 "flat": ("lander_slope", "flat"),
                 "all events": ("lander_slope", "all events"),
                 "hop": ("lander_hop", "all events")}
#: Δt of the default step and the lock in that comparison (s): the study's
#: usual step and its reference's.
ORACLE_DTS = (1e-3, 1e-6)
ORACLE_DT = ORACLE_DTS[-1]
#: The sentence that opens the comparison's table.
ORACLE_INTRO = ("The reference for the held rate of (2.1): the same lander with its absorbers' "
                "branch switch regularised (`smooth = true`, the blend 0.5(1 + tanh(x·ẋ/w)) "
                "of the two curves, `rate_width` w; default step), at a Δt that resolves the "
                "blend, against the default step and the lock at 1e-3 and 1e-6 s: the slope "
                "lander's variants, and the three-legged lander that hops "
                "(`studies/lander_hop.toml`, \"hop\"). Distances are from the finest "
                "regularised run of each variant; the two regularised runs' distance is how "
                "well that reference is known.")


def slip_at_reversals(traj) -> dict:
    """Where a run's feet slide: shares and paths, from its trajectory.

    Returns ``slip_share`` (the share of the contact samples in slip),
    ``reversal_slip`` (the share of the stroke reversals, :func:`reversal_steps`,
    whose step ends in slip; NaN without reversals), ``reversals`` (per leg)
    and ``foot_path`` (per leg, m: the length of the foot's path over the
    steps that start and end in contact).
    """
    contact = np.asarray(traj.contact) > 0.5
    slip = np.asarray(traj.mode) == SLIP_MODE
    both = contact[1:] & contact[:-1]
    turns = reversal_steps(traj)
    foot = np.asarray(traj.foot)
    step = np.linalg.norm(np.diff(foot, axis=0), axis=-1)
    return dict(
        slip_share=float(slip[1:][contact[1:]].mean()) if contact[1:].any() else 0.0,
        reversal_slip=float(slip[1:][turns].mean()) if turns.any() else float("nan"),
        reversals=tuple(int(n) for n in turns.sum(axis=0)),
        foot_path=tuple(float(x) for x in np.where(both, step, 0.0).sum(axis=0)),
    )


def limit_runs(progress=print) -> list:
    """One row per scheme of :data:`LIMIT_SCHEMES` and Δt of :data:`LIMIT_DTS`.

    Each row: ``label``, ``dt``, ``final`` (the centre of mass at the end, m,
    (3,)) and the entries of :func:`slip_at_reversals`.
    """
    slope = {(slip, scene.events): scene for name, label, slip, scene in scenes()
             if name == "lander_slope" and label == case_label("all events", slip, scene.events)}
    rows = []
    for key in LIMIT_SCHEMES:
        scene = slope[key]
        for dt in LIMIT_DTS:
            traj = _trajectory(scene, dt)
            row = dict(label=case_label("all events", *key), dt=dt,
                       final=np.asarray(traj.position[-1], dtype=float), **slip_at_reversals(traj))
            progress(f"{row['label']}, dt = {dt:g}: final x {row['final'][0]:.5f} m, slip "
                     f"{row['slip_share']:.3f}, slip at reversals {row['reversal_slip']:.3f}")
            rows.append(row)
    return rows


def regularized_scene(variant: str, rate_width: float, scene: str = "lander_slope"):
    """The lander of ``studies/<scene>.toml`` with the events of ``variant`` removed
    (``cases._variant_data``) and its absorbers' branch switch regularised: ``smooth =
    true`` and ``rate_width`` on the axial element ``S``; default step."""
    data = _variant_data(read_toml(STUDIES / f"{scene}.toml"), variant)
    data["legs"]["S"].update(smooth=True, rate_width=rate_width)
    data["scene"]["name"] = f"{data['scene']['name']}-regularised-{rate_width:g}"
    return scene_from_dict(data, f"{scene}.toml:{variant} (rate_width {rate_width:g})")


def _trajectory(scene, dt, keep_rows=None):
    """A compiled run of ``scene`` at ``dt`` (the build is cached per scene name); with
    ``keep_rows``, its trajectory thinned to about that many rows (``simulate``)."""
    model = compiled_model(scene, BUILD / scene.name, steps=CHUNK)
    return simulate(scene.with_(dt=dt), model=at_step(model, scene, dt), monitor=False,
                    keep_rows=keep_rows)


def oracle(progress=print) -> list:
    """Final centre of mass of the default step, the lock and the regularised switch.

    One row per variant of :data:`ORACLE_VARIANTS` and run: ``variant``,
    ``scheme`` ("default", "lock" or "regularised"), ``rate_width`` (NaN but
    for the regularised runs), ``dt`` and ``final`` (m, (3,)).
    """
    by_label = {(name, label): scene for name, label, _, scene in scenes()}
    rows = []
    for variant in ORACLE_VARIANTS:
        name, case = ORACLE_SCENES[variant]
        runs = [(scheme, np.nan, by_label[name, label], dt) for dt in ORACLE_DTS
                for scheme, label in (("default", case),
                                      ("lock", case_label(case, "midpoint", "lock")))]
        runs += [("regularised", w, regularized_scene(case, w, name), dt)
                 for w, dt in ORACLE_RUNS]
        for scheme, w, scene, dt in runs:
            final = np.asarray(_trajectory(scene, dt).position[-1], dtype=float)
            rows.append(dict(variant=variant, scheme=scheme, rate_width=w, dt=dt, final=final))
            progress(f"{variant} / {scheme}" + (f" (w = {w:g})" if scheme == "regularised" else "")
                     + f", dt = {dt:g}: final {np.round(final, 5)}")
    return rows


def oracle_text(rows) -> str:
    """The table of :func:`oracle`: each run's distance from the finest regularised run."""
    lines = [ORACLE_INTRO, "",
             "| variant | scheme | rate_width (m²/s) | Δt (s) | final centre of mass (m) "
             "| from the regularised reference (mm) |", "|---|---|---:|---:|---|---:|"]
    for variant in ORACLE_VARIANTS:
        mine = [r for r in rows if r["variant"] == variant]
        ref = [r for r in mine if r["scheme"] == "regularised"][-1]["final"]
        for r in mine:
            width = "—" if np.isnan(r["rate_width"]) else f"{r['rate_width']:g}"
            lines.append(f"| {variant} | {r['scheme']} | {width} | {r['dt']:g} | "
                         f"({', '.join(f'{x:.5f}' for x in r['final'])}) | "
                         f"{1e3 * np.linalg.norm(r['final'] - ref):.2f} |")
    return "\n".join(lines)


def limits_text(rows) -> str:
    """The section "Events: two limits on the slope" from the rows of :func:`limit_runs`."""
    finest = {r["label"]: r for r in rows if r["dt"] == min(LIMIT_DTS)}
    lines = ["| scheme | Δt (s) | final centre of mass (m) | from the scheme's 1e-6 s run (mm) "
             "| from the other scheme's 1e-6 s run (mm) | slipping contact samples "
             "| reversals ending in slip | reversals per leg | foot paths (mm) |",
             "|---|---:|---|---:|---:|---:|---:|---|---|"]
    for r in rows:
        own = finest[r["label"]]["final"]
        other = next(f["final"] for label, f in finest.items() if label != r["label"])
        lines.append(
            f"| {r['label']} | {r['dt']:g} | ({', '.join(f'{x:.5f}' for x in r['final'])}) | "
            f"{1e3 * np.linalg.norm(r['final'] - own):.2f} | "
            f"{1e3 * np.linalg.norm(r['final'] - other):.2f} | {r['slip_share']:.1%} | "
            f"{r['reversal_slip']:.1%} | {' '.join(map(str, r['reversals']))} | "
            f"{' '.join(f'{1e3 * x:.1f}' for x in r['foot_path'])} |")
    return ("Produced by `python studies/event_order.py --limits` (compiled C, the "
            "lander of `studies/lander_slope.toml` as committed, \"all events\"): where the "
            "default step and the stroke lock converge as Δt falls to 1e-6 s.\n\n"
            + "\n".join(lines))
