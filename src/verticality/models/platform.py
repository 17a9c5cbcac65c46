"""The experimental platforms of F: the §4.4 sagittal platform and the ch. 5 gimbal (per axis).

**F §4.4.3 sagittal platform.** One tilt of a platform (inertia ``J_h = 1e-4 kg·m²``) carrying the
10 Hz critically damped liquid inclinometer; this is :mod:`verticality.models.planar` with
``g/l = 3943.8 s⁻²``, ``β/(m l²) = 125.6 s⁻¹``. Only these ratios matter for the pendulum, so the
mass is set to 10 g (``l = g/3943.8 = 2.49 mm``, ``J = m l²``); :func:`f44_params` builds them.

**F ch. 5 gimbal.** Each of the two decoupled axes was identified as ``J θ̈ + b θ̇ = u`` (F §5.2:
pitch J1 = 0.008 kg·m², b1 = 1.35 N·m·s; roll J2 = 0.0006 kg·m², b2 = 0.137 N·m·s; u the amplifier
reference, in N·m-equivalent units). On a moving base the damping (motor back-EMF, cable and bearing
friction) acts on the joint velocity, so a swinging base drags the platform (our reading)::

    J ω̇ = u − b (ω − ω_base),   θ̇ = ω                      (θ, ω: platform tilt/rate in the world)

The inclinometer on it is the identified 2nd-order model of
:mod:`verticality.models.inclinometer`, driven by the apparent tilt ``θ + atan2(a_h, g)``.
"""

from __future__ import annotations

from typing import NamedTuple

import jax.numpy as jnp

from verticality.models import inclinometer as incl
from verticality.models.planar import PlanarParams
from verticality.params import G_M_S2


def f44_params(g_over_l_s2: float = 3943.8, beta_over_ml2_s: float = 125.6,
               J_h_kg_m2: float = 1e-4, m_kg: float = 0.01, g_m_s2: float = G_M_S2) -> PlanarParams:
    """:class:`PlanarParams` of F §4.4.3 (sagittal platform + liquid inclinometer)."""
    l_m = g_m_s2 / g_over_l_s2
    J = m_kg * l_m**2
    return PlanarParams(m_kg=m_kg, l_m=l_m, J_kg_m2=J, beta_Nms=beta_over_ml2_s * J,
                        K_kg_m2=J_h_kg_m2, g_m_s2=g_m_s2)


class AxisParams(NamedTuple):
    """One identified gimbal axis, ``J θ̈ + b θ̇ = u`` (F §5.2), with its inclinometer axis."""

    J_kg_m2: float
    b_Nms: float
    J_s: float = 0.0015
    b_s: float = 0.3776
    k_s: float = 5.629
    g_m_s2: float = G_M_S2

    @property
    def inclinometer(self) -> incl.IdentifiedInclinometerParams:
        return incl.IdentifiedInclinometerParams(self.J_s, self.b_s, self.k_s, self.g_m_s2)


PITCH = AxisParams(J_kg_m2=0.008, b_Nms=1.35)
ROLL = AxisParams(J_kg_m2=0.0006, b_Nms=0.137)


class AxisState(NamedTuple):
    theta_rad: jnp.ndarray  # platform tilt from the world vertical
    omega_rad_s: jnp.ndarray
    y_rad: jnp.ndarray  # inclinometer reading
    ydot_rad_s: jnp.ndarray


class AxisInput(NamedTuple):
    u: jnp.ndarray  # amplifier reference (torque-equivalent)
    a_h_I_m_s2: jnp.ndarray  # linear acceleration of the platform centre along the axis' horizontal
    omega_base_rad_s: jnp.ndarray = 0.0  # base-link angular velocity about this axis (unknown to the observer)


def axis_dynamics(x: AxisState, u: AxisInput, p: AxisParams) -> AxisState:
    """Platform axis plus its inclinometer (module docstring)."""
    omega_dot = (u.u - p.b_Nms * (x.omega_rad_s - u.omega_base_rad_s)) / p.J_kg_m2
    psi = incl.apparent_tilt(x.theta_rad, u.a_h_I_m_s2, 0.0, p.g_m_s2)
    s = incl.identified_dynamics(incl.IdentifiedInclinometerState(x.y_rad, x.ydot_rad_s), psi,
                                 p.inclinometer)
    return AxisState(x.omega_rad_s, omega_dot, s.y_rad, s.ydot_rad_s)


def axis_reading(x: AxisState, u: AxisInput, p: AxisParams):
    """The inclinometer's output ``y``."""
    return x.y_rad
