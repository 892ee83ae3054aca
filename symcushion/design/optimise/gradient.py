"""Checking the design gradients (a mixin of DesignProblem).

Owns the comparison of the AD Jacobian of ``design_fg`` with central
differences on the scaled variables, with the step and agreement levels it
reports against. It must not change the problem.
"""
from __future__ import annotations

import casadi as ca
import numpy as np

__all__ = ["FD_STEP", "ROW_FLOOR", "FD_AGREEMENT", "NOISE_STEP", "NOISE_FACTOR", "GRADIENT_PASS",
           "gradient_verdict"]

#: Central-difference step on the *scaled* design variables (all O(1)):
#: truncation ≈ h²·f‴ ≈ 1e-10, round-off ≈ ε·|f|/h ≈ 1e-11 relative.
FD_STEP = 1e-5
#: Rows of the Jacobian whose norm is below this fraction of the largest are
#: left out of ``worst_row`` in :meth:`DesignProblem.check_gradient`: central
#: differences carry a round-off of about eps/FD_STEP ≈ 2e-11 per unit of the
#: (O(1), scaled) row values, so a relative accuracy of 1e-5 cannot be resolved
#: on rows much smaller than 1e-5. Measured on the lander: the worst error of
#: such rows grows as 1/step (1e-4, 2e-3, 2e-2 at steps 1e-5, 1e-6, 1e-7), the
#: signature of round-off, not of a wrong derivative.
ROW_FLOOR = 1e-4
#: Two central differences of a row, at FD_STEP and FD_STEP/10, agreeing to
#: this fraction of the row's norm mark it smooth within FD_STEP of the design
#: (``check_gradient``); far stricter than any jump, which gives O(1/step).
FD_AGREEMENT = 1e-6
#: The round-off of each row is measured, not assumed: a rollout of a few
#: hundred contact steps amplifies it far beyond eps·|f| (measured on the
#: lander: about 3e-14 on rows of size 1e-2, i.e. ~1e-12 relative). It is
#: taken as the median over the coordinate axes of the row's second
#: difference over this step (scaled variables); the curvature term,
#: NOISE_STEP²·|f''| ~ 1e-24, is far below it, and the step, ~5 000 ulps of
#: an O(1) variable, decorrelates the round-off of the three evaluations.
NOISE_STEP = 1e-12
#: The two difference quotients of a row may differ by this many times the
#: row's measured round-off divided by the finer step.
NOISE_FACTOR = 10.0
#: A gradient check passes when AD and central differences agree to this over
#: the smooth rows (``relative``) and on the objective row: the test suite's
#: level for design gradients. Round-off and truncation at FD_STEP are about
#: 1e-10 relative, so an agreement of 1e-5 leaves a wide margin for them and
#: none for a wrong derivative (which shows as O(1), or as the 1e-4 of a
#: derivative taken on the wrong side of a switch).
GRADIENT_PASS = 1e-5


def gradient_verdict(check: dict, where: str) -> tuple:
    """(passed, one line for the log) of a :meth:`GradientCheck.check_gradient` result."""
    worst = max(check["relative"], check.get("objective", 0.0))
    passed = bool(worst <= GRADIENT_PASS)
    line = (f"gradient check at {where}: AD vs central differences {check['relative']:.2g} "
            f"over the smooth rows (objective {check.get('objective', 0.0):.2g}; "
            f"{check['nonsmooth_rows']} of {check['rows']} rows not smooth within the step): "
            + ("passed" if passed else f"FAILED (above {GRADIENT_PASS:g})"))
    return passed, line


class GradientCheck:
    """AD gradients of a :class:`DesignProblem` against central differences (a mixin)."""

    #: The NLP compiled to C once ``use_compiled`` has built it (else the MX one).
    _compiled_nlp = None

    # -- derivatives --------------------------------------------------------------
    def _row_noise(self, x) -> np.ndarray:
        """Round-off of each row of (f, g) at scaled x, from evaluations only (no AD).

        The median over the coordinate axes of the row's second difference
        over NOISE_STEP: a switch that the step crosses along a few axes (the
        design may sit on one) leaves the median at the round-off of the
        others. One value per row, objective first.
        """
        def fg(z):
            f, g = self.fg(z)
            return np.concatenate([[f], g])

        centre = fg(x)
        second = []
        for i in range(x.size):
            e = np.zeros(x.size)
            e[i] = NOISE_STEP
            second.append(np.abs(fg(x + e) - 2 * centre + fg(x - e)))
        return np.median(second, axis=0)

    def check_gradient(self, theta=None, step: float = FD_STEP) -> dict:
        """Compare the AD Jacobian of (f, g) in the design with central differences.

        Differences are taken on the scaled variables x = (θ/scale, t/t_ref),
        with step ``step`` and, to tell where differences are valid, again
        with ``step/10``. A row whose two difference quotients disagree is not
        smooth within ``step`` of θ (a contact, stick/slip or branch switch
        jumps inside the interval: the quotient then grows like 1/step); such
        rows are counted and named, not compared with AD. Two quotients may
        differ by their round-off, which is measured per row (``NOISE_STEP``,
        ``NOISE_FACTOR``). The smoothness test does not involve AD, so it
        cannot hide a wrong derivative.

        Returns
        -------
        dict
            ``relative``: ‖J_AD − J_FD‖_F/‖J_AD‖_F over the smooth rows;
            ``relative_all``: the same over all rows;
            ``worst_row``: the largest ‖row_AD − row_FD‖/‖row_AD‖ over smooth
            rows whose AD norm is at least :data:`ROW_FLOOR` of the largest;
            ``worst_row_all``: the same over every row above 1e-8 of the largest;
            ``objective``: the relative error of the objective row;
            ``rows``, ``columns``, ``rows_below_floor``, ``nonsmooth_rows``
            (how many), ``nonsmooth`` (a description of the first 5) and
            ``nonsmooth_scenarios`` (the scenarios they belong to).
        """
        theta = self.initial if theta is None else np.asarray(theta, dtype=float)
        x = self.scaled(theta)
        nlp = self.nlp if self._compiled_nlp is None else self._compiled_nlp  # compiled once in use
        jac = ca.Function("design_jac", [nlp["x"]],
                          [ca.jacobian(ca.vertcat(nlp["f"], nlp["g"]), nlp["x"])])
        J = np.asarray(jac(x), dtype=float)

        def differences(h):
            out = np.zeros_like(J)
            for i in range(x.size):
                e = np.zeros(x.size)
                e[i] = h
                f1, g1 = self.fg(x + e)
                f0, g0 = self.fg(x - e)
                out[:, i] = (np.concatenate([[f1], g1]) - np.concatenate([[f0], g0])) / (2 * h)
            return out

        J_fd, J_fine = differences(step), differences(step / 10)
        norm = np.linalg.norm(J, axis=1)
        top = max(norm.max(), 1e-300)
        # two valid quotients differ by truncation (≤ h²·|f‴|) and round-off
        # (noise/h at the finer step, per column); a jump inside the interval
        # makes them differ by O(jump/h)
        spread = np.linalg.norm(J_fd - J_fine, axis=1)
        noise = self._row_noise(x)
        round_off = (100 * np.finfo(float).eps + NOISE_FACTOR * np.sqrt(x.size) * noise) * 10 / step
        smooth = spread <= FD_AGREEMENT * np.maximum(norm, ROW_FLOOR * top) + round_off
        diff = np.linalg.norm(J - J_fd, axis=1)
        big = norm > 1e-8 * top
        row_rel = np.where(big, diff / np.where(big, norm, 1.0), 0.0)
        kept = smooth & (norm >= ROW_FLOOR * top)
        described, where = [], set()
        for k in np.flatnonzero(~smooth):
            if k == 0:
                described.append("objective")
                continue
            b = next(b for b in self.blocks if b.start <= k - 1 < b.stop)
            where.add(b.scenario or "design")
            if len(described) < 5:
                when = f", t = {(k - b.start) * b.dt:.4g} s" if b.dt else ""
                leg = f", leg {b.leg}" if b.leg is not None else ""
                described.append(f"{b.scenario or 'design'}{leg}: {b.label}{when}")
        rel = lambda D, rows: float(np.linalg.norm(D[rows])  # noqa: E731
                                    / max(np.linalg.norm(J[rows]), 1e-300))
        return dict(relative=rel(J - J_fd, smooth), relative_all=rel(J - J_fd, slice(None)),
                    worst_row=float(row_rel[kept].max(initial=0.0)),
                    worst_row_all=float(row_rel.max()), objective=float(row_rel[0]),
                    rows=int(J.shape[0]), columns=int(J.shape[1]),
                    rows_below_floor=int(np.count_nonzero(big & (norm < ROW_FLOOR * top))),
                    nonsmooth_rows=int(np.count_nonzero(~smooth)), nonsmooth=described,
                    nonsmooth_scenarios=sorted(where))
