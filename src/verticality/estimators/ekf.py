"""Multiplicative (error-state) extended Kalman filter, and the medial head–otolith model for it.

The papers (P13 §4, F §4.2.1) run a plain EKF on a 24-element state made of the stacked entries of
``R_IS`` and ``R_IH`` and the two angular velocities; an additive correction pushes those matrices
off SO(3). Here the nominal state keeps its rotation matrices and the filter's covariance lives on
the error state, 3 numbers per rotation (right, body-frame perturbation):

    x ⊞ δ  =  (R_IS exp([δ_S]×), ω_S + δ_ωS, R_IH exp([δ_H]×), ω_H + δ_ωH)
    x₁ ⊟ x₀ = (log(R_IS0ᵀ R_IS1), ω_S1 − ω_S0, log(R_IH0ᵀ R_IH1), ω_H1 − ω_H0)

Filter (P13 §4 with the error state; Joseph form):

    x⁻ = f(x, u, Δt)                 F = ∂/∂δ [ f(x ⊞ δ, u, Δt) ⊟ x⁻ ] at δ = 0      (jax.jacfwd)
    P⁻ = F P Fᵀ + Q
    H  = ∂/∂δ h(x⁻ ⊞ δ, u) at δ = 0,   r = y ⊖ h(x⁻, u),   S = H P⁻ Hᵀ + R,   K = P⁻ Hᵀ S⁻¹
    x⁺ = x⁻ ⊞ K r
    P⁺ = G [(I − K H) P⁻ (I − K H)ᵀ + K R Kᵀ] Gᵀ,   G = ∂/∂e [ (x⁻ ⊞ (K r + e)) ⊟ x⁺ ] at e = 0

``G`` moves the covariance from the tangent space at x⁻ to the one at x⁺ (the "reset" Jacobian of
error-state filters; the identity on a vector space). Both covariances are symmetrized.

The filter is generic: a :class:`Model` is any four functions ``f, h, boxplus, boxminus`` (plus an
optional residual map for angles), so the same code runs a linear model (``linear_model``), where
it is the Kalman filter, the medial model on SO(3) (``medial_model``) and the stacked-matrix
variant of :mod:`verticality.estimators.ekf_stacked`.

A NaN in ``y`` means "no measurement" for that element: its row is dropped from the update (and
flagged); all NaN is a prediction step. An update whose result is not finite is refused (flagged)
and the prediction kept, so nothing turns a finite estimate into NaN.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp

from verticality import integrate, so3
from verticality.models import pendulum
from verticality.models.kinematics import RigidMotion
from verticality.params import HeadParams, PendulumParams


# ----------------------------------------------------------------------------------------------
# Generic filter
# ----------------------------------------------------------------------------------------------
class Model(NamedTuple):
    """A discrete model for the EKF.

    ``f(x, u, dt) -> x`` (nominal state, any pytree), ``h(x, u) -> y`` (p,), ``boxplus(x, dx)`` and
    ``boxminus(x1, x0) -> dx`` (n,) the retraction and its inverse, ``residual(y, y_pred) -> r``
    (p,) (subtraction, or a wrapped difference for angles).
    """

    f: Callable
    h: Callable
    boxplus: Callable
    boxminus: Callable
    residual: Callable | None = None


class EKFState(NamedTuple):
    x: Any  # nominal state (pytree)
    P: jnp.ndarray  # (n, n) error-state covariance


class EKFOut(NamedTuple):
    x: Any  # posterior nominal state
    P: jnp.ndarray  # posterior covariance
    y_pred: jnp.ndarray  # (p,) predicted measurement h(x⁻)
    residual: jnp.ndarray  # (p,) innovation (0 where not measured)
    measured: jnp.ndarray  # (p,) bool: element used in the update
    predict_only: jnp.ndarray  # bool: no element measured
    rejected: jnp.ndarray  # bool: the update was not finite and was refused


def _sym(P):
    return 0.5 * (P + P.T)


class ExtendedKalmanFilter(NamedTuple):
    """EKF over a :class:`Model` with per-step process noise ``Q`` (n, n) and measurement noise ``R``.

    API: ``init(x0, P0)``, ``step(state, u, y, dt) -> (state, out)``,
    ``run(state, us, ys, dts) -> (states, outs)`` (``jax.lax.scan``; jit around it).
    """

    model: Model
    Q: jnp.ndarray
    R: jnp.ndarray
    reset_jacobian: bool = True

    def init(self, x0, P0) -> EKFState:
        P0 = jnp.asarray(P0, dtype=jnp.float64)
        return EKFState(x=x0, P=_sym(P0))

    def _zero(self, P):
        return jnp.zeros(P.shape[0], dtype=P.dtype)

    def predict(self, state: EKFState, u, dt) -> EKFState:
        m = self.model
        x_pred = m.f(state.x, u, dt)
        z = self._zero(state.P)
        F = jax.jacfwd(lambda d: m.boxminus(m.f(m.boxplus(state.x, d), u, dt), x_pred))(z)
        P_pred = _sym(F @ state.P @ F.T + self.Q)
        return EKFState(x=x_pred, P=P_pred)

    def update(self, state: EKFState, u, y):
        m = self.model
        x, P = state.x, state.P
        z = self._zero(P)
        y = jnp.asarray(y, dtype=jnp.float64)
        y_pred = m.h(x, u)
        H = jax.jacfwd(lambda d: m.h(m.boxplus(x, d), u))(z)
        measured = jnp.isfinite(y)
        y_safe = jnp.where(measured, y, y_pred)
        r = y_safe - y_pred if m.residual is None else m.residual(y_safe, y_pred)
        r = jnp.where(measured, r, 0.0)
        H = jnp.where(measured[:, None], H, 0.0)
        S = _sym(H @ P @ H.T + self.R)
        K = jnp.linalg.solve(S, H @ P).T  # P Hᵀ S⁻¹ (S symmetric)
        dx = K @ r
        I_KH = jnp.eye(P.shape[0]) - K @ H
        P_upd = I_KH @ P @ I_KH.T + K @ self.R @ K.T
        x_upd = m.boxplus(x, dx)
        if self.reset_jacobian:
            G = jax.jacfwd(lambda e: m.boxminus(m.boxplus(x, dx + e), x_upd))(z)
            P_upd = G @ P_upd @ G.T
        P_upd = _sym(P_upd)
        ok = jnp.all(jnp.isfinite(P_upd)) & jnp.all(
            jnp.stack([jnp.all(jnp.isfinite(leaf)) for leaf in jax.tree_util.tree_leaves(x_upd)])
        )
        x_new = jax.tree_util.tree_map(lambda a, b: jnp.where(ok, a, b), x_upd, x)
        P_new = jnp.where(ok, P_upd, P)
        out = EKFOut(
            x=x_new,
            P=P_new,
            y_pred=y_pred,
            residual=r,
            measured=measured,
            predict_only=~jnp.any(measured),
            rejected=~ok,
        )
        return EKFState(x=x_new, P=P_new), out

    def step(self, state: EKFState, u, y, dt):
        """Predict over ``dt`` with input ``u``, then update with ``y`` (taken at the new time)."""
        pred = self.predict(state, u, dt)
        pred_ok = jnp.all(jnp.isfinite(pred.P)) & jnp.all(
            jnp.stack([jnp.all(jnp.isfinite(leaf)) for leaf in jax.tree_util.tree_leaves(pred.x)])
        )
        pred = jax.tree_util.tree_map(lambda a, b: jnp.where(pred_ok, a, b), pred, state)
        new, out = self.update(pred, u, y)
        return new, out._replace(rejected=out.rejected | ~pred_ok)

    def run(self, state: EKFState, us, ys, dts):
        def body(s, inp):
            u, y, dt = inp
            return self.step(s, u, y, dt)

        return jax.lax.scan(body, state, (us, ys, jnp.asarray(dts, dtype=jnp.float64)))


# ----------------------------------------------------------------------------------------------
# Linear model (the EKF is then the Kalman filter; used by the tests)
# ----------------------------------------------------------------------------------------------
def linear_model(A, B, C, D=None) -> Model:
    """x_{k+1} = A x_k + B u_k, y_k = C x_k + D u_k on R^n (``dt`` ignored)."""
    A, B, C = (jnp.asarray(M, dtype=jnp.float64) for M in (A, B, C))
    D = jnp.zeros((C.shape[0], B.shape[1])) if D is None else jnp.asarray(D, dtype=jnp.float64)
    return Model(
        f=lambda x, u, dt: A @ x + B @ u,
        h=lambda x, u: C @ x + D @ u,
        boxplus=lambda x, dx: x + dx,
        boxminus=lambda x1, x0: x1 - x0,
    )


# ----------------------------------------------------------------------------------------------
# The medial model (P13 eq. 1–4, F eq. 2.7–2.9) on SO(3) × R³ × SO(3) × R³
# ----------------------------------------------------------------------------------------------
class MedialState(NamedTuple):
    """Nominal state. Angular velocities are body-frame (docs/conventions.md): Ṙ_IS = R_IS [ω_S]×."""

    R_I_S: jnp.ndarray  # (3, 3) pendulum (otolith / inclinometer) frame
    omega_S_rad_s: jnp.ndarray  # (3,)
    R_I_H: jnp.ndarray  # (3, 3) head frame
    omega_H_rad_s: jnp.ndarray  # (3,)


N_ERR = 12
"""Error-state dimension of the medial model: δθ_S, δω_S, δθ_H, δω_H."""
N_Y = 5
"""Measurements: the two inclinometer angles (F 2.8–2.9) and the three gyro rates (P13 eq. 4)."""


def medial_dynamics(x: MedialState, u, p_pend: PendulumParams, p_head: HeadParams) -> MedialState:
    """Continuous medial model (P13 eq. 1–2): free head driven by ``τ_H``, pendulum on its centre.

    ``u = (a_I (3), τ_H (3))``: the head centre's linear acceleration in I (gravity excluded) and the
    total torque on the head in H. The pendulum is :func:`verticality.models.pendulum.dynamics`
    (full Newton–Euler, P13 eq. 1) on the head motion this state implies.
    """
    a_I, tau_H = u[:3], u[3:]
    J = p_head.J_H
    w = x.omega_H_rad_s
    wdot_H = (tau_H - p_head.gyroscopic * jnp.cross(w, J * w)) / J
    head = RigidMotion(R_I_B=x.R_I_H, omega_B_rad_s=w, omegadot_B_rad_s2=wdot_H, a_I_m_s2=a_I)
    dp = pendulum.dynamics(pendulum.PendulumState(x.R_I_S, x.omega_S_rad_s), head, p_pend)
    return MedialState(
        R_I_S=dp.R_I_S,
        omega_S_rad_s=dp.omega_S_rad_s,
        R_I_H=x.R_I_H @ so3.hat(w),
        omega_H_rad_s=wdot_H,
    )


def medial_output(x: MedialState):
    """y = (φ_x, φ_y, ω_H): inclinometer angles of R_HS (F 2.8–2.9) and the gyro rates (P13 eq. 4)."""
    phi = pendulum.otolith_angles(x.R_I_H.T @ x.R_I_S)
    return jnp.concatenate([phi, x.omega_H_rad_s])


def medial_project(x: MedialState) -> MedialState:
    return x._replace(R_I_S=so3.orthonormalize(x.R_I_S), R_I_H=so3.orthonormalize(x.R_I_H))


def medial_discrete(x: MedialState, u_blocks, dt, p_pend, p_head, project=True) -> MedialState:
    """One EKF period: ``len(u_blocks)`` RK4 substeps of ``dt / n``, input held per substep.

    ``u_blocks`` (n_sub, 6): the input averaged over each substep (see the experiment's docstring).
    """
    u_blocks = jnp.atleast_2d(u_blocks)
    h = dt / u_blocks.shape[0]

    def f(t, xx, u):
        return medial_dynamics(xx, u, p_pend, p_head)

    def body(xx, u):
        return integrate.rk4_step(f, 0.0, xx, h, u, project=medial_project if project else None), None

    x_next, _ = jax.lax.scan(body, x, u_blocks)
    return x_next


def medial_boxplus(x: MedialState, dx) -> MedialState:
    return MedialState(
        R_I_S=x.R_I_S @ so3.exp(dx[0:3]),
        omega_S_rad_s=x.omega_S_rad_s + dx[3:6],
        R_I_H=x.R_I_H @ so3.exp(dx[6:9]),
        omega_H_rad_s=x.omega_H_rad_s + dx[9:12],
    )


def log_principal(R):
    """Rotation vector of R for rotation angles below π (cheap and smooth; the error-state maps).

    θ = atan2(|s|, (tr R − 1)/2) with s = vee(R) = sin θ · axis; exact for θ < π, where the error
    state lives (differences of nearby rotations). :func:`verticality.so3.log` covers θ ≈ π.
    """
    s = so3.vee(R)
    sin_t = so3._safe_norm(s)
    cos_t = 0.5 * (jnp.trace(R) - 1.0)
    theta = jnp.arctan2(sin_t, cos_t)
    small = sin_t < 1e-8
    factor = jnp.where(small, 1.0 + sin_t * sin_t / 6.0, theta / jnp.where(small, 1.0, sin_t))
    return factor * s


def medial_boxminus(x1: MedialState, x0: MedialState):
    return jnp.concatenate(
        [
            log_principal(x0.R_I_S.T @ x1.R_I_S),
            x1.omega_S_rad_s - x0.omega_S_rad_s,
            log_principal(x0.R_I_H.T @ x1.R_I_H),
            x1.omega_H_rad_s - x0.omega_H_rad_s,
        ]
    )


def wrap_angle_residual(y, y_pred):
    """y − ŷ with the two angle elements wrapped to (−π, π]."""
    r = y - y_pred
    ang = jnp.arctan2(jnp.sin(r[:2]), jnp.cos(r[:2]))
    return r.at[:2].set(ang)


def medial_model(p_pend: PendulumParams, p_head: HeadParams) -> Model:
    """The medial model of P13 §3 on SO(3) (multiplicative EKF). ``u``: (n_sub, 6) input blocks."""
    p_pend = p_pend.resolved()
    p_head = p_head.resolved()
    return Model(
        f=lambda x, u, dt: medial_discrete(x, u, dt, p_pend, p_head),
        h=lambda x, u: medial_output(x),
        boxplus=medial_boxplus,
        boxminus=medial_boxminus,
        residual=wrap_angle_residual,
    )


def medial_filter(p_pend: PendulumParams, p_head: HeadParams, sigma_process=1e-3,
                  sigma_measurement=2e-2) -> ExtendedKalmanFilter:
    """The multiplicative EKF of the experiments: Q per step, R = σ_v² I₅ (P13 §5: σ_v = 0.02).

    ``sigma_process``: a scalar (P13 §5's σ_w = 0.001 on every error-state element) or four
    standard deviations, per EKF step, for the blocks (δθ_S, δω_S, δθ_H, δω_H).
    """
    sig = jnp.broadcast_to(jnp.asarray(sigma_process, dtype=jnp.float64), (4,))
    q = jnp.repeat(sig**2, 3)
    return ExtendedKalmanFilter(
        model=medial_model(p_pend, p_head),
        Q=jnp.diag(q),
        R=sigma_measurement**2 * jnp.eye(N_Y),
    )


def head_orientation(x: MedialState):
    """The estimate's ``R_IH`` (used by controllers and metrics; same name in the stacked module)."""
    return x.R_I_H
