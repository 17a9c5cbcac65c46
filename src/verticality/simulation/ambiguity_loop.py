"""The sampled closed loop of F §4.5.2 (`ambiguity-*`): the planar head carrying the medial
otolith, a Luenberger observer on its upright linearization (F 4.10) or an EKF on the nonlinear
model, and a PD on the estimate, the head driven by the walking's acceleration.

Everything runs at 10 kHz, the plant by one RK4 step per sample with the walking sampled at the
stage times; the observer is fed the torque and a horizontal acceleration that is known or
reconstructed from the otolith (:data:`KINDS`). F's parameters and the readings of what F leaves
open are in the experiments' docstring (:mod:`verticality.experiments.ambiguity`).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from verticality.analysis import ambiguity as am
from verticality.core.errors import InputError
from verticality.estimators import luenberger as lu
from verticality.estimators.ekf import ExtendedKalmanFilter
from verticality.models.base import Discretized
from verticality.models.linearize import LinearModel, linearize, select_inputs
from verticality.models.params import (
    F452_HEAD_INERTIA_KG_M2,
    F452_OTOLITH_DAMPING_RATIO,
    F452_OTOLITH_NATURAL_HZ,
)
from verticality.models.planar import (
    AccelerationState,
    HeadInput,
    PlanarState,
    TorqueAndVertical,
    WithAccelerationState,
    WithHeadFrameInput,
)
from verticality.models.platform import f44_platform
from verticality.simulation import loop
from verticality.simulation import trajectories as tr

DT_S = 1e-4
SUBSTEPS = 1
OMEGA_N_RAD_S = 2.0 * math.pi * F452_OTOLITH_NATURAL_HZ
HEAD_LOOP_RAD_S = 10.0
THETA0_DEG = 5.0
WALK_T0_S = 2.0  # the walking stimulus from 2 s on: steady gait, after its 1 s start-up
EKF_Q_SIGMAS = (1e-6, 1e-3, 1e-6, 1e-3, 0.05)
EKF_R_RAD = 1e-3
EKF_P0_SIGMAS = (0.1, 1.0, 0.5, 1.0, 3.0)
EKF_GAUSS_MARKOV_TAU_S = 0.2
KINDS = ("known", "luenberger", "luenberger_exact", "ekf", "ekf_gauss_markov")
UNKNOWN_FEEDS = KINDS[1:]


def plant(omega_n_rad_s: float = OMEGA_N_RAD_S,
          damping_ratio: float = F452_OTOLITH_DAMPING_RATIO,
          J_h_kg_m2: float = F452_HEAD_INERTIA_KG_M2) -> WithHeadFrameInput:
    """F §4.5.2's head + otolith (the planar model value, driven by torque and ᴴa); the arguments
    give an internal model with other values (the otolith's natural frequency and damping ratio,
    the head's inertia), defaults F's."""
    return WithHeadFrameInput(f44_platform(
        g_over_l_s2=omega_n_rad_s**2, beta_over_ml2_s=2.0 * damping_ratio * omega_n_rad_s,
        J_h_kg_m2=J_h_kg_m2))


def luenberger_poles(omega_n_rad_s: float = OMEGA_N_RAD_S) -> tuple[float, ...]:
    """The observer's poles, twice the (assumed) sensor's natural frequency: ``−2ω_n·(1, 1.1,
    1.2, 1.3)``."""
    return tuple(-2.0 * omega_n_rad_s * k for k in (1.0, 1.1, 1.2, 1.3))


def pd_gains(J_h_kg_m2: float = F452_HEAD_INERTIA_KG_M2,
             loop_rad_s: float = HEAD_LOOP_RAD_S) -> tuple[float, float]:
    """``(k_p, k_d)`` of a critically damped head loop at ``loop_rad_s`` on the (assumed) head
    inertia: ``(J ω², 2 J ω)``."""
    return J_h_kg_m2 * loop_rad_s**2, 2.0 * J_h_kg_m2 * loop_rad_s


LUENBERGER_POLES = luenberger_poles()
KP_NM_RAD, KD_NMS_RAD = pd_gains()


def linear_model(model: WithHeadFrameInput | None = None) -> LinearModel:
    """F 4.10: ``model`` (default :func:`plant`) linearized at upright; inputs (τ, ᴴa_h), output
    the reading."""
    z = jnp.asarray(0.0)
    model = plant() if model is None else model
    return select_inputs(linearize(model, PlanarState(z, z, z, z), HeadInput(z, z, z)), [0, 1])


def ekf(a_decay_1_s: float = 0.0, model: WithHeadFrameInput | None = None) -> ExtendedKalmanFilter:
    """The EKF on ``model`` (default :func:`plant`) with the horizontal acceleration as a state: a
    random walk (``a_decay_1_s = 0``) or a first-order Gauss–Markov process of time constant
    ``1/a_decay_1_s``."""
    model = Discretized(WithAccelerationState(plant() if model is None else model, a_decay_1_s),
                        substeps=SUBSTEPS, single_input=True)
    return ExtendedKalmanFilter(model=model, Q=jnp.diag(jnp.asarray(EKF_Q_SIGMAS) ** 2),
                                R=jnp.array([[EKF_R_RAD**2]]), reset_jacobian=False)


def walking_head_acceleration(n_steps: int):
    """The walking head's sagittal acceleration in the planar model's components ``(a_h, a_z)``
    at the sample times (n,) and at the RK4 stage times of every sub-step (n, SUBSTEPS, 3)."""
    traj = tr.walking(duration_s=WALK_T0_S + n_steps * DT_S + 1.0)
    h = DT_S / SUBSTEPS
    t = WALK_T0_S + np.arange(n_steps) * DT_S
    stages = (t[:, None, None] + np.arange(SUBSTEPS)[None, :, None] * h
              + np.array([0.0, 0.5, 1.0])[None, None, :] * h)
    a = np.asarray(tr.sample(traj, np.concatenate([t, stages.ravel()])).a_I_m_s2)
    a_h, a_z = -a[:, 0], a[:, 2]  # sagittal: h = −x
    n = t.size
    return (a_h[:n], a_z[:n]), (a_h[n:].reshape(stages.shape), a_z[n:].reshape(stages.shape))


class Series(NamedTuple):
    theta_H: jnp.ndarray
    theta_hat: jnp.ndarray
    omega_H: jnp.ndarray
    omega_hat: jnp.ndarray
    tau: jnp.ndarray
    a_hat: jnp.ndarray
    a_true: jnp.ndarray
    reading: jnp.ndarray


def closed_loop(kind: str, theta0_rad, ref_rad, acc, acc_stages, n_steps: int, obs, disc, filt,
                gains=(KP_NM_RAD, KD_NMS_RAD), noise_rad=None):
    """One closed-loop run (:func:`verticality.simulation.loop.run`) of feed ``kind``
    (:data:`KINDS`) with the Luenberger observer ``obs`` (``disc`` its discretization at
    :data:`DT_S`) or the EKF ``filt``, the PD's ``gains`` ``(k_p, k_d)``; ``noise_rad``
    (n_steps,), if given, is added to the otolith's reading (what the observer, the EKF and the
    reconstruction see); returns :class:`Series` per sample."""
    truth = plant()
    kp, kd = gains
    ekf_fed = kind.startswith("ekf")
    a_h, a_z = (jnp.asarray(v) for v in acc)
    a_h_st, a_z_st = (jnp.asarray(v) for v in acc_stages)
    r0 = am.planar_reading(a_h[0], a_z[0], theta0_rad)
    x0 = PlanarState(theta0_rad + r0, jnp.asarray(0.0), jnp.asarray(theta0_rad, float),
                     jnp.asarray(0.0))
    z = jnp.asarray(0.0)
    e0 = filt.init(AccelerationState(PlanarState(z, z, z, z), z),
                   jnp.diag(jnp.asarray(EKF_P0_SIGMAS) ** 2))
    h = DT_S / SUBSTEPS

    def read(x, k):
        y = truth.output(x)
        return y if noise_rad is None else y + noise_rad[k]

    def correct(est, y, k):
        # the EKF predicts with the previous sample's torque and a_z, then updates with y
        ls, es, u_prev = est
        return (ls, filt.step(es, u_prev, y, DT_S)[0], u_prev) if ekf_fed else est

    def estimate(est):
        """The head's tilt and rate the PD is fed, and the EKF's acceleration state."""
        ls, es, _ = est
        if ekf_fed:
            return es.x.head.theta_H_rad, es.x.head.omega_H_rad_s, es.x.a_h_H_m_s2
        return ls.x[2], ls.x[3], None

    def control(est, y, k):
        # the torque, and the horizontal acceleration the estimate is based on
        th_hat, om_hat, a_hat = estimate(est)
        if kind == "known":
            a_hat = a_h[k]
        elif not ekf_fed:
            a_hat = am.planar_head_acceleration(y[0], a_z[k], th_hat,
                                                small_angle=(kind == "luenberger"))
        return kp * (ref_rad - th_hat) - kd * om_hat, a_hat

    def predict(est, u, y, k):
        ls, es, _ = est
        tau, a_hat = u
        if not ekf_fed:
            ls, _ = obs.step_discrete(ls, jnp.stack([tau, a_hat]), y, disc)
        return ls, es, TorqueAndVertical(tau, a_z[k])

    def f(w, xx):
        return truth.dynamics(xx, w), None

    def advance(x, u, k):
        tau = u[0]
        return loop.rk4_staged_substeps(
            f, lambda i: HeadInput(jnp.broadcast_to(tau, (3,)), a_h_st[k, i], a_z_st[k, i]), x, h,
            SUBSTEPS)

    def record(x, est, y, u, k):
        th_hat, om_hat, _ = estimate(est)
        tau, a_hat = u
        return Series(x.theta_H_rad, th_hat, x.omega_H_rad_s, om_hat, tau, a_hat, a_h[k], y[0])

    parts = loop.LoopParts(read, correct, control, predict, advance, record)
    est0 = (obs.init(jnp.zeros(4)), e0, TorqueAndVertical(z, a_z[0]))
    return loop.run(parts, x0, est0, n_steps)[1]


_closed_loop_batch = jax.jit(
    jax.vmap(closed_loop, in_axes=(None, 0, 0, None, None, None, None, None, None, None, 0)),
    static_argnums=(0, 5))


@jax.jit
def reading_noise_rad(noise_rad, seeds, like):
    """Per run, ``noise_rad`` × standard normal samples of the shape of ``like`` (n_steps,), drawn
    from ``jax.random.PRNGKey(seed)``; at σ = 0 they are −0.0, which added to a reading leaves it
    unchanged to the bit (sign of zero included)."""

    def one(sigma, seed):
        z = jax.random.normal(jax.random.PRNGKey(seed), like.shape)
        return jnp.where(sigma == 0.0, -0.0, sigma * z)

    return jax.vmap(one)(noise_rad, seeds)


def sweep(kind: str, theta0_deg, ref_deg, duration_s: float, walking_scale: float = 1.0, *,
          model: WithHeadFrameInput | None = None, gains=(KP_NM_RAD, KD_NMS_RAD),
          poles=LUENBERGER_POLES, noise_rad=None, seeds=None) -> Series:
    """Runs of ``kind`` for each pair (θ₀, θ_ref) in degrees (arrays of one length), the walking
    acceleration scaled by ``walking_scale`` (0: a head that only rotates); numpy :class:`Series`
    with a leading sweep axis. The internal model ``model`` (default :func:`plant`, the truth's
    value), the observer's ``poles`` and the PD's ``gains`` are those of every run; ``noise_rad``
    and ``seeds`` (arrays of the sweep's length, both or neither) add to each run's reading a white
    noise of σ ``noise_rad`` drawn from its seed (:func:`reading_noise_rad`)."""
    if (noise_rad is None) != (seeds is None):
        raise InputError("ambiguity sweep: give both noise_rad and seeds, or neither")
    n = int(round(duration_s / DT_S))
    acc, acc_st = jax.tree_util.tree_map(lambda v: walking_scale * v, walking_head_acceleration(n))
    th0 = jnp.radians(jnp.asarray(theta0_deg, float))
    ref = jnp.radians(jnp.asarray(ref_deg, float))
    obs = lu.design(linear_model(model), poles)
    filt = ekf(1.0 / EKF_GAUSS_MARKOV_TAU_S if kind == "ekf_gauss_markov" else 0.0, model)
    noise = None
    if noise_rad is not None:
        noise = reading_noise_rad(jnp.asarray(noise_rad, float), jnp.asarray(seeds, jnp.int64),
                                  jnp.zeros(n))
    gains = tuple(jnp.asarray(g, float) for g in gains)
    out = _closed_loop_batch(kind, th0, ref, acc, acc_st, n, obs, obs.discretize(DT_S), filt,
                             gains, noise)
    return Series(*(np.asarray(v) for v in out))
