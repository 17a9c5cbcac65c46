"""Rotations on SO(3): hat/vee, exp/log, quaternions, tilt angles and the tilt error.

Conventions (see docs/conventions.md):
- ``R_A_B`` maps vectors expressed in frame B into frame A (orientation of B in A).
- Quaternions are scalar first ``(w, x, y, z)``; ``q_I_H`` rotates head vectors into frame I.
- Frame I has z up, gravity ``(0, 0, -g)`` (``core.constants.gravity_I``).

Every function is written in ``jax.numpy`` and accepts leading batch axes only where stated;
use ``jax.vmap`` for batches.
"""

from __future__ import annotations

import jax.numpy as jnp

_SMALL_ANGLE = 1e-6


def hat(v):
    """Skew-symmetric matrix [v]x such that hat(v) @ w == cross(v, w)."""
    v = jnp.asarray(v)
    z = jnp.zeros_like(v[..., 0])
    return jnp.stack(
        [
            jnp.stack([z, -v[..., 2], v[..., 1]], axis=-1),
            jnp.stack([v[..., 2], z, -v[..., 0]], axis=-1),
            jnp.stack([-v[..., 1], v[..., 0], z], axis=-1),
        ],
        axis=-2,
    )


def vee(M):
    """Inverse of :func:`hat` (uses the skew part of M)."""
    M = jnp.asarray(M)
    return 0.5 * jnp.stack(
        [M[..., 2, 1] - M[..., 1, 2], M[..., 0, 2] - M[..., 2, 0], M[..., 1, 0] - M[..., 0, 1]],
        axis=-1,
    )


def _safe_norm(v):
    """Norm with a finite gradient at zero."""
    sq = jnp.sum(v * v, axis=-1)
    safe = jnp.where(sq > 0.0, sq, 1.0)
    return jnp.where(sq > 0.0, jnp.sqrt(safe), 0.0)


def exp(omega_rad):
    """Rodrigues' formula: rotation matrix of the rotation vector ``omega_rad`` (3,)."""
    omega_rad = jnp.asarray(omega_rad, dtype=jnp.float64)
    theta = _safe_norm(omega_rad)
    small = theta < _SMALL_ANGLE
    theta_s = jnp.where(small, 1.0, theta)
    theta2 = theta * theta
    a = jnp.where(small, 1.0 - theta2 / 6.0, jnp.sin(theta_s) / theta_s)
    b = jnp.where(small, 0.5 - theta2 / 24.0, (1.0 - jnp.cos(theta_s)) / (theta_s * theta_s))
    K = hat(omega_rad)
    eye = jnp.eye(3, dtype=omega_rad.dtype)
    return eye + a[..., None, None] * K + b[..., None, None] * (K @ K)


def log(R):
    """Rotation vector (rad) of a rotation matrix; robust near 0 and near pi."""
    R = jnp.asarray(R, dtype=jnp.float64)
    q = quat_from_matrix(R)
    return quat_log(q)


def quat_log(q_wxyz):
    """Rotation vector of a unit quaternion (shortest rotation, angle in [0, pi])."""
    q = jnp.asarray(q_wxyz, dtype=jnp.float64)
    q = jnp.where(q[..., :1] < 0.0, -q, q)
    v = q[..., 1:]
    s = _safe_norm(v)
    w = q[..., 0]
    angle = 2.0 * jnp.arctan2(s, w)
    small = s < 1e-12
    s_safe = jnp.where(small, 1.0, s)
    w_safe = jnp.where(small, w, 1.0)
    factor = jnp.where(small, 2.0 / w_safe, angle / s_safe)
    return factor[..., None] * v


def quat_normalize(q_wxyz):
    q = jnp.asarray(q_wxyz, dtype=jnp.float64)
    return q / jnp.linalg.norm(q, axis=-1, keepdims=True)


def quat_multiply_components(p, q):
    """Hamilton product p ⊗ q on component tuples ``(w, x, y, z)`` of arrays (or floats).

    The one definition of the product: :func:`quat_multiply` stacks it, and kernels that keep
    quaternions as separate component arrays (structure-of-arrays) use it directly. Pure
    arithmetic, so it also works on NumPy arrays and Python floats.
    """
    pw, px, py, pz = p
    qw, qx, qy, qz = q
    return (pw * qw - px * qx - py * qy - pz * qz,
            pw * qx + px * qw + py * qz - pz * qy,
            pw * qy - px * qz + py * qw + pz * qx,
            pw * qz + px * qy - py * qx + pz * qw)


def quat_multiply(p_wxyz, q_wxyz):
    """Hamilton product p ⊗ q (scalar first), batched over leading axes."""
    p = jnp.asarray(p_wxyz)
    q = jnp.asarray(q_wxyz)
    return jnp.stack(quat_multiply_components(tuple(p[..., i] for i in range(4)),
                                              tuple(q[..., i] for i in range(4))), axis=-1)


def quat_rotate(q_wxyz, v):
    """``R(q) v`` for a unit quaternion, batched, without forming the matrix
    (``v + w t + u × t`` with ``t = 2 u × v``)."""
    q = jnp.asarray(q_wxyz)
    w, u = q[..., :1], q[..., 1:]
    t = 2.0 * jnp.cross(u, v)
    return v + w * t + jnp.cross(u, t)


def quat_conjugate(q_wxyz):
    q = jnp.asarray(q_wxyz)
    return q * jnp.array([1.0, -1.0, -1.0, -1.0])


def quat_exp(omega_rad):
    """Unit quaternion of the rotation vector ``omega_rad``."""
    omega_rad = jnp.asarray(omega_rad, dtype=jnp.float64)
    theta = _safe_norm(omega_rad)
    small = theta < _SMALL_ANGLE
    theta_s = jnp.where(small, 1.0, theta)
    k = jnp.where(small, 0.5 - theta * theta / 48.0, jnp.sin(0.5 * theta_s) / theta_s)
    return jnp.concatenate([jnp.cos(0.5 * theta)[..., None], k[..., None] * omega_rad], axis=-1)


def matrix_from_quat(q_wxyz):
    """Rotation matrix of a quaternion (normalized first)."""
    return matrix_from_unit_quat(quat_normalize(q_wxyz))


def matrix_from_unit_quat(q):
    """Rotation matrix of a quaternion already of unit norm (not normalized again: a hot loop
    that keeps its quaternion unit saves the norm)."""
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return jnp.stack(
        [
            jnp.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
            jnp.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
            jnp.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
        ],
        axis=-2,
    )


def quat_from_matrix(R):
    """Unit quaternion (w >= 0) of a rotation matrix, by Shepperd's branch-free selection."""
    R = jnp.asarray(R, dtype=jnp.float64)
    m00, m11, m22 = R[..., 0, 0], R[..., 1, 1], R[..., 2, 2]
    tr = m00 + m11 + m22
    # Four candidate solutions; pick the numerically largest denominator.
    cands = jnp.stack(
        [
            jnp.stack(
                [1 + tr, R[..., 2, 1] - R[..., 1, 2], R[..., 0, 2] - R[..., 2, 0],
                 R[..., 1, 0] - R[..., 0, 1]], -1),
            jnp.stack(
                [R[..., 2, 1] - R[..., 1, 2], 1 + m00 - m11 - m22, R[..., 0, 1] + R[..., 1, 0],
                 R[..., 0, 2] + R[..., 2, 0]], -1),
            jnp.stack(
                [R[..., 0, 2] - R[..., 2, 0], R[..., 0, 1] + R[..., 1, 0], 1 - m00 + m11 - m22,
                 R[..., 1, 2] + R[..., 2, 1]], -1),
            jnp.stack(
                [R[..., 1, 0] - R[..., 0, 1], R[..., 0, 2] + R[..., 2, 0],
                 R[..., 1, 2] + R[..., 2, 1], 1 - m00 - m11 + m22], -1),
        ],
        axis=-2,
    )
    diag = jnp.stack([1 + tr, 1 + m00 - m11 - m22, 1 - m00 + m11 - m22, 1 - m00 - m11 + m22], -1)
    idx = jnp.argmax(diag, axis=-1)
    q = jnp.take_along_axis(cands, idx[..., None, None], axis=-2)[..., 0, :]
    q = quat_normalize(q)
    return jnp.where(q[..., :1] < 0.0, -q, q)


def _elementary(angle_rad, rows):
    """Rotation about one axis, entry by entry: ``rows`` picks each entry from (0, 1, cos, sin,
    -sin), so the matrix is exact to the rounding of cos and sin at every angle (Rodrigues'
    form rounds differently); batched over the leading axes of ``angle_rad``."""
    a = jnp.asarray(angle_rad, dtype=jnp.float64)
    c, s = jnp.cos(a), jnp.sin(a)
    entries = {0: jnp.zeros_like(a), 1: jnp.ones_like(a), "c": c, "s": s, "-s": -s}
    return jnp.stack([jnp.stack([entries[e] for e in row], -1) for row in rows], -2)


def rot_x(angle_rad):
    """Rotation by ``angle_rad`` about x, shape ``angle_rad.shape + (3, 3)``."""
    return _elementary(angle_rad, ((1, 0, 0), (0, "c", "-s"), (0, "s", "c")))


def rot_y(angle_rad):
    """Rotation by ``angle_rad`` about y, shape ``angle_rad.shape + (3, 3)``."""
    return _elementary(angle_rad, (("c", 0, "s"), (0, 1, 0), ("-s", 0, "c")))


def rot_z(angle_rad):
    """Rotation by ``angle_rad`` about z, shape ``angle_rad.shape + (3, 3)``."""
    return _elementary(angle_rad, (("c", "-s", 0), ("s", "c", 0), (0, 0, 1)))


def matrix_from_rpy(roll, pitch, yaw):
    """``Rz(yaw) Ry(pitch) Rx(roll)`` (aerospace ZYX order) for scalar angles (rad), entry by
    entry: elementwise, so XLA fuses it, and smooth everywhere (trajectories differentiate it)."""
    cr, sr = jnp.cos(roll), jnp.sin(roll)
    cp, sp = jnp.cos(pitch), jnp.sin(pitch)
    cy, sy = jnp.cos(yaw), jnp.sin(yaw)
    return jnp.stack([
        jnp.stack([cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr]),
        jnp.stack([sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr]),
        jnp.stack([-sp, cp * sr, cp * cr]),
    ])


def rpy_from_matrix(R):
    """(roll, pitch, yaw) of ``R = Rz(yaw) Ry(pitch) Rx(roll)`` (one matrix, |pitch| < π/2)."""
    R = jnp.asarray(R, float)
    return jnp.stack([jnp.arctan2(R[2, 1], R[2, 2]), -jnp.arcsin(jnp.clip(R[2, 0], -1.0, 1.0)),
                      jnp.arctan2(R[1, 0], R[0, 0])])


def log_principal(R):
    """Rotation vector of R for rotation angles below π (cheap and smooth; error-state maps).

    θ = atan2(|s|, (tr R − 1)/2) with s = vee(R) = sin θ · axis; exact for θ < π, where error
    states live (differences of nearby rotations). :func:`log` covers θ ≈ π.
    """
    s = vee(R)
    sin_t = _safe_norm(s)
    cos_t = 0.5 * (jnp.trace(R, axis1=-2, axis2=-1) - 1.0)
    theta = jnp.arctan2(sin_t, cos_t)
    small = sin_t < 1e-8
    factor = jnp.where(small, 1.0 + sin_t * sin_t / 6.0, theta / jnp.where(small, 1.0, sin_t))
    return factor[..., None] * s


def orthonormalize(R):
    """Project a near-rotation matrix back onto SO(3) (one Newton–Schulz polar step twice).

    Exact for matrices within ~1e-3 of SO(3); used after each integration step, where the drift
    is ~1e-12, so the result is on SO(3) to rounding.
    """
    R = jnp.asarray(R)
    for _ in range(2):
        R = 1.5 * R - 0.5 * R @ jnp.swapaxes(R, -1, -2) @ R
    return R


def orthonormality_error(R):
    """Frobenius norm of R^T R - I."""
    R = jnp.asarray(R)
    E = jnp.swapaxes(R, -1, -2) @ R - jnp.eye(3)
    return jnp.sqrt(jnp.sum(E * E, axis=(-2, -1)))


def tilt_angles(R_I_H):
    """Tilt angles (Theta_x, Theta_y) of F eq. 3.8–3.9, in rad.

    ``tan Theta_x = [R_IH]_32 / [R_IH]_33``, ``tan Theta_y = [R_IH]_31 / [R_IH]_33``. Row 3 of
    ``R_IH`` is the world up axis expressed in the head frame, so these do not depend on yaw.
    Computed with ``arctan2`` so that they are defined beyond +-90 deg.
    """
    R = jnp.asarray(R_I_H)
    return jnp.stack(
        [jnp.arctan2(R[..., 2, 1], R[..., 2, 2]), jnp.arctan2(R[..., 2, 0], R[..., 2, 2])], -1
    )


def up_in_frame(R_I_B):
    """World up axis e3 expressed in frame B: ``R_IB^T e3`` (row 3 of R_IB)."""
    return jnp.asarray(R_I_B)[..., 2, :]


def angle_between_unit_vectors(a, b, xp=jnp):
    """Angle (rad) between two unit vectors, accurate near 0 and pi (atan2 of |a x b| and a.b).
    ``xp=numpy``: the same formula on NumPy arrays (no compilation per shape)."""
    a = xp.asarray(a)
    b = xp.asarray(b)
    c = xp.cross(a, b)
    norm = _safe_norm(c) if xp is jnp else xp.sqrt(xp.sum(c * c, axis=-1))
    return xp.arctan2(norm, xp.sum(a * b, axis=-1))


def tilt_error_rad(R_I_H_true, R_I_H_est):
    """Tilt error: angle between the true and estimated gravity direction in the head frame.

    docs/conventions.md: ``arccos(<R_IH^T e3, R̂_IH^T e3>)``; yaw never enters. Radians.
    """
    return angle_between_unit_vectors(up_in_frame(R_I_H_true), up_in_frame(R_I_H_est))


def tilt_error_deg(R_I_H_true, R_I_H_est):
    return jnp.degrees(tilt_error_rad(R_I_H_true, R_I_H_est))


def quat_from_rpy_radians(roll, pitch, yaw):
    """Quaternion of R = Rz(yaw) Ry(pitch) Rx(roll) (aerospace ZYX order)."""
    qx = quat_exp(jnp.array([1.0, 0.0, 0.0]) * roll)
    qy = quat_exp(jnp.array([0.0, 1.0, 0.0]) * pitch)
    qz = quat_exp(jnp.array([0.0, 0.0, 1.0]) * yaw)
    return quat_multiply(qz, quat_multiply(qy, qx))


def roll_pitch_from_up(up_B, xp=jnp):
    """Roll and pitch (ZYX convention, rad) of a frame B from the world up axis expressed in B
    (``xp=numpy``: on NumPy arrays).

    For R_IB = Rz(yaw) Ry(pitch) Rx(roll): up_B = (-sin p, sin r cos p, cos r cos p).
    """
    u = xp.asarray(up_B)
    roll = xp.arctan2(u[..., 1], u[..., 2])
    pitch = xp.arctan2(-u[..., 0], xp.sqrt(u[..., 1] ** 2 + u[..., 2] ** 2))
    return roll, pitch


# --- component-tuple forms (structure-of-arrays kernels: each component a separate array) ---

def quat_exp_components(vx, vy, vz):
    """:func:`quat_exp` on the components of the rotation vector (arrays of any one shape, or
    floats): returns ``(w, x, y, z)``, the same formula, for kernels that keep quaternions as
    separate component arrays (:func:`quat_multiply_components`)."""
    th2 = vx * vx + vy * vy + vz * vz
    theta = jnp.where(th2 > 0.0, jnp.sqrt(jnp.where(th2 > 0.0, th2, 1.0)), 0.0)
    small = theta < _SMALL_ANGLE
    theta_s = jnp.where(small, 1.0, theta)
    k = jnp.where(small, 0.5 - theta * theta / 48.0, jnp.sin(0.5 * theta_s) / theta_s)
    return jnp.cos(0.5 * theta), k * vx, k * vy, k * vz


def quat_rotate_components(q, v):
    """:func:`quat_rotate` on component tuples: ``R(q) v`` for a unit ``q = (w, x, y, z)`` and
    ``v = (vx, vy, vz)`` (``v + w t + u × t``, ``t = 2 u × v``). Pure arithmetic (NumPy, JAX or
    floats)."""
    w, ux, uy, uz = q
    tx = 2.0 * (uy * v[2] - uz * v[1])
    ty = 2.0 * (uz * v[0] - ux * v[2])
    tz = 2.0 * (ux * v[1] - uy * v[0])
    return (v[0] + w * tx + (uy * tz - uz * ty), v[1] + w * ty + (uz * tx - ux * tz),
            v[2] + w * tz + (ux * ty - uy * tx))


def quat_normalize_components(q):
    """A quaternion given as a component tuple divided by its norm. Pure arithmetic except the
    square root (JAX)."""
    n = jnp.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    return tuple(c / n for c in q)
