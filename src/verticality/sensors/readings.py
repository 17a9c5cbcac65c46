"""Simulated sensors: rate gyro, accelerometer, inclinometer (otolith) readings, ADC quantization.

Every noisy reading is a pure function of a ``jax.random`` key, so runs are reproducible and
batchable (``vmap`` over keys). Two forms are offered for each sensor:

- one sample: ``gyro_step(key, bias, omega, dt, p) -> (bias, reading)`` (for closed loops), built
  from ``gyro_white_noise``, ``gyro_reading`` and ``gyro_bias_step`` (a closed loop that draws its
  random numbers in its own order, as the simulator does, calls these three);
- a whole record: ``gyro_record(key, omega_series, dt, p) -> (readings, biases)`` (vectorised,
  the random-walk bias by a cumulative sum, no Python loop).

The error primitives (``random_walk_increments``, ``random_walk``, ``white``, ``white_noise_std``,
``axes_reading``: scale, misalignment, offset, noise, range) are the one sensor-error model; the
gyro and accelerometer above and every experiment's or evaluation's simulated IMU are built
from them. ``raw_axes_reading`` and ``calibrated`` are the same model read in the sensor's raw
axes, clipped there at limits that differ by sign (noise and quantization before or after the
clip), then calibrated by the user's estimate of it: what a calibrated file of a saturating
sensor holds.

Models (T §III.A for the noise levels of docs/reproduction.md `tahboub-*`; P13 §5 for white noise
on the inclinometer angles and gyro rates):

    gyro          ω_m = ω_B + b + n,     ḃ = w,   n ~ N(0, σ²),  w white, E[w w] = q δ(t)
                  (discrete: b_{k+1} = b_k + √(q·dt) N(0, 1))
    accelerometer f_m = R_IBᵀ (a_P − g_I) + n   specific force at a point P of the body, in the
                  sensor (body) frame, gravity included: a level body at rest reads (0, 0, +g);
                  a_P = a_C + R_IB (ω̇ × r + ω × (ω × r)) for a sensor at r from the centre
                  (T eq. 4)
    inclinometer  φ_m = φ + n, optionally quantized (an n-bit ADC over ±full scale)
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from verticality.core.constants import gravity_I
from verticality.models.kinematics import RigidMotion


class GyroParams(NamedTuple):
    noise_std_rad_s: float = 0.0  # white noise σ per sample
    bias_rw_q_rad2_s3: float = 0.0  # random-walk intensity q (T: 1e-6 rad²/s³)


class AccelParams(NamedTuple):
    noise_std_m_s2: float = 0.0
    lever_B_m: jnp.ndarray | None = None  # sensor position from the body centre, body frame
    bias_B_m_s2: jnp.ndarray | float = 0.0  # constant offset of the reading (zero-g level)


# -------------------------------------------------------------------------------------------
# Gyro
# -------------------------------------------------------------------------------------------


def gyro_white_noise(key, shape, p: GyroParams):
    """The gyro's white noise n ~ N(0, σ²) for readings of ``shape`` (e.g. (3,), or (n, 3) drawn at
    once for n readings)."""
    return p.noise_std_rad_s * jax.random.normal(key, shape)


def gyro_reading(omega_B_rad_s, bias_rad_s, noise_rad_s):
    """ω_m = ω_B + b + n: one reading from the true rate, the current bias and a white-noise
    draw."""
    return jnp.asarray(omega_B_rad_s, float) + bias_rad_s + noise_rad_s


def gyro_bias_step(key, bias_rad_s, dt_s, p: GyroParams):
    """The bias random walk over ``dt_s``: b + √(q·dt) N(0, 1)."""
    bias = jnp.asarray(bias_rad_s, float)
    return bias + random_walk_increments(key, bias.shape, p.bias_rw_q_rad2_s3, dt_s)


def gyro_step(key, bias_rad_s, omega_B_rad_s, dt_s, p: GyroParams):
    """One gyro sample: returns (next bias, reading). The reading uses the current bias."""
    k_n, k_b = jax.random.split(key)
    omega = jnp.asarray(omega_B_rad_s, float)
    reading = gyro_reading(omega, bias_rad_s, gyro_white_noise(k_n, omega.shape, p))
    next_bias = gyro_bias_step(k_b, jnp.broadcast_to(bias_rad_s, omega.shape), dt_s, p)
    return next_bias, reading


def gyro_record(key, omega_B_rad_s, dt_s, p: GyroParams, bias0_rad_s=0.0):
    """Gyro readings for a whole record ``omega_B_rad_s`` (N, ...) sampled every ``dt_s``.

    Returns ``(readings, biases)``; the bias starts at ``bias0_rad_s`` and random-walks.
    """
    omega = jnp.asarray(omega_B_rad_s, float)
    k_n, k_b = jax.random.split(key)
    steps = random_walk_increments(k_b, omega.shape, p.bias_rw_q_rad2_s3, dt_s)
    # the reading at t_k carries the bias before the k-th increment, as gyro_step's does
    bias = bias0_rad_s + jnp.concatenate([jnp.zeros_like(steps[:1]), random_walk(steps[:-1])], 0)
    return gyro_reading(omega, bias, gyro_white_noise(k_n, omega.shape, p)), bias


# -------------------------------------------------------------------------------------------
# Error primitives shared by every simulated sensor
# -------------------------------------------------------------------------------------------


def random_walk_increments(key, shape, intensity, dt_s):
    """The increments of a random walk of intensity ``q`` sampled every ``dt_s``: √(q·dt) N(0, 1)
    (``q`` the spectral density of the white noise it integrates, e.g. rad²/s³ for a gyro bias)."""
    return jnp.sqrt(intensity * dt_s) * jax.random.normal(key, shape)


def random_walk(increments, start=0.0):
    """The walk after each increment along axis 0: ``w_k = start + Σ_{j≤k} increments_j``.
    NumPy increments give a NumPy walk, JAX increments a JAX one (the summation is theirs)."""
    return start + increments.cumsum(axis=0)


def white_noise_std(density_per_sqrt_hz, rate_hz):
    """Per-sample standard deviation of white noise of the data-sheet density (unit/√Hz) sampled
    at ``rate_hz``: density · √(rate/2), the noise within the Nyquist band."""
    return density_per_sqrt_hz * np.sqrt(rate_hz / 2)


def axes_reading(true_B, cross, scale, bias, noise, range_):
    """A three-axis sensor's readings of ``true_B`` (N, 3): scaled by ``1 + scale`` per axis,
    mixed by the misalignment ``I + cross`` (off-diagonal cross-axis sensitivities), offset by
    ``bias``, plus ``noise``, clipped at ``±range_`` (the part's measurement range).
    NumPy in, NumPy out."""
    m = np.eye(3) + cross
    out = (true_B * (1.0 + scale)) @ m.T + bias + noise
    return out.clip(-range_, range_)


def quantized(x, step):
    """``x`` rounded to multiples of ``step`` (an ADC's least significant bit; 0 or None: not
    quantized). NumPy; NaN stays NaN."""
    return x if not step else np.round(np.asarray(x) / step) * step


def raw_axes_reading(true_B, cross, scale, bias, noise, lo, hi, step=None,
                     noise_after_clip: bool = False):
    """A three-axis sensor's readings in its own (raw) axes, clipped there: the true ``true_B``
    (N, 3) scaled, mixed and offset as :func:`axes_reading` does, with ``noise`` (N, 3), rounded
    to ``step`` (the LSB), and clipped at the per-axis limits ``lo`` < 0 < ``hi`` (3,) (which
    differ by sign: a two's-complement ADC reads −32768 … +32767 codes, and an offset moves
    both).

    ``noise_after_clip`` False: the sensing element's noise is added before the converter
    saturates (a digital MEMS part: the clipped reading is exactly the end code, flat); True: the
    front end saturates and the converter's noise is added after (the clipped reading is the
    limit plus noise). NumPy in, NumPy out."""
    lo = np.broadcast_to(np.asarray(lo, dtype=np.float64), (3,))
    hi = np.broadcast_to(np.asarray(hi, dtype=np.float64), (3,))
    if noise_after_clip:
        analog = axes_reading(true_B, cross, scale, bias, 0.0, np.inf).clip(lo, hi)
        return quantized(analog + noise, step)
    return quantized(axes_reading(true_B, cross, scale, bias, noise, np.inf), step).clip(lo, hi)


def calibrated(raw, cross_est, scale_est, bias_est):
    """What a user's file holds after calibrating ``raw`` (N, 3) with an *estimated* model of
    :func:`axes_reading`'s errors: the inverse ``diag(1 + scale)⁻¹ (I + cross)⁻¹ (raw − bias)``.
    An estimate is never exact, so the result keeps the residual errors, and a raw axis clipped
    at its limit becomes a plane ``a · y = const`` in the calibrated axes (``a`` the raw axis's
    row of ``(I + cross) diag(1 + scale)``). NumPy in, NumPy out."""
    m = np.eye(3) + cross_est
    return np.linalg.solve(m, (np.asarray(raw) - bias_est).T).T / (1.0 + scale_est)


# -------------------------------------------------------------------------------------------
# Accelerometer
# -------------------------------------------------------------------------------------------


def point_acceleration_I(motion: RigidMotion, lever_B_m):
    """Acceleration (frame I, gravity excluded) of the point at ``lever_B_m`` from the centre."""
    r = jnp.asarray(lever_B_m, float)
    w = motion.omega_B_rad_s
    transport = jnp.cross(motion.omegadot_B_rad_s2, r) + jnp.cross(w, jnp.cross(w, r))
    return motion.a_I_m_s2 + motion.R_I_B @ transport


def specific_force_B(motion: RigidMotion, lever_B_m=None):
    """Noise-free accelerometer reading: R_IBᵀ (a_P − g_I), m/s², body frame, gravity included."""
    a = motion.a_I_m_s2 if lever_B_m is None else point_acceleration_I(motion, lever_B_m)
    return motion.R_I_B.T @ (a - gravity_I())


def accelerometer(key, motion: RigidMotion, p: AccelParams):
    """One accelerometer sample (use ``jax.vmap`` over keys and motions for a record)."""
    f = specific_force_B(motion, p.lever_B_m) + p.bias_B_m_s2
    return f + p.noise_std_m_s2 * jax.random.normal(key, f.shape)


# -------------------------------------------------------------------------------------------
# Inclinometer / otolith angles, quantization
# -------------------------------------------------------------------------------------------


def quantize(x, bits: int, full_scale: float):
    """An n-bit ADC over [−full_scale, +full_scale): round to the step 2·full_scale/2^bits, clip.

    NaN stays NaN (a missing sample remains flagged as missing)."""
    step = 2.0 * full_scale / (2**bits)
    q = jnp.round(jnp.asarray(x, float) / step) * step
    return jnp.clip(q, -full_scale, full_scale - step)


def inclinometer(key, angles_rad, noise_std_rad: float = 0.0, bits: int | None = None,
                 full_scale_rad: float = jnp.pi):
    """Noisy (and optionally quantized) inclinometer / otolith angle readings."""
    a = jnp.asarray(angles_rad, float)
    y = a + noise_std_rad * jax.random.normal(key, a.shape)
    return y if bits is None else quantize(y, bits, full_scale_rad)


def white(key, x, std):
    """``x`` plus white Gaussian noise of standard deviation ``std`` (scalar or per component)."""
    x = jnp.asarray(x, float)
    return x + jnp.asarray(std, float) * jax.random.normal(key, x.shape)
