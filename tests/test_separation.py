"""`separation` (F §4.4): the separation principle on the linearized loop, and the instability
test."""

import numpy as np

from verticality.estimators import luenberger as lu
from verticality.experiments import separation as sep
from verticality.simulation.separation_loop import KD, KP, linear_model


def _pd_row():
    return np.array([[0.0, 0.0, KP, KD]])


def test_observer_based_loop_has_controller_and_observer_poles():
    m = linear_model()
    A, B, C = (np.asarray(v) for v in (m.A, m.B[:, :1], m.C))
    obs = lu.design(m, sep.LUENBERGER_POLES)
    np.testing.assert_allclose(np.sort(obs.poles().real), np.sort(sep.LUENBERGER_POLES), rtol=1e-6)
    L = np.asarray(obs.L)
    K = _pd_row()
    # [x; x̂]:  ẋ = A x − B K x̂,   dx̂ = L C x + (A − B K − L C) x̂
    big = np.block([[A, -B @ K], [L @ C, A - B @ K - L @ C]])
    eig = np.sort_complex(np.linalg.eigvals(big))
    expected = np.sort_complex(np.concatenate([np.linalg.eigvals(A - B @ K), sep.LUENBERGER_POLES]))
    np.testing.assert_allclose(eig, expected, rtol=1e-6, atol=1e-6)
    assert np.all(eig.real < 0)


def test_sensor_fed_linear_loop_is_unstable_state_fed_is_not():
    m = linear_model()
    A, B = np.asarray(m.A), np.asarray(m.B[:, :1])
    sensor = np.array([[-KP, -KD, KP, KD]])  # tilt = θ_H − θ_S, rate its derivative
    assert np.linalg.eigvals(A - B @ sensor).real.max() > 0.1
    assert np.linalg.eigvals(A - B @ _pd_row()).real.max() < 0


def test_model_error_is_ten_percent():
    a, b = linear_model(1.0), linear_model(1.1)
    assert (abs(float(b.A[1, 0] / a.A[1, 0]) - 1.1) < 1e-12
            and abs(float(b.B[3, 0] / a.B[3, 0]) - 1 / 1.1) < 1e-12)


def test_instability_criterion():
    t = np.arange(0, 10, 1e-3)
    assert sep.is_unstable(t, 0.01 * np.exp(0.5 * t) * np.sin(60 * t))
    assert sep.is_unstable(t, np.where(t > 3, np.nan, 0.0))
    assert not sep.is_unstable(t, 0.3 * np.exp(-t) + 0.01 * np.sin(10 * t))
    assert not sep.is_unstable(t, 0.2 * np.sin(10 * t))
