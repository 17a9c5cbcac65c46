"""IMU files in other layouts: EuRoC / TUM-VI, user-mapped columns, time units, and refusals."""

from pathlib import Path

import h5py
import numpy as np
import pytest

from broad_slices import SLOW_ROTATION
from verticality import cli
from verticality.core.errors import InputError
from verticality.io import broad, imu, imu_layout

G = 9.81
EUROC_HEADER = ("#timestamp [ns],w_RS_S_x [rad s^-1],w_RS_S_y [rad s^-1],w_RS_S_z [rad s^-1],"
                "a_RS_S_x [m s^-2],a_RS_S_y [m s^-2],a_RS_S_z [m s^-2]")
T0_NS = 1403636579758555392  # first stamp of EuRoC MH_01_easy
MAPPING = "t=time_ms,gyr_x=wx,gyr_y=wy,gyr_z=wz,acc_x=ax,acc_y=ay,acc_z=az"


def _write_euroc(path, stamps_ns, gyr, acc, header=EUROC_HEADER, sep=","):
    lines = [header]
    for s, g, a in zip(stamps_ns, gyr, acc, strict=True):
        lines.append(sep.join([str(int(s))] + [f"{v:.17g}" for v in (*g, *a)]))
    Path(path).write_text("\n".join(lines) + "\n", encoding="utf-8")
    return Path(path)


def _estimate(argv, out):
    assert cli.main(["estimate", *argv, "--out", str(out)]) == 0
    return imu.read_estimate_csv(out)


def _refused(argv, tmp_path, capsys):
    """Run `verticality estimate` expecting exit status 2; return the one-line message."""
    capsys.readouterr()
    assert cli.main(["estimate", *argv, "--out", str(tmp_path / "never.csv")]) == 2
    err = capsys.readouterr().err.strip()
    assert err and "\n" not in err
    return err


def test_euroc_header_variants_read_back_with_exact_ns_steps(tmp_path, swinging_imu):
    rec = swinging_imu(n=1200, dt_s=0.005, seed=1)
    stamps = T0_NS + 5_000_000 * np.arange(rec.t_s.size, dtype=np.int64)  # 200 Hz
    # float64 holds stamps near 1.4e18 only to 256 ns: these would lose up to 128 ns
    assert np.any(stamps.astype(np.float64).astype(np.int64) != stamps)
    tum_header = " " + EUROC_HEADER[1:].replace(",", ", ")  # TUM-VI: no '#', spaces
    for name, header, sep in (("euroc.csv", EUROC_HEADER, ","), ("tumvi.csv", tum_header, ", ")):
        back = imu.read_imu_csv(_write_euroc(tmp_path / name, stamps, rec.gyr_rad_s,
                                             rec.acc_m_s2, header, sep))
        np.testing.assert_array_equal(back.gyr_rad_s, rec.gyr_rad_s)
        np.testing.assert_array_equal(back.acc_m_s2, rec.acc_m_s2)
        assert back.t0_stamp == T0_NS and isinstance(back.t0_stamp, int)
        assert back.time_unit == "ns" and back.t_s[0] == 0.0
        np.testing.assert_allclose(np.diff(back.t_s), 0.005, rtol=0, atol=1e-9)
        np.testing.assert_allclose(back.dt_s, 0.005, rtol=0, atol=1e-12)
        np.testing.assert_allclose(back.t_s, np.arange(rec.t_s.size) * 0.005, rtol=0, atol=1e-12)
    # one stamp 1 ns late moves its two steps by exactly 1 ns
    late = stamps.copy()
    late[10] += 1
    back = imu.read_imu_csv(_write_euroc(tmp_path / "late.csv", late, rec.gyr_rad_s, rec.acc_m_s2))
    np.testing.assert_allclose(np.diff(back.t_s)[9:11], [0.005 + 1e-9, 0.005 - 1e-9],
                               rtol=0, atol=1e-13)


def test_estimate_on_euroc_slice_of_broad_equals_own_layout(tmp_path, capsys):
    trial = broad.load_trial(SLOW_ROTATION)
    sl = slice(12000, 14000)  # 7 s of slow rotation, up to 3 rad/s
    gyr, acc = trial.gyr_rad_s[sl], trial.acc_m_s2[sl]
    step_ns = 3_500_000  # BROAD's 285.714 Hz
    assert step_ns * 1e-9 == pytest.approx(trial.dt_s, rel=1e-12)
    n = gyr.shape[0]
    euroc = _write_euroc(tmp_path / "imu0.csv", T0_NS + step_ns * np.arange(n), gyr, acc)
    own = imu.write_imu_csv(tmp_path / "own.csv",
                            imu.ImuRecording(np.arange(n) * step_ns / 1e9, gyr, acc))
    capsys.readouterr()
    a = _estimate([str(euroc)], tmp_path / "a.csv")
    assert f"first time stamp, {T0_NS} ns" in capsys.readouterr().out
    b = _estimate([str(own)], tmp_path / "b.csv")
    assert np.ptp(b.roll_rad) > 0.5  # the slice does turn
    np.testing.assert_allclose(a.t_s, b.t_s, rtol=0, atol=1e-12)
    np.testing.assert_allclose(a.roll_rad, b.roll_rad, rtol=0, atol=1e-9)
    np.testing.assert_allclose(a.pitch_rad, b.pitch_rad, rtol=0, atol=1e-9)


def _write_mapped(path, rec, header_t="time_ms", t_scale=1000.0):
    """Reordered columns, an extra temperature column, time in ms (integers)."""
    lines = [f"ax, {header_t},wz,temp_C,wy,ay,wx,az"]
    for t, g, a in zip(rec.t_s, rec.gyr_rad_s, rec.acc_m_s2, strict=True):
        cells = [a[0], int(round(t * t_scale)), g[2], 25.0, g[1], a[1], g[0], a[2]]
        lines.append(",".join(f"{v:.17g}" if isinstance(v, float) else str(v) for v in cells))
    Path(path).write_text("\n".join(lines) + "\n", encoding="utf-8")
    return Path(path)


def test_column_mapping_reordered_extra_column_ms(tmp_path, swinging_imu):
    rec = swinging_imu(dt_s=0.01, n=1500, seed=1)
    mapped = _write_mapped(tmp_path / "mapped.csv", rec)
    columns = imu_layout.parse_columns_spec(MAPPING)
    back = imu.read_imu_csv(mapped, columns=columns, time_unit="ms")
    np.testing.assert_array_equal(back.gyr_rad_s, rec.gyr_rad_s)
    np.testing.assert_array_equal(back.acc_m_s2, rec.acc_m_s2)
    np.testing.assert_allclose(back.t_s, rec.t_s, rtol=0, atol=1e-12)
    assert back.t0_stamp == 0 and back.time_unit == "ms"
    # "[ms]" on the header states the unit; the mapped name may leave the bracket out
    bracket = _write_mapped(tmp_path / "bracket.csv", rec, header_t="#time [ms]")
    back2 = imu.read_imu_csv(bracket, columns={**columns, "t": "time"})
    np.testing.assert_array_equal(back2.t_s, back.t_s)
    # the CLI gives the same estimate as on our own layout
    own = imu.write_imu_csv(tmp_path / "own.csv", rec)
    a = _estimate([str(mapped), "--columns", MAPPING, "--time-unit", "ms"], tmp_path / "a.csv")
    b = _estimate([str(own)], tmp_path / "b.csv")
    np.testing.assert_allclose(a.roll_rad, b.roll_rad, rtol=0, atol=1e-9)
    np.testing.assert_allclose(a.pitch_rad, b.pitch_rad, rtol=0, atol=1e-9)


def test_parse_columns_spec():
    assert (imu_layout.parse_columns_spec(" t = a b ,gyr_x=#w [x]")
            == {"t": "a b", "gyr_x": "#w [x]"})
    for text in ("", "t=a,,gyr_x=b", "t", "t=", "=a", "t=a;gyr_x=b"):
        with pytest.raises(InputError, match="is not NAME=COLUMN"):
            imu_layout.parse_columns_spec(text)
    with pytest.raises(InputError, match="t is given twice"):
        imu_layout.parse_columns_spec("t=a,t=b")


def test_layout_refusals_are_one_line(tmp_path, capsys, swinging_imu):
    rec = swinging_imu(dt_s=0.01, n=600, seed=1)
    mapped = _write_mapped(tmp_path / "mapped.csv", rec)
    own_ms = imu.write_imu_csv(tmp_path / "own_ms.csv", rec._replace(t_s=rec.t_s * 1000.0))
    stamps = T0_NS + 10_000_000 * np.arange(rec.t_s.size)
    euroc = _write_euroc(tmp_path / "euroc.csv", stamps, rec.gyr_rad_s, rec.acc_m_s2)
    hdf5 = tmp_path / "trial.hdf5"
    with h5py.File(hdf5, "w") as f:
        f["imu_gyr"] = rec.gyr_rad_s
        f["imu_acc"] = rec.acc_m_s2
        f.attrs["sampling_rate"] = 100.0

    err = _refused([str(own_ms)], tmp_path, capsys)
    assert "median time step is 10" in err and "--time-unit ms|us|ns" in err
    np.testing.assert_allclose(_estimate([str(own_ms), "--time-unit", "ms"],
                                         tmp_path / "ok.csv").t_s, rec.t_s, atol=1e-12)
    err = _refused([str(mapped), "--time-unit", "ms", "--columns", MAPPING.replace("=wz", "=wq")],
                   tmp_path, capsys)
    assert "not in the file: gyr_z=wq" in err and "'temp_C'" in err
    err = _refused([str(mapped), "--time-unit", "ms", "--columns",
                    MAPPING.replace("gyr_y=wy", "gyr_y=wx")], tmp_path, capsys)
    assert "'wx' is used for gyr_x and gyr_y" in err
    err = _refused([str(mapped), "--columns", "t=time_ms;gyr_x=wx"], tmp_path, capsys)
    assert "'t=time_ms;gyr_x=wx' is not NAME=COLUMN" in err
    err = _refused([str(mapped), "--columns", MAPPING.replace("acc_z=az", "gyro=az")],
                   tmp_path, capsys)
    assert "unknown column name(s) gyro" in err
    err = _refused([str(mapped), "--columns", MAPPING.replace(",acc_z=az", "")], tmp_path, capsys)
    assert "must map all of" in err and "acc_z missing" in err
    err = _refused([str(euroc), "--time-unit", "ms"], tmp_path, capsys)
    assert "says [ns] but --time-unit ms" in err
    assert cli.main(["estimate", str(euroc), "--time-unit", "ns",
                     "--out", str(tmp_path / "ok.csv")]) == 0
    err = _refused([str(euroc), "--time-unit", "min"], tmp_path, capsys)
    assert "unknown time unit 'min'" in err
    # a stated unit that makes no IMU's rate: ms stamps read as ns (100 MHz), ns as ms (1e-4 Hz)
    err = _refused([str(own_ms), "--time-unit", "ns"], tmp_path, capsys)
    assert "with time in ns the median step is 1e-08 s" in err and "check --time-unit" in err
    ns_plain = imu.write_imu_csv(tmp_path / "own_ns.csv", rec._replace(t_s=rec.t_s * 1e9))
    err = _refused([str(ns_plain), "--time-unit", "ms"], tmp_path, capsys)
    assert "with time in ms the median step is 10000 s" in err
    for extra, named in ((["--columns", MAPPING], "--columns applies"),
                         (["--time-unit", "ms"], "--time-unit applies"),
                         (["--time-unit", "ms", "--columns", MAPPING],
                          "--columns and --time-unit apply")):
        err = _refused([str(hdf5), *extra], tmp_path, capsys)
        assert f"{named} to CSV input only" in err
    # a header we do not know: what it has, and the way out
    err = _refused([str(mapped)], tmp_path, capsys)
    assert "missing column(s) t, gyr_x" in err and "'time_ms'" in err and "--columns t=" in err
    # decreasing or non-numeric ns stamps name their line (a repeated stamp is read: the filter
    # flags that row, test_tilt_clock)
    stamps[4] = stamps[3] - 1
    err = _refused([str(_write_euroc(tmp_path / "dup.csv", stamps, rec.gyr_rad_s,
                                     rec.acc_m_s2))], tmp_path, capsys)
    assert "must not decrease (line 6)" in err
    text = euroc.read_text().splitlines()
    text[3] = text[3].replace(str(T0_NS + 20_000_000), "x")
    bad = tmp_path / "nonnumeric.csv"
    bad.write_text("\n".join(text) + "\n")
    err = _refused([str(bad)], tmp_path, capsys)
    assert "column t (timestamp [ns]) has empty or non-numeric cells at lines [4]" in err


def test_long_header_list_is_truncated_on_one_line(tmp_path):
    p = tmp_path / "wide.csv"
    names = [f"channel_{k}" for k in range(40)]
    p.write_text(",".join(names) + "\n" + ",".join(["1"] * 40) + "\n")
    with pytest.raises(InputError, match=r"'channel_11', … \(28 more\)") as exc:
        imu.read_imu_csv(p)
    assert "channel_12" not in str(exc.value) and "\n" not in str(exc.value)


def test_deg_s_in_euroc_layout_is_refused_unless_stated(tmp_path, capsys, swinging_imu):
    rec = swinging_imu(n=1200, dt_s=0.005, seed=1)
    stamps = T0_NS + 5_000_000 * np.arange(rec.t_s.size)
    deg = _write_euroc(tmp_path / "deg.csv", stamps, np.degrees(rec.gyr_rad_s), rec.acc_m_s2)
    err = _refused([str(deg)], tmp_path, capsys)
    assert "looks like deg/s" in err and "--units deg/s" in err
    rad = _write_euroc(tmp_path / "rad.csv", stamps, rec.gyr_rad_s, rec.acc_m_s2)
    a = _estimate([str(deg), "--units", "deg/s"], tmp_path / "a.csv")
    b = _estimate([str(rad)], tmp_path / "b.csv")
    np.testing.assert_allclose(a.roll_rad, b.roll_rad, rtol=0, atol=1e-9)
    # the same through the Python API, and g for the accelerometer too
    g_file = _write_euroc(tmp_path / "g.csv", stamps, rec.gyr_rad_s, rec.acc_m_s2 / G)
    with pytest.raises(InputError, match="looks like g"):
        imu.read_imu_csv(g_file)
    np.testing.assert_allclose(imu.read_imu_csv(g_file, acc_units="g").acc_m_s2, rec.acc_m_s2,
                               rtol=1e-12)
