"""A recorded trunk motion as a trajectory, and `verticality stabilize` end to end."""

import json

import jax
import numpy as np
import pytest

from verticality import cli
from verticality.core.errors import InputError
from verticality.io import motion as io
from verticality.simulation import ekf_runs, trajectories
from verticality.simulation.recorded import from_record, rate_mismatch, record_of, rpy_rates


def _record(traj, rate_hz):
    return record_of(traj, np.arange(int(round(traj.duration_s * rate_hz)) + 1) / rate_hz)


def test_rpy_rates_invert_the_body_rate_map():
    rng = np.random.default_rng(0)
    rpy = rng.uniform([-3.0, -1.4, -3.0], [3.0, 1.4, 3.0], size=(50, 3))
    rates = rng.normal(size=(50, 3))
    omega = np.asarray(jax.vmap(trajectories.omega_from_rpy_rates)(rpy, rates))
    np.testing.assert_allclose(rpy_rates(rpy, omega), rates, atol=1e-10)


@pytest.mark.parametrize("rate_hz, tol_a, tol_wdot", [(1000.0, 0.01, 1e-3), (200.0, 0.2, 5e-3)])
def test_recorded_jump_matches_the_analytic_one(rate_hz, tol_a, tol_wdot):
    """Between samples the interpolant stays close to the motion it was sampled from, and at the
    samples it is the file's (R, ω, a) exactly."""
    traj = ekf_runs.scenario_trajectory("jump", quick=True)
    rec = _record(traj, rate_hz)
    rt = from_record(*rec)
    t = np.linspace(0.0, traj.duration_s, 4001)[1:-1] + 1e-4  # between the samples
    a, b = trajectories.sample(traj, t), trajectories.sample(rt, t)
    np.testing.assert_allclose(b.R_I_B, a.R_I_B, atol=1e-8)
    np.testing.assert_allclose(b.omega_B_rad_s, a.omega_B_rad_s, atol=1e-5)
    np.testing.assert_allclose(b.omegadot_B_rad_s2, a.omegadot_B_rad_s2, atol=tol_wdot * 6.0)
    np.testing.assert_allclose(b.a_I_m_s2, a.a_I_m_s2, atol=tol_a * 30.0)
    at = trajectories.sample(rt, rec.t_s[::7] - rec.t_s[0])
    np.testing.assert_allclose(at.a_I_m_s2, rec.a_I_m_s2[::7], atol=1e-9)
    np.testing.assert_allclose(at.omega_B_rad_s, rec.omega_H_rad_s[::7], atol=1e-9)


def test_recorded_motion_wraps_yaw_and_refuses_what_it_cannot_interpolate():
    # a trunk spinning about the vertical: yaw crosses ±π without a jump in the interpolant
    t = np.linspace(0.0, 4.0, 401)
    yaw = 2.0 * t
    q = np.stack([np.cos(yaw / 2), 0 * t, 0 * t, np.sin(yaw / 2)], axis=1)
    w = np.tile([0.0, 0.0, 2.0], (t.size, 1))
    rt = from_record(t + 10.0, q, w, np.zeros((t.size, 3)))  # starts at 10 s: shifted to 0
    assert rt.events["t0_s"] == 10.0 and rt.duration_s == pytest.approx(4.0)
    m = trajectories.sample(rt, np.linspace(0.0, 4.0, 333))
    np.testing.assert_allclose(m.omega_B_rad_s[:, 2], 2.0, atol=1e-9)
    with pytest.raises(InputError, match="at least two rows"):
        from_record(t[:1], q[:1], w[:1], np.zeros((1, 3)))
    pitch = np.radians(88.0)
    q_up = np.tile([np.cos(pitch / 2), 0.0, np.sin(pitch / 2), 0.0], (t.size, 1))
    with pytest.raises(InputError, match="pitches to 88.0°"):
        from_record(t, q_up, 0 * w, np.zeros((t.size, 3)))


def test_stabilize_on_a_recorded_jump_reproduces_ekf_jump(quick_sweeps, tmp_path, capsys):
    """The quick ekf-jump trunk, written to MOTION.csv at 1 kHz and replayed by the command, gives
    the experiment's errors (same plant, filter and seed; only the trunk is interpolated)."""
    traj = ekf_runs.scenario_trajectory("jump", quick=True)
    motion = io.write_motion_csv(tmp_path / "jump.csv", _record(traj, 1000.0))
    out, png = tmp_path / "tilt.csv", tmp_path / "tilt.png"
    capsys.readouterr()
    assert cli.main(["stabilize", str(motion), "--json", "--out", str(out),
                     "--plot", str(png)]) == 0
    report = json.loads(capsys.readouterr().out)
    ref = quick_sweeps[0]["fixed_head_rate_sigma"]["jump"]["sigma_0.001"]  # the ekf-jump setting
    for cond in ("fixed", "stabilized"):
        assert report["rms_tilt_error_deg"][cond] == pytest.approx(ref[f"{cond}_rms_deg"], rel=0.02)
        assert report["max_tilt_error_deg"][cond] == pytest.approx(ref[f"{cond}_max_deg"], rel=0.03)
    assert report["rms_ratio_stabilized_over_fixed"] == pytest.approx(ref["rms_ratio"], rel=0.03)
    assert report["filter_model"] == "p13-mismatched" and report["rejected_updates"]["fixed"] == 0
    cols = io.read_otolith_csv(out)  # a plain numeric CSV reader
    assert list(cols)[:6] == ["t"] + [f"fixed_{q}" for q in io.TILT_QUANTITIES]
    np.testing.assert_allclose(cols["t"], 0.02 * np.arange(1, 301), atol=1e-9)  # the EKF's samples
    late = cols["t"] >= 2.0
    rms = np.sqrt(np.mean(cols["stabilized_tilt_error_deg"][late] ** 2))
    assert rms == pytest.approx(report["rms_tilt_error_deg"]["stabilized"], rel=1e-9)
    assert png.stat().st_size > 10_000


@pytest.mark.parametrize("extra, message", [
    (["--settle", "10"], "leaves no EKF sample after the 10 s settling time"),
    (["--seeds", "0"], "--seeds must be at least 1"),
    (["--noise", "0"], "--noise must be a positive number"),
])
def test_stabilize_refuses_bad_options_in_one_line(tmp_path, capsys, extra, message):
    motion = io.write_motion_csv(tmp_path / "still.csv",
                                 _record(trajectories.still(duration_s=3.0), 100.0))
    capsys.readouterr()
    assert cli.main(["stabilize", str(motion), *extra]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and "\n" not in err


def test_rate_mismatch_is_zero_for_a_consistent_file_and_large_for_a_wrong_omega():
    rec = _record(ekf_runs.scenario_trajectory("jump", quick=True), 200.0)
    assert rate_mismatch(*rec[:3])[0] < 1e-3
    wrong = rec.omega_H_rad_s.copy()
    wrong[:, [0, 1]] = wrong[:, [1, 0]]  # x and y swapped: another frame's ω
    mismatch, t_at = rate_mismatch(rec.t_s, rec.q_I_H_wxyz, wrong)
    assert mismatch > 0.1 and 2.5 < t_at < 4.5  # during the jump


def test_stabilize_flags_a_diverging_plant_and_an_odd_length_recording(tmp_path, capsys):
    """A file whose ω (60 rad/s oscillation) contradicts its q (still), 6.014 s at 1 kHz: simulated
    to the last whole 20 ms EKF period with a note, the q–ω disagreement warned about, and the
    stabilized plant, which diverges, reported with the time it did, no metric, exit status 1.
    (6 s simulated: the quick ekf-jump's duration, whose compiled closed loops the test above has
    built in this process.)"""
    t = np.arange(7015) / 1000.0  # 7.014 s, of which the window takes the last 6.014 s
    w = np.zeros((t.size, 3))
    w[:, 0] = 60.0 * np.sin(2 * np.pi * 3.0 * t)
    rec = io.MotionRecord(t, np.tile([1.0, 0.0, 0.0, 0.0], (t.size, 1)), w, np.zeros((t.size, 3)))
    motion = io.write_motion_csv(tmp_path / "wild.csv", rec)
    capsys.readouterr()
    assert cli.main(["stabilize", str(motion), "--start", "1", "--duration", "6.014",
                     "--settle", "1", "--json"]) == 1
    out = capsys.readouterr()
    err = " ".join(out.err.split())
    assert "simulating 6 s of the 6.014 s recorded" in err
    assert "the file's ω and q disagree" in err
    assert "stabilized head: the simulated plant became non-finite at t =" in err
    report = json.loads(out.out)  # valid JSON: no NaN
    assert report["duration_s"] == pytest.approx(6.0)
    assert report["rms_tilt_error_deg"]["stabilized"] is None
    assert report["rms_ratio_stabilized_over_fixed"] is None
    assert report["diverged"]["stabilized"][1] == "plant"
    # on the file's clock: the window starts at 1 s
    assert report["diverged"]["stabilized"][0] >= 1.0


def test_motion_window_selects_rows_on_the_file_clock_and_refuses_empty_ones():
    t = 5.0 + np.arange(301) / 100.0  # 3 s from t = 5 s
    rec = io.MotionRecord(t, np.tile([1.0, 0.0, 0.0, 0.0], (t.size, 1)), np.zeros((t.size, 3)),
                          np.arange(t.size * 3, dtype=float).reshape(-1, 3))
    w = io.window(rec, 0.5, 1.0)
    np.testing.assert_allclose(w.t_s[[0, -1]], [5.5, 6.5], atol=1e-12)
    assert w.t_s.size == 101
    np.testing.assert_array_equal(w.a_I_m_s2, rec.a_I_m_s2[50:151])
    assert io.window(rec, 2.0).t_s[-1] == rec.t_s[-1]  # to the end
    for start, duration, message in ((2.5, 1.0, "ends after the recording"),
                                     (-1.0, None, "--start must be a non-negative"),
                                     (0.0, 0.0, "--duration must be a positive"),
                                     (2.999, None, "fewer than two rows")):
        with pytest.raises(InputError, match=message):
            io.window(rec, start, duration)


def test_stabilize_reads_a_broad_recording_window(tmp_path, capsys):
    """A BROAD file is converted as `verticality motion` converts it (same rows), and a window past
    its end is refused in one line before anything is compiled."""
    from broad_slices import FAST_TRANSLATION as path
    from verticality.io import broad

    rec = io.load_motion(path, 38.0, 2.0)
    ref = io.from_broad_trial(broad.load_trial(path), 38.0, 2.0)
    for a, b in zip(rec, ref, strict=True):
        np.testing.assert_array_equal(a, b)
    capsys.readouterr()
    assert cli.main(["stabilize", str(path), "--start", "38", "--duration", "2000"]) == 2
    err = capsys.readouterr().err.strip()
    assert "after the recording" in err and "\n" not in err


def test_whole_periods_and_option_checks():
    from verticality.simulation import stabilization as st

    assert st.whole_periods(2.994) == pytest.approx(2.98)
    assert st.whole_periods(3.0) == pytest.approx(3.0)
    assert st.EKF_PERIOD_S == 0.02
    st.check_options(3.0, 1, 0.02, 2.0)
    for args, message in (((3.0, 0, 0.02, 2.0), "--seeds"),
                          ((3.0, 1, float("nan"), 2.0), "--noise"),
                          ((3.0, 1, 0.02, -1.0), "--settle"),
                          ((2.0, 1, 0.02, 2.0), "no EKF sample")):
        with pytest.raises(InputError, match=message):
            st.check_options(*args)
    series = {"t_s": np.array([0.02, 0.04, 0.06]), "tilt_true_deg": np.zeros((3, 2)),
              "tilt_est_deg": np.array([[0.0, 0.0], [0.0, np.nan], [0.0, 0.0]])}
    assert st.first_non_finite(series, 10.0) == (pytest.approx(10.04), "estimate")
    series["tilt_true_deg"][2, 0] = np.inf
    assert st.first_non_finite(series)[1] == "plant"
