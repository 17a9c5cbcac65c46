"""Group laws and round trips of verticality.core.so3 (property tests)."""

import jax.numpy as jnp
import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from verticality.core import so3

finite = st.floats(-3.0, 3.0, allow_nan=False)
vec3 = st.tuples(finite, finite, finite).map(np.array)
quat = st.tuples(finite, finite, finite, finite).filter(
    lambda q: np.linalg.norm(q) > 1e-3).map(lambda q: np.array(q) / np.linalg.norm(q))

settings.register_profile("ci", max_examples=60, deadline=None)
settings.load_profile("ci")


@given(vec3)
def test_hat_vee_round_trip_and_cross(v):
    w = np.array([0.3, -1.2, 0.7])
    np.testing.assert_allclose(so3.vee(so3.hat(v)), v, atol=1e-15)
    np.testing.assert_allclose(so3.hat(v) @ w, np.cross(v, w), atol=1e-12)


@given(vec3)
def test_exp_is_rotation_and_log_inverts(v):
    R = so3.exp(v)
    assert float(so3.orthonormality_error(R)) < 1e-12
    assert abs(float(jnp.linalg.det(R)) - 1.0) < 1e-12
    theta = np.linalg.norm(v)
    if theta < np.pi - 1e-6:
        np.testing.assert_allclose(so3.log(R), v, atol=1e-9)


@given(vec3, vec3)
def test_exp_composition_matches_quaternion_product(a, b):
    R = so3.exp(a) @ so3.exp(b)
    q = so3.quat_multiply(so3.quat_exp(a), so3.quat_exp(b))
    np.testing.assert_allclose(so3.matrix_from_quat(q), R, atol=1e-12)


@given(quat)
def test_quaternion_matrix_round_trip(q):
    q2 = so3.quat_from_matrix(so3.matrix_from_quat(q))
    # q and -q are the same rotation
    assert min(np.linalg.norm(q2 - q), np.linalg.norm(q2 + q)) < 1e-9


@given(quat, quat)
def test_inverse_and_associativity(p, q):
    r = np.array([0.5, 0.5, -0.5, 0.5])
    lhs = so3.quat_multiply(so3.quat_multiply(p, q), r)
    rhs = so3.quat_multiply(p, so3.quat_multiply(q, r))
    np.testing.assert_allclose(lhs, rhs, atol=1e-12)
    ident = so3.quat_multiply(p, so3.quat_conjugate(p))
    np.testing.assert_allclose(ident, [1, 0, 0, 0], atol=1e-12)


@given(finite, vec3)
def test_tilt_error_ignores_yaw(yaw, v):
    R = so3.exp(v)
    R_yawed = so3.rot_z(yaw) @ R
    assert float(so3.tilt_error_rad(R, R_yawed)) < 1e-7


def test_tilt_angles_single_axis():
    th = 0.3
    np.testing.assert_allclose(so3.tilt_angles(so3.rot_x(th)), [th, 0.0], atol=1e-15)
    np.testing.assert_allclose(so3.tilt_angles(so3.rot_y(th)), [0.0, -th], atol=1e-15)
    np.testing.assert_allclose(float(so3.tilt_error_deg(so3.rot_x(th), np.eye(3))),
                               np.degrees(th), rtol=1e-12)


def test_orthonormalize_repairs_drift():
    R = so3.exp(np.array([0.4, -0.2, 1.0])) + 1e-6 * np.arange(9.0).reshape(3, 3)
    assert float(so3.orthonormality_error(so3.orthonormalize(R))) < 1e-14


def test_roll_pitch_from_up():
    q = so3.quat_from_rpy_radians(0.2, -0.4, 1.3)
    roll, pitch = so3.roll_pitch_from_up(so3.up_in_frame(so3.matrix_from_quat(q)))
    np.testing.assert_allclose([roll, pitch], [0.2, -0.4], atol=1e-12)


@given(finite)
def test_rotations_about_one_axis_are_the_hand_written_matrices_and_exp(angle):
    c, s = np.cos(angle), np.sin(angle)
    want = {"x": [[1, 0, 0], [0, c, -s], [0, s, c]], "y": [[c, 0, s], [0, 1, 0], [-s, 0, c]],
            "z": [[c, -s, 0], [s, c, 0], [0, 0, 1]]}
    for axis, rot in (("x", so3.rot_x), ("y", so3.rot_y), ("z", so3.rot_z)):
        assert np.array_equal(np.asarray(rot(angle)), np.array(want[axis], float))
        e = np.eye(3)["xyz".index(axis)]
        np.testing.assert_allclose(rot(angle), so3.exp(angle * e), atol=1e-15)


def test_rotations_about_one_axis_batch_over_the_angles():
    angles = np.linspace(-3.0, 3.0, 12).reshape(3, 4)
    R = np.asarray(so3.rot_y(angles))
    assert R.shape == (3, 4, 3, 3)
    np.testing.assert_array_equal(R[2, 1], np.asarray(so3.rot_y(angles[2, 1])))


@given(st.floats(-3.0, 3.0), st.floats(-1.5, 1.5), st.floats(-3.0, 3.0))
def test_matrix_from_rpy_is_the_zyx_product_and_rpy_from_matrix_inverts_it(roll, pitch, yaw):
    R = so3.matrix_from_rpy(roll, pitch, yaw)
    np.testing.assert_allclose(R, so3.rot_z(yaw) @ so3.rot_y(pitch) @ so3.rot_x(roll), atol=1e-15)
    np.testing.assert_allclose(R, so3.matrix_from_quat(so3.quat_from_rpy_radians(roll, pitch, yaw)),
                               atol=1e-14)
    np.testing.assert_allclose(so3.rpy_from_matrix(R), [roll, pitch, yaw], atol=1e-8)
