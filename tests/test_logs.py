"""Robotics logs in (docs/logs.md): PX4 ULog, ROS 1 bags, ROS 2 bags (sqlite3, MCAP) and bare
MCAP read into the tilt filter, on logs made here (:mod:`log_cases`: synthetic motion with known
truth; ULogs by :mod:`ulog_writer` in PX4's layouts, bags by rosbags' writers).

* the ULog writer against pyulog, the judge of the format;
* formats told by signature; every bag format gives the same samples, at the header stamps;
* conventions: PX4's FRD/NED turned to ours, the sign of pitch on a known tilt;
* what the logs know: clip bits into the filter's clipped handling, clip counters, drop-outs,
  a change of the selected IMU; sorted and repeated stamps; empty orientations;
* the log's own estimate beside ours (a biased reference shows at rest), topics chosen.
"""

from __future__ import annotations

import shutil

import numpy as np
import pytest

import log_cases as lc
import ulog_writer as uw
from verticality import tilt
from verticality.core import so3
from verticality.core.constants import G_M_S2
from verticality.core.errors import InputError
from verticality.io.logs import formats, frames, read_log, ros
from verticality.tilt.flags import BAD_DT, CLIPPED, INIT, LOG_BREAK

N = 1200  # 12 s at 100 Hz: one compiled shape for every estimate here


@pytest.fixture(scope="module")
def bags(tmp_path_factory):
    """The same motion as a ROS 1 bag, ROS 2 bags (sqlite3, MCAP) and a bare MCAP file."""
    d = tmp_path_factory.mktemp("bags")
    return {fmt: lc.ros_log(d / name, fmt) for fmt, name in
            (("ros1", "run.bag"), ("sqlite3", "run_db3"), ("mcap", "run_mcap"),
             ("bare-mcap", "run.mcap"))}


@pytest.fixture(scope="module")
def px4(tmp_path_factory):
    """A PX4 ULog of the motion, with PX4's estimate pitched up by 1.5° and the ground truth."""
    return lc.px4_log(tmp_path_factory.mktemp("ulog") / "flight.ulg", truth=True,
                      attitude_bias_deg=1.5)


def _truth_up():
    quat = lc.motion()[3]
    return frames.up_in_sensor(quat)


# ------------------------------------------------------------------------------- the ULog writer
def test_our_ulog_writer_writes_what_pyulog_reads(tmp_path):
    from pyulog import ULog

    gyr = np.arange(30.0).reshape(10, 3)
    att_q = np.tile([1.0, 0.0, 0.0, 0.0], (10, 1))
    topics = [uw.Topic("sensor_combined", uw.SENSOR_COMBINED_ACC_CLIP,
                       {"timestamp": 1000 + 10 * np.arange(10), "gyro_rad": gyr,
                        "accelerometer_clipping": np.arange(10) % 8}),
              uw.Topic("vehicle_attitude", uw.VEHICLE_ATTITUDE,  # trailing padding: not logged
                       {"timestamp": 1001 + 10 * np.arange(10), "q": att_q,
                        "timestamp_sample": 1000 + 10 * np.arange(10)}),
              uw.Topic("vehicle_imu", uw.VEHICLE_IMU, {"timestamp": [5, 6]}, multi_id=2)]
    path = uw.write_ulog(tmp_path / "w.ulg", topics, dropouts=[(1040, 25)], start_us=900,
                         info={"sys_name": "PX4"}, params={"MC_ROLL_P": 6.5})
    u = ULog(str(path))
    assert not u.file_corruption
    sc = u.get_dataset("sensor_combined")
    np.testing.assert_array_equal(sc.data["gyro_rad[1]"], gyr[:, 1])
    np.testing.assert_array_equal(sc.data["accelerometer_clipping"], np.arange(10) % 8)
    np.testing.assert_array_equal(u.get_dataset("vehicle_attitude").data["timestamp_sample"],
                                  1000 + 10 * np.arange(10))
    assert u.get_dataset("vehicle_imu", 2).data["timestamp"].tolist() == [5, 6]
    assert [(o.timestamp, o.duration) for o in u.dropouts] == [(1040, 25)]
    assert u.msg_info_dict["sys_name"] == "PX4"
    assert u.initial_parameters["MC_ROLL_P"] == pytest.approx(6.5)


# ---------------------------------------------------------------------------- formats and stamps
def test_formats_are_told_by_their_signature_not_their_suffix(bags, px4, tmp_path):
    assert formats.log_format(bags["ros1"]) == formats.ROS1
    assert formats.log_format(bags["sqlite3"]) == formats.ROS2
    assert formats.log_format(bags["sqlite3"] / "metadata.yaml") == formats.ROS2
    assert formats.log_format(bags["bare-mcap"]) == formats.MCAP
    assert formats.log_format(px4) == formats.ULOG
    renamed = {key: shutil.copy(src, tmp_path / name) for key, src, name in (
        ("ros1", bags["ros1"], "bag.dat"), ("mcap", bags["bare-mcap"], "log.bin"),
        ("ulog", px4, "px4.log"))}
    assert read_log(renamed["ros1"]).format == formats.ROS1
    assert read_log(renamed["mcap"]).t_s.size == N
    assert read_log(renamed["ulog"]).topic == "sensor_combined"
    db3 = bags["sqlite3"] / "run_db3.db3"  # a ROS 2 bag's storage file on its own
    assert formats.log_format(db3) == formats.SQLITE and read_log(db3).t_s.size == N
    csv = tmp_path / "flight.ulg"
    csv.write_text("t,gyr_x,gyr_y,gyr_z,acc_x,acc_y,acc_z\n0,0,0,0,0,0,9.8\n")
    assert formats.log_format(csv) is None
    with pytest.raises(InputError, match="named as a log .* without a log's signature"):
        read_log(csv)


def test_every_bag_format_gives_the_same_samples_at_their_header_stamps(bags):
    t, gyr, acc, quat = lc.motion()
    recs = {fmt: read_log(p) for fmt, p in bags.items()}
    for fmt, rec in recs.items():
        assert rec.topic == "/imu/data" and rec.frame == "imu_link", fmt
        # the header stamps, exactly (ns integers), not the receive times 25 ms later
        assert rec.t_origin == f"{lc.STAMP0_NS} ns"
        np.testing.assert_array_equal(rec.stamps,
                                      lc.STAMP0_NS + np.round(t * 1e9).astype(np.int64))
        np.testing.assert_array_equal(rec.gyr_rad_s, gyr)
        np.testing.assert_array_equal(rec.acc_m_s2, acc)
        (ref,) = rec.references
        assert ref.role == "log" and ref.name == "/imu/data orientation"
        np.testing.assert_allclose(np.abs(np.sum(ref.quat_E_S * quat, axis=1)), 1.0, atol=1e-12)
        assert rec.notes == ()


def test_the_vectorized_decoder_equals_rosbags_deserializer(tmp_path):
    from rosbags.typesys import Stores, get_typestore

    t, gyr, acc, quat = lc.motion(n=6)
    for store_name, ros1 in ((Stores.ROS1_NOETIC, True), (Stores.LATEST, False)):
        store = get_typestore(store_name)
        raws = []
        for frame in ("a", "imu", "imu_link", "base_link_long_name"):  # every CDR alignment
            for _, m in lc.imu_messages(store, t, gyr, acc, quat, frame_id=frame):
                raws.append(bytes((store.serialize_ros1 if ros1 else store.serialize_cdr)(
                    m, ros.IMU_TYPE)))
        decode = store.deserialize_ros1 if ros1 else store.deserialize_cdr
        fast, names = ros.decode_fast(raws, ros1)
        slow, names_slow = ros.decode_each(raws, decode)
        np.testing.assert_array_equal(fast, slow)
        assert names == names_slow == {"a", "imu", "imu_link", "base_link_long_name"}


# -------------------------------------------------------------------------------- conventions
def _static_px4(path, roll_deg, pitch_deg, n=300):
    """PX4 at rest at a PX4 roll and pitch (FRD/NED): its samples and its own estimate."""
    q_ned = np.asarray(so3.quat_from_rpy_radians(np.radians(roll_deg), np.radians(pitch_deg),
                                                 0.3))
    R = np.asarray(so3.matrix_from_quat(q_ned))
    acc_frd = -G_M_S2 * R[2, :]  # specific force: up (−down) in the body
    stamps = 1_000_000 + 10_000 * np.arange(n)
    rows = {"timestamp": stamps, "gyro_rad": np.zeros((n, 3)),
            "accelerometer_m_s2": np.tile(acc_frd, (n, 1))
            + np.random.default_rng(1).normal(0, 0.02, (n, 3))}
    att = {"timestamp": stamps, "timestamp_sample": stamps, "q": np.tile(q_ned, (n, 1))}
    return uw.write_ulog(path, [uw.Topic("sensor_combined", uw.SENSOR_COMBINED, rows),
                                uw.Topic("vehicle_attitude", uw.VEHICLE_ATTITUDE, att)])


def test_px4_nose_up_is_our_negative_pitch_and_roll_is_the_same(tmp_path):
    for roll_deg, pitch_deg in ((0.0, 10.0), (5.0, 0.0), (-20.0, -30.0)):
        rec = read_log(_static_px4(tmp_path / "s.ulg", roll_deg, pitch_deg))
        est = tilt.estimate_log(rec)
        comp = tilt.compare_log(rec, est)
        last = slice(-50, None)
        assert np.degrees(np.median(est.roll_rad[last])) == pytest.approx(roll_deg, abs=0.3)
        assert np.degrees(np.median(est.pitch_rad[last])) == pytest.approx(-pitch_deg, abs=0.3)
        np.testing.assert_allclose(np.degrees(comp.columns["log_roll_rad"]), roll_deg, atol=1e-4)
        np.testing.assert_allclose(np.degrees(comp.columns["log_pitch_rad"]), -pitch_deg,
                                   atol=1e-4)
        assert comp.summary["log"]["rest"]["rms_deg"] < 0.3


def test_the_frd_turn_is_a_rotation_by_pi_about_x():
    q = np.asarray(so3.quat_from_rpy_radians(0.2, -0.4, 1.1))
    turned = frames.quat_nwu_flu(q[None])[0]
    np.testing.assert_allclose(turned, q * np.array([1, 1, -1, -1]), atol=1e-15)
    R, R_t = (np.asarray(so3.matrix_from_quat(x)) for x in (q, turned))
    T = np.diag(frames.FRD_TO_FLU)
    np.testing.assert_allclose(R_t, T @ R @ T, atol=1e-15)
    v = np.array([0.3, -0.2, 0.9])
    np.testing.assert_allclose(R_t @ frames.flu_from_frd(v), T @ (R @ v), atol=1e-15)


# -------------------------------------------------------------------------- ours beside theirs
def test_the_log_estimate_and_ground_truth_beside_ours_show_a_biased_reference(px4):
    rec = read_log(px4)
    assert [(r.name, r.role) for r in rec.references] == [
        ("vehicle_attitude", "log"), ("vehicle_attitude_groundtruth", "truth")]
    est = tilt.estimate_log(rec)
    comp = tilt.compare_log(rec, est)
    s = comp.summary
    # ours follows the truth; PX4's estimate carries the 1.5° bias written into it
    assert s["truth"]["all"]["rms_deg"] < 0.6
    # (a pitch bias about the body's y axis turns the up vector by 1.5° when y is level)
    assert s["truth"]["log_against_truth"]["max_deg"] == pytest.approx(1.5, abs=0.01)
    # at rest the accelerometer shows which reference is biased
    assert s["ours_acc_at_rest"]["rms_deg"] < 0.4
    assert s["log"]["acc_at_rest"]["median_deg"] == pytest.approx(1.5, abs=0.3)
    assert s["at_rest_s"] == pytest.approx(3.0, abs=1.1)
    np.testing.assert_allclose(comp.columns["truth_angle_rad"][-200:],  # (PX4's float32 q)
                               frames.angle_between(est.up_S, _truth_up())[-200:], atol=1e-6)
    assert any("against the ground truth" in line for line in comp.lines)


def test_an_orientation_that_holds_no_estimate_is_left_out(tmp_path):
    for kind in ("none", "zeros", "identity"):
        rec = read_log(lc.ros_log(tmp_path / f"{kind}.bag", "ros1", n=300, orientation=kind))
        assert rec.references == ()
        assert any("hold no orientation estimate" in note for note in rec.notes)
        with pytest.raises(InputError, match="holds no attitude estimate"):
            tilt.compare_log(rec, None)


# --------------------------------------------------------------------- what the logs know
def test_px4_clip_bits_enter_the_filter_as_clipped_samples(tmp_path):
    t, gyr, acc, quat = lc.motion()
    clip = np.zeros((N, 3), dtype=bool)
    clip[600:640, 0] = True  # a gyro x clip inside the roll, invisible in the averaged samples
    aclip = np.zeros((N, 3), dtype=bool)
    aclip[800:805, 2] = True
    path = uw.write_ulog(tmp_path / "c.ulg", lc.px4_topics(t, gyr, acc, quat, gyr_clip=clip,
                                                           acc_clip=aclip))
    rec = read_log(path)
    np.testing.assert_array_equal(rec.gyr_clipped, clip)
    np.testing.assert_array_equal(rec.acc_clipped, aclip)
    est = tilt.estimate_log(rec)
    plain = tilt.estimate(rec.gyr_rad_s, rec.acc_m_s2, rec.t_s)
    flagged = (est.flags & CLIPPED) > 0
    np.testing.assert_array_equal(flagged, clip.any(axis=1) | aclip.any(axis=1))
    assert not np.any(plain.flags & CLIPPED)
    # the unknown excess widens σ over the clipped run (0.5 × the reading's level, ≥ 2 rad/s)
    assert est.sigma_rad[639] > 2 * plain.sigma_rad[639]
    same = tilt.estimate(**rec.estimate_args())
    np.testing.assert_array_equal(same.sigma_rad, est.sigma_rad)
    with pytest.raises(InputError, match=r"gyr_clipped must be \(N, 3\)"):
        tilt.estimate(gyr, acc, t, gyr_clipped=clip[:10])


def test_clip_counters_flag_their_interval_when_the_samples_carry_no_bits(tmp_path):
    t, gyr, acc, quat = lc.motion()
    status_t = 5_000_000 + np.array([0, 2, 4, 6, 8, 10]) * 1_000_000
    counts = np.array([[0, 0, 0], [0, 0, 0], [0, 3, 0], [0, 3, 0], [0, 3, 0], [0, 3, 0]])
    topics = lc.px4_topics(t, gyr, acc, quat, layout=uw.SENSOR_COMBINED_MAG_BARO,
                           attitude_layout=uw.VEHICLE_ATTITUDE_RATES)
    topics.append(uw.Topic("vehicle_imu_status", uw.VEHICLE_IMU_STATUS,
                           {"timestamp": status_t, "accel_clipping": counts,
                            "accel_device_id": 7}))
    rec = read_log(uw.write_ulog(tmp_path / "s.ulg", topics))
    assert rec.gyr_clipped is None and rec.acc_clipped is None
    expected = (rec.stamps > status_t[1]) & (rec.stamps <= status_t[2])
    np.testing.assert_array_equal(rec.clip_counted, expected)
    assert any("vehicle_imu_status counts accelerometer clipping (x 0, y 3, z 0)" in n
               for n in rec.notes)
    est = tilt.estimate_log(rec)
    np.testing.assert_array_equal((est.flags & CLIPPED) > 0, expected)


def test_a_change_of_the_selected_imu_restarts_the_filter_and_drop_outs_are_flagged(tmp_path):
    t, gyr, acc, quat = lc.motion()
    stamps = 5_000_000 + np.round(t * 1e6).astype(np.int64)
    sel = uw.Topic("sensor_selection", uw.SENSOR_SELECTION,
                   {"timestamp": [stamps[0], stamps[700]], "accel_device_id": [1, 2],
                    "gyro_device_id": [1, 2]})
    path = uw.write_ulog(tmp_path / "b.ulg", lc.px4_topics(t, gyr, acc, quat) + [sel],
                         dropouts=[(int(stamps[400]), 40)])
    rec = read_log(path)
    assert np.flatnonzero(rec.restarts).tolist() == [700]
    assert np.flatnonzero(rec.breaks).tolist() == [401]
    est = tilt.estimate_log(rec)
    assert np.flatnonzero(est.flags & INIT).tolist() == [0, 700]  # a fresh start at the change
    assert np.flatnonzero(est.flags & LOG_BREAK).tolist() == [401, 700]
    assert any("selected IMU changes 1 time" in n for n in rec.notes)
    assert any("1 logger drop-out (largest 40 ms" in n for n in rec.notes)


def test_samples_are_sorted_by_stamp_and_a_repeated_stamp_is_flagged(tmp_path):
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.LATEST)
    t, gyr, acc, quat = lc.motion(n=400)
    msgs = lc.imu_messages(store, t, gyr, acc, quat)
    order = np.random.default_rng(3).permutation(400)
    msgs[250] = (msgs[249][0], msgs[250][1].__class__(**{**msgs[250][1].__dict__,
                                                         "header": msgs[249][1].header}))
    path = lc.write_bag(tmp_path / "u.mcap", "bare-mcap", {"/imu": msgs}, order=order)
    rec = read_log(path)
    assert np.all(np.diff(rec.stamps) >= 0)
    np.testing.assert_array_equal(rec.gyr_rad_s[:249], gyr[:249])
    assert any("came before the previous one's time stamp" in n for n in rec.notes)
    assert any("1 sample of /imu repeat" in n for n in rec.notes)
    est = tilt.estimate_log(rec)
    assert np.count_nonzero(est.flags & BAD_DT) == 1


# --------------------------------------------------------------------------------------- topics
def test_the_imu_topic_is_the_only_one_or_chosen_and_refusals_name_them(tmp_path):
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC)
    t, gyr, acc, quat = lc.motion(n=200)
    two = lc.write_bag(tmp_path / "two.bag", "ros1", {
        "/imu/a": lc.imu_messages(store, t, gyr, acc, quat),
        "/imu/b": lc.imu_messages(store, t, gyr, -acc, quat),
        "/chatter": lc.string_messages(store)})
    with pytest.raises(InputError, match=r"several IMU topics \(/imu/a, /imu/b\); choose one"):
        read_log(two)
    np.testing.assert_array_equal(read_log(two, "/imu/b").acc_m_s2, -acc)
    with pytest.raises(InputError, match="topic /chatter holds std_msgs/msg/String, not"):
        read_log(two, "/chatter")
    with pytest.raises(InputError, match="no topic '/nope'; its IMU topics: /imu/a, /imu/b"):
        read_log(two, "/nope")
    none = lc.write_bag(tmp_path / "none.bag", "ros1", {"/chatter": lc.string_messages(store)})
    with pytest.raises(InputError, match=r"no sensor_msgs/Imu topic; its topics: /chatter"):
        read_log(none)


def test_a_ulog_reads_sensor_combined_by_default_or_one_vehicle_imu(tmp_path):
    t, gyr, acc, quat = lc.motion(n=300)
    stamps = 5_000_000 + np.round(t * 1e6).astype(np.int64)
    dt = np.full(300, 10_000)

    def imu(k, scale):
        return uw.Topic("vehicle_imu", uw.VEHICLE_IMU, {
            "timestamp": stamps + 300, "timestamp_sample": stamps,
            "delta_angle": frames.flu_from_frd(gyr) * 0.01 * scale,
            "delta_velocity": frames.flu_from_frd(acc) * 0.01, "delta_angle_dt": dt,
            "delta_velocity_dt": dt, "delta_velocity_clipping": [4] + [0] * 299}, multi_id=k)

    both = lc.px4_topics(t, gyr, acc, quat) + [imu(0, 1.0), imu(1, 2.0)]
    rec = read_log(uw.write_ulog(tmp_path / "i.ulg", both))
    assert rec.topic == "sensor_combined"
    one = read_log(tmp_path / "i.ulg", "vehicle_imu.1")
    np.testing.assert_allclose(one.gyr_rad_s, 2.0 * gyr, rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(one.acc_m_s2, acc, rtol=1e-5, atol=1e-5)
    assert one.acc_clipped[0].tolist() == [False, False, True]
    only_imus = uw.write_ulog(tmp_path / "j.ulg", [imu(0, 1.0), imu(1, 2.0)])
    with pytest.raises(InputError, match=r"several IMU topics \(vehicle_imu.0, vehicle_imu.1\)"):
        read_log(only_imus)
    assert read_log(only_imus, "vehicle_imu").topic == "vehicle_imu.0"


# ------------------------------------------------------------------------------- the extra
def test_a_missing_extra_is_one_line_naming_it(monkeypatch, px4, bags):
    import importlib

    real = importlib.import_module

    def without(name, *a, **k):
        if name.split(".")[0] in ("pyulog", "rosbags"):
            raise ImportError(f"No module named {name!r}")
        return real(name, *a, **k)

    monkeypatch.setattr(importlib, "import_module", without)
    for path, module in ((px4, "pyulog"), (bags["ros1"], "rosbags")):
        with pytest.raises(InputError) as info:
            read_log(path)
        assert str(info.value) == (f"reading robotics logs needs the optional package {module}: "
                                   "pip install 'verticality[logs]'")


def test_the_docs_example_runs_as_written(tmp_path, monkeypatch):
    import re
    from pathlib import Path

    text = (Path(__file__).resolve().parents[1] / "docs" / "logs.md").read_text(encoding="utf-8")
    (code,) = re.findall(r"```python\n(.*?)```", text, re.S)
    lc.px4_log(tmp_path / "flight.ulg", truth=True)
    monkeypatch.chdir(tmp_path)
    namespace: dict = {}
    exec(compile(code, "docs/logs.md", "exec"), namespace)  # noqa: S102
    assert namespace["est"].t_s.size == N and len(namespace["comp"].lines) == 4
