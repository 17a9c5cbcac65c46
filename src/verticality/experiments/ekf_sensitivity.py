"""`ekf-sensitivity`: what the EKF's stabilization benefit in `ekf-impact`/`ekf-jump` depends on.

The three one-at-a-time sweeps (the fixed head's head-rate process noise, the jump's trunk pitch,
the sensor noise) and their metrics are those of :mod:`verticality.simulation.ekf_ratio_sweeps`;
this module runs them and draws the ratio against each swept value. No pass/fail check: this is
the analysis behind the ekf-* numbers (docs/ekf.md), not a published figure.
"""

from __future__ import annotations

import time
from pathlib import Path

from verticality.core import plots
from verticality.experiments import Result, register
from verticality.simulation.ekf_ratio_sweeps import DEFAULT_PITCH_RAD, P13_SIGMA_W, run_sweeps
from verticality.simulation.ekf_runs import SEEDS, SIGMA_MEASUREMENT


@register("ekf-sensitivity", "What the EKF's fixed-vs-stabilized ratio depends on "
          "(head-rate noise, jump pitch, sensor noise)",
          source="P13 §5 (analysis of ekf-impact / ekf-jump)",
          figures=lambda r, d: _figures(r, d))
def run_sensitivity(quick: bool = False) -> Result:
    """Full: 3 seeds, all three sweeps (22 closed-loop runs, each a batch of its seeds on the
    closed loops `ekf-impact` and `ekf-jump` compile). Quick: 1 seed, the ekf-jump quick duration,
    the head-rate sweep of the jump at two values (3 runs)."""
    t0 = time.perf_counter()
    sweeps, simulated_s = run_sweeps(quick)
    metrics = dict(sweeps)
    metrics["seeds"] = list(SEEDS[:1] if quick else SEEDS)
    paper = {"note": "P13 §5 uses σ_w = 0.001 for every process-noise element and gives no trunk "
                     "rotation for the jump; the checks ask rms_ratio ≤ 1/3 (impact) and ≤ 1/2 "
                     "(jump) at the ekf-* setting "
                     f"(σ_ωH = {P13_SIGMA_W:g}, pitch {DEFAULT_PITCH_RAD:g} rad, noise "
                     f"{SIGMA_MEASUREMENT:g})"}
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
    """One panel per sweep present (quick: the head-rate sweep only): the RMS ratio
    (stabilized / fixed) against the swept value, with the impact check's 1/3 line and the ekf-*
    setting marked."""
    m = result.metrics
    panels = [("fixed_head_rate_sigma", "sigma_", "",
               "fixed head's head-rate noise σ_ωH (rad/s per step)",
               P13_SIGMA_W, "P13 σ_w (ekf-*)", True),
              ("jump_pitch", "pitch_", "_rad", "jump: trunk pitch (rad)", DEFAULT_PITCH_RAD,
               "ekf-jump setting", False),
              ("sensor_noise", "noise_", "", "jump: sensor noise σ (simulation and R)",
               SIGMA_MEASUREMENT, "ekf-jump setting", True)]
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
