"""F §4.5.2 under the Fig. 4.12 caption's reading (experiments/ambiguity_upright.py): the walking's
parts, the continuous closed loop, and the loops' stability in continuous time and sampled."""

from __future__ import annotations

import math

import numpy as np

from verticality.analysis import ambiguity_outcome
from verticality.analysis.ambiguity_loop_stability import loop_eigenvalues
from verticality.models.params import G_M_S2
from verticality.simulation import ambiguity_upright_loop as upright_loop
from verticality.simulation import trajectories as tr


def test_walking_without_harmonics_is_the_step_frequency_a_quarter_step_apart():
    n = 10000  # 1 s
    a_h, a_z = upright_loop.walking_half_steps(n)
    assert a_h.shape == (2, 2 * n + 1) and a_z.shape[0] == 2 and a_z.shape[1] > 2 * n + 1
    fund_h, fund_z = a_h[0], a_z[0, : 2 * n + 1]
    w = 2.0 * math.pi * upright_loop.STEP_HZ
    t = 2.0 + np.arange(2 * n + 1) * upright_loop.DT_S / 2.0
    # a_h = −a_x = w²·1 cm·sin(wt); the bounce a_z = w²·2 cm·cos(wt): ≈ 0.16 g and 0.32 g peaks
    np.testing.assert_allclose(fund_h, w**2 * 0.01 * np.sin(w * t), atol=1e-9)
    np.testing.assert_allclose(fund_z, w**2 * 0.02 * np.cos(w * t), atol=1e-9)
    assert (0.15 < np.abs(fund_h).max() / G_M_S2 < 0.17
            and 0.31 < np.abs(fund_z).max() / G_M_S2 < 0.33)
    # the two parts add up to the built-in walking
    full = tr.sample(tr.walking(duration_s=4.0), t).a_I_m_s2
    np.testing.assert_allclose(a_h[0] + a_h[1], -np.asarray(full)[:, 0], atol=1e-9)
    np.testing.assert_allclose((a_z[0] + a_z[1])[: 2 * n + 1], np.asarray(full)[:, 2], atol=1e-9)


def test_the_bounce_lag_shifts_the_vertical_part_by_that_phase():
    assert upright_loop._vertical_shift_samples(upright_loop.NOMINAL_LAG_DEG) == 0
    n = 10000
    a_h, a_z = upright_loop.walking_half_steps(n)
    # in phase with the forward acceleration a_x = −a_h
    shift = upright_loop._vertical_shift_samples(0.0)
    z = a_z[0, shift: shift + 2 * n + 1]
    corr = np.corrcoef(z, -a_h[0])[0, 1]
    assert corr > 0.999
    z_180 = a_z[0, upright_loop._vertical_shift_samples(180.0):][: 2 * n + 1]
    assert np.corrcoef(z_180, -a_h[0])[0, 1] < -0.999


def test_f317_with_the_estimated_tilt_is_unstable_in_continuous_time_and_stable_sampled_at_10_khz():
    lam = loop_eigenvalues("luenberger", 10.0)
    osc = lam[np.abs(lam.imag) > 1.0]
    assert osc[0].real > 10.0 and 30.0 < abs(osc[0].imag) / (2 * math.pi) < 45.0
    sampled = loop_eigenvalues("luenberger", 10.0, 1e-4)
    assert sampled[0].real < 1e-6  # the 10 kHz step's delay stabilizes the pair: an artefact
    finer = loop_eigenvalues("luenberger", 10.0, 1e-5)
    assert finer[0].real > 10.0  # at 100 kHz the continuous pair is back


def test_the_upright_loop_is_marginal_in_continuous_time_and_drifts_sampled():
    """F 3.14 reads a still tilt as acceleration: one eigenvalue at 0 (the head stays where it is
    when only rotating); the 10 kHz sampled loop turns it into a drift."""
    lam = loop_eigenvalues("upright", upright_loop.PD_LOOP_RAD_S)
    assert abs(lam[0].real) < 1e-5 and np.all(lam[1:].real < 0.0)
    assert loop_eigenvalues("upright", upright_loop.PD_LOOP_RAD_S, 1e-4)[0].real > 0.1


def test_the_continuous_loop_keeps_a_still_upright_head_and_the_known_feed_converges():
    still = upright_loop.runs("upright", [0.0], 0.0, upright_loop.PD_LOOP_RAD_S, 0.0, 90.0, 0.0,
                              0.5)
    assert np.all(still.theta_H == 0.0) and np.all(still.theta_hat == 0.0)
    known = upright_loop.runs("known", [10.0], 0.0, 10.0, 1.0, 90.0, 0.0, 2.0)
    assert abs(np.degrees(known.theta_H[0, -1])) < 3.0 and np.degrees(known.theta_H[0, 0]) == 10.0


def test_the_upright_reading_recovers_from_a_small_tilt_and_not_from_a_large_one():
    s = upright_loop.runs("upright", [8.0, 25.0], 0.0, upright_loop.PD_LOOP_RAD_S, 1.0, 90.0, 0.0,
                          3.0)
    end = np.degrees(np.abs(s.theta_H[:, -1]))
    assert end[0] < 8.0  # brought towards upright
    # driven away: the head tumbles, so where it happens to be at the end depends on rounding;
    # that it leaves its starting tilt does not
    large = np.degrees(np.abs(s.theta_H[1]))
    assert not np.all(np.isfinite(large)) or np.max(large) > 25.0
    rows = ambiguity_outcome.summarize_upright(s, [0.0, 0.0])
    assert not rows[1]["converged"]
