"""The tilt filter's paths against each other, case by case: the JAX core's batch ``run``, its
per-sample ``step`` under ``lax.scan`` (the sequential reference of ``run``), the packed real-time
``Stepper``, and the plain-Python ``verticality.tilt.stream.Stream``, an independent implementation
of the same filter (as PyVQF stands beside VQF's C++). The cases: a BROAD slice, NaNs in every
channel, readings beyond any IMU, irregular Δt, gaps (two while one is pending), dropouts of either
sensor, a start in motion, rest, rotations beyond the batch kernel's Taylor range, a given initial
state, no usable accelerometer at all; the σ of every path."""

import jax
import numpy as np
import pytest

from broad_slices import FAST_ROTATION
from imu_cases import G, tumbling
from verticality import tilt
from verticality.estimators.base import scan_steps
from verticality.tilt import core as tilt_core
from verticality.tilt import estimator
from verticality.tilt.flags import (
    ACC_MISSING,
    BAD_DT,
    DT_GAP,
    GYR_MISSING,
    INIT,
    REACQUIRED,
    REACQUIRING,
)
from verticality.tilt.params import BLOCK
from verticality.tilt.stream import Stream

N = 1600  # every case has this many samples: the sequential reference compiles once



def _tumbling(bias, n=N, dt=0.01, rate=0.4, seed=1):
    gyr, acc, _ = tumbling(bias, n, dt, rate, seed)
    return gyr, acc, np.full(n, dt)


def _broad_slice():
    from verticality.io import broad

    trial = broad.load_trial(FAST_ROTATION)  # a fast-rotation stretch of N samples
    assert trial.gyr_rad_s.shape[0] == N
    return (trial.gyr_rad_s, trial.acc_m_s2, np.full(N, trial.dt_s)), None


def _nans_irregular_gap():
    rng = np.random.default_rng(5)
    gyr, acc, _ = _tumbling(np.array([0.01, -0.005, 0.0]))
    dts = rng.uniform(0.005, 0.015, N)
    acc[:3] = np.nan
    acc[300:420] = np.nan
    gyr[700:710] = np.nan
    dts[900] = np.nan
    dts[901] = -0.01
    dts[1200] = 1.5  # gap
    return (gyr, acc, dts), None


def _nan_every_channel():
    """One component at a time (and infinities), in every channel, scattered over blocks."""
    gyr, acc, dts = _tumbling(np.array([0.004, 0.0, -0.003]), seed=2)
    for c in range(3):
        gyr[100 + 37 * c, c] = np.nan
        acc[400 + 41 * c, c] = np.nan
    gyr[600, 1] = np.inf
    acc[650, 2] = -np.inf
    acc[700] = 0.0  # a zero accelerometer is no measurement either
    dts[[800, 801, 900]] = [np.nan, 0.0, np.inf]
    return (gyr, acc, dts), None


def _beyond_limits():
    """Finite readings beyond any IMU (tilt_params.MAX_*): missing, so the estimate stays
    finite."""
    gyr, acc, dts = _tumbling(np.array([0.0, 0.0, 0.004]), seed=8)
    gyr[200] = 1e200
    gyr[210, 1] = -2e4
    acc[400] = 1e300
    acc[410, 0] = 2e6
    dts[[600, 601]] = [1e300, 2e6]
    return (gyr, acc, dts), None


def _gaps_and_dropouts():
    """Gaps while a re-acquisition is pending, an accelerometer dropout that delays one, a gyro
    dropout across a block boundary."""
    gyr, acc, dts = _tumbling(np.array([0.01, 0.0, 0.0]), seed=3)
    dts[[300, 340, 900, 1590]] = [0.3, 0.5, 0.2, 0.3]  # 340 falls while 300 is pending
    acc[950:1150] = np.nan  # no accelerometer: the re-acquisition after 900 waits
    gyr[1300:1340] = np.nan
    return (gyr, acc, dts), None


def _start_in_motion():
    """A level sensor translated back and forth (4 m/s², 0.8 Hz) from its first sample, then
    still: rest detection and the bias update run after it."""
    dt = 0.01
    t = np.arange(N) * dt
    rng = np.random.default_rng(4)
    a_x = np.where(t < 4.0, 4.0 * np.cos(2 * np.pi * 0.8 * t), 0.0)
    acc = np.column_stack([a_x, np.zeros(N), np.full(N, G)]) + rng.normal(0, 0.02, (N, 3))
    gyr = np.array([0.003, -0.002, 0.001]) + rng.normal(0, 1e-3, (N, 3))
    return (gyr, acc, np.full(N, dt)), None


def _large_rotations():
    """|ω|Δt = 0.4 rad per sample: beyond the batch kernel's Taylor range (exact fallback)."""
    return _tumbling(np.zeros(3), dt=0.05, rate=8.0), None


def _given_x0():
    gyr, acc, dts = _tumbling(np.array([0.0, 0.006, 0.0]), seed=6)
    q0 = np.asarray(tilt_core.quat_from_acc(acc[0]))
    return (gyr, acc, dts), (q0, np.array([0.0, 0.005, 0.0]))


def _never_initialized():
    gyr, acc, dts = _tumbling(np.zeros(3), seed=7)
    acc[:] = np.nan
    dts[500] = 0.4
    return (gyr, acc, dts), None


def _kicks_and_shaking():
    """One-sided kicks, then hard shaking: the kick gates forget the velocity (the one-block test,
    and the persistence test at sample 512) and the prior widens under the disturbance (every
    branch of the velocity update)."""
    from verticality.tilt.evaluation.faults import fault_recording

    gyr_k, acc_k, dt, _ = fault_recording("kicks", seed=3)
    gyr_k, acc_k = gyr_k[:N // 2], acc_k[:N // 2]
    gyr_s, acc_s, _, _ = fault_recording("shake", n=2000, seed=1)  # shaking from 12 s to 20 s
    gyr = np.concatenate([gyr_k, gyr_s[2000 - N // 2:]])
    acc = np.concatenate([acc_k, acc_s[2000 - N // 2:]])
    return (gyr, acc, np.full(gyr.shape[0], dt)), None


CASES = {"broad_slice": _broad_slice, "kicks_and_shaking": _kicks_and_shaking,
         "nans_irregular_gap": _nans_irregular_gap,
         "nan_every_channel": _nan_every_channel, "beyond_limits": _beyond_limits,
         "gaps_and_dropouts": _gaps_and_dropouts,
         "start_in_motion": _start_in_motion, "large_rotations": _large_rotations,
         "given_x0": _given_x0, "never_initialized": _never_initialized}

FILTER = estimator.TiltFilter()


@jax.jit
def _scan(state, gyr, acc, dts):
    return scan_steps(FILTER.step, state, gyr, acc, dts)


def _stream(gyr, acc, dts, x0):
    s = Stream(x0=x0, block=FILTER.block)
    rows, sigma = [], []
    for k in range(gyr.shape[0]):
        rows.append(s.step(gyr[k], acc[k], dts[k]))
        sigma.append(s.tilt_sigma_rad)
    return s, {"roll_rad": np.array([r[0] for r in rows]),
               "pitch_rad": np.array([r[1] for r in rows]),
               "up_S": np.array([r[2] for r in rows]), "quat_E_S": np.array([r[3] for r in rows]),
               "bias_S_rad_s": np.array([r[4] for r in rows]),
               "flags": np.array([r[5] for r in rows]), "tilt_sigma_rad": np.array(sigma)}


@pytest.fixture(scope="module", params=list(CASES))
def case(request):
    (gyr, acc, dts), x0 = CASES[request.param]()
    state0 = FILTER.init(x0)
    final, out = FILTER.run(state0, gyr, acc, dts)
    return request.param, (gyr, acc, dts), x0, state0, final, out


def test_reference_stream_equals_core(case):
    """The independent plain-Python filter gives the core's outputs and σ to 1e-9, and ends in
    the same state."""
    name, (gyr, acc, dts), x0, _, final, out = case
    s, got = _stream(gyr, acc, dts, x0)
    sigma = tilt.tilt_sigma_rad(out.var, tilt.DEFAULT_PARAMS)
    for field, val in got.items():
        want = sigma if field == "tilt_sigma_rad" else getattr(out, field)
        np.testing.assert_allclose(val, want, rtol=0, atol=1e-9, err_msg=f"{name}: {field}")
    np.testing.assert_allclose(s.P, final.P, rtol=0, atol=1e-12, err_msg=name)
    np.testing.assert_allclose(s.q, final.quat_E_S, rtol=0, atol=1e-9, err_msg=name)
    assert s.count == int(final.count) and s.initialized == bool(final.initialized)


def test_batch_run_equals_sequential_steps(case):
    """``run`` (the batch kernel) equals ``step`` applied sample by sample under ``lax.scan``,
    outputs and final state (a block in progress included), to rounding."""
    name, (gyr, acc, dts), _, state0, final, out = case
    ref_final, ref = _scan(state0, gyr, acc, dts)
    for field in tilt_core.TiltOutput._fields:
        np.testing.assert_allclose(np.asarray(getattr(out, field)),
                                   np.asarray(getattr(ref, field)), rtol=0, atol=1e-12,
                                   err_msg=f"{name}: {field}")
    for field in tilt_core.TiltState._fields:
        np.testing.assert_allclose(np.asarray(getattr(final, field)),
                                   np.asarray(getattr(ref_final, field)), rtol=0, atol=1e-12,
                                   err_msg=f"{name}: state {field}")
    assert np.array_equal(out.measured, (out.flags & (ACC_MISSING | BAD_DT)) == 0)
    for field in out:  # nothing finite became non-finite
        assert np.all(np.isfinite(np.asarray(field, dtype=float))), name


def test_run_continues_from_any_state(case):
    """``run`` over the recording in four pieces, cut inside blocks (one just after a gap), each
    from the state the previous one returned, gives the single run's outputs."""
    name, (gyr, acc, dts), _, state0, final, out = case
    state, parts = state0, []
    for lo, hi in ((0, 45), (45, 305), (305, 1000), (1000, N)):  # 305: a gap in the block
        state, o = FILTER.run(state, gyr[lo:hi], acc[lo:hi], dts[lo:hi])
        parts.append(o)
    for i, field in enumerate(tilt_core.TiltOutput._fields):
        np.testing.assert_allclose(np.concatenate([p[i] for p in parts]), out[i], rtol=0,
                                   atol=1e-12, err_msg=f"{name}: {field}")
    np.testing.assert_allclose(state.x, final.x, rtol=0, atol=1e-12, err_msg=name)


@pytest.mark.parametrize("name", ["gaps_and_dropouts", "start_in_motion"])
def test_packed_stepper_equals_step(name):
    """The real-time JAX stepper (state and outputs as flat vectors) gives ``step``'s numbers."""
    (gyr, acc, dts), x0 = CASES[name]()
    n = 400 if name == "start_in_motion" else N  # past the re-acquisitions and the gaps
    stepper = estimator.make_step(x0=x0, block=FILTER.block)
    z = stepper.init()
    state = FILTER.init(x0)
    _, ref = _scan(state, gyr, acc, dts)
    for k in range(n):
        z, o = stepper.step(z, gyr[k], acc[k], dts[k])
        want = np.concatenate([[ref.roll_rad[k], ref.pitch_rad[k]], ref.up_S[k], ref.quat_E_S[k],
                               ref.bias_S_rad_s[k], [ref.flags[k]]])
        np.testing.assert_allclose(np.asarray(o), want, rtol=0, atol=1e-12, err_msg=f"{k}")
    final, _ = FILTER.run(FILTER.init(x0), gyr[:n], acc[:n], dts[:n])
    np.testing.assert_allclose(stepper.unpack(z).P, final.P, atol=1e-15)


def _reacquired_once_after(flags, k_gap):
    k_re = np.flatnonzero(flags & REACQUIRED)
    k_re = k_re[k_re > k_gap]
    assert k_re.size == 1
    on = np.flatnonzero(flags & REACQUIRING)
    assert on[on >= k_gap].tolist() == list(range(k_gap, k_re[0]))


def test_the_cases_exercise_what_they_claim(case):
    """Each case reaches the branch it is there for (so that the comparisons above cover it)."""
    name, (gyr, acc, dts), _, _, final, out = case
    f = out.flags
    if name == "broad_slice":
        assert np.max(np.abs(out.bias_S_rad_s[-1])) > 0  # the block updates really ran
    elif name == "nans_irregular_gap":
        assert f[3] & INIT and f[900] & BAD_DT and f[901] & BAD_DT
        assert np.all(f[300:420] & ACC_MISSING) and np.all(f[700:710] & GYR_MISSING)
        assert np.flatnonzero(f & DT_GAP).tolist() == [1200]
        _reacquired_once_after(f, 1200)
        # no estimate before the initialization, and the initialization is unsure: σ says so
        assert np.all(np.degrees(tilt.tilt_sigma_rad(out.var[:4], tilt.DEFAULT_PARAMS)) > 45.0)
    elif name == "nan_every_channel":
        assert all(f[100 + 37 * c] & GYR_MISSING and f[400 + 41 * c] & ACC_MISSING
                   for c in range(3))
        assert f[600] & GYR_MISSING and f[650] & ACC_MISSING and f[700] & ACC_MISSING
        assert all(f[k] & BAD_DT for k in (800, 801, 900))
    elif name == "beyond_limits":
        assert f[200] & GYR_MISSING and f[210] & GYR_MISSING
        assert f[400] & ACC_MISSING and f[410] & ACC_MISSING
        assert f[600] & BAD_DT and f[601] & BAD_DT and not np.any(f & DT_GAP)
    elif name == "gaps_and_dropouts":
        assert np.flatnonzero(f & DT_GAP).tolist() == [300, 340, 900, 1590]
        assert np.count_nonzero(f & REACQUIRED) == 3  # the start, after 340, after 900
        k_re = np.flatnonzero(f & REACQUIRED)
        assert k_re[-1] > 1150  # waited for the accelerometer
        assert np.all(f[1590:] & REACQUIRING) and int(final.count) > 0
    elif name == "start_in_motion":
        assert f[0] & INIT
        assert np.any(np.diff(out.bias_S_rad_s[:, 0]) != 0)
        assert final.rest_s >= tilt.DEFAULT_PARAMS.rest_min_s  # the rest update ran
    elif name == "kicks_and_shaking":
        for change in ({"vel_jump_nis": np.inf}, {"vel_disturbed_hz": 1e9}):  # each branch matters
            other = estimator.estimate_steps(gyr, acc, dts, tilt.DEFAULT_PARAMS._replace(**change))
            assert np.max(np.abs(other.up_S - out.up_S)) > 1e-3, change
    elif name == "large_rotations":
        rot2 = np.sum((gyr * dts[:, None]) ** 2, axis=1)
        from verticality.tilt.kernels import SMALL_TH2

        assert np.all(rot2 > SMALL_TH2)
    elif name == "given_x0":
        assert not np.any(f & (INIT | REACQUIRING | REACQUIRED))
    elif name == "never_initialized":
        assert not np.any(f & INIT) and not bool(final.initialized)
        # no estimate anywhere, and σ says so (not P0's 4°)
        assert np.all(np.degrees(tilt.tilt_sigma_rad(out.var, tilt.DEFAULT_PARAMS)) > 45.0)
        assert f[500] & DT_GAP


def test_predict_is_step_without_accelerometer():
    """``predict`` is ``step`` with the accelerometer missing, in the middle of a block and at its
    end (the block update runs on what the block holds)."""
    gyr, acc, dts = _tumbling(np.array([0.01, 0.0, 0.0]), n=100)
    state, _ = FILTER.run(FILTER.init(), gyr[:60], acc[:60], dts[:60])
    for k in range(60, 100):
        predicted = FILTER.predict(state, gyr[k], dts[k])
        stepped, out = FILTER.step(state, gyr[k], np.full(3, np.nan), dts[k])
        for a, b in zip(predicted, stepped, strict=True):
            np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
        assert not bool(out.measured) and out.flags & ACC_MISSING
        state = predicted
    assert np.asarray(tilt_core.TiltState(*state).count) == (100 - 1) % BLOCK


def _clipped_and_held():
    """A fast roll read by a ±7 rad/s gyro, a shake beyond a ±2 g accelerometer, and held rows
    (a logger repeating its sensor), with the ranges given (a stream cannot infer them)."""
    from imu_cases import fast_roll

    gyr, acc, _ = fast_roll(n=N, peak=12.0, centers_s=(4.0, 10.0), seed=9)
    acc[700:740, 0] += 25.0 * np.sin(np.arange(40) * 2 * np.pi * 3 * 0.01)
    gyr[900:904] = gyr[899]  # held: the sensor's last reading, repeated
    acc[900:904] = acc[899]
    ranges = {"gyr_range_rad_s": 7.0, "acc_range_m_s2": 2 * G}
    return np.clip(gyr, -7.0, 7.0), np.clip(acc, -2 * G, 2 * G), np.full(N, 0.01), ranges


def test_reference_stream_clipping_and_held_rows_equal_core():
    """Clipped gyro and accelerometer samples and held rows: the plain-Python stream (detecting
    them sample by sample from the given ranges) gives the batch run's outputs and σ to 1e-9 given
    the limits a stream can know (it cannot see a clipped run's end, so no peak is fitted:
    ``fit_peaks=False``), and the batch run (``tilt.estimate``, each clipped run's peak fitted and
    added to the readings) equals the core's ``step`` given the same limits and readings."""
    from verticality.tilt import batch as tilt_batch
    from verticality.tilt import limits as tilt_limits
    from verticality.tilt.flags import CLIPPED, HELD

    gyr, acc, dts, ranges = _clipped_and_held()
    block = tilt.block_samples(tilt.DEFAULT_PARAMS, dts)  # as estimate's
    causal = tilt_limits.find_limits(gyr, acc, dts, **ranges, fit_peaks=False)
    out = tilt_batch.run(tilt.DEFAULT_PARAMS, block, tilt.TiltFilter(block=block).init(), gyr,
                         acc, dts, **causal.run_args())[1]
    f = out.flags
    assert np.count_nonzero(f & CLIPPED) > 40 and np.flatnonzero(f & HELD).tolist() == [900, 901,
                                                                                         902, 903]
    assert np.count_nonzero(f & CLIPPED) > 40 and not np.any(f & ACC_MISSING)  # (both kept)
    s = Stream(**ranges, block=block)
    rows, sigma = [], []
    for k in range(N):
        rows.append(s.step(gyr[k], acc[k], dts[k]))
        sigma.append(s.tilt_sigma_rad)
    np.testing.assert_array_equal(np.array([r[5] for r in rows]), f)
    np.testing.assert_allclose(np.array([r[2] for r in rows]), out.up_S, rtol=0, atol=1e-9)
    np.testing.assert_allclose(sigma, tilt.tilt_sigma_rad(out.var, tilt.DEFAULT_PARAMS), rtol=0,
                               atol=1e-9)
    out = estimator.estimate_steps(gyr, acc, dts, **ranges)
    np.testing.assert_array_equal(out.flags & (CLIPPED | HELD), f & (CLIPPED | HELD))
    lim = estimator.recording_limits(gyr, acc, dts, **ranges)
    assert np.all(lim.tilt_var_rad2 >= 0) and lim.tilt_var_rad2.max() > 0
    assert np.all(lim.vel_var_m2_s2 >= 0) and lim.vel_var_m2_s2.max() > 0
    assert lim.gyr_excess_rad_s.any() and lim.acc_excess_m_s2.any()
    gyr, acc = lim.readings(gyr, acc)

    filt = tilt.TiltFilter(block=tilt.block_samples(tilt.DEFAULT_PARAMS, dts))  # as estimate's

    @jax.jit
    def scan(state, gyr, acc, dts, var, vvar, flags):
        def one(state, xs):
            g, a, d, v, vv, fl = xs
            return tilt_core.step(state, g, a, d, filt.params, filt.block, v, fl, vv)
        return jax.lax.scan(one, state, (gyr, acc, dts, var, vvar, flags))

    _, ref = scan(filt.init(), gyr, acc, dts, lim.tilt_var_rad2, lim.vel_var_m2_s2, lim.flags)
    for field in tilt_core.TiltOutput._fields:
        np.testing.assert_allclose(np.asarray(getattr(out, field)),
                                   np.asarray(getattr(ref, field)), rtol=0, atol=1e-12,
                                   err_msg=field)
