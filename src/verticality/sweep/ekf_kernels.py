"""Sweep kernels ``ekf-impact`` and ``ekf-jump``: the closed loop of the ekf-* experiments.

The runs are those of :mod:`verticality.simulation.ekf_runs` (P13's gimbal plant ``PLANT``, the
PD of P13 §3 on the estimate when stabilized, the multiplicative EKF with P13's wrong model
``EKF_MODEL``, its process noise ``SIGMA_PROCESS`` and parameter noise, the common initial
covariance, the 0.1 rad initial error), computed by the experiment's own
:func:`~verticality.simulation.ekf_runs.simulate_runs`; the trunk's trajectory is the experiment's
:func:`~verticality.simulation.ekf_runs.scenario_trajectory`. Knobs:

- ``amplitude_scale``, ``frequency_scale``: the trunk motion's amplitudes and frequencies (time
  scale), through the trajectory's parameters (``scenario_trajectory`` says which);
- ``head``: ``fixed`` (gimbal locked) or ``stabilized``;
- ``head_rate_sigma``: σ_ωH, the head-rate process noise per 20 ms step of the run's filter (the
  value ``ekf-sensitivity`` varies for the fixed head; default P13's σ_w = 0.001);
- ``noise_std``: σ of the sensor noise (inclinometer angles, rad; gyro rates, rad/s), in the
  simulation and in the filter's R alike (default P13's 0.02).

The seed is the noise seed (``jax.random.PRNGKey(seed)``, as the experiment's seeds 0, 1, 2).
Option ``quick``: the experiment's quick duration (6 s for both; default the full 10 s
and 8 s). Metrics per run, over the EKF samples at t ≥ 2 s (the experiment's ``T_SETTLE_S``, as
the experiment scores them): ``max_error_deg`` and ``rms_error_deg``, the tilt error of the
estimated head orientation. A run **diverged** if a scored error is non-finite or its max error
exceeds :data:`DIVERGED_DEG` = 30° (the `newton-lissajous` rule: five times the 5.7° initial error
and six times the worst fixed-head max of the ekf-* runs, so an estimate that far off has lost the
head); the errors of a non-finite run are NaN.

Batching: a batch's runs share one trunk trajectory
(:func:`verticality.simulation.ekf_runs.simulate_runs`), so the runs of one batch are grouped by
(``head``, ``amplitude_scale``, ``frequency_scale``) and each group is one ``vmap`` batch over its
seeds, ``head_rate_sigma`` and ``noise_std`` (the filter's Q and R and the noise levels are traced).
The trunk's motion is data of the compiled closed loop
(:func:`verticality.simulation.closed_loop.make_simulator`), so groups of one head and one batch
size share one compilation.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from verticality.analysis.newton_errors import DIVERGED_DEG as NEWTON_DIVERGED_DEG
from verticality.simulation import ekf_runs
from verticality.sweep.kernels import Kernel, Knob, grouped_rows

DIVERGED_DEG = NEWTON_DIVERGED_DEG  # one rule for every kernel: newton-lissajous's
SCALE_LO, SCALE_HI = 0.25, 3.0  # the trunk-motion scales allowed (a jump 4× faster: 4 ms edges)
HEAD_RATE_SIGMA = ekf_runs.SIGMA_PROCESS[3]  # P13 §5's σ_w


def settings(head_rate_sigma, noise_std) -> list[ekf_runs.Setting]:
    """The experiment's :class:`~verticality.simulation.ekf_runs.Setting` of each run: its process
    noise with the head's rate σ replaced, and its sensor noise."""
    return [ekf_runs.Setting(ekf_runs.SIGMA_PROCESS[:3] + (float(s),), float(n))
            for s, n in zip(head_rate_sigma, noise_std, strict=True)]


def run_scenario(scenario: str, columns: dict[str, np.ndarray], seeds: np.ndarray, *,
                 quick: bool) -> dict[str, np.ndarray]:
    """The metrics of the runs ``columns`` × ``seeds`` of ``scenario`` (``impact`` or ``jump``),
    one compiled batch per (head, amplitude_scale, frequency_scale) group, in row order."""
    n = seeds.shape[0]
    out = {"max_error_deg": np.full(n, np.nan), "rms_error_deg": np.full(n, np.nan),
           "diverged": np.zeros(n, dtype=bool)}
    keys = list(zip(columns["head"].astype(str), columns["amplitude_scale"].astype(float),
                    columns["frequency_scale"].astype(float), strict=True))
    for key, rows in grouped_rows(keys):
        head, amplitude, frequency = key
        traj = ekf_runs.scenario_trajectory(scenario, quick, amplitude_scale=amplitude,
                                     frequency_scale=frequency)
        _, per = ekf_runs.simulate_runs(traj, head, settings(columns["head_rate_sigma"][rows],
                                                      columns["noise_std"][rows]),
                                 [int(s) for s in seeds[rows]],
                                 loop_duration_s=ekf_runs.loop_duration_s(quick))
        mx = np.asarray(per["max_tilt_error_deg"], dtype=np.float64)
        rms = np.asarray(per["rms_tilt_error_deg"], dtype=np.float64)
        finite = np.isfinite(mx) & np.isfinite(rms)
        out["max_error_deg"][rows] = np.where(finite, mx, np.nan)
        out["rms_error_deg"][rows] = np.where(finite, rms, np.nan)
        out["diverged"][rows] = ~finite | (np.where(finite, mx, 0.0) > DIVERGED_DEG)
    return out


def _check_options(o: dict[str, Any]) -> str | None:
    if not isinstance(o["quick"], bool):
        return f"quick must be true or false (got {o['quick']!r})"
    return None


def _kernel(scenario: str, figure: str) -> Kernel:
    scale = dict(lo=SCALE_LO, hi=SCALE_HI)
    return Kernel(
        name=f"ekf-{scenario}",
        doc=f"P13's EKF, fixed or stabilized head, the {scenario} trunk motion scaled",
        knobs={
            "amplitude_scale": Knob(1.0, "the trunk motion's amplitudes × this", **scale),
            "frequency_scale": Knob(1.0, "the trunk motion's frequencies × this (durations ÷)",
                                    **scale),
            "head": Knob("fixed", "fixed (gimbal locked) or stabilized (PD on the estimate)",
                         choices=("fixed", "stabilized")),
            "head_rate_sigma": Knob(HEAD_RATE_SIGMA, "the filter's head-rate process σ per 20 ms "
                                    "step (rad/s)", lo=0.0, lo_open=True, hi=1.0),
            "noise_std": Knob(ekf_runs.SIGMA_MEASUREMENT,
                              "sensor noise σ (rad, rad/s), simulation and R",
                              lo=0.0, lo_open=True, hi=1.0),
        },
        options={"quick": False},
        metrics=("max_error_deg", "rms_error_deg"),
        run_batch=lambda columns, seeds, *, quick: run_scenario(scenario, columns, seeds,
                                                                quick=quick),
        check_options=_check_options,
        published={"amplitude_scale": 1.0, "frequency_scale": 1.0},
        published_label=f"P13 {figure} (no numbers; the ekf-{scenario} run)",
    )


EKF_IMPACT = _kernel("impact", "Fig. 2a–c")
EKF_JUMP = _kernel("jump", "Fig. 2d–f")
