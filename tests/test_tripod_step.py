"""Inverted-tripod legs in the touchdown step (symcushion.legs.tripod through symcushion.scheme.touchdown):
a lander at rest where the hand truss puts it, the memory law on its elements, scene files."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import brentq

from symcushion.legs.characteristics import Crushable, Linear, TwoSided
from symcushion.layout.vectors import output_layout, state_layout
from symcushion.model.obstacles import Plane
from symcushion.model.scene import Body, Scene, load_scene
from symcushion.scheme.touchdown import build_model, initial_state
from symcushion.legs.tripod import InvertedTripod

from conftest import STUDIES
from test_tripod import APOLLO, azimuth, curve_forces, ref_strokes, truss_foot_force

MASS, GRAVITY = 7000.0, 1.62
#: Damping time of every element (s): ζ ≈ 0.6 on the lander's heave mode, so that
#: 3 s of settling leave ~1e-9 of the sink.
SETTLING_TAU = 0.1


def _lander(curves, mu=2.0, duration=3.0):
    """Four tripods at 45° + 90° i, feet on level ground, the body at rest."""
    specs = [{k: (azimuth(np.pi / 4 + i * np.pi / 2) @ np.asarray(v, float)
                  if k != "outer_length" else v) for k, v in APOLLO.items()} for i in range(4)]
    legs = [InvertedTripod(**spec, **curves) for spec in specs]
    height = -min(leg.rest_foot[2] for leg in legs)
    body = Body(mass=MASS, inertia=np.diag([1.7e4, 1.7e4, 2e4]), position=(0.0, 0.0, height))
    scene = Scene(body=body, legs=legs, obstacles=[Plane()], mu=mu, method="implicit",
                  dt=1e-3, duration=duration, gravity=(0.0, 0.0, -GRAVITY),
                  hysteresis="memory", name="tripods")
    return scene, specs


def _run(scene):
    model = build_model(scene)
    X, Y = model.rollout(scene.steps)(initial_state(scene), model.default_p, scene.dt)
    return np.asarray(X), np.asarray(Y)


def test_a_tripod_lander_settles_where_the_hand_truss_holds_it():
    """Dropped from rest with its feet on level ground, the body sinks d with every
    foot stuck where it touched: 4 P_z = m g of the truss solved by hand."""
    def damped(k):
        return Linear(k, damping=SETTLING_TAU * k)
    curves = dict(primary=damped(2e5), secondary2=damped(7e5), secondary3=damped(7e5))
    scene, specs = _lander(curves)
    X, Y = _run(scene)
    xl, yl = state_layout(4), output_layout(4)
    sink = scene.body.position[2] - xl.get(X, "position")[2, -1]
    up = np.array([0.0, 0.0, 1.0])
    plain = dict(primary=Linear(2e5), secondary2=Linear(7e5), secondary3=Linear(7e5))

    def weight_carried(d):
        return sum(truss_foot_force(spec, np.asarray(spec["foot"]) + d * up, curve_forces(
            plain, ref_strokes(spec, np.asarray(spec["foot"]) + d * up)))[2] for spec in specs)

    d_hand = brentq(lambda d: weight_carried(d) - MASS * GRAVITY, 0.0, 0.2, xtol=1e-15)
    assert sink == pytest.approx(d_hand, rel=1e-7)
    strokes = np.c_[yl.legs(Y, "stroke")[:, -1], yl.legs(Y, "secondary_stroke")[:, :, -1]]
    for spec, row in zip(specs, strokes):
        np.testing.assert_allclose(row, ref_strokes(spec, np.asarray(spec["foot"]) + d_hand * up),
                                   rtol=1e-7, atol=1e-12)
    np.testing.assert_array_equal(yl.legs(Y, "mode")[:, -1], 1.0)      # all stuck


def test_a_tripods_crushed_elements_keep_their_sets_across_lift_off():
    """A secondary crushed in tension keeps its set when the foot leaves the ground and
    touches again (the memory law, docs/absorbers.md); the printed law forgets it."""
    two_sided = TwoSided(Crushable(3e6, 1.5e4), Crushable(3e6, 3e3))
    curves = dict(primary=Crushable(2e6, 2e4, 1e4), secondary2=two_sided,
                  secondary3=two_sided)
    scene, _ = _lander(curves, mu=0.5, duration=0.6)
    scene = scene.with_(body=Body(mass=MASS, inertia=np.diag([1.7e4, 1.7e4, 2e4]),
                                  position=scene.body.position + [0, 0, 0.001],
                                  velocity=(0.0, 0.0, -3.05)))
    X, _ = _run(scene)
    sets = state_layout(4).legs(X, "element_set")              # (legs, 2, steps)
    assert np.max(np.abs(sets)) > 1e-3, "the secondaries did not crush"
    crushed = np.abs(sets) > 1e-6
    # a set once made never shrinks back: |s| is non-decreasing along the run
    grow = np.diff(np.abs(sets), axis=2)
    assert np.all(grow[crushed[:, :, 1:]] >= -1e-12)


def test_the_apollo_example_reads_and_steps():
    scene = load_scene(STUDIES / "apollo_lander.toml")
    assert len(scene.legs) == 4 and all(isinstance(leg, InvertedTripod) for leg in scene.legs)
    X, Y = _run(scene.with_(duration=0.2))
    assert np.all(np.isfinite(X)) and np.all(np.isfinite(Y))


def test_tripods_refuse_the_event_rules():
    scene, _ = _lander(dict(primary=Linear(2e5), secondary2=Linear(7e5),
                            secondary3=Linear(7e5)))
    with pytest.raises(ValueError, match="inverted tripods.*events = 'none'"):
        scene.with_(hysteresis="sign", events="branch")


def test_one_build_serves_every_tripod_geometry():
    """A model built for the Apollo-class example and run with the ``p`` of other
    hardpoints, feet and outer cylinders equals the model built for them: bit for bit
    against their own model with geometry as inputs, to round-off against the one with
    the geometry baked in."""
    base = load_scene(STUDIES / "apollo_lander.toml").with_(duration=0.15)
    built = build_model(base)
    variants = [dict(h1=(2.0, 0.0, 1.0), outer_length=2.2),
                dict(foot=(4.4, 0.1, -1.9), h2=(2.1, 1.2, -0.9), h3=(2.1, -1.25, -1.0))]
    for variant in variants:
        spec = dict(h1=base.legs[0].h1, h2=base.legs[0].h2, h3=base.legs[0].h3,
                    foot=base.legs[0].foot, outer_length=base.legs[0].outer_length)
        spec.update(variant)
        curves = {el.name: el.curve for el in base.legs[0].elements}
        legs = [InvertedTripod(**{k: (azimuth(np.pi / 2 * i) @ np.asarray(v, float)
                                      if k != "outer_length" else v) for k, v in spec.items()},
                               **curves) for i in range(4)]
        scene2 = base.with_(legs=legs)
        x0 = initial_state(scene2)
        own, constant = build_model(scene2), build_model(scene2, geometry="constant")
        X1, Y1 = (np.asarray(a) for a in built.rollout(scene2.steps)(x0, own.default_p,
                                                                      scene2.dt))
        X2, Y2 = (np.asarray(a) for a in own.rollout(scene2.steps)(x0, own.default_p,
                                                                    scene2.dt))
        Xc, _ = (np.asarray(a) for a in constant.rollout(scene2.steps)(
            x0, constant.default_p, scene2.dt))
        assert np.array_equal(X1, X2) and np.array_equal(Y1, Y2), variant
        # round-off relative to each field's scale over the run (forces are tens of kN,
        # so a force component near zero is compared with the leg's whole force)
        xl, scale = state_layout(4), np.ones((Xc.shape[0], 1))
        for name in ("position", "velocity", "attitude", "angular_velocity"):
            scale[xl.slice(name)] = max(1.0, np.max(np.abs(Xc[xl.slice(name)])))
        for name in ("foot", "force_body", "stroke_set", "element_set", "stroke_chord",
                     "element_chord"):
            for j in range(4):
                rows = xl.slice(name, j)
                scale[rows] = max(1.0, np.max(np.abs(Xc[rows])))
        assert np.max(np.abs(X1 - Xc) / scale) < 1e-11, variant
        assert np.any(state_layout(4).legs(X1, "contact") > 0.5)      # the feet landed


def test_a_singular_tripod_geometry_in_p_is_refused():
    model = build_model(load_scene(STUDIES / "apollo_lander.toml"))
    h1 = model.default_p[model.params.slice("leg0.h1")]
    with pytest.raises(ValueError, match="leg 0.*outer_length"):
        model.pack_params(**{"leg0.outer_length": 10.0, "leg0.h1": h1})
