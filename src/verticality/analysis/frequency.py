"""Frequency-response identification: PRTS stimulus, transfer function and coherence (T §III.A,
Peterka 2002 J Neurophysiol 88:1097).

The PRTS stimulus itself (the 242-long pseudorandom ternary sequence, velocity held for
Δt = 0.25 s per element, integrated to a lean) is a trajectory:
:func:`verticality.simulation.trajectories.prts_stimulus` and
:func:`verticality.simulation.trajectories.prts`.

* :func:`prts_frequencies` — the odd harmonics of the cycle, where a PRTS has power.
* :func:`cycle_transfer_function` — Peterka's method for a periodic stimulus: one FFT per stimulus
  cycle (rectangular window, no leakage since each cycle is periodic), cross- and auto-spectra
  averaged over cycles, ``H = G_xy / G_xx``, ``γ² = |G_xy|² / (G_xx G_yy)``, at the odd harmonics.
* :func:`welch_transfer_function` — the same estimates for aperiodic (e.g. white-noise) stimuli,
  from SciPy's Welch cross-spectral densities.
* :func:`bode_figure` — gain, phase and coherence against frequency.
"""

from __future__ import annotations

import numpy as np
import scipy.signal

from verticality.core.errors import InputError
from verticality.simulation.trajectories import PRTS_DT_S, PRTS_LENGTH


def prts_frequencies(cycle_s: float = PRTS_LENGTH * PRTS_DT_S, f_max_hz: float = 2.0) -> np.ndarray:
    """The odd harmonics of the cycle frequency up to ``f_max_hz`` (where a PRTS has power)."""
    f0 = 1.0 / cycle_s
    k = np.arange(1, int(f_max_hz / f0) + 1, 2)
    return k * f0


def cycle_transfer_function(x, y, samples_per_cycle: int, fs_hz: float, skip_cycles: int = 1,
                            odd_only: bool = True, end_match: bool = False):
    """Transfer function x → y and coherence from a periodic stimulus (Peterka 2002).

    Returns ``(f_hz, H, coherence)`` at the harmonics (odd ones if ``odd_only``) of the cycle.
    At least two cycles must remain after ``skip_cycles`` (else coherence is trivially 1).

    ``end_match`` subtracts from each cycle of both series the ramp that joins its first sample to
    the first sample of the next cycle. A periodic response has no such ramp (it is unchanged); a
    slow, aperiodic error (a gyro drift below the cycle frequency) would otherwise leak through the
    rectangular window into every harmonic with the same 1/f shape as the PRTS position spectrum.
    Needs one sample beyond the last analysed cycle (the analysed cycles shrink by one if absent).
    """
    x = np.asarray(x, float)
    y = np.asarray(y, float)
    if x.shape != y.shape or x.ndim != 1:
        raise InputError("x and y must be 1-D series of the same length")
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(y))):
        raise InputError("x and y must be finite (NaN samples cannot enter a spectrum)")
    n_cyc = (x.size - (1 if end_match else 0)) // samples_per_cycle - skip_cycles
    if n_cyc < 2:
        raise InputError(f"need at least 2 full cycles after skipping {skip_cycles}, got {n_cyc}")
    start = skip_cycles * samples_per_cycle
    sl = slice(start, start + n_cyc * samples_per_cycle)
    xc = x[sl].reshape(n_cyc, samples_per_cycle)
    yc = y[sl].reshape(n_cyc, samples_per_cycle)
    if end_match:
        nxt = start + samples_per_cycle * np.arange(1, n_cyc + 1)
        ramp = np.arange(samples_per_cycle) / samples_per_cycle
        xc = xc - np.outer(x[nxt] - xc[:, 0], ramp)
        yc = yc - np.outer(y[nxt] - yc[:, 0], ramp)
    X = np.fft.rfft(xc, axis=1)
    Y = np.fft.rfft(yc, axis=1)
    Gxy = np.mean(np.conj(X) * Y, axis=0)
    Gxx = np.mean(np.abs(X) ** 2, axis=0)
    Gyy = np.mean(np.abs(Y) ** 2, axis=0)
    f = np.fft.rfftfreq(samples_per_cycle, 1.0 / fs_hz)
    idx = np.arange(1, f.size, 2) if odd_only else np.arange(1, f.size)
    H = Gxy[idx] / Gxx[idx]
    coh = np.abs(Gxy[idx]) ** 2 / (Gxx[idx] * Gyy[idx])
    return f[idx], H, coh


def welch_transfer_function(x, y, fs_hz: float, nperseg: int = 1024):
    """``(f_hz, H, coherence)`` from Welch cross-spectral densities (Hann window, 50 % overlap)."""
    x = np.asarray(x, float)
    y = np.asarray(y, float)
    if x.shape != y.shape or x.ndim != 1 or x.size < nperseg:
        raise InputError("x and y must be 1-D, of the same length, at least nperseg long")
    f, Pxy = scipy.signal.csd(x, y, fs=fs_hz, nperseg=nperseg)
    _, Pxx = scipy.signal.welch(x, fs=fs_hz, nperseg=nperseg)
    _, Pyy = scipy.signal.welch(y, fs=fs_hz, nperseg=nperseg)
    return f, Pxy / Pxx, np.abs(Pxy) ** 2 / (Pxx * Pyy)


def band_summary(f_hz, H, coh, f_lo: float = 0.05, f_hi: float = 1.0) -> dict:
    """Mean gain, mean |phase| (deg) and mean coherence over ``f_lo ≤ f ≤ f_hi``."""
    sel = (f_hz >= f_lo) & (f_hz <= f_hi)
    return {
        "mean_gain": float(np.mean(np.abs(H[sel]))),
        "mean_abs_phase_deg": float(np.mean(np.abs(np.degrees(np.angle(H[sel]))))),
        "mean_coherence": float(np.mean(coh[sel])),
        "n_frequencies": int(sel.sum()),
    }


def bode_figure(f_hz, gain, phase_deg, coherence, title: str = "", band=(0.05, 1.0),
                published_gain: float | None = 1.0, published_phase_deg: float | None = 0.0):
    """Gain, phase and coherence on a log frequency axis; dashed lines at the published values."""
    from verticality.core.plots import new_figure, published_line

    fig, axes = new_figure(3, 1, width=7.0, height_per_row=2.2)
    ax_g, ax_p, ax_c = axes[:, 0]
    ax_g.semilogx(f_hz, gain, "o-", ms=3, label="simulated")
    ax_p.semilogx(f_hz, phase_deg, "o-", ms=3, label="simulated")
    ax_c.semilogx(f_hz, coherence, "o-", ms=3, label="simulated")
    if published_gain is not None:
        published_line(ax_g, published_gain, label="T Fig. 7 (≈ 1)")
    if published_phase_deg is not None:
        published_line(ax_p, published_phase_deg, label="T Fig. 8 (≈ 0°)")
    for ax in (ax_g, ax_p, ax_c):
        ax.axvspan(*band, color="0.9", zorder=0)
        ax.grid(True, which="both", alpha=0.3)
    ax_g.set_ylabel("gain")
    ax_p.set_ylabel("phase [deg]")
    ax_c.set_ylabel("coherence")
    ax_c.set_ylim(0, 1.05)
    ax_c.set_xlabel("frequency [Hz]")
    ax_g.legend(loc="best", fontsize=8)
    ax_p.legend(loc="best", fontsize=8)
    if title:
        ax_g.set_title(title)
    return fig
