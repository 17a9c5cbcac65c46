"""Sagittal multi-segment body on an inclined, moving ground (T Fig. 1, eq. 4, 16).

Two bodies, both with the vestibular sensors (gyro + accelerometer / canals + otoliths) on the top
segment:

* **single inverted pendulum** (PostuRob, T §III.A): the lean ``φ`` about the ankle; sensors at
  ``h = 0.325 m`` above the ankle (T §III). :func:`single_sensors` gives the readings.
* **two segments on a platform** (PostuRob II / human, T Fig. 1): platform inclination ``θ1(t)``
  (prescribed; it rotates about the ankle axis, so the ankle stays fixed in space), ankle ``θ2``
  (legs relative to the platform), hip ``θ3`` (trunk relative to the legs). Absolute angles from the
  vertical: legs ``a1 = θ1 + θ2``, trunk ``φ = a2 = θ1 + θ2 + θ3``; positive = forward lean.

Dynamics (Lagrange, absolute angles; ``M11 = m1 c1² + I1 + m2 L2²``, ``M22 = m2 c2² + I2``,
``M12 = m2 L2 c2``, ``s = sin(a1 − a2)``, ``c = cos(a1 − a2)``):

    M11 ä1 + M12 c ä2 + M12 s ȧ2² = g (m1 c1 + m2 L2) sin a1 + τ2 − τ3
    M12 c ä1 + M22 ä2 − M12 s ȧ1² = g m2 c2 sin a2 + τ3

with τ2 the ankle torque (platform on legs) and τ3 the hip torque (legs on trunk). In joint
coordinates ``θ̈2 = ä1 − θ̈1``, ``θ̈3 = ä2 − ä1``: the ground enters through gravity (θ1) and the
frame acceleration (θ̈1), giving the disturbance vector ``F_d = (θ1, θ̇1, θ̈1)`` of T eq. 16.

**Accelerometer sign.** The tangential reading is the specific force on the trunk's x axis, with
the axis chosen so that a forward lean reads ``+g sin φ`` (T eq. 5):
``a_x = g sin a2 − L2 (ä1 cos(a1 − a2) − ȧ1² sin(a1 − a2)) − Lv ä2``. Linearized, this is
``g φ − L2 ä1 − Lv ä2``: T eq. 4 prints the acceleration terms with a + sign, which no
accelerometer produces together with ``+g φ`` (a forward angular acceleration and a forward lean
load the proof mass in opposite directions); we keep the physics, and the filter of T eq. 5 treats
that term as noise either way.

Everything is written once in ``jax.numpy``; :func:`linearize` differentiates it (``jax.jacfwd``) at
upright into (A, B, N, C, D_u, D_d) of T eq. 16, exportable with :func:`to_statespace`.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from verticality.params import G_M_S2

# --------------------------------------------------------------------------- single segment


class SingleSegmentParams(NamedTuple):
    """PostuRob as a single inverted pendulum (T §III): sensors 0.325 m above the ankle."""

    m_kg: float = 60.0
    com_m: float = 0.9  # ankle to centre of mass
    J_ankle_kg_m2: float = 60.0 * 0.9**2 + 10.0  # about the ankle
    sensor_m: float = 0.325  # ankle to gyro/accelerometer (T §III)
    g_m_s2: float = G_M_S2


POSTUROB = SingleSegmentParams()
"""The default single-segment body (PostuRob, T §III)."""


def single_dynamics(phi_rad, phi_dot_rad_s, tau_Nm, p: SingleSegmentParams = POSTUROB):
    """``(φ̇, φ̈)`` of ``J φ̈ = m g c sin φ + τ`` (inverted pendulum about the ankle)."""
    return phi_dot_rad_s, (p.m_kg * p.g_m_s2 * p.com_m * jnp.sin(phi_rad) + tau_Nm) / p.J_ankle_kg_m2


def single_sensors(phi_rad, phi_dot_rad_s, phi_ddot_rad_s2, p: SingleSegmentParams = POSTUROB):
    """Noise-free ``(ω_g, a_x)`` at the sensor: ``ω = φ̇``, ``a_x = g sin φ − h φ̈`` (see module doc)."""
    return phi_dot_rad_s, p.g_m_s2 * jnp.sin(phi_rad) - p.sensor_m * phi_ddot_rad_s2


# --------------------------------------------------------------------------- two segments on ground


class TwoSegmentParams(NamedTuple):
    """Legs + trunk (with head and arms) of a 75 kg, 1.75 m adult (Winter's anthropometric tables:
    legs ≈ 32 %, trunk-head-arms ≈ 68 % of body mass, ankle–hip 0.88 m; PostuRob II has the same
    mass range and proportions). Inertias are about each segment's centre of mass."""

    m_legs_kg: float = 24.0
    L2_m: float = 0.88  # ankle to hip
    c_legs_m: float = 0.50  # ankle to legs' CoM
    I_legs_kg_m2: float = 1.6
    m_trunk_kg: float = 51.0
    c_trunk_m: float = 0.32  # hip to trunk CoM
    I_trunk_kg_m2: float = 3.0
    Lv_m: float = 0.70  # hip to vestibular organ (T eq. 4)
    g_m_s2: float = G_M_S2


HUMAN_TWO_SEGMENT = TwoSegmentParams()
"""The default two-segment body (75 kg adult)."""


def _mass_terms(p: TwoSegmentParams):
    M11 = p.m_legs_kg * p.c_legs_m**2 + p.I_legs_kg_m2 + p.m_trunk_kg * p.L2_m**2
    M22 = p.m_trunk_kg * p.c_trunk_m**2 + p.I_trunk_kg_m2
    M12 = p.m_trunk_kg * p.L2_m * p.c_trunk_m
    return M11, M22, M12


def absolute_accelerations(a, a_dot, tau_Nm, p: TwoSegmentParams):
    """``(ä1, ä2)`` of the absolute legs/trunk angles for joint torques ``(τ2, τ3)``."""
    M11, M22, M12 = _mass_terms(p)
    s, c = jnp.sin(a[0] - a[1]), jnp.cos(a[0] - a[1])
    M = jnp.array([[M11, M12 * c], [M12 * c, M22]])
    g = p.g_m_s2
    rhs = jnp.array([
        g * (p.m_legs_kg * p.c_legs_m + p.m_trunk_kg * p.L2_m) * jnp.sin(a[0])
        + tau_Nm[0] - tau_Nm[1] - M12 * s * a_dot[1] ** 2,
        g * p.m_trunk_kg * p.c_trunk_m * jnp.sin(a[1]) + tau_Nm[1] + M12 * s * a_dot[0] ** 2,
    ])
    return jnp.linalg.solve(M, rhs)


def energy(a, a_dot, p: TwoSegmentParams):
    """Kinetic + potential energy in absolute coordinates (conserved for τ = 0, ground still)."""
    M11, M22, M12 = _mass_terms(p)
    T = 0.5 * M11 * a_dot[0] ** 2 + 0.5 * M22 * a_dot[1] ** 2 + M12 * jnp.cos(a[0] - a[1]) * a_dot[0] * a_dot[1]
    V = p.g_m_s2 * ((p.m_legs_kg * p.c_legs_m + p.m_trunk_kg * p.L2_m) * jnp.cos(a[0])
                    + p.m_trunk_kg * p.c_trunk_m * jnp.cos(a[1]))
    return T + V


def two_segment_dynamics(t, x, u, d, p: TwoSegmentParams = HUMAN_TWO_SEGMENT):
    """``ẋ`` for ``x = (θ2, θ3, θ̇2, θ̇3)``, ``u = (τ2, τ3)``, ``d = F_d = (θ1, θ̇1, θ̈1)`` (T eq. 16)."""
    a = jnp.array([d[0] + x[0], d[0] + x[0] + x[1]])
    a_dot = jnp.array([d[1] + x[2], d[1] + x[2] + x[3]])
    acc = absolute_accelerations(a, a_dot, u, p)
    return jnp.array([x[2], x[3], acc[0] - d[2], acc[1] - acc[0]])


def two_segment_outputs(t, x, u, d, p: TwoSegmentParams = HUMAN_TWO_SEGMENT):
    """``y_e = (θ2, θ3, θ̇2, θ̇3, ω, a_x)`` of T eq. 23 (noise-free; ``ω = φ̇`` of the trunk)."""
    a = jnp.array([d[0] + x[0], d[0] + x[0] + x[1]])
    a_dot = jnp.array([d[1] + x[2], d[1] + x[2] + x[3]])
    acc = absolute_accelerations(a, a_dot, u, p)
    s, c = jnp.sin(a[0] - a[1]), jnp.cos(a[0] - a[1])
    a_x = (p.g_m_s2 * jnp.sin(a[1]) - p.L2_m * (acc[0] * c - a_dot[0] ** 2 * s) - p.Lv_m * acc[1])
    return jnp.array([x[0], x[1], x[2], x[3], a_dot[1], a_x])


class LinearBody(NamedTuple):
    """Linearization at upright: ``ẋ = A x + B u + N F_d``, ``y = C x + D u + E F_d`` (T eq. 16)."""

    A: np.ndarray
    B: np.ndarray
    N: np.ndarray
    C: np.ndarray
    D: np.ndarray
    E: np.ndarray


def linearize(p: TwoSegmentParams = HUMAN_TWO_SEGMENT) -> LinearBody:
    """Jacobians (``jax.jacfwd``) of :func:`two_segment_dynamics` / :func:`two_segment_outputs` at 0."""
    x0, u0, d0 = jnp.zeros(4), jnp.zeros(2), jnp.zeros(3)
    f = lambda x, u, d: two_segment_dynamics(0.0, x, u, d, p)  # noqa: E731
    h = lambda x, u, d: two_segment_outputs(0.0, x, u, d, p)  # noqa: E731
    jf = jax.jacfwd(f, argnums=(0, 1, 2))(x0, u0, d0)
    jh = jax.jacfwd(h, argnums=(0, 1, 2))(x0, u0, d0)
    return LinearBody(*(np.asarray(M) for M in (*jf, *jh)))


def to_statespace(lin: LinearBody):
    """``control.StateSpace`` with inputs ``(τ2, τ3, θ1, θ̇1, θ̈1)`` and outputs y_e of T eq. 23."""
    import control

    return control.ss(lin.A, np.hstack([lin.B, lin.N]), lin.C, np.hstack([lin.D, lin.E]),
                      inputs=["tau2", "tau3", "theta1", "theta1_dot", "theta1_ddot"],
                      outputs=["theta2", "theta3", "theta2_dot", "theta3_dot", "omega", "a_x"],
                      states=["theta2", "theta3", "theta2_dot", "theta3_dot"])
