"""`ambiguity-*` — F §4.5.2: observer-based head stabilization when the head's acceleration is
known (Fig. 4.11, 4.14) or reconstructed from the otolith (Fig. 4.12, 4.15, 4.16).

Plant (truth): the planar head carrying the medial otolith,
:class:`~verticality.models.planar.PlanarHead` driven through
:class:`~verticality.models.planar.WithHeadFrameInput` (torque and head-frame acceleration),
nonlinear, RK4 with 4 sub-steps per 1 ms sample. Parameters (F §4.5.2,
:mod:`verticality.models.params`): otolith critically damped at 300 Hz (``g/l = (2π·300)²``,
``β/(m l²) = 2·2π·300``; only the ratios matter), head inertia 0.0174 kg·m². Sagittal plane: the
planar model's rotation is about the head's y axis with ``h = −x``
(:mod:`verticality.models.planar`), so a forward head acceleration is ``a_h = −a_x``. Walking: the
built-in :func:`verticality.simulation.trajectories.walking` (F Fig. 4.13, after Menz, Lord &
Fitzpatrick 2003); its forward and vertical accelerations drive the head as head-frame components
``ᴴa`` (F's input; head-mounted accelerometers measure in the head frame), sampled at every RK4
stage time.

Internal model (F 4.10): the same model value linearized at upright
(:func:`verticality.models.linearize.linearize`), inputs the torque and ``ᴴa_h`` (F: "the only
inputs left after the linearization"; ``ᴴa_z`` drops out at upright); a Luenberger observer
(:func:`verticality.estimators.luenberger.design`) on it, estimate started at zero (F). A PD on the
estimate drives the head: ``τ = k_p (θ_ref − θ̂_H) − k_d ω̂_H``.

Readings the thesis leaves open, fixed here:
- Observer poles: F gives none; as in `separation` (F §4.4) twice the sensor's natural frequency,
  ``−2ω_n·(1, 1.1, 1.2, 1.3)``, ω_n = 2π·300 rad/s.
- PD gains: F gives none for §4.5; a critically damped head loop at 10 rad/s on the true inertia,
  ``k_p = K ω² = 1.74 N·m/rad``, ``k_d = 2 K ω = 0.348 N·m·s/rad``.
- Initial head tilt 5° where F says "about 5 degrees" (`ambiguity-known-acc`,
  `ambiguity-desired-tilt`); the plant's otolith starts at rest under the first sample's
  acceleration (:func:`verticality.analysis.ambiguity.planar_reading`).
- Acceleration reconstruction (Fig. 4.12, "based on the measured angular displacement of
  otolithic organs and estimated head tilt"): F 3.17 with the estimated tilt and the saccule's
  ``a_z`` (the true vertical head-frame acceleration), in the model's signs
  (:func:`verticality.analysis.ambiguity.planar_head_acceleration`, ``small_angle=True``): the
  ``luenberger`` feed. ``luenberger_exact`` uses the exact relation instead (F 3.16).
- Walking from its steady gait on (the stimulus from 2 s, after its 1 s start-up): F's head is
  "during normal locomotion"; a start from rest adds a sustained forward acceleration.
- **Converged**: every quantity finite, and over the last second the mean ``|θ̂_H − θ_H|`` and the
  mean ``|θ_H − θ_ref|`` are both ≤ 10° (``final_tilt_error_deg``, ``final_head_error_deg``).
  The *known*-acceleration observer itself keeps a walking-driven error on the linear internal
  model (it neglects ``ᴴa_z`` and the products of acceleration and angle: 1.9° at upright, up to
  5° at ±20°); the Luenberger loops that drift or diverge end beyond 25°. 10° sits in that gap:
  any bound from 5° to 25° gives the Luenberger feeds the same regions. ``rms_acc_error_m_s2``: RMS
  of ``â_h − a_h`` after the first second. Non-finite values are reported as null.
- ``rotation_only``: the same sweeps with the walking acceleration switched off (the head only
  rotates): where the reconstruction works when nothing but tilt moves the otolith.

Beyond the thesis (F §4.6's question, "a property of the head or of the observer?"): the same
sweeps with an EKF (:class:`~verticality.estimators.ekf.ExtendedKalmanFilter`) on the *nonlinear*
model value with the horizontal acceleration as a random-walk state
(:class:`~verticality.models.planar.WithAccelerationState`, discretized with 4 RK4 sub-steps), fed
the same reading, torque and saccule ``a_z`` (the ``ekf`` feed), and with the acceleration a
first-order Gauss–Markov process of time constant 0.2 s instead (``ekf_gauss_markov``: zero on
average, as for a head that walks on). Q per 0.1 ms step: σ = 1e-6 rad and 1e-3 rad/s on the
otolith, 1e-6 rad and 1e-3 rad/s on the head, 0.05 m/s² on ``a_h``; R = (1e-3 rad)²;
P0 = diag(0.1 rad, 1 rad/s, 0.5 rad, 1 rad/s, 3 m/s²)², started at zero like the observer.

Sampling: the otolith's 300 Hz (1885 rad/s) and observer poles near 4000 rad/s need the
measurement far faster than 1 kHz (held over 1 ms the reading lags the observer by half a sample,
≈ 1 rad of phase at 1885 rad/s, and the loop with the Luenberger observer goes unstable even with
the acceleration known); everything runs at 10 kHz, the plant with one RK4 step per sample.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from verticality.analysis import ambiguity as am
from verticality.analysis.ambiguity_loop_stability import stability_report
from verticality.analysis.ambiguity_outcome import (
    CONVERGED_DEG,
    largest_converging,
    smallest_failing,
    summarize,
)
from verticality.core.constants import G_M_S2
from verticality.experiments import Result, check, register
from verticality.experiments import ambiguity_upright as au
from verticality.simulation import ambiguity_upright_loop
from verticality.simulation.ambiguity_loop import (
    DT_S,
    THETA0_DEG,
    UNKNOWN_FEEDS,
    Series,
    sweep,
)


def _series_for_figure(s: Series, idx, every: int = 10) -> dict:
    out = {}
    for i in idx:
        for name, v in s._asdict().items():
            out[f"{i}/{name}"] = v[i][::every]
    return out


# ----------------------------------------------------------------------------------------------
# The three experiments
# ----------------------------------------------------------------------------------------------


def _duration(quick: bool) -> float:
    return 3.0 if quick else 10.0


@register("ambiguity-known-acc",
          "Tilt estimation and head control with the acceleration known (F §4.5.2)",
          source="F §4.5.2, Fig. 4.11, 4.14",
          figures=lambda r, d: figures(r, d, "ambiguity-known-acc"))
def run_known(quick: bool = False) -> Result:
    duration = _duration(quick)
    refs = [-20.0, 0.0, 20.0] if quick else [-20.0, -15.0, -10.0, -5.0, 0.0, 5.0, 10.0, 15.0, 20.0]
    th0 = [THETA0_DEG] * len(refs)
    s = sweep("known", th0, refs, duration)
    rows = summarize(s, refs, known=True)
    n_conv = sum(r["converged"] for r in rows)
    metrics = {
        "desired_tilt_deg": refs,
        "luenberger": rows,
        "all_converge": n_conv == len(rows),
        "printed_relations": printed_relations(),
        "checks": {"all_converge": check(n_conv, len(rows), n_conv == len(rows))},
    }
    series = {"t": np.arange(s.theta_H.shape[1])[::10] * DT_S, "sweep": refs,
              **_series_for_figure(s, [0, len(refs) // 2, len(refs) - 1])}
    return Result(metrics=metrics, paper={"all_converge": True}, series=series,
                  simulated_s=duration * len(refs))


def printed_relations() -> dict:
    """F 3.14 and 3.16 as printed, against the model's steady state (the otolith angle of
    :func:`verticality.analysis.ambiguity.otolith_angles`) over a grid of ``a_x`` (±5 m/s²),
    ``a_z`` (±3 m/s²) and ``Θ_y`` (±20°): the largest error with F's unstated conventions
    (``φ_F = −φ_y``, ``Θ_F = −Θ_y``, ``a_z`` positive down) and, for F 3.14, read with ``a_z`` up as
    the head frame has it (m/s²)."""
    g = G_M_S2
    ax, az, ty = np.meshgrid(np.linspace(-5, 5, 11), np.linspace(-3, 3, 7),
                             np.radians(np.linspace(-20, 20, 9)), indexing="ij")
    a = np.stack([ax, 0.0 * ax, az], -1)
    phi_F = -np.asarray(am.otolith_angles(a, 0.0, ty))[..., 1]
    phi0_F = -np.asarray(am.otolith_angles(a))[..., 1]
    f316 = -az * np.sin(phi_F) + ax * np.cos(phi_F) - g * np.sin(phi_F - ty)
    return {"f314_with_conventions_max_error_m_s2":
                float(np.abs(ax - (g + az) * np.tan(phi0_F)).max()),
            "f314_as_printed_a_z_up_max_error_m_s2":
                float(np.abs(ax - (g - az) * np.tan(phi0_F)).max()),
            "f316_with_conventions_max_error_m_s2": float(np.abs(f316).max())}


def _unknown(values, th0, refs, duration, swept: str):
    """The reconstructed-acceleration feeds on one sweep, with walking and rotation only."""
    out: dict = {"rotation_only": {}}
    series: dict = {}
    for walking_scale in (1.0, 0.0):
        feeds = UNKNOWN_FEEDS if walking_scale else ("luenberger", "luenberger_exact")
        for kind in feeds:
            s = sweep(kind, th0, refs, duration, walking_scale)
            rows = summarize(s, refs, known=False)
            entry = {
                "per_value": rows,
                f"largest_converging_{swept}_deg": largest_converging(values, rows),
                f"smallest_failing_{swept}_deg": smallest_failing(values, rows),
            }
            if walking_scale:
                out[kind] = entry
                if kind in ("luenberger", "ekf_gauss_markov"):
                    series.update({f"{kind}/{k}": v
                                   for k, v in _series_for_figure(s, range(len(values))).items()})
            else:
                out["rotation_only"][kind] = entry
        series["t"] = np.arange(s.theta_H.shape[1])[::10] * DT_S
    return out, series


@register("ambiguity-initial-tilt",
          "Acceleration reconstructed from the otolith: stabilizing upright from an initial tilt "
          "(F §4.5.2)",
          source="F §4.5.2, Fig. 4.12, 4.15",
          figures=lambda r, d: figures(r, d, "ambiguity-initial-tilt"))
def run_initial(quick: bool = False) -> Result:
    duration = _duration(quick)
    values = [0.0, 12.0, 25.0] if quick else [0.0, 5.0, 10.0, 12.0, 15.0, 20.0, 25.0, 30.0]
    feeds, series = _unknown(values, values, [0.0] * len(values), duration, "initial_tilt")
    upright, up_series, up_s = _upright("initial_tilt", quick)
    upright["loop_stability"] = stability_report()
    metrics = {"initial_tilt_deg": values, **feeds, "upright_assumption": upright,
               "checks": {"sweep_complete": check(len(values), 0, all(
                   len(feeds[k]["per_value"]) == len(values) for k in UNKNOWN_FEEDS))}}
    series["sweep"] = values
    series.update(up_series)
    paper = {"luenberger": {"largest_converging_initial_tilt_deg": 12.0,
                            "smallest_failing_initial_tilt_deg": 25.0},
             "upright_assumption": {"largest_converging_initial_tilt_deg": 12.0,
                                    "smallest_failing_initial_tilt_deg": 25.0}}
    return Result(metrics=metrics, paper=paper, series=series,
                  simulated_s=duration * len(values) * (len(UNKNOWN_FEEDS) + 2) + up_s)


@register("ambiguity-desired-tilt",
          "Acceleration reconstructed from the otolith: holding the head at a desired tilt "
          "(F §4.5.2)",
          source="F §4.5.2, Fig. 4.12, 4.16",
          figures=lambda r, d: figures(r, d, "ambiguity-desired-tilt"))
def run_desired(quick: bool = False) -> Result:
    duration = _duration(quick)
    values = [0.0, 6.0] if quick else [0.0, 1.0, 2.0, 3.0, 4.0, 6.0, 8.0, 10.0, 15.0]
    feeds, series = _unknown(values, [THETA0_DEG] * len(values), values, duration, "desired_tilt")
    upright, up_series, up_s = _upright("desired_tilt", quick)
    metrics = {"desired_tilt_deg": values, **feeds, "upright_assumption": upright,
               "checks": {"sweep_complete": check(len(values), 0, all(
                   len(feeds[k]["per_value"]) == len(values) for k in UNKNOWN_FEEDS))}}
    series["sweep"] = values
    series.update(up_series)
    paper = {"luenberger": {"largest_converging_desired_tilt_deg": 0.0,
                            "smallest_failing_desired_tilt_deg": 6.0},
             "upright_assumption": {"largest_converging_desired_tilt_deg": 0.0,
                                    "smallest_failing_desired_tilt_deg": 6.0}}
    return Result(metrics=metrics, paper=paper, series=series,
                  simulated_s=duration * len(values) * (len(UNKNOWN_FEEDS) + 2) + up_s)


def _upright(swept: str, quick: bool):
    """The Fig. 4.12 caption's reading (:mod:`verticality.experiments.ambiguity_upright`): the
    sweep at the nominal setting, the boundary over the grid, series for the figure, simulated s."""
    duration = au.QUICK_DURATION_S if quick else au.DURATION_S
    grid = au.QUICK_GRID if quick else au.GRID
    entry, s = au.sweeps(swept, duration, grid)
    entry["setting"] = {**au.NOMINAL, "duration_s": duration}
    t = np.arange(s.theta_H.shape[1]) * (ambiguity_upright_loop.OUT_EVERY
                                         * ambiguity_upright_loop.DT_S)
    series = {"upright/t": t, **{f"upright/{name}": v for name, v in s._asdict().items()}}
    n_runs = len(entry["per_value"]) * (1 + sum(len(v) for v in grid.values()))
    return entry, series, duration * n_runs


def _at(values, rows, v) -> bool:
    return bool(rows[list(values).index(v)]["converged"])


# ----------------------------------------------------------------------------------------------
# Figures (like F Figs. 4.14–4.16: time courses for two sweep values and the summary)
# ----------------------------------------------------------------------------------------------


def _relation_maps(fig, axes, rows, sweep_values):
    """The known-acceleration summary and the steady-state relations' error maps (F 3.17 against
    the exact F 3.16; the upright assumption F 3.14) over head tilt × horizontal acceleration."""
    ax = axes[0]
    ax.plot(sweep_values, [r["final_tilt_error_deg"] for r in rows], "o-", label="final |θ̂ − θ|")
    ax.plot(sweep_values, [r["final_head_error_deg"] for r in rows], "s-",
            label="final |θ − θ_ref|")
    ax.axhline(CONVERGED_DEG, color="0.3", ls="--", lw=0.8, label="convergence bound")
    ax.set_xlabel("desired tilt [deg]")
    ax.set_ylabel("deg")
    ax.legend(fontsize=7)
    tilt = np.radians(np.linspace(-30, 30, 61))[:, None]
    acc = np.linspace(-1.0, 1.0, 41)[None, :] * G_M_S2
    for ax, err, title in (
            (axes[1], am.small_angle_error_m_s2(tilt, acc), "F 3.17 (small angle) − exact"),
            (axes[2], am.upright_assumption_error_m_s2(tilt, acc), "upright assumption − exact")):
        im = ax.pcolormesh(acc[0], np.degrees(tilt[:, 0]), np.abs(np.asarray(err)), shading="auto")
        fig.colorbar(im, ax=ax, label="|error| [m/s²]")
        ax.set_xlabel("ᴴa_h [m/s²]")
        ax.set_ylabel("head tilt [deg]")
        ax.set_title(title, fontsize=9)


def figures(result: Result, out_dir: Path, name: str) -> list[Path]:
    from verticality.core.plots import new_figure, save

    s = result.series
    t = s["t"]
    sweep_values = list(s["sweep"])
    m = result.metrics
    if name == "ambiguity-known-acc":
        feeds = [("", m["luenberger"])]
        picks = [0, len(sweep_values) - 1]
    else:
        feeds = [("luenberger/", m["luenberger"]["per_value"]),
                 ("ekf_gauss_markov/", m["ekf_gauss_markov"]["per_value"])]
        conv = [r["converged"] for r in m["luenberger"]["per_value"]]
        ok = [i for i, c in enumerate(conv) if c]
        bad = [i for i, c in enumerate(conv) if not c]
        picks = [ok[-1] if ok else 0, bad[0] if bad and ok else len(sweep_values) - 1]
    paths = []
    fig, axes = new_figure(3, 3, width=13, sharex=False)
    for j, i in enumerate(picks):
        prefix = feeds[0][0]
        axes[0, j].plot(t, np.degrees(s[f"{prefix}{i}/theta_H"]),
                        label="head tilt (Luenberger loop)")
        axes[0, j].plot(t, np.degrees(s[f"{prefix}{i}/theta_hat"]), lw=0.8, label="its estimate")
        if len(feeds) > 1:
            axes[0, j].plot(t, np.degrees(s[f"ekf_gauss_markov/{i}/theta_H"]),
                            label="head tilt (EKF loop, Gauss–Markov a)")
            axes[0, j].plot(t, np.degrees(s[f"ekf_gauss_markov/{i}/theta_hat"]), lw=0.8,
                            label="its estimate")
        axes[0, j].set_title(f"{name}: {sweep_values[i]:g}°", fontsize=9)
        axes[0, j].set_ylabel("deg")
        axes[1, j].plot(t, np.degrees(np.abs(s[f"{prefix}{i}/theta_hat"]
                                             - s[f"{prefix}{i}/theta_H"])),
                        color="C3", label="|estimate − tilt| (Luenberger)")
        axes[1, j].set_ylabel("deg")
        axes[2, j].plot(t, s[f"{prefix}{i}/a_true"], label="ᴴa_h true")
        axes[2, j].plot(t, s[f"{prefix}{i}/a_hat"], lw=0.8, label="ᴴa_h used by the observer")
        axes[2, j].set_ylabel("m/s²")
        axes[2, j].set_xlabel("t [s]")
        for ax in axes[:, j]:
            ax.legend(fontsize=7)
    if len(feeds) > 1:
        ax = axes[0, 2]
        for label, rows in feeds:
            err = [r["final_tilt_error_deg"] if r["final_tilt_error_deg"] is not None else np.nan
                   for r in rows]
            ax.semilogy(sweep_values, np.maximum(err, 1e-6), "o-", label=label.rstrip("/"))
        ax.axhline(CONVERGED_DEG, color="0.3", ls="--", lw=0.8, label="convergence bound")
        ax.set_xlabel("sweep value [deg]")
        ax.set_ylabel("final |θ̂ − θ| [deg]")
        ax.legend(fontsize=7)
        ax = axes[1, 2]
        for label, rows in feeds:
            ax.plot(sweep_values, [float(r["converged"]) for r in rows], "o-",
                    label=label.rstrip("/"))
        ax.set_ylabel("converged")
        ax.set_xlabel("sweep value [deg]")
        ax.legend(fontsize=7)
        ax = axes[2, 2]
        tilt = np.radians(np.linspace(0, 30, 61))[:, None]
        acc = np.linspace(-0.5, 0.5, 41)[None, :] * G_M_S2
        err = np.asarray(am.upright_assumption_error_m_s2(tilt, acc))
        im = ax.pcolormesh(acc[0], np.degrees(tilt[:, 0]), np.abs(err), shading="auto")
        fig.colorbar(im, ax=ax, label="|error| [m/s²]")
        ax.set_xlabel("ᴴa_h [m/s²]")
        ax.set_ylabel("head tilt [deg]")
        ax.set_title("upright-assumption error (F 3.14 vs exact)", fontsize=9)
    if len(feeds) == 1:
        _relation_maps(fig, axes[:, 2], feeds[0][1], sweep_values)
    paths.append(save(fig, out_dir / f"{name.replace('-', '_')}.png"))
    if "upright_assumption" in m:
        paths.append(_upright_figure(result, out_dir, name))
    return paths


_GRID_LABELS = {"pd_loop_rad_s": "PD bandwidth [rad/s]", "walking_scale": "walking amplitude (×)",
                "vertical_lag_deg": "bounce lag behind the sway [deg]",
                "harmonics": "2nd harmonics (× the built-in walking's)"}


def _upright_figure(result: Result, out_dir: Path, name: str) -> Path:
    """The Fig. 4.12 caption's reading: time courses at the nominal setting and how the boundary
    (largest converging, smallest failing value) moves with each parameter of the grid."""
    from verticality.core.plots import new_figure, save

    swept = "initial_tilt" if name == "ambiguity-initial-tilt" else "desired_tilt"
    m, s = result.metrics["upright_assumption"], result.series
    values = m[f"{swept}_deg"]
    published = result.paper["upright_assumption"]
    fig, axes = new_figure(2, 3, width=13, sharex=False)
    ax = axes[0, 0]
    for i, v in enumerate(values):
        th = np.degrees(s["upright/theta_H"][i])
        ax.plot(s["upright/t"], np.clip(th, -60, 60), lw=0.8, label=f"{v:g}°")
    ax.set_ylim(-60, 60)
    ax.set_xlabel("t [s]")
    ax.set_ylabel("head tilt [deg] (clipped at ±60)")
    ax.set_title(f"{name}: F 3.14 upright reading, nominal setting", fontsize=9)
    ax.legend(fontsize=6, ncol=2)
    ax = axes[0, 1]
    err = [r["final_tilt_error_deg"] if r["final_tilt_error_deg"] is not None else np.nan
           for r in m["per_value"]]
    ax.semilogy(values, np.maximum(err, 1e-3), "o-", label="final |θ̂ − θ|")
    ax.axhline(CONVERGED_DEG, color="0.3", ls="--", lw=0.8, label="convergence bound")
    ax.set_xlabel(f"{swept.replace('_', ' ')} [deg]")
    ax.set_ylabel("deg")
    ax.legend(fontsize=7)
    panels = [axes[0, 2], axes[1, 0], axes[1, 1], axes[1, 2]]
    for ax, (param, entry) in zip(panels, m["boundary"].items(), strict=False):
        x = entry["values"]
        lo = [np.nan if v is None else v for v in entry[f"largest_converging_{swept}_deg"]]
        hi = [np.nan if v is None else v for v in entry[f"smallest_failing_{swept}_deg"]]
        ax.plot(x, lo, "o-", label="largest converging")
        ax.plot(x, hi, "s--", label="smallest failing")
        ax.axhline(published[f"largest_converging_{swept}_deg"], color="C2", lw=0.8,
                   label="F: converges")
        ax.axhline(published[f"smallest_failing_{swept}_deg"], color="C3", lw=0.8,
                   label="F: fails")
        ax.axvline(m["setting"][param], color="0.5", ls=":", lw=0.8)
        ax.set_xlabel(_GRID_LABELS.get(param, param))
        ax.set_ylabel(f"{swept.replace('_', ' ')} [deg]")
        ax.legend(fontsize=6)
    return save(fig, out_dir / f"{name.replace('-', '_')}_upright.png")
