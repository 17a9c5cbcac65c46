"""Extended Kalman filter on a model value, multiplicative (error-state) on manifolds.

The papers (P13 §4, F §4.2.1) run a plain EKF on a 24-element state made of the stacked entries of
``R_IS`` and ``R_IH`` and the two angular velocities; an additive correction pushes those matrices
off SO(3). Here the filter takes any discrete model value (``models/base.py``: ``transition``,
``output``, ``retract``, ``difference``); its nominal state keeps its rotation matrices and the
covariance lives on the tangent space of ``retract``, 3 numbers per rotation (for the medial
head–otolith model, the error state δθ_S, δω_S, δθ_H, δω_H):

    x ⊞ δ  =  model.retract(x, δ)          x₁ ⊟ x₀ = model.difference(x₁, x₀)

Filter (P13 §4 with the error state; Joseph form):

    x⁻ = F(x, u, Δt)                 F = ∂/∂δ [ F(x ⊞ δ, u, Δt) ⊟ x⁻ ] at δ = 0      (jax.jacfwd)
    P⁻ = F P Fᵀ + Q
    H  = ∂/∂δ h(x⁻ ⊞ δ, u) at δ = 0,   r = y ⊖ h(x⁻, u),   S = H P⁻ Hᵀ + R,   K = P⁻ Hᵀ S⁻¹
    x⁺ = x⁻ ⊞ K r
    P⁺ = G [(I − K H) P⁻ (I − K H)ᵀ + K R Kᵀ] Gᵀ,   G = ∂/∂e [ (x⁻ ⊞ (K r + e)) ⊟ x⁺ ] at e = 0

``G`` moves the covariance from the tangent space at x⁻ to the one at x⁺ (the "reset" Jacobian of
error-state filters; the identity on a vector space, where ``reset_jacobian=False`` skips it).
Both covariances are symmetrized. ``y ⊖ ŷ`` wraps the outputs listed in ``angle_outputs`` to
(−π, π].

The medial filter of the experiments (:func:`medial_filter`) is the EKF on
``Discretized(medial(pendulum, head, gyro=True), u_blocks)``: the head–otolith model value of
:mod:`verticality.models.otolith_head`, ``u_blocks`` RK4 sub-steps per sample each with its block of
the input held; the papers' stacked variant is the same model value on flat coordinates
(:mod:`verticality.estimators.ekf_stacked`).

Interface (``estimators/base.py``): ``init``, ``predict``, ``step``, ``run``. A NaN in ``y`` means
"no measurement" for that element: its row is dropped from the update (``out.measured``); all NaN
is exactly ``predict``. A predicted or updated state that is not finite is refused (flagged in
``out.rejected``) and the previous one kept, so nothing turns a finite estimate into NaN.
"""

from __future__ import annotations

import dataclasses
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp

from verticality.core.errors import InputError
from verticality.estimators.base import keep_finite, scan_steps, split_measurement
from verticality.models.base import Discretized, model_dataclass, static_field
from verticality.models.otolith_head import OtolithHeadState, medial
from verticality.models.params import HeadParams, PendulumParams


class EKFState(NamedTuple):
    x: Any  # nominal state (the model's state pytree)
    P: jnp.ndarray  # (n, n) covariance on the model's tangent space


class EKFOut(NamedTuple):
    x: Any  # posterior nominal state
    P: jnp.ndarray  # posterior covariance
    y_pred: jnp.ndarray  # (p,) predicted measurement h(x⁻)
    residual: jnp.ndarray  # (p,) innovation (0 where not measured)
    measured: jnp.ndarray  # (p,) bool: element used in the update
    predict_only: jnp.ndarray  # bool: no element measured
    rejected: jnp.ndarray  # bool: the prediction or the update was not finite and was refused


def _sym(P):
    return 0.5 * (P + P.T)


@model_dataclass
class ExtendedKalmanFilter:
    """EKF over a discrete model value with per-step process noise ``Q`` (n, n) and measurement
    noise ``R`` (p, p). ``angle_outputs``: indices of the outputs whose residual is wrapped to
    (−π, π]; ``reset_jacobian``: move the covariance to the posterior's tangent space (off for a
    model on a vector space, where it is the identity)."""

    model: Any
    Q: jnp.ndarray
    R: jnp.ndarray
    angle_outputs: tuple = static_field(())
    reset_jacobian: bool = static_field(True)

    def init(self, x0, P0=None) -> EKFState:
        if P0 is None:
            raise InputError("the EKF needs an initial covariance P0 on the model's tangent space")
        P0 = jnp.asarray(P0, dtype=jnp.float64)
        return EKFState(x=x0, P=_sym(P0))

    def _time_update(self, state: EKFState, u, dt) -> tuple[EKFState, jnp.ndarray]:
        m = self.model
        x_pred = m.transition(state.x, u, dt)
        z = jnp.zeros(state.P.shape[0], dtype=state.P.dtype)
        F = jax.jacfwd(lambda d: m.difference(m.transition(m.retract(state.x, d), u, dt),
                                              x_pred))(z)
        pred = EKFState(x=x_pred, P=_sym(F @ state.P @ F.T + self.Q))
        return keep_finite(pred, state)

    def predict(self, state: EKFState, u, dt) -> EKFState:
        """The time update over ``dt`` with input ``u`` (refused, state kept, if not finite)."""
        return self._time_update(state, u, dt)[0]

    def residual(self, y, y_pred):
        """``y ⊖ ŷ``: the difference, the ``angle_outputs`` wrapped to (−π, π]."""
        r = y - y_pred
        if not self.angle_outputs:
            return r
        idx = jnp.asarray(self.angle_outputs)
        ang = r[idx]
        return r.at[idx].set(jnp.arctan2(jnp.sin(ang), jnp.cos(ang)))

    def update(self, state: EKFState, u, y) -> tuple[EKFState, EKFOut]:
        """The measurement update with ``y`` (NaN elements unmeasured; all NaN: no change)."""
        m = self.model
        x, P = state.x, state.P
        z = jnp.zeros(P.shape[0], dtype=P.dtype)
        y_pred = m.output(x, u)
        H = jax.jacfwd(lambda d: m.output(m.retract(x, d), u))(z)
        y_safe, measured = split_measurement(y, y_pred)
        r = jnp.where(measured, self.residual(y_safe, y_pred), 0.0)
        H = jnp.where(measured[:, None], H, 0.0)
        S = _sym(H @ P @ H.T + self.R)
        K = jnp.linalg.solve(S, H @ P).T  # P Hᵀ S⁻¹ (S symmetric)
        dx = K @ r
        I_KH = jnp.eye(P.shape[0]) - K @ H
        P_upd = I_KH @ P @ I_KH.T + K @ self.R @ K.T
        x_upd = m.retract(x, dx)
        if self.reset_jacobian:
            G = jax.jacfwd(lambda e: m.difference(m.retract(x, dx + e), x_upd))(z)
            P_upd = G @ P_upd @ G.T
        new, ok = keep_finite(EKFState(x=x_upd, P=_sym(P_upd)), state)
        any_measured = jnp.any(measured)
        new = jax.tree_util.tree_map(lambda a, b: jnp.where(any_measured, a, b), new, state)
        out = EKFOut(x=new.x, P=new.P, y_pred=y_pred, residual=r, measured=measured,
                     predict_only=~any_measured, rejected=~ok)
        return new, out

    def step(self, state: EKFState, u, y, dt) -> tuple[EKFState, EKFOut]:
        """Predict over ``dt`` with input ``u``, then update with ``y`` (taken at the new time)."""
        pred, pred_ok = self._time_update(state, u, dt)
        new, out = self.update(pred, u, y)
        return new, out._replace(rejected=out.rejected | ~pred_ok)

    def run(self, state: EKFState, us, ys, dts):
        """:meth:`step` over a sequence (``lax.scan``): the final state and the stacked outputs."""
        return scan_steps(self.step, state, us, ys, dts)


# ----------------------------------------------------------------------------------------------
# The medial head–otolith filter of the experiments (P13 §4–5)
# ----------------------------------------------------------------------------------------------
N_ERR = 12
"""Error-state dimension of the medial model: δθ_S, δω_S, δθ_H, δω_H."""
N_Y = 5
"""Measurements: the two inclinometer angles (F 2.8–2.9) and the three gyro rates (P13 eq. 4)."""


def medial_model(p_pend: PendulumParams, p_head: HeadParams, u_blocks: int = 4) -> Discretized:
    """P13 §3's medial model with its gyro, discretized: ``u_blocks`` RK4 sub-steps per sample, the
    input a :class:`~verticality.models.head.HeadInput` whose leaves have a leading axis of
    ``u_blocks`` (the input's mean over each sub-interval)."""
    return Discretized(medial(p_pend, p_head, gyro=True), substeps=u_blocks)


def block_covariance(sigmas, dims) -> jnp.ndarray:
    """Diagonal covariance with ``sigmas[i]²`` repeated ``dims[i]`` times (one σ per block, a
    scalar σ for every block)."""
    sig = jnp.broadcast_to(jnp.asarray(sigmas, dtype=jnp.float64), (len(dims),))
    return jnp.diag(jnp.concatenate([jnp.full(d, s**2) for s, d in zip(sig, dims, strict=True)]))


def medial_filter(p_pend: PendulumParams, p_head: HeadParams, sigma_process=1e-3,
                  sigma_measurement=2e-2, u_blocks: int = 4) -> ExtendedKalmanFilter:
    """The multiplicative EKF of the experiments: Q per step, R = σ_v² I₅ (P13 §5: σ_v = 0.02).

    ``sigma_process``: a scalar (P13 §5's σ_w = 0.001 on every error-state element) or four
    standard deviations, per EKF step, for the blocks (δθ_S, δω_S, δθ_H, δω_H).
    """
    model = medial_model(p_pend, p_head, u_blocks)
    return ExtendedKalmanFilter(model=model, Q=block_covariance(sigma_process, (3, 3, 3, 3)),
                                R=sigma_measurement**2 * jnp.eye(N_Y),
                                angle_outputs=model.model.angle_outputs)


def with_noise(filt: ExtendedKalmanFilter, Q=None, R=None) -> ExtendedKalmanFilter:
    """``filt`` with another ``Q`` and/or ``R`` (e.g. traced values carried in a state)."""
    return dataclasses.replace(filt, Q=filt.Q if Q is None else Q, R=filt.R if R is None else R)


def head_orientation(x: OtolithHeadState):
    """The estimate's ``R_IH`` (used by controllers and metrics; same name in the stacked
    module)."""
    return x.head.R_I_H
