"""Extended disturbance observer (T eq. 16–19, 23): pole placement and convergence."""

import control
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from verticality.core.errors import InputError
from verticality.estimators.disturbance import (
    extended_disturbance_observer,
    extended_system,
    observability_rank,
    place_gain,
)
from verticality.estimators.kalman import van_loan
from verticality.models.body import HUMAN_TWO_SEGMENT, upright
from verticality.models.linearize import LinearModel, linearize

POLES = (-6.0, -7.0, -8.0, -9.0, -10.0, -11.0, -12.0)


@pytest.fixture(scope="module")
def lin():
    return linearize(HUMAN_TWO_SEGMENT, *upright())


def test_extended_pair_is_observable_with_and_without_a_x(lin):
    A_e, _, C_e, _ = extended_system(lin)
    assert A_e.shape == (7, 7) and C_e.shape == (6, 7)
    assert observability_rank(A_e, C_e) == 7
    assert observability_rank(A_e, C_e[:5]) == 7
    # The hip alone sees θ1 and θ2 only through the legs' angle θ1 + θ2: rank deficient.
    assert observability_rank(A_e, C_e[[1, 3]]) < 7


@pytest.mark.parametrize("outputs", [None, (0, 1, 2, 3, 4)])
def test_observer_poles_are_where_they_were_placed(lin, outputs):
    obs = extended_disturbance_observer(lin, POLES, outputs)
    np.testing.assert_allclose(np.sort(obs.poles().real), np.sort(POLES), rtol=1e-6)
    np.testing.assert_allclose(obs.poles().imag, 0.0, atol=1e-6)
    if outputs is not None:
        np.testing.assert_array_equal(np.asarray(obs.L)[:, 5], 0.0)


def test_complex_poles_are_placed(lin):
    A_e, _, C_e, _ = extended_system(lin)
    poles = np.array([-3 + 2j, -3 - 2j, -5, -6, -7, -8, -9])
    L = place_gain(A_e, C_e, poles)
    got = np.sort_complex(np.linalg.eigvals(A_e - L @ C_e))
    np.testing.assert_allclose(got, np.sort_complex(poles), atol=1e-6)


def test_observer_on_true_linear_plant_converges_from_any_initial_error(lin):
    """Plant = the extended linear model itself (θ̈1 piecewise constant), u held per sample."""
    A_e, B_e, C_e, D = extended_system(lin)
    dt, n = 1e-3, 3000
    Phi, Gam, _ = van_loan(A_e, B_e, np.zeros((7, 7)), dt)
    rng = np.random.default_rng(0)
    K = jnp.asarray(control.lqr(np.asarray(lin.A), np.asarray(lin.B[:, :2]), np.eye(4) * 100,
                                np.eye(2) * 1e-3)[0])
    ws = jnp.asarray(rng.normal(0, 5.0, (n, 2)))
    x0 = jnp.asarray([0.02, -0.03, 0.1, -0.05, 0.04, 0.02, 0.1])

    def plant(x, w):  # the body is unstable: keep it bounded with a state feedback plus excitation
        u = w - K @ x[:4]
        y = jnp.asarray(C_e) @ x + jnp.asarray(D) @ u
        return Phi @ x + Gam @ u, (x, y, u)

    _, (xs, ys, us) = jax.lax.scan(plant, x0, ws)
    obs = extended_disturbance_observer(lin, POLES)
    errs0 = rng.normal(0, 1.0, (4, 7)) * np.array([0.1, 0.1, 1, 1, 0.1, 1, 10])
    finals = []
    for e0 in errs0:
        _, out = obs.run(obs.init(x0 + e0), us, ys, dt)
        err = np.asarray(out.x[:-1] - xs[1:])
        finals.append(np.abs(err[-1]).max() / np.abs(e0).max())
        assert np.all(np.isfinite(err))
    # exp(-6 · 3 s) ≈ 2e-8 of the initial error, plus the O(dt) hold error of a measurement
    # that varies within the sample (independent of the initial error).
    assert max(finals) < 1e-2
    # Linearity: two runs from different starts end on the same trajectory.
    _, a = obs.run(obs.init(x0 + errs0[0]), us, ys, dt)
    _, b = obs.run(obs.init(x0 + errs0[1]), us, ys, dt)
    assert np.abs(np.asarray(a.x[-1] - b.x[-1])).max() < 1e-6 * np.abs(errs0[:2]).max()


def test_extended_system_splits_known_inputs_from_the_disturbance(lin):
    A_e, B_e, C_e, D = extended_system(lin)
    B, N = np.asarray(lin.B[:, :2]), np.asarray(lin.B[:, 2:])
    np.testing.assert_array_equal(A_e[:4, 4:], N)
    np.testing.assert_array_equal(B_e[:4], B)
    np.testing.assert_array_equal(B_e[4:], 0.0)
    np.testing.assert_array_equal(C_e[:, 4:], np.asarray(lin.D[:, 2:]))
    np.testing.assert_array_equal(D, np.asarray(lin.D[:, :2]))
    with pytest.raises(InputError, match="F_d"):
        extended_system(LinearModel(lin.A, lin.B[:, :3], lin.C, lin.D[:, :3]))


def test_bad_poles_raise_input_error(lin):
    A_e, _, C_e, _ = extended_system(lin)
    with pytest.raises(InputError, match="7 observer poles"):
        place_gain(A_e, C_e, POLES[:5])
    with pytest.raises(InputError, match="negative real"):
        place_gain(A_e, C_e, (1.0,) + POLES[1:])
    with pytest.raises(InputError, match="not observable"):
        place_gain(A_e, C_e, POLES, outputs=(1, 3))
    with pytest.raises(InputError, match="indices"):
        place_gain(A_e, C_e, POLES, outputs=(0, 9))
