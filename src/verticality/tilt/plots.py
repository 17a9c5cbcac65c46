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
