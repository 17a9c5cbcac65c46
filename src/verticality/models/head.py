"""The free rigid head (F 2.3–2.4): the one place where the head's Euler equation is written.

    J_H ω̇_H = τ_H − γ ω_H × J_H ω_H          (γ = ``HeadParams.gyroscopic``; F 2.7 drops it)
    Ṙ_IH = R_IH [ω_H]×

State :class:`HeadState` ``(R_I_H, ω_H)`` with ω_H in the head frame; input :class:`HeadInput`
``(τ_H, a_I)``: the torque on the head (head frame) and the acceleration of the head centre in
frame I, gravity excluded (F's input is ``u = (τ_H, H a)``; the centre's acceleration in I is what
a trajectory gives, and it stays valid while the head turns — the head-frame reading is the input
adapter :class:`verticality.models.otolith_head.HeadFrameAcceleration`). The acceleration does not
act on the head's rotation; it is carried into the head's :class:`RigidMotion` for what the head
carries (the otolith pendula). The output is the head's gyro, ``ω_H``.

Tangent space (right, body-frame perturbation; the EKF's error state):
``x ⊞ δ = (R_IH exp([δθ]×), ω_H + δω)``.
"""

from __future__ import annotations

from typing import NamedTuple

import jax.numpy as jnp

from verticality.core import so3
from verticality.models.base import model_dataclass
from verticality.models.kinematics import RigidMotion, RotationAndRate
from verticality.models.params import HeadParams


class HeadState(NamedTuple):
    """Free rigid head (F 2.3–2.4)."""

    R_I_H: jnp.ndarray  # (3, 3)
    omega_H_rad_s: jnp.ndarray  # (3,) head angular velocity w.r.t. I, in H


class HeadInput(NamedTuple):
    """Input of the free head (F 2.10's ``u``, the acceleration in frame I)."""

    tau_H_Nm: jnp.ndarray  # (3,) torque on the head, head frame (neck muscles / motors)
    a_I_m_s2: jnp.ndarray  # (3,) acceleration of the head centre, frame I, gravity excluded


@model_dataclass
class FreeHead(RotationAndRate):
    """The free head as a model value (see the module doc). ``params`` are used resolved."""

    params: HeadParams

    def angular_acceleration(self, omega_H_rad_s, tau_H_Nm):
        """F 2.3: ``ω̇_H = J_H⁻¹ (τ_H − γ ω_H × J_H ω_H)``."""
        p = self.params.resolved()
        J = p.J_H
        w = omega_H_rad_s
        return (tau_H_Nm - p.gyroscopic * jnp.cross(w, J * w)) / J

    def torque(self, omega_H_rad_s, omegadot_H_rad_s2):
        """The inverse of :meth:`angular_acceleration`: ``τ_H = J_H ω̇_H + γ ω_H × J_H ω_H``, the
        total torque (motors, constraints) that gives the head this motion."""
        p = self.params.resolved()
        J = p.J_H
        w = omega_H_rad_s
        return J * omegadot_H_rad_s2 + p.gyroscopic * jnp.cross(w, J * w)

    def rate_and_motion(self, x: HeadState, u: HeadInput) -> tuple[HeadState, RigidMotion]:
        """``(ẋ, the head's RigidMotion)``: the derivative and the kinematics it carries."""
        wdot = self.angular_acceleration(x.omega_H_rad_s, u.tau_H_Nm)
        rate = HeadState(R_I_H=x.R_I_H @ so3.hat(x.omega_H_rad_s), omega_H_rad_s=wdot)
        motion = RigidMotion(R_I_B=x.R_I_H, omega_B_rad_s=x.omega_H_rad_s,
                             omegadot_B_rad_s2=wdot, a_I_m_s2=jnp.asarray(u.a_I_m_s2, dtype=float))
        return rate, motion

    def dynamics(self, x: HeadState, u: HeadInput) -> HeadState:
        return self.rate_and_motion(x, u)[0]

    def motion(self, x: HeadState, u: HeadInput) -> RigidMotion:
        """The head's kinematics in state ``x`` under input ``u``."""
        return self.rate_and_motion(x, u)[1]

    def output(self, x: HeadState, u=None):
        """The head's gyro: ω_H (rad/s, head frame)."""
        return x.omega_H_rad_s


def state_from_motion(head: RigidMotion) -> HeadState:
    """The head state of a head moving as ``head``."""
    return HeadState(R_I_H=head.R_I_B, omega_H_rad_s=head.omega_B_rad_s)
