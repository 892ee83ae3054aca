"""Tests of the contact steps in symcushion.contact (docs/contact-spec.md).

Invariants (hypothesis), the exact implicit step, one test per weak point of
the printed method (docs/paper-notes.md §3 items 1-5: each must fail with 'paper', checked
by ``printed_step_fails``, and pass with 'robust'), the 3-D error (item 6),
Jacobians, and the validation of :func:`solve_contact`.
"""
import functools

import casadi as ca
import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from bench_contact import plane_parallel_cases   # studies/: tests/conftest.py puts it on sys.path
from symcushion.contact import (INPUT_NAMES, METHODS, OUTPUT_NAMES, ContactResult, contact_step,
    contact_step_expr, solve_contact, stack_inputs)

# Tolerances of the tests (not of the method).
CONE_RTOL = 1e-10  # C(P) <= CONE_RTOL |P|^2 in contact (brief)
NORMAL_RTOL = 1e-12  # n.delta = n.l to round-off, relative to |l| + |delta|
RAY_RTOL = 1e-10  # mu = 0: |P_tau| <= RAY_RTOL |P| (the cone is the ray along n)
COULOMB_RTOL = 1e-10  # P_tau parallel to g, docs/paper-notes.md §3.6 example
RESIDUAL_RTOL = 1e-13  # implicit step converged, |R| / |P_t|

SETTINGS = settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
Z = np.array([0.0, 0.0, 1.0])
def printed_step_fails(test):
    """Run a docs/paper-notes.md §3 fix check: it must hold for 'robust' and must FAIL for 'paper'.

    For 'paper' the test body's assertion is required to raise, so the weak
    point of the printed method is demonstrated, not assumed.
    """
    @functools.wraps(test)
    def wrapper(method, *args, **kwargs):
        if method == "paper":
            with pytest.raises(AssertionError):
                test(method, *args, **kwargs)
        else:
            test(method, *args, **kwargs)
    return wrapper


# ---------------------------------------------------------------------------
# helpers
# ---------------------------------------------------------------------------
def step(method, P0, Dp, n, l, mu, u0=None):
    """Evaluate the cached Function; dict of flat numpy arrays."""
    u0 = np.zeros(3) if u0 is None else u0
    out = contact_step(method)(P0, Dp, n, l, mu, u0)
    return {k: np.array(v).ravel() for k, v in zip(OUTPUT_NAMES, out)}


def batch(method, cases):
    """Evaluate a list of (P0, Dp, n, l, mu, u0) with .map; dict of (3, N) arrays."""
    f = contact_step(method).map(len(cases))
    return {k: np.array(v) for k, v in zip(OUTPUT_NAMES, f(*stack_inputs(cases)))}





def cone(P, n, mu):
    """C(P) = P.P - (1 + mu^2)(n.P)^2 (1.5)."""
    return P @ P - (1 + mu**2) * (n @ P) ** 2


def tangential(P, n):
    return P - (n @ P) * n


def rotation(rng):
    Q, R = np.linalg.qr(rng.normal(size=(3, 3)))
    return Q * np.sign(np.diag(R))


def spd(rng, cond, scale=1.0):
    ev = 10 ** rng.uniform(0, np.log10(cond), 3)
    ev[0], ev[1] = 1.0, cond
    Q = rotation(rng)
    return scale * Q @ np.diag(ev) @ Q.T


# ---------------------------------------------------------------------------
# hypothesis strategies
# ---------------------------------------------------------------------------
finite = dict(allow_nan=False, allow_infinity=False)


@st.composite
def unit_vectors(draw):
    v = np.array(draw(st.lists(st.floats(-1, 1, **finite), min_size=3, max_size=3)))
    assume(np.linalg.norm(v) > 0.1)
    return v / np.linalg.norm(v)


@st.composite
def stiffness(draw, max_log_cond=4.0, kinds=("spd", "skew", "general")):
    """D_p: symmetric positive definite, plus optionally a skew or general part."""
    Q, R = np.linalg.qr(np.array(draw(st.lists(st.floats(-1, 1, **finite), min_size=9, max_size=9))).reshape(3, 3))
    assume(np.min(np.abs(np.diag(R))) > 1e-2)
    log_ev = np.array(draw(st.lists(st.floats(0, max_log_cond, **finite), min_size=3, max_size=3)))
    scale = 10 ** draw(st.floats(-1, 4, **finite))
    Dp = scale * Q @ np.diag(10**log_ev) @ Q.T
    kind = draw(st.sampled_from(kinds))
    if kind != "spd":
        W = np.array(draw(st.lists(st.floats(-1, 1, **finite), min_size=9, max_size=9))).reshape(3, 3)
        if kind == "skew":
            W = W - W.T
        Dp = Dp + draw(st.floats(0, 0.5, **finite)) * np.linalg.norm(Dp, 2) * W
    return Dp


@st.composite
def contact_cases(draw, max_log_cond=4.0, kinds=("spd", "skew", "general"), mu=None, admissible=True):
    """(P0, Dp, n, l, mu, u0) with P0 inside or on the cone (as a previous step leaves it)."""
    n = draw(unit_vectors())
    Dp = draw(stiffness(max_log_cond, kinds))
    mu = draw(st.one_of(st.just(0.0), st.floats(0, 2, **finite))) if mu is None else mu
    t = draw(unit_vectors())
    t = t - (t @ n) * n
    assume(np.linalg.norm(t) > 0.1)
    t /= np.linalg.norm(t)
    N0 = 10 ** draw(st.floats(-3, 3, **finite))
    fraction = draw(st.one_of(st.just(1.0), st.floats(0, 1, **finite)))
    if admissible:
        P0 = N0 * (n + fraction * mu * t)
    else:
        P0 = N0 * np.array(draw(st.lists(st.floats(-1, 1, **finite), min_size=3, max_size=3)))
    l_dir = np.array(draw(st.lists(st.floats(-1, 1, **finite), min_size=3, max_size=3)))
    l = l_dir * N0 / np.linalg.norm(Dp, 2) * 10 ** draw(st.floats(-3, 1, **finite))
    try:
        u0 = np.linalg.solve(Dp, P0)
    except np.linalg.LinAlgError:
        u0 = np.zeros(3)
    return P0, Dp, n, l, mu, u0


# ---------------------------------------------------------------------------
# Function signature and API
# ---------------------------------------------------------------------------
@pytest.mark.parametrize("method", METHODS)
def test_function_names_and_io(method):
    f = contact_step(method)
    assert f.name() == f"contact_step_{method}"
    assert f.name_in() == INPUT_NAMES
    assert f.name_out() == OUTPUT_NAMES
    assert [f.size_in(i) for i in range(6)] == [(3, 1), (3, 3), (3, 1), (3, 1), (1, 1), (3, 1)]
    assert [f.size_out(i) for i in range(4)] == [(3, 1), (3, 1), (3, 1), (1, 1)]
    assert contact_step(method) is f  # cached
    assert f.is_a("SXFunction")


def test_contact_step_rejects_unknown_method():
    with pytest.raises(ValueError, match=r"`method` must be one of 'paper', 'robust', 'implicit'; got 'explicit'"):
        contact_step("explicit")
    with pytest.raises(TypeError, match="`friction`"):
        contact_step("robust", friction="no")


@pytest.mark.parametrize("method", METHODS)
def test_frictionless_graph_is_smaller_and_equal_at_mu_zero(method):
    full, small = contact_step(method), contact_step(method, friction=False)
    assert small.name() == f"contact_step_{method}_frictionless"
    assert small.n_instructions() < full.n_instructions()
    rng = np.random.default_rng(1)
    for i in range(100):
        Dp = spd(rng, 100.0, 50.0)
        if i % 2:  # indefinite and non-symmetric: the pole logic must match too
            Dp = Dp + 20.0 * rng.normal(size=(3, 3))
        n = rng.normal(size=3)
        n /= np.linalg.norm(n)
        P0 = n * rng.uniform(0.1, 2)
        args = (P0, Dp, n, rng.normal(size=3) * 0.01, 0.0, np.linalg.solve(Dp, P0))
        a = [np.array(v) for v in full(*args)]
        b = [np.array(v) for v in small(*args)]
        for x, y in zip(a, b):
            np.testing.assert_allclose(x, y, rtol=0, atol=1e-12 * (1 + np.abs(x).max()))
    # mu given as the literal 0.0 selects the frictionless graph
    P0, Dp, n, l = ca.SX.sym("P0", 3), ca.SX.sym("Dp", 3, 3), ca.SX.sym("n", 3), ca.SX.sym("l", 3)
    u0 = ca.SX.sym("u0", 3)
    out = contact_step_expr(method, P0, Dp, n, l, 0.0, u0)
    g = ca.Function("g", [P0, Dp, n, l, u0], [out["P"]])
    assert g.n_instructions() <= small.n_instructions()


@pytest.mark.parametrize("method", METHODS)
def test_inlined_expressions_equal_function(method):
    """contact_step_expr inlined in a larger graph gives the Function's numbers."""
    x = ca.SX.sym("x", 3)  # e.g. a simulator state: the plane moves by x
    Dp = ca.DM(np.diag([10.0, 20.0, 30.0]))
    out = contact_step_expr(method, [0.2, 0.0, 1.0], Dp, [0, 0, 1], x, 0.3, [0.02, 0, 1 / 30])
    g = ca.Function("g", [x], [out["P"], out["contact"]])
    l = np.array([0.003, -0.002, 0.001])
    ref = step(method, np.array([0.2, 0.0, 1.0]), np.diag([10.0, 20.0, 30.0]), Z, l, 0.3, np.array([0.02, 0, 1 / 30]))
    P, contact = g(l)
    np.testing.assert_array_equal(np.array(P).ravel(), ref["P"])
    assert float(contact) == ref["contact"][0]


# ---------------------------------------------------------------------------
# invariants of the robust and implicit steps (hypothesis)
# ---------------------------------------------------------------------------
@pytest.mark.parametrize("method", ["robust", "implicit"])
@SETTINGS
@given(case=contact_cases(max_log_cond=8.0))
def test_contact_invariants(method, case):
    P0, Dp, n, l, mu, u0 = case
    r = step(method, *case)
    assert all(np.all(np.isfinite(v)) for v in r.values())
    if r["contact"][0] == 1.0:
        # the foot follows the plane along n (1.8): n.delta = n.l, to the
        # round-off of the terms delta is made of: l - k1 s - k2 l_tau + k3 e
        # with s = P0 - (n.P0) n formed from |P0| (robust), l - g (implicit)
        k = np.abs(r["k"])
        if method == "robust":
            scale = np.linalg.norm(l) + k[0] * np.linalg.norm(P0) + k[1] * np.linalg.norm(l) + k[2]
        else:
            scale = np.linalg.norm(l) + k.sum()
        scale += np.linalg.norm(r["delta"])
        assert abs(n @ r["delta"] - n @ l) <= NORMAL_RTOL * scale
        # inside the cone (1.5), compressive
        P = r["P"]
        assert cone(P, n, mu) <= CONE_RTOL * (P @ P)
        assert n @ P >= 0
        if mu == 0:  # the cone is the ray along n
            assert np.linalg.norm(tangential(P, n)) <= RAY_RTOL * np.linalg.norm(P)
    else:
        assert r["contact"][0] == 0.0
        np.testing.assert_array_equal(r["P"], np.zeros(3))
        np.testing.assert_array_equal(r["delta"], -u0)


@pytest.mark.parametrize("method", ["robust", "implicit"])
@SETTINGS
@given(case=contact_cases(), fraction=st.floats(0, 0.99, **finite), mu=st.floats(0.05, 2, **finite))
def test_stick_trial_inside_cone_gives_delta_l_exactly(method, case, fraction, mu):
    _, Dp, n, l, _, u0 = case
    t = np.cross(n, [0.3, -0.5, 0.8])
    t /= np.linalg.norm(t)
    P_t = n + fraction * mu * t  # strictly inside the cone
    P0 = P_t - Dp @ l
    r = step(method, P0, Dp, n, l, mu, u0)
    np.testing.assert_array_equal(r["delta"], l)
    np.testing.assert_array_equal(r["k"], np.zeros(3))
    assert r["contact"][0] == 1.0


@pytest.mark.parametrize("method", ["robust", "implicit"])
@SETTINGS
@given(case=contact_cases(), recede=st.floats(1.5, 10, **finite))
def test_receding_plane_lifts_off(method, case, recede):
    """Plane moves away by more than the elastic stroke: P = 0, delta = -u0."""
    P0, Dp, n, _, mu, _ = case
    u0 = 1e-3 * n
    Dp = np.eye(3) * 100.0
    P0 = Dp @ u0
    l = -recede * u0 + 1e-4 * np.cross(n, [1.0, 2.0, 3.0])
    r = step(method, P0, Dp, n, l, mu, u0)
    assert r["contact"][0] == 0.0
    np.testing.assert_array_equal(r["P"], np.zeros(3))
    np.testing.assert_array_equal(r["delta"], -u0)


@pytest.mark.parametrize("method", METHODS)
@SETTINGS
@given(case=contact_cases(max_log_cond=8.0, admissible=False), mu=st.floats(0, 2, **finite))
def test_outputs_finite_for_finite_inputs(method, case, mu):
    """Any sign pattern of D_p, P0 anywhere, cond(D_p) up to 1e8."""
    P0, Dp, n, l, _, u0 = case
    r = step(method, P0, Dp, n, l, mu, u0)
    assert all(np.all(np.isfinite(v)) for v in r.values())


# ---------------------------------------------------------------------------
# the implicit step
# ---------------------------------------------------------------------------
@SETTINGS
@given(case=contact_cases(max_log_cond=3.0, kinds=("spd", "skew"), mu=None))
def test_implicit_coulomb_law(case):
    """P_tau = mu (n.P) g/|g| when slipping: direction to 1e-10, |R| to 1e-13."""
    P0, Dp, n, l, mu, u0 = case
    r = step("implicit", *case)
    g = r["k"]
    assume(r["contact"][0] == 1.0 and np.linalg.norm(g) > 0)
    P = r["P"]
    N = n @ P
    P_tau = tangential(P, n)
    g_hat = g / np.linalg.norm(g)
    assert abs(n @ g) <= NORMAL_RTOL * np.linalg.norm(g)
    P_t = P0 + Dp @ l
    assert np.linalg.norm(P_tau - mu * N * g_hat) <= RESIDUAL_RTOL * np.linalg.norm(P_t)
    if mu > 0 and np.linalg.norm(P_tau) > 1e-3 * np.linalg.norm(P_t):
        assert np.linalg.norm(P_tau / np.linalg.norm(P_tau) - g_hat) <= COULOMB_RTOL
    # and the slip is what the step did: delta = l - g
    np.testing.assert_allclose(r["delta"], l - g, rtol=0, atol=1e-15 * (np.linalg.norm(l) + np.linalg.norm(g)))


def test_implicit_notes_3_6_example():
    """docs/paper-notes.md §3 item 6: D_p = 10 I, P0 on the cone, plane moves across the force."""
    r = solve_contact("implicit", [0.3, 0.0, 1.0], 10 * np.eye(3), Z, [0.0, 0.01, 0.0], 0.3)
    expected = 0.3 * np.array([0.3, 0.1]) / np.sqrt(0.1)  # P_t = (0.3, 0.1, 1) returned radially
    np.testing.assert_allclose(r.P, [expected[0], expected[1], 1.0], rtol=0, atol=COULOMB_RTOL)
    np.testing.assert_allclose(r.P[:2], [0.28460498941515416, 0.09486832980505138], rtol=0, atol=COULOMB_RTOL)
    assert r.contact


def test_paper_3d_error_notes_3_6():
    """The printed step never turns the friction force toward the new slip.

    With the plane moving across P_tau the paper (and robust) step leaves P
    unchanged step after step; the implicit step turns it toward the slip.
    """
    Dp, mu = 10 * np.eye(3), 0.3
    l = np.array([0.0, 0.01, 0.0])
    P = {m: np.array([0.3, 0.0, 1.0]) for m in METHODS}
    for _ in range(3):
        for m in METHODS:
            P[m] = step(m, P[m], Dp, Z, l, mu, P[m] / 10)["P"]
    np.testing.assert_allclose(P["paper"], [0.3, 0.0, 1.0], rtol=0, atol=1e-12)
    np.testing.assert_allclose(P["robust"], [0.3, 0.0, 1.0], rtol=0, atol=1e-12)
    angle = np.arctan2(P["implicit"][1], P["implicit"][0])
    assert angle > 0.8  # three steps of 0.32 rad each, toward +y
    assert abs(np.hypot(*P["implicit"][:2]) - mu * P["implicit"][2]) < 1e-12


def test_implicit_handles_indefinite_and_pole_cases():
    """Indefinite tangential stiffness: finite, and a root on the branch is found."""
    rng = np.random.default_rng(5)
    cases = []
    for _ in range(400):
        Dp = spd(rng, 1e4, 10.0) + 0.3 * rng.normal(size=(3, 3)) * 10 * 1e4 / 3
        n = rng.normal(size=3)
        n /= np.linalg.norm(n)
        P0 = Dp @ (rng.normal(size=3) * 0.01)
        cases.append((P0, Dp, n, rng.normal(size=3) * 0.01, rng.uniform(0, 2), np.zeros(3)))
    r = batch("implicit", cases)
    assert all(np.all(np.isfinite(v)) for v in r.values())
    for i, (P0, Dp, n, l, mu, _) in enumerate(cases):
        if r["contact"][0, i] == 1 and np.linalg.norm(r["k"][:, i]) > 0:
            P, g = r["P"][:, i], r["k"][:, i]
            R = tangential(P, n) - mu * (n @ P) * g / np.linalg.norm(g)
            assert np.linalg.norm(R) <= 1e-9 * np.linalg.norm(P0 + Dp @ l)


def test_implicit_poles_of_negative_tangential_stiffness():
    """D_p = diag(10, -5, 10): negative stiffness along y, n = z.

    Plane-parallel motion in x-z: the trial force has no y part, the pole of
    (K + lam I)^-1 at lam = 5 has zero residue and the step slides as with
    positive stiffness (agreeing with the robust step; the frictionless graph
    agrees with the full one at mu = 0). With a y part the pole is active: at
    mu = 0 the slip would have to pass through infinity, and the step lifts
    off (spec §3), in both graphs; at mu = 0.3 solutions exist above the pole.
    """
    Dp, l = np.diag([10.0, -5.0, 10.0]), np.array([0.01, 0.0, 0.001])
    plane = np.array([0.3, 0.0, 1.0])
    for mu in (0.0, 0.3):
        r = step("implicit", plane, Dp, Z, l, mu)
        assert r["contact"][0] == 1
        np.testing.assert_allclose(r["P"], step("robust", plane, Dp, Z, l, mu)["P"], rtol=0, atol=1e-12)
    full = step("implicit", plane, Dp, Z, l, 0.0)
    small = [np.array(v).ravel() for v in contact_step("implicit", friction=False)(plane, Dp, Z, l, 0.0, np.zeros(3))]
    for key, value in zip(OUTPUT_NAMES, small):
        np.testing.assert_array_equal(full[key], value)
    spatial = np.array([0.3, 0.1, 1.0])
    assert step("implicit", spatial, Dp, Z, l, 0.0)["contact"][0] == 0
    assert contact_step("implicit", friction=False)(spatial, Dp, Z, l, 0.0, np.zeros(3))[3] == 0
    # mu = 0.3: solutions at lam = 3.69 (below the pole), 8.56 and 21.67 (on
    # the branch, tests/oracle_coulomb.py); the first spec lifted off here
    # (F > 0 at the pole, two roots above it), the rule takes lam = 21.67.
    r = step("implicit", spatial, Dp, Z, l, 0.3)
    assert r["contact"][0] == 1
    np.testing.assert_allclose(r["k"], [0.01263019, 0.00599875, 0.0], rtol=1e-6, atol=1e-12)
    N = Z @ r["P"]
    assert 0.3 * N / np.linalg.norm(r["k"]) == pytest.approx(21.67013708, rel=1e-8)


# ---------------------------------------------------------------------------
# docs/paper-notes.md §3 items 1-5: fail with the printed step, pass with the robust one
# ---------------------------------------------------------------------------
@pytest.mark.parametrize("method", ["paper", "robust"])
@printed_step_fails
def test_item1_receding_plane_separates(method):
    """No separation branch: the printed step returns a tensile force."""
    Dp, mu = 10 * np.eye(3), 0.3
    P0 = np.array([0.1, 0.0, 1.0])
    u0 = P0 / 10
    r = step(method, P0, Dp, Z, [0.02, 0.0, -0.2], mu, u0)
    assert Z @ r["P"] >= 0
    if r["contact"][0] == 0:
        np.testing.assert_array_equal(r["P"], np.zeros(3))


@pytest.mark.parametrize("method", ["paper", "robust"])
@printed_step_fails
def test_item2_k2_uses_k1(method):
    """P0 on the cone with C0 = +round-off: k1 fires, and k2 must not count it twice.

    Plane-parallel, symmetric positive-definite D_p with the n-l plane
    invariant: the exact answer is the implicit one.
    """
    Dp = np.array([[10.0, 0, 2], [0, 7, 0], [2, 0, 20]])
    mu, l = 0.3, np.array([0.01, 0, 0.001])
    P0 = np.array([0.3 * (1 + 1e-14), 0, 1.0])  # C0 = +1.6e-15 |P0|^2
    u0 = np.linalg.solve(Dp, P0)
    exact = step("implicit", P0, Dp, Z, l, mu, u0)["P"]
    r = step(method, P0, Dp, Z, l, mu, u0)
    assert r["k"][0] > 0  # the initial slip fired
    np.testing.assert_allclose(r["P"], exact, rtol=0, atol=1e-12)


@pytest.mark.parametrize("method", ["paper", "robust"])
@printed_step_fails
def test_item3_mu_zero_keeps_force_on_the_ray(method):
    """mu = 0: formula (1.15) loses half the digits (double root)."""
    rng = np.random.default_rng(0)
    cases = []
    for _ in range(300):
        n = rng.normal(size=3)
        n /= np.linalg.norm(n)
        Q = rotation(rng)
        Dp = Q @ np.diag(10 ** rng.uniform(0, 3, 3)) @ Q.T
        P0 = abs(rng.normal()) * n
        cases.append((P0, Dp, n, rng.normal(size=3) * 0.01, 0.0, np.linalg.solve(Dp, P0)))
    r = batch(method, cases)
    for i, (_, _, n, _, _, _) in enumerate(cases):
        if r["contact"][0, i] == 1:
            P = r["P"][:, i]
            assert np.linalg.norm(tangential(P, n)) <= RAY_RTOL * np.linalg.norm(P)


@pytest.mark.parametrize("method", ["paper", "robust"])
@printed_step_fails
def test_item3_stiff_leg_cone_residual(method):
    """A3 -> 0 with stiff axial and soft bending (ratio 1e6-1e8, docs/paper-notes.md §3.7)."""
    rng = np.random.default_rng(1)
    cases = []
    for _ in range(300):
        e = rng.normal(size=3)
        e *= np.sign(e[2]) / np.linalg.norm(e)
        kb = 10 ** rng.uniform(1, 3)
        Dp = kb * 10 ** rng.uniform(6, 8) * np.outer(e, e) + kb * (np.eye(3) - np.outer(e, e))
        mu = rng.uniform(0.05, 1)
        N0 = abs(rng.normal()) * 100
        t = rng.normal(size=2)
        t /= np.linalg.norm(t)
        P0 = np.array([mu * N0 * t[0] * rng.uniform(), mu * N0 * t[1], N0])
        cases.append((P0, Dp, Z, rng.normal(size=3) * 1e-3, mu, np.linalg.solve(Dp, P0)))
    r = batch(method, cases)
    for i, (_, _, n, _, mu, _) in enumerate(cases):
        if r["contact"][0, i] == 1:
            P = r["P"][:, i]
            assert cone(P, n, mu) <= CONE_RTOL * (P @ P)


def _rotated_stiffness(theta):
    c, s = np.cos(theta), np.sin(theta)
    R = np.array([[c, 0, -s], [0, 1, 0], [s, 0, c]])
    return R @ np.diag([1.0, 50.0, 100.0]) @ R.T


@pytest.mark.parametrize("method", ["paper", "robust"])
@printed_step_fails
def test_item4_clamp_is_only_a_safeguard(method):
    """(1.10) with u0 = Dp^-1 P0 and anisotropic D_p (plane-parallel).

    theta = pi/2: the clamp bites (0 < ub < k1): the chain must still reach
    the exact answer. theta = 2pi/3: the interval is empty (ub < 0): k1 is
    the value of (1.9), not 0, and the answer is still exact.
    """
    mu, l = 0.3, np.array([0.01, 0, 0])
    P0 = np.array([0.3 * (1 + 1e-14), 0, 1.0])
    for theta in (np.pi / 2, 2 * np.pi / 3):
        Dp = _rotated_stiffness(theta)
        u0 = np.linalg.solve(Dp, P0)
        s = P0 - P0[2] * Z
        ub = s @ u0 / (s @ s)
        exact = step("implicit", P0, Dp, Z, l, mu, u0)
        r = step(method, P0, Dp, Z, l, mu, u0)
        np.testing.assert_allclose(r["P"], exact["P"], rtol=0, atol=1e-12)
        if ub < 0:
            assert r["k"][0] > 0


@pytest.mark.parametrize("method", ["paper", "robust"])
@printed_step_fails
def test_item5_k2_continuous_at_c2_zero(method):
    """P_t on the cone up to round-off: the answer must not jump with the sign of C2."""
    Dp, mu = 10 * np.eye(3), 0.5
    P_t = np.array([0.18, 0.24, 0.6])  # |P_t tau| = mu N_t
    l0 = np.array([-0.01, 0.0, -0.04])  # -Dp l_tau points out of the cone
    P0 = P_t - Dp @ l0
    for eps in (-1e-14, 0.0, 1e-14):  # C(P_t) = -+6.7e-14 |P_t|^2, 0
        l = l0 + np.array([0, 0, -eps])
        r = step(method, P0, Dp, Z, l, mu, P0 / 10)
        np.testing.assert_allclose(r["P"], P0 + Dp @ l, rtol=0, atol=1e-12)


# ---------------------------------------------------------------------------
# robust vs implicit in plane-parallel cases
# ---------------------------------------------------------------------------
def test_robust_agrees_with_implicit_plane_parallel():
    """Where a compressive Coulomb solution exists the two agree to round-off.

    studies/bench_contact.py (docs/contact.md) measures, over 20 000 cases,
    a median of 6e-15 and a worst of 7e-8 of |P_implicit - P0| (the worst at
    small mu, a near-double root of the k2 quadratic; up to 6e-6 was seen on
    other samples, hence the bound 1e-4 on the max). Where no
    Coulomb-consistent contact exists the robust step returns a force on the
    cone with friction along the slip and the implicit step lifts off; those
    cases are excluded here and tested below.
    """
    cases = plane_parallel_cases(np.random.default_rng(11), 2000, mu_zero=False)
    ri, rr = batch("implicit", cases), batch("robust", cases)
    errors = []
    for i, (P0, Dp, n, l, mu, u0) in enumerate(cases):
        if ri["contact"][0, i] == 0:
            continue
        assert rr["contact"][0, i] == 1
        scale = np.linalg.norm(ri["P"][:, i] - P0)
        if scale > 0:
            errors.append(np.linalg.norm(rr["P"][:, i] - ri["P"][:, i]) / scale)
    errors = np.array(errors)
    assert np.median(errors) <= 1e-14
    assert np.percentile(errors, 99) <= 1e-8
    assert errors.max() <= 1e-4


def test_robust_lifts_off_where_no_coulomb_solution():
    """The robust step lifts off where its chain ends with friction along the
    slip under a tensile trial force.

    Before that rule (docs/contact.md, "robust") the robust step kept
    contact, anti-Coulomb (P_tau.g < 0), in 5.7 % of these cases, exactly
    where the implicit step finds no compressive Coulomb solution; 95 % of
    them had a tensile trial force. Now: no anti-Coulomb answer with a
    tensile trial force, the rest (compressive trial) stays below 1 %
    (measured 10 of 2000), and never the other way round.
    """
    cases = plane_parallel_cases(np.random.default_rng(12), 2000, mu_zero=False)
    ri, rr = batch("implicit", cases), batch("robust", cases)
    assert (ri["contact"][0] == 0).sum() > 50            # the sample has such cases
    assert not ((rr["contact"][0] == 0) & (ri["contact"][0] == 1)).any()
    differs = (rr["contact"][0] == 1) & (ri["contact"][0] == 0)
    assert differs.sum() <= 0.01 * len(cases)
    for i in np.nonzero(rr["contact"][0] == 1)[0]:
        P0, Dp, n, l, mu, u0 = cases[i]
        g = tangential(l - rr["delta"][:, i], n)
        P = rr["P"][:, i]
        anti = tangential(P, n) @ g < -1e-12 * np.linalg.norm(P) * np.linalg.norm(g)
        assert not anti or n @ (P0 + Dp @ l) > 0
        assert anti == differs[i]


# ---------------------------------------------------------------------------
# Jacobians
# ---------------------------------------------------------------------------
def jacobian_function(method):
    f = contact_step(method)
    P0, Dp, n, l, mu, u0 = (ca.SX.sym(name, *f.size_in(i)) for i, name in enumerate(INPUT_NAMES))
    out = f(P0, Dp, n, l, mu, u0)
    y = ca.vertcat(out[0], out[1], out[2])
    x = ca.vertcat(P0, ca.vec(Dp), l, mu)
    return ca.Function(f"jac_{method}", [P0, Dp, n, l, mu, u0], [ca.jacobian(y, x)])


@pytest.fixture(scope="module")
def jacobians():
    return {m: jacobian_function(m) for m in METHODS}


def jacobian_cases():
    rng = np.random.default_rng(3)
    cases = (plane_parallel_cases(rng, 100, mu_zero=False)
             + plane_parallel_cases(rng, 30, mu_zero=True))
    for _ in range(200):
        Dp = spd(rng, 10 ** rng.uniform(0, 8), 10 ** rng.uniform(0, 3))
        if rng.random() < 0.5:
            Dp = Dp + 0.3 * rng.normal(size=(3, 3)) * np.linalg.norm(Dp, 2) / 3
        n = rng.normal(size=3)
        n /= np.linalg.norm(n)
        P0 = Dp @ (rng.normal(size=3) * 0.01)
        cases.append((P0, Dp, n, rng.normal(size=3) * 0.01, rng.choice([0.0, rng.uniform(0, 2)]), np.zeros(3)))
    # the special cases above
    cases.append((np.array([0.3, 0, 1.0]), 10 * np.eye(3), Z, np.array([0, 0.01, 0]), 0.3, np.array([0.03, 0, 0.1])))
    cases.append((np.array([0.28, 0.24, 1.0]), 10 * np.eye(3), Z, np.array([-0.01, 0, -0.04]), 0.5, np.array([0.028, 0.024, 0.1])))
    # degenerate points: zero force, zero motion, zero stiffness, P on the
    # axis or the cone exactly, tension, tiny numbers, stiff axis
    zero = np.zeros(3)
    P_cone = np.array([0.3, 0, 1.0])
    for P0, Dp, l, mu in [
        (zero, np.eye(3), zero, 0.3), (zero, np.eye(3), zero, 0.0), (zero, np.zeros((3, 3)), zero, 0.3),
        (Z, np.eye(3), zero, 0.3), (Z, np.eye(3), zero, 0.0), (P_cone, 10 * np.eye(3), zero, 0.3),
        (P_cone, 10 * np.eye(3), np.array([0.01, 0, 0]), 0.3),
        (P_cone, np.zeros((3, 3)), np.array([0.01, 0, 0]), 0.3),
        (np.array([0.3, 0, -1.0]), 10 * np.eye(3), np.array([0.01, 0, 0]), 0.3),
        (np.array([1e-200, 0, 1e-200]), 10 * np.eye(3), np.array([1e-201, 0, 0]), 0.3),
        (Z, np.diag([1e8, 1, 1]), np.array([0, 1e-9, 0]), 2.0),
    ]:
        cases.append((P0, Dp, Z, l, mu, zero))
    return cases


@pytest.mark.parametrize("method", METHODS)
def test_jacobians_finite(jacobians, method):
    cases = jacobian_cases()
    J = np.array(jacobians[method].map(len(cases))(*stack_inputs(cases)))
    assert np.all(np.isfinite(J))


@pytest.mark.parametrize("method", ["robust", "implicit"])
def test_jacobian_matches_finite_differences_in_slip(jacobians, method):
    """Away from switches the unrolled graph has the implicit-function derivative."""
    P0 = np.array([0.2, 0.05, 1.0])
    Dp = np.array([[30.0, 2, 1], [2, 20, 3], [1, 3, 50]])
    l = np.array([0.004, 0.003, 0.001])
    args = [P0, Dp, Z, l, 0.25, np.linalg.solve(Dp, P0)]
    assert step(method, *args)["contact"][0] == 1
    J = np.array(jacobians[method](*args))
    x0 = np.concatenate([P0, Dp.ravel(order="F"), l, [0.25]])

    def y(x):
        a = [x[:3], x[3:12].reshape(3, 3, order="F"), Z, x[12:15], x[15], args[5]]
        r = step(method, *a)
        return np.concatenate([r["delta"], r["P"], r["k"]])

    h = 1e-6
    for j in range(len(x0)):
        e = np.zeros_like(x0)
        e[j] = h * max(1.0, abs(x0[j]))
        fd = (y(x0 + e) - y(x0 - e)) / (2 * e[j])
        np.testing.assert_allclose(J[:, j], fd, rtol=1e-5, atol=1e-7 * (1 + np.abs(J).max()))


@pytest.mark.parametrize("method", ["robust", "implicit"])
def test_jacobian_jumps_at_stick_slip_switch(jacobians, method):
    """The step is continuous but its Jacobian jumps where the trial leaves the cone."""
    Dp, mu = np.diag([10.0, 10.0, 20.0]), 0.3
    P0 = np.array([0.2, 0.0, 1.0])
    l_switch = np.array([0.01, 0.0, 0.0])  # P_t = (0.3, 0, 1): on the cone
    Js, Ps = [], []
    for dx in (-1e-7, 1e-7):
        args = [P0, Dp, Z, l_switch + [dx, 0, 0], mu, P0 / 10]
        Js.append(np.array(jacobians[method](*args)))
        Ps.append(step(method, *args)["P"])
    assert np.all(np.isfinite(Js))
    assert np.linalg.norm(Ps[1] - Ps[0]) < 1e-5  # continuous
    assert np.abs(Js[1] - Js[0]).max() > 1.0  # d P_x / d l_x: 10 in stick, ~0 in slip


# ---------------------------------------------------------------------------
# solve_contact: validation at the boundary
# ---------------------------------------------------------------------------
GOOD = dict(P0=[0.3, 0.0, 1.0], Dp=10 * np.eye(3), n=[0.0, 0.0, 1.0], l=[0.0, 0.01, 0.0], mu=0.3)


def call(**changes):
    kwargs = dict(GOOD, **changes)
    return solve_contact("implicit", **kwargs)


def test_solve_contact_returns_frozen_result():
    r = call()
    assert isinstance(r, ContactResult)
    assert r.contact is True
    for field in (r.delta, r.P, r.k):
        assert field.shape == (3,)
        assert not field.flags.writeable
    with pytest.raises(Exception):
        r.P = np.zeros(3)


def test_validation_method():
    with pytest.raises(ValueError, match=r"`method` must be one of 'paper', 'robust', 'implicit'; got 'newton'"):
        solve_contact("newton", **GOOD)


@pytest.mark.parametrize(
    "name, value, error, pattern",
    [
        ("P0", [1.0, 2.0], ValueError, r"`P0` must have shape \(3,\); got shape \(2,\)"),
        ("P0", [0.0, np.nan, 1.0], ValueError, r"`P0` must be finite.*nan"),
        ("P0", "abc", TypeError, r"`P0` must be a real array"),
        ("Dp", np.eye(2), ValueError, r"`Dp` must have shape \(3, 3\); got shape \(2, 2\).*3x3"),
        ("Dp", np.full((3, 3), np.inf), ValueError, r"`Dp` must be finite.*inf"),
        ("Dp", np.eye(3) * 1j, TypeError, r"`Dp` must be a real array.*complex"),
        ("n", [0.0, 0.0, 2.0], ValueError, r"`n` must be a unit vector.*\|n\| = 2\.0.*np\.linalg\.norm"),
        ("n", [[0.0, 0.0, 1.0]], ValueError, r"`n` must have shape \(3,\); got shape \(1, 3\)"),
        ("l", [0.0, np.inf, 0.0], ValueError, r"`l` must be finite.*inf"),
        ("l", None, TypeError, r"`l` must be a real array.*None"),
        ("mu", -0.1, ValueError, r"`mu` must be finite and >= 0; got -0\.1.*0\.3"),
        ("mu", np.nan, ValueError, r"`mu` must be finite and >= 0; got nan"),
        ("mu", [0.3], TypeError, r"`mu` must be a real (number|scalar); got \[0\.3\]"),
        ("mu", True, TypeError, r"`mu` must be a real number; got True"),
        ("mu", "0.3", TypeError, r"`mu` must be a real number; got '0\.3'"),
        ("u0", [0.0, 0.0], ValueError, r"`u0` must have shape \(3,\); got shape \(2,\).*or None"),
    ],
)
def test_validation_rules(name, value, error, pattern):
    with pytest.raises(error, match=pattern):
        call(**{name: value})


def test_validation_accepts_integer_arrays_and_default_u0():
    r = solve_contact("robust", [0, 0, 1], np.eye(3, dtype=int) * 10, [0, 0, 1], [0, 0, 0.001], 0)
    np.testing.assert_allclose(r.P, [0, 0, 1.01])
    assert r.contact
