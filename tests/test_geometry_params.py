"""Leg geometry as entries of ``p``: one built step serves every geometry.

A model built for geometry G1 and run with the ``p`` of geometry G2 must give
what a model built for G2 gives: bit for bit against G2's own model with
geometry as inputs (the graphs are the same), and to round-off against G2's
model with the geometry baked in as constants. Several hinges, lengths and
directions, with and without friction, under both force laws, and through
``simulate``. Then the naming of the entries, overrides by name, and the
refusal of a geometry the built step cannot take.
"""
from __future__ import annotations

import numpy as np
import pytest

import symcushion as sc
from symcushion import Linear
from symcushion.layout.vectors import state_layout
from symcushion.model.obstacles import Plane
from symcushion.model.scene import Body, Scene, symmetric_legs
from symcushion.scheme.touchdown import build_model, initial_state

#: Steps of the compared rollouts: touchdown, stick and slip on the slope.
STEPS = 120
#: Round-off of a state after STEPS contact steps, against the constant-geometry
#: build (γ₀ may differ by an ulp: NumPy's e₀·e_n may use fused multiply-adds).
STATE_TOL = 1e-9


def lander(law="paper", mu=0.6, radius=0.5, height=-0.2, length=0.8, out=20.0, polar=25.0,
           azimuth0=np.pi / 4):
    """A four-legged lander 2 cm above a 10° slope, falling at 1.5 m/s; the legs ``out``
    degrees outwards from the vertical, their polar axes ``polar`` degrees inwards."""
    a, b = np.deg2rad(out), np.deg2rad(polar)
    legs = symmetric_legs(4, radius, height, length, (np.sin(a), 0, -np.cos(a)),
                          (-np.sin(b), 0, -np.cos(b)), S=Linear(1e5), M_beta=Linear(2e4),
                          M_gamma=Linear(2e4), azimuth0=azimuth0, law=law)
    reach = max(-leg.rest_foot[2] + abs(leg.rest_foot[0]) * np.tan(np.deg2rad(10))
                for leg in legs)
    body = Body(mass=150.0, inertia=[20.0, 20.0, 25.0], position=[0, 0, reach + 0.02],
                velocity=[0.0, 0.3, -1.5])
    return Scene(body, legs, [Plane.inclined(np.deg2rad(10))], mu=mu, dt=1e-3, duration=0.12)


#: Geometries G2 of the same scene (same signs of e₀·e_n): other hinges, lengths,
#: directions.
VARIANTS = [dict(radius=0.45, height=-0.1), dict(length=0.7), dict(out=30.0, polar=15.0),
            dict(radius=0.6, length=0.9, out=10.0, polar=40.0, azimuth0=0.6)]


def rollout(model, x0, p, dt):
    X, Y = model.rollout(STEPS)(x0, p, dt)
    return np.asarray(X), np.asarray(Y)


@pytest.mark.parametrize("law", ["paper", "potential"])
@pytest.mark.parametrize("mu", [0.6, 0.0])
def test_one_build_serves_every_geometry(law, mu):
    built = build_model(lander(law, mu))
    for variant in VARIANTS:
        scene2 = lander(law, mu, **variant)
        x0 = initial_state(scene2)
        own = build_model(scene2)
        constant = build_model(scene2, geometry="constant")
        p2 = own.default_p
        X1, Y1 = rollout(built, x0, p2, scene2.dt)
        X2, Y2 = rollout(own, x0, p2, scene2.dt)
        Xc, _ = rollout(constant, x0, constant.default_p, scene2.dt)
        assert np.array_equal(X1, X2) and np.array_equal(Y1, Y2), variant
        assert np.max(np.abs(X1 - Xc)) < STATE_TOL, variant
        assert np.any(state_layout(4).legs(X1, "contact") > 0.5)      # the feet landed


def test_through_simulate_and_named_overrides():
    built = build_model(lander("potential"))
    scene2 = lander("potential", radius=0.45, length=0.7)
    # the model of G1 with G2's scene: its default p is G2's
    run1 = sc.simulate(scene2, model=built)
    run2 = sc.simulate(scene2)
    for field in ("position", "attitude", "force", "stroke", "beta", "gamma_deflection"):
        np.testing.assert_array_equal(getattr(run1, field), getattr(run2, field))
    # the same p by overriding G1's by name
    overrides = {}
    for j, leg in enumerate(scene2.legs):
        overrides.update({f"leg{j}.hinge": leg.hinge, f"leg{j}.e0": leg.e0,
                          f"leg{j}.en": leg.en, f"leg{j}.length": leg.length})
    p = built.pack_params(**overrides)
    np.testing.assert_array_equal(p, build_model(scene2).default_p)
    # the feet of the initial state at the rest poses of p's geometry (the bodies of the
    # two scenes are placed at different heights)
    xl = state_layout(4)
    feet = [xl.legs(x, "foot") - xl.get(x, "position")
            for x in (initial_state(built.scene, p), initial_state(scene2))]
    np.testing.assert_allclose(feet[0], feet[1], rtol=0, atol=1e-15)


def test_names_and_defaults_of_the_geometry_entries():
    scene = lander()
    model = build_model(scene)
    names = model.param_names
    assert names[-10:] == ("leg3.hinge.x", "leg3.hinge.y", "leg3.hinge.z", "leg3.e0.x",
                           "leg3.e0.y", "leg3.e0.z", "leg3.en.x", "leg3.en.y", "leg3.en.z",
                           "leg3.length")
    constant = build_model(scene, geometry="constant")
    # the geometry comes last: every other entry keeps its index
    assert names[:constant.np] == constant.param_names
    assert model.np == constant.np + 40
    p = model.default_p
    np.testing.assert_array_equal(p[:constant.np], constant.default_p)
    leg = scene.legs[2]
    np.testing.assert_array_equal(model.params.get(p, "leg2.hinge"), leg.hinge)
    assert model.params.get(p, "leg2.length") == leg.length
    p2 = model.pack_params(**{"leg1.length": 0.75, "leg1.hinge": (0.1, 0.2, -0.3)})
    assert p2[model.params.index("leg1.length")] == 0.75
    np.testing.assert_array_equal(model.params.get(p2, "leg1.hinge"), [0.1, 0.2, -0.3])
    with pytest.raises(KeyError, match="geometry = 'input'"):
        constant.pack_params(**{"leg0.length": 0.7})
    with pytest.raises(KeyError, match="leg7.length"):
        model.pack_params(**{"leg7.length": 0.7})


@pytest.mark.parametrize("override, message", [
    ({"leg0.length": -0.5}, "length"),
    ({"leg0.e0": (0, 0, 0)}, "non-zero direction"),
    ({"leg1.en": (0.0, 0.0, 1.0)}, "opposite sign"),
    ({"leg0.hinge": (np.nan, 0, 0)}, "finite"),
])
def test_bad_geometry_in_p_is_refused(override, message):
    model = build_model(lander())
    with pytest.raises(ValueError, match=message):
        model.pack_params(**override)


def test_a_rest_direction_along_the_polar_axis_is_refused():
    model = build_model(lander())
    en = model.params.get(model.default_p, "leg2.en")
    with pytest.raises(ValueError, match="parallel"):
        model.pack_params(**{"leg2.e0": en})


def test_simulate_refuses_a_bad_geometry_in_p():
    scene = lander()
    model = build_model(scene)
    p = model.default_p.copy()
    p[model.params.index("leg0.length")] = 0.0
    with pytest.raises(ValueError, match="leg 0"):
        sc.simulate(scene, model=model, p=p)
