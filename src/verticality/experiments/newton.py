"""`newton-lissajous` and `newton-uncertainty`: the Newton observer on the P11 Lissajous test.

P11 §V–VI (Figs. 3–7), §VII; F §4.3 (eq. 4.1–4.5, Figs. 4.4–4.8). docs/reproduction.md fixes the
parameters; the readings and choices the papers leave open are these:

Plant (models/lissajous_plant.py): the planar head + pendulum of models/planar.py with P11's
parameters (m = 50 g, l = 0.1 m, J = m l², b = 0.005 N·m·s, K = 100 J), driven by the torque and
the head-frame pivot acceleration, integrated by RK4 at 1 ms with the inputs held over each step.
The pivot is the head's origin and moves with the trunk's (x, z)(t); the trunk's Θ(t) is a rotation
in the same (coronal) plane (trajectories.lissajous_trunk).

- **fixed**: the head is rigid on the trunk, θ_H(t) = Θ(t). It is simulated as the same head driven
  by the torque the rigid neck must exert, τ = K·Θ̈(t) (with θ_H(0) = 0, ω_H(0) = Θ̇(0)), so that
  θ_H follows Θ. **Observer states (fixed)**: the observer does not know Θ. Its known inputs are, as
  in P11, the pivot's linear acceleration (head-frame components, from the head's IMU, gravity
  excluded) and the head torque (here the neck torque, e.g. from a torque sensor; equivalently K
  times the gyro-differentiated head rate). It estimates all four states — pendulum angle and rate
  (θ_S, ω_S) and head tilt and rate (θ_H, ω_H) — from the inclinometer reading alone; the head tilt
  is observable only through the gravity term of the pendulum (sin θ_S with θ_S = reading + θ_H).
- **stabilized**: the head turns freely on the trunk (no coupling torque), driven only by the PD
  τ = −K_p θ̂_H − K_d ω̂_H (K_p = 230, K_d = 15), fed by the estimate at 1 ms. **Observer states
  (stabilized)**: the same four states with the same model and inputs; the head stays near
  upright and turns little, so its tilt barely changes over a window and the pendulum is forced
  only by the translation.
- Same model, same four-state observer in both conditions: only the head's motion differs, which is
  the comparison the papers make.

Observer (estimators/newton.py): window N = 24 samples spaced 25 ms (0.575 s), at most d = 5
iterations (stopping early once a step would move the predicted readings by < 1e-8 rad), run at
every sample (every 25 ms), warm-started from the previous window, the window-end estimate carried
forward to the present. **Between window samples** the observer's discrete model F_T (F eq. 4.1,
T = 25 ms) integrates the 1 ms model by 5 RK4 sub-steps of 5 ms; the known inputs are recorded at
1 kHz (the torque the controller applied, the IMU's acceleration), and each sub-step sees its five
1 ms inputs as a ramp with the same mean and first moment — exact for the head's double
integrator, second order for the pendulum (models/ramp_discretized.py of the same model value).
Only the reading is sampled every 25 ms. Between solves the estimate is propagated at 1 ms by the
observer's model, and that 1 ms estimate feeds the PD and is scored. Exact Jacobians by
jax.jacfwd; damped least squares. (25 sub-steps of 1 ms would make the observer's model the
plant's exact discretization; 5 sub-steps cost 5× less and leave a model error far below the
published figures: exact-model errors are ~1e-5°.)

**P11's setting** (``metrics.p11_euler``, run first): P11 §V.C discretizes the observer's model by
forward Euler, x_{k+1} = x_k + T·F(x_k, u_k), and §VI gives "the sampling period was 1 ms", Newton
iterations "every 25 ms with d = 5" and a queue of "the last 24 iterations". Our reading of these:
T = 1 ms, so F_T over 25 ms is 25 forward-Euler steps of 1 ms of the same model value
(``Discretized(..., scheme="euler")``), each with its 1 ms input held, and the 1 ms propagation
between solves is the same Euler step; the window is 24 points 25 ms apart (P11 could also be read
as 24 samples 1 ms apart, solved every 25 ms). The plant is integrated as above (RK4 at 1 ms).
Jacobians stay exact (autodiff); P11 used finite differences, and the two agree on a window to
``jacobian_fd_relative_difference`` (~1e-10). The perturbed cases are run twice: with the Gaussian
noise σ = 1e-4 rad (about one step of a 16-bit ADC over ±180°, 9.6e-5 rad) and with the reading
rounded by that ADC (``sensors.quantize``), both readings of P11's "white Gaussian noise ... which
corresponded to quantization error of a 16-bit analog-to-digital converter". Also measured:
``inclinometer_swing_deg`` (largest |reading| after 1 s; P11: the stabilized head's inclinometer
"oscillated with a magnitude of about 4°") and the errors after the stabilized head's start-up
transient (t ≥ 2 s). **Why the settings differ**: the forward-Euler model lags the head's angle by
half a step of its motion (an error ½·T·Δω_H over a window): ~0.26° over a window of the fixed head,
whose rate swings between ±4.9 rad/s, almost nothing for the stabilized head, whose rate stays near
zero. A coarse internal model is accurate when the head turns slowly, which stabilization ensures:
that is P11's "almost two orders of magnitude". Our RK4 sub-steps with ramp inputs leave no model
error of this kind, so with the exact model both heads are ~1e-5° and stabilization has nothing to
remove; with the 10 % wrong model the K̂ error (below) still gives the fixed head ~3.4°.

Initial conditions: pendulum hanging at rest; the observer starts believing "head upright, at
rest, pendulum at rest" (x̂0 = 0). The fixed head actually starts with Θ̇(0) = 4.9 rad/s; the
stabilized head starts tilted 0.1 rad (the EKF experiments' initial error). The first window is
full at t = 0.6 s; before that the observer only predicts. Scores are taken after t ≥ 1 s.

Perturbed: observer parameters 10 % high (m̂ = 0.055 kg, b̂ = 0.0055, Ĵ = m̂ l², K̂ = 100 Ĵ), plus
white Gaussian noise σ = 1e-4 rad on each 25 ms reading. Note that m̂, b̂, Ĵ all scaled by the same
factor leave the pendulum's equation unchanged (g/l and b/J are the same); the error that matters is
K̂: the observer turns the known torque into a head acceleration 1/(1 + level) of the true one.
That is why the fixed head, driven by large torques, suffers, and the stabilized head does not.

Tilt error: |θ̂_H − θ_H| (the planar case of the angle between true and estimated gravity in the
head frame), in degrees. `newton-uncertainty` uses the perturbed setting (same noise seed) at
levels 0–50 %: the seed's reading (P11 §VI's pattern, every parameter over-estimated, l exact, J and
K derived; each window warm-started) and the readings P11 §VII leaves open (:data:`READINGS`: the
errors' sign and pattern, each window's Newton iteration started from zero). A run is **lost**
(:func:`verticality.analysis.newton_errors.is_lost`) when its error after 1 s passes 90°, is not
finite, or most windows' iterations do not converge; it is reported as null and listed in
``lost_levels_pct``. `fixed_fails_at_level_pct` is the first level at which the fixed head misses
P11's bar (max error < 3°, which the stabilized head meets up to 50 %),
`fixed_within_3deg_up_to_pct` the last level before it, `fixed_lost_at_level_pct` the first lost
level (null: never, up to 50 %). P11: lost "if the uncertainties exceeded 15 %", judged at 17.5 %.
"""

from __future__ import annotations

from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from verticality.analysis.newton_errors import (
    LOST_DEG,
    PAPER_LISSAJOUS,
    SETTLE_S,
    inclinometer_swing_deg,
    is_lost,
    max_error_after,
    tilt_error_deg,
)
from verticality.experiments import Result, check, register
from verticality.models import lissajous_plant as lp
from verticality.models.planar import HeadInput, PlanarState, head_frame_to_inertial
from verticality.simulation import newton_loop
from verticality.simulation.newton_loop import (
    CONFIG,
    DT_S,
    NOISE_RAD,
    SUBSTEPS,
    RunSeries,
    make_observer,
    run_batch,
)

FAIL_DEG = 3.0  # P11 §VII's success criterion in the uncertainty study ("error smaller than 3°")
LEVELS = (0.0, 0.05, 0.10, 0.15, 0.175, 0.20, 0.30, 0.40, 0.50)
TRANSIENT_S = 2.0  # the stabilized head's start-up transient (0.1 rad initial tilt) is over


def _pick(batch: RunSeries, i: int) -> RunSeries:
    return RunSeries(*(np.asarray(a[i]) for a in batch))


CASES = (("fixed", "exact"), ("stabilized", "exact"), ("fixed", "perturbed"),
         ("stabilized", "perturbed"))


def _lanes(cases):
    """run_batch's per-lane arguments for (condition, model) cases."""
    return ([c == "fixed" for c, _ in cases], [0.1 if m == "perturbed" else 0.0 for _, m in cases],
            [NOISE_RAD if m == "perturbed" else 0.0 for _, m in cases])


def jacobian_agreement(scheme: str = "euler", t0_s: float = 2.0) -> float:
    """Largest |exact − finite-difference| entry of the window Jacobian ∂H_T/∂ξ, relative to the
    largest entry, on one window of the fixed head's Lissajous run starting at ``t0_s`` (P11 §V.C
    used central differences of H_T; we use the exact one by autodiff)."""
    obs = make_observer(lp.p11_head(1.0), scheme=scheme)
    n_fast = CONFIG.window * SUBSTEPS
    tr = lp.trunk(t0_s + (jnp.arange(n_fast) + 0.5) * DT_S)
    a_h_H, a_z_H = head_frame_to_inertial(tr.a_h_I_m_s2, tr.a_z_I_m_s2, -tr.Theta_rad)
    tau = lp.p11_head(1.0).K_kg_m2 * tr.Theta_ddot_rad_s2
    us = HeadInput(*(a.reshape(CONFIG.window, SUBSTEPS) for a in (tau, a_h_H, a_z_H)))
    th0 = lp.trunk(jnp.asarray(t0_s))
    xi = jnp.array([0.05, 0.3, float(th0.Theta_rad), float(th0.Theta_dot_rad_s)])

    @jax.jit
    def h_t(v):
        return obs.observability_map(PlanarState(*v), us, SUBSTEPS * DT_S)[0]

    J = np.asarray(jax.jacfwd(h_t)(xi))
    step = 1e-6 * (1.0 + np.abs(np.asarray(xi)))
    J_fd = np.stack([(np.asarray(h_t(xi.at[i].add(step[i])))
                      - np.asarray(h_t(xi.at[i].add(-step[i])))) / (2 * step[i])
                     for i in range(4)], axis=1)
    return float(np.max(np.abs(J - J_fd)) / np.max(np.abs(J)))


def _errors(batch: RunSeries, cases, t0: float) -> dict:
    out: dict = {"fixed": {}, "stabilized": {}}
    for i, (c, m) in enumerate(cases):
        out[c][m] = max_error_after(_pick(batch, i), t0)
    return out


def _ratio(errs: dict, model: str) -> float:
    return errs["fixed"][model] / max(errs["stabilized"][model], 1e-300)


def p11_euler_setting(duration: float) -> tuple[dict, dict]:
    """P11's own reading (module doc, "P11's setting"): the observer's model by forward Euler at
    1 ms; the perturbed cases twice, with Gaussian noise and with the 16-bit ADC's rounding."""
    cases = CASES + (("fixed", "perturbed"), ("stabilized", "perturbed"))
    fixed, level, noise = _lanes(cases)
    batch = run_batch(fixed, level, noise, seed=11, duration_s=duration, scheme="euler",
                      quantized=[False] * 4 + [True] * 2)
    errs = _errors(batch, CASES, SETTLE_S)
    late = _errors(batch, CASES, TRANSIENT_S)
    quant = {c: max_error_after(_pick(batch, 4 + j)) for j, c in enumerate(("fixed", "stabilized"))}
    swing = {c: inclinometer_swing_deg(_pick(batch, j))
             for j, c in enumerate(("fixed", "stabilized"))}
    ratio = {m: _ratio(errs, m) for m in ("exact", "perturbed")}
    ratio_late = {m: _ratio(late, m) for m in ("exact", "perturbed")}
    jac = jacobian_agreement("euler")
    metrics = {
        "max_tilt_error_deg": errs,
        "max_tilt_error_after_transient_deg": late,
        "ratio_fixed_over_stabilized": ratio,
        "ratio_fixed_over_stabilized_after_transient": ratio_late,
        "quantized_16bit": {"max_tilt_error_deg": quant,
                            "ratio_fixed_over_stabilized": quant["fixed"] / quant["stabilized"]},
        "inclinometer_swing_deg": swing,
        "jacobian_fd_relative_difference": jac,
        "checks": {"stabilized_10x_better_exact": check(ratio["exact"], 10.0,
                                                        ratio["exact"] >= 10.0),
                   "stabilized_10x_better_perturbed": check(ratio["perturbed"], 10.0,
                                                            ratio["perturbed"] >= 10.0),
                   "stabilized_swing_about_4deg": check(swing["stabilized"], 4.0,
                                                        abs(swing["stabilized"] - 4.0) <= 1.0),
                   "jacobian_fd_agrees": check(jac, 1e-6, jac <= 1e-6)},
    }
    series = {f"p11_euler.{c}.{m}": _pick(batch, i) for i, (c, m) in enumerate(CASES)}
    return metrics, series


@register("newton-lissajous", "Newton observer, fixed vs stabilized head, Lissajous trunk motion",
          source="P11 §V–VI Figs. 4–7; F §4.3 Figs. 4.5–4.8",
          figures=lambda r, d: _figures_lissajous(r, d))
def run_lissajous(quick: bool = False) -> Result:
    duration = 3.0 if quick else 10.0
    # P11's setting first: its forward-Euler internal model
    p11, series = p11_euler_setting(duration)
    batch = run_batch(*_lanes(CASES), seed=11, duration_s=duration)
    errs: dict = {"fixed": {}, "stabilized": {}}
    conv: dict = {"fixed": {}, "stabilized": {}}
    for i, (c, m) in enumerate(CASES):
        s = _pick(batch, i)
        errs[c][m] = max_error_after(s)
        conv[c][m] = float(np.mean(s.converged[s.t_s[SUBSTEPS - 1::SUBSTEPS] >= SETTLE_S]))
        series[f"{c}.{m}"] = s
    ratio = errs["fixed"]["perturbed"] / errs["stabilized"]["perturbed"]
    pub = PAPER_LISSAJOUS["max_tilt_error_deg"]
    metrics = {
        "max_tilt_error_deg": errs,
        "ratio_fixed_over_stabilized": {"perturbed": ratio, "exact": _ratio(errs, "exact")},
        "converged_fraction": conv,
        "inclinometer_swing_deg": {c: inclinometer_swing_deg(series[f"{c}.exact"])
                                   for c in ("fixed", "stabilized")},
        "p11_euler": p11,
        "checks": {f"{c}.{m}": check(errs[c][m], pub[c][m], errs[c][m] <= pub[c][m])
                   for c in ("fixed", "stabilized") for m in ("exact", "perturbed")}
        | {"ratio_perturbed": check(ratio, 5.0, ratio >= 5.0)},
    }
    return Result(metrics=metrics, paper=PAPER_LISSAJOUS, series=series, simulated_s=10 * duration,
                  notes="P11 §VI; errors after t >= 1 s. p11_euler: P11's own observer model "
                        "(forward Euler at 1 ms, P11 §V.C): a coarse internal model is accurate "
                        "when the head turns slowly, which stabilization ensures, so the "
                        "stabilized head's error is 10-100 times smaller, as P11 reports. Ours "
                        "(RK4 sub-steps with ramp inputs, near the plant's exact discretization) "
                        "has almost no model error left for stabilization to remove: both heads "
                        "are then ~1e-5° with the exact model.")


#: the readings of P11 §VII's "uncertainty" that P11 leaves open, run beside the seed's own
#: (P11 §VI's pattern, warm start): (pattern of :data:`newton_loop.PATTERNS`, cold start, the
#: fixed head's levels, the stabilized head's levels). Only the levels that place a boundary are
#: run, to keep the batch small.
READINGS = {
    "over_cold": ("over", True, (0.20, 0.50), ()),
    "l_under_cold": ("l_under", True, (0.05, 0.10, 0.15, 0.175, 0.20, 0.30, 0.50), (0.20, 0.50)),
    "l_under_warm": ("l_under", False, (0.15, 0.175, 0.20, 0.30, 0.50), ()),
    "l_under_K_exact_cold": ("l_under_K_exact", True, (0.175, 0.20, 0.30, 0.50), ()),
    "all_under_warm": ("all_under", False, (0.15, 0.175, 0.20, 0.30, 0.40, 0.50),
                       (0.30, 0.40, 0.50)),
}


def _pct(level: float) -> float:
    """A level as a percentage (17.5, 20)."""
    v = round(100 * level, 1)
    return int(v) if v == int(v) else v


def _level_stats(runs: list[tuple[float, RunSeries]], bar: bool = True) -> dict:
    """Per level: the max error (null when lost), the lost levels, the first lost one and (with
    ``bar``, for a list of levels from 0) the first level above P11's 3° bar and the largest level
    within 3° before any failure."""
    errs, lost, fails, within = [], [], None, None
    for lv, s in runs:
        e, gone = max_error_after(s), is_lost(s)
        errs.append(None if gone else e)
        if gone:
            lost.append(_pct(lv))
        if fails is None and (gone or not e <= FAIL_DEG):
            fails = _pct(lv)
        if fails is None:
            within = _pct(lv)
    out = {"levels_pct": [_pct(lv) for lv, _ in runs], "max_tilt_error_deg": errs,
           "lost_levels_pct": lost, "lost_at_level_pct": lost[0] if lost else None,
           # the largest error over the levels, null when any level is lost
           "max_over_levels_deg": None if lost else max(errs)}
    return out | ({"fails_at_level_pct": fails, "within_3deg_up_to_pct": within} if bar else {})


@register("newton-uncertainty", "Newton observer under 0–50 % parameter errors (P11 §VII)",
          source="P11 §VII; F §4.3.2",
          figures=lambda r, d: _figures_uncertainty(r, d))
def run_uncertainty(quick: bool = False) -> Result:
    """P11 §VII's uncertainty study: the seed's own reading first (every parameter over-estimated
    as in P11 §VI, l exact, J and K derived; each window's iteration warm-started), then the
    readings P11 leaves open (:data:`READINGS`: the sign and pattern of the errors, where each
    window's Newton iteration starts), all in one batch."""
    duration = 3.0 if quick else 10.0
    lanes = [("seed", f, lv, newton_loop.scales_for("over", lv), False)
             for f in (True, False) for lv in LEVELS]
    for name, (pattern, cold, fixed_lv, stab_lv) in READINGS.items():
        lanes += [(name, True, lv, newton_loop.scales_for(pattern, lv), cold) for lv in fixed_lv]
        lanes += [(name, False, lv, newton_loop.scales_for(pattern, lv), cold) for lv in stab_lv]
    batch = run_batch([ln[1] for ln in lanes], [0.0] * len(lanes), [NOISE_RAD] * len(lanes),
                      seed=12, duration_s=duration, scales=[ln[3] for ln in lanes],
                      cold_start=[ln[4] for ln in lanes])
    by: dict = {}
    for i, (name, fixed, lv, _, _) in enumerate(lanes):
        by.setdefault(name, {}).setdefault("fixed" if fixed else "stabilized", []).append(
            (lv, _pick(batch, i)))
    seed = {c: _level_stats(by["seed"][c]) for c in ("fixed", "stabilized")}
    readings = {}
    for name, (pattern, cold, _, _) in READINGS.items():
        row = {"pattern": pattern, "start": "cold" if cold else "warm"}
        row |= {c: _level_stats(runs, bar=False) for c, runs in by[name].items()}
        readings[name] = row
    raw = {c: [max_error_after(s) for _, s in by["seed"][c]] for c in ("fixed", "stabilized")}
    stab = [v for v in seed["stabilized"]["max_tilt_error_deg"] if v is not None]
    stab_ok = not seed["stabilized"]["lost_levels_pct"] and max(stab) <= FAIL_DEG
    levels_pct = [_pct(lv) for lv in LEVELS]
    metrics = {
        "levels_pct": levels_pct,
        "max_tilt_error_deg": {c: seed[c]["max_tilt_error_deg"] for c in seed},
        "lost_levels_pct": {c: seed[c]["lost_levels_pct"] for c in seed},
        "fixed_fails_at_level_pct": seed["fixed"]["fails_at_level_pct"],
        "fixed_within_3deg_up_to_pct": seed["fixed"]["within_3deg_up_to_pct"],
        "stabilized_within_3deg_up_to_pct": seed["stabilized"]["within_3deg_up_to_pct"],
        "fixed_lost_at_level_pct": seed["fixed"]["lost_at_level_pct"],
        "stabilized_max_over_levels_deg": seed["stabilized"]["max_over_levels_deg"],
        "readings": readings,
        "checks": {"stabilized_within_3deg_up_to_50pct": check(max(stab), FAIL_DEG, stab_ok)},
    }
    paper = {"max_tilt_error_deg": {"stabilized": [3.0] * len(levels_pct)},
             "fixed_lost_at_level_pct": 17.5}
    return Result(metrics=metrics, paper=paper,
                  series={"raw": raw, "levels_pct": levels_pct,
                          "readings": {k: {c: {"levels_pct": [_pct(lv) for lv, _ in runs],
                                               "raw": [max_error_after(s) for _, s in runs]}
                                           for c, runs in by[k].items()} for k in READINGS}},
                  simulated_s=len(lanes) * duration,
                  notes="published: stabilized < 3° up to 50 %; fixed diverges beyond 15 %. "
                        "Seed's reading: every parameter over-estimated (P11 §VI), warm start; "
                        "readings: the errors' sign and pattern, each window's start.")


def _figures_lissajous(result: Result, out_dir: Path) -> list[Path]:
    from verticality.core import plots

    paths = []
    pub = PAPER_LISSAJOUS["max_tilt_error_deg"]
    for model in ("exact", "perturbed"):
        fig, axes = plots.new_figure(2, 2, width=11.0, height_per_row=2.8)
        for j, cond in enumerate(("fixed", "stabilized")):
            s = result.series[f"{cond}.{model}"]
            t = np.asarray(s.t_s)
            ax = axes[0, j]
            ax.plot(t, np.rad2deg(s.theta_H_rad), label="true head tilt", lw=1.2)
            ax.plot(t, np.rad2deg(s.theta_H_hat_rad), "--", label="estimated", lw=1.0)
            ax.plot(t, np.rad2deg(s.reading_rad), ":", label="inclinometer reading", lw=1.0)
            ax.set_title(f"{cond} head, {model} model")
            lim = 1.4 * max(np.max(np.abs(np.rad2deg(s.theta_H_rad))),
                            np.max(np.abs(np.rad2deg(s.reading_rad))))
            ax.set_ylim(-lim, lim)
            ax.set_ylabel("angle (deg)")
            ax.legend(fontsize=7, loc="upper right")
            ax = axes[1, j]
            err = np.asarray(tilt_error_deg(s))
            ax.semilogy(t, np.maximum(err, 1e-12), lw=0.8, label="ours |tilt error|")
            plots.published_line(ax, pub[cond][model], label=f"published max {pub[cond][model]}°")
            ax.axvline(SETTLE_S, color="0.7", lw=0.8)
            ax.set_xlabel("time (s)")
            ax.set_ylabel("tilt error (deg)")
            ax.set_ylim(1e-9, 100)
            ax.legend(fontsize=7, loc="lower right")
        paths.append(plots.save(fig, out_dir / f"newton_lissajous_{model}.png"))
    if "p11_euler.fixed.exact" in result.series:
        fig, axes = plots.new_figure(1, 2, width=11.0, height_per_row=3.2)
        for j, model in enumerate(("exact", "perturbed")):
            ax = axes[0, j]
            for cond in ("fixed", "stabilized"):
                s = result.series[f"p11_euler.{cond}.{model}"]
                err = np.asarray(tilt_error_deg(s))
                line = ax.semilogy(np.asarray(s.t_s), np.maximum(err, 1e-12), lw=0.8,
                                   label=f"{cond} head (ours)")[0]
                plots.published_line(ax, pub[cond][model], color=line.get_color(),
                                     label=f"published {cond} max {pub[cond][model]}°")
            ax.axvline(SETTLE_S, color="0.7", lw=0.8)
            ax.axvline(TRANSIENT_S, color="0.7", lw=0.8, ls=":")
            ax.set_title(f"P11's Euler observer model, {model} model")
            ax.set_xlabel("time (s)")
            ax.set_ylabel("tilt error (deg)")
            ax.set_ylim(1e-5, 100)
            ax.legend(fontsize=7, loc="lower right")
        paths.append(plots.save(fig, out_dir / "newton_lissajous_p11_euler.png"))
    return paths


def _figures_uncertainty(result: Result, out_dir: Path) -> list[Path]:
    """Max error against the level: the seed's reading (both heads) and, lighter, the readings
    P11 leaves open (the fixed head; the stabilized head where run)."""
    from verticality.core import plots

    fig, axes = plots.new_figure(1, 1, width=8.0, height_per_row=4.0)
    ax = axes[0, 0]
    lv = result.series["levels_pct"]
    for cond, mk in (("fixed", "o-"), ("stabilized", "s-")):
        raw = np.asarray(result.series["raw"][cond], dtype=float)
        ax.semilogy(lv, np.where(np.isfinite(raw), raw, 1e3), mk, lw=1.6,
                    label=f"{cond} head, P11 §VI's pattern, warm (seed)")
    for name, by in result.series.get("readings", {}).items():
        for cond, mk in (("fixed", "--"), ("stabilized", ":")):
            if cond in by:
                raw = np.asarray(by[cond]["raw"], dtype=float)
                ax.semilogy(by[cond]["levels_pct"], np.where(np.isfinite(raw), raw, 1e3), mk,
                            marker=".", lw=0.8, label=f"{cond}, {name.replace('_', ' ')}")
    plots.published_line(ax, 3.0, label="published: stabilized < 3° up to 50 %")
    ax.axhline(LOST_DEG, color="r", lw=0.8, ls=":", label=f"lost (> {LOST_DEG:.0f}°)")
    ax.axvline(15, color="0.5", lw=0.8, ls="-.", label="published: fixed diverges beyond 15 %")
    ax.set_xlabel("observer parameter error (%)")
    ax.set_ylabel("max tilt error after 1 s (deg)")
    ax.legend(fontsize=6, ncol=2)
    return [plots.save(fig, out_dir / "newton_uncertainty.png")]
