"""The figure of the ekf-* runs (P13 Fig. 2's layout), shared by `ekf-impact`, `ekf-jump` and
`stabilize`."""

from __future__ import annotations

from pathlib import Path

from verticality.core import plots
from verticality.simulation.ekf_runs import T_SETTLE_S


def plot_fixed_vs_stabilized(series: dict, title: str, path, *, t_settle_s: float = T_SETTLE_S,
                             required_max_deg: float | None = 1.0, t0_s: float = 0.0) -> Path:
    """P13 Fig. 2's layout: the trunk's acceleration; true and estimated tilt (θx, θy) of the fixed
    and the stabilized head; both heads' tilt errors (log scale; the stacked EKF's too when
    ``series`` has them), the settling time and, unless None, the required stabilized maximum.
    ``t0_s`` is added to the time axis (a recording's own clock)."""
    fig, axes = plots.new_figure(4, 1, width=9.0, height_per_row=2.2)
    s0 = series["fixed"]
    ax = axes[0, 0]
    ax.plot(t0_s + s0["t_s"], s0["a_I_m_s2"], lw=0.8)
    ax.set_ylabel("trunk accel. (m/s²)")
    ax.legend(["x", "y", "z"], fontsize=7, ncol=3, loc="upper right")
    for row, cond in ((1, "fixed"), (2, "stabilized")):
        s = series[cond]
        ax = axes[row, 0]
        for i, (c, lab) in enumerate((("C0", "θx"), ("C3", "θy"))):
            ax.plot(t0_s + s["t_s"], s["tilt_true_deg"][:, i], color=c, lw=1.0, label=f"{lab} true")
            ax.plot(t0_s + s["t_s"], s["tilt_est_deg"][:, i], color=c, lw=1.0, ls="--",
                    label=f"{lab} EKF")
        ax.set_ylabel(f"{cond}: tilt (deg)")
        ax.legend(fontsize=7, ncol=4, loc="upper right")
    ax = axes[3, 0]
    for key, c in (("fixed", "C1"), ("stabilized", "C2"), ("fixed_stacked", "0.6"),
                   ("stabilized_stacked", "0.3")):
        if key in series:
            s = series[key]
            ax.plot(t0_s + s["t_s"], s["tilt_error_deg"], color=c, lw=0.9,
                    label=key.replace("_", " "))
    if required_max_deg is not None:
        plots.published_line(ax, required_max_deg,
                             label=f"required max, stabilized (t ≥ {t_settle_s:g} s)")
    ax.axvline(t0_s + t_settle_s, color="0.7", lw=0.8)
    ax.set_yscale("log")
    ax.set_ylim(1e-2, None)
    ax.set_ylabel("tilt error (deg)")
    ax.set_xlabel("time (s)")
    ax.legend(fontsize=7, ncol=3, loc="upper right")
    axes[0, 0].set_title(title, fontsize=9)
    return plots.save(fig, path)
