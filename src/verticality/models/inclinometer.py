"""Liquid inclinometer (Applied Geomechanics Model 900): pendulum model and identified model.

Two forms, F §5.1.3 and §5.2:

1. **Pendulum** (F eq. 5.1–5.3), written per unit inertia so that only the two ratios the thesis
   gives are needed (F §4.4.3: ``g/l = 3943.8 s⁻²`` and ``β/(m l²) = 125.6 s⁻¹``, i.e. critically
   damped at 10 Hz)::

       φ̇ = ω
       ω̇ = −(g/l + a_z/l) sin φ − (a_h/l) cos φ − β/(m l²) (ω − Ω)
       y  = φ − θ_frame                                           (reading relative to the vial)

   φ is the pendulum angle from the world vertical and (a_h, a_z) the pivot acceleration in the
   world (gravity excluded), in the sign convention of :mod:`verticality.models.planar` (rotation
   about x, h the horizontal axis). F 5.2 as printed has ``+a_x cos φ/l + a_y sin φ/l``: the same
   equation with ``a_x = −a_h`` and ``a_y = −a_z`` (its axes point the other way; with a_y upward a
   ``+`` sign would weaken gravity under an upward push, which is unphysical).

2. **Identified** second-order system (F §5.2: ``J_s = 0.0015``, ``b_s = 0.3776``, ``k_s = 5.629``).
   The thesis gives only the three numbers. Reading: the reading ``y`` is dragged towards the
   apparent (gravito-inertial) tilt ψ of the platform through a unit-DC-gain low-pass::

       J_s ÿ + b_s ẏ + k_s y = k_s ψ,     ψ = θ + atan2(a_h, g + a_z)

   (θ the platform tilt, (a_h, a_z) its pivot acceleration, world frame). This is the behaviour F
   describes in Fig. 5.7 ("inclinometer measurements lagged behind the encoder measurements"). Its
   poles are −15.9 and −235.8 rad/s (ζ = 2.05, ω_n = 61.3 rad/s ≈ 9.8 Hz, the 10 Hz of §4.4).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import jax.numpy as jnp

from verticality.errors import InputError
from verticality.params import G_M_S2


class PendulumInclinometerParams(NamedTuple):
    """Per-unit-inertia pendulum (F 5.1–5.3); defaults are F §4.4.3's 10 Hz critically damped vial."""

    g_over_l_s2: float = 3943.8
    beta_over_ml2_s: float = 125.6
    g_m_s2: float = G_M_S2

    @property
    def l_m(self) -> float:
        return self.g_m_s2 / self.g_over_l_s2


class PendulumInclinometerState(NamedTuple):
    phi_rad: jnp.ndarray  # pendulum angle from the world vertical
    omega_rad_s: jnp.ndarray


class PendulumInclinometerInput(NamedTuple):
    omega_frame_rad_s: jnp.ndarray  # Ω of F 5.2: angular velocity of the sensor's frame
    a_h_I_m_s2: jnp.ndarray
    a_z_I_m_s2: jnp.ndarray


def pendulum_dynamics(x: PendulumInclinometerState, u: PendulumInclinometerInput,
                      p: PendulumInclinometerParams) -> PendulumInclinometerState:
    """F eq. 5.1–5.2 (signs as in the module docstring)."""
    gl = p.g_over_l_s2
    a_scale = gl / p.g_m_s2  # 1/l
    omega_dot = (-(gl + a_scale * u.a_z_I_m_s2) * jnp.sin(x.phi_rad)
                 - a_scale * u.a_h_I_m_s2 * jnp.cos(x.phi_rad)
                 - p.beta_over_ml2_s * (x.omega_rad_s - u.omega_frame_rad_s))
    return PendulumInclinometerState(x.omega_rad_s, omega_dot)


def pendulum_reading(x: PendulumInclinometerState, theta_frame_rad):
    """F eq. 5.3 on a tilted frame: the pendulum angle relative to the vial, ``φ − θ_frame``."""
    return x.phi_rad - theta_frame_rad


class IdentifiedInclinometerParams(NamedTuple):
    """F §5.2 identified 2nd-order model of the inclinometer (per axis)."""

    J_s: float = 0.0015
    b_s: float = 0.3776
    k_s: float = 5.629
    g_m_s2: float = G_M_S2


class IdentifiedInclinometerState(NamedTuple):
    y_rad: jnp.ndarray  # the reading
    ydot_rad_s: jnp.ndarray


def apparent_tilt(theta_rad, a_h_I_m_s2, a_z_I_m_s2=0.0, g_m_s2: float = G_M_S2):
    """ψ = θ + atan2(a_h, g + a_z): the tilt a still inclinometer would read under that acceleration."""
    return theta_rad + jnp.arctan2(a_h_I_m_s2, g_m_s2 + a_z_I_m_s2)


def identified_dynamics(x: IdentifiedInclinometerState, psi_rad,
                        p: IdentifiedInclinometerParams) -> IdentifiedInclinometerState:
    """``J_s ÿ + b_s ẏ + k_s y = k_s ψ`` (F §5.2, input reading in the module docstring)."""
    ydd = (p.k_s * (psi_rad - x.y_rad) - p.b_s * x.ydot_rad_s) / p.J_s
    return IdentifiedInclinometerState(x.ydot_rad_s, ydd)


def natural_frequency_rad_s(stiffness_per_inertia: float) -> float:
    """ω_n = √(k/J) (or √(g/l) for the pendulum)."""
    if stiffness_per_inertia <= 0:
        raise InputError(f"stiffness per inertia must be positive, got {stiffness_per_inertia}")
    return math.sqrt(stiffness_per_inertia)


def damping_ratio(damping_per_inertia: float, stiffness_per_inertia: float) -> float:
    """ζ = (b/J) / (2 √(k/J))."""
    return damping_per_inertia / (2.0 * natural_frequency_rad_s(stiffness_per_inertia))


def identified_as_pendulum(p: IdentifiedInclinometerParams) -> PendulumInclinometerParams:
    """The pendulum with the identified model's small-angle stiffness and damping per inertia."""
    if p.J_s <= 0:
        raise InputError(f"J_s must be positive, got {p.J_s}")
    return PendulumInclinometerParams(g_over_l_s2=p.k_s / p.J_s, beta_over_ml2_s=p.b_s / p.J_s,
                                      g_m_s2=p.g_m_s2)
