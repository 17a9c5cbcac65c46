"""IMU CSV in/out, unit checks, and `verticality estimate` round-tripping through io."""

import numpy as np
import pytest

from verticality import cli, tilt
from verticality.core.errors import InputError
from verticality.io import imu

G = 9.81


def test_csv_round_trip(tmp_path, swinging_imu):
    rec = swinging_imu(n=200)
    rec.acc_m_s2[10] = np.nan
    path = imu.write_imu_csv(tmp_path / "rec.csv", rec)
    back = imu.read_imu_csv(path)
    np.testing.assert_array_equal(back.t_s, rec.t_s)
    np.testing.assert_array_equal(back.gyr_rad_s, rec.gyr_rad_s)
    np.testing.assert_array_equal(np.isnan(back.acc_m_s2), np.isnan(rec.acc_m_s2))
    np.testing.assert_allclose(back.dt_s, 0.01, rtol=1e-9)


def test_units_g_and_deg_s_are_refused_unless_stated(swinging_imu):
    rec = swinging_imu()
    with pytest.raises(InputError, match="looks like g"):
        imu.check_units(rec.gyr_rad_s, rec.acc_m_s2 / G)
    with pytest.raises(InputError, match="deg/s"):
        imu.check_units(np.degrees(rec.gyr_rad_s), rec.acc_m_s2, dt_s=0.01)
    gyr, acc = imu.check_units(np.degrees(rec.gyr_rad_s), rec.acc_m_s2 / G, gyr_units="deg/s",
                               acc_units="g", dt_s=0.01)
    np.testing.assert_allclose(gyr, rec.gyr_rad_s, rtol=1e-12)
    np.testing.assert_allclose(acc, rec.acc_m_s2, rtol=1e-12)
    # SI data pass untouched
    gyr, acc = imu.check_units(rec.gyr_rad_s, rec.acc_m_s2, dt_s=0.01)
    np.testing.assert_array_equal(gyr, rec.gyr_rad_s)
    assert not imu.looks_like_deg_s(rec.gyr_rad_s, rec.acc_m_s2, 0.01)
    with pytest.raises(InputError, match="unknown gyro unit"):
        imu.check_units(rec.gyr_rad_s, rec.acc_m_s2, gyr_units="rpm")


def test_bad_csv_gives_one_line_errors(tmp_path):
    p = tmp_path / "bad.csv"
    p.write_text("t,gyr_x,gyr_y,acc_x,acc_y,acc_z\n0,0,0,0,0,9.81\n")
    with pytest.raises(InputError, match="missing column"):
        imu.read_imu_csv(p)
    p.write_text("t,gyr_x,gyr_y,gyr_z,acc_x,acc_y,acc_z\n0,0,0,0,0,0,9.81\n0,0,0,0,0,0,9.81\n")
    with pytest.raises(InputError, match="repeats in most rows"):
        imu.read_imu_csv(p)
    p.write_text("t,gyr_x,gyr_y,gyr_z,acc_x,acc_y,acc_z\n1,0,0,0,0,0,9.81\n0,0,0,0,0,0,9.81\n")
    with pytest.raises(InputError, match="must not decrease"):
        imu.read_imu_csv(p)
    with pytest.raises(InputError, match="no such file"):
        imu.read_imu_csv(tmp_path / "nope.csv")


def test_estimate_cli_round_trips_through_io(tmp_path, capsys, swinging_imu):
    rec = swinging_imu()
    rec.acc_m_s2[100:110] = np.nan
    src = imu.write_imu_csv(tmp_path / "rec.csv", rec)
    out_csv = tmp_path / "est.csv"
    png = tmp_path / "est.png"
    assert cli.main(["estimate", str(src), "--out", str(out_csv), "--plot", str(png),
                     "--sigma"]) == 0
    assert "tilt σ outside re-acquisitions: median" in capsys.readouterr().out
    table = imu.read_estimate_csv(out_csv)
    ref = tilt.estimate(rec.gyr_rad_s, rec.acc_m_s2, rec.t_s)
    np.testing.assert_allclose(table.tilt_sigma_rad, ref.sigma_rad, rtol=1e-15)
    np.testing.assert_allclose(table.t_s, rec.t_s, rtol=1e-15)
    np.testing.assert_allclose(table.roll_rad, ref.roll_rad, atol=1e-12)
    np.testing.assert_allclose(table.pitch_rad, ref.pitch_rad, atol=1e-12)
    np.testing.assert_allclose(table.gravity_S, -ref.up_S, atol=1e-12)
    np.testing.assert_allclose(table.bias_S_rad_s, ref.bias_S_rad_s, atol=1e-15)
    np.testing.assert_array_equal(table.flags, ref.flags)
    assert np.all(table.flags[100:110] & tilt.ACC_MISSING)
    np.testing.assert_allclose(np.linalg.norm(table.gravity_S, axis=1), 1.0, atol=1e-12)
    assert png.stat().st_size > 10_000
    # unit mistake: one line on stderr, exit status 2, unless --units says so
    g_csv = imu.write_imu_csv(tmp_path / "g.csv", rec._replace(acc_m_s2=rec.acc_m_s2 / G))
    assert cli.main(["estimate", str(g_csv), "--out", str(tmp_path / "x.csv")]) == 2
    err = capsys.readouterr().err
    assert "looks like g" in err and len(err.strip().splitlines()) == 1
    assert cli.main(["estimate", str(g_csv), "--out", str(tmp_path / "x.csv"), "--units", "g"]) == 0
    x = imu.read_estimate_csv(tmp_path / "x.csv")
    np.testing.assert_allclose(x.roll_rad, ref.roll_rad, atol=1e-9)
    assert x.tilt_sigma_rad is None  # the contract's columns unless --sigma asks for σ
    assert (tmp_path / "x.csv").read_text().splitlines()[0] == ",".join(imu.ESTIMATE_COLUMNS)
    # one row has no time step: refused
    one = tmp_path / "one.csv"
    one.write_text(src.read_text().splitlines()[0] + "\n" + src.read_text().splitlines()[1] + "\n")
    assert cli.main(["estimate", str(one), "--out", str(tmp_path / "y.csv")]) == 2
    assert "one data row; the filter needs at least two" in capsys.readouterr().err
    # a peer reports no uncertainty: --sigma is refused before anything runs
    capsys.readouterr()
    assert cli.main(["estimate", str(src), "--out", str(tmp_path / "y.csv"), "--filter", "vqf",
                     "--sigma"]) == 2
    assert "reports no uncertainty" in capsys.readouterr().err
    assert not (tmp_path / "y.csv").exists()


def test_estimate_plot_has_one_labelled_row_per_flag_that_occurs():
    import matplotlib.pyplot as plt

    from verticality import tilt
    from verticality.tilt.plots import plot_flags

    t = np.arange(100) * 0.01
    flags = np.zeros(100, dtype=np.int32)
    flags[40] |= tilt.DT_GAP
    flags[40:50] |= tilt.REACQUIRING
    fig, ax = plt.subplots()
    plot_flags(ax, t, flags)
    labels = [lab.get_text() for lab in ax.get_yticklabels()]
    assert labels == ["gap in the time stamps (32): 1", "re-acquiring (128): 10"]
    gap_bar, reacq_bar = ax.collections  # per row, one bar per run of flagged samples
    np.testing.assert_allclose(np.asarray(gap_bar.get_segments()), [[[t[40], 0], [t[40], 0]]])
    np.testing.assert_allclose(np.asarray(reacq_bar.get_segments()), [[[t[40], 1], [t[49], 1]]])
    plot_flags(ax2 := fig.add_subplot(2, 1, 2), t, np.zeros(100, dtype=np.int32))
    assert ax2.get_title() == "flags: none"
    plt.close(fig)


@pytest.mark.parametrize("body,fast", [
    ("0,0.1,0.2,0.3,0,0,9.81\n0.01,0.1,0.2,0.3,0,0,9.81\n", True),  # seconds from "0"
    ("1403715273262142976,1,2,3,4,5,6\n1403715273267142912,1,2,3,4,5,6\n", True),  # ns, exact
    ("0,1,2,3,4,5,6 # note\n1,nan,2,3,4,5,6\n", True),  # inline comment, a nan cell
    ("0,1,,3,4,5,6\n1,1,2,3,4,5,6\n", False),  # empty cell: NaN, by the general parser
    ("0,1,x,3,4,5,6\n1,1,2,3,4,5,6\n", False),  # text in a data cell: NaN, as before
    ("5.0,1,2,3,4,5,6\n6,1,2,3,4,5,6\n", False),  # integer-valued but not all integers: float
    ("99999999999999999999,1,2,3,4,5,6\n", False),  # beyond int64: refused by the general one
])
def test_fast_csv_parser_agrees_with_the_general_one(body, fast):
    """read_imu_csv parses clean files with NumPy's C parser and everything else with the general
    parser; where the fast one answers, both give the same values and time type (ns stamps stay
    int64, exact)."""
    from verticality.io import imu_layout, imu_rows

    rows = body.splitlines()
    lay = imu_layout.locate(",".join(imu.IMU_COLUMNS))
    got = imu_rows.parse_clean_rows(rows, lay)
    assert (got is not None) == fast
    try:
        ref = imu_rows.parse_rows(rows, list(range(2, len(rows) + 2)), lay, "f.csv")
    except InputError as exc:
        assert not fast and "beyond int64" in str(exc)
        return
    if got is not None:
        np.testing.assert_array_equal(got[0], ref[0])
        assert got[1].dtype == ref[1].dtype
        np.testing.assert_array_equal(got[1], ref[1])


def _still_imu(n=1000, dt_s=0.01, bias_deg_s=(0.4, -0.3, 0.5), seed=0):
    """A sensor lying still (tilted 20° about x), its gyro logged in deg/s with a turn-on bias."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * dt_s
    up = np.array([0.0, np.sin(np.radians(20.0)), np.cos(np.radians(20.0))])
    acc = 9.81 * up + rng.normal(0, 0.02, (n, 3))
    gyr_deg_s = np.asarray(bias_deg_s) + rng.normal(0, 0.05, (n, 3))
    return imu.ImuRecording(t, gyr_deg_s, acc)


def test_a_still_gyro_in_deg_s_is_caught_by_its_rest_rate(tmp_path):
    """At rest a gyro reads its bias: a still recording in deg/s read as rad/s shows a rest rate
    of ~0.7 rad/s, beyond any turn-on offset, and is refused naming both overrides; stated as
    deg/s it reads, and stated as rad/s it is taken as written."""
    path = imu.write_imu_csv(tmp_path / "still.csv", _still_imu())
    with pytest.raises(InputError, match=r"gyro reads 0.7\d* rad/s.*--units deg/s.*--units rad/s"):
        imu.read_imu_csv(path)
    rec = imu.read_imu_csv(path, gyr_units="deg/s")
    assert imu.rest_rate_rad_s(rec.gyr_rad_s, rec.acc_m_s2, rec.dt_s) < 0.02
    assert imu.read_imu_csv(path, gyr_units="rad/s").gyr_rad_s[0, 0] == pytest.approx(
        _still_imu().gyr_rad_s[0, 0])
    # a real rad/s gyro with a large (0.3 rad/s) turn-on bias is no deg/s gyro
    big_bias = _still_imu(bias_deg_s=(0.3, -0.1, 0.0))
    imu.read_imu_csv(imu.write_imu_csv(tmp_path / "b.csv", big_bias))


def test_a_fast_spin_message_names_the_rad_s_override(tmp_path):
    rec = _still_imu()
    rec.gyr_rad_s[:, 2] = 40.0  # 40 rad/s about the vertical: deg/s, or a real spin
    path = imu.write_imu_csv(tmp_path / "spin.csv", rec)
    with pytest.raises(InputError, match="--units deg/s.*--units rad/s"):
        imu.read_imu_csv(path)
    assert imu.read_imu_csv(path, gyr_units="rad/s").gyr_rad_s[0, 2] == 40.0


def test_milliseconds_at_a_high_rate_are_not_read_as_seconds(tmp_path, swinging_imu):
    """Stamps in ms at 2 kHz (0.5 ms steps) read as seconds would be a 2 Hz recording whose every
    step is a gap; ms at 20 kHz (0.05 steps) would pass the rate check, but the gyro turns the
    accelerometer 1000x too far: both are refused naming --time-unit ms and --time-unit s; stated,
    they read. ms since 1970 read as seconds are refused by their size."""
    rec = swinging_imu(n=3000, dt_s=0.0005, seed=1)
    ms = imu.ImuRecording(rec.t_s * 1e3, rec.gyr_rad_s, rec.acc_m_s2)
    path = imu.write_imu_csv(tmp_path / "ms.csv", ms)
    with pytest.raises(InputError, match="below 10 Hz.*--time-unit ms.*--time-unit s"):
        imu.read_imu_csv(path)
    back = imu.read_imu_csv(path, time_unit="ms")
    np.testing.assert_allclose(np.diff(back.t_s), 0.0005, rtol=1e-9)
    rec = swinging_imu(n=30000, dt_s=0.00005, seed=2)
    fast = imu.ImuRecording(rec.t_s * 1e3, rec.gyr_rad_s, rec.acc_m_s2)
    path = imu.write_imu_csv(tmp_path / "fast.csv", fast)
    with pytest.raises(InputError, match="time steps were ms.*--time-unit ms.*--time-unit s"):
        imu.read_imu_csv(path)
    imu.read_imu_csv(path, time_unit="ms")
    epoch = imu.ImuRecording(rec.t_s[:300] * 1e3 + 1.7e12, rec.gyr_rad_s[:300],
                             rec.acc_m_s2[:300])
    with pytest.raises(InputError, match="after the year 5000.*--time-unit"):
        imu.read_imu_csv(imu.write_imu_csv(tmp_path / "epoch.csv", epoch))
    # the ordinary recordings are not touched by these checks
    imu.read_imu_csv(imu.write_imu_csv(tmp_path / "ok.csv", swinging_imu(n=3000, dt_s=0.01)))


def test_a_ragged_row_is_named_by_its_line(tmp_path):
    path = tmp_path / "rag.csv"
    path.write_text("t,gyr_x,gyr_y,gyr_z,acc_x,acc_y,acc_z\n0,0,0,0,0,0,9.81\n0.01,,0,0,0,0,9.81\n"
                    "0.02,0,0,0,0,9.81\n0.03,0,0,0,0,0,9.81\n")
    with pytest.raises(InputError, match="line 4: 6 values, but the header has 7 columns"):
        imu.read_imu_csv(path)
