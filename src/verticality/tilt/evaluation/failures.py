"""Synthetic recordings of the ways real sensors and logs fail, each a class of the validation set
(:mod:`verticality.tilt.evaluation.validation`; docs/tilt.md, "Failure classes of the validation
set"), with known truth:

* ``sat-gyro``, ``sat-acc``: the vigorous hand-held motion
  (:mod:`~verticality.tilt.evaluation.realistic`; for the accelerometer with hand translations of
  ±15 cm, 2–4 g) read by a sensor that clips in its own raw axes
  and is calibrated afterwards (:func:`verticality.sensors.readings.raw_axes_reading`, then
  :func:`~verticality.sensors.readings.calibrated` with an estimated, slightly wrong, model): the
  file holds plateaus that are flat only along the raw axis, at limits that differ by sign. The
  full scale is set so that a given share of the samples clips (:data:`CLIP_SHARES`);
* ``shock``: rest and slow hand motion broken by impacts of 10–30 g lasting a few ms, each with a
  gyro spike of 10–15 rad/s (the sensor knocked over by a few degrees), then 10 s at rest: the
  tilt must come back at rest (the 1–10 s after each shock are scored apart, ``after_shock``);
* ``crash``: a crashed drone (:mod:`~verticality.tilt.evaluation.shocks`): slow motion, a free
  fall, an impact of about 100 m/s² with the body knocked over by 45–180°, then rest; read by a
  ±2000 °/s, ±16 g sensor (no clipping). The 5 s at rest after the event are scored apart
  (``after_impact``): the tilt must come back there as fast as the evidence of rest allows;
* ``dropout``: runs of missing rows (the time stamps skip 0.05–1 s);
* ``clock-jump``: the time stamps step forward or back by 2–10 s (a logger's clock reset), the
  readings continuous;
* ``jitter``: samples taken at irregular instants (each step ±40 % of the nominal), stamped with
  their true times.

The peers get the same rows and the nominal sampling period, as a user would give it; our filter
gets the time stamps (:func:`verticality.tilt.output.time_axis`).
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from verticality.core import so3
from verticality.core.constants import G_M_S2
from verticality.sensors import readings
from verticality.simulation import trajectories
from verticality.tilt.evaluation import realistic as rr

SATURATION = ("sat-gyro", "sat-acc")
TIMING = ("dropout", "clock-jump", "jitter")
CLASSES = SATURATION + ("shock", "crash") + TIMING
CLIP_SHARES = (0.01, 0.02, 0.05, 0.10, 0.20)
DURATION_S = 40.0
DEG = np.pi / 180.0
_LSB_CODES = 32768.0  # a 16-bit converter: −32768 … +32767 codes over ± full scale


class Failure(NamedTuple):
    """One recording of a failure class: readings (N, 3), the time stamps ``t_s`` (N,) the file
    holds, the nominal sampling period, the true orientation (N, 4) wxyz, the samples truly
    clipped (N,) bool, and extra scored windows ``{name: (N,) bool}``."""

    gyr_rad_s: np.ndarray
    acc_m_s2: np.ndarray
    t_s: np.ndarray
    period_s: float
    quat_E_S: np.ndarray
    clipped: np.ndarray
    windows: dict


class RawSensor(NamedTuple):
    """A three-axis sensor with raw-axis limits and the user's calibration of it
    (:func:`read_raw_then_calibrated`)."""

    scale: np.ndarray  # (3,) true sensitivity error
    cross: np.ndarray  # (3, 3) true cross-axis terms
    bias: np.ndarray  # (3,) true offset (in the raw reading)
    full_scale: float  # the converter's full scale (symmetric in codes)
    noise_std: float  # white noise per sample
    noise_after_clip: bool
    scale_est: np.ndarray  # the user's calibration: estimates of the three above
    cross_est: np.ndarray
    bias_est: np.ndarray


def cross_terms(rng, size):
    """(3, 3) cross-axis sensitivities uniform in ±``size``, zero diagonal."""
    m = rng.uniform(-size, size, (3, 3))
    np.fill_diagonal(m, 0.0)
    return m


def draw_raw_sensor(rng, offset, noise_std, full_scale, noise_after_clip=False) -> RawSensor:
    """Data-sheet ranges of consumer MEMS parts (BMI160, MPU-9250, ICM-20948, LSM6DS): sensitivity
    error ±2 %, cross-axis ±2 %, the offset uniform in ±``offset``; the user's calibration (a
    six-position or turntable fit) leaves sensitivity and cross-axis errors of ±0.2 % and 5 % of
    the offset."""
    scale, cross = rng.uniform(-0.02, 0.02, 3), cross_terms(rng, 0.02)
    bias = rng.uniform(-offset, offset, 3)
    return RawSensor(scale, cross, bias, float(full_scale), float(noise_std),
                     bool(noise_after_clip), scale + rng.uniform(-0.002, 0.002, 3),
                     cross + cross_terms(rng, 0.002), bias + rng.uniform(-0.05, 0.05, 3) * offset)


def read_raw_then_calibrated(true_B, s: RawSensor, rng):
    """``(file (N, 3), clipped (N,) bool: a raw axis read at its limit)``: ``true_B`` read in
    the sensor's raw axes (:func:`~verticality.sensors.readings.raw_axes_reading`: 16-bit
    codes over ± full scale, −32768 … +32767), clipped there, then calibrated with the estimated
    model (:func:`~verticality.sensors.readings.calibrated`)."""
    lsb = s.full_scale / _LSB_CODES
    lo, hi = -s.full_scale, s.full_scale - lsb
    noise = rng.normal(0.0, s.noise_std, true_B.shape)
    raw = readings.raw_axes_reading(true_B, s.cross, s.scale, s.bias, noise, lo, hi, lsb,
                                    s.noise_after_clip)
    if s.noise_after_clip:  # the front end's clipping, before the converter's noise
        raw_clean = readings.axes_reading(true_B, s.cross, s.scale, s.bias, 0.0, np.inf)
        clipped = np.any((raw_clean >= hi) | (raw_clean <= lo), axis=1)
    else:  # the converter's end codes
        clipped = np.any((raw >= hi) | (raw <= lo), axis=1)
    return readings.calibrated(raw, s.cross_est, s.scale_est, s.bias_est), clipped


_SHAKEN = "shaken"  # the vigorous rotations with ±15 cm hand translations: 2–4 g peaks


def _shaken(rng, duration_s):
    """:data:`_SHAKEN`: the vigorous hand-held rotations with translations of up to ±15 cm at
    1.5–4 Hz, whose accelerations (up to 2–4 g beyond gravity) pass a small accelerometer's
    range."""
    ra, rf, rp = (jnp.asarray(v) for v in rr.random_sines(rng, 3, [0.8, 0.5, 0.8], 1.5, 4.0))
    pa, pf, pp = (jnp.asarray(v) for v in rr.random_sines(rng, 3, [0.15] * 3, 1.5, 4.0))

    def series(t, a, f, ph):
        return jnp.sum(a * (jnp.sin(2 * jnp.pi * f * t + ph) - jnp.sin(ph)), axis=1)

    return trajectories.from_euler(lambda t: series(t, pa, pf, pp),
                                   lambda t: series(t, ra, rf, rp), duration_s, _SHAKEN)


def _truth(kind, rng, t):
    """The motion ``kind`` (:func:`verticality.tilt.evaluation.realistic.motion`) at times ``t``
    for a sensor at a lever arm drawn from ``rng``: ``(ω_B (N, 3), f_B (N, 3), quat (N, 4))``."""
    traj = (_shaken(rng, float(t[-1]) + 1.0) if kind == _SHAKEN
            else rr.motion(kind, rng, float(t[-1]) + 1.0))
    lever_B_m = jnp.asarray(rng.uniform(-0.1, 0.1, 3))
    m = trajectories.sample(traj, t)
    f_B = np.asarray(jax.vmap(lambda mm: readings.specific_force_B(mm, lever_B_m))(m))
    return (np.asarray(m.omega_B_rad_s), f_B, np.asarray(so3.quat_from_matrix(m.R_I_B)))


def full_scale_for_share(true_B, s: RawSensor, share: float) -> float:
    """The full scale at which ``share`` of the samples has a raw axis beyond it."""
    raw = readings.axes_reading(true_B, s.cross, s.scale, s.bias, 0.0, np.inf)
    return float(np.quantile(np.max(np.abs(raw), axis=1), 1.0 - share))


def saturated(sensor: str, share: float, seed: int, rate_hz: float,
              duration_s: float = DURATION_S, noise_after_clip: bool = False) -> Failure:
    """The vigorous hand-held motion read by a gyro (``sensor`` "gyr") or accelerometer ("acc")
    that clips ``share`` of the samples in its raw axes and is calibrated afterwards; the other
    sensor is read as in :mod:`~verticality.tilt.evaluation.realistic` (±2000 °/s, ±16 g: no
    clipping). The motion, lever arm and sensor errors depend on the seed only, the noise on the
    rate too."""
    rng = np.random.default_rng([seed, 7, 0 if sensor == "gyr" else 1])
    dt = 1.0 / rate_hz
    t = np.arange(int(round(duration_s * rate_hz))) * dt
    omega, f_B, quat = _truth(rr.VIGOROUS if sensor == "gyr" else _SHAKEN, rng, t)
    e = rr.draw_errors(rng)
    gyr_sd = readings.white_noise_std(e.gyr_noise_rad_s_sqrt_hz, rate_hz)
    acc_sd = readings.white_noise_std(e.acc_noise_m_s2_sqrt_hz, rate_hz)
    if sensor == "gyr":
        s = draw_raw_sensor(rng, 3.0 * DEG, gyr_sd, 1.0, noise_after_clip)
        s = s._replace(full_scale=full_scale_for_share(omega, s, share))
        noise_rng = np.random.default_rng([seed, 7, 0, int(rate_hz)])
        gyr, clipped = read_raw_then_calibrated(omega, s, noise_rng)
        acc = readings.axes_reading(f_B, e.acc_cross, e.acc_scale, e.acc_bias_m_s2,
                                    noise_rng.normal(0.0, acc_sd, f_B.shape), 16.0 * G_M_S2)
    else:
        s = draw_raw_sensor(rng, 0.04 * G_M_S2, acc_sd, 1.0, noise_after_clip)
        s = s._replace(full_scale=full_scale_for_share(f_B, s, share))
        noise_rng = np.random.default_rng([seed, 7, 1, int(rate_hz)])
        acc, clipped = read_raw_then_calibrated(f_B, s, noise_rng)
        gyr = readings.axes_reading(omega, e.gyr_cross, e.gyr_scale, e.gyr_bias_rad_s,
                                    noise_rng.normal(0.0, gyr_sd, omega.shape), 2000.0 * DEG)
    return Failure(gyr, acc, t, dt, quat, clipped, {})


# --- shocks --------------------------------------------------------------------------------

SHOCK_TIMES_S = (10.0, 24.0, 38.0)
SHOCK_REST_S = 11.0
_FINE_HZ = 8000.0  # the truth's grid: resolves a 1 ms pulse; readings average it per sample


def _shock_trajectory(rng, duration_s):
    """Slow hand rotation (±0.4 rad at 0.1–0.5 Hz) that stops before each shock and resumes
    :data:`SHOCK_REST_S` after it; each shock a biphasic acceleration spike of peak 10–30 g
    (σ 1–3 ms, random direction) and a rotation of the sensor by a Gaussian rate pulse of peak
    10–15 rad/s (σ 2–5 ms) about its x or y axis."""
    ra, rf, rp = (jnp.asarray(v) for v in rr.random_sines(rng, 3, [0.4, 0.4, 0.6], 0.1, 0.5))
    times = jnp.asarray(SHOCK_TIMES_S)
    peak_a = rng.uniform(10.0, 30.0, len(SHOCK_TIMES_S)) * G_M_S2
    sig_a = rng.uniform(1e-3, 3e-3, len(SHOCK_TIMES_S))
    d = rng.normal(size=(len(SHOCK_TIMES_S), 3))
    d = jnp.asarray(d / np.linalg.norm(d, axis=1, keepdims=True))
    sig_r = rng.uniform(2e-3, 5e-3, len(SHOCK_TIMES_S))
    turn = (rng.uniform(10.0, 15.0, len(SHOCK_TIMES_S)) * rng.choice([-1.0, 1.0], 3)
            * sig_r * np.sqrt(2 * np.pi))  # the angle of each rate pulse
    axis = np.zeros((len(SHOCK_TIMES_S), 3))
    axis[np.arange(len(SHOCK_TIMES_S)), rng.integers(0, 2, len(SHOCK_TIMES_S))] = 1.0
    angles = jnp.asarray(axis * turn[:, None])
    sig_a, sig_r = jnp.asarray(sig_a), jnp.asarray(sig_r)

    def moving(t):  # 1 while the hand moves, 0 from 1 s before a shock to SHOCK_REST_S after
        gate = jnp.prod(1.0 - trajectories.smoothstep((t - times + 1.0) / 0.8)
                        * (1.0 - trajectories.smoothstep((t - times - SHOCK_REST_S) / 0.8)))
        return gate * trajectories.smoothstep(t / 0.5)

    def rpy(t):
        osc = jnp.sum(ra * (jnp.sin(2 * jnp.pi * rf * t + rp) - jnp.sin(rp)), axis=1)
        knocks = jnp.sum(angles * jax.scipy.special.ndtr((t - times) / sig_r)[:, None], axis=0)
        return osc * moving(t) + knocks

    def position(t):
        return jnp.sum(d * trajectories.jolt_position(t, times + sig_a, sig_a, peak_a)[:, None],
                       axis=0)

    return trajectories.from_euler(position, rpy, duration_s, "shock")


def shock(seed: int, rate_hz: float, duration_s: float = 50.0) -> Failure:
    """:func:`_shock_trajectory` read by a consumer IMU (:func:`verticality.tilt.evaluation.
    realistic.draw_errors`, ±2000 °/s, ±16 g: the largest shocks clip the accelerometer) whose
    samples are the mean of the true rate and specific force over each sampling interval (an
    integrating sensor, as a decimating filter reads a pulse shorter than a sample)."""
    rng = np.random.default_rng([seed, 8])
    traj = _shock_trajectory(rng, duration_s)
    e = rr.draw_errors(rng)
    lever_B_m = jnp.asarray(rng.uniform(-0.05, 0.05, 3))
    fine = np.arange(int(duration_s * _FINE_HZ) + 1) / _FINE_HZ
    m = trajectories.sample(traj, fine)
    f_B = np.asarray(jax.vmap(lambda mm: readings.specific_force_B(mm, lever_B_m))(m))
    omega = np.asarray(m.omega_B_rad_s)
    n = int(round(duration_s * rate_hz))
    t = np.arange(n) / rate_hz
    per = _FINE_HZ / rate_hz  # fine samples per interval (not necessarily whole)
    edges = np.clip(np.round(np.arange(-1, n) * per).astype(int), 0, fine.size - 1)
    edges[0] = 0

    def mean_over(x):
        c = np.concatenate([np.zeros((1, 3)), np.cumsum(x, axis=0)])
        width = np.maximum(np.diff(edges), 1)[:, None]
        lo = np.where(np.diff(edges) > 0, edges[:-1] + 1, edges[1:])
        return (c[edges[1:] + 1] - c[lo]) / width

    idx = np.clip(np.round(t * _FINE_HZ).astype(int), 0, fine.size - 1)
    quat = np.asarray(so3.quat_from_matrix(m.R_I_B[idx]))
    noise_rng = np.random.default_rng([seed, 8, int(rate_hz)])
    gyr = readings.axes_reading(
        mean_over(omega), e.gyr_cross, e.gyr_scale, e.gyr_bias_rad_s,
        noise_rng.normal(0.0, readings.white_noise_std(e.gyr_noise_rad_s_sqrt_hz, rate_hz),
                         (n, 3)), 2000.0 * DEG)
    acc = readings.axes_reading(
        mean_over(f_B), e.acc_cross, e.acc_scale, e.acc_bias_m_s2,
        noise_rng.normal(0.0, readings.white_noise_std(e.acc_noise_m_s2_sqrt_hz, rate_hz),
                         (n, 3)), 16.0 * G_M_S2)
    after = np.zeros(n, dtype=bool)
    for ts in SHOCK_TIMES_S:
        after |= (t >= ts + 1.0) & (t <= ts + 10.0)
    clipped = np.any(np.abs(acc) >= 16.0 * G_M_S2, axis=1)
    return Failure(gyr, acc, t, 1.0 / rate_hz, quat, clipped, {"after_shock": after})


# --- time stamps ---------------------------------------------------------------------------

def timing(kind: str, seed: int, rate_hz: float, duration_s: float = DURATION_S) -> Failure:
    """A realistic hand-held recording (:mod:`~verticality.tilt.evaluation.realistic`, its motion
    class cycling with the seed) whose log fails in time: ``kind`` one of :data:`TIMING`."""
    rng = np.random.default_rng([seed, 9, TIMING.index(kind)])
    motion = rr.MOTIONS[seed % len(rr.MOTIONS)]
    period = 1.0 / rate_hz
    n = int(round(duration_s * rate_hz))
    t_true = np.arange(n) * period
    if kind == "jitter":  # irregular instants: each step 60–140 % of the nominal
        t_true = np.concatenate([[0.0], np.cumsum(rng.uniform(0.6, 1.4, n - 1) * period)])
    omega, f_B, quat = _truth(motion, rng, t_true)
    e = rr.draw_errors(rng)
    noise_rng = np.random.default_rng([seed, 9, TIMING.index(kind), int(rate_hz)])
    walk = readings.random_walk(
        noise_rng.normal(0.0, e.gyr_bias_walk_rad_s_sqrt_s * np.sqrt(period), (n, 3)))
    gyr = readings.axes_reading(
        omega, e.gyr_cross, e.gyr_scale, e.gyr_bias_rad_s + walk,
        noise_rng.normal(0.0, readings.white_noise_std(e.gyr_noise_rad_s_sqrt_hz, rate_hz),
                         (n, 3)), e.gyr_range_rad_s)
    acc = readings.axes_reading(
        f_B, e.acc_cross, e.acc_scale, e.acc_bias_m_s2,
        noise_rng.normal(0.0, readings.white_noise_std(e.acc_noise_m_s2_sqrt_hz, rate_hz),
                         (n, 3)), e.acc_range_m_s2)
    stamps = t_true.copy()
    keep = np.ones(n, dtype=bool)
    if kind == "dropout":  # 8 runs of missing rows of 0.05–1 s
        for start in rng.uniform(6.0, duration_s - 2.0, 8):
            keep &= ~((t_true >= start) & (t_true < start + rng.uniform(0.05, 1.0)))
    elif kind == "clock-jump":  # 3 steps of the logger's clock by ±2–10 s, kept afterwards
        for start in rng.uniform(6.0, duration_s - 2.0, 3):
            stamps = stamps + (t_true >= start) * rng.choice([-1.0, 1.0]) * rng.uniform(2.0, 10.0)
    clipped = np.zeros(int(keep.sum()), dtype=bool)
    return Failure(gyr[keep], acc[keep], stamps[keep], period, quat[keep], clipped, {})


def crash(seed: int, rate_hz: float) -> Failure:
    """The ``crash`` class: :func:`~verticality.tilt.evaluation.shocks.shock_recording` (30 s,
    the impact at 15 s) as a failure recording, with the 5 s at rest after the event as the window
    ``after_impact``. Its sensor's ranges hold the event: nothing is clipped."""
    from verticality.tilt.evaluation.shocks import shock_recording

    r = shock_recording(seed, rate_hz)
    n = r.gyr_rad_s.shape[0]
    t = np.arange(n) * r.dt_s
    after = (t >= r.rest_s) & (t < r.rest_s + 5.0)
    return Failure(r.gyr_rad_s, r.acc_m_s2, t, r.dt_s, r.quat_E_S, np.zeros(n, dtype=bool),
                   {"after_impact": after})


def recording(cls: str, seed: int, rate_hz: float, share: float | None = None) -> Failure:
    """The recording of failure class ``cls`` (:data:`CLASSES`; ``share`` the clipped share for
    the saturation classes)."""
    if cls == "sat-gyro":
        return saturated("gyr", share, seed, rate_hz)
    if cls == "sat-acc":
        return saturated("acc", share, seed, rate_hz)
    if cls == "shock":
        return shock(seed, rate_hz)
    if cls == "crash":
        return crash(seed, rate_hz)
    if cls in TIMING:
        return timing(cls, seed, rate_hz)
    raise ValueError(f"unknown failure class {cls!r}; choose from {', '.join(CLASSES)}")
