"""The potential force law of the hinged strut beside the paper's (2.1).

``law = "potential"`` is P = f_S ∇δ_S + f_β ∇β + f_γ ∇(γ − γ₀) with the
gradients by AD. Checked here: its D_p is symmetric where (2.1)'s is not;
the work of the force around a closed loop of the foot vanishes for it (to
the accuracy of the quadrature, which a refinement shows) and does not for
(2.1); the two laws agree at the unloaded rest pose and to first order
about it; D_p by AD against finite differences; the scene field.
"""
from __future__ import annotations

import numpy as np
import pytest

from symcushion import HingedStrut, Linear, PiecewiseLinear
from symcushion.model.scene import SceneError, scene_from_dict, symmetric_legs

#: The leg of the loop checks: a lander leg (20° out, polar axis 45° from it)
#: with elastic curves.
LEG = dict(hinge=(0.35, 0.35, -0.2), e0=(0.242, 0.242, -0.94), en=(-0.3, -0.3, -0.906),
           length=0.8)
#: A 2 cm loop about a foot deflected by (3, −2, 4) cm from rest: a circle in the
#: plane spanned by these unit vectors.
LOOP_CENTRE = np.array([0.03, -0.02, 0.04])
LOOP_RADIUS = 0.02
LOOP_PLANE = (np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.6, 0.8]))
#: The work of (2.1) around that loop (J), from this file's quadrature at 256 and
#: 512 nodes (they agree to 1e-13 J).
PAPER_LOOP_WORK = -1.33039980066


def make_leg(law, **curves):
    curves = curves or dict(S=Linear(1e5), M_beta=Linear(2e4), M_gamma=Linear(2e4))
    return HingedStrut(**LEG, **curves, law=law)


def loop_work(leg, n):
    """∮ P·dr around the loop by the periodic trapezoid rule on ``n`` nodes (J)."""
    a, b = LOOP_PLANE
    theta = 2 * np.pi * np.arange(n) / n
    work = 0.0
    for t in theta:
        r = leg.rest_foot + LOOP_CENTRE + LOOP_RADIUS * (np.cos(t) * a + np.sin(t) * b)
        dr = LOOP_RADIUS * (-np.sin(t) * a + np.cos(t) * b) * (2 * np.pi / n)
        work += leg.force(r) @ dr
    return work


def random_poses(leg, rng, count=20, reach=0.08):
    return [leg.rest_foot + rng.uniform(-reach, reach, 3) for _ in range(count)]


def asymmetry(D):
    return np.linalg.norm(D - D.T) / np.linalg.norm(D)


def test_potential_stiffness_is_symmetric_and_paper_is_not():
    rng = np.random.default_rng(1)
    curves = dict(S=PiecewiseLinear([-0.2, 0.0, 0.05], [-3e4, 0.0, 1e4]),
                  M_beta=Linear(2e4, 50.0), M_gamma=Linear(1.5e4))
    potential, paper = make_leg("potential", **curves), make_leg("paper", **curves)
    poses = random_poses(potential, rng)
    assert max(asymmetry(potential.stiffness(r)) for r in poses) < 1e-13
    assert max(asymmetry(paper.stiffness(r)) for r in poses) > 1e-2


def test_loop_work_vanishes_for_the_potential_law():
    leg = make_leg("potential")
    coarse, fine = loop_work(leg, 128), loop_work(leg, 256)
    # the force is O(1 kN) and the loop 0.13 m long: 1e-10 J is round-off
    assert abs(fine) < 1e-10 and abs(coarse) < 1e-10


def test_loop_work_of_the_paper_law_is_the_known_value():
    leg = make_leg("paper")
    coarse, fine = loop_work(leg, 128), loop_work(leg, 256)
    assert abs(fine - coarse) < 1e-10          # converged: the error is not the quadrature's
    assert fine == pytest.approx(PAPER_LOOP_WORK, rel=1e-9)


def test_laws_agree_at_rest_and_to_first_order_about_it():
    potential, paper = make_leg("potential"), make_leg("paper")
    rest = potential.rest_foot
    np.testing.assert_allclose(potential.force(rest), paper.force(rest), atol=1e-9)
    D = paper.stiffness(rest)
    np.testing.assert_allclose(potential.stiffness(rest), D, rtol=0, atol=1e-12 * np.abs(D).max())
    np.testing.assert_allclose(potential.stiffness(rest), potential.rest_stiffness_closed_form(),
                               rtol=0, atol=1e-12 * np.abs(D).max())
    # off rest the difference is second order in the deflection: halving it quarters it
    d = np.array([0.02, -0.01, 0.015])
    gaps = [np.linalg.norm(potential.force(rest + s * d) - paper.force(rest + s * d))
            for s in (1.0, 0.5, 0.25)]
    assert gaps[0] / gaps[1] == pytest.approx(4.0, rel=0.1)
    assert gaps[1] / gaps[2] == pytest.approx(4.0, rel=0.05)


def test_a_preload_keeps_the_rest_force_but_not_the_rest_stiffness():
    """With f(0) ≠ 0 the rest forces still agree (∇β = e_β/L there) but D_p differs by
    f(0)(∇²β − ∂(e_β/L)/∂r): the potential law's stays symmetric."""
    curves = dict(S=Linear(1e5), M_beta=Linear(2e4, 200.0), M_gamma=Linear(2e4))
    potential, paper = make_leg("potential", **curves), make_leg("paper", **curves)
    rest = potential.rest_foot
    np.testing.assert_allclose(potential.force(rest), paper.force(rest), rtol=1e-12, atol=1e-9)
    assert asymmetry(potential.stiffness(rest)) < 1e-13
    assert np.abs(potential.stiffness(rest) - paper.stiffness(rest)).max() > 1.0


@pytest.mark.parametrize("law", ["potential", "paper"])
def test_stiffness_by_ad_matches_finite_differences(law):
    rng = np.random.default_rng(7)
    curves = dict(S=PiecewiseLinear([-0.2, 0.0, 0.05], [-3e4, 0.0, 1e4]),
                  M_beta=Linear(2e4, 50.0), M_gamma=Linear(1.5e4))
    leg = make_leg(law, **curves)
    h = 1e-6
    for r in random_poses(leg, rng, count=8, reach=0.04):
        fd = np.column_stack([(leg.force(r + h * e) - leg.force(r - h * e)) / (2 * h)
                              for e in np.eye(3)])
        D = leg.stiffness(r)
        np.testing.assert_allclose(D, fd, rtol=0, atol=1e-6 * np.abs(D).max())


def test_potential_law_input_geometry_matches_constant():
    leg = make_leg("potential")
    p = np.concatenate([leg.param_values, leg.geometry_values])
    fns = leg.functions("input")
    r = leg.rest_foot + np.array([0.03, 0.01, -0.02])
    np.testing.assert_allclose(np.asarray(fns["strut_force"](r, 0, p)).ravel(), leg.force(r),
                               rtol=1e-14, atol=1e-10)


def test_law_is_validated_and_paper_formula_refused_for_potential():
    with pytest.raises(ValueError, match="`law`"):
        make_leg("conservative")
    leg = make_leg("potential")
    assert "strut_stiffness_paper" not in leg.functions()
    with pytest.raises(ValueError, match="paper"):
        leg.stiffness(leg.rest_foot, paper=True)


def _legs_dict(law):
    return {"scene": {"mu": 0.5},
            "body": {"mass": 50.0, "inertia": [2.0, 2.0, 2.0], "position": [0, 0, 1.0]},
            "legs": {"count": 3, "radius": 0.3, "height": 0.0, "length": 0.6,
                     "e0": [0.3, 0, -1], "en": [-0.4, 0, -1], "law": law,
                     "S": {"type": "linear", "stiffness": 1e5},
                     "M_beta": {"type": "linear", "stiffness": 1e4},
                     "M_gamma": {"type": "linear", "stiffness": 1e4}},
            "obstacle": [{"type": "plane"}]}


def test_scene_field_law():
    assert [leg.law for leg in scene_from_dict(_legs_dict("potential")).legs] == ["potential"] * 3
    assert [leg.law for leg in scene_from_dict(_legs_dict("paper")).legs] == ["paper"] * 3
    data = _legs_dict("paper")
    del data["legs"]["law"]
    # a scene file that names no law takes the energy-consistent one (docs/strut.md)
    assert scene_from_dict(data).legs[0].law == "potential"
    single = _legs_dict("paper")
    del single["legs"]
    single["leg"] = [{"hinge": [0.3, 0, 0], "e0": [0.3, 0, -1], "en": [-0.4, 0, -1],
                      "length": 0.6, "law": "potential",
                      "M_beta": {"type": "linear", "stiffness": 1e4}}]
    assert scene_from_dict(single).legs[0].law == "potential"
    with pytest.raises(SceneError, match="law"):
        scene_from_dict(_legs_dict("potental"))
    legs = symmetric_legs(3, 0.3, 0.0, 0.6, (0.3, 0, -1), (-0.4, 0, -1), S=Linear(1e5),
                          law="potential")
    assert {leg.law for leg in legs} == {"potential"}
