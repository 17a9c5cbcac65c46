"""`model-checks` — validation of the physics models (F §2.1–2.2, P13 §3, F §4.4).

Every check is a metric ``{"value", "tolerance", "pass"}``; the measurements and their tolerances
are the functions of :mod:`verticality.analysis.model_checks` (its docstring gives each check and
the reading it fixes), the same ones the tests assert. Plant: the P13 otolith pendulum and head,
full Newton–Euler forms, fixed-step RK4 at 1 ms with rotation matrices re-orthonormalized each
step.

``quick`` runs the same checks (their durations are the checks' definitions and cost little after
compilation) but skips the extra 60 s run (free-head lateral).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from verticality.analysis import model_checks as mc
from verticality.core import so3
from verticality.experiments import Result, check, register

__all__ = ["TOL", "figures", "run"]

TOL = mc.TOL


def _check(value, tol_key: str) -> dict:
    return check(value, TOL[tol_key], value <= TOL[tol_key])


def still_metrics() -> tuple[dict, dict]:
    """Metrics and series of the still-head runs (oscillation, energy, deflection, tilt)."""
    runs = mc.still_runs()
    w_analytic = mc.analytic_frequency_rad_s()
    m, series = {}, {"t": np.arange(runs["energy"]["E"].shape[0]) * mc.DT_S}
    freq = {}
    for ax in "xy":
        w = mc.oscillation_frequency_rad_s(ax)
        freq[ax] = _check(abs(w / w_analytic - 1.0), "oscillation")
        m[f"oscillation_frequency_rad_s_{ax}"] = w
    m["oscillation_frequency_rel_error"] = freq
    m["oscillation_frequency_analytic_rad_s"] = w_analytic
    series["osc_phi_x"] = runs["osc_x"]["phi"][:, 0]
    series["omega_analytic"] = w_analytic

    drift = mc.energy_drift_rel()
    m["energy_drift_rel"] = _check(drift.max(), "energy")
    series["energy_drift_rel"] = drift
    m["energy_rate_identity_rel"] = _check(mc.energy_rate_identity_rel(), "energy_rate")
    m["energy_balance_rel"] = _check(mc.energy_balance_rel(), "energy_balance")
    damped = runs["damped"]
    diss = damped["diss"]
    series["damped_E_change"] = damped["E"] - damped["E"][0]
    series["damped_minus_dissipated"] = -np.concatenate(
        [[0.0], np.cumsum(0.5 * (diss[1:] + diss[:-1])) * mc.DT_S])

    steady, direction = {}, {}
    for ax in "xy":
        err, derr = mc.steady_deflection_errors_rad(ax)
        steady[ax] = _check(err, "steady")
        direction[ax] = _check(derr, "steady")
        series[f"deflection_{ax}"] = mc.deflection_rad(ax)
    m["steady_deflection_error_rad"] = steady
    m["steady_deflection_direction_error_rad"] = direction
    series["deflection_expected"] = float(np.arctan(mc.A_STEADY_M_S2 / mc.G_M_S2))

    tilt, mag, axis_err = {}, {}, {}
    for ax in ("x", "y", "xy"):
        e = mc.still_tilt_errors_rad(ax)
        axis_err[ax] = _check(e.axis_error, "still_tilt")
        mag[ax] = _check(e.magnitude_error, "still_tilt")
        if ax == "xy":  # information: see mc.still_tilt_errors_rad
            m["still_tilt_phi_xy_minus_tilt_of_R_HI_rad"] = e.phi_error
        else:
            tilt[ax] = _check(e.phi_error, "still_tilt")
        series[f"still_phi_{ax}"] = runs[f"tilt_{ax}"]["phi"]
        series[f"still_expected_{ax}"] = np.asarray(
            so3.tilt_angles(np.asarray(mc.still_case(f"tilt_{ax}")[0]).T))
    m["still_tilt_error_rad"] = tilt
    m["still_tilt_axis_error_rad"] = axis_err
    m["still_tilt_magnitude_error_rad"] = mag
    return m, series


def planar_metrics() -> tuple[dict, dict]:
    m, series = {"planar_vs_3d_max_error_rad": {}}, {}
    for name in ("medial", "lateral"):
        m["planar_vs_3d_max_error_rad"][name] = _check(mc.planar_vs_3d_max_error_rad(name),
                                                       "planar")
        series[f"planar_{name}"], series[f"planar3d_{name}"] = mc.planar_vs_3d(name)
    return m, series


def lateral_medial_metrics() -> tuple[dict, dict]:
    run = mc.lateral_vs_medial()
    m = {"lateral_r0_vs_medial_max_error": _check(mc.lateral_r0_vs_medial_max_error(),
                                                  "lateral_r0"),
         "lateral_minus_medial_max_rad": mc.lateral_minus_medial_max_rad()}
    diff, phi_max = mc.p13_outputs_minus_abs_f_max_rad()
    m["p13_eq3_minus_abs_f28_max_rad"] = diff
    m["p13_eq3_phi_max_rad"] = phi_max
    return m, {"lm_t": run.t_s, "lm_medial": run.phi_medial, "lm_lateral": run.phi_lateral}


def controller_metrics() -> tuple[dict, dict]:
    ang, final = mc.global_stabilizer_angle_rad()
    m = {"global_stabilizer_final_angle_rad": _check(final, "global"),
         "pd_poles_max_error": _check(mc.pd_poles_error(), "poles"),
         "pd_poles": [[float(z.real), float(z.imag)] for z in mc.closed_loop_poles()]}
    return m, {"global_angle": ang,
               "global_t": np.arange(ang.shape[0]) * mc.DT_S * mc.EVERY_GLOBAL}


def so3_metrics(quick: bool) -> tuple[dict, dict]:
    err, unprojected = mc.so3_drift_medial()
    m = {"so3_orthonormality": _check(err.max(), "so3"),
         "so3_orthonormality_unprojected": float(unprojected.max())}
    series = {"so3_t": np.arange(err.shape[0]) * mc.DT_S * mc.EVERY_SO3, "so3_err": err,
              "so3_err_unprojected": unprojected}
    if not quick:
        e2 = mc.so3_drift_lateral_free_head()
        m["so3_orthonormality_free_head_lateral"] = _check(e2.max(), "so3")
        series["so3_err_lateral"] = e2
    return m, series


# ------------------------------------------------------------------------------------- run
@register("model-checks",
          "Validation of the pendulum, medial/lateral, planar models and stabilizers",
          source="F §2.1–2.2, F §4.4 (4.6–4.9), P13 §3",
          figures=lambda result, out_dir: figures(result, out_dir))
def run(quick: bool = False) -> Result:
    metrics, series = {}, {}
    simulated = 0.0
    for fn, sim_s in ((still_metrics, 9 * mc.T_SHORT_S), (planar_metrics, 4 * mc.T_SHORT_S),
                      (lateral_medial_metrics, 3 * mc.T_SHORT_S),
                      (controller_metrics, mc.GLOBAL_T_S),
                      (lambda: so3_metrics(quick), (2 if quick else 3) * mc.T_LONG_S)):
        m, s = fn()
        metrics.update(m)
        series.update(s)
        simulated += sim_s
    paper = {"oscillation_frequency_analytic_rad_s":
             metrics["oscillation_frequency_analytic_rad_s"]}
    return Result(metrics=metrics, paper=paper, series=series, simulated_s=simulated,
                  notes="tolerances: docs/models.md")


# ---------------------------------------------------------------------------------- figures
def figures(result: Result, out_dir: Path) -> list[Path]:
    from verticality.core import plots

    s, m = result.series, result.metrics
    out_dir = Path(out_dir)
    paths = []
    t = s["t"]

    fig, ax = plots.new_figure(2, 1, height_per_row=2.4, sharex=False)
    k = t <= 2.0
    analytic = mc.OSC_AMPLITUDE_RAD * np.cos(s["omega_analytic"] * t)
    ax[0, 0].plot(t[k], s["osc_phi_x"][k], label="3-D model φx")
    ax[0, 0].plot(t[k], analytic[k], "--", label="0.01 cos(√(mgl/Jxx) t)")
    ax[0, 0].set_ylabel("rad")
    ax[0, 0].set_title("Small oscillation, still head (β = 0): "
                       f"ω = {m['oscillation_frequency_rad_s_x']:.5f} vs "
                       f"{s['omega_analytic']:.5f} rad/s")
    ax[0, 0].legend(loc="upper right", fontsize=8)
    ax[1, 0].plot(t, s["osc_phi_x"] - analytic)
    ax[0, 0].set_xlabel("t (s), first 2 s")
    ax[1, 0].set_ylabel("model − analytic (rad)")
    ax[1, 0].set_xlabel("t (s): phase drift from the amplitude shift θ0²/16")
    paths.append(plots.save(fig, out_dir / "oscillation.png"))

    fig, ax = plots.new_figure(2, 1, height_per_row=2.4)
    ax[0, 0].semilogy(t[1:], np.maximum(s["energy_drift_rel"][1:], 1e-18))
    plots.published_line(ax[0, 0], TOL["energy"], label="tolerance 1e-6")
    ax[0, 0].set_ylabel("|E−E0| / (E0 − Emin)")
    ax[0, 0].set_title("Undamped pendulum: energy drift (RK4, 1 ms)")
    ax[0, 0].legend(fontsize=8)
    ax[1, 0].plot(t, s["damped_E_change"], label="E(t) − E(0)")
    ax[1, 0].plot(t, s["damped_minus_dissipated"], "--", label="−∫ β|ωS|² dt")
    ax[1, 0].set_ylabel("J")
    ax[1, 0].set_xlabel("t (s)")
    ax[1, 0].set_title("Damped pendulum, still head: energy balance")
    ax[1, 0].legend(fontsize=8)
    paths.append(plots.save(fig, out_dir / "energy.png"))

    fig, ax = plots.new_figure(1, 1, height_per_row=3.0)
    a = ax[0, 0]
    a.semilogy(s["so3_t"], np.maximum(s["so3_err"], 1e-18), label="medial, projected (R_IS)")
    if "so3_err_lateral" in s:
        a.semilogy(s["so3_t"], np.maximum(s["so3_err_lateral"], 1e-18),
                   label="lateral + free head, projected (R_IL, R_IR, R_IH)")
    a.semilogy(s["so3_t"], np.maximum(s["so3_err_unprojected"], 1e-18),
               label="medial, no projection (information)")
    plots.published_line(a, TOL["so3"], label="tolerance 1e-9")
    a.set_xlabel("t (s)")
    a.set_ylabel("‖RᵀR − I‖")
    a.set_title("Rotation matrices on SO(3): 60 s of the P13 impact motion")
    a.legend(fontsize=8)
    paths.append(plots.save(fig, out_dir / "so3.png"))

    fig, ax = plots.new_figure(2, 1, height_per_row=2.4)
    for row, name in enumerate(("medial", "lateral")):
        yp, y3 = s[f"planar_{name}"], s[f"planar3d_{name}"]
        tp = np.arange(yp.shape[0]) * mc.DT_S
        labels = ["θS", "θH"] if name == "medial" else ["θL", "θR", "θH"]
        for j, lab in enumerate(labels):
            ax[row, 0].plot(tp, yp[:, j], label=f"{lab} planar", lw=2, alpha=0.5)
            ax[row, 0].plot(tp, y3[:, j], "--", label=f"{lab} 3-D", lw=1)
        err = m["planar_vs_3d_max_error_rad"][name]["value"]
        ax[row, 0].set_title(f"{name}: planar vs 3-D in the coronal plane (max diff {err:.1e} rad)")
        ax[row, 0].set_ylabel("rad")
        ax[row, 0].legend(fontsize=7, ncol=3)
    ax[1, 0].set_xlabel("t (s)")
    paths.append(plots.save(fig, out_dir / "planar_vs_3d.png"))

    fig, ax = plots.new_figure(2, 1, height_per_row=2.4)
    tl = s["lm_t"]
    for j, comp in enumerate(("φx", "φy")):
        ax[j, 0].plot(tl, s["lm_medial"][:, j], label=f"medial {comp}", lw=2, alpha=0.5)
        ax[j, 0].plot(tl, s["lm_lateral"][:, j], "--", label=f"left {comp}", lw=1)
        ax[j, 0].plot(tl, s["lm_lateral"][:, 2 + j], ":", label=f"right {comp}", lw=1)
        ax[j, 0].set_ylabel("rad")
        ax[j, 0].legend(fontsize=8)
    ax[0, 0].set_title("Lateral (r = 0.05 m) vs medial otolith angles, P13 impact motion")
    ax[1, 0].set_xlabel("t (s)")
    paths.append(plots.save(fig, out_dir / "lateral_vs_medial.png"))

    fig, ax = plots.new_figure(2, 1, height_per_row=2.4)
    k = t <= 3.0
    for ax_name, col in (("x", 0), ("y", 1)):
        ax[0, 0].plot(t[k], s[f"still_phi_{ax_name}"][k, col],
                      label=f"φ{ax_name}, tilt about {ax_name}")
        ax[0, 0].axhline(s[f"still_expected_{ax_name}"][col], color="0.3", ls="--", lw=1)
    ax[0, 0].set_title(f"Still head tilted by {mc.TILT_RAD} rad: φ → −Θ (dashed)")
    ax[0, 0].set_ylabel("rad")
    ax[0, 0].legend(fontsize=8)
    for ax_name in ("x", "y"):
        ax[1, 0].plot(t[k], s[f"deflection_{ax_name}"][k], label=f"a along {ax_name}")
    plots.published_line(ax[1, 0], s["deflection_expected"], label="atan(a/g)")
    ax[1, 0].set_title(f"Constant horizontal acceleration {mc.A_STEADY_M_S2} m/s²: "
                       "pendulum deflection")
    ax[1, 0].set_ylabel("rad")
    ax[1, 0].set_xlabel("t (s)")
    ax[1, 0].legend(fontsize=8)
    paths.append(plots.save(fig, out_dir / "still_head.png"))
    return paths
