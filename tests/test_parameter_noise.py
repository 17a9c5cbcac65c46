"""Parameter-uncertainty ("consider") process noise of the medial EKF (estimators/parameter_noise.py)."""

import jax.numpy as jnp
import numpy as np

from verticality import so3
from verticality.estimators import ekf, parameter_noise
from verticality.params import P13_EKF_HEAD, P13_EKF_PENDULUM, PendulumParams

DT = 0.02


def _state(tilt_S=(0.0, 0.0, 0.0), omega_S=(0.0, 0.0, 0.0)):
    return ekf.MedialState(R_I_S=so3.exp(jnp.asarray(tilt_S, float)),
                           omega_S_rad_s=jnp.asarray(omega_S, float),
                           R_I_H=jnp.eye(3), omega_H_rad_s=jnp.zeros(3))


def test_pendulum_at_rest_in_still_head_gives_no_parameter_noise():
    # hanging along gravity, no acceleration, no torque: the equilibrium does not depend on m, l, β, J
    Q = parameter_noise.medial_parameter_noise(_state(), jnp.zeros((4, 6)), DT,
                                               P13_EKF_PENDULUM, P13_EKF_HEAD)
    assert Q.shape == (ekf.N_ERR, ekf.N_ERR)
    assert float(jnp.max(jnp.abs(Q))) < 1e-24


def test_head_torque_noise_is_the_inertia_sensitivity():
    # still head, torque τ: ω̇_H = τ / J, ∂ω̇_H/∂log J = −τ / J, so Q_HH = (Δt σ τ / J)² per axis
    tau = jnp.array([0.3, -0.1, 0.05])
    u = jnp.tile(jnp.concatenate([jnp.zeros(3), tau]), (4, 1))
    Q = parameter_noise.medial_parameter_noise(_state(), u, DT, P13_EKF_PENDULUM, P13_EKF_HEAD,
                                               sigma_relative=(0.5, 0.5, 0.5, 0.2))
    expected = (DT * 0.2 * tau / P13_EKF_HEAD.J_H) ** 2
    np.testing.assert_allclose(np.diag(Q)[9:12], expected, rtol=1e-9)
    assert float(jnp.max(jnp.abs(Q[0:3]))) == 0.0 and float(jnp.max(jnp.abs(Q[6:9]))) == 0.0


def test_deflected_pendulum_noise_matches_finite_differences():
    x = _state(tilt_S=(0.2, -0.1, 0.0), omega_S=(0.5, 0.2, 0.0))
    u = jnp.tile(jnp.array([1.0, -2.0, 0.5, 0.0, 0.0, 0.0]), (4, 1))
    sig = (0.5, 0.4, 0.3, 0.2)
    Q = np.asarray(parameter_noise.medial_parameter_noise(x, u, DT, P13_EKF_PENDULUM, P13_EKF_HEAD,
                                                          sigma_relative=sig))
    p = P13_EKF_PENDULUM

    def rates(scale):
        m, l, b, J = scale
        pp = PendulumParams(m_kg=p.m_kg * m, l_m=p.l_m * l, beta_Nms=p.beta_Nms * b).resolved()
        d = ekf.medial_dynamics(x, u[0], pp, P13_EKF_HEAD._replace(J_H=P13_EKF_HEAD.J_H * J))
        return np.concatenate([np.asarray(d.omega_S_rad_s), np.asarray(d.omega_H_rad_s)])

    S = np.zeros((6, 4))
    for k in range(4):  # central differences in log p
        e = np.zeros(4)
        e[k] = 1e-6
        S[:, k] = (rates(np.exp(e)) - rates(np.exp(-e))) / 2e-6
    Qfd = DT**2 * (S * np.asarray(sig)) @ (S * np.asarray(sig)).T
    idx = np.r_[3:6, 9:12]
    np.testing.assert_allclose(Q[np.ix_(idx, idx)], Qfd, rtol=1e-6, atol=1e-14)
    assert Q[3, 3] > 1e-6  # a deflected, swinging pendulum is uncertain
    assert np.all(np.linalg.eigvalsh(Q) > -1e-18)  # a covariance
