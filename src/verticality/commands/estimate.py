"""``verticality estimate INPUT --out OUT.csv [--filter NAME] [--plot OUT.png] [--units ...]
[--columns t=NAME,...] [--time-unit s|ms|us|ns]``.

INPUT is an IMU CSV (``t,gyr_x,gyr_y,gyr_z,acc_x,acc_y,acc_z``, SI units; an EuRoC / TUM-VI IMU
file; or any header mapped with ``--columns``) or a BROAD-layout HDF5 file. Writes
``t,roll_rad,pitch_rad,gx,gy,gz,bias_x,bias_y,bias_z,flags``; with ``--sigma`` (our filter) a last
column ``tilt_sigma_rad``, the tilt's standard deviation.
"""

from __future__ import annotations

from pathlib import Path
from typing import NamedTuple

import numpy as np

from verticality.errors import InputError


def register(sub):
    from verticality.analysis.broad_eval import FILTERS, OURS

    p = sub.add_parser("estimate", help="estimate roll, pitch and the gravity direction from an "
                                        "IMU recording (CSV or BROAD HDF5)")
    p.add_argument("input", type=Path, metavar="INPUT",
                   help="CSV t,gyr_x,gyr_y,gyr_z,acc_x,acc_y,acc_z (s, rad/s, m/s²), EuRoC/TUM-VI "
                        "IMU CSV, CSV with --columns, or BROAD .hdf5")
    p.add_argument("--out", type=Path, required=True, metavar="OUT.csv",
                   help="output CSV t,roll_rad,pitch_rad,gx,gy,gz,bias_x,bias_y,bias_z,flags")
    p.add_argument("--sigma", action="store_true",
                   help="also write a last column tilt_sigma_rad, the standard deviation of the "
                        "tilt (our filter only; docs/tilt.md)")
    p.add_argument("--filter", default=OURS, choices=FILTERS,
                   help=f"filter (default {OURS}; peers need the optional peers extra)")
    p.add_argument("--plot", type=Path, default=None, metavar="OUT.png",
                   help="also draw roll, pitch, bias, the tilt's σ and the flags over time")
    add_layout_options(p)
    p.set_defaults(func=run)


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


class LoadedInput(NamedTuple):
    t_s: np.ndarray
    gyr_rad_s: np.ndarray
    acc_m_s2: np.ndarray
    dt_s: np.ndarray
    t_origin: str | None  # e.g. "1403636579758555392 ns" when t_s is relative to that stamp


def load_input(path: Path, units: list[str], columns: str | None = None,
               time_unit: str | None = None) -> LoadedInput:
    """Time, gyro, accelerometer and steps from a CSV (any layout :func:`imu.read_imu_csv`
    reads; ``columns`` is the ``--columns`` text) or a BROAD HDF5 file, units checked.
    ``columns`` and ``time_unit`` describe CSV files only and are refused with an HDF5 file."""
    from verticality.io import broad, imu, imu_layout

    gyr_u, acc_u = _parse_units(units)
    if broad.is_broad_file(path):
        given = [o for o, v in (("--columns", columns), ("--time-unit", time_unit)) if v is not None]
        if given:
            verb = "apply" if len(given) > 1 else "applies"
            raise InputError(f"{path}: {' and '.join(given)} {verb} to CSV input only, not to a "
                             "BROAD HDF5 file")
        trial = broad.load_trial(path)
        gyr, acc = imu.check_units(trial.gyr_rad_s, trial.acc_m_s2, gyr_units=gyr_u,
                                   acc_units=acc_u, source=str(path), dt_s=trial.dt_s)
        t = trial.t_s
        return LoadedInput(t, gyr, acc, np.full(t.shape, trial.dt_s), None)
    mapping = imu_layout.parse_columns_spec(columns) if columns is not None else None
    rec = imu.read_imu_csv(path, gyr_units=gyr_u, acc_units=acc_u, columns=mapping,
                           time_unit=time_unit)
    if rec.t_s.size < 2:
        raise InputError(f"{path}: one data row; the filter needs at least two (a time step)")
    origin = None if rec.t0_stamp is None else f"{rec.t0_stamp} {rec.time_unit}"
    return LoadedInput(rec.t_s, rec.gyr_rad_s, rec.acc_m_s2, rec.dt_s, origin)


def run(args) -> int:
    from verticality.analysis.broad_eval import OURS, run_filter
    from verticality.io import imu

    if not args.input.is_file():
        raise InputError(f"{args.input}: no such file")
    if args.sigma and args.filter != OURS:
        raise InputError(f"--sigma: filter {args.filter} reports no uncertainty; use --filter {OURS}")
    from rich.console import Console

    from verticality.io.output import check_writable_file

    check_writable_file(args.out, "--out")
    if args.plot is not None:
        check_writable_file(args.plot, "--plot")

    # a spinner on a terminal (nothing otherwise): a long recording takes a while to read and write
    with Console(stderr=True).status(f"reading {args.input} …") as status:
        t, gyr, acc, dt, t_origin = load_input(args.input, args.units, args.columns,
                                               args.time_unit)
        status.update(f"filtering {t.size} samples ({args.filter}) …")
        sigma = None
        if args.filter == OURS:
            from verticality.estimators import tilt

            out = tilt.estimate(gyr, acc, dt)
            sigma = tilt.tilt_sigma_rad(out.var)
        else:
            quat, bias = run_filter(args.filter, gyr, acc, dt)
            out = _peer_output(np.asarray(quat), np.asarray(bias), dt)
        status.update(f"writing {args.out} …")
        imu.write_estimate_csv(args.out, t, out, tilt_sigma_rad=sigma if args.sigma else None)
    print(f"wrote {args.out} ({t.size} samples, filter {args.filter})")
    if sigma is not None:
        _print_sigma(sigma, np.asarray(out.flags))
    _warn_gaps(t, dt, ours=args.filter == OURS)
    if t_origin is not None:
        print(f"t is in seconds from the input's first time stamp, {t_origin}")
    if args.plot is not None:
        path = _plot(args.plot, t, out, args.filter, sigma)
        print(f"wrote {path}")
    return 0


def _print_sigma(sigma_rad, flags) -> None:
    """One line: the tilt's standard deviation over the samples from the initialization on that
    are not flagged re-acquiring (after the start and each gap the filter has not yet settled on
    the vertical)."""
    from verticality.estimators.tilt import INIT, REACQUIRING

    init = np.flatnonzero(flags & INIT)
    if init.size == 0:
        print("tilt σ: no sample initialized the filter (no usable accelerometer sample with a "
              "valid time step), so there is no estimate")
        return
    settled = (flags & REACQUIRING) == 0
    settled[:init[0]] = False
    s = np.degrees(sigma_rad[settled])
    if s.size == 0:
        print("tilt σ: every sample is still re-acquiring (the recording is shorter than the "
              "re-acquisition time), the estimate is unconfirmed")
        return
    print(f"tilt σ outside re-acquisitions: median {np.median(s):.2f}°, "
          f"95 % of samples below {np.percentile(s, 95):.2f}°, largest {np.max(s):.2f}°")


def _warn_gaps(t, dt, ours: bool = True) -> None:
    """One line on stderr when the time stamps have gaps longer than the tilt filter's
    ``gap_flag_s``: motion inside a gap goes unseen by the gyro integration."""
    import sys

    from verticality.estimators import tilt

    p = tilt.DEFAULT_PARAMS
    gaps = np.flatnonzero(np.isfinite(dt) & (dt > p.gap_flag_s))
    if gaps.size == 0:
        return
    k = gaps[np.argmax(dt[gaps])]
    if ours:
        what = (f"our filter re-acquires the tilt from the accelerometer {p.reacquire_s:g} s after "
                f"each gap (flag {tilt.REACQUIRED}); until then the estimate can be off by the "
                f"rotation inside the gap (flag {tilt.REACQUIRING})")
    else:
        what = "this filter's estimate after a gap can be off for seconds"
    print(f"warning: {gaps.size} gap(s) in the time stamps longer than {p.gap_flag_s:g} s "
          f"(largest {dt[k]:.6g} s, ending at t = {t[k]:.6g} s): the gyro rate is integrated "
          f"across a gap, so motion inside one is not seen; {what}. Flag {tilt.DT_GAP} marks the "
          "sample that ends each gap", file=sys.stderr)


def _peer_output(quat, bias, dt):
    """A peer filter's output as a ``TiltOutput``: its quaternions and bias, no variances, and of
    our flags only ``DT_GAP`` (a property of the input)."""
    from verticality.estimators import tilt

    quat = quat / np.linalg.norm(quat, axis=1, keepdims=True)
    n = quat.shape[0]
    gap = dt > tilt.DEFAULT_PARAMS.gap_flag_s
    from verticality.estimators.tilt_core import up_roll_pitch

    up, roll, pitch = up_roll_pitch(tuple(quat.T), xp=np)
    return tilt.TiltOutput(roll, pitch, np.stack(up, axis=1), quat, bias, np.zeros((n, 7)),
                           np.where(gap, tilt.DT_GAP, 0).astype(np.int32), np.ones(n, dtype=bool))


def _runs(flags, bit):
    """(first, last) sample indices of each run of consecutive samples carrying ``bit``."""
    on = np.concatenate([[0], (flags & bit) > 0, [0]]).astype(int)
    return np.flatnonzero(np.diff(on) == 1), np.flatnonzero(np.diff(on) == -1) - 1


def _shade_reacquiring(ax, t, flags) -> None:
    """Shade the spans from the start or a gap to the tilt's re-acquisition (flag REACQUIRING)."""
    from verticality.estimators.tilt import REACQUIRING

    starts, lasts = _runs(flags, REACQUIRING)
    for j, (a, b) in enumerate(zip(starts, lasts + 1, strict=True)):
        ax.axvspan(t[a], t[min(b, t.size - 1)], color="0.85", zorder=0,
                   label="re-acquiring (after the start or a gap)" if j == 0 else None)


def _plot(path: Path, t, out, name: str, sigma_rad=None) -> Path:
    from verticality.plots import new_figure, save

    fig, axes = new_figure(3 if sigma_rad is None else 4, 1, height_per_row=2.2)
    ax = axes[:, 0]
    ax[0].plot(t, np.degrees(out.roll_rad), label="roll")
    ax[0].plot(t, np.degrees(out.pitch_rad), label="pitch")
    ax[0].set_ylabel("angle (deg)")
    flags = np.asarray(out.flags)
    _shade_reacquiring(ax[0], t, flags)
    ax[0].legend(loc="upper right")
    ax[0].set_title(f"tilt estimate ({name})")
    for i, c in enumerate("xyz"):
        ax[1].plot(t, np.degrees(out.bias_S_rad_s[:, i]), label=f"bias {c}")
    ax[1].set_ylabel("gyro bias (deg/s)")
    ax[1].legend(loc="upper right")
    if sigma_rad is not None:
        _plot_sigma(ax[2], t, sigma_rad, flags)
    _plot_flags(ax[-1], t, flags)
    ax[-1].set_xlabel("t (s)")
    return save(fig, path)


def _plot_sigma(ax, t, sigma_rad, flags) -> None:
    """The tilt's standard deviation on a log scale (it spans ~0.3° at rest to tens of degrees
    after the start or a gap), with the accelerometer-calibration floor it never goes below."""
    from verticality.estimators.tilt import DEFAULT_PARAMS as p

    ax.semilogy(t, np.degrees(sigma_rad), color="C3", label="tilt σ")
    ax.axhline(np.degrees(p.acc_calib_m_s2 / p.g_m_s2), color="0.4", linestyle=":",
               label=f"accelerometer calibration ({p.acc_calib_m_s2:g} m/s²)")
    _shade_reacquiring(ax, t, flags)
    ax.set_ylabel("tilt σ (deg)")
    ax.legend(loc="upper right")


def _plot_flags(ax, t, flags) -> None:
    """One row per flag bit that occurs: a bar over each run of flagged samples and a tick at
    its start (one-sample events, such as a gap, stay visible); the row's label gives the bit and
    the number of samples."""
    from verticality.estimators.tilt import FLAG_NAMES

    rows = [(bit, name) for bit, name in FLAG_NAMES.items() if np.any(flags & bit)]
    for y, (bit, _) in enumerate(rows):
        starts, lasts = _runs(flags, bit)
        ax.hlines(np.full(starts.size, y), t[starts], t[lasts], linewidth=6, color=f"C{y % 10}")
        ax.plot(t[starts], np.full(starts.size, y), "|", markersize=10, color=f"C{y % 10}")
    ax.set_yticks(range(len(rows)),
                  [f"{name} ({bit}): {np.count_nonzero(flags & bit)}" for bit, name in rows])
    ax.set_ylim(-0.6, max(len(rows), 1) - 0.4)
    ax.set_title("flags (samples)" if rows else "flags: none", fontsize="medium")
