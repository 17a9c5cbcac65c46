"""The offline smoother of the tilt filter (``tilt.smooth``, verticality.tilt.smoother):
better than the filter on synthetic recordings with truth and an honest σ; the RTS identity at the
end; a gap splits the smoothing; the filter's flags and rows; the backward pass against the dense
batch solution of a linear-Gaussian chain; the command line."""

import numpy as np
import pytest

from verticality import cli, tilt
from verticality.core.errors import InputError
from verticality.tilt import batch as tilt_batch
from verticality.tilt import estimator
from verticality.tilt import smoother as tilt_smoother
from verticality.tilt.evaluation.faults import fault_recording
from verticality.tilt.layout import NE


def _err_rad(up_true, up_est):
    return np.arccos(np.clip(np.sum(up_true * up_est, axis=-1), -1.0, 1.0))


@pytest.mark.parametrize("fault", ["clean", "shake"])
def test_smoother_beats_the_filter_with_an_honest_sigma(fault):
    for seed in (0, 1):
        gyr, acc, dt, up = fault_recording(fault, seed=seed)
        causal = tilt.estimate(gyr, acc, period_s=dt)
        smooth = tilt.smooth(gyr, acc, period_s=dt)
        e_c, e_s = _err_rad(up, causal.up_S), _err_rad(up, smooth.up_S)
        rms_c, rms_s = np.sqrt(np.mean(e_c**2)), np.sqrt(np.mean(e_s**2))
        assert rms_s < 0.9 * rms_c, (fault, seed, rms_s, rms_c)
        sigma = smooth.sigma_rad
        assert np.mean(e_s <= 2 * sigma) >= 0.95
        # at the block updates (the last sample of a block) the smoothed σ is not above the
        # filter's (P^s ≤ P⁺: it uses more data), and below it on average
        ends = _block_ends(gyr, acc, dt)
        s_c = causal.sigma_rad[ends]
        assert np.all(sigma[ends] <= s_c * (1 + 1e-12)) and np.mean(sigma[ends]) < np.mean(s_c)


def _block_ends(gyr, acc, dt):
    """The last sample of every updated block of the filter's run."""
    f = tilt.TiltFilter(block=tilt.block_samples(tilt.DEFAULT_PARAMS, dt))  # as estimate's
    _, _, trans = tilt_batch.run(f.params, f.block, f.init(), gyr, acc, dt, transitions=True)
    return trans.start + f.block * np.arange(1, trans.rows.shape[0] + 1) - 1


def test_the_end_of_the_recording_is_the_filter_estimate():
    """RTS identity: after the last block update the smoothed estimate is the filtered one (the
    last updated block's last sample, and the unfinished block after it), while earlier samples
    move."""
    gyr, acc, dt, _ = fault_recording("shake", n=3000 + 17, seed=2)
    causal = tilt.estimate(gyr, acc, period_s=dt)
    smooth = tilt.smooth(gyr, acc, period_s=dt)
    end = _block_ends(gyr, acc, dt)[-1] + 1  # the unfinished block's first sample
    assert 0 < gyr.shape[0] - end < tilt.block_samples(tilt.DEFAULT_PARAMS, dt)
    for name in ("quat_E_S", "roll_rad", "pitch_rad", "bias_S_rad_s", "var"):
        a, b = getattr(causal, name), getattr(smooth, name)
        np.testing.assert_array_equal(a[end:], b[end:], err_msg=name)
        np.testing.assert_allclose(b[end - 1], a[end - 1], rtol=0, atol=1e-15, err_msg=name)
    moved = np.degrees(_err_rad(causal.up_S[:end - 1], smooth.up_S[:end - 1]))
    assert np.max(moved) > 0.1


def _with_gap(seed_after: int):
    """A recording with a 0.5 s gap before sample ``k``: the samples the sensor took meanwhile are
    missing (its readings jump across the gap; a step of the stamps over readings that go on
    would be a clock jump), and with ``seed_after`` other data after the gap."""
    k, n = 3001, 6000

    def shake(seed):
        lost = 49  # 0.5 s at fault_recording's 100 Hz, less the step that spans them
        gyr, acc, dt, up = fault_recording("shake", n=n + lost, seed=seed)
        keep = np.r_[0:k, k + lost:n + lost]
        return gyr[keep], acc[keep], dt, up[keep]

    gyr, acc, dt, up = shake(3)
    dts = np.full(n, dt)
    dts[k] = 0.5
    if seed_after:
        g2, a2, _, up2 = shake(seed_after)
        gyr[k:], acc[k:], up[k:] = g2[k:], a2[k:], up2[k:]
    return gyr, acc, dts, up, k


def test_a_gap_splits_the_smoothing():
    gyr, acc, dts, _, k = _with_gap(0)
    gyr2, acc2, dts2, _, _ = _with_gap(7)
    a, b = estimator.smooth_steps(gyr, acc, dts), estimator.smooth_steps(gyr2, acc2, dts2)
    assert a.flags[k] & tilt.DT_GAP
    for name in ("quat_E_S", "bias_S_rad_s", "var", "flags"):
        np.testing.assert_array_equal(getattr(a, name)[:k], getattr(b, name)[:k], err_msg=name)
    # ... while after the gap they differ, and before it the smoothing did act
    assert np.max(np.abs(a.quat_E_S[k + 500:] - b.quat_E_S[k + 500:])) > 1e-3
    causal = estimator.estimate_steps(gyr, acc, dts)
    assert np.max(np.degrees(_err_rad(causal.up_S[:k - 100], a.up_S[:k - 100]))) > 0.1


def test_flags_and_rows_are_the_filters():
    """Missing samples, a repeated stamp (Δt = 0), a gap, a sample out of range: the same rows
    and flags as the filter, finite estimates where the filter's are."""
    gyr, acc, dt, _ = fault_recording("shake", n=4000, seed=4)
    dts = np.full(gyr.shape[0], dt)
    acc[500:560] = np.nan
    gyr[900:905] = np.nan
    dts[1200] = 0.0
    dts[2500] = 0.4
    gyr[3000, 1] = 1e6
    causal = estimator.estimate_steps(gyr, acc, dts)
    smooth = estimator.smooth_steps(gyr, acc, dts)
    assert smooth._fields == causal._fields
    for a, b in zip(causal, smooth, strict=True):
        assert a.shape == b.shape and a.dtype == b.dtype
    np.testing.assert_array_equal(smooth.flags, causal.flags)
    np.testing.assert_array_equal(smooth.measured, causal.measured)
    for name in ("quat_E_S", "up_S", "var", "bias_S_rad_s"):
        assert np.all(np.isfinite(getattr(smooth, name)))
    # inside the gap's block and the re-acquisition after it the filter's estimate is kept
    reacq = np.flatnonzero(causal.flags & tilt.REACQUIRING)
    reacq = reacq[reacq > 2500]
    inner = reacq[:-1][np.diff(reacq) == 1]
    block = tilt.block_samples(tilt.DEFAULT_PARAMS, dts)
    inner = inner[(inner + 1) % block != 0]  # not a block's last sample (the updated end)
    np.testing.assert_allclose(smooth.quat_E_S[inner], causal.quat_E_S[inner], rtol=0,
                               atol=1e-15)


def _kalman_chain(rng, m=6):
    """A random linear-Gaussian chain x_j = F_j x_{j−1} + w_j, y_j = H_j x_j + v_j (7 states,
    2 measurements; one block's F with zeroed velocity rows and the reset variance in Q, as a
    velocity reset), filtered by a plain Kalman filter. Returns the filter's quantities and the
    dense batch posterior (information form) of all states."""
    P_init = np.diag(rng.uniform(0.5, 2.0, NE))
    Fs, Qs, Hs, Rs, ys = [], [], [], [], []
    x = rng.multivariate_normal(np.zeros(NE), P_init)
    for j in range(m):
        F = np.eye(NE) + 0.3 * rng.normal(size=(NE, NE))
        Q = np.diag(rng.uniform(0.05, 0.3, NE))
        if j == 3:  # a velocity reset
            F[2:4] = 0.0
            Q[2:4, 2:4] = np.diag([1.5, 1.5])
        H = rng.normal(size=(2, NE))
        R = np.diag(rng.uniform(0.1, 0.5, 2))
        x = F @ x + rng.multivariate_normal(np.zeros(NE), Q)
        ys.append(H @ x + rng.multivariate_normal(np.zeros(2), R))
        Fs.append(F), Qs.append(Q), Hs.append(H), Rs.append(R)
    # forward: a plain Kalman filter
    mean, P = np.zeros(NE), P_init
    means, P0s, Pps, dxs = [mean], [], [], []
    for F, Q, H, R, y in zip(Fs, Qs, Hs, Rs, ys, strict=True):
        P0s.append(P)
        m_pred, P_pred = F @ mean, F @ P @ F.T + Q
        K = P_pred @ H.T @ np.linalg.inv(H @ P_pred @ H.T + R)
        mean = m_pred + K @ (y - H @ m_pred)
        P = (np.eye(NE) - K @ H) @ P_pred
        Pps.append(P_pred), dxs.append(mean - m_pred), means.append(mean)
    # dense: the joint posterior of (x_{-1}, x_0, ..., x_{m-1})
    N = NE * (m + 1)
    J, h = np.zeros((N, N)), np.zeros(N)
    J[:NE, :NE] = np.linalg.inv(P_init)
    for j, (F, Q, H, R, y) in enumerate(zip(Fs, Qs, Hs, Rs, ys, strict=True)):
        A = np.zeros((NE, N))
        A[:, j * NE:(j + 1) * NE] = -F
        A[:, (j + 1) * NE:(j + 2) * NE] = np.eye(NE)
        J += A.T @ np.linalg.inv(Q) @ A
        s = slice((j + 1) * NE, (j + 2) * NE)
        J[s, s] += H.T @ np.linalg.inv(R) @ H
        h[s] += H.T @ np.linalg.inv(R) @ y
    cov = np.linalg.inv(J)
    return (np.array(means), np.array(P0s), np.array(Fs), np.array(Pps), np.array(dxs), P,
            cov @ h, cov)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_backward_pass_equals_the_dense_batch_solution(seed):
    rng = np.random.default_rng(seed)
    m = 6
    means, P0, F, Pp, dx, P_end, dense_mean, dense_cov = _kalman_chain(rng, m)
    e, Ps = tilt_smoother.rts_backward(P0, F, Pp, dx, np.zeros(m, dtype=bool), P_end)
    e, Ps = np.asarray(e), np.asarray(Ps)
    for j in range(m):  # block j starts at state x_{j−1}: index j of the stacked states
        s = slice(j * NE, (j + 1) * NE)
        np.testing.assert_allclose(means[j] + e[j], dense_mean[s], rtol=0, atol=1e-9)
        np.testing.assert_allclose(Ps[j], dense_cov[s, s], rtol=0, atol=1e-9)
    # the last state: the filter's is already the smoothed one
    s = slice(m * NE, (m + 1) * NE)
    np.testing.assert_allclose(means[m], dense_mean[s], atol=1e-9)
    # a split block cuts the chain: before it, the smoothed values are the filter's
    split = np.zeros(m, dtype=bool)
    split[2] = True
    e2, Ps2 = (np.asarray(v) for v in tilt_smoother.rts_backward(P0, F, Pp, dx, split, P_end))
    np.testing.assert_array_equal(e2[2], 0.0)
    np.testing.assert_allclose(Ps2[2], P0[2], atol=0)
    np.testing.assert_allclose(e2[3:], e[3:], atol=0)
    assert np.max(np.abs(e2[:2] - e[:2])) > 1e-6
    # a singular prior (a zero variance) cuts the chain there instead of spreading NaN
    Pp_sing = Pp.copy()
    Pp_sing[4] = 0.0
    e3, Ps3 = (np.asarray(v) for v in tilt_smoother.rts_backward(P0, F, Pp_sing, dx,
                                                                   np.zeros(m, dtype=bool), P_end))
    assert np.all(np.isfinite(e3)) and np.all(np.isfinite(Ps3))
    np.testing.assert_array_equal(e3[4], 0.0)
    np.testing.assert_allclose(e3[5:], e[5:], atol=0)


def test_a_recording_beyond_memory_is_refused(monkeypatch):
    import verticality.core.sizing

    gyr, acc, dt, _ = fault_recording("clean", n=1000, seed=0)
    monkeypatch.setattr(verticality.core.sizing, "MAX_WORK_BYTES",
                        999 * tilt_smoother.BYTES_PER_SAMPLE)
    with pytest.raises(InputError, match="offline smoother"):
        tilt.smooth(gyr, acc, period_s=dt)


def test_estimate_offline_command(tmp_path, capsys, monkeypatch):
    import verticality.core.sizing
    from verticality.io import imu
    from verticality.io.recording import load_imu

    gyr, acc, dt, _ = fault_recording("shake", n=2000, seed=5)
    t = np.arange(gyr.shape[0]) * dt
    path = imu.write_imu_csv(tmp_path / "rec.csv", imu.ImuRecording(t, gyr, acc))
    assert cli.main(["estimate", str(path), "--out", str(tmp_path / "est.csv"), "--offline",
                     "--sigma"]) == 0
    assert "offline (smoothed)" in capsys.readouterr().out
    est = imu.read_estimate_csv(tmp_path / "est.csv")
    rec = load_imu(path)
    ref = tilt.smooth(rec.gyr_rad_s, rec.acc_m_s2, rec.t_s)
    np.testing.assert_allclose(est.roll_rad, ref.roll_rad, atol=1e-12)
    np.testing.assert_array_equal(est.flags, ref.flags)
    # refused: a peer offline, and a recording beyond memory (sized before it is read)
    assert cli.main(["estimate", str(path), "--out", str(tmp_path / "e2.csv"), "--offline",
                     "--filter", "vqf"]) != 0
    assert "offline smoother" in capsys.readouterr().err
    monkeypatch.setattr(verticality.core.sizing, "MAX_WORK_BYTES",
                        1000 * tilt_smoother.BYTES_PER_SAMPLE)
    assert cli.main(["estimate", str(path), "--out", str(tmp_path / "e3.csv"), "--offline"]) != 0
    assert "offline smoother" in capsys.readouterr().err and not (tmp_path / "e3.csv").exists()


def test_estimate_offline_reads_every_format(tmp_path):
    """`estimate --offline` on an EuRoC-layout CSV, a CSV with mapped columns and a BROAD-layout
    HDF5 file: the smoother of the recording as `estimate` reads it."""
    import h5py

    from verticality.io import imu
    from verticality.io.recording import load_imu

    gyr, acc, dt, _ = fault_recording("shake", n=1500, seed=6)
    n = gyr.shape[0]
    stamps = 1_403_636_579_758_555_392 + int(dt * 1e9) * np.arange(n, dtype=np.int64)
    euroc = tmp_path / "euroc.csv"
    euroc.write_text("\n".join(["#timestamp [ns],w_RS_S_x [rad s^-1],w_RS_S_y [rad s^-1],"
                                "w_RS_S_z [rad s^-1],a_RS_S_x [m s^-2],a_RS_S_y [m s^-2],"
                                "a_RS_S_z [m s^-2]"]
                               + [",".join([str(int(s))] + [f"{v:.17g}" for v in (*g, *a)])
                                  for s, g, a in zip(stamps, gyr, acc, strict=True)]) + "\n")
    mapped = tmp_path / "mapped.csv"
    mapped.write_text("\n".join(["time_ms,wx,wy,wz,ax,ay,az"]
                                + [",".join(f"{v:.17g}" for v in (1e3 * k * dt, *g, *a))
                                   for k, (g, a) in enumerate(zip(gyr, acc, strict=True))]) + "\n")
    hdf5 = tmp_path / "trial.hdf5"
    with h5py.File(hdf5, "w") as f:
        f["imu_gyr"], f["imu_acc"] = gyr, acc
        f["opt_quat"] = np.tile([1.0, 0.0, 0.0, 0.0], (n, 1))
        f["movement"] = np.ones(n, dtype=bool)
        f.attrs["sampling_rate"] = 1.0 / dt
    columns = "t=time_ms,gyr_x=wx,gyr_y=wy,gyr_z=wz,acc_x=ax,acc_y=ay,acc_z=az"
    for path, extra in ((euroc, []), (mapped, ["--columns", columns, "--time-unit", "ms"]),
                        (hdf5, [])):
        out = tmp_path / (path.stem + "_est.csv")
        assert cli.main(["estimate", str(path), "--out", str(out), "--offline", *extra]) == 0
        est = imu.read_estimate_csv(out)
        rec = load_imu(path, columns=columns if extra else None,
                       time_unit="ms" if extra else None)
        ref = tilt.smooth(rec.gyr_rad_s, rec.acc_m_s2, rec.t_s)
        assert est.roll_rad.shape == (n,)
        np.testing.assert_allclose(est.roll_rad, ref.roll_rad, rtol=0, atol=1e-12)
        np.testing.assert_array_equal(est.flags, ref.flags)
