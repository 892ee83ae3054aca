"""Absorbers with memory (symcushion.absorber): the law (A1)-(A4) and the step on it."""
from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from symcushion import absorber
from symcushion.characteristics import Crushable, Linear, PiecewiseLinear
from symcushion.layout import output_layout, state_layout
from symcushion.scene import load_scene
from symcushion.touchdown import build_model, initial_state

from conftest import STUDIES

HONEYCOMB = dict(stiffness=1e5, crush_force=2000.0, plateau_slope=5e3)


def _law(curve):
    """NumPy callables f(x, s), s⁺(x, s) of the memory law of ``curve``."""
    x, s = ca.SX.sym("x"), ca.SX.sym("s")
    f = ca.Function("f", [x, s], [absorber.memory_force(curve, x, s)])
    n = ca.Function("n", [x, s], [absorber.next_set(curve, x, s)])
    return (lambda a, b: float(f(a, b))), (lambda a, b: float(n(a, b)))


def _walk(curve, path):
    """Forces and sets along a path of deflections, the set carried from point to point."""
    force, step = _law(curve)
    s, forces, sets = 0.0, [], []
    for x in path:
        forces.append(force(x, s))
        s = step(x, s)
        sets.append(s)
    return np.array(forces), np.array(sets)


def test_honeycomb_crushes_at_its_force_unloads_elastically_and_keeps_its_stroke():
    curve = Crushable(**HONEYCOMB)
    down = np.linspace(0.0, -0.1, 201)
    back = np.linspace(-0.1, -0.05, 101)
    again = np.linspace(-0.05, -0.15, 201)
    forces, sets = _walk(curve, np.r_[down, back, again])
    onset = -HONEYCOMB["crush_force"] / HONEYCOMB["stiffness"]
    # loading: elastic to the crush force, then the plateau
    np.testing.assert_allclose(forces[200], -2000.0 + 5e3 * (-0.1 - onset), rtol=1e-12)
    # unloading: along the elastic line k(x − s) from where crushing stopped
    s_after = sets[200]
    np.testing.assert_allclose(s_after, -0.1 + 2400.0 / 1e5, rtol=1e-12)
    np.testing.assert_allclose(forces[201:302], 1e5 * (back - s_after), rtol=1e-12)
    np.testing.assert_array_equal(sets[201:302], s_after)
    # reloading: elastic up to the loading curve at the old stroke, then crushing on
    crushing = np.diff(np.r_[0.0, sets]) < 0
    path = np.r_[down, back, again]
    loading = np.where(path < onset, -2000.0 + 5e3 * (path - onset), 1e5 * path)
    assert np.all(forces[crushing] <= loading[crushing] + 1e-9)
    assert not crushing[201:302 + 100].any()
    assert crushing[-1]


def test_the_force_is_continuous_along_any_path():
    curve = Crushable(**HONEYCOMB, unloading=PiecewiseLinear([-0.3, -0.03, 0.0],
                                                            [-450.0, -450.0, 0.0]))
    rng = np.random.default_rng(3)
    path = np.cumsum(rng.normal(0.0, 1e-4, 4000)) - 0.05
    forces, _ = _walk(curve, path)
    # a force that jumped between the curves would change by ~1.5 kN in one 0.1-mm step
    assert np.max(np.abs(np.diff(forces))) <= 1e5 * np.max(np.abs(np.diff(path))) * (1 + 1e-9)


def test_free_deflection_is_the_set_or_the_spring_back_curves_zero():
    bare = Crushable(**HONEYCOMB)
    sprung = Crushable(**HONEYCOMB, unloading=PiecewiseLinear([-0.3, -0.03, -0.01],
                                                              [-450.0, -450.0, 0.0]))
    free = lambda c, s: float(absorber.free_deflection(c, s))  # noqa: E731
    assert free(bare, -0.07) == -0.07            # it keeps its crushed stroke
    assert free(sprung, -0.07) == pytest.approx(-0.01)  # pushed out to f_U = 0 at −0.01
    assert free(sprung, -0.005) == -0.005        # zero force is inside the band there
    assert float(PiecewiseLinear([-0.3, -0.03, 0.0], [-450.0, -450.0, 0.0]).loading_zero()) == 0.0


def test_large_elastic_stiffness_tends_to_the_printed_laws_branches():
    """As k_e → ∞ the band's elastic line turns vertical: a compression follows the
    loading curve, an extension the unloading curve, as the printed law does."""
    unloading = Linear(5e3)
    down, back = np.linspace(0, -0.1, 10001), np.linspace(-0.1, -0.02, 8001)[1:]
    printed = np.r_[Crushable(**HONEYCOMB).force(down, -1.0), unloading.force(back)]
    errors = []
    for k_e in (1e6, 1e7, 1e8):
        curve = Crushable(**HONEYCOMB, unloading=unloading, elastic_stiffness=k_e)
        forces, _ = _walk(curve, np.r_[down, back])
        # the mean over the path: the band is crossed over a stroke (f_L − f_U)/k_e
        errors.append(np.mean(np.abs(forces - printed)))
    ratios = np.array(errors[:-1]) / np.array(errors[1:])
    assert np.all(ratios > 5), (errors, ratios)   # O(1/k_e): a tenth per decade


def test_a_free_damped_element_relaxes_at_second_order():
    """(A4) on the elastic line: x(t) = s + (x₀ − s) e^(−k t/c), BDF2 second order."""
    k, c, s, x0, T = 1e5, 2e3, -0.02, -0.05, 0.05
    curve = Crushable(k, 1e6, damping=c)          # crush force far away: elastic
    errors = []
    for dt in (2e-3, 1e-3, 5e-4, 2.5e-4):
        x, rate = x0, 0.0
        exact_prev = x0
        for n in range(int(round(T / dt))):
            # start the two-step rule with the exact first rate, as a step after another does
            if n == 0:
                rate = -k / c * (x0 - s)
            x1 = float(absorber.relaxed_deflection(curve, x, s, rate, dt))
            rate, x = (x1 - x) / dt, x1
            exact_prev = s + (x0 - s) * np.exp(-k / c * (n + 1) * dt)
        errors.append(abs(x - exact_prev))
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all(orders > 1.8), orders


def _lunar(hysteresis, dt=1e-3, slip="midpoint", duration=None):
    scene = load_scene(STUDIES / "lunar_lander300.toml").with_(hysteresis=hysteresis, dt=dt,
                                                                slip=slip)
    if duration is not None:
        scene = scene.with_(duration=duration)
    model = build_model(scene)
    X, Y = model.rollout(scene.steps)(initial_state(scene), model.default_p, dt)
    return scene, np.asarray(X), np.asarray(Y)


@pytest.fixture(scope="module")
def lunar_memory():
    return _lunar("memory")


def test_lunar_lander_crushes_only_at_the_crush_force(lunar_memory):
    """No stroke grows while the leg's axial force is below its loading curve: every
    step in which a set moves inwards carries at least the crush force."""
    scene, X, Y = lunar_memory
    n = len(scene.legs)
    sets = state_layout(n).legs(X, "stroke_set")
    yl = output_layout(n)
    axial = -np.einsum("jkt,jkt->jt", yl.legs(Y, "force"), yl.legs(Y, "axis"))
    crush = scene.legs[0].elements[0].curve.param_values[1]
    crushing = np.diff(np.c_[np.zeros(n), sets], axis=1) < -1e-12
    assert crushing.sum() > 50
    assert np.all(axial[crushing] >= crush * (1 - 1e-9))
    # the energy the crushing absorbed: at least the crush force times the crushed stroke
    crushed = -np.where(crushing, np.diff(np.c_[np.zeros(n), sets], axis=1), 0.0)
    absorbed = np.sum(axial * crushed, axis=1)
    assert np.all(absorbed >= crush * crushed.sum(axis=1) * (1 - 0.01))


def test_the_printed_law_crushes_below_the_crush_force():
    """The defect the memory law removes, measured on the printed law: legs crush
    (their stroke grows) in steps whose axial force is a third of the crush force."""
    scene, X, Y = _lunar("sign", slip="backward")
    yl = output_layout(len(scene.legs))
    stroke = yl.legs(Y, "stroke")
    axial = -np.einsum("jkt,jkt->jt", yl.legs(Y, "force"), yl.legs(Y, "axis"))
    grows = np.diff(stroke, axis=1) < -1e-6
    assert np.any(grows & (axial[:, 1:] < 1000.0))


def test_memory_law_on_the_lunar_lander_is_second_order():
    """Final position at Δt = 2 … 0.25 ms against 31.25 µs: order ≥ 1.8, and under
    0.5 % of the travel at 1 ms (memory law, midpoint slip)."""
    finals = {}
    for dt in (2e-3, 1e-3, 5e-4, 2.5e-4, 3.125e-5):
        scene, X, _ = _lunar("memory", dt=dt)
        finals[dt] = state_layout(len(scene.legs)).get(X, "position")[:, -1]
    x0 = initial_state(scene)[:3]
    ref = finals.pop(3.125e-5)
    travel = np.linalg.norm(ref - x0)
    errors = np.array([np.linalg.norm(finals[dt] - ref) / travel for dt in sorted(finals)[::-1]])
    order = np.polyfit(np.log(sorted(finals)[::-1]), np.log(errors), 1)[0]
    assert order >= 1.8, (order, errors)
    assert errors[1] < 5e-3, errors


def test_memory_law_settings_are_checked():
    scene = load_scene(STUDIES / "lunar_lander300.toml")
    with pytest.raises(ValueError, match="events"):
        scene.with_(hysteresis="memory", events="branch")
    with pytest.raises(ValueError, match="hysteresis"):
        scene.with_(hysteresis="elastic")
    with pytest.raises(ValueError, match="damping"):
        Crushable(**HONEYCOMB, damping=-1.0)


def _rest(dt):
    """Largest force jump over the mean force, and the std of the vertical acceleration,
    of the damped lander after t = 0.5 s."""
    scene = load_scene(STUDIES / "lander_damped.toml").with_(dt=dt)
    model = build_model(scene)
    _, Y = model.rollout(scene.steps)(initial_state(scene), model.default_p, dt)
    Y = np.asarray(Y)
    yl = output_layout(len(scene.legs))
    rest = dt * np.arange(1, scene.steps + 1) > 0.5
    force = np.linalg.norm(yl.legs(Y, "force"), axis=1)[:, rest]
    jump = np.max(np.abs(np.diff(force, axis=1)), axis=1) / np.mean(force, axis=1)
    return np.max(jump), np.std(yl.get(Y, "acceleration")[2, rest])


def test_the_damped_lander_comes_to_rest_without_chatter():
    """After 0.5 s no contact force jumps by 5 % of its leg's mean in a step, the vertical
    acceleration's spread is under 0.05 m/s², and it is the same at half the step (what
    remains is physics, not the step)."""
    jump, spread = _rest(1e-3)
    jump_half, spread_half = _rest(5e-4)
    assert jump < 0.05 and jump_half < 0.05, (jump, jump_half)
    assert spread <= 0.05, spread
    assert abs(spread - spread_half) <= 0.1 * spread_half, (spread, spread_half)
