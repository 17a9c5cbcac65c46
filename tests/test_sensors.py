"""Sensors: statistics of the seeded noise, the specific force, quantization."""

import jax
import jax.numpy as jnp
import numpy as np

from verticality.core import so3
from verticality.models.kinematics import RigidMotion, still
from verticality.models.params import G_M_S2
from verticality.sensors import readings as sensors


def test_gyro_white_noise_and_random_walk_bias():
    p = sensors.GyroParams(noise_std_rad_s=3.2e-3, bias_rw_q_rad2_s3=1e-6)
    dt, n, runs = 0.01, 1000, 400
    keys = jax.random.split(jax.random.PRNGKey(3), runs)
    readings, bias = jax.vmap(lambda k: sensors.gyro_record(k, jnp.zeros((n, 1)), dt, p))(keys)
    noise = np.asarray(readings - bias)
    assert abs(noise.std() / 3.2e-3 - 1.0) < 0.02
    var_end = float(np.var(np.asarray(bias)[:, -1, 0]))
    expected = 1e-6 * dt * (n - 1)  # random walk: variance q·t
    assert abs(var_end / expected - 1.0) < 0.25
    # the same key gives the same record; the one-sample form matches the record's statistics
    r2, _ = sensors.gyro_record(keys[0], jnp.zeros((n, 1)), dt, p)
    np.testing.assert_array_equal(np.asarray(r2), np.asarray(readings[0]))
    b, r = sensors.gyro_step(jax.random.PRNGKey(0), jnp.zeros(3), jnp.ones(3), dt, p)
    assert b.shape == (3,) and np.all(np.abs(np.asarray(r) - 1.0) < 0.02)


def test_accelerometer_specific_force():
    np.testing.assert_allclose(sensors.specific_force_B(still()), [0.0, 0.0, G_M_S2], atol=1e-15)
    theta = 0.3
    f = sensors.specific_force_B(still(so3.rot_x(theta)))
    np.testing.assert_allclose(f, G_M_S2 * np.array([0.0, np.sin(theta), np.cos(theta)]),
                               atol=1e-14)
    # spinning about z at ω with the sensor r along x: centripetal −ω² r along x
    w, r = 2.0, 0.1
    spin = RigidMotion(jnp.eye(3), jnp.array([0.0, 0.0, w]), jnp.zeros(3), jnp.zeros(3))
    f = sensors.specific_force_B(spin, jnp.array([r, 0.0, 0.0]))
    np.testing.assert_allclose(f, [-w * w * r, 0.0, G_M_S2], atol=1e-14)
    acc = sensors.accelerometer(jax.random.PRNGKey(1), still(), sensors.AccelParams(0.05))
    assert 0.0 < float(jnp.max(jnp.abs(acc - jnp.array([0.0, 0.0, G_M_S2])))) < 0.3


def test_quantization_and_inclinometer():
    step = 2 * np.pi / 2**16
    x = jnp.array([0.1, -0.1, 1.2345678, 10.0, jnp.nan])
    q = np.asarray(sensors.quantize(x, 16, np.pi))
    assert np.all(np.abs(q[:3] - np.asarray(x[:3])) <= step / 2 + 1e-15)
    np.testing.assert_allclose(q[:3] / step, np.round(q[:3] / step), atol=1e-9)
    assert q[3] == np.pi - step  # clipped to full scale
    assert np.isnan(q[4])  # a missing sample stays missing
    y = sensors.inclinometer(jax.random.PRNGKey(0), jnp.zeros(20000), noise_std_rad=1e-4)
    assert abs(float(jnp.std(y)) / 1e-4 - 1.0) < 0.03
