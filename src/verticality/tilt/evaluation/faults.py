"""Synthetic IMU recordings with known truth and one fault each, to measure whether the tilt
filter's σ stays honest at the sensor's limits (docs/tilt.md, "The uncertainty under faults"):
the share of unflagged samples whose tilt error is within 2σ.

The motion: a sensor turning about all three axes (three sinusoids per axis, 0.1–0.8 Hz, up to
~1.5 rad/s), 100 Hz, 60 s, gyro noise 0.002 rad/s and accelerometer noise 0.03 m/s²; a shaking
variant adds 3 Hz translations of 25 and 15 m/s² for 8 s out of every 20. The faults:

* ``bias_0.1``, ``bias_0.2``: a constant gyro bias of |b| ≈ 0.1 and 0.2 rad/s (MEMS turn-on
  offsets), from the start;
* ``shake``: the shaking, clean (the reference for the next one);
* ``clipped_2g``: the shaking read by an accelerometer of range ±2 g (components clipped at
  19.62 m/s²; the filter infers the range from the flat tops, :mod:`~verticality.tilt.limits`);
* ``taps``: 30 taps of ~140 m/s² that bounce back (2 samples out, 2 back: the velocity returns);
* ``kicks``: 30 one-sided impulses of ~140 m/s² (the sensor is set moving at ~1.6 m/s each time
  and keeps that speed: outside the filter's model, in which accelerations are short and periodic).
"""

from __future__ import annotations

from math import erf, sqrt

import numpy as np

from verticality import tilt
from verticality.core import so3
from verticality.core.constants import G_M_S2

FAULTS = ("clean", "bias_0.1", "bias_0.2", "shake", "clipped_2g", "taps", "kicks")


def turning(n: int, dt: float, rng, max_rate_rad_s: float = 0.8):
    """A sensor turning about all three axes: per axis three sinusoids of 0.1–0.8 Hz and
    amplitudes 0.2–``max_rate_rad_s`` rad/s (random phases), the rotation integrated exactly over
    each step. Returns ``(w (n, 3) rad/s, R_E_S (n, 3, 3))``."""
    t = np.arange(n) * dt
    w = np.zeros((n, 3))
    for ax in range(3):
        for f, a in zip(rng.uniform(0.1, 0.8, 3), rng.uniform(0.2, max_rate_rad_s, 3),
                        strict=True):
            w[:, ax] += a * np.sin(2 * np.pi * f * t + rng.uniform(0, 2 * np.pi))
    steps = np.asarray(so3.exp(w * dt))
    R = np.empty((n, 3, 3))
    R[0] = np.eye(3)
    for k in range(1, n):
        R[k] = R[k - 1] @ steps[k]
    return w, R


def _motion(n: int, dt: float, rng, shake: bool):
    t = np.arange(n) * dt
    w, R = turning(n, dt, rng)
    a_lin = np.zeros((n, 3))
    if shake:
        seg = (t % 20.0) > 12.0
        a_lin[seg, 0] = 25.0 * np.sin(2 * np.pi * 3.0 * t[seg])
        a_lin[seg, 1] = 15.0 * np.cos(2 * np.pi * 3.0 * t[seg])
    acc = np.einsum("nji,nj->ni", R, a_lin + [0.0, 0.0, G_M_S2])
    gyr = w + rng.normal(0, 0.002, w.shape)
    return gyr, acc + rng.normal(0, 0.03, acc.shape), R[:, 2, :]


def fault_recording(fault: str, n: int = 6000, dt: float = 0.01, seed: int = 0):
    """``(gyr (n, 3) rad/s, acc (n, 3) m/s², dt s, up_S (n, 3) the true up direction)`` of the
    recording with ``fault`` (one of :data:`FAULTS`)."""
    rng = np.random.default_rng(seed)
    gyr, acc, up = _motion(n, dt, rng, shake=fault in ("shake", "clipped_2g"))
    if fault == "bias_0.1":
        gyr = gyr + np.array([0.06, -0.06, 0.05])
    elif fault == "bias_0.2":
        gyr = gyr + np.array([0.12, -0.12, 0.1])
    elif fault == "clipped_2g":
        acc = np.clip(acc, -2 * G_M_S2, 2 * G_M_S2)
    elif fault in ("taps", "kicks"):
        for k in rng.integers(200, n - 100, 30):
            shock = rng.normal(0, 80.0, 3)
            acc[k:k + 2] += shock
            if fault == "taps":
                acc[k + 2:k + 4] -= shock
    elif fault not in FAULTS:
        raise ValueError(f"unknown fault {fault!r}")
    return gyr, acc, dt, up


def fast_roll(n=2000, dt=0.01, peak=12.0, width_s=0.1, centers_s=(5.0, 10.0, 15.0),
              seed=3):
    """A level sensor turned about its x axis (horizontal at the start) by pulses of rate
    ``peak`` (rad/s, Gaussian in time of standard deviation ``width_s``, alternating in sign,
    centred at ``centers_s``), still in between: ``(gyr (n, 3), acc (n, 3), true up_S (n, 3))``
    with white noise on both sensors (the true rate and specific force, before any clipping).
    Gyro sample k is the mean rate over its interval (t_{k−1}, t_k], as the filter integrates it
    (an integrating gyro), so that the discretization of the simulated rate adds no error."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * dt
    angle = np.zeros(n)
    for j, c in enumerate(centers_s):
        s = peak * (-1) ** j
        angle += (s * width_s * sqrt(np.pi / 2)
                  * (1 + np.vectorize(erf)((t - c) / (width_s * sqrt(2)))))
    R = np.asarray(so3.exp(np.outer(angle, [1.0, 0.0, 0.0])))
    acc = G_M_S2 * R[:, 2, :] + rng.normal(0, 0.02, (n, 3))
    mean_rate = np.diff(angle, prepend=angle[0]) / dt
    gyr = np.column_stack([mean_rate, np.zeros(n), np.zeros(n)]) + rng.normal(0, 1e-3, (n, 3))
    return gyr, acc, R[:, 2, :]


def _errors(fault: str, seed: int):
    """Our filter on :func:`fault_recording`: (tilt error rad, σ rad, unflagged) per sample."""
    gyr, acc, dt, up = fault_recording(fault, seed=seed)
    out = tilt.estimate(gyr, acc, period_s=dt)
    err = np.asarray(so3.angle_between_unit_vectors(out.up_S, up))
    return err, out.sigma_rad, out.flags == 0


def sigma_honesty(fault: str, seed: int = 0) -> dict[str, float]:
    """Our filter on :func:`fault_recording`: the share of samples unflagged, the share of those
    within σ and 2σ of the true tilt, and the largest error (deg) of an unflagged sample."""
    return sigma_honesty_over_seeds(fault, (seed,))


def sigma_honesty_over_seeds(fault: str, seeds=range(20)) -> dict[str, float]:
    """:func:`sigma_honesty` pooled over the recordings of ``seeds`` (the shares count every
    unflagged sample of them all), with the smallest share within 2σ of any one recording."""
    runs = [_errors(fault, s) for s in seeds]
    err = np.concatenate([r[0] for r in runs])
    sigma = np.concatenate([r[1] for r in runs])
    ok = np.concatenate([r[2] for r in runs])
    return {"unflagged": float(ok.mean()),
            "within_1sigma": float(np.mean(err[ok] <= sigma[ok])),
            "within_2sigma": float(np.mean(err[ok] <= 2 * sigma[ok])),
            "worst_within_2sigma": min(float(np.mean(e[k] <= 2 * s[k])) for e, s, k in runs),
            "max_unflagged_error_deg": float(np.degrees(err[ok].max())),
            "median_sigma_deg": float(np.degrees(np.median(sigma[ok])))}
