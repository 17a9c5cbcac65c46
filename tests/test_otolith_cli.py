"""`verticality motion` and `verticality otolith` end to end (through cli.main)."""

import math

import numpy as np

from verticality import cli
from verticality.core import so3
from verticality.io import motion as io
from verticality.models.params import G_M_S2


def test_recorded_impact_medial_lateral_and_refusals(tmp_path, capsys):
    motion = tmp_path / "motion.csv"
    assert cli.main(["motion", "impact", "--out", str(motion), "--duration", "6",
                     "--rate", "250"]) == 0
    rec = io.read_motion_csv(motion)
    assert rec.t_s.size == 1501
    out = tmp_path / "out.csv"
    assert cli.main(["otolith", str(motion), "--out", str(out)]) == 0
    o = io.read_otolith_csv(out)
    assert list(o) == ["t", "sx", "sy", "sz", "phi_x", "phi_y"]
    np.testing.assert_array_equal(o["t"], rec.t_s)
    s = np.column_stack([o["sx"], o["sy"], o["sz"]])
    np.testing.assert_allclose(np.linalg.norm(s, axis=1), 1.0, atol=1e-12)
    assert np.max(np.abs(o["phi_x"]) + np.abs(o["phi_y"])) > 0.5  # the spike swings it
    # lateral with r = 0 is the medial model (model-checks: 1e-12)
    lat = tmp_path / "lat.csv"
    assert cli.main(["otolith", str(motion), "--out", str(lat), "--model", "lateral",
                     "--param", "r=0"]) == 0
    o2 = io.read_otolith_csv(lat)
    for side in ("_left", "_right"):
        np.testing.assert_allclose(o2["phi_x" + side], o["phi_x"], atol=1e-12)
        np.testing.assert_allclose(o2["sy" + side], o["sy"], atol=1e-12)
    # refusals: one line, exit status 2
    capsys.readouterr()
    bad = tmp_path / "bad.csv"
    bad.write_text(motion.read_text().replace("\n0.008,", "\n0.004,", 1))
    assert cli.main(["otolith", str(bad), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert "row 3 (line 4), column t" in err and "\n" not in err
    assert cli.main(["otolith", str(motion), "--out", str(out), "--param", "Jxx=-1"]) == 2
    assert cli.main(["otolith", str(motion), "--out", str(out), "--param", "mass=1"]) == 2


def test_still_tilted_head_and_constant_acceleration(tmp_path):
    """A still head tilted by θ reads φ = −θ (docs/conventions.md); a constant horizontal
    acceleration a deflects the pendulum by atan(a/g) — both exactly, from the rest start."""
    theta, accel = 0.3, 2.0
    n = 401
    t = np.arange(n) * 0.005
    q = np.tile(np.asarray(so3.quat_from_matrix(so3.rot_x(theta))), (n, 1))
    a = np.tile([0.0, accel, 0.0], (n, 1))
    motion = io.write_motion_csv(tmp_path / "m.csv", io.MotionRecord(t, q, np.zeros((n, 3)), a))
    out = tmp_path / "o.csv"
    assert cli.main(["otolith", str(motion), "--out", str(out), "--param", "beta=0.002",
                     "--param", "l=0.05"]) == 0
    o = io.read_otolith_csv(out)
    # the gravito-inertial up (−(g − a)) in I, then in the head frame
    up_I = np.array([0.0, accel, G_M_S2])
    expected = -theta - math.atan2(accel, G_M_S2)  # GIF up leans to +y, the head to −y
    np.testing.assert_allclose(o["phi_x"], expected, atol=1e-9)
    np.testing.assert_allclose(o["phi_y"], 0.0, atol=1e-12)
    s_I = -up_I / np.linalg.norm(up_I)
    s_H = np.asarray(so3.rot_x(theta)).T @ s_I
    np.testing.assert_allclose(np.column_stack([o["sx"], o["sy"], o["sz"]])[-1], s_H, atol=1e-9)


def test_motion_window_of_a_built_in_and_its_refusals(tmp_path, capsys):
    out = tmp_path / "m.csv"
    assert cli.main(["motion", "impact", "--start", "4.5", "--duration", "1", "--rate", "100",
                     "--out", str(out)]) == 0
    rec = io.read_motion_csv(out)
    np.testing.assert_allclose(rec.t_s, 4.5 + np.arange(101) / 100.0, atol=1e-12)
    assert np.max(np.abs(rec.a_I_m_s2)) > 20.0  # the 30 m/s² impact at 5 s is inside
    capsys.readouterr()
    for argv, message in ((["nothing"], "neither a built-in trajectory"),
                          (["impact", "--start", "20"], "--start 20 is at or after the end"),
                          (["impact", "--start", "-1"], "--start must be a non-negative number"),
                          (["impact", "--rate", "0"], "--rate must be a positive number")):
        assert cli.main(["motion", *argv, "--out", str(out)]) == 2
        err = capsys.readouterr().err.strip()
        assert message in err and "\n" not in err


def test_otolith_presets_and_their_checks():
    """otolith_presets.otolith_pendula: the P13 plant, J from the final m and l unless given, the
    lateral pivots at ±r, and one-line refusals of the values; the command line's NAME=VALUE
    strings are read (and refused) in cli.name_values."""
    import pytest

    from verticality.cli.name_values import parse_name_values
    from verticality.core.errors import InputError
    from verticality.models.otolith_presets import OTOLITH_PARAM_NAMES, otolith_pendula
    from verticality.models.params import P13_PENDULUM

    (med,), sfx = otolith_pendula("medial")
    assert sfx == ("",)
    np.testing.assert_allclose(med.params.J_pivot_S, P13_PENDULUM.J_pivot_S, rtol=1e-15)
    np.testing.assert_array_equal(med.params.pivot_H_m, np.zeros(3))
    values = parse_name_values(["l=0.05", "r=0.04", "Jzz=1e-5", "beta=0"], OTOLITH_PARAM_NAMES)
    assert values == {"l": 0.05, "r": 0.04, "Jzz": 1e-5, "beta": 0.0}
    (left, right), sfx = otolith_pendula("lateral", values)
    assert sfx == ("_left", "_right")
    np.testing.assert_allclose(left.params.J_pivot_S, [0.05 * 0.05**2, 0.05 * 0.05**2, 1e-5])
    np.testing.assert_array_equal(left.params.pivot_H_m, [0.0, 0.04, 0.0])
    np.testing.assert_array_equal(right.params.pivot_H_m, [0.0, -0.04, 0.0])
    assert float(right.params.beta_Nms) == 0.0
    for items, message in ((["m"], "expected NAME=VALUE"), (["mass=1"], "unknown name"),
                           (["l=x"], "not a number"), (["l=inf"], "not finite"),
                           (["l=nan"], "NaN is not a value")):
        with pytest.raises(InputError, match=message):
            parse_name_values(items, OTOLITH_PARAM_NAMES)
    for values, model, message in (({"Jxx": -1.0}, "medial", "must be positive"),
                                   ({"beta": -1.0}, "medial", "must not be negative"),
                                   ({"r": 0.1}, "medial", "lateral model only"),
                                   ({"mass": 1.0}, "medial", "unknown name"),
                                   ({"l": float("inf")}, "medial", "not finite"),
                                   ({}, "planar", "model must be one of")):
        with pytest.raises(InputError, match=message):
            otolith_pendula(model, values)


def test_stiff_or_absurd_physics_is_integrated_or_refused_never_nan(tmp_path, capsys):
    """A short arm (a stiff spin about it) is integrated with steps from the model's fastest time
    constant, finite on every row; a damping too large to integrate, a time stamp that jumps by
    10⁶ s and one absurd acceleration are refused in one line (exit 2), no file written."""
    import numpy as np

    from verticality.io.motion import read_otolith_csv

    m = tmp_path / "m.csv"
    assert cli.main(["motion", "impact", "--duration", "2", "--out", str(m)]) == 0
    out = tmp_path / "o.csv"
    assert cli.main(["otolith", str(m), "--out", str(out), "--param", "l=0.001"]) == 0
    cols = read_otolith_csv(out)
    assert all(np.all(np.isfinite(v)) for v in cols.values())
    out.unlink()
    lines = m.read_text().splitlines()
    jump = lines[:50] + [",".join([repr(float(r.split(",")[0]) + 1e6)] + r.split(",")[1:])
                         for r in lines[50:]]
    (tmp_path / "jump.csv").write_text("\n".join(jump) + "\n")
    cells = lines[100].split(",")
    cells[8] = "1e200"
    (tmp_path / "huge.csv").write_text("\n".join(lines[:100] + [",".join(cells)] + lines[101:])
                                       + "\n")
    for argv, words in ((["--param", "beta=1000"], "too stiff"), ([], "GiB")):
        src = m if argv else tmp_path / "jump.csv"
        capsys.readouterr()
        assert cli.main(["otolith", str(src), "--out", str(out), *argv]) == 2
        err = capsys.readouterr().err.strip()
        assert words in err and len(err.splitlines()) == 1 and not out.exists()
    assert cli.main(["otolith", str(tmp_path / "huge.csv"), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert "became non-finite at row 100" in err and not out.exists()
    assert cli.main(["stabilize", str(tmp_path / "jump.csv")]) == 2
    assert "plant steps" in capsys.readouterr().err
    assert cli.main(["motion", "impact", "--rate", "1e9", "--out", str(out)]) == 2
    assert "lower --rate or --duration" in capsys.readouterr().err and not out.exists()


def test_a_byte_order_mark_is_read_by_every_reader(tmp_path, capsys):
    m = tmp_path / "m.csv"
    assert cli.main(["motion", "still", "--duration", "0.5", "--out", str(m)]) == 0
    bom = tmp_path / "bom.csv"
    bom.write_text(m.read_text(), encoding="utf-8-sig")
    assert cli.main(["otolith", str(bom), "--out", str(tmp_path / "o.csv")]) == 0
    assert (tmp_path / "o.csv").read_text() != ""
