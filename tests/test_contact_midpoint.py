"""The midpoint slip rule of the implicit contact step (symcushion.contact.midpoint).

Checked against closed forms and a fine reference: the fitted weight θ(z);
one step of an isotropic foot against the exact turn of its force,
tan(φ₁/2) = tan(φ₀/2) e^(−z); the local order of one step of a lander leg
against a thousand backward-Euler sub-steps; no ringing in the stiff limit;
Coulomb's law at the end of the step; and the cases the rule leaves to the
backward-Euler step (stick, lift-off, a slip whose direction does not turn).
The scene option, its validation and its graph are checked at the end.
"""
from __future__ import annotations

from pathlib import Path

import casadi as ca
import numpy as np
import pytest

from symcushion.contact.dispatch import contact_step
from symcushion.contact.midpoint import THETA_SERIES, _build, fitted_theta
from symcushion.design.optimise import study_from_dict
from symcushion.model.scene import SceneError, load_scene, read_toml, scene_from_dict
from symcushion.layout.vectors import output_layout, state_layout
from symcushion.scheme.touchdown import build_model, initial_state
from symcushion.run.driver import simulate
from symcushion.run.error_control import fitted_order

ROOT = Path(__file__).resolve().parent.parent

#: Isotropic foot: tangential and normal stiffness (N/m), load (N), μ.
K_T, K_N, N_LOAD, MU = 3e4, 1e5, 400.0, 0.2
#: Its slip length s = μN/k_t (m).
SLIP_LENGTH = MU * N_LOAD / K_T
#: Relative round-off allowed on the cone and in bit-equal comparisons.
ROUND_OFF = 1e-12
#: Backward-Euler sub-steps of the reference step, run with SUBSTEPS and
#: 2·SUBSTEPS and extrapolated (Richardson): its error, O(1/SUBSTEPS²) of the
#: one-step error, stays far below the midpoint error it is compared with.
SUBSTEPS = 500


def _steps():
    return contact_step("implicit"), _build()


def _step(P0, Dp, n, l, mu, rule):
    """One contact step (outputs as NumPy) with the backward-Euler or the midpoint rule."""
    be, mid = _steps()
    out = be(P0=P0, Dp=Dp, n=n, l=l, mu=mu, u0=np.zeros(3))
    if rule == "midpoint":
        out = mid(P0=P0, Dp=Dp, n=n, l=l, mu=mu, delta_be=out["delta"], P_be=out["P"],
                  k_be=out["k"], contact_be=out["contact"])
    return {k: np.asarray(v, dtype=float).ravel() for k, v in out.items()}


def _isotropic_start(phi0):
    """(P0, Dp, n): an isotropic foot slipping at angle φ₀ from the +x motion of the plane."""
    n = np.array([0.0, 0.0, 1.0])
    Dp = np.diag([K_T, K_T, K_N])
    P0 = np.array([MU * N_LOAD * np.cos(phi0), MU * N_LOAD * np.sin(phi0), N_LOAD])
    return P0, Dp, n


def _angle(P):
    return np.arctan2(P[1], P[0])


def test_fitted_theta_limits_and_series():
    theta = ca.Function("theta", [z := ca.SX.sym("z")], [fitted_theta(z)])
    assert float(theta(0.0)) == 0.5
    # on both sides of the switch to the series and far from it; the closed
    # form just above the switch carries a round-off of 1e-16/z² = 1e-12
    for value in (1e-3, THETA_SERIES * (1 - 1e-9), THETA_SERIES, 0.1, 1.0, 10.0):
        exact = -1.0 / np.expm1(-value) - 1.0 / value
        assert abs(float(theta(value)) - exact) < 1e-11, value
    assert abs(float(theta(1e3)) - (1.0 - 1e-3)) < 1e-12


def test_isotropic_step_matches_the_exact_turn_at_third_order():
    # the plane moves along +x by L: z = L/s; exact tan(φ₁/2) = tan(φ₀/2) e^(−z)
    phi0 = np.deg2rad(70.0)
    P0, Dp, n = _isotropic_start(phi0)
    errors = {"backward": [], "midpoint": []}
    zs = np.array([0.2, 0.1, 0.05, 0.025])
    for z in zs:
        exact = 2 * np.arctan(np.tan(phi0 / 2) * np.exp(-z))
        for rule in errors:
            out = _step(P0, Dp, n, np.array([z * SLIP_LENGTH, 0.0, 0.0]), MU, rule)
            errors[rule].append(abs(_angle(out["P"]) - exact))
    order = {rule: fitted_order(zs, e) for rule, e in errors.items()}
    assert 1.8 <= order["backward"] <= 2.2, (order, errors)   # local error O(z²)
    assert order["midpoint"] >= 2.8, (order, errors)           # local error O(z³)
    # at z = 0.025 the ratio of the two is O(z)
    assert errors["midpoint"][-1] < 0.03 * errors["backward"][-1], errors


def test_stiff_limit_does_not_ring():
    # a step 50 slip lengths long: the force ends along the motion (exact:
    # φ₁ = 2 atan(tan 35° e^(−50))), not mirrored to −φ₀ as by the midpoint rule
    P0, Dp, n = _isotropic_start(np.deg2rad(70.0))
    out = _step(P0, Dp, n, np.array([50 * SLIP_LENGTH, 0.0, 0.0]), MU, "midpoint")
    assert abs(_angle(out["P"])) < 1e-3, np.rad2deg(_angle(out["P"]))


def _lander_leg():
    """(P0, Dp, n, l_dir) of a leg of the event-order study's sliding lander, slipping."""
    scene = load_scene(ROOT / "studies" / "lander_slope.toml")
    leg = scene.legs[0]
    fns = leg.functions()
    rho = np.asarray(leg.rest_foot, dtype=float) + np.array([0.0, 0.0, 0.01])
    p = np.asarray(leg.param_values, dtype=float)
    P0 = np.asarray(fns["strut_force"](rho, np.zeros(3), p), dtype=float).ravel()
    Dp = np.asarray(fns["strut_stiffness"](rho, np.zeros(3), p), dtype=float)
    return P0, Dp


def test_local_order_on_a_lander_leg():
    # anisotropic D_p with normal coupling: one step against many
    # backward-Euler sub-steps of the same linear law, from a slipping start
    P_free, Dp = _lander_leg()
    n = np.array([0.0, 0.0, 1.0])
    mu = 0.1
    assert np.hypot(P_free[0], P_free[1]) > mu * P_free[2] > 0   # outside the cone: slips
    P0 = _step(P_free, Dp, n, np.zeros(3), mu, "backward")["P"]  # onto the cone
    velocity = np.array([-0.3, 0.05, 0.0])                       # m/s, plane vs body
    hs = np.array([2e-3, 1e-3, 5e-4, 2.5e-4])
    errors = {"backward": [], "midpoint": []}
    for h in hs:
        fine = []
        for m in (SUBSTEPS, 2 * SUBSTEPS):
            P = P0
            for _ in range(m):
                P = _step(P, Dp, n, velocity * h / m, mu, "backward")["P"]
            fine.append(P)
        ref = 2 * fine[1] - fine[0]
        for rule in errors:
            errors[rule].append(np.linalg.norm(_step(P0, Dp, n, velocity * h, mu, rule)["P"]
                                               - ref))
    order = {rule: fitted_order(hs[1:], e[1:]) for rule, e in errors.items()}
    assert 1.7 <= order["backward"] <= 2.3, (order, errors)
    assert order["midpoint"] >= 2.7, (order, errors)            # 2.9 measured


#: The slope lander at 45 ms: both uphill feet slide while the body tips.
SLIDING_STATE_TIME = 0.045
#: Step lengths of the local-order fit (s) and the sub-steps of its reference.
LOCAL_DTS, LOCAL_SUBSTEPS = (1.6e-4, 8e-5, 4e-5), 64
#: A local error O(Δt³) fits above this order; O(Δt²) (the rule in mixed frames,
#: backward Euler) at about 2.
THIRD_ORDER_LOCAL = 2.7
#: Backward Euler's local error across the slide is at least this many times the
#: rule's on these steps.
BACKWARD_EULER_FACTOR = 10


def _local_foot_errors(slip):
    """Distance across their slide of the sliding uphill feet after one step of each
    ``LOCAL_DTS`` from ``LOCAL_SUBSTEPS`` steps over the same time, from one state of
    the slope lander.

    Across the slide: an error in the slip's direction stays in the foot's
    position; one along it (the slip's length, O(Δt²) locally for a force law
    linearised at the start of the step) does not, as the next step's exact
    start force pulls the foot back onto the cone.
    """
    data = read_toml(ROOT / "studies" / "lander_slope.toml")
    data["scene"].update(slip=slip, duration=SLIDING_STATE_TIME, dt=1e-4)
    scene = scene_from_dict(data, f"lander_slope.toml ({slip})")
    model = build_model(scene)
    p = model.default_p
    x0 = np.asarray(simulate(scene, model=model, monitor=False).info["final_state"],
                    dtype=float).ravel()
    layout = state_layout(len(scene.legs))
    assert np.all(layout.unpack(x0)["contact"][1:3] == 1.0)           # both uphill feet down
    model_out = np.asarray(model.step(x0, p, LOCAL_DTS[-1])[1]).ravel()
    assert np.all(output_layout(len(scene.legs)).unpack(model_out)["mode"][1:3] == 2.0)  # slide

    def feet(x):
        return np.asarray(layout.unpack(x)["foot"])[1:3]

    errors = []
    for dt in LOCAL_DTS:
        x_fine = x0
        for _ in range(LOCAL_SUBSTEPS):
            x_fine = np.asarray(model.step(x_fine, p, dt / LOCAL_SUBSTEPS)[0]).ravel()
        x_one = np.asarray(model.step(x0, p, dt)[0]).ravel()
        slide = feet(x_fine) - feet(x0)
        along = slide / np.linalg.norm(slide, axis=1, keepdims=True)
        miss = feet(x_one) - feet(x_fine)
        across = miss - np.sum(miss * along, axis=1, keepdims=True) * along
        errors.append(np.max(np.linalg.norm(across, axis=1)))
    return np.array(errors)


def test_sliding_feet_of_a_turning_body_move_at_third_order_locally():
    """The slip direction of (M1) in the frame of the end of the step.

    The lander tips while its uphill feet slide: the body turns under the
    plane. Mixing the start force of the start frame with the end force of
    the end frame turned the slip direction by O(ωΔt) in every step: a local
    foot error O(Δt²), first order over the slide. With the start force
    carried into the end frame the local error is O(Δt³).
    """
    errors = _local_foot_errors("midpoint")
    order = fitted_order(LOCAL_DTS, errors)
    assert order >= THIRD_ORDER_LOCAL, (order, errors)             # 2.96 measured
    # backward Euler's own direction is first order: its local error O(Δt²),
    # 2,300–8,700 times the rule's here
    errors_be = _local_foot_errors("backward")
    assert np.all(errors_be > BACKWARD_EULER_FACTOR * errors), (errors_be, errors)


def test_end_force_obeys_coulomb_and_the_flow_rule():
    P0, Dp, n = _isotropic_start(np.deg2rad(50.0))
    Dp = Dp + np.array([[0.0, 4e3, -2e3], [4e3, 1e4, 3e3], [-2e3, 3e3, 0.0]])  # anisotropic
    out = _step(P0, Dp, n, np.array([2e-3, 5e-4, -1e-4]), MU, "midpoint")
    P, g = out["P"], out["k"]
    N = P @ n
    tangential = P - N * n
    assert out["contact"][0] == 1.0 and N > 0
    assert abs(np.linalg.norm(tangential) - MU * N) <= ROUND_OFF * N
    # (M1): g along (1 − θ) P₀,τ + θ P_τ, θ of z = |(D_p l)_τ|/(μ n·P₀) (P₀ on the cone)
    l = np.array([2e-3, 5e-4, -1e-4])
    Dl = Dp @ l
    z = np.linalg.norm(Dl - (Dl @ n) * n) / (MU * (P0 @ n))
    theta = 1.0 / (1.0 - np.exp(-z)) - 1.0 / z
    mean = (1 - theta) * (P0 - (P0 @ n) * n) + theta * tangential
    cross = np.cross(g / np.linalg.norm(g), mean / np.linalg.norm(mean)) @ n
    assert abs(cross) < 1e-10, cross
    assert g @ mean > 0
    assert np.allclose(out["delta"], np.array([2e-3, 5e-4, -1e-4]) - g, rtol=0, atol=1e-15)


@pytest.mark.parametrize("case", ["stick", "lift-off", "straight slip"])
def test_rule_keeps_what_does_not_turn(case):
    P0, Dp, n = _isotropic_start(0.0)
    if case == "stick":
        l = np.array([-1e-4, 0.0, 1e-4])        # back into the cone
    elif case == "lift-off":
        l = np.array([0.0, 0.0, -0.01])         # the plane moves away
    else:
        l = np.array([3e-3, 0.0, 1e-4])         # along the force: the direction is fixed
    be, mid = _step(P0, Dp, n, l, MU, "backward"), _step(P0, Dp, n, l, MU, "midpoint")
    for key in be:
        assert np.allclose(mid[key], be[key], rtol=ROUND_OFF, atol=1e-15), (key, be, mid)


# ---------------------------------------------------------------------------
# the scene option
# ---------------------------------------------------------------------------
def _scene(**changes):
    return load_scene(ROOT / "studies" / "lander_hop.toml").with_(**changes)


def test_bad_slip_rule_is_rejected():
    with pytest.raises(ValueError, match="`slip`.*'midpoint'"):
        _scene(slip="trapezoid")
    with pytest.raises(ValueError, match="`slip`.*`method`"):
        _scene(method="robust", slip="midpoint")
    data = read_toml(ROOT / "studies" / "lander_hop.toml")
    data["scene"]["slip"] = "midpiont"
    with pytest.raises(SceneError, match="slip"):
        scene_from_dict(data, "hop.toml")


def test_default_graph_is_the_backward_euler_graph():
    default = build_model(_scene())
    backward = build_model(_scene(slip="backward"))
    midpoint = build_model(_scene(slip="midpoint"))
    assert _scene().slip == "backward"
    names = {f.name() for f in default.step.find_functions()}
    assert not any("midpoint" in name for name in names), names
    assert any("midpoint" in f.name() for f in midpoint.step.find_functions())
    assert default.graph_size() == backward.graph_size()
    x0, p = initial_state(default.scene), default.default_p
    for h in (1e-3, 0.2):   # free fall, then a step deep into the ground
        a, b = default.step(x0, p, h), backward.step(x0, p, h)
        assert all(np.array_equal(np.asarray(u), np.asarray(v)) for u, v in zip(a, b))


def test_frictionless_scene_builds_no_slip_rule():
    plain = build_model(_scene(mu=0.0))
    midpoint = build_model(_scene(mu=0.0, slip="midpoint"))
    assert plain.graph_size() == midpoint.graph_size()
    assert not any("midpoint" in f.name() for f in midpoint.step.find_functions())


#: The optimiser's bound on AD against central differences (tests/test_optimise.py).
GRADIENT_TOL = 1e-5
#: Simulated time of the gradient case (s): the drift touchdown's first
#: 0.1 s, in which the feet land and slide sideways.
GRADIENT_DURATION = 0.1


def test_lander_gradient_with_the_midpoint_rule():
    # the lander design study's drift touchdown (1 m/s sideways, μ = 0.5),
    # shortened, with the midpoint slip rule: AD against central differences
    data = read_toml(ROOT / "studies" / "optimise_lander.toml")
    data["scene"].update(slip="midpoint", duration=GRADIENT_DURATION)
    data["scenario"] = [s for s in data["scenario"] if s["name"] == "drift"]
    problem = study_from_dict(data, "optimise_lander.toml:midpoint",
                              base_dir=ROOT / "studies").problem
    assert problem.scenarios[0].scene.slip == "midpoint"
    check = problem.check_gradient(problem.initial)
    assert check["relative"] <= GRADIENT_TOL, check
    assert check["objective"] <= GRADIENT_TOL, check
    assert check["worst_row"] <= GRADIENT_TOL, check
