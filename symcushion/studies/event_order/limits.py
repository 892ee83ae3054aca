"""The two limits of the 10° lander: the default step and the stroke lock as Δt → 0.

Owns the runs of ``--limits``: the lander of ``studies/lander_slope.toml``
with the default step and with the midpoint rule and the stroke lock, at
Δt from :data:`LIMIT_DTS` down to 1e-6 s, and what each run says about
where it converges: the final position of the centre of mass, the slipping
share of the contact samples, the share of the stroke reversals at which
the foot slips, and each foot's sliding path. It must not fit orders or
write files (``main`` writes its section).

Why: the two schemes converge to final positions a centimetre apart. The
default step takes the branch of each step from the sign of its stroke
change, so a leg whose absorber the model holds between its curves
alternates between them step after step (docs/speed-vs-error.md, "The
stroke lock on the lander"); its foot then sees a force that jumps by the
gap between the curves at every step, however small the step, and
Coulomb's law responds to each half of that alternation rather than to its
mean. These runs measure where each scheme converges, which legs keep
alternating, and how far the feet slide on the way.
"""
from __future__ import annotations

import numpy as np

from symcushion.codegen import compiled_model
from symcushion.simulate import simulate

from .cases import BUILD, CHUNK, case_label, scenes
from .runs import at_step, reversal_steps

#: Δt of the limit runs (s): two decades below the study's grid and down to
#: its reference's check (1e-6 s: 800,000 steps, about 30 s compiled).
LIMIT_DTS = (1e-4, 1e-5, 1e-6)
#: (slip rule, event rule) of the two schemes compared: the default step and
#: the scheme with the stroke lock.
LIMIT_SCHEMES = (("backward", "none"), ("midpoint", "lock"))
#: The mode of a sliding foot in a trajectory (``Trajectory.mode``).
SLIP_MODE = 2


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


def limits(progress=print) -> list:
    """One row per scheme of :data:`LIMIT_SCHEMES` and Δt of :data:`LIMIT_DTS`.

    Each row: ``label``, ``dt``, ``final`` (the centre of mass at the end, m,
    (3,)) and the entries of :func:`slip_at_reversals`.
    """
    slope = {(slip, scene.events): scene for name, label, slip, scene in scenes()
             if name == "lander_slope" and label == case_label("all events", slip, scene.events)}
    rows = []
    for key in LIMIT_SCHEMES:
        scene = slope[key]
        model = compiled_model(scene, BUILD / scene.name, steps=CHUNK)
        for dt in LIMIT_DTS:
            traj = simulate(scene.with_(dt=dt), model=at_step(model, scene, dt), monitor=False)
            row = dict(label=case_label("all events", *key), dt=dt,
                       final=np.asarray(traj.position[-1], dtype=float), **slip_at_reversals(traj))
            progress(f"{row['label']}, dt = {dt:g}: final x {row['final'][0]:.5f} m, slip "
                     f"{row['slip_share']:.3f}, slip at reversals {row['reversal_slip']:.3f}")
            rows.append(row)
    return rows


def limits_text(rows) -> str:
    """The section "Events: two limits on the slope" from the rows of :func:`limits`."""
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
