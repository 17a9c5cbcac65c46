"""The papers' EKF: a plain, additive EKF on the 24-element stacked state (P13 §4, F §4.2.1).

State (P13 §4's order): ``x = (ω_S, vec R_IS, ω_H, vec R_IH)`` — 3 + 9 + 3 + 9 = 24 numbers, the
matrices stored row by row. The model is the *same* one as the multiplicative filter's
(:func:`verticality.estimators.ekf.medial_dynamics`, RK4 substeps, the same inputs and outputs), but
integrated on the flat coordinates without projection and corrected additively, ``x⁺ = x⁻ + K r``,
so the estimated "rotation matrices" leave SO(3); that is the point of the comparison. The same
generic :class:`verticality.estimators.ekf.ExtendedKalmanFilter` runs it (``boxplus`` is ``+``), so
the Jacobians are autodiff and the covariance update Joseph form here too; Q = σ_w² I₂₄ (P13 §5).

The tilt read from it uses the third row of the estimated ``R_IH`` (the world up axis in the head
frame); :func:`verticality.so3.tilt_error_rad` is invariant to its length, and the controller's
Λ⁻¹ normalizes it, so no re-orthonormalization is needed downstream.
"""

from __future__ import annotations

import jax.numpy as jnp

from verticality.estimators import ekf
from verticality.params import HeadParams, PendulumParams

N_STATE = 24


def to_flat(x: ekf.MedialState):
    return jnp.concatenate([x.omega_S_rad_s, x.R_I_S.reshape(9), x.omega_H_rad_s, x.R_I_H.reshape(9)])


def from_flat(v) -> ekf.MedialState:
    return ekf.MedialState(
        R_I_S=v[3:12].reshape(3, 3), omega_S_rad_s=v[0:3], R_I_H=v[15:24].reshape(3, 3),
        omega_H_rad_s=v[12:15],
    )


def stacked_model(p_pend: PendulumParams, p_head: HeadParams) -> ekf.Model:
    p_pend = p_pend.resolved()
    p_head = p_head.resolved()

    def f(v, u, dt):
        x = ekf.medial_discrete(from_flat(v), u, dt, p_pend, p_head, project=False)
        return to_flat(x)

    return ekf.Model(
        f=f,
        h=lambda v, u: ekf.medial_output(from_flat(v)),
        boxplus=lambda v, dv: v + dv,
        boxminus=lambda v1, v0: v1 - v0,
        residual=ekf.wrap_angle_residual,
    )


def stacked_filter(p_pend: PendulumParams, p_head: HeadParams, sigma_process=1e-3,
                   sigma_measurement=2e-2) -> ekf.ExtendedKalmanFilter:
    """``sigma_process``: scalar, or four σ for the blocks (ω_S, R_IS, ω_H, R_IH) in P13's order."""
    sig = jnp.broadcast_to(jnp.asarray(sigma_process, dtype=jnp.float64), (4,))
    q = jnp.concatenate([jnp.full(3, sig[0] ** 2), jnp.full(9, sig[1] ** 2),
                         jnp.full(3, sig[2] ** 2), jnp.full(9, sig[3] ** 2)])
    return ekf.ExtendedKalmanFilter(
        model=stacked_model(p_pend, p_head),
        Q=jnp.diag(q),
        R=sigma_measurement**2 * jnp.eye(ekf.N_Y),
        reset_jacobian=False,
    )


def init_covariance(sigma_rotation_rad=0.1, sigma_rate_rad_s=0.1):
    """Diagonal P0: σ_rate² on the rates, σ_rotation² on each matrix entry (an entry of R exp[δ]×
    moves by at most |δ| for a rotation error δ)."""
    d = jnp.concatenate([jnp.full(3, sigma_rate_rad_s**2), jnp.full(9, sigma_rotation_rad**2),
                         jnp.full(3, sigma_rate_rad_s**2), jnp.full(9, sigma_rotation_rad**2)])
    return jnp.diag(d)


def head_orientation(v):
    return from_flat(v).R_I_H
