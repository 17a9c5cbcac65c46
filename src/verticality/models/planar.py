"""Planar head (platform) carrying a damped pendulum (otolith / inclinometer), in one vertical
plane.

The planar medial model of F p. 36, the platform/pendulum system of P11 §V.A and the sagittal
platform of F §4.4 are this one system. The plane is the head's y–z plane (rotations about x, the
coronal plane of F and P11); for the sagittal plane use the same equations with the horizontal axis
``h = −x`` (a rotation about y moves z towards +x).

Angles are rotations about x, measured from the world vertical: ``theta_S_rad`` of the pendulum
(0 when hanging straight down), ``theta_H_rad`` of the head (0 upright). With ``R_IS = Rx(θ_S)``
and ``R_IH = Rx(θ_H)`` this is the 3-D model of :mod:`verticality.models.pendulum` restricted to the
plane, and the otolith angle φ_x of F 2.8 is ``θ_S − θ_H`` (the inclinometer reading).

    J θ̈_S = −m l ((g + a_z) sin θ_S + a_h cos θ_S) − β (θ̇_S − θ̇_H)
    K θ̈_H = τ

with (a_h, a_z) the pivot's acceleration in frame I (gravity excluded). In head-frame components
the acceleration term is ``−m l (a_h^H cos(θ_S − θ_H) + a_z^H sin(θ_S − θ_H))``, F p. 36's form.

Three model values (:mod:`verticality.models.base`), one pendulum equation
(:func:`pendulum_angular_acceleration`):

* :class:`PlanarPendulum` — the pendulum alone in a frame whose motion is given
  (:class:`FrameMotion`); the liquid inclinometer of F 5.1–5.3
  (:mod:`verticality.models.inclinometer`);
* :class:`PlanarHead` — the head driven by a torque, carrying that pendulum (F p. 36, P11 §V.A,
  F §4.4); its pendulum is :attr:`PlanarHead.pendulum`;
* :class:`WithHeadFrameInput` — a model driven by the pivot acceleration in **head-frame**
  components (what an IMU on the head provides, F's ``ᴴa``), rotated into frame I with the head
  angle of the state: an input adapter, not a new model (P11's plant, F §4.4's platform);
* :class:`WithAccelerationState` — a :class:`WithHeadFrameInput` whose horizontal head-frame
  acceleration is a state (a random walk, ``ȧ_h = 0``) instead of an input: the internal model of
  an estimator that must infer the acceleration (the tilt–translation ambiguity, F §4.5).
"""

from __future__ import annotations

from typing import Any, NamedTuple

import jax.numpy as jnp

from verticality.core.constants import G_M_S2
from verticality.models.base import EuclideanState, model_dataclass


class PendulumState(NamedTuple):
    theta_rad: jnp.ndarray  # pendulum angle from the world vertical (0 hanging straight down)
    omega_rad_s: jnp.ndarray


class FrameMotion(NamedTuple):
    """The motion of the frame that carries a pendulum (the head, a platform, a sensor's case)."""

    theta_rad: jnp.ndarray  # frame tilt from the world vertical
    omega_rad_s: jnp.ndarray  # Ω of F 5.2: the frame's angular velocity (drags the damping)
    a_h_I_m_s2: jnp.ndarray  # pivot acceleration, horizontal (frame I)
    a_z_I_m_s2: jnp.ndarray  # pivot acceleration, vertical (frame I), gravity excluded


class PlanarState(NamedTuple):
    theta_S_rad: jnp.ndarray
    omega_S_rad_s: jnp.ndarray
    theta_H_rad: jnp.ndarray
    omega_H_rad_s: jnp.ndarray


class PlanarInput(NamedTuple):
    tau_Nm: jnp.ndarray  # torque on the head about x
    a_h_I_m_s2: jnp.ndarray  # pivot acceleration, horizontal (frame I)
    a_z_I_m_s2: jnp.ndarray  # pivot acceleration, vertical (frame I), gravity excluded


class HeadInput(NamedTuple):
    """Head torque and the pivot acceleration in head-frame components
    (:class:`WithHeadFrameInput`)."""

    tau_Nm: jnp.ndarray
    a_h_H_m_s2: jnp.ndarray  # horizontal head axis (y of the coronal plane)
    a_z_H_m_s2: jnp.ndarray  # head z axis; gravity excluded


def pendulum_angular_acceleration(theta_S, omega_S, omega_H, a_h_I, a_z_I, p):
    """θ̈_S of the damped pendulum (the one equation of this module); ``p`` has ``m_kg``, ``l_m``,
    ``J_kg_m2``, ``beta_Nms``, ``g_m_s2`` (a :class:`PlanarPendulum` or a :class:`PlanarHead`)."""
    gravito = -p.m_kg * p.l_m * ((p.g_m_s2 + a_z_I) * jnp.sin(theta_S) + a_h_I * jnp.cos(theta_S))
    return (gravito - p.beta_Nms * (omega_S - omega_H)) / p.J_kg_m2


def head_frame_to_inertial(a_h_H, a_z_H, theta_H):
    """Head-frame acceleration components (h, z) to frame I."""
    c, s = jnp.cos(theta_H), jnp.sin(theta_H)
    return c * a_h_H - s * a_z_H, s * a_h_H + c * a_z_H


def rest_angle(a_h_I, a_z_I, g_m_s2: float = G_M_S2):
    """Pendulum angle at rest under a constant pivot acceleration: atan2(−a_h, g + a_z)."""
    return jnp.arctan2(-a_h_I, g_m_s2 + a_z_I)


@model_dataclass
class PlanarPendulum(EuclideanState):
    """The damped pendulum in a moving frame: state :class:`PendulumState`, input
    :class:`FrameMotion`, output the reading relative to the frame ``θ − θ_frame`` (F 5.3)."""

    m_kg: Any = 0.05
    l_m: Any = 0.1
    J_kg_m2: Any = 0.05 * 0.1**2  # about the pivot
    beta_Nms: Any = 0.005
    g_m_s2: Any = G_M_S2

    def dynamics(self, x: PendulumState, u: FrameMotion) -> PendulumState:
        return PendulumState(x.omega_rad_s, pendulum_angular_acceleration(
            x.theta_rad, x.omega_rad_s, u.omega_rad_s, u.a_h_I_m_s2, u.a_z_I_m_s2, self))

    def output(self, x: PendulumState, u: FrameMotion):
        return jnp.atleast_1d(x.theta_rad - u.theta_rad)


@model_dataclass
class PlanarHead(EuclideanState):
    """Head (platform) of inertia ``K`` driven by a torque, carrying a :class:`PlanarPendulum`.

    State :class:`PlanarState`, input :class:`PlanarInput`, output the reading ``θ_S − θ_H``
    (shape (1,)). The pendulum's parameters are fields of the head, so that a parameter is one
    leaf; :attr:`pendulum` is the pendulum model they make."""

    m_kg: Any = 0.05
    l_m: Any = 0.1
    J_kg_m2: Any = 0.05 * 0.1**2  # pendulum inertia about the pivot
    beta_Nms: Any = 0.005
    K_kg_m2: Any = 100 * 0.05 * 0.1**2  # head (platform) inertia
    g_m_s2: Any = G_M_S2

    @property
    def pendulum(self) -> PlanarPendulum:
        return PlanarPendulum(self.m_kg, self.l_m, self.J_kg_m2, self.beta_Nms, self.g_m_s2)

    def dynamics(self, x: PlanarState, u: PlanarInput) -> PlanarState:
        pend = self.pendulum.dynamics(
            PendulumState(x.theta_S_rad, x.omega_S_rad_s),
            FrameMotion(x.theta_H_rad, x.omega_H_rad_s, u.a_h_I_m_s2, u.a_z_I_m_s2))
        return PlanarState(theta_S_rad=pend.theta_rad, omega_S_rad_s=pend.omega_rad_s,
                           theta_H_rad=x.omega_H_rad_s, omega_H_rad_s=u.tau_Nm / self.K_kg_m2)

    def output(self, x: PlanarState, u=None):
        return jnp.atleast_1d(inclinometer_reading(x))


@model_dataclass
class WithHeadFrameInput(EuclideanState):
    """``head`` (a :class:`PlanarHead`) driven by :class:`HeadInput`: the pivot acceleration in
    head-frame components, rotated into frame I with the state's head angle. Everything else —
    state, output, parameters — is the head's."""

    head: PlanarHead

    def dynamics(self, x: PlanarState, u: HeadInput) -> PlanarState:
        a_h_I, a_z_I = head_frame_to_inertial(u.a_h_H_m_s2, u.a_z_H_m_s2, x.theta_H_rad)
        return self.head.dynamics(x, PlanarInput(u.tau_Nm, a_h_I, a_z_I))

    def output(self, x: PlanarState, u=None):
        return self.head.output(x, u)


class AccelerationState(NamedTuple):
    """:class:`PlanarState` with the horizontal head-frame acceleration appended."""

    head: PlanarState
    a_h_H_m_s2: jnp.ndarray


class TorqueAndVertical(NamedTuple):
    """The inputs left to :class:`WithAccelerationState`: head torque and the vertical head-frame
    acceleration (measured by the saccule, F §3.2)."""

    tau_Nm: jnp.ndarray
    a_z_H_m_s2: jnp.ndarray


@model_dataclass
class WithAccelerationState(EuclideanState):
    """``model`` (a :class:`WithHeadFrameInput`) with its horizontal head-frame acceleration as a
    state: constant (``ȧ_h = 0``; an estimator adds the random walk as process noise), or with
    ``a_decay_1_s = 1/τ > 0`` decaying towards zero (``ȧ_h = −a_h/τ``; with process noise a
    first-order Gauss–Markov acceleration: zero on average, as for a head that does not travel
    off). State :class:`AccelerationState`, input :class:`TorqueAndVertical`, output the model's."""

    model: WithHeadFrameInput
    a_decay_1_s: Any = 0.0

    def dynamics(self, x: AccelerationState, u: TorqueAndVertical) -> AccelerationState:
        d = self.model.dynamics(x.head, HeadInput(u.tau_Nm, x.a_h_H_m_s2, u.a_z_H_m_s2))
        return AccelerationState(d, -self.a_decay_1_s * x.a_h_H_m_s2)

    def output(self, x: AccelerationState, u=None):
        return self.model.output(x.head, u)


def inclinometer_reading(x: PlanarState):
    """Pendulum angle relative to the head (F 2.8 in the plane; P11's measured tilt)."""
    return x.theta_S_rad - x.theta_H_rad
