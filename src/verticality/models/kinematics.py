"""Rigid-body motion at one instant, the common currency between trajectories and models."""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp

from verticality.core import so3
from verticality.core.compiling import jit_evaluated_once


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


class RotationAndRate:
    """``retract``/``difference``/``project`` of a model whose state is a NamedTuple ``(R, ω)``
    (a rotation matrix and a body-frame angular velocity, e.g. the head's or a pendulum's):
    ``x ⊞ (δθ, δω) = (R exp([δθ]×), ω + δω)``, 6 tangent coordinates."""

    def retract(self, x, dx):
        return type(x)(rotation_retract(x[0], dx[0:3]), x[1] + dx[3:6])

    def difference(self, x1, x0):
        return jnp.concatenate([rotation_difference(x1[0], x0[0]), x1[1] - x0[1]])

    def project(self, x):
        return type(x)(so3.orthonormalize(x[0]), x[1])


class TabulatedMotion(NamedTuple):
    """A head (or trunk) motion sampled at the stage times of a fixed-step RK4 run.

    ``samples`` is a :class:`RigidMotion` whose leaves have a leading axis over
    ``t0_s + k·step_s`` (``step_s`` = half the integration step, so every RK4 stage time is a
    sample). Evaluating a trajectory once per sample and looking it up inside the time loop keeps
    the (autodiff-heavy) trajectory out of the integrator's compiled program and lets several runs
    share one evaluation (bit-identical to calling the trajectory at the stage times). Pass it to
    jitted functions as an argument (not as a closure constant).
    """

    samples: RigidMotion
    t0_s: jnp.ndarray
    step_s: jnp.ndarray

    def motion(self, t) -> RigidMotion:
        n = self.samples.a_I_m_s2.shape[0]
        k = jnp.clip(jnp.round((t - self.t0_s) / self.step_s).astype(jnp.int32), 0, n - 1)
        return jax.tree_util.tree_map(lambda a: a[k], self.samples)


def tabulate(motion, dt_s: float, n_steps: int, t0_s: float = 0.0,
             chunk: int = 1000) -> TabulatedMotion:
    """Sample ``motion(t) -> RigidMotion`` at ``t0 + k·dt/2``, ``k = 0 … 2·n_steps`` (jitted,
    chunked)."""
    n = 2 * n_steps + 1
    n_pad = -(-n // chunk) * chunk
    step = 0.5 * dt_s

    @jit_evaluated_once
    def sample(k):
        return jax.lax.map(jax.vmap(lambda kk: motion(t0_s + kk * step)), k.reshape(-1, chunk))

    out = sample(jnp.arange(n_pad, dtype=jnp.float64))
    samples = jax.tree_util.tree_map(lambda a: a.reshape((n_pad,) + a.shape[2:])[:n], out)
    return TabulatedMotion(samples, jnp.asarray(t0_s, dtype=float), jnp.asarray(step, dtype=float))
