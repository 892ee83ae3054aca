"""The absorbers' stroke lock (``events = "lock"``, ``symcushion.scheme.stroke_lock``).

A crushable leg whose stroke turns with its load between the loading and the
unloading curve holds its stroke (the Filippov motion of P(δ_S, sign δ_S′));
the default step and the located switch imitate that by alternating
branches, an O(Δt) error. These tests check that the lock does what it
claims and nothing else: on the lander whose feet stick (level ground,
μ = 2, the study's "stick, flat" variant) the step converges at second order
where the located switch alone does not; a locked stroke is held to
round-off with its force between the curves; the number of lock episodes
does not grow as Δt falls; the scenes without an unloading branch build the
step unchanged; the option is validated; the solves stay finite where four
locked legs are dependent; gradients through a lock match finite differences.
"""
from __future__ import annotations

from pathlib import Path

import casadi as ca
import numpy as np
import pytest

from symcushion.layout.vectors import state_layout
from symcushion.scheme.quaternion import quat_to_rot_np
from symcushion.model.scene import load_scene, read_toml, scene_from_dict
from symcushion.scheme.touchdown import build_model, initial_state
from symcushion.run.driver import simulate
from symcushion.scheme import touchdown_events as touchdown
from symcushion.scheme.stroke_lock import (LOCKED, UNLOADING, axial_branches, newton_masked,
    skip_unless, solve_masked)
from symcushion.run.error_control import fitted_order

from research import event_order   # not installed: tests/conftest.py puts it on sys.path

ROOT = Path(__file__).resolve().parent.parent

#: Δt of the order fit (s): five halvings from 2 ms.
DTS = (2e-3, 1e-3, 5e-4, 2.5e-4, 1.25e-4)
#: Reference and its check (s): 4× and 8× below the finest fitted Δt (the
#: lock converges at second order, so the reference's error is 1/16 of it).
REF_DT, CHECK_DT = 3.125e-5, 1.5625e-5
#: Simulated time (s): touchdown, crush, the turn onto the unloading curves,
#: two legs lifting off, the other two locking (0.257 s) and releasing (0.378 s).
DURATION = 0.42
MIN_SECOND_ORDER = 1.8
#: The located switch alone on the same scene, measured at order 0.9 (the
#: legs chatter between their curves where they should hold).
MAX_SWITCH_ORDER = 1.5
REF_SHARE = 0.1


def _scene(events):
    data = event_order._variant_data(read_toml(ROOT / "studies" / "lander_slope.toml"),
                                     "stick, flat", "midpoint", events)
    return scene_from_dict(data, f"stick-flat:{events}").with_(duration=DURATION)


def _final(scene, model, dt):
    traj = simulate(scene.with_(dt=dt), model=model, monitor=False)
    return np.concatenate([traj.position[-1], traj.velocity[-1]]), traj


@pytest.fixture(scope="module")
def lock_runs():
    scene = _scene("lock")
    model = build_model(scene)
    ref, ref_traj = _final(scene, model, REF_DT)
    check, _ = _final(scene, model, CHECK_DT)
    runs = {dt: _final(scene, model, dt) for dt in DTS}
    return dict(scene=scene, model=model, ref=ref, ref_traj=ref_traj,
                ref_error=float(np.linalg.norm(ref - check)),
                errors=np.array([np.linalg.norm(runs[dt][0] - ref) for dt in DTS]),
                runs=runs)


def test_second_order_through_locks(lock_runs):
    errors = lock_runs["errors"]
    assert lock_runs["ref_error"] <= REF_SHARE * errors.min(), (lock_runs["ref_error"], errors)
    order = fitted_order(DTS, errors)
    assert order >= MIN_SECOND_ORDER, (order, errors)


def test_the_located_switch_alone_is_not_second_order_there():
    scene = _scene("branch")
    model = build_model(scene)
    ref, _ = _final(scene, model, REF_DT)
    errors = [np.linalg.norm(_final(scene, model, dt)[0] - ref) for dt in DTS]
    order = fitted_order(DTS, errors)
    assert order <= MAX_SWITCH_ORDER, (order, errors)


def _flags(model, scene, dt):
    """The state's contact flags (steps × legs) of a run and its states."""
    n = round(scene.duration / dt)
    X, Y = model.rollout(n)(initial_state(scene), model.default_p, dt)
    X = np.asarray(X)
    xl = state_layout(model.n_legs)
    return np.array([[xl.get(X[:, k], "contact", j) for j in range(model.n_legs)]
                     for k in range(n)]), X


def test_the_locks_happen_and_their_number_does_not_grow(lock_runs):
    # the same lock episodes at every Δt: entries into the lock per leg
    scene, model = lock_runs["scene"], lock_runs["model"]
    entries = []
    for dt in (1e-3, 2.5e-4):
        flags, _ = _flags(model, scene, dt)
        locked = np.isclose(flags, LOCKED)
        entries.append(np.sum(np.diff(locked.astype(int), axis=0) == 1, axis=0))
    assert entries[0].sum() >= 2, entries           # the scene does lock
    np.testing.assert_array_equal(entries[0], entries[1])
    assert set(np.unique(flags)) <= {0.0, 1.0, LOCKED, UNLOADING}


def test_a_locked_stroke_is_held_between_the_curves(lock_runs):
    scene, model = lock_runs["scene"], lock_runs["model"]
    flags, X = _flags(model, scene, 1e-3)
    xl = state_layout(model.n_legs)
    r = ca.SX.sym("r", 3)
    held_steps = 0
    for j, leg in enumerate(scene.legs):
        fns = leg.functions()
        ax = axial_branches(fns, ca.DM.zeros(0), r)
        curves = ca.Function("curves", [r], [ax["lo"], ax["hi"], ax["delta_S"], ax["e_S"]])
        for k in range(1, flags.shape[0]):
            if not (np.isclose(flags[k - 1, j], LOCKED) and np.isclose(flags[k, j], LOCKED)):
                continue
            held = []
            for i in (k - 1, k):
                x = X[:, i]
                rho = quat_to_rot_np(xl.get(x, "attitude")).T @ (
                    xl.get(x, "foot", j) - xl.get(x, "position"))
                lo, hi, stroke, e_S = (np.asarray(v, float).ravel() for v in curves(rho))
                held.append((stroke[0], float(xl.get(x, "force_body", j) @ e_S), lo[0], hi[0]))
            (s0, _, _, _), (s1, S, lo, hi) = held
            assert abs(s1 - s0) <= 1e-12, (j, k, s0, s1)          # the stroke is held
            assert lo <= S <= hi, (j, k, lo, S, hi)               # by a force between the curves
            np.testing.assert_allclose(xl.get(X[:, k], "foot", j), xl.get(X[:, k - 1], "foot", j),
                                       atol=1e-15)                # on a foot that sticks
            held_steps += 1
    assert held_steps > 50


def _same_step(scene):
    plain, lock = build_model(scene), build_model(scene.with_(events="lock"))
    assert plain.graph_size() == lock.graph_size()
    x0, p = initial_state(scene), plain.default_p
    for h in (1e-3, 0.2):
        a, b = plain.step(x0, p, h), lock.step(x0, p, h)
        assert all(np.array_equal(np.asarray(u), np.asarray(v)) for u, v in zip(a, b))


def test_fig_4_is_unchanged():
    # no unloading branch on the dome legs: nothing to lock
    _same_step(load_scene(ROOT / "studies" / "fig4.toml"))


def test_without_unloading_branch_the_step_is_unchanged():
    data = event_order._variant_data(read_toml(ROOT / "studies" / "lander_slope.toml"),
                                     "elastic", "midpoint")
    _same_step(scene_from_dict(data, "elastic"))


def test_without_friction_the_lock_is_refused():
    scene = load_scene(ROOT / "studies" / "lander_slope.toml")
    with pytest.raises(ValueError, match="`events` = 'lock'.*mu = 0"):
        scene.with_(mu=0.0, events="lock")
    data = read_toml(ROOT / "studies" / "lander_slope.toml")
    data["scene"].update(events="lock", mu=0.0)
    with pytest.raises(ValueError, match="events = 'branch'"):
        scene_from_dict(data, "frictionless.toml")


def test_the_lock_and_the_split_add_gated_calls_of_their_own():
    scene = load_scene(ROOT / "studies" / "lander_slope.toml")
    branch = build_model(scene.with_(events="branch", slip="midpoint"))
    lock = build_model(scene.with_(events="lock", slip="midpoint"))
    # the located switch's split contact step is in calls of its own, one per leg; the
    # lock splits its direct switches the same way
    splits = {f"touchdown_split_{j}" for j in range(len(scene.legs))}
    assert set(branch.gated) == splits
    assert set(lock.gated) == splits | {"touchdown_lock_shake", "touchdown_lock_hold"}
    # the lock's work is in calls that run only in the steps that need it
    assert lock.graph_size()["gated"] > branch.graph_size()["instructions"]


def _masked(n):
    A, b, m = ca.SX.sym("A", n, n), ca.SX.sym("b", n), ca.SX.sym("m", n)
    return ca.Function("masked", [A, b, m], [solve_masked(A, b, [m[i] > 0.5 for i in range(n)])])


def test_masked_solve():
    f = _masked(3)
    rng = np.random.default_rng(3)
    G = rng.normal(size=(3, 6))
    A = -G @ G.T                                      # the lock's matrices: negative definite
    b = rng.normal(size=3)
    np.testing.assert_allclose(np.asarray(f(A, b, [1, 1, 1])).ravel(), np.linalg.solve(A, b),
                               rtol=1e-8)
    x = np.asarray(f(A, b, [1, 0, 1])).ravel()
    assert x[1] == 0.0
    np.testing.assert_allclose(x[[0, 2]], np.linalg.solve(A[np.ix_([0, 2], [0, 2])], b[[0, 2]]),
                               rtol=1e-8)
    assert np.all(np.asarray(f(A, b, [0, 0, 0])) == 0.0)


def test_dependent_held_strokes_get_finite_forces():
    # four legs of a symmetric lander: the alternating sum of their rows vanishes; the
    # consistent right-hand side has solutions differing by a self-stress, and the shift
    # picks the one without it
    f = _masked(4)
    e = np.array([[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0], [0.0, -1.0]])
    G = np.hstack([e, np.ones((4, 1))])               # rows sum to zero with signs (+,−,+,−)
    A = -G @ G.T
    target = np.array([1.0, -2.0, 0.5])
    b = A @ np.linalg.pinv(A) @ (G @ target)          # a consistent right-hand side
    x = np.asarray(f(A, b, [1, 1, 1, 1])).ravel()
    assert np.all(np.isfinite(x))
    np.testing.assert_allclose(A @ x, b, atol=1e-6 * np.abs(b).max())
    # no self-stress: what is left is b's round-off along the null direction (1e-16)
    # over the shift (1e-10), where the unshifted QR solve gave ±2.8e3
    assert abs(x @ np.array([1, -1, 1, -1])) <= 1e-4 * np.abs(x).max()


def test_newton_masked_finds_the_root():
    u = ca.SX.sym("u", 2)
    # nearly affine, as the held stroke in Λ: SHAKE_ITERATIONS reach round-off
    residual = ca.vertcat(u[0] + 0.01 * u[0] ** 2 - 0.5, u[1] - 3.0)
    x = np.asarray(ca.evalf(newton_masked(residual, u, [ca.SX(1), ca.SX(0)]))).ravel()
    assert abs(x[0] + 0.01 * x[0] ** 2 - 0.5) <= 1e-15 and x[1] == 0.0


def test_gradient_through_a_lock(lock_runs):
    # AD against central differences of 20 steps across a lock, from a state where two legs
    # are about to lock (0.25 s, the lock begins at 0.257 s)
    scene, model = lock_runs["scene"], lock_runs["model"]
    dt = 1e-3
    flags, X = _flags(model, scene, dt)
    k = round(0.25 / dt) - 1
    assert not np.any(np.isclose(flags[k], LOCKED))
    assert np.any(np.isclose(flags[k + 20], LOCKED))
    x0 = X[:, k]
    roll = model.rollout(20)
    xs = ca.MX.sym("x", model.nx)
    end = roll(xs, model.default_p, dt)[0][:, -1]
    jac = ca.Function("end_jacobian", [xs], [ca.jacobian(end, xs)])
    J = np.asarray(jac(x0))
    xl = state_layout(model.n_legs)
    for name in ("velocity", "angular_velocity"):
        for i in range(3):
            col = xl.slice(name).start + i
            step = 1e-7
            up, down = x0.copy(), x0.copy()
            up[col] += step
            down[col] -= step
            fd = (np.asarray(roll(up, model.default_p, dt)[0])[:, -1]
                  - np.asarray(roll(down, model.default_p, dt)[0])[:, -1]) / (2 * step)
            body = slice(0, xl.slice("angular_velocity").stop)
            np.testing.assert_allclose(J[body, col], fd[body], rtol=1e-5,
                                       atol=1e-5 * np.abs(fd[body]).max())


def test_skip_unless_gives_the_list_its_flag_picks():
    x, c = ca.SX.sym("x"), ca.SX.sym("c")
    # `on` is NaN for x < 0: a branch-free if_else would carry it into the result
    on, off = [ca.sqrt(x) * x, ca.SX(1.0)], [2 * x, ca.SX(0.0)]
    (y, flag), f_on = skip_unless("gate_test", c > 0.5, [x], [x], on, off)
    f = ca.Function("f", [x, c], [y, flag, ca.jacobian(y, x)])
    assert f_on.n_instructions() > 0
    for xv, cv, want, dwant in ((4.0, 1.0, 8.0, 3.0), (-4.0, 0.0, -8.0, 2.0),
                                (4.0, 0.0, 8.0, 2.0)):
        yv, fv, dv = (float(v) for v in f(xv, cv))
        assert (yv, fv, dv) == (want, cv, dwant)


def test_the_skipped_lock_gives_the_bits_of_the_lock_run_every_step(monkeypatch):
    # the same scene with the lock's work inlined into every step, as a branch-free graph
    scene = _scene("lock").with_(duration=0.3)
    gated = build_model(scene)

    def inline(name, flag, inputs, args, on, off):
        return ca.substitute(on, inputs, args), ca.Function(name, inputs, on)

    monkeypatch.setattr(touchdown, "skip_unless", inline)
    every_step = build_model(scene)
    assert every_step.step.n_instructions() > 2 * gated.step.n_instructions()
    dt = 1e-3
    flags, X = _flags(gated, scene, dt)
    assert np.any(np.isclose(flags, LOCKED)) and not np.all(np.isclose(flags, LOCKED))
    x0 = np.asarray(initial_state(scene)).ravel()
    steps = round(scene.duration / dt)
    a = gated.step.mapaccum(steps)(x0, gated.default_p, dt)
    b = every_step.step.mapaccum(steps)(x0, every_step.default_p, dt)
    for u, v in zip(a, b):
        assert np.array_equal(np.asarray(u), np.asarray(v))
    # and the Jacobian of 20 steps across the lock entry at 0.257 s
    xs = ca.MX.sym("x", gated.nx)
    k = round(0.25 / dt) - 1
    jac = [np.asarray(ca.Function("J", [xs], [ca.jacobian(
        m.step.mapaccum(20)(xs, m.default_p, dt)[0][:, -1], xs)])(X[:, k]))
           for m in (gated, every_step)]
    assert np.array_equal(*jac)
