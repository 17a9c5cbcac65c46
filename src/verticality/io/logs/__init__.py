"""Robotics logs (docs/logs.md): PX4 ULog (:mod:`~verticality.io.logs.ulog`), ROS 1 bags, ROS 2
bags and bare MCAP files (:mod:`~verticality.io.logs.ros`), told by their signature
(:mod:`~verticality.io.logs.formats`), read into one :class:`LogRecording` in our convention
(:mod:`~verticality.io.logs.frames`), and the tilt written back as MCAP or a ROS 2 bag
(:mod:`~verticality.io.logs.write`). The readers need the optional ``logs`` extra."""

from __future__ import annotations

from pathlib import Path

from verticality.core.errors import InputError
from verticality.io.logs.formats import (
    FORMAT_NAMES,
    MCAP,
    ROS1,
    ROS2,
    SQLITE,
    ULOG,
    log_format,
    suffix_without_signature,
)
from verticality.io.logs.recording import LOG, TRUTH, LogRecording, Reference

__all__ = ["read_log", "log_format", "is_log", "LogRecording", "Reference", "FORMAT_NAMES",
           "ULOG", "ROS1", "ROS2", "MCAP", "SQLITE", "LOG", "TRUTH"]


def is_log(path) -> bool:
    """Whether ``path`` is a robotics log (by signature) or is named as one (then the reader
    refuses it in one line)."""
    return log_format(path) is not None or suffix_without_signature(path) is not None


def read_log(path, topic: str | None = None, *, gyr_units: str | None = None,
             acc_units: str | None = None) -> LogRecording:
    """The IMU samples of a PX4 ULog, a ROS 1 or ROS 2 bag or an MCAP file, with what the log
    knows about them and its own attitude estimate (:class:`LogRecording`): ``topic`` the IMU
    topic (default: ``sensor_combined`` in a ULog, the only ``sensor_msgs/Imu`` topic in a bag);
    ``gyr_units``, ``acc_units`` as for :func:`verticality.io.imu.read_imu_csv` (a driver that
    publishes deg/s or g; the logs' own are rad/s and m/s²).

    Example::

        from verticality import tilt
        rec = tilt.read_log("flight.ulg")
        est = tilt.estimate(**rec.estimate_args())     # or tilt.estimate_log(rec)
    """
    path = Path(path)
    if not path.exists():
        raise InputError(f"{path}: no such file or folder")
    refusal = suffix_without_signature(path)
    if refusal is not None:
        raise InputError(refusal)
    fmt = log_format(path)
    if fmt is None:
        raise InputError(f"{path}: not a PX4 ULog, ROS bag or MCAP file (no log signature; a "
                         "ROS 2 bag is a folder with metadata.yaml)")
    if fmt == ULOG:
        from verticality.io.logs.ulog import read_ulog

        return read_ulog(path, topic, (gyr_units, acc_units))
    from verticality.io.logs.ros import read_ros

    return read_ros(path, fmt, topic, (gyr_units, acc_units))
