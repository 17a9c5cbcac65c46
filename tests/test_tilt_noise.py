"""The noise levels a recording implies (``tilt.noise``, docs/tilt.md, "Noise levels from the
recording"): measured on synthetic recordings with known truth, the orientation given (no filter
run, no JAX compilation)."""

import math

import numpy as np
import pytest

from imu_cases import G
from verticality.tilt import noise
from verticality.tilt.params import DEFAULT_PARAMS

RATE_HZ = 200.0
DT = 1.0 / RATE_HZ


def _level(n):
    return np.tile([1.0, 0.0, 0.0, 0.0], (n, 1))


def _still(seconds, gyr_density, acc_density, seed=0):
    rng = np.random.default_rng(seed)
    n = int(seconds * RATE_HZ)
    gyr = rng.normal(0.0, gyr_density / math.sqrt(DT), (n, 3))
    acc = [0.0, 0.0, G] + rng.normal(0.0, acc_density / math.sqrt(DT), (n, 3))
    return gyr, acc


def _shaken(seconds, amp_m_s2, freq_hz, seed=0, kicks=0):
    """A level sensor translated along x (and y at a third of it), read without noise; ``kicks``
    one-sided 140 m/s² impulses of two samples."""
    rng = np.random.default_rng(seed)
    n = int(seconds * RATE_HZ)
    t = np.arange(n) * DT
    acc = np.zeros((n, 3))
    acc[:, 0] = amp_m_s2 * np.sin(2 * np.pi * freq_hz * t)
    acc[:, 1] = amp_m_s2 / 3 * np.cos(2 * np.pi * freq_hz * t)
    acc[:, 2] = G
    for k in rng.integers(100, n - 100, kicks):
        acc[k:k + 2, 0] += 140.0
    gyr = np.zeros((n, 3))
    gyr[:, 2] = 0.3 * np.sin(2 * np.pi * 0.2 * t)  # turning about the vertical: moving blocks
    return gyr, acc


def test_white_noise_is_measured_on_still_blocks():
    gyr_d, acc_d = math.radians(0.01), 200e-6 * G  # a consumer part's data sheet
    gyr, acc = _still(30.0, gyr_d, acc_d)
    rn = noise.recording_noise(gyr, acc, DT, _level(gyr.shape[0]))
    assert rn.still_blocks > 200 and rn.moving_blocks == 0
    assert rn.gyr_noise_rad_s_sqrt_hz == pytest.approx(gyr_d, rel=0.1)
    assert rn.acc_noise_m_s2_sqrt_hz == pytest.approx(acc_d, rel=0.1)
    assert math.isnan(rn.vel_change_density_m2_s3)  # no motion, no speed prior
    p = noise.params_from_noise(rn)
    # the defaults are floors for unmodelled errors: a quieter sensor keeps them
    assert p.gyr_noise == DEFAULT_PARAMS.gyr_noise and p.acc_noise == DEFAULT_PARAMS.acc_noise
    assert p.vel_m_s == DEFAULT_PARAMS.vel_m_s


def test_a_noisy_gyro_raises_the_floor_within_the_data_sheet_range():
    gyr, acc = _still(30.0, 1.2e-3, 200e-6 * G)  # above the default (the steady test passes
    # a gyro up to ~rest_gyr/√(3 × rate) ≈ 1.4e-3 rad/s/√Hz at 200 Hz)
    p = noise.params_from_noise(noise.recording_noise(gyr, acc, DT, _level(gyr.shape[0])))
    assert p.gyr_noise == pytest.approx(1.2e-3, rel=0.1)
    beyond = noise.RecordingNoise(math.nan, 0.05, 0.05, 0, 100)  # beyond any data sheet
    p = noise.params_from_noise(beyond)
    assert p.gyr_noise == noise.GYR_NOISE_RANGE[1]
    assert p.acc_noise == DEFAULT_PARAMS.acc_noise  # (the range's top is below the default)


def test_the_speed_prior_follows_the_motion_within_bounds():
    vel = {}
    for name, (amp, freq) in {"gentle": (0.05, 0.3), "hand": (0.5, 1.0),
                              "shaking": (30.0, 3.0)}.items():
        gyr, acc = _shaken(30.0, amp, freq)
        rn = noise.recording_noise(gyr, acc, DT, _level(gyr.shape[0]))
        vel[name] = noise.params_from_noise(rn).vel_m_s
    assert vel["gentle"] == noise.VEL_MIN_M_S and vel["shaking"] == noise.VEL_MAX_M_S
    assert noise.VEL_MIN_M_S < vel["hand"] < noise.VEL_MAX_M_S


def test_kicks_do_not_set_the_speed_prior():
    """Thirty one-sided kicks in a gentle motion (as the fault recordings' kicks) are a few blocks,
    no statistic of the motion: the robust variance leaves them out."""
    gyr, acc = _shaken(60.0, 0.5, 1.0)
    q0 = noise.recording_noise(gyr, acc, DT, _level(gyr.shape[0])).vel_change_density_m2_s3
    gyr, acc = _shaken(60.0, 0.5, 1.0, kicks=30)
    q1 = noise.recording_noise(gyr, acc, DT, _level(gyr.shape[0])).vel_change_density_m2_s3
    assert q1 == pytest.approx(q0, rel=0.15)
