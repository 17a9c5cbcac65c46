"""Head stabilizers: the global SO(3) law (F 2.20–2.21), PD on tilt angles and its linearization
(F 4.6–4.9), and the joint-space PD of the gimbal head (P13 §3).

All laws return torques and are pure ``jax.numpy`` functions (jit/vmap/jacfwd-able). Gains may be
scalars, per-axis vectors or (for the global law) 3×3 matrices.

**Sign readings** (the sources leave them open or are inconsistent with our conventions):

* F 2.21 prints ``Ω = Σ e_i × (R e_i)`` with ``R`` typeset ambiguously between ``R_IH`` and
  ``R_HI``. ``Σ e_i × (A e_i) = vee(A − Aᵀ)``, which for ``A = R_IH = exp(θ [e]×)`` is ``≈ 2θ e``:
  with ``τ = K_p Ω`` that is positive feedback. The stabilizing reading, used here, is
  ``A = R_HI = R_IHᵀ``: ``Ω = Σ e_i × (R_IHᵀ e_i) = vee(R_IHᵀ − R_IH) ≈ −2θ e``, so the linearized
  loop is ``J θ̈ = −2 K_p θ − K_d θ̇``. It regulates the full orientation (yaw too) to the identity,
  as F says.
* F 4.6–4.9 were used in the thesis for one plane only. With the tilt angles of F 3.8–3.9,
  ``Θ_x = atan2(R32, R33)`` grows with a positive rotation about x, but ``Θ_y = atan2(R31, R33)``
  grows with a *negative* rotation about y (``R_IH = R_y(θ)`` gives ``Θ_y = −θ``). Applied about
  the body y axis literally, F 4.7/4.9 would push the head away from the reference. We keep F's
  tilt angles and references and flip the sign of the y torque, i.e. ``τ_y = −k_p (φ_{y,d} − Θ_y) −
  k_d ω_y``, which is F 4.7 written for a rotation about +y. The yaw torque is ``−k_{d,z} ω_z``
  (``k_{d,z} = 0`` by default: F controls only the two tilts).
* P13's joint-space PD: ``θ_d = Λ⁻¹`` of the upright head given the trunk's orientation estimate,
  ``m = k_p (θ_d − θ) − k_d θ̇``; the trunk's orientation estimate is ``R̂_IT = R̂_IH Λ(θ)ᵀ``.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from verticality.core import so3
from verticality.models import gimbal


def _gain(K, v):
    """Apply a gain given as a scalar, a per-axis vector or a matrix to the vector ``v``."""
    K = jnp.asarray(K, dtype=float)
    if K.ndim == 2:
        return K @ v
    return K * v


# ------------------------------------------------------------------------------ global law
def omega_map(R_I_H):
    """F 2.21 (stabilizing reading): ``Ω = Σ_i e_i × (R_IHᵀ e_i) = vee(R_IHᵀ − R_IH)``."""
    R_H_I = jnp.swapaxes(jnp.asarray(R_I_H), -1, -2)
    eye = jnp.eye(3)
    return sum(jnp.cross(eye[i], R_H_I[..., :, i]) for i in range(3))


def global_stabilizer(R_I_H, omega_H, Kp, Kd):
    """F 2.20: ``τ_H = K_p Ω(R_IH) − K_d ω_H`` (head frame), regulating R_IH to the identity."""
    return _gain(Kp, omega_map(R_I_H)) - _gain(Kd, jnp.asarray(omega_H))


# ----------------------------------------------------------------------------- tilt PD laws
_Y_SIGN = jnp.array([1.0, -1.0])
"""Rotation about +x raises Θ_x, rotation about +y lowers Θ_y (see module docstring)."""


def _tilt_torque(tilt_rad, omega_H, kp, kd, tilt_desired_rad, kd_z):
    tilt_desired_rad = jnp.zeros(2) if tilt_desired_rad is None else jnp.asarray(tilt_desired_rad)
    kp2 = jnp.broadcast_to(jnp.asarray(kp, dtype=float), (2,))
    kd2 = jnp.broadcast_to(jnp.asarray(kd, dtype=float), (2,))
    w = jnp.asarray(omega_H)
    tau_xy = _Y_SIGN * kp2 * (tilt_desired_rad - tilt_rad) - kd2 * w[:2]
    return jnp.concatenate([tau_xy, (-kd_z * w[2])[None]])


def tilt_pd(R_I_H, omega_H, kp, kd, tilt_desired_rad=None, kd_z=0.0):
    """F 4.6–4.7: PD on the tilt angles ``Θ = (atan2(R32, R33), atan2(R31, R33))``.

    ``τ_x = k_p (φ_{x,d} − Θ_x) − k_d ω_x``, ``τ_y = −k_p (φ_{y,d} − Θ_y) − k_d ω_y`` (sign of y:
    see the module docstring), ``τ_z = −k_{d,z} ω_z``. ``kp``, ``kd``: scalars or (k_x, k_y).
    """
    return _tilt_torque(so3.tilt_angles(R_I_H), omega_H, kp, kd, tilt_desired_rad, kd_z)


def tilt_pd_linearized(R_I_H, omega_H, kp, kd, tilt_desired_rad=None, kd_z=0.0):
    """F 4.8–4.9: the same law with ``atan`` linearized at upright, ``Θ ≈ (R32, R31)``."""
    R = jnp.asarray(R_I_H)
    return _tilt_torque(jnp.stack([R[2, 1], R[2, 0]]), omega_H, kp, kd, tilt_desired_rad, kd_z)


def tilt_pd_closed_loop_matrix(J_H, kp, kd, kd_z=0.0):
    """Closed-loop ``A`` of the head linearized at upright under F 4.8–4.9 (τ from the law).

    State ``(δ, ω_H)`` with ``R_IH = exp([δ]×)``: ``δ̇ = ω``, ``J ω̇ = τ`` (the gyroscopic term is
    quadratic, so it drops out), and to first order ``(R32, R31) = (δ_x, −δ_y)``, so
    ``τ_{x,y} = −k_p δ_{x,y} − k_d ω_{x,y}``, ``τ_z = −k_{d,z} ω_z``. Poles: roots of
    ``J_i s² + k_d s + k_p`` (x, y), and ``0``, ``−k_{d,z}/J_z`` (yaw).
    """
    J = jnp.asarray(J_H, dtype=float)
    kp2 = jnp.broadcast_to(jnp.asarray(kp, dtype=float), (2,))
    kd2 = jnp.broadcast_to(jnp.asarray(kd, dtype=float), (2,))
    Kp = jnp.diag(jnp.concatenate([kp2, jnp.zeros(1)]))
    Kd = jnp.diag(jnp.concatenate([kd2, jnp.atleast_1d(jnp.asarray(kd_z, dtype=float))]))
    Jinv = jnp.diag(1.0 / J)
    top = jnp.concatenate([jnp.zeros((3, 3)), jnp.eye(3)], axis=1)
    bottom = jnp.concatenate([-Jinv @ Kp, -Jinv @ Kd], axis=1)
    return jnp.concatenate([top, bottom], axis=0)


# --------------------------------------------------------------------- joint-space PD (P13)
def trunk_orientation_estimate(R_I_H_est, theta_rad):
    """``R̂_IT = R̂_IH Λ(θ)ᵀ``: the trunk's orientation from the head's estimate and the
    encoders."""
    return jnp.asarray(R_I_H_est) @ gimbal.Lambda(theta_rad).T


def joint_space_pd(theta, thetadot, R_I_T_est, kp, kd):
    """P13 §3: motor torques ``m = k_p (θ_d − θ) − k_d θ̇`` with ``θ_d = Λ⁻¹`` (upright head).

    ``θ_d = joint_angles_for_up(R̂_ITᵀ e3)``: the joint angles that put the head's z axis on the
    world vertical seen from the (estimated) trunk. ``kp``, ``kd``: scalars or per-joint (2,).
    """
    up_T = so3.up_in_frame(R_I_T_est)
    theta_d = gimbal.joint_angles_for_up(up_T)
    return jnp.asarray(kp) * (theta_d - theta) - jnp.asarray(kd) * thetadot


def desired_joint_rates(R_I_T_est, omega_T_rad_s):
    """θ̇_d: the rate of θ_d = Λ⁻¹(upright) as the trunk turns at ω_T (trunk frame).

    ``u_T = R_ITᵀ e3`` changes as ``u̇_T = −ω_T × u_T``; θ̇_d is the forward-mode derivative of
    :func:`gimbal.joint_angles_for_up` along it.
    """
    up_T = so3.up_in_frame(R_I_T_est)
    return jax.jvp(gimbal.joint_angles_for_up, (up_T,), (-jnp.cross(omega_T_rad_s, up_T),))[1]


def trunk_rate_from_head(theta_rad, thetadot_rad_s, omega_H_rad_s):
    """ω_T (trunk frame) from the head's gyro and the encoders: ω_H = Λᵀ ω_T + E θ̇."""
    return gimbal.Lambda(theta_rad) @ (omega_H_rad_s
                                       - gimbal.body_jacobian(theta_rad) @ thetadot_rad_s)


def joint_space_pd_tracking(theta, thetadot, R_I_T_est, omega_H_rad_s, kp, kd):
    """P13 §3 read as a PD on the joint error, ``m = k_p (θ_d − θ) + k_d (θ̇_d − θ̇)``.

    P13 writes ``m = PD(θ_d − θ)``; its derivative needs θ̇_d, which follows from the trunk's rate,
    itself known from the head's gyro and the encoders (:func:`trunk_rate_from_head`); F §4.2.2:
    "the head stabilization controller used the estimated head's angular orientation and velocity".
    Unlike :func:`joint_space_pd`, which damps the joint rate and so lags a turning trunk by
    about (k_d/k_p)·θ̇_d, this tracks θ_d without that lag.
    """
    theta_d = gimbal.joint_angles_for_up(so3.up_in_frame(R_I_T_est))
    omega_T = trunk_rate_from_head(theta, thetadot, omega_H_rad_s)
    thetadot_d = desired_joint_rates(R_I_T_est, omega_T)
    return jnp.asarray(kp) * (theta_d - theta) + jnp.asarray(kd) * (thetadot_d - thetadot)


def head_torque_from_motor_torques(theta_rad, m_Nm, damping=1e-9):
    """P13's ``τ_H = M^{-T} m`` for the 3×2 Jacobian E: the least-norm τ_H with ``Eᵀ τ_H = m``.

    Solved by damped least squares, ``τ_H = E (EᵀE + λ I)⁻¹ m`` (E loses rank at |θ2| = π/2).
    """
    E = gimbal.body_jacobian(theta_rad)
    G = E.T @ E + damping * jnp.eye(2)
    return E @ jnp.linalg.solve(G, m_Nm)
