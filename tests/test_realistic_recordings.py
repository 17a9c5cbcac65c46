"""The realistic synthetic recordings (verticality.tilt.evaluation.realistic): the truth is
consistent with what a perfect sensor reads, the drawn errors are applied as documented, the
readings clip at the range, and a recording is a pure function of its seed."""

import numpy as np
import pytest

from verticality.core import so3
from verticality.sensors import readings
from verticality.tilt.evaluation import realistic as rr


@pytest.fixture(scope="module")
def pair():
    return (rr.recording("fast_rotation", 3, duration_s=4.0),
            rr.recording("fast_rotation", 3, duration_s=4.0, ideal=True))


def test_a_perfect_gyro_integrates_to_the_true_orientation(pair):
    _, ide = pair
    q = ide.quat_E_S[0]
    for k in range(ide.gyr_rad_s.shape[0] - 1):  # midpoint rate over each step
        w = 0.5 * (ide.gyr_rad_s[k] + ide.gyr_rad_s[k + 1])
        q = np.asarray(so3.quat_multiply(q, so3.quat_exp(w * ide.dt_s)))
    err = np.degrees(np.linalg.norm(np.asarray(so3.quat_log(
        so3.quat_multiply(so3.quat_conjugate(ide.quat_E_S[-1]), q)))))
    assert err < 0.05, err


def test_a_perfect_accelerometer_reads_gravity_plus_the_lever_arm_motion(pair):
    _, ide = pair
    up_S = np.asarray(so3.quat_rotate(so3.quat_conjugate(ide.quat_E_S), np.array([0, 0, 1.0])))
    # the specific force's component along up is g plus the vertical inertial acceleration,
    # which for these small translations stays well below g
    along = np.sum(ide.acc_m_s2 * up_S, axis=1)
    assert np.all(np.abs(along - 9.81) < 9.81)
    assert np.isclose(np.median(along), 9.81, atol=1.5)


def test_the_drawn_errors_are_applied_and_the_readings_clip(pair):
    rec, ide = pair
    e = rec.errors
    assert (np.all(np.abs(e.gyr_bias_rad_s) <= np.radians(1.0))
            and np.all(np.abs(e.gyr_scale) <= 0.01))
    assert e.rate_hz in rr.RATES_HZ and np.all(np.diag(e.gyr_cross) == 0)
    expect = readings.axes_reading(ide.gyr_rad_s, e.gyr_cross, e.gyr_scale, e.gyr_bias_rad_s, 0.0,
                                   e.gyr_range_rad_s)
    # what remains is the white noise and the bias walk
    resid = rec.gyr_rad_s - expect
    assert np.std(resid) < 5 * e.gyr_noise_rad_s_sqrt_hz * np.sqrt(e.rate_hz / 2) + 1e-3
    clipped = readings.axes_reading(ide.acc_m_s2 * 10, np.zeros((3, 3)), np.zeros(3), np.zeros(3),
                                    0.0, 20.0)
    assert clipped.max() == 20.0 and clipped.min() == -20.0


def test_a_recording_is_a_pure_function_of_its_seed():
    a = rr.recording("slow_translation", 1, duration_s=2.0)
    b = rr.recording("slow_translation", 1, duration_s=2.0)
    c = rr.recording("slow_translation", 2, duration_s=2.0)
    np.testing.assert_array_equal(a.gyr_rad_s, b.gyr_rad_s)
    np.testing.assert_array_equal(a.acc_m_s2, b.acc_m_s2)
    assert not np.array_equal(a.gyr_rad_s[:10], c.gyr_rad_s[:10])
    with pytest.raises(ValueError, match="unknown motion"):
        rr.recording("jogging", 0)


def test_our_filter_is_scored_on_a_recording():
    rec = rr.recording("rotation_with_breaks", 0, duration_s=20.0)
    out = rr.compare(["rotation_with_breaks"], [0], filters=("verticality",))
    assert set(out) == {("rotation_with_breaks", 0)}
    r = out[("rotation_with_breaks", 0)]["verticality"]
    assert np.isfinite(r) and 0.0 < r < 5.0
    assert rec.gyr_rad_s.shape == (int(round(20.0 * rec.errors.rate_hz)), 3)
