"""PRTS stimulus (trajectories.py) and transfer-function / coherence estimates
(analysis/frequency.py)."""

import numpy as np
import pytest
import scipy.signal

from verticality.analysis import frequency
from verticality.core.errors import InputError
from verticality.simulation import trajectories as tr


def test_prts_is_a_balanced_antisymmetric_m_sequence():
    s = tr.prts_sequence()
    assert s.size == 242
    v = tr.prts_velocity_levels()
    assert (v == 1).sum() == 81 and (v == -1).sum() == 81 and (v == 0).sum() == 80
    np.testing.assert_array_equal(v[121:], -v[:121])
    # maximal period: no shorter shift reproduces the sequence
    assert all(not np.array_equal(np.roll(s, k), s) for k in range(1, 242))
    # velocity spectrum: power on odd harmonics only
    V = np.abs(np.fft.rfft(v))
    assert V[2::2].max() < 1e-9 * V[1::2].max()
    f = frequency.prts_frequencies()
    np.testing.assert_allclose(f[:3], np.array([1, 3, 5]) / 60.5)
    assert f[-1] <= 2.0


def test_prts_stimulus_has_the_requested_peak_and_period():
    t, pos, vel = tr.prts_stimulus(np.radians(5.0), 100.0, 2)
    per = 6050
    assert t.size == 2 * per and abs(t[per] - 60.5) < 1e-12
    np.testing.assert_allclose(pos[:per], pos[per:], atol=1e-12)
    np.testing.assert_allclose(np.abs(pos).max(), np.radians(5.0), rtol=1e-12)
    np.testing.assert_allclose(pos.max(), -pos.min(), rtol=1e-12)  # centred on the middle
    np.testing.assert_allclose(np.diff(pos[:per]) * 100.0, vel[: per - 1], atol=1e-12)
    # the velocity is held at ±v or 0 for 0.25 s: three levels, 25 samples each
    assert np.unique(np.round(vel / vel.max(), 12)).tolist() == [-1.0, 0.0, 1.0]
    np.testing.assert_array_equal(vel[:per].reshape(242, 25), vel[:per:25, None].repeat(25, axis=1))
    # any rate samples the same lean (the integral of the held levels, exact between the knots)
    t3, pos3, _ = tr.prts_stimulus(np.radians(5.0), 30.0, 1)
    np.testing.assert_allclose(pos3, np.interp(t3, t, pos), atol=1e-12)
    with pytest.raises(InputError, match="positive"):
        tr.prts_stimulus(0.1, 0.0, 1)
    with pytest.raises(InputError, match="cycle"):
        tr.prts_stimulus(0.1, 10.0, 0)


def test_white_noise_transfer_function_of_first_order_system():
    fs = 50.0
    rng = np.random.default_rng(1)
    x = rng.normal(size=200_000)
    b, a = [0.1], [1.0, -0.9]  # y[k] = 0.9 y[k-1] + 0.1 x[k]: first order, DC gain 1
    y = scipy.signal.lfilter(b, a, x)
    f, H, coh = frequency.welch_transfer_function(x, y, fs, nperseg=1024)
    _, H_true = scipy.signal.freqz(b, a, worN=f, fs=fs)
    sel = (f > 0) & (f <= 10.0)
    np.testing.assert_allclose(np.abs(H[sel]), np.abs(H_true[sel]), rtol=0.03)
    np.testing.assert_allclose(np.angle(H[sel]), np.angle(H_true[sel]), atol=np.radians(2.0))
    assert coh[sel].min() > 0.98
    # Output noise lowers the coherence but leaves H unbiased.
    y_noisy = y + rng.normal(scale=0.2, size=y.size)
    _, Hn, cohn = frequency.welch_transfer_function(x, y_noisy, fs, nperseg=1024)
    low = (f > 0) & (f <= 3.0)
    np.testing.assert_allclose(np.abs(Hn[low]), np.abs(H_true[low]), rtol=0.1)
    assert cohn[sel].mean() < 0.9


def test_cycle_transfer_function_on_prts_is_exact_for_a_linear_system():
    fs = 20.0
    _, pos, _ = tr.prts_stimulus(0.1, fs, 4)
    b, a = [0.2], [1.0, -0.8]
    y = scipy.signal.lfilter(b, a, pos)
    per = int(60.5 * fs)
    f, H, coh = frequency.cycle_transfer_function(pos, y, per, fs, skip_cycles=1)
    _, H_true = scipy.signal.freqz(b, a, worN=f, fs=fs)
    np.testing.assert_allclose(H, H_true, rtol=1e-6)
    np.testing.assert_allclose(coh, 1.0, atol=1e-9)
    np.testing.assert_allclose(f[:3], np.array([1, 3, 5]) / 60.5)
    np.testing.assert_allclose(f, frequency.prts_frequencies(f_max_hz=f[-1] + 1e-9))
    # End matching leaves a periodic response alone and removes a slow drift added to it.
    t = np.arange(y.size) / fs
    _, H_em, _ = frequency.cycle_transfer_function(pos, y, per, fs, end_match=True)
    np.testing.assert_allclose(H_em, H_true[: H_em.size], rtol=1e-6)
    drifting = y + 0.02 * np.sin(2 * np.pi * t / 1000.0)
    _, H_raw, c_raw = frequency.cycle_transfer_function(pos, drifting, per, fs)
    _, H_fix, c_fix = frequency.cycle_transfer_function(pos, drifting, per, fs, end_match=True)
    err_raw = np.abs(H_raw[:10] / H_true[:10] - 1).max()
    err_fix = np.abs(H_fix[:10] / H_true[:10] - 1).max()
    assert err_fix < 0.02 < err_raw and c_fix[:10].min() > c_raw[:10].min()
    with pytest.raises(InputError, match="2 full cycles"):
        frequency.cycle_transfer_function(pos[: 2 * per], y[: 2 * per], per, fs, skip_cycles=1)
    bad = pos.copy()
    bad[5] = np.nan
    with pytest.raises(InputError, match="finite"):
        frequency.cycle_transfer_function(bad, y, per, fs)
