"""Tests of ``symcushion.legs.characteristics``: the resistance curves f(x, sign ẋ).

Each curve (Linear, PiecewiseLinear, Crushable; exact and smooth; with and
without an unloading branch) is checked against this file's own NumPy
formulas: values at and between the knots, ``slope()`` against
``casadi.jacobian`` and against finite differences, float = SX = MX, the
smoothed curve within (slope change)·kink_width/2 of the exact one, branch
selection by the sign of x·ẋ, and input validation. Hypothesis draws random
knots where a fixed example would prove little.
"""
from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from symcushion import Crushable, Curve, Linear, PiecewiseLinear
from symcushion.legs.curve_base import KINK_WIDTH, RATE_WIDTH

#: Relative agreement of two evaluations of the same expression (float vs
#: SX vs MX, hand slope vs casadi.jacobian): a few ulps of the curve's scale.
RTOL_SAME = 1e-13
#: Relative agreement of slope() with central differences (step below).
RTOL_FD = 1e-7
#: A smooth blend is saturated beyond this many RATE_WIDTHs of x·ẋ (tanh(40)
#: rounds to 1).
SATURATED = 40.0

# ---------------------------------------------------------------------------
# Plain-number descriptions of curves and this file's own formulas for them
# ---------------------------------------------------------------------------

LINEAR = ("linear", 2.0e4, 50.0)                                 # k (N/m), preload (N)
PWL = ("pwl", [-0.1, 0.0, 0.05, 0.2], [-500.0, 0.0, 800.0, 1200.0])
CRUSH = ("crush", 2.0e6, 8.0e3, 1.0e4)                           # k, F_c, plateau slope
UNLOAD_LINEAR = ("linear", 5.0e3, -20.0)
UNLOAD_PWL = ("pwl", [-0.05, 0.02, 0.1], [-100.0, 30.0, 90.0])


def build(spec, **options):
    kind = spec[0]
    if kind == "linear":
        return Linear(spec[1], spec[2], **options)
    if kind == "pwl":
        return PiecewiseLinear(spec[1], spec[2], **options)
    return Crushable(spec[1], spec[2], spec[3], **options)


def kinks(spec):
    """Deflections where the exact curve has a corner."""
    if spec[0] == "pwl":
        return list(spec[1][1:-1])
    if spec[0] == "crush":
        return [-spec[2] / spec[1]]
    return []


def slope_changes(spec):
    """Jump of the slope at each corner of :func:`kinks`."""
    if spec[0] == "pwl":
        s = np.diff(spec[2]) / np.diff(spec[1])
        return list(np.diff(s))
    if spec[0] == "crush":
        return [spec[1] - spec[3]]
    return []


def exact_value(spec, x):
    """f(x) of the exact curve, written from its definition."""
    x = np.asarray(x, float)
    kind = spec[0]
    if kind == "linear":
        return spec[2] + spec[1] * x
    if kind == "pwl":
        xs, fs = np.asarray(spec[1]), np.asarray(spec[2])
        inside = np.interp(x, xs, fs)
        left = fs[0] + (fs[1] - fs[0]) / (xs[1] - xs[0]) * (x - xs[0])
        right = fs[-1] + (fs[-1] - fs[-2]) / (xs[-1] - xs[-2]) * (x - xs[-1])
        return np.where(x < xs[0], left, np.where(x > xs[-1], right, inside))
    k, f_c, k_p = spec[1:]
    x_c = -f_c / k
    return np.where(x >= x_c, k * x, -f_c + k_p * (x - x_c))


def exact_slope(spec, x):
    """df/dx of the exact curve away from its corners."""
    x = np.asarray(x, float)
    kind = spec[0]
    if kind == "linear":
        return spec[1] + 0 * x
    if kind == "pwl":
        xs, fs = np.asarray(spec[1]), np.asarray(spec[2])
        s = np.diff(fs) / np.diff(xs)
        return s[np.clip(np.searchsorted(xs, x) - 1, 0, len(s) - 1)]
    k, f_c, k_p = spec[1:]
    return np.where(x >= -f_c / k, k, k_p)


CASES = {                                     # id: (loading spec, unloading spec)
    "linear": (LINEAR, None),
    "linear+unload": (LINEAR, UNLOAD_PWL),
    "pwl": (PWL, None),
    "pwl+unload": (PWL, UNLOAD_LINEAR),
    "crush": (CRUSH, None),
    "crush+unload": (CRUSH, UNLOAD_LINEAR),
}


def make(case, smooth, **options):
    load, unload = CASES[case]
    unloading = build(unload) if unload is not None else None
    return build(load, unloading=unloading, smooth=smooth, **options)


def all_kinks(case):
    load, unload = CASES[case]
    return kinks(load) + (kinks(unload) if unload is not None else [])


def sample_x(case, rng, n=200, margin=1e-4):
    """Deflections spread over the curve's range, ≥ margin from any corner."""
    load = CASES[case][0]
    span = 0.03 if load[0] == "crush" else 0.3
    x = rng.uniform(-span, span, n)
    corners = np.array(all_kinks(case) + [0.0])          # 0: the branch switch
    far = np.all(np.abs(x[:, None] - corners[None, :]) > margin, axis=1)
    return x[far]


# ---------------------------------------------------------------------------
# Values
# ---------------------------------------------------------------------------

def test_linear_values_and_slope():
    curve = build(LINEAR)
    for x in (-0.3, 0.0, 0.01, 0.25):
        assert curve.force(x) == pytest.approx(50.0 + 2e4 * x, rel=1e-15, abs=1e-12)
        assert curve.slope(x) == 2e4
        assert curve(x) == curve.force(x)


def test_piecewise_linear_passes_through_its_knots():
    curve = build(PWL)
    for xk, fk in zip(*PWL[1:]):
        assert curve.force(xk) == pytest.approx(fk, rel=1e-14, abs=1e-11)


def test_piecewise_linear_between_and_beyond_the_knots():
    curve = build(PWL)
    xs = np.concatenate([np.linspace(-0.3, 0.4, 141), [0.025, 0.125]])
    for x in xs:
        assert curve.force(x) == pytest.approx(exact_value(PWL, x), rel=1e-13, abs=1e-10)
    # the end segments are extended, not clamped
    assert curve.force(0.4) == pytest.approx(1200.0 + 400.0 / 0.15 * 0.2)
    assert curve.force(-0.3) == pytest.approx(-500.0 - 5000.0 * 0.2)


def test_crushable_rises_then_crushes():
    k, f_c, k_p = CRUSH[1:]
    curve = build(CRUSH)
    x_c = -f_c / k
    assert curve.force(x_c) == pytest.approx(-f_c, rel=1e-14)           # onset
    assert curve.force(0.001) == pytest.approx(k * 0.001, rel=1e-14)    # elastic tension
    assert curve.force(x_c - 0.02) == pytest.approx(-f_c - k_p * 0.02, rel=1e-14)
    assert curve.slope(x_c / 2) == k and curve.slope(x_c - 0.01) == k_p
    assert curve.force(0.0) == 0.0


@pytest.mark.parametrize("case", CASES)
def test_exact_values_match_own_formula(case):
    """Loading branch (ẋ = 0 or x·ẋ > 0) and unloading branch (x·ẋ < 0)."""
    rng = np.random.default_rng(1)
    curve = make(case, smooth=False)
    load, unload = CASES[case]
    for x in sample_x(case, rng):
        assert curve.force(x) == pytest.approx(exact_value(load, x), rel=1e-13, abs=1e-9)
        assert curve.force(x, np.sign(x)) == pytest.approx(exact_value(load, x),
                                                            rel=1e-13, abs=1e-9)
        other = unload if unload is not None else load
        assert curve.force(x, -np.sign(x)) == pytest.approx(exact_value(other, x),
                                                             rel=1e-13, abs=1e-9)


# ---------------------------------------------------------------------------
# Slope = derivative
# ---------------------------------------------------------------------------

def _jacobian_function(curve):
    x, rate = ca.SX.sym("x"), ca.SX.sym("rate")
    f = curve.force(x, rate)
    return ca.Function("df", [x, rate], [ca.jacobian(f, x), curve.slope(x, rate)])


@pytest.mark.parametrize("smooth", [False, True], ids=["exact", "smooth"])
@pytest.mark.parametrize("case", CASES)
def test_slope_equals_jacobian_and_finite_differences(case, smooth):
    """slope() = ∂f/∂x by casadi.jacobian and by central differences.

    Errors are relative to the largest |slope| of the curve. Exact curves:
    sampled ≥ 1e-4 from every corner with the step h = 1e-7, so the stencil
    never crosses one and the branches are linear (no truncation error);
    round-off eps·|f|/h ≈ 1e-9. Smooth curves: also inside the rounded
    corners, with h = 1e-4·w: the hyperbola of width w has truncation
    ≈ (h/w)²/6 ≈ 2e-9 and round-off eps·|f|/h ≈ 1e-9. Blends that are
    mid-switch are skipped: see test_smooth_blend_slope_is_the_active_branch_only.
    """
    rng = np.random.default_rng(2)
    curve = make(case, smooth=smooth)
    df = _jacobian_function(curve)
    x = sample_x(case, rng)
    if smooth:                                # and points inside each rounded corner
        x = np.concatenate([x] + [k + curve.kink_width * rng.uniform(-5, 5, 10)
                                  for k in all_kinks(case)])
    scale = max(abs(curve.slope(t)) for t in x)
    h = 1e-4 * curve.kink_width if smooth else 1e-7
    for xi in x:
        for rate in (1.0, -1.0, 0.0):
            if smooth and 0 < abs(xi * rate) < SATURATED * RATE_WIDTH:
                continue
            jac, slope = (float(v) for v in df(xi, rate))
            assert slope == pytest.approx(curve.slope(xi, rate), rel=RTOL_SAME, abs=1e-9)
            assert abs(jac - slope) <= RTOL_SAME * scale, (xi, rate, jac, slope)
            fd = (curve.force(xi + h, rate) - curve.force(xi - h, rate)) / (2 * h)
            assert abs(fd - slope) <= RTOL_FD * scale, (xi, rate, fd, slope)


def test_exact_slope_matches_own_formula():
    rng = np.random.default_rng(3)
    for case in ("linear", "pwl", "crush"):
        curve = make(case, smooth=False)
        for x in sample_x(case, rng):
            assert curve.slope(x) == pytest.approx(exact_slope(CASES[case][0], x), rel=1e-13)


def test_slope_exactly_at_a_knot():
    """At a corner the derivative does not exist. Documented choices: slope()
    returns the slope on the left of it, casadi.jacobian of the exact curve
    the mean of both sides (CasADi differentiates fmax(u, 0) at u = 0 as ½)."""
    curve = build(PWL)
    df = _jacobian_function(curve)
    jac, slope = (float(v) for v in df(0.05, 0.0))
    left, right = 800.0 / 0.05, 400.0 / 0.15
    assert slope == pytest.approx(left, rel=1e-14)
    assert jac == pytest.approx((left + right) / 2, rel=1e-14)


def test_smooth_blend_slope_is_the_active_branch_only():
    """slope() is the blend of the branches' slopes, w f_l′ + (1 − w) f_u′; the
    full derivative adds (f_l − f_u)·∂w/∂x, w = ½(1 + tanh(x ẋ/RATE_WIDTH)).
    The two agree where the blend is saturated or ẋ = 0."""
    curve = make("linear+unload", smooth=True)
    df = _jacobian_function(curve)
    for x, rate in ((2e-6, 1.0), (-1e-6, 3.0), (5e-5, -0.5)):
        z = x * rate / RATE_WIDTH
        w = 0.5 * (1 + np.tanh(z))
        dw = 0.5 * (1 - np.tanh(z) ** 2) * rate / RATE_WIDTH
        f_l, f_u = exact_value(LINEAR, x), curve.unloading.force(x)
        jac, slope = (float(v) for v in df(x, rate))
        expected_slope = w * LINEAR[1] + (1 - w) * curve.unloading.slope(x)
        assert slope == pytest.approx(expected_slope, rel=1e-12)
        assert jac - slope == pytest.approx((f_l - f_u) * dw, rel=1e-9)


# ---------------------------------------------------------------------------
# Float, SX and MX give the same numbers; theta
# ---------------------------------------------------------------------------

@pytest.mark.parametrize("sym", [ca.SX, ca.MX], ids=["SX", "MX"])
@pytest.mark.parametrize("smooth", [False, True], ids=["exact", "smooth"])
@pytest.mark.parametrize("case", CASES)
def test_float_and_symbolic_agree(case, smooth, sym):
    """force/slope on floats = the same on SX/MX symbols (x, ẋ and θ symbolic)."""
    curve = make(case, smooth=smooth, tunable=True)
    x, rate, theta = sym.sym("x"), sym.sym("rate"), sym.sym("theta", curve.n_params)
    fun = ca.Function("f", [x, rate, theta],
                      [curve.force(x, rate, theta), curve.slope(x, rate, theta)])
    fun_default = ca.Function("g", [x, rate], [curve.force(x, rate), curve.slope(x, rate)])
    rng = np.random.default_rng(4)
    for xi in np.concatenate([sample_x(case, rng, 40), all_kinks(case)]):
        for ri in (1.3, -0.7, 0.0):
            f_num, s_num = curve.force(xi, ri), curve.slope(xi, ri)
            assert isinstance(f_num, float) and isinstance(s_num, float)
            for f_sym, s_sym in (fun(xi, ri, curve.param_values), fun_default(xi, ri)):
                assert float(f_sym) == pytest.approx(f_num, rel=RTOL_SAME, abs=1e-10)
                assert float(s_sym) == pytest.approx(s_num, rel=RTOL_SAME, abs=1e-10)


def test_theta_overrides_the_numbers():
    curve = Crushable(2e6, 8e3, 1e4, unloading=Linear(2e4, 5.0))
    assert curve.param_names == ("k", "crush_force", "plateau_slope", "unload.k",
                                 "unload.preload")
    np.testing.assert_array_equal(curve.param_values, [2e6, 8e3, 1e4, 2e4, 5.0])
    theta = [1e6, 4e3, 0.0, 1e4, 0.0]
    other = Crushable(1e6, 4e3, 0.0, unloading=Linear(1e4))
    for x in (-0.01, -0.001, 0.002):
        for rate in (1.0, -1.0):
            assert curve.force(x, rate, theta) == pytest.approx(other.force(x, rate), rel=1e-14)
            assert curve.slope(x, rate, theta) == pytest.approx(other.slope(x, rate), rel=1e-14)


# ---------------------------------------------------------------------------
# Smooth versus exact
# ---------------------------------------------------------------------------

@pytest.mark.parametrize("case", CASES)
def test_smooth_within_half_kink_width_of_exact(case):
    """The hyperbola ½(u + sqrt(u² + w²)) lies at most w/2 above max(u, 0), so
    the smoothed curve is within Σ|Δs_i|·w/2 of the exact one (Δs_i the slope
    change at corner i): w/2 in deflection, scaled by the slope change. It
    touches that bound at an isolated corner. Rates with a saturated blend."""
    load, unload = CASES[case]
    exact, smooth = make(case, smooth=False), make(case, smooth=True)
    w = smooth.kink_width
    assert w == KINK_WIDTH
    x = np.concatenate([np.linspace(-0.3, 0.3, 2001), all_kinks(case)])
    x = x[np.abs(x) > SATURATED * RATE_WIDTH]
    for branch, spec in ((1.0, load), (-1.0, unload if unload is not None else load)):
        bound = sum(abs(ds) for ds in slope_changes(spec)) * w / 2

        def gap(t):
            rate = branch * np.sign(t)
            return abs(smooth.force(t, rate) - exact.force(t, rate))

        dev = np.array([gap(t) for t in x])
        assert dev.max() <= bound * (1 + 1e-9) + 1e-12
        for corner, ds in zip(kinks(spec), slope_changes(spec)):
            if abs(corner) > SATURATED * RATE_WIDTH:
                assert gap(corner) == pytest.approx(abs(ds) * w / 2, rel=1e-2)


def test_smooth_curve_rounds_its_unloading_branch_too():
    """smooth=True removes every corner, including the unloading branch's."""
    unloading = build(UNLOAD_PWL)
    curve = Linear(2e4, unloading=unloading, smooth=True, kink_width=1e-3)
    assert not unloading.smooth                    # the caller's curve is untouched
    x = ca.SX.sym("x")
    expr = curve.force(x, -1.0)
    assert "fmax" not in str(expr) and "if_else" not in str(expr)
    # slope() inside the unloading corner is the hyperbola's, not a step
    corner = UNLOAD_PWL[1][1]
    s_left, s_right = np.diff(UNLOAD_PWL[2])[:2] / np.diff(UNLOAD_PWL[1])[:2]
    assert curve.slope(corner, -np.sign(corner)) == pytest.approx((s_left + s_right) / 2,
                                                                  rel=1e-12)


# ---------------------------------------------------------------------------
# Branch selection
# ---------------------------------------------------------------------------

def test_exact_branch_follows_sign_of_x_times_rate():
    """Loading while x·ẋ ≥ 0 (|x| grows, or ẋ = 0, or x = 0), unloading while x·ẋ < 0."""
    curve = Linear(1e4, unloading=Linear(2e3, 1.0))
    for x in (0.02, -0.02):
        assert curve.force(x, np.sign(x)) == pytest.approx(1e4 * x)        # growing
        assert curve.force(x, 0.0) == pytest.approx(1e4 * x)               # at rest
        assert curve.force(x, -np.sign(x)) == pytest.approx(1.0 + 2e3 * x)  # shrinking
        assert curve.slope(x, -np.sign(x)) == 2e3
        assert curve.slope(x, np.sign(x)) == 1e4
    assert curve.force(0.0, -1.0) == 0.0 and curve.force(0.0, 1.0) == 0.0
    # only the sign of the rate matters
    assert curve.force(0.02, -1e-12) == curve.force(0.02, -1e3)


def test_smooth_branch_blend():
    """smooth=True: f = w f_l + (1 − w) f_u, w = ½(1 + tanh(x ẋ/RATE_WIDTH));
    equal to the exact branch choice once |x ẋ| ≥ 40 RATE_WIDTH."""
    exact = Linear(1e4, unloading=Linear(2e3, 1.0))
    smooth = Linear(1e4, unloading=Linear(2e3, 1.0), smooth=True)
    for x, rate in ((1e-4, 0.01), (-2e-4, 0.005), (3e-4, -0.001), (0.02, 1.0), (0.02, -1.0)):
        w = 0.5 * (1 + np.tanh(x * rate / RATE_WIDTH))
        expected = w * 1e4 * x + (1 - w) * (1.0 + 2e3 * x)
        assert smooth.force(x, rate) == pytest.approx(expected, rel=1e-13)
        if abs(x * rate) >= SATURATED * RATE_WIDTH:
            assert smooth.force(x, rate) == pytest.approx(exact.force(x, rate), rel=1e-15)
    assert smooth.force(0.01, 0.0) == pytest.approx(0.5 * (100 + 21.0), rel=1e-14)


def test_symbolic_branch_selection_matches_numeric():
    curve = make("pwl+unload", smooth=False)
    x, rate = ca.SX.sym("x"), ca.SX.sym("rate")
    fun = ca.Function("f", [x, rate], [curve.force(x, rate)])
    for xi in (-0.08, -0.01, 0.03, 0.15):
        for ri in (-2.0, 2.0):
            assert float(fun(xi, ri)) == curve.force(xi, ri)
            expected = exact_value(PWL if xi * ri >= 0 else UNLOAD_LINEAR, xi)
            assert float(fun(xi, ri)) == pytest.approx(float(expected), rel=1e-13)


# ---------------------------------------------------------------------------
# Validation
# ---------------------------------------------------------------------------

@pytest.mark.parametrize("factory, error, name, value", [
    (lambda: Linear("1e4"), TypeError, "stiffness", "'1e4'"),
    (lambda: Linear(True), TypeError, "stiffness", "True"),
    (lambda: Linear(np.nan), ValueError, "stiffness", "nan"),
    (lambda: Linear(1e4, preload=np.inf), ValueError, "preload", "inf"),
    (lambda: Crushable(0.0, 1e3), ValueError, "stiffness", "0.0"),
    (lambda: Crushable(1e6, -5.0), ValueError, "crush_force", "-5.0"),
    (lambda: Crushable(1e6, 1e3, -1.0), ValueError, "plateau_slope", "-1.0"),
    (lambda: PiecewiseLinear([0.0], [1.0]), ValueError, "x", "got 1"),
    (lambda: PiecewiseLinear([0.0, 1.0], [1.0]), ValueError, "f", "got 1"),
    (lambda: PiecewiseLinear([0.0, 0.0], [1.0, 2.0]), ValueError, "x", "[0.0, 0.0]"),
    (lambda: PiecewiseLinear([1.0, 0.0], [1.0, 2.0]), ValueError, "x", "[1.0, 0.0]"),
    (lambda: PiecewiseLinear([0.0, np.nan], [1.0, 2.0]), ValueError, "x", "nan"),
    (lambda: PiecewiseLinear([0.0, 1.0], [1.0, np.inf]), ValueError, "f", "inf"),
    (lambda: Linear(1e4, unloading=2e3), TypeError, "unloading", "2000.0"),
    (lambda: Linear(1e4, unloading=Linear(1.0, unloading=Linear(2.0))), ValueError,
     "unloading", "unloading branch"),
    (lambda: Linear(1e4, smooth=True, kink_width=0.0), ValueError, "kink_width", "0.0"),
    (lambda: Linear(1e4, rate_width=-1e-6), ValueError, "rate_width", "-1e-06"),
    (lambda: Linear(1e4).force(0.1, theta=[1.0]), ValueError, "theta", "got 1"),
    (lambda: Linear(1e4).slope(0.1, theta=ca.SX.sym("t", 3)), ValueError, "theta", "got 3"),
    (lambda: PiecewiseLinear([0, 1, 2], [0, 1, 3]).force(0.1, theta=[1.0, 2.0]), ValueError,
     "theta", "'f0', 'f1', 'f2'"),
])
def test_bad_input_is_rejected(factory, error, name, value):
    with pytest.raises(error) as excinfo:
        factory()
    message = str(excinfo.value)
    assert f"`{name}`" in message, message
    assert value in message, message
    assert any(word in message for word in ("give", "pass", "sort", "must")), message


def test_curve_base_class_is_abstract():
    assert issubclass(Linear, Curve)
    with pytest.raises(NotImplementedError):
        Curve()._loading(0.0, None)


# ---------------------------------------------------------------------------
# Hypothesis: random knots
# ---------------------------------------------------------------------------

@st.composite
def piecewise_curves(draw):
    m = draw(st.integers(2, 6))
    gaps = draw(st.lists(st.floats(0.01, 0.2), min_size=m - 1, max_size=m - 1))
    x0 = draw(st.floats(-0.3, 0.0))
    xs = x0 + np.concatenate([[0.0], np.cumsum(gaps)])
    fs = draw(st.lists(st.floats(-1e4, 1e4), min_size=m, max_size=m))
    return xs, np.array(fs)


@settings(max_examples=150, deadline=None)
@given(curve=piecewise_curves(), t=st.floats(-0.6, 1.0))
def test_piecewise_linear_random(curve, t):
    """Exact: the linear interpolant with extended end segments, slope = its
    slope (FD); smooth: within Σ|Δs|·w/2 and slope = casadi.jacobian."""
    xs, fs = curve
    spec = ("pwl", xs, fs)
    exact = PiecewiseLinear(xs, fs)
    smooth = PiecewiseLinear(xs, fs, smooth=True)
    scale = max(1.0, np.abs(fs).max())
    assert exact.force(t) == pytest.approx(float(exact_value(spec, t)), rel=1e-12,
                                           abs=1e-12 * scale)
    if np.min(np.abs(t - xs)) > 1e-6:
        h = 1e-8
        fd = (exact.force(t + h) - exact.force(t - h)) / (2 * h)
        slope_scale = max(1.0, np.abs(np.diff(fs) / np.diff(xs)).max())
        assert exact.slope(t) == pytest.approx(float(exact_slope(spec, t)), rel=1e-12,
                                               abs=1e-12 * slope_scale)
        assert abs(fd - exact.slope(t)) <= 1e-5 * slope_scale
    bound = sum(abs(ds) for ds in slope_changes(spec)) * smooth.kink_width / 2
    assert abs(smooth.force(t) - exact.force(t)) <= bound * (1 + 1e-9) + 1e-12 * scale
    x = ca.SX.sym("x")
    jac = ca.Function("j", [x], [ca.jacobian(smooth.force(x), x)])
    assert float(jac(t)) == pytest.approx(smooth.slope(t), rel=1e-12, abs=1e-12 * scale)


@settings(max_examples=100, deadline=None)
@given(k=st.floats(1e2, 1e7), f_c=st.floats(1.0, 1e5), ratio=st.floats(0.0, 1.0),
       t=st.floats(-0.5, 0.5))
def test_crushable_random(k, f_c, ratio, t):
    """Continuous at the onset −F_c/k; values and slope as defined."""
    spec = ("crush", k, f_c, ratio * k)
    curve = Crushable(k, f_c, ratio * k)
    # on the plateau the curve is k x + (k − k_p)(x_c − x): two terms of size
    # k|x| cancel, so the error is a few eps·k|x|, not eps·F_c
    assert curve.force(t) == pytest.approx(float(exact_value(spec, t)), rel=1e-12,
                                           abs=1e-15 * k * (abs(t) + f_c / k))
    x_c = -f_c / k
    for side in (1, -1):                        # continuity across the onset
        assert curve.force(x_c + side * 1e-12 * abs(x_c)) == pytest.approx(-f_c, rel=1e-9)
    if abs(t - x_c) > 1e-9:                     # k_p is computed as k − (k − k_p)
        assert curve.slope(t) == pytest.approx(float(exact_slope(spec, t)), abs=1e-14 * k)


def test_zero_deflection_loads_whatever_the_sign_of_the_rate():
    """A strut's unloaded pose carries round-off deflections (1e-16) of either sign:
    from there the element can only load, so the loading branch is taken even
    where x·ẋ < 0 by that round-off; past ZERO_DEFLECTION the test is x·ẋ again."""
    from symcushion.legs.curve_base import ZERO_DEFLECTION
    curve = Crushable(1e5, 2500.0, 5e3, unloading=PiecewiseLinear([-0.3, -0.03, 0.0],
                                                                   [-500.0, -500.0, 0.0]))
    loading, unloading = 1e5, 500.0 / 0.03
    for x in (1.1e-16, -1.1e-16, ZERO_DEFLECTION, -ZERO_DEFLECTION):
        for rate in (1.0, -1.0):
            assert curve.slope(x, rate) == pytest.approx(loading, rel=1e-12)
    for x in (10 * ZERO_DEFLECTION, -1e-3):
        assert curve.slope(x, -np.sign(x)) == pytest.approx(unloading, rel=1e-12)
        assert curve.slope(x, np.sign(x)) == pytest.approx(loading, rel=1e-12)
    # the same on CasADi symbols: the step's graph takes this branch
    xs, rs = ca.SX.sym("x"), ca.SX.sym("r")
    fn = ca.Function("s", [xs, rs], [curve.slope(xs, rs)])
    assert float(fn(1.1e-16, -1.0)) == pytest.approx(loading, rel=1e-12)
    assert float(fn(-1e-3, 1.0)) == pytest.approx(unloading, rel=1e-12)


# ---------------------------------------------------------------------------
# TwoSided: a compression curve and a mirrored tension curve
# ---------------------------------------------------------------------------

def _two_sided(**options):
    from symcushion.legs.characteristics import TwoSided
    return TwoSided(Crushable(2e6, 8e3, 1e4), Crushable(1e6, 5e3, 2e3), **options)


def test_two_sided_follows_each_side_and_mirrors_tension():
    curve = _two_sided()
    comp, tens = Crushable(2e6, 8e3, 1e4), Crushable(1e6, 5e3, 2e3)
    for x in (-0.2, -0.01, -1e-3, -1e-5):
        assert curve.force(x) == pytest.approx(comp.force(x), rel=1e-14)
        assert curve.slope(x) == pytest.approx(comp.slope(x), rel=1e-14)
    for x in (1e-5, 1e-3, 0.01, 0.2):
        assert curve.force(x) == pytest.approx(-tens.force(-x), rel=1e-14)
        assert curve.slope(x) == pytest.approx(tens.slope(-x), rel=1e-14)
    assert curve.force(0.0) == 0.0
    assert curve.slope(0.0) == 1e6                    # the tension side's, as documented
    # crushes at 8 kN in compression and 5 kN in tension
    assert curve.force(-0.05) == pytest.approx(-8e3 - 1e4 * (0.05 - 4e-3), rel=1e-13)
    assert curve.force(0.05) == pytest.approx(5e3 + 2e3 * (0.05 - 5e-3), rel=1e-13)
    assert curve.param_names == ("compression.k", "compression.crush_force",
                                 "compression.plateau_slope", "tension.k",
                                 "tension.crush_force", "tension.plateau_slope")


@pytest.mark.parametrize("smooth", [False, True], ids=["exact", "smooth"])
def test_two_sided_slope_equals_jacobian_and_differences(smooth):
    curve = _two_sided(smooth=smooth, unloading=Linear(3e4))
    fn = _jacobian_function(curve)
    h = 1e-7
    for x in (-0.03, -2e-3, -3e-4, 3e-4, 2e-3, 0.03):     # away from the knots ±4, ±5 mm
        for rate in (1.0, -1.0):
            jac, slope = (float(v) for v in fn(x, rate))
            assert slope == pytest.approx(jac, rel=RTOL_SAME)
            fd = (curve.force(x + h, rate) - curve.force(x - h, rate)) / (2 * h)
            assert slope == pytest.approx(fd, rel=RTOL_FD)


def test_two_sided_theta_and_validation():
    from symcushion.legs.characteristics import TwoSided
    curve = _two_sided()
    theta = curve.param_values.copy()
    theta[4] = 7e3                                            # tension crush force
    assert curve.force(0.05, theta=theta) == pytest.approx(7e3 + 2e3 * (0.05 - 7e-3))
    with pytest.raises(ValueError, match="`tension`.*zero force.*preload"):
        TwoSided(Linear(1e5), Linear(1e5, preload=10.0))
    with pytest.raises(ValueError, match="`compression` must be a plain curve"):
        TwoSided(Linear(1e5, unloading=Linear(1e3)), Linear(1e5))
    with pytest.raises(TypeError, match="`tension` must be a Curve"):
        TwoSided(Linear(1e5), 1e5)
