"""Semicircular canals: the torsion-pendulum cupula (F eq. 1.2–1.3) and its high-pass form.

Three canals, one per head axis (x, y, z of the head frame: the idealized orthogonal triplet the
perception models assume), each driven by the component of the head's angular velocity about its
axis. Two model values, both with input ``u = ω_H`` (rad/s, head frame, (3,)) and output the canal
afferent signals in rad/s, (3,), scaled so that the mid-band gain is 1:

:class:`TorsionPendulumCanal` — F eq. 1.2 forced by the head: the endolymph's deviation ξ relative
to the canal obeys ``Θ ξ̈ + Π ξ̇ + Δ ξ = Θ ω̇`` (Θ inertia of the endolymph, Π viscous moment per
unit angular velocity, Δ the cupula's restoring moment per unit angle). Written without ω̇ (so
that only ω is needed), with the state ``(ξ, p = ξ̇ − ω)``::

    ξ̇ = p + ω,      ṗ = −(Π/Θ)(p + ω) − (Δ/Θ) ξ,      y = (Π/Θ) ξ

so that ``y/ω (s) = (Π/Θ) s / (s² + (Π/Θ) s + Δ/Θ)``. F eq. 1.3 (Θ = 1, Π = 10, Δ = 1 in the
normalized time of the source) has the long time constant ≈ Π/Δ ≈ 9.9 and the short one ≈ Θ/Π
≈ 0.1; :func:`torsion_pendulum` builds the model from the two time constants (seconds), e.g. the
default τ1 = 5.7 s, τ2 = 0.005 s.

:class:`HighPassCanal` — the first-order form the perception models use,
``y/ω = s/(s + 1/τ)``, optionally in series with the adaptation operator ``s/(s + 1/τ_a)``::

    ċ = (ω − c)/τ,   v = ω − c,    ḋ = (v − d)/τ_a,   y = v − d      (d ≡ 0 without adaptation)

``tau_a_s = inf`` (the default) means no adaptation (the d state stays zero). τ ≈ 5–6 s, τ_a ≈ 80 s
(Merfeld & Zupan 2002; Rader et al. 2009 Table 4: 5.7 s, 80 s).

:func:`implicit_euler_coefficients` gives the high-pass canal's implicit-Euler step, the canal of
the discrete-time perception model; :func:`transfer_function` gives each model's ``y/ω`` at
complex frequencies, the reference the tests compare the state-space models with.
"""

from __future__ import annotations

from typing import NamedTuple

import jax.numpy as jnp
import numpy as np

from verticality.core.errors import InputError
from verticality.models.base import EuclideanState, model_dataclass


class TorsionState(NamedTuple):
    xi_rad: jnp.ndarray  # (3,) endolymph deviation relative to the canal
    p_rad_s: jnp.ndarray  # (3,) ξ̇ − ω


class HighPassState(NamedTuple):
    c_rad_s: jnp.ndarray  # (3,) the low-passed angular velocity (ω − c is the canal signal)
    d_rad_s: jnp.ndarray  # (3,) the adaptation state


@model_dataclass
class TorsionPendulumCanal(EuclideanState):
    """Three torsion-pendulum canals (F eq. 1.2) as a model value; ``u = ω_H`` (3,)."""

    Pi_over_Theta_s_inv: jnp.ndarray  # Π/Θ, 1/s
    Delta_over_Theta_s_inv2: jnp.ndarray  # Δ/Θ, 1/s²

    def dynamics(self, x: TorsionState, u) -> TorsionState:
        w = jnp.asarray(u)
        xi_dot = x.p_rad_s + w
        return TorsionState(xi_dot, -self.Pi_over_Theta_s_inv * xi_dot
                            - self.Delta_over_Theta_s_inv2 * x.xi_rad)

    def output(self, x: TorsionState, u=None):
        return self.Pi_over_Theta_s_inv * x.xi_rad

    def rest_state(self) -> TorsionState:
        return TorsionState(jnp.zeros(3), jnp.zeros(3))


@model_dataclass
class HighPassCanal(EuclideanState):
    """Three first-order canals ``s/(s + 1/τ)`` with optional adaptation; ``u = ω_H`` (3,)."""

    tau_s: jnp.ndarray
    tau_a_s: jnp.ndarray = float("inf")

    def dynamics(self, x: HighPassState, u) -> HighPassState:
        v = jnp.asarray(u) - x.c_rad_s
        return HighPassState(v / self.tau_s, (v - x.d_rad_s) / self.tau_a_s)

    def output(self, x: HighPassState, u):
        return jnp.asarray(u) - x.c_rad_s - x.d_rad_s

    def rest_state(self) -> HighPassState:
        return HighPassState(jnp.zeros(3), jnp.zeros(3))


def torsion_pendulum(tau_long_s: float = 5.7, tau_short_s: float = 0.005) -> TorsionPendulumCanal:
    """The torsion pendulum whose two real poles are at −1/τ_long and −1/τ_short:
    ``Π/Θ = 1/τ_long + 1/τ_short``, ``Δ/Θ = 1/(τ_long τ_short)``. F eq. 1.3's normalized equation
    is ``torsion_pendulum_from_coefficients(1, 10, 1)``."""
    if not (tau_long_s > tau_short_s > 0.0):
        raise InputError(f"torsion pendulum: need tau_long > tau_short > 0, got {tau_long_s}, "
                         f"{tau_short_s}")
    return TorsionPendulumCanal(jnp.asarray(1.0 / tau_long_s + 1.0 / tau_short_s),
                                jnp.asarray(1.0 / (tau_long_s * tau_short_s)))


def torsion_pendulum_from_coefficients(Theta: float, Pi: float,
                                       Delta: float) -> TorsionPendulumCanal:
    """F eq. 1.2 with its three coefficients (F eq. 1.3: Θ = 1, Π = 10, Δ = 1)."""
    if not (Theta > 0 and Pi > 0 and Delta > 0):
        raise InputError("torsion pendulum: Θ, Π and Δ must be positive")
    return TorsionPendulumCanal(jnp.asarray(Pi / Theta), jnp.asarray(Delta / Theta))


def high_pass(tau_s: float = 5.7, tau_a_s: float | None = None) -> HighPassCanal:
    """The high-pass canal ``s/(s + 1/τ)``, in series with ``s/(s + 1/τ_a)`` when ``tau_a_s`` is
    given."""
    if not tau_s > 0.0 or (tau_a_s is not None and not tau_a_s > 0.0):
        raise InputError("canal: time constants must be positive")
    return HighPassCanal(jnp.asarray(float(tau_s)),
                         jnp.asarray(float("inf") if tau_a_s is None else float(tau_a_s)))


def implicit_euler_coefficients(tau_s, dt_s):
    """``(k₁, k₂)`` of the high-pass canal's low-passed state stepped by implicit Euler,
    ``c_t = k₁ c_{t−1} + k₂ ω_t``: ``ċ = (ω − c)/τ`` (:meth:`HighPassCanal.dynamics`) taken at the
    end of the step gives ``k₁ = τ/(τ + δt)``, ``k₂ = δt/(τ + δt)``; stable for every step, as the
    discrete-time perception models (Laurens & Angelaki 2017) need."""
    return tau_s / (tau_s + dt_s), dt_s / (tau_s + dt_s)


def transfer_function(canal, s) -> np.ndarray:
    """``y/ω`` of one canal at the complex frequencies ``s`` (the closed form of the module doc)."""
    s = np.asarray(s, dtype=complex)
    if isinstance(canal, TorsionPendulumCanal):
        a, b = float(canal.Pi_over_Theta_s_inv), float(canal.Delta_over_Theta_s_inv2)
        return a * s / (s * s + a * s + b)
    tau, tau_a = float(canal.tau_s), float(canal.tau_a_s)
    h = s / (s + 1.0 / tau)
    return h if np.isinf(tau_a) else h * s / (s + 1.0 / tau_a)
