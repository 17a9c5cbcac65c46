"""Linearization by autodiff (F 4.10) against finite differences and analytic entries."""

import jax.numpy as jnp
import numpy as np
import pytest
import scipy.signal

from verticality.errors import InputError
from verticality.experiments.separation import f_model, h_model, linear_model
from verticality.models import planar
from verticality.models.linearize import (
    LinearModel,
    discretize_zoh,
    from_statespace,
    linearize,
    to_statespace,
)
from verticality.models.platform import f44_params


def _fd_jac(fun, z0, eps=1e-6):
    z0 = np.asarray(z0, float)
    cols = []
    for i in range(z0.size):
        dz = np.zeros_like(z0)
        dz[i] = eps
        cols.append((np.asarray(fun(z0 + dz)) - np.asarray(fun(z0 - dz))) / (2 * eps))
    return np.stack(cols, axis=-1)


def test_matches_finite_differences_away_from_upright():
    p = f44_params()
    x0 = jnp.array([0.3, -2.0, 0.7, 1.5])
    u0 = jnp.array([0.2, 1.3])
    m = linearize(f_model, h_model, x0, u0, p)
    A_fd = _fd_jac(lambda x: f_model(jnp.asarray(x), u0, p), x0)
    B_fd = _fd_jac(lambda u: f_model(x0, jnp.asarray(u), p), u0)
    C_fd = _fd_jac(lambda x: h_model(jnp.asarray(x), u0, p), x0)
    np.testing.assert_allclose(m.A, A_fd, rtol=1e-6, atol=1e-4)
    np.testing.assert_allclose(m.B, B_fd, rtol=1e-6, atol=1e-4)
    np.testing.assert_allclose(m.C, C_fd, atol=1e-8)
    assert np.all(np.asarray(m.D) == 0.0)
    # and it is not trivially the upright matrix: the cos(θ_S) factor changed entries.
    assert not np.allclose(m.A, linear_model().A)


def test_upright_entries_are_the_thesis_ratios():
    m = linear_model()
    A, B = np.asarray(m.A), np.asarray(m.B)
    assert A[1, 0] == pytest.approx(-3943.8)
    assert A[1, 1] == pytest.approx(-125.6)
    assert A[1, 3] == pytest.approx(125.6)
    assert B[3, 0] == pytest.approx(1.0 / 1e-4)
    assert B[1, 1] == pytest.approx(-3943.8 / 9.81)  # −1/l
    np.testing.assert_allclose(np.asarray(m.C), [[1.0, 0.0, -1.0, 0.0]])


def test_pytree_states_and_statespace_roundtrip():
    p = planar.PlanarParams()
    x0 = planar.PlanarState(*(jnp.asarray(0.0) for _ in range(4)))
    u0 = planar.PlanarInput(jnp.asarray(0.0), jnp.asarray(0.0), jnp.asarray(0.0))
    m = linearize(lambda x, u, p: planar.dynamics(x, u, p),
                  lambda x, u, p: planar.inclinometer_reading(x), x0, u0, p)
    assert m.A.shape == (4, 4) and m.B.shape == (4, 3) and m.C.shape == (1, 4)
    assert float(m.A[1, 0]) == pytest.approx(-p.m_kg * p.l_m * p.g_m_s2 / p.J_kg_m2)
    sys = to_statespace(m)
    back = from_statespace(sys)
    for a, b in zip(m, back, strict=True):
        np.testing.assert_allclose(a, b)


def test_zoh_matches_scipy():
    m = linear_model()
    Ad, Bd = discretize_zoh(m, 1e-3)
    ref = scipy.signal.cont2discrete(tuple(np.asarray(v) for v in m), 1e-3, method="zoh")
    np.testing.assert_allclose(Ad, ref[0], rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(Bd, ref[1], rtol=1e-9, atol=1e-12)


def test_bad_model_is_an_input_error():
    with pytest.raises(InputError):
        linearize(lambda x, u, p: x[:1], lambda x, u, p: x[0], jnp.zeros(3), jnp.zeros(1))
    assert isinstance(linear_model(), LinearModel)
