"""Tests of symcushion.layout.vectors: field tables, pack/unpack, CSV names, quaternions."""
import casadi as ca
import numpy as np
import pytest

from symcushion.layout import vectors as layout
from symcushion.layout.vectors import output_columns, output_layout, state_columns, state_layout
from symcushion.scheme.quaternion import (quat_exp, quat_from_axis_angle_np, quat_mul,
    quat_mul_np, quat_to_rot, quat_to_rot_np, tilt, tilt_np)

ROUND_OFF = 1e-14      # a few ulps of O(1) quantities


def _random_quats(rng, n):
    q = rng.normal(size=(n, 4))
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def test_block_sizes_and_reexport():
    import symcushion.layout as sim  # the folder re-exports the layouts of x and y
    assert (layout.BODY_STATE, layout.LEG_STATE, layout.BODY_OUT, layout.LEG_OUT) == (13, 13, 3, 19)
    assert (sim.BODY_STATE, sim.LEG_STATE, sim.BODY_OUT, sim.LEG_OUT) == (13, 13, 3, 19)
    assert sim.MODES == {0: "free", 1: "stick", 2: "slip", 3: "lift-off"}


def test_columns_follow_the_naming_scheme():
    cols = state_columns(3)
    assert len(cols) == 13 + 13 * 3 and len(set(cols)) == len(cols)
    assert cols[:4] == ["body_position_x_m", "body_position_y_m", "body_position_z_m",
                        "body_velocity_x_m_s"]
    assert cols[6:10] == ["body_attitude_w_1", "body_attitude_x_1", "body_attitude_y_1",
                          "body_attitude_z_1"]
    assert cols[13:17] == ["leg0_foot_x_m", "leg0_foot_y_m", "leg0_foot_z_m", "leg0_contact_1"]
    out = output_columns(3)
    assert len(out) == 3 + 19 * 3
    assert out[0] == "body_acceleration_x_m_s2"
    assert out[layout.BODY_OUT + 2 * layout.LEG_OUT + 4] == "leg2_force_z_N"
    assert out[layout.BODY_OUT + 1] == "leg0_mode_1"
    assert out[layout.BODY_OUT + 11:layout.BODY_OUT + 14] == ["leg0_stroke_m", "leg0_beta_rad",
                                                            "leg0_gamma_deflection_rad"]


def test_pack_unpack_roundtrip_numpy_1d_and_2d():
    rng = np.random.default_rng(0)
    lay = state_layout(4)
    x = rng.normal(size=lay.size)
    fields = lay.unpack(x)
    assert fields["foot"].shape == (4, 3) and fields["contact"].shape == (4,)
    np.testing.assert_array_equal(lay.pack(**fields), x)
    X = rng.normal(size=(lay.size, 5))            # columns are steps
    assert lay.legs(X, "force_body").shape == (4, 3, 5)
    assert lay.legs(X, "contact").shape == (4, 5)
    np.testing.assert_array_equal(lay.get(X, "velocity"), X[3:6])
    np.testing.assert_array_equal(lay.get(X, "contact", 2), X[13 + 2 * 13 + 3])


def test_pack_unpack_casadi():
    lay = output_layout(2)
    y = ca.SX.sym("y", lay.size)
    parts = lay.unpack(y)
    assert isinstance(parts["stroke"], list) and len(parts["stroke"]) == 2
    packed = lay.pack(**parts)
    f = ca.Function("f", [y], [packed])
    v = np.arange(lay.size, dtype=float)
    np.testing.assert_array_equal(np.asarray(f(v)).ravel(), v)
    Y = ca.DM(np.arange(lay.size * 3, dtype=float).reshape(lay.size, 3))
    assert lay.get(Y, "beta", 1).shape == (1, 3)


def test_bad_arguments_name_themselves():
    lay = state_layout(2)
    with pytest.raises(ValueError, match="`n_legs`"):
        state_layout(-1)
    with pytest.raises(KeyError, match="stroke"):
        lay.slice("stroke", 0)
    with pytest.raises(IndexError, match="`leg`"):
        lay.slice("foot", 2)
    with pytest.raises(ValueError, match="39 rows"):
        lay.get(np.zeros(5), "position")
    with pytest.raises(ValueError, match="missing"):
        lay.pack(position=np.zeros(3))
    with pytest.raises(ValueError, match="`q`"):
        quat_to_rot_np(np.zeros(3))


def test_rotation_matrices_agree_and_are_orthonormal():
    rng = np.random.default_rng(1)
    q = _random_quats(rng, 20)
    R = quat_to_rot_np(q)
    np.testing.assert_allclose(R @ np.swapaxes(R, 1, 2), np.broadcast_to(np.eye(3), R.shape),
                               atol=ROUND_OFF)
    np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=ROUND_OFF)
    R_ca = np.array([np.asarray(ca.evalf(quat_to_rot(ca.DM(qi)))) for qi in q])
    np.testing.assert_allclose(R_ca, R, atol=ROUND_OFF)
    from scipy.spatial.transform import Rotation
    R_sp = Rotation.from_quat(q[:, [1, 2, 3, 0]]).as_matrix()     # SciPy is scalar-last
    np.testing.assert_allclose(R, R_sp, atol=1e-12)


def test_product_exp_and_axis_angle():
    rng = np.random.default_rng(2)
    a, b = _random_quats(rng, 2)
    ab_ca = np.asarray(quat_mul(ca.DM(a), ca.DM(b))).ravel()
    np.testing.assert_allclose(quat_mul_np(a, b), ab_ca, atol=ROUND_OFF)
    # R(a ⊗ b) = R(a) R(b)
    np.testing.assert_allclose(quat_to_rot_np(quat_mul_np(a, b)),
                               quat_to_rot_np(a) @ quat_to_rot_np(b), atol=1e-13)
    axis = np.array([1.0, 2.0, -2.0]) / 3.0
    angle = 0.7
    q_exp = np.asarray(quat_exp(ca.DM(angle * axis))).ravel()
    np.testing.assert_allclose(q_exp, quat_from_axis_angle_np(axis, angle), atol=ROUND_OFF)
    np.testing.assert_array_equal(np.asarray(quat_exp(ca.DM.zeros(3))).ravel(), [1, 0, 0, 0])
    # a tiny angle takes the series branch and matches the closed form
    tiny = np.asarray(quat_exp(ca.DM(1e-9 * axis))).ravel()
    np.testing.assert_allclose(tiny, quat_from_axis_angle_np(axis, 1e-9), atol=ROUND_OFF)


def test_tilt_of_the_body_axis():
    up = np.array([0.0, 0.0, 1.0])
    angles = np.array([0.0, 0.3, 1.2, 3.0])
    q = quat_from_axis_angle_np(np.array([[0.0, 1.0, 0.0]] * 4), angles)
    np.testing.assert_allclose(tilt_np(q, up), angles, atol=1e-7)   # arccos near 0: √ulp
    t_ca = np.asarray(tilt(ca.DM(q.T), ca.DM(up))).ravel()
    np.testing.assert_allclose(t_ca, angles, atol=1e-7)
