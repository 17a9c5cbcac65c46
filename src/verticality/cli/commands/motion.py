"""``verticality motion NAME|TRIAL.hdf5 --out MOTION.csv [--rate HZ] [--start S] [--duration S]``:
record a trajectory of :mod:`verticality.simulation.trajectories` (the head rigid on the trunk), or
convert a window of a BROAD-layout recording (optical orientation, gyro, accelerometer), as a
head-motion file for `otolith` and `stabilize`."""

from __future__ import annotations

from pathlib import Path

from verticality.core.errors import InputError


def register(sub):
    from verticality.simulation.recorded import DEFAULT_RATE_HZ
    from verticality.simulation.trajectories import BY_NAME

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


def run(args) -> int:
    from verticality.io.motion import broad_motion, write_motion_csv
    from verticality.io.paths import check_input_file, check_paths, check_written
    from verticality.simulation.recorded import built_in_motion
    from verticality.simulation.trajectories import BY_NAME

    is_file = args.name not in BY_NAME and Path(args.name).exists()
    if is_file:
        check_input_file(args.name)
    check_paths({"--out": args.out}, [args.name] if is_file else [])
    if args.name in BY_NAME:
        rec, what = built_in_motion(args.name, args.rate, args.start, args.duration)
    elif is_file:
        if args.rate is not None:
            raise InputError("--rate applies to built-in trajectories; a recording keeps its own "
                             "sampling rate")
        rec, what = broad_motion(Path(args.name), args.start, args.duration)
    else:
        raise InputError(f"{args.name!r} is neither a built-in trajectory "
                         f"({', '.join(sorted(BY_NAME))}) nor an existing file")
    write_motion_csv(args.out, rec)
    check_written(args.out)
    print(f"wrote {rec.t_s.size} rows of {what} to {args.out}")
    return 0
