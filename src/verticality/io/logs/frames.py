"""The frames of the logs and ours (docs/logs.md, Conventions).

Ours (docs/tilt.md): the sensor frame S of the samples and an Earth frame E with z up; roll and
pitch are the ZYX angles of ``R_E_S``. ROS (REP-103, REP-145) is already that: an ``Imu`` message's
samples are in its ``frame_id`` (x forward, y left, z up on a body: FLU) and its orientation maps
that frame into a z-up world (ENU), so both are taken as they are.

PX4 writes body vectors in FRD (x forward, y right, z down) and attitudes as ``q`` FRD → NED
(north, east, down). A turn of π about x takes FRD to FLU and NED to NWU (north, west, up: z up):
vectors change the sign of y and z, and the attitude becomes ``q_NWU_FLU = r ⊗ q_NED_FRD ⊗ r*``
with ``r`` that turn. For ``R = Rz(ψ) Ry(θ) Rx(φ)`` the turn keeps φ and negates θ and ψ: our roll
is PX4's roll, our pitch is minus PX4's pitch (PX4: nose up is positive pitch; FLU: nose down).
"""

from __future__ import annotations

import numpy as np

from verticality.core import so3

FRD_TO_FLU = np.array([1.0, -1.0, -1.0])  # a vector's components: FRD → FLU (and NED → NWU)
TURN_X_PI = np.array([0.0, 1.0, 0.0, 0.0])  # the quaternion of a turn of π about x


def flu_from_frd(v) -> np.ndarray:
    """(…, 3) body vectors (a gyro or accelerometer sample) from PX4's FRD to FLU."""
    return np.asarray(v, dtype=np.float64) * FRD_TO_FLU


def quat_nwu_flu(q_ned_frd) -> np.ndarray:
    """(M, 4) PX4 attitudes ``q`` (FRD → NED, wxyz) as ``q_NWU_FLU`` (FLU → NWU, z up), our
    convention for samples turned by :func:`flu_from_frd`."""
    q = tuple(np.asarray(q_ned_frd, dtype=np.float64).T)
    r, r_conj = tuple(TURN_X_PI), tuple(TURN_X_PI * np.array([1.0, -1.0, -1.0, -1.0]))
    return np.stack(so3.quat_multiply_components(so3.quat_multiply_components(r, q), r_conj),
                    axis=-1)


def up_in_sensor(quat_E_S) -> np.ndarray:
    """(M, 3) the unit up vector (E's z) in the sensor frame: ``R_E_S^T e_z``, the conjugate's
    rotation of e_z (NumPy: no compilation per shape)."""
    q = np.asarray(quat_E_S, dtype=np.float64)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    conj = (q[..., 0], -q[..., 1], -q[..., 2], -q[..., 3])
    zero, one = np.zeros(q.shape[:-1]), np.ones(q.shape[:-1])
    return np.stack(so3.quat_rotate_components(conj, (zero, zero, one)), axis=-1)


def roll_pitch_of_up(up_S) -> tuple[np.ndarray, np.ndarray]:
    """ZYX roll and pitch (rad) of the sensor given its up vector (as ours)."""
    return so3.roll_pitch_from_up(np.asarray(up_S), xp=np)


def angle_between(a, b) -> np.ndarray:
    """(…,) the angle (rad) between unit vectors ``a`` and ``b`` (NaN where either is)."""
    return so3.angle_between_unit_vectors(a, b, xp=np)
