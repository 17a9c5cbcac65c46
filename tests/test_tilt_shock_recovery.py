"""After a violent event (docs/tilt.md, "After a violent event"): the prototype in the plain-Python
filter (``tilt.stream.Stream`` with ``params.SHOCK_RECOVERY``) brings the tilt back once the
sensor is still, where today's filter stays degrees off for seconds. Stream only (no JAX
compilation): the JAX core has today's behaviour until the port."""

import math

import numpy as np
import pytest

from imu_cases import G
from verticality.core import so3
from verticality.io.broad import inclination_error_deg
from verticality.tilt.evaluation.shocks import shock_recording
from verticality.tilt.flags import ACC_DISTURBED
from verticality.tilt.params import DEFAULT_PARAMS, SHOCK_RECOVERY
from verticality.tilt.stream import Stream

NEW = DEFAULT_PARAMS._replace(**SHOCK_RECOVERY)


def _run(params, gyr, acc, dt, x0=None):
    s = Stream(params, period_s=dt, x0=x0)
    quat, flags, rest, dev = [], [], [], []
    for g, a in zip(gyr.tolist(), acc.tolist(), strict=True):
        out = s.step(g, a, dt)
        quat.append(out[3])
        flags.append(out[5])
        rest.append(s.rest_s)
        dev.append(s.acc_dev_var)
    return s, np.array(quat), np.array(flags), np.array(rest), np.array(dev)


@pytest.fixture(scope="module")
def crash():
    """A crash (free fall, a ~100 m/s² impact with a 13.9 rad/s gyro spike and a spurious gyro
    rotation of several degrees, then rest) at 100 Hz; the seed whose bias the old filter
    corrupts."""
    return shock_recording(6, 100.0, duration_s=12.0, impact_s=5.0)


def test_the_tilt_is_back_once_the_sensor_is_still(crash):
    r = crash
    k0 = int(round(r.impact_s / r.dt_s))
    after = slice(k0 + int(2.0 / r.dt_s), None)  # from 2 s after the impact to the end (7 s)
    _, q_old, *_ = _run(DEFAULT_PARAMS, r.gyr_rad_s, r.acc_m_s2, r.dt_s)
    _, q_new, *_ = _run(NEW, r.gyr_rad_s, r.acc_m_s2, r.dt_s)
    e_old = inclination_error_deg(q_old, r.quat_E_S)
    e_new = inclination_error_deg(q_new, r.quat_E_S)
    assert r.peak_acc_m_s2 > 90.0 and r.peak_rate_rad_s > 13.0
    assert e_old[k0 + int(3.0 / r.dt_s)] > 3.0  # today: still degrees off 3 s after
    assert np.max(e_new[after]) < 1.0  # the accelerometer's calibration error is ~0.8° here
    assert np.max(e_new[:k0]) == pytest.approx(np.max(e_old[:k0]))  # nothing before it moves


def test_a_corrupted_bias_estimate_does_not_block_rest():
    """A still, level sensor whose filter believes a 0.08 rad/s bias on z (as a violent event
    can leave it): today the rest detector waits for |ḡ − b̂| < 2°/s, which the velocity updates
    take seconds to bring; a gyro reading no rotation is rest at once."""
    rng = np.random.default_rng(3)
    n, dt = 500, 0.01
    gyr = rng.normal(0, 1e-3, (n, 3))
    acc = np.tile([0.0, 0.0, G], (n, 1)) + rng.normal(0, 0.02, (n, 3))
    x0 = (np.array([1.0, 0.0, 0.0, 0.0]), np.array([0.0, 0.0, 0.08]))
    s_old, _, _, rest_old, _ = _run(DEFAULT_PARAMS, gyr, acc, dt, x0)
    s_new, _, _, rest_new, _ = _run(NEW, gyr, acc, dt, x0)
    assert np.max(rest_old[:300]) == 0.0  # not rest for 3 s
    assert np.max(rest_new) >= DEFAULT_PARAMS.rest_min_s  # the rest update ran
    assert abs(s_new.b[2]) < 0.005 < abs(s_old.b[2])


def test_a_steady_block_ends_the_disturbance():
    """One block of a 100 m/s² shock on a still sensor: today the disturbance estimate's
    0.5 s low-pass keeps it (and ACC_DISTURBED, and the widened velocity prior) for seconds;
    with the prototype the first steady block after it ends it."""
    rng = np.random.default_rng(4)
    n, dt = 400, 0.01
    gyr = rng.normal(0, 1e-3, (n, 3))
    acc = np.tile([0.0, 0.0, G], (n, 1)) + rng.normal(0, 0.02, (n, 3))
    acc[100:103, 0] += 100.0
    acc[103:106, 0] -= 100.0  # (the velocity comes back: a knock, not a kick)
    _, _, f_old, _, dev_old = _run(DEFAULT_PARAMS, gyr, acc, dt)
    _, _, f_new, _, dev_new = _run(NEW, gyr, acc, dt)
    after = slice(130, None)  # from the second block after the knock
    assert np.any(f_old[after] & ACC_DISTURBED) and dev_old[200] > 1.0
    assert not np.any(f_new[after] & ACC_DISTURBED) and np.max(dev_new[after]) < 0.01


def test_the_defaults_keep_todays_filter():
    """The new parameters' defaults are today's behaviour (the reference tests compare Stream
    with the JAX core to 1e-9): the steady blocks' disturbance time constant is the usual one,
    the raw-gyro rest test is off, and the velocity's rest prior waits as long as the bias's."""
    p = DEFAULT_PARAMS
    assert p.acc_tau_steady_s == p.acc_tau_s and p.rest_gyr_raw_rad_s == 0.0
    assert p.rest_tilt_s == p.rest_min_s
    assert math.isclose(SHOCK_RECOVERY["rest_gyr_raw_rad_s"], p.rest_gyr_rad_s)


def test_crash_recording_is_what_it_says(crash):
    """The shock class: the true body at rest after the event in a new orientation, knocked over
    by tens of degrees, the accelerometer reading g at rest."""
    r = crash
    t = np.arange(r.gyr_rad_s.shape[0]) * r.dt_s
    rest = t > r.rest_s
    assert np.allclose(np.linalg.norm(r.acc_m_s2[rest], axis=1), G, atol=0.3)
    z = np.array([0.0, 0.0, 1.0])
    up_before = np.asarray(so3.quat_rotate(so3.quat_conjugate(r.quat_E_S[0]), z))
    up_after = np.asarray(so3.quat_rotate(so3.quat_conjugate(r.quat_E_S[-1]), z))
    assert np.degrees(np.arccos(np.clip(up_before @ up_after, -1, 1))) > 20.0
