"""`ekf-sensitivity`: what the EKF's stabilization benefit in `ekf-impact` and `ekf-jump` depends on.

The ekf-* experiments score the ratio of the stabilized head's RMS tilt error (after 2 s) to the
fixed head's (the jump's check asks ≤ 1/2, the impact's ≤ 1/3). Three one-at-a-time sweeps around their setting (same plant,
filter, seeds and trajectories as :mod:`verticality.experiments.ekf`; one value changed at a time):

1. **The fixed head's head-rate process noise** σ_ωH (rad/s per 20 ms EKF step), impact and jump.
   In the fixed condition the gimbal is locked and the filter's free-head model receives no torque:
   the trunk's torque on the head is unknown. σ_ωH is how much angular acceleration the filter
   admits it does not model (σ_ωH/Δt = 0.015 … 5 rad/s² over the sweep). The ekf-* experiments use
   P13 §5's σ_w = 0.001 in both conditions; the stabilized head's filter (whose torque is known) is
   the same in every row.
2. **The trunk's pitch during the jump** (rad; ekf-jump: 0.2). P13 gives the jump's translation
   only; the trunk's rotation is this project's choice (:func:`verticality.simulation.trajectories.jump`).
3. **Sensor noise** σ on the two inclinometer angles (rad) and the three gyro rates (rad/s), in
   the simulation and in the filter's R alike (P13 §5: 0.02), jump.

Metrics per row: ``fixed_max_deg``, ``fixed_rms_deg``, ``stabilized_max_deg``,
``stabilized_rms_deg``, ``rms_ratio`` (stabilized / fixed). No pass/fail check: this is the
analysis behind the ekf-* numbers (docs/ekf.md), not a published figure.
"""

from __future__ import annotations

import inspect
import time
from pathlib import Path

from verticality.core import plots
from verticality.experiments import Result, register
from verticality.experiments import ekf as ekf_exp
from verticality.simulation import trajectories

HEAD_RATE_SIGMAS = (3e-4, 1e-3, 3e-3, 1e-2, 3e-2)
HEAD_RATE_SIGMAS_QUICK = (1e-3, 3e-2)
JUMP_PITCHES_RAD = (0.1, 0.2, 0.3, 0.4)
SENSOR_NOISE_STDS = (0.005, 0.01, 0.02)
P13_SIGMA_W = ekf_exp.SIGMA_PROCESS[3]
DEFAULT_PITCH_RAD = inspect.signature(trajectories.jump).parameters["pitch_rad"].default  # ekf-jump's


def _row(fixed: dict, stabilized: dict) -> dict:
    return {"fixed_max_deg": fixed["max_tilt_error_deg"], "fixed_rms_deg": fixed["rms_tilt_error_deg"],
            "stabilized_max_deg": stabilized["max_tilt_error_deg"],
            "stabilized_rms_deg": stabilized["rms_tilt_error_deg"],
            "rms_ratio": stabilized["rms_tilt_error_deg"] / max(fixed["rms_tilt_error_deg"], 1e-12)}


def _plan(quick: bool) -> dict:
    """The sweeps' layout: ``{sweep: {scenario: {row label: (fixed run, stabilized run)}}}``, a
    run being ``(scenario, condition, σ_ωH, pitch, noise)``."""

    def runs(scenario, sigma_head_rate=P13_SIGMA_W, pitch=DEFAULT_PITCH_RAD, noise=ekf_exp.SIGMA_MEASUREMENT,
             stabilized_sigma=P13_SIGMA_W):
        return ((scenario, "fixed", sigma_head_rate, pitch, noise),
                (scenario, "stabilized", stabilized_sigma, pitch, noise))

    sigmas = HEAD_RATE_SIGMAS_QUICK if quick else HEAD_RATE_SIGMAS
    plan: dict = {"fixed_head_rate_sigma": {
        scenario: {f"sigma_{s:g}": runs(scenario, sigma_head_rate=s) for s in sigmas}
        for scenario in (("jump",) if quick else ("impact", "jump"))}}
    if not quick:
        plan["jump_pitch"] = {"jump": {f"pitch_{p:g}_rad": runs("jump", pitch=p)
                                       for p in JUMP_PITCHES_RAD}}
        plan["sensor_noise"] = {"jump": {f"noise_{n:g}": runs("jump", noise=n)
                                         for n in SENSOR_NOISE_STDS}}
    return plan


def run_sweeps(quick: bool = False, progress=None) -> tuple[dict, float]:
    """The three sweeps; returns ``({sweep: {scenario: {row key: row}}}, simulated seconds)``.

    Each distinct run is computed once (the ekf-* setting is shared between sweeps), and the runs
    that differ only in the filter's process noise or the sensor noise (same scenario, condition
    and trunk pitch) share one compiled simulator, batched under ``vmap``
    (:func:`verticality.experiments.ekf.run_settings`): compiling dominates a run. ``progress``: an
    optional callable given a short label before each compiled batch."""
    seeds = ekf_exp.SEEDS[:1] if quick else ekf_exp.SEEDS
    plan = _plan(quick)
    groups: dict = {}  # (scenario, condition, pitch) -> distinct runs, in plan order
    for table in plan.values():
        for rows in table.values():
            for pair in rows.values():
                for run in pair:
                    group = groups.setdefault((run[0], run[1], run[3]), [])
                    if run not in group:
                        group.append(run)
    metrics: dict = {}
    simulated_s = 0.0
    for (scenario, condition, pitch), runs in groups.items():
        if progress is not None:
            progress(f"{scenario} {condition} pitch={pitch:g}: {len(runs)} setting(s)")
        traj = ekf_exp.scenario_trajectory(
            scenario, quick, **({"pitch_rad": pitch} if scenario == "jump" else {}))
        settings = [ekf_exp.Setting(ekf_exp.SIGMA_PROCESS[:3] + (sigma,), noise)
                    for _, _, sigma, _, noise in runs]
        results = ekf_exp.run_settings(traj, condition, settings, seeds=seeds)
        for run, (m, _) in zip(runs, results, strict=True):
            metrics[run] = m
        simulated_s += traj.duration_s * len(seeds) * len(runs)
    out = {sweep: {scenario: {label: _row(metrics[fixed], metrics[stab])
                              for label, (fixed, stab) in rows.items()}
                   for scenario, rows in table.items()}
           for sweep, table in plan.items()}
    return out, simulated_s


@register("ekf-sensitivity", "What the EKF's fixed-vs-stabilized ratio depends on (head-rate noise, "
          "jump pitch, sensor noise)", source="P13 §5 (analysis of ekf-impact / ekf-jump)",
          figures=lambda r, d: _figures(r, d))
def run_sensitivity(quick: bool = False) -> Result:
    """Full: 3 seeds, all three sweeps (22 closed-loop runs in 10 compiled batches). Quick: 1 seed,
    the ekf-jump quick duration, the head-rate sweep of the jump at two values (3 runs, 2 batches)."""
    t0 = time.perf_counter()
    sweeps, simulated_s = run_sweeps(quick)
    metrics = dict(sweeps)
    metrics["seeds"] = list(ekf_exp.SEEDS[:1] if quick else ekf_exp.SEEDS)
    paper = {"note": "P13 §5 uses σ_w = 0.001 for every process-noise element and gives no trunk "
                     "rotation for the jump; the checks ask rms_ratio ≤ 1/3 (impact) and ≤ 1/2 (jump) at the ekf-* setting "
                     f"(σ_ωH = {P13_SIGMA_W:g}, pitch {DEFAULT_PITCH_RAD:g} rad, noise "
                     f"{ekf_exp.SIGMA_MEASUREMENT:g})"}
    return Result(metrics=metrics, paper=paper, simulated_s=simulated_s,
                  notes=f"wall {time.perf_counter() - t0:.1f} s")


def _plot_ratio(ax, table: dict, prefix: str, suffix: str, color: str, label: str):
    """The rms ratio against the swept value, each point labelled with the fixed head's RMS."""
    xs = [float(k[len(prefix):len(k) - len(suffix)]) for k in table]
    ys = [row["rms_ratio"] for row in table.values()]
    ax.plot(xs, ys, "o-", color=color, label=label)
    for x, y, row in zip(xs, ys, table.values(), strict=True):
        ax.annotate(f"{row['fixed_rms_deg']:.2f}°", (x, y), textcoords="offset points",
                    xytext=(4, 4), fontsize=6, color=color)


def _figures(result: Result, out_dir: Path) -> list[Path]:
    """One panel per sweep present (quick: the head-rate sweep only): the RMS ratio (stabilized /
    fixed) against the swept value, with the impact check's 1/3 line and the ekf-* setting marked."""
    m = result.metrics
    panels = [("fixed_head_rate_sigma", "sigma_", "", "fixed head's head-rate noise σ_ωH (rad/s per step)",
               P13_SIGMA_W, "P13 σ_w (ekf-*)", True),
              ("jump_pitch", "pitch_", "_rad", "jump: trunk pitch (rad)", DEFAULT_PITCH_RAD,
               "ekf-jump setting", False),
              ("sensor_noise", "noise_", "", "jump: sensor noise σ (simulation and R)",
               ekf_exp.SIGMA_MEASUREMENT, "ekf-jump setting", True)]
    panels = [p for p in panels if p[0] in m]
    fig, axes = plots.new_figure(1, len(panels), width=4.4 * len(panels), height_per_row=3.6,
                                 sharex=False)
    for ax, (key, prefix, suffix, xlabel, default, default_label, log_x) in zip(axes[0], panels,
                                                                                  strict=True):
        for scenario, c in (("impact", "C0"), ("jump", "C3")):
            if scenario in m[key]:
                _plot_ratio(ax, m[key][scenario], prefix, suffix, c, scenario)
        ax.axvline(default, color="0.6", lw=0.8, ls=":", label=default_label)
        plots.published_line(ax, 1.0 / 3.0, label="impact check: ≤ 1/3")
        if log_x:
            ax.set_xscale("log")
        ax.set_xlabel(xlabel)
        ax.set_ylim(0.0, 1.2)
        ax.legend(fontsize=7, loc="upper left")
    axes[0, 0].set_ylabel("RMS tilt error, stabilized / fixed")
    axes[0, 0].set_title("ekf-sensitivity (point labels: the fixed head's RMS)", fontsize=9,
                         loc="left")
    return [plots.save(fig, Path(out_dir) / "ekf-sensitivity.png")]
