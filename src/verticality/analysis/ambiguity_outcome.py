"""Outcome of an `ambiguity-*` run: converged or not (mean tilt-estimate and head errors over
the last second within :data:`CONVERGED_DEG`), the final errors, the RMS error of the fed
acceleration, and the boundary of a sweep (largest converging, smallest failing value)."""

from __future__ import annotations

import math

import numpy as np

from verticality.simulation.ambiguity_loop import DT_S, Series
from verticality.simulation.ambiguity_upright_loop import DT_S as UPRIGHT_DT_S
from verticality.simulation.ambiguity_upright_loop import OUT_EVERY, LoopSummary

CONVERGED_DEG = 10.0


def finite_or_none(v):
    v = float(v)
    return v if math.isfinite(v) else None


def summarize(s: Series, ref_deg, known: bool) -> list[dict]:
    """Per sweep value: converged, final tilt and head errors (deg), RMS acceleration error."""
    n = s.theta_H.shape[1]
    t = np.arange(n) * DT_S
    last1 = t >= t[-1] - 1.0
    after1 = t >= 1.0
    rows = []
    for i, ref in enumerate(np.radians(np.asarray(ref_deg, float))):
        est_err = np.degrees(np.abs(s.theta_hat[i] - s.theta_H[i]))
        head_err = np.degrees(np.abs(s.theta_H[i] - ref))
        finite = all(np.all(np.isfinite(v[i])) for v in s)
        converged = bool(finite and est_err[last1].mean() <= CONVERGED_DEG
                         and head_err[last1].mean() <= CONVERGED_DEG)
        acc_err = s.a_hat[i] - s.a_true[i]
        rows.append({
            "converged": converged,
            "final_tilt_error_deg": finite_or_none(est_err[last1].mean()),
            "final_head_error_deg": finite_or_none(head_err[last1].mean()),
            "rms_acc_error_m_s2": None if known else finite_or_none(
                np.sqrt(np.mean(acc_err[after1] ** 2))),
        })
    return rows


def largest_converging(values_deg, rows) -> float | None:
    """The largest |value| such that every sweep value of smaller or equal magnitude converged
    (None if the smallest fails)."""
    best = None
    for v, r in sorted(zip(values_deg, rows, strict=True), key=lambda p: abs(p[0])):
        if not r["converged"]:
            break
        best = abs(float(v))
    return best


def smallest_failing(values_deg, rows) -> float | None:
    fails = [abs(float(v)) for v, r in zip(values_deg, rows, strict=True) if not r["converged"]]
    return min(fails) if fails else None


def summarize_upright(s: LoopSummary, ref_deg) -> list[dict]:
    """Per run of the continuous loop (:class:`LoopSummary`, 100 Hz): converged
    (:data:`CONVERGED_DEG`, as :func:`summarize`), final tilt and head errors (deg), RMS error of
    the fed acceleration after the first second."""
    n = s.theta_H.shape[1]
    last1 = np.arange(n) >= n - int(round(1.0 / (OUT_EVERY * UPRIGHT_DT_S)))
    after1 = np.arange(n) >= int(round(1.0 / (OUT_EVERY * UPRIGHT_DT_S)))
    rows = []
    for i, ref in enumerate(np.radians(np.broadcast_to(np.asarray(ref_deg, float),
                                                       (len(s.theta_H),)))):
        est = np.degrees(np.abs(s.theta_hat[i] - s.theta_H[i]))
        head = np.degrees(np.abs(s.theta_H[i] - ref))
        finite = all(np.all(np.isfinite(v[i])) for v in s)
        e, h = est[last1].mean(), head[last1].mean()
        rows.append({"converged": bool(finite and e <= CONVERGED_DEG and h <= CONVERGED_DEG),
                     "final_tilt_error_deg": finite_or_none(e),
                     "final_head_error_deg": finite_or_none(h),
                     "rms_acc_error_m_s2": finite_or_none(
                         np.sqrt(np.mean((s.a_hat[i] - s.a_true[i])[after1] ** 2)))})
    return rows
