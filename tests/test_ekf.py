"""Multiplicative EKF (estimators/ekf.py) and the stacked variant (estimators/ekf_stacked.py)."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from verticality.core import so3
from verticality.core.errors import InputError
from verticality.estimators import base, ekf, ekf_stacked
from verticality.models.base import EuclideanState, model_dataclass
from verticality.models.head import HeadInput, HeadState
from verticality.models.otolith_head import OtolithHeadState
from verticality.models.params import P13_EKF_HEAD, P13_EKF_PENDULUM
from verticality.models.pendulum import PendulumState


@model_dataclass
class Linear(EuclideanState):
    """x_{k+1} = A x_k + B u_k, y_k = C x_k on R^n (``dt`` ignored): the EKF is then the KF."""

    A: jnp.ndarray
    B: jnp.ndarray
    C: jnp.ndarray

    def transition(self, x, u, dt):
        return self.A @ x + self.B @ u

    def output(self, x, u):
        return self.C @ x


def same_value(a, b) -> bool:
    """The same model value: one tree structure (static settings included), equal leaves."""
    la, ta = jax.tree_util.tree_flatten(a)
    lb, tb = jax.tree_util.tree_flatten(b)
    return ta == tb and all(np.array_equal(x, y) for x, y in zip(la, lb, strict=True))


def linear(A, B, C):
    return Linear(*(jnp.asarray(M, dtype=jnp.float64) for M in (A, B, C)))


# ------------------------------------------------------------------ linear model == Kalman filter
def _kf_reference(A, B, C, Q, R, x0, P0, us, ys):
    """Textbook KF (NumPy), Joseph form; rows of y that are NaN are dropped."""
    x, P = np.array(x0), np.array(P0)
    xs, Ps = [], []
    for u, y in zip(us, ys, strict=True):
        x = A @ x + B @ u
        P = A @ P @ A.T + Q
        m = np.isfinite(y)
        if m.any():
            Cm, Rm = C[m], R[np.ix_(m, m)]
            S = Cm @ P @ Cm.T + Rm
            K = P @ Cm.T @ np.linalg.inv(S)
            x = x + K @ (y[m] - Cm @ x)
            I_KC = np.eye(len(x)) - K @ Cm
            P = I_KC @ P @ I_KC.T + K @ Rm @ K.T
        xs.append(x.copy())
        Ps.append(P.copy())
    return np.array(xs), np.array(Ps)


def test_ekf_on_linear_model_equals_kalman_filter():
    rng = np.random.default_rng(1)
    n, m, p, N = 4, 2, 3, 60
    A = np.eye(n) + 0.1 * rng.standard_normal((n, n))
    B = rng.standard_normal((n, m))
    C = rng.standard_normal((p, n))
    Q = 0.01 * np.eye(n)
    R = np.diag([0.1, 0.2, 0.05])
    us = rng.standard_normal((N, m))
    ys = rng.standard_normal((N, p))
    ys[10] = np.nan  # no measurement: predict only
    ys[20, 1] = np.nan  # one element missing
    x0, P0 = rng.standard_normal(n), np.eye(n)
    filt = ekf.ExtendedKalmanFilter(linear(A, B, C), jnp.asarray(Q), jnp.asarray(R))
    assert isinstance(filt, base.Estimator)
    _, outs = jax.jit(filt.run)(filt.init(jnp.asarray(x0), jnp.asarray(P0)), us, ys,
                                np.full(N, 0.1))
    xs_ref, Ps_ref = _kf_reference(A, B, C, Q, R, x0, P0, us, ys)
    np.testing.assert_allclose(outs.x, xs_ref, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(outs.P, Ps_ref, rtol=1e-9, atol=1e-9)
    assert bool(outs.predict_only[10]) and not bool(outs.predict_only[11])
    assert list(np.asarray(outs.measured[20])) == [True, False, True]
    assert not np.any(np.asarray(outs.rejected))


def test_non_finite_measurement_never_makes_nan():
    filt = ekf.ExtendedKalmanFilter(linear(np.eye(2), np.zeros((2, 1)), np.eye(2)),
                                    1e-3 * jnp.eye(2), 1e-2 * jnp.eye(2))
    s = filt.init(jnp.array([1.0, 2.0]), jnp.eye(2))
    s, out = filt.step(s, jnp.zeros(1), jnp.array([jnp.inf, jnp.nan]), 0.1)
    assert bool(out.predict_only)
    np.testing.assert_allclose(s.x, [1.0, 2.0])
    assert np.all(np.isfinite(np.asarray(s.P)))
    with pytest.raises(InputError, match="initial covariance"):
        filt.init(jnp.zeros(2))


def test_all_missing_measurement_is_exactly_predict(medial, medial_step):
    """Compiled, as ``run`` uses them: ``step`` with the shapes of test_run_equals_repeated_step
    (four substeps, a float64 measurement), so that both use one compiled step."""
    filt, x = medial
    s = filt.init(x, 0.01 * jnp.eye(ekf.N_ERR))
    u = _u_blocks(4)
    pred = jax.jit(filt.predict)(s, u, 0.02)
    new, out = medial_step(s, u, jnp.full(ekf.N_Y, jnp.nan, dtype=float), 0.02)
    for a, b in zip(jax.tree_util.tree_leaves(new), jax.tree_util.tree_leaves(pred), strict=True):
        np.testing.assert_array_equal(a, b)
    assert bool(out.predict_only) and not bool(out.rejected)
    assert not np.any(np.asarray(out.measured))


def test_a_non_finite_prediction_is_refused():
    """A model that blows up: the state is kept and the step flagged."""
    filt = ekf.ExtendedKalmanFilter(linear(np.eye(2), np.eye(2), np.eye(2)), 1e-3 * jnp.eye(2),
                                    1e-2 * jnp.eye(2))
    s = filt.init(jnp.array([1.0, 2.0]), jnp.eye(2))
    new, out = filt.step(s, jnp.array([jnp.inf, 0.0]), jnp.array([1.0, 2.0]), 0.1)
    assert bool(out.rejected)
    assert np.all(np.isfinite(np.asarray(new.x))) and np.all(np.isfinite(np.asarray(new.P)))
    np.testing.assert_array_equal(filt.predict(s, jnp.array([jnp.inf, 0.0]), 0.1).x, s.x)


# ------------------------------------------------------------------ medial model on SO(3)
def _state(R_S, w_S, R_H, w_H):
    return OtolithHeadState((PendulumState(R_S, w_S),), HeadState(R_H, w_H))


def _u_blocks(n, a_I=(1.0, 0.5, -0.3), tau=(0.01, -0.02, 0.005)):
    """n input blocks, each the same (τ_H, a_I)."""
    return HeadInput(jnp.tile(jnp.asarray(tau), (n, 1)), jnp.tile(jnp.asarray(a_I), (n, 1)))


@pytest.fixture(scope="module")
def medial():
    filt = ekf.medial_filter(P13_EKF_PENDULUM, P13_EKF_HEAD, (1e-3, 0.3, 1e-3, 0.03))
    x = _state(so3.exp(jnp.array([0.1, -0.2, 0.3])), jnp.array([0.3, 0.1, -0.2]),
               so3.exp(jnp.array([0.2, 0.1, 0.4])), jnp.array([0.5, -0.3, 1.0]))
    return filt, x


@pytest.fixture(scope="module")
def medial_step(medial):
    """``medial``'s ``step`` compiled once for the module (each ``jax.jit`` of the bound method
    would trace and compile it again)."""
    return jax.jit(medial[0].step)


def test_autodiff_jacobians_match_finite_differences(medial):
    filt, x = medial
    m = filt.model
    u = _u_blocks(2)
    dt = 0.02

    @jax.jit
    def jacobians(x, u):
        x_pred = m.transition(x, u, dt)
        z = jnp.zeros(ekf.N_ERR)
        F = jax.jacfwd(lambda d: m.difference(m.transition(m.retract(x, d), u, dt), x_pred))(z)
        H = jax.jacfwd(lambda d: m.output(m.retract(x_pred, d), u))(z)
        return F, H, x_pred

    @jax.jit
    def perturbed(x, u, x_pred, d):
        return (m.difference(m.transition(m.retract(x, d), u, dt), x_pred),
                m.output(m.retract(x_pred, d), u))

    F, H, x_pred = jacobians(x, u)
    eps = 1e-6
    cols_F, cols_H = [], []
    for e in np.eye(ekf.N_ERR):
        fp, hp = perturbed(x, u, x_pred, eps * e)
        fm, hm = perturbed(x, u, x_pred, -eps * e)
        cols_F.append((fp - fm) / (2 * eps))
        cols_H.append((hp - hm) / (2 * eps))
    np.testing.assert_allclose(F, np.stack(cols_F, 1),
                               atol=1e-7 * max(1.0, float(jnp.abs(F).max())))
    np.testing.assert_allclose(H, np.stack(cols_H, 1), atol=1e-7)
    # F is not the identity: the pendulum couples rotations and rates
    assert float(jnp.abs(F - jnp.eye(ekf.N_ERR)).max()) > 1e-3


def test_multiplicative_ekf_keeps_rotations_on_so3_over_1e5_steps(medial):
    filt, x = medial
    n_steps = 100_000
    u = _u_blocks(1, a_I=(0.0, 0.0, 0.0), tau=(0.01, 0.0, -0.005))  # one substep; the head spins
    key = jax.random.PRNGKey(3)

    @jax.jit
    def run(state):
        def body(s, k):
            y = jnp.concatenate([0.2 * jax.random.normal(jax.random.fold_in(key, k), (2,)),
                                 jnp.array([0.5, -0.3, 1.0])])
            s, out = filt.step(s, u, y, 0.01)
            err = jnp.maximum(so3.orthonormality_error(s.x.pendula[0].R_I_S),
                              so3.orthonormality_error(s.x.head.R_I_H))
            return s, (err, out.rejected)

        return jax.lax.scan(body, state, jnp.arange(n_steps))

    s, (err, rejected) = run(filt.init(x, 0.01 * jnp.eye(ekf.N_ERR)))
    assert float(jnp.max(err)) < 1e-12
    assert abs(float(jnp.linalg.det(s.x.head.R_I_H)) - 1.0) < 1e-12
    assert not bool(jnp.any(rejected))
    assert np.all(np.isfinite(np.asarray(s.P)))
    # the covariance stays symmetric positive definite
    assert float(jnp.min(jnp.linalg.eigvalsh(s.P))) > 0.0


def test_stacked_model_is_the_same_model(medial):
    """One step of the stacked model equals the SO(3) model up to the projection onto SO(3).

    The stacked model integrates the matrices in the embedding without projection (as the papers);
    the two differ only by that drift, so the difference is bounded by a few times the drift.
    """
    filt, x = medial
    ms = ekf_stacked.stacked_model(P13_EKF_PENDULUM, P13_EKF_HEAD)
    assert same_value(ms.head_model, filt.model.model)  # the same model value, not a re-derivation
    u = _u_blocks(2)
    a = filt.model.transition(x, u, 0.02)
    b = ekf_stacked.from_flat(ms.transition(ekf_stacked.to_flat(x), u, 0.02))
    drift = max(float(so3.orthonormality_error(b.pendula[0].R_I_S)),
                float(so3.orthonormality_error(b.head.R_I_H)))
    assert 0.0 < drift < 1e-4
    for la, lb in zip(jax.tree_util.tree_leaves(a), jax.tree_util.tree_leaves(b), strict=True):
        np.testing.assert_allclose(la, lb, atol=5.0 * drift)
    assert float(so3.orthonormality_error(a.pendula[0].R_I_S)) < 1e-13
    np.testing.assert_allclose(ms.output(ekf_stacked.to_flat(x), u), filt.model.output(x, u),
                               atol=1e-15)
    # P13 §4's order: ω_S, vec R_IS, ω_H, vec R_IH
    v = ekf_stacked.to_flat(x)
    np.testing.assert_array_equal(v[:3], x.pendula[0].omega_S_rad_s)
    np.testing.assert_array_equal(v[15:24], x.head.R_I_H.reshape(9))


# ------------------------------------------------------------------ experiment readings (ekf-*)
def test_head_frame_acceleration_input_is_the_same_model(medial):
    """F §4.2.1's u = (ᴴa, ᴴτ): the model rotating ᴴa with its own R̂_IH equals the ᴵa model."""
    from verticality.models.head import FreeHead
    from verticality.models.kinematics import RigidMotion
    from verticality.models.otolith_head import HeadFrameAcceleration, HeadFrameInput
    from verticality.simulation import closed_loop as sim
    from verticality.simulation import ekf_runs

    filt, x = medial
    x = x._replace(head=x.head._replace(omega_H_rad_s=jnp.zeros(3)))  # a head at rest: R_IH
    tau = jnp.zeros(3)  # constant over the step, so ᴵa = R_IH ᴴa holds throughout and the two
    a_I = jnp.array([1.0, 0.5, -0.3])  # models agree to round-off
    R = x.head.R_I_H
    u_I = _u_blocks(2, a_I=a_I, tau=tau)
    u_H = HeadFrameInput(u_I.tau_H_Nm, jnp.tile(R.T @ a_I, (2, 1)))
    f_H = ekf_runs.multiplicative_filter(ekf_runs.SIGMA_PROCESS, "head")
    assert isinstance(f_H.model.model, HeadFrameAcceleration)
    assert same_value(f_H.model.model.model,
                      ekf_runs.multiplicative_filter(ekf_runs.SIGMA_PROCESS,
                                                     "inertial").model.model)
    for la, lb in zip(jax.tree_util.tree_leaves(f_H.model.transition(x, u_H, 0.02)),
                      jax.tree_util.tree_leaves(filt.model.transition(x, u_I, 0.02)), strict=True):
        np.testing.assert_allclose(la, lb, atol=1e-12)
    # the simulator's head-frame input is R_IHᵀ ᴵa, the torque unchanged
    head = RigidMotion(R, x.head.omega_H_rad_s, jnp.array([0.3, -0.2, 0.1]), a_I)
    model = FreeHead(P13_EKF_HEAD)
    uI = sim.estimator_input(head, model)
    uH = sim.estimator_input(head, model, "head")
    np.testing.assert_allclose(uH.a_H_m_s2, R.T @ a_I, atol=1e-15)
    np.testing.assert_allclose(uH.tau_H_Nm, uI.tau_H_Nm, atol=0.0)
    np.testing.assert_array_equal(uI.a_I_m_s2, a_I)
    with pytest.raises(ValueError):
        sim.estimator_input(head, model, "trunk")
    # the parameter noise's blocks in frame I are the adapter's inertial input of each block
    blocks = HeadFrameInput(jnp.asarray(np.random.default_rng(2).normal(size=(4, 3))),
                            jnp.asarray(np.random.default_rng(3).normal(size=(4, 3))))
    got = ekf_runs.inertial_blocks(x, blocks)
    ref = jax.vmap(lambda b: f_H.model.model.inertial_input(x, b))(blocks)
    np.testing.assert_allclose(got.a_I_m_s2, ref.a_I_m_s2, rtol=1e-14, atol=1e-15)
    np.testing.assert_array_equal(got.tau_H_Nm, blocks.tau_H_Nm)


def test_common_initial_covariance_is_one_rotation_of_both(medial):
    """P0 "common": δθ_S = R_SH δθ_H up to the small relative term; symmetric, PSD."""
    from verticality.simulation import ekf_runs

    _, x = medial
    P = np.asarray(ekf_runs.initial_covariance(x, "common"))
    np.testing.assert_allclose(P, P.T, atol=1e-15)
    assert np.linalg.eigvalsh(P).min() > -1e-14
    R_SH = np.asarray(x.pendula[0].R_I_S.T @ x.head.R_I_H)
    # the conditional covariance of δθ_S given δθ_H is the relative term only
    Pss, Psh, Phh = P[0:3, 0:3], P[0:3, 6:9], P[6:9, 6:9]
    np.testing.assert_allclose(Psh, ekf_runs.INITIAL_ERROR_RAD**2 * R_SH, atol=1e-15)
    cond = Pss - Psh @ np.linalg.solve(Phh, Psh.T)
    np.testing.assert_allclose(cond, ekf_runs.SIGMA_RELATIVE_PENDULUM_RAD**2 * np.eye(3),
                               atol=1e-12)
    np.testing.assert_allclose(np.asarray(ekf_runs.initial_covariance(x, "diagonal")),
                               ekf_runs.INITIAL_ERROR_RAD**2 * np.eye(12), atol=0.0)


def test_run_equals_repeated_step(medial, medial_step):
    filt, x = medial
    s0 = filt.init(x, 0.01 * jnp.eye(ekf.N_ERR))
    n = 30  # test_estimator_contract's length: one compiled run for both
    us = HeadInput(jnp.tile(jnp.array([0.01, -0.02, 0.005]), (n, 4, 1)),
                   jnp.tile(jnp.array([1.0, 0.5, -0.3]), (n, 4, 1)))
    ys = jnp.asarray(np.random.default_rng(4).normal(scale=0.1, size=(n, ekf.N_Y)))
    ys = ys.at[2].set(jnp.nan).at[3, 0].set(jnp.nan)
    final, outs = jax.jit(filt.run)(s0, us, ys, 0.02)
    step = medial_step
    s = s0
    for k in range(n):
        s, out = step(s, jax.tree_util.tree_map(lambda a, k=k: a[k], us), ys[k], 0.02)
        np.testing.assert_allclose(out.P, outs.P[k], rtol=1e-12, atol=1e-15)
    for a, b in zip(jax.tree_util.tree_leaves(s), jax.tree_util.tree_leaves(final), strict=True):
        np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-15)
    assert bool(outs.predict_only[2]) and list(np.asarray(outs.measured[3])) == [False] + [True] * 4
