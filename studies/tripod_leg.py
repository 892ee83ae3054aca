"""The inverted-tripod leg: its figure, and how much work a closed foot loop does.

Draws ``figures/tripod_leg.png`` for docs/tripod.md: an Apollo-like leg
(``InvertedTripod``) in side and top view, at rest and with its foot pushed
0.3 m up, and the foot force and element forces along that push and back
(loading, then unloading branches). Measures the work ∮ P·dr around a
circle 2 cm across at a loaded pose, for the tripod and for a hinged strut
(2.1) of the same rest pose, and writes both to ``figures/tripod_leg.json``.

Run: ``python studies/tripod_leg.py``.
"""
from __future__ import annotations

import json
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from symcushion import HingedStrut  # noqa: E402
from symcushion.legs.characteristics import Crushable, GasSpring, Linear, TwoSided  # noqa: E402
from symcushion.legs.tripod import InvertedTripod  # noqa: E402

FIGURES = Path(__file__).resolve().parents[1] / "figures"

#: An Apollo-like leg in body axes (z up, m), as in tests/test_tripod.py.
GEOMETRY = dict(h1=(2.0, 0.0, 1.0), h2=(1.9, 1.0, -0.6), h3=(1.9, -1.0, -0.6),
                foot=(3.6, 0.0, -1.4), outer_length=1.9)
#: Vertical push of the foot for the figure (m), and points along it.
PUSH, PUSH_POINTS = 0.3, 121
#: The loop: radius (m), centre offset from the rest foot (m), trapezoid points.
LOOP_RADIUS, LOOP_OFFSET, LOOP_POINTS = 0.01, (0.03, 0.02, 0.15), 256


def crushing_leg():
    """Crushable primary (unloading nearly free), secondaries crushing both ways."""
    secondary = TwoSided(Crushable(3e6, 1.5e4, 2e4), Crushable(3e6, 1e4, 2e4),
                         unloading=Linear(2e5))
    return InvertedTripod(**GEOMETRY, primary=Crushable(1e6, 2e4, 5e4, unloading=Linear(1e5)),
                          secondary2=secondary, secondary3=secondary)


def elastic_leg():
    """A gas-spring primary and smooth secondaries: an elastic leg, for the loop."""
    secondary = TwoSided(Crushable(3e6, 1.5e4, 2e4), Crushable(2e6, 1e4, 2e4), smooth=True)
    return InvertedTripod(**GEOMETRY, primary=GasSpring(2e5, 5e-3, 2e-3, 1.3),
                          secondary2=secondary, secondary3=secondary)


def hinged_strut():
    """A hinged strut (2.1) with the tripod's rest foot, hinge at h₁."""
    axis = np.subtract(GEOMETRY["foot"], GEOMETRY["h1"])
    return HingedStrut(hinge=GEOMETRY["h1"], e0=axis, en=(0.3, 0.2, -1.0),
                       length=float(np.linalg.norm(axis)), S=Linear(2e5),
                       M_beta=Linear(3e5), M_gamma=Linear(3e5))


def loop_work(force, centre):
    """∮ P·dr (J) around the circle of LOOP_RADIUS about ``centre``, and |P|·perimeter."""
    a = np.array([1.0, 1.0, 0.0]) / np.sqrt(2)
    b = np.array([-0.3, 0.3, 1.0])
    b -= (b @ a) * a
    b /= np.linalg.norm(b)
    work = 0.0
    for t in 2 * np.pi * np.arange(LOOP_POINTS) / LOOP_POINTS:
        r = centre + LOOP_RADIUS * (np.cos(t) * a + np.sin(t) * b)
        work += force(r) @ (LOOP_RADIUS * (-np.sin(t) * a + np.cos(t) * b))
    scale = np.linalg.norm(force(centre)) * 2 * np.pi * LOOP_RADIUS
    return work * 2 * np.pi / LOOP_POINTS, scale


def draw_leg(ax, leg, r, axes, style):
    """The leg projected on the ``axes`` pair (indices into x, y, z)."""
    geo = leg.functions()["tripod_geometry"].call(dict(r=r))
    Q = np.asarray(geo["Q"]).ravel()
    i, j = axes
    line = lambda a, b, **kw: ax.plot([a[i], b[i]], [a[j], b[j]], **kw)  # noqa: E731
    line(leg.h1, Q, lw=5, color=style["outer"], solid_capstyle="butt")
    line(Q, r, lw=2.5, color=style["inner"])
    for h in (leg.h2, leg.h3):
        line(h, Q, lw=1.8, color=style["secondary"])
    ax.plot(*[[p[i] for p in (leg.h1, leg.h2, leg.h3)], [p[j] for p in (leg.h1, leg.h2, leg.h3)]],
            "ks", ms=5)
    ax.plot(Q[i], Q[j], "o", color=style["inner"], ms=5)
    ax.plot(r[i], r[j], "v", color=style["inner"], ms=8)
    return Q


def label_points(ax, leg, Q, axes):
    i, j = axes
    names = dict(h1=leg.h1, h2=leg.h2, Q=Q, foot=leg.rest_foot)
    if axes == (0, 1):
        names["h3"] = leg.h3
    for name, p in names.items():
        ax.annotate(name, (p[i], p[j]), textcoords="offset points", xytext=(5, 4), fontsize=8)


def push(leg):
    """Foot force and element forces along a vertical push and back."""
    up = np.array([0.0, 0.0, 1.0])
    z = np.linspace(0.0, PUSH, PUSH_POINTS)
    rows = []
    for zs, v in ((z, up), (z[::-1], -up)):
        for dz in zs:
            r = leg.rest_foot + dz * up
            rows.append((dz, leg.force(r, v)[2], *leg.forces(r, v)))
    return np.array(rows)


def figure(leg, path):
    fig, axs = plt.subplots(1, 3, figsize=(12.5, 4.2))
    rest = dict(outer="0.75", inner="0.6", secondary="0.7")
    loaded = dict(outer="tab:blue", inner="tab:orange", secondary="tab:green")
    r_loaded = leg.rest_foot + np.array([0.0, 0.0, PUSH])
    for ax, axes, title in ((axs[0], (0, 2), "side view (x–z)"), (axs[1], (0, 1), "top view (x–y)")):
        Q = draw_leg(ax, leg, leg.rest_foot, axes, rest)
        draw_leg(ax, leg, r_loaded, axes, loaded)
        label_points(ax, leg, Q, axes)
        ax.set_aspect("equal")
        ax.set_title(title + f"; grey: rest, colour: foot {PUSH:g} m up", fontsize=9)
        ax.set_xlabel("xyz"[axes[0]] + " [m]")
        ax.set_ylabel("xyz"[axes[1]] + " [m]")
        ax.grid(alpha=0.3)
    axs[0].plot([], [], lw=5, color="tab:blue", label="primary, outer cylinder (ℓ_o)")
    axs[0].plot([], [], lw=2.5, color="tab:orange", label="primary, inner cylinder")
    axs[0].plot([], [], lw=1.8, color="tab:green", label="secondaries h2, h3 → Q")
    axs[0].legend(fontsize=7, loc="lower left")
    rows = push(leg)
    n = PUSH_POINTS
    ax = axs[2]
    for col, label, color in ((1, "P_z (foot)", "k"), (2, "S (primary)", "tab:orange"),
                              (3, "T₂ = T₃ (secondaries)", "tab:green")):
        ax.plot(rows[:n, 0] * 1e3, rows[:n, col] / 1e3, color=color, label=label)
        ax.plot(rows[n:, 0] * 1e3, rows[n:, col] / 1e3, "--", color=color)
    ax.axhline(0, color="k", lw=0.5)
    ax.set_xlabel("foot pushed up [mm]")
    ax.set_ylabel("force [kN]")
    ax.set_title("push (solid, loading) and return (dashed, unloading)", fontsize=9)
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main():
    FIGURES.mkdir(exist_ok=True)
    figure(crushing_leg(), FIGURES / "tripod_leg.png")
    tripod, strut = elastic_leg(), hinged_strut()
    results = {}
    for name, leg in (("tripod", tripod), ("hinged_strut", strut)):
        work, scale = loop_work(leg.force, leg.rest_foot + np.array(LOOP_OFFSET))
        results[name] = dict(loop_work_J=work, force_times_perimeter_J=scale,
                             relative=work / scale)
        print(f"{name:13s} loop work {work:+.3e} J, |P|·perimeter {scale:.4g} J, "
              f"ratio {work / scale:+.2e}")
    (FIGURES / "tripod_leg.json").write_text(json.dumps(results, indent=2) + "\n")


if __name__ == "__main__":
    main()
