"""The noise levels a recording implies, offline (docs/tilt.md, "Noise levels from the
recording"): given a whole recording, the :class:`~verticality.tilt.params.TiltParams` to run the
filter or the smoother with, each level bounded by physics.

* **The motion's speed prior** (``vel_m_s``). The velocity pseudo-measurement's noise is the one
  level that the recordings of the validation set disagree on (docs/tilt.md): a hand turning an
  IMU near its wrist makes velocities of centimetres per second, a hand shaking it metres per
  second. It is set from the density of the velocity changes the motion makes: the horizontal
  specific force in Earth (rotated by a first run of the filter), integrated over each update
  interval T, ``Δv``; its per-axis variance over the moving blocks, over T, is ``q_v`` (m²/s³,
  the density of a velocity random walk with those increments), taken robustly (from the median
  absolute deviation: a kick, a tap or a crash is a few blocks, no statistic of the motion; a
  constant tilt error adds a constant ``g δ T`` to every ``Δv`` and leaves it alone), and
  ``vel_m_s = VEL_GAIN_S · √q_v`` within ``[VEL_MIN_M_S, VEL_MAX_M_S]`` (m/s: from a hand turning
  a device about the wrist to a hand shaking it). ``VEL_GAIN_S`` (√s) was chosen by leaving each
  class of the validation set out in turn.
* **The sensors' white noise** (``gyr_noise``, ``acc_noise``), measured on the still blocks (the
  rest detector's test: gyro and accelerometer without variation within the block, the gyro's
  mean below the rest threshold) as the
  within-block variance times the sampling period, bounded by data-sheet ranges (gyro
  0.003–0.1 °/s/√Hz, accelerometer 50–1000 µg/√Hz). The defaults are floors, not sensor
  values (they stand for unmodelled vibration and residual motion as well: docs/tilt.md, "The
  filter (choices)"), so a measured level only raises them.

Maximum likelihood of the velocity innovations was measured and is not used: the
pseudo-measurement's innovation shrinks with its own prior (the prior pulls the velocity state to
zero), so the likelihood grows as the prior tightens and chose the narrowest prior offered on every
recording of the validation set, the least accurate on most of them (docs/tilt.md).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from verticality.core import so3
from verticality.core.constants import G_M_S2
from verticality.tilt.params import DEFAULT_PARAMS, TiltParams, block_samples

VEL_GAIN_S = 4.0  # √s: vel_m_s = VEL_GAIN_S · √(velocity-change density)
VEL_MIN_M_S = 0.2  # a hand turning a device about the wrist
VEL_MAX_M_S = 2.0  # a hand shaking it
GYR_NOISE_RANGE = (math.radians(0.003), math.radians(0.1))  # rad/s/√Hz, data sheets
ACC_NOISE_RANGE = (50e-6 * G_M_S2, 1000e-6 * G_M_S2)  # m/s²/√Hz, data sheets (in g)


class RecordingNoise(NamedTuple):
    """What a recording says of its noise levels (:func:`recording_noise`)."""

    vel_change_density_m2_s3: float  # q_v, per axis (nan: no moving block)
    gyr_noise_rad_s_sqrt_hz: float  # measured on the still blocks (nan: none)
    acc_noise_m_s2_sqrt_hz: float  # (nan: none)
    moving_blocks: int
    still_blocks: int


def _blocks(x, n):
    """(B, n, ...) full blocks of ``x`` (the tail dropped)."""
    b = x.shape[0] // n
    return x[: b * n].reshape((b, n) + x.shape[1:])


def recording_noise(gyr_rad_s, acc_m_s2, dt_s: float, quat_E_S,
                    params: TiltParams = DEFAULT_PARAMS) -> RecordingNoise:
    """The noise statistics of a recording (module doc), given the orientation a first run of
    the filter estimated (``quat_E_S`` (N, 4) wxyz). ``dt_s``: the sampling period (s). Samples
    with a non-finite gyro or accelerometer reading are left out of their block's sums."""
    gyr = np.asarray(gyr_rad_s, dtype=np.float64)
    acc = np.asarray(acc_m_s2, dtype=np.float64)
    n = block_samples(params, dt_s)
    ok = np.all(np.isfinite(gyr), axis=1) & np.all(np.isfinite(acc), axis=1)
    ok &= np.all(np.isfinite(quat_E_S), axis=1)
    f_E = np.asarray(so3.quat_rotate(np.where(ok[:, None], quat_E_S, [1.0, 0, 0, 0]),
                                     np.where(ok[:, None], acc, 0.0)))
    w = _blocks(ok.astype(float), n)
    t_blk = w.sum(axis=1) * dt_s  # the accelerometer's time in each block
    full = t_blk > 0.5 * n * dt_s
    dv = (_blocks(np.where(ok[:, None], f_E[:, :2], 0.0), n).sum(axis=1) * dt_s)
    g = _blocks(np.where(ok[:, None], gyr, 0.0), n)
    a = _blocks(np.where(ok[:, None], acc, 0.0), n)
    cnt = np.maximum(w.sum(axis=1), 1.0)[:, None]
    g_mean = g.sum(axis=1) / cnt
    a_mean = a.sum(axis=1) / cnt
    g_var = np.sum((g - g_mean[:, None]) ** 2 * w[..., None], axis=(1, 2)) / cnt[:, 0]
    a_var = np.sum((a - a_mean[:, None]) ** 2 * w[..., None], axis=(1, 2)) / cnt[:, 0]
    steady = full & (g_var < params.rest_gyr_rad_s**2) & (a_var < params.rest_acc_m_s2**2)
    still = steady & (np.sum(g_mean**2, axis=1) < params.rest_gyr_rad_s**2)
    moving = full & ~still
    if np.count_nonzero(moving) >= 2:
        dvn = dv[moving] / np.sqrt(t_blk[moving])[:, None]
        # a robust variance (the median absolute deviation's, 1.4826 MAD for a Gaussian): a kick,
        # a tap or a crash is a few blocks of the recording and no statistic of its motion
        mad = np.median(np.abs(dvn - np.median(dvn, axis=0)), axis=0)
        q_v = float(np.mean((1.4826 * mad) ** 2))
    else:
        q_v = math.nan
    if np.any(still) and n >= 2:
        # per-axis sample variance × the sampling period: the white noise's density squared
        # (the median over the still blocks: a block with residual motion counts once)
        gyr_d = math.sqrt(float(np.median(g_var[still])) / 3.0 * dt_s * n / (n - 1))
        acc_d = math.sqrt(float(np.median(a_var[still])) / 3.0 * dt_s * n / (n - 1))
    else:
        gyr_d = acc_d = math.nan
    return RecordingNoise(q_v, gyr_d, acc_d, int(np.count_nonzero(moving)),
                          int(np.count_nonzero(still)))


def params_from_noise(noise: RecordingNoise, params: TiltParams = DEFAULT_PARAMS) -> TiltParams:
    """``params`` with the levels ``noise`` implies (module doc), each within its bounds; a level
    the recording does not show (no moving or no still block) is left as it is."""
    out = {}
    if math.isfinite(noise.vel_change_density_m2_s3):
        out["vel_m_s"] = min(max(VEL_GAIN_S * math.sqrt(noise.vel_change_density_m2_s3),
                                 VEL_MIN_M_S), VEL_MAX_M_S)
    if math.isfinite(noise.gyr_noise_rad_s_sqrt_hz):
        lo, hi = GYR_NOISE_RANGE
        out["gyr_noise"] = max(params.gyr_noise, min(max(noise.gyr_noise_rad_s_sqrt_hz, lo), hi))
    if math.isfinite(noise.acc_noise_m_s2_sqrt_hz):
        lo, hi = ACC_NOISE_RANGE
        out["acc_noise"] = max(params.acc_noise, min(max(noise.acc_noise_m_s2_sqrt_hz, lo), hi))
    return params._replace(**out)


def offline_params(gyr_rad_s, acc_m_s2, dt_s: float,
                   params: TiltParams = DEFAULT_PARAMS) -> TiltParams:
    """The :class:`TiltParams` a whole recording implies (module doc): the filter is run once
    with ``params`` (``tilt.estimate``'s batch path) for the orientation that rotates the specific
    force to Earth, then :func:`recording_noise` and :func:`params_from_noise`. For the offline
    estimate (``tilt.smooth``): ``tilt.smooth(gyr, acc, period_s=dt, params=offline_params(gyr,
    acc, dt))``. ``dt_s``: the sampling period (s)."""
    from verticality.tilt import estimator

    out = estimator.estimate_steps(gyr_rad_s, acc_m_s2, dt_s, params)
    return params_from_noise(recording_noise(gyr_rad_s, acc_m_s2, dt_s,
                                             np.asarray(out.quat_E_S), params), params)
