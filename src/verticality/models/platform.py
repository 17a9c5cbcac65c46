"""The experimental platforms of F: the §4.4 sagittal platform and the ch. 5 gimbal (per axis).

**F §4.4.3 sagittal platform** (:func:`f44_platform`). One tilt of a platform (inertia
``J_h = 1e-4 kg·m²``) carrying the 10 Hz critically damped liquid inclinometer: the
:class:`~verticality.models.planar.PlanarHead` whose pendulum is
:func:`~verticality.models.inclinometer.pendulum_from_ratios` (``g/l = 3943.8 s⁻²``,
``β/(m l²) = 125.6 s⁻¹``; only these ratios matter, the mass is set to 10 g, ``l = 2.49 mm``).

**F ch. 5 gimbal** (:class:`PlatformAxis`). Each of the two decoupled axes was identified as
``J θ̈ + b θ̇ = u`` (F §5.2: pitch J1 = 0.008 kg·m², b1 = 1.35 N·m·s; roll J2 = 0.0006 kg·m²,
b2 = 0.137 N·m·s; u the amplifier reference, in N·m-equivalent units). F identified b with the base
still, so F does not fix how much of it acts on the joint's velocity (a swinging base then drags
the platform) and how much on the platform's own rate; ``base_drag_share`` s is that split (a
reading, :mod:`verticality.experiments.platform`)::

    J ω̇ = u − b (ω − s ω_base),   θ̇ = ω                    (θ, ω: platform tilt/rate in the world)

The inclinometer on it is the identified 2nd-order model
(:class:`~verticality.models.inclinometer.IdentifiedInclinometer`), a component of the axis, driven
by the platform's motion (apparent tilt ``θ + atan2(a_h, g)``).
"""

from __future__ import annotations

from typing import Any, NamedTuple

import jax.numpy as jnp

from verticality.core.constants import G_M_S2
from verticality.models.base import EuclideanState, model_dataclass
from verticality.models.inclinometer import (
    F44_BETA_OVER_ML2_S,
    F44_G_OVER_L_S2,
    IdentifiedInclinometer,
    IdentifiedInclinometerState,
    pendulum_from_ratios,
)
from verticality.models.planar import FrameMotion, PlanarHead


def f44_platform(g_over_l_s2: float = F44_G_OVER_L_S2, beta_over_ml2_s: float = F44_BETA_OVER_ML2_S,
                 J_h_kg_m2: float = 1e-4, m_kg: float = 0.01, g_m_s2: float = G_M_S2) -> PlanarHead:
    """F §4.4.3's sagittal platform + liquid inclinometer as a :class:`PlanarHead`."""
    pend = pendulum_from_ratios(g_over_l_s2, beta_over_ml2_s, m_kg, g_m_s2)
    return PlanarHead(m_kg=pend.m_kg, l_m=pend.l_m, J_kg_m2=pend.J_kg_m2, beta_Nms=pend.beta_Nms,
                      K_kg_m2=J_h_kg_m2, g_m_s2=g_m_s2)


class AxisState(NamedTuple):
    theta_rad: jnp.ndarray  # platform tilt from the world vertical
    omega_rad_s: jnp.ndarray
    y_rad: jnp.ndarray  # inclinometer reading
    ydot_rad_s: jnp.ndarray


class AxisInput(NamedTuple):
    u: jnp.ndarray  # amplifier reference (torque-equivalent)
    a_h_I_m_s2: jnp.ndarray  # linear acceleration of the platform centre along the axis' horizontal
    # base-link angular velocity about this axis (unknown to the observer)
    omega_base_rad_s: jnp.ndarray = 0.0


@model_dataclass
class PlatformAxis(EuclideanState):
    """One identified gimbal axis, ``J θ̈ + b (θ̇ − s θ̇_base) = u`` (F §5.2), carrying its
    inclinometer: state :class:`AxisState`, input :class:`AxisInput`, output the reading ``y``.
    ``base_drag_share`` s: the share of b through which the base drags the platform (1: all of it
    acts on the joint's velocity)."""

    J_kg_m2: Any
    b_Nms: Any
    inclinometer: IdentifiedInclinometer = IdentifiedInclinometer()
    base_drag_share: Any = 1.0

    def dynamics(self, x: AxisState, u: AxisInput) -> AxisState:
        omega_dot = (u.u - self.b_Nms * (x.omega_rad_s - self.base_drag_share
                                         * u.omega_base_rad_s)) / self.J_kg_m2
        s = self.inclinometer.dynamics(IdentifiedInclinometerState(x.y_rad, x.ydot_rad_s),
                                       FrameMotion(x.theta_rad, x.omega_rad_s, u.a_h_I_m_s2, 0.0))
        return AxisState(x.omega_rad_s, omega_dot, s.y_rad, s.ydot_rad_s)

    def output(self, x: AxisState, u=None):
        return jnp.atleast_1d(x.y_rad)


PITCH = PlatformAxis(J_kg_m2=0.008, b_Nms=1.35)
ROLL = PlatformAxis(J_kg_m2=0.0006, b_Nms=0.137)
