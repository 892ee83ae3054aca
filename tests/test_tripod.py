"""Tests of ``symcushion.legs.tripod``: the inverted-tripod leg's force P = Jᵀf and D_p.

What is checked, and against what:

* ``tripod_stiffness`` (``casadi.jacobian``) against fourth-order central
  differences of ``tripod_force`` at loaded poses with nonlinear curves, on
  both branches, away from the curves' kinks.
* D_p at rest against the hand derivation (``rest_stiffness_closed_form``)
  and against this file's own NumPy gradients of the strokes.
* The static truss, solved by hand in NumPy from the equilibrium of the
  massless primary (axial balance of the piston, moments about h₁): one
  Apollo-like leg under a vertical load, and a four-legged lander resting on
  level ground with its feet held where they touched.
* Conservation: D_p symmetric for elastic curves and no work around a
  closed 2 cm foot loop; the hinged strut's (2.1) does work on the same loop.
* Singular geometry refused with a ValueError naming the fix; branch
  selection by the foot velocity; the leg-scheme interface.
"""
from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import brentq

from symcushion import HingedStrut
from symcushion.legs.characteristics import Crushable, GasSpring, Linear, TwoSided
from symcushion.legs.tripod import SINGULAR_ANGLE, InvertedTripod

#: AD stiffness vs central differences, relative to |D_p| (Frobenius).
RTOL_FD = 1e-7
#: Fourth-order central differences with step FD_STEP (m): the curves are
#: linear between their kinks and the geometry bends on the scale of the
#: leg (≈ 1 m), so truncation is ≈ (1e-4)⁴ and round-off ≈ eps|P|/(h|D_p|)
#: ≈ 1e-12.
FD_STEP = 1e-4
FD_OFFSETS = (2.0, 1.0, -1.0, -2.0)
FD_WEIGHTS = np.array([-1.0, 8.0, -8.0, 1.0]) / 12.0
#: A pose is "away from kinks" if every stroke is this far from each kink (m).
KINK_MARGIN = 1e-3
#: Hand closed form at rest vs AD, relative.
RTOL_REST = 1e-10
#: The truss and the lander: forces relative to the load, strokes in m.
RTOL_TRUSS = 1e-9
ATOL_STROKE = 1e-9
#: Symmetry of D_p, relative to |D_p|: round-off of a few hundred operations.
RTOL_SYMMETRY = 1e-12
#: Points of the trapezoid rule around the loop: exact to round-off for a
#: smooth periodic integrand well below this count.
LOOP_POINTS = 256
LOOP_RADIUS = 0.01                     # m: a loop 2 cm across

#: An Apollo-like leg in body axes (z up, m): the primary from an upper
#: hardpoint out and down to the foot; the secondaries from the stage's
#: lower corners to the pin 1.9 m down the primary.
APOLLO = dict(h1=(2.0, 0.0, 1.0), h2=(1.9, 1.0, -0.6), h3=(1.9, -1.0, -0.6),
              foot=(3.6, 0.0, -1.4), outer_length=1.9)


def crushing_curves(smooth=False):
    """Crushable primary (unloading almost free), secondaries crushing both ways."""
    primary = Crushable(1e6, 2e4, 5e4, unloading=Linear(1e5), smooth=smooth)
    secondary = TwoSided(Crushable(3e6, 1.5e4, 2e4), Crushable(3e6, 1e4, 2e4),
                         unloading=Linear(2e5), smooth=smooth)
    return dict(primary=primary, secondary2=secondary, secondary3=secondary)


def gas_curves():
    """A gas-spring primary and smooth two-sided secondaries: nonlinear everywhere."""
    primary = GasSpring(2e5, 5e-3, 2e-3, 1.3, unloading=GasSpring(1.5e5, 5e-3, 2e-3, 1.2))
    secondary = TwoSided(Crushable(3e6, 1.5e4, 2e4), Crushable(2e6, 1e4, 2e4), smooth=True)
    return dict(primary=primary, secondary2=secondary, secondary3=secondary)


#: Strokes (m) where each set's curves bend: the knees of the crushables
#: (−F_c/k, F_t/k) and the switch between the sides of a TwoSided curve.
KINKS = dict(crushing=[0.0, -2e4 / 1e6, -1.5e4 / 3e6, 1e4 / 3e6],
             gas=[0.0, -1.5e4 / 3e6, 1e4 / 2e6])


def linear_curves(k=(2e5, 1e6, 7e5)):
    return dict(primary=Linear(k[0]), secondary2=Linear(k[1]), secondary3=Linear(k[2]))


def make_leg(curves, **geometry):
    return InvertedTripod(**dict(APOLLO, **geometry), **curves)


# --------------------------------------------------------------------------
# Independent reference: the truss in NumPy
# --------------------------------------------------------------------------

def ref_geometry(spec, r):
    """L, e, Q, secondary lengths l_k and unit vectors u_k (h_k → Q)."""
    h1 = np.asarray(spec["h1"], float)
    d = np.asarray(r, float) - h1
    L = np.linalg.norm(d)
    e = d / L
    Q = h1 + spec["outer_length"] * e
    spans = [Q - np.asarray(spec[k], float) for k in ("h2", "h3")]
    lengths = [np.linalg.norm(s) for s in spans]
    return L, e, Q, lengths, [s / n for s, n in zip(spans, lengths)]


def ref_strokes(spec, r):
    L, _, _, l, _ = ref_geometry(spec, r)
    L0, _, _, l0, _ = ref_geometry(spec, spec["foot"])
    return np.array([L - L0, l[0] - l0[0], l[1] - l0[1]])


def ref_gradients(spec, r):
    """Rows ∂q_i/∂r by hand: e, and (ℓ_o/L)(I − eeᵀ)u_k since Q = h₁ + ℓ_o e."""
    L, e, _, _, u = ref_geometry(spec, r)
    across = np.eye(3) - np.outer(e, e)
    return np.array([e] + [spec["outer_length"] / L * across @ uk for uk in u])


def _truss_rows(spec, r):
    """The three equilibrium equations of the massless primary, as matrices.

    Forces on the primary: F from the obstacle at the foot, −T_k u_k from
    secondary k at the pin (T_k > 0 in tension pulls Q towards h_k), and the
    joint's reaction at h₁. The piston's axial balance gives e·F = S (S > 0:
    the primary pulls the foot in); moments about h₁, on two axes b ⊥ e
    (about e both arms vanish), give b·((r − h₁) × F) = Σ T_k b·((Q − h₁) × u_k).
    Returns (A_F, A_f) with A_F F = A_f (S, T₂, T₃).
    """
    h1 = np.asarray(spec["h1"], float)
    _, e, Q, _, u = ref_geometry(spec, r)
    b1 = np.cross(e, [0.3, -0.5, 0.8])
    b1 /= np.linalg.norm(b1)
    b2 = np.cross(e, b1)
    arm_foot, arm_pin = np.asarray(r, float) - h1, Q - h1
    A_F = np.array([e, np.cross(b1, arm_foot), np.cross(b2, arm_foot)])  # b·(a×F) = (b×a)·F
    A_f = np.zeros((3, 3))
    A_f[0, 0] = 1.0
    for j, b in enumerate((b1, b2), start=1):
        A_f[j, 1:] = [b @ np.cross(arm_pin, uk) for uk in u]
    return A_F, A_f


def truss_element_forces(spec, r, F):
    """(S, T₂, T₃) that hold the foot force F at pose r (N)."""
    A_F, A_f = _truss_rows(spec, r)
    return np.linalg.solve(A_f, A_F @ F)


def truss_foot_force(spec, r, f):
    """The foot force F held by element forces f = (S, T₂, T₃) at pose r (N)."""
    A_F, A_f = _truss_rows(spec, r)
    return np.linalg.solve(A_F, A_f @ f)


def curve_forces(curves, q, rates=(0.0, 0.0, 0.0)):
    return np.array([curves[n].force(x, rate) for n, x, rate in
                     zip(("primary", "secondary2", "secondary3"), q, rates)])


# --------------------------------------------------------------------------
# Stiffness
# --------------------------------------------------------------------------

LOADED = [(0.0, 0.0, 0.15), (0.05, 0.03, 0.25), (-0.04, -0.06, 0.35), (0.08, -0.02, 0.1),
          (-0.1, 0.05, 0.2)]


def central_differences(leg, r, v):
    cols = []
    for i in range(3):
        step = np.zeros(3)
        step[i] = FD_STEP
        cols.append(sum(w * leg.force(r + o * step, v) for o, w in zip(FD_OFFSETS, FD_WEIGHTS))
                    / FD_STEP)
    return np.array(cols).T


@pytest.mark.parametrize("name", ["crushing", "gas"])
@pytest.mark.parametrize("v", [(0.0, 0.0, 1.0), (0.0, 0.0, -1.0), (0.3, -0.2, 0.1)])
def test_stiffness_matches_central_differences(name, v):
    """On the branch v selects; the stencil must not cross a kink or a branch switch."""
    leg = make_leg(dict(crushing=crushing_curves, gas=gas_curves)[name]())
    for d in LOADED:
        r = leg.foot + np.array(d)
        q, rates = leg.strokes(r), ref_gradients(APOLLO, r) @ np.asarray(v)
        assert min(abs(x - k) for x in q for k in KINKS[name]) > KINK_MARGIN, (d, q)
        assert np.all(np.abs(rates) > 1e-2), (d, rates)      # the rate keeps its sign
        Dp, fd = leg.stiffness(r, v), central_differences(leg, r, v)
        assert np.linalg.norm(Dp) > 1e4
        err = np.linalg.norm(Dp - fd) / np.linalg.norm(Dp)
        assert err < RTOL_FD, (d, v, err)


@pytest.mark.parametrize("seed", range(6))
def test_rest_stiffness_matches_hand_derivation(seed):
    """Apollo's leg and random non-singular legs with linear elements."""
    rng = np.random.default_rng(seed)
    spec = dict(APOLLO)
    if seed:
        spec = dict(h1=rng.normal(0, 1, 3), h2=rng.normal(0, 1, 3), h3=rng.normal(0, 1, 3),
                    foot=rng.normal(0, 1, 3) + (0, 0, -2), outer_length=0.0)
        spec["outer_length"] = rng.uniform(0.3, 0.8) * np.linalg.norm(
            spec["foot"] - spec["h1"])
    k = rng.uniform(1e4, 1e6, 3)
    try:
        leg = InvertedTripod(**spec, **linear_curves(k))
    except ValueError as err:                         # a random singular leg
        assert "singular" in str(err)
        pytest.skip(str(err))
    Dp = leg.stiffness(leg.rest_foot)
    hand = leg.rest_stiffness_closed_form()
    assert np.linalg.norm(Dp - hand) <= RTOL_REST * np.linalg.norm(hand)
    grads = ref_gradients(spec, spec["foot"])                 # this file's own ∂q/∂r
    ref = sum(ki * np.outer(g, g) for ki, g in zip(k, grads))
    assert np.linalg.norm(hand - ref) <= RTOL_REST * np.linalg.norm(ref)
    assert np.all(np.linalg.eigvalsh(Dp) > 0)


def test_rest_closed_form_refuses_a_preload():
    leg = make_leg(dict(linear_curves(), secondary2=Linear(1e6, preload=50.0)))
    with pytest.raises(ValueError, match="`secondary2` carries 50 N at rest"):
        leg.rest_stiffness_closed_form()


# --------------------------------------------------------------------------
# Statics: the truss by hand
# --------------------------------------------------------------------------

def pose_under(leg, F, r=None, iterations=30):
    """Newton on P(r) = F with the module's D_p (the module's pose)."""
    r = leg.rest_foot.copy() if r is None else r
    for _ in range(iterations):
        residual = leg.force(r) - F
        if np.linalg.norm(residual) < 1e-12 * np.linalg.norm(F):
            return r
        r = r - np.linalg.solve(leg.stiffness(r), residual)
    raise AssertionError(f"Newton did not converge: residual {residual}")


@pytest.mark.parametrize("load", [5e3, 2.5e4])
def test_single_leg_truss_under_a_vertical_load(load):
    """Element forces and strokes at the pose that holds (0, 0, load)."""
    curves = dict(primary=Crushable(1e6, 2e4, 5e4), secondary2=Linear(8e5),
                  secondary3=Linear(5e5))
    leg = make_leg(curves)
    F = np.array([0.0, 0.0, load])
    r = pose_under(leg, F)
    q_hand = ref_strokes(APOLLO, r)
    f_truss = truss_element_forces(APOLLO, r, F)
    # the module's pose must be the truss's: curves at the hand strokes
    # give the forces the truss needs for this load
    np.testing.assert_allclose(curve_forces(curves, q_hand), f_truss, rtol=0,
                               atol=RTOL_TRUSS * load)
    np.testing.assert_allclose(leg.forces(r), f_truss, rtol=0, atol=RTOL_TRUSS * load)
    np.testing.assert_allclose(leg.strokes(r), q_hand, rtol=0, atol=ATOL_STROKE)
    assert q_hand[0] < 0                              # the primary shortens under load
    if load > 2e4:
        assert q_hand[0] < -2e4 / 1e6                 # and crushes past 20 kN


def test_primary_is_in_equilibrium_about_its_joint():
    """P from (T1) with the module's element forces satisfies the truss equations."""
    leg = make_leg(crushing_curves())
    for d in LOADED:
        r = leg.foot + np.array(d)
        P, f = leg.force(r), leg.forces(r)
        np.testing.assert_allclose(truss_foot_force(APOLLO, r, f), P, rtol=0,
                                   atol=1e-12 * np.linalg.norm(f))


def azimuth(angle):
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def test_four_legged_lander_rests_on_level_ground():
    """Body lowered by d with its feet held where they touched (friction): 4 P_z = m g.

    The module solves d by Newton with its own D_p; the hand model by
    bracketing on the truss's foot forces.
    """
    m, g = 7000.0, 1.62                              # an Apollo LM on the Moon
    curves = dict(primary=Crushable(2e5, 2e4, 5e4), secondary2=TwoSided(
        Crushable(3e6, 1.5e4), Crushable(3e6, 1e4)), secondary3=TwoSided(
        Crushable(3e6, 1.5e4), Crushable(3e6, 1e4)))
    rotations = [azimuth(np.pi / 4 + i * np.pi / 2) for i in range(4)]
    specs = [{k: (R @ np.asarray(v, float) if k != "outer_length" else v)
              for k, v in APOLLO.items()} for R in rotations]
    legs = [InvertedTripod(**spec, **curves) for spec in specs]
    up = np.array([0.0, 0.0, 1.0])                   # body down = feet up in body axes

    def module_forces(d):
        return [leg.force(leg.rest_foot + d * up) for leg in legs]

    d = 0.0
    for _ in range(30):
        excess = sum(P[2] for P in module_forces(d)) - m * g
        if abs(excess) < 1e-12 * m * g:
            break
        d -= excess / sum(leg.stiffness(leg.rest_foot + d * up)[2, 2] for leg in legs)
    else:
        raise AssertionError(f"Newton on the height did not converge: {excess} N left")

    def hand_forces(dd):
        return [truss_foot_force(spec, np.asarray(spec["foot"]) + dd * up,
                                 curve_forces(curves, ref_strokes(spec, np.asarray(spec["foot"])
                                                                  + dd * up)))
                for spec in specs]

    d_hand = brentq(lambda dd: sum(F[2] for F in hand_forces(dd)) - m * g, 0.0, 0.2,
                    xtol=1e-15, rtol=4 * np.finfo(float).eps)
    assert d == pytest.approx(d_hand, abs=ATOL_STROKE)
    for leg, spec, P, F in zip(legs, specs, module_forces(d), hand_forces(d_hand)):
        np.testing.assert_allclose(P, F, rtol=0, atol=RTOL_TRUSS * m * g)
        np.testing.assert_allclose(leg.strokes(leg.rest_foot + d * up),
                                   ref_strokes(spec, np.asarray(spec["foot"]) + d_hand * up),
                                   rtol=0, atol=ATOL_STROKE)
    total = sum(module_forces(d))
    np.testing.assert_allclose(total, [0.0, 0.0, m * g], rtol=0, atol=RTOL_TRUSS * m * g)
    assert 0 < d < 0.2


# --------------------------------------------------------------------------
# Conservation
# --------------------------------------------------------------------------

@pytest.mark.parametrize("curves", [linear_curves, gas_curves, crushing_curves],
                         ids=["linear", "gas", "crushing"])
def test_stiffness_is_symmetric(curves):
    leg = make_leg(curves())
    for d in LOADED:
        for v in [(0.0, 0.0, 1.0), (0.0, 0.0, -1.0)]:
            Dp = leg.stiffness(leg.foot + np.array(d), v)
            assert np.linalg.norm(Dp - Dp.T) <= RTOL_SYMMETRY * np.linalg.norm(Dp)


def loop_work(force, centre):
    """∮ P·dr around a circle of LOOP_RADIUS about ``centre`` (J), trapezoid rule."""
    a = np.array([1.0, 1.0, 0.0]) / np.sqrt(2)
    b = np.array([-0.3, 0.3, 1.0])
    b -= (b @ a) * a
    b /= np.linalg.norm(b)
    theta = 2 * np.pi * np.arange(LOOP_POINTS) / LOOP_POINTS
    work = 0.0
    for t in theta:
        r = centre + LOOP_RADIUS * (np.cos(t) * a + np.sin(t) * b)
        dr = LOOP_RADIUS * (-np.sin(t) * a + np.cos(t) * b)
        work += force(r) @ dr
    return work * 2 * np.pi / LOOP_POINTS


def loop_scale(force, centre):
    """|P|·perimeter at the centre (J): the size of the work a loop could do."""
    return np.linalg.norm(force(centre)) * 2 * np.pi * LOOP_RADIUS


def loop_numbers():
    """Work around the loop: the tripod (gas primary) and a hinged strut (2.1)."""
    leg = make_leg(gas_curves())
    centre = leg.foot + np.array([0.03, 0.02, 0.15])
    tripod = loop_work(leg.force, centre), loop_scale(leg.force, centre)
    L0 = np.linalg.norm(np.subtract(APOLLO["foot"], APOLLO["h1"]))
    strut = HingedStrut(hinge=APOLLO["h1"], e0=np.subtract(APOLLO["foot"], APOLLO["h1"]),
                        en=(0.3, 0.2, -1.0), length=L0, S=Linear(2e5),
                        M_beta=Linear(3e5), M_gamma=Linear(3e5))
    centre = strut.rest_foot + np.array([0.03, 0.02, 0.15])
    hinged = loop_work(strut.force, centre), loop_scale(strut.force, centre)
    return tripod, hinged


def test_no_work_around_a_closed_loop_unlike_the_hinged_strut():
    (w_tripod, s_tripod), (w_strut, s_strut) = loop_numbers()
    assert abs(w_tripod) < 1e-11 * s_tripod, (w_tripod, s_tripod)
    assert abs(w_strut) > 1e-5 * s_strut, (w_strut, s_strut)


# --------------------------------------------------------------------------
# Singular geometry, input validation
# --------------------------------------------------------------------------

E0 = np.subtract(APOLLO["foot"], APOLLO["h1"]) / np.linalg.norm(
    np.subtract(APOLLO["foot"], APOLLO["h1"]))
Q0 = np.asarray(APOLLO["h1"]) + APOLLO["outer_length"] * E0


@pytest.mark.parametrize("geometry, name, fix", [
    (dict(h3=2 * Q0 - np.asarray(APOLLO["h2"])), "collinear", "move `h2` or `h3` sideways"),
    (dict(h2=Q0 - 0.8 * E0), "secondary 2 lies along", "move `h2` off"),
    (dict(h3=Q0 + 0.3 * E0 + [0.0, 0.0, 1e-3]), "secondary 3 lies along", "move `h3` off"),
    (dict(h2=(1.9, 0.0, -0.6), h3=(3.0, 0.0, 0.8)), "one plane", "out of that plane"),
    (dict(h2=Q0), "zero length", "move `h2` off the primary"),
    (dict(outer_length=3.0), "`outer_length`", "lies between `h1` and the foot"),
    (dict(outer_length=-1.0), "`outer_length` must be positive", "give a value > 0"),
    (dict(foot=APOLLO["h1"]), "`foot`", "put the foot away from `h1`"),
    (dict(h2=(1.9, np.nan, -0.6)), "`h2` must be finite", "give finite"),
    (dict(h1=(1.0, 2.0)), "`h1` must have shape (3,)", "give (3,)"),
])
def test_singular_or_bad_geometry_is_refused(geometry, name, fix):
    with pytest.raises(ValueError) as info:
        make_leg(linear_curves(), **geometry)
    message = str(info.value)
    assert name in message and fix in message, message


def test_check_pose_reports_the_smallest_angle():
    leg = make_leg(linear_curves())
    angles = leg.pose_angles(leg.rest_foot)
    assert set(angles) == {"secondaries", "secondary2_primary", "secondary3_primary", "plane"}
    assert leg.check_pose(leg.rest_foot) == min(angles.values()) > SINGULAR_ANGLE
    # swing the foot so that the primary's axis points at h2 through Q: u₂ ∥ e_S
    h1, h2 = np.asarray(APOLLO["h1"]), np.asarray(APOLLO["h2"])
    towards = (h1 - h2) / np.linalg.norm(h1 - h2)
    foot = h1 + leg.length * towards
    assert leg.check_pose(foot) < 1e-7
    near = h1 + leg.length * (towards + np.array([0.0, 0.0, 0.02]))
    assert 0 < leg.check_pose(near) < SINGULAR_ANGLE
    with pytest.raises(ValueError, match="`r`.*at the hardpoint h1"):
        leg.force(APOLLO["h1"])
    with pytest.raises(TypeError, match="`secondary3` must be a characteristic curve"):
        make_leg(dict(linear_curves(), secondary3=1e5))


# --------------------------------------------------------------------------
# Branches and the interface
# --------------------------------------------------------------------------

def test_branch_selection_follows_each_elements_rate():
    """Each element on its loading branch iff q_i·(∂q_i/∂r · v) ≥ 0, as in the strut."""
    curves = crushing_curves()
    leg = make_leg(curves)
    r = leg.foot + np.array([0.05, 0.03, 0.25])
    q, grads = ref_strokes(APOLLO, r), ref_gradients(APOLLO, r)
    seen = set()
    for v in [(0, 0, 1), (0, 0, -1), (1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0),
              (0.2, -1, 0.1), (-0.2, 1, -0.1)]:
        rates = grads @ np.asarray(v, float)
        loading = q * rates >= 0
        seen.update((i, bool(b)) for i, b in enumerate(loading))
        f = np.array([curve.force(x) if b else curve.unloading.force(x) for curve, x, b in
                      zip(curves.values(), q, loading)])
        np.testing.assert_allclose(leg.forces(r, v), f, rtol=1e-13, atol=1e-9)
        np.testing.assert_allclose(leg.force(r, v), grads.T @ f, rtol=1e-12, atol=1e-8)
    assert seen == {(i, b) for i in range(3) for b in (True, False)}   # every branch met
    # at rest every element loads whatever the rate: the rest stiffness stays
    for v in [(0, 0, 1), (0, 0, -1), (1, 1, 1)]:
        np.testing.assert_allclose(leg.stiffness(leg.rest_foot, v),
                                   make_leg(linear_curves((1e6, 3e6, 3e6))).stiffness(
                                       leg.rest_foot), rtol=1e-12)


def test_leg_scheme_interface():
    curves = dict(primary=Linear(2e5, tunable=True), secondary2=TwoSided(
        Crushable(3e6, 1.5e4), Crushable(3e6, 1e4), tunable=True), secondary3=Linear(7e5))
    leg = make_leg(curves)
    assert leg.param_names == ("primary.k", "primary.preload", "secondary2.compression.k",
                               "secondary2.compression.crush_force",
                               "secondary2.compression.plateau_slope", "secondary2.tension.k",
                               "secondary2.tension.crush_force",
                               "secondary2.tension.plateau_slope")
    np.testing.assert_array_equal(leg.param_values, [2e5, 0, 3e6, 1.5e4, 0, 3e6, 1e4, 0])
    fns = leg.functions()
    for scheme in ("strut", "tripod"):
        assert fns[f"{scheme}_force"].name() == f"{scheme}_force"
        assert fns[f"{scheme}_force"].name_in() == ["r", "v", "p"]
        assert fns[f"{scheme}_stiffness"].name_out() == ["Dp"]
        assert fns[f"{scheme}_geometry"].name_out() == ["L", "delta_S", "e_S", "Q",
                                                        "stroke_secondary"]
    r = leg.foot + np.array([0.02, -0.01, 0.2])
    p = leg.param_values * np.array([2, 1, 1, 1, 1, 1, 0.5, 1])
    assert float(fns["strut_geometry"](r)[1]) == pytest.approx(leg.strokes(r)[0], abs=0)
    np.testing.assert_array_equal(np.asarray(fns["strut_force"](r, [0, 0, 1], p)),
                                  np.asarray(fns["tripod_force"](r, [0, 0, 1], p)))
    f = leg.forces(r, (0, 0, 1), p)
    assert f[0] == pytest.approx(2 * 2e5 * leg.strokes(r)[0], rel=1e-13)
    assert f[1] == pytest.approx(5e3, rel=1e-13)   # tension crush force halved by p
    # a crushable secondary keeps a set under the memory law; linear elements keep none
    assert np.array_equal(leg.hinge, APOLLO["h1"]) and leg.axial_state is True
    assert make_leg(dict(primary=Linear(2e5), secondary2=Linear(7e5),
                         secondary3=Linear(7e5))).axial_state is False
    assert leg.length == pytest.approx(np.linalg.norm(np.subtract(APOLLO["foot"], APOLLO["h1"])),
                                       rel=1e-15)
    with pytest.raises(ValueError, match="`p` must have 8 entries"):
        leg.force(r, p=[1.0])
