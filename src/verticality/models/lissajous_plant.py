"""The P11 platform/inclinometer plant driven through the Lissajous trajectory (P11 §VI, F §4.3.2).

Additions to :mod:`verticality.models.planar` needed by the Newton-observer experiments:

- the pivot acceleration is given in **head-frame** components (what an IMU on the head provides,
  F's medial model input ``ᴴa``, gravity excluded) and rotated into frame I with the head angle of
  the state, so the observer's model uses its own estimate of the head tilt to do it;
- a 1 ms RK4 step with the input held over the step (zero-order hold), and the block transition that
  composes those steps over one observer interval (25 ms): the observer's discrete model F_T of
  F eq. 4.1 is exactly the plant's discretization, fed the recorded fast-rate inputs;
- the trunk trajectory (x, z, Θ)(t) = 0.25·(sin 0.5πt, sin πt, π sin 2πt) and its derivatives.

State: :class:`~verticality.models.planar.PlanarState` (θ_S, ω_S, θ_H, ω_H), angles from the vertical.
Output: the inclinometer reading θ_S − θ_H.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp

from verticality.integrate import rk4_step
from verticality.models import planar
from verticality.models.planar import PlanarParams, PlanarState


class HeadInput(NamedTuple):
    """Known input over one plant step: head torque and the pivot acceleration in head frame."""

    tau_Nm: jnp.ndarray
    a_h_H_m_s2: jnp.ndarray  # horizontal head axis (y of the coronal plane)
    a_z_H_m_s2: jnp.ndarray  # head z axis; gravity excluded


def p11_params(scale: float = 1.0) -> PlanarParams:
    """P11 §VI plant (m = 50 g, l = 0.1 m, J = m l², b = 0.005, K = 100 J), masses scaled by ``scale``.

    ``scale = 1.1`` gives P11's perturbed observer model (m̂ = 0.055 kg, b̂ = 0.0055, Ĵ = m̂ l²,
    K̂ = 100 Ĵ; l and g unchanged).
    """
    m = 0.05 * scale
    l_m = 0.1
    J = m * l_m**2
    return PlanarParams(m_kg=m, l_m=l_m, J_kg_m2=J, beta_Nms=0.005 * scale, K_kg_m2=100.0 * J)


def dynamics(x: PlanarState, u: HeadInput, p: PlanarParams) -> PlanarState:
    """Planar head+pendulum (planar.py) with the pivot acceleration given in head frame."""
    a_h_I, a_z_I = planar.head_frame_to_inertial(u.a_h_H_m_s2, u.a_z_H_m_s2, x.theta_H_rad)
    return planar.dynamics(x, planar.PlanarInput(u.tau_Nm, a_h_I, a_z_I), p)


def step(x: PlanarState, u: HeadInput, p: PlanarParams, dt_s: float) -> PlanarState:
    """One RK4 step with the input held (the plant's and the observer's fast-rate step)."""
    return rk4_step(lambda t, xx, uu, pp: dynamics(xx, uu, pp), 0.0, x, dt_s, u, p)


def block_transition(x: PlanarState, u_block: HeadInput, p: PlanarParams, dt_s: float,
                     unroll: int = 5) -> PlanarState:
    """Compose :func:`step` over a block of inputs (leading axis = fast steps in one interval)."""

    def body(xx, uu):
        return step(xx, uu, p, dt_s), None

    x_end, _ = jax.lax.scan(body, x, u_block, unroll=unroll)
    return x_end


def dynamics_flat(x, u: HeadInput, p: PlanarParams):
    """:func:`dynamics` on a flat state ``(θ_S, ω_S, θ_H, ω_H)``: the observer's hot path."""
    return jnp.stack(dynamics(PlanarState(x[0], x[1], x[2], x[3]), u, p))


def step_flat(x, u: HeadInput, p: PlanarParams, dt_s, du: HeadInput | None = None):
    """RK4 step of :func:`dynamics_flat`; the input is ``u`` held, or if ``du`` is given the ramp
    ``u + du·(t/dt − 1/2)`` across the step (``u`` is then the mean over the step)."""
    if du is None:
        u0 = uh = u1 = u
    else:
        u0 = jax.tree_util.tree_map(lambda a, b: a - 0.5 * b, u, du)
        uh = u
        u1 = jax.tree_util.tree_map(lambda a, b: a + 0.5 * b, u, du)
    k1 = dynamics_flat(x, u0, p)
    k2 = dynamics_flat(x + 0.5 * dt_s * k1, uh, p)
    k3 = dynamics_flat(x + 0.5 * dt_s * k2, uh, p)
    k4 = dynamics_flat(x + dt_s * k3, u1, p)
    return x + (dt_s / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)


def block_transition_flat(x, u_block: HeadInput, p: PlanarParams, interval_s: float,
                          substeps: int):
    """Observer model F_T over one interval: ``substeps`` RK4 steps over a fast-rate input block.

    Each sub-step sees its share of the held fast-rate inputs as a ramp with the same mean and the
    same first moment about the sub-step's centre (for the torque: the same velocity and position
    increments of the head, whose double integrator is then integrated exactly). The block length
    must be a multiple of ``substeps``. The sub-steps run under ``lax.scan``: XLA compiles one RK4
    step well, while a chain of unrolled steps gets fused with duplicated work (2–3× slower).
    """
    n_fast = u_block.tau_Nm.shape[0]
    if n_fast % substeps:
        raise ValueError(f"input block of {n_fast} samples is not a multiple of {substeps} sub-steps")
    k = n_fast // substeps
    # sample centres in units of the sub-step, relative to its centre: (j + 1/2)/k − 1/2
    c = (jnp.arange(k) + 0.5) / k - 0.5
    u_mean = jax.tree_util.tree_map(lambda a: a.reshape(substeps, k).mean(axis=1), u_block)
    # ramp amplitude du with ∫ du·s·ds (s ∈ [−½, ½]) = mean of a·c, i.e. du = 12·mean(a·c)
    u_ramp = jax.tree_util.tree_map(lambda a: 12.0 * (a.reshape(substeps, k) * c).mean(axis=1),
                                    u_block)
    h = interval_s / substeps

    def body(xx, u_mr):
        return step_flat(xx, u_mr[0], p, h, u_mr[1]), None

    x_end, _ = jax.lax.scan(body, x, (u_mean, u_ramp))
    return x_end


def reading(x: PlanarState):
    """Inclinometer reading, rad (P11's measured tilt; F 2.8 in the plane)."""
    return planar.inclinometer_reading(x)


class TrunkSample(NamedTuple):
    a_h_I_m_s2: jnp.ndarray
    a_z_I_m_s2: jnp.ndarray
    Theta_rad: jnp.ndarray
    Theta_dot_rad_s: jnp.ndarray
    Theta_ddot_rad_s2: jnp.ndarray


def lissajous(t_s, amplitude: float = 0.25) -> TrunkSample:
    """P11 §VI / F §4.3.2: (x, z, Θ)(t) = A·(sin 0.5πt, sin πt, π sin 2πt), A = 0.25."""
    w1, w2, w3 = 0.5 * jnp.pi, jnp.pi, 2.0 * jnp.pi
    A = amplitude
    return TrunkSample(
        a_h_I_m_s2=-A * w1**2 * jnp.sin(w1 * t_s),
        a_z_I_m_s2=-A * w2**2 * jnp.sin(w2 * t_s),
        Theta_rad=A * jnp.pi * jnp.sin(w3 * t_s),
        Theta_dot_rad_s=A * jnp.pi * w3 * jnp.cos(w3 * t_s),
        Theta_ddot_rad_s2=-A * jnp.pi * w3**2 * jnp.sin(w3 * t_s),
    )
