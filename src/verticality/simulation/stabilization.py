"""Would servoing the head upright help on a recorded trunk motion? (`verticality stabilize`)

The trunk of a :class:`~verticality.io.motion.MotionRecord` carries P13's gimbal head with its
otolith pendulum and gyros; the EKF on SO(3) of ``ekf-impact``/``ekf-jump`` estimates the head's
tilt, once with the head rigid on the trunk (``fixed``) and once servoed upright by P13's PD fed by
the estimate (``stabilized``). Everything but the trunk motion is the ekf-* setting
(:mod:`verticality.simulation.ekf_runs`): P13's plant, sensor noise σ = 0.02, EKF every 20 ms
started 0.1 rad off, its model given P13's wrong parameters unless ``exact_model``.

:func:`compare_heads` runs both and returns a :class:`Comparison`: the metrics (max and RMS tilt
error after the settling time, their ratio), the tilt series, what the run had to adapt (the
recording cut to whole EKF periods, a first non-finite sample per head) and what the input looks
like (the disagreement of its ω with its q, the longest gap between rows).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import NamedTuple

import numpy as np

from verticality.core.errors import InputError
from verticality.io.motion import MotionRecord
from verticality.models.params import P13_HEAD, P13_PENDULUM
from verticality.simulation import closed_loop as sim
from verticality.simulation import ekf_runs
from verticality.simulation import recorded as rt
from verticality.simulation.ekf_figures import plot_fixed_vs_stabilized

EKF_PERIOD_S = sim.DEFAULT_CONFIG.dt_estimator_s
PLANT_STEP_S = sim.DEFAULT_CONFIG.dt_plant_s
"""The ekf-* runs' EKF period (20 ms): the simulator runs whole periods."""


class Comparison(NamedTuple):
    report: dict  # the metrics and settings (JSON-ready: None where a head diverged)
    series: dict  # {condition: the tilt series of the first seed} (ekf_runs.run_condition)
    name: str  # the recording's name
    t0_s: float  # the recording's first time: series times + t0_s are on the file's clock
    recorded_s: float  # the recording's duration; report["duration_s"] is what was simulated
    rate_mismatch_rad: float  # largest disagreement of ω with q over a window (recorded_trajectory)
    rate_mismatch_t_s: float  # where that window starts (the file's clock relative to t0)
    max_gap_s: float  # the longest interval between rows

    @property
    def cut_s(self) -> float:
        """The recording's last seconds that do not fill an EKF period (not simulated)."""
        return self.recorded_s - self.report["duration_s"]

    @property
    def rate_mismatch_warning(self) -> bool:
        return self.rate_mismatch_rad > rt.RATE_MISMATCH_WARN_RAD

    @property
    def diverged(self) -> dict:
        """{condition: (time on the file's clock, "plant" or "estimate")} of the first non-finite
        sample (first seed), for the heads that diverged."""
        return self.report["diverged"]

    def t_file_s(self) -> np.ndarray:
        """The EKF's sample times on the file's clock."""
        return np.asarray(next(iter(self.series.values()))["t_s"]) + self.t0_s


def whole_periods(duration_s: float, period_s: float = EKF_PERIOD_S) -> float:
    """The longest whole number of periods within ``duration_s``."""
    return math.floor(duration_s / period_s + 1e-9) * period_s


def check_options(duration_s: float, seeds: int, noise: float, settle_s: float,
                  period_s: float = EKF_PERIOD_S) -> None:
    """:class:`InputError` for settings that cannot give a result."""
    if seeds < 1:
        raise InputError(f"--seeds must be at least 1, not {seeds}")
    if not (math.isfinite(noise) and noise > 0.0):
        raise InputError("--noise must be a positive number (it is also the filter's R), "
                         f"not {noise}")
    if not (math.isfinite(settle_s) and settle_s >= 0.0):
        raise InputError(f"--settle must be a non-negative number, not {settle_s}")
    if settle_s + 2 * period_s > duration_s:
        raise InputError(f"the recording lasts {duration_s:g} s, which leaves no EKF sample "
                         f"after the {settle_s:g} s settling time (shorten it with --settle)")
    from verticality.core.sizing import check_work_size

    # the plant's 1 ms RK4 steps of every seed are held at once (~58 B each, measured)
    check_work_size(duration_s / PLANT_STEP_S * seeds, 64,
                    f"plant steps ({duration_s:g} s at {PLANT_STEP_S * 1e3:g} ms "
                    f"× {seeds} seed(s))",
                    "take a shorter window (--start, --duration; a time stamp that jumps makes a "
                    "long recording) or fewer --seeds")


def first_non_finite(series: dict, t0_s: float = 0.0):
    """(time + ``t0_s``, "plant" or "estimate") of the first non-finite tilt sample, or None."""
    for key, what in (("tilt_true_deg", "plant"), ("tilt_est_deg", "estimate")):
        bad = ~np.all(np.isfinite(np.asarray(series[key]).reshape(len(series["t_s"]), -1)), axis=1)
        if bad.any():
            return float(series["t_s"][np.argmax(bad)] + t0_s), what
    return None


def compare_heads(record: MotionRecord, name: str = "recorded", *, source: str | None = None,
                  seeds: int = 1, noise: float | None = None, exact_model: bool = False,
                  settle_s: float | None = None, progress=None) -> Comparison:
    """The fixed and the stabilized head on the trunk motion ``record`` (see the module doc).

    ``name``: the recording's name (figure titles); ``source``: where it came from (the report's
    ``input``, default ``name``); ``seeds``: sensor-noise realizations (one batch); ``noise``: σ
    of the inclinometer and gyro noise, also the filter's R (default P13's 0.02); ``exact_model``:
    the filter gets the plant's parameters; ``settle_s``: seconds excluded from the metrics
    (default 2). ``progress(text)`` is called before each head's (compiled, batched) run."""
    traj = rt.from_record(record.t_s, record.q_I_H_wxyz, record.omega_H_rad_s, record.a_I_m_s2,
                          name=name)
    recorded_s = traj.duration_s
    traj = traj._replace(duration_s=whole_periods(recorded_s))
    noise = ekf_runs.SIGMA_MEASUREMENT if noise is None else noise
    settle_s = ekf_runs.T_SETTLE_S if settle_s is None else settle_s
    check_options(traj.duration_s, seeds, noise, settle_s)
    mismatch, t_mismatch = rt.rate_mismatch(record.t_s, record.q_I_H_wxyz, record.omega_H_rad_s)
    t0 = traj.events["t0_s"]
    model = (P13_PENDULUM, P13_HEAD) if exact_model else ekf_runs.EKF_MODEL
    seed_list = tuple(range(seeds))
    metrics: dict = {"max_tilt_error_deg": {}, "rms_tilt_error_deg": {}, "rejected_updates": {}}
    series: dict = {}
    diverged: dict = {}
    for cond in sim.CONDITIONS:
        if progress is not None:
            progress(f"{cond} head: compiling and simulating {traj.duration_s:g} s "
                     f"× {seeds} seed(s)")
        m, s = ekf_runs.run_condition(traj, cond, seeds=seed_list, sensor_noise_std=noise,
                                     model_params=model, t_settle_s=settle_s)
        where = first_non_finite(s, t0)
        if where is not None:
            diverged[cond] = where
        ok = where is None and math.isfinite(m["rms_tilt_error_deg"])
        metrics["max_tilt_error_deg"][cond] = m["max_tilt_error_deg"] if ok else None
        metrics["rms_tilt_error_deg"][cond] = m["rms_tilt_error_deg"] if ok else None
        metrics["rejected_updates"][cond] = m["rejected_updates"]
        series[cond] = s
    rms = metrics["rms_tilt_error_deg"]
    metrics["rms_ratio_stabilized_over_fixed"] = (
        None if diverged else rms["stabilized"] / max(rms["fixed"], 1e-12))
    report = {"input": name if source is None else source, "duration_s": traj.duration_s,
              "rows": int(record.t_s.size), "seeds": seeds, "sensor_noise_std": noise,
              "settle_s": settle_s, "filter_model": "exact" if exact_model else "p13-mismatched",
              **metrics, "diverged": diverged}
    return Comparison(report, series, name, t0, recorded_s, mismatch, t_mismatch,
                      float(np.max(np.diff(record.t_s))))


def plot_comparison(c: Comparison, path) -> Path:
    """P13 Fig. 2's layout for the comparison (:func:`verticality.simulation.ekf_figures.
    plot_fixed_vs_stabilized`), on the file's clock; not for a run in which a head diverged."""
    if c.diverged:
        raise InputError("a head diverged: there is no comparison to plot")
    r = c.report
    mx, rms = r["max_tilt_error_deg"], r["rms_tilt_error_deg"]
    title = (f"{c.name}: tilt error after its first {r['settle_s']:g} s (max / RMS) — fixed "
             f"{mx['fixed']:.2f} / {rms['fixed']:.2f}°, stabilized {mx['stabilized']:.2f} / "
             f"{rms['stabilized']:.2f}°")
    return plot_fixed_vs_stabilized(c.series, title, path, t_settle_s=r["settle_s"],
                                            required_max_deg=None, t0_s=c.t0_s)
