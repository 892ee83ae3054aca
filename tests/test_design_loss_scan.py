"""studies/design_loss_scan.py: what it reads off a scan, on scans made by hand."""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "studies"))

import design_loss_scan as dls  # noqa: E402

T = (np.arange(-dls.HALF, dls.HALF + 1) * dls.STEP).tolist()


def _run(risk, losses=None):
    """A scan of one variable ``a``: its risk and losses (points × 1 check × 2 scenarios)."""
    if losses is None:
        losses = np.zeros((len(T), 1, 2))
    return dict(t=T, checks=["stroke"], scenarios=["s0", "s1"],
                lines={"a": dict(risk=list(risk), losses=np.asarray(losses).tolist())})


def test_a_straight_risk_has_one_slope_and_a_jump_shows_as_a_wide_range():
    t = np.asarray(T)
    lo, hi = dls.spread(_run(0.3 * t))["a"]
    assert abs(lo - 0.3) < 1e-9 and abs(hi - 0.3) < 1e-9
    jumped = 0.3 * t + np.where(t > 0, 1e-4, 0.0)         # a step of 1e-4 inside the line
    lo, hi = dls.spread(_run(jumped))["a"]
    assert abs(lo - 0.3) < 1e-9 and abs(hi - (0.3 + 1e-4 / dls.STEP)) < 1e-6


def test_the_largest_step_of_one_loss_names_its_check_and_scenario():
    losses = np.zeros((len(T), 1, 2))
    losses[dls.HALF + 3:, 0, 1] = 2e-3                     # scenario s1 jumps once
    step, check, case = dls.jumps(_run(np.zeros(len(T)), losses))["a"]
    assert (check, case) == ("stroke", "s1") and abs(step - 2e-3) < 1e-15


def test_the_figure_is_written_whole(tmp_path):
    t = np.asarray(T)
    path = dls.draw(_run(np.sin(1e4 * t) * 1e-4), _run(np.abs(t)), tmp_path / "scan.png")
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert [p.name for p in tmp_path.iterdir()] == ["scan.png"]
