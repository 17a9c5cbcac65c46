"""Robotics logs made for the tests from synthetic motion with known truth: PX4 ULogs
(:mod:`ulog_writer`, PX4's layouts) and ROS 1 bags, ROS 2 bags (sqlite3, MCAP) and bare MCAP
files (rosbags' writers, ``sensor_msgs/msg/Imu`` with real header stamps), small and in temporary
folders. Frames as the logs write them: ROS FLU/ENU as ours, PX4 FRD/NED turned
(:mod:`verticality.io.logs.frames`).
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np

import ulog_writer as uw
from verticality.core import so3
from verticality.core.constants import G_M_S2
from verticality.io.logs import frames

RATE_HZ = 100.0
STAMP0_NS = 1_700_000_000_123_456_789  # a real epoch stamp: ns precision beyond float64's


def motion(n: int = 1200, seed: int = 0, pitch0_deg: float = 8.0, amp_deg: float = 25.0,
           still_s: float = 3.0):
    """A sensor (FLU) held still for ``still_s`` at a fixed pitch, then rolling ±``amp_deg``
    at 0.5 Hz: ``(t_s, gyr, acc, quat_E_S)`` (z-up Earth, noise on the samples), at
    :data:`RATE_HZ`."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / RATE_HZ
    moving = t > still_s
    tau = np.where(moving, t - still_s, 0.0)
    roll = np.radians(amp_deg) * np.sin(np.pi * tau) * moving
    rate = np.radians(amp_deg) * np.pi * np.cos(np.pi * tau) * moving
    # R_E_S = Ry(pitch0) Rx(roll) in NumPy (a new length compiles nothing): its third row is
    # the up vector in the sensor frame, (−sin p, cos p sin r, cos p cos r)
    p0 = np.radians(pitch0_deg)
    up = np.column_stack([np.full(n, -np.sin(p0)), np.cos(p0) * np.sin(roll),
                          np.cos(p0) * np.cos(roll)])
    acc = G_M_S2 * up + rng.normal(0, 0.03, (n, 3))
    gyr = np.column_stack([rate, np.zeros(n), np.zeros(n)]) + rng.normal(0, 2e-3, (n, 3))
    qy = (np.full(n, np.cos(p0 / 2)), 0.0, np.full(n, np.sin(p0 / 2)), 0.0)
    qx = (np.cos(roll / 2), np.sin(roll / 2), 0.0, 0.0)
    quat = np.column_stack(np.broadcast_arrays(*so3.quat_multiply_components(qy, qx)))
    return t, gyr, acc, quat


# ------------------------------------------------------------------------------------ PX4 ULog
def px4_topics(t_s, gyr_flu, acc_flu, quat_flu, *, layout=None, t0_us: int = 5_000_000,
               gyr_clip=None, acc_clip=None, attitude_layout=None, attitude_bias_deg=0.0,
               truth: bool = False):
    """``sensor_combined`` (FRD) and ``vehicle_attitude`` (FRD → NED) of samples in our frames;
    ``attitude_bias_deg`` tilts PX4's estimate (a pitch bias); ``truth``: also
    ``vehicle_attitude_groundtruth``."""
    layout = layout or uw.SENSOR_COMBINED
    stamps = t0_us + np.round(np.asarray(t_s) * 1e6).astype(np.int64)
    rows = {"timestamp": stamps, "gyro_rad": frames.flu_from_frd(gyr_flu),
            "accelerometer_m_s2": frames.flu_from_frd(acc_flu), "gyro_integral_dt": 10000,
            "accelerometer_integral_dt": 10000}
    fields = " ".join(layout)
    for name, clip in (("gyro_clipping", gyr_clip), ("accelerometer_clipping", acc_clip)):
        if clip is not None and name in fields:
            rows[name] = np.asarray(clip, dtype=np.int64) @ np.array([1, 2, 4])
    q_ned = frames.quat_nwu_flu(quat_flu)  # the turn is its own inverse
    att_layout = attitude_layout or uw.VEHICLE_ATTITUDE
    biased = q_ned
    if attitude_bias_deg:
        tilt = np.asarray(so3.quat_exp(np.array([0.0, np.radians(attitude_bias_deg), 0.0])))
        biased = np.asarray(so3.quat_multiply(q_ned, tilt))
    att = {"timestamp": stamps[::2] + 1500, "q": biased[::2]}
    if "uint64_t timestamp_sample" in att_layout:
        att["timestamp_sample"] = stamps[::2]
    else:
        att["timestamp"] = stamps[::2]
    topics = [uw.Topic("sensor_combined", layout, rows),
              uw.Topic("vehicle_attitude", att_layout, att)]
    if truth:
        topics.append(uw.Topic("vehicle_attitude_groundtruth", uw.VEHICLE_ATTITUDE_RATES,
                               {"timestamp": stamps, "q": q_ned}))
    return topics


def px4_log(path, n: int = 1200, seed: int = 0, **kw) -> Path:
    t, gyr, acc, quat = motion(n, seed)
    extra = {k: kw.pop(k) for k in ("dropouts", "cut_at") if k in kw}
    more = kw.pop("more_topics", [])
    return uw.write_ulog(path, px4_topics(t, gyr, acc, quat, **kw) + more, **extra)


# ------------------------------------------------------------------------------------ ROS bags
def imu_messages(store, t_s, gyr, acc, quat, frame_id="imu_link", orientation="estimate"):
    """``sensor_msgs/msg/Imu`` messages of samples in our frames (ROS FLU/ENU), stamped from
    :data:`STAMP0_NS`; ``orientation``: ``estimate`` (the truth), ``none`` (covariance[0] -1),
    ``zeros``, ``identity`` (with a zero covariance)."""
    T = store.types
    stamps = STAMP0_NS + np.round(np.asarray(t_s) * 1e9).astype(np.int64)
    msgs = []
    for k in range(len(stamps)):
        s = int(stamps[k])
        q = {"estimate": quat[k], "none": quat[k], "zeros": np.zeros(4),
             "identity": np.array([1.0, 0, 0, 0])}[orientation]
        cov = np.zeros(9) if orientation in ("zeros", "identity") else np.diag([1e-4] * 3).ravel()
        if orientation == "none":
            cov = -np.ones(9)
        stamp = T["builtin_interfaces/msg/Time"](sec=s // 10**9, nanosec=s % 10**9)
        ros1 = "seq" in T["std_msgs/msg/Header"].__dataclass_fields__
        header = T["std_msgs/msg/Header"](**({"seq": k} if ros1 else {}), stamp=stamp,
                                          frame_id=frame_id)
        msgs.append((s, T["sensor_msgs/msg/Imu"](
            header=header,
            orientation=T["geometry_msgs/msg/Quaternion"](x=q[1], y=q[2], z=q[3], w=q[0]),
            orientation_covariance=cov,
            angular_velocity=T["geometry_msgs/msg/Vector3"](x=gyr[k, 0], y=gyr[k, 1],
                                                            z=gyr[k, 2]),
            angular_velocity_covariance=np.diag([1e-6] * 3).ravel(),
            linear_acceleration=T["geometry_msgs/msg/Vector3"](x=acc[k, 0], y=acc[k, 1],
                                                               z=acc[k, 2]),
            linear_acceleration_covariance=np.diag([1e-3] * 3).ravel())))
    return msgs


def write_bag(path, fmt: str, topics: dict, *, receive_offset_ns: int = 25_000_000,
              order=None) -> Path:
    """A bag of ``topics`` ``{name: [(stamp ns, message)]}`` in format ``fmt`` (``ros1``,
    ``sqlite3``, ``mcap`` (a ROS 2 bag folder), ``bare-mcap``), each message received
    ``receive_offset_ns`` after its stamp (rosbags writes in the order given: ``order``, a
    permutation of one topic's messages, writes them out of stamp order)."""
    from rosbags.rosbag1 import Writer as Writer1
    from rosbags.rosbag2 import StoragePlugin
    from rosbags.rosbag2 import Writer as Writer2
    from rosbags.typesys import Stores, get_typestore

    path = Path(path)
    ros1 = fmt == "ros1"
    store = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.LATEST)
    target = path.with_name(path.name + ".dir") if fmt == "bare-mcap" else path
    writer = (Writer1(target) if ros1 else
              Writer2(target, version=9, storage_plugin=StoragePlugin.SQLITE3 if fmt == "sqlite3"
                      else StoragePlugin.MCAP))
    with writer:
        items = []
        for topic, msgs in topics.items():
            conn = writer.add_connection(topic, msgs[0][1].__msgtype__, typestore=store)
            seq = msgs if order is None else [msgs[i] for i in order]
            for k, (stamp, msg) in enumerate(seq):
                raw = (store.serialize_ros1 if ros1 else store.serialize_cdr)(msg,
                                                                            msg.__msgtype__)
                # received in the order written (out of stamp order when ``order`` says so)
                receive = (stamp if order is None else msgs[0][0] + k * 10**7) + receive_offset_ns
                items.append((receive, conn, raw))
        for receive, conn, raw in sorted(items, key=lambda x: x[0]):
            writer.write(conn, receive, raw)
    if fmt == "bare-mcap":
        inner = next(target.glob("*.mcap"))
        shutil.move(inner, path)
        shutil.rmtree(target)
    return path


def ros_log(path, fmt: str, n: int = 1200, seed: int = 0, orientation="estimate",
            topic="/imu/data", extra_topics=None, **kw) -> Path:
    """A bag of the :func:`motion` on ``topic`` (and ``extra_topics`` ``{name: messages}``)."""
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC if fmt == "ros1" else Stores.LATEST)
    t, gyr, acc, quat = motion(n, seed)
    topics = {topic: imu_messages(store, t, gyr, acc, quat, orientation=orientation)}
    for name, make in (extra_topics or {}).items():
        topics[name] = make(store)
    return write_bag(path, fmt, topics, **kw)


def string_messages(store, n: int = 5):
    """A few ``std_msgs/msg/String`` messages: a topic that is not an IMU."""
    return [(STAMP0_NS + k * 10**8, store.types["std_msgs/msg/String"](data=f"hello {k}"))
            for k in range(n)]
