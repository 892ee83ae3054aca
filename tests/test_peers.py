"""Peer simulators: penalty contact by CVODES and MuJoCo, against symcushion."""
import sys
from pathlib import Path

import numpy as np
import pytest

from symcushion.legs.characteristics import Linear, PiecewiseLinear
from symcushion.model.obstacles import ImplicitSurface, Plane
from symcushion.model.scene import Body, Scene, load_scene
from symcushion.scheme.touchdown import initial_state
from symcushion.run.driver import simulate
from symcushion.legs.strut import HingedStrut
from symcushion.peers import (PeerRun, mujoco_available, mujoco_simulate, penalty_simulate,
    rebound_speed, trajectory_deflection)

ROOT = Path(__file__).resolve().parents[1]
SLOPE = np.deg2rad(10.0)


# ---------------------------------------------------------------------------
# scenes
# ---------------------------------------------------------------------------
def fig3(duration=None):
    scene = load_scene(ROOT / "studies" / "fig3.toml").with_(method="implicit")
    return scene if duration is None else scene.with_(duration=duration)


def free_fall_scene():
    """Fig. 3's ball on its rods, thrown up 5 m above a plane: no contact in 0.3 s."""
    scene = fig3(duration=0.3).with_(obstacles=[Plane()])
    scene.body.position = np.array([0.3, -0.2, 5.0])
    scene.body.velocity = np.array([0.4, 0.1, 2.0])
    return scene


def slope_scene(duration=0.15):
    """Fig. 3's ball landing with 1 m/s of horizontal speed on a 10° slope, μ = 0.3."""
    scene = fig3(duration=duration).with_(
        obstacles=[Plane(normal=(np.sin(SLOPE), 0.0, np.cos(SLOPE)))], mu=0.3, name="slope")
    scene.body.velocity = np.array([1.0, 0.0, -0.5])
    # the uphill foot (x = −0.3 m) 1 mm above the plane z = −x tan 10°
    scene.body.position = np.array([0.0, 0.0, 0.78 + 0.3 * np.tan(SLOPE) + 1e-3])
    return scene


def hysteretic_scene():
    """One leg whose axial absorber has a (non-smooth) unloading branch."""
    S = PiecewiseLinear([-0.2, 0.0], [-2000.0, 0.0],
                        unloading=PiecewiseLinear([-0.2, -0.05, 0.0], [-300.0, -300.0, 0.0]))
    leg = HingedStrut(hinge=(0, 0, -0.1), e0=(0, 0, -1), en=(0, 0.6, -0.8), length=0.5,
                      S=S, M_beta=Linear(500.0), M_gamma=Linear(500.0))
    body = Body(mass=10.0, inertia=[0.5, 0.5, 0.5], position=[0, 0, 0.61],
                velocity=[0, 0, -1.0])
    return Scene(body, [leg], [Plane()], duration=0.2)


def parabola(scene, t):
    b = scene.body
    return b.position + np.outer(t, b.velocity) + 0.5 * np.outer(t ** 2, scene.gravity)


@pytest.fixture(scope="module")
def symcushion_fig3():
    scene = fig3()
    return scene, simulate(scene)


def check_run(run, scene):
    T, N = len(run.t), len(scene.legs)
    assert isinstance(run, PeerRun)
    assert run.position.shape == run.velocity.shape == run.acceleration.shape == (T, 3)
    assert run.attitude.shape == (T, 4) and run.foot.shape == (T, N, 3)
    assert run.stroke.shape == run.deflection.shape == run.contact.shape == (T, N)
    for name in ("position", "velocity", "acceleration", "attitude", "foot", "stroke",
                 "deflection"):
        assert np.all(np.isfinite(getattr(run, name))), name
    np.testing.assert_allclose(run.t, scene.dt * np.arange(T), rtol=0, atol=1e-12)


def kinetic_energy_deficit(scene, v_reference, v_peer):
    return 0.5 * scene.body.mass * (v_reference ** 2 - v_peer ** 2)


# ---------------------------------------------------------------------------
# penalty peer
# ---------------------------------------------------------------------------
def test_penalty_free_fall_follows_the_parabola_to_solver_tolerance():
    scene = free_fall_scene()
    rtol = 1e-10
    run = penalty_simulate(scene, rtol=rtol)
    check_run(run, scene)
    assert not run.contact.any()
    exact = parabola(scene, run.t)
    # CVODES controls the local error to rtol·|x| + atol; over ~100 steps of a
    # 5 m state the global error stays within a few hundred rtol·|x|
    tol = 1e3 * rtol * np.max(np.abs(exact))
    assert np.max(np.abs(run.position - exact)) < tol
    # the legs hang unloaded: the feet fall with the body, g on both
    assert np.max(np.abs(run.stroke)) < tol and np.max(run.deflection) < 1e-6
    assert run.info["steps"] > 0 and run.info["rhs_evaluations"] >= run.info["steps"]


def test_penalty_fig3_rebound_matches_symcushion_within_the_feet_energy(symcushion_fig3):
    scene, traj = symcushion_fig3
    v_sym = rebound_speed(traj, scene)
    devs = {}
    for ratio in (1e-4, 1e-5):
        m_f = ratio * scene.body.mass
        run = penalty_simulate(scene, rtol=1e-8, foot_mass=m_f)
        check_run(run, scene)
        v_pen = rebound_speed(run, scene)
        assert np.isfinite(v_pen)
        # The only energy the penalty model can lose that symcushion does not is
        # what its feet carry: each foot is stopped by the critically damped
        # contact at impact and accelerated again at lift-off, at most ½ m_f u²
        # twice, u the largest foot speed. Measured: 0.012 J of a 0.029 J budget
        # at 1e-4 (Δv = 4.6e-4 m/s), so this bound is what the physics permits.
        u_max = np.max(np.linalg.norm(run.info["foot_velocity"], axis=-1))
        deficit = kinetic_energy_deficit(scene, v_sym, v_pen)
        assert 0 < deficit <= len(scene.legs) * m_f * u_max ** 2
        devs[ratio] = abs(v_pen - v_sym)
    # and it vanishes with the foot mass (about linearly: 4.6e-4 → 2.8e-5 m/s)
    assert devs[1e-5] < devs[1e-4] / 3


def test_penalty_converges_as_rtol_tightens():
    scene = fig3(duration=0.2)
    runs = {rtol: penalty_simulate(scene, rtol=rtol) for rtol in (1e-5, 1e-7, 1e-9, 1e-10)}
    err = {rtol: np.max(np.abs(runs[rtol].velocity - runs[1e-10].velocity))
           for rtol in (1e-5, 1e-7, 1e-9)}
    # measured over 0.4 s: 3.5e-5, 2.1e-6, 5.0e-8 m/s, about rtol^0.7 (the
    # impact transient is non-smooth); four decades of rtol must buy two
    assert err[1e-9] < err[1e-7] < err[1e-5]
    assert err[1e-9] < err[1e-5] / 100


def test_penalty_runs_fig4_and_a_slope_with_horizontal_speed():
    scene = load_scene(ROOT / "studies" / "fig4.toml").with_(method="implicit", duration=1.0)
    run = penalty_simulate(scene, rtol=1e-7)
    check_run(run, scene)
    traj = simulate(scene)
    # μ = 0.05: the ball sticks on the dome as symcushion's does; the rest height
    # differs by the contact spring's sink (≈1e-6 m) and the creep at v_s
    assert run.contact[-1].all()
    assert abs(run.position[-1, 2] - traj.position[-1, 2]) < 1e-3
    defl_sym = trajectory_deflection(traj, scene)
    assert abs(run.deflection.max() - defl_sym.max()) < 0.01 * defl_sym.max()
    slope = slope_scene()
    run = penalty_simulate(slope, rtol=1e-7)
    check_run(run, slope)
    assert run.contact.any() and run.velocity[-1, 0] > 1.0   # lands and is pushed downhill


def test_penalty_bad_arguments_name_the_argument():
    scene = fig3(duration=0.01)
    for kwargs, name in [({"rtol": -1e-8}, "rtol"), ({"rtol": 0.5}, "rtol"),
                         ({"atol": 0.0}, "atol"), ({"stiffness": 0.0}, "stiffness"),
                         ({"damping": -1.0}, "damping"), ({"slip_velocity": np.nan},
                                                         "slip_velocity"),
                         ({"foot_mass": -1.0}, "foot_mass"), ({"output_dt": 1.0}, "output_dt"),
                         ({"x0": np.zeros(5)}, "x0")]:
        with pytest.raises(ValueError, match=f"`{name}`"):
            penalty_simulate(scene, **kwargs)
    with pytest.raises(TypeError, match="`foot_mass`"):
        penalty_simulate(scene, foot_mass="light")
    with pytest.raises(TypeError, match="`scene`"):
        penalty_simulate("studies/fig3.toml")
    with pytest.raises(ValueError, match="unloading"):
        penalty_simulate(hysteretic_scene())


def test_penalty_accepts_symcushion_and_own_state_layouts():
    scene = fig3(duration=0.05)
    a = penalty_simulate(scene, x0=initial_state(scene))
    own = np.concatenate([a.position[0], a.velocity[0], a.attitude[0], np.zeros(3),
                          *[np.concatenate([a.foot[0, j], a.velocity[0]]) for j in range(4)]])
    b = penalty_simulate(scene, x0=own)
    np.testing.assert_allclose(a.position, b.position, rtol=0, atol=1e-12)


# ---------------------------------------------------------------------------
# MuJoCo peer
# ---------------------------------------------------------------------------
def test_mujoco_simulate_without_mujoco_names_the_extra(monkeypatch):
    monkeypatch.setitem(sys.modules, "mujoco", None)    # makes `import mujoco` fail
    assert not mujoco_available()
    with pytest.raises(ImportError, match=r"pip install symcushion\[peers\]"):
        mujoco_simulate(fig3(duration=0.01))


def test_mujoco_model_has_the_scene_masses_and_stiffnesses():
    mujoco = pytest.importorskip("mujoco", reason="MuJoCo peer needs the optional `mujoco`")
    from symcushion.peers import build_mjcf

    scene = fig3()
    xml, settings = build_mjcf(scene)
    model = mujoco.MjModel.from_xml_string(xml)
    body = model.body("body")
    assert body.mass[0] == pytest.approx(scene.body.mass, rel=1e-12)
    np.testing.assert_allclose(np.sort(body.inertia), np.sort(np.linalg.eigvalsh(
        scene.body.inertia)), rtol=1e-12)
    m_f = settings["foot_mass"]
    assert m_f == pytest.approx(1e-4 * scene.body.mass)
    for j in range(len(scene.legs)):
        assert model.body(f"leg{j}").mass[0] == pytest.approx(m_f, rel=1e-12)
        for name in ("gamma", "beta"):
            joint = model.joint(f"leg{j}_{name}")
            assert joint.stiffness[0] == pytest.approx(1200.0)
            assert model.qpos_spring[model.jnt_qposadr[joint.id]] == 0.0
    assert model.nv == 6 + 2 * len(scene.legs)        # rigid rods: no slide joint
    assert model.opt.timestep == pytest.approx(settings["timestep"])
    assert model.opt.cone == mujoco.mjtCone.mjCONE_ELLIPTIC
    assert np.all(model.geom_condim[[model.geom(f"leg{j}_foot").id for j in range(4)]] == 1)
    np.testing.assert_allclose(model.opt.gravity, scene.gravity)
    # the stiff slide joint of the 'spring' option carries the rod's axial spring
    xml, _ = build_mjcf(scene.with_(mu=0.05), rigid_axial="spring")
    model = mujoco.MjModel.from_xml_string(xml)
    k_S = scene.legs[0].rest_stiffness_closed_form() @ scene.legs[0].e0 @ scene.legs[0].e0
    assert model.joint("leg0_axial").stiffness[0] == pytest.approx(k_S, rel=1e-12)
    assert model.geom("leg0_foot").condim[0] == 3
    assert model.geom("leg0_foot").friction[0] == pytest.approx(0.05)


def test_mujoco_free_fall_follows_the_parabola_up_to_euler_lag():
    pytest.importorskip("mujoco", reason="MuJoCo peer needs the optional `mujoco`")
    scene = free_fall_scene()
    run = mujoco_simulate(scene, timestep=1e-4)
    check_run(run, scene)
    assert not run.contact.any()
    # semi-implicit Euler: z_n = z₀ + v₀t + ½gt² + ½g h t exactly
    h = run.info["timestep"]
    lag = 0.5 * np.outer(run.t * h, scene.gravity)
    np.testing.assert_allclose(run.position, parabola(scene, run.t) + lag, rtol=0, atol=1e-9)
    assert np.max(run.deflection) < 1e-9


def test_mujoco_fig3_rebound_converges_to_symcushion_within_the_feet_energy(symcushion_fig3):
    pytest.importorskip("mujoco", reason="MuJoCo peer needs the optional `mujoco`")
    scene, traj = symcushion_fig3
    v_sym = rebound_speed(traj, scene)
    v = {}
    for h in (1e-4, 5e-5, 2.5e-5):
        run = mujoco_simulate(scene, timestep=h)
        v[h] = rebound_speed(run, scene)
    check_run(run, scene)
    # MuJoCo's step is first order: the error halves with h (measured
    # +6.4e-4, +1.4e-4, −1.1e-4 m/s against symcushion)
    assert abs(v[2.5e-5] - v_sym) < abs(v[1e-4] - v_sym)
    # Richardson's h → 0 limit loses to symcushion what the light feet carry off
    # (as in the penalty test): between 0 and N m_f u_max²
    v_limit = 2 * v[2.5e-5] - v[5e-5]
    u = np.linalg.norm(run.info["foot_velocity"], axis=-1)
    deficit = kinetic_energy_deficit(scene, v_sym, v_limit)
    assert 0 < deficit <= len(scene.legs) * run.info["foot_mass"] * np.max(u) ** 2


def test_mujoco_runs_fig4_and_a_slope_with_horizontal_speed():
    pytest.importorskip("mujoco", reason="MuJoCo peer needs the optional `mujoco`")
    scene = load_scene(ROOT / "studies" / "fig4.toml").with_(method="implicit", duration=1.0)
    run = mujoco_simulate(scene)
    check_run(run, scene)
    traj = simulate(scene)
    # sticks on the dome; MuJoCo's soft contact sinks ≤ 0.3 mm here
    assert run.contact[-1].all()
    assert abs(run.position[-1, 2] - traj.position[-1, 2]) < 1e-3
    slope = slope_scene()
    run = mujoco_simulate(slope)
    check_run(run, slope)
    assert run.contact.any() and run.velocity[-1, 0] > 1.0


def test_mujoco_rejects_what_it_cannot_represent():
    pytest.importorskip("mujoco", reason="MuJoCo peer needs the optional `mujoco`")
    with pytest.raises(ValueError, match="linear"):
        mujoco_simulate(hysteretic_scene())
    preloaded = fig3(duration=0.01)
    leg = preloaded.legs[0]
    preloaded.legs[0] = HingedStrut(leg.hinge, leg.e0, leg.en, leg.length,
                                    M_beta=Linear(1200.0, preload=5.0), M_gamma=Linear(1200.0))
    with pytest.raises(ValueError, match="preload"):
        mujoco_simulate(preloaded)
    bowl = fig3(duration=0.01).with_(obstacles=[ImplicitSurface(lambda p: p[2] - p[0] ** 2)])
    with pytest.raises(ValueError, match="Plane and Sphere"):
        mujoco_simulate(bowl)
    with pytest.raises(ValueError, match="`timestep`"):
        mujoco_simulate(fig3(duration=0.01), timestep=3e-4)
    with pytest.raises(ValueError, match="`rigid_axial`"):
        mujoco_simulate(fig3(duration=0.01), rigid_axial="stiff")
