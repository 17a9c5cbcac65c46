"""Irregular clocks: jittered stamps and repeated stamps (Δt = 0 rows) are filtered with the true
Δt, a row whose stamp is unusable is flagged, and the output keeps one row per input row, in the
library and through ``verticality estimate``."""

import numpy as np
import pytest

from verticality import cli, tilt
from verticality.io import imu
from verticality.tilt import estimator
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
