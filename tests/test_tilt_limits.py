"""Sensors at their limits (tilt/limits.py): clipped gyro and accelerometer axes, given
or inferred from flat tops, and held rows; what the filter makes of them against the unclipped
truth."""

import numpy as np
import pytest

from broad_slices import ALL
from imu_cases import G, fast_roll
from verticality import tilt
from verticality.core.errors import InputError
from verticality.tilt import limits as tilt_limits
from verticality.tilt.flags import ACC_MISSING, CLIPPED, HELD

CLIP_RAD_S = 7.0


def _err_deg(out, up):
    return np.degrees(np.arccos(np.clip(np.sum(np.asarray(out.up_S) * up, axis=1), -1.0, 1.0)))


@pytest.fixture(scope="module")
def clipped_roll():
    """A 12 rad/s roll pulse (about a horizontal axis) read by a ±7 rad/s gyro: the clipped
    recording, the truth, and the filter's outputs with clipping detected (inferred; and given)
    and with detection off (today's filter)."""
    gyr, acc, up = fast_roll(n=2000, peak=12.0, centers_s=(5.0,), seed=1)
    assert np.max(np.abs(gyr)) > 10.0
    clipped = np.clip(gyr, -CLIP_RAD_S, CLIP_RAD_S)
    outs = {"inferred": tilt.estimate(clipped, acc, period_s=0.01),
            "given": tilt.estimate(clipped, acc, period_s=0.01, gyr_range_rad_s=CLIP_RAD_S),
            "off": tilt.estimate(clipped, acc, period_s=0.01, detect_clipping=False),
            "unclipped": tilt.estimate(gyr, acc, period_s=0.01)}
    return clipped, acc, up, outs


def test_clipped_rotation_error_is_at_most_half_of_the_undetected(clipped_roll):
    """While the gyro is clipped and in the 2 s after, the mean tilt error with the clipping
    detected is at most half of the filter's without detection (measured 10.5° against 35.6°;
    unclipped 0.3°), and the widened σ covers ≥ 95 % of the unflagged-or-clipped samples within
    2σ (without detection the filter claims 1° while 37° off)."""
    gyr, _, up, outs = clipped_roll
    at = np.any(np.abs(gyr) >= CLIP_RAD_S, axis=1)
    k0, k1 = np.flatnonzero(at)[[0, -1]]
    window = slice(k0, k1 + 201)
    assert k1 - k0 + 1 == np.count_nonzero(at) > 10  # one clipped run
    err = {k: _err_deg(o, up) for k, o in outs.items()}
    assert np.mean(err["inferred"][window]) <= 0.5 * np.mean(err["off"][window])
    assert np.mean(err["unclipped"][window]) < 1.0
    for name in ("inferred", "off"):
        out = outs[name]
        scored = (out.flags & ~CLIPPED) == 0
        within = np.mean(err[name][scored] <= 2 * out.sigma_rad[scored] * 180 / np.pi)
        assert (within >= 0.95) == (name == "inferred"), (name, within)


def test_clipped_samples_are_flagged_and_the_inferred_range_is_the_given_one(clipped_roll):
    gyr, _, _, outs = clipped_roll
    at = np.any(np.abs(gyr) >= CLIP_RAD_S, axis=1)
    assert np.array_equal((outs["inferred"].flags & CLIPPED) > 0, at)
    assert not np.any(outs["off"].flags & CLIPPED)
    for field in tilt.TiltEstimate._fields:
        np.testing.assert_array_equal(getattr(outs["inferred"], field),
                                      getattr(outs["given"], field), err_msg=field)
    # outside the clipped run (before it) nothing changes
    k0 = np.flatnonzero(at)[0]
    np.testing.assert_array_equal(outs["inferred"].up_S[:k0 - 32], outs["off"].up_S[:k0 - 32])


def test_smoother_uses_the_same_limits(clipped_roll):
    gyr, acc, up, outs = clipped_roll
    sm = tilt.smooth(gyr, acc, period_s=0.01)
    off = tilt.smooth(gyr, acc, period_s=0.01, detect_clipping=False)
    np.testing.assert_array_equal(sm.flags, outs["inferred"].flags)
    assert np.mean(_err_deg(sm, up)) < 0.5 * np.mean(_err_deg(off, up))


def test_clip_variance_is_an_unknown_constant_excess_over_each_run():
    """The tilt variance added over a clipped run of duration t is (σ t)² (σ the excess's standard
    deviation), whatever the steps, and restarts with each run."""
    clipped = np.zeros((10, 3), dtype=bool)
    clipped[2:6, 0] = True  # a run of 4 steps
    clipped[8:10, 0] = True
    clipped[3:5, 2] = True
    dts = np.array([0.01, 0.02, 0.01, 0.03, 0.01, 0.02, 0.01, 0.01, 0.02, 0.01])
    sigma = np.full((10, 3), 2.0)
    var = tilt_limits.clip_variance(clipped, sigma, dts)
    run0 = dts[2:6].sum()
    np.testing.assert_allclose(var[:6].sum() - 4.0 * dts[3:5].sum() ** 2, 4.0 * run0**2)
    np.testing.assert_allclose(var[8:].sum(), 4.0 * dts[8:].sum() ** 2)
    assert np.all(var[[0, 1, 6, 7]] == 0)


def test_a_clipped_accelerometer_sample_is_kept_and_flagged():
    """A shake beyond a ±2 g accelerometer: the clipped samples are flagged CLIPPED, given the
    range or inferred, and still used (their other axes are right), each with its peak's fitted
    excess added (``peak_excess``); what is left of the excess widens the velocity variance
    (``vel_var_m2_s2``, the σ of each run)."""
    rng = np.random.default_rng(2)
    n = 1200
    acc = np.zeros((n, 3)) + [0.0, 0.0, G] + rng.normal(0, 0.03, (n, 3))
    acc[500:700, 0] += 30.0 * np.sin(np.arange(200) * 2 * np.pi * 3 * 0.01)
    acc = np.clip(acc, -2 * G, 2 * G)
    gyr = rng.normal(0, 1e-3, (n, 3))
    at = np.any(np.abs(acc) >= 2 * G, axis=1)
    assert at.sum() > 20
    lim = tilt_limits.find_limits(gyr, acc, 0.01, acc_range_m_s2=2 * G)
    clipped = np.abs(acc) >= 2 * G
    excess, sigma = tilt_limits.peak_excess(acc, clipped, np.full(n, 0.01),
                                            np.where(clipped, 2 * G, 0.0))
    np.testing.assert_array_equal(lim.acc_excess_m_s2, excess)
    assert np.all(np.sign(excess[clipped]) == np.sign(acc[clipped]))  # beyond, on the clip's side
    assert not np.any(excess[~clipped])
    np.testing.assert_allclose(lim.vel_var_m2_s2, tilt_limits.clip_variance(
        clipped, sigma, np.full(n, 0.01)), rtol=1e-12)
    assert np.all(lim.vel_var_m2_s2[at] > 0) and not np.any(lim.vel_var_m2_s2[~at])
    # the 3 Hz sinusoid of 30 m/s² clipped at 2 g (49° either side of each peak): its true
    # excess over the runs is found within 15 % (measured 98 %; 88 % by the parabola through the
    # flanks alone: a sinusoid's peak is fuller, PEAK_CHORD_SHARE)
    truth = 30.0 * np.sin(np.arange(200) * 2 * np.pi * 3 * 0.01)
    peaks = clipped[500:700, 0]
    true = np.sum(np.abs(truth[peaks]) - 2 * G)
    assert abs(np.sum(np.abs(excess[500:700, 0])) / true - 1.0) < 0.15
    for kw in ({}, {"acc_range_m_s2": 2 * G}):
        out = tilt.estimate(gyr, acc, period_s=0.01, **kw)
        assert np.array_equal((out.flags & CLIPPED) > 0, at)
        assert not np.any(out.flags & ACC_MISSING) and np.all(out.measured)


def test_keeping_clipped_accelerometer_samples_beats_dropping_them():
    """A synthetic fast translation read by a ±4 g accelerometer (4 % of its samples clipped, more
    on one side: ``realistic_recordings``): dropping the clipped samples leaves the velocity
    without the clipped side's impulse and the tilt follows (2.16° RMS when measured); keeping
    them with the excess's velocity variance stays near the filter without detection (0.60° and
    0.57°)."""
    from verticality.tilt.evaluation import realistic as rr

    rec = rr.recording("fast_translation", 2)
    lim = tilt_limits.find_limits(rec.gyr_rad_s, rec.acc_m_s2, rec.dt_s)
    assert 0.02 < np.mean(lim.acc_clipped) < 0.1
    dropped = np.where(lim.acc_clipped[:, None], np.nan, rec.acc_m_s2)

    def rmse(acc, **kw):
        return rr.inclination_rmse_deg(
            tilt.estimate(rec.gyr_rad_s, acc, period_s=rec.dt_s, **kw).quat_E_S, rec)

    kept, off = rmse(rec.acc_m_s2), rmse(rec.acc_m_s2, detect_clipping=False)
    assert kept < 0.4 * rmse(dropped) and kept < 1.2 * off


def test_clipping_is_never_inferred_on_clean_broad_data():
    """On the BROAD slices no axis has a flat top: nothing is clipped, no variance is added, and
    the estimates are those with clipping detection off; the rows that repeat the previous one bit
    for bit (BROAD has some) are flagged HELD, and only they. (The whole trials:
    benchmarks/broad_eval.py.)"""
    from verticality.io import broad

    held = 0
    for path in ALL:
        trial = broad.load_trial(path)
        lim = tilt_limits.find_limits(trial.gyr_rad_s, trial.acc_m_s2, trial.dt_s)
        assert not lim.gyr_clipped.any() and not lim.acc_clipped.any(), path.name
        assert np.all(lim.tilt_var_rad2 == 0)
        rows = tilt_limits.held_rows(trial.gyr_rad_s, trial.acc_m_s2)
        np.testing.assert_array_equal(lim.held, rows)
        out = tilt.estimate(trial.gyr_rad_s, trial.acc_m_s2, period_s=trial.dt_s)
        np.testing.assert_array_equal((out.flags & HELD) > 0, rows)
        off = tilt.estimate(trial.gyr_rad_s, trial.acc_m_s2, period_s=trial.dt_s,
                            detect_clipping=False)
        np.testing.assert_array_equal(out.quat_E_S, off.quat_E_S)
        assert not np.any(out.flags & CLIPPED)
        held += int(rows.sum())
    assert held > 0  # the case is exercised


def test_no_clip_level_below_the_smallest_ranges_or_without_a_flat_top():
    rng = np.random.default_rng(0)
    x = rng.normal(0, 1.0, (500, 3))
    x[:, 1] = 0.0  # a dead axis: constant, but no range is that small
    x[:, 2] *= 0.2
    x[100:110, 2] = 1.5  # a flat top, but at 1.5 rad/s
    held = np.zeros(500, dtype=bool)
    lo, hi = tilt_limits.inferred_levels(x, held, tilt_limits.GYR_FLOOR_RAD_S)
    assert np.all(np.isinf(lo)) and np.all(np.isinf(hi))
    x[200:204, 0] = 5.0  # a flat top of MIN_RUN samples at 5 rad/s
    lo, hi = tilt_limits.inferred_levels(x, held, tilt_limits.GYR_FLOOR_RAD_S)
    assert hi[0] == 5.0 and np.isinf(lo[0])
    held[201] = True  # a held row does not count towards the run
    x[201] = x[200]
    lo, hi = tilt_limits.inferred_levels(x, held, tilt_limits.GYR_FLOOR_RAD_S)
    assert np.isinf(hi[0])


@pytest.mark.parametrize("bad", [0.0, -1.0, np.nan, [1.0, 2.0], "x"])
def test_a_bad_range_is_refused(bad):
    with pytest.raises(InputError, match="range"):
        tilt.estimate(np.zeros((10, 3)), np.tile([0, 0, G], (10, 1)), period_s=0.01,
                      gyr_range_rad_s=bad)


def test_held_rows_are_flagged_bit_for_bit():
    g = np.array([[0.1, 0.2, 0.3], [0.1, 0.2, 0.3], [0.1, 0.2, 0.3], [-0.0, 0.2, 0.3],
                  [0.0, 0.2, 0.3]])
    a = np.tile([0.0, 0.0, G], (5, 1))
    assert tilt_limits.held_rows(g, a).tolist() == [False, True, True, False, False]
    out = tilt.estimate(g, a, period_s=0.01)
    assert ((out.flags & HELD) > 0).tolist() == [False, True, True, False, False]


def test_a_logger_faster_than_its_sensor_costs_nothing():
    """A 100 Hz sensor logged at 400 Hz (each reading held for four rows): the rows are flagged
    HELD, the output keeps one row per input row, the tilt error is that of the 100 Hz recording
    within a small factor (measured 0.207° against 0.224° RMS) and σ stays honest (all samples
    within 2σ in both)."""
    from verticality.tilt.evaluation.faults import fault_recording

    n = 24000
    gyr, acc, _, up = fault_recording("clean", n=n, dt=0.0025, seed=0)
    k = np.arange(0, n, 4)  # the sensor's samples
    hold = np.arange(n) // 4 * 4  # the row the logger repeats
    outs = {"100": tilt.estimate(gyr[k], acc[k], period_s=0.01),
            "400 held": tilt.estimate(gyr[hold], acc[hold], period_s=0.0025)}
    truth = {"100": up[k], "400 held": up}
    rms = {}
    for name, out in outs.items():
        err = _err_deg(out, truth[name])
        scored = (out.flags & ~HELD) == 0
        assert scored.mean() > 0.95
        sigma = np.degrees(out.sigma_rad)
        assert np.mean(err[scored] <= 2 * sigma[scored]) >= 0.95, name
        rms[name] = np.sqrt(np.mean(err[scored] ** 2))
    held = outs["400 held"].flags & HELD > 0
    assert held.shape == (n,) and np.array_equal(held, np.arange(n) % 4 != 0)
    assert 0.67 < rms["400 held"] / rms["100"] < 1.5, rms


def test_estimate_command_finds_the_limits_of_a_csv_read_in_pieces(tmp_path):
    """``verticality estimate`` on a CSV read in pieces: the clipped rows (range given in °/s, or
    inferred) and the held rows (one straddling a piece boundary) are flagged as ``tilt.estimate``
    flags them on the whole recording; a range is refused for a peer filter."""
    from verticality import cli
    from verticality.io import imu
    from verticality.tilt.files import check_ranges, estimate_file

    gyr, acc, _ = fast_roll(n=1500, peak=12.0, centers_s=(5.0,), seed=4)
    gyr = np.clip(gyr, -CLIP_RAD_S, CLIP_RAD_S)
    gyr[600:603], acc[600:603] = gyr[599], acc[599]  # held across the boundary at 601
    t = np.arange(1500) * 0.01
    path = imu.write_imu_csv(tmp_path / "roll.csv", imu.ImuRecording(t, gyr, acc))
    rec = imu.read_imu_csv(path)  # the values as the CSV holds them
    ref = tilt.estimate(rec.gyr_rad_s, rec.acc_m_s2, rec.t_s, gyr_range_rad_s=CLIP_RAD_S)
    assert np.flatnonzero(ref.flags & HELD).tolist() == [600, 601, 602]
    assert np.count_nonzero(ref.flags & CLIPPED) > 10
    for ranges in ({"gyr_range_rad_s": CLIP_RAD_S}, {}):
        run = estimate_file(path, tmp_path / "out.csv", piece_rows=601, keep=True, ranges=ranges)
        np.testing.assert_array_equal(run.out.flags, ref.flags)
        # (the σ left over a fitted peak counts the noise read from the piece: 3e-8 apart)
        np.testing.assert_allclose(run.out.up_S, ref.up_S, rtol=0, atol=1e-6)
    out = tmp_path / "cli.csv"
    assert cli.main(["estimate", str(path), "--out", str(out),
                     "--gyr-range", str(np.degrees(CLIP_RAD_S))]) == 0
    np.testing.assert_array_equal(imu.read_estimate_csv(out).flags, ref.flags)
    with pytest.raises(InputError, match="does not take a sensor range"):
        check_ranges("vqf", {"gyr_range_rad_s": 1.0})


def _candidates_by_listed_pools(x, i, sign, band, tol, rng):
    """``_raw_axis_candidates`` as first written: each trial's pool listed and drawn with
    ``rng.choice``, the cross product and its test one trial at a time."""
    k = np.flatnonzero(band[:-1] & band[1:])
    steps = x[k + 1] - x[k]
    size = np.linalg.norm(steps, axis=1)
    other = np.sqrt(np.maximum(size**2 - steps[:, i] ** 2, 0.0))
    flat = (size > 0) & (np.abs(steps[:, i]) <= np.tan(tilt_limits.PLANE_TILT_RAD) * other + tol)
    k, steps = k[flat], steps[flat]
    run = np.cumsum(np.concatenate([[0], np.diff(k) > 1]))
    found, trials = [], tilt_limits.PLANE_TRIALS
    while trials > 0:
        j1 = rng.integers(k.size)
        same = run == run[j1]
        far = np.abs(k - k[j1]) >= tilt_limits.MIN_RUN
        pool = np.flatnonzero(~same if trials % 2 else same & far)
        trials -= 1
        if pool.size == 0:
            continue
        a = np.cross(steps[j1], steps[rng.choice(pool)])
        norm = np.linalg.norm(a)
        if norm == 0:
            continue
        a = a / norm * np.sign(a[i])
        if a[i] < np.cos(tilt_limits.PLANE_TILT_RAD):
            continue
        inl = np.abs(steps @ a) <= tol
        if np.count_nonzero(inl) >= 3:
            a = np.linalg.svd(steps[inl], full_matrices=False)[2][-1]
            a = a * np.sign(a[i])
            inl = np.abs(steps @ a) <= tol
        found.append((int(np.count_nonzero(inl)), a))
    found.sort(key=lambda f: -f[0])
    out = []
    for _, a in found:
        if all(np.linalg.norm(a - b) > 1e-9 for b in out):
            out.append(a)
        if len(out) == tilt_limits.PLANE_KEEP:
            break
    return out


def test_plateau_step_pairs_are_drawn_as_from_the_listed_pools():
    """The search for a raw axis's plateau draws its pairs of steps without listing each trial's
    pool (the faster form): on plateaus seen through a tilted axis, in one band run and in
    several, it finds the very directions, bit for bit, of the listed pools drawn with
    ``rng.choice``."""
    rng = np.random.default_rng(5)
    for seed in range(6):
        x = rng.normal(0, 0.05, (1500, 3)).cumsum(axis=0)
        a = np.array([1.0, 0.03 * (seed - 2), -0.02 * seed])
        a /= np.linalg.norm(a)
        p = x @ a
        top = np.quantile(p, 0.9 if seed % 2 else 0.97)
        over = p > top
        x[over] -= np.outer(p[over] - top, a)  # flat along a above the level
        band = x[:, 0] >= x[:, 0].max() - 0.5 * abs(x[:, 0].max())
        got = tilt_limits._raw_axis_candidates(x, 0, 1.0, band, 1e-3, np.random.default_rng(seed))
        want = _candidates_by_listed_pools(x, 0, 1.0, band, 1e-3, np.random.default_rng(seed))
        assert len(got) == len(want) > 0
        for u, v in zip(got, want, strict=True):
            np.testing.assert_array_equal(u, v)
