"""Trajectories: exact, mutually consistent kinematics and the published stimulus shapes."""

import math

import jax
import jax.numpy as jnp
import numpy as np

from verticality.core import so3
from verticality.models.lissajous import lissajous_trunk
from verticality.models.params import G_M_S2
from verticality.simulation import trajectories as tr


def _finite_difference_check(traj, times, h=1e-4):
    """ω, a from autodiff against central differences of R and p."""
    ts = np.concatenate([times - h, times, times + h])
    m = tr.sample(traj, ts)
    p = np.asarray(tr.positions(traj, ts))
    n = len(times)
    R = np.asarray(m.R_I_B)
    R_dot = (R[2 * n:] - R[:n]) / (2 * h)
    omega_fd = np.asarray(so3.vee(np.swapaxes(R[n:2 * n], -1, -2) @ R_dot))
    a_fd = (p[2 * n:] - 2 * p[n:2 * n] + p[:n]) / h**2
    w = np.asarray(m.omega_B_rad_s)
    wdot_fd = (w[2 * n:] - w[:n]) / (2 * h)
    np.testing.assert_allclose(w[n:2 * n], omega_fd, atol=1e-6)
    np.testing.assert_allclose(np.asarray(m.a_I_m_s2)[n:2 * n], a_fd, atol=2e-3)
    np.testing.assert_allclose(np.asarray(m.omegadot_B_rad_s2)[n:2 * n], wdot_fd, atol=1e-5)
    assert np.max(so3.orthonormality_error(R)) < 1e-12


def test_impact_kinematics_consistent_spike_and_stop():
    traj = tr.impact()
    _finite_difference_check(traj, np.array([0.7, 2.3, 4.1, 5.5]))
    ts = np.linspace(4.8, 5.2, 4001)
    m = tr.sample(traj, np.concatenate([ts, [7.0, 9.9]]))
    a = np.asarray(m.a_I_m_s2)
    peak = np.max(np.linalg.norm(a[:-2], axis=1))
    assert 28.0 < peak < 33.0  # the 30 m/s² spike (plus the oscillation's own acceleration)
    assert abs(np.max(a[:-2, 0]) - 30.0) < 2.0
    assert abs(ts[np.argmax(np.abs(a[:-2, 0]))] - 5.0) < 0.05  # at t = 5 s
    # stopped: at rest and upright after the deceleration
    np.testing.assert_allclose(a[-2:], 0.0, atol=1e-12)
    np.testing.assert_allclose(np.asarray(m.omega_B_rad_s)[-2:], 0.0, atol=1e-12)
    np.testing.assert_allclose(np.asarray(m.R_I_B)[-1], np.eye(3), atol=1e-12)
    m0 = jax.jit(traj.motion)(0.0)  # starts at rest
    assert float(jnp.max(jnp.abs(m0.a_I_m_s2))) < 1e-12


def test_jump_free_fall_landing_and_rest():
    traj = tr.jump()
    ev = traj.events
    m = tr.sample(traj, np.array([ev["apex_s"], 0.5, traj.duration_s - 0.1]))
    a = np.asarray(m.a_I_m_s2)
    np.testing.assert_allclose(a[0], [0.0, 0.0, -G_M_S2], atol=1e-5)  # free fall
    np.testing.assert_allclose(a[1:], 0.0, atol=1e-9)  # before and after: at rest
    p = np.asarray(tr.positions(traj, np.array([0.0, ev["apex_s"], traj.duration_s])))
    np.testing.assert_allclose(p[-1], [0.8, 0.0, 0.0], atol=1e-9)  # forward 0.8 m, same height
    assert p[1, 2] > 0.2  # airborne
    ts = np.linspace(ev["touchdown_s"] - 0.05, ev["touchdown_s"] + 0.2, 5001)
    az = np.asarray(tr.sample(traj, ts).a_I_m_s2)[:, 2]
    assert abs(az.max() - 30.0) < 0.01  # the landing spike (net of the fading −g)
    _finite_difference_check(traj, np.array([1.0, ev["landing_peak_s"]]))


def test_lissajous_is_p11():
    traj = tr.lissajous()
    t0 = np.array([0.3, 1.7])
    np.testing.assert_allclose(np.asarray(lissajous_trunk(t0)),
                               0.25 * np.stack([np.sin(0.5 * np.pi * t0), np.sin(np.pi * t0),
                                                np.pi * np.sin(2 * np.pi * t0)]), atol=1e-15)
    t = np.array([0.3, 1.7, 4.2])
    m = tr.sample(traj, t)
    p = np.asarray(tr.positions(traj, t))
    np.testing.assert_allclose(p[:, 1], 0.25 * np.sin(0.5 * np.pi * t), atol=1e-14)
    np.testing.assert_allclose(p[:, 2], 0.25 * np.sin(np.pi * t), atol=1e-14)
    theta = np.asarray(so3.tilt_angles(m.R_I_B))[:, 0]
    np.testing.assert_allclose(theta, 0.25 * np.pi * np.sin(2 * np.pi * t), atol=1e-12)
    a = np.asarray(m.a_I_m_s2)
    np.testing.assert_allclose(a[:, 2], -0.25 * np.pi**2 * np.sin(np.pi * t), atol=1e-10)
    np.testing.assert_allclose(np.asarray(m.omegadot_B_rad_s2)[:, 0],
                               -0.25 * np.pi * (2 * np.pi) ** 2 * np.sin(2 * np.pi * t), atol=1e-9)


def test_tahboub_stimuli():
    lv = tr.prts_velocity_levels()
    assert lv.size == 242 and (lv == 1).sum() == 81 and (lv == -1).sum() == 81
    prts = tr.prts(cycles=1)
    assert prts.duration_s == 60.5
    ts = np.arange(0.0, 60.5, 0.01)
    m = tr.sample(prts, ts)
    lean = -np.asarray(so3.tilt_angles(m.R_I_B))[:, 1]  # Θy = −pitch (Ry(θ))
    assert abs(np.degrees(np.max(np.abs(lean))) - 5.0) < 1e-9
    # the lean is the sampled PRTS stimulus; its rate is held at +v, 0, −v for 0.25 s each
    np.testing.assert_allclose(lean, tr.prts_stimulus(np.radians(5.0), 100.0, 1)[1], atol=1e-12)
    rate = np.asarray(m.omega_B_rad_s)[:, 1]
    v = np.abs(rate).max()
    np.testing.assert_allclose(rate, v * np.repeat(lv, 25), atol=1e-12)
    np.testing.assert_allclose(np.asarray(m.omegadot_B_rad_s2), 0.0, atol=1e-12)
    step = tr.step(lever_m=0.325)
    m = tr.sample(step, np.array([1.3, 9.0]))
    lean = -np.degrees(np.asarray(so3.tilt_angles(m.R_I_B))[:, 1])  # Θy = −pitch (Ry(θ))
    np.testing.assert_allclose(lean, [0.95 * 5.0, 5.0], atol=1e-3)  # 95 % at 0.3 s
    # the sensor point 0.325 m above the ankle sees the lean's tangential acceleration
    sine = tr.sine(lever_m=0.325)
    m = tr.sample(sine, np.array([0.0]))
    A, w = math.radians(5.0), 2 * math.pi * 0.2
    np.testing.assert_allclose(np.asarray(m.omega_B_rad_s)[0], [0.0, A * w, 0.0], atol=1e-14)
    np.testing.assert_allclose(np.asarray(m.a_I_m_s2)[0], [0.0, 0.0, -0.325 * (A * w) ** 2],
                               atol=1e-12)


def test_walking_head_acceleration_range():
    m = tr.sample(tr.walking(), np.arange(2.0, 6.0, 0.005))
    a = np.asarray(m.a_I_m_s2)
    assert 2.0 < np.max(np.abs(a[:, 2])) < 5.0  # ≈ 0.3 g vertical at the step frequency
    assert 1.0 < np.max(np.abs(a[:, 0])) < 4.0  # fore–aft
    assert np.max(np.abs(a[:, 1])) == 0.0  # sagittal
