"""The planar lock control (studies/lock_control.py): a stroke lock as a constraint.

The control is a model of its own (a planar body on two legs with stuck
feet), independent of the package, with an event-driven Filippov reference.
These tests pin its findings (docs/event-order.md, "A planar control of
the lock"): the chord branch rule converges at first order where a stroke
locks, the RATTLE lock with the holding-force test at second order and with
the reference's lock episodes; where a stroke also reverses without locking
(a direct switch) only the lock and the located switch together do.
"""
from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

PATH = Path(__file__).resolve().parent.parent / "studies" / "lock_control.py"


@pytest.fixture(scope="module")
def lock():
    spec = importlib.util.spec_from_file_location("lock_control", PATH)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def lock_only(lock):
    """Reference of the lock-only start, and each stepper's error at T over the Δt grid."""
    v0 = np.array(lock.SCENARIOS["lock-only"])
    segs, log, y_end = lock.reference(v0)
    runs = {name: [lock.stepper(h, how, v0) for h in lock.STEPS]
            for name, how in (("chord", None), ("hold", "hold"))}
    errors = {name: [max(q / lock.Q_SCALE, v / lock.V_SCALE)
                     for q, v in (lock.err(traj[-1], y_end) for traj, *_ in rs)]
              for name, rs in runs.items()}
    return dict(v0=v0, log=log, y_end=y_end, runs=runs, errors=errors)


def test_the_model_derivatives_agree_with_differences(lock):
    lock.check_gradients()


def test_the_reference_is_converged(lock, lock_only):
    finer = lock.reference(lock_only["v0"], 1e-13)[2]
    q, v = lock.err(finer, lock_only["y_end"])
    smallest = min(min(e) for e in lock_only["errors"].values())
    assert max(q / lock.Q_SCALE, v / lock.V_SCALE) < 1e-3 * smallest


def test_the_reference_locks_and_releases(lock, lock_only):
    kinds = [(old[i], new[i]) for _, old, new, _, _ in lock_only["log"] for i in range(2)
             if old[i] != new[i]]
    assert (lock.LOAD, lock.LOCK) in kinds and (lock.LOCK, lock.UNLOAD) in kinds
    # no direct switch between the curves: every change goes through a lock
    assert all(lock.LOCK in pair for pair in kinds)


def test_the_chord_rule_chatters_and_is_first_order(lock, lock_only):
    assert lock.slope(lock_only["errors"]["chord"]) < 1.2
    reversals = [sum(rev) for _, _, rev, _ in lock_only["runs"]["chord"]]
    assert reversals[-1] > 4 * reversals[1]      # grows like 1/Δt: a sliding mode


def test_the_rattle_lock_is_second_order_with_the_reference_locks(lock, lock_only):
    assert lock.slope(lock_only["errors"]["hold"]) >= 1.8
    n_locks = sum(1 for _, old, new, _, _ in lock_only["log"] for i in range(2)
                  if old[i] != lock.LOCK and new[i] == lock.LOCK)
    assert [locks for *_, locks in lock_only["runs"]["hold"]] == [n_locks] * len(lock.STEPS)


def test_direct_switches_need_the_lock_and_the_located_switch_together(lock):
    v0 = np.array(lock.SCENARIOS["direct-switch"])
    segs, log, y_end = lock.reference(v0)
    direct = [(old[i], new[i]) for _, old, new, _, _ in log for i in range(2)
              if old[i] != new[i] and lock.LOCK not in (old[i], new[i])]
    assert len(direct) >= 2
    orders = {}
    for name, how, switch in (("lock", "hold", False), ("switch", None, True),
                              ("both", "hold", True)):
        errors = []
        for h in lock.STEPS:
            q, v = lock.err(lock.stepper(h, how, v0, switch)[0][-1], y_end)
            errors.append(max(q / lock.Q_SCALE, v / lock.V_SCALE))
        orders[name] = lock.slope(errors)
    assert orders["lock"] < 1.3 and orders["switch"] < 1.3
    assert orders["both"] >= 1.8


# -- the memory law as the band stiffness grows (symcushion.legs.absorber) -------------------
def _memory_run(lock, v0, k_e, h):
    """Velocity Verlet on the control's model with each leg's axial force from the
    package's memory law (A1)-(A2) of the control's curves, elastic stiffness ``k_e``:
    the state (q, v) at T."""
    import casadi as ca

    from symcushion.legs import absorber
    from symcushion.legs.characteristics import Crushable, PiecewiseLinear
    curve = Crushable(lock.K, lock.F_C, lock.K_P, elastic_stiffness=k_e,
                      unloading=PiecewiseLinear([-1.0, -lock.C_U, 0.0], [-lock.S_U, -lock.S_U, 0.0]))
    x, s = ca.SX.sym("x", 2), ca.SX.sym("s", 2)      # x = −c: the package's deflection
    law = ca.Function("law", [x, s], [ca.vertcat(*[absorber.memory_force(curve, x[i], s[i])
                                                   for i in range(2)]),
                                      ca.vertcat(*[absorber.next_set(curve, x[i], s[i])
                                                   for i in range(2)])])
    to_load = ca.Function("to_load", [x], [ca.vertcat(*[absorber.set_on_loading(curve, x[i])
                                                        for i in range(2)])])

    def force(q, sets):
        c, G, Q, _ = lock.kin(q)
        f, sets_next = (np.asarray(a).ravel() for a in law(-c, sets))
        return Q + f @ G, sets_next                    # S = −f pushes the hinge off the foot

    q, v = lock.Q0.copy(), np.asarray(v0, dtype=float)
    sets = np.asarray(to_load(-lock.kin(q)[0])).ravel()   # on the loading curve at start
    F, _ = force(q, sets)
    for _ in range(int(round(lock.T / h))):
        v_half = v + 0.5 * h * lock.MINV * F
        q = q + h * v_half
        F, sets = force(q, sets)
        v = v_half + 0.5 * h * lock.MINV * F
    return np.r_[q, v]


def test_the_memory_law_tends_to_the_lock_as_its_band_stiffens(lock, lock_only):
    """Between its curves the memory law is elastic with stiffness k_e; as k_e grows its
    stroke moves less there, and its motion tends to the printed law's Filippov motion,
    which locks the stroke: the control's event-driven reference at T."""
    errors = []
    for k_e in (1e5, 1e6, 1e7):
        h = 0.2 / np.sqrt(k_e / lock.MASS)        # ω h = 0.2 on the band's fastest mode
        pos, vel = lock.err(_memory_run(lock, lock_only["v0"], k_e, h), lock_only["y_end"])
        errors.append(max(pos / lock.Q_SCALE, vel / lock.V_SCALE))
    assert errors[0] > errors[1] > errors[2], errors
    assert errors[2] < 0.1 * errors[0], errors
