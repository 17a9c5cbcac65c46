"""`verticality perceive`: the command on a built-in motion file gives the registered experiment's
output; bad input is one line and exit status 2, as for `otolith`."""

import json

import numpy as np

from verticality import cli
from verticality.experiments import perception as exp
from verticality.io.motion import read_otolith_csv, write_motion_csv
from verticality.perception import paradigms as pp


def test_perceive_on_the_paradigm_file_equals_the_experiment(tmp_path):
    motion = write_motion_csv(tmp_path / "somatogravic.csv", pp.somatogravic(0.2, on_s=30.0))
    result = exp.run_somatogravic(quick=True)
    for model in ("merfeld", "laurens"):
        out = tmp_path / f"{model}.csv"
        assert cli.main(["perceive", str(motion), "--model", model, "--out", str(out)]) == 0
        rows = read_otolith_csv(out)  # any CSV of numbers with a header
        np.testing.assert_allclose(rows["tilt_deg"][::exp.DECIMATE],
                                   result.series[f"{model}/tilt_deg"], rtol=1e-12, atol=1e-12)
        assert rows["pitch_up_deg"][-1] == result.metrics[model]["final_pitch_deg"]


def test_perceive_json_and_plot_on_motion_command_output(tmp_path, capsys):
    motion = tmp_path / "still.csv"
    assert cli.main(["motion", "still", "--out", str(motion), "--rate", "100",
                     "--duration", "2"]) == 0
    capsys.readouterr()
    png = tmp_path / "p.png"
    assert cli.main(["perceive", str(motion), "--model", "laurens", "--otolith", "pendulum",
                     "--plot", str(png), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["rows"] == 201 and summary["max_tilt_error_deg"] < 0.5
    assert png.stat().st_size > 1000


def test_bad_input_is_one_line_and_status_2(tmp_path, capsys):
    bad = tmp_path / "bad.csv"
    bad.write_text("t,qw,qx,qy,qz,wx,wy,wz,ax,ay,az\n0,1,0,0,0,0,0,0,0,0,x\n")
    assert cli.main(["perceive", str(bad)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "column az" in err
    good = write_motion_csv(tmp_path / "m.csv", pp.yaw_step(on_s=1.0, after_s=1.0))
    assert cli.main(["perceive", str(good), "--param", "k_omega=abc"]) == 2
    assert "not a number" in capsys.readouterr().err
    assert cli.main(["perceive", str(good), "--model", "laurens", "--preset", "human"]) == 2
    assert "unknown preset" in capsys.readouterr().err
    assert cli.main(["perceive", str(tmp_path / "missing.csv")]) == 2
