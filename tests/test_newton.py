"""Newton (Moraal–Grizzle) observer: exact recovery, autodiff Jacobian, least squares, flags."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from verticality.errors import InputError
from verticality.estimators import newton
from verticality.models import lissajous_plant as lp

N_WIN = 24
FAST = 25  # 1 ms inputs per 25 ms observer interval
P = lp.p11_params()


def _planar_observer(config=None):
    u_t = lp.HeadInput(jnp.zeros(FAST), jnp.zeros(FAST), jnp.zeros(FAST))
    return newton.make(lambda x, u: lp.block_transition_flat(x, u, P, 0.025, 5),
                       lambda x, u: x[0] - x[2], u_t, jnp.zeros(4),
                       config or newton.NewtonConfig(window=N_WIN, iterations=5, every=1))


def _inputs(n_blocks):
    """A forced, fixed-head-like input history: neck torque and rotating pivot acceleration."""
    t = (np.arange(n_blocks * FAST) + 0.5) * 1e-3
    tr = lp.lissajous(t)
    tau = P.K_kg_m2 * np.asarray(tr.Theta_ddot_rad_s2)
    blocks = lambda a: jnp.asarray(np.asarray(a).reshape(n_blocks, FAST))  # noqa: E731
    return lp.HeadInput(blocks(tau), blocks(tr.a_h_I_m_s2), blocks(tr.a_z_I_m_s2))


@pytest.fixture(scope="module")
def exact_run():
    obs = _planar_observer()
    us = _inputs(N_WIN)
    x0 = jnp.array([0.02, -0.1, 0.0, lp.lissajous(0.0).Theta_dot_rad_s])

    def truth_step(x, u):
        x1 = lp.block_transition_flat(x, u, P, 0.025, 5)
        return x1, x1

    _, xs = jax.lax.scan(truth_step, x0, us)
    ys = xs[:, 0] - xs[:, 2]
    guess = x0 + jnp.array([0.1, 0.5, -0.2, -1.0])  # head tilt off by 11°, rate by 1 rad/s
    _, outs = jax.jit(obs.run)(obs.init(guess), us, ys)
    return obs, us, xs, ys, outs


def test_recovers_exact_state_after_one_window(exact_run):
    _, _, xs, _, outs = exact_run
    # no solve before the window is full: prediction only
    assert not bool(np.any(np.asarray(outs.solved[:-1])))
    assert bool(outs.solved[-1]) and bool(outs.converged[-1]) and not bool(outs.rank_deficient[-1])
    # before the solve the open-loop prediction is far off ...
    assert float(jnp.max(jnp.abs(outs.x_hat[-2] - xs[-2]))) > 0.1
    # ... after one window the present state is recovered to 1e-8
    np.testing.assert_allclose(np.asarray(outs.x_hat[-1]), np.asarray(xs[-1]), atol=1e-8, rtol=0)
    assert float(outs.residual_rms[-1]) < 1e-10
    assert 1 <= int(outs.iterations[-1]) <= 5


def test_autodiff_jacobian_matches_finite_differences(exact_run):
    obs, us, xs, _, _ = exact_run
    xi = np.asarray(xs[0]) + np.array([0.03, 0.1, -0.05, 0.2])
    J = np.asarray(jax.jit(jax.jacfwd(lambda x: obs.observability_map(x, us)[0]))(jnp.asarray(xi)))
    fmap = jax.jit(lambda x: obs.observability_map(x, us)[0])
    J_fd = np.zeros_like(J)
    for j in range(4):
        h = 1e-6 * max(1.0, abs(xi[j]))
        e = np.zeros(4)
        e[j] = h
        J_fd[:, j] = (np.asarray(fmap(xi + e)) - np.asarray(fmap(xi - e))) / (2 * h)
    assert J.shape == (N_WIN, 4)
    np.testing.assert_allclose(J, J_fd, rtol=1e-5, atol=1e-7 * np.max(np.abs(J)))


def _linear_observer(A, C, config):
    return newton.make(lambda x, u: A @ x + u, lambda x, u: C @ x, jnp.zeros(A.shape[0]),
                       jnp.zeros(A.shape[0]), config)


def test_linear_model_solve_is_the_least_squares_solution():
    """For a linear model H_T is linear: the damped Newton step lands on the LS solution."""
    rng = np.random.default_rng(0)
    A = jnp.array([[1.0, 0.1], [-0.2, 0.95]])
    C = jnp.array([[1.0, 0.0]])
    cfg = newton.NewtonConfig(window=8, iterations=5, damping=1e-12)
    obs = _linear_observer(A, C, cfg)
    us = jnp.asarray(rng.normal(size=(8, 2)) * 0.1)
    ys = jnp.asarray(rng.normal(size=(8, 1)))  # arbitrary data: nonzero residual
    sol = jax.jit(obs.solve)(jnp.array([5.0, -3.0]), us, ys, jnp.ones((8, 1)))
    # build H_T = O ξ + c explicitly and solve with numpy
    O = np.zeros((8, 2))
    c = np.zeros(8)
    Ak, ck = np.eye(2), np.zeros(2)
    for k in range(8):
        if k > 0:
            Ak = np.asarray(A) @ Ak
            ck = np.asarray(A) @ ck + np.asarray(us[k])
        O[k] = (np.asarray(C) @ Ak)[0]
        c[k] = (np.asarray(C) @ ck)[0]
    xi_ls = np.linalg.lstsq(O, np.asarray(ys)[:, 0] - c, rcond=None)[0]
    np.testing.assert_allclose(np.asarray(sol.xi), xi_ls, rtol=1e-9, atol=1e-9)
    assert bool(sol.converged) and not bool(sol.rank_deficient)


def test_rank_deficient_window_is_flagged_and_finite():
    """x2 never reaches the output: the window cannot determine it."""
    A = jnp.array([[0.9, 0.0], [0.0, 1.0]])
    C = jnp.array([[1.0, 0.0]])
    obs = _linear_observer(A, C, newton.NewtonConfig(window=6, iterations=5))
    us = jnp.zeros((6, 2))
    ys = (0.9 ** jnp.arange(6.0))[:, None] * 2.0
    xi0 = jnp.array([0.0, 7.0])
    sol = jax.jit(obs.solve)(xi0, us, ys, jnp.ones((6, 1)))
    assert bool(sol.rank_deficient) and not bool(sol.converged)
    assert bool(jnp.all(jnp.isfinite(sol.xs)))
    np.testing.assert_allclose(float(sol.xi[0]), 2.0, atol=1e-9)  # the observable part is solved
    assert float(sol.xi[1]) == pytest.approx(7.0)  # the unobservable part keeps the warm start


def test_window_without_measurements_is_flagged_not_nan(exact_run):
    obs, us, xs, ys, _ = exact_run
    ys_nan = jnp.full_like(ys, jnp.nan)
    guess = xs[0] + 0.1
    _, outs = jax.jit(obs.run)(obs.init(guess), us, ys_nan)
    assert bool(jnp.all(jnp.isfinite(outs.x_hat)))
    assert not bool(jnp.any(outs.measured))
    assert bool(outs.rank_deficient[-1]) and not bool(outs.converged[-1])


def test_bad_configuration_is_an_input_error():
    with pytest.raises(InputError, match="window"):
        _planar_observer(newton.NewtonConfig(window=0))
    with pytest.raises(InputError, match="iterations"):
        _planar_observer(newton.NewtonConfig(iterations=0))
    obs = _planar_observer()
    with pytest.raises(InputError, match="x0"):
        obs.init(jnp.zeros(3))
