"""ROS 1 bags, ROS 2 bags (a folder with ``metadata.yaml``, sqlite3 or MCAP storage) and bare
MCAP files (``rosbags``): the ``sensor_msgs/Imu`` samples of one topic and the orientation the
messages carry (docs/logs.md).

* Time: each message's ``header.stamp`` (the sample's time, ns integers), never the bag's receive
  time. A zero stamp (a driver that does not stamp) is refused.
* Frames (REP-103, REP-145): the samples are in the message's ``frame_id`` and the orientation maps
  that frame into a z-up world: our convention as it is.
* Missing data (sensor_msgs/Imu): ``*_covariance[0] = -1`` says the message holds no such data:
  such a gyro or accelerometer sample is missing (NaN: the filter flags it); an orientation with
  ``orientation_covariance[0] = -1``, all zeros, or the identity with an all-zero covariance holds
  no estimate and is left out of the reference.
* Topics: the only ``sensor_msgs/Imu`` topic by default; with several, ``topic`` chooses and
  a refusal names them.
"""

from __future__ import annotations

import contextlib
from pathlib import Path

import numpy as np

from verticality.core.errors import InputError
from verticality.io.logs import formats
from verticality.io.logs.recording import LOG, LogRecording, assemble, count_line, raw_reference

IMU_TYPE = "sensor_msgs/msg/Imu"
NO_DATA = -1.0  # element 0 of a covariance: the message holds no such data


@contextlib.contextmanager
def open_bag(path: Path, fmt: str):
    """``(reader, decode)`` of a bag told by its signature ``fmt``: ``reader`` has
    ``connections`` and ``messages(connections)`` (rosbags' readers, or its MCAP and sqlite3
    storage readers for a bare file named otherwise than ``.mcap`` / ``.db3``), ``decode(raw,
    msgtype)`` the deserializer of its serialization (ROS 1 or CDR)."""
    formats.require("rosbags")
    from rosbags.rosbag1 import Reader as Reader1
    from rosbags.rosbag2 import Reader as Reader2
    from rosbags.typesys import Stores, get_typestore

    if fmt == formats.ROS1:
        reader, store = Reader1(path), get_typestore(Stores.ROS1_NOETIC)
        decode = store.deserialize_ros1
    else:
        store = get_typestore(Stores.LATEST)
        decode = store.deserialize_cdr
        if fmt == formats.ROS2:
            reader = Reader2(path.parent if path.name == "metadata.yaml" else path)
        elif path.suffix.lower() == {formats.MCAP: ".mcap", formats.SQLITE: ".db3"}[fmt]:
            reader = Reader2(path)
        elif fmt == formats.MCAP:
            from rosbags.rosbag2.storage_mcap import McapReader

            reader = McapReader(path)
        else:
            from rosbags.rosbag2.storage_sqlite3 import Sqlite3Reader

            reader = Sqlite3Reader(path)
    reader.open()
    try:
        yield reader, decode, store
    finally:
        reader.close()


def _reason(exc: BaseException) -> str:
    text = str(exc).strip()
    return text.splitlines()[0][:200] if text else type(exc).__name__


def choose(path, connections, topic: str | None) -> tuple[str, list]:
    """The topic to read and its connections: ``topic``, or the only ``sensor_msgs/Imu`` topic;
    a one-line refusal naming the IMU topics (or all topics when there is none)."""
    imu = sorted({c.topic for c in connections if c.msgtype == IMU_TYPE})
    kinds = {c.topic: c.msgtype for c in connections}
    if topic is None:
        if len(imu) == 1:
            topic = imu[0]
        elif not imu:
            others = ", ".join(f"{t} ({m})" for t, m in sorted(kinds.items())) or "none"
            raise InputError(f"{path}: no sensor_msgs/Imu topic; its topics: {others}")
        else:
            raise InputError(f"{path}: several IMU topics ({', '.join(imu)}); choose one with "
                             "--topic")
    if topic not in kinds:
        raise InputError(f"{path}: no topic {topic!r}; its IMU topics: {', '.join(imu) or 'none'}")
    if topic not in imu:
        raise InputError(f"{path}: topic {topic} holds {kinds[topic]}, not sensor_msgs/Imu")
    return topic, [c for c in connections if c.topic == topic]


def check_definition(path, conns, store) -> None:
    """Refuse a ROS 1 connection whose Imu definition is not the standard one (its MD5 differs):
    its bytes would be read with the wrong layout."""
    expected = store.generate_msgdef(IMU_TYPE)[1]
    for c in conns:
        digest = getattr(c, "digest", None)
        if digest and digest != expected:
            raise InputError(f"{path}: topic {c.topic}'s sensor_msgs/Imu definition is not the "
                             f"standard one (MD5 {digest}, expected {expected})")


def no_orientation(q, cov) -> np.ndarray:
    """(M,) bool: the orientation field holds no estimate (module doc)."""
    q, cov = np.asarray(q), np.asarray(cov)
    identity = np.all(q == np.array([1.0, 0.0, 0.0, 0.0]), axis=1)
    return ((cov[:, 0] == NO_DATA) | np.all(q == 0, axis=1)
            | (identity & np.all(cov == 0, axis=1)) | ~np.all(np.isfinite(q), axis=1))


FLOATS = 37  # float64 after the header: orientation (4), 3 covariances (9 each), 2 vectors (3)


def _fixed_layout(raw: bytes, ros1: bool) -> tuple[int, int] | None:
    """``(length of the frame_id's bytes, offset of the first float64)`` of a serialized Imu, or
    None when it is not a layout the vectorized decoder takes (big-endian CDR). Both layouts
    start ``[4 bytes] sec nsec length frame_id``: ROS 1's 4 bytes are ``seq``, CDR's the
    encapsulation header; CDR counts the name's terminating NUL and aligns the floats to 8 from
    the end of the encapsulation header, ROS 1 does neither."""
    if len(raw) < 16 or (not ros1 and raw[:2] != b"\x00\x01"):  # CDR: little-endian only
        return None
    n = int.from_bytes(raw[12:16], "little")
    if ros1:
        return n, 16 + n
    body = 12 + n
    return max(n - 1, 0), 4 + body + (-body) % 8


def decode_fast(raws: list[bytes], ros1: bool) -> tuple[np.ndarray, set] | None:
    """(M, 2 + 37) the stamps (sec, nsec) and floats of serialized Imu messages, and their frame
    ids, decoded with NumPy in groups of one length (the frame_id's length then fixes the layout,
    checked per message); None when some message is not of that layout (the caller decodes one
    by one)."""
    out, frame_ids = np.empty((len(raws), 2 + FLOATS)), set()
    # a group: one length and one frame_id length (CDR pads two names to one length)
    keys = np.fromiter(((len(r) << 32) | int.from_bytes(r[12:16], "little") if len(r) >= 16
                        else -1 for r in raws), dtype=np.int64, count=len(raws))
    for key in np.unique(keys):
        rows = np.flatnonzero(keys == key)
        size = int(key) >> 32
        layout = _fixed_layout(raws[rows[0]], ros1) if key >= 0 else None
        if layout is None or layout[1] + 8 * FLOATS != size:
            return None
        name_len, floats_at = layout
        block = np.frombuffer(b"".join(raws[i] for i in rows), dtype=np.uint8).reshape(-1, size)
        if not ros1 and not np.all(block[:, :2] == block[0, :2]):
            return None  # a big-endian message among little-endian ones
        sec = block[:, 4:8].copy().view("<u4" if ros1 else "<i4")[:, 0]
        nsec = block[:, 8:12].copy().view("<u4")[:, 0]
        out[rows, 0], out[rows, 1] = sec, nsec
        out[rows, 2:] = block[:, floats_at:].copy().view("<f8")
        names = np.unique(block[:, 16:16 + name_len], axis=0)
        frame_ids |= {bytes(row).decode("utf-8", "replace") for row in names}
    return out, frame_ids


def decode_each(raws: list[bytes], decode) -> tuple[np.ndarray, set]:
    """:func:`decode_fast`'s results by rosbags' deserializer, one message at a time."""
    out, frame_ids = np.empty((len(raws), 2 + FLOATS)), set()
    for i, raw in enumerate(raws):
        m = decode(raw, IMU_TYPE)
        o, w, a = m.orientation, m.angular_velocity, m.linear_acceleration
        out[i, :2] = m.header.stamp.sec, m.header.stamp.nanosec
        out[i, 2:] = np.concatenate([[o.x, o.y, o.z, o.w], m.orientation_covariance,
                                     [w.x, w.y, w.z], m.angular_velocity_covariance,
                                     [a.x, a.y, a.z], m.linear_acceleration_covariance])
        frame_ids.add(m.header.frame_id)
    return out, frame_ids


def read_messages(path, fmt: str, topic: str | None):
    """``(topic, frame ids, stamps ns, gyr, acc, quat wxyz, covariances (M, 3, 9))`` of the
    topic's messages in the bag's order."""
    try:
        with open_bag(path, fmt) as (reader, decode, store):
            topic, conns = choose(path, reader.connections, topic)
            ros1 = fmt == formats.ROS1
            if ros1:
                check_definition(path, conns, store)
            raws = [bytes(raw) for _, _, raw in reader.messages(connections=conns)]
            if not raws:
                raise InputError(f"{path}: topic {topic} holds no messages")
            table, frame_ids = decode_fast(raws, ros1) or decode_each(raws, decode)
    except InputError:
        raise
    except Exception as exc:  # noqa: BLE001 (rosbags and its storage raise many kinds)
        hint = ("; a ROS 1 bag cut short is repaired by rosbag reindex"
                if fmt == formats.ROS1 and "index" in str(exc).lower() else "")
        raise InputError(f"{path}: not a readable {formats.FORMAT_NAMES[fmt]} "
                         f"({_reason(exc)}){hint}") from None
    stamps = table[:, 0].astype(np.int64) * 1_000_000_000 + table[:, 1].astype(np.int64)
    f = table[:, 2:]
    quat = f[:, [3, 0, 1, 2]]  # ROS writes x, y, z, w
    cov = np.stack([f[:, 16:25], f[:, 28:37], f[:, 4:13]], axis=1)
    return topic, frame_ids, stamps, f[:, 13:16], f[:, 25:28], quat, cov


def read_ros(path, fmt: str, topic: str | None = None, units=(None, None)) -> LogRecording:
    """The :class:`~verticality.io.logs.recording.LogRecording` of a bag or MCAP file (module
    doc)."""
    path = Path(path)
    topic, frame_ids, stamps, gyr, acc, quat, cov = read_messages(path, fmt, topic)
    notes = []
    zero = stamps <= 0
    if np.any(zero):
        raise InputError(f"{path}: topic {topic}: header.stamp is zero in "
                         f"{count_line(int(np.count_nonzero(zero)), 'messages')}; the bag's "
                         "receive time is not the sample's time, so the samples have none")
    for v, c, what in ((gyr, cov[:, 0], "angular_velocity"),
                       (acc, cov[:, 1], "linear_acceleration")):
        missing = c[:, 0] == NO_DATA
        if np.any(missing):
            v[missing] = np.nan
            notes.append(f"{count_line(int(np.count_nonzero(missing)), 'messages')} hold no "
                         f"{what} ({what}_covariance[0] = -1): those samples are missing")
    frame = ", ".join(sorted(frame_ids)) or "(no frame_id)"
    if len(frame_ids) > 1:
        notes.append(f"topic {topic} changes its frame_id ({frame}): the samples are taken "
                     "as one sensor's")
    empty = no_orientation(quat, cov[:, 2])
    refs = []
    if np.all(empty):
        notes.append(f"the messages of {topic} hold no orientation estimate (all zeros, the "
                     "identity with a zero covariance, or orientation_covariance[0] = -1): "
                     "nothing to compare with")
    else:
        if np.any(empty):
            notes.append(f"{count_line(int(np.count_nonzero(empty)), 'messages')} of {topic} "
                         "hold no orientation estimate: left out of the comparison")
        ref = raw_reference(f"{topic} orientation", LOG, stamps[~empty], quat[~empty])
        if ref is not None:
            refs.append(ref)
    return assemble(str(path), fmt, topic, frame, stamps, "ns", gyr, acc, references=refs,
                    notes=notes, units=units)
