"""Tahboub's stand-alone otolith–canal Kalman filter on PostuRob (T §II.A, §III.A.1, eq. 20–22,
Fig. 5–8): ``tahboub-gains``, ``tahboub-step``, ``tahboub-sine``, ``tahboub-prts``.

Readings and choices (the paper leaves them open; docs/reproduction.md fixes the first ones):

* Filter: F_v, H_v of T eq. 7–8 with g = ``G_M_S2``, measurement order ``(ω_g, a_xa)``, Q and R of
  T eq. 20–21 read as continuous noise intensities; steady-state gain from the CARE (T eq. 10–11).
  Run in its steady-state form (T eq. 9), discretized exactly at 100 Hz with the samples held.
  Started at the true initial lean (``phi0_rad``; 0 here, the body starts upright), ω̂0 = 0, no
  drift: with T's slow accelerometer weighting a wrong start takes ~25 s to forget, and a start
  levelled from the first accelerometer sample is spoiled by the body's own acceleration.
* Body: a single inverted pendulum about the ankle (PostuRob), sensors 0.325 m above the ankle.
  The robot follows its command through a critically damped 2nd-order servo with natural frequency
  ω_n = 11.2 rad/s (10–90 % rise time ≈ 0.3 s); the actual lean and its exact first and second
  derivatives come from that servo. The accelerometer reads ``g sin φ − h φ̈`` (physical sign;
  see :mod:`verticality.models.body`), the gyro ``φ̇ + drift + noise``.
* Sensor noise (docs/reproduction.md): gyro white σ = 3.2e-3 rad/s per 100 Hz sample, drift a random
  walk of intensity 1e-6 rad²/s³ starting at 0; accelerometer white σ = 0.05 m/s². Seeded with
  ``jax.random`` keys (one fixed seed per experiment).
* Step: 5° step commanded at t = 2 s, 20 s run (quick 8 s). Sine: 5°, 0.2 Hz, 60 s (quick 20 s).
* PRTS: the 242-long ternary m-sequence, Δt = 0.25 s, cycle 60.5 s, velocity levels ±v scaled so
  the lean spans ±5° (:func:`prts_command`: the lean of `verticality motion prts`, sampled at
  100 Hz, :func:`verticality.simulation.trajectories.prts_stimulus`); 6 cycles (quick 3), the first
  discarded as a transient; transfer function actual → estimated lean and coherence from
  cross-spectra averaged over cycles at the odd harmonics (Peterka 2002). Each cycle is
  end-matched before its FFT (``cycle_transfer_function(end_match=True)``): the gyro drift makes
  the estimate's error a slow random walk with T's weak accelerometer weighting (R = 10), and a
  ramp within a 60.5 s cycle leaks through the rectangular window into every harmonic with the
  same 1/f shape as the stimulus. Without end matching the in-band coherence depends on the drift
  realization (0.71–0.98 over seeds 7–9); ``mean_coherence_no_end_match`` reports it.
* Errors are taken after t ≥ 1 s (docs/reproduction.md default).
"""

from __future__ import annotations

from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from verticality.analysis import frequency
from verticality.core.constants import G_M_S2
from verticality.core.integrate import zoh
from verticality.estimators import otolith_canal
from verticality.experiments import Result, check, register
from verticality.models import tahboub
from verticality.models.body import POSTUROB, SingleSegmentBody
from verticality.sensors import readings
from verticality.simulation.trajectories import PRTS_DT_S, PRTS_LENGTH, prts_stimulus

FS_HZ = 100.0
SERVO_WN_RAD_S = 11.2
GYRO_SIGMA_RAD_S = 3.2e-3
DRIFT_INTENSITY = 1e-6  # rad^2/s^3
ACC_SIGMA_M_S2 = 0.05
SETTLE_S = 1.0
SOURCE = "T §III.A, eq. 20–22, Fig. 5–8"


# --------------------------------------------------------------------------- simulation


def servo_response(command_rad, fs_hz: float = FS_HZ, wn: float = SERVO_WN_RAD_S):
    """Actual lean ``(φ, φ̇, φ̈)`` of the critically damped servo following ``command_rad`` (held)."""
    M = jnp.array([[0.0, 1.0], [-wn**2, -2.0 * wn]])
    N = jnp.array([[0.0], [wn**2]])
    Phi, Gam = zoh(M, N, 1.0 / fs_hz)
    cmd = jnp.asarray(command_rad, float)

    def body(s, r):
        acc = wn**2 * (r - s[0]) - 2.0 * wn * s[1]
        return Phi @ s + Gam[:, 0] * r, jnp.array([s[0], s[1], acc])

    _, out = jax.lax.scan(body, jnp.zeros(2), cmd)
    return out[:, 0], out[:, 1], out[:, 2]


def sensor_readings(key, phi, phi_dot, phi_ddot, fs_hz: float = FS_HZ,
                    body: SingleSegmentBody = POSTUROB):
    """Noisy ``(ω_g, a_xa)`` samples (n, 2) and the true drift (n,)."""
    n = phi.shape[0]
    k_drift, k_gyro, k_acc = jax.random.split(key, 3)
    steps = readings.random_walk_increments(k_drift, (n,), DRIFT_INTENSITY, 1.0 / fs_hz)
    drift = readings.random_walk(steps.at[0].set(0.0))  # the drift starts at 0 at the first sample
    omega, a_x = body.sensors(phi, phi_dot, phi_ddot)
    gyro_params = readings.GyroParams(GYRO_SIGMA_RAD_S, DRIFT_INTENSITY)
    gyro = readings.gyro_reading(omega, drift, readings.gyro_white_noise(k_gyro, (n,), gyro_params))
    acc = readings.white(k_acc, a_x, ACC_SIGMA_M_S2)
    return jnp.stack([gyro, acc], axis=1), drift


def estimate_lean(ys, fs_hz: float = FS_HZ, form: str = "steady", phi0_rad: float = 0.0,
                  omega0_rad_s: float = 0.0):
    """Run the otolith–canal filter on samples ``ys`` (n, 2); estimate aligned with the samples.

    The steady-state form holds sample k over [t_k, t_k+1) and returns x̂(t_k+1); the estimate at
    t_0 is the initial state ``(phi0_rad, omega0_rad_s, 0)``. The time-varying form updates with
    sample k at t_k.
    """
    dt = 1.0 / fs_hz
    x0 = jnp.array([phi0_rad, omega0_rad_s, 0.0])
    if form == "steady":
        est = otolith_canal.steady_state_filter()
        _, out = est.run(est.init(x0), None, ys, dt)
        return jnp.concatenate([x0[None, :], out.x[:-1]], axis=0)
    est = otolith_canal.time_varying_filter()
    P0 = jnp.diag(jnp.array([(5.0 * np.pi / 180) ** 2, 1e-2, 1e-4]))
    _, out = est.run(est.init(x0, P0), None, ys, dt)
    return out.x


def _rms_deg(err_rad, t, settle=SETTLE_S):
    sel = np.asarray(t) >= settle
    return float(np.degrees(np.sqrt(np.mean(np.asarray(err_rad)[sel] ** 2))))


def _lean_experiment(command, seed: int, extra_forms: bool = False):
    phi, phi_dot, phi_ddot = servo_response(command)
    ys, drift = sensor_readings(jax.random.PRNGKey(seed), phi, phi_dot, phi_ddot)
    x_hat = estimate_lean(ys)
    t = np.arange(phi.shape[0]) / FS_HZ
    series = {"t_s": t, "phi_rad": np.asarray(phi), "phi_hat_rad": np.asarray(x_hat[:, 0]),
              "drift_rad_s": np.asarray(drift), "drift_hat_rad_s": np.asarray(x_hat[:, 2])}
    metrics = {"rms_error_deg": _rms_deg(x_hat[:, 0] - phi, t)}
    if extra_forms:
        x_tv = estimate_lean(ys, form="time-varying")
        metrics["rms_error_deg_time_varying"] = _rms_deg(x_tv[:, 0] - phi, t)
        series["phi_hat_tv_rad"] = np.asarray(x_tv[:, 0])
    metrics["max_error_deg"] = float(np.degrees(np.max(np.abs(
        np.asarray(x_hat[:, 0] - phi)[t >= SETTLE_S]))))
    return metrics, series, float(t[-1] + 1.0 / FS_HZ)


# --------------------------------------------------------------------------- experiments


def _gain_figures(result: Result, out_dir: Path):
    from verticality.core.plots import new_figure, save

    ours = np.asarray(result.metrics["gain"])
    pub = np.asarray(result.paper["gain"])
    fig, axes = new_figure(1, 1, width=7.0, height_per_row=3.2)
    ax = axes[0, 0]
    labels = [f"L[{i},{j}]" for i in range(3) for j in range(2)]
    xs = np.arange(6)
    ax.bar(xs - 0.2, np.abs(ours.ravel()), 0.4, label="ours (CARE)")
    ax.bar(xs + 0.2, np.abs(pub.ravel()), 0.4, label="T eq. 22")
    for x, o in zip(xs, ours.ravel(), strict=True):
        ax.text(x - 0.2, abs(o) * 1.3, f"{o:.2g}", ha="center", fontsize=7)
    ax.set_yscale("log")
    ax.set_xticks(xs, labels)
    ax.set_ylabel("|gain entry|")
    ax.set_title("Otolith–canal steady-state Kalman gain (columns: ω_g, a_xa)")
    ax.legend(fontsize=8)
    return [save(fig, out_dir / "tahboub_gains.png")]


@register("tahboub-gains", "Steady-state otolith–canal Kalman gain (T eq. 22)",
          source="T eq. 7–13, 20–22", figures=_gain_figures)
def run_gains(quick: bool = False) -> Result:
    L = otolith_canal.steady_state_gain()
    pub = tahboub.TAHBOUB_GAIN_PUBLISHED
    rel = np.abs(L - pub) / np.abs(pub)
    return Result(
        metrics={"gain": L.tolist(), "relative_difference": rel.tolist(),
                 "max_relative_difference": check(rel.max(), 0.05, rel.max() <= 0.05)},
        paper={"gain": pub.tolist()},
        simulated_s=0.0,
    )


def _time_figure(name, fig_label):
    def figures(result: Result, out_dir: Path):
        from verticality.core.plots import new_figure, save

        s = result.series
        fig, axes = new_figure(2, 1, width=8.0, height_per_row=2.4)
        ax, ax_e = axes[:, 0]
        ax.plot(s["t_s"], np.degrees(s["phi_rad"]), label="actual")
        ax.plot(s["t_s"], np.degrees(s["phi_hat_rad"]), "--", label="estimated (steady-state KF)")
        ax.set_ylabel("body lean [deg]")
        ax.set_title(f"{name}: actual vs estimated lean (cf. {fig_label})")
        ax.legend(fontsize=8)
        ax_e.plot(s["t_s"], np.degrees(s["phi_hat_rad"] - s["phi_rad"]), lw=0.8)
        ax_e.set_ylabel("error [deg]")
        ax_e.set_xlabel("time [s]")
        ax_e.text(0.01, 0.9, f"rms {result.metrics['rms_error_deg']:.3f}°",
                  transform=ax_e.transAxes, fontsize=8, va="top")
        return [save(fig, out_dir / f"{name.replace('-', '_')}.png")]

    return figures


@register("tahboub-step", "Otolith–canal filter, 5° lean step (T Fig. 5)", source=SOURCE,
          figures=_time_figure("tahboub-step", "T Fig. 5"))
def run_step(quick: bool = False) -> Result:
    dur = 8.0 if quick else 20.0
    t = np.arange(int(dur * FS_HZ)) / FS_HZ
    command = np.where(t >= 2.0, np.radians(5.0), 0.0)
    metrics, series, sim = _lean_experiment(command, seed=5, extra_forms=True)
    return Result(metrics=metrics, paper={}, series=series, simulated_s=sim,
                  notes="T Fig. 5 shows the estimate on top of the encoder reading; no number")


@register("tahboub-sine", "Otolith–canal filter, 5° 0.2 Hz sine (T Fig. 6)", source=SOURCE,
          figures=_time_figure("tahboub-sine", "T Fig. 6"))
def run_sine(quick: bool = False) -> Result:
    dur = 20.0 if quick else 60.0
    t = np.arange(int(dur * FS_HZ)) / FS_HZ
    command = np.radians(5.0) * np.sin(2 * np.pi * 0.2 * t)
    metrics, series, sim = _lean_experiment(command, seed=6)
    return Result(metrics=metrics, paper={}, series=series, simulated_s=sim,
                  notes="T Fig. 6 shows the estimate following the encoder reading; no number")


def _prts_figures(result: Result, out_dir: Path):
    from verticality.core.plots import new_figure, save

    m = result.metrics
    fig = frequency.bode_figure(np.array(m["frequency_hz"]), np.array(m["gain"]),
                                np.array(m["phase_deg"]), np.array(m["coherence"]),
                                title="tahboub-prts: actual → estimated lean (cf. T Fig. 7–8)")
    paths = [save(fig, out_dir / "tahboub_prts_bode.png")]
    s = result.series
    fig, axes = new_figure(1, 1, width=8.0, height_per_row=2.6)
    ax = axes[0, 0]
    sel = s["t_s"] <= 121.0
    ax.plot(s["t_s"][sel], np.degrees(s["phi_rad"][sel]), label="actual")
    ax.plot(s["t_s"][sel], np.degrees(s["phi_hat_rad"][sel]), "--", label="estimated")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("lean [deg]")
    ax.set_title("PRTS stimulus, first two cycles")
    ax.legend(fontsize=8)
    paths.append(save(fig, out_dir / "tahboub_prts_time.png"))
    return paths


def prts_command(n_cycles: int, fs_hz: float = FS_HZ, peak_rad: float = np.radians(5.0)):
    """The lean commanded in `tahboub-prts`: ``n_cycles`` PRTS cycles sampled at ``fs_hz``, plus
    one sample past the last cycle (for end matching)."""
    _, command, _ = prts_stimulus(peak_rad, fs_hz, n_cycles + 1)
    return command[: n_cycles * int(round(PRTS_LENGTH * PRTS_DT_S * fs_hz)) + 1]


@register("tahboub-prts", "Otolith–canal filter, PRTS frequency response (T Fig. 7–8)",
          source=SOURCE, figures=_prts_figures)
def run_prts(quick: bool = False) -> Result:
    n_cycles = 3 if quick else 6
    per = int(PRTS_LENGTH * PRTS_DT_S * FS_HZ)
    command = prts_command(n_cycles)
    metrics, series, sim = _lean_experiment(command, seed=7)
    f, H, coh = frequency.cycle_transfer_function(series["phi_rad"], series["phi_hat_rad"], per,
                                                  FS_HZ, end_match=True)
    f0, H0, coh0 = frequency.cycle_transfer_function(series["phi_rad"], series["phi_hat_rad"], per,
                                                     FS_HZ, end_match=False)
    raw = frequency.band_summary(f0, H0, coh0)
    metrics["mean_coherence_no_end_match"] = raw["mean_coherence"]
    metrics["mean_gain_no_end_match"] = raw["mean_gain"]
    keep = f <= 2.0
    f, H, coh = f[keep], H[keep], coh[keep]
    band = frequency.band_summary(f, H, coh)
    metrics.update({
        "frequency_hz": f.tolist(), "gain": np.abs(H).tolist(),
        "phase_deg": np.degrees(np.angle(H)).tolist(), "coherence": coh.tolist(),
        "mean_gain": band["mean_gain"], "mean_abs_phase_deg": band["mean_abs_phase_deg"],
        "mean_coherence": band["mean_coherence"],
        "coherence_ok": check(band["mean_coherence"], 0.9, band["mean_coherence"] >= 0.9),
        "gain_ok": check(band["mean_gain"], 0.1, 0.9 <= band["mean_gain"] <= 1.1),
        "peak_lean_deg": float(np.degrees(np.max(np.abs(series["phi_rad"])))),
        "g_m_s2": G_M_S2,
    })
    return Result(metrics=metrics,
                  paper={"mean_gain": 1.0, "mean_abs_phase_deg": 0.0},  # T Fig. 7–8, read off
                  series=series, simulated_s=sim)
