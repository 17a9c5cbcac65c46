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
ω_H map, so nothing is differentiated by hand; ``J_H ω̇_H + γ ω_H × J_H ω_H`` is the free head's
Euler equation (:meth:`verticality.models.head.FreeHead.torque`). The head-frame torque a motor
pair exerts is ``τ_H`` with ``m = Eᵀ τ_H`` (P13's ``τ = M^{-T} m`` for a square M; here the
projection).

The model value is :class:`GimbalHead` (u = the motor torques and the trunk's :class:`RigidMotion`);
the functions are its implementation.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp

from verticality.core import so3
from verticality.models.base import EuclideanState, model_dataclass
from verticality.models.head import FreeHead
from verticality.models.kinematics import RigidMotion


class GimbalState(NamedTuple):
    theta_rad: jnp.ndarray  # (2,) motor angles (θ1 pitch about trunk y, θ2 roll about link x)
    thetadot_rad_s: jnp.ndarray  # (2,)


def Lambda(theta_rad):
    """R_TH = Λ(θ1, θ2) = Ry(θ1) Rx(θ2), entry by entry (tested equal to the product)."""
    c1, s1 = jnp.cos(theta_rad[0]), jnp.sin(theta_rad[0])
    c2, s2 = jnp.cos(theta_rad[1]), jnp.sin(theta_rad[1])
    z = jnp.zeros_like(c1)
    return jnp.stack([jnp.stack([c1, s1 * s2, s1 * c2]),
                      jnp.stack([z, c2, -s2]),
                      jnp.stack([-s1, c1 * s2, c1 * c2])])


def body_jacobian(theta_rad):
    """E(θ) (3×2): head-frame angular velocity of the head relative to the trunk per joint rate.

    For Λ = Ry(θ1) Rx(θ2), ω_rel = θ̇1 Rx(θ2)ᵀ e_y + θ̇2 e_x, so E = [[0, 1], [cos θ2, 0],
    [−sin θ2, 0]] (tested equal to :func:`body_jacobian_autodiff`).
    """
    c2, s2 = jnp.cos(theta_rad[1]), jnp.sin(theta_rad[1])
    z, one = jnp.zeros_like(c2), jnp.ones_like(c2)
    return jnp.stack([jnp.stack([z, one]), jnp.stack([c2, z]), jnp.stack([-s2, z])])


def body_jacobian_autodiff(theta_rad):
    """E(θ) from the definition, vee(Λᵀ ∂Λ/∂θ_i), by forward-mode autodiff (the reference)."""
    dLambda = jax.jacfwd(Lambda)(theta_rad)  # (3, 3, 2)
    R = Lambda(theta_rad)
    return jnp.stack([so3.vee(R.T @ dLambda[..., i]) for i in range(2)], axis=-1)


def joint_angles_for_up(up_T):
    """Λ⁻¹ restricted to tilt: motor angles that put the head's z axis along ``up_T``.

    ``up_T`` is the direction the head's z axis should take, in the trunk frame (for an upright
    head, the world vertical expressed in T: ``R_IT^T e3``). With Λ e3 = (sin θ1 cos θ2, −sin θ2,
    cos θ1 cos θ2): θ2 = −asin(u_y), θ1 = atan2(u_x, u_z).
    """
    u = up_T / jnp.linalg.norm(up_T)
    theta2 = -jnp.arcsin(jnp.clip(u[1], -1.0, 1.0))
    theta1 = jnp.arctan2(u[0], u[2])
    return jnp.stack([theta1, theta2])


def _omega_head(theta, thetadot, omega_T):
    return Lambda(theta).T @ omega_T + body_jacobian(theta) @ thetadot


def _omega_and_bias(x: GimbalState, trunk: RigidMotion):
    """ω_H and the part of ω̇_H that does not depend on θ̈ (one forward-mode pass)."""
    return jax.jvp(
        _omega_head,
        (x.theta_rad, x.thetadot_rad_s, trunk.omega_B_rad_s),
        (x.thetadot_rad_s, jnp.zeros(2), trunk.omegadot_B_rad_s2),
    )


def _solve_spd_2x2(M, b):
    """M⁻¹ b by Cramer's rule for the 2×2 joint-space inertia (SPD, det > 0); inside the 1 ms loop
    a LAPACK call would cost more than the rest of the gimbal's dynamics (docs/simulation.md)."""
    det = M[0, 0] * M[1, 1] - M[0, 1] * M[1, 0]
    return jnp.stack([M[1, 1] * b[0] - M[0, 1] * b[1], M[0, 0] * b[1] - M[1, 0] * b[0]]) / det


def head_motion(x: GimbalState, thetaddot_rad_s2, trunk: RigidMotion) -> RigidMotion:
    """The head's kinematics from the gimbal state, its acceleration and the trunk's motion."""
    omega_H, omegadot_bias = _omega_and_bias(x, trunk)
    return RigidMotion(
        R_I_B=trunk.R_I_B @ Lambda(x.theta_rad),
        omega_B_rad_s=omega_H,
        omegadot_B_rad_s2=omegadot_bias + body_jacobian(x.theta_rad) @ thetaddot_rad_s2,
        a_I_m_s2=trunk.a_I_m_s2,
    )


def head_angular_velocity(x: GimbalState, trunk: RigidMotion):
    """ω_H = Λᵀ ω_T + E(θ) θ̇ (θ̈ does not enter it)."""
    return _omega_head(x.theta_rad, x.thetadot_rad_s, trunk.omega_B_rad_s)


def driven_head_motion(x: GimbalState, motor_torque_Nm, trunk: RigidMotion, head: FreeHead):
    """The head's kinematics and θ̈ under the motor torques m (2,), for the head on the moving
    trunk: Eᵀ τ_H = m with τ_H = ``head.torque(ω_H, ω̇_H)`` (the free head's Euler equation) solved
    for θ̈."""
    omega_H, omegadot_bias = _omega_and_bias(x, trunk)
    E = body_jacobian(x.theta_rad)
    J = head.params.resolved().J_H
    bias_torque = head.torque(omega_H, omegadot_bias)
    M = E.T @ (J[:, None] * E)  # joint-space inertia, 2×2, positive definite
    thetaddot = _solve_spd_2x2(M, motor_torque_Nm - E.T @ bias_torque)
    head_motion_ = RigidMotion(
        R_I_B=trunk.R_I_B @ Lambda(x.theta_rad),
        omega_B_rad_s=omega_H,
        omegadot_B_rad_s2=omegadot_bias + E @ thetaddot,
        a_I_m_s2=trunk.a_I_m_s2,
    )
    return head_motion_, thetaddot


def motor_torques_from_head_torque(theta_rad, tau_H_Nm):
    """Project a head-frame torque onto the two motors: m = Eᵀ τ_H."""
    return body_jacobian(theta_rad).T @ tau_H_Nm


class GimbalInput(NamedTuple):
    """Input of the gimbal head: the two motor torques and the trunk's motion."""

    motor_torque_Nm: jnp.ndarray  # (2,) m: M1 (pitch, on the trunk), M2 (roll, on the link)
    trunk: RigidMotion  # the trunk T; its a_I_m_s2 is the acceleration of the head centre C


@model_dataclass
class GimbalHead(EuclideanState):
    """The head (a :class:`FreeHead`) on the gimbal over a trunk whose motion is prescribed, as a
    model value: state :class:`GimbalState` (θ, θ̇), input :class:`GimbalInput`, output the
    encoders (θ, θ̇). :meth:`head_motion` is the head's kinematics (what the head carries sees)."""

    head: FreeHead

    def head_motion(self, x: GimbalState, u: GimbalInput) -> tuple[RigidMotion, jnp.ndarray]:
        """(the head's RigidMotion, θ̈)."""
        return driven_head_motion(x, u.motor_torque_Nm, u.trunk, self.head)

    def dynamics(self, x: GimbalState, u: GimbalInput) -> GimbalState:
        return GimbalState(theta_rad=x.thetadot_rad_s, thetadot_rad_s=self.head_motion(x, u)[1])

    def output(self, x: GimbalState, u=None):
        return jnp.concatenate([x.theta_rad, x.thetadot_rad_s])

    def head_orientation(self, x: GimbalState, trunk: RigidMotion):
        """R_IH = R_IT Λ(θ)."""
        return trunk.R_I_B @ Lambda(x.theta_rad)

    def head_angular_velocity(self, x: GimbalState, trunk: RigidMotion):
        return head_angular_velocity(x, trunk)
