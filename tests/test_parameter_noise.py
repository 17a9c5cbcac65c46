"""Parameter-uncertainty ("consider") process noise of the medial EKF
(estimators/parameter_noise.py)."""

import jax.numpy as jnp
import numpy as np

from verticality.core import so3
from verticality.estimators import ekf, parameter_noise
from verticality.models.head import HeadInput, HeadState
from verticality.models.otolith_head import OtolithHeadState, medial
from verticality.models.params import P13_EKF_HEAD, P13_EKF_PENDULUM, PendulumParams
from verticality.models.pendulum import PendulumState

DT = 0.02
MODEL = medial(P13_EKF_PENDULUM, P13_EKF_HEAD, gyro=True)


def _state(tilt_S=(0.0, 0.0, 0.0), omega_S=(0.0, 0.0, 0.0)):
    return OtolithHeadState((PendulumState(so3.exp(jnp.asarray(tilt_S, float)),
                                           jnp.asarray(omega_S, float)),),
                            HeadState(jnp.eye(3), jnp.zeros(3)))


def _blocks(n, tau=(0.0, 0.0, 0.0), a_I=(0.0, 0.0, 0.0)):
    return HeadInput(jnp.tile(jnp.asarray(tau, float), (n, 1)),
                     jnp.tile(jnp.asarray(a_I, float), (n, 1)))


def test_pendulum_at_rest_in_still_head_gives_no_parameter_noise():
    # hanging along gravity, no acceleration, no torque: the equilibrium does not depend
    # on m, l, β, J
    Q = parameter_noise.medial_parameter_noise(MODEL, _state(), _blocks(4), DT)
    assert Q.shape == (ekf.N_ERR, ekf.N_ERR)
    assert float(jnp.max(jnp.abs(Q))) < 1e-24


def test_head_torque_noise_is_the_inertia_sensitivity():
    # still head, torque τ: ω̇_H = τ / J, ∂ω̇_H/∂log J = −τ / J, so Q_HH = (Δt σ τ / J)² per axis
    tau = jnp.array([0.3, -0.1, 0.05])
    Q = parameter_noise.medial_parameter_noise(MODEL, _state(), _blocks(4, tau=tau), DT,
                                               sigma_relative=(0.5, 0.5, 0.5, 0.2))
    expected = (DT * 0.2 * tau / P13_EKF_HEAD.J_H) ** 2
    np.testing.assert_allclose(np.diag(Q)[9:12], expected, rtol=1e-9)
    assert float(jnp.max(jnp.abs(Q[0:3]))) == 0.0 and float(jnp.max(jnp.abs(Q[6:9]))) == 0.0


def test_scaling_the_value_scales_its_parameters():
    """m, l, β and J_H scale as asked; the pendulum's inertia as m l² (a similar pendulum)."""
    s = jnp.log(jnp.array([1.2, 0.7, 2.0, 1.5]))
    m = parameter_noise.scaled(MODEL, s)
    p, p0 = m.pendula[0].params, MODEL.pendula[0].params
    np.testing.assert_allclose([p.m_kg, p.l_m, p.beta_Nms],
                               [1.2 * p0.m_kg, 0.7 * p0.l_m, 2.0 * p0.beta_Nms], rtol=1e-14)
    ref = PendulumParams(m_kg=1.2 * p0.m_kg, l_m=0.7 * p0.l_m).resolved().J_pivot_S
    np.testing.assert_allclose(p.J_pivot_S, ref, rtol=1e-14)
    np.testing.assert_allclose(m.head.params.J_H, 1.5 * P13_EKF_HEAD.J_H, rtol=1e-14)
    assert m.gyro == MODEL.gyro


def test_deflected_pendulum_noise_matches_finite_differences():
    x = _state(tilt_S=(0.2, -0.1, 0.0), omega_S=(0.5, 0.2, 0.0))
    u = _blocks(4, a_I=(1.0, -2.0, 0.5))
    sig = (0.5, 0.4, 0.3, 0.2)
    Q = np.asarray(parameter_noise.medial_parameter_noise(MODEL, x, u, DT, sigma_relative=sig))
    p = P13_EKF_PENDULUM
    u0 = HeadInput(u.tau_H_Nm[0], u.a_I_m_s2[0])

    def rates(scale):  # the model rebuilt from scaled parameters (J = m l² (1, 1, 1/20))
        m, l, b, J = scale
        pp = PendulumParams(m_kg=p.m_kg * m, l_m=p.l_m * l, beta_Nms=p.beta_Nms * b)
        d = medial(pp, P13_EKF_HEAD._replace(J_H=P13_EKF_HEAD.J_H * J)).dynamics(x, u0)
        return np.concatenate([np.asarray(d.pendula[0].omega_S_rad_s),
                               np.asarray(d.head.omega_H_rad_s)])

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
