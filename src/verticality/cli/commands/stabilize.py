"""``verticality stabilize MOTION.csv|TRIAL.hdf5 [--start S] [--duration S] [--out OUT.csv]
[--plot OUT.png] [--json] [--seeds N] [--noise SIGMA] [--exact-model] [--settle S]``

Would servoing the head upright help on *this* trunk motion? The trunk of MOTION.csv (t, q_I_T,
ω_T, a_I; :mod:`verticality.io.motion`), or of a BROAD-layout recording converted as
``verticality motion`` does, over an optional window:
:func:`verticality.simulation.stabilization.compare_heads` (the ekf-* setting with a fixed and a
stabilized head). Prints max and RMS tilt error after the settling time for both heads and their RMS
ratio; writes the tilt series and P13 Fig. 2's figure on request.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path


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
                   help="seconds from the recording's start excluded from the metrics while the "
                        "EKF converges (default 2)")
    p.set_defaults(func=run)


def run(args) -> int:
    from rich.console import Console
    from rich.progress import Progress, SpinnerColumn, TextColumn, TimeElapsedColumn

    from verticality.io.motion import load_motion, write_tilt_comparison_csv
    from verticality.io.paths import check_input_file, check_paths, check_written
    from verticality.simulation import stabilization as st
    from verticality.simulation import stabilization_notes as notes

    check_input_file(args.motion)
    check_paths({"--out": args.out, "--plot": args.plot}, [args.motion], figures=["--plot"])
    rec = load_motion(args.motion, args.start, args.duration)
    err = Console(stderr=True)
    with Progress(SpinnerColumn(), TextColumn("{task.description}"), TimeElapsedColumn(),
                  console=err, transient=True, disable=not err.is_terminal) as progress:
        task = progress.add_task("reading", total=None)
        c = st.compare_heads(rec, args.motion.stem, source=str(args.motion), seeds=args.seeds,
                             noise=args.noise, exact_model=args.exact_model, settle_s=args.settle,
                             progress=lambda text: progress.update(task, description=text))
    report = c.report
    say = {"note": "[yellow]note:[/yellow]", "warning": "[yellow]warning:[/yellow]",
           "error": "[red]error:[/red]"}
    for note in notes.input_notes(c):
        err.print(f"{say[note.level]} {note.text}")
    if args.out is not None:
        write_tilt_comparison_csv(args.out, c.t_file_s(), c.series)
        check_written(args.out)
        err.print(f"wrote {args.out}")
    for note in notes.diverged_notes(c):
        err.print(f"{say[note.level]} {note.text}")
    if args.plot is not None and not c.diverged:
        st.plot_comparison(c, args.plot)
        err.print(f"wrote {args.plot}")
    for note in notes.rejected_notes(c):
        err.print(f"{say[note.level]} {note.text}")
    if args.json:
        json.dump(report, sys.stdout, indent=2)
        sys.stdout.write("\n")
    else:
        _print_table(report)
    return 1 if c.diverged else 0


def _print_table(report: dict) -> None:
    from rich.console import Console
    from rich.table import Table

    from verticality.cli.commands import print_table

    table = Table(title=f"{report['input']}: {report['duration_s']:g} s, "
                        f"{report['seeds']} seed(s), EKF model {report['filter_model']}")
    after = f"t ≥ {report['settle_s']:g} s"
    table.add_column("head", no_wrap=True)
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
    print_table(table, console)
    if report["rms_ratio_stabilized_over_fixed"] is not None:
        console.print("RMS ratio stabilized / fixed: "
                      f"{report['rms_ratio_stabilized_over_fixed']:.3f}")
