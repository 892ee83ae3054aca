"""Brute-force oracle of the exact Coulomb contact step -- independent of the quartic.

Test oracle, not part of the package: it imports nothing from ``symcushion``
except, in :func:`random_cases`, ``symcushion.legs.strut`` to build stiffness
matrices of real struts. It finds *every* slip solution of the backward-Euler
Coulomb step by scanning the direction of the slip, and states the step's
selection rule (:func:`chosen`), so that ``tests/test_contact_exact.py`` can check the
package's implicit step against it.

The problem: P(g) = P_t - D_p g with P_t = P0 + D_p l, the slip g
tangential (n.g = 0). A slip solution has g = rho u, u a unit tangent,
rho > 0, and P_tau(g) = mu N(g) u with N(g) = n.P(g) > 0. In a tangent
basis (b1, b2), P_tau = p - rho K u and N = N_t - rho a.u with
K_ij = b_i.D_p b_j, a_j = n.D_p b_j, p_i = b_i.P_t. With w = n x u:

* across u: w.p - rho w.K u = 0, so rho(theta) = w.p / D, D = w.K u;
* along u:  u.p - rho u.K u = mu (N_t - rho a.u).

Multiplying the second by D removes the pole of rho:

    H(theta) = D u.p - (w.p) u.K u - mu (N_t D - (w.p) a.u) = 0,

a trigonometric polynomial of degree 3 (at most 6 roots on the circle).
The oracle evaluates H on SCAN angles, bisects every sign change to the last
bit, adds the two directions u = +-p/|p| (where w.p = 0, so that H vanishes
identically when p is an eigenvector of K and rho comes from the along
equation instead), and keeps a root when rho > 0, N > 0 and the 2-unknown residual
|P_tau - mu N u| is below ACCEPT_TOL |P_t|. Two roots closer than 2 pi/SCAN
(a near-double root) can be missed; the tests allow for that explicitly.

Everything is vectorised over cases: arrays carry a leading axis m.
"""
from __future__ import annotations

import numpy as np

#: Angles scanned on [0, 2 pi): 2 pi/1024 = 6e-3 rad between samples.
SCAN = 1024
#: Bisection steps on a sign change: 2 pi/SCAN / 2^48 is below round-off.
BISECT = 48
#: A bisected root is a solution when |P_tau - mu N u| <= ACCEPT_TOL |P_t|:
#: at a simple root the residual is ~1e-14; spurious sign changes of H (a
#: pole of rho with w.p = 0 crossing) leave O(1).
ACCEPT_TOL = 1e-8
#: A slip solution must end with N > N_MIN |P_t|: a slip that ends at N of
#: round-off is a foot sliding off its load, which the step calls lift-off.
N_MIN = 1e-12
#: A root of det(K + lam I) is a pole of g(lam) when its residue
#: |adj(K + lam I) p| exceeds this times (|K| + lam) |p| (round-off: 1e-16).
POLE_RTOL = 1e-9
#: Largest number of roots kept per case (H has at most 6).
MAX_ROOTS = 6


def tangent_basis(n):
    """Orthonormal (b1, b2), each (m, 3), orthogonal to the unit normals n (m, 3)."""
    axis = np.zeros_like(n)
    axis[np.arange(len(n)), np.argmin(np.abs(n), axis=1)] = 1.0
    b1 = np.cross(n, axis)
    b1 /= np.linalg.norm(b1, axis=1, keepdims=True)
    return b1, np.cross(n, b1)


def _frame(P0, Dp, n, l):
    """Trial force and the tangent-frame quantities p (m,2), K (m,2,2), a (m,2), N_t (m,)."""
    Pt = P0 + np.einsum("mij,mj->mi", Dp, l)
    b1, b2 = tangent_basis(n)
    B = np.stack([b1, b2], axis=2)  # (m, 3, 2)
    K = np.einsum("mia,mij,mjb->mab", B, Dp, B)
    a = np.einsum("mi,mij,mjb->mb", n, Dp, B)
    p = np.einsum("mia,mi->ma", B, Pt)
    return Pt, B, p, K, a, np.einsum("mi,mi->m", n, Pt)


def _times(lin, quad):
    """Coefficients (m, 4) on (c^3, c^2 s, c s^2, s^3) of a linear form (m, 2) in
    (c, s) times a quadratic form (m, 3) on (c^2, c s, s^2)."""
    x, y = lin[:, 0:1], lin[:, 1:2]
    zero = np.zeros_like(x)
    return (np.hstack([x * quad, zero]) + np.hstack([zero, y * quad]))


def _coefficients(p, K, a, Nt, mu):
    """H(theta) as coefficients (m, 7) on the monomials of :func:`_monomials`."""
    K11, K12, K21, K22 = K[:, 0, 0], K[:, 0, 1], K[:, 1, 0], K[:, 1, 1]
    up = p                                         # u.p = p1 c + p2 s
    wp = np.stack([p[:, 1], -p[:, 0]], axis=1)     # w.p = p2 c - p1 s
    uKu = np.stack([K11, K12 + K21, K22], axis=1)
    D = np.stack([K21, K22 - K11, -K12], axis=1)   # w.K u
    cubic = _times(up, D) - _times(wp, uKu)
    # mu (N_t D - (w.p)(a.u)) on (c^2, c s, s^2)
    wa = np.stack([wp[:, 0] * a[:, 0], wp[:, 0] * a[:, 1] + wp[:, 1] * a[:, 0],
                   wp[:, 1] * a[:, 1]], axis=1)
    quad = mu[:, None] * (Nt[:, None] * D - wa)
    return np.hstack([cubic, -quad]), wp, D


def _monomials(theta):
    """(7, k): c^3, c^2 s, c s^2, s^3, c^2, c s, s^2 at angles theta (k,)."""
    c, s = np.cos(theta), np.sin(theta)
    return np.stack([c**3, c * c * s, c * s * s, s**3, c * c, c * s, s * s])


def coulomb_solutions(P0, Dp, n, l, mu):
    """Every slip solution of each case, by scanning the slip direction.

    Parameters
    ----------
    P0, n, l : ndarray, shape (m, 3)
        Force at t (N), unit normal, plane displacement (m).
    Dp : ndarray, shape (m, 3, 3)
        Stiffness dP/dr (N/m).
    mu : ndarray, shape (m,)
        Coulomb coefficient.

    Returns
    -------
    dict
        ``g`` (m, MAX_ROOTS, 3) slip vectors (m; NaN where absent), ``N``
        (m, MAX_ROOTS) their normal forces (N; NaN where absent), ``lam``
        (m, MAX_ROOTS) their mu N/|g|, ``count`` (m,), ``stick`` (m,) bool:
        the trial force is inside the cone, ``Pt`` (m, 3), ``lam_p`` (m,)
        the largest active pole of g(lam) (:func:`largest_pole`).
    """
    m = len(mu)
    Pt, B, p, K, a, Nt = _frame(P0, Dp, n, l)
    T = np.linalg.norm(p, axis=1)
    stick = (T <= mu * Nt) & (Nt > 0)
    todo = np.flatnonzero(~stick)
    coef, wp, D = _coefficients(p[todo], K[todo], a[todo], Nt[todo], mu[todo])
    theta = np.linspace(0.0, 2 * np.pi, SCAN, endpoint=False)
    H = coef @ _monomials(theta)                   # (m', SCAN)
    change = (np.sign(H) != np.sign(np.roll(H, -1, axis=1))) | (H == 0)
    sub, cols = np.nonzero(change)
    rows = todo[sub]
    lo = theta[cols]
    hi = lo + 2 * np.pi / SCAN
    f_lo = H[sub, cols]
    cf = coef[sub]
    for _ in range(BISECT):
        mid = 0.5 * (lo + hi)
        f_mid = np.einsum("kj,jk->k", cf, _monomials(mid))
        same = np.sign(f_mid) == np.sign(f_lo)
        lo = np.where(same, mid, lo)
        f_lo = np.where(same, f_mid, f_lo)
        hi = np.where(same, hi, mid)
    root = 0.5 * (lo + hi)
    c, s = np.cos(root), np.sin(root)
    with np.errstate(divide="ignore", invalid="ignore"):
        rho = (wp[sub, 0] * c + wp[sub, 1] * s) / (D[sub, 0] * c * c + D[sub, 1] * c * s + D[sub, 2] * s * s)
        # u = +-p/|p| (w.p = 0): H vanishes there identically when also D = 0
        # (p an eigenvector of K), and rho = 0/0; take rho from the along
        # equation instead, rho = (u.p - mu N_t)/(u.K u - mu a.u).
        for sign in (1.0, -1.0):
            u = sign * p[todo] / np.linalg.norm(p[todo], axis=1, keepdims=True)
            uKu = np.einsum("ma,mab,mb->m", u, K[todo], u)
            rho_p = (sign * np.linalg.norm(p[todo], axis=1) - mu[todo] * Nt[todo]) / (
                uKu - mu[todo] * np.einsum("ma,ma->m", a[todo], u))
            rows = np.concatenate([rows, todo])
            root = np.concatenate([root, np.arctan2(u[:, 1], u[:, 0])])
            rho = np.concatenate([rho, rho_p])
    c, s = np.cos(root), np.sin(root)
    au = a[rows, 0] * c + a[rows, 1] * s
    u2 = np.stack([np.cos(root), np.sin(root)], axis=1)
    g = np.einsum("kia,ka->ki", B[rows], u2) * rho[:, None]
    N = Nt[rows] - rho * au
    P = Pt[rows] - np.einsum("kij,kj->ki", Dp[rows], g)
    P_tau = P - np.einsum("ki,ki->k", n[rows], P)[:, None] * n[rows]
    u3 = np.einsum("kia,ka->ki", B[rows], u2)
    resid = np.linalg.norm(P_tau - (mu[rows] * N)[:, None] * u3, axis=1)
    ok = (np.isfinite(rho) & (rho > 0) & (N > N_MIN * np.linalg.norm(Pt[rows], axis=1)) & ~stick[rows]
          & (resid <= ACCEPT_TOL * np.linalg.norm(Pt[rows], axis=1)))
    out_g = np.full((m, MAX_ROOTS, 3), np.nan)
    out_N = np.full((m, MAX_ROOTS), np.nan)
    count = np.zeros(m, dtype=int)
    for k in np.flatnonzero(ok):
        i = rows[k]
        if count[i] and np.any(np.linalg.norm(out_g[i, :count[i]] - g[k], axis=1)
                               <= 1e-9 * np.linalg.norm(g[k])):
            continue  # the same root bracketed twice (H == 0 on a sample)
        if count[i] < MAX_ROOTS:
            out_g[i, count[i]], out_N[i, count[i]] = g[k], N[k]
            count[i] += 1
    lam = mu[:, None] * out_N / np.linalg.norm(out_g, axis=2)
    return dict(g=out_g, N=out_N, lam=lam, count=count, stick=stick, Pt=Pt,
                lam_p=largest_pole(K, p))


def largest_pole(K, p):
    """The largest lam > 0 where g(lam) = (K + lam I)^-1 p has a pole (0 if none), (m,).

    The poles are lam = -e for the real eigenvalues e < 0 of K, each counted
    only when the residue adj(K + lam I) p is not zero (POLE_RTOL relative).
    """
    ev = np.linalg.eigvals(K)
    out = np.zeros(len(K))
    for j in range(2):
        r = -ev[:, j].real
        real = np.abs(ev[:, j].imag) <= 1e-12 * np.abs(ev[:, j])
        v1 = (K[:, 1, 1] + r) * p[:, 0] - K[:, 0, 1] * p[:, 1]
        v2 = (K[:, 0, 0] + r) * p[:, 1] - K[:, 1, 0] * p[:, 0]
        size = (np.linalg.norm(K, axis=(1, 2)) + r) * np.linalg.norm(p, axis=1)
        active = real & (r > 0) & (np.hypot(v1, v2) > POLE_RTOL * size)
        out = np.where(active & (r > out), r, out)
    return out


def chosen(sol):
    """Index (m,) of the solution the rule takes per case (-1 where none).

    The rule: of the solutions on the branch lam > lam_p (lam = mu N/|g|,
    lam_p from :func:`largest_pole`), the one of largest lam -- the first met
    when the slip grows from zero along g(lam), lam coming down from infinity.
    """
    lam = sol["lam"]
    ok = np.isfinite(lam) & ((lam > sol["lam_p"][:, None]) | (sol["lam_p"][:, None] <= 0))
    idx = np.argmax(np.where(ok, lam, -np.inf), axis=1)
    return np.where(ok.any(axis=1), idx, -1)


# ---------------------------------------------------------------------------
# case classes
# ---------------------------------------------------------------------------
def _orth(rng, m):
    Q, R = np.linalg.qr(rng.standard_normal((m, 3, 3)))
    return Q * np.sign(np.diagonal(R, axis1=1, axis2=2))[:, None, :]


def _unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _spd(rng, m, log_cond):
    scale = 10.0 ** rng.uniform(1, 5, m)
    lam = scale[:, None] * 10.0 ** (-rng.uniform(0, 1, (m, 3)) * log_cond[:, None])
    Q = _orth(rng, m)
    M = np.einsum("mij,mj,mkj->mik", Q, lam, Q)
    return 0.5 * (M + M.transpose(0, 2, 1))


def _strut_dp(rng, m):
    """D_p of real struts (symcushion.legs.strut) at random poses: non-symmetric off rest."""
    from symcushion.legs.characteristics import Linear
    from symcushion.legs.strut import HingedStrut

    out = np.empty((m, 3, 3))
    per = 500
    for start in range(0, m, per):
        k = min(per, m - start)
        e0 = _unit(np.array([0.0, rng.uniform(0.1, 0.6), -1.0]))
        leg = HingedStrut(hinge=(0, 0, 0), e0=e0, en=(0, 0, -1), length=rng.uniform(0.3, 1.0),
                          S=Linear(10 ** rng.uniform(4, 6)), M_beta=Linear(10 ** rng.uniform(2, 4)),
                          M_gamma=Linear(10 ** rng.uniform(2, 4)))
        tilt = rng.uniform(0, 0.6, k)
        d = _unit(e0[None, :] + tilt[:, None] * _unit(rng.standard_normal((k, 3))))
        r = d * (leg.length * rng.uniform(0.7, 1.1, k))[:, None]
        v = rng.standard_normal((k, 3))
        f = leg.functions()["strut_stiffness"].map(k)
        Dp = np.asarray(f(r.T, v.T, np.zeros((0, k))))  # (3, 3k)
        out[start:start + k] = Dp.reshape(3, k, 3).transpose(1, 0, 2)
    return out


#: The case classes of the tests.
CLASSES = ("spd", "nonsym", "strut", "near_singular", "grazing", "receding")


def _stiffness(rng, m, base):
    """m stiffness matrices (m, 3, 3) of one of the first four classes."""
    if base == "spd":
        return _spd(rng, m, rng.uniform(0, 4, m))
    if base == "nonsym":
        W = rng.standard_normal((m, 3, 3))
        scale = 10.0 ** rng.uniform(1, 5, m)[:, None, None]
        skew = (_spd(rng, m, rng.uniform(0, 3, m))
                + scale * rng.uniform(0, 1, m)[:, None, None] * (W - W.transpose(0, 2, 1)))
        return np.where(rng.uniform(size=m)[:, None, None] < 0.5, skew, scale * W)
    if base == "strut":
        return _strut_dp(rng, m)
    cond = 10.0 ** rng.uniform(4, 8, m)
    scale = 10.0 ** rng.uniform(1, 5, m)
    sig = np.stack([scale, scale * cond ** -rng.uniform(0, 1, m), scale / cond], axis=1)
    U = _orth(rng, m)
    V = np.where(rng.uniform(size=m)[:, None, None] < 0.5, U, _orth(rng, m))
    return np.einsum("mij,mj,mkj->mik", U, sig, V)


def random_cases(rng, m, kind):
    """m random cases of one class; each a slip-prone step from a loaded contact.

    Classes: ``spd`` (symmetric positive definite D_p, cond <= 1e4),
    ``nonsym`` (SPD plus a skew part, or any sign pattern), ``strut`` (D_p of
    random struts at random poses), ``near_singular`` (cond 1e4 .. 1e8,
    symmetric or not), ``grazing`` (n.l = 0 or |n.l| <= 1e-12 |l|) and
    ``receding`` (n.l < 0), both with D_p drawn from the first four classes.
    In every class mu is uniform in [0.01, 2], n random, P0 compressive on or
    inside the cone, and |D_p l| / |P0| log-uniform in 1e-2 .. 1e2.

    Returns a dict of arrays P0 (m, 3), Dp (m, 3, 3), n (m, 3), l (m, 3),
    mu (m,), u0 (m, 3).
    """
    if kind not in CLASSES:
        raise ValueError(f"`kind` must be one of {CLASSES}; got {kind!r}.")
    if kind in CLASSES[:4]:
        Dp = _stiffness(rng, m, kind)
    else:  # a per-case mixture of the four stiffness classes
        pick = rng.integers(4, size=m)
        Dp = np.empty((m, 3, 3))
        for j, base in enumerate(CLASSES[:4]):
            Dp[pick == j] = _stiffness(rng, int(np.sum(pick == j)), base)
    n = _unit(rng.standard_normal((m, 3)))
    mu = rng.uniform(0.01, 2.0, m)
    b1, b2 = tangent_basis(n)
    phi = rng.uniform(0, 2 * np.pi, m)
    t = np.cos(phi)[:, None] * b1 + np.sin(phi)[:, None] * b2
    N0 = 10.0 ** rng.uniform(0, 3, m)
    P0 = N0[:, None] * (n + (mu * rng.uniform(0, 1, m) ** 0.25)[:, None] * t)
    l = _unit(rng.standard_normal((m, 3)))
    nl = np.einsum("mi,mi->m", n, l)
    if kind == "grazing":
        l = l - nl[:, None] * n
        l = l + (rng.uniform(-1e-12, 1e-12, m) * (rng.uniform(size=m) < 0.5))[:, None] * n
    elif kind == "receding":
        l = l - 2 * np.maximum(nl, 0)[:, None] * n - 1e-3 * n
    size = np.linalg.norm(P0, axis=1) * 10.0 ** rng.uniform(-2, 2, m)
    l = l * (size / np.linalg.norm(np.einsum("mij,mj->mi", Dp, l), axis=1))[:, None]
    return dict(P0=P0, Dp=Dp, n=n, l=l, mu=mu, u0=np.zeros((m, 3)))
