"""The continuous-time closed loop of F §4.5.2 under the Fig. 4.12 caption's reading (the
acceleration fed to the internal model reconstructed with the head taken as upright): the plant,
the observer ODE (F 4.10), the PD on the estimate and the fed acceleration as one ODE integrated
by RK4 at 10 kHz, driven by the walking at the step frequency (and its 2nd harmonics scaled).
The readings behind it are in :mod:`verticality.experiments.ambiguity_upright`.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from verticality.analysis import ambiguity as am
from verticality.core.integrate import rk4_step_staged
from verticality.estimators import luenberger as lu
from verticality.models.planar import HeadInput, PlanarState
from verticality.simulation import ambiguity_loop
from verticality.simulation import trajectories as tr

DT_S = 1e-4
PD_LOOP_RAD_S = 4.0
STEP_HZ = 2.0  # the walking's cadence (trajectories.walking)
NOMINAL_LAG_DEG = 90.0  # trajectories.walking: the bounce lags the fore–aft sway by a quarter step
OUT_EVERY = 100  # series kept at 100 Hz


def fed_acceleration(feed: str, reading_rad, a_z_m_s2, theta_hat_rad, a_h_true_m_s2):
    """The horizontal head-frame acceleration the internal model is fed: ``upright`` F 3.14 with
    the head taken as upright (the Fig. 4.12 caption), ``luenberger`` F 3.17 with the estimated
    tilt (F's text before Fig. 4.12), ``known`` the true one (Fig. 4.11)."""
    if feed == "upright":
        return am.planar_head_acceleration(reading_rad, a_z_m_s2, 0.0)
    if feed == "luenberger":
        return am.planar_head_acceleration(reading_rad, a_z_m_s2, theta_hat_rad, small_angle=True)
    if feed == "known":
        return a_h_true_m_s2
    raise ValueError(f"unknown feed {feed!r}")


def _vertical_shift_samples(lag_deg: float) -> int:
    """Half-samples by which the bounce is read later than the sway for a lag of ``lag_deg``
    (relative to the walking's own quarter step), in [0, one step)."""
    period_half_samples = int(round(2.0 / (STEP_HZ * DT_S)))
    shift = -(lag_deg - NOMINAL_LAG_DEG) / 360.0 * period_half_samples
    return int(round(shift)) % period_half_samples


def walking_half_steps(n_steps: int, t0_s: float = 2.0):
    """The walking's ``(a_h, a_z)`` on a grid of half samples from its steady gait (``t0_s``), each
    (2, ·): the step frequency alone (``harmonics=0``) and the 2nd harmonics' part; ``2 n + 1``
    values for the sway, one step's period more for the bounce (to shift it)."""
    period_s = 1.0 / STEP_HZ
    n_half = 2 * n_steps + 1
    extra = int(round(2.0 * period_s / DT_S))
    t = t0_s + np.arange(n_half + extra) * (DT_S / 2.0)
    a = [np.asarray(tr.sample(tr.walking(duration_s=t0_s + n_steps * DT_S + period_s + 1.0,
                                         harmonics=h), t).a_I_m_s2) for h in (0.0, 1.0)]
    a_h = -np.stack([a[0][:n_half, 0], a[1][:n_half, 0] - a[0][:n_half, 0]])  # sagittal: h = −x
    a_z = np.stack([a[0][:, 2], a[1][:, 2] - a[0][:, 2]])
    return a_h, a_z


class LoopSummary(NamedTuple):
    """Per run, at 100 Hz: the head's tilt, its estimate, the fed and true accelerations."""

    theta_H: jnp.ndarray
    theta_hat: jnp.ndarray
    a_hat: jnp.ndarray
    a_true: jnp.ndarray


def closed_loop(feed: str, theta0_rad, ref_rad, kp, kd, scale, harmonics, shift, a_h_half,
                a_z_half, n_steps: int, obs, truth):
    """One continuous-time closed loop (plant, observer ODE F 4.10, PD on the estimate, the fed
    acceleration of ``feed``) by RK4 at :data:`DT_S`; the walking (:func:`walking_half_steps`)
    with its 2nd harmonics scaled by ``harmonics``, all scaled by ``scale``, its bounce read
    ``shift`` half-samples later. Returns :class:`LoopSummary` every :data:`OUT_EVERY` steps."""
    A, B, C, D, L = (jnp.asarray(m) for m in (obs.A, obs.B, obs.C, obs.D, obs.L))

    def field(w, z):
        x, xh = z
        a_h, a_z = w
        y = truth.output(x)
        tau = kp * (ref_rad - xh[2]) - kd * xh[3]
        a_hat = fed_acceleration(feed, y[0], a_z, xh[2], a_h)
        u = jnp.stack([tau, a_hat])
        dx = truth.dynamics(x, HeadInput(tau, a_h, a_z))
        dxh = A @ xh + B @ u + L @ (y - C @ xh - D @ u)
        return (dx, dxh), a_hat

    mix = scale * jnp.stack([1.0, harmonics])
    a_h_all, a_z_all = mix @ a_h_half, mix @ a_z_half

    def acc3(k):
        j = 2 * k + jnp.arange(3)
        return a_h_all[j], a_z_all[j + shift]

    def step(z, k):
        w = acc3(k)
        z_new, a_hat = rk4_step_staged(field, w, z, DT_S)
        return z_new, (a_hat, w[0][0])

    def block(z, b):
        z_end, (a_hat, a_true) = jax.lax.scan(step, z, b * OUT_EVERY + jnp.arange(OUT_EVERY))
        x, xh = z
        return z_end, LoopSummary(x.theta_H_rad, xh[2], a_hat.mean(), a_true.mean())

    th0 = jnp.asarray(theta0_rad, float)
    r0 = am.planar_reading(a_h_all[0], a_z_all[shift], th0)
    x0 = PlanarState(th0 + r0, 0.0 * th0, th0, 0.0 * th0)
    return jax.lax.scan(block, (x0, jnp.zeros(4)), jnp.arange(n_steps // OUT_EVERY))[1]


_batch = jax.jit(jax.vmap(closed_loop, in_axes=(None, 0, 0, 0, 0, 0, 0, 0, None, None, None, None,
                                                None)),
                 static_argnums=(0, 10))


def runs(feed: str, theta0_deg, ref_deg, pd_loop_rad_s, walking_scale, vertical_lag_deg,
         harmonics, duration_s: float) -> LoopSummary:
    """A batch of runs (the arguments broadcast to one length); numpy :class:`LoopSummary` with a
    leading run axis."""
    th0, ref, w, scale, lag, harm = np.broadcast_arrays(*(np.asarray(v, float) for v in (
        theta0_deg, ref_deg, pd_loop_rad_s, walking_scale, vertical_lag_deg, harmonics)))
    n = int(round(duration_s / DT_S))
    kp, kd = ambiguity_loop.pd_gains(loop_rad_s=w)
    shift = np.array([_vertical_shift_samples(v) for v in lag.ravel()], np.int64)
    a_h_half, a_z_half = walking_half_steps(n)
    obs = lu.design(ambiguity_loop.linear_model(), ambiguity_loop.LUENBERGER_POLES)
    out = _batch(feed, jnp.radians(th0.ravel()), jnp.radians(ref.ravel()), jnp.asarray(kp.ravel()),
                 jnp.asarray(kd.ravel()), jnp.asarray(scale.ravel()), jnp.asarray(harm.ravel()),
                 jnp.asarray(shift),
                 jnp.asarray(a_h_half), jnp.asarray(a_z_half), n, obs, ambiguity_loop.plant())
    return LoopSummary(*(np.asarray(v) for v in out))
