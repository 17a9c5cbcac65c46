"""The figure of a tilt estimate over time (``verticality estimate --plot``): roll and pitch, the
gyro bias, our filter's σ of the tilt, and one row per flag bit that occurs."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from verticality.tilt.flags import FLAG_NAMES, REACQUIRING
from verticality.tilt.params import DEFAULT_PARAMS


def flag_runs(flags, bit):
    """(first, last) sample indices of each run of consecutive samples carrying ``bit``."""
    on = np.concatenate([[0], (np.asarray(flags) & bit) > 0, [0]]).astype(int)
    return np.flatnonzero(np.diff(on) == 1), np.flatnonzero(np.diff(on) == -1) - 1


def shade_reacquiring(ax, t, flags) -> None:
    """Shade the spans from the start or a gap to the tilt's re-acquisition (flag REACQUIRING)."""
    starts, lasts = flag_runs(flags, REACQUIRING)
    for j, (a, b) in enumerate(zip(starts, lasts + 1, strict=True)):
        ax.axvspan(t[a], t[min(b, t.size - 1)], color="0.85", zorder=0,
                   label="re-acquiring (after the start or a gap)" if j == 0 else None)


def plot_sigma(ax, t, sigma_rad, flags, params=DEFAULT_PARAMS) -> None:
    """The tilt's standard deviation on a log scale (it spans ~0.3° at rest to tens of degrees
    after the start or a gap), with the accelerometer-calibration floor it never goes below."""
    p = params
    ax.semilogy(t, np.degrees(sigma_rad), color="C3", label="tilt σ")
    ax.axhline(np.degrees(p.acc_calib_m_s2 / p.g_m_s2), color="0.4", linestyle=":",
               label=f"accelerometer calibration ({p.acc_calib_m_s2:g} m/s²)")
    shade_reacquiring(ax, t, flags)
    ax.set_ylabel("tilt σ (deg)")
    ax.legend(loc="upper right")


def plot_flags(ax, t, flags) -> None:
    """One row per flag bit that occurs: a bar over each run of flagged samples and a tick at
    its start (one-sample events, such as a gap, stay visible); the row's label gives the bit and
    the number of samples."""
    rows = [(bit, name) for bit, name in FLAG_NAMES.items() if np.any(flags & bit)]
    for y, (bit, _) in enumerate(rows):
        starts, lasts = flag_runs(flags, bit)
        ax.hlines(np.full(starts.size, y), t[starts], t[lasts], linewidth=6, color=f"C{y % 10}")
        ax.plot(t[starts], np.full(starts.size, y), "|", markersize=10, color=f"C{y % 10}")
    ax.set_yticks(range(len(rows)),
                  [f"{name} ({bit}): {np.count_nonzero(flags & bit)}" for bit, name in rows])
    ax.set_ylim(-0.6, max(len(rows), 1) - 0.4)
    ax.set_title("flags (samples)" if rows else "flags: none", fontsize="medium")


def plot_estimate(path: Path, t, out, name: str, sigma_rad=None) -> Path:
    """Draw ``out`` (a ``TiltOutput``) of filter ``name`` over time ``t`` into ``path``: roll and
    pitch, the bias, the σ (when given) and the flags. Returns the path written."""
    from verticality.core.plots import new_figure, save

    fig, axes = new_figure(3 if sigma_rad is None else 4, 1, height_per_row=2.2)
    ax = axes[:, 0]
    ax[0].plot(t, np.degrees(out.roll_rad), label="roll")
    ax[0].plot(t, np.degrees(out.pitch_rad), label="pitch")
    ax[0].set_ylabel("angle (deg)")
    flags = np.asarray(out.flags)
    shade_reacquiring(ax[0], t, flags)
    ax[0].legend(loc="upper right")
    ax[0].set_title(f"tilt estimate ({name})")
    for i, c in enumerate("xyz"):
        ax[1].plot(t, np.degrees(out.bias_S_rad_s[:, i]), label=f"bias {c}")
    ax[1].set_ylabel("gyro bias (deg/s)")
    ax[1].legend(loc="upper right")
    if sigma_rad is not None:
        plot_sigma(ax[2], t, sigma_rad, flags)
    plot_flags(ax[-1], t, flags)
    ax[-1].set_xlabel("t (s)")
    return save(fig, path)


def shade_rest(ax, t, at_rest) -> None:
    """Shade the spans where the IMU is still (a comparison's ``at_rest``)."""
    starts, lasts = flag_runs(np.asarray(at_rest).astype(int), 1)
    for j, (a, b) in enumerate(zip(starts, lasts, strict=True)):
        ax.axvspan(t[a], t[b], color="#dde8f3", zorder=0, label="at rest" if j == 0 else None)


def plot_log_comparison(path: Path, comp, out, name: str) -> Path:
    """Our estimate beside a log's own (``comp``, :class:`verticality.tilt.logs.LogComparison`):
    roll and pitch of each, the angle between the up vectors, and our flags. Returns the path
    written."""
    from verticality.core.plots import new_figure, save

    c = comp.columns
    t = np.asarray(c["t"])
    refs = [(r, comp.summary[r]["name"]) for r in ("log", "truth") if r in comp.summary]
    fig, axes = new_figure(4, 1, height_per_row=2.2)
    ax = axes[:, 0]
    for i, angle in enumerate(("roll", "pitch")):
        for r, label in refs:
            ax[i].plot(t, np.degrees(c[f"{r}_{angle}_rad"]), label=label,
                       color="0.2" if r == "truth" else "C1", linewidth=1.0)
        ax[i].plot(t, np.degrees(c[f"{angle}_rad"]), label=name, color="C0", linewidth=0.8)
        ax[i].set_ylabel(f"{angle} (deg)")
        shade_rest(ax[i], t, c["at_rest"])
        ax[i].legend(loc="upper right", fontsize="small")
    ax[0].set_title(f"{name} beside the log's own estimate (our convention: Earth z up)")
    for r, label in refs:
        ax[2].plot(t, np.degrees(c[f"{r}_angle_rad"]), label=f"{name} vs {label}",
                   color="0.2" if r == "truth" else "C1", linewidth=0.8)
    if "log_truth_angle_rad" in c:
        ax[2].plot(t, np.degrees(c["log_truth_angle_rad"]), label=f"{refs[0][1]} vs "
                   f"{refs[1][1]}", color="C2", linewidth=0.8)
    ax[2].set_ylabel("angle between\nup vectors (deg)")
    shade_rest(ax[2], t, c["at_rest"])
    ax[2].legend(loc="upper right", fontsize="small")
    plot_flags(ax[3], t, np.asarray(out.flags))
    ax[3].set_xlabel("t (s)")
    return save(fig, path)
