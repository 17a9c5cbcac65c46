"""`verticality stream`: IMU CSV rows in (a pipe or a file), one estimate row out per row."""

import io

import numpy as np

from verticality import cli, tilt
from verticality.io import imu

EUROC_HEADER = ("#timestamp [ns],w_RS_S_x [rad s^-1],w_RS_S_y [rad s^-1],w_RS_S_z [rad s^-1],"
                "a_RS_S_x [m s^-2],a_RS_S_y [m s^-2],a_RS_S_z [m s^-2]")
T0_NS = 1403636579758555392  # first stamp of EuRoC MH_01_easy


def _stream(argv, capsys, monkeypatch, stdin_text=None):
    if stdin_text is not None:
        monkeypatch.setattr("sys.stdin", io.StringIO(stdin_text))
    capsys.readouterr()
    code = cli.main(["stream", *argv])
    cap = capsys.readouterr()
    return code, cap.out, cap.err


def _table(text, tmp_path):
    (tmp_path / "out.csv").write_text(text)
    return imu.read_estimate_csv(tmp_path / "out.csv")


def test_stream_from_stdin_equals_estimate_on_the_file(tmp_path, capsys, monkeypatch,
                                                       swinging_imu):
    """The pipe gives, row for row, what `estimate --sigma` gives for the whole file (the
    plain-Python twin of the filter equals the batch run), including the held-back first
    second."""
    rec = swinging_imu(n=1500, dt_s=0.01, seed=3)
    rec.acc_m_s2[700:705] = np.nan
    src = imu.write_imu_csv(tmp_path / "rec.csv", rec)
    code, out, _ = _stream(["--sigma"], capsys, monkeypatch, src.read_text())
    assert code == 0
    got = _table(out, tmp_path)
    assert cli.main(["estimate", str(src), "--out", str(tmp_path / "est.csv"), "--sigma"]) == 0
    ref = imu.read_estimate_csv(tmp_path / "est.csv")
    for name in ref._fields:
        np.testing.assert_allclose(getattr(got, name), getattr(ref, name), rtol=0, atol=1e-9,
                                   err_msg=name)
    assert np.all(got.flags[700:705] & tilt.ACC_MISSING)


def test_unreadable_rows_are_written_flagged_and_named(tmp_path, capsys, monkeypatch,
                                                       swinging_imu):
    """After the checked head, a row with too few cells, one with a time that is not a number and
    one whose time goes back are each still written (one output row per input row), flagged as a
    bad time step, and named on stderr; the rows after them are filtered as usual."""
    rec = swinging_imu(n=400, dt_s=0.01, seed=4)
    lines = imu.write_imu_csv(tmp_path / "rec.csv", rec).read_text().splitlines()
    cells = lines[301].split(",")
    lines[301] = ",".join(cells[:3])  # data row 300: too few cells
    lines[302] = ",".join(["x"] + lines[302].split(",")[1:])  # row 301: time not a number
    lines[303] = ",".join(["0.5"] + lines[303].split(",")[1:])  # row 302: time goes back
    code, out, err = _stream([], capsys, monkeypatch, "\n".join(lines) + "\n")
    assert code == 0
    got = _table(out, tmp_path)
    assert got.t_s.size == 400
    assert np.all(got.flags[300:303] & tilt.BAD_DT)
    assert not np.any(got.flags[303:] & tilt.BAD_DT)
    assert "line 302: 3 cells, the header has 7" in err
    assert "line 303: time 'x' is not a number" in err
    assert "line 304: time 0.5 s does not follow 2.99 s" in err
    np.testing.assert_allclose(got.t_s[303:], rec.t_s[303:], rtol=0, atol=1e-12)


def test_euroc_ns_stamps_on_a_pipe_and_refusals(tmp_path, capsys, monkeypatch, swinging_imu):
    """EuRoC rows: times relative to the first stamp, exact to the ns; data in g are refused
    before any row is written, as `estimate` refuses the file."""
    rec = swinging_imu(n=600, dt_s=0.005, seed=5)
    stamps = T0_NS + np.arange(600, dtype=np.int64) * 5_000_000
    rows = [EUROC_HEADER] + [",".join([str(int(s))] + [f"{v:.17g}" for v in (*g, *a)])
                             for s, g, a in zip(stamps, rec.gyr_rad_s, rec.acc_m_s2, strict=True)]
    code, out, err = _stream([], capsys, monkeypatch, "\n".join(rows) + "\n")
    assert code == 0 and f"first time stamp, {T0_NS} ns" in err
    got = _table(out, tmp_path)
    np.testing.assert_array_equal(got.t_s, (stamps - T0_NS) / 1e9)
    src = imu.write_imu_csv(tmp_path / "g.csv", rec._replace(acc_m_s2=rec.acc_m_s2 / 9.81))
    code, out, err = _stream([str(src)], capsys, monkeypatch)
    assert code == 2 and out == "" and "looks like g" in err
    code, out, err = _stream([str(src), "--units", "g"], capsys, monkeypatch)
    assert code == 0 and len(out.splitlines()) == 601


def test_a_byte_order_mark_on_the_pipe_is_ignored(tmp_path, capsys, monkeypatch, swinging_imu):
    """Files are read as utf-8-sig; a pipe gets the same treatment of a leading BOM."""
    src = imu.write_imu_csv(tmp_path / "rec.csv", swinging_imu(n=300, dt_s=0.01, seed=6))
    code, out, err = _stream([], capsys, monkeypatch, "\ufeff" + src.read_text())
    assert code == 0 and err == "" and len(out.splitlines()) == 301


def test_one_absurd_time_stamp_costs_its_own_row_only(tmp_path, capsys, monkeypatch,
                                                      swinging_imu):
    """A stamp of 1e300 s, one far back and one far ahead (then the clock goes on) while the
    readings go on: each is a clock jump, its row taken at the nominal step and flagged (the row
    after a followed absurd stamp steps back from it: a jump too); no gap, nothing skipped, and
    the rows after them are filtered as the clean stream's are."""
    rec = swinging_imu(n=600, dt_s=0.01, seed=5)
    clean = imu.write_imu_csv(tmp_path / "rec.csv", rec).read_text().splitlines()
    lines = list(clean)
    for row, stamp in ((300, "1e300"), (350, "-7"), (420, "5e4"), (500, "1e308")):
        lines[row + 1] = ",".join([stamp] + lines[row + 1].split(",")[1:])
    code, out, err = _stream([], capsys, monkeypatch, "\n".join(lines) + "\n")
    assert code == 0 and "Traceback" not in err
    got = _table(out, tmp_path)
    _, ref_out, _ = _stream([], capsys, monkeypatch, "\n".join(clean) + "\n")
    ref = _table(ref_out, tmp_path)
    assert got.t_s.size == ref.t_s.size == 600
    jumps = np.flatnonzero(got.flags & tilt.CLOCK_JUMP).tolist()
    assert jumps == [300, 301, 350, 420, 421, 500, 501], jumps
    assert not np.any(got.flags & (tilt.BAD_DT | tilt.DT_GAP))
    assert not np.any(got.flags[200:] & tilt.REACQUIRED)  # (the start's only)
    assert np.all(np.isfinite(got.roll_rad)) and np.all(np.isfinite(got.pitch_rad))
    np.testing.assert_allclose(got.roll_rad, ref.roll_rad, atol=np.radians(0.5))
    np.testing.assert_allclose(got.pitch_rad, ref.pitch_rad, atol=np.radians(0.5))


def test_huge_values_and_garbage_rows_never_stop_the_stream(tmp_path, capsys, monkeypatch,
                                                            swinging_imu):
    rec = swinging_imu(n=400, dt_s=0.01, seed=6)
    lines = imu.write_imu_csv(tmp_path / "rec.csv", rec).read_text().splitlines()
    lines[250] = lines[250].rsplit(",", 1)[0] + ",1e308"
    lines[260] = ",".join(lines[260].split(",")[:2] + ["1e10"] + lines[260].split(",")[3:])
    lines[270] = "\x00\x01garbage,,,;;"
    lines[280] = "1e999,inf,-inf,nan,1,2,3"
    code, out, err = _stream(["--sigma"], capsys, monkeypatch, "\n".join(lines) + "\n")
    assert code == 0
    got = _table(out, tmp_path)
    assert got.t_s.size == 400
    assert got.flags[249] & tilt.OUT_OF_RANGE and got.flags[259] & tilt.OUT_OF_RANGE
    assert got.flags[269] & tilt.BAD_DT and got.flags[279] & tilt.BAD_DT
    assert np.all(np.isfinite(got.roll_rad)) and np.all(np.isfinite(got.tilt_sigma_rad))
