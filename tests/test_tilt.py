"""3-D otolith–canal tilt filter (verticality.tilt) on synthetic recordings with known
truth: static tilts, constant rotation with a known gyro bias, linear acceleration, NaN, gaps,
irregular time steps; the error-state Jacobian against autodiff; the two batch kernels. The paths
of the filter against each other: tests/test_tilt_reference.py."""

import jax.numpy as jnp
import numpy as np
import pytest

from imu_cases import G, tumbling
from imu_cases import up_S as _up_S
from verticality import tilt
from verticality.core import so3
from verticality.core.errors import InputError
from verticality.tilt import estimator
from verticality.tilt.core import TiltOutput, quat_from_acc
from verticality.tilt.params import BLOCK


def _tilt_err_deg(up_true, up_est):
    c = np.clip(np.sum(up_true * up_est, axis=-1), -1, 1)
    return np.degrees(np.arccos(c))


def _static(roll, pitch, n=1500, dt=0.01, seed=0, gyr_sigma=1e-3, acc_sigma=0.02):
    rng = np.random.default_rng(seed)
    R = np.asarray(so3.matrix_from_quat(so3.quat_from_rpy_radians(roll, pitch, 0.3)))
    acc = G * _up_S(R) + rng.normal(0, acc_sigma, (n, 3))
    gyr = rng.normal(0, gyr_sigma, (n, 3))
    return gyr, acc, dt, _up_S(R)


@pytest.mark.parametrize("roll_deg,pitch_deg", [(0.0, 0.0), (20.0, -35.0), (120.0, 10.0)])
def test_static_tilt_converges_to_truth(roll_deg, pitch_deg):
    gyr, acc, dt, up = _static(np.radians(roll_deg), np.radians(pitch_deg))
    out = tilt.estimate(gyr, acc, period_s=dt)
    assert _tilt_err_deg(up, out.up_S[-1]) < 0.2
    assert abs(np.degrees(out.roll_rad[-1]) - roll_deg) < 0.3
    assert abs(np.degrees(out.pitch_rad[-1]) - pitch_deg) < 0.3
    assert np.all(np.isfinite(out.var)) and np.all(out.var > 0)


def _tumbling(bias, n=6000, dt=0.01, rate=0.4, seed=1):
    gyr, acc, up = tumbling(bias, n, dt, rate, seed)
    return gyr, acc, dt, up


def test_constant_rotation_recovers_known_gyro_bias():
    bias = np.array([0.01, -0.008, 0.006])
    gyr, acc, dt, up = _tumbling(bias)
    out = tilt.estimate(gyr, acc, period_s=dt)
    assert np.max(np.abs(out.bias_S_rad_s[-1] - bias)) < 1.5e-3
    # and the bias variance shrank far below its prior (0.1 rad/s)²
    assert np.all(out.var[-1, 4:7] < 0.2 * 0.01**2)
    err = _tilt_err_deg(up, out.up_S)
    assert np.sqrt(np.mean(err[-2000:] ** 2)) < 0.5
    # gyro integration alone with that bias drifts far more
    assert np.max(np.abs(bias)) * dt * gyr.shape[0] > np.radians(20)


def test_linear_acceleration_rejected_as_translation():
    """Level, still sensor pushed along x at 1 m/s² for 2 s then braked: an accelerometer-only
    tilt reads atan(1/9.81) = 5.8°; the filter keeps most of it out and recovers."""
    dt, n = 0.01, 4000
    t = np.arange(n) * dt
    a_x = np.where((t >= 10) & (t < 12), 1.0, 0.0) - np.where((t >= 12) & (t < 14), 1.0, 0.0)
    rng = np.random.default_rng(2)
    acc = np.column_stack([a_x, np.zeros(n), np.full(n, G)]) + rng.normal(0, 0.02, (n, 3))
    gyr = rng.normal(0, 1e-3, (n, 3))
    out = tilt.estimate(gyr, acc, period_s=dt)
    err = _tilt_err_deg(np.array([0.0, 0.0, 1.0]), out.up_S)
    naive = np.degrees(np.arctan(1.0 / G))
    assert np.max(err) < 0.5 * naive
    assert np.max(err[t > 25]) < 0.2


def test_nan_samples_are_skipped_and_flagged():
    gyr, acc, dt, up = _static(np.radians(10), np.radians(5), n=1200)
    acc[300:400] = np.nan
    gyr[500:520] = np.nan
    dts = np.full(gyr.shape[0], dt)
    dts[700] = np.nan
    dts[701] = -0.01
    acc[:5] = np.nan  # no estimate before the first accelerometer sample
    out = estimator.estimate_steps(gyr, acc, dts)
    for field in out:
        assert np.all(np.isfinite(np.asarray(field))), "a NaN sample leaked into the estimate"
    assert np.all(out.flags[:5] & tilt.ACC_MISSING)
    assert out.flags[5] & tilt.INIT
    assert np.all(out.flags[300:400] & tilt.ACC_MISSING)
    assert np.all(out.flags[500:520] & tilt.GYR_MISSING)
    assert out.flags[700] & tilt.BAD_DT and out.flags[701] & tilt.BAD_DT
    assert not np.any(out.flags[800:] & (tilt.ACC_MISSING | tilt.GYR_MISSING | tilt.BAD_DT))
    # gyro dropout inflates the tilt variance (unknown rotation), the accelerometer pulls it back
    assert out.var[519, 0] > 10 * out.var[499, 0]
    assert _tilt_err_deg(up, out.up_S[-1]) < 0.2


def test_irregular_time_steps_and_gap_use_true_dt():
    """Jittered sampling (5–15 ms) with a 2 s gap during a constant rotation: with the true Δt the
    gyro integration stays right (across the gap by the trapezoid, which carries a steady turn
    whole; the default bridge carries 2τ tanh(T/2τ) = 0.5 s of it, tests/test_tilt_gap_bridge.py);
    the gap inflates the variance."""
    rng = np.random.default_rng(3)
    dts = rng.uniform(0.005, 0.015, 3000)
    dts[1500] = 2.0
    t = np.cumsum(dts)
    rate = 0.3
    R = np.asarray(so3.exp(np.outer(t, [rate, 0.0, 0.0])))
    acc = G * _up_S(R) + rng.normal(0, 0.02, (t.size, 3))
    gyr = np.tile([rate, 0.0, 0.0], (t.size, 1)) + rng.normal(0, 1e-3, (t.size, 3))
    out = estimator.estimate_steps(gyr, acc, dts,
                                   params=tilt.DEFAULT_PARAMS._replace(gap_rate_corr_s=np.inf))
    err = _tilt_err_deg(_up_S(R), out.up_S)
    assert np.sqrt(np.mean(err[500:] ** 2)) < 0.3
    assert np.flatnonzero(out.flags & tilt.DT_GAP).tolist() == [1500]
    # same data but a wrong constant dt (the mean step ignoring the gap) goes wrong at the gap
    bad = tilt.estimate(gyr, acc, period_s=float(np.median(dts)))
    assert np.max(_tilt_err_deg(_up_S(R), bad.up_S)[1500:1600]) > 5 * np.max(err[1500:1600])


def _assert_reacquired_once_after(flags, k_gap):
    """One re-acquisition after the gap at ``k_gap``; every sample from the gap to it (and none
    after it) is flagged REACQUIRING."""
    k_re = np.flatnonzero(flags & tilt.REACQUIRED)
    k_re = k_re[k_re > k_gap]
    assert k_re.size == 1
    on = np.flatnonzero(flags & tilt.REACQUIRING)
    assert on[on >= k_gap].tolist() == list(range(k_gap, k_re[0]))


def test_init_with_given_state_and_quaternion_helper():
    q = quat_from_acc(jnp.array([0.0, 0.0, -G]))  # upside down
    up = np.asarray(so3.matrix_from_quat(q))[2]
    np.testing.assert_allclose(up, [0.0, 0.0, -1.0], atol=1e-12)
    filt = tilt.TiltFilter()
    with pytest.raises(InputError, match="P0 must be"):
        filt.init(P0=np.eye(5))
    with pytest.raises(InputError, match="x0 must be"):
        filt.init((np.zeros(4), np.zeros(3)))
    gyr, acc, dt, up_true = _static(0.2, 0.1, n=300)
    q0 = so3.quat_from_rpy_radians(0.2, 0.1, 0.0)
    _, out = filt.run(filt.init((q0, np.zeros(3))), gyr, acc, dt)
    assert not np.any(out.flags & tilt.INIT)
    assert np.max(_tilt_err_deg(up_true, out.up_S)) < 0.3


def test_start_in_motion_is_reacquired():
    """A level sensor translated back and forth (4 m/s², 0.8 Hz) from its first sample: that
    sample reads 22° of tilt. The filter takes it with an honest variance (init_tilt_rad), flags
    REACQUIRING, and re-acquires the tilt from the specific force averaged over reacquire_s;
    trusting the first sample instead (the same filter given it as x0) is still 11° off at 1.5 s."""
    dt = 0.01
    t = np.arange(0.0, 10.0, dt)
    rng = np.random.default_rng(4)
    a_x = np.where(t < 4.0, 4.0 * np.cos(2 * np.pi * 0.8 * t), 0.0)
    acc = np.column_stack([a_x, np.zeros(t.size), np.full(t.size, G)])
    acc += rng.normal(0, 0.02, acc.shape)
    gyr = rng.normal(0, 1e-3, acc.shape)
    out = tilt.estimate(gyr, acc, period_s=dt)
    err = _tilt_err_deg(np.array([0.0, 0.0, 1.0]), out.up_S)
    k_re = int(np.flatnonzero(out.flags & tilt.REACQUIRED)[0])
    assert out.flags[0] & tilt.INIT and err[0] > 20.0
    _assert_reacquired_once_after(out.flags, 0)
    assert 1.0 <= t[k_re] <= 1.0 + 2 * BLOCK * dt
    assert np.all(np.degrees(np.sqrt(out.var[:k_re, 0])) > 45.0)  # it says it does not know
    k15 = int(round(1.5 / dt))
    assert err[k15] < 2.0 and np.degrees(np.sqrt(out.var[k15, 0])) > err[k15]
    # at rest after the motion it converges, σ covering the error (measured: 0.22° at 8 s, 0.08° at
    # the end)
    sigma = np.degrees(np.sqrt(out.var[:, 0] + out.var[:, 1]))
    assert np.max(err[-200:]) < 0.25 and err[-1] < 0.1 and np.all(err[-200:] < 2 * sigma[-200:])
    filt = tilt.TiltFilter()
    _, trusted = filt.run(filt.init((quat_from_acc(acc[0]), np.zeros(3))), gyr, acc, dt)
    err_trusted = _tilt_err_deg(np.array([0.0, 0.0, 1.0]), trusted.up_S)
    assert err_trusted[k15] > 5 * err[k15]


def test_start_at_rest_reacquires_precisely():
    """Started at rest, every block before the re-acquisition is quiet: the mean specific force is
    then as good as the rest velocity prior says (vel_rest_m_s), not the moving one."""
    gyr, acc, dt, up = _static(np.radians(20.0), np.radians(-35.0), n=300)
    out = tilt.estimate(gyr, acc, period_s=dt)
    k_re = int(np.flatnonzero(out.flags & tilt.REACQUIRED)[0])
    assert np.degrees(np.sqrt(out.var[k_re, 0])) < 0.2
    assert np.max(_tilt_err_deg(up, out.up_S[k_re:])) < 0.2


def test_tilt_sigma_spans_the_start_and_rests_on_the_calibration_floor():
    """The reported σ (tilt_sigma_rad): wide on the sample that initializes from the
    accelerometer, and at rest after the re-acquisition no smaller than the accelerometer's
    calibration error allows (atan(c/g)) and not far above it; the errors stay inside it; a larger
    calibration error raises the floor, the estimate is unchanged."""
    gyr, acc, dt, up = _static(np.radians(20.0), np.radians(-35.0), n=1000)
    out = tilt.estimate(gyr, acc, period_s=dt)
    sigma = np.degrees(out.sigma_rad)
    floor = np.degrees(tilt.DEFAULT_PARAMS.acc_calib_m_s2 / tilt.DEFAULT_PARAMS.g_m_s2)
    assert sigma[0] > 45.0
    k_re = int(np.flatnonzero(out.flags & tilt.REACQUIRED)[0])
    # until the rest update has measured the gyro bias (rest_min_s of quiet) its prior (0.1 rad/s)
    # widens the tilt by 0.1 rad/s × t after the re-acquisition: σ reaches 2.7° for 0.3 s at
    # 100 Hz; from rest on it sits on the floor
    k_rest = int(round(tilt.DEFAULT_PARAMS.rest_min_s / dt)) + 60
    assert np.all(sigma[k_re:] >= floor) and np.all(sigma[k_rest:] < 1.5 * floor)
    assert np.all(_tilt_err_deg(up, out.up_S) <= sigma)
    wide = tilt.DEFAULT_PARAMS._replace(acc_calib_m_s2=0.5)
    out_wide = tilt.estimate(gyr, acc, period_s=dt, params=wide)
    np.testing.assert_array_equal(out_wide.quat_E_S, out.quat_E_S)
    assert np.degrees(out_wide.sigma_rad[-1]) > 2.5


def test_start_in_motion_on_broad():
    """BROAD trial 15 (fast translation) started mid-trial, at sample 15 000: the first sample is
    51° off; from 1.5 to 10 s the RMS error is 2.8° (9.5° when the first sample is trusted; 1.6°
    before the velocity pseudo-measurement was widened under disturbance, which slows the
    convergence during this fast translation while σ keeps covering the error)."""
    from broad_slices import FAST_TRANSLATION
    from verticality.io import broad

    trial = broad.load_trial(FAST_TRANSLATION)
    k0, n = 15_000, int(10 / trial.dt_s)
    out = tilt.estimate(trial.gyr_rad_s[k0:k0 + n], trial.acc_m_s2[k0:k0 + n],
                        period_s=trial.dt_s)
    err = broad.inclination_error_deg(out.quat_E_S, trial.quat_E_S_opt[k0:k0 + n])
    assert err[0] > 40.0
    sel = slice(int(1.5 / trial.dt_s), n)
    assert np.sqrt(np.nanmean(err[sel] ** 2)) < 3.2
    # the reported σ covers the error throughout, the first wrong second included
    sigma = np.degrees(out.sigma_rad)
    fin = np.isfinite(err)
    assert np.all(err[fin] <= 2 * sigma[fin])


def test_taylor_exponential_matches_the_exact_one():
    """The batch kernel's Taylor series of the quaternion exponential matches so3's exact
    exponential to rounding over its whole range (beyond it the kernel falls back to the exact
    one: the large_rotations case of tests/test_tilt_reference.py); and so3's component form
    equals its array form."""
    from verticality.tilt import kernels as tk

    v = np.random.default_rng(6).normal(size=(1000, 3))
    v *= (np.sqrt(tk.SMALL_TH2) * np.random.default_rng(7).uniform(0, 1, 1000)
          / np.linalg.norm(v, axis=1))[:, None]
    v[0] = 0.0
    v[1] = [1e-7, 0.0, 0.0]  # inside the exact formula's small-angle branch
    exact = np.stack(so3.quat_exp_components(v[:, 0], v[:, 1], v[:, 2]), 1)
    taylor = np.stack(tk.quat_exp_taylor(v[:, 0], v[:, 1], v[:, 2]), 1)
    np.testing.assert_allclose(taylor, exact, rtol=0, atol=3e-16)
    np.testing.assert_array_equal(exact, np.asarray(so3.quat_exp(v)))
    q = np.asarray(so3.quat_exp(v * 30.0))  # also large rotations
    r = np.stack(so3.quat_rotate_components(tuple(q.T), tuple(v.T)), 1)
    np.testing.assert_allclose(r, np.asarray(so3.quat_rotate(q, v)), rtol=0, atol=1e-15)


def test_motion_hidden_in_a_gap_is_reacquired_flagged_and_warned_about(tmp_path, capsys):
    """A logger gap of 1 s during which the sensor turns by 30° (still on both sides): the rate
    integrated across the gap is ~0, so the estimate is ~30° off after it. The filter then sums
    the specific force for reacquire_s (1 s) and re-acquires the tilt from its mean. The samples
    in between are flagged REACQUIRING and their variance admits the unknown rotation; the sample
    that ends the gap carries DT_GAP, and `estimate` warns."""
    from verticality import cli
    from verticality.io import imu

    rng = np.random.default_rng(0)
    t = np.concatenate([np.arange(0.0, 10.0, 0.01), np.arange(11.0, 20.0, 0.01)])
    roll = np.where(t < 10.5, 0.0, np.radians(30.0))
    up = _up_S(np.asarray(so3.exp(np.outer(roll, [1.0, 0.0, 0.0]))))
    acc = G * up + rng.normal(0, 0.02, (t.size, 3))
    gyr = rng.normal(0, 1e-3, (t.size, 3))
    out = tilt.estimate(gyr, acc, t)
    err = _tilt_err_deg(up, out.up_S)
    k = int(np.searchsorted(t, 11.0))
    assert np.flatnonzero(out.flags & tilt.DT_GAP).tolist() == [k]
    _assert_reacquired_once_after(out.flags, k)
    k_re = int(np.flatnonzero((out.flags & tilt.REACQUIRED > 0) & (np.arange(t.size) > k))[0])
    assert 1.0 <= t[k_re] - t[k] <= 1.0 + 2 * BLOCK * 0.01  # the averaging time, whole blocks
    assert err[k] > 25.0 and np.all(err[k:k_re] > 25.0)  # what the flags warn of
    # an honest variance from the gap on (mid-block too: the gap's variance is added at once)
    sigma = np.degrees(out.sigma_rad)
    assert np.all(sigma[k:k_re] > 30.0) and np.all(err[k:] < 2 * sigma[k:])
    assert err[k_re] < 1.0 and np.max(err[k_re + 100:]) < 0.3  # re-acquired, then converged
    assert np.sqrt(np.mean(err[200:k] ** 2)) < 0.05  # before the gap: unaffected
    path = imu.write_imu_csv(tmp_path / "gap.csv", imu.ImuRecording(t, gyr, acc))
    capsys.readouterr()
    assert cli.main(["estimate", str(path), "--out", str(tmp_path / "est.csv")]) == 0
    err_txt = capsys.readouterr().err
    assert ("1 gap(s) in the time stamps longer than 0.1 s (largest 1.01 s, ending at t = 11 s)"
            in err_txt)
    est = imu.read_estimate_csv(tmp_path / "est.csv")
    assert est.flags[k] & tilt.DT_GAP and est.flags[k_re] & tilt.REACQUIRED


def test_kernel_without_gap_handling_gives_the_same_numbers(monkeypatch):
    """The batch run uses the kernel without gap handling, in long chunks, where no gap and no
    re-acquisition is in reach (it is faster), and short chunks with gap handling elsewhere (the
    initialization, which is re-acquired too, and the gaps); on a recording with a gap near its
    start and one near its end, that equals the kernel with gap handling everywhere, to
    rounding."""
    from verticality.tilt import batch as tilt_batch
    from verticality.tilt import kernels as tilt_kernels

    n = 2 * tilt_batch.CHUNK_SAMPLES + 3000
    gyr, acc, dt, _ = _tumbling(np.array([0.01, -0.005, 0.002]), n=n)
    acc[100:150] = np.nan
    dts = np.full(n, dt)
    dts[200] = 0.3  # a gap in the first chunk
    dts[n - 1500] = 0.4  # a gap in the third chunk
    used = []
    real = tilt_kernels.run_chunk

    def spy(*args, gaps=True, **kw):
        used.append((gaps, args[2].shape[0] // args[4]))  # (nb * block, CHUNK_SAMPLE), block
        return real(*args, gaps=gaps, **kw)

    monkeypatch.setattr(tilt_kernels, "run_chunk", spy)
    # the filter on the steps as given (estimate would read these continuous readings' steps
    # as clock jumps, tilt.clock)
    filt = estimator.TiltFilter(block=BLOCK)
    fast = filt.run(filt.init(), gyr, acc, dts)[1]  # (the chunks counted in it)
    short, long = ((True, tilt_batch.chunk_blocks(BLOCK, True)),
                   (False, tilt_batch.chunk_blocks(BLOCK, False)))
    assert set(used) == {short, long}
    # one short chunk covers the initialization and the first gap; two long chunks follow (the
    # second gap, in block 558, is beyond the reach of the one starting at block 288); short
    # chunks from block 544 to the end (1975 samples; a tail this short takes them anyway)
    assert short[1] == 32 and long[1] == 256
    assert used == [short, long, long, short, short]
    monkeypatch.setattr(tilt_kernels, "run_chunk", lambda *a, gaps=True, **kw: real(*a, **kw))
    ref = filt.run(filt.init(), gyr, acc, dts)[1]
    for name in TiltOutput._fields:
        np.testing.assert_allclose(getattr(fast, name), getattr(ref, name), rtol=0, atol=1e-12,
                                   err_msg=name)
    _assert_reacquired_once_after(ref.flags, n - 1500)


def test_host_twin_of_the_reacquisition_flag_covers_the_kernel(monkeypatch):
    """``tilt_batch.blocks_needing_gaps`` tells from the data alone which blocks need the kernel's
    gap handling. Against the kernel's own flag (the kernel with gap handling everywhere): every
    block that starts pending or holds a gap is marked, plus at most one block per
    re-acquisition."""
    from verticality.tilt import batch as tilt_batch
    from verticality.tilt import kernels as tilt_kernels

    gyr, acc, dt, _ = _tumbling(np.array([0.01, 0.0, 0.0]), n=3000)
    dts = np.full(3000, dt)
    dts[[800, 850, 1450, 2990]] = [0.3, 0.5, 0.2, 0.3]  # 850 falls while 800 is pending
    acc[1500:1700] = np.nan  # no accelerometer: the re-acquisition after 1450 waits
    real = tilt_kernels.run_chunk
    monkeypatch.setattr(tilt_kernels, "run_chunk", lambda *a, gaps=True, **kw: real(*a, **kw))
    block = tilt.block_samples(tilt.DEFAULT_PARAMS, dts)  # estimate's samples per update
    filt = estimator.TiltFilter(block=block)  # the steps as given (no clock: tilt.clock)
    out = filt.run(filt.init(), gyr, acc, dts)[1]
    fl = out.flags[1:]  # blocks start after the sample that initializes
    nb = -(-fl.size // block)
    pad = np.zeros(nb * block, dtype=fl.dtype)
    pad[:fl.size] = fl
    blocks = pad.reshape(nb, block)
    truth = (blocks[:, 0] & tilt.REACQUIRING > 0) | np.any(blocks & tilt.DT_GAP > 0, axis=1)
    # pending from the start: the initializing sample is re-acquired too
    need = tilt_batch.blocks_needing_gaps(dts, acc, 1, block, tilt.DEFAULT_PARAMS, True, 0.0)
    assert need.shape == truth.shape and np.all(need[truth]) and truth[0]
    n_reacq = int(np.count_nonzero(out.flags & tilt.REACQUIRED))
    assert n_reacq == 3 and np.count_nonzero(need & ~truth) <= n_reacq
    assert truth[(1600 - 1) // block]  # still pending inside the accelerometer dropout


def _error_flow(e, q_hat0, b_hat, omega_rad_s, n, dt):
    """The block's error flow: the true state is the estimate perturbed by the error ``e``
    (``tilt_layout.E``: ``R_true = exp([δ, 0]) R_est``, ``v_true = v_est + ṽ``, ``b_true = b_est
    + b̃``, ``s_true = s_est + s̃`` with ``s_est = 0``); the truth turns at ``omega_rad_s`` (sensor
    frame) without translating, so its gyro reads ``(1 + s_true) ω + b_true`` and its
    accelerometer gravity; the estimate pre-integrates those samples
    with the core and predicts the block (``tilt_core.block_prediction``); the result is the
    error at the block's end. Also returns the nominal block end and the block's inputs."""
    import jax

    from verticality.tilt import core
    from verticality.tilt.layout import NE, E, X

    p = tilt.DEFAULT_PARAMS
    q_true = so3.quat_multiply(so3.quat_exp(jnp.concatenate([e[E.tilt], jnp.zeros(1)])), q_hat0)
    gyr = omega_rad_s * (1.0 + e[E.scale]) + b_hat + e[E.bias]

    def body(c, _):
        q, sums = c
        q = so3.quat_multiply(q, so3.quat_exp(omega_rad_s * dt))
        acc = so3.quat_rotate(so3.quat_conjugate(q), jnp.array([0.0, 0.0, p.g_m_s2]))
        t = core.sample_terms(gyr, acc, jnp.asarray(dt), p)
        return (q, core.accumulate(sums, t)), None

    (q_true, sums), _ = jax.lax.scan(body, (q_true, core.empty_sums()), None, length=n)
    x_hat = X.pack(q=q_hat0, b=b_hat, s=jnp.zeros(3), v=jnp.zeros(2), P=jnp.eye(NE).reshape(-1),
                   acc_dev_var=0.0, rest_s=0.0, reacquire=0.0, reacq_f_E=jnp.zeros(3), reacq_t=0.0,
                   vel_inn=jnp.zeros(2), vel_fix=jnp.zeros(5), speed_var=0.0, dv_var=0.0)
    c = core.block_inputs(sums, p)
    q_end, _, v_end = core.block_prediction(x_hat, c)
    err = so3.quat_log(so3.quat_multiply(q_true, so3.quat_conjugate(q_end)))
    return jnp.concatenate([err[:2], e[E.vel] - v_end, e[E.bias], e[E.scale]]), (q_end, c)


@pytest.mark.parametrize("omega,b_hat", [(np.zeros(3), np.zeros(3)),
                                         ([0.5, -0.3, 0.8], [0.01, -0.02, 0.005])])
def test_error_transition_is_the_jacobian_of_the_block_prediction(omega, b_hat):
    """The hand-derived error-state transition the core uses (``tilt_core.error_transition``)
    against ``jax.jacfwd`` of the error flow (perturb the state by the error → pre-integrate the
    block's samples and predict with the core → difference), at a block of 32 samples of 3.5 ms.

    Sensor still, bias known: equal to rounding, except that the velocity's response to a bias
    (or scale) error is larger by 1 + 1/N: the pre-integration rotates each sample's force by the
    rotation at the sample's end, a right Riemann sum of ∫ t dt = T²/2. Sensor turning at
    |ω| = 1 rad/s: ``F`` holds the block-end rotation over the block (F = exp(F_c T) with R
    frozen), so they differ at first order in |ω|T: by less than |ω|T / 2 of F's largest entry."""
    import jax

    from verticality.tilt import core
    from verticality.tilt.layout import NE, C, E

    n, dt = 32, 0.0035
    omega, b_hat = jnp.asarray(omega, dtype=float), jnp.asarray(b_hat, dtype=float)
    q0 = so3.quat_from_rpy_radians(0.3, -0.2, 0.5)

    def flow(e):
        return _error_flow(e, q0, b_hat, omega, n, dt)

    F_auto = np.asarray(jax.jacfwd(lambda e: flow(e)[0])(jnp.zeros(NE)))
    q_end, c = flow(jnp.zeros(NE))[1]
    F = np.array(core.error_transition(so3.matrix_from_quat(q_end), c[C.T],
                                       tilt.DEFAULT_PARAMS.g_m_s2, c[C.gsum]))
    assert np.max(np.abs(F[E.vel, E.bias])) > 0.01 and np.max(np.abs(F[E.tilt, E.bias])) > 0.05
    # a scale error acts only while turning, as a bias error s̃ ⊙ ω
    assert (np.max(np.abs(F[E.tilt, E.scale])) > 0.01) == bool(np.any(omega))
    F[E.vel, E.bias] *= 1.0 + 1.0 / n
    F[E.vel, E.scale] *= 1.0 + 1.0 / n
    off = np.max(np.abs(F - np.eye(NE)))
    if not np.any(omega):
        np.testing.assert_allclose(F_auto, F, rtol=0, atol=1e-12)
    else:
        wT = float(np.linalg.norm(omega)) * n * dt
        assert 1e-4 * off < np.max(np.abs(F_auto - F)) < 0.5 * wT * off


def test_structured_covariance_propagation_is_the_dense_product():
    """``tilt_core.propagate_covariance`` (the block update's ``F P Fᵀ`` from the structure of
    ``F``, element-wise) equals the dense product with ``error_transition``'s ``F`` to rounding,
    on random covariances, orientations and gyro sums, and is symmetric when ``P`` is."""
    from verticality.tilt import core

    rng = np.random.default_rng(3)
    for _ in range(20):
        q = rng.normal(size=4)
        R = np.asarray(so3.matrix_from_quat(jnp.asarray(q)))[:2]
        T, g, G = rng.uniform(0.01, 1.0), 9.81, rng.normal(size=3)
        M = rng.normal(size=(10, 10)) * rng.uniform(1e-3, 10.0, size=10)
        P = M @ M.T
        F = np.asarray(core.error_transition(R, T, g, G))
        dense = F @ P @ F.T
        assert np.max(np.abs(dense - P)) > 1e-3 * np.max(np.abs(P))  # F is not the identity
        got = np.asarray(core.propagate_covariance(jnp.asarray(P), R, T, g, G))
        np.testing.assert_allclose(got, dense, rtol=0, atol=1e-14 * np.max(np.abs(dense)))
        np.testing.assert_allclose(got, got.T, rtol=0, atol=1e-14 * np.max(np.abs(dense)))


def test_the_filter_is_an_estimator_value_with_named_state():
    """TiltFilter follows the project's estimator interface; its state reads by name the flat
    vectors the kernels use, through one layout per vector."""
    from verticality.estimators.base import Estimator
    from verticality.tilt.layout import NE, Packed, S, X

    filt = tilt.TiltFilter()
    assert isinstance(filt, Estimator)
    assert tilt.TiltFilter(block=16) != filt and hash(tilt.TiltFilter()) == hash(filt)
    q0 = np.asarray(so3.quat_from_rpy_radians(0.2, -0.1, 0.4))
    P0 = np.diag(np.arange(1.0, NE + 1))
    state = filt.init((2.0 * q0, [0.01, 0.02, 0.03]), P0)
    np.testing.assert_allclose(state.quat_E_S, q0, rtol=0, atol=1e-15)
    np.testing.assert_array_equal(state.bias_S_rad_s, [0.01, 0.02, 0.03])
    np.testing.assert_array_equal(state.P, P0)
    assert state.x.shape == (X.size,) and state.sums.shape == (S.size,)
    assert bool(state.initialized) and int(state.count) == 0 and not bool(state.reacquire)
    assert X.size == 128 and S.size == 22 and X.P == slice(9, 109) and X.reacq_t == 115
    assert X.vel_inn == slice(116, 118) and X.vel_fix == slice(118, 123)
    assert X.speed_var == 123 and X.dv_var == 124 and X.s == slice(125, 128)
    L = Packed([("a", 2), ("b", None)])
    np.testing.assert_array_equal(L.pack(xp=np, b=3.0, a=(1.0, 2.0)), [1.0, 2.0, 3.0])
    # the summed form (zero-padded fields added: what the block update's scan fuses) is the same
    rng = np.random.default_rng(1)
    vals = {name: rng.normal(size=size) if size else rng.normal() for name, size in X.fields}
    for xp in (np, jnp):
        np.testing.assert_array_equal(np.asarray(X.pack(xp=xp, summed=True, **vals)),
                                      np.asarray(X.pack(xp=xp, **vals)))
    np.testing.assert_array_equal(L.pack(xp=np, summed=True, b=np.array([3.0, -1.0]),
                                         a=np.array([[1.0, 2.0], [4.0, 5.0]]), axis=0),
                                  [[1.0, 2.0], [4.0, 5.0], [3.0, -1.0]])
    with pytest.raises(ValueError, match="missing"):
        L.pack(xp=np, a=(1.0, 2.0))
    with pytest.raises(ValueError, match="expected 2"):
        L.pack(xp=np, a=np.zeros(3), b=0.0)


@pytest.mark.parametrize("where,value", [("gyr", 1e308), ("gyr", 1e10), ("gyr", -np.inf),
                                         ("gyr", 80.0), ("acc", 1e308), ("acc", 600.0),
                                         ("acc", np.inf)])
def test_one_corrupt_sample_is_flagged_and_skipped_on_every_path(where, value):
    """A component beyond the sensor's physical range is a missing sample flagged OUT_OF_RANGE:
    the batch run, the per-sample step, the stepper and the reference Stream give what they give
    with that component missing (NaN), and everything after it is finite and unflagged by it."""
    from verticality.tilt.stream import Stream

    gyr, acc = _tumbling(np.array([0.01, -0.02, 0.005]), n=700)[:2]
    k = 400
    bad_g, bad_a, nan_g, nan_a = gyr.copy(), acc.copy(), gyr.copy(), acc.copy()
    (bad_g if where == "gyr" else bad_a)[k, 1] = value
    (nan_g if where == "gyr" else nan_a)[k, 1] = np.nan
    out = tilt.estimate(bad_g, bad_a, period_s=0.01)
    ref = tilt.estimate(nan_g, nan_a, period_s=0.01)
    assert out.flags[k] & tilt.OUT_OF_RANGE and not np.any(np.delete(out.flags, k)
                                                            & tilt.OUT_OF_RANGE)
    assert out.flags[k] & (tilt.GYR_MISSING if where == "gyr" else tilt.ACC_MISSING)
    np.testing.assert_array_equal(out.flags & ~tilt.OUT_OF_RANGE, ref.flags)
    np.testing.assert_allclose(out.quat_E_S, ref.quat_E_S, rtol=0, atol=1e-12)
    assert np.all(np.isfinite(out.quat_E_S)) and np.all(np.isfinite(out.var))
    filt = tilt.TiltFilter(block=tilt.block_samples(tilt.DEFAULT_PARAMS, 0.01))  # as estimate's
    s = filt.init()
    stepper = estimator.make_step(period_s=0.01)
    z = stepper.init()
    stream = Stream(period_s=0.01)
    for j in range(k - 40, k + 40):
        if j == k - 40:
            s = filt.run(s, bad_g[:j], bad_a[:j], 0.01)[0]
            for i in range(j):
                z = stepper.step(z, bad_g[i], bad_a[i], 0.01)[0]
                stream.step(bad_g[i], bad_a[i], 0.01)
        s, o = filt.step(s, bad_g[j], bad_a[j], 0.01)
        z, packed = stepper.step(z, bad_g[j], bad_a[j], 0.01)
        fl_stream = stream.step(bad_g[j], bad_a[j], 0.01)[5]
        assert int(o.flags) == int(out.flags[j]) == int(np.asarray(packed)[-1]) == fl_stream
        np.testing.assert_allclose(np.asarray(o.quat_E_S), out.quat_E_S[j], atol=1e-9)


def test_a_regular_10_hz_clock_is_no_gap():
    """Steps of a 10 Hz clock that rounding puts a hair above the gap threshold (0.1 s) are no
    gap: no DT_GAP flag, no re-acquisition after the start's."""
    t = np.arange(300) * 0.1 + 1.7e5  # float stamps: diffs of 0.1 ± 3e-11
    dt = np.diff(t, prepend=t[0] - 0.1)
    assert np.any(dt > 0.1)
    gyr = np.zeros((300, 3))
    acc = np.tile([0.0, 0.0, 9.81], (300, 1))
    out = tilt.estimate(gyr, acc, t)
    assert not np.any(out.flags & tilt.DT_GAP)
    gap = dt.copy()
    gap[150] = 0.1 + 2e-6
    filt = estimator.TiltFilter(block=tilt.block_samples(tilt.DEFAULT_PARAMS, gap))
    assert filt.run(filt.init(), gyr, acc, gap)[1].flags[150] & tilt.DT_GAP  # the filter's rule
    # (through the clock, a sensor at rest on both sides shows no motion lost: one sample)
    assert estimator.estimate_steps(gyr, acc, gap).flags[150] & tilt.CLOCK_JUMP


def test_sigma_stays_honest_under_a_turn_on_bias_of_0_1_rad_s():
    """A gyro bias of 0.1 rad/s (5.7 °/s, inside common MEMS turn-on offsets) on a sensor that
    tumbles from the start: at least 95 % of the unflagged samples are within 2σ of the truth
    (the bias prior covers it: the filter learns it while σ says how far it may be off)."""
    bias = np.array([0.06, -0.06, 0.05])
    gyr, acc, dt, up = _tumbling(bias, n=4000)
    out = tilt.estimate(gyr, acc, period_s=dt)
    err = np.radians(_tilt_err_deg(up, out.up_S))
    sigma = out.sigma_rad
    ok = out.flags == 0
    assert ok.mean() > 0.9
    assert np.mean(err[ok] <= 2 * sigma[ok]) >= 0.95
    np.testing.assert_allclose(out.bias_S_rad_s[-1], bias, atol=0.01)


def test_a_long_recording_read_and_written_in_pieces_equals_the_one_pass(tmp_path, monkeypatch,
                                                                         swinging_imu):
    """`estimate` reads, filters and writes a CSV piece by piece (memory proportional to a piece):
    with pieces of 700 rows, a recording of 5000 rows with NaNs, a gap and an initialization late
    in the first piece gives tilt.estimate's result in the same pieces bit for bit, and the
    one-pass run's to rounding."""
    from verticality.io import imu
    from verticality.tilt import batch as tilt_batch
    from verticality.tilt.files import estimate_file

    rec = swinging_imu(n=5000, dt_s=0.01, seed=7)
    rec.acc_m_s2[:650] = np.nan  # initialized at row 650, late in the first piece
    rec.gyr_rad_s[2000:2010] = np.nan
    t = rec.t_s.copy()
    t[3000:] += 0.5  # a gap
    rec = imu.ImuRecording(t, rec.gyr_rad_s, rec.acc_m_s2)
    src = imu.write_imu_csv(tmp_path / "rec.csv", rec)
    whole = imu.read_imu_csv(src)
    one_pass = tilt.estimate(whole.gyr_rad_s, whole.acc_m_s2, whole.t_s)
    monkeypatch.setattr(tilt_batch, "PIECE_SAMPLES", 700)
    ref = tilt.estimate(whole.gyr_rad_s, whole.acc_m_s2, whole.t_s)
    run = estimate_file(src, tmp_path / "est.csv", sigma=True, piece_rows=700, keep=True)
    got = imu.read_estimate_csv(tmp_path / "est.csv")
    assert run.n == 5000 and not (tmp_path / "est.csv.part").exists()
    np.testing.assert_array_equal(got.roll_rad, ref.roll_rad)
    np.testing.assert_array_equal(got.flags, ref.flags)
    np.testing.assert_array_equal(got.tilt_sigma_rad, ref.sigma_rad)
    for name in tilt.TiltEstimate._fields:
        np.testing.assert_array_equal(getattr(run.out, name), getattr(ref, name), err_msg=name)
        np.testing.assert_allclose(getattr(run.out, name), getattr(one_pass, name), rtol=0,
                                   atol=1e-12, err_msg=name)


@pytest.mark.parametrize("fault", ["bias_0.2", "clipped_2g", "taps"])
def test_sigma_stays_honest_on_the_fault_recordings(fault):
    """On the synthetic fault recordings with known truth (a gyro bias twice the prior, a shake
    clipped by a ±2 g accelerometer, taps that bounce back) at least 95 % of the unflagged samples
    are within 2σ (docs/tilt.md, "The uncertainty under faults")."""
    from verticality.tilt.evaluation.faults import sigma_honesty

    h = sigma_honesty(fault)
    assert h["unflagged"] > 0.75
    assert h["within_2sigma"] >= 0.95, h


def test_sigma_stays_honest_over_the_kick_recordings():
    """Kicks that leave the sensor moving (the benchmark's 20 recordings, pooled): at least 95 %
    of the unflagged samples within 2σ, and no recording below 70 % (before the persistence test
    widened the bias too, a bias the kicks had made wrong drifted the tilt unseen: 68 %)."""
    from verticality.tilt.evaluation.faults import sigma_honesty_over_seeds

    h = sigma_honesty_over_seeds("kicks", range(20))
    assert h["unflagged"] > 0.9
    assert h["within_2sigma"] >= 0.95 and h["worst_within_2sigma"] > 0.7, h


def test_a_csv_with_saturated_readings_is_read_as_it_is_and_the_filter_flags_them(tmp_path):
    """A file's saturated accelerometer readings are read as written (no reader marks them: the
    filter's limits detection is the one place that does, from the flat tops) and flagged
    CLIPPED by ``estimate``, the samples kept."""
    from verticality.io import imu

    rng = np.random.default_rng(3)
    n = 500
    acc = rng.normal(0, 0.03, (n, 3)) + [0.0, 0.0, 9.81]
    acc[100:300, 0] += 30.0 * np.sin(np.arange(200) * 2 * np.pi * 3 * 0.01)  # a shake beyond 2 g
    acc = np.clip(acc, -19.62, 19.62)
    gyr = rng.normal(0, 1e-3, (n, 3))
    path = tmp_path / "clipped.csv"
    rows = np.column_stack([np.arange(n) * 0.01, gyr, acc])
    path.write_text("t,gyr_x,gyr_y,gyr_z,acc_x,acc_y,acc_z\n"
                    + "".join(",".join(repr(float(v)) for v in r) + "\n" for r in rows))
    rec = imu.read_imu_csv(path)
    np.testing.assert_array_equal(rec.acc_m_s2, acc)
    at = np.any(np.abs(acc) == 19.62, axis=1)
    assert at.sum() > 10
    out = tilt.estimate(rec.gyr_rad_s, rec.acc_m_s2, rec.t_s)
    assert np.array_equal((out.flags & tilt.CLIPPED) > 0, at)
    assert not np.any(out.flags & (tilt.OUT_OF_RANGE | tilt.ACC_MISSING))


def test_sigma_stays_honest_under_shaking_and_clipping_and_kicks_are_not_read_as_tilt():
    """On the synthetic fault recordings with known truth (docs/tilt.md, "The uncertainty under
    faults"): shaking, clipped or not, taps and kicks keep ≥ 95 % of the unflagged samples within
    2σ (five recordings of each, pooled); forgetting a kick's velocity keeps the error of the kick
    recording below what reading it as tilt gives."""
    from verticality.tilt.evaluation.faults import fault_recording, sigma_honesty_over_seeds

    for fault in ("shake", "clipped_2g", "taps", "kicks"):
        # measured 100.0, 100.0, 100.0 and 99.5 %; kicks 80.0 % without the persistence test
        assert sigma_honesty_over_seeds(fault, range(5))["within_2sigma"] >= 0.95, fault
    gyr, acc, dt, up = fault_recording("kicks", seed=2)
    rms = []
    for params in (tilt.DEFAULT_PARAMS, tilt.DEFAULT_PARAMS._replace(vel_jump_nis=np.inf)):
        out = tilt.estimate(gyr, acc, period_s=dt, params=params)
        err = np.arccos(np.clip(np.sum(out.up_S * up, axis=1), -1, 1))
        rms.append(np.degrees(np.sqrt(np.mean(err**2))))
    assert rms[0] < 0.7 * rms[1], rms  # measured 3.0° against 5.9°
