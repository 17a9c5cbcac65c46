"""Linear Kalman filter, Van Loan discretization, steady-state gains (estimators/kalman.py)."""

import jax.numpy as jnp
import numpy as np
import pytest

from verticality.core.errors import InputError
from verticality.estimators import otolith_canal
from verticality.estimators.kalman import (
    continuous_observer,
    continuous_steady_gain,
    discrete_steady_gain,
    kalman_filter,
    van_loan,
)

DT = 0.01


def test_van_loan_double_integrator_matches_closed_form():
    A = np.array([[0.0, 1.0], [0.0, 0.0]])
    B = np.array([[0.0], [1.0]])
    q, dt = 0.7, 0.3
    Phi, Gamma, Qd = van_loan(A, B, np.diag([0.0, q]), dt)
    np.testing.assert_allclose(Phi, [[1, dt], [0, 1]], atol=1e-13)
    np.testing.assert_allclose(Gamma[:, 0], [dt**2 / 2, dt], atol=1e-13)
    np.testing.assert_allclose(Qd, q * np.array([[dt**3 / 3, dt**2 / 2], [dt**2 / 2, dt]]),
                               rtol=1e-10)


def test_care_gain_satisfies_riccati_equation():
    F, H = otolith_canal.matrices()
    Q, R = otolith_canal.TAHBOUB_Q, otolith_canal.TAHBOUB_R
    L, P = continuous_steady_gain(F, H, Q, R)
    res = F @ P + P @ F.T + Q - P @ H.T @ np.linalg.solve(R, H @ P)
    assert np.max(np.abs(res)) < 1e-8 * np.max(np.abs(P))
    assert np.all(np.linalg.eigvals(F - L @ H).real < 0)


def test_discrete_gain_approaches_continuous_gain_as_sampling_gets_finer():
    F, H = otolith_canal.matrices()
    Q, R = otolith_canal.TAHBOUB_Q, otolith_canal.TAHBOUB_R
    L, _ = continuous_steady_gain(F, H, Q, R)
    errs = []
    for dt in (1e-2, 1e-3, 1e-4):
        Phi, _, Qd = van_loan(F, np.zeros((3, 1)), Q, dt)
        K, _, _ = discrete_steady_gain(np.asarray(Phi), H, np.asarray(Qd), R / dt)
        errs.append(np.max(np.abs(K / dt - L) / np.abs(L)))
    assert errs[2] < 0.01
    assert errs[0] > errs[1] > errs[2]
    assert errs[1] / errs[2] > 5.0  # first order in dt


def test_time_varying_filter_converges_to_dare_gain_and_stays_psd():
    F, H = otolith_canal.matrices()
    Q, R = otolith_canal.TAHBOUB_Q, otolith_canal.TAHBOUB_R
    kf = kalman_filter(F, None, H, None, Q, R)
    n = 20000
    ys = np.zeros((n, 2))
    _, out = kf.run(kf.init(jnp.zeros(3), jnp.eye(3)), None, ys, DT)
    Phi, _, Qd = van_loan(F, np.zeros((3, 1)), Q, DT)
    K_ss, _, P_post = discrete_steady_gain(np.asarray(Phi), H, np.asarray(Qd), R / DT)
    np.testing.assert_allclose(out.K[-1], K_ss, rtol=1e-5, atol=1e-12)
    np.testing.assert_allclose(out.P[-1], P_post, rtol=1e-5, atol=1e-14)
    P = np.asarray(out.P[::500])
    np.testing.assert_allclose(P, np.swapaxes(P, 1, 2), atol=1e-15)
    assert np.all(np.linalg.eigvalsh(P) > 0)


def test_nan_measurement_is_predict_only_and_flagged():
    F, H = otolith_canal.matrices()
    kf = kalman_filter(F, None, H, None, otolith_canal.TAHBOUB_Q, otolith_canal.TAHBOUB_R)
    s0 = kf.init(jnp.array([0.1, 0.2, 0.0]), jnp.eye(3) * 0.01)
    s1, out = kf.step(s0, 0.0, jnp.array([jnp.nan, jnp.nan]), DT)
    Phi, _, Qd = van_loan(F, np.zeros((3, 1)), otolith_canal.TAHBOUB_Q, DT)
    np.testing.assert_allclose(s1.x, Phi @ np.array([0.1, 0.2, 0.0]), atol=1e-14)
    np.testing.assert_allclose(s1.P, Phi @ (np.eye(3) * 0.01) @ Phi.T + Qd, atol=1e-14)
    assert not bool(out.measured.any())
    # One component missing: that gain column is zero, the other is used, all finite.
    s2, out2 = kf.step(s0, 0.0, jnp.array([0.5, jnp.nan]), DT)
    assert np.all(np.isfinite(s2.x)) and np.all(np.isfinite(s2.P))
    np.testing.assert_allclose(out2.K[:, 1], 0.0, atol=0)
    assert np.abs(out2.K[:, 0]).max() > 0
    assert bool(out2.measured[0]) and not bool(out2.measured[1])
    obs = continuous_observer(F, None, H, None, otolith_canal.steady_state_gain())
    o1, oo = obs.step(obs.init(jnp.array([0.1, 0.2, 0.0])), 0.0, jnp.array([jnp.nan, 1.0]), DT)
    assert np.all(np.isfinite(o1.x)) and not bool(oo.measured[0]) and bool(oo.measured[1])


def test_bad_inputs_raise_input_error():
    F, H = otolith_canal.matrices()
    with pytest.raises(InputError, match="positive definite"):
        kalman_filter(F, None, H, None, otolith_canal.TAHBOUB_Q, np.diag([1e-5, 0.0]))
    with pytest.raises(InputError, match="shape"):
        kalman_filter(F, None, H[:, :2], None, otolith_canal.TAHBOUB_Q, otolith_canal.TAHBOUB_R)
    with pytest.raises(InputError, match="NaN"):
        continuous_observer(F, None, H, None, np.full((3, 2), np.nan))
