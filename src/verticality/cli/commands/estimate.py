"""``verticality estimate INPUT --out OUT.csv [--filter NAME] [--offline] [--plot OUT.png]
[--gyr-range DEG_S] [--acc-range G] [--units ...] [--columns t=NAME,...] [--time-unit s|ms|us|ns]``.

``verticality estimate FOLDER --out DIR [--workers N] [--scheduler ADDRESS] [--resume]``: every
recording of FOLDER (or of a quoted glob pattern) into ``DIR/NAME.csv``, one Dask task each, and
the summary table ``DIR/summary.csv`` / ``.json`` (docs/sweep.md, Folders of recordings).

INPUT is an IMU CSV (``t,gyr_x,gyr_y,gyr_z,acc_x,acc_y,acc_z``, SI units; an EuRoC / TUM-VI IMU
file; or any header mapped with ``--columns``), a BROAD-layout HDF5 file, or a robotics log (PX4
ULog, ROS 1 bag, ROS 2 bag folder, MCAP; docs/logs.md: ``--topic``, ``--compare OUT.csv``,
``--out OUT.mcap``, ``--ros2-bag DIR``). Writes
``t,roll_rad,pitch_rad,gx,gy,gz,bias_x,bias_y,bias_z,flags``; with ``--sigma`` (our filter) a last
column ``tilt_sigma_rad``, the tilt's standard deviation. ``--offline``: our smoother
(``tilt.smooth``) over the whole recording instead of the causal filter.
"""

from __future__ import annotations

import sys
from pathlib import Path

from verticality.cli.commands import add_engine_arguments
from verticality.core.errors import InputError


def register(sub):
    from verticality.tilt.evaluation.broad import FILTERS, OURS

    p = sub.add_parser("estimate", help="estimate roll, pitch and the gravity direction from an "
                                        "IMU recording (CSV, BROAD HDF5, PX4 ULog, ROS bag, "
                                        "MCAP)")
    p.add_argument("input", type=Path, metavar="INPUT",
                   help="CSV t,gyr_x,gyr_y,gyr_z,acc_x,acc_y,acc_z (s, rad/s, m/s²), EuRoC/TUM-VI "
                        "IMU CSV, CSV with --columns, BROAD .hdf5, PX4 .ulg, ROS 1 .bag, ROS 2 bag "
                        "folder or .mcap (logs need the logs extra); or a folder (or a quoted "
                        "glob) of them: one output each in --out DIR and a summary table")
    p.add_argument("--out", type=Path, required=True, metavar="OUT.csv",
                   help="output CSV t,roll_rad,pitch_rad,gx,gy,gz,bias_x,bias_y,bias_z,flags "
                        "(a folder when INPUT is one); for a log, a name ending in .mcap writes "
                        "the tilt as MCAP (sensor_msgs/Imu on --tilt-topic)")
    add_engine_arguments(p, "folder only: one task per recording",
                         "the recordings one after the other in this process")
    p.add_argument("--resume", action="store_true",
                   help="folder only: keep the outputs of DIR that are complete, compute the rest")
    p.add_argument("--sigma", action="store_true",
                   help="also write a last column tilt_sigma_rad, the standard deviation of the "
                        "tilt (our filter only; docs/tilt.md)")
    p.add_argument("--filter", default=OURS, choices=FILTERS,
                   help=f"filter (default {OURS}; peers need the optional peers extra)")
    p.add_argument("--offline", action="store_true",
                   help="smooth: every sample's estimate also uses the samples after it (our "
                        "filter followed by a backward pass over the whole recording, read at "
                        "once; docs/tilt.md, Offline smoothing)")
    p.add_argument("--gyr-range", type=float, default=None, metavar="DEG_S",
                   help="the gyro's full-scale range in °/s (e.g. 2000): a reading there is "
                        "clipped (flag 512; our filter only; default: inferred from flat tops; "
                        "docs/tilt.md, Sensors at their limits)")
    p.add_argument("--acc-range", type=float, default=None, metavar="G",
                   help="the accelerometer's full-scale range in g (e.g. 16): a reading there is "
                        "clipped, kept with its excess's uncertainty (flag 512; our filter only; "
                        "default: inferred)")
    p.add_argument("--plot", type=Path, default=None, metavar="OUT.png",
                   help="also draw roll, pitch, bias, the tilt's σ and the flags over time")
    add_layout_options(p)
    add_log_options(p)
    p.set_defaults(func=run)


def add_log_options(p) -> None:
    """The options of a robotics log input (docs/logs.md)."""
    p.add_argument("--topic", default=None, metavar="NAME",
                   help="log only: the IMU topic to read (default: sensor_combined in a ULog, "
                        "the only sensor_msgs/Imu topic in a bag)")
    p.add_argument("--compare", type=Path, default=None, metavar="OUT.csv",
                   help="log only: write the log's own attitude estimate (PX4's vehicle_attitude, "
                        "the Imu orientation; a simulation's ground truth) beside ours, per "
                        "sample, and print the angles between them while moving and at rest")
    p.add_argument("--ros2-bag", type=Path, default=None, metavar="DIR",
                   help="log only: also write the tilt as a new ROS 2 bag folder (sqlite3 "
                        "storage)")
    p.add_argument("--tilt-topic", default=None, metavar="/NAME",
                   help="the topic of the tilt in an .mcap --out or --ros2-bag (default /tilt)")
    p.add_argument("--tilt-message", default="imu", choices=("imu", "quaternion"),
                   help="the message of the tilt there: sensor_msgs/Imu (orientation and its "
                        "covariance) or geometry_msgs/QuaternionStamped (default imu)")


def add_layout_options(p) -> None:
    """``--units``, ``--columns`` and ``--time-unit``: how an IMU CSV is read (also ``stream``)."""
    p.add_argument("--units", nargs="+", default=[], metavar="UNIT",
                   help="input units when not SI: deg/s and/or g (e.g. --units deg/s g)")
    p.add_argument("--columns", default=None, metavar="t=NAME,gyr_x=NAME,...",
                   help="CSV only: the file's column for each of t,gyr_x,gyr_y,gyr_z,acc_x,acc_y,"
                        "acc_z (all seven), e.g. --columns t=timestamp,gyr_x=wx,gyr_y=wy,gyr_z=wz,"
                        "acc_x=ax,acc_y=ay,acc_z=az")
    p.add_argument("--time-unit", default=None, metavar="s|ms|us|ns",
                   help="CSV only: unit of the time column (default: the header's [unit], else s; "
                        "ms, us and ns times are written relative to the first stamp)")


def run(args) -> int:
    from rich.console import Console

    from verticality.io.logs import is_log
    from verticality.io.paths import check_input_file, check_paths, check_written
    from verticality.tilt.files import check_sigma, estimate_file
    from verticality.tilt.folder import is_folder_input
    from verticality.tilt.limits import datasheet_ranges

    if is_log(args.input):
        return run_log(args)
    given = [o for o, v in (("--topic", args.topic), ("--compare", args.compare),
                            ("--ros2-bag", args.ros2_bag), ("--tilt-topic", args.tilt_topic))
             if v is not None]
    if args.out.suffix.lower() == ".mcap" and not is_folder_input(args.input):
        given.append("--out .mcap")
    if given:
        raise InputError(f"{', '.join(given)}: for a robotics log (PX4 ULog, ROS bag, MCAP); "
                         f"{args.input} is none")
    if is_folder_input(args.input):
        return run_folder(args)
    given = [o for o, v in (("--workers", args.workers), ("--scheduler", args.scheduler),
                            ("--resume", args.resume)) if v not in (None, False)]
    if given:
        raise InputError(f"{', '.join(given)}: for a folder of recordings; {args.input} is a file")
    check_input_file(args.input)
    check_sigma(args.filter, args.sigma)
    check_paths({"--out": args.out, "--plot": args.plot}, [args.input], figures=["--plot"])

    # a spinner on a terminal (nothing otherwise): a long recording takes a while to read and write
    with Console(stderr=True).status(f"reading, filtering ({args.filter}) and writing …"):
        run = estimate_file(args.input, args.out, args.units, args.columns, args.time_unit,
                            args.filter, sigma=args.sigma, keep=args.plot is not None,
                            offline=args.offline,
                            ranges=datasheet_ranges(args.gyr_range, args.acc_range))
    check_written(args.out)
    how = ", offline (smoothed)" if args.offline else ""
    print(f"wrote {args.out} ({run.n} samples, filter {args.filter}{how})")
    if run.sigma_line is not None:
        print(run.sigma_line)
    if run.gap_line is not None:
        print(run.gap_line, file=sys.stderr)
    if run.t_origin is not None:
        print(f"t is in seconds from the input's first time stamp, {run.t_origin}")
    if args.plot is not None:
        from verticality.tilt.plots import plot_estimate

        print("wrote "
              f"{plot_estimate(args.plot, run.t_s, run.out, args.filter, run.tilt_sigma_rad)}")
    return 0


def run_log(args) -> int:
    """``estimate LOG``: the tilt of a robotics log (:func:`verticality.tilt.logs.
    estimate_log_file`), its notes on stderr, the comparison's lines on stdout."""
    from verticality.io.paths import check_paths, check_written
    from verticality.tilt.limits import datasheet_ranges
    from verticality.tilt.logs import check_log_outputs, estimate_log_file

    given = [o for o, v in (("--workers", args.workers), ("--scheduler", args.scheduler),
                            ("--resume", args.resume), ("--columns", args.columns),
                            ("--time-unit", args.time_unit)) if v not in (None, False)]
    if given:
        raise InputError(f"{', '.join(given)}: not for a robotics log ({args.input})")
    inputs = check_log_outputs(args.input, args.ros2_bag, [args.out, args.compare, args.plot])
    check_paths({"--out": args.out, "--plot": args.plot, "--compare": args.compare}, inputs,
                figures=["--plot"])
    lr = estimate_log_file(args.input, args.out, topic=args.topic, units=args.units,
                           filter_name=args.filter, sigma=args.sigma, offline=args.offline,
                           ranges=datasheet_ranges(args.gyr_range, args.acc_range),
                           compare_path=args.compare, ros2_bag=args.ros2_bag,
                           tilt_topic=args.tilt_topic, message=args.tilt_message,
                           keep_comparison=args.plot is not None)
    for path in lr.written:
        if Path(path).is_file():
            check_written(path)
    run, rec = lr.run, lr.recording
    how = ", offline (smoothed)" if args.offline else ""
    print(f"wrote {', '.join(map(str, lr.written))} ({run.n} samples of {rec.topic}, filter "
          f"{args.filter}{how})")
    for note in rec.notes:
        print(f"note: {note}", file=sys.stderr)
    if run.sigma_line is not None:
        print(run.sigma_line)
    if run.gap_line is not None:
        print(run.gap_line, file=sys.stderr)
    print(f"t is in seconds from the log's first time stamp, {run.t_origin}")
    if lr.comparison is not None:
        for line in lr.comparison.lines:
            print(line)
    if args.plot is not None:
        from verticality.tilt.plots import plot_estimate, plot_log_comparison

        if lr.comparison is not None:
            drawn = plot_log_comparison(args.plot, lr.comparison, run.out, args.filter)
        else:
            drawn = plot_estimate(args.plot, run.t_s, run.out, args.filter, run.tilt_sigma_rad)
        print(f"wrote {drawn}")
    return 0


def run_folder(args) -> int:
    """``estimate FOLDER --out DIR``: exit status 0 when every recording was estimated, 1 when
    some failed (each a row of the summary with its error, named on stderr)."""
    from verticality.tilt.folder import estimate_folder
    from verticality.tilt.limits import datasheet_ranges

    if args.plot is not None:
        raise InputError("--plot: one recording at a time; a folder's run writes no figures")
    s = estimate_folder(args.input, args.out, units=args.units, columns=args.columns,
                        time_unit=args.time_unit, filter_name=args.filter, sigma=args.sigma,
                        offline=args.offline,
                        ranges=datasheet_ranges(args.gyr_range, args.acc_range),
                        scheduler=args.scheduler, workers=args.workers, resume=args.resume)
    failed = [r for r in s.rows if r["status"] != "ok"]
    for r in failed:
        print(r["error"] if r["error"].startswith(r["file"]) else f"{r['file']}: {r['error']}",
              file=sys.stderr)
    print(f"{len(s.rows)} recordings ({len(s.computed)} computed now, {s.wall_s:.1f} s), "
          f"{len(failed)} failed → {s.out_dir}, table {s.table_csv}")
    return 1 if failed else 0
