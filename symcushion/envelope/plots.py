"""Figures of an envelope study.

Owns the three figures (stability boundary panels with a logistic fit,
P(stable) by slope, distributions of the measures). It must not compute
anything a figure does not show.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from symcushion.run.output_files import atomic_write_text, replacing
from symcushion.envelope.build import safe_file_name
from symcushion.envelope.classify import CLASSES
from symcushion.envelope.statistics import slope_ranges, CONFIDENCE, EnvelopeResult, wilson_interval

__all__ = ["LOGISTIC_RIDGE", "plot_envelope"]

#: Ridge penalty of the logistic boundary fit (standardised features): keeps
#: the fit finite when a panel's classes are separable.
LOGISTIC_RIDGE = 1e-2
#: Colours of the outcome classes in the plots.
_COLOURS = {"stable": "#b8c4cc", "tip_over": "#d62728", "stroke": "#ff7f0e",
            "deflection": "#9467bd", "deceleration": "#1f77b4", "rebound": "#2ca02c",
            "moving": "#8c564b", "no_touchdown": "#000000"}
#: Heading bins of the boundary plot: direction of travel against the fall line (deg).
_HEADINGS = (("downhill", 0.0, 45.0), ("across", 45.0, 135.0), ("uphill", 135.0, 180.0))



def _margins(fig, nr: int, nc: int, *, left: float, right: float, bottom: float, top: float,
             hgap: float, wgap: float):
    """Place a figure's nr × nc panels with margins and gaps given in inches.

    The figures' sizes and texts are fixed, so fixed margins lay them out as
    ``tight_layout`` did, without its extra drawing pass (about a third of the
    figures' time, docs/envelope.md, "Throughput")."""
    width, height = fig.get_size_inches()
    l, r, b, t = left / width, 1 - right / width, bottom / height, 1 - top / height
    ah = (height * (t - b) - (nr - 1) * hgap) / nr
    aw = (width * (r - l) - (nc - 1) * wgap) / nc
    fig.subplots_adjust(left=l, right=r, bottom=b, top=t, hspace=hgap / ah, wspace=wgap / aw)


def _save(fig, path):
    """Write ``fig`` to ``path`` atomically (no half-written PNG) and close it."""
    import matplotlib.pyplot as plt   # the backend is chosen by plot_envelope

    with replacing(path) as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)
    return path

def _logistic_fit(a, b, y, ridge=LOGISTIC_RIDGE, iterations=50):
    """Quadratic logistic regression of y on (a, b) by Newton's method with a ridge.

    Returns a function P(a, b), or None when the classes are too few to fit.
    """
    if min(np.sum(y), np.sum(~y)) < 5:
        return None
    ma, sa = a.mean(), a.std() or 1.0
    mb, sb = b.mean(), b.std() or 1.0

    def features(a_, b_):
        u, v = (a_ - ma) / sa, (b_ - mb) / sb
        return np.column_stack([np.ones_like(u), u, v, u * u, v * v, u * v])

    X = features(a, b)
    w = np.zeros(X.shape[1])
    penalty = ridge * len(y) * np.diag([0.0] + [1.0] * (X.shape[1] - 1))
    for _ in range(iterations):
        prob = 1 / (1 + np.exp(-np.clip(X @ w, -30, 30)))
        grad = X.T @ (prob - y) + penalty @ w
        hess = X.T @ (X * (prob * (1 - prob))[:, None]) + penalty
        step = np.linalg.solve(hess, grad)
        w -= step
        if np.max(np.abs(step)) < 1e-10:
            break
    return lambda a_, b_: 1 / (1 + np.exp(-np.clip(features(a_, b_) @ w, -30, 30)))


def _heading_from_fall_line(heading_deg):
    """|heading| folded to [0°, 180°]: 0 downhill, 180 uphill."""
    return np.abs((np.asarray(heading_deg) + 180.0) % 360.0 - 180.0)


#: Names shared by the figures of :func:`plot_envelope`.
_CONTEXT = ("out", "st", "c", "col", "name", "cls", "stable", "vh", "vv", "slope",
            "heading", "slope_bins", "heading_bins", "result")


def plot_envelope(result: EnvelopeResult, out_dir) -> dict:
    """Write the envelope figures; return their paths by kind.

    * ``<name>.png``: the stability boundary in the (horizontal speed,
      vertical speed) plane, one panel per slope bin (columns) and heading
      bin (rows: travelling downhill, across, uphill). Cases are dots coloured
      by class; the line is P(stable) = 0.5 of a quadratic logistic
      regression fitted to the panel's cases (with a small ridge,
      :data:`LOGISTIC_RIDGE`), drawn where both outcomes occur.
    * ``<name>_pstable.png``: P(stable) against slope with Wilson intervals
      (:data:`CONFIDENCE`), overall and per heading bin.
    * ``<name>_distributions.png``: histograms of peak deceleration, largest
      stroke and largest tilt, with the limits.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    st = result.study
    c, col = result.conditions, result.columns
    name = safe_file_name(st.name)
    files = {}
    cls = col["class"]
    stable = col["stable"]
    vh, vv = c["horizontal_speed"], c["vertical_speed"]
    slope = c["slope_deg"]
    heading = _heading_from_fall_line(c["heading_deg"])
    slope_bins = slope_ranges(slope)
    heading_bins = _HEADINGS if np.ptp(heading) > 0 and np.ptp(vh) > 0 else (("all", 0, 180),)

    context = dict(out=out, st=st, c=c, col=col, name=name, cls=cls, stable=stable, vh=vh,
                   vv=vv, slope=slope, heading=heading, slope_bins=slope_bins,
                   heading_bins=heading_bins, result=result)
    for draw in (_plot_boundary, _plot_pstable, _plot_distributions):
        draw(plt, context, files)
    return files


def _plot_boundary(plt, context: dict, files: dict):
    """The stability-boundary panels (``<name>.png``)."""
    (out, st, c, col, name, cls, stable, vh, vv, slope, heading, slope_bins, heading_bins,
     result) = (context[k] for k in _CONTEXT)
    # 1. boundary panels
    nr, nc = len(heading_bins), len(slope_bins)
    fig, axes = plt.subplots(nr, nc, figsize=(3.6 * nc + 1.2, 3.0 * nr + 0.8), squeeze=False,
                             sharex=True, sharey=True)
    for r, (hname, h_lo, h_hi) in enumerate(heading_bins):
        for k, (s_lo, s_hi) in enumerate(slope_bins):
            ax = axes[r, k]
            sel = (heading >= h_lo) & (heading <= h_hi) & (slope >= s_lo) & (slope <= s_hi)
            for label in CLASSES:
                m = sel & (cls == label)
                if np.any(m):
                    ax.scatter(vh[m], vv[m], s=4 if label == "stable" else 7,
                               c=_COLOURS[label], lw=0, label=label.replace("_", "-"))
            fit = _logistic_fit(vh[sel], vv[sel], stable[sel]) if np.sum(sel) > 20 else None
            if fit is not None:
                ga, gb = np.meshgrid(np.linspace(vh.min(), vh.max(), 120),
                                     np.linspace(vv.min(), vv.max(), 120))
                prob = fit(ga.ravel(), gb.ravel()).reshape(ga.shape)
                if prob.min() < 0.5 < prob.max():
                    ax.contour(ga, gb, prob, levels=[0.5], colors="k", linewidths=1.2)
            k_s, n_s = int(np.sum(stable[sel])), int(np.sum(sel))
            est, lo, hi = wilson_interval(k_s, n_s)
            title = f"slope {s_lo:.0f}–{s_hi:.0f}°" if nc > 1 or s_hi > s_lo else \
                f"slope {s_lo:.0f}°"
            if len(heading_bins) > 1:
                title += f", {hname}"
            ax.set_title(f"{title}\nP(stable) = {est:.2f} [{lo:.2f}, {hi:.2f}], n = {n_s}",
                         fontsize=8)
            if r == nr - 1:
                ax.set_xlabel("horizontal speed (m/s)")
            if k == 0:
                ax.set_ylabel("vertical speed (m/s)")
    handles = {}
    for ax in axes.ravel():
        for h, lab in zip(*ax.get_legend_handles_labels()):
            handles.setdefault(lab, h)
    fig.legend(list(handles.values()), list(handles.keys()), loc="lower center",
               ncol=len(handles), fontsize=8, markerscale=2, frameon=False)
    fig.suptitle(f"{st.name}: outcome of {result.n:,} touchdowns; line: P(stable) = 0.5 "
                 "(quadratic logistic fit)", fontsize=10)
    _margins(fig, nr, nc, left=0.6, right=0.12, bottom=0.95, top=0.95, hgap=0.62, wgap=0.2)
    files["boundary"] = _save(fig, out / f"{name}.png")


def _plot_pstable(plt, context: dict, files: dict):
    """P(stable) against slope, with its CSV (``<name>_pstable.*``)."""
    (out, st, c, col, name, cls, stable, vh, vv, slope, heading, slope_bins, heading_bins,
     result) = (context[k] for k in _CONTEXT)
    # 2. P(stable) against slope
    fig, ax = plt.subplots(figsize=(6, 4))
    edges = np.linspace(slope.min(), slope.max(), 7) if np.ptp(slope) > 0 else \
        np.array([slope.min() - 0.5, slope.max() + 0.5])
    centres = 0.5 * (edges[:-1] + edges[1:])
    groups = [("all headings", np.ones_like(stable, bool))]
    if len(heading_bins) > 1:
        groups += [(hname, (heading >= lo) & (heading <= hi)) for hname, lo, hi in heading_bins]
    rows = []
    for g_i, (gname, gsel) in enumerate(groups):
        idx = np.clip(np.digitize(slope, edges[1:-1]), 0, len(centres) - 1)
        k = np.array([np.sum(stable[gsel & (idx == b)]) for b in range(len(centres))])
        n = np.array([np.sum(gsel & (idx == b)) for b in range(len(centres))])
        est, lo, hi = wilson_interval(k, n)
        offset = (g_i - (len(groups) - 1) / 2) * 0.08 * (edges[1] - edges[0])
        ax.errorbar(centres + offset, est, yerr=[est - lo, hi - est], marker="o", ms=4,
                    capsize=3, lw=2 if g_i == 0 else 1, label=gname)
        rows += [(gname, float(a), float(b), int(kk), int(nn), float(e), float(lw), float(hg))
                 for a, b, kk, nn, e, lw, hg in zip(edges[:-1], edges[1:], k, n, est, lo, hi)]
    ax.set_xlabel("slope (deg)")
    ax.set_ylabel(f"P(stable), {CONFIDENCE:.0%} Wilson interval")
    ax.set_ylim(-0.02, 1.02)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title(f"{st.name}: P(stable) by slope", fontsize=10)
    _margins(fig, 1, 1, left=0.62, right=0.12, bottom=0.5, top=0.32, hgap=0, wgap=0)
    files["pstable"] = _save(fig, out / f"{name}_pstable.png")
    table = ["heading,slope_lo_deg,slope_hi_deg,stable,cases,p,low,high"]
    table += [f"{g},{a:.4g},{b:.4g},{k},{n},{e:.4f},{lw:.4f},{hg:.4f}"
              for g, a, b, k, n, e, lw, hg in rows]
    files["pstable_csv"] = out / f"{name}_pstable.csv"
    atomic_write_text(files["pstable_csv"], "\n".join(table) + "\n")


def _plot_distributions(plt, context: dict, files: dict):
    """Histograms of the measures against the limits."""
    (out, st, c, col, name, cls, stable, vh, vv, slope, heading, slope_bins, heading_bins,
     result) = (context[k] for k in _CONTEXT)
    # 3. distributions
    lim = st.limits
    panels = (("peak_decel", "peak deceleration |a − g| (m/s²)", lim.deceleration),
              ("max_stroke", "largest axial stroke (m)", lim.stroke),
              ("max_tilt_deg", "largest tilt from the vertical (deg)", lim.tilt_deg))
    fig, axes = plt.subplots(1, 3, figsize=(13, 3.6))
    for ax, (key, label, limit) in zip(axes, panels):
        shown, note = np.ones(len(cls), bool), ""
        if key == "max_tilt_deg" and st.stop and np.any(cls == "tip_over"):
            # a case that tips over stops just past the limit: its tilt says no more
            shown = cls != "tip_over"
            note = f"\n({np.sum(~shown):,} tip-overs stopped at the limit, not drawn)"
        values = col[key][shown]
        bins = np.linspace(values.min(), values.max(), 50) if np.ptp(values) > 0 else 10
        ax.hist(values[stable[shown]], bins=bins, color=_COLOURS["stable"], label="stable")
        ax.hist(values[~stable[shown]], bins=bins, color="#d62728", alpha=0.6,
                label="not stable" + note)
        if limit is not None:
            ax.axvline(limit, color="k", ls="--", lw=1, label="limit")
        ax.set_xlabel(label)
        ax.set_ylabel("cases")
        ax.legend(fontsize=8)
    fig.suptitle(f"{st.name}: distributions over {result.n:,} cases", fontsize=10)
    _margins(fig, 1, 3, left=0.75, right=0.12, bottom=0.5, top=0.36, hgap=0, wgap=0.7)
    files["distributions"] = _save(fig, out / f"{name}_distributions.png")
