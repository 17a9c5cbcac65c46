"""The registered experiments tahboub-* and ground-* (docs/reproduction.md contracts)."""

import numpy as np

from verticality import cli, experiments
from verticality.core import so3
from verticality.experiments import ground, tahboub
from verticality.io.motion import read_motion_csv


def test_tahboub_gains_experiment_matches_t_eq_22():
    r = experiments.get("tahboub-gains").run(quick=True)
    ours, pub = np.array(r.metrics["gain"]), np.array(r.paper["gain"])
    assert ours.shape == (3, 2)
    assert np.all(np.abs(ours - pub) <= 0.05 * np.abs(pub))
    assert r.metrics["max_relative_difference"]["pass"]


def test_tahboub_prts_quick_has_unit_gain_and_high_coherence():
    r = experiments.get("tahboub-prts").run(quick=True)
    m = r.metrics
    for key in ("frequency_hz", "gain", "phase_deg", "coherence"):
        assert len(m[key]) == len(m["frequency_hz"]) > 10
    assert m["mean_coherence"] >= 0.9
    assert 0.9 <= m["mean_gain"] <= 1.1
    assert m["mean_abs_phase_deg"] < 15.0
    assert 4.0 < m["peak_lean_deg"] < 5.5
    assert abs(r.simulated_s - 181.5) < 0.02  # 3 cycles (+ one sample for end matching)


def test_motion_prts_is_the_tahboub_prts_stimulus(tmp_path):
    """One PRTS: the lean recorded by `verticality motion prts` (two cycles) is the command of
    `tahboub-prts`, sample by sample."""
    out = tmp_path / "prts.csv"
    assert cli.main(["motion", "prts", "--out", str(out), "--rate", "100"]) == 0
    rec = read_motion_csv(out)
    lean = -np.asarray(so3.tilt_angles(so3.matrix_from_quat(rec.q_I_H_wxyz)))[:, 1]  # forward +
    command = tahboub.prts_command(2)
    assert lean.size == command.size == 12101  # two cycles and one sample (121 s at 100 Hz)
    np.testing.assert_allclose(lean, command, rtol=0, atol=1e-12)
    assert np.abs(command).max() == np.radians(5.0)


def test_ground_edo_beats_stand_alone_filter_when_motions_superimpose():
    res, m_kf, m_edo, sim = ground.trial(quick=True)
    assert sim == 20.0
    assert m_edo["rms_error_deg"] < m_kf["rms_error_deg"]
    assert m_edo["rms_error_deg_s"] < m_kf["rms_error_deg_s"]
    # Both estimates are meaningful: well below the ±3° ground motion.
    assert m_kf["rms_error_deg"] < 1.5 and m_edo["rms_error_deg"] < 0.5
    assert np.degrees(np.abs(res["theta1"]).max()) > 2.5
    r = experiments.get("ground-edo").run(quick=True)  # cached trial: same numbers
    assert r.metrics["rms_error_deg"] == m_edo["rms_error_deg"]
    assert r.metrics["better_than_kf"]["pass"]
