"""The closed loop of the gimbal platform of F ch. 5 (`platform`): one axis (pitch or roll) of
the platform on its moving base, the inclinometer read every 3 ms, a Luenberger observer on the
axis model linearized at upright (F 4.10) fed the command and a horizontal acceleration (the true
one or the platform accelerometer's), and a saturated PD fed the reading (and its difference
quotient) or the estimate. The plant is integrated by 3 RK4 sub-steps of 1 ms per sample with the
command held. The readings of F behind the numbers are in :mod:`verticality.experiments.platform`.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp

from verticality.core.integrate import rk4_step
from verticality.estimators import luenberger as lu
from verticality.estimators.kalman import ContinuousObserver
from verticality.models import platform as pf
from verticality.models.kinematics import RigidMotion
from verticality.models.linearize import linearize, select_inputs
from verticality.sensors import readings as sensors
from verticality.simulation import loop

LOOP_DT_S = 3e-3
SUBSTEPS = 3
ACC_AMP_M_S2 = 2.0
OBSERVER_POLES = (-150.0, -170.0, -190.0, -210.0)
SIGMA_Y_RAD = 1e-3
SIGMA_ACC_M_S2 = 0.02


def observer_for(axis: pf.PlatformAxis) -> ContinuousObserver:
    """Luenberger observer on the axis model linearized at upright (F 4.10), with the inputs it
    knows: the command u and the acceleration a_h (not the base's rate)."""
    z = jnp.asarray(0.0)
    lin = linearize(axis, pf.AxisState(z, z, z, z), pf.AxisInput(z, z, z))
    return lu.design(select_inputs(lin, [0, 1]), OBSERVER_POLES)


class AxisCfg(NamedTuple):
    p: pf.PlatformAxis
    kp: jnp.ndarray
    kd: jnp.ndarray
    u_max: jnp.ndarray
    base_amp: jnp.ndarray
    base_w: jnp.ndarray
    acc_w: jnp.ndarray
    acc_phase: jnp.ndarray
    obs: ContinuousObserver
    use_observer: jnp.ndarray  # 0.0 sensor, 1.0 observer
    key: jnp.ndarray
    # the observer's a_h: 0.0 the true one (gravity-free; with the accelerometer's offset and
    # lever-arm errors when those are set), 1.0 the accelerometer's reading
    use_accelerometer: jnp.ndarray = 0.0
    acc_bias_m_s2: jnp.ndarray = 0.0  # the accelerometer's constant offset along its axis
    acc_below_pivot_m: jnp.ndarray = 0.0  # its distance below the pivot (F: the lower surface)


def _ramp(t, t0):
    return jnp.clip(t - t0, 0.0, 1.0)


def _drive(cfg: AxisCfg, t, swing_s):
    """Base angular velocity and platform linear acceleration at time t (the two phases)."""
    in_swing = t < swing_s
    r = _ramp(t, 0.0)
    omega_base = jnp.where(in_swing, r * cfg.base_amp * cfg.base_w * jnp.cos(cfg.base_w * t)
                           + (t < 1.0) * cfg.base_amp * jnp.sin(cfg.base_w * t), 0.0)
    a = jnp.where(in_swing, 0.0,
                  _ramp(t, swing_s) * ACC_AMP_M_S2
                  * jnp.sin(cfg.acc_w * (t - swing_s) + cfg.acc_phase))
    return omega_base, a


def accelerometer_reading(key, theta_rad, omega_rad_s, a_h_I_m_s2, omegadot_rad_s2=0.0,
                          bias_m_s2=0.0, below_pivot_m=0.0):
    """The platform accelerometer's reading along the axis' horizontal (F §5.1.1: tri-axial, on
    the platform, axes aligned with the platform's):
    :func:`verticality.sensors.readings.accelerometer` for the platform tilted by θ about its axis
    and its pivot accelerated by ``a_h`` — the specific force ``a_h cos θ + g sin θ`` plus white
    noise of σ :data:`SIGMA_ACC_M_S2` (signs of the inclinometer's apparent tilt
    ``θ + atan2(a_h, g)``: the tilt about y is ``−θ``); with a constant offset ``bias_m_s2`` and
    the sensor ``below_pivot_m`` below the pivot (it then also reads the platform's angular
    acceleration, ``below_pivot_m · ω̇``)."""
    c, s_ = jnp.cos(theta_rad), jnp.sin(theta_rad)
    R_I_B = jnp.array([[c, 0.0, -s_], [0.0, 1.0, 0.0], [s_, 0.0, c]])  # R_y(−θ)
    z = 0.0 * omega_rad_s
    w = jnp.stack([z, -omega_rad_s, z])
    w_dot = jnp.stack([z, -(z + omegadot_rad_s2), z])
    motion = RigidMotion(R_I_B, w, w_dot, jnp.stack([a_h_I_m_s2, 0.0, 0.0]))
    lever = jnp.stack([z, z, -(z + below_pivot_m)])
    bias = jnp.stack([z + bias_m_s2, z, z])
    return sensors.accelerometer(key, motion,
                                 sensors.AccelParams(SIGMA_ACC_M_S2, lever, bias))[0]


def simulate(cfg: AxisCfg, n_loops: int, swing_s: float):
    """One run of the axis' loop (:func:`verticality.simulation.loop.run`); per sample the tilt,
    the reading, the estimate, the base angle, the command, the acceleration and the
    accelerometer's reading."""
    h = LOOP_DT_S / SUBSTEPS
    noise = jax.random.normal(cfg.key, (n_loops,)) * SIGMA_Y_RAD
    acc_keys = jax.random.split(jax.random.fold_in(cfg.key, 1), n_loops)

    def f_plant(t, x, u):
        omega_base, a = _drive(cfg, t, swing_s)
        return cfg.p.dynamics(x, pf.AxisInput(u, a, omega_base))

    def read(plant, k):
        # the inclinometer and the platform accelerometer (the true acceleration beside it); the
        # platform's angular acceleration under the command still held
        x, _, u_held = plant
        t = k * LOOP_DT_S
        _, a_now = _drive(cfg, t, swing_s)
        omega_dot = f_plant(t, x, u_held).omega_rad_s
        a_acc = accelerometer_reading(acc_keys[k], x.theta_rad, x.omega_rad_s, a_now, omega_dot,
                                      cfg.acc_bias_m_s2, cfg.acc_below_pivot_m)
        # the gravity-free feed: the true acceleration with the accelerometer's offset and
        # lever-arm errors (zero unless the configuration sets them), its noise left out
        a_err = a_acc - accelerometer_reading(acc_keys[k], x.theta_rad, x.omega_rad_s, a_now)
        return x.y_rad + noise[k], a_now + a_err, a_acc

    def control(est, y, k):
        ls, y_prev = est
        rate = jnp.where(k > 0, (y[0] - y_prev) / LOOP_DT_S, 0.0)
        th = jnp.where(cfg.use_observer > 0, ls.x[0], y[0])
        om = jnp.where(cfg.use_observer > 0, ls.x[1], rate)
        return jnp.clip(-cfg.kp * th - cfg.kd * om, -cfg.u_max, cfg.u_max)

    def predict(est, u, y, k):
        reading, a_now, a_acc = y
        a_fed = jnp.where(cfg.use_accelerometer > 0, a_acc, a_now)
        return cfg.obs.step(est[0], jnp.array([u, a_fed]), jnp.atleast_1d(reading),
                            LOOP_DT_S)[0], reading

    def advance(plant, u, k):
        # the platform by RK4 sub-steps, the base's angle by the rate at each sub-step's start
        t = k * LOOP_DT_S

        def sub(i, xb):
            xx, bb = xb
            ts = t + i * h
            om_b, _ = _drive(cfg, ts, swing_s)
            return rk4_step(f_plant, ts, xx, h, u), bb + h * om_b

        return (*jax.lax.fori_loop(0, SUBSTEPS, sub, plant[:2]), u)

    def record(plant, est, y, u, k):
        (x, base, _), (reading, a_now, a_acc) = plant, y
        return x.theta_rad, reading, est[0].x[0], base, u, a_now, a_acc

    z = jnp.asarray(0.0)
    parts = loop.LoopParts(read, loop.unchanged, control, predict, advance, record)
    plant0 = (pf.AxisState(z, z, z, z), 0.0, z)
    return loop.run(parts, plant0, (cfg.obs.init(jnp.zeros(4)), 0.0), n_loops)[1]


simulate_batch = jax.jit(jax.vmap(simulate, in_axes=(0, None, None)), static_argnums=(1, 2))
