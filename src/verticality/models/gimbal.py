"""Head on a 2-DOF gimbal over a trunk whose motion is prescribed (P13 §3, Fig. 1).

The gimbal's centre is the head's centre C and a point fixed on the trunk, so the trunk's
prescribed motion (a :class:`RigidMotion` of frame T, whose ``a_I_m_s2`` is the acceleration of C)
gives the head centre's acceleration directly. The map of P13 §3,

    R_TH = Λ(θ1, θ2) = Ry(θ1) Rx(θ2),

puts the pitch motor M1 on the trunk (axis y_T) and the roll motor M2 on the intermediate link
(axis x). Any head tilt with |θ1|, |θ2| < π/2 is reachable; the head's rotation about the world
vertical follows the trunk and cannot be effected (P13: "the rotation about k_I that cannot be
effected").

Joint-space dynamics (link inertias neglected, the head's inertia J_H about C):

    ω_H = Λᵀ ω_T + E(θ) θ̇                       E: body Jacobian of Λ (3×2), by autodiff
    Eᵀ (J_H ω̇_H + γ ω_H × J_H ω_H) = m          m: the two motor torques (virtual power)

solved for θ̈; ω̇_H's part that does not depend on θ̈ comes from a forward-mode derivative of the
ω_H map, so nothing is differentiated by hand. The head-frame torque a motor pair exerts is
``τ_H`` with ``m = Eᵀ τ_H`` (P13's ``τ = M^{-T} m`` for a square M; here the projection).
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp

from verticality import so3
from verticality.models.kinematics import RigidMotion
from verticality.params import HeadParams


class GimbalState(NamedTuple):
    theta_rad: jnp.ndarray  # (2,) motor angles (θ1 pitch about trunk y, θ2 roll about link x)
    thetadot_rad_s: jnp.ndarray  # (2,)


def Lambda(theta_rad):
    """R_TH = Λ(θ1, θ2) = Ry(θ1) Rx(θ2)."""
    return so3.rot_y(theta_rad[0]) @ so3.rot_x(theta_rad[1])


def body_jacobian(theta_rad):
    """E(θ) (3×2): head-frame angular velocity of the head relative to the trunk per joint rate."""
    dLambda = jax.jacfwd(Lambda)(theta_rad)  # (3, 3, 2)
    R = Lambda(theta_rad)
    return jnp.stack([so3.vee(R.T @ dLambda[..., i]) for i in range(2)], axis=-1)


def joint_angles_for_up(up_T):
    """Λ⁻¹ restricted to tilt: motor angles that put the head's z axis along ``up_T``.

    ``up_T`` is the direction the head's z axis should take, in the trunk frame (for an upright head,
    the world vertical expressed in T: ``R_IT^T e3``). With Λ e3 = (sin θ1 cos θ2, −sin θ2,
    cos θ1 cos θ2): θ2 = −asin(u_y), θ1 = atan2(u_x, u_z).
    """
    u = up_T / jnp.linalg.norm(up_T)
    theta2 = -jnp.arcsin(jnp.clip(u[1], -1.0, 1.0))
    theta1 = jnp.arctan2(u[0], u[2])
    return jnp.stack([theta1, theta2])


def _omega_head(theta, thetadot, omega_T):
    return Lambda(theta).T @ omega_T + body_jacobian(theta) @ thetadot


def head_motion(x: GimbalState, thetaddot_rad_s2, trunk: RigidMotion) -> RigidMotion:
    """The head's kinematics from the gimbal state, its acceleration and the trunk's motion."""
    omega_H, omegadot_bias = jax.jvp(
        _omega_head,
        (x.theta_rad, x.thetadot_rad_s, trunk.omega_B_rad_s),
        (x.thetadot_rad_s, jnp.zeros(2), trunk.omegadot_B_rad_s2),
    )
    omegadot_H = omegadot_bias + body_jacobian(x.theta_rad) @ thetaddot_rad_s2
    return RigidMotion(
        R_I_B=trunk.R_I_B @ Lambda(x.theta_rad),
        omega_B_rad_s=omega_H,
        omegadot_B_rad_s2=omegadot_H,
        a_I_m_s2=trunk.a_I_m_s2,
    )


def joint_acceleration(x: GimbalState, motor_torque_Nm, trunk: RigidMotion, p: HeadParams):
    """θ̈ from the motor torques m (2,) for the head on the moving trunk."""
    E = body_jacobian(x.theta_rad)
    J = p.J_H
    omega_H, omegadot_bias = jax.jvp(
        _omega_head,
        (x.theta_rad, x.thetadot_rad_s, trunk.omega_B_rad_s),
        (x.thetadot_rad_s, jnp.zeros(2), trunk.omegadot_B_rad_s2),
    )
    bias_torque = J * omegadot_bias + p.gyroscopic * jnp.cross(omega_H, J * omega_H)
    M = E.T @ (J[:, None] * E)  # joint-space inertia, 2×2, positive definite
    return jnp.linalg.solve(M, motor_torque_Nm - E.T @ bias_torque)


def dynamics(x: GimbalState, motor_torque_Nm, trunk: RigidMotion, p: HeadParams) -> GimbalState:
    return GimbalState(
        theta_rad=x.thetadot_rad_s,
        thetadot_rad_s=joint_acceleration(x, motor_torque_Nm, trunk, p),
    )


def motor_torques_from_head_torque(theta_rad, tau_H_Nm):
    """Project a head-frame torque onto the two motors: m = Eᵀ τ_H."""
    return body_jacobian(theta_rad).T @ tau_H_Nm


def head_torque_total(head: RigidMotion, p: HeadParams):
    """Total torque on the head (motors plus gimbal constraint), head frame: J ω̇ + γ ω × J ω.

    This is the torque input of the free-head model of F 2.3 that reproduces the head's actual
    motion, whichever way the head is driven.
    """
    J = p.J_H
    w = head.omega_B_rad_s
    return J * head.omegadot_B_rad_s2 + p.gyroscopic * jnp.cross(w, J * w)


def fixed(trunk: RigidMotion) -> RigidMotion:
    """The `fixed` condition: head rigid on the trunk (Λ = I), so the head's motion is the trunk's."""
    return trunk
