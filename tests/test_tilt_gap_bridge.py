"""The rotation across a gap in the recording bridged from the rates at both its ends
(``TiltParams.gap_rate_corr_s``, docs/tilt.md "Gaps."): a steady turn, an oscillation whose rate
differs at the two ends, the batch run against the plain-Python ``Stream`` on gaps that start a
chunk or a run, and the variance against the error across gaps."""

import math

import numpy as np
import pytest

from imu_cases import G
from imu_cases import up_S as _up_S
from verticality import tilt
from verticality.core import so3
from verticality.tilt import batch as tilt_batch
from verticality.tilt import core as tilt_core
from verticality.tilt import estimator
from verticality.tilt.params import BLOCK, DEFAULT_PARAMS
from verticality.tilt.stream import Stream as ReferenceStream

DT = 0.01
OLD = DEFAULT_PARAMS._replace(gap_rate_corr_s=0.0)  # the rate after the gap over the whole gap
TRAPEZOID = DEFAULT_PARAMS._replace(gap_rate_corr_s=math.inf)


def _rolling(roll_of_t, rate_of_t, t_end, gaps, seed=0):
    """A sensor rolling about its x axis (roll ``roll_of_t(t)``, rate ``rate_of_t(t)``) sampled
    at 100 Hz with the samples inside ``gaps`` ((start, length) s) removed, their stamps kept:
    ``(t, gyr, acc, up)``."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, t_end, DT)
    keep = np.ones(t.size, dtype=bool)
    for start, length in gaps:
        keep &= ~((t > start + 1e-9) & (t < start + length - 1e-9))
    t = t[keep]
    up = _up_S(np.asarray(so3.exp(np.outer(roll_of_t(t), [1.0, 0.0, 0.0]))))
    acc = G * up + rng.normal(0, 0.02, (t.size, 3))
    gyr = np.outer(rate_of_t(t), [1.0, 0.0, 0.0]) + rng.normal(0, 1e-3, (t.size, 3))
    return t, gyr, acc, up


def _run(params, t, gyr, acc):
    filt = estimator.TiltFilter(params, BLOCK)
    return filt.run(filt.init(), gyr, acc, np.diff(t, prepend=t[0] - DT))[1]


def _err_deg(up, out):
    return np.degrees(np.arccos(np.clip(np.sum(up * out.up_S, axis=1), -1.0, 1.0)))


def test_bridge_share_limits():
    """The share of a gap the end rates carry, 2τ tanh(T/2τ)/T: 1 for T ≪ τ and τ = inf (the
    trapezoid), 2τ/T for T ≫ τ; in NumPy as in JAX."""
    T = np.array([1e-6, 0.05, 0.5, 1.0, 20.0])
    for xp in (np, tilt_core.jnp):
        s = np.asarray(tilt_core.bridge_share(xp.asarray(T), 0.25, xp))
        np.testing.assert_allclose(s, 0.5 / T * np.tanh(T / 0.5), rtol=1e-12)
        assert s[0] == pytest.approx(1.0) and s[-1] == pytest.approx(0.5 / 20.0)
        np.testing.assert_array_equal(np.asarray(tilt_core.bridge_share(xp.asarray(T), math.inf,
                                                                        xp)), 1.0)


def test_a_steady_turn_is_carried_across_a_gap_by_the_trapezoid():
    """A steady roll at 0.4 rad/s across a 0.6 s gap: the trapezoid (τ = inf) and the old rule
    (the same rate) carry it whole; the bridge at τ = 0.25 s carries 2τ tanh(T/2τ) of it and is
    off by the rest, as the rule says, until the tilt is re-acquired."""
    rate, t0, T = 0.4, 4.0, 0.6
    t, gyr, acc, up = _rolling(lambda t: rate * t, lambda t: np.full(t.size, rate), 8.0,
                               [(t0, T)])
    k = int(np.searchsorted(t, t0 + T - 1e-6))  # the sample after the gap
    after = slice(k, k + 50)  # 0.5 s after the gap, before the re-acquisition
    for params in (TRAPEZOID, OLD):
        assert np.max(_err_deg(up, _run(params, t, gyr, acc))[after]) < 0.5
    lost = np.degrees(rate * (T - 2 * 0.25 * math.tanh(T / 0.5)))  # 3.1°
    err = _err_deg(up, _run(DEFAULT_PARAMS, t, gyr, acc))[after]
    assert np.all(np.abs(err - lost) < 0.5)


def _oscillation():
    """A roll oscillating at 1 Hz (rate 1 rad/s cos 2π t) with a 0.5 s gap from a peak of the rate
    (ω0 = 1 rad/s) to a trough (ω1 = −1 rad/s): the roll is the same on both sides."""
    w = 2 * math.pi
    return _rolling(lambda t: np.sin(w * t) / w, lambda t: np.cos(w * t), 8.0, [(4.0, 0.5)])


def test_an_oscillation_across_a_gap_is_bridged_from_both_ends():
    """Across the oscillation's gap the rate after it over the whole gap turns the estimate by
    −0.5 rad (29°); the bridge's (ω0 + ω1) τ tanh(T/2τ) is 0, the truth."""
    t, gyr, acc, up = _oscillation()
    k = int(np.searchsorted(t, 4.5 - 1e-6))
    assert t[k] - t[k - 1] == pytest.approx(0.5) and gyr[k - 1, 0] == pytest.approx(1, abs=0.01)
    after = slice(k, k + 50)
    old = _err_deg(up, _run(OLD, t, gyr, acc))[after]
    new = _err_deg(up, _run(DEFAULT_PARAMS, t, gyr, acc))[after]
    assert np.min(old) > 25.0 and np.max(new) < 1.0


def test_tilt_stream_equals_estimate_across_a_bridged_gap():
    """``tilt.Stream`` at the oscillation's time stamps equals ``tilt.estimate`` to 1e-9 (the
    stamps read by the same clock, the gap bridged by the same rule)."""
    t, gyr, acc, _ = _oscillation()
    est = tilt.estimate(gyr, acc, t)
    assert np.count_nonzero(est.flags & tilt.DT_GAP) == 1
    s = tilt.Stream(DT)
    quat = np.array([s.step(g, a, tk).quat_E_S for g, a, tk in zip(gyr, acc, t, strict=True)])
    np.testing.assert_allclose(quat, est.quat_E_S, rtol=0, atol=1e-9)


def test_stream_equals_the_batch_run_across_bridged_gaps():
    """The plain-Python filter (``tilt.Stream``'s) equals the batch run to 1e-9 across bridged
    gaps: in the middle of a chunk, at the first sample of a chunk (the rate before it in the
    chunk's header), at the first sample of a run that goes on from a block begun before it (the
    rate in the row before the chunk's first sample), and after a sample whose gyro is missing (no
    rate before: the old rule)."""
    w = 2 * math.pi * 0.7
    short = tilt_batch.chunk_blocks(BLOCK, True) * BLOCK  # 1024 samples

    def recording(second_s):
        t, gyr, acc, _ = _rolling(lambda t: 0.3 * np.sin(w * t),
                                  lambda t: 0.3 * w * np.cos(w * t), 19.0,
                                  [(3.0, 0.4), (second_s, 0.3), (14.0, 0.8), (16.0, 0.25)])
        dts = np.diff(t, prepend=t[0] - DT)
        return t, gyr, acc, dts, np.flatnonzero(dts > 0.1)

    # the second gap at the first sample of the second chunk (the first holds the initializing
    # sample's re-acquisition: short)
    gaps = recording(11.0)[4]
    t, gyr, acc, dts, gaps = recording(11.0 + (1 + short - gaps[1]) * DT)
    gyr[gaps[2] - 1] = np.nan  # the third gap has no rate before it
    assert gaps[1] == 1 + short and len(gaps) == 4
    s = ReferenceStream(DEFAULT_PARAMS, block=BLOCK)
    rows = [s.step(g, a, d) for g, a, d in zip(gyr, acc, dts, strict=True)]
    filt = estimator.TiltFilter(DEFAULT_PARAMS, BLOCK)
    whole = filt.run(filt.init(), gyr, acc, dts)[1]
    cut = gaps[3]  # a run that starts with a gap, mid-block
    state, first = filt.run(filt.init(), gyr[:cut], acc[:cut], dts[:cut])
    assert int(state.count) != 0
    second = filt.run(state, gyr[cut:], acc[cut:], dts[cut:])[1]
    for out in (whole, estimator.concatenate_outputs([first, second])):
        np.testing.assert_allclose(np.array([r[3] for r in rows]), out.quat_E_S, rtol=0,
                                   atol=1e-9)
        np.testing.assert_allclose(np.array([r[4] for r in rows]), out.bias_S_rad_s, rtol=0,
                                   atol=1e-9)
    # the bridge acted: the old rule gives other numbers after each gap with a rate before it
    old = _run(OLD, t, gyr, acc)
    for g in gaps[[0, 1, 3]]:
        assert np.max(np.abs(old.quat_E_S[g] - whole.quat_E_S[g])) > 1e-3
    # and the same before the first gap (to rounding: a chunk's large rotation, the old rule's
    # here, makes it use the exact exponential for all its samples, kernels.quat_exp_batched)
    np.testing.assert_allclose(old.quat_E_S[:gaps[0]], whole.quat_E_S[:gaps[0]], rtol=0,
                               atol=1e-12)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_variance_covers_the_error_across_gaps(seed):
    """On a random sum of sines (0.2–2 Hz, up to ±0.6 rad of roll) with three gaps of 0.2–1 s, the
    error from each gap to its re-acquisition stays within 2σ."""
    rng = np.random.default_rng(seed)
    a, f, ph = (rng.uniform(0.05, 0.2, 3), rng.uniform(0.2, 2.0, 3),
                rng.uniform(0, 2 * np.pi, 3))
    w = 2 * np.pi * f

    def roll(t):
        return np.sum(a * np.sin(np.outer(t, w) + ph), axis=1)

    def rate(t):
        return np.sum(a * w * np.cos(np.outer(t, w) + ph), axis=1)

    gaps = [(s, rng.uniform(0.2, 1.0)) for s in (3.0, 6.0, 9.0)]
    t, gyr, acc, up = _rolling(roll, rate, 12.0, gaps, seed=seed)
    out = _run(DEFAULT_PARAMS, t, gyr, acc)
    err = np.radians(_err_deg(up, out))
    sigma = tilt.tilt_sigma_rad(out.var, DEFAULT_PARAMS)
    k = int(np.flatnonzero(out.flags & tilt.DT_GAP)[0])
    assert np.all(err[k:] < 2 * sigma[k:])
