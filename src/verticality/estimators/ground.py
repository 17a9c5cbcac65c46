"""Ground (platform) inclination from the otolith–canal filter and the joint angles (T eq. 14–15).

With the trunk orientation in space ``φ = θ1 + θ2 + θ3`` (T eq. 1), ankle ``θ2`` and hip ``θ3``
measured by proprioception:

    θ̂1  = φ̂ − θ2 − θ3          (T eq. 14)
    θ̂̇1 = ω̂ − θ̇2 − θ̇3          (T eq. 15; ω̂ = φ̂̇ is the filter's second state)

Works on scalars or on whole time series (any broadcastable shapes). A NaN joint reading gives a
NaN ground estimate for that sample only (flagged by ``jnp.isnan``), never a lost series.
"""

from __future__ import annotations

from typing import NamedTuple

import jax.numpy as jnp


class GroundEstimate(NamedTuple):
    theta1_rad: jnp.ndarray
    theta1_dot_rad_s: jnp.ndarray


def ground_from_filter(phi_hat_rad, omega_hat_rad_s, theta2_rad, theta3_rad,
                       theta2_dot_rad_s, theta3_dot_rad_s) -> GroundEstimate:
    """T eq. 14–15."""
    return GroundEstimate(
        jnp.asarray(phi_hat_rad) - theta2_rad - theta3_rad,
        jnp.asarray(omega_hat_rad_s) - theta2_dot_rad_s - theta3_dot_rad_s,
    )


def ground_from_states(x_hat, joints) -> GroundEstimate:
    """From filter outputs ``x_hat[..., (φ, ω, ω_drift)]`` and ``joints[..., (θ2, θ3, θ̇2, θ̇3)]``."""
    x_hat = jnp.asarray(x_hat)
    joints = jnp.asarray(joints)
    return ground_from_filter(x_hat[..., 0], x_hat[..., 1], joints[..., 0], joints[..., 1],
                              joints[..., 2], joints[..., 3])
