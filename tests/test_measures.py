"""Tests of touchdown_measures and of the scene entries of p (gravity, body, μ as inputs)."""
import casadi as ca
import numpy as np
import pytest

from symcushion.layout import output_layout, quat_from_axis_angle_np, state_layout
from symcushion.measures import MEASURES, measures_function
from symcushion.simulate import build_model, initial_state

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
