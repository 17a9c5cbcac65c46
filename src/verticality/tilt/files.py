"""Tilt estimates of an IMU recording (``verticality estimate``): our filter or a peer's, as one
output type, the summary of our filter's uncertainty, and the warning about gaps in the time
stamps."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from verticality.core.errors import InputError
from verticality.core.sizing import check_work_size
from verticality.io.paths import atomic_output
from verticality.tilt import batch as tilt_batch
from verticality.tilt import estimator
from verticality.tilt.clock import Clock, Judged
from verticality.tilt.core import TiltOutput, gaps_in, up_roll_pitch
from verticality.tilt.evaluation.broad import OURS, run_filter
from verticality.tilt.flags import CLOCK_JUMP, DT_GAP, INIT, REACQUIRED, REACQUIRING
from verticality.tilt.layout import NE
from verticality.tilt.output import TiltEstimate, estimate_of, tilt_sigma_rad
from verticality.tilt.params import DEFAULT_PARAMS, block_samples


class ImuEstimate(NamedTuple):
    out: TiltEstimate  # NumPy arrays
    tilt_sigma_rad: np.ndarray | None  # (N,) our filter's σ of the tilt (out.sigma_rad); None for
    #                                    a peer


def check_offline(filter_name: str, offline: bool) -> None:
    """Refuse ``offline`` for a filter other than ours (the smoother is ours)."""
    if offline and filter_name != OURS:
        raise InputError(f"--offline: the offline smoother is {OURS}'s; filter {filter_name} "
                         f"runs causally only (use --filter {OURS}, or leave out --offline)")


def check_sigma(filter_name: str, sigma: bool) -> None:
    """Refuse ``sigma`` for a filter other than ours (the peers report no uncertainty)."""
    if sigma and filter_name != OURS:
        raise InputError(f"--sigma: filter {filter_name} reports no uncertainty; use --filter "
                         f"{OURS}")


def check_ranges(filter_name: str, ranges: dict | None) -> dict:
    """The sensor ranges (``tilt.estimate``'s ``gyr_range_rad_s``, ``acc_range_m_s2``) that were
    given, refused for a filter other than ours (the peers do not take them)."""
    given = {k: v for k, v in (ranges or {}).items() if v is not None}
    if given and filter_name != OURS:
        raise InputError(f"--gyr-range/--acc-range: the clipping treatment is {OURS}'s; filter "
                         f"{filter_name} does not take a sensor range")
    return given


def estimate_imu(gyr_rad_s, acc_m_s2, t_s, dt_s, filter_name: str = OURS,
                 offline: bool = False, ranges: dict | None = None,
                 clipped: dict | None = None) -> ImuEstimate:
    """Roll, pitch, gravity direction, bias and flags of a recording at times ``t_s`` with steps
    ``dt_s`` as a reader found them (non-finite where a time stamp is missing: that sample is
    skipped and flagged) by ``filter_name`` (ours: ``tilt.estimate`` with its σ, or with
    ``offline`` the smoother ``tilt.smooth``, given the sensor's ``ranges`` if known
    (``gyr_range_rad_s``, ``acc_range_m_s2``); a peer: :func:`peer_output` of its quaternions and
    bias). ``clipped``: the components a log says clipped (``gyr_clipped``, ``acc_clipped``,
    (N, 3) bool or None; our filter only, the peers have no clipped treatment)."""
    check_offline(filter_name, offline)
    ranges = check_ranges(filter_name, ranges)
    if filter_name == OURS:
        run = estimator.smooth_steps if offline else estimator.estimate_steps
        out = estimate_of(run(gyr_rad_s, acc_m_s2, dt_s, **ranges, **(clipped or {})), t_s,
                          DEFAULT_PARAMS)
        return ImuEstimate(out, out.sigma_rad)
    quat, bias = run_filter(filter_name, gyr_rad_s, acc_m_s2, dt_s)
    return ImuEstimate(peer_output(np.asarray(quat), np.asarray(bias), t_s, dt_s), None)


def peer_output(quat_wxyz, bias_rad_s, t_s, dt_s) -> TiltEstimate:
    """A peer filter's output as a :class:`~verticality.tilt.TiltEstimate`: its quaternions
    (normalized) and bias, the angles from them (as ours), no variances and no σ (NaN), and of our
    flags only ``DT_GAP`` (a property of the input); every accelerometer sample counted as used
    (the peers take no missing samples)."""
    quat = np.asarray(quat_wxyz, dtype=np.float64)
    quat = quat / np.linalg.norm(quat, axis=1, keepdims=True)
    n = quat.shape[0]
    gap = gaps_in(np.broadcast_to(np.asarray(dt_s, dtype=np.float64), (n,)), DEFAULT_PARAMS,
                  xp=np)
    up, roll, pitch = up_roll_pitch(tuple(quat.T), xp=np)
    return TiltEstimate(np.asarray(t_s, dtype=np.float64), roll, pitch, np.stack(up, axis=1), quat,
                        np.asarray(bias_rad_s, dtype=np.float64), np.full(n, np.nan),
                        np.full((n, NE), np.nan), np.where(gap, DT_GAP, 0).astype(np.int32),
                        np.ones(n, dtype=bool))


def settled_samples(flags) -> np.ndarray:
    """The samples from the initialization on that are not flagged re-acquiring (after the start
    and each gap the filter has not yet settled on the vertical); none without an
    initialization."""
    flags = np.asarray(flags)
    init = np.flatnonzero(flags & INIT)
    settled = (flags & REACQUIRING) == 0
    settled[:init[0] if init.size else flags.size] = False
    return settled


def sigma_summary(sigma_rad, flags) -> str:
    """One line on the tilt's standard deviation over the :func:`settled_samples`."""
    if not np.any(np.asarray(flags) & INIT):
        return ("tilt σ: no sample initialized the filter (no usable accelerometer sample with a "
                "valid time step), so there is no estimate")
    s = np.degrees(np.asarray(sigma_rad)[settled_samples(flags)])
    if s.size == 0:
        return ("tilt σ: every sample is still re-acquiring (the recording is shorter than the "
                "re-acquisition time), the estimate is unconfirmed")
    return (f"tilt σ outside re-acquisitions: median {np.median(s):.2f}°, "
            f"95 % of samples below {np.percentile(s, 95):.2f}°, largest {np.max(s):.2f}°")


def gap_warning(t_s, dt_s, ours: bool = True, flags=None) -> str | None:
    """A one-line warning when the time stamps have gaps longer than the tilt filter's
    ``gap_flag_s`` (motion inside a gap goes unseen by the gyro integration), else None.
    ``flags``: our filter's flags of the same samples, whose clock jumps (``CLOCK_JUMP``: the
    stamps stepped while the readings went on, taken as one sample) are no gaps."""
    p = DEFAULT_PARAMS
    dt = np.asarray(dt_s, dtype=np.float64)
    gap = gaps_in(dt, p, xp=np)
    if flags is not None:
        gap &= (np.asarray(flags) & CLOCK_JUMP) == 0
    gaps = np.flatnonzero(gap)
    if gaps.size == 0:
        return None
    k = gaps[np.argmax(dt[gaps])]
    if ours:
        what = (f"our filter re-acquires the tilt from the accelerometer {p.reacquire_s:g} s after "
                f"each gap (flag {REACQUIRED}); until then the estimate can be off by the "
                f"rotation inside the gap (flag {REACQUIRING})")
    else:
        what = "this filter's estimate after a gap can be off for seconds"
    return (f"warning: {gaps.size} gap(s) in the time stamps longer than {p.gap_flag_s:g} s "
            f"(largest {dt[k]:.6g} s, ending at t = {t_s[k]:.6g} s): motion inside a gap is not "
            f"seen; {what}. Flag {DT_GAP} marks the sample that ends each gap")


WRITE_ROWS = 65536  # estimate rows formatted and written at a time
# a peer's run holds the recording (t, gyro, accelerometer, the pieces and their join), its
# quaternions and bias, and the output with its variances: about this much per sample
PEER_BYTES_PER_SAMPLE = 512


class EstimateRun(NamedTuple):
    """What :func:`estimate_file` did: the samples, the filter, the summary lines to print, and
    the output (``out`` all the outputs only when kept for a figure); ``duration_s``, every
    sample's ``flags`` and σ (``sigma_rad``, None for a peer) for a summary of the run."""

    n: int
    filter_name: str
    sigma_line: str | None
    gap_line: str | None
    t_origin: str | None
    t_s: np.ndarray | None = None
    out: TiltEstimate | None = None
    tilt_sigma_rad: np.ndarray | None = None
    duration_s: float | None = None
    flags: np.ndarray | None = None
    sigma_rad: np.ndarray | None = None


def count_rows(path, piece_bytes: int = 2**22) -> int:
    """The number of lines of a text file (read in pieces: nothing is parsed or kept), to size
    work on the whole recording before reading it."""
    n, last = 0, b"\n"
    with open(path, "rb") as fh:
        while piece := fh.read(piece_bytes):
            n += piece.count(b"\n")
            last = piece[-1:]
    return n + (last != b"\n")


def estimate_file(path, out_path, units=(), columns=None, time_unit=None,
                  filter_name: str = OURS, sigma: bool = False, keep: bool = False,
                  piece_rows: int = tilt_batch.PIECE_SAMPLES,
                  offline: bool = False, ranges: dict | None = None) -> EstimateRun:
    """``verticality estimate``: filter the recording in ``path`` and write the estimate CSV to
    ``out_path`` (through a temporary file beside it, renamed at the end: a refusal midway leaves
    no partial file, a link there is replaced, a second run writing it is refused;
    :func:`verticality.io.paths.atomic_output`). An IMU CSV through our filter is read, filtered
    and written piece by piece (:func:`verticality.io.imu.iter_imu_csv`,
    :func:`verticality.tilt.estimator.run_in_pieces`'s pieces: the numbers of the in-memory run
    bit for bit), so that memory stays proportional to a piece, not to the file; ``keep`` (a
    figure) also keeps every output. A BROAD HDF5 file (its declared size checked first) and the
    peers are read whole (a CSV's rows counted first, and refused beyond what memory allows).
    ``offline``: our smoother (``tilt.smooth``), which needs the whole
    recording: read whole, after its size is checked (a CSV's rows counted first), and refused
    beyond what memory allows. ``ranges``: the sensor's full-scale readings
    (``gyr_range_rad_s``, ``acc_range_m_s2``, our filter only); without them clipping is inferred
    from flat tops (per piece of ``piece_rows`` rows when read in pieces)."""
    from verticality.io import broad, imu, imu_layout
    from verticality.io.recording import load_imu, parse_units
    from verticality.tilt import smoother as tilt_smoother

    check_offline(filter_name, offline)
    ranges = check_ranges(filter_name, ranges)
    if offline and not broad.is_broad_file(path):
        tilt_smoother.check_size(count_rows(path))
    elif filter_name != OURS and not broad.is_broad_file(path):
        check_work_size(count_rows(path), PEER_BYTES_PER_SAMPLE, "samples read at once for a "
                        "peer filter", f"use our filter (--filter {OURS}), which reads the "
                        "recording piece by piece, or cut the recording in parts")
    # written beside out_path and renamed at the end (io.paths.atomic_output): a refusal midway
    # leaves no partial file, a link there is replaced rather than written through, a second run
    # writing the same file is refused
    with atomic_output(out_path) as part:
        if filter_name != OURS or offline or broad.is_broad_file(path):
            rec = load_imu(path, units, columns, time_unit)
            est = estimate_imu(rec.gyr_rad_s, rec.acc_m_s2, rec.t_s, rec.dt_s, filter_name,
                               offline, ranges)
            imu.write_estimate_csv(part, rec.t_s, est.out,
                                   tilt_sigma_rad=est.tilt_sigma_rad if sigma else None)
            s_line = (None if est.tilt_sigma_rad is None
                      else sigma_summary(est.tilt_sigma_rad, est.out.flags))
            return EstimateRun(rec.t_s.size, filter_name, s_line,
                               gap_warning(rec.t_s, rec.dt_s, ours=filter_name == OURS,
                                           flags=est.out.flags if filter_name == OURS else None),
                               rec.t_origin, rec.t_s, est.out, est.tilt_sigma_rad,
                               float(rec.t_s[-1] - rec.t_s[0]), np.asarray(est.out.flags),
                               est.tilt_sigma_rad)
        gyr_u, acc_u = parse_units(units)
        mapping = imu_layout.parse_columns_spec(columns) if isinstance(columns, str) else columns
        pieces = imu.iter_imu_csv(path, gyr_units=gyr_u, acc_units=acc_u, columns=mapping,
                                  time_unit=time_unit, piece_rows=piece_rows)
        filt = None  # its update interval in samples comes from the first piece's period
        state = estimator.TiltFilter().init()
        # for the summary lines: every sample's flags and σ (6 bytes), the gaps' t and dt
        kept: dict[str, list] = {"t": [], "dt": [], "flags": [], "sigma": [], "out": [],
                                 "t_all": []}
        n_done = [0]
        t_last = [None]  # the last filtered row's time
        # samples read but not yet filtered: (t, gyr, acc, the stamps' steps, the steps taken,
        # their tilt variance and flags)
        buf = None
        clock = Clock(DEFAULT_PARAMS)  # the steps judged as the rows arrive (tilt.clock)
        first = None
        prev = [None]  # the last filtered row (gyro, accelerometer), for the held rows
        with open(part, "w", encoding="utf-8") as fh:
            fh.write(imu.estimate_header(sigma) + "\n")

            def filter_some(final: bool):
                nonlocal buf, state, filt
                # a window that may be the last is left until the input's end is known (as
                # run_in_pieces cuts: the last window of a recording is taken whole)
                while buf is not None and buf[0].size and (final or buf[0].size > piece_rows):
                    w = min(buf[0].size, piece_rows)
                    t, g, a_read, d_raw, d, d_var, d_flags = (v[:w] for v in buf)
                    last = final and w == buf[0].size
                    lim = estimator.with_clock(
                        estimator.recording_limits(g, a_read, d, prev=prev[0], **ranges),
                        Judged(d, d_var, d_flags, None))
                    if filt is None:
                        filt = estimator.TiltFilter(block=block_samples(DEFAULT_PARAMS, d))
                    m = tilt_batch.piece_cut(state, a_read, d, filt.block, final=last) or w
                    state, o = tilt_batch.run(filt.params, filt.block, state,
                                              *lim.readings(g[:m], a_read[:m], slice(m)), d[:m],
                                              **lim.run_args(slice(m)))
                    prev[0] = np.concatenate([g[m - 1], a_read[m - 1]])
                    sig = tilt_sigma_rad(o.var, filt.params)
                    for lo in range(0, m, WRITE_ROWS):  # the rows' text, a slice at a time
                        hi = min(m, lo + WRITE_ROWS)
                        part_out = TiltOutput(*(v[lo:hi] for v in o))
                        fh.write(imu.estimate_rows(t[lo:hi], part_out,
                                                   sig[lo:hi] if sigma else None))
                    # the gap warning's rows: the stamps' gaps that are not clock jumps
                    gaps = gaps_in(d_raw[:m], filt.params, xp=np) & ((o.flags & CLOCK_JUMP) == 0)
                    for key, v in (("t", t[:m][gaps]), ("dt", d_raw[:m][gaps]),
                                   ("flags", o.flags.astype(np.int16)),
                                   ("sigma", sig.astype(np.float32))):
                        kept[key].append(v)
                    n_done[0] += m
                    t_last[0] = t[m - 1]
                    if keep:
                        kept["out"].append(o)
                        kept["t_all"].append(t[:m])
                    buf = tuple(v[m:] for v in buf)

            for piece in pieces:
                if first is None:
                    first = piece
                j = clock.steps(piece.dt_s, piece.gyr_rad_s, piece.acc_m_s2)
                new = (piece.t_s, piece.gyr_rad_s, piece.acc_m_s2, piece.dt_s, j.dt_s,
                       j.tilt_var_rad2, j.flags)
                buf = new if buf is None else tuple(np.concatenate([b, v])
                                                    for b, v in zip(buf, new, strict=True))
                filter_some(final=False)
            n_total = n_done[0] + (buf[0].size if buf is not None else 0)
            if n_total < 2:
                raise InputError(f"{path}: one data row; the filter needs at least two (a time "
                                 "step)")
            filter_some(final=True)
    flags, sig_all = np.concatenate(kept["flags"]), np.concatenate(kept["sigma"])
    origin = None if first.t0_stamp is None else f"{first.t0_stamp} {first.time_unit}"
    out_all = (estimate_of(estimator.concatenate_outputs(kept["out"]),
                           np.concatenate(kept["t_all"]), filt.params) if keep else None)
    return EstimateRun(n_done[0], filter_name, sigma_summary(sig_all.astype(np.float64), flags),
                       gap_warning(np.concatenate(kept["t"]), np.concatenate(kept["dt"])), origin,
                       out_all.t_s if keep else None, out_all,
                       out_all.sigma_rad if keep else None,
                       float(t_last[0] - first.t_s[0]), flags, sig_all)
