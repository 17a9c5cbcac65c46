"""BROAD reader, the official inclination metric, and `verticality evaluate broad` on a slice."""

import json

import h5py
import numpy as np
import pytest

from broad_slices import FAST_TRANSLATION, SLOW_ROTATION
from verticality import cli, tilt
from verticality.core import so3
from verticality.core.errors import InputError
from verticality.io import broad
from verticality.tilt.evaluation.broad import evaluate_trials


def _q(axis, deg):
    return np.asarray(so3.quat_exp(np.radians(deg) * np.asarray(axis, dtype=float)))


def test_inclination_error_hand_computed():
    ident = np.array([1.0, 0, 0, 0])
    # pure tilt of 10° about x: e = q_est, w = cos 5°, z = 0 -> 2 acos(cos 5°) = 10°
    assert broad.inclination_error_deg(_q([1, 0, 0], 10.0), ident) == pytest.approx(10.0, abs=1e-9)
    # pure heading error does not count
    assert broad.inclination_error_deg(_q([0, 0, 1], 70.0), ident) == pytest.approx(0.0, abs=1e-6)
    # heading 40° after a 10° tilt about y, against the same tilt: e = q_z(40): 0°
    q_ref = _q([0, 1, 0], 10.0)
    q_est = np.asarray(so3.quat_multiply(_q([0, 0, 1], 40.0), q_ref))
    assert broad.inclination_error_deg(q_est, q_ref) == pytest.approx(0.0, abs=1e-6)
    # e = q_z(30) ⊗ q_x(6): sqrt(w² + z²) = cos 3° -> 6°
    q_est = np.asarray(so3.quat_multiply(so3.quat_multiply(_q([0, 0, 1], 30.0), _q([1, 0, 0], 6.0)),
                                         q_ref))
    assert broad.inclination_error_deg(q_est, q_ref) == pytest.approx(6.0, abs=1e-9)


def _write_trial(path, n=400, rate=100.0, quat_est_err_deg=None):
    rng = np.random.default_rng(0)
    with h5py.File(path, "w") as f:
        f["imu_gyr"] = rng.normal(0, 1e-3, (n, 3))
        f["imu_acc"] = np.tile([0.0, 0.0, 9.81], (n, 1)) + rng.normal(0, 0.02, (n, 3))
        quat = np.tile([1.0, 0, 0, 0], (n, 1))
        quat[5:10] = np.nan
        f["opt_quat"] = quat
        mv = np.zeros(n, bool)
        mv[n // 2:] = True
        f["movement"] = mv
        f.attrs["sampling_rate"] = rate


def test_rmse_uses_movement_and_skips_nan_rows(tmp_path):
    p = tmp_path / "t.hdf5"
    _write_trial(p)
    trial = broad.load_trial(p)
    n = trial.gyr_rad_s.shape[0]
    q_est = np.tile([1.0, 0, 0, 0], (n, 1))
    q_est[n // 2: n // 2 + 100] = _q([1, 0, 0], 4.0)  # 100 of the 200 movement samples 4° off
    q_est[: n // 2] = _q([0, 1, 0], 30.0)  # outside movement: ignored
    assert broad.inclination_rmse_deg(q_est, trial) == pytest.approx(np.sqrt(16 / 2), rel=1e-9)
    trial_nan = trial._replace(quat_E_S_opt=np.where(np.arange(n)[:, None] >= n // 2 + 100,
                                                     np.nan, trial.quat_E_S_opt))
    assert broad.inclination_rmse_deg(q_est, trial_nan) == pytest.approx(4.0, rel=1e-9)


def test_reader_errors(tmp_path):
    with pytest.raises(InputError, match="no such file"):
        broad.load_trial(tmp_path / "missing.hdf5")
    p = tmp_path / "x.hdf5"
    with h5py.File(p, "w") as f:
        f["imu_gyr"] = np.zeros((3, 3))
    with pytest.raises(InputError, match="imu_acc"):
        broad.load_trial(p)
    with pytest.raises(InputError, match="not a directory"):
        broad.list_trials(tmp_path / "missing_dir")
    (tmp_path / "empty").mkdir()
    with pytest.raises(InputError, match="no .hdf5"):
        broad.list_trials(tmp_path / "empty")


def test_broad_slice_ours_accurate_and_evaluate_json(tmp_path, capsys):
    """45 s (rest, then motion) of a BROAD trial: our filter's official inclination RMSE stays
    under 1°, and `evaluate broad --json` reports it in the contract's shape."""
    src = SLOW_ROTATION
    n = 13000
    with h5py.File(src, "r") as f, h5py.File(tmp_path / "slice.hdf5", "w") as g:
        for key in ("imu_gyr", "imu_acc", "opt_quat", "movement"):
            g[key] = f[key][:n]
        g.attrs["sampling_rate"] = f.attrs["sampling_rate"]
    trial = broad.load_trial(tmp_path / "slice.hdf5")
    assert trial.movement.sum() > 2000
    out = tilt.estimate(trial.gyr_rad_s, trial.acc_m_s2, period_s=trial.dt_s)
    rmse = broad.inclination_rmse_deg(out.quat_E_S, trial)
    assert rmse < 1.0
    assert cli.main(["evaluate", "broad", str(tmp_path), "--json", "--filters", "verticality"]) == 0
    res = json.loads(capsys.readouterr().out)
    assert set(res) == {"trials", "mean", "sigma"}
    assert res["trials"]["slice"]["verticality"] == pytest.approx(rmse, rel=1e-9)
    assert res["mean"]["verticality"] == pytest.approx(rmse, rel=1e-9)
    # VQF on the same slice in the same run: ours within 1.25× of it (measured 1.01×, 0.245°
    # against 0.242°)
    both = evaluate_trials([tmp_path / "slice.hdf5"], ["verticality", "vqf"])["trials"]["slice"]
    assert both["verticality"] == pytest.approx(rmse, rel=1e-9)
    assert both["verticality"] < 1.25 * both["vqf"]
    # the reported σ against the same errors: it covers them, conservatively in motion (the RMS
    # σ is 3.5× the RMSE on this slice: 0.85° against 0.245°), and the table and the JSON show it
    cal = evaluate_trials([tmp_path / "slice.hdf5"], ["verticality"])["sigma"]["slice"]
    assert res["sigma"] == {"verticality": {"slice": cal}}
    assert cal["within_1sigma"] > 0.9 and cal["within_2sigma"] > 0.99
    assert rmse < cal["rms_sigma_deg"] < 5 * rmse
    assert cli.main(["evaluate", "broad", str(tmp_path), "--filters", "verticality"]) == 0
    assert "within σ / 2σ" in capsys.readouterr().out
    # the smoother beside the filter in the same run: its own σ calibration, and better here
    res = evaluate_trials([tmp_path / "slice.hdf5"], ["verticality", "verticality-offline"])
    smooth = tilt.smooth(trial.gyr_rad_s, trial.acc_m_s2, period_s=trial.dt_s)
    assert res["trials"]["slice"]["verticality-offline"] == pytest.approx(
        broad.inclination_rmse_deg(smooth.quat_E_S, trial), rel=1e-12)
    assert res["trials"]["slice"]["verticality-offline"] < rmse
    assert res["sigma_offline"]["slice"]["within_2sigma"] > 0.95


def test_sigma_calibration_counts_errors_within_sigma(tmp_path):
    """The fractions within σ and 2σ over the scored samples (movement, valid reference), on a
    hand-made case: 100 movement samples 1° off with σ 0.8°, 100 with σ 2°."""
    from verticality.tilt.evaluation.broad import sigma_calibration

    p = tmp_path / "t.hdf5"
    _write_trial(p)
    trial = broad.load_trial(p)
    n = trial.gyr_rad_s.shape[0]
    mov = np.flatnonzero(trial.movement)
    assert mov.size == 200
    q_est = np.tile([1.0, 0, 0, 0], (n, 1))
    q_est[mov] = _q([1, 0, 0], 1.0)
    sigma = np.full(n, np.radians(0.1))  # outside movement: ignored
    sigma[mov[:100]] = np.radians(0.8)
    sigma[mov[100:]] = np.radians(2.0)
    cal = sigma_calibration(q_est, sigma, trial)
    assert cal["within_1sigma"] == pytest.approx(0.5)
    assert cal["within_2sigma"] == pytest.approx(1.0)
    assert cal["rms_sigma_deg"] == pytest.approx(np.sqrt((0.8**2 + 2.0**2) / 2), rel=1e-12)


def test_motion_from_a_broad_trial_window(tmp_path, capsys):
    """`verticality motion TRIAL.hdf5`: q from the optical reference, ω the gyro, a_I the specific
    force rotated into I with gravity removed (≈ 0 while the IMU lies still); a window holding an
    optical dropout is refused, naming the longest clean stretch."""
    path = FAST_TRANSLATION
    out = tmp_path / "m.csv"
    assert cli.main(["motion", str(path), "--start", "38", "--duration", "4",
                     "--out", str(out)]) == 0
    from verticality.io.motion import read_motion_csv

    rec = read_motion_csv(out)
    trial = broad.load_trial(path)
    i0 = int(np.searchsorted(trial.t_s, 38.0 - 1e-9))
    assert rec.t_s[0] == pytest.approx(38.0, abs=1.0 / trial.sampling_rate_hz)
    assert rec.t_s.size == pytest.approx(4.0 * trial.sampling_rate_hz, abs=1.5)
    np.testing.assert_allclose(rec.omega_H_rad_s, trial.gyr_rad_s[i0:i0 + rec.t_s.size], atol=1e-15)
    # still before the movement starts at 40.5 s: the accelerometer's bias is all that is left
    still = rec.t_s < 40.0
    assert np.all(np.linalg.norm(rec.a_I_m_s2[still], axis=1) < 0.5)
    # the accelerometer reads the specific force: R a_I-with-gravity gives back imu_acc
    R = np.asarray(so3.matrix_from_quat(rec.q_I_H_wxyz))
    f_B = np.einsum("nji,nj->ni", R, rec.a_I_m_s2 + np.array([0.0, 0.0, 9.81]))
    np.testing.assert_allclose(f_B, trial.acc_m_s2[i0:i0 + rec.t_s.size], atol=1e-2)
    capsys.readouterr()
    assert cli.main(["motion", str(path), "--start", "80", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert "t = 84.200 s" in err and "longest stretch with one is 0.000–84.196 s" in err
    assert cli.main(["motion", str(path), "--rate", "100", "--out", str(out)]) == 2
    assert "keeps its own sampling rate" in capsys.readouterr().err
