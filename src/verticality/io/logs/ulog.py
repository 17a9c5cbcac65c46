"""PX4 ULog files (``pyulog``): the IMU samples, what the log knows about them, and PX4's own
attitude estimates (docs/logs.md).

* IMU topics: ``sensor_combined`` (PX4's selected IMU, what its estimator EKF2 reads; the default)
  and each instance of ``vehicle_imu`` (one IMU each: ``vehicle_imu.1``; its delta angle and
  delta velocity over their intervals are the mean rate and specific force). Gyro time stamps
  (``timestamp`` of ``sensor_combined``, ``timestamp_sample`` of ``vehicle_imu``), µs integers.
* Frames: PX4's FRD body vectors are turned to FLU, its NED attitudes to NWU
  (:mod:`verticality.io.logs.frames`).
* Clipping: the per-sample, per-axis bits ``accelerometer_clipping`` and ``gyro_clipping`` of
  ``sensor_combined`` (``delta_velocity_clipping``, ``delta_angle_clipping`` of ``vehicle_imu``)
  become the filter's clipped samples. The samples are averages over a few raw readings, so a clip
  of one reading never shows as a value at full scale: the bits are the only trace. Where the log
  has no bits for a sensor, the clip counters of ``vehicle_imu_status`` (cumulative, per axis)
  say that some sample between two status messages clipped: those samples are flagged.
* Breaks: a logger drop-out (an ``O`` message: samples lost) before a sample, and a change of the
  selected IMU (``sensor_selection``: another sensor, another bias) at a sample, where the filter
  starts afresh.
* References: ``vehicle_attitude`` (EKF2; at ``timestamp_sample`` where the layout has it, else at
  ``timestamp``) and, in a simulation, ``vehicle_attitude_groundtruth``.
"""

from __future__ import annotations

import contextlib
import io
from pathlib import Path

import numpy as np

from verticality.core.errors import InputError
from verticality.io.logs import formats, frames
from verticality.io.logs.recording import (
    LOG,
    TRUTH,
    LogRecording,
    assemble,
    count_line,
    raw_reference,
)

IMU_TOPICS = ("sensor_combined", "vehicle_imu")
DEFAULT_TOPIC = "sensor_combined"
ATTITUDES = (("vehicle_attitude", LOG), ("vehicle_attitude_groundtruth", TRUTH))
READ = (*IMU_TOPICS, "vehicle_imu_status", "sensor_selection", *(n for n, _ in ATTITUDES))
RELATIVE_TIMESTAMP_INVALID = 0x7FFFFFFF  # sensor_combined: this accelerometer sample is missing


def parse(path):
    """The pyulog ``ULog`` of ``path`` with the messages this reader uses, or a one-line
    refusal. pyulog's own prints (on a damaged file) are kept out of the command's output."""
    pyulog = formats.require("pyulog")
    chatter = io.StringIO()
    try:
        with contextlib.redirect_stdout(chatter):
            return pyulog.ULog(str(path), list(READ))
    except Exception as exc:  # noqa: BLE001 (pyulog raises plain exceptions on damaged files)
        reason = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise InputError(f"{path}: not a readable PX4 ULog ({reason})") from None


def _field(d, name: str, n: int | None = None):
    """``d.data[name]`` (or ``name[0]``..``name[n-1]`` stacked), None when the layout has no
    such field."""
    if n is None:
        return d.data.get(name)
    cols = [d.data.get(f"{name}[{i}]") for i in range(n)]
    return None if any(c is None for c in cols) else np.column_stack(cols)


def _bits(values) -> np.ndarray | None:
    """(N, 3) bool from per-axis clip bit fields (x = 1, y = 2, z = 4)."""
    if values is None:
        return None
    v = np.asarray(values).astype(np.int64)
    return np.column_stack([(v & 1) > 0, (v & 2) > 0, (v & 4) > 0])


def topic_label(d, instances: int) -> str:
    """A data set's name as ``--topic`` takes it: the message name, with ``.k`` for instance k
    when the log has several."""
    return d.name if instances == 1 else f"{d.name}.{d.multi_id}"


def imu_topics(ulog) -> dict[str, object]:
    """``{label: data set}`` of the log's IMU topics (:data:`IMU_TOPICS`)."""
    out = {}
    for name in IMU_TOPICS:
        sets = sorted((d for d in ulog.data_list if d.name == name), key=lambda d: d.multi_id)
        for d in sets:
            out[topic_label(d, len(sets))] = d
    return out


def choose(path, topics: dict, topic: str | None):
    """The data set of ``topic`` (``name`` also names instance 0 of ``name.0``), by default
    ``sensor_combined`` or the only IMU topic; a one-line refusal naming the IMU topics."""
    names = ", ".join(topics) or "none"
    if topic is None:
        if DEFAULT_TOPIC in topics:
            return DEFAULT_TOPIC, topics[DEFAULT_TOPIC]
        if len(topics) == 1:
            return next(iter(topics.items()))
        if not topics:
            raise InputError(f"{path}: no IMU topic in this ULog (sensor_combined or "
                             "vehicle_imu): not logged, or the file ends before its data")
        raise InputError(f"{path}: several IMU topics ({names}) and no sensor_combined; choose "
                         "one with --topic")
    for label in (topic, f"{topic}.0"):
        if label in topics:
            return label, topics[label]
    raise InputError(f"{path}: no IMU topic {topic!r} in this ULog; its IMU topics: {names}")


def samples(d):
    """``(stamps µs, gyr FRD, acc FRD, gyr_clipped, acc_clipped)`` of a ``sensor_combined`` or
    ``vehicle_imu`` data set (clip arrays None where the layout has no bits)."""
    if d.name == "sensor_combined":
        stamps = d.data["timestamp"]
        gyr = _field(d, "gyro_rad", 3)
        acc = _field(d, "accelerometer_m_s2", 3)
        rel = _field(d, "accelerometer_timestamp_relative")
        if gyr is None or acc is None:
            raise InputError("sensor_combined: no gyro_rad or accelerometer_m_s2 fields")
        acc = acc.astype(np.float64)
        if rel is not None:
            acc[np.asarray(rel) == RELATIVE_TIMESTAMP_INVALID] = np.nan
        return (stamps, gyr, acc, _bits(_field(d, "gyro_clipping")),
                _bits(_field(d, "accelerometer_clipping")))
    stamps = _field(d, "timestamp_sample")
    stamps = d.data["timestamp"] if stamps is None else stamps
    angle, velocity = _field(d, "delta_angle", 3), _field(d, "delta_velocity", 3)
    if angle is None or velocity is None:
        raise InputError("vehicle_imu: no delta_angle or delta_velocity fields")
    with np.errstate(divide="ignore", invalid="ignore"):
        da_s = np.asarray(_field(d, "delta_angle_dt"), dtype=np.float64) * 1e-6
        dv_s = np.asarray(_field(d, "delta_velocity_dt"), dtype=np.float64) * 1e-6
        gyr = np.where(da_s[:, None] > 0, angle / da_s[:, None], np.nan)
        acc = np.where(dv_s[:, None] > 0, velocity / dv_s[:, None], np.nan)
    return (stamps, gyr, acc, _bits(_field(d, "delta_angle_clipping")),
            _bits(_field(d, "delta_velocity_clipping")))


def first_at_or_after(stamps, events, strict: bool = False) -> np.ndarray:
    """(N,) bool: the first sample at (or, ``strict``, after) each event's stamp."""
    mark = np.zeros(stamps.size, dtype=bool)
    k = np.searchsorted(stamps, np.asarray(events, dtype=np.int64),
                        side="right" if strict else "left")
    mark[k[k < stamps.size]] = True
    return mark


def selection_changes(ulog, stamps) -> tuple[np.ndarray, list[str]]:
    """(N,) bool: the samples where ``sensor_selection`` names another IMU (accelerometer or
    gyro device) than before; and a note."""
    d = next((d for d in ulog.data_list if d.name == "sensor_selection"), None)
    restarts = np.zeros(stamps.size, dtype=bool)
    if d is None or d.data["timestamp"].size < 2:
        return restarts, []
    ids = np.column_stack([np.asarray(d.data.get(f, np.zeros(d.data["timestamp"].size)))
                           for f in ("accel_device_id", "gyro_device_id")])
    changed = np.flatnonzero(np.any(ids[1:] != ids[:-1], axis=1)) + 1
    at = d.data["timestamp"][changed]
    at = at[(at > stamps[0]) & (at <= stamps[-1])]
    if at.size == 0:
        return restarts, []
    restarts = first_at_or_after(stamps, at)
    return restarts, [f"the selected IMU changes {count_line(at.size, 'times')} "
                      "(sensor_selection): the filter starts afresh at each change (flag 2048)"]


def dropout_breaks(ulog, stamps) -> tuple[np.ndarray, list[str]]:
    """(N,) bool: the first sample after each logger drop-out (its stamp is the last message's
    before it); and a note."""
    drops = [(o.timestamp, o.duration) for o in ulog.dropouts if o.duration > 0]
    if not drops:
        return np.zeros(stamps.size, dtype=bool), []
    at = np.array([t for t, _ in drops], dtype=np.int64)
    ms = np.array([m for _, m in drops])
    return first_at_or_after(stamps, at, strict=True), [
        f"{count_line(len(drops), 'logger drop-outs')} (largest {ms.max()} ms, {ms.sum()} ms in "
        "all): the sample after each is flagged 2048"]


def status_counts(ulog, d, stamps, known) -> tuple[np.ndarray, list[str]]:
    """(N,) bool: samples in an interval between two ``vehicle_imu_status`` messages of the
    IMU read whose clip counters rose, for a sensor whose samples carry no clip bits (``known``:
    ``{"accel": bits or None, "gyro": bits or None}``); and a note of the counts."""
    marked = np.zeros(stamps.size, dtype=bool)
    sets = [s for s in ulog.data_list if s.name == "vehicle_imu_status"]
    if not sets:
        return marked, []
    if d.name == "vehicle_imu":
        sets = [s for s in sets if s.multi_id == d.multi_id]
    elif len(sets) > 1:
        sets = _selected_status(ulog, sets)
    notes = []
    for s in sets[:1]:
        t = s.data["timestamp"]
        for sensor in ("accel", "gyro"):
            counts = _field(s, f"{sensor}_clipping", 3)
            if counts is None or t.size < 2:
                continue
            rose = np.diff(counts.astype(np.int64), axis=0)
            total = np.maximum(rose, 0).sum(axis=0)
            if not np.any(total):
                continue
            what = "accelerometer" if sensor == "accel" else "gyro"
            per_axis = ", ".join(f"{a} {int(c)}" for a, c in zip("xyz", total, strict=True))
            if known[sensor] is None:
                for k in np.flatnonzero(np.any(rose > 0, axis=1)):
                    marked |= (stamps > t[k]) & (stamps <= t[k + 1])
                notes.append(f"vehicle_imu_status counts {what} clipping ({per_axis}) and the "
                             f"samples carry no clip bits: the {int(np.count_nonzero(marked))} "
                             "samples of those status intervals are flagged clipped (512)")
            else:
                notes.append(f"vehicle_imu_status counts {what} clipping ({per_axis}); the "
                             "samples' own clip bits mark which")
    return marked, notes


def _selected_status(ulog, sets):
    """The ``vehicle_imu_status`` instances of the IMU that ``sensor_selection`` names first
    (all when it names none of them)."""
    sel = next((d for d in ulog.data_list if d.name == "sensor_selection"), None)
    if sel is None or "accel_device_id" not in sel.data:
        return sets
    device = sel.data["accel_device_id"][0]
    chosen = [s for s in sets if s.data.get("accel_device_id") is not None
              and np.any(s.data["accel_device_id"] == device)]
    return chosen or sets


def references(ulog) -> list:
    """PX4's attitudes (:data:`ATTITUDES`) in our convention, at their sample times."""
    refs = []
    for name, role in ATTITUDES:
        d = next((d for d in ulog.data_list if d.name == name and d.multi_id == 0), None)
        q = None if d is None else _field(d, "q", 4)
        if q is None:
            continue
        t = _field(d, "timestamp_sample")
        t = d.data["timestamp"] if t is None else t
        ref = raw_reference(name, role, t, frames.quat_nwu_flu(q))
        if ref is not None:
            refs.append(ref)
    return refs


def read_ulog(path, topic: str | None = None, units=(None, None)) -> LogRecording:
    """The :class:`~verticality.io.logs.recording.LogRecording` of a PX4 ULog (module doc):
    ``topic`` one of its IMU topics (default ``sensor_combined``)."""
    path = Path(path)
    ulog = parse(path)
    notes = []
    if getattr(ulog, "file_corruption", False):
        notes.append("the log is damaged in places: pyulog skipped the damaged bytes")
    label, d = choose(path, imu_topics(ulog), topic)
    try:
        stamps, gyr, acc, g_bits, a_bits = samples(d)
    except InputError as exc:
        raise InputError(f"{path}: {exc}") from None
    stamps = np.asarray(stamps).astype(np.int64)
    order = np.argsort(stamps, kind="stable")  # the events below are placed on sorted stamps
    sorted_stamps = stamps[order]
    back = np.empty_like(order)
    back[order] = np.arange(order.size)
    restarts, n1 = (selection_changes(ulog, sorted_stamps) if d.name == DEFAULT_TOPIC
                    else (np.zeros(stamps.size, dtype=bool), []))
    breaks, n2 = dropout_breaks(ulog, sorted_stamps)
    counted, n3 = status_counts(ulog, d, sorted_stamps, {"accel": a_bits, "gyro": g_bits})
    n_bits = [f"{what} clip bits set on "
              f"{count_line(int(np.count_nonzero(b.any(axis=1))), 'samples')}: clipped (512)"
              for what, b in (("Gyro", g_bits), ("Accelerometer", a_bits))
              if b is not None and b.any()]
    return assemble(str(path), formats.ULOG, label, "FLU (PX4's FRD body turned by π about x)",
                    stamps, "us", frames.flu_from_frd(gyr), frames.flu_from_frd(acc),
                    gyr_clipped=g_bits, acc_clipped=a_bits, clip_counted=counted[back],
                    breaks=breaks[back], restarts=restarts[back], references=references(ulog),
                    notes=notes + n1 + n2 + n3 + n_bits,
                    units=units)
