"""`ekf-impact` and `ekf-jump`: the EKF on the gimbal head, fixed vs stabilized (P13 §5, F §4.2.2).

The runs, their settings and the readings where the papers are silent are those of
:mod:`verticality.simulation.ekf_runs`; this module runs them for each reading, scores the ratio
of the stabilized head's RMS tilt error to the fixed head's and draws P13 Fig. 2.
"""

from __future__ import annotations

import time
from pathlib import Path

from verticality.experiments import Result, check, register
from verticality.simulation import closed_loop as sim
from verticality.simulation.ekf_figures import plot_fixed_vs_stabilized
from verticality.simulation.ekf_runs import (
    SEEDS,
    SIGMA_PROCESS,
    SIGMA_PROCESS_CONSTANT,
    loop_duration_s,
    run_condition,
    scenario_trajectory,
)

PAPER_NOTE = "P13 Fig. 2: errors much smaller when stabilized (no numbers published)"
# Pass/fail check on the RMS ratio stabilized / fixed (thresholds, not metrics). P13 calls the
# impact's errors "much smaller" and the jump's "also smaller" when stabilized, without numbers.
# The jump's ratio at P13's stated settings is 0.43 (ekf-sensitivity shows how it depends on the
# trunk's pitch and on the fixed head's filter); the check accepts it with <= 1/2.
RATIO_LIMIT = {"impact": 1.0 / 3.0, "jump": 1.0 / 2.0}
RATIO_LIMIT_TEXT = {"impact": "1/3", "jump": "1/2"}


def _experiment(traj, quick: bool, scenario: str) -> Result:
    t0 = time.perf_counter()
    metrics: dict = {"max_tilt_error_deg": {}, "rms_tilt_error_deg": {}}
    series: dict = {}
    seeds = SEEDS[:1] if quick else SEEDS
    # (suffix, variant, torque reading, process noise, acceleration frame, P0, parameter noise)
    runs = [("", "multiplicative", "gimbal", SIGMA_PROCESS, "inertial", "common", True)]
    if not quick:
        runs += [("_head_frame_accel", "multiplicative", "gimbal", SIGMA_PROCESS, "head",
                  "common", True),
                 ("_total_torque", "multiplicative", "total", SIGMA_PROCESS, "inertial",
                  "common", True),
                 ("_constant_q", "multiplicative", "gimbal", SIGMA_PROCESS_CONSTANT, "inertial",
                  "common", False),
                 ("_stacked", "stacked", "gimbal", None, "inertial", "common", False)]
    for suffix, variant, torque, sig, frame, p0, consider in runs:
        mx, rms = f"max_tilt_error_deg{suffix}", f"rms_tilt_error_deg{suffix}"
        metrics.setdefault(mx, {})
        metrics.setdefault(rms, {})
        for cond in sim.CONDITIONS:
            m, s = run_condition(traj, cond, variant, torque, sig, seeds, frame, p0, consider,
                                 loop_duration_s=loop_duration_s(quick))
            metrics[mx][cond] = m["max_tilt_error_deg"]
            metrics[rms][cond] = m["rms_tilt_error_deg"]
            metrics.setdefault(f"max_tilt_error_deg_per_seed{suffix}", {})[cond] = (
                m["max_tilt_error_deg_per_seed"])
            metrics.setdefault(f"orthonormality_error_max{suffix}", {})[cond] = (
                m["orthonormality_error_max"])
            metrics.setdefault(f"rejected_updates{suffix}", {})[cond] = m["rejected_updates"]
            series[f"{cond}{suffix}"] = s
        metrics[f"rms_ratio{suffix}"] = (metrics[rms]["stabilized"]
                                         / max(metrics[rms]["fixed"], 1e-12))
    metrics["seeds"] = list(seeds)
    mx, rms = metrics["max_tilt_error_deg"], metrics["rms_tilt_error_deg"]
    ratio = rms["stabilized"] / max(rms["fixed"], 1e-12)
    limit = RATIO_LIMIT[scenario]
    metrics["rms_ratio_stabilized_over_fixed"] = check(ratio, limit, ratio <= limit)
    metrics["stabilized_max_le_1deg"] = check(mx["stabilized"], 1.0, mx["stabilized"] <= 1.0)
    claim = "'much smaller'" if scenario == "impact" else "'also smaller'"
    paper = {
        "max_tilt_error_deg": {"fixed": "no number (Fig. 2)",
                               "stabilized": f"P13: {claim} than fixed"},
        "rms_tilt_error_deg": {"fixed": "no number (Fig. 2)",
                               "stabilized": f"P13: {claim} than fixed"},
        "rms_ratio_stabilized_over_fixed": f"check <= {RATIO_LIMIT_TEXT[scenario]}; P13: {claim}",
        "stabilized_max_le_1deg": "check <= 1 deg after 2 s",
        "note": PAPER_NOTE,
    }
    return Result(metrics=metrics, paper=paper, series=series, simulated_s=float(traj.duration_s),
                  notes=f"wall {time.perf_counter() - t0:.1f} s")


def _figures(result: Result, out_dir: Path, name: str) -> list[Path]:
    """P13 Fig. 2: true and estimated tilt (θx, θy), fixed vs stabilized, and the tilt error."""
    mx, rms = result.metrics["max_tilt_error_deg"], result.metrics["rms_tilt_error_deg"]
    title = (f"{name}: max/rms tilt error after 2 s — fixed {mx['fixed']:.2f}/{rms['fixed']:.2f}°, "
             f"stabilized {mx['stabilized']:.2f}/{rms['stabilized']:.2f}° (P13 Fig. 2: "
             + ("'much smaller')" if name == "ekf-impact" else "'also smaller')"))
    return [plot_fixed_vs_stabilized(result.series, title, Path(out_dir) / f"{name}.png")]


def _figures_impact(result, out_dir):
    return _figures(result, out_dir, "ekf-impact")


def _figures_jump(result, out_dir):
    return _figures(result, out_dir, "ekf-jump")


@register("ekf-impact", "EKF on SO(3), scenario A: 3-D oscillation and 30 m/s² impact, "
          "fixed vs stabilized",
          source="P13 §5 Fig. 2a–c, F §4.2.2 Fig. 4.2", figures=_figures_impact)
def run_impact(quick: bool = False) -> Result:
    """P13 scenario A. ``quick``: 6 s (the impact at 5 s and the stop included), one seed,
    multiplicative EKF only."""
    return _experiment(scenario_trajectory("impact", quick), quick, "impact")


@register("ekf-jump", "EKF on SO(3), scenario B: forward jump, fixed vs stabilized",
          source="P13 §5 Fig. 2d–f, F §4.2.2 Fig. 4.3", figures=_figures_jump)
def run_jump(quick: bool = False) -> Result:
    """P13 scenario B, the push at 3 s. ``quick``: 6 s, one seed, multiplicative EKF only."""
    return _experiment(scenario_trajectory("jump", quick), quick, "jump")
