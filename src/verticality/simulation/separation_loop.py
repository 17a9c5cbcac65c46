"""The closed loops of F §4.4 (`separation`): the platform carrying the medial inclinometer, its
pivot accelerated along the platform's forward axis, a PD fed the inclinometer, the true state, a
Luenberger observer or a Kalman filter on the upright linearization (F 4.10), 1 ms samples with
one RK4 step of the plant each; and the Luenberger-fed loop on the lateral model (two
inclinometers at ±r, F 2.18–2.19). The readings of F behind the numbers are in
:mod:`verticality.experiments.separation`.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp

from verticality.core.integrate import rk4_step_staged
from verticality.estimators import kalman as kf
from verticality.models.inclinometer import F44_BETA_OVER_ML2_S, F44_G_OVER_L_S2
from verticality.models.linearize import LinearModel, linearize, select_inputs
from verticality.models.otolith_head import PlanarLateral, PlanarLateralState
from verticality.models.params import LATERAL_R_M
from verticality.models.planar import (
    HeadInput,
    PlanarInput,
    PlanarState,
    WithHeadFrameInput,
    head_frame_to_inertial,
)
from verticality.models.platform import f44_platform
from verticality.simulation import loop

KP, KD = 1.0, 0.1
THETA0_RAD = 0.4
A_AMP_M_S2, A_FREQ_RAD_S = 3.0, 10.0
DT_S = 1e-3
SIGMA_Y_RAD = 5e-3
SIGMA_TAU_NM = 2e-3
#: what the PD is fed, in the order of :attr:`Config.feed`'s index
FEEDS = ("sensor", "state", "luenberger", "kalman")


def head_accel_m_s2(t):
    """ᴴa: pivot acceleration along the platform's forward axis (F §4.4.3)."""
    return A_AMP_M_S2 * jnp.sin(A_FREQ_RAD_S * t)


def plant(scale: float = 1.0) -> WithHeadFrameInput:
    """The platform driven by torque and head-frame acceleration, for a model whose g/l, β/(ml²)
    and J_h are multiplied by ``scale`` (1: the truth)."""
    return WithHeadFrameInput(f44_platform(g_over_l_s2=F44_G_OVER_L_S2 * scale,
                                           beta_over_ml2_s=F44_BETA_OVER_ML2_S * scale,
                                           J_h_kg_m2=1e-4 * scale))


def linear_model(scale: float = 1.0) -> LinearModel:
    """F 4.10: :func:`plant` linearized at upright; inputs (τ, ᴴa_h) (ᴴa_z is zero here),
    output the reading."""
    z = jnp.asarray(0.0)
    lin = linearize(plant(scale), PlanarState(z, z, z, z), HeadInput(z, z, z))
    return select_inputs(lin, [0, 1])


def kalman_design(model: LinearModel) -> kf.KalmanFilter:
    Bt = model.B[:, :1]
    Q = Bt @ Bt.T * SIGMA_TAU_NM**2 * DT_S + 1e-2 * jnp.eye(4)
    R = jnp.array([[SIGMA_Y_RAD**2 * DT_S]])
    return kf.kalman_filter(model.A, model.B, model.C, model.D, Q, R)


class Config(NamedTuple):
    ref_rad: jnp.ndarray
    feed: jnp.ndarray  # index into FEEDS
    noise: jnp.ndarray  # 0 or 1
    obs: kf.ContinuousObserver
    kfilt: kf.KalmanFilter
    key: jnp.ndarray


def simulate(cfg: Config, n_steps: int, truth: WithHeadFrameInput):
    """One closed-loop run (:func:`verticality.simulation.loop.run`); returns time series (θ_H,
    θ̂_H of the fed estimator, all estimates, y)."""
    x0 = jnp.array([0.0, 0.0, THETA0_RAD, 0.0])  # (θ_S, ω_S, θ_H, ω_H) stacked (see f_plant)
    l_state = cfg.obs.init(jnp.zeros(4))
    P0 = jnp.diag(jnp.array([0.1, 10.0, 0.5, 10.0])) ** 2
    k_state = cfg.kfilt.init(jnp.zeros(4), P0)
    noise = jax.random.normal(cfg.key, (n_steps, 2)) * cfg.noise

    def f_plant(w, x):
        # the model on the stacked state vector: XLA rounds a 4-vector's RK4 the same way from
        # one compilation to the next, four separate scalars not necessarily
        return jnp.stack(truth.dynamics(PlanarState(*x), w)), None

    def read(x, k):
        # the inclinometer, and the state itself for the "state" feed
        return truth.output(PlanarState(*x)) + SIGMA_Y_RAD * noise[k, 0], x

    def correct(est, y, k):
        # the Kalman filter predicts with the previous sample's control
        ls, ks, tilt_meas_prev, u_prev = est
        return ls, cfg.kfilt.step(ks, u_prev, y[0], DT_S)[0], tilt_meas_prev, u_prev

    def control(est, y, k):
        ls, ks, tilt_meas_prev, _ = est
        (reading, x), a_now = y, head_accel_m_s2(k * DT_S)
        tilt_meas = -reading[0]
        rate_meas = jnp.where(k > 0, (tilt_meas - tilt_meas_prev) / DT_S, 0.0)
        th = jnp.stack([tilt_meas, x[2], ls.x[2], ks.x[2]])
        om = jnp.stack([rate_meas, x[3], ls.x[3], ks.x[3]])
        tau = KP * (cfg.ref_rad - th[cfg.feed]) - KD * om[cfg.feed]
        return jnp.array([tau, a_now]), tilt_meas

    def predict(est, u, y, k):
        ls, ks, _, _ = est
        u_known, tilt_meas = u
        return cfg.obs.step(ls, u_known, y[0], DT_S)[0], ks, tilt_meas, u_known

    def advance(x, u, k):
        t = k * DT_S
        tau_true = u[0][0] + SIGMA_TAU_NM * noise[k, 1]
        # the acceleration at the RK4 stages (t, t + h/2, t + h), the torque held
        a_stages = jnp.stack([head_accel_m_s2(t), head_accel_m_s2(t + 0.5 * DT_S),
                              head_accel_m_s2(t + DT_S)])
        stages = HeadInput(jnp.broadcast_to(tau_true, (3,)), a_stages, jnp.zeros(3))
        return rk4_step_staged(f_plant, stages, x, DT_S)[0]

    def record(x, est, y, u, k):
        ls, ks, _, _ = est
        (u_known, tilt_meas) = u
        return x[2], ls.x[2], ks.x[2], tilt_meas, u_known[0]

    parts = loop.LoopParts(read, correct, control, predict, advance, record)
    est0 = (l_state, k_state, 0.0, jnp.zeros(2))
    return loop.run(parts, x0, est0, n_steps)[1]


simulate_batch = jax.jit(jax.vmap(simulate, in_axes=(0, None, None)), static_argnums=1)


def lateral_plant(euler: float = 0.0, r_m: float = LATERAL_R_M) -> PlanarLateral:
    """F 2.18–2.19 in the plane: the platform of :func:`plant` carrying two inclinometers at
    ±5 cm on its horizontal axis (the lateral model); tilting about the axis normal to the line
    through both pivots, so their transport accelerations are opposite. ``euler = 0``: F 2.19 as
    printed (centripetal term only, F 2.12 neglects the Euler term); 1: the full model."""
    return PlanarLateral(params=f44_platform(), r_m=r_m, euler=euler)


def lateral_linear_model() -> LinearModel:
    """F 4.10 for the lateral model: linearized at upright; inputs (τ, a_h); outputs both
    readings."""
    z = jnp.asarray(0.0)
    lin = linearize(lateral_plant(), PlanarLateralState(*([z] * 6)), PlanarInput(z, z, z))
    return select_inputs(lin, [0, 1])

def simulate_lateral(ref_rad, obs: kf.ContinuousObserver, euler, r_m, n_steps: int):
    """The Luenberger-fed PD of :func:`simulate` on the lateral plant with pivots at ±``r_m``
    (nominal, no noise; :func:`verticality.simulation.loop.run`); returns (θ_H, θ̂_H) every
    1 ms."""
    truth = lateral_plant(euler, r_m)
    x0 = PlanarLateralState(*(jnp.asarray(v) for v in (0.0, 0.0, 0.0, 0.0, THETA0_RAD, 0.0)))

    def f_plant(w, x):
        tau, a_h_H = w
        a_h_I, a_z_I = head_frame_to_inertial(a_h_H, 0.0, x.theta_H_rad)
        return truth.dynamics(x, PlanarInput(tau, a_h_I, a_z_I)), None

    def control(ls, y, k):
        return KP * (ref_rad - ls.x[4]) - KD * ls.x[5]

    def predict(ls, tau, y, k):
        return obs.step(ls, jnp.array([tau, head_accel_m_s2(k * DT_S)]), y, DT_S)[0]

    def advance(x, tau, k):
        t = k * DT_S
        a_stages = jnp.stack([head_accel_m_s2(t), head_accel_m_s2(t + 0.5 * DT_S),
                              head_accel_m_s2(t + DT_S)])
        return rk4_step_staged(f_plant, (jnp.broadcast_to(tau, (3,)), a_stages), x, DT_S)[0]

    def record(x, ls, y, tau, k):
        return x.theta_H_rad, ls.x[4]

    parts = loop.LoopParts(lambda x, k: truth.output(x), loop.unchanged, control, predict,
                           advance, record)
    return loop.run(parts, x0, obs.init(jnp.zeros(6)), n_steps)[1]


simulate_lateral_batch = jax.jit(jax.vmap(simulate_lateral, in_axes=(0, None, 0, 0, None)),
                                  static_argnums=4)
