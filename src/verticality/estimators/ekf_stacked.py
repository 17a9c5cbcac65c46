"""The papers' EKF: a plain, additive EKF on the 24-element stacked state (P13 §4, F §4.2.1).

State (P13 §4's order): ``x = (ω_S, vec R_IS, ω_H, vec R_IH)`` — 3 + 9 + 3 + 9 = 24 numbers, the
matrices stored row by row. The model is the *same* model value as the multiplicative filter's
(:func:`verticality.estimators.ekf.medial_model`: the medial head–otolith model, RK4 sub-steps, the
same inputs and outputs), seen through two adapters: :class:`Unprojected` integrates it in the
embedding without the projection onto SO(3), and :class:`StackedCoordinates` puts it on the flat
coordinates with the additive correction ``x⁺ = x⁻ + K r``, so the estimated "rotation matrices"
leave SO(3); that is the point of the comparison. The same
:class:`verticality.estimators.ekf.ExtendedKalmanFilter` runs it, so the Jacobians are autodiff and
the covariance update Joseph form here too; Q = σ_w² I₂₄ (P13 §5).

The tilt read from it uses the third row of the estimated ``R_IH`` (the world up axis in the head
frame); :func:`verticality.core.so3.tilt_error_rad` is invariant to its length, and the controller's
Λ⁻¹ normalizes it, so no re-orthonormalization is needed downstream.
"""

from __future__ import annotations

from typing import Any

import jax.numpy as jnp

from verticality.estimators import ekf
from verticality.models.base import Discretized, EuclideanState, OnModel, model_dataclass
from verticality.models.head import HeadState
from verticality.models.otolith_head import OtolithHeadState, medial
from verticality.models.params import HeadParams, PendulumParams
from verticality.models.pendulum import PendulumState

N_STATE = 24


@model_dataclass
class Unprojected(OnModel):
    """``model`` integrated in the embedding: the same dynamics, output and tangent maps, and no
    projection back onto the manifold after a step."""

    model: Any

    def dynamics(self, x, u):
        return self.model.dynamics(x, u)

    def project(self, x):
        return x


def _rotation_rate_blocks(R, omega):
    return [omega, R.reshape(9)]


def to_flat(x: OtolithHeadState):
    """(ω, vec R) of each pendulum, then of the head (P13 §4's order for the medial model)."""
    parts = []
    for p in x.pendula:
        parts += _rotation_rate_blocks(p.R_I_S, p.omega_S_rad_s)
    parts += _rotation_rate_blocks(x.head.R_I_H, x.head.omega_H_rad_s)
    return jnp.concatenate(parts)


def from_flat(v, n_pendula: int = 1) -> OtolithHeadState:
    def block(i):
        return v[12 * i + 3:12 * i + 12].reshape(3, 3), v[12 * i:12 * i + 3]

    pendula = tuple(PendulumState(*block(i)) for i in range(n_pendula))
    return OtolithHeadState(pendula, HeadState(*block(n_pendula)))


@model_dataclass
class StackedCoordinates(EuclideanState):
    """A discrete head–otolith model on the flat stacked coordinates (:func:`to_flat`), on which the
    filter acts additively (``retract`` is ``+``)."""

    discrete: Any  # a DiscreteModel whose states are OtolithHeadState

    @property
    def head_model(self):
        """The continuous head–otolith model inside the adapters."""
        m = self.discrete.model
        return m.model if isinstance(m, Unprojected) else m

    def transition(self, v, u, dt):
        n = len(self.head_model.pendula)
        return to_flat(self.discrete.transition(from_flat(v, n), u, dt))

    def output(self, v, u=None):
        return self.discrete.output(from_flat(v, len(self.head_model.pendula)), u)


def stacked_model(p_pend: PendulumParams, p_head: HeadParams,
                  u_blocks: int = 4) -> StackedCoordinates:
    """The medial model of :func:`verticality.estimators.ekf.medial_model`, unprojected, on the
    stacked coordinates."""
    return StackedCoordinates(Discretized(Unprojected(medial(p_pend, p_head, gyro=True)),
                                          substeps=u_blocks))


def stacked_filter(p_pend: PendulumParams, p_head: HeadParams, sigma_process=1e-3,
                   sigma_measurement=2e-2, u_blocks: int = 4) -> ekf.ExtendedKalmanFilter:
    """``sigma_process``: scalar, or four σ for the blocks (ω_S, R_IS, ω_H, R_IH) in P13's order."""
    model = stacked_model(p_pend, p_head, u_blocks)
    return ekf.ExtendedKalmanFilter(
        model=model,
        Q=ekf.block_covariance(sigma_process, (3, 9, 3, 9)),
        R=sigma_measurement**2 * jnp.eye(ekf.N_Y),
        angle_outputs=model.head_model.angle_outputs,
        reset_jacobian=False,
    )


def init_covariance(sigma_rotation_rad=0.1, sigma_rate_rad_s=0.1):
    """Diagonal P0: σ_rate² on the rates, σ_rotation² on each matrix entry (an entry of R exp[δ]×
    moves by at most |δ| for a rotation error δ)."""
    return ekf.block_covariance((sigma_rate_rad_s, sigma_rotation_rad, sigma_rate_rad_s,
                                 sigma_rotation_rad), (3, 9, 3, 9))


def head_orientation(v):
    return from_flat(v).head.R_I_H
