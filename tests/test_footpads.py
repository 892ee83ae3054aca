"""Footpads (docs/footpads.md): a foot of pad radius a is the pad's centre, on the
obstacle's surface offset by a. Exact equivalences on planes and spheres, the rest
geometry on a dome, the first-order offset of implicit surfaces and terrain, the
narrow rock a pad cannot sink into, bad radii, the checks, and the parameter vector."""
from __future__ import annotations

import copy
from dataclasses import replace

import casadi as ca
import numpy as np
import pytest

from symcushion.legs.characteristics import Linear
from symcushion.run.checks import FOOTPAD_FRACTION, check_scene
from symcushion.run.driver import simulate
from symcushion.layout.vectors import output_layout, state_layout
from symcushion.model.obstacles import ImplicitSurface, Plane, Sphere, Terrain
from symcushion.model.scene import Body, Scene, scene_from_dict
from symcushion.legs.strut import HingedStrut
from symcushion.scheme.touchdown import build_model, equilibrium_state, initial_state
from symcushion.run.trajectory import contact_points
from symcushion.legs.tripod import InvertedTripod
from symcushion.run.error_control import fitted_order

from conftest import make_sled
from test_tripod import APOLLO, azimuth

#: Apollo LM footpad radius (m): 0.94 m across.
APOLLO_PAD = 0.47


def with_pads(scene: Scene, a) -> Scene:
    """``scene`` with every leg's footpad radius set to ``a`` (m)."""
    legs = []
    for leg in scene.legs:
        padded = copy.copy(leg)
        padded.footpad = float(a)
        legs.append(padded)
    return scene.with_(legs=legs)


def rollout(scene, model=None, x0=None, p=None):
    model = build_model(scene) if model is None else model
    x0 = initial_state(scene) if x0 is None else x0
    p = model.default_p if p is None else p
    X, Y = model.rollout(scene.steps)(x0, p, scene.dt)
    return np.asarray(X), np.asarray(Y)


def one_leg(obstacle, hinge_xy=(0.0, 0.0), pad=0.0, length=1.5, mu=1.0, height=None):
    """A heavy-inertia body on one vertical strut above ``hinge_xy`` (the hinge at the
    centre of mass), at rest ``height`` above the obstacle's origin."""
    leg = HingedStrut(hinge=(0.0, 0.0, 0.0), e0=(0, 0, -1), en=(0.6, 0, -0.8), length=length,
                      S=Linear(2e4), M_beta=Linear(2e3), M_gamma=Linear(2e3), footpad=pad)
    body = Body(mass=10.0, inertia=[1e6, 1e6, 1e6],
                position=(hinge_xy[0], hinge_xy[1], 2.5 if height is None else height))
    return Scene(body, [leg], [obstacle], mu=mu, method="implicit", dt=1e-3, duration=0.1)


# ---------------------------------------------------------------------------
# the obstacles' offset surfaces
# ---------------------------------------------------------------------------
def _at(obstacle, x, a):
    x = ca.DM(x)
    return tuple(np.asarray(ca.evalf(v), float).ravel() for v in
                 (obstacle.distance(x, a), obstacle.normal(x, a), obstacle.project(x, a)))


def test_planes_and_spheres_offset_exactly():
    x, a = np.array([0.3, -0.2, 1.4]), 0.25
    plane = Plane.inclined(0.3, point=(0.1, 0.0, 0.2))
    d, n, proj = _at(plane, x, a)
    d0, n0, _ = _at(plane, x, 0.0)
    np.testing.assert_allclose(d, d0 - a, rtol=0, atol=1e-15)
    np.testing.assert_array_equal(n, n0)
    np.testing.assert_allclose(_at(plane, proj, 0.0)[0], a, rtol=0, atol=1e-15)
    sphere = Sphere((0.1, 0.2, -0.3), 0.8)
    d, n, proj = _at(sphere, x, a)
    np.testing.assert_allclose(d, np.linalg.norm(x - sphere.center) - 1.05, rtol=0, atol=1e-15)
    np.testing.assert_allclose(np.linalg.norm(proj - sphere.center), 1.05, rtol=0, atol=1e-15)
    np.testing.assert_allclose(proj - a * n, sphere.center + 0.8 * n, rtol=0, atol=1e-15)


def test_the_implicit_offset_is_exact_for_a_signed_distance_and_first_order_elsewhere():
    x, a, R = np.array([0.4, 0.3, 1.1]), 0.2, 0.9
    distance = ImplicitSurface(lambda p: ca.norm_2(p) - R)        # |∇φ| = 1
    _, n, proj = _at(distance, x, a)
    np.testing.assert_allclose(np.linalg.norm(proj), R + a, rtol=0, atol=1e-12)
    np.testing.assert_allclose(n, proj / np.linalg.norm(proj), rtol=0, atol=1e-12)
    # φ = |x|² − R²: ψ = φ − a|∇φ| = 0 at |x| = a + √(a² + R²), not R + a
    squared = ImplicitSurface(lambda p: ca.dot(p, p) - R ** 2)
    proj = _at(squared, x, a)[2]
    for _ in range(5):                                           # to convergence
        proj = _at(squared, proj, a)[2]
    np.testing.assert_allclose(np.linalg.norm(proj), a + np.hypot(a, R), rtol=0, atol=1e-12)
    # a terrain that is a plane: exact (the spline reproduces a linear height)
    g = np.linspace(-2, 2, 9)
    tilted = Terrain(g, g, -np.tan(0.2) * g[:, None] + 0 * g[None, :])
    d, n, proj = _at(tilted, x, a)
    plane = Plane.inclined(0.2)
    np.testing.assert_allclose(d, _at(plane, x, a)[0], rtol=0, atol=1e-12)
    np.testing.assert_allclose(_at(plane, proj, 0.0)[0], a, rtol=0, atol=1e-12)


def _true_offset_height(h, X, a):
    """Height of the true offset of z = h(x) (a ridge along y) above X: the highest
    centre of a ball of radius a over the profile, by dense sampling."""
    s = np.linspace(X - a, X + a, 40001)
    return np.max(h(s) + np.sqrt(np.clip(a * a - (s - X) ** 2, 0.0, None)))


def test_the_terrain_offset_error_falls_as_a_squared():
    h0, sigma = 0.05, 0.3                                          # a gentle ridge
    g = np.linspace(-3, 3, 241)
    H = h0 * np.exp(-g[:, None] ** 2 / (2 * sigma ** 2)) + 0 * g[None, :]
    ridge = Terrain(g, g, H)

    def h(x):
        return h0 * np.exp(-x ** 2 / (2 * sigma ** 2))

    X, errors, pads = 0.2, [], (0.02, 0.04, 0.08)
    for a in pads:
        psi = ridge._offset()[0]
        z = 1.0
        for _ in range(50):                                      # ψ(X, 0, z) = 0 in z
            z -= float(psi([X, 0.0, z], a)) / float(ridge._offset()[1]([X, 0.0, z], a)[2])
        errors.append(abs(z - _true_offset_height(h, X, a)))
    order = fitted_order(pads, errors)
    assert 1.8 < order < 2.3, (errors, order)


# ---------------------------------------------------------------------------
# exact equivalences in the step
# ---------------------------------------------------------------------------
def test_a_pad_on_a_level_plane_is_a_point_foot_on_the_plane_raised_by_a():
    """Bit for bit: the sled sliding with friction, pads of a vs the plane moved up by a."""
    a = 0.1
    sled = make_sled(0.0, 0.3).with_(duration=0.3)
    sled = sled.with_(body=replace(sled.body, velocity=np.array([0.8, 0.2, -0.5])))
    padded = with_pads(sled, a)
    raised = sled.with_(obstacles=[Plane((0.0, 0.0, a))])
    body = replace(sled.body, position=sled.body.position + (0.0, 0.0, a))
    X1, Y1 = rollout(padded.with_(body=body))
    X2, Y2 = rollout(raised.with_(body=body))
    np.testing.assert_array_equal(X1, X2)
    np.testing.assert_array_equal(Y1, Y2)
    assert np.any(output_layout(4).legs(Y1, "mode") == 2)      # the feet slid


def test_a_pad_on_an_inclined_plane_is_a_point_foot_on_the_plane_moved_by_a():
    theta, a = 0.3, 0.1
    sled = make_sled(theta, 0.2).with_(duration=0.4)           # slides down the slope
    n = np.array([np.sin(theta), 0.0, np.cos(theta)])
    X1, _ = rollout(with_pads(sled, a))
    X2, _ = rollout(sled.with_(obstacles=[Plane(a * n, n)]))
    xl = state_layout(4)
    np.testing.assert_allclose(xl.get(X1, "position"), xl.get(X2, "position"), rtol=0,
                               atol=1e-12)
    assert np.ptp(xl.get(X1, "position")[0]) > 0.01             # it moved


def test_a_pad_on_the_dome_is_a_point_foot_on_a_dome_of_radius_R_plus_a(fig3_scene):
    """Fig. 3 with pads: bit for bit the run on a dome of radius R + a, the body placed
    so that the pads touch at t = 0 (geometry as inputs and baked in)."""
    a, R = 0.1, 0.5
    z = np.sqrt((R + a) ** 2 - 0.3 ** 2) + 0.78
    body = replace(fig3_scene.body, position=np.array([0.0, 0.0, z]))
    padded = with_pads(fig3_scene, a).with_(body=body, duration=0.3)
    bigger = fig3_scene.with_(body=body, duration=0.3, obstacles=[Sphere((0, 0, 0), R + a)])
    X2, _ = rollout(bigger)
    for geometry in ("input", "constant"):
        X1, _ = rollout(padded, build_model(padded, geometry))
        np.testing.assert_array_equal(X1, X2)


def test_tripod_pads_on_a_level_plane():
    a = APOLLO_PAD
    legs = [InvertedTripod(**{k: (azimuth(np.pi / 4 + i * np.pi / 2) @ np.asarray(v, float)
                                  if k != "outer_length" else v) for k, v in APOLLO.items()},
                           primary=Linear(2e5), secondary2=Linear(1e6), secondary3=Linear(1e6),
                           footpad=a) for i in range(4)]
    height = -legs[0].rest_foot[2] + a
    body = Body(mass=7000.0, inertia=np.diag([1.7e4, 1.7e4, 2e4]), position=(0.0, 0.0, height),
                velocity=(0.5, 0.0, -1.0))
    padded = Scene(body, legs, [Plane()], mu=0.5, dt=1e-3, duration=0.2, gravity=(0, 0, -1.62))
    point = with_pads(padded, 0.0).with_(obstacles=[Plane((0.0, 0.0, a))])
    X1, _ = rollout(padded)
    X2, _ = rollout(point)
    np.testing.assert_array_equal(X1, X2)


# ---------------------------------------------------------------------------
# at rest on a dome
# ---------------------------------------------------------------------------
@pytest.mark.parametrize("b", [0.0, 0.25])
def test_a_pad_rests_on_a_sphere_with_its_centre_at_R_plus_a(b):
    """One leg above the dome's top (b = 0) or b off it: the pad's centre lands on the
    vertical through the hinge at R + a from the centre, the contact normal tilted by
    asin(b/(R + a)) (a point foot's by asin(b/R)), and the foot stays there."""
    R, a = 1.0, 0.3
    scene = one_leg(Sphere((0, 0, 0), R), (b, 0.0), pad=a)
    x0 = equilibrium_state(scene, solve_attitude=False)
    xl = state_layout(1)
    foot = xl.get(x0, "foot", 0)
    np.testing.assert_allclose(foot, [b, 0.0, np.sqrt((R + a) ** 2 - b ** 2)], rtol=0,
                               atol=1e-12)
    # the body held by the strut's static compression mg/k above the foot
    np.testing.assert_allclose(xl.get(x0, "position")[2] - foot[2], 1.5 - 10 * 9.81 / 2e4,
                               rtol=0, atol=1e-9)
    model = build_model(scene)
    traj = simulate(scene, model=model, x0=x0)
    assert np.all(traj.contact[:, 0] == 1) and np.all(traj.mode[1:, 0] == 1)   # stuck
    np.testing.assert_allclose(traj.foot[:, 0], np.broadcast_to(foot, (len(traj.t), 3)),
                               rtol=0, atol=1e-12)
    n = traj.normal[-1, 0]
    np.testing.assert_allclose(n, foot / (R + a), rtol=0, atol=1e-12)
    assert np.isclose(np.arcsin(np.hypot(n[0], n[1])), np.arcsin(b / (R + a)), atol=1e-12)
    point = contact_points(traj, [a])[-1, 0]
    np.testing.assert_allclose(np.linalg.norm(point), R, rtol=0, atol=1e-12)
    # a point foot at the same place lands lower, on the dome itself
    bare = equilibrium_state(one_leg(Sphere((0, 0, 0), R), (b, 0.0)), solve_attitude=False)
    np.testing.assert_allclose(xl.get(bare, "foot", 0)[2], np.sqrt(R ** 2 - b ** 2), atol=1e-12)


# ---------------------------------------------------------------------------
# a narrow rock
# ---------------------------------------------------------------------------
ROCK_HEIGHT, ROCK_SIGMA = 0.1, 0.1      # m: 0.24 m across at half its height


def _rock_terrain():
    g = np.linspace(-1.0, 1.0, 161)
    X, Y = np.meshgrid(g, g, indexing="ij")
    return Terrain(g, g, ROCK_HEIGHT * np.exp(-(X ** 2 + Y ** 2) / (2 * ROCK_SIGMA ** 2)))


def _clearance(terrain, centre, a):
    """Least distance from ``centre`` to the terrain's surface, less a (m), by dense
    sampling of the surface under the pad."""
    s = np.linspace(-a, a, 241)
    X, Y = np.meshgrid(centre[0] + s, centre[1] + s, indexing="ij")
    Z = np.asarray(terrain._h(np.vstack([X.ravel(), Y.ravel()])), float).reshape(X.shape)
    return np.sqrt((X - centre[0]) ** 2 + (Y - centre[1]) ** 2 + (Z - centre[2]) ** 2).min() - a


def test_a_pad_wider_than_a_rock_does_not_sink_into_it():
    """A leg whose foot comes down 0.15 m beside the peak of a rock narrower than its
    pad (a = 0.3 m, 0.6 m across): the pad rests on the rock, its true clearance (the
    least distance from its centre to the surface, less a) within 3 % of a (−1.6 %
    measured: the offset is first order); on the leg lengthened by a, a point foot
    comes down lower, on the rock's flank, and a pad centred a above it would be 12 %
    of a inside the rock."""
    a, offset = 0.3, (0.15, 0.0)
    terrain = _rock_terrain()
    padded = one_leg(terrain, offset, pad=a)
    lengthened = one_leg(terrain, offset, length=1.5 + a)
    xl = state_layout(1)
    # the feet held where they land (cone=False): on the rock's flank no rest exists
    traj = simulate(padded, x0=equilibrium_state(padded, solve_attitude=False, cone=False))
    pad = traj.foot[-1, 0]
    assert traj.contact[-1, 0] == 1
    assert _clearance(terrain, pad, a) > -0.03 * a
    foot = xl.get(equilibrium_state(lengthened, solve_attitude=False, cone=False), "foot", 0)
    assert _clearance(terrain, foot + (0.0, 0.0, a), a) < -0.1 * a
    assert pad[2] - a > foot[2] + 0.02                          # the pad rides higher


# ---------------------------------------------------------------------------
# input and checks
# ---------------------------------------------------------------------------
@pytest.mark.parametrize("bad", [-0.1, float("nan"), float("inf")])
def test_a_bad_footpad_is_refused_naming_the_field(bad):
    with pytest.raises(ValueError, match="`footpad`"):
        HingedStrut((0, 0, 0), (0, 0, -1), (0.6, 0, -0.8), 0.5, S=Linear(1e4), footpad=bad)
    with pytest.raises(ValueError, match="`footpad`"):
        InvertedTripod(**APOLLO, primary=Linear(1e5), secondary2=Linear(1e5),
                       secondary3=Linear(1e5), footpad=bad)


def _scene_dict(legs_table: dict, scheme="legs") -> dict:
    strut = dict(e0=[0.0, 0.0, -1.0], en=[0.6, 0.0, -0.8], length=0.5,
                 S={"type": "linear", "stiffness": 1e4},
                 M_beta={"type": "linear", "stiffness": 1e3},
                 M_gamma={"type": "linear", "stiffness": 1e3})
    legs = (dict(count=3, radius=0.3, height=0.0, **strut, **legs_table) if scheme == "legs"
            else [dict(hinge=[0.3, 0.0, 0.0], **strut, **legs_table)])
    return {"body": {"mass": 10.0, "inertia": [1.0, 1.0, 1.0], "position": [0.0, 0.0, 1.0]},
            scheme: legs, "obstacle": [{"type": "plane"}]}


def test_scene_files_take_a_footpad_per_leg_and_refuse_a_bad_one():
    scene = scene_from_dict(_scene_dict({"footpad": 0.05}))
    assert [leg.footpad for leg in scene.legs] == [0.05] * 3
    scene = scene_from_dict(_scene_dict({"footpad": 0.07}, "leg"))
    assert scene.legs[0].footpad == 0.07
    assert scene_from_dict(_scene_dict({})).legs[0].footpad == 0.0
    with pytest.raises(ValueError, match=r"legs\.footpad"):
        scene_from_dict(_scene_dict({"footpad": -0.05}))
    with pytest.raises(ValueError, match=r"leg\[0\]\.footpad"):
        scene_from_dict(_scene_dict({"footpad": float("nan")}, "leg"))


def test_a_large_pad_is_a_warning_and_a_pad_in_the_ground_an_error():
    scene = scene_from_dict(_scene_dict({"footpad": 0.05}))
    assert not [f for f in check_scene(scene) if f.kind == "footpad_large"]
    big = scene_from_dict(_scene_dict({"footpad": 0.5 * (FOOTPAD_FRACTION + 1) * 0.5}))
    found = [f for f in check_scene(big) if f.kind == "footpad_large"]
    assert len(found) == 3 and found[0].severity == "warning"
    assert "legs[0].footpad" in found[0].message
    # the feet 0.5 m below the body at z = 1: a pad of 0.6 m is in the ground
    sunk = scene_from_dict(_scene_dict({"footpad": 0.6}))
    inside = [f for f in check_scene(sunk) if f.kind == "foot_inside"]
    assert inside and inside[0].severity == "error" and "footpad" in inside[0].message


# ---------------------------------------------------------------------------
# the parameter vector
# ---------------------------------------------------------------------------
def test_footpads_are_entries_of_p_only_in_a_scene_with_a_pad():
    sled = make_sled(0.0, 0.3)
    model = build_model(sled)
    assert not any(name.endswith("footpad") for name in model.param_names)
    with pytest.raises(KeyError, match="point"):
        model.pack_params(**{"leg0.footpad": 0.1})
    padded = with_pads(sled, 0.1)
    model = build_model(padded)
    assert model.param_names[-4:] == tuple(f"leg{j}.footpad" for j in range(4))
    assert model.param_names[:-4] == build_model(sled).param_names
    with pytest.raises(ValueError, match="leg2.footpad"):
        model.pack_params(**{"leg2.footpad": -0.1})


def test_one_build_serves_every_pad_radius():
    """A build with pads of 0.1 m run with 0.2 m in p is the build with 0.2 m, and
    with 0 in p on a plane it is the point foot's run."""
    sled = make_sled(0.0, 0.3).with_(duration=0.2)
    sled = sled.with_(body=replace(sled.body, position=np.array([0.0, 0.0, 0.25]),
                                   velocity=np.array([0.5, 0.0, -0.5])))
    model = build_model(with_pads(sled, 0.1))
    p = model.pack_params(**{f"leg{j}.footpad": 0.2 for j in range(4)})
    X1, _ = rollout(sled, model, initial_state(sled), p)
    X2, _ = rollout(with_pads(sled, 0.2))
    np.testing.assert_array_equal(X1, X2)
    p0 = model.pack_params(**{f"leg{j}.footpad": 0.0 for j in range(4)})
    X3, _ = rollout(sled, model, initial_state(sled), p0)
    X4, _ = rollout(sled)
    np.testing.assert_array_equal(X3, X4)
