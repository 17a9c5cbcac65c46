"""Planar head (platform) carrying a damped pendulum (otolith / inclinometer), in one vertical plane.

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
"""

from __future__ import annotations

from typing import NamedTuple

import jax.numpy as jnp

from verticality.params import G_M_S2


class PlanarParams(NamedTuple):
    m_kg: float = 0.05
    l_m: float = 0.1
    J_kg_m2: float = 0.05 * 0.1**2  # pendulum inertia about the pivot
    beta_Nms: float = 0.005
    K_kg_m2: float = 100 * 0.05 * 0.1**2  # head (platform) inertia
    g_m_s2: float = G_M_S2


class PlanarState(NamedTuple):
    theta_S_rad: jnp.ndarray
    omega_S_rad_s: jnp.ndarray
    theta_H_rad: jnp.ndarray
    omega_H_rad_s: jnp.ndarray


class PlanarInput(NamedTuple):
    tau_Nm: jnp.ndarray  # torque on the head about x
    a_h_I_m_s2: jnp.ndarray  # pivot acceleration, horizontal (frame I)
    a_z_I_m_s2: jnp.ndarray  # pivot acceleration, vertical (frame I), gravity excluded


def pendulum_angular_acceleration(theta_S, omega_S, omega_H, a_h_I, a_z_I, p: PlanarParams):
    gravito = -p.m_kg * p.l_m * ((p.g_m_s2 + a_z_I) * jnp.sin(theta_S) + a_h_I * jnp.cos(theta_S))
    return (gravito - p.beta_Nms * (omega_S - omega_H)) / p.J_kg_m2


def dynamics(x: PlanarState, u: PlanarInput, p: PlanarParams) -> PlanarState:
    """Head driven by torque (the actuated platform)."""
    return PlanarState(
        theta_S_rad=x.omega_S_rad_s,
        omega_S_rad_s=pendulum_angular_acceleration(
            x.theta_S_rad, x.omega_S_rad_s, x.omega_H_rad_s, u.a_h_I_m_s2, u.a_z_I_m_s2, p),
        theta_H_rad=x.omega_H_rad_s,
        omega_H_rad_s=u.tau_Nm / p.K_kg_m2,
    )


def inclinometer_reading(x: PlanarState):
    """Pendulum angle relative to the head (F 2.8 in the plane; P11's measured tilt)."""
    return x.theta_S_rad - x.theta_H_rad


def head_frame_to_inertial(a_h_H, a_z_H, theta_H):
    """Head-frame acceleration components (h, z) to frame I."""
    c, s = jnp.cos(theta_H), jnp.sin(theta_H)
    return c * a_h_H - s * a_z_H, s * a_h_H + c * a_z_H


def rest_angle(a_h_I, a_z_I, g_m_s2: float = G_M_S2):
    """Pendulum angle at rest under a constant pivot acceleration: atan2(−a_h, g + a_z)."""
    return jnp.arctan2(-a_h_I, g_m_s2 + a_z_I)
