"""Parameters of the 3-D tilt filter (:mod:`verticality.tilt`): one set for every
recording, physically motivated (docs/tilt.md, "The filter"), and the default prior covariance and
block length. Constants only, so that the plain-Python reference
(:mod:`verticality.tilt.stream`) can share them without sharing any arithmetic.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from verticality.core.constants import G_M_S2


class TiltParams(NamedTuple):
    """One parameter set for all recordings (physically motivated; see docs/tilt.md).

    Spectral densities, so that the filter behaves the same at any sampling rate:
    ``gyr_noise`` gyro white noise (rad/s/√Hz, T's δ_c); ``bias_walk`` gyro bias random walk
    (rad/s/√s, T's δ_drift, eq. 2); ``acc_noise`` accelerometer white noise entering the integrated
    velocity (m/s²/√Hz, T's δ_a). Velocity prior: ``vel_m_s`` typical speed of the motion with
    correlation time ``vel_corr_s`` (the longest: while moving, the motion's own correlation time,
    estimated from its velocity moments, replaces it when shorter, down to a block; also the
    window of those moments); ``vel_rest_m_s`` at rest. ``acc_missing_m_s2``: unknown
    acceleration assumed while the accelerometer drops out; ``acc_tau_s``: low-pass of ``(|f|−g)²``
    used for the ACC_DISTURBED flag. ``omega_missing_rad_s``: unknown rate assumed while the gyro
    drops out. ``gap_flag_s``: a step Δt above it is a gap in the recording (flag ``DT_GAP``):
    the rotation inside it is unknown (``omega_missing_rad_s`` over the gap); after it the filter
    averages the specific force for ``reacquire_s`` and re-acquires the tilt from that mean
    (flag ``REACQUIRED``). ``init_tilt_rad``: when the accelerometer initializes the filter (no
    ``x0``), the tilt standard deviation added for that sample's unknown inertial acceleration;
    the tilt is then re-acquired after ``reacquire_s`` as after a gap, so a start in motion is
    caught (flag ``REACQUIRING`` until then).
    ``acc_calib_m_s2``: the accelerometer's calibration error (bias, scale, misalignment), which
    gravity alone cannot reveal; it does not change the estimate, only the reported uncertainty
    (``tilt.tilt_sigma_rad``). Its default is a consumer MEMS part's after a user's calibration:
    offsets of ±10 mg and cross-axis sensitivities of ±1 % per axis (data sheets of the Bosch
    BMI160, InvenSense MPU-9250 and ICM-20948), each uniform, tilt gravity's horizontal
    components by about 0.08 m/s² per axis, 0.11 m/s² over both; a better-calibrated part may
    set its own. ``update_s``: the Kalman update interval (s); the gyro is integrated over it
    between updates (:func:`block_samples` turns it into samples at a recording's rate). Short
    against the motion's correlation times (≥ 0.3 s), long enough for the block's velocity
    pseudo-measurement to average the accelerometer's noise: 32 samples at BROAD's 285.7 Hz,
    11 at 100 Hz, 6 at 50 Hz.
    ``acc_disturbed_m_s2``: flag threshold on the disturbance estimate. Under a disturbance the
    speed prior of the velocity pseudo-measurement grows to the speed the disturbance's RMS
    acceleration makes at ``vel_disturbed_hz`` (``a_rms / 2πf`` when above ``vel_m_s``), so that
    hard shaking is not read as tilt. ``vel_jump_nis``: a velocity whose normalized innovation
    squared under the undisturbed prior exceeds it (χ², 2 degrees of freedom; 9.21 is its 99th
    percentile) is a kick that left the sensor moving, not a tilt error: the velocity is forgotten
    and the block flagged ``ACC_DISTURBED``. The same χ² bounds the running mean of the whitened
    velocity innovations over ``vel_corr_s`` (a smaller kick whose velocity persists beyond the
    prior's correlation time): the velocity is then forgotten too, and the tilt and bias variances
    widened by the tilt and bias corrections that velocity made. ``gyr_scale_noise`` (√s):
    gyro errors that grow with the rate (scale factor, axis misalignment), process noise density
    ``(k |ω|)²``. Rest (T eq. 1 with ω = 0, so the canal signal is the drift): when for
    ``rest_min_s`` every block has gyro deviation below ``rest_gyr_rad_s`` and accelerometer
    deviation below ``rest_acc_m_s2``, the block-mean gyro measures the bias, with the residual
    motion ``rest_motion_rad_s`` as extra noise.

    After a violent event (docs/tilt.md, "After a violent event"): a block is *steady* when both
    sensors are present, there is no gap and neither varies within it (gyro and accelerometer
    deviations below ``rest_gyr_rad_s`` and ``rest_acc_m_s2``); ``acc_tau_steady_s`` the
    disturbance estimate's time constant in a steady block (0: the block's own ``(|f| − g)²`` at
    once, so that a shock's memory ends with the shock); ``rest_gyr_raw_rad_s``: a steady block
    whose raw gyro mean is below it counts as quiet whatever the bias estimate (which a violent
    event may have corrupted), besides the usual ``|ḡ − b̂| < rest_gyr_rad_s``; ``rest_tilt_s``:
    the quiet time after which the velocity takes its rest prior (the bias's rest update waits
    ``rest_min_s``). :data:`NO_SHOCK_RECOVERY` sets the filter without them, for comparison.

    ``gap_rate_corr_s``: the correlation time of the angular rate inside a gap, which bridges
    the gap from the rates at both its ends (docs/tilt.md, "Gaps."); 0.25 s = 1 / (2π f) at
    f = 0.64 Hz, the middle (geometric) of hand, head and robot-body motion's 0.2–2 Hz: the
    exponential that integrates like a sinusoid's rate correlation up to its first zero, chosen
    before any measurement; ``math.inf`` the trapezoid, 0 the rate after the gap over the whole
    gap.
    """

    gyr_noise: float = 1e-3
    bias_walk: float = 1e-4
    acc_noise: float = 0.05
    vel_m_s: float = 0.5
    vel_corr_s: float = 1.0
    vel_rest_m_s: float = 0.01
    acc_missing_m_s2: float = 5.0
    acc_tau_s: float = 0.5
    gyr_scale_noise: float = 0.005
    rest_gyr_rad_s: float = 0.035
    rest_acc_m_s2: float = 0.5
    rest_min_s: float = 1.5
    rest_motion_rad_s: float = 0.002
    omega_missing_rad_s: float = 1.0
    acc_disturbed_m_s2: float = 1.0
    g_m_s2: float = G_M_S2
    gap_flag_s: float = 0.1
    reacquire_s: float = 1.0
    init_tilt_rad: float = 1.0
    acc_calib_m_s2: float = 0.11
    vel_disturbed_hz: float = 1.0
    vel_jump_nis: float = 9.21
    update_s: float = 0.112
    acc_tau_steady_s: float = 0.0
    rest_gyr_raw_rad_s: float = 0.035
    rest_tilt_s: float = 0.5
    gap_rate_corr_s: float = 0.25


DEFAULT_PARAMS = TiltParams()
# the filter without the recovery after a violent event (docs/tilt.md, "After a violent event"):
# a steady block's disturbance low-pass as any block's, no raw-gyro rest test, the velocity's rest
# prior after rest_min_s; ``DEFAULT_PARAMS._replace(**NO_SHOCK_RECOVERY)``, for comparisons
NO_SHOCK_RECOVERY = {"acc_tau_steady_s": DEFAULT_PARAMS.acc_tau_s, "rest_gyr_raw_rad_s": 0.0,
                     "rest_tilt_s": DEFAULT_PARAMS.rest_min_s}
# prior covariance of the error state (δx, δy [rad], ṽx, ṽy [m/s], b̃x, b̃y, b̃z [rad/s]). The
# gyro bias prior, 0.1 rad/s (5.7 °/s), covers the turn-on offsets of common MEMS gyros (±1–10 °/s):
# with a tighter prior a bias of 0.1 rad/s left the estimate 11° off for tens of seconds while σ
# claimed 1° (docs/tilt.md, "The uncertainty under faults").
BIAS_PRIOR_RAD_S = 0.1
SCALE_PRIOR = 0.005
DEFAULT_P0 = np.diag([0.05**2, 0.05**2, 0.1**2, 0.1**2] + [BIAS_PRIOR_RAD_S**2] * 3
                     + [SCALE_PRIOR**2] * 3)
BLOCK = 32  # samples per Kalman update of a TiltFilter built without a sampling period


def block_samples(params: TiltParams, dt_s) -> int:
    """The number of samples per Kalman update: ``params.update_s`` over the recording's sampling
    period (the median of its valid steps ``dt_s``, scalar or (N,)), at least one. The filter's
    noise terms are densities and its velocity prior a time constant, so the update interval in
    seconds, not in samples, keeps the filter the same at every rate."""
    dt = np.asarray(dt_s, dtype=np.float64).reshape(-1)
    dt = dt[np.isfinite(dt) & (dt > 0) & (dt < MAX_DT_S)]
    if dt.size == 0:
        return 1
    period = float(dt[0]) if dt.size == 1 else float(np.median(dt))
    return max(1, int(round(params.update_s / period)))

# Physical range of a sample: twice the largest common MEMS ranges (gyros ±2000 °/s, accelerometers
# ±16 g; high-g parts read to ±32 g): a gyro or accelerometer component at or beyond them (±inf
# included) cannot be a reading of the motion but is a corrupt sample (a bit flip, a logger's
# garbage, a wrong unit): it is taken as missing and flagged OUT_OF_RANGE, so that it is never
# propagated. A step beyond MAX_DT_S is a bad step. With these limits no finite input turns the
# estimate non-finite.
MAX_RATE_RAD_S = float(np.radians(4000.0))  # ≈ 69.8 rad/s
MAX_ACC_M_S2 = 50.0 * G_M_S2  # ≈ 490 m/s²
MAX_DT_S = 1e6
# A step counts as a gap when it exceeds gap_flag_s by more than this: the rounding of a regular
# clock's stamps (a 10 Hz clock's 0.1 s steps read as 0.10000000000000009 s; seconds since 1970 in
# float64 are quantized to 2.4e-7 s) is no gap.
GAP_TOLERANCE_S = 1e-6
