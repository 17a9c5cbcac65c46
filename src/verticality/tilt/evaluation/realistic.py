"""Synthetic IMU recordings of handheld motion with realistic sensor errors and known truth: a
generalization check of the tilt filter that the project runs itself, beside VQF, on recordings
that no parameter of the filter was chosen on (docs/tilt.md, "Realistic synthetic recordings").

A recording is a motion class (like BROAD's: slow or fast rotation, slow or fast translation, with
or without rest breaks), drawn at random, simulated exactly
(:mod:`verticality.simulation.trajectories`, autodiff kinematics; the accelerometer is
:func:`verticality.sensors.readings.specific_force_B` at a lever arm from the rotation centre, as a
hand's IMU sits away from the wrist), and read by a sensor with errors drawn per recording from
consumer MEMS datasheet ranges (:func:`draw_errors`; e.g. Bosch BMI160, InvenSense MPU-9250 and
ICM-20948 data sheets):

* gyro: zero-rate offset uniform in ±1 °/s per axis, sensitivity (scale) error ±1 %, cross-axis
  sensitivity (misalignment) ±1 %, white noise density 0.01 °/s/√Hz, bias random walk
  1e-4 rad/s/√s, range ±2000 °/s or ±500 °/s (half the recordings each), readings clipped there;
* accelerometer: offset ±10 mg per axis (after a user's calibration; uncalibrated parts are
  specified at up to ±40 mg), sensitivity ±1 %, cross-axis ±1 %, white noise 200 µg/√Hz, range
  ±16 g or ±4 g (half each), clipped there;
* sampling rate 100, 200 or 400 Hz (constant: the peers need one rate).

The truth is the simulated orientation; the error of an estimate is BROAD's inclination error
(:func:`verticality.io.broad.inclination_error_deg`), scored from ``SCORE_FROM_S`` on (the filters'
initialization is not what is compared).
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from verticality.core import so3
from verticality.core.constants import G_M_S2
from verticality.io.broad import inclination_error_deg
from verticality.sensors import readings
from verticality.simulation import trajectories

MOTIONS = ("slow_rotation", "fast_rotation", "slow_translation", "fast_translation",
           "rotation_with_breaks", "translation_with_breaks")
# a hand swinging the IMU at a few Hz: rates whose peaks pass a ±500 °/s gyro's range (a few per
# cent of the samples clipped) and accelerations of about a g that are motion, not disturbance
VIGOROUS = "vigorous_handheld"
ALL_MOTIONS = MOTIONS + (VIGOROUS,)
RATES_HZ = (100.0, 200.0, 400.0)
SCORE_FROM_S = 5.0
DEG = np.pi / 180.0


class SensorErrors(NamedTuple):
    """One IMU's errors: a reading is ``clip(M (1 + scale) true + bias + noise, ±range)``, ``M``
    the misalignment (identity plus the cross-axis terms), as ``sensors.readings.axes_reading``
    applies them."""

    gyr_bias_rad_s: np.ndarray  # (3,)
    gyr_scale: np.ndarray  # (3,) relative
    gyr_cross: np.ndarray  # (3, 3) off-diagonal cross-axis sensitivity, zero diagonal
    gyr_noise_rad_s_sqrt_hz: float
    gyr_bias_walk_rad_s_sqrt_s: float
    gyr_range_rad_s: float
    acc_bias_m_s2: np.ndarray  # (3,)
    acc_scale: np.ndarray  # (3,)
    acc_cross: np.ndarray  # (3, 3)
    acc_noise_m_s2_sqrt_hz: float
    acc_range_m_s2: float
    rate_hz: float


def draw_errors(rng: np.random.Generator) -> SensorErrors:
    """A consumer MEMS IMU's errors, drawn from the ranges of the module docstring."""
    def cross(size):
        m = rng.uniform(-size, size, (3, 3))
        np.fill_diagonal(m, 0.0)
        return m

    # Data sheets state accelerometer quantities in g (standard gravity, 9.80665 m/s²); they are
    # converted with the simulation's own gravity so that a range of 16 g is 16 times the gravity
    # the simulated sensor reads at rest.
    return SensorErrors(
        gyr_bias_rad_s=rng.uniform(-1.0, 1.0, 3) * DEG, gyr_scale=rng.uniform(-0.01, 0.01, 3),
        gyr_cross=cross(0.01), gyr_noise_rad_s_sqrt_hz=0.01 * DEG,
        gyr_bias_walk_rad_s_sqrt_s=1e-4,
        gyr_range_rad_s=(2000.0 if rng.uniform() < 0.5 else 500.0) * DEG,
        acc_bias_m_s2=rng.uniform(-0.01, 0.01, 3) * G_M_S2, acc_scale=rng.uniform(-0.01, 0.01, 3),
        acc_cross=cross(0.01), acc_noise_m_s2_sqrt_hz=200e-6 * G_M_S2,
        acc_range_m_s2=(16.0 if rng.uniform() < 0.5 else 4.0) * G_M_S2,
        rate_hz=float(rng.choice(RATES_HZ)))


def random_sines(rng, n_axes, amp, f_lo, f_hi, n_terms=3):
    """Random sums of ``n_terms`` sinusoids per axis: (amplitudes, frequencies Hz, phases)."""
    a = rng.uniform(0.3, 1.0, (n_axes, n_terms)) * np.asarray(amp, float)[:, None] / n_terms
    return (a, rng.uniform(f_lo, f_hi, (n_axes, n_terms)),
            rng.uniform(0, 2 * np.pi, (n_axes, n_terms)))


def _envelope(t, breaks: bool, period_s: float = 20.0):
    """1 throughout, or, with breaks, a smooth on/off of ``period_s``: 5 s of rest in each."""
    if not breaks:
        return 1.0
    u = jnp.mod(t, period_s)
    up = trajectories.smoothstep(jnp.clip(u / 2.0, 0.0, 1.0))
    down = trajectories.smoothstep(jnp.clip((period_s - 5.0 - u) / 2.0, 0.0, 1.0))
    return up * down


def motion(kind: str, rng: np.random.Generator, duration_s: float = 60.0):
    """A handheld motion of class ``kind`` (:data:`MOTIONS`) as a trajectory: Euler angles and a
    position, each a sum of random sinusoids whose amplitudes and frequencies set the class
    (rotation: up to ±1 rad at 0.1–0.4 Hz slow, 0.5–1.5 Hz fast; translation: up to ±0.3 m at
    0.2–0.5 Hz slow, ±0.2 m at 1–3 Hz fast, with small rotations)."""
    if kind not in ALL_MOTIONS:
        raise ValueError(f"unknown motion {kind!r}; choose one of {', '.join(ALL_MOTIONS)}")
    if kind == VIGOROUS:
        return _vigorous(rng, duration_s)
    rotation = "rotation" in kind
    fast = kind.startswith("fast")
    breaks = kind.endswith("with_breaks")
    rot_amp = [1.0, 0.8, 1.5] if rotation else [0.2, 0.2, 0.3]
    rot_f = (0.5, 1.5) if fast else (0.1, 0.4)
    pos_amp = ([0.02] * 3 if rotation else ([0.2] * 3 if fast else [0.3] * 3))
    pos_f = (1.0, 3.0) if fast and not rotation else (0.2, 0.5)
    ra, rf, rp = (jnp.asarray(v) for v in random_sines(rng, 3, rot_amp, *rot_f))
    pa, pf, pp = (jnp.asarray(v) for v in random_sines(rng, 3, pos_amp, *pos_f))

    def series(t, a, f, ph):
        return jnp.sum(a * (jnp.sin(2 * jnp.pi * f * t + ph) - jnp.sin(ph)), axis=1)

    def rpy(t):
        return series(t, ra, rf, rp) * _envelope(t, breaks)

    def position(t):
        return series(t, pa, pf, pp) * _envelope(t, breaks)

    return trajectories.from_euler(position, rpy, duration_s, kind)


def _vigorous(rng: np.random.Generator, duration_s: float):
    """:data:`VIGOROUS`: rotations of up to ±0.8 rad in roll and yaw (±0.5 rad in pitch, clear of
    the Euler angles' singularity) and hand translations of up to ±5 cm, both at 1.5–4 Hz,
    throughout."""
    ra, rf, rp = (jnp.asarray(v) for v in random_sines(rng, 3, [0.8, 0.5, 0.8], 1.5, 4.0))
    pa, pf, pp = (jnp.asarray(v) for v in random_sines(rng, 3, [0.05] * 3, 1.5, 4.0))

    def series(t, a, f, ph):
        return jnp.sum(a * (jnp.sin(2 * jnp.pi * f * t + ph) - jnp.sin(ph)), axis=1)

    return trajectories.from_euler(lambda t: series(t, pa, pf, pp),
                                   lambda t: series(t, ra, rf, rp), duration_s, VIGOROUS)


class Recording(NamedTuple):
    gyr_rad_s: np.ndarray  # (N, 3) as read
    acc_m_s2: np.ndarray  # (N, 3) as read
    dt_s: float
    quat_E_S: np.ndarray  # (N, 4) wxyz, the truth
    errors: SensorErrors
    kind: str


def perfect(e: SensorErrors) -> SensorErrors:
    """``e`` without its errors: no offset, scale, cross-axis, noise or range (the rate kept)."""
    z = np.zeros(3)
    return e._replace(gyr_bias_rad_s=z, gyr_scale=z, gyr_cross=np.zeros((3, 3)),
                      gyr_noise_rad_s_sqrt_hz=0.0, gyr_bias_walk_rad_s_sqrt_s=0.0,
                      gyr_range_rad_s=np.inf, acc_bias_m_s2=z, acc_scale=z,
                      acc_cross=np.zeros((3, 3)), acc_noise_m_s2_sqrt_hz=0.0,
                      acc_range_m_s2=np.inf)


def recording(kind: str, seed: int, duration_s: float = 60.0, ideal: bool = False,
              rate_hz: float | None = None) -> Recording:
    """The recording of motion ``kind`` drawn with ``seed`` (motion, lever arm, sensor errors,
    noise all from it); ``ideal``: the same motion read by a perfect sensor; ``rate_hz``: sampled
    at that rate instead of the drawn one (the same motion and errors; the noise drawn anew)."""
    if kind not in ALL_MOTIONS:
        raise ValueError(f"unknown motion {kind!r}; choose one of {', '.join(ALL_MOTIONS)}")
    rng = np.random.default_rng([seed, ALL_MOTIONS.index(kind)])
    e = draw_errors(rng)
    if kind == VIGOROUS:  # a ±500 °/s gyro (common industrial IMUs' range), a ±16 g accelerometer
        e = e._replace(gyr_range_rad_s=500.0 * DEG, acc_range_m_s2=16.0 * G_M_S2)
    if rate_hz is not None:
        e = e._replace(rate_hz=float(rate_hz))
    e = perfect(e) if ideal else e
    traj = motion(kind, rng, duration_s)
    lever_B_m = rng.uniform(-0.1, 0.1, 3)
    dt = 1.0 / e.rate_hz
    t = np.arange(int(round(duration_s * e.rate_hz))) * dt
    m = trajectories.sample(traj, t)
    f_B = np.asarray(jax.vmap(lambda mm: readings.specific_force_B(mm, jnp.asarray(lever_B_m)))(m))
    n = t.size
    # the draws are NumPy's (one generator per recording, in this order); the error model is
    # the one of sensors.readings
    walk = readings.random_walk(
        rng.normal(0.0, e.gyr_bias_walk_rad_s_sqrt_s * np.sqrt(dt), (n, 3)))
    gyr = readings.axes_reading(
        np.asarray(m.omega_B_rad_s), e.gyr_cross, e.gyr_scale, e.gyr_bias_rad_s + walk,
        rng.normal(0.0, readings.white_noise_std(e.gyr_noise_rad_s_sqrt_hz, e.rate_hz), (n, 3)),
        e.gyr_range_rad_s)
    acc = readings.axes_reading(
        f_B, e.acc_cross, e.acc_scale, e.acc_bias_m_s2,
        rng.normal(0.0, readings.white_noise_std(e.acc_noise_m_s2_sqrt_hz, e.rate_hz), (n, 3)),
        e.acc_range_m_s2)
    quat = np.asarray(so3.quat_from_matrix(m.R_I_B))
    return Recording(gyr, acc, dt, quat, e, kind)


def inclination_rmse_deg(quat_est_wxyz, rec: Recording) -> float:
    """RMS inclination error (deg) from :data:`SCORE_FROM_S` on."""
    err = inclination_error_deg(quat_est_wxyz, rec.quat_E_S)
    k = int(round(SCORE_FROM_S / rec.dt_s))
    return float(np.sqrt(np.mean(err[k:] ** 2)))


def compare(kinds=MOTIONS, seeds=range(5), filters=("verticality", "vqf"), progress=None):
    """Each filter's RMSE (deg) on each recording: ``{(kind, seed): {filter: rmse}}``.
    ``progress(done, total)`` is called after each recording."""
    from verticality.tilt.evaluation.broad import run_filter

    kinds, seeds = list(kinds), list(seeds)
    out = {}
    for i, (kind, seed) in enumerate((k, s) for k in kinds for s in seeds):
        rec = recording(kind, seed)
        out[(kind, seed)] = {f: inclination_rmse_deg(run_filter(f, rec.gyr_rad_s, rec.acc_m_s2,
                                                                rec.dt_s)[0], rec)
                             for f in filters}
        if progress is not None:
            progress(i + 1, len(kinds) * len(seeds))
    return out
