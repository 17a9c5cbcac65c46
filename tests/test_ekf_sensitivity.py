"""ekf-sensitivity: the sweeps behind the ekf-* ratios (quick mode: the jump, two head-rate
noises)."""

import pytest

from verticality.experiments import Result
from verticality.simulation import ekf_ratio_sweeps as sens
from verticality.simulation import ekf_runs


def test_quick_sweep_runs_each_setting_once(quick_sweeps):
    out, simulated_s, labels = quick_sweeps
    rows = out["fixed_head_rate_sigma"]["jump"]
    assert set(rows) == {f"sigma_{s:g}" for s in sens.HEAD_RATE_SIGMAS_QUICK}
    # one stabilized run shared by both rows, one fixed run per σ; one label per group of runs
    assert len(labels) == 2
    assert simulated_s == pytest.approx((1 + len(sens.HEAD_RATE_SIGMAS_QUICK))
                                        * ekf_runs.QUICK_DURATION_S)
    stab = {r["stabilized_rms_deg"] for r in rows.values()}
    assert len(stab) == 1
    for r in rows.values():
        assert r["rms_ratio"] == pytest.approx(r["stabilized_rms_deg"] / r["fixed_rms_deg"])


def test_fixed_head_admitting_unknown_torque_closes_the_gap(quick_sweeps):
    """The finding docs/ekf.md reports: at P13's σ_w the fixed head's filter lags the trunk; told
    its torque is unknown (σ_ωH = 0.03 rad/s per step), it is almost as good as the stabilized
    head."""
    rows = quick_sweeps[0]["fixed_head_rate_sigma"]["jump"]
    p13, loose = rows["sigma_0.001"], rows["sigma_0.03"]
    assert loose["fixed_rms_deg"] < 0.6 * p13["fixed_rms_deg"]
    assert loose["fixed_max_deg"] < 0.5 * p13["fixed_max_deg"]
    assert p13["rms_ratio"] < 0.6
    assert loose["rms_ratio"] > 0.8


def test_figure_from_a_quick_result(quick_sweeps, tmp_path):
    out, simulated_s, _ = quick_sweeps
    from verticality import experiments

    result = Result(metrics=dict(out), simulated_s=simulated_s)
    paths = experiments.get("ekf-sensitivity").figures(result, tmp_path)
    assert [p.name for p in paths] == ["ekf-sensitivity.png"]
    assert paths[0].stat().st_size > 10_000


def test_batched_settings_equal_separate_runs(quick_sweeps):
    """run_settings batches settings under one compiled simulator: each setting's result is the
    one a separate run gives (the sweep runs its σ_ωH = 0.03 row on its own), and the
    sensor noise really is per setting (half the noise, about half the error)."""
    traj = ekf_runs.scenario_trajectory("jump", quick=True)
    loose = ekf_runs.SIGMA_PROCESS[:3] + (0.03,)
    (m_loose, _), (m_quiet, _) = ekf_runs.run_settings(
        traj, "fixed",
        [ekf_runs.Setting(loose), ekf_runs.Setting(None, 0.5 * ekf_runs.SIGMA_MEASUREMENT)])
    row = quick_sweeps[0]["fixed_head_rate_sigma"]["jump"]["sigma_0.03"]
    assert m_loose["rms_tilt_error_deg"] == pytest.approx(row["fixed_rms_deg"], rel=1e-9)
    assert m_loose["max_tilt_error_deg"] == pytest.approx(row["fixed_max_deg"], rel=1e-9)
    p13 = quick_sweeps[0]["fixed_head_rate_sigma"]["jump"]["sigma_0.001"]["fixed_rms_deg"]
    assert 0.35 < m_quiet["rms_tilt_error_deg"] / p13 < 0.65


def test_run_settings_refuses_bad_settings():
    traj = ekf_runs.scenario_trajectory("jump", quick=True)
    with pytest.raises(ValueError, match="at least one setting"):
        ekf_runs.run_settings(traj, "fixed", [])
    with pytest.raises(ValueError, match="sensor_noise_std must be > 0"):
        ekf_runs.run_settings(traj, "fixed", [ekf_runs.Setting(None, 0.0)])
