"""Stability of F §4.5.2's loops linearized at upright, head only rotating: the continuous loop
of :mod:`verticality.simulation.ambiguity_upright_loop` and the sampled one of
:mod:`verticality.simulation.ambiguity_loop` (both sit on a marginal mode: the still tilt is read
as acceleration), for the F 3.17 and F 3.14 upright feeds."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np

from verticality.core.compiling import jit_evaluated_once
from verticality.core.integrate import rk4_step_staged
from verticality.estimators import luenberger as lu
from verticality.models.planar import HeadInput, PlanarState
from verticality.simulation import ambiguity_loop
from verticality.simulation.ambiguity_upright_loop import PD_LOOP_RAD_S, fed_acceleration


def _loop_map(z, feed: str, sampled: bool, kp, kd, dt_s, disc, obs, truth):
    """The loop of ``feed`` linearized in :func:`loop_eigenvalues`: ``ż`` (continuous) or the state
    one sample later (``sampled``), ``z`` = (plant state, observer state), head only rotating."""
    zero = jnp.asarray(0.0)
    x, xh = PlanarState(*z[:4]), z[4:]
    y = truth.output(x)
    tau = -kp * xh[2] - kd * xh[3]
    u = jnp.stack([tau, fed_acceleration(feed, y[0], zero, xh[2], zero)])
    if not sampled:
        dx = truth.dynamics(x, HeadInput(tau, zero, zero))
        dxh = obs.A @ xh + obs.B @ u + obs.L @ (y - obs.C @ xh - obs.D @ u)
        return jnp.concatenate([jnp.stack(list(dx)), dxh])
    xh_new = obs.step_discrete(obs.init(xh), u, y, disc)[0].x
    stages = HeadInput(jnp.broadcast_to(tau, (3,)), jnp.zeros(3), jnp.zeros(3))
    x_new = rk4_step_staged(lambda w, xx: (truth.dynamics(xx, w), None), stages, x, dt_s)[0]
    return jnp.concatenate([jnp.stack(list(x_new)), xh_new])


_loop_jacobian = jit_evaluated_once(jax.jacfwd(_loop_map), static_argnums=(1, 2))


def loop_eigenvalues(feed: str, pd_loop_rad_s: float, dt_s: float | None = None) -> np.ndarray:
    """Eigenvalues (1/s) of the loop of ``feed`` linearized at upright, head only rotating: the
    continuous-time Jacobian (``dt_s`` None) or the sampled loop of
    :func:`verticality.simulation.ambiguity_loop.closed_loop` (reading and fed acceleration held
    over ``dt_s``, observer stepped exactly, plant by RK4), its multipliers μ mapped to
    ``log μ / dt``; sorted by decreasing real part."""
    obs = lu.design(ambiguity_loop.linear_model(), ambiguity_loop.LUENBERGER_POLES)
    kp, kd = ambiguity_loop.pd_gains(loop_rad_s=pd_loop_rad_s)
    sampled = dt_s is not None
    dt = jnp.asarray(dt_s if sampled else 1.0)
    disc = obs.discretize(dt)
    J = np.asarray(_loop_jacobian(jnp.zeros(8), feed, sampled, kp, kd, dt, disc, obs,
                                  ambiguity_loop.plant()))
    lam = np.linalg.eigvals(J).astype(complex)
    if sampled:
        lam = np.log(lam) / dt_s
    return lam[np.argsort(-lam.real)]


def stability_report(pd_loops=(PD_LOOP_RAD_S, 10.0), steps=(1e-4, 2.5e-5, 1e-5)) -> dict:
    """The upright-linearized loops, F 3.17 with the estimated tilt (``luenberger``) and F 3.14
    upright, head only rotating, in continuous time and sampled at ``steps``: the largest real part
    of any eigenvalue (1/s) and the oscillatory pair with the largest real part (1/s, Hz)."""
    out: dict = {}
    for feed in ("luenberger", "upright"):
        for w in pd_loops:
            entry = {}
            for dt in (None, *steps):
                lam = loop_eigenvalues(feed, w, dt)
                osc = lam[np.abs(lam.imag) > 1.0]
                key = "continuous" if dt is None else f"sampled_{1.0 / dt / 1e3:g}_kHz"
                entry[key] = {"max_real_1_s": float(lam[0].real),
                              "oscillatory_real_1_s": float(osc[0].real),
                              "oscillatory_hz": float(abs(osc[0].imag) / (2.0 * math.pi))}
            out.setdefault(feed, {})[f"pd_{w:g}_rad_s"] = entry
    return out
