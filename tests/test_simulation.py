"""Closed-loop simulator: plug-in API, conditions, SO(3), cross-checks with the gimbal module and
with the open-loop replay of the `otolith` command."""

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from verticality.core import so3
from verticality.models import gimbal
from verticality.models.gimbal_plant import gimbal_plant
from verticality.models.head import HeadInput
from verticality.models.params import P13_HEAD, P13_PENDULUM, PendulumParams, lateral_pendulums
from verticality.models.pendulum import Pendulum
from verticality.simulation import closed_loop as sim
from verticality.simulation import trajectories as tr


class Probe(NamedTuple):
    """A do-nothing estimator that keeps what the simulator hands it (the plug-in API)."""

    ticks: jnp.ndarray
    u: HeadInput
    y: jnp.ndarray
    dt: jnp.ndarray


def _probe_step(state, u, y, dt):
    new = Probe(state.ticks + 1, u, y, jnp.asarray(dt, float))
    return new, new


PROBE = sim.Estimator(step=_probe_step, R_I_H=lambda s: jnp.eye(3))
PROBE0 = Probe(jnp.array(0), HeadInput(jnp.zeros((4, 3)), jnp.zeros((4, 3))), jnp.zeros(5),
               jnp.array(0.0))


def test_fixed_condition_api_so3_and_replay_cross_check():
    traj = tr.impact(duration_s=6.0)
    cfg = sim.SimConfig(duration_s=6.0, condition="fixed", u_blocks=4)
    run = sim.make_simulator(traj, cfg, estimator=PROBE)
    res = run(jax.random.PRNGKey(0), sim.DEFAULT_PLANT, sim.noiseless(), PROBE0)
    rec = res.record
    assert rec.t_s.shape == (300,) and float(rec.t_s[-1]) == 6.0
    assert int(res.final_estimator.ticks) == 300
    np.testing.assert_allclose(rec.estimator_out.dt, 0.02)
    # y = (otolith angles, gyro) at the tick; noiseless here
    np.testing.assert_allclose(rec.y[:, :2], rec.otolith_rad[:, 0], atol=1e-15)
    truth = tr.sample(traj, np.asarray(rec.t_s))
    np.testing.assert_allclose(rec.y[:, 2:], truth.omega_B_rad_s, atol=1e-15)
    np.testing.assert_allclose(rec.R_I_H, truth.R_I_B, atol=1e-15)  # fixed: head = trunk
    # u: block means of (τ_H, a_I) over each 5 ms quarter of the 20 ms interval
    t_mid = np.asarray(rec.t_s)[100] - 0.02 + 0.005 * (np.arange(4) + 0.5)
    a_mid = np.asarray(tr.sample(traj, t_mid).a_I_m_s2)
    np.testing.assert_allclose(rec.u.a_I_m_s2[100], a_mid, atol=5e-3)
    assert rec.u.tau_H_Nm.shape == (300, 4, 3)
    # the tilt error is that of the probe's identity estimate
    np.testing.assert_allclose(rec.tilt_error_deg,
                               so3.tilt_error_deg(rec.R_I_H,
                                                  jnp.broadcast_to(jnp.eye(3), (300, 3, 3))),
                               atol=1e-12)
    # pendulum stays on SO(3) through the spike
    assert float(so3.orthonormality_error(res.final_plant.pendula[0].R_I_S)) < 1e-9
    # the open-loop replay (the `otolith` command's integrator) of the same motion agrees
    t_rows = np.arange(0, 6001) * 1e-3
    m = tr.sample(traj, t_rows)
    _, phi = sim.otolith_replay(t_rows, so3.quat_from_matrix(m.R_I_B), m.omega_B_rad_s,
                                m.a_I_m_s2, (Pendulum(PendulumParams()),))
    np.testing.assert_allclose(phi[20::20, 0], rec.otolith_rad[:, 0], atol=2e-4)

    # a vmapped batch over keys, with noise: the same truth, different measurements
    keys = jax.random.split(jax.random.PRNGKey(7), 2)
    batch = sim.simulate_batch(run, keys, sim.DEFAULT_PLANT, sim.NoiseParams(), PROBE0)
    np.testing.assert_allclose(batch.record.R_I_H[1], rec.R_I_H, atol=1e-15)
    noise = np.asarray(batch.record.y[0] - batch.record.y[1])
    # P13: σ = 0.02 on every channel; 1500 samples put the estimate within ±0.0004 (1σ)
    assert 0.018 < noise.std() / np.sqrt(2) < 0.022
    np.testing.assert_allclose(batch.record.y[0, :, :2] - rec.otolith_rad[:, 0], 0.0, atol=0.12)


def test_stabilized_truth_feedback_brings_head_upright():
    R_trunk = so3.rot_x(0.25) @ so3.rot_y(-0.15)
    traj = tr.still(3.0, R_trunk)
    cfg = sim.SimConfig(duration_s=3.0, condition="stabilized", record_control=True)
    run = sim.make_simulator(traj, cfg, controller=sim.p13_controller(), theta0_rad=jnp.zeros(2))
    res = run(jax.random.PRNGKey(0), sim.DEFAULT_PLANT, sim.noiseless())
    tilt0 = float(so3.tilt_error_deg(jnp.eye(3), res.control.R_I_H[0]))
    assert tilt0 > 10.0  # starts with the trunk's tilt (θ0 = 0)
    final_tilt = float(so3.tilt_error_deg(jnp.eye(3), res.record.R_I_H[-1]))
    assert final_tilt < 0.05
    theta_d = gimbal.joint_angles_for_up(so3.up_in_frame(R_trunk))
    np.testing.assert_allclose(res.record.theta_rad[-1], theta_d, atol=1e-3)
    # the otolith reads the head's (small) tilt: φ → 0 once upright
    assert float(jnp.max(jnp.abs(res.record.otolith_rad[-1]))) < 2e-3
    assert res.control.t_s.shape == (3000,)
    np.testing.assert_allclose(res.record.tilt_error_deg, 0.0, atol=1e-6)  # truth-fed


def test_sensors_draw_the_documented_random_numbers():
    """The measurements are the sensors module's readings with the keys of the simulator's scheme:
    per estimator tick k, ``k_ctrl, key_k = split(fold_in(key, k))`` (the control ticks' gyro
    noise from k_ctrl, drawn at once), ``k_phi, k_gyro, k_bias = split(key_k, 3)``."""
    from verticality.sensors import readings as sensors

    traj = tr.impact(duration_s=0.2)
    noise = sim.NoiseParams(otolith_std_rad=0.02,
                            gyro=sensors.GyroParams(noise_std_rad_s=0.01, bias_rw_q_rad2_s3=0.5))
    plant = gimbal_plant(P13_HEAD, lateral_pendulums(P13_PENDULUM))
    run = sim.make_simulator(traj, sim.SimConfig(duration_s=0.2, condition="fixed", u_blocks=4),
                             estimator=PROBE)
    key = jax.random.PRNGKey(5)
    p0 = Probe(jnp.array(0), HeadInput(jnp.zeros((4, 3)), jnp.zeros((4, 3))), jnp.zeros(7),
               jnp.array(0.0))
    rec = run(key, plant, noise, p0, jnp.array([0.1, -0.2, 0.3])).record
    truth = tr.sample(traj, np.asarray(rec.t_s))
    bias = jnp.array([0.1, -0.2, 0.3])
    for k in range(3):
        _, key_k = jax.random.split(jax.random.fold_in(key, k))
        k_phi, k_gyro, k_bias = jax.random.split(key_k, 3)
        phi = sensors.inclinometer(k_phi, rec.otolith_rad[k], noise.otolith_std_rad)
        gyro = sensors.gyro_reading(truth.omega_B_rad_s[k], bias,
                                    sensors.gyro_white_noise(k_gyro, (3,), noise.gyro))
        # equal to rounding (the jitted run may fuse a + σ·n); another draw would differ by ~σ
        np.testing.assert_allclose(rec.y[k], jnp.concatenate([phi.reshape(-1), gyro]), rtol=1e-14,
                                   atol=1e-16)
        bias = sensors.gyro_bias_step(k_bias, bias, 0.02, noise.gyro)
    assert rec.y.shape == (10, 7)  # two pendula (lateral), then the gyro
    assert not np.allclose(rec.otolith_rad[:, 0], rec.otolith_rad[:, 1], atol=1e-9)
