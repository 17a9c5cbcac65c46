"""After a violent event (docs/tilt.md, "After a violent event"): the filter brings the tilt back
once the sensor is still, where the filter without the recovery (``params.NO_SHOCK_RECOVERY``)
stays degrees off for seconds; the plain-Python ``tilt.stream.Stream`` and the JAX batch filter
alike, and equal to each other on a crash."""

import math

import numpy as np
import pytest

from imu_cases import G
from verticality import tilt
from verticality.core import so3
from verticality.io.broad import inclination_error_deg
from verticality.tilt import estimator
from verticality.tilt.evaluation.shocks import shock_recording
from verticality.tilt.flags import ACC_DISTURBED
from verticality.tilt.params import DEFAULT_PARAMS, NO_SHOCK_RECOVERY
from verticality.tilt.stream import Stream

NEW = DEFAULT_PARAMS
OLD = DEFAULT_PARAMS._replace(**NO_SHOCK_RECOVERY)


def _run(params, gyr, acc, dt, x0=None):
    s = Stream(params, period_s=dt, x0=x0)
    quat, flags, rest, dev, bias, sigma = [], [], [], [], [], []
    for g, a in zip(gyr.tolist(), acc.tolist(), strict=True):
        out = s.step(g, a, dt)
        quat.append(out[3])
        bias.append(out[4])
        flags.append(out[5])
        rest.append(s.rest_s)
        dev.append(s.acc_dev_var)
        sigma.append(s.tilt_sigma_rad)
    return s, np.array(quat), np.array(flags), np.array(rest), np.array(dev), np.array(
        bias), np.array(sigma)


@pytest.fixture(scope="module")
def crash():
    """A crash (free fall, a ~100 m/s² impact with a 13.9 rad/s gyro spike and a spurious gyro
    rotation of several degrees, then rest) at 100 Hz; the seed whose bias the old filter
    corrupts."""
    return shock_recording(6, 100.0, duration_s=12.0, impact_s=5.0)


@pytest.fixture(scope="module")
def crash_runs(crash):
    """The crash through Stream and through the batch filter (``tilt.estimate``'s path; one
    compiled shape for both parameter sets), with and without the recovery."""
    r = crash
    return {name: (_run(p, r.gyr_rad_s, r.acc_m_s2, r.dt_s),
                   estimator.estimate_steps(r.gyr_rad_s, r.acc_m_s2, r.dt_s, p))
            for name, p in (("new", NEW), ("old", OLD))}


def _rest_tilt_deg(r):
    """The accelerometer's own tilt error once the sensor is still (its calibration errors: what
    any filter reading it converges to at rest): the angle between the mean specific force from
    0.5 s after the bounce and the true up."""
    t = np.arange(r.gyr_rad_s.shape[0]) * r.dt_s
    f = r.acc_m_s2[t > r.rest_s + 0.5].mean(axis=0)
    up = np.asarray(so3.quat_rotate(so3.quat_conjugate(r.quat_E_S[-1]), np.array([0, 0, 1.0])))
    return math.degrees(math.acos(float(f @ up) / float(np.linalg.norm(f))))


def test_the_tilt_is_back_once_the_sensor_is_still(crash, crash_runs):
    r = crash
    k0 = int(round(r.impact_s / r.dt_s))
    after = slice(k0 + int(2.0 / r.dt_s), None)  # from 2 s after the impact to the end (7 s)
    q_old, q_new = crash_runs["old"][0][1], crash_runs["new"][0][1]
    e_old = inclination_error_deg(q_old, r.quat_E_S)
    e_new = inclination_error_deg(q_new, r.quat_E_S)
    assert r.peak_acc_m_s2 > 90.0 and r.peak_rate_rad_s > 13.0
    assert e_old[k0 + int(3.0 / r.dt_s)] > 3.0  # without the recovery: degrees off 3 s after
    assert np.max(e_new[after]) < 1.0  # the accelerometer's calibration error is ~0.8° here
    assert np.max(e_new[:k0]) == pytest.approx(np.max(e_old[:k0]))  # nothing before it moves


def test_the_batch_filter_recovers_as_the_stream_does(crash, crash_runs):
    """The batch filter (the JAX core's kernel) on the crash: five seconds after the impact
    (3.7 s after the bounce) its tilt is within 0.25° of the accelerometer's own tilt error at
    rest, the best a filter reading that accelerometer can do, and from 2 s on within 0.5° of it;
    without the recovery it is still 2° beyond it. Both equal Stream to 1e-9 (quaternion, bias,
    σ, flags)."""
    r = crash
    k0 = int(round(r.impact_s / r.dt_s))
    k5 = k0 + int(round(5.0 / r.dt_s))
    floor = _rest_tilt_deg(r)
    assert 0.3 < floor < 1.5  # a consumer part's calibration error (tilt.params: ±10 mg, ±1 %)
    err = {name: inclination_error_deg(np.asarray(out.quat_E_S), r.quat_E_S)
           for name, (_, out) in crash_runs.items()}
    assert err["new"][k5] < floor + 0.25
    assert np.max(err["new"][k0 + int(round(2.0 / r.dt_s)):]) < floor + 0.5
    assert err["old"][k5] > floor + 2.0
    for name, ((_, quat, flags, _, _, bias, sigma), out) in crash_runs.items():
        p = NEW if name == "new" else OLD
        np.testing.assert_allclose(quat, out.quat_E_S, rtol=0, atol=1e-9, err_msg=name)
        np.testing.assert_allclose(bias, out.bias_S_rad_s, rtol=0, atol=1e-9, err_msg=name)
        np.testing.assert_allclose(sigma, tilt.tilt_sigma_rad(out.var, p), rtol=0, atol=1e-9,
                                   err_msg=name)
        assert np.array_equal(flags, out.flags), name


def test_a_corrupted_bias_estimate_does_not_block_rest():
    """A still, level sensor whose filter believes a 0.08 rad/s bias on z (as a violent event
    can leave it): without the raw-gyro test the rest detector waits for |ḡ − b̂| < 2°/s, which
    the velocity updates take seconds to bring; a gyro reading no rotation is rest at once."""
    rng = np.random.default_rng(3)
    n, dt = 500, 0.01
    gyr = rng.normal(0, 1e-3, (n, 3))
    acc = np.tile([0.0, 0.0, G], (n, 1)) + rng.normal(0, 0.02, (n, 3))
    x0 = (np.array([1.0, 0.0, 0.0, 0.0]), np.array([0.0, 0.0, 0.08]))
    s_old, _, _, rest_old, *_ = _run(OLD, gyr, acc, dt, x0)
    s_new, _, _, rest_new, *_ = _run(NEW, gyr, acc, dt, x0)
    assert np.max(rest_old[:300]) == 0.0  # not rest for 3 s
    assert np.max(rest_new) >= DEFAULT_PARAMS.rest_min_s  # the rest update ran
    assert abs(s_new.b[2]) < 0.005 < abs(s_old.b[2])


def test_a_steady_block_ends_the_disturbance():
    """One block of a 100 m/s² shock on a still sensor: without the recovery the disturbance
    estimate's 0.5 s low-pass keeps it (and ACC_DISTURBED, and the widened velocity prior) for
    seconds; with it the first steady block after it ends it."""
    rng = np.random.default_rng(4)
    n, dt = 400, 0.01
    gyr = rng.normal(0, 1e-3, (n, 3))
    acc = np.tile([0.0, 0.0, G], (n, 1)) + rng.normal(0, 0.02, (n, 3))
    acc[100:103, 0] += 100.0
    acc[103:106, 0] -= 100.0  # (the velocity comes back: a knock, not a kick)
    _, _, f_old, _, dev_old, *_ = _run(OLD, gyr, acc, dt)
    _, _, f_new, _, dev_new, *_ = _run(NEW, gyr, acc, dt)
    after = slice(130, None)  # from the second block after the knock
    assert np.any(f_old[after] & ACC_DISTURBED) and dev_old[200] > 1.0
    assert not np.any(f_new[after] & ACC_DISTURBED) and np.max(dev_new[after]) < 0.01


def test_no_shock_recovery_is_the_filter_without_it():
    """``NO_SHOCK_RECOVERY`` turns the three parts off (the comparisons above need it to): a
    steady block's disturbance time constant is any block's, the raw-gyro rest test is off, and
    the velocity's rest prior waits as long as the bias's; the defaults have all three on."""
    assert OLD.acc_tau_steady_s == OLD.acc_tau_s and OLD.rest_gyr_raw_rad_s == 0.0
    assert OLD.rest_tilt_s == OLD.rest_min_s
    assert NEW.acc_tau_steady_s < NEW.acc_tau_s and NEW.rest_tilt_s < NEW.rest_min_s
    assert math.isclose(NEW.rest_gyr_raw_rad_s, NEW.rest_gyr_rad_s)


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


def test_the_crash_is_a_class_of_the_validation_set():
    """The validation set's ``crash`` class is this recording, with the 5 s at rest after the
    event as its own scored window and nothing clipped (its sensor's ranges hold the event)."""
    from verticality.tilt.evaluation import failures as fl
    from verticality.tilt.evaluation import validation as tv

    assert "crash" in fl.CLASSES
    f = fl.recording("crash", 1, 50.0)
    r = shock_recording(1, 50.0)
    np.testing.assert_array_equal(f.gyr_rad_s, r.gyr_rad_s)
    np.testing.assert_array_equal(f.quat_E_S, r.quat_E_S)
    after = f.windows["after_impact"]
    assert not f.clipped.any() and math.isclose(f.period_s, r.dt_s)
    assert math.isclose(after.sum() * r.dt_s, 5.0, abs_tol=2 * r.dt_s)
    assert np.all(f.t_s[after] >= r.rest_s)
    assert np.all(np.linalg.norm(f.acc_m_s2[after], axis=1) < G + 0.3)
    case = next(iter(tv.failure_cases(["crash"], [1], [50.0])))
    assert case.dataset == "crash" and case.t_s is None and case.windows["after_impact"].any()
