"""``verticality stabilize MOTION.csv|TRIAL.hdf5 [--start S] [--duration S] [--out OUT.csv]
[--plot OUT.png] [--json] [--seeds N] [--noise SIGMA] [--exact-model] [--settle S]``

Would servoing the head upright help on *this* trunk motion? The trunk of MOTION.csv (t, q_I_T,
ω_T, a_I; :mod:`verticality.io.motion`), or of a BROAD-layout recording converted as
``verticality motion`` does, over an optional window, carries P13's gimbal head with its otolith pendulum and
gyros; the EKF on SO(3) of ``ekf-impact``/``ekf-jump`` estimates the head's tilt, once with the
head rigid on the trunk (``fixed``) and once servoed upright by P13's PD fed by the estimate
(``stabilized``). Everything but the trunk motion is the ekf-* setting (:mod:`
verticality.experiments.ekf`): P13's plant, sensor noise σ = 0.02, EKF every 20 ms started 0.1 rad
off, its model given P13's wrong parameters unless ``--exact-model``. Prints max and RMS tilt error
after the settling time for both heads and their RMS ratio; writes the tilt series and P13 Fig. 2's
figure on request.
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

from verticality.errors import InputError


def register(sub):
    p = sub.add_parser(
        "stabilize",
        help="EKF tilt error of a head rigid on a recorded trunk motion vs. one servoed upright",
        description="Put P13's gimbal head (otolith pendulum, gyros, EKF on SO(3)) on the trunk "
                    "motion of MOTION.csv (columns t,qw,qx,qy,qz,wx,wy,wz,ax,ay,az; see "
                    "docs/simulation.md), once rigid and once stabilized, and compare the tilt "
                    "errors.",
    )
    p.add_argument("motion", type=Path, metavar="MOTION.csv|TRIAL.hdf5",
                   help="the trunk's motion (e.g. from `verticality motion NAME --out ...`), or a "
                        "BROAD-layout recording (optical q, gyro ω, a_I from the accelerometer)")
    p.add_argument("--start", type=float, default=0.0, metavar="S",
                   help="seconds from the file's first row at which the window starts (default 0)")
    p.add_argument("--duration", type=float, default=None, metavar="S",
                   help="seconds to take from --start (default: to the file's end)")
    p.add_argument("--out", type=Path, default=None, metavar="OUT.csv",
                   help="write t (the file's clock) and each head's true/estimated tilt and error "
                        "at the EKF's 50 Hz")
    p.add_argument("--plot", type=Path, default=None, metavar="OUT.png",
                   help="draw the trunk acceleration, both heads' tilt and the errors")
    p.add_argument("--json", action="store_true", help="print the metrics as one JSON object")
    p.add_argument("--seeds", type=int, default=1,
                   help="sensor-noise realizations, run as one batch (default 1)")
    p.add_argument("--noise", type=float, default=None, metavar="SIGMA",
                   help="σ of the inclinometer (rad) and gyro (rad/s) noise, also the filter's R "
                        "(default P13's 0.02)")
    p.add_argument("--exact-model", action="store_true",
                   help="give the EKF the plant's true parameters (default: P13's wrong ones)")
    p.add_argument("--settle", type=float, default=None, metavar="S",
                   help="seconds from the recording's start excluded from the metrics while the EKF "
                        "converges (default 2)")
    p.set_defaults(func=run)


def _options(args, duration_s: float, ekf_period_s: float) -> tuple[float, float]:
    from verticality.experiments.ekf import SIGMA_MEASUREMENT, T_SETTLE_S

    if args.seeds < 1:
        raise InputError(f"--seeds must be at least 1, not {args.seeds}")
    noise = SIGMA_MEASUREMENT if args.noise is None else args.noise
    if not (math.isfinite(noise) and noise > 0.0):
        raise InputError(f"--noise must be a positive number (it is also the filter's R), not {noise}")
    settle = T_SETTLE_S if args.settle is None else args.settle
    if not (math.isfinite(settle) and settle >= 0.0):
        raise InputError(f"--settle must be a non-negative number, not {settle}")
    if settle + 2 * ekf_period_s > duration_s:
        raise InputError(f"the recording lasts {duration_s:g} s, which leaves no EKF sample after the "
                         f"{settle:g} s settling time (shorten it with --settle)")
    return noise, settle


def run(args) -> int:
    import numpy as np
    from rich.console import Console
    from rich.progress import Progress, SpinnerColumn, TextColumn, TimeElapsedColumn

    from verticality import recorded_trajectory as rt
    from verticality.experiments import ekf as ekf_exp
    from verticality.io.motion import load_motion, write_tilt_comparison_csv
    from verticality.params import P13_HEAD, P13_PENDULUM
    from verticality.simulation import CONDITIONS, SimConfig

    if not args.motion.is_file():
        raise InputError(f"{args.motion}: no such file")
    from verticality.io.output import check_writable_file

    for option, path in (("--out", args.out), ("--plot", args.plot)):
        if path is not None:
            check_writable_file(path, option)
    rec = load_motion(args.motion, args.start, args.duration)
    traj = rt.from_record(rec.t_s, rec.q_I_H_wxyz, rec.omega_H_rad_s, rec.a_I_m_s2,
                       name=args.motion.stem)
    err = Console(stderr=True)
    ekf_period_s = SimConfig._field_defaults["dt_estimator_s"]  # the ekf-* runs' (20 ms)
    n_periods = math.floor(traj.duration_s / ekf_period_s + 1e-9)
    if n_periods * ekf_period_s < traj.duration_s - 1e-9:  # the simulator runs whole EKF periods
        err.print(f"[yellow]note:[/yellow] simulating {n_periods * ekf_period_s:g} s of the "
                  f"{traj.duration_s:g} s recorded: the last "
                  f"{1e3 * (traj.duration_s - n_periods * ekf_period_s):.1f} ms do not fill an EKF period")
        traj = traj._replace(duration_s=n_periods * ekf_period_s)
    noise, settle = _options(args, traj.duration_s, ekf_period_s)
    mismatch, t_mismatch = rt.rate_mismatch(rec.t_s, rec.q_I_H_wxyz, rec.omega_H_rad_s)
    if mismatch > rt.RATE_MISMATCH_WARN_RAD:
        err.print(f"[yellow]warning:[/yellow] the file's ω and q disagree: over the "
                  f"{rt.RATE_MISMATCH_WINDOW_S:g} s from t = {t_mismatch:g} s, ω integrates to a "
                  f"rotation {mismatch:.3g} rad away from q's; the trunk then follows neither "
                  "exactly between rows (check ω's frame and units)")
    gap = float(np.max(np.diff(rec.t_s)))
    if gap > ekf_period_s:
        err.print(f"[yellow]note:[/yellow] rows up to {gap:g} s apart, longer than the EKF's "
                  f"{ekf_period_s:g} s period: between rows the trunk's acceleration is interpolated "
                  "linearly and its rotation by cubic Hermite")
    model = (P13_PENDULUM, P13_HEAD) if args.exact_model else ekf_exp.EKF_MODEL
    seeds = tuple(range(args.seeds))
    metrics: dict = {"max_tilt_error_deg": {}, "rms_tilt_error_deg": {}, "rejected_updates": {}}
    series: dict = {}
    diverged: dict = {}
    with Progress(SpinnerColumn(), TextColumn("{task.description}"), TimeElapsedColumn(),
                  console=err, transient=True, disable=not err.is_terminal) as progress:
        for cond in CONDITIONS:
            task = progress.add_task(f"{cond} head: compiling and simulating {traj.duration_s:g} s "
                                     f"× {len(seeds)} seed(s)", total=None)
            m, s = ekf_exp.run_condition(traj, cond, seeds=seeds, sensor_noise_std=noise,
                                         model_params=model, t_settle_s=settle)
            progress.remove_task(task)
            where = _first_non_finite(s, traj.events["t0_s"])
            if where is not None:
                diverged[cond] = where
            ok = where is None and math.isfinite(m["rms_tilt_error_deg"])
            metrics["max_tilt_error_deg"][cond] = m["max_tilt_error_deg"] if ok else None
            metrics["rms_tilt_error_deg"][cond] = m["rms_tilt_error_deg"] if ok else None
            metrics["rejected_updates"][cond] = m["rejected_updates"]
            series[cond] = s
    rms = metrics["rms_tilt_error_deg"]
    metrics["rms_ratio_stabilized_over_fixed"] = (
        None if diverged else rms["stabilized"] / max(rms["fixed"], 1e-12))
    report = {"input": str(args.motion), "duration_s": traj.duration_s, "rows": int(rec.t_s.size),
              "seeds": len(seeds), "sensor_noise_std": noise, "settle_s": settle,
              "filter_model": "exact" if args.exact_model else "p13-mismatched", **metrics,
              "diverged": diverged}
    if args.out is not None:
        t_file = series["fixed"]["t_s"] + traj.events["t0_s"]  # back on the file's clock
        write_tilt_comparison_csv(args.out, t_file, series)
        err.print(f"wrote {args.out}")
    for cond, (t_bad, what) in diverged.items():
        err.print(f"[red]error:[/red] {cond} head: the simulated {what} became non-finite at "
                  f"t = {t_bad:g} s (first seed); its metrics are left out. The trunk's motion may "
                  "be too violent for the simulated plant (2-DOF gimbal, 1 ms RK4 step), or its "
                  "q and ω may disagree")
    if args.plot is not None and not diverged:
        title = (f"{traj.name}: tilt error after its first {settle:g} s (max / RMS) — fixed "
                 f"{metrics['max_tilt_error_deg']['fixed']:.2f} / {rms['fixed']:.2f}°, stabilized "
                 f"{metrics['max_tilt_error_deg']['stabilized']:.2f} / {rms['stabilized']:.2f}°")
        ekf_exp.plot_fixed_vs_stabilized(series, title, args.plot, t_settle_s=settle,
                                         required_max_deg=None, t0_s=traj.events["t0_s"])
        err.print(f"wrote {args.plot}")
    rejected = sum(metrics["rejected_updates"].values())
    if rejected:
        err.print(f"[yellow]warning:[/yellow] the EKF refused {rejected} update(s) that would have "
                  "made its state non-finite (first seed); the estimates there are predictions")
    if args.json:
        json.dump(report, sys.stdout, indent=2)
        sys.stdout.write("\n")
    else:
        _print_table(report)
    return 1 if diverged else 0


def _first_non_finite(series: dict, t0_s: float):
    """(time on the file's clock, "plant" or "estimate") of the first non-finite sample, or None."""
    import numpy as np

    for key, what in (("tilt_true_deg", "plant"), ("tilt_est_deg", "estimate")):
        bad = ~np.all(np.isfinite(np.asarray(series[key]).reshape(len(series["t_s"]), -1)), axis=1)
        if bad.any():
            return float(series["t_s"][np.argmax(bad)] + t0_s), what
    return None


def _print_table(report: dict) -> None:
    from rich.console import Console
    from rich.table import Table

    table = Table(title=f"{report['input']}: {report['duration_s']:g} s, {report['seeds']} seed(s), "
                        f"EKF model {report['filter_model']}")
    after = f"t ≥ {report['settle_s']:g} s"
    table.add_column("head")
    table.add_column(f"max tilt error, {after} (deg)", justify="right")
    table.add_column(f"RMS tilt error, {after} (deg)", justify="right")
    for cond in ("fixed", "stabilized"):
        if cond in report["diverged"]:
            t_bad, what = report["diverged"][cond]
            table.add_row(cond, f"{what} diverged at {t_bad:g} s", "—")
        else:
            table.add_row(cond, f"{report['max_tilt_error_deg'][cond]:.3f}",
                          f"{report['rms_tilt_error_deg'][cond]:.3f}")
    console = Console()
    console.print(table)
    if report["rms_ratio_stabilized_over_fixed"] is not None:
        console.print(f"RMS ratio stabilized / fixed: {report['rms_ratio_stabilized_over_fixed']:.3f}")
