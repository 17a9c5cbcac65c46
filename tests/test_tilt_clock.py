"""Irregular clocks: jittered stamps and repeated stamps (Δt = 0 rows) are filtered with the true
Δt, a row whose stamp is unusable is flagged, and the output keeps one row per input row, in the
library and through ``verticality estimate``."""

import numpy as np
import pytest

from verticality import cli, tilt
from verticality.io import imu
from verticality.tilt import clock, estimator
from verticality.tilt.evaluation.faults import turning
from verticality.tilt.flags import BAD_DT, INIT

G = 9.81
FINE_S = 0.001  # the truth's grid


@pytest.fixture(scope="module")
def truth():
    """A sensor turning about all three axes (up to ~1.5 rad/s) for 40 s on a 1 kHz grid: the
    rate, the rotation and the specific force (gravity only) at every grid time."""
    return turning(40_000, FINE_S, np.random.default_rng(11), max_rate_rad_s=0.5)


def _sample(truth, idx, seed=0):
    """The IMU read at grid indices ``idx``: the mean rate over each interval since the previous
    sample (an integrating gyro), the specific force, white noise; the true up_S and steps."""
    w, R = truth
    rng = np.random.default_rng(seed)
    cum = np.concatenate([np.zeros((1, 3)), np.cumsum(w[1:], axis=0)])  # Σω on the grid
    prev = np.concatenate([[idx[0] - 10], idx[:-1]])
    span = np.maximum(idx - prev, 1)
    gyr = (cum[idx] - cum[prev]) / span[:, None]
    gyr[idx == prev] = w[idx[idx == prev]]  # a repeated stamp: the rate at that time
    acc = G * R[idx, 2, :]
    gyr = gyr + rng.normal(0, 0.002, gyr.shape)
    acc = acc + rng.normal(0, 0.03, acc.shape)
    dts = (idx - prev) * FINE_S
    return gyr, acc, dts, R[idx, 2, :]


def _rms_deg(out, up, keep):
    err = np.degrees(np.arccos(np.clip(np.sum(out.up_S * up, axis=1), -1.0, 1.0)))
    return float(np.sqrt(np.mean(err[keep] ** 2))), err


def test_jittered_stamps_are_filtered_with_the_true_dt(truth):
    """Samples at 100 Hz ± 20 % of Δt: the error is that of the regular recording within a small
    factor, σ covers it, and the nominal Δt in place of the true one is worse."""
    rng = np.random.default_rng(1)
    regular = np.arange(10, 39_990, 10)
    jittered = regular + rng.integers(-2, 3, regular.size)  # ±2 ms of 10 ms
    g0, a0, d0, up0 = _sample(truth, regular)
    g1, a1, d1, up1 = _sample(truth, jittered)
    assert d1.min() < 0.0075 and d1.max() > 0.0125
    ok = slice(300, None)  # after the start's re-acquisition
    rms0, _ = _rms_deg(estimator.estimate_steps(g0, a0, d0), up0, ok)
    out = estimator.estimate_steps(g1, a1, d1)
    rms1, err = _rms_deg(out, up1, ok)
    assert out.flags.shape == (jittered.size,) and not np.any(out.flags[ok] & BAD_DT)
    assert rms1 < 1.5 * rms0, (rms1, rms0)
    sigma = np.degrees(tilt.tilt_sigma_rad(out.var, tilt.DEFAULT_PARAMS))
    assert np.mean(err[ok] <= 2 * sigma[ok]) >= 0.95
    rms_nominal, _ = _rms_deg(tilt.estimate(g1, a1, period_s=0.01), up1, ok)
    assert rms_nominal > 1.2 * rms1, (rms_nominal, rms1)


def test_repeated_stamps_are_flagged_and_keep_their_row(truth):
    """1 % of the rows carry the previous row's stamp (Δt = 0; the next step spans both): those
    rows have nothing to integrate over, so they are skipped and flagged BAD_DT, keep their output
    row (the estimate as it stands), and the rest is filtered as the regular recording."""
    rng = np.random.default_rng(2)
    idx = np.arange(10, 39_990, 10)
    rep = np.sort(rng.choice(np.arange(300, idx.size - 1), 40, replace=False))
    rep = rep[np.diff(rep, prepend=0) > 1]  # no two in a row
    idx[rep] = idx[rep - 1]
    gyr, acc, dts, up = _sample(truth, idx)
    assert np.flatnonzero(dts == 0).tolist() == rep.tolist()
    out = estimator.estimate_steps(gyr, acc, dts)
    assert out.flags.shape == (idx.size,)
    assert np.flatnonzero(out.flags & BAD_DT).tolist() == rep.tolist()
    assert not np.any(out.measured[rep])
    # nothing integrated: the estimate as it stands (unless the row closes a block, whose update
    # then runs as for any skipped sample)
    k_init = int(np.flatnonzero(out.flags & INIT)[0])
    inside = (rep - k_init) % tilt.block_samples(tilt.DEFAULT_PARAMS, dts) != 0
    assert inside.sum() > 25
    np.testing.assert_allclose(out.up_S[rep[inside]], out.up_S[rep[inside] - 1], rtol=0,
                               atol=1e-12)
    g0, a0, d0, up0 = _sample(truth, np.arange(10, 39_990, 10))
    keep = np.ones(idx.size, dtype=bool)
    keep[:300] = False
    rms0, _ = _rms_deg(estimator.estimate_steps(g0, a0, d0), up0, keep)
    rms, err = _rms_deg(out, up, keep)
    assert rms < 1.5 * rms0, (rms, rms0)
    assert np.all(np.isfinite(out.up_S))


def test_estimate_reads_repeated_and_jittered_stamps(tmp_path, truth):
    """``verticality estimate`` on a CSV with jittered and repeated stamps writes one row per input
    row and flags the repeated ones (it used to refuse the file)."""
    rng = np.random.default_rng(3)
    idx = np.arange(10, 20_000, 10) + np.concatenate([[0], rng.integers(-2, 3, 1997), [0]])
    idx[[500, 900, 1400]] = idx[[499, 899, 1399]]
    gyr, acc, _, _ = _sample(truth, idx)
    path = imu.write_imu_csv(tmp_path / "clock.csv", imu.ImuRecording(idx * FINE_S, gyr, acc))
    out_path = tmp_path / "out.csv"
    assert cli.main(["estimate", str(path), "--out", str(out_path)]) == 0
    est = imu.read_estimate_csv(out_path)
    flags = np.asarray(est.flags)
    assert flags.shape == (idx.size,)
    assert np.flatnonzero(flags & BAD_DT).tolist() == [500, 900, 1400]


# ------------------------------------------------------------------ clock jumps and gaps
def _regular_100hz(truth):
    """40 s read at 100 Hz, the readings continuous: gyro, accelerometer, the true stamps."""
    idx = np.arange(10, 39_990, 10)
    gyr, acc, _, up = _sample(truth, idx)
    return gyr, acc, idx * FINE_S, up


def _steps(t):
    return np.concatenate([[0.01], np.diff(t)])


def _kinds(judged):
    return {k: int(judged.kind[k]) for k in np.flatnonzero(judged.kind != clock.NORMAL)}


def test_a_clock_set_forward_or_back_is_a_jump_a_lost_stretch_is_a_gap(truth):
    """The stamps step by +5 s and by −3 s while the readings go on: each is a clock jump (one
    sample at the nominal step, flagged, a small tilt variance); 0.5 s of rows lost: a gap, the step
    as the stamps say (the filter's gap handling); a repeated stamp: skipped (never a zero step)."""
    gyr, acc, t, _ = _regular_100hz(truth)
    t_set = t + 5.0 * (np.arange(t.size) >= 1200) - 3.0 * (np.arange(t.size) >= 2500)
    j = clock.judge_steps(_steps(t_set), gyr, acc)
    assert _kinds(j) == {1200: clock.JUMP, 2500: clock.JUMP}
    assert np.flatnonzero(j.flags & tilt.CLOCK_JUMP).tolist() == [1200, 2500]
    np.testing.assert_allclose(j.dt_s, 0.01, rtol=0, atol=1e-12)  # every step the nominal one
    assert 0.0 < j.tilt_var_rad2[1200] < np.radians(3.0) ** 2  # a few degrees at most
    assert np.count_nonzero(j.tilt_var_rad2) == 2
    # the same rows with 0.5 s lost: the readings after it are the motion's, not the next sample
    lost = np.r_[0:1200, 1250:t.size]
    j = clock.judge_steps(_steps(t[lost]), gyr[lost], acc[lost])
    assert _kinds(j) == {1200: clock.GAP} and not np.any(j.flags)
    assert j.dt_s[1200] == pytest.approx(0.51) and not np.any(j.tilt_var_rad2)
    # a repeated stamp: nothing to integrate over, skipped and left to the filter's BAD_DT
    t_rep = t.copy()
    t_rep[[700, 1900]] = t_rep[[699, 1899]]
    j = clock.judge_steps(_steps(t_rep), gyr, acc)
    assert _kinds(j) == {700: clock.SKIP, 1900: clock.SKIP}
    assert np.isnan(j.dt_s[[700, 1900]]).all() and np.all(j.dt_s[np.isfinite(j.dt_s)] > 0)


def test_a_clock_set_back_across_a_discontinuity_is_a_break(truth):
    """The stamps step back by 3 s where the readings do not go on (0.5 s lost): the sample is
    skipped (the clock not followed), the next one follows the new clock as a gap."""
    gyr, acc, t, _ = _regular_100hz(truth)
    lost = np.r_[0:1200, 1250:t.size]
    t_back = t[lost] - 3.5 * (np.arange(lost.size) >= 1200)
    j = clock.judge_steps(_steps(t_back), gyr[lost], acc[lost])
    assert _kinds(j) == {1200: clock.SKIP, 1201: clock.GAP} and not np.any(j.flags)
    assert j.dt_s[1201] == clock.break_step_s() and np.isnan(j.dt_s[1200])


def test_the_clock_judges_the_same_sample_by_sample_and_in_pieces(truth):
    """:meth:`Clock.step` (the stream), :meth:`Clock.steps` over pieces cut anywhere (the file
    reader) and :func:`judge_steps` (estimate) take every step the same, bit for bit."""
    gyr, acc, t, _ = _regular_100hz(truth)
    t = t + 5.0 * (np.arange(t.size) >= 1200) - 3.0 * (np.arange(t.size) >= 2500)
    t[[700, 3000]] = t[[699, 2999]]
    t[1800] = 1e300
    keep = np.r_[0:2000, 2040:t.size]
    gyr, acc, d = gyr[keep], acc[keep], _steps(t[keep])
    whole = clock.judge_steps(d, gyr, acc)
    assert set(_kinds(whole).values()) == {clock.JUMP, clock.GAP, clock.SKIP}
    c = clock.Clock()
    c.first(gyr[0], acc[0])
    one = [c.step(d[k], gyr[k], acc[k]) for k in range(1, d.size)]
    c = clock.Clock()
    cuts = [0, 5, 1200, 1201, 1799, 2500, d.size]
    pieces = [c.steps(d[a:b], gyr[a:b], acc[a:b]) for a, b in zip(cuts, cuts[1:], strict=False)]
    for k, name in enumerate(clock.Judged._fields[:3]):
        np.testing.assert_array_equal(np.concatenate([getattr(p, name) for p in pieces]),
                                      getattr(whole, name), name)
        np.testing.assert_array_equal([o[k] for o in one], getattr(whole, name)[1:], name)


def test_estimate_and_stream_carry_the_tilt_across_clock_jumps(truth):
    """Clock jumps (+5 s, −3 s, a stamp of 1e300) in a recording whose readings go on: no gap, no
    re-acquisition, the estimate within a small angle of the run on the true stamps, σ covering
    the error; :class:`tilt.Stream` at the same stamps equals it to 1e-9."""
    gyr, acc, t, up = _regular_100hz(truth)
    t_set = t + 5.0 * (np.arange(t.size) >= 1200) - 3.0 * (np.arange(t.size) >= 2500)
    t_set[3100] = 1e300
    clean = tilt.estimate(gyr, acc, t)
    est = tilt.estimate(gyr, acc, t_set)
    assert np.flatnonzero(est.flags & tilt.CLOCK_JUMP).tolist() == [1200, 2500, 3100, 3101]
    assert not np.any(est.flags & (tilt.DT_GAP | tilt.BAD_DT))
    assert not np.any(est.flags[300:] & tilt.REACQUIRED)
    ok = slice(300, None)
    diff = np.degrees(np.arccos(np.clip(np.sum(est.up_S * clean.up_S, axis=1), -1.0, 1.0)))
    assert np.max(diff[ok]) < 0.2, np.max(diff[ok])
    _, err = _rms_deg(est, up, ok)
    assert np.mean(err[ok] <= 2 * np.degrees(est.sigma_rad[ok])) >= 0.95
    s = tilt.Stream(period_s=0.01)
    one = [s.step(gyr[k], acc[k], t_set[k]) for k in range(t.size)]
    for name in ("up_S", "bias_S_rad_s", "var"):
        np.testing.assert_allclose(np.array([getattr(o, name) for o in one]),
                                   np.asarray(getattr(est, name)), rtol=0, atol=1e-9,
                                   err_msg=name)
    np.testing.assert_array_equal([o.flags for o in one], est.flags)
