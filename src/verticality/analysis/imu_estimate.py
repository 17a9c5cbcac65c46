"""Tilt estimates of an IMU recording (``verticality estimate``): our filter or a peer's, as one
output type, the summary of our filter's uncertainty, and the warning about gaps in the time
stamps."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from verticality.analysis.broad_eval import OURS, run_filter
from verticality.estimators import tilt
from verticality.estimators.tilt_core import gaps_in, up_roll_pitch
from verticality.estimators.tilt_flags import DT_GAP, INIT, REACQUIRED, REACQUIRING


class ImuEstimate(NamedTuple):
    out: tilt.TiltOutput  # NumPy arrays
    tilt_sigma_rad: np.ndarray | None  # (N,) our filter's σ of the tilt; None for a peer


def estimate_imu(gyr_rad_s, acc_m_s2, dt_s, filter_name: str = OURS) -> ImuEstimate:
    """Roll, pitch, gravity direction, bias and flags of a recording by ``filter_name`` (ours:
    ``tilt.estimate`` with its σ; a peer: :func:`peer_output` of its quaternions and bias)."""
    if filter_name == OURS:
        out = tilt.estimate(gyr_rad_s, acc_m_s2, dt_s)
        return ImuEstimate(out, tilt.tilt_sigma_rad(out.var))
    quat, bias = run_filter(filter_name, gyr_rad_s, acc_m_s2, dt_s)
    return ImuEstimate(peer_output(np.asarray(quat), np.asarray(bias), dt_s), None)


def peer_output(quat_wxyz, bias_rad_s, dt_s) -> tilt.TiltOutput:
    """A peer filter's output as a :class:`~verticality.estimators.tilt.TiltOutput`: its
    quaternions (normalized) and bias, the angles from them (as ours), no variances, and of our
    flags only ``DT_GAP`` (a property of the input); every accelerometer sample counted as used
    (the peers take no missing samples)."""
    quat = np.asarray(quat_wxyz, dtype=np.float64)
    quat = quat / np.linalg.norm(quat, axis=1, keepdims=True)
    n = quat.shape[0]
    gap = gaps_in(np.broadcast_to(np.asarray(dt_s, dtype=np.float64), (n,)), tilt.DEFAULT_PARAMS,
                  xp=np)
    up, roll, pitch = up_roll_pitch(tuple(quat.T), xp=np)
    return tilt.TiltOutput(roll, pitch, np.stack(up, axis=1), quat,
                           np.asarray(bias_rad_s, dtype=np.float64), np.zeros((n, 7)),
                           np.where(gap, DT_GAP, 0).astype(np.int32), np.ones(n, dtype=bool))


def sigma_summary(sigma_rad, flags) -> str:
    """One line on the tilt's standard deviation over the samples from the initialization on that
    are not flagged re-acquiring (after the start and each gap the filter has not yet settled on
    the vertical)."""
    init = np.flatnonzero(flags & INIT)
    if init.size == 0:
        return ("tilt σ: no sample initialized the filter (no usable accelerometer sample with a "
                "valid time step), so there is no estimate")
    settled = (flags & REACQUIRING) == 0
    settled[:init[0]] = False
    s = np.degrees(np.asarray(sigma_rad)[settled])
    if s.size == 0:
        return ("tilt σ: every sample is still re-acquiring (the recording is shorter than the "
                "re-acquisition time), the estimate is unconfirmed")
    return (f"tilt σ outside re-acquisitions: median {np.median(s):.2f}°, "
            f"95 % of samples below {np.percentile(s, 95):.2f}°, largest {np.max(s):.2f}°")


def gap_warning(t_s, dt_s, ours: bool = True) -> str | None:
    """A one-line warning when the time stamps have gaps longer than the tilt filter's
    ``gap_flag_s`` (motion inside a gap goes unseen by the gyro integration), else None."""
    p = tilt.DEFAULT_PARAMS
    dt = np.asarray(dt_s, dtype=np.float64)
    gaps = np.flatnonzero(gaps_in(dt, p, xp=np))
    if gaps.size == 0:
        return None
    k = gaps[np.argmax(dt[gaps])]
    if ours:
        what = (f"our filter re-acquires the tilt from the accelerometer {p.reacquire_s:g} s after "
                f"each gap (flag {REACQUIRED}); until then the estimate can be off by the "
                f"rotation inside the gap (flag {REACQUIRING})")
    else:
        what = "this filter's estimate after a gap can be off for seconds"
    return (f"warning: {gaps.size} gap(s) in the time stamps longer than {p.gap_flag_s:g} s "
            f"(largest {dt[k]:.6g} s, ending at t = {t_s[k]:.6g} s): the gyro rate is integrated "
            f"across a gap, so motion inside one is not seen; {what}. Flag {DT_GAP} marks the "
            "sample that ends each gap")
