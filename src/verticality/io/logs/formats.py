"""Which robotics log a path holds, told by its signature (the first bytes of a file, the
``metadata.yaml`` of a ROS 2 bag folder), not by its suffix; and the optional packages that read
them (the ``logs`` extra: ``pyulog`` for PX4 ULog, ``rosbags`` for the bags and MCAP), refused in
one line naming the extra when missing.
"""

from __future__ import annotations

import importlib
from pathlib import Path

from verticality.core.errors import InputError

ULOG = "ulog"  # PX4 ULog (.ulg)
ROS1 = "ros1"  # ROS 1 bag (.bag)
ROS2 = "ros2"  # ROS 2 bag: a folder with metadata.yaml and sqlite3 (.db3) or MCAP storage
MCAP = "mcap"  # a bare MCAP file (.mcap)
SQLITE = "sqlite3"  # a ROS 2 bag's sqlite3 storage file (.db3) on its own
FORMAT_NAMES = {ULOG: "PX4 ULog", ROS1: "ROS 1 bag", ROS2: "ROS 2 bag", MCAP: "MCAP",
                SQLITE: "ROS 2 sqlite3 storage"}
LOG_SUFFIXES = (".ulg", ".bag", ".mcap", ".db3")

ULOG_MAGIC = b"ULog\x01\x12\x35"  # then a version byte and the start time (uint64, µs)
ROS1_MAGIC = b"#ROSBAG V2.0\n"
MCAP_MAGIC = b"\x89MCAP0\r\n"
SQLITE_MAGIC = b"SQLite format 3\x00"
EXTRA = "logs"  # pip install 'verticality[logs]'


def log_format(path) -> str | None:
    """The log format of ``path`` (:data:`ULOG`, :data:`ROS1`, :data:`ROS2`, :data:`MCAP`,
    :data:`SQLITE`) from its signature, or None when it is none of them (a CSV, an HDF5 file, a
    folder of recordings). A folder is a ROS 2 bag when it holds ``metadata.yaml``."""
    path = Path(path)
    if path.is_dir():
        return ROS2 if (path / "metadata.yaml").is_file() else None
    if path.name == "metadata.yaml" and path.is_file():
        return ROS2
    if not path.is_file():  # a pipe or a device: reading its first bytes would consume them
        return None
    try:
        with open(path, "rb") as fh:
            head = fh.read(16)
    except OSError:
        return None
    for magic, fmt in ((ULOG_MAGIC, ULOG), (ROS1_MAGIC, ROS1), (MCAP_MAGIC, MCAP),
                       (SQLITE_MAGIC, SQLITE)):
        if head.startswith(magic):
            return fmt
    return None


def suffix_without_signature(path) -> str | None:
    """A one-line refusal for a file named as a log (``.ulg``, ``.bag``, ``.mcap``, ``.db3``)
    whose first bytes are no log's signature (a truncated or foreign file), else None."""
    path = Path(path)
    if path.is_file() and path.suffix.lower() in LOG_SUFFIXES and log_format(path) is None:
        size = path.stat().st_size
        what = "empty" if size == 0 else f"{size} bytes without a log's signature"
        return (f"{path}: named as a log ({path.suffix}) but {what}: not a PX4 ULog, ROS bag or "
                "MCAP file (truncated at its start, or another format)")
    return None


def require(module: str):
    """Import ``module`` (``pyulog``, ``rosbags``), or refuse in one line naming the extra that
    installs it."""
    try:
        return importlib.import_module(module)
    except ImportError:
        raise InputError(f"reading robotics logs needs the optional package {module}: pip "
                         f"install 'verticality[{EXTRA}]'") from None
