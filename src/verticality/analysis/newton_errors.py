"""Scores of a `newton-lissajous` run (:class:`verticality.simulation.newton_loop.RunSeries`):
the head's tilt error, its maximum after the start-up, the inclinometer's swing, the divergence
rule, and P11's published maxima they are compared with."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from verticality.simulation.newton_loop import RunSeries

SETTLE_S = 1.0
DIVERGED_DEG = 30.0

PAPER_LISSAJOUS = {"max_tilt_error_deg": {"fixed": {"exact": 3.0, "perturbed": 6.0},
                                          "stabilized": {"exact": 0.1, "perturbed": 0.5}},
                   "ratio_fixed_over_stabilized": {"perturbed": 12.0}}


def tilt_error_deg(s: RunSeries):
    e = jnp.angle(jnp.exp(1j * (s.theta_H_hat_rad - s.theta_H_rad)))
    return jnp.rad2deg(jnp.abs(e))


def max_error_after(s: RunSeries, t0: float = SETTLE_S) -> float:
    err = np.asarray(tilt_error_deg(s))
    t = np.asarray(s.t_s)
    sel = err[t >= t0 - 1e-9]
    if not np.all(np.isfinite(sel)) or not np.all(np.isfinite(np.asarray(s.theta_H_hat_rad))):
        return float("nan")
    return float(np.max(sel))


def inclinometer_swing_deg(s: RunSeries, t0: float = SETTLE_S) -> float:
    """Largest |inclinometer reading| after ``t0`` (P11 §VI: the stabilized head's inclinometer
    "oscillated with a magnitude of about 4°")."""
    return float(np.max(np.abs(np.rad2deg(np.asarray(s.reading_rad)[np.asarray(s.t_s) >= t0]))))
