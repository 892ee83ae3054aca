"""Reproduction of Figs. 3–4: the paper's two claims at μ = 0, and at μ = 0.05
what our Fig. 4 scene really does with each method (docs/reproduction.md).

The printed contact step and the exact implicit step are checked; the robust
step matches the implicit one on these scenes (studies/fig4_sweep.py).
"""
from pathlib import Path

import numpy as np
import pytest

from symcushion.cli import main
from symcushion.reproduce import ALIGN_BOUND, REBOUND_BOUND, measure_claims
from symcushion.model.scene import load_scene
from symcushion.run.driver import simulate

ROOT = Path(__file__).resolve().parents[1]
STUDIES = ROOT / "studies"
METHODS = ("paper", "implicit")

#: Fig. 3 run length (s): the single contact phase ends near 0.35 s.
FIG3_DURATION = 0.45
#: Fig. 4 run length (s): the paper step's flight ends near 0.42 s, and four
#: swings of the stuck oscillation follow.
FIG4_DURATION = 1.5
#: Slack on the Coulomb bound |α − γ| ≤ atan μ (rad): round-off of the angles.
CONE_SLACK = 1e-6


def run(name, method, duration):
    scene = load_scene(STUDIES / f"{name}.toml").with_(method=method, duration=duration)
    traj = simulate(scene)
    return scene, traj, measure_claims(traj, scene)


@pytest.fixture(scope="module", params=METHODS)
def fig3(request):
    return run("fig3", request.param, FIG3_DURATION)


@pytest.fixture(scope="module")
def fig4():
    return {method: run("fig4", method, FIG4_DURATION) for method in METHODS}


def flights(traj):
    """Start indices of the flights: steps at which every foot has left the dome."""
    airborne = ~(traj.contact > 0.5).any(axis=1)
    airborne[0] = False                      # the feet touch the dome at t = 0
    return np.where(airborne[1:] & ~airborne[:-1])[0] + 1


def friction_work(traj, foot=0):
    """(positive, negative) work of the tangential contact force on one foot (J).

    Over a step in which the foot stays in contact the friction force at the
    end of the step times the foot's slip on the (fixed) dome; Coulomb's law
    makes every term ≤ 0.
    """
    on = traj.contact[:, foot] > 0.5
    both = on[1:] & on[:-1]
    slip = np.diff(traj.foot[:, foot], axis=0)
    P, n = traj.force[1:, foot], traj.normal[1:, foot]
    P_tau = P - np.einsum("ij,ij->i", P, n)[:, None] * n
    work = np.where(both, np.einsum("ij,ij->i", P_tau, slip), 0.0)
    return work[work > 0].sum(), work[work < 0].sum()


# ---------------------------------------------------------------------------
# Fig. 3, μ = 0: the paper's quantitative claims hold for both methods
# ---------------------------------------------------------------------------
def test_fig3_force_along_normal(fig3):
    _, _, claims = fig3
    assert claims.max_align < ALIGN_BOUND


def test_fig3_rebound_speed_equals_impact_speed(fig3):
    _, _, claims = fig3
    assert claims.lifted_off
    assert abs(claims.rebound_dv) < REBOUND_BOUND


# ---------------------------------------------------------------------------
# Fig. 4, μ = 0.05
# ---------------------------------------------------------------------------
def test_fig4_implicit_sticks_with_decaying_oscillation(fig4):
    _, traj, claims = fig4["implicit"]
    assert (traj.contact[1:] > 0.5).all(), "a foot left the dome"
    assert not claims.lifted_off
    assert claims.decay < 0.05       # last swing of y′ under 5 % of the first
    assert abs(traj.velocity[-1, 2]) < 0.01


def test_fig4_paper_bounces_once_then_sticks(fig4):
    """The printed step does not do what the paper says: one short flight."""
    scene, traj, claims = fig4["paper"]
    starts = flights(traj)
    assert len(starts) == 1
    assert 0.30 < traj.t[starts[0]] < 0.40
    assert claims.lifted_off
    restitution = 1 + claims.rebound_dv / abs(scene.body.velocity[2])
    assert 0.55 < restitution < 0.70
    landed = np.where(~(traj.contact > 0.5).all(axis=1))[0][-1] + 1
    assert traj.t[landed] < 0.45
    assert (traj.contact[landed:] > 0.5).all(), "a foot left the dome after landing"
    assert claims.decay < 1          # the y′ swing still decays


@pytest.mark.parametrize("method", METHODS)
def test_fig4_force_within_friction_cone_while_sliding(fig4, method):
    _, traj, claims = fig4[method]
    assert (traj.mode[:, 0] == 2).any()
    assert claims.slide_excess <= CONE_SLACK


def test_fig4_friction_dissipates_with_implicit_step(fig4):
    _, traj, _ = fig4["implicit"]
    positive, negative = friction_work(traj)
    assert negative < -1.0
    assert positive < 1e-9 * abs(negative)


def test_fig4_printed_step_friction_does_positive_work(fig4):
    """Why the printed step lifts off: its force jumps between the edges of the
    cone once the slip reverses, and on the steps with the wrong edge friction
    pushes the foot along its slip (docs/reproduction.md)."""
    _, traj, _ = fig4["paper"]
    positive, negative = friction_work(traj)
    assert positive > 0.2 * abs(negative)


# ---------------------------------------------------------------------------
# command line
# ---------------------------------------------------------------------------
def test_cli_reproduce_writes_figures_and_table(tmp_path, capsys):
    out = tmp_path / "figs"
    code = main(["reproduce", "--scenes", str(STUDIES), "--out", str(out), "--duration", "0.05"])
    assert code == 0
    expected = [f"{fig}{suffix}.csv" for fig in ("fig3", "fig4")
                for suffix in ("", "_robust", "_implicit")]
    expected += [f"{fig}{suffix}.png" for fig in ("fig3", "fig4") for suffix in ("", "_methods")]
    expected += ["claims.md"]
    for name in expected:
        assert (out / name).is_file() and (out / name).stat().st_size > 0, name
    table = (out / "claims.md").read_text()
    rows = [line for line in table.splitlines() if line.startswith(("| fig3 |", "| fig4 |"))]
    assert len(rows) == 3 * 2 + 3 * 3     # 2 claims × 3 methods (Fig. 3), 3 × 3 (Fig. 4)
    assert "| figure | method | claim | measured | holds |" in capsys.readouterr().out
