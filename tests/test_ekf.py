"""Multiplicative EKF (estimators/ekf.py) and the stacked variant (estimators/ekf_stacked.py)."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from verticality import so3
from verticality.estimators import ekf, ekf_stacked
from verticality.params import P13_EKF_HEAD, P13_EKF_PENDULUM


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
    filt = ekf.ExtendedKalmanFilter(ekf.linear_model(A, B, C), jnp.asarray(Q), jnp.asarray(R))
    _, outs = jax.jit(filt.run)(filt.init(jnp.asarray(x0), jnp.asarray(P0)), us, ys, np.full(N, 0.1))
    xs_ref, Ps_ref = _kf_reference(A, B, C, Q, R, x0, P0, us, ys)
    np.testing.assert_allclose(outs.x, xs_ref, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(outs.P, Ps_ref, rtol=1e-9, atol=1e-9)
    assert bool(outs.predict_only[10]) and not bool(outs.predict_only[11])
    assert list(np.asarray(outs.measured[20])) == [True, False, True]
    assert not np.any(np.asarray(outs.rejected))


def test_non_finite_measurement_never_makes_nan():
    filt = ekf.ExtendedKalmanFilter(ekf.linear_model(np.eye(2), np.zeros((2, 1)), np.eye(2)),
                                    1e-3 * jnp.eye(2), 1e-2 * jnp.eye(2))
    s = filt.init(jnp.array([1.0, 2.0]), jnp.eye(2))
    s, out = filt.step(s, jnp.zeros(1), jnp.array([jnp.inf, jnp.nan]), 0.1)
    assert bool(out.predict_only)
    np.testing.assert_allclose(s.x, [1.0, 2.0])
    assert np.all(np.isfinite(np.asarray(s.P)))


# ------------------------------------------------------------------ medial model on SO(3)
@pytest.fixture(scope="module")
def medial():
    filt = ekf.medial_filter(P13_EKF_PENDULUM, P13_EKF_HEAD, (1e-3, 0.3, 1e-3, 0.03))
    x = ekf.MedialState(
        so3.exp(jnp.array([0.1, -0.2, 0.3])), jnp.array([0.3, 0.1, -0.2]),
        so3.exp(jnp.array([0.2, 0.1, 0.4])), jnp.array([0.5, -0.3, 1.0]))
    return filt, x


def test_autodiff_jacobians_match_finite_differences(medial):
    filt, x = medial
    m = filt.model
    u = jnp.tile(jnp.array([1.0, 0.5, -0.3, 0.01, -0.02, 0.005]), (2, 1))
    dt = 0.02

    @jax.jit
    def jacobians(x, u):
        x_pred = m.f(x, u, dt)
        z = jnp.zeros(ekf.N_ERR)
        F = jax.jacfwd(lambda d: m.boxminus(m.f(m.boxplus(x, d), u, dt), x_pred))(z)
        H = jax.jacfwd(lambda d: m.h(m.boxplus(x_pred, d), u))(z)
        return F, H, x_pred

    @jax.jit
    def perturbed(x, u, x_pred, d):
        return m.boxminus(m.f(m.boxplus(x, d), u, dt), x_pred), m.h(m.boxplus(x_pred, d), u)

    F, H, x_pred = jacobians(x, u)
    eps = 1e-6
    cols_F, cols_H = [], []
    for e in np.eye(ekf.N_ERR):
        fp, hp = perturbed(x, u, x_pred, eps * e)
        fm, hm = perturbed(x, u, x_pred, -eps * e)
        cols_F.append((fp - fm) / (2 * eps))
        cols_H.append((hp - hm) / (2 * eps))
    np.testing.assert_allclose(F, np.stack(cols_F, 1), atol=1e-7 * max(1.0, float(jnp.abs(F).max())))
    np.testing.assert_allclose(H, np.stack(cols_H, 1), atol=1e-7)
    # F is not the identity: the pendulum couples rotations and rates
    assert float(jnp.abs(F - jnp.eye(ekf.N_ERR)).max()) > 1e-3


def test_multiplicative_ekf_keeps_rotations_on_so3_over_1e5_steps(medial):
    filt, x = medial
    n_steps = 100_000
    u = jnp.array([[0.0, 0.0, 0.0, 0.01, 0.0, -0.005]])  # one substep; the head spins
    key = jax.random.PRNGKey(3)

    @jax.jit
    def run(state):
        def body(s, k):
            y = jnp.concatenate([0.2 * jax.random.normal(jax.random.fold_in(key, k), (2,)),
                                 jnp.array([0.5, -0.3, 1.0])])
            s, out = filt.step(s, u, y, 0.01)
            err = jnp.maximum(so3.orthonormality_error(s.x.R_I_S), so3.orthonormality_error(s.x.R_I_H))
            return s, (err, out.rejected)

        return jax.lax.scan(body, state, jnp.arange(n_steps))

    s, (err, rejected) = run(filt.init(x, 0.01 * jnp.eye(ekf.N_ERR)))
    assert float(jnp.max(err)) < 1e-12
    assert abs(float(jnp.linalg.det(s.x.R_I_H)) - 1.0) < 1e-12
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
    u = jnp.tile(jnp.array([1.0, 0.5, -0.3, 0.01, -0.02, 0.005]), (2, 1))
    a = filt.model.f(x, u, 0.02)
    b = ekf_stacked.from_flat(ms.f(ekf_stacked.to_flat(x), u, 0.02))
    drift = max(float(so3.orthonormality_error(b.R_I_S)), float(so3.orthonormality_error(b.R_I_H)))
    assert 0.0 < drift < 1e-4
    for la, lb in zip(jax.tree_util.tree_leaves(a), jax.tree_util.tree_leaves(b), strict=True):
        np.testing.assert_allclose(la, lb, atol=5.0 * drift)
    assert float(so3.orthonormality_error(a.R_I_S)) < 1e-13
    np.testing.assert_allclose(ms.h(ekf_stacked.to_flat(x), u), filt.model.h(x, u), atol=1e-15)


# ------------------------------------------------------------------ experiment readings (ekf-*)
def test_head_frame_acceleration_input_is_the_same_model(medial):
    """F §4.2.1's u = (ᴴa, ᴴτ): the model rotating ᴴa with its own R̂_IH equals the ᴵa model."""
    from verticality import simulation as sim
    from verticality.experiments import ekf as exp
    from verticality.models.kinematics import RigidMotion

    filt, x = medial
    x = x._replace(omega_H_rad_s=jnp.zeros(3))  # a head at rest: R_IH constant over the step,
    tau = jnp.zeros(3)  # so ᴵa = R_IH ᴴa holds throughout and the two models agree to round-off
    a_I = jnp.array([1.0, 0.5, -0.3])
    u_I = jnp.tile(jnp.concatenate([a_I, tau]), (2, 1))
    u_H = jnp.tile(jnp.concatenate([x.R_I_H.T @ a_I, tau]), (2, 1))
    m_H = exp._head_accel_model(P13_EKF_PENDULUM, P13_EKF_HEAD)
    for la, lb in zip(jax.tree_util.tree_leaves(m_H.f(x, u_H, 0.02)),
                      jax.tree_util.tree_leaves(filt.model.f(x, u_I, 0.02)), strict=True):
        np.testing.assert_allclose(la, lb, atol=1e-12)
    # the simulator's head-frame input is R_IHᵀ ᴵa, the torque rows unchanged
    head = RigidMotion(x.R_I_H, x.omega_H_rad_s, jnp.array([0.3, -0.2, 0.1]), a_I)
    uI = sim.estimator_input(head, P13_EKF_HEAD)
    uH = sim.estimator_input(head, P13_EKF_HEAD, "head")
    np.testing.assert_allclose(uH[:3], x.R_I_H.T @ a_I, atol=1e-15)
    np.testing.assert_allclose(uH[3:], uI[3:], atol=0.0)
    with pytest.raises(ValueError):
        sim.estimator_input(head, P13_EKF_HEAD, "trunk")


def test_common_initial_covariance_is_one_rotation_of_both(medial):
    """P0 "common": δθ_S = R_SH δθ_H up to the small relative term; symmetric, PSD."""
    from verticality.experiments import ekf as exp

    _, x = medial
    P = np.asarray(exp.initial_covariance(x, "common"))
    np.testing.assert_allclose(P, P.T, atol=1e-15)
    assert np.linalg.eigvalsh(P).min() > -1e-14
    R_SH = np.asarray(x.R_I_S.T @ x.R_I_H)
    # the conditional covariance of δθ_S given δθ_H is the relative term only
    Pss, Psh, Phh = P[0:3, 0:3], P[0:3, 6:9], P[6:9, 6:9]
    np.testing.assert_allclose(Psh, exp.INITIAL_ERROR_RAD**2 * R_SH, atol=1e-15)
    cond = Pss - Psh @ np.linalg.solve(Phh, Psh.T)
    np.testing.assert_allclose(cond, exp.SIGMA_RELATIVE_PENDULUM_RAD**2 * np.eye(3), atol=1e-12)
    np.testing.assert_allclose(np.asarray(exp.initial_covariance(x, "diagonal")),
                               exp.INITIAL_ERROR_RAD**2 * np.eye(12), atol=0.0)
