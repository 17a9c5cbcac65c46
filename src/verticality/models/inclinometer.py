"""Liquid inclinometer (Applied Geomechanics Model 900): pendulum model and identified model.

Two forms, F §5.1.3 and §5.2:

1. **Pendulum** (F eq. 5.1–5.3): the planar pendulum of :mod:`verticality.models.planar`
   (:class:`~verticality.models.planar.PlanarPendulum`, the one pendulum equation of the project)
   with the two ratios the thesis gives (F §4.4.3: ``g/l = 3943.8 s⁻²`` and
   ``β/(m l²) = 125.6 s⁻¹``, i.e. critically damped at 10 Hz); :func:`pendulum_from_ratios`
   builds it. Per unit inertia the equation reads::

       φ̇ = ω
       ω̇ = −(g/l + a_z/l) sin φ − (a_h/l) cos φ − β/(m l²) (ω − Ω)
       y  = φ − θ_frame                                           (reading relative to the vial)

   φ is the pendulum angle from the world vertical, Ω the frame's angular velocity and
   (a_h, a_z) the pivot acceleration in the world (gravity excluded), in the sign convention of
   :mod:`verticality.models.planar` (rotation about x, h the horizontal axis). F 5.2 as printed has
   ``+a_x cos φ/l + a_y sin φ/l``: the same equation with ``a_x = −a_h`` and ``a_y = −a_z`` (its
   axes point the other way; with a_y upward a ``+`` sign would weaken gravity under an upward
   push, which is unphysical). Only the ratios matter; the mass is a free scale.

2. **Identified** second-order system (F §5.2: ``J_s = 0.0015``, ``b_s = 0.3776``, ``k_s = 5.629``),
   :class:`IdentifiedInclinometer`. The thesis gives only the three numbers. Reading: the reading
   ``y`` is dragged towards the apparent (gravito-inertial) tilt ψ of the frame through a
   unit-DC-gain low-pass::

       J_s ÿ + b_s ẏ + k_s y = k_s ψ,     ψ = θ + atan2(a_h, g + a_z)

   (θ the frame's tilt, (a_h, a_z) its pivot acceleration, world frame). This is the behaviour F
   describes in Fig. 5.7 ("inclinometer measurements lagged behind the encoder measurements"). Its
   poles are −15.9 and −235.8 rad/s (ζ = 2.05, ω_n = 61.3 rad/s ≈ 9.8 Hz, the 10 Hz of §4.4).

Both forms take the frame's motion (:class:`~verticality.models.planar.FrameMotion`) as input.
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

import jax.numpy as jnp

from verticality.core.constants import G_M_S2
from verticality.core.errors import InputError
from verticality.models.base import EuclideanState, model_dataclass
from verticality.models.planar import FrameMotion, PlanarPendulum

F44_G_OVER_L_S2 = 3943.8  # F §4.4.3: 10 Hz vial
F44_BETA_OVER_ML2_S = 125.6  # F §4.4.3: critically damped


def pendulum_from_ratios(g_over_l_s2: float = F44_G_OVER_L_S2,
                         beta_over_ml2_s: float = F44_BETA_OVER_ML2_S, m_kg: float = 0.01,
                         g_m_s2: float = G_M_S2) -> PlanarPendulum:
    """The pendulum with stiffness ``g/l`` and damping ``β/(m l²)`` per inertia (F 5.1–5.2);
    ``l = g/(g/l)``, ``J = m l²``; the defaults are F §4.4.3's 10 Hz critically damped vial."""
    if not g_over_l_s2 > 0:
        raise InputError(f"g/l must be positive, got {g_over_l_s2}")
    l_m = g_m_s2 / g_over_l_s2
    J = m_kg * l_m**2
    return PlanarPendulum(m_kg=m_kg, l_m=l_m, J_kg_m2=J, beta_Nms=beta_over_ml2_s * J,
                          g_m_s2=g_m_s2)


class IdentifiedInclinometerState(NamedTuple):
    y_rad: jnp.ndarray  # the reading
    ydot_rad_s: jnp.ndarray


def apparent_tilt(theta_rad, a_h_I_m_s2, a_z_I_m_s2=0.0, g_m_s2: float = G_M_S2):
    """ψ = θ + atan2(a_h, g + a_z): the tilt a still inclinometer would read under that
    acceleration."""
    return theta_rad + jnp.arctan2(a_h_I_m_s2, g_m_s2 + a_z_I_m_s2)


@model_dataclass
class IdentifiedInclinometer(EuclideanState):
    """F §5.2 identified 2nd-order model of the inclinometer (per axis): state
    :class:`IdentifiedInclinometerState`, input :class:`~verticality.models.planar.FrameMotion`,
    output the reading ``y``."""

    J_s: Any = 0.0015
    b_s: Any = 0.3776
    k_s: Any = 5.629
    g_m_s2: Any = G_M_S2

    def dynamics(self, x: IdentifiedInclinometerState,
                 u: FrameMotion) -> IdentifiedInclinometerState:
        """``J_s ÿ + b_s ẏ + k_s y = k_s ψ`` (F §5.2, input reading in the module docstring)."""
        psi = apparent_tilt(u.theta_rad, u.a_h_I_m_s2, u.a_z_I_m_s2, self.g_m_s2)
        ydd = (self.k_s * (psi - x.y_rad) - self.b_s * x.ydot_rad_s) / self.J_s
        return IdentifiedInclinometerState(x.ydot_rad_s, ydd)

    def output(self, x: IdentifiedInclinometerState, u=None):
        return jnp.atleast_1d(x.y_rad)


def natural_frequency_rad_s(stiffness_per_inertia: float) -> float:
    """ω_n = √(k/J) (or √(g/l) for the pendulum)."""
    if stiffness_per_inertia <= 0:
        raise InputError(f"stiffness per inertia must be positive, got {stiffness_per_inertia}")
    return math.sqrt(stiffness_per_inertia)


def damping_ratio(damping_per_inertia: float, stiffness_per_inertia: float) -> float:
    """ζ = (b/J) / (2 √(k/J))."""
    return damping_per_inertia / (2.0 * natural_frequency_rad_s(stiffness_per_inertia))


def identified_as_pendulum(p: IdentifiedInclinometer) -> PlanarPendulum:
    """The pendulum with the identified model's small-angle stiffness and damping per inertia."""
    if not p.J_s > 0:
        raise InputError(f"J_s must be positive, got {p.J_s}")
    return pendulum_from_ratios(p.k_s / p.J_s, p.b_s / p.J_s, g_m_s2=p.g_m_s2)
