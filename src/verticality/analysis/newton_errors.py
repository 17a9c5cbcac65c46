"""Scores of a `newton-lissajous` run (:class:`verticality.simulation.newton_loop.RunSeries`):
the head's tilt error, its maximum after the start-up, the inclinometer's swing, the divergence
rule, and P11's published maxima they are compared with."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from verticality.simulation.newton_loop import RunSeries

SETTLE_S = 1.0
DIVERGED_DEG = 30.0
#: a run is **lost** when its estimate points away from the truth by more than this after the
#: start-up (the estimate no longer tells the tilt's sign), when it is not finite, or when fewer
#: than :data:`LOST_CONVERGED_FRACTION` of its windows' Newton iterations converged
LOST_DEG = 90.0
LOST_CONVERGED_FRACTION = 0.5

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


def converged_fraction(s: RunSeries, t0: float = SETTLE_S) -> float:
    """Share of the observer's solves after ``t0`` whose Newton iteration converged."""
    t = np.asarray(s.t_s)
    per_block = t.size // np.asarray(s.converged).size
    t_solve = t[per_block - 1::per_block]
    return float(np.mean(np.asarray(s.converged)[t_solve >= t0 - 1e-9]))


def is_lost(s: RunSeries, t0: float = SETTLE_S) -> bool:
    """The run is lost (:data:`LOST_DEG`): its error after ``t0`` passes 90° or is not finite, or
    most of its Newton iterations did not converge."""
    e = max_error_after(s, t0)
    return bool(not np.isfinite(e) or e > LOST_DEG
                or converged_fraction(s, t0) < LOST_CONVERGED_FRACTION)


def inclinometer_swing_deg(s: RunSeries, t0: float = SETTLE_S) -> float:
    """Largest |inclinometer reading| after ``t0`` (P11 §VI: the stabilized head's inclinometer
    "oscillated with a magnitude of about 4°")."""
    return float(np.max(np.abs(np.rad2deg(np.asarray(s.reading_rad)[np.asarray(s.t_s) >= t0]))))
