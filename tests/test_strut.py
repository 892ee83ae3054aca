"""Tests of ``symcushion.legs.strut``: the force law (2.1) and its stiffness D_p.

What is checked, and against what:

* ``strut_stiffness`` (``casadi.jacobian`` of (2.1)) against
  ``strut_stiffness_paper`` (the hand formula (2.3)) and against
  fourth-order central differences of ``strut_force``, over random legs (random hinge, e₀,
  e_n, L₀; every curve type, exact and smooth, with and without unloading
  branches and preload; rigid rods) and random poses, including poses within
  1° of the two singular sets of (2.1) (e_S ∥ e_n and e_S ⊥ e_n).
* ``strut_force`` against an independent NumPy transcription of (2.1)
  (:func:`ref_geometry`, written from the paper, not from the module), and
  near the singular sets against the same transcription in 50-digit mpmath.
* The rest pose: P = 0, D_p symmetric positive definite and equal to the
  closed form of docs/paper-notes.md §2, for both signs of e₀·e_n.
* Loading/unloading branches, with the rate signs of the module docstring.
* Input validation, the axially rigid rod, tunable curves.

Errors are relative to the Frobenius norm of the reference matrix.
"""
from __future__ import annotations

import mpmath
import numpy as np
import pytest

from symcushion import Crushable, HingedStrut, Linear, PiecewiseLinear
from symcushion.legs.curve_base import RATE_WIDTH
from symcushion.legs.strut import RIGID_AXIAL_RATIO
from symcushion.legs.strut_geometry import SINGULAR_ANGLE

EPS = np.finfo(float).eps

#: AD stiffness vs (2.3), relative to |D_p| (the brief's requirement).
RTOL_PAPER = 1e-12
#: AD stiffness vs central finite differences of the force, relative to |D_p|.
RTOL_FD = 1e-6
#: Finite differences: the fourth-order central formula (offsets and weights
#: below) with the step h = FD_STEP_REL·ℓ, ℓ the shortest length on which
#: P(r) bends at the pose (:func:`fd_length_scale`); ℓ shrinks to L·α near the
#: singular sets, so h follows it. Error ≈ (h/ℓ)⁴·K/30 (truncation) +
#: δP/(h·|D_p|) (round-off, δP the round-off of P). Near e_S ∥ e_n both are
#: at their worst: P is normalised by |e_S × e_n| ≈ α, so δP/(ℓ|D_p|) ≈ eps/α,
#: and K ≈ 50. With the second-order formula no step serves both: its best
#: (h = 1e-4·ℓ) still gave 1.6e-6 on one of four seeded sweeps. The
#: fourth-order formula at h = 1e-3·ℓ keeps truncation ≈ 1e-12·K and
#: round-off ≈ 1e3·eps/α; measured worst over 25 seeded sweeps (36 000
#: poses): 3e-7, typically 1e-8.
FD_STEP_REL = 1e-3
FD_OFFSETS = (2.0, 1.0, -1.0, -2.0)
FD_WEIGHTS = np.array([-1.0, 8.0, -8.0, 1.0]) / 12.0
#: Within this many kink widths of a smoothed knot the hyperbola's curvature
#: sets ℓ (its third derivative decays like w²/u⁴, negligible beyond).
SMOOTH_KNOT_ZONE = 100.0
#: A smooth loading/unloading blend counts as switched when |x·ẋ| exceeds
#: this many RATE_WIDTHs: tanh(40) rounds to 1 in double precision.
SATURATED_BLEND = 40.0
#: Near e_S ⊥ e_n the hand formula (2.3) divides e_n·∂e_γ (≈ α) by
#: sqrt(1 − (e_n·e_γ)²) (≈ α), both computed from e_n·e_γ = 1 − α²/2 with an
#: absolute round-off of eps, so its relative error grows like eps/α², α the
#: angle between e_S and the plane ⊥ e_n. Measured over 17 sweeps of 1440
#: poses: at most 1.3 eps/α²; the bound leaves a factor of 3.
PERP_LOSS = 4.0
#: Near e_S ∥ e_n both e_β and e_γ are normalised by |e_S × e_n| ≈ α, so any
#: evaluation of (2.1) or (2.3) carries a relative error ≈ eps/α. Measured
#: against 50-digit arithmetic: at most 0.33 eps/α.
PAR_LOSS = 1.0

N_LEGS = 60
#: Poses per leg: regular, within 1° of e_S ∥ e_n, within 1° of e_S ⊥ e_n.
N_REGULAR, N_NEAR_PARALLEL, N_NEAR_PERP = 12, 6, 6
#: The near-singular poses of the main test sit at α ∈ [NEAR_MIN, 1°],
#: log-uniform; deeper poses are measured against mpmath below.
NEAR_MIN = np.deg2rad(1e-3)
NEAR_MAX = np.deg2rad(1.0)


# --------------------------------------------------------------------------
# Independent reference: (2.1) written from the paper, in NumPy
# --------------------------------------------------------------------------

def unit(v):
    return np.asarray(v, float) / np.linalg.norm(v)


def ref_geometry(hinge, e0, en, r):
    """Geometry of (2.1) for a foot at ``r``; e₀ and e_n unit vectors.

    Written from the paper with different formulas from the module where two
    are possible: e_γ = (e_n − (e_S·e_n)e_S)/|…| (the triple product expanded)
    and γ = atan2(|e_S × e_n|, |e_S·e_n|) (= arcsin(e_n·e_γ), docs/paper-notes.md §1).
    """
    d = np.asarray(r, float) - hinge
    L = np.linalg.norm(d)
    e_S = d / L
    cos_n = e_S @ en
    cross_n = np.cross(e_S, en)
    e_beta = cross_n / np.linalg.norm(cross_n)
    w = en - cos_n * e_S
    e_gamma = w / np.linalg.norm(w)
    beta = -np.arcsin(np.clip(e0 @ e_beta, -1, 1))
    gamma = np.arctan2(np.linalg.norm(cross_n), abs(cos_n))
    return dict(L=L, e_S=e_S, e_beta=e_beta, e_gamma=e_gamma, beta=beta, gamma=gamma)


def ref_deflections(leg_spec, r, v):
    """Deflections (δ_S, β, γ − γ₀) and rates of the three elements.

    The rates are the module docstring's: V·e_S, (V·e_β)/L and
    −sign(e₀·e_n)(V·e_γ)/L; only their signs matter for exact curves.
    """
    hinge, e0, en, L0 = leg_spec["hinge"], leg_spec["e0"], leg_spec["en"], leg_spec["L0"]
    g = ref_geometry(hinge, e0, en, r)
    sigma = np.sign(e0 @ en)
    gamma0 = np.arctan2(np.linalg.norm(np.cross(e0, en)), abs(e0 @ en))
    x = dict(S=g["L"] - L0, M_beta=g["beta"], M_gamma=g["gamma"] - gamma0)
    rate = dict(S=v @ g["e_S"], M_beta=v @ g["e_beta"] / g["L"],
                M_gamma=-sigma * (v @ g["e_gamma"]) / g["L"])
    return g, x, rate, sigma


def ref_force_linear(leg_spec, curves, r, v):
    """P of (2.1) for elements with linear loading and unloading branches.

    ``curves[name] = (k_load, preload_load, k_unload, preload_unload)`` or
    None; the loading branch is taken while x·ẋ ≥ 0 (the deflection grows).
    """
    g, x, rate, sigma = ref_deflections(leg_spec, r, v)
    f = dict(S=0.0, M_beta=0.0, M_gamma=0.0)
    for name, c in curves.items():
        if c is None:
            continue
        k, f0, ku, fu0 = c
        loading = x[name] * rate[name] >= 0
        f[name] = (f0 + k * x[name]) if loading else (fu0 + ku * x[name])
    M_gamma = -sigma * f["M_gamma"]                         # docs/paper-notes.md §2
    return (f["S"] * g["e_S"] + f["M_beta"] / g["L"] * g["e_beta"]
            + M_gamma / g["L"] * g["e_gamma"])


# --------------------------------------------------------------------------
# Random legs and poses
# --------------------------------------------------------------------------

def random_unit(rng):
    return unit(rng.normal(size=3))


def perpendicular_unit(rng, a):
    """A random unit vector perpendicular to the unit vector ``a``."""
    return unit(np.cross(a, random_unit(rng)))


def tilted(a, b, angle):
    """Unit vector at ``angle`` from unit a, towards unit b ⊥ a."""
    return np.cos(angle) * a + np.sin(angle) * b


def random_axis_pair(rng, sign):
    """(e₀, e_n) with e₀·e_n of the given sign, 1.5°–88.5° from both singular sets."""
    e0 = random_unit(rng)
    angle = np.deg2rad(rng.uniform(1.5, 88.5))
    en = tilted(e0, perpendicular_unit(rng, e0), angle)
    return e0, (en if sign > 0 else -en)


def random_curve(rng, role):
    """A random resistance curve and what the FD check must know about it.

    ``role`` 'S' (N vs m) or 'M' (N·m vs rad). Returns (curve, info) with
    info = dict(kinks, smooth, width, unloading).
    """
    scale = 0.1 if role == "S" else 0.4                       # stroke range, m or rad
    k = 10 ** rng.uniform(4, 6) if role == "S" else 10 ** rng.uniform(2, 4)
    smooth = rng.random() < 0.35
    options = dict(smooth=smooth)
    if smooth:
        options["kink_width"] = 10 ** rng.uniform(-4, -2.5)
    kinks = []

    def plain(kind):
        if kind == "linear":
            preload = 0.0 if rng.random() < 0.5 else rng.uniform(-0.2, 0.2) * k * scale
            return Linear(k * rng.uniform(0.3, 1.5), preload), []
        if kind == "pwl":
            m = int(rng.integers(2, 6))
            xs = np.sort(rng.uniform(-scale, scale, m))
            while np.min(np.diff(xs)) < 0.05 * scale:
                xs = np.sort(rng.uniform(-scale, scale, m))
            slopes = k * rng.uniform(0.2, 2.0, m - 1)
            fs = np.concatenate([[rng.uniform(-0.5, 0.5) * k * scale],
                                 np.diff(xs) * slopes]).cumsum()
            return PiecewiseLinear(xs, fs), list(xs[1:-1])
        f_c = k * rng.uniform(0.02, 0.5) * scale
        return Crushable(k, f_c, k * rng.uniform(0, 0.1)), [-f_c / k]

    kinds = ["linear", "pwl", "crush"] if role == "S" else ["linear", "pwl"]
    kind = kinds[int(rng.integers(len(kinds)))]
    unloading = None
    if rng.random() < 0.5:
        unloading, more = plain(["linear", "pwl"][int(rng.integers(2))])
        kinks += more
    if kind == "linear":
        preload = 0.0 if rng.random() < 0.5 else rng.uniform(-0.2, 0.2) * k * scale
        curve = Linear(k, preload, unloading=unloading, **options)
    elif kind == "pwl":
        base, more = plain("pwl")
        curve = PiecewiseLinear(base.knots, base.param_values, unloading=unloading, **options)
        kinks += more
    else:
        base, more = plain("crush")
        curve = Crushable(*base.param_values, unloading=unloading, **options)
        kinks += more
    info = dict(kinks=kinks, smooth=smooth, width=curve.kink_width,
                unloading=unloading is not None)
    return curve, info


def random_leg(rng):
    """A random HingedStrut and the plain data the reference needs."""
    e0, en = random_axis_pair(rng, 1 if rng.random() < 0.5 else -1)
    hinge = rng.uniform(-1, 1, 3)
    L0 = rng.uniform(0.2, 2.0)
    curves, infos = {}, {}
    for name, role in (("S", "S"), ("M_beta", "M"), ("M_gamma", "M")):
        if rng.random() < 0.15:                       # element absent
            continue
        curves[name], infos[name] = random_curve(rng, role)
    if not any(n in curves for n in ("M_beta", "M_gamma")):
        curves["M_beta"], infos["M_beta"] = random_curve(rng, "M")
    if "S" not in curves:
        infos["S"] = dict(kinks=[], smooth=False, width=None, unloading=False)
    leg = HingedStrut(hinge=hinge, e0=e0, en=en, length=L0, **curves)
    spec = dict(hinge=hinge, e0=unit(e0), en=unit(en), L0=L0, infos=infos)
    return leg, spec


def random_poses(rng, spec):
    """Foot positions and velocities: regular and near both singular sets.

    Returns (r, v, kind) with r, v of shape (N, 3) and kind a list of
    'regular', 'parallel', 'perp'.
    """
    e0, en, L0, hinge = spec["e0"], spec["en"], spec["L0"], spec["hinge"]
    dirs, kinds = [], []
    for _ in range(N_REGULAR):                         # within 25° of rest
        dirs.append(tilted(e0, perpendicular_unit(rng, e0), np.deg2rad(rng.uniform(0, 25))))
        kinds.append("regular")
    side = np.sign(e0 @ en)
    for _ in range(N_NEAR_PARALLEL):
        alpha = np.exp(rng.uniform(np.log(NEAR_MIN), np.log(NEAR_MAX)))
        axis = side * en if rng.random() < 0.8 else -side * en
        dirs.append(tilted(axis, perpendicular_unit(rng, en), alpha))
        kinds.append("parallel")
    for _ in range(N_NEAR_PERP):                       # on either side of the plane
        alpha = np.exp(rng.uniform(np.log(NEAR_MIN), np.log(NEAR_MAX)))
        in_plane = perpendicular_unit(rng, en)
        dirs.append(tilted(in_plane, en * rng.choice([-1.0, 1.0]), alpha))
        kinds.append("perp")
    lengths = L0 * rng.uniform(0.8, 1.15, len(dirs))
    r = hinge + lengths[:, None] * np.array(dirs)
    v = rng.normal(size=r.shape)
    v[rng.random(len(v)) < 0.15] = 0.0                # some poses at rest velocity
    return r, v, kinds


# --------------------------------------------------------------------------
# Batched evaluation
# --------------------------------------------------------------------------

def batch(f, r, v, p):
    """Evaluate a (r, v, p) Function on N poses with ``f.map``; (N, …) array."""
    n = len(r)
    out = f.map(n)(r.T, v.T, np.tile(np.reshape(p, (-1, 1)), (1, n)))
    out = np.asarray(out, float)                       # (rows, cols·n), blocks side by side
    if f.size2_out(0) == 1:
        return out.T
    return out.reshape(f.size1_out(0), n, f.size2_out(0)).transpose(1, 0, 2)


def stiffness_fd(f_force, r, v, p, h):
    """Fourth-order central differences of P over a batch: (N, 3, 3).

    ∂P/∂q_j ≈ [−P(r + 2h e_j) + 8P(r + h e_j) − 8P(r − h e_j) + P(r − 2h e_j)]/(12h),
    with the step h of shape (N,).
    """
    n = len(r)
    stencil_r = np.concatenate([r + s * h[:, None] * np.eye(3)[j]
                                for j in range(3) for s in FD_OFFSETS])
    stencil_v = np.tile(v, (3 * len(FD_OFFSETS), 1))
    P = batch(f_force, stencil_r, stencil_v, p).reshape(3, len(FD_OFFSETS), n, 3)
    D = np.tensordot(FD_WEIGHTS, P, axes=(0, 1)) / h[None, :, None]
    return D.transpose(1, 2, 0)


def singular_angles(spec, r):
    """Angles (rad) between e_S and the e_n axis line, and the plane ⊥ e_n."""
    e_S = unit(r - spec["hinge"])
    to_axis = np.arctan2(np.linalg.norm(np.cross(e_S, spec["en"])), abs(e_S @ spec["en"]))
    return to_axis, np.pi / 2 - to_axis


def fd_length_scale(spec, r, v):
    """Shortest length ℓ (m) on which P(r) bends at this pose.

    ℓ = L·(angle to the nearer singular set) — near e_S ∥ e_n the direction
    e_β turns by O(1) over a distance L·α, and near e_S ⊥ e_n γ has a kink
    at distance L·α — and, within SMOOTH_KNOT_ZONE widths w of a smoothed
    knot at distance u, the scale max(w, u) on which its hyperbola bends,
    mapped to the foot: max(w, u)/|∇x| (|∇β| ≫ 1/L near e_n).
    """
    _, x, _, _ = ref_deflections(spec, r, v)
    ell = np.linalg.norm(r - spec["hinge"]) * min(1.0, *singular_angles(spec, r))
    for name, info in spec["infos"].items():
        if not info["smooth"]:
            continue
        near = [abs(x[name] - k) for k in info["kinks"]
                if abs(x[name] - k) < SMOOTH_KNOT_ZONE * info["width"]]
        if near:
            step = 1e-6 * ell
            grad = [(ref_deflections(spec, r + step * e, v)[1][name]
                     - ref_deflections(spec, r - step * e, v)[1][name]) / (2 * step)
                    for e in np.eye(3)]
            # the hyperbola bends on the scale max(w, distance to its knot)
            ell = min(ell, max(info["width"], min(near)) / np.linalg.norm(grad))
    return ell


def smooth_blend_saturated(spec, r, v):
    """False when a smooth loading/unloading blend is mid-switch at r."""
    if not np.any(v):
        return True                                    # x·ẋ ≡ 0: constant weight 1/2
    _, x, rate, _ = ref_deflections(spec, r, v)
    return all(abs(x[n] * rate[n]) >= SATURATED_BLEND * RATE_WIDTH
               for n, info in spec["infos"].items() if info["smooth"] and info["unloading"])


def regime(spec, r, v):
    """Which side of every exact knot and every branch switch r is on.

    (Smoothed knots are not listed: within SMOOTH_KNOT_ZONE of one the step
    is shrunk instead, see :func:`fd_length_scale`.)
    """
    _, x, rate, _ = ref_deflections(spec, r, v)
    key = []
    for name, info in spec["infos"].items():
        if not info["smooth"]:
            key += [x[name] > k for k in info["kinks"]]
        if info["unloading"]:
            key.append(x[name] * rate[name] >= 0)
    key.append(unit(r - spec["hinge"]) @ spec["en"] > 0)   # side of the plane ⊥ e_n
    return tuple(key)


def fd_valid(spec, r, v, h):
    """True when P is smooth over the whole central-difference stencil."""
    points = [r] + [r + s * h * np.eye(3)[j] for j in range(3) for s in FD_OFFSETS]
    if len({regime(spec, q, v) for q in points}) != 1:
        return False
    return all(smooth_blend_saturated(spec, q, v) for q in points)


def rel_err(a, b):
    """|a − b| / |b| per pose (Frobenius)."""
    return (np.linalg.norm(a - b, axis=(-2, -1)) / np.linalg.norm(b, axis=(-2, -1)))


# --------------------------------------------------------------------------
# AD stiffness vs (2.3) vs finite differences, and P vs the NumPy reference
# --------------------------------------------------------------------------

def run_sweep(seed=20240521):
    """Evaluate N_LEGS random legs at their random poses; one row per pose."""
    rng = np.random.default_rng(seed)
    rows = []
    for _ in range(N_LEGS):
        leg, spec = random_leg(rng)
        F = leg.functions()                          # built once per leg
        p = leg.param_values
        r, v, kinds = random_poses(rng, spec)
        P = batch(F["strut_force"], r, v, p)
        D_ad = batch(F["strut_stiffness"], r, v, p)
        D_paper = batch(F["strut_stiffness_paper"], r, v, p)
        ell = np.array([fd_length_scale(spec, ri, vi) for ri, vi in zip(r, v)])
        h = FD_STEP_REL * ell
        D_fd = stiffness_fd(F["strut_force"], r, v, p, h)
        for i in range(len(r)):
            to_axis, to_plane = singular_angles(spec, r[i])
            rows.append(dict(
                kind=kinds[i], to_axis=to_axis, to_plane=abs(to_plane),
                blend_ok=smooth_blend_saturated(spec, r[i], v[i]),
                fd_ok=fd_valid(spec, r[i], v[i], h[i]),
                err_paper=rel_err(D_paper[i], D_ad[i]),
                err_fd=rel_err(D_fd[i], D_ad[i]),
                finite=bool(np.all(np.isfinite(D_ad[i])) and np.all(np.isfinite(D_paper[i]))
                            and np.all(np.isfinite(P[i]))),
                rigid=leg.rigid))
    return rows


@pytest.fixture(scope="module")
def random_sweep():
    return run_sweep()


def test_sweep_covers_the_required_cases(random_sweep):
    kinds = [row["kind"] for row in random_sweep]
    assert len(random_sweep) >= 1000
    assert kinds.count("parallel") >= 300 and kinds.count("perp") >= 300
    assert sum(row["fd_ok"] for row in random_sweep) >= 1000
    assert any(row["rigid"] for row in random_sweep)
    assert all(row["finite"] for row in random_sweep)


def test_ad_stiffness_equals_paper_formula(random_sweep):
    """AD = (2.3) to 1e-12, except (2.3)'s own eps/α² loss within 1° of e_S ⊥ e_n.

    Poses where a smooth loading/unloading blend is mid-switch are left out
    here and tested in :func:`test_smooth_blend_adds_a_term_the_paper_lacks`:
    there the AD stiffness contains the derivative of the blend weight, which
    (2.3), written for P(δ, sign δ′) with a frozen sign, does not have.
    """
    rows = [row for row in random_sweep if row["blend_ok"]]
    assert len(rows) >= 0.98 * len(random_sweep)
    for row in rows:
        bound = RTOL_PAPER
        if row["to_plane"] < np.deg2rad(1.0):
            bound = max(RTOL_PAPER, PERP_LOSS * EPS / row["to_plane"] ** 2)
        assert row["err_paper"] <= bound, row
    # within 1° of e_S ∥ e_n the plain requirement holds
    assert max(row["err_paper"] for row in rows if row["kind"] == "parallel") <= RTOL_PAPER


def test_ad_stiffness_equals_finite_differences(random_sweep):
    """AD = central differences of strut_force to 1e-6 wherever P is smooth
    over the stencil (no knot, branch switch or the plane ⊥ e_n inside it)."""
    checked = [row for row in random_sweep if row["fd_ok"]]
    for row in checked:
        assert row["err_fd"] <= RTOL_FD, row
    kinds = {row["kind"] for row in checked}
    assert kinds == {"regular", "parallel", "perp"}


def test_force_matches_numpy_reference():
    """strut_force = (2.1) transcribed independently (linear curves, both branches)."""
    rng = np.random.default_rng(7)
    for _ in range(20):
        e0, en = random_axis_pair(rng, rng.choice([-1, 1]))
        hinge, L0 = rng.uniform(-1, 1, 3), rng.uniform(0.3, 1.5)
        spec = dict(hinge=hinge, e0=e0, en=en, L0=L0)
        params = {n: (k, f0, 0.3 * k, 0.5 * f0) for n, k, f0 in
                  (("S", 1e5, 200.0), ("M_beta", 2e3, 15.0), ("M_gamma", 3e3, -20.0))}
        curves = {n: Linear(k, f0, unloading=Linear(ku, fu0))
                  for n, (k, f0, ku, fu0) in params.items()}
        leg = HingedStrut(hinge=hinge, e0=e0, en=en, length=L0, **curves)
        for _ in range(20):
            d = tilted(e0, perpendicular_unit(rng, e0), np.deg2rad(rng.uniform(0, 40)))
            r = hinge + L0 * rng.uniform(0.8, 1.2) * d
            v = rng.normal(size=3)
            expected = ref_force_linear(spec, params, r, v)
            np.testing.assert_allclose(leg.force(r, v), expected,
                                       rtol=0, atol=1e-12 * np.linalg.norm(expected))


# --------------------------------------------------------------------------
# Near and on the singular sets
# --------------------------------------------------------------------------

def _mp_force(spec, k, r):
    """(2.1) with linear curves in 50-digit arithmetic (mpmath)."""
    mp = mpmath.mp
    vec = lambda a: [mp.mpf(float(t)) for t in a]          # noqa: E731
    dot = lambda a, b: sum(s * t for s, t in zip(a, b))   # noqa: E731

    def cross(a, b):
        return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]

    hinge, e0, en = vec(spec["hinge"]), vec(spec["e0"]), vec(spec["en"])
    d = [s - t for s, t in zip(r, hinge)]
    L = mp.sqrt(dot(d, d))
    e_S = [t / L for t in d]
    c = dot(e_S, en)
    cr = cross(e_S, en)
    s = mp.sqrt(dot(cr, cr))
    e_beta = [t / s for t in cr]
    w = [a - c * b for a, b in zip(en, e_S)]
    e_gamma = [t / mp.sqrt(dot(w, w)) for t in w]
    beta = -mp.asin(dot(e0, e_beta))
    gamma = mp.atan2(s, abs(c))
    c0 = cross(e0, en)
    gamma0 = mp.atan2(mp.sqrt(dot(c0, c0)), abs(dot(e0, en)))
    sigma = mp.sign(dot(e0, en))
    S = k["S"] * (L - mp.mpf(spec["L0"]))
    Mb = k["M_beta"] * beta
    Mg = -sigma * k["M_gamma"] * (gamma - gamma0)
    return [S * a + Mb / L * b + Mg / L * g for a, b, g in zip(e_S, e_beta, e_gamma)]


def _mp_stiffness(spec, k, r):
    """D_p by central differences in 50-digit arithmetic: exact to ~1e-30."""
    with mpmath.workdps(50):
        h = mpmath.mpf("1e-22")
        base = [mpmath.mpf(float(t)) for t in r]
        cols = []
        for j in range(3):
            plus, minus = list(base), list(base)
            plus[j] += h
            minus[j] -= h
            fp, fm = _mp_force(spec, k, plus), _mp_force(spec, k, minus)
            cols.append([float((a - b) / (2 * h)) for a, b in zip(fp, fm)])
    return np.array(cols).T


SINGULAR_LEG = dict(hinge=np.array([0.1, 0.2, 0.3]), e0=unit([0.0, 0.3, -1.0]),
                    en=unit([0.0, 0.5, -1.0]), L0=0.6)
SINGULAR_K = dict(S=2e5, M_beta=3e3, M_gamma=2e3)


def _singular_leg():
    spec = SINGULAR_LEG
    return HingedStrut(hinge=spec["hinge"], e0=spec["e0"], en=spec["en"], length=spec["L0"],
                       **{n: Linear(k) for n, k in SINGULAR_K.items()})


def _pose_near(spec, alpha, which, azimuth=0.7, length=0.55):
    """Foot at angle alpha (signed, rad) from the axis line or from the plane ⊥ e_n."""
    en = spec["en"]
    a = unit(np.cross(np.cross(en, spec["e0"]), en))   # ⊥ e_n, in the plane of e₀
    b = np.cross(en, a)
    radial = np.cos(azimuth) * a + np.sin(azimuth) * b
    e_S = tilted(en, radial, alpha) if which == "parallel" else tilted(radial, en, alpha)
    return spec["hinge"] + length * e_S


@pytest.mark.parametrize("which", ["parallel", "perp"])
def test_accuracy_deep_inside_one_degree(which):
    """Against a 50-digit reference, from 1° down to 1e-6° of each singular set.

    Measured behaviour, asserted as bounds:

    * near e_S ∥ e_n, D_p grows like 1/α and the AD and (2.3) stiffnesses both
      carry the relative error ≈ eps/α of normalising by |e_S × e_n| ≈ α
      (the direction e_β itself is that ill-determined); they agree with each
      other to 1e-14;
    * near e_S ⊥ e_n, D_p stays bounded and AD is exact to ~1e-15 (γ is
      evaluated as atan2); (2.3) loses digits like eps/α² (it divides by
      sqrt(1 − (e_n·e_γ)²)): 1e-6 at 1e-4°; at 1e-6° (α² ≈ eps) that
      square root is round-off and (2.3) may return inf.
    """
    spec, leg = SINGULAR_LEG, _singular_leg()
    F = leg.functions()
    for degrees in (1.0, 1e-1, 1e-2, 1e-3, 1e-4, 1e-5, 1e-6):
        for sign in (1, -1):
            alpha = sign * np.deg2rad(degrees)
            r = _pose_near(spec, alpha, which)
            truth = _mp_stiffness(spec, SINGULAR_K, r)
            ad = np.asarray(F["strut_stiffness"](r, np.zeros(3), []))
            paper = np.asarray(F["strut_stiffness_paper"](r, np.zeros(3), []))
            err_ad, err_paper = rel_err(ad, truth), rel_err(paper, truth)
            a = abs(alpha)
            if which == "parallel":
                assert err_ad <= max(1e-14, PAR_LOSS * EPS / a), (degrees, sign, err_ad)
                assert err_paper <= max(1e-14, PAR_LOSS * EPS / a), (degrees, sign, err_paper)
                assert rel_err(ad, paper) <= 1e-14
                # D_p ~ M_β′/(L² α): the 1/α growth of docs/paper-notes.md §2
                assert np.linalg.norm(ad) * a > 1e2
            else:
                assert err_ad <= 1e-14, (degrees, sign, err_ad)
                assert np.linalg.norm(ad) < 1e6
                if a ** 2 > 10 * EPS:
                    assert err_paper <= max(1e-14, PERP_LOSS * EPS / a ** 2), (degrees, sign)
                else:   # 1 − (e_n·e_γ)² is round-off: (2.3) may divide by zero
                    assert not np.all(np.isfinite(paper)) or err_paper <= 1.0


def test_exactly_on_the_singular_sets():
    """Documented behaviour on the sets themselves (measure zero for a sweep).

    * e_S ∥ e_n: e_β = e_S × e_n/|e_S × e_n| is 0/0, so P and both
      stiffnesses are NaN. Keep e₀ away (the constructor enforces 1°).
    * e_S ⊥ e_n: γ has a kink. (2.3) gives non-finite entries (it divides by
      sqrt(1 − (e_n·e_γ)²) = 0); P is finite and continuous, and the AD
      stiffness is finite: CasADi's d|u|/du = sign(0) = 0 makes it the mean
      of the two one-sided stiffnesses.
    """
    leg = HingedStrut(hinge=(0, 0, 0), e0=(0, 0.3, -1), en=(0, 0, -1), length=0.6,
                      S=Linear(2e5), M_beta=Linear(3e3), M_gamma=Linear(2e3))
    F = leg.functions()
    zero = np.zeros(3)
    on_axis = np.array([0.0, 0.0, -0.5])
    for name in ("strut_force", "strut_stiffness", "strut_stiffness_paper"):
        assert np.all(np.isnan(np.asarray(F[name](on_axis, zero, []))))
    in_plane = np.array([0.3, 0.4, 0.0])
    assert np.all(np.isfinite(np.asarray(F["strut_force"](in_plane, zero, []))))
    paper = np.asarray(F["strut_stiffness_paper"](in_plane, zero, []))
    assert not np.all(np.isfinite(paper))
    ad = np.asarray(F["strut_stiffness"](in_plane, zero, []))
    offset = np.array([0.0, 0.0, 1e-9])
    above = np.asarray(F["strut_stiffness"](in_plane + offset, zero, []))
    below = np.asarray(F["strut_stiffness"](in_plane - offset, zero, []))
    assert rel_err(above, below) > 0.01                # the kink: D_p jumps
    np.testing.assert_allclose(ad, (above + below) / 2, rtol=0,
                               atol=1e-6 * np.linalg.norm(ad))


# --------------------------------------------------------------------------
# The rest pose (docs/paper-notes.md §2)
# --------------------------------------------------------------------------

def _restoring_curves(rng, smooth):
    """Increasing curves through f(0) = 0 with no knot at 0, and their slopes there.

    Exact: every curve type. Smooth: linear curves only, because a rounded
    knot at distance u from 0 adds a preload Δs·w²/(4u) and a slope change
    Δs·w²/(4u²) at rest (1e-9 of the slope for a 0.1 mm knot 5 mm away),
    which would blur an exact comparison. A smooth unloading blend at rest
    (x·ẋ = 0) weighs both branches ½, so its slope is the mean.
    """
    k_S, k_b, k_g = 10 ** rng.uniform(4, 6), 10 ** rng.uniform(2, 4), 10 ** rng.uniform(2, 4)
    if smooth:
        curves = dict(S=Linear(k_S, unloading=Linear(0.2 * k_S), smooth=True),
                      M_beta=Linear(k_b, unloading=Linear(0.5 * k_b), smooth=True),
                      M_gamma=Linear(k_g, smooth=True))
        return curves, dict(S=0.6 * k_S, M_beta=0.75 * k_b, M_gamma=k_g)
    kind = rng.integers(3)
    if kind == 0:
        S = Linear(k_S, unloading=Linear(0.2 * k_S))    # loading branch at rest
    elif kind == 1:
        S = Crushable(k_S, 0.01 * k_S, 0.02 * k_S)
    else:
        S = PiecewiseLinear([-0.2, -0.05, 0.04, 0.1],
                            np.array([-0.095, -0.05, 0.04, 0.16]) * k_S)
    M_beta = PiecewiseLinear([-0.3, 0.1, 0.4], [-0.3 * k_b, 0.1 * k_b, 0.7 * k_b],
                             unloading=Linear(0.3 * k_b))
    M_gamma = Crushable(k_g, 0.05 * k_g)
    return dict(S=S, M_beta=M_beta, M_gamma=M_gamma), dict(S=k_S, M_beta=k_b, M_gamma=k_g)


@pytest.mark.parametrize("sign", [1, -1], ids=["e0.en>0", "e0.en<0"])
@pytest.mark.parametrize("smooth", [False, True], ids=["exact", "smooth"])
def test_rest_pose(sign, smooth):
    """At r = r_h + L₀e₀ with no preload: P = 0; D_p symmetric positive
    definite, = S′e_Se_Sᵀ + (M_β′/L₀²)e_βe_βᵀ + (m′/L₀²)e_γe_γᵀ (docs/paper-notes.md §2)."""
    rng = np.random.default_rng(11 + sign + 3 * smooth)
    for _ in range(25):
        e0, en = random_axis_pair(rng, sign)
        hinge, L0 = rng.uniform(-1, 1, 3), rng.uniform(0.2, 2.0)
        curves, slopes = _restoring_curves(rng, smooth)
        leg = HingedStrut(hinge=hinge, e0=e0, en=en, length=L0, **curves)
        assert np.sign(leg.e0 @ leg.en) == sign
        r = leg.rest_foot
        P = leg.force(r)
        D = leg.stiffness(r)
        scale = np.linalg.norm(D)
        assert np.linalg.norm(P) <= 1e-12 * scale * L0
        assert np.linalg.norm(D - D.T) <= 1e-12 * scale
        assert np.linalg.eigvalsh((D + D.T) / 2).min() > 0
        assert rel_err(D, leg.rest_stiffness_closed_form()) <= 1e-12
        # the closed form itself, from this test's own geometry and slopes
        e_S = unit(e0)
        e_beta = unit(np.cross(e_S, unit(en)))
        e_gamma = unit(unit(en) - (e_S @ unit(en)) * e_S)
        expected = (slopes["S"] * np.outer(e_S, e_S)
                    + slopes["M_beta"] / L0 ** 2 * np.outer(e_beta, e_beta)
                    + slopes["M_gamma"] / L0 ** 2 * np.outer(e_gamma, e_gamma))
        assert rel_err(D, expected) <= 1e-12
        assert rel_err(leg.stiffness(r, paper=True), D) <= 1e-12


# --------------------------------------------------------------------------
# Loading and unloading branches
# --------------------------------------------------------------------------

BRANCH_PARAMS = {"S": (2e5, 0.0, 3e4, 0.0), "M_beta": (3e3, 0.0, 5e2, 0.0),
                 "M_gamma": (2e3, 0.0, 4e2, 0.0)}


@pytest.mark.parametrize("sign", [1, -1], ids=["e0.en>0", "e0.en<0"])
@pytest.mark.parametrize("element", ["S", "M_beta", "M_gamma"])
def test_branch_follows_the_sign_of_the_deflection_rate(element, sign):
    """Loading branch while x·ẋ > 0, unloading while x·ẋ < 0, for each element.

    The foot is moved from rest along the element's own direction (e_S, e_β
    or e_γ at rest) by ±d, so that element is deflected; V is then ± that
    direction plus a random part. The expected force uses this test's own
    geometry and rate signs sign(V·e_S), sign(V·e_β), −sign(e₀·e_n)(V·e_γ).
    """
    rng = np.random.default_rng(5)
    e0, en = random_axis_pair(rng, sign)
    hinge, L0 = np.array([0.0, 0.1, -0.2]), 0.7
    spec = dict(hinge=hinge, e0=e0, en=en, L0=L0)
    curves = {n: Linear(k, f0, unloading=Linear(ku, fu0))
              for n, (k, f0, ku, fu0) in BRANCH_PARAMS.items()}
    leg = HingedStrut(hinge=hinge, e0=e0, en=en, length=L0, **curves)
    g0 = ref_geometry(hinge, e0, en, hinge + L0 * e0)
    direction = dict(S=g0["e_S"], M_beta=g0["e_beta"], M_gamma=g0["e_gamma"])[element]
    seen = set()
    for offset in (0.02, -0.02):
        r = hinge + L0 * e0 + offset * direction
        _, x, _, _ = ref_deflections(spec, r, np.zeros(3))
        assert abs(x[element]) > 0.01                   # the element is deflected
        for along in (1.0, -1.0):
            for _ in range(5):
                v = along * direction + 0.3 * rng.normal(size=3)
                _, x, rate, _ = ref_deflections(spec, r, v)
                loading = x[element] * rate[element] > 0
                seen.add((np.sign(x[element]), loading))
                k, f0, ku, fu0 = BRANCH_PARAMS[element]
                moment = (f0 + k * x[element]) if loading else (fu0 + ku * x[element])
                # the element's own contribution, from the reference (2.1)
                only = {n: (c if n == element else None) for n, c in BRANCH_PARAMS.items()}
                expected_part = ref_force_linear(spec, only, r, v)
                g = ref_geometry(hinge, e0, en, r)
                along_dir = dict(S=g["e_S"], M_beta=g["e_beta"] / g["L"],
                                 M_gamma=-np.sign(e0 @ en) * g["e_gamma"] / g["L"])[element]
                np.testing.assert_allclose(expected_part, moment * along_dir, rtol=1e-13)
                expected = ref_force_linear(spec, BRANCH_PARAMS, r, v)
                np.testing.assert_allclose(leg.force(r, v), expected, rtol=0,
                                           atol=1e-12 * np.linalg.norm(expected))
    assert seen == {(1.0, True), (1.0, False), (-1.0, True), (-1.0, False)}


@pytest.mark.parametrize("sign", [1, -1], ids=["e0.en>0", "e0.en<0"])
def test_rate_signs_are_the_true_deflection_rates(sign):
    """The docstring's rate signs equal the signs of d/dt of (δ_S, β, γ − γ₀),
    the latter from finite differences of this test's geometry along V."""
    rng = np.random.default_rng(3)
    checked = 0
    for _ in range(60):
        e0, en = random_axis_pair(rng, sign)
        spec = dict(hinge=np.zeros(3), e0=e0, en=en, L0=1.0)
        d = tilted(e0, perpendicular_unit(rng, e0), np.deg2rad(rng.uniform(0, 20)))
        r = rng.uniform(0.8, 1.2) * d
        # stay on e₀'s side of the plane ⊥ e_n and within 90° of its azimuth
        # about e_n: beyond, β = −arcsin(e₀·e_β) turns back and sign(V·e_β)
        # is no longer the sign of β′ (a limit of the paper's definition)
        if np.sign(d @ en) != sign or (d - (d @ en) * en) @ (e0 - (e0 @ en) * en) <= 0:
            continue
        for _ in range(10):
            v = rng.normal(size=3)
            _, _, rate, _ = ref_deflections(spec, r, v)
            tiny = 1e-7
            _, x_plus, _, _ = ref_deflections(spec, r + tiny * v, v)
            _, x_minus, _, _ = ref_deflections(spec, r - tiny * v, v)
            for name in ("S", "M_beta", "M_gamma"):
                true_rate = (x_plus[name] - x_minus[name]) / (2 * tiny)
                if abs(true_rate) > 1e-6:
                    assert np.sign(rate[name]) == np.sign(true_rate), (name, rate, true_rate)
                    checked += 1
    assert checked >= 600


def test_smooth_stiffness_holds_the_branch_weight():
    """With smooth=True the branch weight w = ½(1 + tanh(x·ẋ/RATE_WIDTH)) is a
    function of r (through x and ẋ). `strut_stiffness` holds w (the active
    branch's slope, as (2.3) with sign δ′ frozen), so AD equals (2.3) even
    inside the blend, while the full derivative of P — central differences of
    `strut_force` — has the extra term (f_load − f_unload)·e_S ∇wᵀ, computed
    here from this test's own ∇w. Without holding w that term reaches D_p
    and made it indefinite at touchdown (docs/optimise.md)."""
    hinge, e0, en, L0 = np.zeros(3), unit([0, 0.2, -1]), unit([0, 0.6, -1]), 0.6
    k, ku = 2e5, 2e4
    leg = HingedStrut(hinge=hinge, e0=e0, en=en, length=L0,
                      S=Linear(k, unloading=Linear(ku), smooth=True),
                      M_beta=Linear(3e3), M_gamma=Linear(3e3))
    F = leg.functions()
    in_blend = 0
    for delta, speed in ((1e-6, 0.3), (-2e-6, 0.2), (1e-3, 1.0)):
        r = hinge + (L0 + delta) * e0 + np.array([1e-3, 0, 0])
        v = speed * unit([0.2, 0.1, -1.0])
        g = ref_geometry(hinge, e0, en, r)
        x, rate = g["L"] - L0, v @ g["e_S"]
        z = x * rate / RATE_WIDTH
        in_blend += abs(z) < 1.0
        dx = g["e_S"]                                     # ∂δ_S/∂r
        drate = (v - (v @ g["e_S"]) * g["e_S"]) / g["L"]  # ∂(V·e_S)/∂r
        grad_w = 0.5 * (1 - np.tanh(z) ** 2) / RATE_WIDTH * (rate * dx + x * drate)
        extra = np.outer((k - ku) * x * g["e_S"], grad_w)
        ad = np.asarray(F["strut_stiffness"](r, v, []))
        paper = np.asarray(F["strut_stiffness_paper"](r, v, []))
        assert rel_err(paper, ad) <= RTOL_PAPER
        h = 1e-9
        full = np.column_stack([
            (np.asarray(F["strut_force"](r + h * e, v, [])).ravel()
             - np.asarray(F["strut_force"](r - h * e, v, [])).ravel()) / (2 * h)
            for e in np.eye(3)])
        # central differences at h = 1e-9 m: the truncation error h²·P‴ (P‴ up
        # to k·ẋ²/RATE_WIDTH² inside the blend) and the round-off eps·|P|/h
        # both stay below 1e-5·|D_p| on these poses
        np.testing.assert_allclose(full - ad, extra, rtol=0, atol=1e-5 * np.linalg.norm(ad))
    assert in_blend >= 2   # the check ran inside the blend, where the term is large


# --------------------------------------------------------------------------
# Validation
# --------------------------------------------------------------------------

GOOD = dict(hinge=(0, 0, 0), e0=(0, 0, -1), en=(0, 0.5, -1), length=0.6,
            S=Linear(2e5), M_beta=Linear(3e3), M_gamma=Linear(3e3))
#: words with which a message states the rule to follow or the fix
FIX_WORDS = ("give", "tilt", "pass", "must be", "must have")


def _check_message(excinfo, name, value):
    message = str(excinfo.value)
    assert f"`{name}`" in message, message
    assert value in message, message
    assert any(word in message for word in FIX_WORDS), message


@pytest.mark.parametrize("changes, error, name, value", [
    (dict(e0=(0, 0.5, -1)), ValueError, "e0", "°"),                  # e0 ∥ en
    (dict(e0=(0, -0.5, 1)), ValueError, "e0", "°"),                  # anti-parallel
    (dict(e0=(0, 0.5, -1.01)), ValueError, "e0", "0.2"),              # 0.2° from en
    (dict(e0=(1, 0, 0), en=(0, 0, 1)), ValueError, "e0", "90°"),     # e0 ⊥ en
    (dict(e0=(0, 0, -1), en=(0, 1, -0.01)), ValueError, "e0", "89.4"),
    (dict(e0=(0, np.nan, -1)), ValueError, "e0", "nan"),
    (dict(en=(np.inf, 0, 1)), ValueError, "en", "inf"),
    (dict(hinge=(0, np.nan, 0)), ValueError, "hinge", "nan"),
    (dict(e0=(0, 0, 0)), ValueError, "e0", "[0.0, 0.0, 0.0]"),
    (dict(en=(0, 0, 0)), ValueError, "en", "[0.0, 0.0, 0.0]"),
    (dict(e0=(0, 1)), ValueError, "e0", "(0, 1)"),
    (dict(e0="up"), TypeError, "e0", "'up'"),
    (dict(length=0.0), ValueError, "length", "0.0"),
    (dict(length=-0.5), ValueError, "length", "-0.5"),
    (dict(length=np.inf), ValueError, "length", "inf"),
    (dict(length="0.6"), TypeError, "length", "'0.6'"),
    (dict(S=2e5), TypeError, "S", "200000.0"),
    (dict(S=None, M_beta=None, M_gamma=None), ValueError, "S=None", "M_beta"),
    (dict(S=None, M_beta=Linear(0.0), M_gamma=None), ValueError, "S=None", "M_beta"),
    (dict(S=None, axial_ratio=-1.0), ValueError, "axial_ratio", "-1.0"),
])
def test_constructor_rejects_bad_input(changes, error, name, value):
    with pytest.raises(error) as excinfo:
        HingedStrut(**{**GOOD, **changes})
    _check_message(excinfo, name, value)


def test_singular_angle_is_the_limit():
    """e₀ must be at least SINGULAR_ANGLE (1°) from the e_n axis and from the
    plane ⊥ e_n: 0.99° is rejected, 1.01° accepted, on both sides."""
    en = np.array([0.0, 0.0, -1.0])
    side = np.array([1.0, 0.0, 0.0])
    for degrees, ok in ((0.99, False), (1.01, True)):
        angle = np.deg2rad(degrees)
        for e0 in (tilted(en, side, angle), tilted(side, en, angle),
                   tilted(-en, side, angle), tilted(side, -en, angle)):
            kwargs = {**GOOD, "e0": e0, "en": en}
            if ok:
                HingedStrut(**kwargs)
            else:
                with pytest.raises(ValueError, match="`e0`"):
                    HingedStrut(**kwargs)
    assert SINGULAR_ANGLE == pytest.approx(np.deg2rad(1.0))


def test_evaluation_rejects_bad_input():
    leg = HingedStrut(**GOOD)
    with pytest.raises(ValueError) as excinfo:
        leg.force(leg.hinge)                              # foot at the hinge
    _check_message(excinfo, "r", "[0.0, 0.0, 0.0]")
    with pytest.raises(ValueError) as excinfo:
        leg.stiffness((0, np.nan, -0.6))
    _check_message(excinfo, "r", "nan")
    with pytest.raises(ValueError) as excinfo:
        leg.force((0, 0, -0.6), v=(1, 2))
    _check_message(excinfo, "v", "(1, 2)")
    with pytest.raises(ValueError) as excinfo:
        leg.force((0, 0, -0.6), p=[1.0])                  # no tunable curves: p is empty
    assert "`p`" in str(excinfo.value) and "got 1" in str(excinfo.value)


def test_wrong_parameter_count_is_rejected():
    """A curve's theta and a strut's p of the wrong length name the fix."""
    curve = Linear(2e5, tunable=True)
    with pytest.raises(ValueError) as excinfo:
        curve.force(0.1, theta=[1.0, 2.0, 3.0])
    message = str(excinfo.value)
    assert "`theta`" in message and "got 3" in message and "'k', 'preload'" in message
    assert "pass one value per parameter" in message
    leg = HingedStrut(**{**GOOD, "S": curve})
    with pytest.raises(ValueError) as excinfo:
        leg.force((0, 0, -0.6), p=[1.0])
    message = str(excinfo.value)
    assert "`p`" in message and "got 1" in message and "S.k" in message


# --------------------------------------------------------------------------
# Axially rigid rod, tunable curves
# --------------------------------------------------------------------------

@pytest.mark.parametrize("ratio", [None, 1e2, 1e6])
@pytest.mark.parametrize("hinge_curves", [
    dict(M_beta=Linear(1200.0), M_gamma=Linear(1200.0)),
    dict(M_beta=Linear(800.0), M_gamma=Linear(2500.0)),
    dict(M_beta=Linear(900.0)),
    dict(M_gamma=Crushable(3000.0, 100.0)),
], ids=["equal", "gamma-stiffer", "beta-only", "gamma-only"])
def test_rigid_rod_axial_stiffness(ratio, hinge_curves):
    """S=None: e₀ᵀD_pe₀ = axial_ratio·max(M_β′, M_γ′)/L₀² at rest (RIGID_AXIAL_RATIO
    by default), i.e. the axial stroke is 1/axial_ratio of the bending
    deflection under the same force."""
    L0 = 0.6
    kwargs = {} if ratio is None else dict(axial_ratio=ratio)
    leg = HingedStrut(hinge=(0.3, 0, -0.18), e0=(0, 0, -1), en=(-1, 0, -1), length=L0,
                      S=None, **hinge_curves, **kwargs)
    assert leg.rigid
    D = leg.stiffness(leg.rest_foot)
    bend = max(c.slope(0.0) for c in hinge_curves.values())
    expected_ratio = RIGID_AXIAL_RATIO if ratio is None else ratio
    axial = leg.e0 @ D @ leg.e0
    assert axial == pytest.approx(expected_ratio * bend / L0 ** 2, rel=1e-12)
    en = unit((-1, 0, -1))
    e_beta = unit(np.cross(leg.e0, en))
    e_gamma = unit(en - (leg.e0 @ en) * leg.e0)
    bending = max(e_beta @ D @ e_beta, e_gamma @ D @ e_gamma)   # the hinge directions
    # The rest pose has δ_S = round-off (≈ eps·|r_h|), whose force k_S δ_S adds
    # a geometric stiffness k_S·δ_S/L to the bending directions: a relative
    # error ≈ ratio·eps there, 2e-10 at ratio 1e6.
    assert axial / bending == pytest.approx(expected_ratio, rel=max(1e-12, 1e-14 * expected_ratio))


def test_tunable_curves_expose_named_parameters():
    """tunable=True puts the curve's parameters into p under '<element>.<name>';
    with p at its defaults the Functions equal those of the numeric strut."""
    def curves(tunable):
        return dict(
            S=Crushable(2e5, 4e3, 1e3, unloading=Linear(2e4), tunable=tunable),
            M_beta=Linear(3e3, 10.0, tunable=tunable),
            M_gamma=PiecewiseLinear([-0.2, 0.0, 0.3], [-300.0, 0.0, 900.0], tunable=tunable))
    geometry = dict(hinge=(0.1, 0.0, 0.0), e0=(0.2, 0, -1), en=(-0.5, 0.1, -1), length=0.6)
    tuned = HingedStrut(**geometry, **curves(True))
    baked = HingedStrut(**geometry, **curves(False))
    assert tuned.param_names == (
        "S.k", "S.crush_force", "S.plateau_slope", "S.unload.k", "S.unload.preload",
        "M_beta.k", "M_beta.preload", "M_gamma.f0", "M_gamma.f1", "M_gamma.f2")
    np.testing.assert_array_equal(tuned.param_values,
                                  [2e5, 4e3, 1e3, 2e4, 0.0, 3e3, 10.0, -300.0, 0.0, 900.0])
    assert baked.param_names == () and baked.param_values.size == 0
    Ft, Fb = tuned.functions(), baked.functions()
    assert Ft["strut_force"].name_in() == ["r", "v", "p"]
    assert Ft["strut_force"].size1_in(2) == 10 and Fb["strut_force"].size1_in(2) == 0
    rng = np.random.default_rng(2)
    n = 50
    r = tuned.rest_foot + rng.normal(scale=0.05, size=(n, 3))
    v = rng.normal(size=(n, 3))
    for name in ("strut_force", "strut_stiffness", "strut_stiffness_paper"):
        a = batch(Ft[name], r, v, tuned.param_values)
        b = batch(Fb[name], r, v, np.zeros(0))
        np.testing.assert_allclose(a, b, rtol=1e-14, atol=1e-14 * np.abs(b).max())
    # and p really is used: doubling S.k doubles the elastic axial force
    p = tuned.param_values.copy()
    p[0] *= 2
    r_ext = tuned.rest_foot + 1e-3 * tuned.e0
    base = tuned.force(r_ext)
    assert tuned.e0 @ tuned.force(r_ext, p=p) == pytest.approx(2 * (tuned.e0 @ base), rel=1e-9)
