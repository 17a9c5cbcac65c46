"""Newton (Moraal–Grizzle) observer: exact recovery, autodiff Jacobian, least squares, flags,
missing data, and the Newton step in the tangent coordinates of a rotation state."""

from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from verticality.core import so3
from verticality.core.errors import InputError
from verticality.estimators import newton
from verticality.models import lissajous_plant as lp
from verticality.models.base import EuclideanState, model_dataclass
from verticality.models.planar import HeadInput, PlanarState

N_WIN = 24
FAST = 25  # 1 ms inputs per 25 ms observer interval
DT = 0.025
P = lp.p11_head()
MODEL = lp.observer_model(P, 5)


def _planar_observer(config=None):
    z = jnp.zeros(FAST)
    return newton.NewtonObserver(MODEL, HeadInput(z, z, z),
                                 config or newton.NewtonConfig(window=N_WIN, iterations=5, every=1))


def _inputs(n_blocks):
    """A forced, fixed-head-like input history: neck torque and rotating pivot acceleration."""
    t = (np.arange(n_blocks * FAST) + 0.5) * 1e-3
    tr = lp.trunk(t)
    tau = P.K_kg_m2 * np.asarray(tr.Theta_ddot_rad_s2)
    blocks = lambda a: jnp.asarray(np.asarray(a).reshape(n_blocks, FAST))  # noqa: E731
    return HeadInput(blocks(tau), blocks(tr.a_h_I_m_s2), blocks(tr.a_z_I_m_s2))


def _state(v):
    return PlanarState(*(jnp.asarray(a) for a in v))


def _flat(x):
    return np.stack([np.asarray(a) for a in x], axis=-1)


@pytest.fixture(scope="module")
def exact_run():
    obs = _planar_observer()
    us = _inputs(N_WIN)
    x0 = _state([0.02, -0.1, 0.0, float(lp.trunk(0.0).Theta_dot_rad_s)])

    def truth_step(x, u):
        x1 = MODEL.transition(x, u, DT)
        return x1, x1

    _, xs = jax.lax.scan(truth_step, x0, us)
    ys = xs.theta_S_rad - xs.theta_H_rad
    # head tilt off by 11°, rate by 1 rad/s
    guess = _state(_flat(x0) + np.array([0.1, 0.5, -0.2, -1.0]))
    _, outs = jax.jit(obs.run)(obs.init(guess), us, ys, DT)
    return obs, us, xs, ys, outs


def test_recovers_exact_state_after_one_window(exact_run):
    _, _, xs, _, outs = exact_run
    xh, xt = _flat(outs.x_hat), _flat(xs)
    # no solve before the window is full: prediction only
    assert not bool(np.any(np.asarray(outs.solved[:-1])))
    assert bool(outs.solved[-1]) and bool(outs.converged[-1]) and not bool(outs.rank_deficient[-1])
    # before the solve the open-loop prediction is far off ...
    assert float(np.max(np.abs(xh[-2] - xt[-2]))) > 0.1
    # ... after one window the present state is recovered to 1e-8
    np.testing.assert_allclose(xh[-1], xt[-1], atol=1e-8, rtol=0)
    assert float(outs.residual_rms[-1]) < 1e-10
    assert 1 <= int(outs.iterations[-1]) <= 5
    assert outs.measured.shape == (N_WIN, 1) and bool(np.all(outs.measured))


def test_autodiff_jacobian_matches_finite_differences(exact_run):
    obs, us, xs, _, _ = exact_run
    xi = _flat(xs)[0] + np.array([0.03, 0.1, -0.05, 0.2])
    fmap = jax.jit(lambda x: obs.observability_map(_state(x), us, DT)[0])
    J = np.asarray(jax.jit(jax.jacfwd(lambda x: obs.observability_map(_state(x), us, DT)[0]))(
        jnp.asarray(xi)))
    J_fd = np.zeros_like(J)
    for j in range(4):
        h = 1e-6 * max(1.0, abs(xi[j]))
        e = np.zeros(4)
        e[j] = h
        J_fd[:, j] = (np.asarray(fmap(xi + e)) - np.asarray(fmap(xi - e))) / (2 * h)
    assert J.shape == (N_WIN, 4)
    np.testing.assert_allclose(J, J_fd, rtol=1e-5, atol=1e-7 * np.max(np.abs(J)))


@model_dataclass
class LinearDiscrete(EuclideanState):
    """x_{k+1} = A x_k + u, y = C x (a discrete model value for the tests)."""

    A: Any
    C: Any

    def transition(self, x, u, dt):
        return self.A @ x + u

    def output(self, x, u):
        return self.C @ x


def _linear_observer(A, C, config):
    return newton.NewtonObserver(LinearDiscrete(A, C), jnp.zeros(A.shape[0]), config)


def test_linear_model_solve_is_the_least_squares_solution():
    """For a linear model H_T is linear: the damped Newton step lands on the LS solution."""
    rng = np.random.default_rng(0)
    A = jnp.array([[1.0, 0.1], [-0.2, 0.95]])
    C = jnp.array([[1.0, 0.0]])
    cfg = newton.NewtonConfig(window=8, iterations=5, damping=1e-12)
    obs = _linear_observer(A, C, cfg)
    us = jnp.asarray(rng.normal(size=(8, 2)) * 0.1)
    ys = jnp.asarray(rng.normal(size=(8, 1)))  # arbitrary data: nonzero residual
    sol = jax.jit(obs.solve)(jnp.array([5.0, -3.0]), us, ys, jnp.ones((8, 1)), 1.0)
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
    sol = jax.jit(obs.solve)(xi0, us, ys, jnp.ones((6, 1)), 1.0)
    assert bool(sol.rank_deficient) and not bool(sol.converged)
    assert bool(jnp.all(jnp.isfinite(sol.xs)))
    np.testing.assert_allclose(float(sol.xi[0]), 2.0, atol=1e-9)  # the observable part is solved
    assert float(sol.xi[1]) == pytest.approx(7.0)  # the unobservable part keeps the warm start


def test_missing_measurements_predict_only_and_sparse_windows_are_flagged(exact_run):
    obs, us, xs, ys, _ = exact_run
    guess = _state(_flat(xs)[0] + 0.1)
    step, predict = jax.jit(obs.step), jax.jit(obs.predict)
    # no measurement at all: every step is the prediction, nothing is solved, nothing is NaN
    s, p = obs.init(guess), obs.init(guess)
    for k in range(N_WIN):
        s, out = step(s, jax.tree_util.tree_map(lambda a, k=k: a[k], us), jnp.nan, DT)
        p = predict(p, jax.tree_util.tree_map(lambda a, k=k: a[k], us), DT)
        assert not bool(out.solved) and not bool(out.measured[0])
    for a, b in zip(jax.tree_util.tree_leaves(s), jax.tree_util.tree_leaves(p), strict=True):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    assert np.all(np.isfinite(_flat(s.x_hat)))
    # one reading in the whole window: solved, but 1 equation cannot fix 4 states
    ys_one = jnp.full_like(ys, jnp.nan).at[-1].set(ys[-1])
    _, outs = jax.jit(obs.run)(obs.init(guess), us, ys_one, DT)
    assert bool(outs.solved[-1]) and bool(outs.rank_deficient[-1]) and not bool(outs.converged[-1])
    assert np.all(np.isfinite(_flat(outs.x_hat)))


@model_dataclass
class SpinningBody:
    """A body spinning at a known constant rate ω (the input), seen through a fixed unit vector:
    x = R_I_B on SO(3), R_{k+1} = R_k exp(ω dt), y = R_I_Bᵀ e_z (gravity in the body frame) and
    R_I_Bᵀ e_x (a heading reference), so that the whole attitude is observable."""

    def transition(self, R, omega, dt):
        return R @ so3.exp(omega * dt)

    def output(self, R, omega):
        return jnp.concatenate([R.T @ jnp.array([0.0, 0.0, 1.0]), R.T @ jnp.array([1.0, 0.0, 0.0])])

    def retract(self, R, dx):
        return R @ so3.exp(dx)

    def difference(self, R1, R0):
        return so3.log(R0.T @ R1)


def test_newton_step_on_a_rotation_state_stays_on_so3_and_recovers_the_attitude():
    obs = newton.NewtonObserver(SpinningBody(), jnp.zeros(3), newton.NewtonConfig(window=4))
    omega = jnp.array([0.3, -0.5, 0.8])
    R_true = so3.exp(jnp.array([0.4, -0.2, 1.0]))
    us = jnp.tile(omega, (8, 1))
    Rs, R = [], R_true
    for _ in range(8):
        R = R @ so3.exp(omega * 0.1)
        Rs.append(R)
    ys = jnp.stack([SpinningBody().output(R, omega) for R in Rs])
    guess = R_true @ so3.exp(jnp.array([0.5, 0.3, -0.4]))  # 40° off
    final, outs = jax.jit(obs.run)(obs.init(guess), us, ys, 0.1)
    assert bool(outs.solved[-1]) and bool(outs.converged[-1])
    err = np.asarray(so3.log(Rs[-1].T @ final.x_hat))
    assert np.linalg.norm(err) < 1e-9
    assert float(so3.orthonormality_error(final.x_hat)) < 1e-12


def test_bad_configuration_is_an_input_error():
    with pytest.raises(InputError, match="window"):
        _planar_observer(newton.NewtonConfig(window=0))
    with pytest.raises(InputError, match="iterations"):
        _planar_observer(newton.NewtonConfig(iterations=0))
    obs = _planar_observer()
    with pytest.raises(InputError, match="x0"):
        obs.init(jnp.zeros(3))
    with pytest.raises(InputError, match="x0"):
        _linear_observer(jnp.eye(2), jnp.eye(2)[:1],
                         newton.NewtonConfig(window=3)).init(jnp.zeros(3))
