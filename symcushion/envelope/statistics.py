"""Statistics and results of an envelope study.

Owns the Wilson interval of P(stable), :class:`EnvelopeResult` (cases,
counts, CSV text, the summary JSON) and the slope bins of the summary. It
must not run or plot.
"""
from __future__ import annotations

import csv
import dataclasses
import io
from dataclasses import dataclass, field

import numpy as np
from scipy.stats import binomtest

from symcushion.envelope.classify import CLASSES
from symcushion.envelope.study import EnvelopeStudy, VARIABLES

__all__ = ["CONFIDENCE", "wilson_interval", "EnvelopeResult"]

#: Confidence level of the Wilson interval on P(stable).
CONFIDENCE = 0.95


def wilson_interval(k, n, confidence: float = CONFIDENCE) -> tuple:
    """Wilson score interval of a binomial proportion k/n (SciPy's ``binomtest``).

    Parameters
    ----------
    k, n : int or array_like of int
        Successes and trials (broadcast together); n = 0 is allowed.
    confidence : float
        Confidence level in (0, 1).

    Returns
    -------
    tuple of ndarray
        (estimate, low, high), each of the broadcast shape; (nan, 0, 1) where n = 0.
    """
    if not 0 < confidence < 1:
        raise ValueError(f"`confidence` must lie in (0, 1), got {confidence!r}.")
    k, n = np.broadcast_arrays(np.asarray(k), np.asarray(n))
    if np.any(k < 0) or np.any(k > n) or np.any(k != np.round(k)) or np.any(n != np.round(n)):
        raise ValueError(f"`k` and `n` must be whole numbers with 0 ≤ k ≤ n, got {k!r}, {n!r}.")
    est, low, high = (np.full(k.shape, np.nan), np.zeros(k.shape), np.ones(k.shape))
    for idx in np.ndindex(k.shape):
        if n[idx] > 0:
            test = binomtest(int(k[idx]), int(n[idx]))
            ci = test.proportion_ci(confidence_level=confidence, method="wilson")
            est[idx], low[idx], high[idx] = test.statistic, ci.low, ci.high
    return est[()], low[()], high[()]


@dataclass
class EnvelopeResult:
    """Cases of an envelope study and what was measured.

    Attributes
    ----------
    study : EnvelopeStudy
    conditions : dict of str to ndarray, shape (n,)
        The sampled conditions (:data:`VARIABLES`).
    columns : dict of str to ndarray, shape (n,)
        Measures, margins, ``class`` and ``stable`` (:func:`classify`).
    timings : dict
        ``build_seconds``, ``run_seconds``, ``cases_per_second``, backend details.
    files : dict of str to Path
        What :func:`run_envelope` wrote.
    """

    study: EnvelopeStudy
    conditions: dict
    columns: dict
    timings: dict = field(default_factory=dict)
    files: dict = field(default_factory=dict)

    @property
    def n(self) -> int:
        return len(self.columns["class"])

    def counts(self) -> dict:
        """Cases per class (every class of :data:`CLASSES`, zeros included)."""
        cls = self.columns["class"]
        return {c: int(np.sum(cls == c)) for c in CLASSES}

    def p_stable(self) -> dict:
        """P(stable) with its Wilson interval at :data:`CONFIDENCE`."""
        k = int(np.sum(self.columns["stable"]))
        est, lo, hi = wilson_interval(k, self.n)
        return {"stable": k, "cases": self.n, "p": float(est), "low": float(lo),
                "high": float(hi), "confidence": CONFIDENCE}

    def csv_text(self) -> str:
        """Every case as CSV: index, conditions, measures, margins, class.

        Numbers are written with ``repr`` (shortest round-trip form), so equal
        results give equal bytes.
        """
        table = self.table()
        numbers = [col for name, col in table.items() if name not in ("case", "class")]
        buf = io.StringIO()
        writer = csv.writer(buf, lineterminator="\n")
        writer.writerow(list(table))
        for i in range(self.n):
            writer.writerow([i] + [repr(float(col[i])) for col in numbers]
                            + [table["class"][i]])
        return buf.getvalue()

    def table(self) -> dict:
        """The columns of ``cases.csv`` in its order: ``case``, conditions, measures,
        margins, ``class`` (arrays of shape (n,); ``class`` holds words)."""
        measures = [k for k in self.columns if k not in ("class", "stable")]
        return {"case": np.arange(self.n), **{k: self.conditions[k] for k in VARIABLES},
                **{k: self.columns[k] for k in measures}, "class": self.columns["class"]}

    def summary(self) -> dict:
        """The summary JSON: study, counts, P(stable) overall and per slope bin, timings."""
        st = self.study
        slope = self.conditions["slope_deg"]
        bins = slope_ranges(slope)
        per_bin = []
        for lo, hi in bins:
            sel = (slope >= lo) & (slope <= hi) if hi == bins[-1][1] else \
                (slope >= lo) & (slope < hi)
            k, n = int(np.sum(self.columns["stable"][sel])), int(np.sum(sel))
            est, low, high = wilson_interval(k, n)
            per_bin.append({"slope_deg": [lo, hi], "cases": n, "stable": k,
                            "p": None if n == 0 else float(est), "low": float(low),
                            "high": float(high)})
        return {
            "study": st.name, "description": st.description, "source": st.source,
            "cases": self.n, "seed": st.seed, "sampling": st.method,
            "scene": {"method": st.scene.method, "slip": st.scene.slip,
                      "events": st.scene.events, "dt": st.scene.dt,
                      "duration": st.scene.duration, "legs": len(st.scene.legs),
                      "mass": st.scene.body.mass},
            "ranges": {k: r.describe() for k, r in st.ranges.items()},
            "limits": {k: v for k, v in dataclasses.asdict(st.limits).items() if v is not None},
            "clearance": st.clearance,
            "counts": self.counts(), "p_stable": self.p_stable(), "p_stable_by_slope": per_bin,
            "timings": self.timings,
        }


def slope_ranges(slope: np.ndarray, count: int = 3) -> list:
    lo, hi = float(np.min(slope)), float(np.max(slope))
    if hi - lo < 1e-9:
        return [(lo, hi)]
    edges = np.linspace(lo, hi, count + 1)
    return [(float(a), float(b)) for a, b in zip(edges[:-1], edges[1:])]
