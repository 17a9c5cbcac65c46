"""``verticality estimate LOG`` as a user runs it (docs/logs.md), in-process: a ULog, a ROS 1 bag,
a ROS 2 bag folder and an MCAP file each give the estimate CSV; ``--compare`` the log's estimate
beside ours; ``--out X.mcap`` and ``--ros2-bag`` the tilt written back, read by the MCAP
reference library and by rosbags; ``--plot`` the figure. Bad and foreign logs (truncated, no IMU
topic, a topic that is not an Imu, several IMUs, unstamped) are one line and status 2, never a
traceback; a folder of logs is estimated as a folder of CSVs is.
"""

from __future__ import annotations

import random
import shutil

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import log_cases as lc
import ulog_writer as uw
from test_reliability import _check_status, run_cli
from verticality.io.imu import read_estimate_csv

N = 1200


@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    d = tmp_path_factory.mktemp("logs")
    made = {fmt: lc.ros_log(d / name, fmt) for fmt, name in
            (("ros1", "run.bag"), ("mcap", "run_bag"), ("bare-mcap", "run.mcap"))}
    made["ulog"] = lc.px4_log(d / "flight.ulg", truth=True)
    return made


def one_line_refusal(code, err: str) -> bool:
    found: list[str] = []
    _check_status(code, err, found)
    return code == 2 and not found


def test_estimate_works_on_each_log_format_as_a_user_runs_it(logs, tmp_path):
    for fmt, path in logs.items():
        out = tmp_path / f"{fmt}.csv"
        code, stdout, err = run_cli(["estimate", str(path), "--out", str(out)])
        assert code == 0, (fmt, err)
        table = read_estimate_csv(out)
        assert table.t_s.size == N and table.t_s[0] == 0.0
        assert f"wrote {out} ({N} samples of" in stdout
        origin = "5000000 us" if fmt == "ulog" else f"{lc.STAMP0_NS} ns"
        assert f"first time stamp, {origin}" in stdout
        t, _, _, quat = lc.motion()
        truth = lc.frames.up_in_sensor(quat)
        settled = (table.flags & 128) == 0
        angle = np.degrees(lc.frames.angle_between(-table.gravity_S[settled], truth[settled]))
        assert np.sqrt(np.mean(angle**2)) < 1.0, fmt


def test_compare_writes_the_logs_estimate_beside_ours_and_plot_draws_it(logs, tmp_path):
    cmp_csv, png = tmp_path / "cmp.csv", tmp_path / "cmp.png"
    code, stdout, err = run_cli(["estimate", str(logs["ulog"]), "--out", str(tmp_path / "o.csv"),
                                 "--compare", str(cmp_csv), "--plot", str(png)])
    assert code == 0, err
    header = cmp_csv.read_text().splitlines()[0].split(",")
    assert header == ["t", "roll_rad", "pitch_rad", "at_rest", "acc_angle_rad", "log_roll_rad",
                      "log_pitch_rad", "log_angle_rad", "log_acc_angle_rad", "truth_roll_rad",
                      "truth_pitch_rad", "truth_angle_rad", "truth_acc_angle_rad",
                      "log_truth_angle_rad"]
    data = np.loadtxt(cmp_csv, delimiter=",", skiprows=1)
    assert data.shape == (N, len(header))
    assert "vehicle_attitude (the log's estimate) against verticality" in stdout
    assert "at rest, angle to the accelerometer's direction" in stdout
    assert png.stat().st_size > 10_000 and f"wrote {png}" in stdout


def test_the_tilt_written_back_is_read_by_standard_readers(logs, tmp_path):
    from mcap.reader import make_reader
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import Stores, get_typestore

    out, bag = tmp_path / "tilt.mcap", tmp_path / "tilt_bag"
    code, _, err = run_cli(["estimate", str(logs["ros1"]), "--out", str(out), "--ros2-bag",
                            str(bag), "--tilt-topic", "/imu/tilt"])
    assert code == 0, err
    code, _, err = run_cli(["estimate", str(logs["ros1"]), "--out", str(tmp_path / "e.csv")])
    est = read_estimate_csv(tmp_path / "e.csv")
    stamps = lc.STAMP0_NS + np.round(lc.motion()[0] * 1e9).astype(np.int64)
    with open(out, "rb") as fh:  # the MCAP reference reader
        reader = make_reader(fh)
        summary = reader.get_summary()
        (channel,) = summary.channels.values()
        assert reader.get_header().profile == "ros2" and channel.topic == "/imu/tilt"
        assert summary.schemas[channel.schema_id].name == "sensor_msgs/msg/Imu"
        assert channel.message_encoding == "cdr" and summary.statistics.message_count == N
    store = get_typestore(Stores.LATEST)
    for path in (out, bag):
        with Reader(path) as r:
            msgs = [store.deserialize_cdr(raw, c.msgtype) for c, _, raw in r.messages()]
        got = np.array([m.header.stamp.sec * 10**9 + m.header.stamp.nanosec for m in msgs])
        np.testing.assert_array_equal(got, stamps)  # the samples' own stamps, exactly
        up = lc.frames.up_in_sensor(np.array([[m.orientation.w, m.orientation.x,
                                               m.orientation.y, m.orientation.z] for m in msgs]))
        np.testing.assert_allclose(up, -est.gravity_S, atol=1e-12)
        assert all(m.angular_velocity_covariance[0] == -1 and m.header.frame_id == "imu_link"
                   for m in msgs)
    assert sorted(p.name for p in bag.iterdir()) == ["metadata.yaml", "tilt_bag.db3"]
    code, _, err = run_cli(["estimate", str(logs["ulog"]), "--out", str(tmp_path / "q.mcap"),
                            "--tilt-message", "quaternion"])
    assert code == 0, err
    with Reader(tmp_path / "q.mcap") as r:
        assert [c.msgtype for c in r.connections] == ["geometry_msgs/msg/QuaternionStamped"]


def _bad_cases(logs, d):
    """``{name: (argv, text the one line must hold)}``: damaged and foreign logs, and options
    that do not apply."""
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC)
    t, gyr, acc, quat = lc.motion(n=50)
    raw_bag = logs["ros1"].read_bytes()
    raw_ulog = logs["ulog"].read_bytes()
    files = {
        "cut.bag": raw_bag[:len(raw_bag) // 2],
        "head.bag": raw_bag[:20],
        "cut.ulg": raw_ulog[:200],
        "short.ulg": raw_ulog[:10],
        "empty.mcap": b"",
        "cut.mcap": logs["bare-mcap"].read_bytes()[:3000],
        "text.ulg": b"t,gyr_x,gyr_y,gyr_z,acc_x,acc_y,acc_z\n0,0,0,0,0,0,9.8\n",
        "garbage.ulg": uw.MAGIC + bytes(range(256)) * 4,
    }
    for name, raw in files.items():
        (d / name).write_bytes(raw)
    lc.write_bag(d / "two.bag", "ros1", {"/a": lc.imu_messages(store, t, gyr, acc, quat),
                                         "/b": lc.imu_messages(store, t, gyr, acc, quat)})
    lc.write_bag(d / "chatter.bag", "ros1", {"/chatter": lc.string_messages(store)})
    unstamped = [(s, m.__class__(**{**m.__dict__, "header": m.header.__class__(
        seq=0, stamp=m.header.stamp.__class__(sec=0, nanosec=0), frame_id="imu")}))
        for s, m in lc.imu_messages(store, t, gyr, acc, quat)]
    lc.write_bag(d / "unstamped.bag", "ros1", {"/imu": unstamped})
    lc.ros_log(d / "empty_orientation.bag", "ros1", n=200, orientation="none")
    uw.write_ulog(d / "no_imu.ulg", [uw.Topic("vehicle_status", uw.VEHICLE_STATUS,
                                              {"timestamp": [1, 2, 3]})])
    csv = d / "rec.csv"
    csv.write_text("t,gyr_x,gyr_y,gyr_z,acc_x,acc_y,acc_z\n0,0,0,0,0,0,9.8\n0.01,0,0,0,0,0,9.8\n")
    out = ["--out", str(d / "out.csv")]
    cases = {name: ([str(d / name)] + out, "") for name in files}
    cases |= {
        "two": ([str(d / "two.bag")] + out, "several IMU topics (/a, /b); choose one with --topic"),
        "not imu": ([str(d / "two.bag"), "--topic", "/chatter"] + out, "no topic '/chatter'"),
        "chatter": ([str(d / "chatter.bag")] + out, "no sensor_msgs/Imu topic"),
        "chatter topic": ([str(d / "chatter.bag"), "--topic", "/chatter"] + out,
                          "holds std_msgs/msg/String, not sensor_msgs/Imu"),
        "unstamped": ([str(d / "unstamped.bag")] + out, "header.stamp is zero in 50 messages"),
        "no estimate": ([str(d / "empty_orientation.bag"), "--compare", str(d / "c.csv")] + out,
                        "holds no attitude estimate"),
        "no imu": ([str(d / "no_imu.ulg")] + out, "no IMU topic in this ULog"),
        "csv topic": ([str(csv), "--topic", "/imu"] + out, "--topic: for a robotics log"),
        "csv mcap": ([str(csv), "--out", str(d / "o.mcap")], "--out .mcap: for a robotics log"),
        "columns": ([str(logs["ulog"]), "--columns", "t=a"] + out, "--columns: not for a"),
        "bag exists": ([str(logs["ulog"]), "--ros2-bag", str(d)] + out, "exists"),
        "sigma mcap": ([str(logs["ulog"]), "--sigma", "--out", str(d / "s.mcap")], "--sigma"),
        "out is input": ([str(logs["ulog"]), "--out", str(logs["ulog"])], "is the input"),
    }
    return cases


def test_bad_and_foreign_logs_are_one_line_never_a_traceback(logs, tmp_path):
    before = {p: p.read_bytes() for p in logs.values() if p.is_file()}
    for name, (argv, text) in _bad_cases(logs, tmp_path).items():
        code, _, err = run_cli(["estimate", *argv])
        assert one_line_refusal(code, err), (name, code, err)
        assert text in err, (name, err)
        assert not (tmp_path / "out.csv").exists(), name
    code, _, err = run_cli(["stream", str(logs["ulog"])])
    assert one_line_refusal(code, err) and "use verticality estimate LOG" in err
    assert all(p.read_bytes() == raw for p, raw in before.items())


def test_a_folder_of_logs_is_estimated_as_a_folder_of_recordings(logs, tmp_path):
    d = tmp_path / "in"
    d.mkdir()
    for key in ("ulog", "ros1"):
        shutil.copy(logs[key], d)
    (d / "bad.mcap").write_bytes(b"\x89MCAP0\r\n")
    code, stdout, err = run_cli(["estimate", str(d), "--out", str(tmp_path / "out")])
    assert code == 1 and "3 recordings" in stdout, err
    assert "bad.mcap: not a readable MCAP" in err
    for name in ("flight.csv", "run.csv"):
        assert read_estimate_csv(tmp_path / "out" / name).t_s.size == N


SEEDS = st.integers(min_value=0, max_value=2**31 - 1)
FEW = settings(max_examples=16, deadline=None, derandomize=True,
               suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])


def damaged(raw: bytes, rng: random.Random) -> bytes:
    """``raw`` cut short, with bytes flipped, or with a stretch zeroed (one to three of them)."""
    data = bytearray(raw)
    for _ in range(rng.randint(1, 3)):
        kind = rng.choice(["cut", "flip", "zero"])
        if kind == "cut" and len(data) > 16:
            del data[rng.randint(16, len(data) - 1):]
        elif kind == "flip" and data:
            for _ in range(rng.randint(1, 40)):
                data[rng.randrange(len(data))] ^= 1 << rng.randrange(8)
        elif data:
            a = rng.randrange(len(data))
            data[a:a + rng.randint(1, 4096)] = bytes(min(4096, len(data) - a))
    return bytes(data)


@FEW
@given(seed=SEEDS)
def test_a_damaged_log_is_estimated_or_refused_in_one_line(logs, tmp_path_factory, seed):
    rng = random.Random(seed)
    key = rng.choice(["ros1", "bare-mcap", "ulog"])
    d = tmp_path_factory.mktemp("damaged")
    path = d / logs[key].name
    path.write_bytes(damaged(logs[key].read_bytes(), rng))
    code, _, err = run_cli(["estimate", str(path), "--out", str(d / "out.csv")])
    found: list[str] = []
    _check_status(code, err, found)
    assert not found, (seed, key, code, err)
    if code == 0:
        table = read_estimate_csv(d / "out.csv")
        assert table.t_s.size >= 2 and np.all(np.isfinite(table.t_s))


def test_log_outputs_never_write_through_a_link_planted_where_they_go(logs, tmp_path):
    """The estimate CSV, the comparison CSV and the MCAP written back replace a link planted at
    their names (the link's own path), never the file it points to."""
    victims = {}
    outs = {"--out": tmp_path / "tilt.mcap", "--compare": tmp_path / "cmp.csv"}
    for opt, out in outs.items():
        victim = tmp_path / f"victim{opt}.txt"
        victim.write_text("private")
        out.symlink_to(victim)
        victims[opt] = victim
    code, _, err = run_cli(["estimate", str(logs["ulog"]), "--out", str(outs["--out"]),
                            "--compare", str(outs["--compare"])])
    assert code == 0, err
    for opt, out in outs.items():
        assert victims[opt].read_text() == "private", opt
        assert not out.is_symlink() and out.stat().st_size > 0, opt
