"""``verticality motion NAME|TRIAL.hdf5 --out MOTION.csv [--rate HZ] [--start S] [--duration S]``:
record a trajectory of :mod:`verticality.trajectories` (the head rigid on the trunk), or convert
a window of a BROAD-layout recording (optical orientation, gyro, accelerometer), as a head-motion
file for `otolith` and `stabilize`."""

from __future__ import annotations

from pathlib import Path

from verticality.errors import InputError

DEFAULT_RATE_HZ = 1000.0


def register(sub):
    from verticality.trajectories import BY_NAME

    p = sub.add_parser(
        "motion",
        help="write a MOTION.csv (t, q_I_H, ω_H, a_I) of a built-in trajectory or a BROAD "
             "recording, for `otolith` and `stabilize`",
    )
    p.add_argument("name", metavar="NAME|TRIAL.hdf5",
                   help=f"trajectory: {', '.join(sorted(BY_NAME))}; or a BROAD-layout HDF5 file")
    p.add_argument("--out", type=Path, required=True, help="MOTION.csv to write")
    p.add_argument("--rate", type=float, default=None,
                   help=f"rows per second of a built-in trajectory (default {DEFAULT_RATE_HZ:g}); "
                        "a recording keeps its own")
    p.add_argument("--start", type=float, default=0.0,
                   help="first second to take (default 0)")
    p.add_argument("--duration", type=float, default=None,
                   help="seconds to take (default: the trajectory's own duration, or to the "
                        "recording's end)")
    p.set_defaults(func=run)


def _check_positive(name: str, value) -> None:
    import math

    if value is not None and not (math.isfinite(value) and value > 0):
        raise InputError(f"--{name} must be a positive number, not {value}")


def run(args) -> int:
    from verticality.io.motion import write_motion_csv
    from verticality.io.output import check_writable_file
    from verticality.trajectories import BY_NAME

    check_writable_file(args.out, "--out")
    _check_positive("duration", args.duration)
    _check_positive("rate", args.rate)
    if not args.start >= 0.0:
        raise InputError(f"--start must be a non-negative number, not {args.start}")
    if args.name in BY_NAME:
        rec, what = _built_in(args)
    elif Path(args.name).exists():
        rec, what = _recording(args)
    else:
        raise InputError(f"{args.name!r} is neither a built-in trajectory ({', '.join(sorted(BY_NAME))}) "
                         "nor an existing file")
    write_motion_csv(args.out, rec)
    print(f"wrote {rec.t_s.size} rows of {what} to {args.out}")
    return 0


def _built_in(args):
    import numpy as np

    from verticality.recorded_trajectory import record_of
    from verticality.trajectories import BY_NAME

    traj = BY_NAME[args.name]()
    rate = DEFAULT_RATE_HZ if args.rate is None else args.rate
    duration = (traj.duration_s - args.start) if args.duration is None else args.duration
    if not duration > 0:
        raise InputError(f"--start {args.start:g} is at or after the end of `{args.name}` "
                         f"({traj.duration_s:g} s)")
    n = int(round(duration * rate)) + 1
    rec = record_of(traj, args.start + np.arange(n) / rate)
    return rec, f"`{args.name}` ({duration:g} s from {args.start:g} s at {rate:g} Hz)"


def _recording(args):
    from verticality.io import broad
    from verticality.io.motion import from_broad_trial

    path = Path(args.name)
    if not broad.is_broad_file(path):
        raise InputError(f"{path}: not an HDF5 file (a recording must be in the BROAD layout: "
                         "imu_gyr, imu_acc, opt_quat, sampling_rate)")
    if args.rate is not None:
        raise InputError("--rate applies to built-in trajectories; a recording keeps its own "
                         "sampling rate")
    trial = broad.load_trial(path)
    rec = from_broad_trial(trial, args.start, args.duration)
    span = rec.t_s[-1] - rec.t_s[0]
    return rec, f"{path.name} ({span:.3f} s from {rec.t_s[0]:.3f} s at {trial.sampling_rate_hz:g} Hz)"
