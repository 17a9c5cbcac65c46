"""The closed loop of the `newton-lissajous` setup: P11's planar head + pendulum, the Newton
observer on it, and the stabilized head's PD (or the fixed head's neck torque), over the Lissajous
trunk motion.

The plant (models/lissajous_plant.py) is integrated by RK4 at 1 ms with its inputs held over each
step; the reading is sampled every 25 ms, when the observer solves its window; between solves the
estimate is propagated at 1 ms by the observer's own model, and that estimate feeds the PD. The
choices and readings of P11 behind the numbers are in the experiment's docstring
(:mod:`verticality.experiments.newton`).
"""

from __future__ import annotations

from functools import partial
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from verticality.estimators import newton
from verticality.models import lissajous_plant as lp
from verticality.models.base import Discretized, step_euler, step_rk4
from verticality.models.planar import (
    HeadInput,
    PlanarHead,
    PlanarState,
    head_frame_to_inertial,
    inclinometer_reading,
)
from verticality.sensors import readings as sensors
from verticality.simulation.trajectories import LISSAJOUS_AMPLITUDE

DT_S = 1e-3
SUBSTEPS = 25  # 1 ms plant steps per observer sample (25 ms spacing)
OBS_SUBSTEPS = 5  # RK4 sub-steps of the observer's model per 25 ms interval (5 ms each)
KP, KD = 230.0, 15.0
NOISE_RAD = 1e-4
CONFIG = newton.NewtonConfig(window=24, iterations=5, every=1, step_tol=1e-8)
#: the observer's discretization: "rk4-ramp" (ours, near the plant's exact discretization) or
#: "euler" (P11 §V.C: x_{k+1} = x_k + T·F(x_k, u_k) at the 1 ms sampling period)
SCHEMES = ("rk4-ramp", "euler")
ADC_BITS = 16  # P11 §VI: the reading's noise "corresponded to quantization error of a 16-bit ADC"
ADC_FULL_SCALE_RAD = float(np.pi)  # our reading: the ADC spans the inclinometer's ±180°


class RunSeries(NamedTuple):
    t_s: jnp.ndarray  # (T,) at 1 ms
    theta_H_rad: jnp.ndarray
    theta_H_hat_rad: jnp.ndarray
    reading_rad: jnp.ndarray
    tau_Nm: jnp.ndarray
    converged: jnp.ndarray  # (B,) per observer sample
    rank_deficient: jnp.ndarray
    residual_rms_rad: jnp.ndarray
    iterations: jnp.ndarray


def make_observer(p_obs: PlanarHead, config: newton.NewtonConfig = CONFIG,
                  substeps: int = OBS_SUBSTEPS, scheme: str = "rk4-ramp") -> newton.NewtonObserver:
    """The Newton observer on the P11 plant; state (θ_S, ω_S, θ_H, ω_H); y = θ_S − θ_H.

    ``scheme="rk4-ramp"``: F_T = ``substeps`` RK4 steps over 25 ms fed the 1 ms inputs as ramps
    (:func:`lissajous_plant.observer_model`). ``scheme="euler"``: F_T = 25 forward-Euler steps of
    1 ms, each with its 1 ms input held (P11 §V.C; ``substeps`` unused)."""
    z = jnp.zeros(SUBSTEPS)
    if scheme == "euler":
        model = Discretized(lp.plant(p_obs), substeps=SUBSTEPS, scheme="euler")
    else:
        model = lp.observer_model(p_obs, substeps)
    return newton.NewtonObserver(model, HeadInput(z, z, z), config)


@partial(jax.jit, static_argnames=("n_blocks", "config", "scheme"))
def simulate(p_true: PlanarHead, p_obs: PlanarHead, fixed, noise_rad, key, n_blocks: int,
             config: newton.NewtonConfig = CONFIG, *, amplitude_scale=1.0, frequency_scale=1.0,
             kp_Nm_rad=KP, kd_Nms_rad=KD, scheme: str = "rk4-ramp",
             quantized=False, cold_start=False) -> RunSeries:
    """Closed loop of plant, 1 ms estimate propagation, PD (stabilized) and the Newton observer.

    The trunk moves through :func:`lissajous_plant.trunk` with amplitude ``amplitude_scale`` × P11's
    A and time scale ``frequency_scale`` (the motion at t is the published one at
    ``frequency_scale · t``); the fixed head starts with the rate of that motion, ω_H(0) = Θ̇(0).
    ``kp_Nm_rad``, ``kd_Nms_rad``: the stabilized head's PD gains (the fixed head has no
    controller). All four may be traced (vmapped over); at their defaults the run is P11's.
    ``scheme`` (static): the observer's discretization (:data:`SCHEMES`), used both for F_T and
    for the 1 ms propagation of the estimate between solves. ``quantized`` (traced): the reading
    is the true one rounded by a :data:`ADC_BITS`-bit ADC over ±:data:`ADC_FULL_SCALE_RAD`
    instead of the true one plus Gaussian noise of σ ``noise_rad``. ``cold_start`` (traced): each
    window's Newton iteration starts from the zero state (ξ_k⁰ = 0) instead of the previous
    window's solution carried forward (the warm start; P11 §V.B does not say where ξ_k⁰ is)."""
    obs = make_observer(p_obs, config, scheme=scheme)
    step_obs = step_euler if scheme == "euler" else step_rk4
    plant, model = lp.plant(p_true), lp.plant(p_obs)
    amplitude = LISSAJOUS_AMPLITUDE * amplitude_scale

    def trunk_at(t):
        return lp.trunk(t, amplitude, frequency_scale)

    theta_dot0 = trunk_at(0.0).Theta_dot_rad_s
    x0 = PlanarState(jnp.asarray(0.0), jnp.asarray(0.0), jnp.where(fixed, 0.0, 0.1),
                     jnp.where(fixed, theta_dot0, 0.0))
    xh0 = PlanarState(*(jnp.zeros(()) for _ in range(4)))
    noise = noise_rad * jax.random.normal(key, (n_blocks,))
    # the trunk's motion at the middle of every 1 ms step, for the whole run at once (vectorized)
    t_mid = jnp.arange(n_blocks * SUBSTEPS) * DT_S + 0.5 * DT_S
    trunk = jax.tree_util.tree_map(lambda a: a.reshape(n_blocks, SUBSTEPS), trunk_at(t_mid))

    def fast(carry, tr):
        x, xh = carry
        # the trunk's acceleration in head-frame components (what the head's IMU reads)
        a_h_H, a_z_H = head_frame_to_inertial(tr.a_h_I_m_s2, tr.a_z_I_m_s2, -x.theta_H_rad)
        tau = jnp.where(fixed, p_true.K_kg_m2 * tr.Theta_ddot_rad_s2,
                        -kp_Nm_rad * xh.theta_H_rad - kd_Nms_rad * xh.omega_H_rad_s)
        u = HeadInput(tau, a_h_H, a_z_H)
        x1 = step_rk4(plant, x, u, DT_S)
        xh1 = step_obs(model, xh, u, DT_S)
        return (x1, xh1), (u, x1.theta_H_rad, xh1.theta_H_rad, inclinometer_reading(x1))

    def block(carry, b_trunk):
        b, trunk_blk = b_trunk
        x, ost = carry
        xh = ost.x_hat
        # a cold start: the window's first guess (its carried trajectory's entry 1, which the
        # step shifts to the front) is the zero state; the present estimate is kept
        ost = ost._replace(xs_window=jax.tree_util.tree_map(
            lambda a: jnp.where(cold_start, jnp.zeros_like(a), a), ost.xs_window))
        (x, _), (u_blk, th, thh, rd) = jax.lax.scan(fast, (x, xh), trunk_blk)
        y = jnp.where(quantized,
                      sensors.quantize(inclinometer_reading(x), ADC_BITS, ADC_FULL_SCALE_RAD),
                      inclinometer_reading(x) + noise[b])
        ost, out = obs.step(ost, u_blk, y, SUBSTEPS * DT_S)
        # the last fast sample's estimate is the observer's (solved) estimate at this sample
        thh = thh.at[-1].set(out.x_hat.theta_H_rad)
        return (x, ost), (th, thh, rd, u_blk.tau_Nm, out.converged & out.solved,
                          out.rank_deficient & out.solved, out.residual_rms,
                          jnp.where(out.solved, out.iterations, 0))

    _, (th, thh, rd, tau, conv, rdef, res, its) = jax.lax.scan(
        block, (x0, obs.init(xh0)), (jnp.arange(n_blocks), trunk))
    t = (jnp.arange(n_blocks * SUBSTEPS) + 1) * DT_S
    return RunSeries(t, th.reshape(-1), thh.reshape(-1), rd.reshape(-1), tau.reshape(-1),
                     conv, rdef, res, its)


#: the observer's parameters as multiples of the plant's, per "pattern" of P11 §VII's
#: "uncertainty" at a level ε (:func:`scales_for`): (m, l, b, J, K) with Ĵ = m̂ l̂² and K̂ = 100 Ĵ
#: unless a pattern sets them apart. ``over``: P11 §VI's own pattern (m̂, b̂ high by ε, l exact,
#: J and K derived); ``l_under``: l̂ low by ε, J and K derived from it (m, b exact);
#: ``l_under_K_exact``: the same with K̂ = K; ``all_under``: each of the five low by ε.
PATTERNS = ("over", "l_under", "l_under_K_exact", "all_under")


def scales_for(pattern: str, level: float) -> tuple[float, float, float, float, float]:
    """The multiples (m, l, b, J, K) of the plant's parameters that the observer is given."""
    e = float(level)
    if pattern == "over":
        s = 1.0 + e
        return (s, 1.0, s, s, s)
    if pattern == "l_under":
        return (1.0, 1.0 - e, 1.0, (1.0 - e) ** 2, (1.0 - e) ** 2)
    if pattern == "l_under_K_exact":
        return (1.0, 1.0 - e, 1.0, (1.0 - e) ** 2, 1.0)
    if pattern == "all_under":
        return (1.0 - e,) * 5
    raise ValueError(f"unknown pattern {pattern!r}; known: {PATTERNS}")


def scaled_head(p: PlanarHead, scales) -> PlanarHead:
    """``p`` with its (m, l, b, J, K) multiplied by ``scales`` (traced)."""
    s_m, s_l, s_b, s_J, s_K = (scales[i] for i in range(5))
    return PlanarHead(m_kg=p.m_kg * s_m, l_m=p.l_m * s_l, J_kg_m2=p.J_kg_m2 * s_J,
                      beta_Nms=p.beta_Nms * s_b, K_kg_m2=p.K_kg_m2 * s_K, g_m_s2=p.g_m_s2)


def run_batch(fixed, level, noise_rad, seed: int, duration_s: float,
              config: newton.NewtonConfig = CONFIG, scheme: str = "rk4-ramp",
              quantized=None, scales=None, cold_start=None) -> RunSeries:
    """vmap of :func:`simulate` over conditions (fixed flags, levels, noise σ, quantized flags),
    one compile per ``scheme``. The observer's model is P11's plant with m̂, b̂, Ĵ, K̂ scaled by
    1 + level (P11 §VI's pattern), or, given ``scales`` ((B, 5): :func:`scales_for`), by those;
    ``cold_start`` (B,) flags: :func:`simulate`'s."""
    fixed = jnp.asarray(fixed, dtype=bool)
    level = jnp.asarray(level, dtype=float)
    noise = jnp.asarray(noise_rad, dtype=float)
    quant = jnp.zeros_like(fixed) if quantized is None else jnp.asarray(quantized, dtype=bool)
    cold = jnp.zeros_like(fixed) if cold_start is None else jnp.asarray(cold_start, dtype=bool)
    if scales is None:
        scales = jnp.stack([1.0 + level, jnp.ones_like(level), 1.0 + level, 1.0 + level,
                            1.0 + level], axis=1)
    scales = jnp.asarray(scales, dtype=float)
    n_blocks = int(round(duration_s / (SUBSTEPS * DT_S)))
    key = jax.random.PRNGKey(seed)
    p_true = lp.p11_head(1.0)

    def one(f, sc, sg, q, c):
        return simulate(p_true, scaled_head(p_true, sc), f, sg, key, n_blocks, config,
                        scheme=scheme, quantized=q, cold_start=c)

    return jax.vmap(one)(fixed, scales, noise, quant, cold)
