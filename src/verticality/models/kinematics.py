"""Rigid-body motion at one instant, the common currency between trajectories and models."""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp

from verticality import so3


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


def from_functions(position_I_m, R_I_B, t) -> RigidMotion:
    """The motion at time ``t`` of a body whose position ``position_I_m(t)`` and orientation
    ``R_I_B(t)`` are smooth functions of time: ω = vee(RᵀṘ), ω̇ and a by forward-mode autodiff."""

    def omega(s):
        Rs, Rdot = jax.jvp(R_I_B, (s,), (1.0,))
        return so3.vee(Rs.T @ Rdot)

    w, wdot = jax.jvp(omega, (t,), (1.0,))
    velocity = lambda s: jax.jvp(position_I_m, (s,), (1.0,))[1]  # noqa: E731
    a = jax.jvp(velocity, (t,), (1.0,))[1]
    return RigidMotion(R_I_B(t), w, wdot, a)


def rotation_retract(R, dtheta_rad):
    """``R ⊞ δ = R exp([δ]×)``: a right (body-frame) perturbation of a rotation matrix."""
    return R @ so3.exp(dtheta_rad)


def rotation_difference(R1, R0):
    """``R1 ⊟ R0 = log(R0ᵀ R1)``, the inverse of :func:`rotation_retract` (angles below π)."""
    return so3.log_principal(R0.T @ R1)
