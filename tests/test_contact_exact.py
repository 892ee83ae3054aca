"""The implicit contact step against a brute-force search of all Coulomb solutions.

``tests/oracle_coulomb.py`` finds every slip solution by scanning the slip
direction (no quartic, no Newton). On CASES_PER_CLASS random cases of each
class (SPD, non-symmetric, strut-built, near-singular D_p; grazing and
receding motion; mu in [0.01, 2]) the tests assert the rule of
docs/contact.md ("Selection rule"): stick when the trial force is inside the
cone, else of the slip solutions on the branch connected to zero slip the
one of largest lam = mu N/|g| (the first met as the slip grows from zero),
lift-off only when there is none; every answer in contact is Coulomb-exact; the Jacobian is finite and
equals central differences away from switches. The degenerate cases of
docs/contact.md each have a test at the end.
"""
from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

import oracle_coulomb as oq
from symcushion.contact import solve_contact
from symcushion.contact.dispatch import contact_step

#: Random cases per class (the issue asks for at least 10 000).
CASES_PER_CLASS = 10_000
SEED = 14
#: Step vs oracle slip, relative: the oracle's root is bisected to round-off
#: in the angle; rho = w.p/D then carries cond(D_p) round-off (measured worst
#: 9e-7 at cond 1e8).
G_RTOL = 1e-5
#: Cone: C(P) = |P|^2 - (1 + mu^2)(n.P)^2 <= CONE_RTOL |P|^2 (the issue's bound).
CONE_RTOL = 1e-10
#: Friction opposite the slip: |P_tau - mu N g/|g|| <= DIR_RTOL |P_t|.
DIR_RTOL = 1e-9
#: n.delta = n.l to this, relative to |l| + |g| (the slip is tangential).
NL_RTOL = 1e-13
#: Cases where the step finds a smaller slip than the oracle (two roots
#: closer than the oracle's angle grid, 2 pi/SCAN) may be at most this share.
ORACLE_MISS_MAX = 1e-3
#: Jacobian: slip cases per class, relative step and tolerance.
JAC_CASES = 150
FD_STEP = 1e-6
JAC_RTOL = 1e-5
#: A case is at a switch when central differences with FD_STEP and
#: FD_STEP/4 disagree by more than this (a branch flips inside the stencil).
SWITCH_RTOL = 1e-4


def _args(cs):
    return [cs["P0"].T, np.hstack(list(cs["Dp"])), cs["n"].T, cs["l"].T, cs["mu"][None, :], cs["u0"].T]


def _run(cs):
    m = len(cs["mu"])
    delta, P, g, c = (np.asarray(x) for x in contact_step("implicit").map(m)(*_args(cs)))
    return dict(delta=delta.T, P=P.T, g=g.T, contact=c[0] > 0.5)


@pytest.fixture(scope="module", params=oq.CLASSES)
def data(request):
    cs = oq.random_cases(np.random.default_rng([SEED, oq.CLASSES.index(request.param)]),
                         CASES_PER_CLASS, request.param)
    sol = oq.coulomb_solutions(cs["P0"], cs["Dp"], cs["n"], cs["l"], cs["mu"])
    return request.param, cs, sol, _run(cs)


def _least(sol):
    """The slip the rule takes per case (NaN where none)."""
    idx = oq.chosen(sol)
    m = len(idx)
    return np.where(idx[:, None] >= 0, sol["g"][np.arange(m), np.maximum(idx, 0)], np.nan)


def test_classes_cover_stick_slip_several_and_none(data):
    kind, cs, sol, out = data
    slip = ~sol["stick"]
    assert sol["stick"].mean() > 0.2 and (slip & (sol["count"] > 0)).mean() > 0.2
    assert (slip & (sol["count"] == 0)).sum() > 100          # no solution: lift-off
    if kind not in ("spd",):
        assert (sol["count"] > 1).sum() > 100                # several slips
    assert np.all(cs["mu"] >= 0.01) and np.all(cs["mu"] <= 2)


def _has(sol):
    """Slip cases where the rule takes a solution."""
    return ~sol["stick"] & (oq.chosen(sol) >= 0)


def test_no_spurious_lift_off(data):
    """A slip solution with n.P > 0 exists on the branch, so the step must stay in contact."""
    kind, cs, sol, out = data
    has = _has(sol)
    lifted = np.flatnonzero(has & ~out["contact"])
    assert lifted.size == 0, f"{kind}: lifts off in cases {lifted[:10]} with a slip solution"


def test_stick_when_inside_the_cone(data):
    kind, cs, sol, out = data
    st = sol["stick"]
    assert np.all(out["contact"][st])
    assert np.array_equal(out["delta"][st], cs["l"][st])


def test_rule_takes_the_first_solution_on_the_branch(data):
    """Of several solutions the one the rule picks; the oracle may miss a root only rarely."""
    kind, cs, sol, out = data
    has = _has(sol) & out["contact"]
    ref = _least(sol)[has]
    g = out["g"][has]
    size = np.linalg.norm(ref, axis=1)
    err = np.linalg.norm(g - ref, axis=1) / size
    N = np.einsum("mi,mi->m", cs["n"][has], out["P"][has])
    lam = cs["mu"][has] * N / np.linalg.norm(g, axis=1)
    lam_ref = oq.chosen(sol)
    lam_ref = sol["lam"][np.flatnonzero(has), lam_ref[has]]
    # a larger lam than the oracle's: two roots closer than its angle grid
    missed = (err > G_RTOL) & (lam > lam_ref)
    bad = (err > G_RTOL) & ~missed
    assert not bad.any(), f"{kind}: another solution in {np.flatnonzero(has)[bad][:10]}, err {err[bad][:5]}"
    assert missed.sum() <= ORACLE_MISS_MAX * len(g)


def test_lift_off_only_without_solution(data):
    """Lifted off: no slip solution; in contact without an oracle solution: rare, and exact (next test)."""
    kind, cs, sol, out = data
    lifted = ~out["contact"]
    assert not np.any(lifted & sol["stick"])
    assert not np.any(lifted & _has(sol))
    extra = out["contact"] & ~_has(sol) & ~sol["stick"]
    assert extra.sum() <= ORACLE_MISS_MAX * len(extra)


def test_contact_answers_are_coulomb_exact(data):
    kind, cs, sol, out = data
    c = out["contact"]
    P, g, n, mu = out["P"][c], out["g"][c], cs["n"][c], cs["mu"][c]
    N = np.einsum("mi,mi->m", n, P)
    PP = np.einsum("mi,mi->m", P, P)
    assert np.all(N > 0)
    cone = PP - (1 + mu**2) * N**2
    assert np.all(cone <= CONE_RTOL * PP), f"{kind}: worst cone residual {np.max(cone / PP):.2e}"
    slipping = np.linalg.norm(g, axis=1) > 0
    assert np.all(np.abs(cone[slipping]) <= CONE_RTOL * PP[slipping])    # on the cone
    P_tau = P - N[:, None] * n
    gs = g[slipping]
    ghat = gs / np.linalg.norm(gs, axis=1)[:, None]
    resid = np.linalg.norm(P_tau[slipping] - (mu * N)[slipping, None] * ghat, axis=1)
    Pt = sol["Pt"][c][slipping]
    assert np.all(resid <= DIR_RTOL * np.linalg.norm(Pt, axis=1)), f"{kind}: worst {np.max(resid / np.linalg.norm(Pt, axis=1)):.2e}"
    assert np.all(np.einsum("mi,mi->m", P_tau[slipping], gs) >= 0)       # opposite the slip
    nd = np.einsum("mi,mi->m", n, out["delta"][c])
    nl = np.einsum("mi,mi->m", n, cs["l"][c])
    scale = np.linalg.norm(cs["l"][c], axis=1) + np.linalg.norm(g, axis=1)
    assert np.all(np.abs(nd - nl) <= NL_RTOL * scale)


def _jacobian_function():
    f = contact_step("implicit")
    sym = [ca.SX.sym(name, *f.size_in(i)) for i, name in enumerate(f.name_in())]
    P = f(*sym)[1]
    x = ca.vertcat(sym[0], ca.vec(sym[1]), sym[3])
    return ca.Function("contact_step_implicit_jac", sym, [ca.jacobian(P, x)], f.name_in(), ["dP_dx"])


def test_jacobian_finite_and_equal_to_central_differences(data):
    kind, cs, sol, out = data
    idx = np.flatnonzero(_has(sol))[:JAC_CASES]
    sub = {k: v[idx] for k, v in cs.items()}
    m = len(idx)
    J = np.asarray(_jacobian_function().map(m)(*_args(sub))).reshape(3, m, 15).transpose(1, 0, 2)
    assert np.all(np.isfinite(J))
    x0 = np.hstack([sub["P0"], sub["Dp"].transpose(0, 2, 1).reshape(m, 9), sub["l"]])
    # per entry: its size, or a thousandth of its group's (P0, Dp, l) size
    group = np.hstack([np.repeat(np.linalg.norm(x0[:, a:b], axis=1, keepdims=True), b - a, axis=1)
                       for a, b in ((0, 3), (3, 12), (12, 15))])
    scale = np.abs(x0) + 1e-3 * group

    def P_at(x):
        s = dict(sub, P0=x[:, :3], Dp=x[:, 3:12].reshape(m, 3, 3).transpose(0, 2, 1), l=x[:, 12:])
        return _run(s)["P"]

    def central(h):
        cols = []
        for j in range(15):
            e = np.zeros(15)
            e[j] = 1
            dx = (h * scale[:, j])[:, None] * e
            cols.append((P_at(x0 + dx) - P_at(x0 - dx)) / (2 * h * scale[:, j])[:, None])
        return np.stack(cols, axis=2)

    fd, fd4 = central(FD_STEP), central(FD_STEP / 4)
    norm = np.linalg.norm((J * scale[:, None, :]).reshape(m, -1), axis=1)
    smooth = np.linalg.norm(((fd - fd4) * scale[:, None, :]).reshape(m, -1), axis=1) <= SWITCH_RTOL * norm
    assert smooth.mean() >= 0.9, f"{kind}: only {smooth.mean():.2f} away from switches"
    err = np.linalg.norm(((J - fd4) * scale[:, None, :]).reshape(m, -1), axis=1) / norm
    assert np.all(err[smooth] <= JAC_RTOL), f"{kind}: worst {np.max(err[smooth]):.2e}"


# ---------------------------------------------------------------------------
# degenerate cases (docs/contact.md, "Degenerate cases")
# ---------------------------------------------------------------------------
Z = np.array([0.0, 0.0, 1.0])


def _oracle_least(P0, Dp, n, l, mu):
    sol = oq.coulomb_solutions(*(np.asarray(x, dtype=float)[None] for x in (P0, Dp, n, l)),
                               np.array([float(mu)]))
    return _least(sol)[0], sol


def _check_exact(r, n, mu, Pt_norm):
    P, g = r.P, r.k
    N = n @ P
    P_tau = P - N * n
    assert abs(P @ P - (1 + mu**2) * N**2) <= CONE_RTOL * (P @ P)
    assert np.linalg.norm(P_tau - mu * N * g / np.linalg.norm(g)) <= DIR_RTOL * Pt_norm


def test_degenerate_singular_K():
    """K singular (a zero tangential stiffness): det K = 0, the quartic keeps its roots."""
    Dp = np.array([[10.0, 0, 0], [0, 0.0, 0], [2.0, 1.0, 20.0]])
    P0, l, mu = np.array([0.5, 0.3, 1.0]), np.array([0.05, 0.02, 0.01]), 0.4
    r = solve_contact("implicit", P0, Dp, Z, l, mu)
    ref, sol = _oracle_least(P0, Dp, Z, l, mu)
    assert sol["count"][0] >= 1 and r.contact
    np.testing.assert_allclose(r.k, ref, rtol=G_RTOL, atol=0)
    _check_exact(r, Z, mu, np.linalg.norm(P0 + Dp @ l))


def test_degenerate_trial_force_along_n():
    """p = 0: the trial force is normal; compressive sticks, tensile lifts off."""
    Dp = np.diag([10.0, 10.0, 20.0])
    r = solve_contact("implicit", [0, 0, 1.0], Dp, Z, [0, 0, 0.01], 0.3)
    assert r.contact and np.array_equal(r.delta, [0, 0, 0.01])
    r = solve_contact("implicit", [0, 0, 1.0], Dp, Z, [0, 0, -0.1], 0.3)
    assert not r.contact and np.array_equal(r.P, np.zeros(3))


def test_degenerate_mu_zero_is_the_frictionless_slide():
    """mu = 0: lam = 0 is the only root, g = K^-1 p; full and frictionless graphs agree."""
    Dp = np.array([[10.0, 3.0, 1.0], [-2.0, 8.0, 0.5], [1.0, 2.0, 30.0]])
    P0, l = np.array([0.4, -0.2, 1.0]), np.array([0.03, 0.01, 0.01])
    r = solve_contact("implicit", P0, Dp, Z, l, 0.0)
    Pt = P0 + Dp @ l
    g2 = np.linalg.solve(Dp[:2, :2], Pt[:2])
    np.testing.assert_allclose(r.k[:2], g2, rtol=1e-12)
    small = contact_step("implicit", friction=False)(P0, Dp, Z, l, 0.0, np.zeros(3))
    np.testing.assert_allclose(np.asarray(small[1]).ravel(), r.P, rtol=1e-12, atol=1e-15)


def test_degenerate_no_normal_coupling():
    """a = 0 (n an eigenvector of D_p^T): N = N_t on every slip, one solution for SPD K."""
    Dp = np.array([[10.0, 2.0, 0.0], [2.0, 5.0, 0.0], [0.0, 0.0, 20.0]])
    P0, l, mu = np.array([0.2, 0.1, 1.0]), np.array([0.06, -0.03, 0.01]), 0.3
    r = solve_contact("implicit", P0, Dp, Z, l, mu)
    ref, sol = _oracle_least(P0, Dp, Z, l, mu)
    assert sol["count"][0] == 1
    np.testing.assert_allclose(r.k, ref, rtol=G_RTOL)
    assert abs(Z @ r.P - (Z @ (P0 + Dp @ l))) <= 1e-12 * np.linalg.norm(r.P)


def test_degenerate_double_root():
    """mu swept across the value where two slip solutions merge and vanish.

    At the merge the secular function touches zero (a double root of the
    quartic). On both sides and at the merge the step answers exactly:
    the least slip while solutions exist, lift-off after."""
    P0, Dp, l = ([7.04, 10.4, 10.8], [[0.901, 0.312, 0.291], [0.312, 0.183, 0.243],
                                      [0.291, 0.243, 1.06]], [0.544, -1.28, -0.328])
    P0, Dp, l = (np.asarray(x, dtype=float) for x in (P0, Dp, l))
    mus = np.linspace(0.3, 1.3, 201)
    m = len(mus)
    cs = dict(P0=np.tile(P0, (m, 1)), Dp=np.tile(Dp, (m, 1, 1)), n=np.tile(Z, (m, 1)),
              l=np.tile(l, (m, 1)), mu=mus, u0=np.zeros((m, 3)))
    sol = oq.coulomb_solutions(cs["P0"], cs["Dp"], cs["n"], cs["l"], cs["mu"])
    out = _run(cs)
    counts = sol["count"][~sol["stick"]]
    assert counts.max() >= 2 and counts.min() == 0          # the sweep crosses the merge
    has = _has(sol)
    assert np.all(out["contact"][has])
    assert not np.any(out["contact"] & ~sol["stick"] & ~has)
    ref = _least(sol)[has]
    np.testing.assert_allclose(out["g"][has], ref, rtol=0, atol=G_RTOL * np.max(np.abs(ref)))


def test_degenerate_det_zero_at_a_root():
    """det(K + lam I) = 0 at the solution: K21 = 0 and lam = -K22 > 0.

    g is then not unique, (K + lam I) g = p holds on a line, and the
    quartic has a double root at lam; the solutions are the two points of
    the line where lam |g| = mu N (docs/contact.md)."""
    Dp = np.array([[10.0, -2.26, 0.0], [0.0, -5.0, 0.0], [3.24, 7.1, 10.0]])
    P0, l, mu = np.array([0.127, 0.0, 1.0]), np.array([0.173, 0.0, -0.044]), 0.633
    r = solve_contact("implicit", P0, Dp, Z, l, mu)
    ref, sol = _oracle_least(P0, Dp, Z, l, mu)
    assert sol["count"][0] >= 1 and r.contact
    lam = mu * (Z @ r.P) / np.linalg.norm(r.k)
    assert abs(lam - 5.0) <= 1e-9 * 5.0                      # on the root of det
    np.testing.assert_allclose(r.k, ref, rtol=G_RTOL, atol=0)
    _check_exact(r, Z, mu, np.linalg.norm(P0 + Dp @ l))
