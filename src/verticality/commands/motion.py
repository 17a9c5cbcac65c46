"""``verticality motion NAME --out MOTION.csv``: record a trajectory of
:mod:`verticality.trajectories` as a head-motion file (the head rigid on the trunk)."""

from __future__ import annotations

from pathlib import Path

from verticality.errors import InputError


def register(sub):
    from verticality.trajectories import BY_NAME

    p = sub.add_parser(
        "motion",
        help="write a MOTION.csv (t, q_I_H, ω_H, a_I) of a built-in trajectory, for `otolith`",
    )
    p.add_argument("name", metavar="NAME", help=f"trajectory: {', '.join(sorted(BY_NAME))}")
    p.add_argument("--out", type=Path, required=True, help="MOTION.csv to write")
    p.add_argument("--rate", type=float, default=1000.0, help="rows per second (default 1000)")
    p.add_argument("--duration", type=float, default=None,
                   help="seconds to record (default: the trajectory's own duration)")
    p.set_defaults(func=run)


def run(args) -> int:
    import numpy as np

    from verticality import so3
    from verticality.io.motion import MotionRecord, write_motion_csv
    from verticality.trajectories import BY_NAME, sample

    if args.name not in BY_NAME:
        raise InputError(f"unknown trajectory {args.name!r}; choose from {', '.join(sorted(BY_NAME))}")
    if not (args.rate > 0 and np.isfinite(args.rate)):
        raise InputError(f"--rate must be a positive number, not {args.rate}")
    traj = BY_NAME[args.name]()
    duration = traj.duration_s if args.duration is None else args.duration
    if not (duration > 0 and np.isfinite(duration)):
        raise InputError(f"--duration must be a positive number, not {duration}")
    n = int(round(duration * args.rate)) + 1
    t = np.arange(n) / args.rate
    m = sample(traj, t)
    q = np.asarray(so3.quat_from_matrix(m.R_I_B))
    write_motion_csv(args.out, MotionRecord(t, q, np.asarray(m.omega_B_rad_s), np.asarray(m.a_I_m_s2)))
    print(f"wrote {n} rows of `{args.name}` ({duration:g} s at {args.rate:g} Hz) to {args.out}")
    return 0
