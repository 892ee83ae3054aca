"""Does a RATTLE lock restore second order where a leg's stroke locks? A planar control.

Question
    An absorber's force follows a loading curve S_l(c) while the compression c
    grows and a lower unloading curve S_u(c) while it shrinks. When the load
    lies between them the Filippov motion locks the stroke (c' = 0, force
    anywhere in [S_u, S_l]) until that force reaches a curve. Velocity Verlet
    taking the branch from the sign of the stroke change over the step cannot
    lock; it alternates branches (a sliding mode), an O(h) velocity error.
    Does a RATTLE-type step for locked legs restore second order, and what
    else does it need (a reversal that does not lock: a direct switch)? A
    planar model, independent of the package, against an event-driven
    reference.

Model
    Body in the x-z plane (m = 150 kg, J = 20 kg m^2, q = (x, z, theta)) on two
    legs with fixed feet r_i: hinge h_i = (x, z) + R b_i, d_i = r_i - h_i,
    c_i = L0 - |d_i|. The axial force S pushes the hinge away from the foot:
    generalized force -S G_i, G_i = dc_i/dq. S_l(c) = min(k c, F_c + k_p
    (c - F_c/k)); S_u = 500 N for c >= 0.03 m, linear from 0 below; both k c
    for c <= 0 (not reached). Bending springs k_b/2 (phi_i - phi_i0)^2 on the
    angle phi_i of d_i in the body frame.

Methods
    Reference: a mode per leg (loading, unloading, locked); locked legs carry
    multipliers from c_i'' = G_i q'' + kappa_i = 0; DOP853, rtol = atol = 1e-12,
    terminal events (free leg: c_i' = 0; locked leg: its force reaching S_l or
    S_u), restart in the new modes.
    verlet_chord: the end-of-step branch is loading if c grew over the step.
    rattle_mu, rattle_hold: a locked leg's force is Lam_i in the first kick,
    with c_i(q_{n+1}) = c_i(q_n) (SHAKE), and mu_i in the second, with
    G_i(q_{n+1}) v_{n+1} = 0 (RATTLE); mu_i off [S_u, S_l] releases the leg
    onto the curve crossed. A free leg whose chord branch flips is locked if
    (rattle_mu, as proposed) its mu_i lies within the curves, or (rattle_hold)
    after projecting v onto G_L v = 0, its holding force from c'' = 0 does.
    Lock entry: near the lock instant the leg carried a partly wrong branch
    force, along its own wrench G_i^T, so the velocity error is M^-1 G_i^T b.
    The projection v -= M^-1 G^T (G M^-1 G^T)^-1 G v removes exactly that and
    keeps the exact velocity (G_i v = 0); left is the locked stroke's offset
    c''/2 (t_{n+1} - t*)^2, t_{n+1} - t* < 3h/2: O(h^2), once. Release: mu_i
    crosses a curve, so the force taken on equals mu_i up to one step's drift:
    an O(h^2) impulse, once. But mu_i at lock entry is not the holding force:
    it carries the projection impulse, (2/h) G_i v_half / (G_i M^-1 G_i^T) =
    O(gap), so rattle_mu can refuse a lock (an O(h) impulse error) and, via the
    joint solve, release the other leg; rattle_hold keeps impulse and force
    apart. Neither treats a direct switch (a reversal with the holding force
    off the curves): a force jump by the gap at an unlocated instant, O(h).
    verlet_switch, rattle_hold_switch: the chord and hold steppers with the
    direct switch located. A leg that reverses without locking changed its
    node force's branch between t_n and t_{n+1}, so the kicks switch at
    t_n + h/2; the stroke rate's zero t* = t_n + theta h is interpolated
    through the rate at t_n and the chord's, (c_{n+1} - c_n)/h, at mid-step
    (both follow the old branch: the drift used F_n only), and the missing
    impulse -(t* - t_n - h/2) G^T (S_old - S_new) is added to v_{n+1}.
    Scenarios: "direct-switch", (vx, vz, omega)(0) = (0.3, -2, 0.5), has
    direct switches; "lock-only", (0.3, -1, 0), the nearest start in a small scan
    whose reference only crushes, locks and releases; three more lock-only
    starts check the orders. Errors: |(dx, dz, ARM dtheta)|, |(dvx, dvz,
    ARM domega)|, relative max(pos/0.1 m, vel/1 m/s), at T and RMS over
    t = 0, 4 ms, ...; orders: least-squares slopes in log-log.

Output
    Per scenario the reference's events and self-check, a Markdown table
    (errors, stroke reversals per leg, lock episodes, wall time per simulated
    second) and fitted orders; figures/lock_control.png.

Run
    python studies/lock_control.py
"""
import math
import os
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy.integrate import solve_ivp

from symcushion.run.error_control import fitted_order

MASS, INERTIA, GRAV = 150.0, 20.0, 9.81          # kg, kg m^2, m/s^2
MINV = 1.0 / np.array([MASS, MASS, INERTIA])      # M^-1 (diagonal)
B = np.array([[-0.5, -0.2], [0.5, -0.2]])         # hinges in the body frame (m)
L0 = 0.8                                          # rest length (m)
K, F_C, K_P = 1e5, 2500.0, 5e3                    # N/m, N, N/m: loading curve
S_U, C_U = 500.0, 0.03                            # N, m: unloading curve
K_B = 2e4                                         # bending spring (N m/rad)
PHI0 = np.radians([-20.0, 20.0])                  # rest directions, splayed out
Q0 = np.array([0.0, 1.0, np.radians(3.0)])        # initial pose (m, m, rad)
SCENARIOS = {"direct-switch": (0.3, -2.0, 0.5), "lock-only": (0.3, -1.0, 0.0)}   # (vx, vz, omega)
CHECKS = [(0.3, -0.9, 0.1), (0.3, -0.8, 0.2), (0.0, -0.8, 0.0)]  # more lock-only starts
C_INIT = 0.001                                    # initial compression (m)
T = 0.6                                           # simulated time (s)
STEPS = [4e-3, 2e-3, 1e-3, 5e-4, 2.5e-4, 1.25e-4]
SAMPLE = 4e-3                                     # RMS grid: a multiple of every step
ARM = 0.5                                         # m: theta errors counted as ARM*dtheta
Q_SCALE, V_SCALE = 0.1, 1.0                       # m, m/s: scales of the combined error
LOAD, UNLOAD, LOCK = 0, 1, 2
NAMES = ("loading", "unloading", "locked")
#: (name, lock rule, located direct switch)
STEPPERS = (("verlet_chord", None, False), ("verlet_switch", None, True),
            ("rattle_mu", "mu", False), ("rattle_hold", "hold", False),
            ("rattle_hold_switch", "hold", True))
FIG = Path(__file__).resolve().parent.parent / "figures" / "lock_control.png"


def s_load(c):
    return min(K * c, F_C + K_P * (c - F_C / K))


def s_unload(c):
    return K * c if c <= 0.0 else S_U * min(c / C_U, 1.0)


def curve(c, branch):
    return s_load(c) if branch == LOAD else s_unload(c)


# Feet: the rest pose's feet at Q0 (phi = phi0), moved C_INIT along the leg to the hinge.
R0 = np.array([[math.cos(Q0[2]), -math.sin(Q0[2])], [math.sin(Q0[2]), math.cos(Q0[2])]])
FEET = np.array([Q0[:2] + R0 @ (B[i] + (L0 - C_INIT) * np.array([np.sin(p), -np.cos(p)]))
                 for i, p in enumerate(PHI0)])


def kin(q, v=None):
    """Compressions c (2,), G = dc/dq (2, 3), gravity + bending force Q (3,),
    and, given v, the bias kappa (2,) of c'' = G q'' + kappa."""
    x, z, th = q
    co, si = math.cos(th), math.sin(th)
    c, G, kap = np.empty(2), np.empty((2, 3)), np.empty(2)
    Q = np.array([0.0, -MASS * GRAV, 0.0])
    for i in range(2):
        bx, bz = B[i]
        rbx, rbz = co * bx - si * bz, si * bx + co * bz            # R b
        dx, dz = FEET[i, 0] - x - rbx, FEET[i, 1] - z - rbz        # d = r - h
        L = math.hypot(dx, dz)
        ex, ez = dx / L, dz / L
        c[i] = L0 - L
        # c = L0 - |d|: dc/dq = e . dh/dq, dh/dtheta = R'b = (-rbz, rbx)
        G[i] = (ex, ez, -ex * rbz + ez * rbx)
        # Bending: u = R^T (r - p) - b = R^T d (body frame), phi = atan2(u_x, -u_z),
        # dphi = w . du with w = (-u_z, u_x)/L^2; du/dp = -R^T,
        # du/dtheta = dR^T/dtheta (r - p) = (u_z + b_z, -u_x - b_x).
        ux, uz = co * dx + si * dz, -si * dx + co * dz
        wx, wz = -uz / L**2, ux / L**2
        dphi = (-(co * wx - si * wz), -(si * wx + co * wz),
                wx * (uz + bz) - wz * (ux + bx))
        Q -= K_B * (math.atan2(ux, -uz) - PHI0[i]) * np.array(dphi)   # -grad V_i
        if v is not None:
            # d' = -p' - omega R'b; c'' = G q'' - omega^2 e.(R b) - (|d'|^2 - (e.d')^2)/L
            w = v[2]
            ddx, ddz = -v[0] + w * rbz, -v[1] - w * rbx
            ed = ex * ddx + ez * ddz
            kap[i] = -w * w * (ex * rbx + ez * rbz) - (ddx**2 + ddz**2 - ed**2) / L
    return c, G, Q, kap


def project(G, v):
    """v - M^-1 G^T (G M^-1 G^T)^-1 G v: the nearest velocity (M-norm) with G v = 0."""
    return v - MINV * (G.T @ np.linalg.solve((G * MINV) @ G.T, G @ v))


def check_gradients():
    """Hand derivatives against central differences (the model's own check)."""
    def potential(q):   # m g z + sum k_b/2 (phi_i - phi_i0)^2, u = R^T (r - p) - b
        co, si = math.cos(q[2]), math.sin(q[2])
        u = (FEET - q[:2]) @ np.array([[co, -si], [si, co]]) - B
        return MASS * GRAV * q[1] + 0.5 * K_B * np.sum((np.arctan2(u[:, 0], -u[:, 1]) - PHI0) ** 2)
    q, v, eps = Q0 + [0.01, -0.05, 0.04], np.array([0.3, -2.0, 0.5]), 1e-6
    c, G, Q, kap = kin(q, v)
    for dq in np.eye(3) * eps:
        j = np.argmax(dq)
        assert abs((potential(q - dq) - potential(q + dq)) / (2 * eps) - Q[j]) < 1e-4
        assert np.allclose((kin(q + dq)[0] - kin(q - dq)[0]) / (2 * eps), G[:, j], atol=1e-8)
    # c'' along q(t) = q + v t + a t^2/2: G a + kappa
    a, tau = np.array([0.3, -1.0, 2.0]), 1e-4
    cs = [kin(q + v * t + 0.5 * a * t * t)[0] for t in (-tau, 0.0, tau)]
    assert np.allclose((cs[0] - 2 * cs[1] + cs[2]) / tau**2, G @ a + kap, atol=1e-5)


# --------------------------------------------------------------------------- reference
def forces(q, v, modes):
    """Generalized force, axial forces (2,), c and G in the given modes. Locked legs:
    q'' = M^-1 (F - G_L^T lam), G_L q'' + kappa_L = 0
    => (G_L M^-1 G_L^T) lam = G_L M^-1 F + kappa_L."""
    c, G, F, kap = kin(q, v)
    ax = np.zeros(2)
    for i in range(2):
        if modes[i] != LOCK:
            ax[i] = curve(c[i], modes[i])
            F -= ax[i] * G[i]
    lk = [i for i in range(2) if modes[i] == LOCK]
    if lk:
        GL = G[lk]
        ax[lk] = np.linalg.solve((GL * MINV) @ GL.T, (GL * MINV) @ F + kap[lk])
        F -= GL.T @ ax[lk]
    return F, ax, c, G


def make_events(modes):
    """Terminal events of the modes; direction= keeps a restart from re-firing."""
    evs = []
    def ev(fun, direction, tag):
        fun.terminal, fun.direction, fun.tag = True, direction, tag
        evs.append(fun)
    for i in range(2):
        if modes[i] == LOCK:
            ev(lambda t, y, i=i: (lambda F, ax, c, G: ax[i] - s_load(c[i]))(
                *forces(y[:3], y[3:], modes)), +1, (i, LOAD))
            ev(lambda t, y, i=i: (lambda F, ax, c, G: ax[i] - s_unload(c[i]))(
                *forces(y[:3], y[3:], modes)), -1, (i, UNLOAD))
        else:   # c' = G v falls through 0 (loading) or rises through 0 (unloading)
            ev(lambda t, y, i=i: kin(y[:3])[1][i] @ y[3:],
               -1 if modes[i] == LOAD else +1, (i, "reversal"))
    return evs


def settle(y, modes, fired):
    """New modes after an event, then velocities projected onto c' = 0 of locked legs."""
    q, v = y[:3], y[3:].copy()
    i, kind = fired
    modes = list(modes)
    if kind == "reversal":          # lock if the holding force lies within the curves
        trial = modes.copy()
        trial[i] = LOCK
        _, ax, c, _ = forces(q, v, trial)
        if s_unload(c[i]) <= ax[i] <= s_load(c[i]):
            modes = trial
        else:
            modes[i] = LOAD if ax[i] > s_load(c[i]) else UNLOAD
    else:
        modes[i] = kind
    for _ in range(4):              # a new lock changes the other leg's holding force
        _, ax, c, G = forces(q, v, modes)
        tol = 1e-6 * (1.0 + abs(ax))
        out = [(j, LOAD if ax[j] > s_load(c[j]) else UNLOAD) for j in range(2)
               if modes[j] == LOCK and j != i
               and not s_unload(c[j]) - tol[j] <= ax[j] <= s_load(c[j]) + tol[j]]
        for j, m in out:
            modes[j] = m
        if not out:
            break
    lk = [j for j in range(2) if modes[j] == LOCK]
    if lk:
        v = project(G[lk], v)
    return np.concatenate([q, v]), modes


def reference(v0, tol=1e-12):
    """Event-driven Filippov solution: segments (t0, t1, dense, modes) and events."""
    y = np.concatenate([Q0, v0])
    G = kin(Q0)[1]
    modes = [LOAD if G[i] @ v0 > 0 else UNLOAD for i in range(2)]
    t, segs, log = 0.0, [], []
    while t < T:
        evs = make_events(modes)
        sol = solve_ivp(lambda t, y: np.concatenate([y[3:], MINV * forces(y[:3], y[3:], modes)[0]]),
                        (t, T), y, method="DOP853", rtol=tol, atol=tol, events=evs,
                        dense_output=True)
        segs.append((sol.t[0], sol.t[-1], sol.sol, tuple(modes)))
        t, y = sol.t[-1], sol.y[:, -1]
        if sol.status == 1:
            fired = next(e.tag for e, te in zip(evs, sol.t_events) if len(te))
            old = modes
            y, modes = settle(y, modes, fired)
            c = kin(y[:3])[0]
            log.append((t, old, tuple(modes), c.copy(), forces(y[:3], y[3:], modes)[1]))
            if len(log) > 200:
                raise RuntimeError("reference: more than 200 events (chattering?)")
    return segs, log, y


def ref_at(segs, t):
    """Reference state and axial forces at time t."""
    for t0, t1, sol, modes in segs:
        if t <= t1 or t1 == segs[-1][1]:
            y = sol(min(max(t, t0), t1))
            return y, forces(y[:3], y[3:], modes)[1], kin(y[:3])[0]


# --------------------------------------------------------------------------- steppers
def stepper(h, lock, v0, switch=False):
    """Velocity Verlet, chord branch rule; lock "mu" or "hold" adds the RATTLE lock,
    ``switch`` the located direct switch."""
    n = round(T / h)
    q, v = Q0.copy(), np.array(v0, float)
    c, G, Q, _ = kin(q)
    br = [LOAD if G[i] @ v > 0 else UNLOAD for i in range(2)]
    locked = [False, False]
    ax = np.array([curve(c[i], br[i]) for i in range(2)])       # stored axial forces
    traj, axial = np.empty((n + 1, 6)), np.empty(n + 1)
    traj[0], axial[0] = np.concatenate([q, v]), ax[0]
    rev, locks = [0, 0], 0
    for k in range(n):
        lk = [i for i in range(2) if locked[i]]
        rate0 = G @ v                                               # c' at the start
        # first kick and drift: v½ = v + h/2 M^-1 F_n, q1 = q + h v½
        vh = v + 0.5 * h * MINV * (Q - G.T @ ax)
        q1 = q + h * vh
        if lk:  # SHAKE: replace the locked forces by Lam with c_L(q1) = c_L(q)
            GL0 = G[lk]
            for it in range(30):
                c1, G1 = kin(q1)[:2]
                r = c1[lk] - c[lk]
                if np.max(np.abs(r)) < 1e-14:
                    break
                # dc_L(q1)/dLam = G_L(q1) (-h^2/2 M^-1 G_L(q)^T)
                dlam = np.linalg.solve(-0.5 * h * h * (G1[lk] * MINV) @ GL0.T, -r)
                ax[lk] += dlam
                vh -= 0.5 * h * MINV * (GL0.T @ dlam)
                q1 = q + h * vh
            else:
                raise RuntimeError("SHAKE did not converge")
        c1, G1, Q1, _ = kin(q1)
        new, rev_legs = list(br), []
        for i in range(2):
            if not locked[i]:
                new[i] = LOAD if c1[i] > c[i] else UNLOAD          # chord rule
                if new[i] != br[i]:
                    rev[i] += 1
                    rev_legs.append(i)
        cand = lk + (rev_legs if lock == "mu" else [])   # "mu": test reversals by mu
        ax1 = np.array([curve(c1[i], new[i]) for i in range(2)])
        while cand:
            # RATTLE: G_C(q1) v1 = 0, v1 = v½ + h/2 M^-1 (F_free - G_C^T mu)
            free = [i for i in range(2) if i not in cand]
            Ff = Q1 - G1[free].T @ ax1[free]
            GC = G1[cand]
            mu = np.linalg.solve((GC * MINV) @ GC.T, (2.0 / h) * GC @ vh + (GC * MINV) @ Ff)
            bad = [(j, m) for j, m in zip(cand, mu)
                   if not s_unload(c1[j]) <= m <= s_load(c1[j])]
            if not bad:
                ax1[cand] = mu
                break
            for j, m in bad:
                cand.remove(j)
                if locked[j]:       # release onto the curve it crossed
                    locked[j] = False
                    new[j] = LOAD if m > s_load(c1[j]) else UNLOAD
                    ax1[j] = curve(c1[j], new[j])
        for j in cand:
            if not locked[j]:
                locked[j] = True
                locks += 1
        v = vh + 0.5 * h * MINV * (Q1 - G1.T @ ax1)                 # second kick
        if lock == "hold":
            for i in rev_legs:      # lock test on the holding force, after the projection
                trial, br_t = list(locked), list(new)
                trial[i] = True
                for _ in range(3):
                    L = [j for j in range(2) if trial[j]]
                    vp = project(G1[L], v)     # an impulse along the wrenches
                    lam = forces(q1, vp, [LOCK if trial[j] else br_t[j] for j in range(2)])[1]
                    out = [j for j in L if j != i
                           and not s_unload(c1[j]) <= lam[j] <= s_load(c1[j])]
                    for j in out:   # the new lock moves the other's holding force off range
                        trial[j], br_t[j] = False, LOAD if lam[j] > s_load(c1[j]) else UNLOAD
                    if not out:
                        break
                if s_unload(c1[i]) <= lam[i] <= s_load(c1[i]):
                    locked, new, v, ax1 = trial, br_t, vp, lam
                    locks += 1
        if switch:
            # Located direct switch: node n+1 took the new branch, so the two kicks
            # switch at t_n + h/2; the stroke rate's zero t* = t_n + theta h lies in
            # (t_n - h/2, t_n + h/2) (the chord rule's branch is the rate's sign at
            # mid-step). theta: the rate interpolated through its value at t_n and
            # the chord's, (c_{n+1} - c_n)/h, at t_n + h/2; both follow the old
            # branch (the drift used F_n only), the end rate would not. The missing
            # impulse -(t* - t_n - h/2) G^T (S_old - S_new) is added to v_{n+1}:
            # O(h) in theta, O(h^2) in the impulse, once.
            for i in rev_legs:
                if locked[i]:
                    continue
                r0, r_mid = rate0[i], (c1[i] - c[i]) / h
                theta = 0.5 * r0 / (r0 - r_mid) if r0 != r_mid else 0.5
                theta = min(max(theta, -0.5), 0.5)
                jump = curve(c1[i], br[i]) - curve(c1[i], new[i])   # S_old - S_new
                v = v - h * (theta - 0.5) * MINV * G1[i] * jump
        q, c, G, Q, ax, br = q1, c1, G1, Q1, ax1, new
        traj[k + 1], axial[k + 1] = np.concatenate([q, v]), ax[0]
    return traj, axial, rev, locks


def err(ya, yb):
    """Position error (m, theta as ARM*dtheta) and velocity error (m/s)."""
    d = (np.asarray(ya) - np.asarray(yb)) * [1, 1, ARM, 1, 1, ARM]
    return np.linalg.norm(d[..., :3], axis=-1), np.linalg.norm(d[..., 3:], axis=-1)


def run(v0, grid, self_check=True):
    """Reference and all steppers from initial velocity v0: events, results.

    ``self_check`` also solves the reference at 1e-13 for the printed
    self-check; the extra starts, whose orders alone are printed, skip it."""
    segs, log, yT = reference(v0)
    eq, ev = err(yT, reference(v0, 1e-13)[2]) if self_check else (np.nan, np.nan)
    yref = np.array([ref_at(segs, t)[0] for t in grid])
    res = {}
    for name, lock, switch in STEPPERS:
        for h in STEPS:
            t1 = time.perf_counter()
            traj, axial, rev, locks = stepper(h, lock, v0, switch)
            wall = (time.perf_counter() - t1) / T
            pq, pv = err(traj[-1], yT)
            gq, gv = err(traj[::round(SAMPLE / h)], yref)
            rms = math.sqrt(np.mean(np.maximum(gq / Q_SCALE, gv / V_SCALE) ** 2))
            res[name, h] = dict(pos=pq, vel=pv, rel=max(pq / Q_SCALE, pv / V_SCALE), rms=rms,
                                axial=axial, rev=rev, locks=locks, wall=wall,
                                grid=np.maximum(gq / Q_SCALE, gv / V_SCALE))
    return segs, log, (eq, ev), res


def slope(es):
    return fitted_order(STEPS, es)


def main():
    check_gradients()
    t0 = time.perf_counter()
    grid = np.arange(0.0, T + 1e-12, SAMPLE)
    out = {}
    for scen, v0 in SCENARIOS.items():
        segs, log, (eq, ev), res = run(np.array(v0), grid)
        out[scen] = segs, res
        nrev = [sum(1 for _, o, n, _, _ in log if o[i] != LOCK and o[i] != n[i]) for i in range(2)]
        nlock = sum(1 for _, o, n, _, _ in log for i in range(2) if o[i] != LOCK and n[i] == LOCK)
        print(f"\n## Scenario {scen}: (vx, vz, omega)(0) = {v0}\n\nReference events "
              f"({len(segs)} segments; reversals per leg {nrev[0]} / {nrev[1]}, "
              f"lock episodes {nlock}):\n")
        print("| t (ms) | leg 1 | leg 2 | c1 (mm) | c2 (mm) | S1 (N) | S2 (N) |")
        print("|---:|---|---|---:|---:|---:|---:|")
        print(f"| 0 | {NAMES[segs[0][3][0]]} | {NAMES[segs[0][3][1]]} | | | | |")
        for t, old, new, c, ax in log:
            leg = [f"{NAMES[o]} -> **{NAMES[n]}**" if o != n else NAMES[n]
                   for o, n in zip(old, new)]
            print(f"| {1e3 * t:.3f} | {leg[0]} | {leg[1]} | {1e3 * c[0]:.2f} | "
                  f"{1e3 * c[1]:.2f} | {ax[0]:.0f} | {ax[1]:.0f} |")
        print(f"\nReference self-check (tol 1e-12 vs 1e-13), state at T: position {eq:.1e} m, "
              f"velocity {ev:.1e} m/s\n")
        print("| stepper | Δt (s) | pos. error at T (m) | vel. error at T (m/s) | rel. error at T "
              "| RMS rel. error | reversals leg 1 / 2 | lock episodes | wall s per sim. s |")
        print("|---|---:|---:|---:|---:|---:|---:|---:|---:|")
        for name, lock, _ in STEPPERS:
            for h in STEPS:
                r = res[name, h]
                print(f"| {name} | {h:.3g} | {r['pos']:.2e} | {r['vel']:.2e} | {r['rel']:.2e} "
                      f"| {r['rms']:.2e} | {r['rev'][0]} / {r['rev'][1]} "
                      f"| {r['locks'] if lock else '-'} | {r['wall']:.2f} |")
        print("\nFitted orders (least squares over all Δt):\n")
        print("| stepper | position at T | velocity at T | rel. at T | RMS rel. |")
        print("|---|---:|---:|---:|---:|")
        for name, *_ in STEPPERS:
            print(f"| {name} | " + " | ".join(f"{slope([res[name, h][k] for h in STEPS]):.2f}"
                                             for k in ("pos", "vel", "rel", "rms")) + " |")
        direct = [t for t, o, n, _, _ in log for i in range(2)
                  if o[i] != n[i] and LOCK not in (o[i], n[i])]
        if direct:  # the error just before and just after the first direct switch
            k0, k1 = int(direct[0] / SAMPLE), int(direct[0] / SAMPLE) + 1
            print(f"\nFirst direct switch at {1e3 * direct[0]:.1f} ms. Rel. error on the grid at "
                  f"{1e3 * grid[k0]:.0f} ms / {1e3 * grid[k1]:.0f} ms, Δt = "
                  + ", ".join(f"{1e3 * h:g}" for h in STEPS) + " ms, and fitted orders:\n")
            for name, *_ in STEPPERS:
                e = [[res[name, h]["grid"][k] for h in STEPS] for k in (k0, k1)]
                print(f"- {name}: " + " / ".join(
                    " ".join(f"{x:.1e}" for x in ek) + f" (order {slope(ek):.2f})" for ek in e))
    print("\n## Other lock-only starts: fitted orders, rel. error at T / RMS rel.\n")
    print("| (vx, vz, omega)(0) | " + " | ".join(n for n, *_ in STEPPERS) + " |")
    print("|---|" + "---:|" * len(STEPPERS))
    for v0 in CHECKS:
        res = run(np.array(v0), grid, self_check=False)[3]
        print(f"| {v0} | " + " | ".join(" / ".join(
            f"{slope([res[n, h][k] for h in STEPS]):.2f}" for k in ("rel", "rms"))
            for n, *_ in STEPPERS) + " |")
    plot(out)
    print(f"\nTotal wall time {time.perf_counter() - t0:.0f} s.")


def plot(out):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, (a, b, b2) = plt.subplots(1, 3, figsize=(18, 5.2))
    segs, res = out["lock-only"]
    tt = np.linspace(0.0, T, 3001)
    ref = [ref_at(segs, t) for t in tt]
    cc = [r[2][0] for r in ref]
    for f, lab in ((s_load, "S_l(c₁) and S_u(c₁), c₁ of the reference"), (s_unload, None)):
        a.plot(tt, [f(c) for c in cc], color="0.55", lw=0.7, ls="--", label=lab)
    h = 1e-3
    th = np.arange(round(T / h) + 1) * h
    a.plot(tt, [r[1][0] for r in ref], color="k", lw=2.2, alpha=0.45, label="reference (Filippov)")
    a.plot(th, res["verlet_chord", h]["axial"], ".", color="tab:red", ms=2,
           label="verlet_chord, Δt = 1 ms (points)")
    for name, col, ls in (("rattle_mu", "tab:orange", "--"), ("rattle_hold", "tab:blue", "-")):
        a.plot(th, res[name, h]["axial"], color=col, lw=1.0, ls=ls, label=f"{name}, Δt = 1 ms")
    a.set(xlabel="time (s)", ylabel="axial force of leg 1 (N)", ylim=(0, 3300),
          title="(a) leg 1, lock-only start")
    a.legend(fontsize=8, loc="upper right")
    hs = np.array(STEPS)
    style = {"verlet_chord": ("tab:red", "o-"), "verlet_switch": ("tab:purple", "v--"),
             "rattle_mu": ("tab:orange", "s:"), "rattle_hold": ("tab:blue", "o-"),
             "rattle_hold_switch": ("tab:green", "^-")}
    for ax_, scen, tag in ((b, "lock-only", "(b)"), (b2, "direct-switch", "(c)")):
        for name, *_ in STEPPERS:
            col, st = style[name]
            ring = dict(ms=10, mfc="none") if name == "rattle_hold" else {}   # visible under
            ax_.loglog(hs, [out[scen][1][name, h]["rel"] for h in hs], st, color=col,
                       label=name, **ring)                                  # its twin
        e0 = out[scen][1]["verlet_chord", hs[0]]["rel"]
        for p, f, ls in ((1, 1.0, "--"), (2, 0.1, "-.")):
            ax_.loglog(hs, f * e0 * (hs / hs[0]) ** p, color="0.5", lw=0.8, ls=ls,
                       label=f"slope {p}")
        ax_.set(ylabel=f"error at T = {T} s: max(|Δq|/{Q_SCALE} m, |Δv|/{V_SCALE} m/s)",
                title=f"{tag} error at T vs step, {scen} start", xlabel="Δt (ms)")
        ax_.set_xticks(hs, [f"{1e3 * h:g}" for h in hs])
        ax_.minorticks_off()
        ax_.legend(fontsize=8, ncol=2, loc="lower right")
        ax_.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    fd, tmp = tempfile.mkstemp(suffix=".png", dir=FIG.parent)   # write atomically
    os.close(fd)
    fig.savefig(tmp, dpi=130)
    os.chmod(tmp, 0o644)        # mkstemp makes it private; a figure is for everyone
    os.replace(tmp, FIG)
    print(f"\nWrote figures/{FIG.name}")


if __name__ == "__main__":
    main()
