"""A leg's force–stroke loop over two touchdowns, under the printed law and the memory law.

Question (docs/absorbers.md, "A loop over two touchdowns"): what path does an
axial absorber take in the (stroke, force) plane when its lander lands, springs
back, leaves the ground and lands again? Two scenes, each rolled out at
Δt = 1 ms and 0.25 ms; for the leg that strokes most, its axial force
S = −P·e_S (compression positive) is drawn against its compression −δ_S over
the element's loading and unloading curves:

- the hopping lander, whose absorbers spring back on a strong unloading curve,
  under the printed law P(δ, sign δ′) (``studies/lander_hop.toml``) and on the
  memory law with dampers of τ = 10 ms (``studies/lander_hop_memory.toml``);
- a one-shot honeycomb leg on the Moon that hops on the energy of its elastic
  line and lands a second time (``studies/honeycomb_bounce.toml``).

What to see: under the printed law the force jumps between the two curves at
every turn of the stroke rate (the vertical segments). Under the memory law it
leaves the loading curve along the elastic line of slope k_e until it meets the
unloading curve; the honeycomb leg unloads along its elastic line to zero,
leaves the ground, and on the second landing reloads along the same line from
the stroke it kept, towards the crush force, instead of crushing again from the
top of the curve.

Output: ``figures/force_stroke_loop.png`` and, per law, the crushed set after
each touchdown, the largest force jump between steps, and the force the stroke
grew below. Run: ``python studies/force_stroke_loop.py``.
"""
from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from absorbers import rollout  # noqa: E402  (studies/absorbers.py, beside this file)
from symcushion.layout.vectors import output_layout, state_layout  # noqa: E402
from symcushion.run.output_files import replacing  # noqa: E402
from symcushion.model.scene import load_scene  # noqa: E402

HERE = Path(__file__).resolve().parent
FIGURE = HERE.parent / "figures" / "force_stroke_loop.png"
#: (title, scene file, laws to draw): the hopping lander's spring-back absorber
#: under both laws, and a honeycomb leg that lands twice on the memory law.
PANELS = (("hopping lander, printed law P(δ, sign δ′)", HERE / "lander_hop.toml"),
          ("hopping lander, memory law, τ = 10 ms", HERE / "lander_hop_memory.toml"),
          ("honeycomb leg landing twice (Moon), memory law", HERE / "honeycomb_bounce.toml"))
STEPS = (1e-3, 2.5e-4)
#: Shortest run (s): long enough for the hopping lander's second landing on either law.
DURATION = 1.0


def leg_loop(scene, dt):
    """Per leg and step: compression −δ_S (m), axial force S (N), set (m), contact flag."""
    X, Y = rollout(scene, dt)
    n = len(scene.legs)
    yl, xl = output_layout(n), state_layout(n)
    axial = -np.einsum("jkt,jkt->jt", yl.legs(Y, "force"), yl.legs(Y, "axis"))
    return (-yl.legs(Y, "stroke"), axial, -xl.legs(X, "stroke_set"),
            yl.legs(Y, "in_contact") > 0.5)


def contact_phases(contact):
    """(first, last) step of each contact phase of one leg."""
    edges = np.diff(np.r_[0, contact.astype(int), 0])
    return list(zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1) - 1))


def draw_curves(ax, curve, top):
    """The element's loading and unloading curves, compression positive."""
    c = np.linspace(0.0, top, 400)
    ax.plot(1e3 * c, -curve.force(-c, -np.ones_like(c)), color="0.6", lw=1,
            label="loading curve")
    if curve.unloading is not None:
        ax.plot(1e3 * c, -curve.force(-c, np.ones_like(c)), color="0.6", lw=1, ls="--",
                label="unloading curve")


def report(scene, j, comp, force, crushed, contact):
    """Print the leg's peaks, its largest force jump in contact, and per touchdown its peak
    force and (one-shot elements) its crushed set."""
    both = contact[1:] & contact[:-1]          # steps in contact at both ends
    jump = np.max(np.abs(np.diff(force))[both])
    print(f"{scene.name}: leg {j}, peak compression {1e3 * comp.max():.1f} mm, largest "
          f"force jump between contact steps {jump:.0f} N")
    for k, (a, b) in enumerate(contact_phases(contact)):
        line = (f"  touchdown {k + 1}: t = {a * scene.dt:.3f} … {(b + 1) * scene.dt:.3f} s, "
                f"peak force {force[a:b + 1].max():.0f} N")
        if scene.hysteresis == "memory" and scene.legs[j].elements[0].curve.unloading is None:
            line += f", crushed set at its end {1e3 * crushed[b]:.2f} mm"
        print(line)


def main():
    fig, axes = plt.subplots(1, 3, figsize=(14, 4.4))
    for ax, (title, path) in zip(axes, PANELS):
        scene = load_scene(path)
        scene = scene.with_(duration=max(scene.duration, DURATION))
        curve = scene.legs[0].elements[0].curve
        runs = {dt: leg_loop(scene, dt) for dt in STEPS}
        comp, force, crushed, contact = runs[STEPS[0]]
        j = int(np.argmax(comp.max(axis=1)))
        draw_curves(ax, curve, 1.15 * comp[j].max())
        for k, (a, b) in enumerate(contact_phases(contact[j])):
            ax.plot(1e3 * comp[j, a:b + 1], force[j, a:b + 1], color=f"C{3 * k}", lw=1.4,
                    label=f"leg {j}, touchdown {k + 1}, Δt = {1e3 * STEPS[0]:g} ms")
        c, f, _, _ = runs[STEPS[1]]
        ax.plot(1e3 * c[j], f[j], ":", color="k", lw=0.8, label=f"Δt = {1e3 * STEPS[1]:g} ms")
        ax.set_title(title, fontsize=10)
        ax.set_xlabel("compression −δ_S [mm]")
        ax.axhline(0, color="k", lw=0.5)
        ax.legend(fontsize=7, loc="lower right")
        report(scene, j, comp[j], force[j], crushed[j], contact[j])
    axes[0].set_ylabel("axial force S [N], compression positive")
    fig.suptitle("The axial absorber of the leg that strokes most, over its touchdowns", fontsize=11)
    fig.tight_layout()
    with replacing(FIGURE) as tmp:          # no half-written figure on an interrupt
        fig.savefig(tmp, dpi=130)
    print(f"wrote {FIGURE}")


if __name__ == "__main__":
    main()
