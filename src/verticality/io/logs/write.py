"""The tilt written back for robotics tools (``rosbags``' writers): a bare MCAP file or a ROS 2
bag folder (sqlite3 storage, metadata version 8), one message per sample on a topic of its own,
stamped with the sample's own time stamp (ns):

* ``sensor_msgs/msg/Imu`` (default): the orientation (sensor → a z-up Earth frame, REP-145; the
  heading is the gyro's integral, not a measured one), its covariance ``diag(var_x, var_y, π²/3)``
  (the tilt's variances about Earth's horizontal axes, taken as roll's and pitch's; the
  heading's variance that of an angle spread evenly over the circle: unknown), and
  ``angular_velocity_covariance[0] = linear_acceleration_covariance[0] = -1`` (the message holds
  no such data: the samples are in the input);
* ``geometry_msgs/msg/QuaternionStamped``: the orientation alone.

Each output is written under a temporary name beside it and renamed at the end, so a failure
leaves nothing behind.
"""

from __future__ import annotations

import math
import os
import shutil
import tempfile
from pathlib import Path

import numpy as np

from verticality.core.errors import InputError
from verticality.io.logs import formats

MESSAGES = {"imu": "sensor_msgs/msg/Imu", "quaternion": "geometry_msgs/msg/QuaternionStamped"}
DEFAULT_TOPIC = "/tilt"
BAG_VERSION = 8  # the oldest metadata version rosbags writes
HEADING_VAR_RAD2 = math.pi**2 / 3  # the variance of an angle uniform on (−π, π]


def _messages(store, message: str, stamps_ns, quat_wxyz, tilt_var, frame_id: str):
    """The serialized messages (CDR), one per sample."""
    t = store.types
    Time, Header = t["builtin_interfaces/msg/Time"], t["std_msgs/msg/Header"]
    Quaternion, Vector3 = t["geometry_msgs/msg/Quaternion"], t["geometry_msgs/msg/Vector3"]
    msgtype = MESSAGES[message]
    no_data = np.zeros(9)
    no_data[0] = -1.0
    zero = Vector3(x=0.0, y=0.0, z=0.0)
    for k in range(len(stamps_ns)):
        s = int(stamps_ns[k])
        header = Header(stamp=Time(sec=s // 1_000_000_000, nanosec=s % 1_000_000_000),
                        frame_id=frame_id)
        w, x, y, z = (float(c) for c in quat_wxyz[k])
        q = Quaternion(x=x, y=y, z=z, w=w)
        if message == "imu":
            cov = np.zeros(9)
            cov[0], cov[4], cov[8] = tilt_var[k, 0], tilt_var[k, 1], HEADING_VAR_RAD2
            msg = t[msgtype](header=header, orientation=q, orientation_covariance=cov,
                             angular_velocity=zero, angular_velocity_covariance=no_data,
                             linear_acceleration=zero, linear_acceleration_covariance=no_data)
        else:
            msg = t[msgtype](header=header, quaternion=q)
        yield s, store.serialize_cdr(msg, msgtype)


def _write_bag(folder: Path, storage: str, topic: str, message: str, stamps_ns, quat_wxyz,
               tilt_var, frame_id: str) -> None:
    formats.require("rosbags")
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    if message not in MESSAGES:
        raise InputError(f"unknown message {message!r}; use {' or '.join(MESSAGES)}")
    if not topic.startswith("/") or any(c.isspace() for c in topic):
        raise InputError(f"topic {topic!r}: a ROS topic name starts with / and has no spaces")
    store = get_typestore(Stores.LATEST)
    plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
    tilt_var = np.asarray(tilt_var, dtype=np.float64)
    with Writer(folder, version=BAG_VERSION, storage_plugin=plugin) as writer:
        conn = writer.add_connection(topic, MESSAGES[message], typestore=store)
        for stamp, data in _messages(store, message, stamps_ns, quat_wxyz, tilt_var, frame_id):
            writer.write(conn, stamp, data)


def _checked_stamps(stamps_ns) -> np.ndarray:
    s = np.asarray(stamps_ns, dtype=np.int64)
    if s.size == 0 or np.any(s < 0):
        raise InputError("the tilt's time stamps must be non-negative ns, at least one")
    return s


def write_mcap(path, stamps_ns, quat_wxyz, tilt_var, frame_id: str, topic: str = DEFAULT_TOPIC,
               message: str = "imu") -> Path:
    """Write the tilt (module doc) as the bare MCAP file ``path`` (ROS 2 profile, CDR): one
    message per sample at ``stamps_ns``, ``quat_wxyz`` (N, 4) sensor → Earth (z up),
    ``tilt_var`` (N, 2) the tilt's variances (rad²) about Earth's x and y. The file appears whole
    or not at all (:func:`verticality.io.paths.atomic_output`: never written through a link, one
    writer at a time)."""
    from verticality.io.paths import atomic_output

    path = Path(path)
    stamps = _checked_stamps(stamps_ns)
    with atomic_output(path) as tmp:
        # rosbags writes a bag folder; it is built in a fresh folder of its own beside the output
        work = Path(tempfile.mkdtemp(prefix=f".{path.name}.", dir=path.parent))
        try:
            _write_bag(work / "bag", "mcap", topic, message, stamps, quat_wxyz, tilt_var,
                       frame_id)
            inner = [p for p in (work / "bag").iterdir() if p.suffix == ".mcap"]
            shutil.copyfile(inner[0], tmp)  # into the locked temporary file, by content
        finally:
            shutil.rmtree(work, ignore_errors=True)
    return path


def write_ros2_bag(folder, stamps_ns, quat_wxyz, tilt_var, frame_id: str,
                   topic: str = DEFAULT_TOPIC, message: str = "imu") -> Path:
    """Write the tilt (as :func:`write_mcap`) as a new ROS 2 bag ``folder`` (metadata.yaml and
    sqlite3 storage); an existing ``folder`` (or one that another run creates meanwhile) is
    refused. It is built in a fresh folder beside it and renamed: it appears whole or not at
    all."""
    folder = Path(folder)
    if folder.exists() or folder.is_symlink():
        raise InputError(f"--ros2-bag {folder}: exists; a ROS 2 bag is written as a new folder")
    stamps = _checked_stamps(stamps_ns)
    folder.parent.mkdir(parents=True, exist_ok=True)
    work = Path(tempfile.mkdtemp(prefix=f".{folder.name}.", dir=folder.parent))
    try:
        part = work / folder.name
        _write_bag(part, "sqlite3", topic, message, stamps, quat_wxyz, tilt_var, frame_id)
        try:
            os.rename(part, folder)  # fails on a folder that is not empty: never a mix
        except OSError as exc:
            raise InputError(f"--ros2-bag {folder}: cannot be written ({exc.strerror}; another "
                             "run may have written it)") from None
    finally:
        shutil.rmtree(work, ignore_errors=True)
    return folder
