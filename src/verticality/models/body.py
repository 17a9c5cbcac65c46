"""Sagittal multi-segment body on an inclined, moving ground (T Fig. 1, eq. 4, 16).

Two bodies, both model values (:mod:`verticality.models.base`) with the vestibular sensors
(gyro + accelerometer / canals + otoliths) on the top segment:

* :class:`SingleSegmentBody` — the **single inverted pendulum** (PostuRob, T §III.A): the lean
  ``φ`` about the ankle; sensors at ``h = 0.325 m`` above the ankle (T §III).
* :class:`TwoSegmentBody` — **two segments on a platform** (PostuRob II / human, T Fig. 1):
  platform inclination ``θ1(t)`` (prescribed; it rotates about the ankle axis, so the ankle stays
  fixed in space), ankle ``θ2`` (legs relative to the platform), hip ``θ3`` (trunk relative to the
  legs). Absolute angles from the vertical: legs ``a1 = θ1 + θ2``, trunk ``φ = a2 = θ1 + θ2 + θ3``;
  positive = forward lean.

Dynamics (Lagrange, absolute angles; ``M11 = m1 c1² + I1 + m2 L2²``, ``M22 = m2 c2² + I2``,
``M12 = m2 L2 c2``, ``s = sin(a1 − a2)``, ``c = cos(a1 − a2)``):

    M11 ä1 + M12 c ä2 + M12 s ȧ2² = g (m1 c1 + m2 L2) sin a1 + τ2 − τ3
    M12 c ä1 + M22 ä2 − M12 s ȧ1² = g m2 c2 sin a2 + τ3

with τ2 the ankle torque (platform on legs) and τ3 the hip torque (legs on trunk). In joint
coordinates ``θ̈2 = ä1 − θ̈1``, ``θ̈3 = ä2 − ä1``: the ground enters through gravity (θ1) and the
frame acceleration (θ̈1), giving the disturbance vector ``F_d = (θ1, θ̇1, θ̈1)`` of T eq. 16, the
second part of the model's input (:class:`GroundInput`).

**Accelerometer sign.** The tangential reading is the specific force on the trunk's x axis, with
the axis chosen so that a forward lean reads ``+g sin φ`` (T eq. 5):
``a_x = g sin a2 − L2 (ä1 cos(a1 − a2) − ȧ1² sin(a1 − a2)) − Lv ä2``. Linearized, this is
``g φ − L2 ä1 − Lv ä2``: T eq. 4 prints the acceleration terms with a + sign, which no
accelerometer produces together with ``+g φ`` (a forward angular acceleration and a forward lean
load the proof mass in opposite directions); we keep the physics, and the filter of T eq. 5 treats
that term as noise either way.

T eq. 16 is :func:`verticality.models.linearize.linearize` of :class:`TwoSegmentBody` at upright:
its B has the columns ``(τ2, τ3, θ1, θ̇1, θ̈1)`` — T's B and N side by side — and its D the
columns of T's D and E (:data:`TWO_SEGMENT_INPUTS`).
"""

from __future__ import annotations

from typing import Any, NamedTuple

import jax.numpy as jnp

from verticality.core.constants import G_M_S2
from verticality.models.base import EuclideanState, model_dataclass

# --------------------------------------------------------------------------- single segment


class LeanState(NamedTuple):
    phi_rad: jnp.ndarray  # lean about the ankle, forward positive
    phi_dot_rad_s: jnp.ndarray


@model_dataclass
class SingleSegmentBody(EuclideanState):
    """PostuRob as a single inverted pendulum (T §III): ``J φ̈ = m g c sin φ + τ``; state
    :class:`LeanState`, input the ankle torque τ, output the noise-free ``(ω_g, a_x)``."""

    m_kg: Any = 60.0
    com_m: Any = 0.9  # ankle to centre of mass
    J_ankle_kg_m2: Any = 60.0 * 0.9**2 + 10.0  # about the ankle
    sensor_m: Any = 0.325  # ankle to gyro/accelerometer (T §III)
    g_m_s2: Any = G_M_S2

    def lean_acceleration(self, phi_rad, tau_Nm):
        return ((self.m_kg * self.g_m_s2 * self.com_m * jnp.sin(phi_rad) + tau_Nm)
                / self.J_ankle_kg_m2)

    def dynamics(self, x: LeanState, u) -> LeanState:
        return LeanState(x.phi_dot_rad_s, self.lean_acceleration(x.phi_rad, u))

    def sensors(self, phi_rad, phi_dot_rad_s, phi_ddot_rad_s2):
        """Noise-free ``(ω_g, a_x)`` of a lean with these kinematics: ``ω = φ̇``,
        ``a_x = g sin φ − h φ̈`` (see the module doc)."""
        return phi_dot_rad_s, self.g_m_s2 * jnp.sin(phi_rad) - self.sensor_m * phi_ddot_rad_s2

    def output(self, x: LeanState, u):
        w, a = self.sensors(x.phi_rad, x.phi_dot_rad_s, self.lean_acceleration(x.phi_rad, u))
        return jnp.stack([w, a])


POSTUROB = SingleSegmentBody()
"""The default single-segment body (PostuRob, T §III)."""


# --------------------------------------------------------------------------- two segments on ground


class GroundInput(NamedTuple):
    """Input of :class:`TwoSegmentBody`: the joint torques and the ground motion (T eq. 16)."""

    tau_Nm: jnp.ndarray  # (τ2, τ3): ankle, hip
    F_d: jnp.ndarray  # (θ1, θ̇1, θ̈1): platform inclination and its derivatives


TWO_SEGMENT_STATES = ("theta2", "theta3", "theta2_dot", "theta3_dot")
TWO_SEGMENT_INPUTS = ("tau2", "tau3", "theta1", "theta1_dot", "theta1_ddot")
TWO_SEGMENT_OUTPUTS = ("theta2", "theta3", "theta2_dot", "theta3_dot", "omega", "a_x")


@model_dataclass
class TwoSegmentBody(EuclideanState):
    """Legs + trunk (with head and arms) of a 75 kg, 1.75 m adult (Winter's anthropometric tables:
    legs ≈ 32 %, trunk-head-arms ≈ 68 % of body mass, ankle–hip 0.88 m; PostuRob II has the same
    mass range and proportions). Inertias are about each segment's centre of mass.

    State ``x = (θ2, θ3, θ̇2, θ̇3)`` (array (4,)), input :class:`GroundInput`, output
    ``y_e = (θ2, θ3, θ̇2, θ̇3, ω, a_x)`` of T eq. 23 (noise-free; ``ω = φ̇`` of the trunk)."""

    m_legs_kg: Any = 24.0
    L2_m: Any = 0.88  # ankle to hip
    c_legs_m: Any = 0.50  # ankle to legs' CoM
    I_legs_kg_m2: Any = 1.6
    m_trunk_kg: Any = 51.0
    c_trunk_m: Any = 0.32  # hip to trunk CoM
    I_trunk_kg_m2: Any = 3.0
    Lv_m: Any = 0.70  # hip to vestibular organ (T eq. 4)
    g_m_s2: Any = G_M_S2

    def mass_terms(self):
        M11 = self.m_legs_kg * self.c_legs_m**2 + self.I_legs_kg_m2 + self.m_trunk_kg * self.L2_m**2
        M22 = self.m_trunk_kg * self.c_trunk_m**2 + self.I_trunk_kg_m2
        M12 = self.m_trunk_kg * self.L2_m * self.c_trunk_m
        return M11, M22, M12

    def absolute_accelerations(self, a, a_dot, tau_Nm):
        """``(ä1, ä2)`` of the absolute legs/trunk angles for joint torques ``(τ2, τ3)``."""
        M11, M22, M12 = self.mass_terms()
        s, c = jnp.sin(a[0] - a[1]), jnp.cos(a[0] - a[1])
        M = jnp.array([[M11, M12 * c], [M12 * c, M22]])
        g = self.g_m_s2
        rhs = jnp.array([
            g * (self.m_legs_kg * self.c_legs_m + self.m_trunk_kg * self.L2_m) * jnp.sin(a[0])
            + tau_Nm[0] - tau_Nm[1] - M12 * s * a_dot[1] ** 2,
            g * self.m_trunk_kg * self.c_trunk_m * jnp.sin(a[1]) + tau_Nm[1]
            + M12 * s * a_dot[0] ** 2,
        ])
        return jnp.linalg.solve(M, rhs)

    def energy(self, a, a_dot):
        """Kinetic + potential energy in absolute coordinates (conserved for τ = 0, ground
        still)."""
        M11, M22, M12 = self.mass_terms()
        T = (0.5 * M11 * a_dot[0] ** 2 + 0.5 * M22 * a_dot[1] ** 2
             + M12 * jnp.cos(a[0] - a[1]) * a_dot[0] * a_dot[1])
        V = self.g_m_s2 * ((self.m_legs_kg * self.c_legs_m + self.m_trunk_kg * self.L2_m)
                           * jnp.cos(a[0])
                           + self.m_trunk_kg * self.c_trunk_m * jnp.cos(a[1]))
        return T + V

    @staticmethod
    def absolute_angles(x, d):
        """Absolute angles and rates ``(a, ȧ)`` of legs and trunk from the joints and F_d."""
        a = jnp.array([d[0] + x[0], d[0] + x[0] + x[1]])
        a_dot = jnp.array([d[1] + x[2], d[1] + x[2] + x[3]])
        return a, a_dot

    def dynamics(self, x, u: GroundInput):
        a, a_dot = self.absolute_angles(x, u.F_d)
        acc = self.absolute_accelerations(a, a_dot, u.tau_Nm)
        return jnp.array([x[2], x[3], acc[0] - u.F_d[2], acc[1] - acc[0]])

    def output(self, x, u: GroundInput):
        a, a_dot = self.absolute_angles(x, u.F_d)
        acc = self.absolute_accelerations(a, a_dot, u.tau_Nm)
        s, c = jnp.sin(a[0] - a[1]), jnp.cos(a[0] - a[1])
        a_x = (self.g_m_s2 * jnp.sin(a[1]) - self.L2_m * (acc[0] * c - a_dot[0] ** 2 * s)
               - self.Lv_m * acc[1])
        return jnp.array([x[0], x[1], x[2], x[3], a_dot[1], a_x])


HUMAN_TWO_SEGMENT = TwoSegmentBody()
"""The default two-segment body (75 kg adult)."""


def upright():
    """``(x0, u0)``: the operating point of T eq. 16 (upright, at rest, no torque, level still
    ground)."""
    return jnp.zeros(4), GroundInput(jnp.zeros(2), jnp.zeros(3))
