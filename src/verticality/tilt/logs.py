"""Tilt of a robotics log (docs/logs.md): the filter over a log's IMU samples with what the log
knows about them (clip bits, breaks), the log's own attitude estimate beside ours, and the tilt
written back as MCAP or a ROS 2 bag.

* :func:`estimate_log`: our filter (or a peer) over the samples; at a change of the selected IMU
  the filter starts afresh (another sensor, another bias), and the samples after a logger
  drop-out or at such a change carry ``LOG_BREAK``; a sample that the log's clip counters place
  in a clipping interval carries ``CLIPPED``.
* :func:`compare_log`: per sample, the log's estimate (and a simulation's ground truth) as roll,
  pitch and the angle between its up vector and ours, interpolated to our samples; summarized
  apart while the IMU moves and while it is at rest, where the angle between each estimate and
  the accelerometer's direction also shows a biased reference for what it is.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from verticality.core.errors import InputError
from verticality.io.imu import (
    REST_ACC_NORM_M_S2,
    REST_ACC_STD_M_S2,
    REST_GYR_STD_RAD_S,
    REST_WINDOW_S,
)
from verticality.io.logs import LOG, TRUTH, LogRecording, read_log
from verticality.io.logs.frames import angle_between, roll_pitch_of_up, up_in_sensor
from verticality.tilt.evaluation.broad import OURS
from verticality.tilt.files import estimate_imu, settled_samples
from verticality.tilt.flags import CLIPPED, INIT, LOG_BREAK
from verticality.tilt.output import TiltEstimate
from verticality.tilt.params import DEFAULT_PARAMS

ROLE_NAMES = {LOG: "the log's estimate", TRUTH: "ground truth"}
REF_GAP_STEPS = 4  # a reference sample is interpolated only between stamps this many steps apart


def as_recording(log, topic: str | None = None) -> LogRecording:
    return log if isinstance(log, LogRecording) else read_log(log, topic)


def segments(rec: LogRecording) -> list[slice]:
    """The stretches between changes of the selected IMU (each filtered from a fresh start)."""
    cuts = [0, *(np.flatnonzero(rec.restarts[1:]) + 1).tolist(), rec.t_s.size]
    return [slice(a, b) for a, b in zip(cuts[:-1], cuts[1:], strict=True) if b > a]


def estimate_log(log, topic: str | None = None, *, filter_name: str = OURS,
                 offline: bool = False, ranges: dict | None = None) -> TiltEstimate:
    """The tilt of a log (a path or a :class:`~verticality.io.logs.LogRecording`; ``topic`` its
    IMU topic) by ``filter_name``, causal or (``offline``, ours) smoothed, given the sensor's
    ``ranges`` (``gyr_range_rad_s``, ``acc_range_m_s2``) if known, with the log's clip bits and
    breaks (module doc). One :class:`~verticality.tilt.TiltEstimate` over all the samples."""
    rec = as_recording(log, topic)
    parts = []
    for s in segments(rec):
        clipped = {"gyr_clipped": None if rec.gyr_clipped is None else rec.gyr_clipped[s],
                   "acc_clipped": None if rec.acc_clipped is None else rec.acc_clipped[s]}
        parts.append(estimate_imu(rec.gyr_rad_s[s], rec.acc_m_s2[s], rec.t_s[s], rec.dt_s[s],
                                  filter_name, offline, ranges, clipped=clipped).out)
    out = TiltEstimate(*(np.concatenate(f) for f in zip(*parts, strict=True)))
    extra = np.where(rec.breaks | rec.restarts, LOG_BREAK, 0)
    known = np.zeros(rec.t_s.size, dtype=bool)
    for mask in (rec.gyr_clipped, rec.acc_clipped):
        if mask is not None:
            known |= mask.any(axis=1)
    extra |= np.where(rec.clip_counted | known, CLIPPED, 0)
    return out._replace(flags=(np.asarray(out.flags) | extra).astype(np.int32))


def rest_samples(gyr, acc, dt_s) -> np.ndarray:
    """(N,) bool: the samples in still windows of ``REST_WINDOW_S`` (the accelerometer varies by
    less than ``REST_ACC_STD_M_S2`` per axis with a norm within ``REST_ACC_NORM_M_S2`` of g, the
    gyro by less than ``REST_GYR_STD_RAD_S``: the criteria of the unit checks)."""
    n = gyr.shape[0]
    dts = np.asarray(dt_s, dtype=np.float64)
    dt = float(np.nanmedian(dts)) if np.any(np.isfinite(dts) & (dts > 0)) else np.nan
    rest = np.zeros(n, dtype=bool)
    if not np.isfinite(dt) or dt <= 0:
        return rest
    w = max(5, int(round(REST_WINDOW_S / dt)))
    nw = n // w
    if nw == 0:
        return rest
    g = gyr[:nw * w].reshape(nw, w, 3)
    a = acc[:nw * w].reshape(nw, w, 3)
    with np.errstate(invalid="ignore", over="ignore"):
        finite = np.all(np.isfinite(g), axis=(1, 2)) & np.all(np.isfinite(a), axis=(1, 2))
        still = (finite & (np.sqrt(np.mean(np.var(a, axis=1), axis=1)) < REST_ACC_STD_M_S2)
                 & (np.sqrt(np.mean(np.var(g, axis=1), axis=1)) < REST_GYR_STD_RAD_S)
                 & (np.abs(np.linalg.norm(np.mean(a, axis=1), axis=1) - DEFAULT_PARAMS.g_m_s2)
                    < REST_ACC_NORM_M_S2))
    rest[:nw * w] = np.repeat(still, w)
    return rest


def up_at(t_ref, quat_E_S, t_s) -> np.ndarray:
    """(N, 3) the reference's up vector at times ``t_s``: linear between its two nearest samples
    (renormalized), NaN outside its span or between samples more than ``REF_GAP_STEPS`` median
    steps apart (a reference that stopped is not drawn across)."""
    up = up_in_sensor(quat_E_S)
    t_ref = np.asarray(t_ref, dtype=np.float64)
    t = np.asarray(t_s, dtype=np.float64)
    out = np.full((t.size, 3), np.nan)
    if t_ref.size == 0:
        return out
    k = np.searchsorted(t_ref, t, side="left")
    exact = (k < t_ref.size) & (t_ref[np.minimum(k, t_ref.size - 1)] == t)
    out[exact] = up[k[exact]]
    if t_ref.size > 1:
        step = float(np.median(np.diff(t_ref)))
        inside = ~exact & (k > 0) & (k < t_ref.size)
        lo, hi = k[inside] - 1, k[inside]
        span = t_ref[hi] - t_ref[lo]
        near = span <= REF_GAP_STEPS * step
        f = ((t[inside] - t_ref[lo]) / np.where(span > 0, span, 1.0))[:, None]
        v = (1 - f) * up[lo] + f * up[hi]
        v /= np.linalg.norm(v, axis=1, keepdims=True)
        rows = np.flatnonzero(inside)[near]
        out[rows] = v[near]
    return out


def angle_stats(angle_rad, mask, dt_s) -> dict:
    """RMS, median, 95th percentile and largest of ``angle_rad`` (deg) over the finite samples
    of ``mask``, with their count and duration (s)."""
    a = np.asarray(angle_rad)
    m = np.asarray(mask) & np.isfinite(a)
    d = np.degrees(a[m])
    dt = np.asarray(dt_s)[m]
    if d.size == 0:
        return {"n": 0, "seconds": 0.0, "rms_deg": None, "median_deg": None, "p95_deg": None,
                "max_deg": None}
    return {"n": int(d.size), "seconds": float(np.sum(np.where(np.isfinite(dt), dt, 0.0))),
            "rms_deg": float(np.sqrt(np.mean(d * d))), "median_deg": float(np.median(d)),
            "p95_deg": float(np.percentile(d, 95)), "max_deg": float(np.max(d))}


class LogComparison(NamedTuple):
    """Our estimate beside the log's (:func:`compare_log`)."""

    columns: dict  # name → (N,) array: the comparison CSV, one row per sample
    summary: dict  # the numbers of the lines
    lines: tuple  # one line each, for a person


def _fmt(s: dict) -> str:
    if not s["n"]:
        return "no samples"
    return (f"RMS {s['rms_deg']:.2f}° (median {s['median_deg']:.2f}°, 95 % below "
            f"{s['p95_deg']:.2f}°, {s['seconds']:.1f} s)")


def judged_samples(flags, t_s) -> np.ndarray:
    """The samples a comparison judges: our filter's settled ones (after its initialization and
    outside re-acquisitions); a peer's (no such flags) from ``reacquire_s`` after the start."""
    flags = np.asarray(flags)
    if np.any(flags & INIT):
        return settled_samples(flags)
    return np.asarray(t_s) >= t_s[0] + DEFAULT_PARAMS.reacquire_s


def check_comparable(rec: LogRecording) -> None:
    """Refuse, in one line, a comparison with a log that holds no attitude estimate."""
    if not rec.references:
        raise InputError(f"{rec.source}: --compare: the log holds no attitude estimate of its own "
                         "(no vehicle_attitude; or Imu messages whose orientation is empty)")


def compare_log(rec: LogRecording, est: TiltEstimate, name: str = OURS) -> LogComparison:
    """Our estimate ``est`` of ``rec`` beside the log's references (module doc); ``name`` ours
    in the lines (the filter's name). Refuses a log that holds no estimate."""
    check_comparable(rec)
    t = rec.t_s
    up = np.asarray(est.up_S)
    rest = rest_samples(rec.gyr_rad_s, rec.acc_m_s2, rec.dt_s)
    judged = judged_samples(est.flags, t)
    with np.errstate(invalid="ignore", divide="ignore"):
        acc_dir = rec.acc_m_s2 / np.linalg.norm(rec.acc_m_s2, axis=1, keepdims=True)
    cols = {"t": t, "roll_rad": np.asarray(est.roll_rad), "pitch_rad": np.asarray(est.pitch_rad),
            "at_rest": rest.astype(np.int64), "acc_angle_rad": angle_between(up, acc_dir)}
    summary: dict = {"samples": int(t.size), "judged": int(np.count_nonzero(judged)),
                     "at_rest_s": float(np.sum(rec.dt_s[judged & rest])),
                     "ours_acc_at_rest": angle_stats(cols["acc_angle_rad"], judged & rest,
                                                     rec.dt_s)}
    lines = []
    ups = {}
    for ref in rec.references:
        r = ref.role
        ups[r] = u = up_at(ref.t_s, ref.quat_E_S, t)
        cols[f"{r}_roll_rad"], cols[f"{r}_pitch_rad"] = roll_pitch_of_up(u)
        cols[f"{r}_angle_rad"] = angle_between(up, u)
        cols[f"{r}_acc_angle_rad"] = angle_between(u, acc_dir)
        moving = angle_stats(cols[f"{r}_angle_rad"], judged & ~rest, rec.dt_s)
        still = angle_stats(cols[f"{r}_angle_rad"], judged & rest, rec.dt_s)
        summary[r] = {"name": ref.name, "moving": moving, "rest": still,
                      "all": angle_stats(cols[f"{r}_angle_rad"], judged, rec.dt_s),
                      "acc_at_rest": angle_stats(cols[f"{r}_acc_angle_rad"], judged & rest,
                                                 rec.dt_s)}
        lines.append(f"{ref.name} ({ROLE_NAMES[r]}) against {name}, angle between the up "
                     f"vectors: moving {_fmt(moving)}; at rest {_fmt(still)}")
    if LOG in ups and TRUTH in ups:
        cols["log_truth_angle_rad"] = angle_between(ups[LOG], ups[TRUTH])
        log_truth = angle_stats(cols["log_truth_angle_rad"], judged, rec.dt_s)
        summary[TRUTH]["log_against_truth"] = log_truth
        lines.append(f"against the ground truth: {name} {_fmt(summary[TRUTH]['all'])}; "
                     f"{summary[LOG]['name']} {_fmt(log_truth)}")
    acc_parts = [f"{name} {_fmt(summary['ours_acc_at_rest'])}"]
    acc_parts += [f"{summary[r]['name']} {_fmt(summary[r]['acc_at_rest'])}"
                  for r in (LOG, TRUTH) if r in summary]
    lines.append("at rest, angle to the accelerometer's direction: " + "; ".join(acc_parts)
                 if summary["ours_acc_at_rest"]["n"] else
                 "at rest: no still stretch of the IMU to compare with the accelerometer")
    return LogComparison(cols, summary, tuple(lines))


def write_comparison_csv(path, comp: LogComparison) -> None:
    """The comparison's columns as a CSV (``t`` s, angles rad, ``at_rest`` 0/1), written whole or
    not at all (:func:`verticality.io.paths.write_atomic`: never through a link, one writer at a
    time, an existing file's permissions kept)."""
    from verticality.io.paths import write_atomic

    names = list(comp.columns)
    data = np.column_stack([np.asarray(comp.columns[k], dtype=np.float64) for k in names])
    fmt = ["%d" if k == "at_rest" else "%.17g" for k in names]
    write_atomic(path, lambda tmp: np.savetxt(tmp, data, delimiter=",", header=",".join(names),
                                              comments="", fmt=fmt), option="--compare")


def write_tilt_log(path, rec: LogRecording, est: TiltEstimate, *, ros2_bag: bool = False,
                   topic: str | None = None, message: str = "imu"):
    """Write ``est`` as a bare MCAP file ``path`` or (``ros2_bag``) a ROS 2 bag folder: one
    message per sample at the input's own stamps, in the samples' frame
    (:mod:`verticality.io.logs.write`)."""
    from verticality.io.logs import write
    from verticality.tilt.layout import E

    frame = rec.frame if rec.format != "ulog" else "base_link"
    var = np.asarray(est.var)[:, E.tilt]
    fn = write.write_ros2_bag if ros2_bag else write.write_mcap
    return fn(path, rec.stamps_ns, np.asarray(est.quat_E_S), var, frame,
              topic or write.DEFAULT_TOPIC, message)


def check_log_outputs(path, ros2_bag, outputs) -> list:
    """The files a log input reads (a ROS 2 bag: the files of its folder), for the output checks
    (:func:`verticality.io.paths.check_paths`); and the ROS 2 bag output ``ros2_bag`` checked
    before any work: a new folder, not inside the input, holding none of the other ``outputs``."""
    from pathlib import Path

    from verticality.io.paths import resolved

    path = Path(path)
    folder = path if path.is_dir() else None
    inputs = sorted(p for p in folder.iterdir() if p.is_file()) if folder else [path]
    if ros2_bag is not None:
        bag = Path(ros2_bag)
        if bag.exists():
            raise InputError(f"--ros2-bag {bag}: exists; a ROS 2 bag is written as a new folder")
        if folder is not None and resolved(bag).startswith(resolved(folder) + "/"):
            raise InputError(f"--ros2-bag {bag}: inside the input bag {folder}; give a folder "
                             "beside it")
        for out in outputs:
            if out is not None and resolved(out).startswith(resolved(bag) + "/"):
                raise InputError(f"--ros2-bag {bag}: would hold the output {out}; give two "
                                 "places")
    return inputs


class LogRun(NamedTuple):
    """What :func:`estimate_log_file` did: the run as ``estimate`` reports any (``run``), the
    recording read, the comparison (None unless asked) and the files written."""

    run: object  # verticality.tilt.files.EstimateRun
    recording: LogRecording
    comparison: LogComparison | None
    written: tuple


def estimate_log_file(path, out_path, *, topic: str | None = None, units=(),
                      filter_name: str = OURS, sigma: bool = False, offline: bool = False,
                      ranges: dict | None = None, compare_path=None, ros2_bag=None,
                      tilt_topic: str | None = None, message: str = "imu",
                      keep_comparison: bool = False) -> LogRun:
    """``verticality estimate LOG``: read the log (``topic``, ``units``), estimate its tilt
    (:func:`estimate_log`) and write it to ``out_path``: an estimate CSV as for any recording,
    or, named ``.mcap``, a bare MCAP file of ``message`` on ``tilt_topic``; also a ROS 2 bag
    folder ``ros2_bag`` and the comparison CSV ``compare_path`` (:func:`compare_log`) when
    given; ``keep_comparison``: the comparison also without a CSV (for a figure) when the log
    holds an estimate. Each output is written whole or not at all, never through a link, one
    writer at a time (:func:`verticality.io.paths.atomic_output`)."""
    from pathlib import Path

    from verticality.io import imu
    from verticality.io.paths import atomic_output
    from verticality.io.recording import parse_units
    from verticality.tilt.files import (
        EstimateRun,
        check_offline,
        check_ranges,
        check_sigma,
        gap_warning,
        sigma_summary,
    )

    check_offline(filter_name, offline)
    check_sigma(filter_name, sigma)
    ranges = check_ranges(filter_name, ranges)
    gyr_u, acc_u = parse_units(units)
    out_path = Path(out_path)
    mcap_out = out_path.suffix.lower() == ".mcap"
    if mcap_out and sigma:
        raise InputError("--sigma: a column of the estimate CSV; the MCAP output carries the "
                         "tilt's variances in its covariance")
    rec = read_log(path, topic, gyr_units=gyr_u, acc_units=acc_u)
    if compare_path is not None:
        check_comparable(rec)
    if offline:
        from verticality.tilt import smoother

        smoother.check_size(rec.t_s.size)
    est = estimate_log(rec, filter_name=filter_name, offline=offline, ranges=ranges)
    out_path.parent.mkdir(parents=True, exist_ok=True)
    written = []
    if mcap_out:
        write_tilt_log(out_path, rec, est, topic=tilt_topic, message=message)
    else:
        with atomic_output(out_path) as part:
            imu.write_estimate_csv(part, rec.t_s, est,
                                   tilt_sigma_rad=est.sigma_rad if sigma else None)
    written.append(out_path)
    if ros2_bag is not None:
        written.append(write_tilt_log(ros2_bag, rec, est, ros2_bag=True, topic=tilt_topic,
                                      message=message))
    comp = None
    if compare_path is not None or (keep_comparison and rec.references):
        comp = compare_log(rec, est, filter_name)
    if compare_path is not None:
        write_comparison_csv(compare_path, comp)
        written.append(Path(compare_path))
    ours = filter_name == OURS
    sig = est.sigma_rad if ours else None
    run = EstimateRun(rec.t_s.size, filter_name, sigma_summary(sig, est.flags) if ours else None,
                      gap_warning(rec.t_s, rec.dt_s, ours=ours, flags=est.flags if ours else None),
                      rec.t_origin, rec.t_s, est, sig,
                      float(rec.t_s[-1] - rec.t_s[0]), np.asarray(est.flags), sig)
    return LogRun(run, rec, comp, tuple(written))
