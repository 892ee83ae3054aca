"""What the regularised branch switch holds where a foot slides: the stroke, or the rate of (2.1)?

Owns the runs of ``--held``: the lander of ``studies/lander_slope.toml``
with its absorbers' branch switch regularised (``limits.regularized_scene``)
at several widths, and, over the contact samples where a leg's axial force
lies strictly between its two curves, two rates: the stroke's own rate
δ_S′ and the rate that (2.1) gives the branch test, the hinge's approach
to the foot's world point along the strut, −V_h·e_S (V_h the hinge's
velocity). The two are the same while the foot sticks; where it slides
they differ by the foot's velocity along e_S, and whichever stays near
zero is the one the regularised limit holds. It must not fit orders or
write files (``main`` writes its section).

Why: a lock for a sliding foot has to hold the quantity this limit holds.
(2.1) selects the branch by sign(V·e_S), the stuck-foot chord of the strut
(``symcushion.legs.strut``), so its closure holds that rate, and a sliding
foot's stroke moves with the foot.
"""
from __future__ import annotations

import numpy as np

from .limits import _trajectory, regularized_scene

#: A sample counts as held between the curves where the loading curve's weight
#: σ = (|S| − |S_u|)/(|S_l| − |S_u|) lies in this band (|S| the axial force).
SIGMA_BAND = (0.02, 0.98)
#: A foot slower than this over an interval (m/s) is stuck in it; faster, it slides.
#: A stuck foot moves by round-off only (about 1e-11 m/s in these runs).
FOOT_STILL = 1e-6
#: A gap between the curves below this (N) has no interior: such samples are skipped.
MIN_GAP = 1.0
#: (variant, rate_width w in m²/s, Δt in s) of the runs. The finest needs
#: 2.7e7 steps; its trajectory is thinned to :data:`KEEP_ROWS` rows, so its
#: rates are means over the kept rows' spacing.
HELD_RUNS = (("flat", 1e-5, 1e-6), ("flat", 1e-6, 3e-7),
             ("all events", 1e-5, 1e-6), ("all events", 1e-6, 3e-7),
             ("all events", 1e-6, 1e-7), ("all events", 1e-7, 3e-8))
#: Rows kept of each run's trajectory (``simulate(keep_rows=...)``).
KEEP_ROWS = 200_000


def interior_rates(traj, leg) -> dict:
    """The stroke rate and the (2.1) rate over a run's samples held between the curves.

    Parameters
    ----------
    traj : Trajectory
        A run of a scene whose legs are all ``leg`` (rows may be thinned).
    leg : HingedStrut
        The legs' strut: its axial curve gives S_l(δ) and S_u(δ).

    Returns
    -------
    dict
        ``slide`` and ``stick``, each a dict with ``samples`` (intervals between
        two kept rows, both in contact, whose force at the start lies in
        :data:`SIGMA_BAND`; stuck where the foot moves slower than
        :data:`FOOT_STILL`), and the medians over them of
        ``rate_21`` (|V_h·e_S|, m/s), ``stroke_rate`` (|δ_S′|, m/s) and
        ``foot_rate`` (|r′·e_S|, m/s); NaN without samples.
    """
    curve = next(e for e in leg.elements if e.name == "S").curve
    t = np.asarray(traj.t, dtype=float)
    dt = np.diff(t)
    out = {name: dict(samples=0, rate_21=[], stroke_rate=[], foot_rate=[])
           for name in ("slide", "stick")}
    for j in range(np.asarray(traj.stroke).shape[1]):
        d, e_S = np.asarray(traj.stroke[:, j]), np.asarray(traj.axis[:, j])
        foot, force = np.asarray(traj.foot[:, j]), np.asarray(traj.force[:, j])
        contact = np.asarray(traj.contact[:, j]) > 0.5
        S = np.abs(np.einsum("ti,ti->t", force, e_S))
        # the curve's rate argument only carries the sign of x·ẋ: ≥ 0 loads, < 0 unloads
        grows = np.where(d < 0, -1.0, 1.0)
        S_l = np.abs(np.asarray(curve.force(d, grows), dtype=float)).ravel()
        S_u = np.abs(np.asarray(curve.force(d, -grows), dtype=float)).ravel()
        gap = S_l - S_u
        sigma = np.where(np.abs(gap) > MIN_GAP, (S - S_u) / np.where(gap == 0, 1.0, gap), np.nan)
        hinge = foot - (leg.length + d)[:, None] * e_S
        v_h = np.diff(hinge, axis=0) / dt[:, None]
        v_f = np.diff(foot, axis=0) / dt[:, None]
        rate_21 = np.abs(np.einsum("ti,ti->t", v_h, e_S[:-1]))
        foot_rate = np.abs(np.einsum("ti,ti->t", v_f, e_S[:-1]))
        stroke_rate = np.abs(np.diff(d) / dt)
        held = (contact[:-1] & contact[1:] & (sigma[:-1] > SIGMA_BAND[0])
                & (sigma[:-1] < SIGMA_BAND[1]))
        still = np.linalg.norm(v_f, axis=1) < FOOT_STILL
        for name, m in (("slide", held & ~still), ("stick", held & still)):
            out[name]["samples"] += int(m.sum())
            out[name]["rate_21"].append(rate_21[m])
            out[name]["stroke_rate"].append(stroke_rate[m])
            out[name]["foot_rate"].append(foot_rate[m])
    for entry in out.values():
        for key in ("rate_21", "stroke_rate", "foot_rate"):
            values = np.concatenate(entry[key])
            entry[key] = float(np.median(values)) if values.size else float("nan")
    return out


def held_runs(progress=print) -> list:
    """One row per run of :data:`HELD_RUNS`: ``variant``, ``rate_width``, ``dt``,
    ``final`` (centre of mass at the end, m, (3,)) and the entries of
    :func:`interior_rates`."""
    rows = []
    for variant, width, dt in HELD_RUNS:
        scene = regularized_scene(variant, width)
        traj = _trajectory(scene, dt, keep_rows=KEEP_ROWS)
        rates = interior_rates(traj, scene.legs[0])
        rows.append(dict(variant=variant, rate_width=width, dt=dt,
                         final=np.asarray(traj.position[-1], dtype=float), **rates))
        progress(f"{variant}, w = {width:g}, dt = {dt:g}: final {np.round(rows[-1]['final'], 5)}; "
                 f"sliding held samples {rates['slide']['samples']}, median (2.1) rate "
                 f"{rates['slide']['rate_21']:.2e}, stroke rate {rates['slide']['stroke_rate']:.2e} m/s")
    return rows


def held_text(rows) -> str:
    """The section "Events: what the regularised switch holds" from :func:`held_runs`."""
    lines = ["Produced by `python studies/event_order.py --held` (compiled C): the lander of "
             "`studies/lander_slope.toml` with its absorbers' branch switch regularised "
             "(`smooth = true`, `rate_width` w; default step). Over the intervals between "
             "kept rows where a leg is in contact and its axial force lies strictly between "
             f"its curves (loading weight σ in ({SIGMA_BAND[0]:g}, {SIGMA_BAND[1]:g})), the "
             "medians of |V_h·e_S| (the hinge's approach to the foot's point along the strut: "
             "the rate whose sign (2.1) takes), of the stroke rate |δ_S′| and of the foot's "
             "rate along the strut |r′·e_S|, for the intervals in which the foot slides and "
             f"those in which it stays (slower than {FOOT_STILL:g} m/s). "
             "Distances are from the last run of each variant.", "",
             "| variant | w (m²/s) | Δt (s) | final centre of mass (m) | from the last run (mm) "
             "| held samples, sliding | (2.1) rate | stroke rate | foot rate "
             "| held samples, stuck | (2.1) rate | stroke rate |",
             "|---|---:|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|"]
    last = {r["variant"]: r["final"] for r in rows}
    for r in rows:
        sl, st = r["slide"], r["stick"]
        lines.append(
            f"| {r['variant']} | {r['rate_width']:g} | {r['dt']:g} | "
            f"({', '.join(f'{x:.5f}' for x in r['final'])}) | "
            f"{1e3 * np.linalg.norm(r['final'] - last[r['variant']]):.2f} | "
            f"{sl['samples']} | {sl['rate_21']:.1e} | {sl['stroke_rate']:.1e} | "
            f"{sl['foot_rate']:.1e} | {st['samples']} | {st['rate_21']:.1e} | "
            f"{st['stroke_rate']:.1e} |")
    return "\n".join(lines)
