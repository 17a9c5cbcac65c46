"""``verticality estimate INPUT --out OUT.csv [--filter NAME] [--plot OUT.png] [--units ...]``.

INPUT is an IMU CSV (``t,gyr_x,gyr_y,gyr_z,acc_x,acc_y,acc_z``, SI units) or a BROAD-layout HDF5
file. Writes ``t,roll_rad,pitch_rad,gx,gy,gz,bias_x,bias_y,bias_z,flags``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from verticality.errors import InputError


def register(sub):
    from verticality.analysis.broad_eval import FILTERS, OURS

    p = sub.add_parser("estimate", help="estimate roll, pitch and the gravity direction from an "
                                        "IMU recording (CSV or BROAD HDF5)")
    p.add_argument("input", type=Path, metavar="INPUT",
                   help="CSV t,gyr_x,gyr_y,gyr_z,acc_x,acc_y,acc_z (s, rad/s, m/s²) or BROAD .hdf5")
    p.add_argument("--out", type=Path, required=True, metavar="OUT.csv",
                   help="output CSV t,roll_rad,pitch_rad,gx,gy,gz,bias_x,bias_y,bias_z,flags")
    p.add_argument("--filter", default=OURS, choices=FILTERS,
                   help=f"filter (default {OURS}; peers need the optional peers extra)")
    p.add_argument("--plot", type=Path, default=None, metavar="OUT.png",
                   help="also draw roll, pitch and bias over time")
    p.add_argument("--units", nargs="+", default=[], metavar="UNIT",
                   help="input units when not SI: deg/s and/or g (e.g. --units deg/s g)")
    p.set_defaults(func=run)


def _parse_units(units: list[str]) -> tuple[str | None, str | None]:
    from verticality.io.imu import ACC_UNITS, GYR_UNITS

    gyr_u = acc_u = None
    for u in units:
        if u in GYR_UNITS:
            gyr_u = u
        elif u in ACC_UNITS:
            acc_u = u
        else:
            raise InputError(f"unknown unit {u!r}; use {', '.join(GYR_UNITS)} for the gyro and "
                             f"{', '.join(ACC_UNITS)} for the accelerometer")
    return gyr_u, acc_u


def load_input(path: Path, units: list[str]):
    """(t_s, gyr_rad_s, acc_m_s2, dt_s) from a CSV or a BROAD HDF5 file, units checked."""
    from verticality.io import broad, imu

    gyr_u, acc_u = _parse_units(units)
    if broad.is_broad_file(path):
        trial = broad.load_trial(path)
        gyr, acc = imu.check_units(trial.gyr_rad_s, trial.acc_m_s2, gyr_units=gyr_u,
                                   acc_units=acc_u, source=str(path), dt_s=trial.dt_s)
        t = trial.t_s
        return t, gyr, acc, np.full(t.shape, trial.dt_s)
    rec = imu.read_imu_csv(path, gyr_units=gyr_u, acc_units=acc_u)
    return rec.t_s, rec.gyr_rad_s, rec.acc_m_s2, rec.dt_s


def run(args) -> int:
    from verticality.analysis.broad_eval import OURS, run_filter
    from verticality.io import imu

    if not args.input.is_file():
        raise InputError(f"{args.input}: no such file")
    t, gyr, acc, dt = load_input(args.input, args.units)
    if args.filter == OURS:
        from verticality.estimators import tilt

        out = tilt.run(gyr, acc, dt)
    else:
        quat, bias = run_filter(args.filter, gyr, acc, dt)
        out = _peer_output(np.asarray(quat), np.asarray(bias))
    imu.write_estimate_csv(args.out, t, out)
    print(f"wrote {args.out} ({t.size} samples, filter {args.filter})")
    if args.plot is not None:
        path = _plot(args.plot, t, out, args.filter)
        print(f"wrote {path}")
    return 0


def _peer_output(quat, bias):
    from verticality.estimators import tilt

    quat = quat / np.linalg.norm(quat, axis=1, keepdims=True)
    n = quat.shape[0]
    res = tilt.TiltOutput(np.zeros(n), np.zeros(n), np.zeros((n, 3)), quat, bias,
                          np.zeros((n, 7)), np.zeros(n, dtype=np.int32))
    tilt._angles_np(res)
    return res


def _plot(path: Path, t, out, name: str) -> Path:
    from verticality.plots import new_figure, save

    fig, axes = new_figure(3, 1, height_per_row=2.2)
    ax = axes[:, 0]
    ax[0].plot(t, np.degrees(out.roll_rad), label="roll")
    ax[0].plot(t, np.degrees(out.pitch_rad), label="pitch")
    ax[0].set_ylabel("angle (deg)")
    ax[0].legend(loc="upper right")
    ax[0].set_title(f"tilt estimate ({name})")
    for i, c in enumerate("xyz"):
        ax[1].plot(t, np.degrees(out.bias_S_rad_s[:, i]), label=f"bias {c}")
    ax[1].set_ylabel("gyro bias (deg/s)")
    ax[1].legend(loc="upper right")
    flags = np.asarray(out.flags)
    ax[2].step(t, flags, where="post")
    ax[2].set_ylabel("flags (bits)")
    ax[2].set_xlabel("t (s)")
    return save(fig, path)
