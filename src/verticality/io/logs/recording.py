"""What a robotics log gives the tilt filter (:class:`LogRecording`): the IMU samples in the
frame and units the filter takes, their time stamps as the log wrote them (integers), what the log
knows beyond the samples (per-sample clip bits, logger drop-outs, a change of the selected IMU)
and the log's own attitude estimates (:class:`Reference`), all in one convention
(docs/logs.md): the sensor frame of the samples, an Earth frame with z up.

:func:`assemble` is the one place where a reader's arrays become a recording: sorted by time
stamp, the stamps made seconds from the first, units checked.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from verticality.core.errors import InputError
from verticality.io.imu import check_units, dt_from_t

STAMP_SECONDS = {"us": 1e-6, "ns": 1e-9}
LOG = "log"  # a reference's role: the log's own estimate (PX4's EKF2, the Imu's orientation)
TRUTH = "truth"  # ... or the ground truth of a simulation (vehicle_attitude_groundtruth)


class Reference(NamedTuple):
    """An attitude the log holds beside the samples, converted to our convention."""

    name: str  # where it comes from: "vehicle_attitude", "/imu/data orientation"
    role: str  # LOG or TRUTH
    t_s: np.ndarray  # (M,) s from the recording's first stamp (the estimate's sample time)
    quat_E_S: np.ndarray  # (M, 4) wxyz: the samples' frame S → an Earth frame E with z up


class LogRecording(NamedTuple):
    """The IMU samples of a log, ready for :func:`verticality.tilt.estimate`, and what the log
    knows about them (docs/logs.md)."""

    source: str  # the path read
    format: str  # verticality.io.logs.formats: ULOG, ROS1, ROS2, MCAP, SQLITE
    topic: str  # the IMU topic read
    frame: str  # the samples' frame: "FLU (PX4's FRD body turned)", or the Imu's frame_id
    t_s: np.ndarray  # (N,) s from the first stamp
    gyr_rad_s: np.ndarray  # (N, 3)
    acc_m_s2: np.ndarray  # (N, 3)
    dt_s: np.ndarray  # (N,) dt[k] = t[k] − t[k−1], the first one the median step
    stamps: np.ndarray  # (N,) int64: the samples' time stamps as the log wrote them
    stamp_unit: str  # "us" (ULog) or "ns" (ROS header.stamp)
    gyr_clipped: np.ndarray | None  # (N, 3) bool: the log says the gyro axis clipped
    acc_clipped: np.ndarray | None  # (N, 3) bool: ... the accelerometer axis clipped
    clip_counted: np.ndarray  # (N,) bool: the log counts clipping in the interval holding the
    #                           sample without saying which sample (vehicle_imu_status counts)
    breaks: np.ndarray  # (N,) bool: samples were lost before this one (a logger drop-out)
    restarts: np.ndarray  # (N,) bool: the selected IMU changed at this sample
    references: tuple[Reference, ...]  # the log's own estimate(s), LOG first
    notes: tuple[str, ...]  # one line each: what was sorted, refused in part, counted

    @property
    def t_origin(self) -> str:
        """The first sample's stamp, e.g. ``"1432235497988949113 ns"``: ``t_s`` is relative to
        it."""
        return f"{int(self.stamps[0])} {self.stamp_unit}"

    @property
    def stamps_ns(self) -> np.ndarray:
        """(N,) int64 the stamps in ns (exact: a µs stamp times 1000)."""
        return self.stamps * (1000 if self.stamp_unit == "us" else 1)

    def estimate_args(self) -> dict:
        """The keyword arguments of :func:`verticality.tilt.estimate` for these samples:
        ``tilt.estimate(**rec.estimate_args())`` (a change of the selected IMU is not among them:
        :func:`verticality.tilt.estimate_log` starts the filter afresh there)."""
        return {"gyr_rad_s": self.gyr_rad_s, "acc_m_s2": self.acc_m_s2, "t_s": self.t_s,
                "gyr_clipped": self.gyr_clipped, "acc_clipped": self.acc_clipped}


def count_line(n: int, what: str) -> str:
    return f"{n} {what}" if n != 1 else f"1 {what.rstrip('s')}"


def assemble(source: str, fmt: str, topic: str, frame: str, stamps, stamp_unit: str, gyr, acc, *,
             gyr_clipped=None, acc_clipped=None, clip_counted=None, breaks=None, restarts=None,
             references=(), notes=(), units=(None, None)) -> LogRecording:
    """The :class:`LogRecording` of a reader's per-sample arrays (in the log's order): sorted by
    stamp (stable: samples of one stamp keep the log's order; a note says how many were out of
    order), a stamp repeated is kept as its own sample whose step 0 the filter skips and flags
    (``BAD_DT``; a note counts them), the stamps made seconds from the first, the references put
    on the same clock, units checked (:func:`verticality.io.imu.check_units`, ``units`` the
    ``(gyr_units, acc_units)`` stated by the user). At least two samples."""
    stamps = np.asarray(stamps, dtype=np.int64)
    n = stamps.size
    if n < 2:
        raise InputError(f"{source}: topic {topic} holds {n} sample{'s' if n != 1 else ''}; the "
                         "filter needs at least two (a time step)")
    notes = list(notes)
    order = np.argsort(stamps, kind="stable")
    late = int(np.count_nonzero(np.diff(stamps) < 0))
    if late:
        notes.append(f"{count_line(late, 'samples')} of {topic} came before the previous one's "
                     "time stamp in the log: the samples are taken in stamp order")

    def per_sample(x, shape, dtype=bool):
        return np.zeros(shape, dtype=dtype) if x is None else np.asarray(x, dtype=dtype)[order]

    stamps = stamps[order]
    gyr = np.asarray(gyr, dtype=np.float64)[order]
    acc = np.asarray(acc, dtype=np.float64)[order]
    gyr_clipped = None if gyr_clipped is None else per_sample(gyr_clipped, (n, 3))
    acc_clipped = None if acc_clipped is None else per_sample(acc_clipped, (n, 3))
    repeated = int(np.count_nonzero(np.diff(stamps) == 0))
    if repeated:
        notes.append(f"{count_line(repeated, 'samples')} of {topic} repeat the previous "
                     "sample's time stamp: each is kept and skipped by the filter (flag 4, bad "
                     "time step)")
    scale = STAMP_SECONDS[stamp_unit]
    t_s = (stamps - stamps[0]).astype(np.float64) * scale
    dt_s = dt_from_t(t_s)
    gyr, acc = check_units(gyr, acc, gyr_units=units[0], acc_units=units[1],
                           source=f"{source} ({topic})", dt_s=dt_s)
    refs = tuple(Reference(r.name, r.role, (np.asarray(r.t_stamps, dtype=np.int64)
                                            - stamps[0]).astype(np.float64) * scale,
                           np.asarray(r.quat_E_S, dtype=np.float64))
                 for r in references)
    return LogRecording(source, fmt, topic, frame, t_s, gyr, acc, dt_s, stamps, stamp_unit,
                        gyr_clipped, acc_clipped, per_sample(clip_counted, n),
                        per_sample(breaks, n), per_sample(restarts, n), refs, tuple(notes))


class RawReference(NamedTuple):
    """A reader's reference before :func:`assemble` puts it on the samples' clock."""

    name: str
    role: str
    t_stamps: np.ndarray  # (M,) int stamps in the samples' unit, sorted
    quat_E_S: np.ndarray  # (M, 4)


def raw_reference(name: str, role: str, stamps, quat_wxyz) -> RawReference | None:
    """A :class:`RawReference` of the rows whose quaternion is finite and not zero, sorted by
    stamp (the last of a repeated stamp kept), normalized; None when no row is left."""
    stamps = np.asarray(stamps, dtype=np.int64)
    q = np.asarray(quat_wxyz, dtype=np.float64)
    norm = np.linalg.norm(q, axis=1) if q.size else np.zeros(0)
    ok = np.all(np.isfinite(q), axis=1) & (norm > 0.5) & (norm < 2.0)
    if not np.any(ok):
        return None
    stamps, q = stamps[ok], q[ok] / norm[ok, None]
    order = np.argsort(stamps, kind="stable")
    stamps, q = stamps[order], q[order]
    last = np.concatenate([stamps[1:] != stamps[:-1], [True]])
    return RawReference(name, role, stamps[last], q[last])
