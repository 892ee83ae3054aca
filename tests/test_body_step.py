"""Tests of the body's part of the touchdown step: the legs' wrench, the kicks, the drift."""
import casadi as ca
import numpy as np
import pytest

from symcushion.scheme.body_step import (BodyParams, body_acceleration, drift, half_kick,
    legs_wrench)
from symcushion.layout.vectors import output_layout, state_layout
from symcushion.scheme.quaternion import quat_from_axis_angle_np, quat_to_rot_np
from symcushion.scheme.touchdown import build_model, initial_state
from symcushion.scheme.stability import body_stiffness, stable_dt

#: Agreement of quantities computed two ways in double precision from O(1..1000) inputs.
ROUND_OFF = 1e-9


def _legs(n=3, seed=5):
    rng = np.random.default_rng(seed)
    return rng.normal(size=(n, 3)), 100.0 * rng.normal(size=(n, 3))


def test_legs_wrench_is_the_force_and_torque_about_the_centre_of_mass():
    rho, P = _legs()
    force, torque = legs_wrench([ca.DM(r) for r in rho], [ca.DM(f) for f in P])
    assert np.allclose(np.asarray(force).ravel(), P.sum(axis=0), atol=ROUND_OFF)
    assert np.allclose(np.asarray(torque).ravel(), np.cross(rho, P).sum(axis=0), atol=ROUND_OFF)


def test_legs_wrench_in_world_axes_turns_each_leg():
    rho, P = _legs()
    R = quat_to_rot_np(quat_from_axis_angle_np(np.array([0.3, -1.0, 0.5]), 0.7))
    body = legs_wrench([ca.DM(r) for r in rho], [ca.DM(f) for f in P])
    world = legs_wrench([ca.DM(r) for r in rho], [ca.DM(f) for f in P], ca.DM(R))
    for b, w in zip(body, world):
        assert np.allclose(np.asarray(w).ravel(), R @ np.asarray(b).ravel(), atol=ROUND_OFF)


def test_no_leg_no_wrench():
    force, torque = legs_wrench([], [])
    assert np.array_equal(np.asarray(force).ravel(), np.zeros(3))
    assert np.array_equal(np.asarray(torque).ravel(), np.zeros(3))


def test_a_free_body_kicks_and_drifts_with_gravity():
    g = ca.DM([0.0, 0.0, -9.81])
    body = BodyParams(m=2.0, inertia=ca.DM.eye(3), inertia_inv=ca.DM.eye(3), g=g)
    acc = body_acceleration(body, ca.DM.eye(3), ca.DM.zeros(3), ca.DM.zeros(3), ca.DM.zeros(3))
    v, w = half_kick(ca.DM([1.0, 0, 0]), ca.DM.zeros(3), acc, 0.1)
    assert np.allclose(np.asarray(v).ravel(), [1.0, 0.0, -0.4905])
    pos, quat = drift(ca.DM.zeros(3), ca.DM([1.0, 0, 0, 0]), v, w, 0.1)
    assert np.allclose(np.asarray(pos).ravel(), [0.1, 0.0, -0.04905])
    assert np.allclose(np.asarray(quat).ravel(), [1.0, 0.0, 0.0, 0.0])


def test_the_step_kicks_the_body_with_the_legs_wrench(fig4_scene):
    # a step of a scene without events: a = g + R' ΣP_j/m of the end forces it stores
    scene = fig4_scene.with_(duration=0.05)
    model = build_model(scene)
    n = len(scene.legs)
    xl, yl = state_layout(n), output_layout(n)
    X, Y = model.rollout(scene.steps)(initial_state(scene), model.default_p, scene.dt)
    X, Y = np.asarray(X), np.asarray(Y)
    k = int(np.argmax(np.abs(yl.legs(Y, "force")).sum(axis=(0, 1)) > 0))
    x, y = X[:, k], Y[:, k]
    P = [ca.DM(xl.get(x, "force_body", j)) for j in range(n)]
    assert any(float(ca.norm_2(f)) > 0 for f in P)
    force, _ = legs_wrench([ca.DM.zeros(3)] * n, P)
    R = quat_to_rot_np(xl.get(x, "attitude"))
    want = scene.gravity + R @ np.asarray(force).ravel() / scene.body.mass
    assert np.allclose(yl.get(y, "acceleration"), want, rtol=1e-12, atol=ROUND_OFF)


def test_the_body_stiffness_is_a_derived_function_of_the_model(fig4_scene):
    model = build_model(fig4_scene)
    K = body_stiffness(model)
    assert model.derived["body_stiffness"] is K and body_stiffness(model) is K
    assert np.isfinite(stable_dt(model, initial_state(fig4_scene)))


@pytest.mark.parametrize("name", ["body_stiffness"])
def test_derived_functions_are_built_once(fig4_scene, name):
    model = build_model(fig4_scene)
    built = []

    def build(m):
        built.append(m)
        return ca.Function(name, [], [])

    assert model.derived_function(name, build) is model.derived_function(name, build)
    assert built == [model]
