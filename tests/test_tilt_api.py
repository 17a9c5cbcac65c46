"""The tilt API (``verticality.tilt``): ``estimate``, ``smooth`` and ``Stream`` return one output
type, ``TiltEstimate``, on the same input the same fields; the time as stamps or a period gives the
numbers of the steps the readers compute; σ comes from the run's own parameters; the flags are
exported; bad input is a one-line InputError."""

from __future__ import annotations

import numpy as np
import pytest

from imu_cases import tumbling
from verticality import tilt
from verticality.core.errors import InputError
from verticality.io.imu import dt_from_t
from verticality.tilt import estimator, flags

DT = 0.01


@pytest.fixture(scope="module")
def recording():
    """A sensor turning with a gyro bias, with missing accelerometer and gyro samples."""
    gyr, acc, _ = tumbling(np.array([0.01, -0.005, 0.002]), 1500, DT)
    acc[400:430] = np.nan
    gyr[900:905] = np.nan
    return gyr, acc


def test_batch_stream_and_offline_return_one_type_with_the_same_fields(recording):
    gyr, acc = recording
    est = tilt.estimate(gyr, acc, period_s=DT)
    off = tilt.smooth(gyr, acc, period_s=DT)
    s = tilt.Stream(period_s=DT)
    one = [s.step(gyr[k], acc[k]) for k in range(gyr.shape[0])]
    assert type(est) is type(off) is type(one[0]) is tilt.TiltEstimate
    n = gyr.shape[0]
    shapes = {"t_s": (n,), "roll_rad": (n,), "pitch_rad": (n,), "up_S": (n, 3),
              "quat_E_S": (n, 4), "bias_S_rad_s": (n, 3), "sigma_rad": (n,), "var": (n, 10),
              "flags": (n,), "measured": (n,)}
    assert set(tilt.TiltEstimate._fields) == set(shapes)
    for name, shape in shapes.items():
        assert np.shape(getattr(est, name)) == shape == np.shape(getattr(off, name)), name
        stream = np.array([getattr(o, name) for o in one])
        assert stream.shape == shape, name
        # the stream is the plain-Python implementation: equal to the batch kernel to rounding
        np.testing.assert_allclose(stream.astype(float), np.asarray(getattr(est, name), float),
                                   rtol=0, atol=1e-9, err_msg=name)
    np.testing.assert_array_equal(est.t_s, np.arange(n) * DT)
    np.testing.assert_array_equal(off.t_s, est.t_s)
    np.testing.assert_array_equal(off.flags, est.flags)
    np.testing.assert_array_equal(off.measured, est.measured)
    assert np.any(est.flags & tilt.ACC_MISSING) and not np.all(est.measured)
    # the smoother's own σ: from its (smaller) variances, by the same function
    np.testing.assert_array_equal(off.sigma_rad, tilt.tilt_sigma_rad(off.var, tilt.DEFAULT_PARAMS))
    settled = slice(300, None)
    assert np.median(off.sigma_rad[settled]) < np.median(est.sigma_rad[settled])


def test_time_stamps_and_a_period_give_the_numbers_of_the_steps(recording):
    """``period_s`` is the scalar step of the step-level run bit for bit; time stamps are the
    readers' steps (``io.imu.dt_from_t``: their differences, the first the median) bit for bit,
    and a regular clock's stamps equal the period to rounding."""
    gyr, acc = recording
    t = 3.0 + np.arange(gyr.shape[0]) * DT
    by_period = tilt.estimate(gyr, acc, period_s=DT)
    by_stamps = tilt.estimate(gyr, acc, t)
    raw_period = estimator.estimate_steps(gyr, acc, DT)
    raw_stamps = estimator.estimate_steps(gyr, acc, dt_from_t(t))
    for name in raw_period._fields:
        np.testing.assert_array_equal(getattr(by_period, name), getattr(raw_period, name), name)
        np.testing.assert_array_equal(getattr(by_stamps, name), getattr(raw_stamps, name), name)
        np.testing.assert_allclose(np.asarray(getattr(by_stamps, name), float),
                                   np.asarray(getattr(by_period, name), float), rtol=0,
                                   atol=1e-9, err_msg=name)
    np.testing.assert_array_equal(by_stamps.t_s, t)
    off = tilt.smooth(gyr, acc, t)
    raw_off = estimator.smooth_steps(gyr, acc, dt_from_t(t))
    for name in raw_off._fields:
        np.testing.assert_array_equal(getattr(off, name), getattr(raw_off, name), name)
    # the stream at the same stamps: the same samples as with the period
    s_t, s_p = tilt.Stream(), tilt.Stream(period_s=DT)
    for k in range(400):
        a, b = s_t.step(gyr[k], acc[k], t[k]), s_p.step(gyr[k], acc[k])
        assert a.t_s == t[k] and b.t_s == k * DT
        np.testing.assert_allclose(a.up_S, b.up_S, rtol=0, atol=1e-9)
        assert a.flags == b.flags


def test_sigma_is_computed_from_the_runs_own_parameters(recording):
    """A run with a wider accelerometer calibration error reports the σ of that calibration, not
    of the default parameters, in every path."""
    gyr, acc = recording
    wide = tilt.DEFAULT_PARAMS._replace(acc_calib_m_s2=0.5)  # a 2.9° floor instead of ~0.3°
    floor_deg = np.degrees(wide.acc_calib_m_s2 / wide.g_m_s2)
    est = tilt.estimate(gyr, acc, period_s=DT, params=wide)
    off = tilt.smooth(gyr, acc, period_s=DT, params=wide)
    s = tilt.Stream(period_s=DT, params=wide)
    last = [s.step(gyr[k], acc[k]) for k in range(gyr.shape[0])][-1]
    for sigma in (est.sigma_rad, off.sigma_rad, np.array([last.sigma_rad])):
        assert np.all(np.degrees(sigma) >= floor_deg)
    np.testing.assert_array_equal(est.sigma_rad, tilt.tilt_sigma_rad(est.var, wide))
    default_sigma = tilt.tilt_sigma_rad(est.var, tilt.DEFAULT_PARAMS)
    settled = slice(-300, None)  # long after the dropouts: the calibration floor shows
    assert np.all(np.degrees(est.sigma_rad[settled] - default_sigma[settled]) > 1.0)
    assert abs(last.sigma_rad - est.sigma_rad[-1]) < 1e-9
    with pytest.raises(TypeError):
        tilt.tilt_sigma_rad(est.var)  # no default parameters to fall back on


def test_flag_constants_are_exported():
    names = ["ACC_MISSING", "GYR_MISSING", "BAD_DT", "ACC_DISTURBED", "INIT", "DT_GAP",
             "REACQUIRED", "REACQUIRING", "OUT_OF_RANGE", "CLIPPED", "HELD", "LOG_BREAK",
             "CLOCK_JUMP"]
    bits = [getattr(tilt, name) for name in names]
    assert bits == [getattr(flags, name) for name in names] == [getattr(tilt.flags, name)
                                                                 for name in names]
    assert len(set(bits)) == len(bits) and all(b & (b - 1) == 0 and b > 0 for b in bits)
    assert set(tilt.FLAG_NAMES) == set(bits)


@pytest.mark.parametrize(("args", "kwargs", "match"), [
    ((np.zeros((10, 3)), np.zeros((10, 3))), {}, "t_s .* or period_s"),
    ((np.zeros((10, 3)), np.zeros((10, 3)), np.arange(10.0)), {"period_s": 0.01}, "one of the two"),
    ((np.zeros((10, 3)), np.zeros((10, 3))), {"period_s": 0.0}, "period_s must be"),
    ((np.zeros((10, 3)), np.zeros((10, 3))), {"period_s": np.nan}, "period_s must be"),
    ((np.zeros((10, 3)), np.zeros((10, 3)), np.arange(9.0)), {}, r"t_s must have shape \(10,\)"),
    ((np.zeros((10, 3)), np.zeros((10, 3)), np.r_[np.arange(9.0), np.nan]), {},
     "non-finite time stamp"),
    ((np.zeros((10, 2)), np.zeros((10, 3))), {"period_s": 0.01}, r"shape \(N, 3\)"),
    ((np.zeros((10, 3)), np.zeros((9, 3))), {"period_s": 0.01}, r"shape \(N, 3\)"),
    ((np.zeros((1, 3)), np.zeros((1, 3)), np.zeros(1)), {}, "one time stamp"),
])
@pytest.mark.parametrize("fn", ["estimate", "smooth"])
def test_bad_input_is_a_one_line_input_error(fn, args, kwargs, match):
    with pytest.raises(InputError, match=match) as info:
        getattr(tilt, fn)(*args, **kwargs)
    assert "\n" not in str(info.value)


def test_a_stream_needs_its_time():
    g, a = np.zeros(3), np.array([0.0, 0.0, 9.81])
    with pytest.raises(InputError, match="t_s"):
        tilt.Stream().step(g, a)
    with pytest.raises(InputError, match="period_s"):
        tilt.Stream(period_s=-1.0)
    s = tilt.Stream()
    s.step(g, a, 1.0)
    with pytest.raises(InputError, match="finite"):
        s.step(g, a, np.nan)
    # a stamp that does not go forward skips its sample and leaves the clock where it was
    assert s.step(g, a, 0.5).flags & tilt.BAD_DT
    assert not s.step(g, a, 1.01).flags & tilt.BAD_DT
