"""A small PX4 ULog writer for the tests: the file format as PX4 documents it (a 16-byte header:
the magic ``ULog\\x01\\x12\\x35``, a version byte and the start time in µs; a definitions section
of a flag-bits ``B`` message, ``I`` info, ``P`` parameters and ``F`` formats; a data section of
``A`` subscriptions, ``D`` data and ``O`` drop-outs, each message ``uint16 size, uint8 type,
payload``, little-endian, fields packed, a layout's trailing ``_padding`` field not written), with
PX4's own message layouts (:data:`LAYOUTS`, as
PX4's logs define them, field order and padding included). pyulog's reader is the judge of what
it writes (tests/test_logs.py).
"""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np

MAGIC = b"ULog\x01\x12\x35"
TYPES = {"uint64_t": "<u8", "int64_t": "<i8", "uint32_t": "<u4", "int32_t": "<i4",
         "uint16_t": "<u2", "int16_t": "<i2", "uint8_t": "u1", "int8_t": "i1", "float": "<f4",
         "double": "<f8", "bool": "u1", "char": "S1"}

# PX4's layouts as its logs define them ("type[n] name", in the logged order)
SENSOR_COMBINED = [  # recent PX4: per-axis clip bits of both sensors
    "uint64_t timestamp", "float[3] gyro_rad", "uint32_t gyro_integral_dt",
    "int32_t accelerometer_timestamp_relative", "float[3] accelerometer_m_s2",
    "uint32_t accelerometer_integral_dt", "uint8_t accelerometer_clipping",
    "uint8_t gyro_clipping", "uint8_t accel_calibration_count", "uint8_t gyro_calibration_count"]
SENSOR_COMBINED_ACC_CLIP = [  # the accelerometer's clip bits only (pyulog's sample_log_small)
    "uint64_t timestamp", "float[3] gyro_rad", "uint32_t gyro_integral_dt",
    "int32_t accelerometer_timestamp_relative", "float[3] accelerometer_m_s2",
    "uint32_t accelerometer_integral_dt", "uint8_t accelerometer_clipping",
    "uint8_t[3] _padding0"]
SENSOR_COMBINED_MAG_BARO = [  # magnetometer and barometer inside, no clip bits (an older SITL)
    "uint64_t timestamp", "float[3] gyro_rad", "uint32_t gyro_integral_dt",
    "int32_t accelerometer_timestamp_relative", "float[3] accelerometer_m_s2",
    "uint32_t accelerometer_integral_dt", "int32_t magnetometer_timestamp_relative",
    "float[3] magnetometer_ga", "int32_t baro_timestamp_relative", "float baro_alt_meter",
    "float baro_temp_celcius"]
VEHICLE_ATTITUDE = [  # recent PX4: the estimate's sample time
    "uint64_t timestamp", "uint64_t timestamp_sample", "float[4] q", "float[4] delta_q_reset",
    "uint8_t quat_reset_counter", "uint8_t[7] _padding0"]
VEHICLE_ATTITUDE_RATES = [  # older: with rates; also vehicle_attitude_groundtruth's there
    "uint64_t timestamp", "float rollspeed", "float pitchspeed", "float yawspeed", "float[4] q",
    "float[4] delta_q_reset", "uint8_t quat_reset_counter", "uint8_t[3] _padding0"]
VEHICLE_IMU = [
    "uint64_t timestamp", "uint64_t timestamp_sample", "uint32_t accel_device_id",
    "uint32_t gyro_device_id", "float[3] delta_angle", "float[3] delta_velocity",
    "uint16_t delta_angle_dt", "uint16_t delta_velocity_dt", "uint8_t delta_velocity_clipping",
    "uint8_t[3] _padding0"]
VEHICLE_IMU_STATUS = [
    "uint64_t timestamp", "uint32_t accel_device_id", "uint32_t gyro_device_id",
    "uint32_t[3] accel_clipping", "uint32_t accel_error_count", "uint32_t gyro_error_count",
    "float accel_vibration_metric", "float gyro_vibration_metric", "float gyro_coning_vibration",
    "uint16_t accel_rate_hz", "uint16_t gyro_rate_hz", "uint8_t[4] _padding0"]
SENSOR_SELECTION = [
    "uint64_t timestamp", "uint32_t accel_device_id", "uint32_t gyro_device_id",
    "uint32_t mag_device_id", "uint8_t[4] _padding0"]
VEHICLE_STATUS = ["uint64_t timestamp", "uint8_t arming_state", "uint8_t[7] _padding0"]


def _dtype(fields: list[str]) -> np.dtype:
    parts = []
    for f in fields:
        typ, name = f.split(" ")
        n = 1
        if "[" in typ:
            typ, n = typ.split("[")[0], int(typ.split("[")[1].rstrip("]"))
        parts.append((name, TYPES[typ], (n,)) if n > 1 else (name, TYPES[typ]))
    return np.dtype(parts)


def _message(kind: bytes, payload: bytes) -> bytes:
    return struct.pack("<HB", len(payload), kind[0]) + payload


def _info(key: str, value) -> bytes:
    if isinstance(value, str):
        raw = value.encode()
        k = f"char[{len(raw)}] {key}".encode()
    elif isinstance(value, float):
        raw, k = struct.pack("<f", value), f"float {key}".encode()
    else:
        raw, k = struct.pack("<i", value), f"int32_t {key}".encode()
    return bytes([len(k)]) + k + raw


class Topic:
    """One logged instance: ``name``, its layout ``fields`` and its rows ``{field: array}``
    (arrays of the field's shape; absent fields are zero)."""

    def __init__(self, name: str, fields: list[str], rows: dict, multi_id: int = 0):
        self.name, self.fields, self.multi_id = name, fields, multi_id
        n = len(np.asarray(rows["timestamp"]))
        self.data = np.zeros(n, dtype=_dtype(fields))
        for key, value in rows.items():
            self.data[key] = value

    def format_text(self) -> bytes:
        return f"{self.name}:{';'.join(self.fields)};".encode()

    def logged_size(self) -> int:
        """A row's bytes in a ``D`` message: PX4's logger leaves out a trailing padding field."""
        last = self.fields[-1].split(" ")[1]
        tail = self.data.dtype.fields[last][0].itemsize if last.startswith("_padding") else 0
        return self.data.dtype.itemsize - tail


def write_ulog(path, topics: list[Topic], *, start_us: int = 1_000_000, dropouts=(),
               info: dict | None = None, params: dict | None = None,
               cut_at: int | None = None) -> Path:
    """Write a ULog of ``topics`` (their rows interleaved by timestamp), ``dropouts`` as
    ``(after this µs stamp, duration ms)``, ``info`` and ``params`` in the definitions;
    ``cut_at``: keep only the first bytes (a truncated file)."""
    out = bytearray(MAGIC + b"\x01" + struct.pack("<Q", start_us))
    out += _message(b"B", bytes(16) + struct.pack("<3Q", 0, 0, 0))
    for key, value in {"sys_name": "PX4", "ver_hw": "PX4_SITL", **(info or {})}.items():
        out += _message(b"I", _info(key, value))
    for key, value in (params or {"SYS_AUTOSTART": 10016}).items():
        out += _message(b"P", _info(key, value))
    for name in dict.fromkeys(t.name for t in topics):
        out += _message(b"F", next(t for t in topics if t.name == name).format_text())
    rows = []
    for msg_id, t in enumerate(topics):
        out += _message(b"A", struct.pack("<BH", t.multi_id, msg_id) + t.name.encode())
        raw = t.data.tobytes()
        size, logged = t.data.dtype.itemsize, t.logged_size()
        rows += [(int(t.data["timestamp"][k]), 1, struct.pack("<H", msg_id)
                  + raw[k * size:k * size + logged]) for k in range(t.data.size)]
    rows += [(int(at), 2, struct.pack("<H", ms)) for at, ms in dropouts]
    for _, kind, payload in sorted(rows, key=lambda r: (r[0], r[1])):
        out += _message(b"D" if kind == 1 else b"O", payload)
    path = Path(path)
    path.write_bytes(bytes(out if cut_at is None else out[:cut_at]))
    return path
