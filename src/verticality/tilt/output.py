"""The one output type of the tilt filter: :func:`verticality.tilt.estimate` (causal, a whole
recording), :func:`verticality.tilt.smooth` (offline) and :meth:`verticality.tilt.Stream.step` (one
sample) all return a :class:`TiltEstimate`, whose σ is computed from the parameters of the run
that made it; and the time axis of a recording, from its time stamps or a fixed sampling period.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from verticality.core.errors import InputError
from verticality.io.imu import dt_from_t
from verticality.tilt.layout import E
from verticality.tilt.params import TiltParams


class TiltEstimate(NamedTuple):
    """The tilt filter's estimate, per sample. For a recording every field is an array whose first
    axis is the sample (N); for one sample of a :class:`~verticality.tilt.Stream`, the same fields
    without that axis. Frames: ``S`` the sensor, ``E`` an Earth frame with z up (its heading is
    arbitrary: the filter does not observe it)."""

    t_s: np.ndarray
    """(N,) time of the sample (s): the time stamps given, or ``k × period_s`` from 0."""
    roll_rad: np.ndarray
    """(N,) roll (rad), ZYX convention: ``atan2(up_y, up_z)``."""
    pitch_rad: np.ndarray
    """(N,) pitch (rad), ZYX convention: ``atan2(−up_x, √(up_y² + up_z²))``."""
    up_S: np.ndarray
    """(N, 3) unit vector "up" (opposite to gravity) in the sensor frame: the estimated vertical.
    At rest the accelerometer reads ``g × up_S``."""
    quat_E_S: np.ndarray
    """(N, 4) orientation sensor → Earth as a unit quaternion (w, x, y, z); only its tilt is
    estimated, its heading is the integrated gyro's."""
    bias_S_rad_s: np.ndarray
    """(N, 3) estimated gyro bias (rad/s) in the sensor frame: the gyro reads ω + bias."""
    sigma_rad: np.ndarray
    """(N,) standard deviation of the tilt (rad): the RMS angle between the true and the estimated
    vertical (:func:`tilt_sigma_rad` of ``var`` with the run's parameters)."""
    var: np.ndarray
    """(N, 10) variances of the filter's error state: tilt error about Earth's x and y (rad²),
    horizontal velocity error (m²/s²), gyro bias error (rad²/s²), gyro scale-factor error."""
    flags: np.ndarray
    """(N,) int32 bit set of the sample's events (:mod:`verticality.tilt.flags`: ``DT_GAP``,
    ``REACQUIRING``, ``CLIPPED``, …); 0 for an ordinary sample."""
    measured: np.ndarray
    """(N,) bool: the accelerometer sample entered the filter (False when missing or skipped)."""


def tilt_sigma_rad(var, params: TiltParams) -> np.ndarray:
    """Standard deviation of the tilt (rad) from variances ``var`` ((..., 10)) of a run with
    ``params``: the RMS angle between the true and the estimated vertical, ``sqrt(var_δx + var_δy +
    (c/g)²)``. The first two terms are the filter's covariance of its tilt error (frame-free: the
    trace does not depend on the heading); ``c = params.acc_calib_m_s2`` adds the accelerometer's
    calibration error, a systematic error that the filter cannot average out and that sets the
    error at rest (docs/tilt.md, "The uncertainty"). ``params`` has no default: they must be the
    run's own."""
    v = np.asarray(var, dtype=np.float64)[..., E.tilt]
    # (the two tilt variances added as np.sum adds them, in one buffer: no strided reduction)
    s = np.add(v[..., 0], v[..., 1])
    s += (params.acc_calib_m_s2 / params.g_m_s2) ** 2
    return np.sqrt(s, out=s)


def estimate_of(out, t_s, params: TiltParams) -> TiltEstimate:
    """The :class:`TiltEstimate` of the filter's raw outputs ``out`` (the core's ``TiltOutput``:
    roll, pitch, up, quaternion, bias, variances, flags, measured; NumPy arrays) at times ``t_s``,
    its σ from ``params``, the parameters of the run that made ``out``."""
    return TiltEstimate(np.asarray(t_s, dtype=np.float64), out.roll_rad, out.pitch_rad, out.up_S,
                        out.quat_E_S, out.bias_S_rad_s, tilt_sigma_rad(out.var, params), out.var,
                        out.flags, out.measured)


def time_axis(n: int, t_s=None, period_s=None) -> tuple[np.ndarray, np.ndarray | float]:
    """``(t_s, dt_s)`` of a recording of ``n`` samples given either its time stamps ``t_s`` (N,)
    (s, finite; or date-times, :mod:`verticality.tilt.stamps`: seconds since 1970-01-01 UTC, the
    steps exact) or a fixed sampling period ``period_s`` (s, positive): the time of every sample and
    the step from the previous sample that the filter integrates. With time stamps the first
    sample's step is the median step (:func:`verticality.io.imu.dt_from_t`, as the file readers
    take it; the first sample only initializes the tilt, so its step enters no integration), a
    step that does not go forward skips its sample (flag ``BAD_DT``) and one above
    ``gap_flag_s`` is a gap (flag ``DT_GAP``). With a period, the scalar step itself."""
    if (t_s is None) == (period_s is None):
        raise InputError("give the time as t_s (the N time stamps, s) or period_s (the sampling "
                         "period, s), one of the two")
    if period_s is not None:
        p = np.asarray(period_s, dtype=np.float64)
        if p.ndim != 0 or not np.isfinite(p) or p <= 0:
            raise InputError(f"period_s must be one positive, finite number of seconds; got "
                             f"{period_s!r}")
        return np.arange(n) * float(p), float(p)
    from verticality.tilt.stamps import stamps_seconds, steps_from_ns

    t, ns = stamps_seconds(t_s)  # date-times as seconds since 1970 (UTC), their steps exact
    if t.shape != (n,):
        raise InputError(f"t_s must have shape ({n},), one time stamp per sample; got {t.shape}")
    if not np.all(np.isfinite(t)):
        raise InputError(f"t_s holds {int(np.sum(~np.isfinite(t)))} non-finite time stamp(s) "
                         f"(first at index {int(np.flatnonzero(~np.isfinite(t))[0])}); give "
                         "finite times in seconds")
    if n < 2:
        raise InputError("t_s: one time stamp gives no time step; pass period_s for a single "
                         "sample")
    return t, (dt_from_t(t) if ns is None else steps_from_ns(ns))
