"""`verticality ambiguity` end to end (through cli.main) and its library function."""

import json
import math

import numpy as np

from verticality import cli
from verticality.analysis.ambiguity_replay import upright_reading
from verticality.core import so3
from verticality.io import motion as io
from verticality.models.params import G_M_S2


def _still(R_I_H, a_I=(0.0, 0.0, 0.0), n=201, dt=0.01):
    t = np.arange(n) * dt
    q = np.tile(np.asarray(so3.quat_from_matrix(R_I_H)), (n, 1))
    return io.MotionRecord(t, q, np.zeros((n, 3)), np.tile(np.asarray(a_I, float), (n, 1)))


def test_still_upright_head_reads_its_acceleration_exactly():
    for a in ((0.0, 0.0, 0.0), (2.0, -1.0, 0.5)):
        r = upright_reading(_still(np.eye(3), a))
        np.testing.assert_allclose(r.a_indicated_H_m_s2, r.a_true_H_m_s2, atol=1e-9)
        assert max(r.summary["rms_error_m_s2"].values()) < 1e-9


def test_still_tilted_head_reads_g_tan_tilt_in_the_tilt_plane():
    tilt = math.radians(10.0)
    R = np.asarray(so3.exp(np.array([0.0, tilt, 0.0])))  # pitch: tilt about y biases a_x
    r = upright_reading(_still(R))
    theta_y = math.radians(r.tilt_deg[0, 1])
    assert abs(abs(theta_y) - tilt) < 1e-12
    np.testing.assert_allclose(np.abs(r.error_H_m_s2[:, 0]), G_M_S2 * math.tan(tilt), rtol=1e-9)
    np.testing.assert_allclose(r.error_H_m_s2[:, 1], 0.0, atol=1e-9)
    assert r.summary["still_head_error_at_max_tilt_m_s2"]["x"] == G_M_S2 * math.tan(
        math.radians(r.summary["max_abs_tilt_deg"]["y"]))


def test_command_writes_csv_plot_and_json(tmp_path, capsys):
    motion = tmp_path / "motion.csv"
    assert cli.main(["motion", "walking", "--out", str(motion), "--duration", "2",
                     "--rate", "200"]) == 0
    out, fig = tmp_path / "amb.csv", tmp_path / "amb.png"
    capsys.readouterr()
    assert cli.main(["ambiguity", str(motion), "--out", str(out), "--plot", str(fig),
                     "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    o = io.read_otolith_csv(out)
    assert list(o)[:8] == ["t", "ax_true", "ay_true", "az_true", "ax_upright", "ay_upright",
                           "ax_error", "ay_error"]
    np.testing.assert_allclose(o["ax_error"], o["ax_upright"] - o["ax_true"], atol=1e-12)
    rms = math.sqrt(np.mean(o["ax_error"] ** 2))
    assert abs(rms - summary["rms_error_m_s2"]["x"]) < 1e-12
    assert 0.0 < rms < summary["rms_true_acceleration_m_s2"]["x"]  # it bites, but reads most
    assert fig.stat().st_size > 1000
    # the P13 pendulum (slow, lightly damped) reads the same walk far worse
    assert cli.main(["ambiguity", str(motion), "--json", "--otolith", "p13"]) == 0
    p13 = json.loads(capsys.readouterr().out)
    assert p13["rms_error_m_s2"]["x"] > 3 * summary["rms_error_m_s2"]["x"]
    # refusals: one line, exit status 2
    assert cli.main(["ambiguity", str(tmp_path / "missing.csv")]) == 2
    err = capsys.readouterr().err.strip()
    assert err and "\n" not in err
