"""Rigid-body motion at one instant, the common currency between trajectories and models."""

from __future__ import annotations

from typing import NamedTuple

import jax.numpy as jnp


class RigidMotion(NamedTuple):
    """Kinematics of a body B at one instant.

    ``a_I_m_s2`` is the linear acceleration of the body's reference point (its centre) in frame I,
    gravity excluded. Angular velocity and acceleration are in the body frame.
    """

    R_I_B: jnp.ndarray  # (3, 3)
    omega_B_rad_s: jnp.ndarray  # (3,)
    omegadot_B_rad_s2: jnp.ndarray  # (3,)
    a_I_m_s2: jnp.ndarray  # (3,)


def still(R_I_B=None) -> RigidMotion:
    """A body at rest (optionally tilted)."""
    R = jnp.eye(3) if R_I_B is None else jnp.asarray(R_I_B, dtype=float)
    z = jnp.zeros(3)
    return RigidMotion(R, z, z, z)
