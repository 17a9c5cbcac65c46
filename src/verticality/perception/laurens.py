"""The Laurens & Angelaki 2017 Kalman-filter model of self-motion perception (passive motion),
reimplemented from its equations.

The model's two linear variants (one axis, time step δt, motion variables drawn afresh each step):

*Yaw (velocity storage)* — states ``X = (Ω, C)``: head angular velocity and the canal's internal
state; sensory signal ``V`` (canal)::

    Ω_t = Ωε_t                                  (σΩ: passive rotation is unpredictable)
    C_t = k₁ C_{t−1} + k₂ Ω_t                   (first-order canal, τc: k₁ = τc/(τc + δt),
                                                 k₂ = δt/(τc + δt), the implicit step; the
                                                 authors' reading, models.canal)
    V_t = Ω_t − C_t + Vη_t                      (σV)

*Tilt and translation* (pitch or roll) — states ``X = (Ω, C, G, A)``: adds the tilt G (integral of
Ω, rad) and the linear acceleration A (white, σA, in g); the otolith signal is the GIF
``F_t = G_t + A_t + Fη_t`` (σF, small-angle, in g).

Every time constant of the percepts emerges from the filter: the gains are the steady-state
Kalman gains of these discrete models, from their own discrete Riccati equation
(:func:`verticality.estimators.kalman.discrete_steady_gain`); nothing else is tuned.

3-D reading (ours; the paper's variants are one-axis): the state carries a unit gravity vector
``ĝ`` (head frame, pointing down) instead of G, and the 3-vectors Ω̂, Ĉ, Â (Â in g). Each sample:

    predicted:   Ω^p = 0,  C^p = k₁ Ĉ,  ĝ^p = ĝ,  A^p = 0
    errors:      δV = V − (Ω^p − C^p),   δF = F − (ĝ^p − A^p)     (F = g − a, in g)
    split:       δV∥ = (ĝ·δV) ĝ (rotation about gravity: the yaw variant),  δV⊥ = δV − δV∥;
                 e_F = δF × ĝ (the otolith error as a tilt, rad; the tilt variant's δF),
                 δF∥ = ĝ·δF (along gravity: only A explains it)
    update:      Ω̂ = k_ΩV^yaw δV∥ + k_ΩV δV⊥ + k_ΩF e_F
                 Ĉ = C^p + k_CV^yaw δV∥ + k_CV δV⊥ + k_CF e_F
                 ĝ = exp(−[k_GV δV⊥ + k_GF e_F]×) ĝ^p
                 Â = (k_AV δV⊥ + k_AF e_F) × ĝ − k_A∥ δF∥ ĝ,   k_A∥ = σA²/(σA² + σF²)

so that for rotations about gravity the yaw filter acts, for tilts the tilt/translation filter, and
the tilt stays a rotation (|ĝ| = 1): a held 0.2 g acceleration ends at atan(0.2), not 0.2 rad. The
perceived velocity integrates Â: ``v̂_t = v̂_{t−1} + δt (g₀ Â − Ω̂ × v̂_{t−1})`` (head frame, m/s).

Estimator interface (:mod:`verticality.estimators.base`): ``y = (V (3), F (3))``; ``u`` is not
used; ``dt`` should be the design step δt (the gains are those of δt; the canal prediction uses
the ``dt`` given). A NaN component of ``y`` contributes no error (its innovation is zero);
``measured`` flags the six components; an all-NaN ``y`` is :meth:`LaurensAngelaki.predict`.
"""

from __future__ import annotations

from typing import NamedTuple

import jax.numpy as jnp
import numpy as np

from verticality.core import so3
from verticality.core.constants import G_M_S2
from verticality.estimators.base import keep_finite, scan_steps, split_measurement
from verticality.estimators.kalman import discrete_steady_gain
from verticality.models import canal
from verticality.models.base import model_dataclass
from verticality.perception.params import LaurensParams


def yaw_model(p: LaurensParams):
    """``(D, T, Q, R)`` of the yaw variant: ``X_t = D X_{t−1} + ε``, ``S_t = T X_t + η``."""
    a, b = canal.implicit_euler_coefficients(p.tau_c_s, p.dt_s)
    D = np.diag([0.0, a])
    E = np.array([[1.0], [b]])
    return (D, np.array([[1.0, -1.0]]), E @ E.T * p.sigma_omega_rad_s**2,
            np.array([[p.sigma_v_rad_s**2]]))


def tilt_model(p: LaurensParams):
    """``(D, T, Q, R)`` of the tilt/translation variant, states (Ω, C, G, A), signals (V, F)."""
    (a, b), dt = canal.implicit_euler_coefficients(p.tau_c_s, p.dt_s), p.dt_s
    D = np.diag([0.0, a, 1.0, 0.0])
    E = np.array([[1.0, 0.0], [b, 0.0], [dt, 0.0], [0.0, 1.0]])  # columns: Ωε, Aε
    Q = E @ np.diag([p.sigma_omega_rad_s**2, p.sigma_a_g**2]) @ E.T
    T = np.array([[1.0, -1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 1.0]])
    return D, T, Q, np.diag([p.sigma_v_rad_s**2, p.sigma_f_g**2])


def steady_gain(D, T, Q, R) -> np.ndarray:
    """The steady-state Kalman gain ``K = P Tᵀ (T P Tᵀ + R)⁻¹`` of ``X_t = D X_{t−1} + ε``,
    ``S_t = T X_t + η`` (P the predicted covariance, from the discrete Riccati equation)."""
    return np.asarray(discrete_steady_gain(D, T, Q, R)[0])


class LaurensState(NamedTuple):
    g_H: jnp.ndarray  # (3,) perceived gravity (unit, down), head frame
    omega_H_rad_s: jnp.ndarray  # (3,) Ω̂
    c_rad_s: jnp.ndarray  # (3,) Ĉ
    a_H_g: jnp.ndarray  # (3,) Â, in g
    v_H_m_s: jnp.ndarray  # (3,) perceived velocity


class LaurensOut(NamedTuple):
    g_H: jnp.ndarray
    omega_H_rad_s: jnp.ndarray
    a_H_m_s2: jnp.ndarray
    v_H_m_s: jnp.ndarray
    measured: jnp.ndarray  # (6,) bool


@model_dataclass
class LaurensAngelaki:
    """The filter as an estimator value (build it with :func:`laurens_angelaki`)."""

    tau_c_s: jnp.ndarray
    K_yaw: jnp.ndarray  # (2, 1): rows Ω, C
    K_tilt: jnp.ndarray  # (4, 2): rows Ω, C, G, A; columns V, F
    k_a_parallel: jnp.ndarray

    def init(self, x0=None, P0=None) -> LaurensState:
        if x0 is None:
            z = jnp.zeros(3)
            return LaurensState(jnp.array([0.0, 0.0, -1.0]), z, z, z, z)
        return LaurensState(*(jnp.asarray(v, dtype=jnp.float64) for v in x0))

    def predict(self, state: LaurensState, u, dt) -> LaurensState:
        return self.step(state, u, jnp.full(6, jnp.nan), dt)[0]

    def step(self, state: LaurensState, u, y, dt):
        y_safe, measured = split_measurement(y)
        c_p = canal.implicit_euler_coefficients(self.tau_c_s, dt)[0] * state.c_rad_s
        g = state.g_H / jnp.linalg.norm(state.g_H)
        dV = jnp.where(measured[:3], y_safe[:3] + c_p, 0.0)
        dF = jnp.where(measured[3:], y_safe[3:] - g, 0.0)
        dV_par = jnp.dot(g, dV) * g
        dV_perp = dV - dV_par
        e_F = jnp.cross(dF, g)
        dF_par = jnp.dot(g, dF)
        K, Ky = self.K_tilt, self.K_yaw
        omega = Ky[0, 0] * dV_par + K[0, 0] * dV_perp + K[0, 1] * e_F
        c = c_p + Ky[1, 0] * dV_par + K[1, 0] * dV_perp + K[1, 1] * e_F
        g_new = so3.quat_rotate(so3.quat_exp(-(K[2, 0] * dV_perp + K[2, 1] * e_F)), g)
        a = jnp.cross(K[3, 0] * dV_perp + K[3, 1] * e_F, g) - self.k_a_parallel * dF_par * g
        v = state.v_H_m_s + dt * (G_M_S2 * a - jnp.cross(omega, state.v_H_m_s))
        new, _ = keep_finite(LaurensState(g_new, omega, c, a, v), state)
        return new, LaurensOut(new.g_H, new.omega_H_rad_s, G_M_S2 * new.a_H_g, new.v_H_m_s,
                               measured)

    def run(self, state: LaurensState, us, ys, dts):
        return scan_steps(self.step, state, us, ys, dts)


def laurens_angelaki(p: LaurensParams) -> LaurensAngelaki:
    """The filter for the parameters ``p`` (presets in :mod:`verticality.perception.params`)."""
    return LaurensAngelaki(
        tau_c_s=jnp.asarray(p.tau_c_s),
        K_yaw=jnp.asarray(steady_gain(*yaw_model(p))),
        K_tilt=jnp.asarray(steady_gain(*tilt_model(p))),
        k_a_parallel=jnp.asarray(p.sigma_a_g**2 / (p.sigma_a_g**2 + p.sigma_f_g**2)),
    )
