"""Tests of touchdown_measures and of the scene entries of p (gravity, body, μ as inputs)."""
import casadi as ca
import numpy as np
import pytest

from symcushion.layout.vectors import output_layout, state_layout
from symcushion.scheme.quaternion import quat_from_axis_angle_np
from symcushion.scheme.measures import MEASURES, measures_function, support_edges
from symcushion.scheme.touchdown import build_model, initial_state

#: Agreement of quantities computed two ways in double precision from O(1..10) inputs.
ROUND_OFF = 1e-12


@pytest.fixture(scope="module")
def fig4(fig4_scene):
    return fig4_scene.with_(method="robust", duration=0.1)


def test_measures_read_the_named_fields(fig4):
    n = len(fig4.legs)
    f = measures_function(fig4)
    assert f.name() == "touchdown_measures"
    assert f.name_in() == ["x", "y", "p"] and f.name_out() == list(MEASURES)
    xl, yl = state_layout(n), output_layout(n)
    rng = np.random.default_rng(3)
    x, y = rng.normal(size=xl.size), rng.normal(size=yl.size)
    q = quat_from_axis_angle_np(np.array([1.0, 0.0, 0.0]), 0.4)     # tilted 0.4 rad
    x[xl.slice("attitude")] = q
    model = build_model(fig4)
    p = model.default_p
    out = f.call(dict(x=x, y=y, p=p))
    g = np.asarray(fig4.gravity, float)
    np.testing.assert_allclose(np.asarray(out["specific_force"]).ravel(),
                               yl.get(y, "acceleration") - g, atol=ROUND_OFF)
    np.testing.assert_array_equal(np.asarray(out["stroke"]).ravel(), yl.legs(y, "stroke"))
    np.testing.assert_array_equal(np.asarray(out["contact"]).ravel(), yl.legs(y, "in_contact"))
    assert float(out["one_minus_cos_tilt"]) == pytest.approx(1 - np.cos(0.4), abs=ROUND_OFF)
    up = -g / np.linalg.norm(g)
    assert float(out["upward_speed"]) == pytest.approx(up @ xl.get(x, "velocity"), abs=ROUND_OFF)
    # Fig. 4's feet start on the dome: no penetration beyond round-off
    x0 = initial_state(fig4)
    pen = np.asarray(f(x0, y, p)[7]).ravel()
    assert np.all((pen >= 0) & (pen < ROUND_OFF))


def test_penetration_of_a_foot_below_a_plane(lander_scene):
    scene = lander_scene
    n = len(scene.legs)
    xl = state_layout(n)
    x = initial_state(scene)
    foot = xl.get(x, "foot", 0).copy()
    d = float(ca.evalf(scene.obstacles[0].distance(ca.DM(foot))))
    normal = np.asarray(ca.evalf(scene.obstacles[0].normal(ca.DM(foot)))).ravel()
    x[xl.slice("foot", 0)] = foot - (d + 0.01) * normal            # 1 cm below the surface
    y = np.zeros(output_layout(n).size)
    pen = np.asarray(measures_function(scene)(x, y, build_model(scene).default_p)[7]).ravel()
    assert pen[0] == pytest.approx(0.01, abs=1e-9)


def test_gravity_mass_and_mu_are_inputs(fig4):
    """The step with p's gravity, mass and μ equals a step built with those values."""
    model = build_model(fig4)
    # the scene entries, before the legs' geometry
    scene_names = model.param_names[:model.params.slice("leg0.hinge").start]
    assert scene_names[-11:] == ("mu", "gravity.x", "gravity.y", "gravity.z", "mass",
                                 "inertia.xx", "inertia.yy", "inertia.zz", "inertia.xy",
                                 "inertia.xz", "inertia.yz")
    other = fig4.with_(mu=0.4, gravity=np.array([0.5, 0.0, -1.62]))
    rebuilt = build_model(other)
    p = model.pack_params(mu=0.4, gravity=(0.5, 0.0, -1.62))
    np.testing.assert_array_equal(p, rebuilt.default_p)
    x0 = initial_state(fig4)
    steps = fig4.steps
    X1, _ = model.rollout(steps)(x0, p, fig4.dt)
    X2, _ = rebuilt.rollout(steps)(x0, rebuilt.default_p, fig4.dt)
    np.testing.assert_allclose(np.asarray(X1), np.asarray(X2), rtol=ROUND_OFF, atol=ROUND_OFF)


def test_frictionless_scene_has_no_mu_entry(fig3_scene):
    scene = fig3_scene
    model = build_model(scene)
    assert "mu" not in model.param_names
    with pytest.raises(KeyError, match="frictionless"):
        model.pack_params(mu=0.3)
    with pytest.raises(ValueError, match="`inertia`"):
        model.pack_params(inertia=np.array([[1.0, 2.0, 0.0], [0.0, 1.0, 0.0], [0, 0, 1.0]]))
    with pytest.raises(ValueError, match="`mass`"):
        model.pack_params(mass=np.nan)


def _square_stance(scene, *, velocity=(0.0, 0.0, 0.0), omega=(0.0, 0.0, 0.0), height=0.8):
    """State of a lander whose four feet stand at (±D, 0, 0), (0, ±D, 0), centre `height` up."""
    xl = state_layout(len(scene.legs))
    D = 0.7
    feet = np.array([[D, 0, 0], [0, D, 0], [-D, 0, 0], [0, -D, 0]], dtype=float)
    return xl.pack(position=[0.0, 0.0, height], velocity=velocity,
                   attitude=[1.0, 0.0, 0.0, 0.0], angular_velocity=omega, foot=feet,
                   contact=np.ones(4), force_body=np.zeros((4, 3))), D


def test_tip_surplus_at_rest_is_the_lift_over_the_edge(fig3_scene):
    """A level lander at rest needs r − H of lift to pass over an edge (r: edge to centre)."""
    scene = fig3_scene
    f = measures_function(scene)
    model = build_model(scene)
    x, D = _square_stance(scene)
    y = np.zeros(output_layout(4).size)
    surplus = np.asarray(f.call(dict(x=x, y=y, p=model.default_p))["tip_surplus"]).ravel()
    a = D / np.sqrt(2)                          # the edges are at D/√2 from the axis
    H = 0.8
    assert surplus.shape == (4,)
    np.testing.assert_allclose(surplus, H - np.hypot(H, a), atol=ROUND_OFF)


def test_tip_surplus_counts_the_rotation_that_lifts_the_centre_of_mass(fig3_scene):
    """Rolling towards an edge with ½ I_e Ω² = m g (r − H) has zero surplus over it."""
    scene = fig3_scene
    f = measures_function(scene)
    model = build_model(scene)
    m, I, g = scene.body.mass, scene.body.inertia[0, 0], 9.81
    H, D = 0.8, 0.7
    a = D / np.sqrt(2)
    r = np.hypot(H, a)
    I_e = m * r ** 2 + I
    omega = np.sqrt(2 * m * g * (r - H) / I_e)
    # edge of feet 0 (D, 0) and 3 (0, −D): outward normal (1, −1)/√2; rotating about
    # u = (1, 1)/√2 moves the centre of mass outward and up; the other way, in and down
    u = np.array([1.0, 1.0, 0.0]) / np.sqrt(2)
    for sign, expected in ((1.0, 0.0), (-1.0, H - r)):
        w = sign * omega * u
        d = np.array([-a / np.sqrt(2), a / np.sqrt(2), H])       # edge → centre of mass
        v = np.cross(w, d)                                        # pivoting on the edge
        x, _ = _square_stance(scene, velocity=v, omega=w)
        y = np.zeros(output_layout(4).size)
        s = np.asarray(f.call(dict(x=x, y=y, p=model.default_p))["tip_surplus"]).ravel()
        edges = [set(e) for e in support_edges(scene)]
        k = edges.index({0, 3})
        assert s[k] == pytest.approx(expected, abs=1e-12), sign


def test_support_edges_follow_the_legs_azimuth(fig3_scene):
    scene = fig3_scene
    edges = support_edges(scene)
    assert len(edges) == 4 and all(len(set(e)) == 2 for e in edges)
    # every leg in two edges, consecutive legs (90° apart) joined
    assert sorted(j for e in edges for j in e) == [0, 0, 1, 1, 2, 2, 3, 3]
    assert {frozenset(e) for e in edges} == {frozenset(e) for e in ((0, 1), (1, 2), (2, 3),
                                                                     (3, 0))}
    assert support_edges(scene.with_(legs=scene.legs[:2])) == []
