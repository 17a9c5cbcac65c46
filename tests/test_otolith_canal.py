"""Tahboub's otolith–canal filter (T eq. 1–13, 20–22) and the ground estimate (T eq. 14–15)."""

import jax
import jax.numpy as jnp
import numpy as np

from verticality.estimators import otolith_canal
from verticality.estimators.ground import ground_from_states
from verticality.experiments.tahboub import estimate_lean, sensor_readings, servo_response
from verticality.models import tahboub


def test_steady_state_gain_equals_t_eq_22_to_printed_digits():
    L = otolith_canal.steady_state_gain()
    pub = tahboub.TAHBOUB_GAIN_PUBLISHED
    rel = np.abs(L - pub) / np.abs(pub)
    assert np.all(rel <= 0.05), rel
    assert np.all(np.sign(L) == np.sign(pub))


def test_steady_state_filter_equals_time_varying_after_convergence():
    fs, dt = 100.0, 0.01
    t = np.arange(int(200 * fs)) / fs
    phi, phid, phidd = servo_response(np.radians(5.0) * np.sin(2 * np.pi * 0.2 * t), fs)
    ys, _ = sensor_readings(jax.random.PRNGKey(3), phi, phid, phidd, fs)
    tv = otolith_canal.time_varying_filter()
    ss = otolith_canal.discrete_steady_state_filter(dt)
    _, o_tv = tv.run(tv.init(jnp.zeros(3), jnp.eye(3) * 1e-6), None, ys, dt)
    _, o_ss = ss.run(ss.init(jnp.zeros(3)), None, ys, dt)
    d = np.abs(np.asarray(o_tv.x[:, 0] - o_ss.x[:, 0]))
    assert d[t < 10].max() > 1e-3  # different before the covariance converges (P0 far off)
    k0 = int(160 * fs)
    np.testing.assert_allclose(o_tv.K[k0], ss.K, rtol=1e-3, atol=1e-12)
    # From there on the two are the same filter: restarted from the same state they agree.
    _, o_ss2 = ss.run(ss.init(o_tv.x[k0]), None, ys[k0 + 1:], dt)
    assert np.abs(np.asarray(o_ss2.x[:, 0] - o_tv.x[k0 + 1:, 0])).max() < 1e-5
    # The continuous form of T eq. 9 (static CARE gain) gives nearly the same lean at 100 Hz.
    x_c = np.asarray(estimate_lean(ys, fs, "steady"))
    late = t >= 160
    amp = np.sqrt(np.mean(np.asarray(phi)[late] ** 2))
    assert np.sqrt(np.mean((x_c[late, 0] - np.asarray(o_ss.x[late, 0])) ** 2)) < 0.03 * amp


def test_filter_tracks_a_still_tilt_from_the_accelerometer():
    """A constant 3° lean, gyro silent: φ̂ must converge to 3° (the otolith part of the fusion)."""
    fs, n = 100.0, 40000
    a = 9.81 * np.sin(np.radians(3.0))
    ys = np.tile([0.0, a], (n, 1))
    x = np.asarray(estimate_lean(jnp.asarray(ys), fs, "steady"))
    assert abs(np.degrees(x[-1, 0]) - np.degrees(np.arcsin(a / 9.81))) < 0.05
    assert abs(x[-1, 2]) < 1e-4  # no drift inferred


def test_ground_from_filter_is_t_eq_14_15():
    x_hat = jnp.array([[0.3, 0.05, 0.0]])
    joints = jnp.array([[0.1, 0.15, 0.02, 0.01]])
    g = ground_from_states(x_hat, joints)
    np.testing.assert_allclose(g.theta1_rad, [0.05], atol=1e-15)
    np.testing.assert_allclose(g.theta1_dot_rad_s, [0.02], atol=1e-15)
