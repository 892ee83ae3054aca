"""Choosing the scenarios of a design for the envelope from a sampled pool.

Owns the rule that picks, from the classified cases of an envelope run on
the starting design, the touchdowns the optimiser sees: failures that a
design can plausibly turn (their worst margin not below ``worst_margin``;
tip-overs of every depth, whose tip-over energy margin keeps a gradient
however far the body tipped) and stable cases close to a limit, each group ordered by how close it is to
the boundary and spread over the failure classes in proportion to their
counts. It must not run, classify or optimise.
"""
from __future__ import annotations

import numpy as np

__all__ = ["MARGINS", "DEFAULT_WORST_MARGIN", "DEFAULT_FAIL_SHARE", "ANY_DEPTH", "worst_margin",
           "select_scenarios", "left_out"]

#: Margin columns of the envelope's classification that the design acts on.
MARGINS = ("margin_tip_over", "margin_stroke", "margin_deflection", "margin_deceleration",
           "margin_rebound", "margin_moving")
#: Failures whose worst margin is below this are left out: a case 100 % over
#: a limit (a tilt of twice the limit, a rebound at twice the limit speed) is
#: one no change of the curves turns, and it would only flatten the risk.
DEFAULT_WORST_MARGIN = -1.0
#: Failure classes kept whatever their worst margin. A tip-over's tilt margin
#: says nothing of how near it came to staying up (every tipped lander ends on
#: its side), while the design's tip-over energy margin
#: (symcushion.design.robust.margins) falls smoothly as the stance widens or the
#: legs take more energy: a deep tip-over is one the geometry can turn.
ANY_DEPTH = ("tip_over",)
#: Share of the scenarios taken from the failures; the rest are stable cases
#: with the smallest margins, so that the design does not buy the failures
#: with new ones.
DEFAULT_FAIL_SHARE = 0.6


def worst_margin(columns: dict) -> np.ndarray:
    """The smallest of the envelope's margins per case (:data:`MARGINS` present)."""
    present = [np.asarray(columns[m], dtype=float) for m in MARGINS if m in columns]
    if not present:
        raise ValueError(f"`columns` has none of the margins {list(MARGINS)}; pass the "
                         "columns of `symcushion.envelope.classify`.")
    return np.min(present, axis=0)


def select_scenarios(columns: dict, n: int, *, fail_share: float = DEFAULT_FAIL_SHARE,
                     worst: float = DEFAULT_WORST_MARGIN) -> np.ndarray:
    """Indices of the cases to design for, most informative first within each group.

    Parameters
    ----------
    columns : dict
        The classified pool (``classify`` columns: ``class`` and the margins).
    n : int
        Scenarios wanted (≥ 1); fewer are returned when the pool has fewer
        candidates.
    fail_share : float
        Share of failures in [0, 1].
    worst : float
        Failures with a worst margin below this are not candidates.

    Returns
    -------
    ndarray of int
        Sorted indices into the pool.
    """
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise ValueError(f"`n` must be a positive integer, got {n!r}.")
    if not 0.0 <= fail_share <= 1.0:
        raise ValueError(f"`fail_share` must be in [0, 1], got {fail_share!r}.")
    cls = np.asarray(columns["class"])
    margin = worst_margin(columns)
    failing = _candidates(cls, margin, worst)
    stable = cls == "stable"
    n_fail = min(int(round(fail_share * n)), int(failing.sum()))
    n_stable = min(n - n_fail, int(stable.sum()))
    chosen = []
    # failures: each class in proportion to its count, closest to the boundary first
    classes, counts = np.unique(cls[failing], return_counts=True)
    quota = _apportion(counts, n_fail)
    for c, q in zip(classes, quota):
        idx = np.flatnonzero(failing & (cls == c))
        chosen += list(idx[np.argsort(-margin[idx], kind="stable")][:q])
    idx = np.flatnonzero(stable)
    chosen += list(idx[np.argsort(margin[idx], kind="stable")][:n_stable])
    return np.sort(np.asarray(chosen, dtype=int))


def _candidates(cls, margin, worst) -> np.ndarray:
    """Failures a design can plausibly turn: within ``worst``, or of a class in ANY_DEPTH."""
    failed = (cls != "stable") & (cls != "no_touchdown")
    return failed & ((margin >= worst) | np.isin(cls, ANY_DEPTH))


def left_out(columns: dict, *, worst: float = DEFAULT_WORST_MARGIN) -> dict:
    """Failures that are no candidates, counted by class: ``{class: count}``.

    They failed a limit by more than ``-worst`` of it (a rebound at twice the
    limit speed, say), which no change of the design turns; the scenarios do
    not represent them, and the CLI says so.
    """
    cls = np.asarray(columns["class"])
    failed = (cls != "stable") & (cls != "no_touchdown")
    out = failed & ~_candidates(cls, worst_margin(columns), worst)
    classes, counts = np.unique(cls[out], return_counts=True)
    return {str(c): int(n) for c, n in zip(classes, counts)}


def _apportion(counts, total: int) -> list:
    """Integer shares of ``total`` proportional to ``counts`` (largest remainders)."""
    counts = np.asarray(counts, dtype=float)
    if total <= 0 or counts.sum() == 0:
        return [0] * len(counts)
    exact = counts / counts.sum() * total
    share = np.floor(exact).astype(int)
    for i in np.argsort(-(exact - share), kind="stable")[:total - share.sum()]:
        share[i] += 1
    return [int(min(s, c)) for s, c in zip(share, counts)]
