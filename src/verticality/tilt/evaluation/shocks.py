"""Synthetic recordings of a violent event followed by rest, with known truth: how fast the tilt
filter is back on its feet once the event is over (docs/tilt.md, "After a violent event").

A vehicle (or a dropped hand-held device) moves gently, falls freely for a fraction of a second,
hits the ground and comes to rest in a new orientation, as a crashed drone does:

* before: turning at up to ~0.4 rad/s (three sinusoids per axis, 0.1–0.6 Hz) and translating
  back and forth (horizontal accelerations of up to ~1 m/s², 0.3–1 Hz);
* a free fall of 0.2–0.5 s (the accelerometer reads ~0), then the impact: the velocity stopped
  within a half-sine pulse of the given peak specific force (tens of g), while the gyro reads a
  half-sine spike of the given peak rate (the body knocked over by 45–180°) about a random axis;
* a bounce (rate and acceleration oscillating at 5–8 Hz, decaying in ~0.1 s), then rest to the
  end of the recording;
* the gyro's response to the shock: MEMS gyros read spurious rates under shocks of tens of g (the
  proof masses are knocked off their drive), so during the impact pulse the reading carries an
  extra rotation of 2–10° about a random axis that the body did not make: the tilt is wrong by up
  to that much when the event is over, and only the accelerometer can tell.

The motion is integrated at 10 kHz and read as an IMU at the recording's rate: each gyro sample
the mean rate over its interval (an integrating gyro, as :func:`~.faults.fast_roll`), each
accelerometer sample the mean specific force over it (an IMU's averaging anti-alias filter); the
sensor's errors are drawn as for the realistic recordings (:func:`.realistic.draw_errors`,
consumer MEMS data-sheet ranges) with a ±2000 °/s gyro and a ±16 g accelerometer, so that the
event is read without clipping unless ``acc_range_g`` says otherwise.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from verticality.core import so3
from verticality.core.constants import G_M_S2
from verticality.sensors import readings

FINE_HZ = 10_000.0  # the motion's integration rate


class ShockRecording(NamedTuple):
    gyr_rad_s: np.ndarray  # (N, 3) as read
    acc_m_s2: np.ndarray  # (N, 3) as read
    dt_s: float
    quat_E_S: np.ndarray  # (N, 4) wxyz, the truth
    impact_s: float  # the time of the impact (its pulse starts here)
    rest_s: float  # from here on the sensor is at rest
    peak_rate_rad_s: float  # the largest true |ω| of the event
    peak_acc_m_s2: float  # the largest true |f|


def _half_sine(t, t0, width):
    u = (t - t0) / width
    return np.where((u >= 0) & (u <= 1), np.sin(np.pi * np.clip(u, 0, 1)), 0.0)


def _unit(v):
    return v / np.linalg.norm(v)


def shock_recording(seed: int, rate_hz: float = 200.0, duration_s: float = 30.0,
                    impact_s: float = 15.0, peak_rate_rad_s: float = 13.9,
                    peak_acc_m_s2: float = 100.0, acc_range_g: float = 16.0,
                    ideal: bool = False, shock_error_deg=(2.0, 10.0)) -> ShockRecording:
    """The crash recording drawn with ``seed`` (module doc), read at ``rate_hz``. ``ideal``: by a
    perfect sensor (no offset, scale, cross-axis, noise or range). ``shock_error_deg``: the range
    of the gyro's spurious rotation during the impact (uniform; (0, 0): none)."""
    from verticality.tilt.evaluation import realistic as rr

    rng = np.random.default_rng([seed, 104729])
    n_fine = int(round(duration_s * FINE_HZ))
    h = 1.0 / FINE_HZ
    t = (np.arange(n_fine) + 0.5) * h  # the middle of each fine step
    fall_s = rng.uniform(0.2, 0.5)
    t_fall = impact_s - fall_s
    moving = t < t_fall
    # gentle motion before the fall
    w = np.zeros((n_fine, 3))
    a_W = np.zeros((n_fine, 3))
    for ax in range(3):
        for f, amp in zip(rng.uniform(0.1, 0.6, 3), rng.uniform(0.05, 0.15, 3), strict=True):
            w[:, ax] += amp * np.sin(2 * np.pi * f * t + rng.uniform(0, 2 * np.pi))
    for ax in range(2):
        for f, amp in zip(rng.uniform(0.3, 1.0, 2), rng.uniform(0.2, 0.5, 2), strict=True):
            om = 2 * np.pi * f
            ph = rng.uniform(0, 2 * np.pi)
            # velocity amp/om (sin(om t + ph) - sin(ph)): zero at the start
            a_W[:, ax] += amp * np.cos(om * t + ph)
    w[~moving] = 0.0
    a_W[~moving] = 0.0
    # the free fall: no support, the specific force vanishes
    falling = (t >= t_fall) & (t < impact_s)
    a_W[falling, 2] = -G_M_S2
    # the velocity at the impact (horizontal from the motion, vertical from the fall)
    v_hit = np.sum(a_W[t < impact_s], axis=0) * h
    # the impact stops it within a half-sine pulse of peak specific force ~peak_acc_m_s2
    dv = -v_hit
    width = np.pi * np.linalg.norm(dv) / (2.0 * max(peak_acc_m_s2 - G_M_S2, 10.0))
    pulse = _half_sine(t, impact_s, width)
    a_W += np.outer(pulse, dv * np.pi / (2.0 * width))
    # the gyro spike: the body knocked over about a random axis
    axis = _unit(rng.normal(size=3) * [1.0, 1.0, 0.3])
    # the angle knocked over (45–180°) at the given peak rate sets the spike's width
    width_g = np.radians(rng.uniform(45.0, 180.0)) * np.pi / (2.0 * peak_rate_rad_s)
    w += np.outer(_half_sine(t, impact_s, width_g), axis * peak_rate_rad_s)
    # the bounce: rate and velocity oscillating and decaying to zero (no net velocity change)
    t_b = impact_s + max(width, width_g)
    u = np.clip(t - t_b, 0.0, None)
    on = t >= t_b
    f_b = rng.uniform(5.0, 8.0)
    decay = np.exp(-u / 0.1) * on
    axis_b = _unit(rng.normal(size=3))
    w += np.outer(decay * np.sin(2 * np.pi * f_b * u), axis_b * rng.uniform(1.0, 3.0))
    v_b = _unit(rng.normal(size=3)) * rng.uniform(0.1, 0.4)
    # a = d/dt [e^(−u/τ) sin(2π f u)] v_b
    a_W += np.outer(decay * (2 * np.pi * f_b * np.cos(2 * np.pi * f_b * u)
                             - np.sin(2 * np.pi * f_b * u) / 0.1), v_b)
    rest_s = t_b + 1.0  # the bounce has decayed to e^-10
    w[t >= rest_s] = 0.0
    a_W[t >= rest_s] = 0.0
    # integrate the orientation exactly over each fine step
    steps = np.asarray(so3.quat_exp(w * h)).tolist()
    qs = [(1.0, 0.0, 0.0, 0.0)]
    a0, a1, a2, a3 = qs[0]
    for b0, b1, b2, b3 in steps:  # (sequential: a product of rotations; plain floats for speed)
        a0, a1, a2, a3 = (a0 * b0 - a1 * b1 - a2 * b2 - a3 * b3,
                          a0 * b1 + a1 * b0 + a2 * b3 - a3 * b2,
                          a0 * b2 - a1 * b3 + a2 * b0 + a3 * b1,
                          a0 * b3 + a1 * b2 - a2 * b1 + a3 * b0)
        qs.append((a0, a1, a2, a3))
    q = np.array(qs)
    q_mid = 0.5 * (q[:-1] + q[1:])
    q_mid /= np.linalg.norm(q_mid, axis=1, keepdims=True)
    f_B = np.asarray(so3.quat_rotate(so3.quat_conjugate(q_mid), a_W + [0.0, 0.0, G_M_S2]))
    # read at rate_hz: means over each sample's interval (the first sample: the first interval)
    per = int(round(FINE_HZ / rate_hz))
    n = n_fine // per
    gyr_true = w[:n * per].reshape(n, per, 3).mean(axis=1)
    acc_true = f_B[:n * per].reshape(n, per, 3).mean(axis=1)
    quat = q[per * np.arange(1, n + 1)]
    dt = per / FINE_HZ
    # the gyro's spurious rotation during the impact pulse (drawn whatever the range, so that the
    # rest of the recording is the same for every range)
    spurious_rad = np.radians(rng.uniform(*shock_error_deg))
    spurious_axis = _unit(rng.normal(size=3))
    e = rr.draw_errors(rng)._replace(gyr_range_rad_s=np.radians(2000.0),
                                     acc_range_m_s2=acc_range_g * G_M_S2, rate_hz=1.0 / dt)
    if ideal:
        e = rr.perfect(e)
    # (a half-sine rate over the impact pulse whose integral is the spurious angle)
    t_s = (np.arange(n) + 0.5) * dt
    spurious = _half_sine(t_s, impact_s, width) * spurious_rad * np.pi / (2.0 * width)
    gyr_true_read = gyr_true + np.outer(spurious, spurious_axis)
    walk = readings.random_walk(
        rng.normal(0.0, e.gyr_bias_walk_rad_s_sqrt_s * np.sqrt(dt), (n, 3)))
    gyr = readings.axes_reading(
        gyr_true_read, e.gyr_cross, e.gyr_scale, e.gyr_bias_rad_s + walk,
        rng.normal(0.0, readings.white_noise_std(e.gyr_noise_rad_s_sqrt_hz, 1.0 / dt), (n, 3)),
        e.gyr_range_rad_s)
    acc = readings.axes_reading(
        acc_true, e.acc_cross, e.acc_scale, e.acc_bias_m_s2,
        rng.normal(0.0, readings.white_noise_std(e.acc_noise_m_s2_sqrt_hz, 1.0 / dt), (n, 3)),
        e.acc_range_m_s2)
    return ShockRecording(np.asarray(gyr), np.asarray(acc), dt, quat, impact_s, float(rest_s),
                          float(np.linalg.norm(w, axis=1).max()),
                          float(np.linalg.norm(f_B, axis=1).max()))
