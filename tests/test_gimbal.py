"""Head on a 2-DOF gimbal over a prescribed trunk (models/gimbal.py, P13 §3) and its joint-space
PD."""

import functools

import jax
import jax.numpy as jnp
import numpy as np

from verticality.core import so3
from verticality.core.integrate import rk4_step
from verticality.models import base, gimbal
from verticality.models.gimbal import GimbalHead, GimbalInput
from verticality.models.head import FreeHead
from verticality.models.kinematics import RigidMotion, still
from verticality.models.params import P13_HEAD, P13_KD_NMS_RAD, P13_KP_NM_RAD
from verticality.simulation.control import joint_space_pd, trunk_orientation_estimate

DT = 1e-3


def test_joint_angles_for_up_inverts_Lambda_on_tilt():
    rng = np.random.default_rng(1)
    for _ in range(20):
        theta = rng.uniform(-1.2, 1.2, size=2)
        up = gimbal.Lambda(jnp.asarray(theta))[:, 2]  # head z axis in the trunk frame
        np.testing.assert_allclose(gimbal.joint_angles_for_up(up), theta, atol=1e-12)
        u = rng.normal(size=3)
        u[2] = abs(u[2]) + 0.1
        th = gimbal.joint_angles_for_up(jnp.asarray(u))
        np.testing.assert_allclose(gimbal.Lambda(th)[:, 2], u / np.linalg.norm(u), atol=1e-12)


def _trunk_motion(t):
    """Trunk tilting in 3-D about a moving axis (closed form), centre accelerating."""
    ax = jnp.array([0.8, 0.6, 0.0])
    th, thd, thdd = 0.3 * jnp.sin(1.5 * t), 0.45 * jnp.cos(1.5 * t), -0.675 * jnp.sin(1.5 * t)
    R = so3.exp(ax * th)
    return RigidMotion(R, ax * thd, ax * thdd, jnp.array([jnp.sin(t), 0.0, 0.5 * jnp.cos(2 * t)]))


HP_ANISO = P13_HEAD._replace(J_H=jnp.array([0.1, 0.125, 0.15]))


@functools.lru_cache(maxsize=1)
def _runs():
    """Two gimbal runs in one compiled batch (flag 0: still trunk, no torque, anisotropic head;
    flag 1: moving trunk, joint-space PD with the true trunk orientation, P13 head)."""

    def f(t, x, flag):
        moving = _trunk_motion(t)
        trunk = jax.tree_util.tree_map(lambda a, b: flag * a + (1.0 - flag) * b, moving, still())
        R_I_H = trunk.R_I_B @ gimbal.Lambda(x.theta_rad)
        m = flag * joint_space_pd(x.theta_rad, x.thetadot_rad_s,
                                  trunk_orientation_estimate(R_I_H, x.theta_rad), P13_KP_NM_RAD,
                                  P13_KD_NMS_RAD)
        hp = P13_HEAD._replace(J_H=flag * P13_HEAD.J_H + (1.0 - flag) * HP_ANISO.J_H)
        return GimbalHead(FreeHead(hp)).dynamics(x, GimbalInput(m, trunk))

    def out(t, x, flag):
        trunk_R = _trunk_motion(t).R_I_B
        R_T = flag * trunk_R + (1.0 - flag) * jnp.eye(3)
        R_I_H = R_T @ gimbal.Lambda(x.theta_rad)
        w = gimbal.head_motion(x, jnp.zeros(2), still()).omega_B_rad_s  # valid for flag 0
        return (0.5 * jnp.sum(HP_ANISO.J_H * w * w), jnp.arccos(jnp.clip(R_I_H[2, 2], -1.0, 1.0)),
                jnp.arccos(trunk_R[2, 2]))

    def one(x0, flag):
        def block(x, kb):  # the output every 10 steps, then 10 RK4 steps
            y = out(kb * 10 * DT, x, flag)
            x = jax.lax.fori_loop(0, 10, lambda i, xx: rk4_step(
                lambda t, z: f(t, z, flag), (kb * 10 + i) * DT, xx, DT), x)
            return x, y

        return jax.lax.scan(block, x0, jnp.arange(400))

    x0 = gimbal.GimbalState(jnp.array([[0.3, -0.2], [0.4, -0.3]]),
                            jnp.array([[1.0, -2.0], [0.0, 0.0]]))
    xf, outs = jax.jit(jax.vmap(one))(x0, jnp.array([0.0, 1.0]))
    return jax.tree_util.tree_map(np.asarray, (x0, xf, outs))


def test_energy_conserved_on_still_trunk():
    """No motor torque, trunk at rest: the constraint does no work, ½ ω_Hᵀ J ω_H is constant."""
    x0, xf, (E, _, _) = _runs()
    E = E[0]
    assert np.max(np.abs(E - E[0])) / E[0] < 1e-9
    # the anisotropic head's joint rates do change (the test is not trivially static)
    assert np.max(np.abs(xf.thetadot_rad_s[0] - x0.thetadot_rad_s[0])) > 0.01


def test_joint_space_pd_brings_head_upright_on_moving_trunk():
    _, _, (_, head_tilt, trunk_tilt) = _runs()
    head_tilt, trunk_tilt = head_tilt[1], trunk_tilt[1]
    assert head_tilt[0] > 0.4  # starts well off upright
    late = slice(200, None)  # t >= 2 s
    assert np.max(trunk_tilt[late]) > 0.25
    # the crude decentralized PD lags the moving target by ~ k_d/k_p·|θ̇_d| (≈ 5/32 · 0.45 rad/s
    # here), so the head stays within that lag of upright: a fraction of the trunk's tilt
    lag = P13_KD_NMS_RAD / P13_KP_NM_RAD * 0.45
    assert np.max(head_tilt[late]) < 1.5 * lag
    assert np.max(head_tilt[late]) < 0.3 * np.max(trunk_tilt[late])


def test_joint_space_pd_zero_at_target():
    R_I_T = so3.rot_x(0.2) @ so3.rot_y(-0.1)
    theta_d = gimbal.joint_angles_for_up(so3.up_in_frame(R_I_T))
    m = joint_space_pd(theta_d, jnp.zeros(2), R_I_T, 32.0, 5.0)
    np.testing.assert_allclose(m, 0.0, atol=1e-12)
    # the head is then upright: its z axis is the world's
    np.testing.assert_allclose((R_I_T @ gimbal.Lambda(theta_d))[:, 2], [0, 0, 1], atol=1e-12)
    # the estimate of the trunk orientation from the head estimate and the encoders
    R_I_H = R_I_T @ gimbal.Lambda(jnp.array([0.1, 0.2]))
    np.testing.assert_allclose(trunk_orientation_estimate(R_I_H, jnp.array([0.1, 0.2])), R_I_T,
                               atol=1e-12)


def test_closed_forms_equal_their_definitions():
    """Λ entry by entry equals Ry·Rx; E equals vee(Λᵀ∂Λ/∂θ) by autodiff; the driven head's θ̈
    equals a general linear solve of the joint-space equation."""
    from verticality.simulation import trajectories as tr

    theta = jnp.array([0.3, -0.7])
    np.testing.assert_allclose(gimbal.Lambda(theta), so3.rot_y(0.3) @ so3.rot_x(-0.7), atol=1e-15)
    np.testing.assert_allclose(gimbal.body_jacobian(theta), gimbal.body_jacobian_autodiff(theta),
                               atol=1e-15)
    x = gimbal.GimbalState(theta, jnp.array([0.4, -1.1]))
    trunk = jax.jit(tr.impact().motion)(2.3)
    m = jnp.array([1.5, -0.8])
    model = GimbalHead(FreeHead(P13_HEAD))
    head, thdd = jax.jit(model.head_motion)(x, GimbalInput(m, trunk))
    E = gimbal.body_jacobian(theta)
    J = P13_HEAD.J_H
    w = head.omega_B_rad_s
    # Eᵀ (J ω̇ + ω × Jω) = m must hold for the returned head motion
    np.testing.assert_allclose(E.T @ (J * head.omegadot_B_rad_s2 + jnp.cross(w, J * w)), m,
                               rtol=1e-12, atol=1e-12)
    head_ref = gimbal.head_motion(x, thdd, trunk)
    for a, b in zip(head, head_ref, strict=True):
        np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-12)
    # the value: ẋ = (θ̇, θ̈), the encoders as output, the head's ω without θ̈
    dx = model.dynamics(x, GimbalInput(m, trunk))
    np.testing.assert_allclose(dx.thetadot_rad_s, thdd, rtol=1e-14)
    np.testing.assert_array_equal(dx.theta_rad, x.thetadot_rad_s)
    np.testing.assert_array_equal(model.output(x), jnp.concatenate([theta, x.thetadot_rad_s]))
    np.testing.assert_allclose(model.head_angular_velocity(x, trunk), head.omega_B_rad_s,
                               rtol=1e-14)
    np.testing.assert_allclose(model.head_orientation(x, trunk), head.R_I_B, rtol=1e-14)
    assert isinstance(model, base.Model)
