"""Damped spherical pendulum on a moving, rotating pivot: the otolith and the liquid inclinometer.

Full Newton–Euler form of F eq. 2.5 (medial) and 2.11 (pivot off the head's centre), written about
the pivot, in the pendulum's own frame S:

    J ω̇_S = −γ ω_S × J ω_S                        (gyroscopic, γ = params.gyroscopic)
            + m c_S × R_SI (g_I − a_P_I)            (gravity and pivot acceleration)
            − β (ω_S − R_SI R_IH ω_H)              (viscous coupling to the head)
    Ṙ_IS = R_IS [ω_S]×

with the pivot acceleration a_P_I = a_C_I + R_IH (ε ω̇_H × r_H + κ ω_H × (ω_H × r_H)) for a pivot at
r_H from the head centre C (ε = params.euler, κ = params.centripetal).

Frame S convention. The thesis writes the arm as ``S l = (0, 0, l)`` with gravity ``(0, 0, −g)``,
which taken literally is an inverted (unstable) pendulum; its planar form (F p. 36) is stable only
if g is read as negative. We keep the physics of a hanging pendulum and put the z axis of S *from
the mass to the pivot*: the centre of mass is at ``c_S = (0, 0, −l)``. The z axis of S is then the
normal of the liquid surface of an inclinometer (the gravito-inertial "up"), a pendulum at rest in a
level head has ``R_HS = I``, and the otolith angles of F 2.8–2.9 read zero. ``s_H``
(docs/conventions.md: unit vector from pivot to mass, head frame) is ``−R_HS e3``.

Sign of the otolith angles: for a still head, ``R_HS = R_IH^T`` (up to yaw of the pendulum), so the
otolith angles are the tilt angles (F 3.8–3.9) of ``R_HI``: φ = Θ(R_IH^T). For a tilt about one axis
that is φ = −Θ: the pendulum leans, relative to the head, opposite to the head's tilt.

The model value is :class:`Pendulum`: driven kinematically by the head's :class:`RigidMotion` (its
input ``u``), output the otolith angles (φ_x, φ_y); the functions below are its implementation.
Tangent space: ``x ⊞ δ = (R_IS exp([δθ]×), ω_S + δω)``.
"""

from __future__ import annotations

from typing import NamedTuple

import jax.numpy as jnp

from verticality.core import so3
from verticality.core.constants import gravity_I
from verticality.models.base import model_dataclass
from verticality.models.kinematics import RigidMotion, RotationAndRate
from verticality.models.params import PendulumParams


class PendulumState(NamedTuple):
    R_I_S: jnp.ndarray  # (3, 3) orientation of the pendulum frame in I
    omega_S_rad_s: jnp.ndarray  # (3,) angular velocity of S w.r.t. I, in S


HeadMotion = RigidMotion
"""The head's kinematics as seen by a pendulum pivoting on it (``R_I_B`` is ``R_IH``, ``a_I_m_s2``
the acceleration of the head centre C)."""


def pivot_acceleration_I(head: HeadMotion, p: PendulumParams):
    """Linear acceleration of the pivot in frame I (gravity excluded), F 2.11's transport terms."""
    r = p.pivot_H_m
    w = head.omega_B_rad_s
    transport_H = p.euler * jnp.cross(head.omegadot_B_rad_s2, r) + p.centripetal * jnp.cross(
        w, jnp.cross(w, r)
    )
    return head.a_I_m_s2 + head.R_I_B @ transport_H


def com_arm_S(p: PendulumParams):
    """Vector from pivot to centre of mass in S: (0, 0, −l)."""
    return jnp.array([0.0, 0.0, -1.0]) * p.l_m


def angular_acceleration(x: PendulumState, head: HeadMotion, p: PendulumParams):
    """ω̇_S of the pendulum (rad/s², frame S) for the head motion ``head``."""
    R_S_I = x.R_I_S.T
    w = x.omega_S_rad_s
    J = p.J_pivot_S
    specific_gravity_I = gravity_I() - pivot_acceleration_I(head, p)
    torque = (
        -p.gyroscopic * jnp.cross(w, J * w)
        + p.m_kg * jnp.cross(com_arm_S(p), R_S_I @ specific_gravity_I)
        - p.beta_Nms * (w - R_S_I @ (head.R_I_B @ head.omega_B_rad_s))
    )
    return torque / J


def dynamics(x: PendulumState, head: HeadMotion, p: PendulumParams) -> PendulumState:
    """Time derivative of the pendulum state (``Ṙ_IS``, ``ω̇_S``)."""
    return PendulumState(
        R_I_S=x.R_I_S @ so3.hat(x.omega_S_rad_s),
        omega_S_rad_s=angular_acceleration(x, head, p),
    )


def R_H_S(x: PendulumState, R_I_H):
    return R_I_H.T @ x.R_I_S


def arm_direction_H(x: PendulumState, R_I_H):
    """``s_H``: unit vector from pivot to mass, in the head frame."""
    return -R_H_S(x, R_I_H)[:, 2]


def otolith_angles(R_H_S_):
    """(φ_x, φ_y) of F 2.8–2.9: ``tan φ_x = [R_HS]_32/[R_HS]_33``,
    ``tan φ_y = [R_HS]_31/[R_HS]_33``."""
    R = jnp.asarray(R_H_S_)
    return jnp.stack(
        [jnp.arctan2(R[..., 2, 1], R[..., 2, 2]), jnp.arctan2(R[..., 2, 0], R[..., 2, 2])], -1
    )


def p13_inclinometer_angles(R_H_S_):
    """P13 eq. 3's inclinometer outputs: ``y1 = arcsin‖j_H × j_S‖``, ``y2 = arcsin‖i_H × i_S‖`` (the
    angles between the head's and the pendulum's y axes and x axes; the norm is the same in every
    frame, so it is taken in H). Unsigned, and not differentiable where the axes align (upright).
    With no turn of the pendulum about its arm relative to the head these are |φ_x|, |φ_y| of
    F 2.8–2.9 to third order in the tilt; a relative turn ψ about the arm enters both at first
    order (y ≈ √(φ² + ψ²)). The package's otolith output is :func:`otolith_angles` (F 2.8–2.9)."""
    R = jnp.asarray(R_H_S_)
    e = jnp.eye(3)

    def angle(k):
        c = jnp.cross(e[k], R[..., :, k])
        return jnp.arcsin(jnp.clip(jnp.linalg.norm(c, axis=-1), 0.0, 1.0))

    return jnp.stack([angle(1), angle(0)], -1)


def energy_J(x: PendulumState, p: PendulumParams):
    """Mechanical energy in a still frame (pivot at rest): kinetic plus gravitational potential."""
    w = x.omega_S_rad_s
    kinetic = 0.5 * jnp.sum(p.J_pivot_S * w * w)
    potential = -p.m_kg * gravity_I() @ (x.R_I_S @ com_arm_S(p))
    return kinetic + potential


def rest_orientation(up_H, R_I_H):
    """Pendulum orientation R_IS whose z axis (mass → pivot) is along ``up_H`` (head frame).

    ``up_H`` is the gravito-inertial up, ``−(g − a_P)``, in the head frame (any length). Of the
    frames with that z axis, the one reached from the head frame by the smallest rotation is taken,
    so the pendulum's yaw follows the head's.
    """
    up_H = up_H / jnp.linalg.norm(up_H)
    ez = jnp.array([0.0, 0.0, 1.0])
    axis = jnp.cross(ez, up_H)
    angle = so3.angle_between_unit_vectors(ez, up_H)
    n = jnp.linalg.norm(axis)
    rotvec = jnp.where(n > 1e-15, axis / jnp.where(n > 1e-15, n, 1.0) * angle, jnp.zeros(3))
    R_H_S_ = so3.exp(rotvec)
    return R_I_H @ R_H_S_


def rest_state(head: HeadMotion, p: PendulumParams) -> PendulumState:
    """At rest relative to the head, along the gravito-inertial vertical of ``head``.

    The axis of S points along ``−(g_I − a_P_I)`` (up when the pivot is still); its angular velocity
    equals the head's.
    """
    up_I = -(gravity_I() - pivot_acceleration_I(head, p))
    up_H = head.R_I_B.T @ up_I
    R_I_S = rest_orientation(up_H, head.R_I_B)
    omega_S = R_I_S.T @ (head.R_I_B @ head.omega_B_rad_s)
    return PendulumState(R_I_S=R_I_S, omega_S_rad_s=omega_S)


@model_dataclass
class Pendulum(RotationAndRate):
    """One otolith pendulum as a model value: ``ẋ = f(x, u)`` with ``u`` the head's
    :class:`RigidMotion` (the pivot sits at ``params.pivot_H_m`` on that head), ``y`` the otolith
    angles (φ_x, φ_y) of F 2.8–2.9 (rad). ``params`` are used resolved."""

    params: PendulumParams

    def dynamics(self, x: PendulumState, u: RigidMotion) -> PendulumState:
        return dynamics(x, u, self.params.resolved())

    def angles(self, x: PendulumState, R_I_H):
        """(φ_x, φ_y) of F 2.8–2.9 seen from a head at ``R_I_H``."""
        return otolith_angles(R_H_S(x, R_I_H))

    def output(self, x: PendulumState, u: RigidMotion):
        return self.angles(x, u.R_I_B)

    def rest_state(self, u: RigidMotion) -> PendulumState:
        """At rest relative to the head moving as ``u``, along its pivot's gravito-inertial
        vertical."""
        return rest_state(u, self.params.resolved())

    def energy_J(self, x: PendulumState):
        """Mechanical energy in a still frame (:func:`energy_J`)."""
        return energy_J(x, self.params.resolved())
