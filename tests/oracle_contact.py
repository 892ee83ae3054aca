"""Test oracle for the contact steps -- independent of the package.

This module is a *test oracle*: a plain, scalar NumPy transcription of the
three contact steps of Khvostov (1976) section 1, written line by line from
``docs/contact-spec.md`` and ``docs/paper-notes.md`` without looking at
``symcushion/contact/solve.py``.  It is not imported by the package and imports
nothing from it; ``tests/test_contact_oracle.py`` compares the package's
CasADi Functions with it.

Each step takes one case (``P0`` 3, ``Dp`` 3x3, ``n`` 3 unit, ``l`` 3,
``mu`` >= 0, ``u0`` 3) and returns ``(delta, P, k, contact)``: ``delta``, ``P``,
``k`` as float arrays of length 3 and ``contact`` as a float 0.0 / 1.0.

Every step optionally records its *branch path* (the discrete decisions it
took, as (name, value) pairs) in a list passed as ``path=``, and accepts
``force=`` (a dict name -> value) to take given decisions the other way.  The
test uses both to recognise cases that sit at a branch threshold (the path
changes under a perturbation of the inputs by a few ulp) and to evaluate the
other side of that branch on the same inputs.  Neither changes anything when
left at None.

The implicit step states the spec's rule (section 3: stick, else the first
slip solution on the branch from zero slip, else lift-off) on top of ``implicit_solutions``, an
iteration-free solver (all slip solutions by bracketing the direction angle
of the slip), independent of the package's quartic.

``random_cases`` generates the cases the comparison runs on; see its
docstring for the distribution.
"""

from __future__ import annotations

import math

import numpy as np

# Named constants: the same values as docs/contact-spec.md.
CONE_TOL = 1e-12   # robust step: on-cone(P) is gap(P) <= CONE_TOL |P|
TINY = 1e-300      # a denominator with |d| <= TINY is treated as zero


# ---------------------------------------------------------------------------
# small helpers, spelled out as in the spec
# ---------------------------------------------------------------------------

def _dot(a, b):
    return float(a[0] * b[0] + a[1] * b[1] + a[2] * b[2])


def _cross(a, b):
    return np.array([a[1] * b[2] - a[2] * b[1],
                     a[2] * b[0] - a[0] * b[2],
                     a[0] * b[1] - a[1] * b[0]])


def _sdiv(a, b):
    """Safe division a/b: 0 (of the shape of a) when |b| <= TINY."""
    if abs(b) > TINY:
        return a / b
    return a * 0.0


def _snorm(v):
    """Safe norm: sqrt(v.v), and 0 where v.v <= TINY."""
    vv = _dot(v, v)
    if vv > TINY:
        return math.sqrt(vv)
    return 0.0


def _sign(x):
    """sign with sign(0) = 0."""
    if x > 0:
        return 1.0
    if x < 0:
        return -1.0
    return 0.0


def _cone(P, n, mu):
    """C(P) = P.P - (1+mu^2)(n.P)^2, equation (1.5)."""
    nP = _dot(n, P)
    return _dot(P, P) - (1.0 + mu * mu) * nP * nP


def _gap(P, n, mu):
    """gap(P) = |P_tau| - mu n.P (1.4), safe norm: the cone as a distance."""
    return _snorm(P - _dot(n, P) * n) - mu * _dot(n, P)


def _on_cone(P, n, mu):
    """on-cone(P): gap(P) <= CONE_TOL |P| (safe norm) and n.P > 0."""
    return (_gap(P, n, mu) <= CONE_TOL * _snorm(P)) and (_dot(n, P) > 0)


def _tangential(v, n):
    """v_tau = v - (n.v) n."""
    return v - _dot(n, v) * n


def _prep(P0, Dp, n, l, mu, u0):
    P0 = np.asarray(P0, dtype=float).reshape(3)
    Dp = np.asarray(Dp, dtype=float).reshape(3, 3)
    n = np.asarray(n, dtype=float).reshape(3)
    l = np.asarray(l, dtype=float).reshape(3)
    u0 = np.asarray(u0, dtype=float).reshape(3)
    mu = float(np.asarray(mu, dtype=float).reshape(-1)[0])
    return P0, Dp, n, l, mu, u0


class _Decisions:
    """Records the branch decisions of one step; optionally forces some.

    ``path`` is a list receiving (name, value) pairs; ``force`` maps a
    decision name to the value to use instead of the computed one (the test
    uses it to evaluate the other side of a branch threshold on the same
    inputs).  Neither changes anything when left at None.
    """

    def __init__(self, path=None, force=None):
        self.path = path
        self.force = force or {}

    def __call__(self, name, value):
        value = self.force.get(name, value)
        if self.path is not None:
            self.path.append((name, value))
        return value


def _direction_e(P3, Dp, n):
    """e = w/|w|, w = n x (Dp^T (n x P3)), safe norm (e = 0 when w.w <= TINY)."""
    w = _cross(n, Dp.T @ _cross(n, P3))
    return _sdiv(w, _snorm(w))


# ---------------------------------------------------------------------------
# 1. the printed step (1.8)-(1.15)
# ---------------------------------------------------------------------------

def paper_step(P0, Dp, n, l, mu, u0, path=None, force=None):
    """Spec section 1: the printed step (1.8)-(1.15), docs/paper-notes.md §1 readings."""
    P0, Dp, n, l, mu, u0 = _prep(P0, Dp, n, l, mu, u0)
    d = _Decisions(path, force)
    m2 = 1.0 + mu * mu

    # 1. k1 (1.9), (1.10): only when (1.5) is violated, C0 > 0 strictly
    C0 = _cone(P0, n, mu)
    s = P0 - _dot(n, P0) * n
    if d("C0>0", C0 > 0):
        Dl = Dp @ l
        Ds = Dp @ s
        nP0 = _dot(n, P0)
        num = _dot(P0, Dl) - m2 * nP0 * _dot(n, Dl)
        den = _dot(P0, Ds) - m2 * nP0 * _dot(n, Ds)
        # a zero crossing of den makes k1 jump from +inf to -inf (recorded only)
        d("sign den", _sign(den) if abs(den) > TINY else 0.0)
        k1 = _sdiv(num, den)
        ub = _sdiv(_dot(s, u0), _dot(s, s))
        k1 = min(max(k1, 0.0), max(ub, 0.0))   # empty interval (ub < 0): k1 = 0
    else:
        k1 = 0.0

    # 2. k2 (1.11) with the printed P2 = P0 + Dp l (ignores k1)
    l_tau = l - _dot(n, l) * n
    P2 = P0 + Dp @ l
    Dlt = Dp @ l_tau
    nDlt = _dot(n, Dlt)
    A2 = _dot(Dlt, Dlt) - m2 * nDlt * nDlt
    B2 = _dot(P2, Dlt) - m2 * _dot(n, P2) * nDlt
    C2 = _cone(P2, n, mu)
    if d("k2=0", (C2 < 0) and (_dot(n, P2) > 0)):
        k2 = 0.0
    else:
        roots = []
        if d("A2!=0", A2 != 0):                          # exact comparison
            disc = B2 * B2 - A2 * C2
            if not d("disc2<0", disc < 0):              # no real root
                sq = math.sqrt(max(disc, 0.0))          # max: only if forced
                roots = [(B2 + sq) / A2, (B2 - sq) / A2]
        elif d("B2!=0", B2 != 0):
            roots = [C2 / (2.0 * B2)]
        inside = [r for i, r in enumerate(roots)
                  if d(f"root{i} in (0,1)", 0.0 < r < 1.0)]
        k2 = min(inside) if inside else 1.0

    # 3. k3 (1.12)-(1.15)
    d3 = l - k1 * s - k2 * l_tau
    P3 = P0 + Dp @ d3
    e = _direction_e(P3, Dp, n)
    Pe = Dp @ e
    nPe = _dot(n, Pe)
    nP3 = _dot(n, P3)
    A3 = _dot(Pe, Pe) - m2 * nPe * nPe
    B3 = _dot(P3, Pe) - m2 * nP3 * nPe
    C3 = _cone(P3, n, mu)
    H = _dot(_tangential(P3, n), _tangential(Pe, n))
    if d("C3>0", C3 > 0):
        if d("A3!=0", A3 != 0):                          # exact comparison
            sH = d("sign H", _sign(H))                  # sign(0) = 0
            # max(., 0): the one departure from print (docs/paper-notes.md §3.3)
            k3 = (-B3 + math.sqrt(max(B3 * B3 - A3 * C3, 0.0)) * sH) / A3
        elif d("B3!=0", B3 != 0):
            k3 = -C3 / (2.0 * B3)
        else:
            k3 = 0.0
    else:
        k3 = 0.0

    # 4. delta, P (1.3)
    delta = d3 + k3 * e
    P = P0 + Dp @ delta
    # 5. no separation branch: P and delta as computed; contact is a diagnostic
    contact = 1.0 if d("n.P>0", _dot(n, P) > 0) else 0.0
    return delta, P, np.array([k1, k2, k3]), contact


# ---------------------------------------------------------------------------
# 2. the robust step: docs/paper-notes.md §3 items 1-5 fixed
# ---------------------------------------------------------------------------

def _cone_cleanup(P, n, mu):
    """P_tau <- P_tau min(1, mu n.P / |P_tau|) (safe division, safe norm)."""
    N = _dot(n, P)
    Pt = P - N * n
    T = _snorm(Pt)
    factor = min(1.0, _sdiv(mu * N, T))
    return N * n + factor * Pt


def robust_step(P0, Dp, n, l, mu, u0, path=None, force=None):
    """Spec section 2: the printed method with docs/paper-notes.md §3 items 1-5 fixed."""
    P0, Dp, n, l, mu, u0 = _prep(P0, Dp, n, l, mu, u0)
    d = _Decisions(path, force)
    m2 = 1.0 + mu * mu

    # 1. stick trial
    Pt = P0 + Dp @ l
    if d("stick", _on_cone(Pt, n, mu)):
        return l.copy(), Pt, np.zeros(3), 1.0

    # 2. k1 with a tolerance on "(1.5) violated"; the clamp (1.10) only as a
    # safeguard
    s = P0 - _dot(n, P0) * n
    nrm0 = _snorm(P0)
    nP0 = _dot(n, P0)
    if d("k1 fires", (_gap(P0, n, mu) >= -CONE_TOL * nrm0) and (nP0 > 0)
         and (_dot(s, s) > CONE_TOL * nrm0 * nrm0)):
        Dl = Dp @ l
        Ds = Dp @ s
        num = _dot(P0, Dl) - m2 * nP0 * _dot(n, Dl)
        den = _dot(P0, Ds) - m2 * nP0 * _dot(n, Ds)
        d("sign den", _sign(den) if abs(den) > TINY else 0.0)   # recorded only
        k1 = max(_sdiv(num, den), 0.0)
        ub = _sdiv(_dot(s, u0), _dot(s, s))
        if d("ub>0", ub > 0):
            k1 = min(k1, ub)
    else:
        k1 = 0.0

    # 3. k2 with P2 = P0 + Dp (l - k1 s), a tolerance, and stable roots
    l_tau = l - _dot(n, l) * n
    P2 = P0 + Dp @ (l - k1 * s)
    Dlt = Dp @ l_tau
    nDlt = _dot(n, Dlt)
    nP2 = _dot(n, P2)
    A2 = _dot(Dlt, Dlt) - m2 * nDlt * nDlt
    B2 = _dot(P2, Dlt) - m2 * nP2 * nDlt
    C2 = _cone(P2, n, mu)
    if d("k2=0", _on_cone(P2, n, mu)):
        k2 = 0.0
    else:
        D = B2 * B2 - A2 * C2
        if d("D<0", D < 0):
            k2 = 1.0
        else:
            q = B2 + (1.0 if B2 >= 0 else -1.0) * math.sqrt(max(D, 0.0))
            cands = []
            if d("|A2|>TINY", abs(A2) > TINY):
                cands.append(("q/A2", q / A2))
            if d("|q|>TINY", abs(q) > TINY):
                cands.append(("C2/q", C2 / q))
            counts = [lam for name, lam in cands
                      if d(f"{name} counts",
                           0.0 < lam < 1.0 and _dot(n, P2 - lam * Dlt) > 0)]
            k2 = min(counts) if counts else 1.0
            if len(counts) == 2:
                d("k2 choice", counts[1] < counts[0])          # recorded only

    # 4. k3 by the closed-form roots (docs/paper-notes.md §3.3)
    d3 = l - k1 * s - k2 * l_tau
    P3 = P0 + Dp @ d3
    N = _dot(n, P3)
    P3t = P3 - N * n
    T = _snorm(P3t)
    t_hat = _sdiv(P3t, T)
    e = _direction_e(P3, Dp, n)
    Pe = Dp @ e
    a = _dot(n, Pe)
    b = _dot(t_hat, Pe)
    no_root = False
    if d("k3=0", _on_cone(P3, n, mu)):
        k3 = 0.0
    else:
        cands = []
        den_p = b - mu * a
        if d("|b-mu a|>TINY", abs(den_p) > TINY):
            cands.append(("k+", (mu * N - T) / den_p))
        den_m = b + mu * a
        if d("|b+mu a|>TINY", abs(den_m) > TINY):
            cands.append(("k-", -(T + mu * N) / den_m))
        counts = [k for name, k in cands
                  if d(f"{name} counts", k * b < 0 and N + k * a > 0)]
        if counts:
            # the counting candidate of smallest |k| (an exact tie keeps k+)
            k3 = counts[0]
            if len(counts) == 2 and d("k3 takes k-", abs(counts[1]) < abs(counts[0])):
                k3 = counts[1]
        else:
            k3 = 0.0
            no_root = True

    # 5. delta, P; cone clean-up (the chain ran)
    delta = d3 + k3 * e
    P = _cone_cleanup(P0 + Dp @ delta, n, mu)
    k = np.array([k1, k2, k3])

    # 6. separation: n.P <= 0 (the P of step 5, after the clean-up), no k3
    # candidate counted when one was needed, or, with a tensile trial force
    # n.P_t <= 0, friction along the accumulated slip l - delta
    # (P_tau . (l - delta) < 0: no Coulomb state)
    PN = _dot(n, P)
    # (with a tolerance: at mu = 0 P_tau is round-off and must not decide)
    anti = (_dot(P - PN * n, l - delta) < -CONE_TOL * _snorm(P) * _snorm(l - delta)
            and _dot(n, Pt) <= 0)
    if d("lift", (PN <= 0) or no_root or anti):
        return -u0.copy(), np.zeros(3), k, 0.0
    return delta, P, k, 1.0


# ---------------------------------------------------------------------------
# 3. the implicit (backward-Euler) Coulomb step
# ---------------------------------------------------------------------------

def _snorm2(x, y):
    """Safe norm of a 2-vector (x, y): sqrt(x^2 + y^2), 0 where that is <= TINY."""
    s = x * x + y * y
    return math.sqrt(s) if s > TINY else 0.0


def _implicit_trial(Pt, n):
    """Spec section 3 step 1: the fixed tangent basis and the tangential trial
    force.  The axis a in {x, y, z} with the smallest |n_i| (first on a tie;
    not a recorded decision: it changes only the round-off),
    e1 = (n x a)/|n x a| (safe), e2 = n x e1, c_i = e_i.P_t,
    T_t = sqrt(c1^2 + c2^2) (safe).  Returns e1, e2, c1, c2, T_t."""
    ax, ay, az = abs(n[0]), abs(n[1]), abs(n[2])
    if ax <= ay and ax <= az:
        axis = 0
    elif ay <= az:
        axis = 1
    else:
        axis = 2
    a = np.zeros(3)
    a[axis] = 1.0
    w = _cross(n, a)
    e1 = _sdiv(w, _snorm(w))
    e2 = _cross(n, e1)
    c1, c2 = _dot(e1, Pt), _dot(e2, Pt)
    return e1, e2, c1, c2, _snorm2(c1, c2)


def _largest_pole(Pt, Dp, n):
    """The largest lam > 0 at which g(lam) = (K + lam I)^-1 p has a pole (0 if
    none): lam = -e for a real eigenvalue e < 0 of K whose residue
    adj(K + lam I) p is not zero (1e-9 relative)."""
    t1 = _tangential(Pt, n)
    T = np.linalg.norm(t1)
    if T == 0.0:
        return 0.0
    t1 = t1 / T
    B = np.stack([t1, _cross(n, t1)], axis=1)
    K = B.T @ Dp @ B
    p = np.array([T, 0.0])
    best = 0.0
    for e in np.linalg.eigvals(K):
        r = -e.real
        if abs(e.imag) > 1e-12 * abs(e) or r <= best:
            continue
        v = np.array([[K[1, 1] + r, -K[0, 1]], [-K[1, 0], K[0, 0] + r]]) @ p
        if np.linalg.norm(v) > 1e-9 * (np.linalg.norm(K) + r) * T:
            best = r
    return best


def implicit_step(P0, Dp, n, l, mu, u0, path=None, force=None):
    """Spec section 3: the exact backward-Euler Coulomb step, by its rule.

    Stick when the trial force is inside the cone (T_t <= mu N_t, N_t > 0);
    else every slip solution with n.P > 0 from ``implicit_solutions`` (a scan
    of the slip direction, independent of the package's quartic) on the
    branch above the largest pole of g(lam), and the one of largest
    lam = mu N/|g|; lift-off when there is none.  In contact P = N n +
    mu N g/|g| with N = n.(P0 + Dp (l - g)), on the cone by construction."""
    P0, Dp, n, l, mu, u0 = _prep(P0, Dp, n, l, mu, u0)
    d = _Decisions(path, force)
    Pt = P0 + Dp @ l
    Nt = _dot(n, Pt)
    _, _, _, _, Tt = _implicit_trial(Pt, n)
    if d("stick", (Tt <= mu * Nt) and (Nt > 0)):
        return l.copy(), Pt, np.zeros(3), 1.0
    # a slip ending at N of round-off is lift-off: N > CONE_TOL |P_t|; only
    # the branch lam > lam_p counts (lam_p the largest pole of g(lam) with a
    # non-zero residue); of those the largest lam = mu N/|g|
    lam_p = _largest_pole(Pt, Dp, n)
    sols = [(mu * N / np.linalg.norm(g), g) for g, N in implicit_solutions(P0, Dp, n, l, mu)
            if N > CONE_TOL * _snorm(Pt)]
    sols = [(lam, g) for lam, g in sols if lam > lam_p or lam_p <= 0]
    if d("no slip solution", not sols):
        return -u0.copy(), np.zeros(3), np.zeros(3), 0.0
    g = max(sols, key=lambda s: s[0])[1]
    delta = l - g
    N = _dot(n, P0 + Dp @ delta)
    P = N * n + mu * N * g / np.linalg.norm(g)
    return delta, P, g, 1.0


def implicit_solutions(P0, Dp, n, l, mu):
    """Iteration-free check of the implicit step (not part of the spec).

    For a slip case (not stick, by the same test as the step: T_t > mu N_t
    or N_t <= 0, in the spec's fixed basis) returns the list of *all* slip
    vectors g (3-vectors, n.g = 0) with P = P0 + Dp (l - g) on the cone:
    P_tau = mu (n.P) g/|g|, g != 0, found by ``_slip_solutions``, each with
    its n.P.  Returns None for a stick case.
    """
    P0, Dp, n, l, mu, _ = _prep(P0, Dp, n, l, mu, np.zeros(3))
    Pt = P0 + Dp @ l
    Nt = _dot(n, Pt)
    e1, e2, c1, c2, Tt = _implicit_trial(Pt, n)
    if Tt <= mu * Nt and Nt > 0:
        return None
    if Tt == 0.0:
        return []
    t1 = (c1 / Tt) * e1 + (c2 / Tt) * e2
    t2 = _cross(n, t1)
    out = []
    for g2 in _slip_solutions(Dp, n, t1, t2, Tt, Nt, mu):
        g = g2[0] * t1 + g2[1] * t2
        out.append((g, _dot(n, P0 + Dp @ (l - g))))
    return out


IMPLICIT_SCAN = 720   # angles scanned to bracket the slip solutions


def _slip_solutions(Dp, n, t1, t2, T, Nt, mu):
    """All slip vectors g = rho (cos th, sin th) in the (t1, t2) basis with

        P_tau(g) = mu N(g) g/|g|,  P(g) = P_t - Dp g,  rho > 0,

    where P_t,tau = (T, 0).  For a fixed direction th the condition is linear
    in rho: a(th) = rho b(th), a = (T, 0) - mu Nt (cos, sin),
    b = M (cos, sin) - mu (c.(cos, sin)) (cos, sin), M the tangential block of
    Dp and c = n^T Dp restricted to the plane.  The roots of the 2-D cross
    product a x b are bracketed on a grid of IMPLICIT_SCAN angles, refined by
    bisection to the last bit, and each solution is polished by Newton steps
    on the original 2-unknown residual.  Returns a list of (g1, g2)."""
    B = np.stack([t1, t2], axis=1)
    M = B.T @ Dp @ B
    c = n @ Dp @ B
    th = np.linspace(-math.pi, math.pi, IMPLICIT_SCAN, endpoint=False)

    def parts(theta):
        ct, st = np.cos(theta), np.sin(theta)
        a1, a2 = T - mu * Nt * ct, -mu * Nt * st
        cu = c[0] * ct + c[1] * st
        b1 = M[0, 0] * ct + M[0, 1] * st - mu * cu * ct
        b2 = M[1, 0] * ct + M[1, 1] * st - mu * cu * st
        return a1, a2, b1, b2

    m00, m01, m10, m11 = (float(x) for x in M.ravel())
    c0, c1 = float(c[0]), float(c[1])

    def cross(theta):      # scalar version of a x b, for the bisection
        ct, st = math.cos(theta), math.sin(theta)
        cu = c0 * ct + c1 * st
        return ((T - mu * Nt * ct) * (m10 * ct + m11 * st - mu * cu * st)
                + mu * Nt * st * (m00 * ct + m01 * st - mu * cu * ct))

    a1, a2, b1, b2 = parts(th)
    f = a1 * b2 - a2 * b1
    roots = []
    for i in np.flatnonzero((f * np.roll(f, -1) <= 0) | (f == 0)):
        lo, hi = float(th[i]), float(th[i]) + 2 * math.pi / IMPLICIT_SCAN
        flo = float(f[i])
        if flo == 0.0:
            roots.append(lo)
            continue
        if flo * float(f[(i + 1) % IMPLICIT_SCAN]) > 0:
            continue
        for _ in range(200):
            mid = 0.5 * (lo + hi)
            if mid <= lo or mid >= hi:
                break
            fm = cross(mid)
            if fm == 0.0:
                lo = hi = mid
                break
            if (fm > 0) == (flo > 0):
                lo, flo = mid, fm
            else:
                hi = mid
        roots.append(0.5 * (lo + hi))
    sols = []
    for theta in roots:
        A1, A2, B1, B2 = parts(theta)
        bb = B1 * B1 + B2 * B2
        if not bb > 0:
            continue
        rho = (A1 * B1 + A2 * B2) / bb
        if not rho > 0:
            continue
        g = np.array([rho * math.cos(theta), rho * math.sin(theta)])
        g = _polish(g, M, c, T, Nt, mu)
        if g is not None and all(math.hypot(*(g - h)) > 1e-9 * math.hypot(*g)
                                 for h in sols):
            sols.append(g)
    return sols


def _polish(g, M, c, T, Nt, mu, iters=4):
    """Newton steps on R(g) = P_tau(g) - mu N(g) g/|g| = 0 (2 unknowns)."""
    def resid(gg):
        r = math.hypot(gg[0], gg[1])
        N = Nt - (c[0] * gg[0] + c[1] * gg[1])
        Pt_ = np.array([T, 0.0]) - M @ gg
        return Pt_ - mu * N * gg / r, r, N

    for _ in range(iters):
        R, r, N = resid(g)
        gh = g / r
        J = -M + mu * np.outer(gh, c) - mu * N * (np.eye(2) - np.outer(gh, gh)) / r
        try:
            step = np.linalg.solve(J, -R)
        except np.linalg.LinAlgError:
            break
        g_new = g + step
        if not np.all(np.isfinite(g_new)) or math.hypot(*g_new) == 0.0:
            break
        if np.linalg.norm(resid(g_new)[0]) > np.linalg.norm(R):
            break
        g = g_new
    return g


# ---------------------------------------------------------------------------
# random cases
# ---------------------------------------------------------------------------

KINDS = ("spd", "nonsym", "singular", "plane")


def _unit(v):
    return v / np.linalg.norm(v)


def _orth(rng):
    q, r = np.linalg.qr(rng.standard_normal((3, 3)))
    return q * np.sign(np.diag(r))


def _dp_spd(rng, K):
    lam = K * 10.0 ** rng.uniform(-3.0, 0.0, 3)
    Q = _orth(rng)
    M = Q @ np.diag(lam) @ Q.T
    return 0.5 * (M + M.T)


def _dp_nonsym(rng, K):
    c = rng.integers(3)
    if c == 0:     # SPD plus a skew part of comparable size
        W = rng.standard_normal((3, 3))
        return _dp_spd(rng, K) + K * rng.uniform(0, 1) * (W - W.T)
    if c == 1:     # any sign pattern, possibly indefinite
        return K * rng.standard_normal((3, 3))
    # SPD rotated (non-symmetric, still "mostly restoring")
    return _dp_spd(rng, K) @ _orth(rng)


def _dp_singular(rng, K):
    cond = 10.0 ** rng.uniform(4.0, 8.0)
    if rng.uniform() < 0.1:
        cond = 1e8
    sig = np.array([K, K * cond ** -rng.uniform(0.0, 1.0), K / cond])
    U = _orth(rng)
    V = U if rng.uniform() < 0.5 else _orth(rng)
    return U @ np.diag(sig) @ V.T


def random_cases(rng, count, kind="mixed"):
    """Random contact-step cases.

    ``kind``: ``"spd"`` (symmetric positive definite Dp, condition number up
    to 1e3), ``"nonsym"`` (SPD + skew, Gaussian of any sign pattern, or SPD
    times a rotation), ``"singular"`` (U diag(sigma) V^T with condition number
    10^4 .. 10^8, symmetric in half of the cases), ``"plane"`` (plane-parallel
    cases: P0, l, u0 in the plane of n and a tangent t1, Dp = B M B^T in the
    basis B = [t1, n, t2] with M[2,0] = M[2,1] = 0, so that plane is
    invariant; its 2x2 block is drawn as one of the other kinds), or
    ``"mixed"`` (each case one of the four).

    In every kind: n is a coordinate axis (+-) in a quarter of the cases, a
    random unit vector otherwise; mu is exactly 0 (15 %), exactly 2 (5 %) or
    uniform in (0, 2); P0 is inside the cone (25 %), exactly on it by
    construction, P0 = N0 n + mu N0 t with |t| = 1, n.t = 0 (25 %), outside
    it with n.P0 > 0 (30 %), tensile n.P0 < 0 (10 %), or zero (10 %, the
    first contact, with u0 = 0); l is landing n.l > 0 (40 %), grazing (20 %:
    n.l = 0 exactly by construction or |n.l| <= 1e-14 |l|), receding
    n.l < 0 (40 %), with |Dp||l| / |P0| log-uniform in 1e-3 .. 10; u0 is
    zero (with P0 = 0, and in 5 % of the other cases: the clamp bound
    ub = 0), solve(Dp, P0) when cond(Dp) < 1e4 (70 % of those) and random
    of size |P0|/|Dp| otherwise.

    Returns a dict of arrays: P0 (N,3), Dp (N,3,3), n (N,3), l (N,3),
    mu (N,), u0 (N,3), and labels kind, cone, motion, u0_kind (N,) of str.
    """
    out = {key: [] for key in ("P0", "Dp", "n", "l", "mu", "u0",
                               "kind", "cone", "motion", "u0_kind")}
    for _ in range(count):
        kd = KINDS[rng.integers(4)] if kind == "mixed" else kind
        if kd not in KINDS:
            raise ValueError(f"unknown kind {kind!r}")
        # normal and tangent basis
        if rng.uniform() < 0.25:
            n = np.zeros(3)
            n[rng.integers(3)] = rng.choice([-1.0, 1.0])
        else:
            n = _unit(rng.standard_normal(3))
        t1 = _unit(_cross(n, rng.standard_normal(3)))
        t2 = _cross(n, t1)
        # friction
        r = rng.uniform()
        mu = 0.0 if r < 0.15 else (2.0 if r < 0.20 else rng.uniform(0.0, 2.0))
        # stiffness
        K = 10.0 ** rng.uniform(1.0, 5.0)
        if kd == "spd":
            Dp = _dp_spd(rng, K)
        elif kd == "nonsym":
            Dp = _dp_nonsym(rng, K)
        elif kd == "singular":
            Dp = _dp_singular(rng, K)
        else:
            sub = ("spd", "nonsym", "singular")[rng.integers(3)]
            gen = {"spd": _dp_spd, "nonsym": _dp_nonsym, "singular": _dp_singular}[sub]
            G = gen(rng, K)
            M = np.zeros((3, 3))
            M[:2, :2] = G[:2, :2]
            M[:2, 2] = G[:2, 2]
            M[2, 2] = G[2, 2] if sub != "nonsym" else K * rng.uniform(0.01, 1.0)
            B = np.stack([t1, n, t2], axis=1)
            Dp = B @ M @ B.T
        # tangential direction of P0 and l
        if kd == "plane":
            tP = rng.choice([-1.0, 1.0]) * t1
            tl = rng.choice([-1.0, 1.0]) * t1
        else:
            tP = _unit(rng.uniform(-1, 1) * t1 + rng.uniform(-1, 1) * t2)
            tl = _unit(rng.uniform(-1, 1) * t1 + rng.uniform(-1, 1) * t2)
        # P0
        F = 10.0 ** rng.uniform(-1.0, 3.0)
        N0 = F * rng.uniform(0.1, 1.0)
        r = rng.uniform()
        if r < 0.25:
            cone = "inside"
            P0 = N0 * n + mu * N0 * rng.uniform(0.0, 1.0) * tP
        elif r < 0.50:
            cone = "on"
            P0 = N0 * n + mu * N0 * tP
        elif r < 0.80:
            cone = "outside"
            P0 = N0 * n + N0 * (mu + 10.0 ** rng.uniform(-3.0, 0.5)) * tP
        elif r < 0.90:
            cone = "tensile"
            P0 = -N0 * n + N0 * rng.uniform(0.0, 2.0) * tP
        else:
            cone = "zero"
            P0 = np.zeros(3)
        # l
        normDp = np.linalg.norm(Dp, 2)
        L = F * 10.0 ** rng.uniform(-3.0, 1.0) / normDp
        lt = L * rng.uniform(0.0, 1.0) * tl
        r = rng.uniform()
        if r < 0.4:
            motion = "landing"
            l = L * rng.uniform(0.05, 1.0) * n + lt
        elif r < 0.6:
            motion = "grazing"
            if rng.uniform() < 0.5:
                l = lt.copy()
            else:
                l = L * 1e-14 * rng.uniform(-1.0, 1.0) * n + lt
        else:
            motion = "receding"
            l = -L * rng.uniform(0.05, 1.0) * n + lt
        # u0
        if cone == "zero" or rng.uniform() < 0.05:
            u0, u0_kind = np.zeros(3), "zero"
        elif np.linalg.cond(Dp) < 1e4 and rng.uniform() < 0.7:
            u0, u0_kind = np.linalg.solve(Dp, P0), "solve"
        else:
            u0 = np.linalg.norm(P0) / normDp * rng.uniform(0.0, 2.0) * _unit(
                rng.standard_normal(3))
            if kd == "plane":
                u0 = u0 - _dot(t2, u0) * t2
            u0_kind = "random"
        for key, val in (("P0", P0), ("Dp", Dp), ("n", n), ("l", l), ("mu", mu),
                         ("u0", u0), ("kind", kd), ("cone", cone),
                         ("motion", motion), ("u0_kind", u0_kind)):
            out[key].append(val)
    res = {key: np.array(out[key], dtype=float) for key in
           ("P0", "Dp", "n", "l", "mu", "u0")}
    for key in ("kind", "cone", "motion", "u0_kind"):
        res[key] = np.array(out[key])
    return res
