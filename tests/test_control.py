"""Stabilizers: global law (F 2.20–2.21), tilt PD and its linearization (F 4.6–4.9), DLS torque
map."""

import jax
import jax.numpy as jnp
import numpy as np

from verticality.analysis.model_checks import nonlinear_loop_jacobian
from verticality.core import so3
from verticality.core.integrate import rk4_step
from verticality.models import gimbal
from verticality.models.head import FreeHead, HeadInput, HeadState
from verticality.models.params import P13_HEAD
from verticality.simulation.control import (
    global_stabilizer,
    head_torque_from_motor_torques,
    omega_map,
    tilt_pd,
    tilt_pd_closed_loop_matrix,
    tilt_pd_linearized,
)


def test_omega_map_is_vee_of_skew_part():
    rng = np.random.default_rng(2)
    for _ in range(5):
        R = so3.exp(jnp.asarray(rng.normal(size=3)))
        np.testing.assert_allclose(omega_map(R), so3.vee(R.T - R) * 2.0 / 2.0 * 1.0, atol=1e-12)
    e = jnp.array([0.0, 0.6, 0.8])
    np.testing.assert_allclose(omega_map(so3.exp(1e-4 * e)), -2e-4 * e, atol=1e-11)


def test_global_stabilizer_brings_free_head_upright_from_large_tilt():
    hp = P13_HEAD._replace(J_H=jnp.array([0.1, 0.125, 0.15]))
    axis = jnp.array([1.0, -1.0, 0.5])
    R0 = so3.exp(2.8 * axis / jnp.linalg.norm(axis))

    head = FreeHead(hp)

    def f(t, h):
        tau = global_stabilizer(h.R_I_H, h.omega_H_rad_s, 16.0, 4.0)
        return head.dynamics(h, HeadInput(tau, jnp.zeros(3)))

    hf = jax.jit(lambda h: jax.lax.fori_loop(
        0, 4000, lambda k, x: rk4_step(f, k * 1e-3, x, 1e-3, project=head.project), h))(
        HeadState(R0, jnp.array([0.5, 0.0, -0.5])))
    assert float(jnp.linalg.norm(so3.log(hf.R_I_H))) < 1e-5
    assert float(jnp.linalg.norm(hf.omega_H_rad_s)) < 1e-4


def test_tilt_pd_torque_opposes_tilt_about_each_axis():
    z = jnp.zeros(3)
    assert float(tilt_pd(so3.rot_x(0.1), z, 10.0, 1.0)[0]) < 0.0
    assert float(tilt_pd(so3.rot_y(0.1), z, 10.0, 1.0)[1]) < 0.0
    # a reference tilt is reached: no torque at Θ = reference
    R = so3.rot_x(0.2) @ so3.rot_y(-0.3)
    ref = so3.tilt_angles(R)
    np.testing.assert_allclose(tilt_pd(R, z, 10.0, 1.0, ref), 0.0, atol=1e-12)


def test_linearized_law_agrees_to_first_order():
    R = so3.exp(jnp.array([1e-3, -2e-3, 0.5e-3]))
    w = jnp.array([0.1, -0.2, 0.3])
    d = tilt_pd(R, w, 32.0, 5.0) - tilt_pd_linearized(R, w, 32.0, 5.0)
    assert float(jnp.max(jnp.abs(d))) < 32.0 * 1e-8


def test_linearized_pd_poles_equal_nonlinear_loop_jacobian():
    J = jnp.array([0.1, 0.125, 0.15])
    kp, kd, kdz = jnp.array([30.0, 20.0]), jnp.array([4.0, 3.0]), 0.5
    A_lin = np.asarray(tilt_pd_closed_loop_matrix(J, kp, kd, kdz))
    poles = np.sort_complex(np.linalg.eigvals(A_lin))
    for law in (tilt_pd, tilt_pd_linearized):
        A = np.asarray(nonlinear_loop_jacobian(law, J, kp, kd, kdz))
        np.testing.assert_allclose(np.sort_complex(np.linalg.eigvals(A)), poles, atol=1e-9)
    roots = (list(np.roots([0.1, 4.0, 30.0])) + list(np.roots([0.125, 3.0, 20.0]))
             + [0.0, -0.5 / 0.15])
    np.testing.assert_allclose(poles, np.sort_complex(np.asarray(roots, complex)), atol=1e-9)
    assert np.all(poles.real[np.abs(poles) > 1e-12] < 0)


def test_head_torque_from_motor_torques_is_consistent():
    theta = jnp.array([0.3, -0.5])
    m = jnp.array([0.7, -0.2])
    tau = head_torque_from_motor_torques(theta, m)
    np.testing.assert_allclose(gimbal.motor_torques_from_head_torque(theta, tau), m, atol=1e-8)


def test_desired_joint_rates_match_finite_differences_and_trunk_rate_inverts_head_rate():
    from verticality.simulation import control

    R_I_T = so3.exp(jnp.array([0.2, -0.3, 0.5]))
    omega_T = jnp.array([0.7, -1.1, 0.4])
    h = 1e-6
    th = lambda R: gimbal.joint_angles_for_up(so3.up_in_frame(R))  # noqa: E731
    fd = (th(R_I_T @ so3.exp(h * omega_T)) - th(R_I_T @ so3.exp(-h * omega_T))) / (2 * h)
    np.testing.assert_allclose(control.desired_joint_rates(R_I_T, omega_T), fd, atol=1e-8)
    theta, thetadot = jnp.array([0.3, -0.2]), jnp.array([0.5, 1.5])
    omega_H = gimbal.Lambda(theta).T @ omega_T + gimbal.body_jacobian(theta) @ thetadot
    np.testing.assert_allclose(control.trunk_rate_from_head(theta, thetadot, omega_H), omega_T,
                               atol=1e-14)
    # on the joint error: zero torque when the head tracks θ_d at θ̇_d exactly
    theta_d = th(R_I_T)
    thetadot_d = control.desired_joint_rates(R_I_T, omega_T)
    omega_H_d = gimbal.Lambda(theta_d).T @ omega_T + gimbal.body_jacobian(theta_d) @ thetadot_d
    m = control.joint_space_pd_tracking(theta_d, thetadot_d, R_I_T, omega_H_d, 32.0, 5.0)
    np.testing.assert_allclose(m, 0.0, atol=1e-12)
