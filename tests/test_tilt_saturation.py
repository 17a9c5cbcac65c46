"""Saturation in a calibrated recording (tilt/limits.py, "A plateau after calibration"): a sensor
that clips in its own raw axes and is calibrated afterwards (sensors/readings.py), the detector
that finds the plateau from the recording alone, and that it finds nothing on clean recordings;
the validation set's failure classes and leave-one-class-out (tilt/evaluation/)."""

import numpy as np
import pytest

from broad_slices import ALL
from verticality import tilt
from verticality.sensors import readings
from verticality.tilt import limits as tilt_limits
from verticality.tilt.evaluation import failures, faults
from verticality.tilt.evaluation import validation as tv
from verticality.tilt.flags import CLIPPED

N, DT = 2000, 0.01  # the shape of the other limits tests: the compiled filter is shared


def _turning_fast(seed):
    """A sensor turning about all three axes at up to ~8 rad/s (faults.turning's sinusoids), 100
    Hz: the true rate (N, 3), specific force (N, 3) and up direction (N, 3)."""
    rng = np.random.default_rng(seed)
    w, R = faults.turning(N, DT, rng, max_rate_rad_s=4.0)
    acc = 9.81 * R[:, 2, :]
    return w, acc, R[:, 2, :]


@pytest.fixture(scope="module")
def calibrated_clip():
    """The fast turning read by a gyro that clips 5 % of the samples in its raw axes, then
    calibrated with a slightly wrong estimate of its errors (failures.read_raw_then_calibrated)."""
    w, acc, up = _turning_fast(1)
    rng = np.random.default_rng(11)
    sensor = failures.draw_raw_sensor(rng, np.radians(3.0), 1.2e-3, 1.0)
    sensor = sensor._replace(full_scale=failures.full_scale_for_share(w, sensor, 0.05))
    gyr, clipped = failures.read_raw_then_calibrated(w, sensor, np.random.default_rng(12))
    acc = acc + np.random.default_rng(13).normal(0, 0.02, acc.shape)
    return gyr, acc, up, clipped, sensor


def test_a_raw_axis_clip_after_calibration_is_a_plane_not_a_flat_top(calibrated_clip):
    """The file's plateau: no calibrated axis is flat (the flat-top detector finds nothing), the
    limits differ by sign, and along the raw axis's direction (its row of the estimated forward
    model) the plateau's samples are constant to rounding while they wander along the axis by far
    more than the noise."""
    gyr, _, _, clipped, s = calibrated_clip
    assert 0.03 < clipped.mean() < 0.07
    lo, hi = tilt_limits.inferred_levels(gyr, np.zeros(N, bool), tilt_limits.GYR_FLOOR_RAD_S)
    assert np.all(np.isinf(lo)) and np.all(np.isinf(hi))
    forward = (np.eye(3) + s.cross_est) * (1.0 + s.scale_est)  # raw = forward @ y + bias_est
    raw = gyr @ forward.T + s.bias_est
    tops = raw >= raw.max(axis=0) - 1e-9
    i = int(np.argmax(tops.sum(axis=0)))  # the raw axis clipped longest at its top
    top = tops[:, i]
    assert top.sum() >= 10
    assert np.ptp(gyr[top, i]) > 3 * 1.2e-3  # the calibrated axis wanders beyond the noise
    assert np.ptp(raw[top, i]) < 1e-9  # the raw axis is flat
    bottom = raw[:, i] <= raw[:, i].min() + 1e-9
    assert abs(gyr[top, i].max() + gyr[bottom, i].min()) > 0.01  # limits differ by sign


def test_the_detector_finds_the_raw_plateau_and_only_it(calibrated_clip):
    """The recording alone gives ≥ 95 % of the clipped samples flagged and ≤ 0.5 % of the others
    (measured 100 % and 0 % here)."""
    gyr, acc, _, clipped, _ = calibrated_clip
    lim = tilt_limits.find_limits(gyr, acc, DT)
    flagged = lim.gyr_clipped.any(axis=1)
    assert flagged[clipped].mean() >= 0.95
    assert flagged[~clipped].mean() <= 0.005
    assert np.all(lim.tilt_var_rad2[~flagged] == 0) and np.all(lim.tilt_var_rad2[flagged] > 0)


def test_detection_matches_the_given_range_for_the_filter(calibrated_clip):
    """The filter with the plateau found is at least as close to the truth as the filter told
    nothing, and within 20 % of the filter given the full scale."""
    gyr, acc, up, _, s = calibrated_clip

    def err(**kw):
        out = tilt.estimate(gyr, acc, period_s=DT, **kw)
        cos = np.clip(np.sum(np.asarray(out.up_S) * up, axis=1), -1, 1)
        return float(np.sqrt(np.mean(np.degrees(np.arccos(cos[500:])) ** 2))), out

    found, out = err()
    off, _ = err(detect_clipping=False)
    given, _ = err(gyr_range_rad_s=s.full_scale * 0.98)  # a user's rounded data-sheet range
    assert np.any(out.flags & CLIPPED)
    assert found <= off
    assert found <= 1.2 * given + 0.05


def test_noise_after_the_clip_is_noise_on_the_plateau():
    """A front end that saturates before the converter's noise: the plateau is no longer flat
    along the raw axis (the case the detector cannot tell from a noisy peak: docs/tilt.md)."""
    rng = np.random.default_rng(0)
    true = np.column_stack([np.linspace(-10, 10, 400), np.zeros(400), np.zeros(400)])
    noise = rng.normal(0, 0.01, true.shape)
    before = readings.raw_axes_reading(true, np.zeros((3, 3)), np.zeros(3), 0.0, noise,
                                       -7.0, 7.0)
    after = readings.raw_axes_reading(true, np.zeros((3, 3)), np.zeros(3), 0.0, noise,
                                      -7.0, 7.0, noise_after_clip=True)
    top = true[:, 0] > 7.2
    assert np.all(before[top, 0] == 7.0)
    assert np.std(after[top, 0]) > 0.005


def test_calibrated_inverts_the_model_it_is_given():
    rng = np.random.default_rng(1)
    x = rng.normal(0, 3, (50, 3))
    cross, scale = failures.cross_terms(rng, 0.02), rng.uniform(-0.02, 0.02, 3)
    bias = rng.normal(0, 1, 3)
    raw = readings.axes_reading(x, cross, scale, bias, 0.0, np.inf)
    np.testing.assert_allclose(readings.calibrated(raw, cross, scale, bias), x, atol=1e-12)


def test_no_clipping_is_found_on_clean_recordings():
    """Nothing clipped, no variance added, on the BROAD slices at their rate and resampled to 100
    and 1000 Hz (an upsampled recording holds runs of collinear samples that fit a plane), and on
    the clean, biased, shaken and tapped fault recordings."""
    from verticality.io import broad

    for path in ALL:
        trial = broad.load_trial(path)
        for rate in (None, 100.0, 1000.0):
            c = (trial if rate is None else tv.resample_trial(trial, rate))
            g = trial.gyr_rad_s if rate is None else c.gyr_rad_s
            a = trial.acc_m_s2 if rate is None else c.acc_m_s2
            lim = tilt_limits.find_limits(g, a, trial.dt_s if rate is None else 1 / rate)
            assert not np.any(lim.flags & CLIPPED), (path.name, rate)
            assert np.all(lim.tilt_var_rad2 == 0) and np.all(lim.vel_var_m2_s2 == 0)
    for fault in ("clean", "bias_0.2", "shake", "taps", "kicks"):
        gyr, acc, dt, _ = faults.fault_recording(fault, n=N, seed=3)
        lim = tilt_limits.find_limits(gyr, acc, dt)
        assert not np.any(lim.flags & CLIPPED), fault


def test_noise_is_read_from_the_recording():
    """noise_std: white noise under a slow motion gives its σ to within 10 %; a quantized quiet
    axis's σ comes from its code steps, and an axis that never changes gives 0."""
    rng = np.random.default_rng(2)
    t = np.arange(20000) * 0.01
    x = np.column_stack([np.sin(t), 3 * np.cos(0.5 * t), np.zeros_like(t)])
    x[:, :2] += rng.normal(0, 0.01, (t.size, 2))
    sd = tilt_limits.noise_std(x)
    np.testing.assert_allclose(sd[:2], 0.01, rtol=0.1)
    assert sd[2] == 0.0
    assert tilt_limits.noise_std(np.round(x / 0.05) * 0.05)[0] > 0.0


def test_timing_classes_hold_what_they_name():
    """Drop-outs skip rows (stamps jump by ≥ 50 ms), clock jumps step the stamps by seconds while
    the readings continue, jitter keeps the true, irregular instants."""
    d = failures.timing("dropout", 0, 50.0, duration_s=20.0)
    steps = np.diff(d.t_s)
    assert np.max(steps) >= 0.05 and d.t_s.size < 1000
    c = failures.timing("clock-jump", 0, 50.0, duration_s=20.0)
    assert c.t_s.size == 1000 and np.max(np.abs(np.diff(c.t_s))) >= 2.0
    j = failures.timing("jitter", 0, 50.0, duration_s=20.0)
    s = np.diff(j.t_s)
    assert np.all(s > 0) and s.min() < 0.014 and s.max() > 0.026


def test_leave_one_class_out_reports_the_other_classes_choice():
    """Three classes; variant "a" is better on two of them, "b" on the third: each class is given
    the variant the other two prefer, so the third gets "a" (its own best is "b"), with a's ratio
    there. (A stand-in runner: estimates off by a known angle per class and variant, the class
    read from the readings, the peer 2° off everywhere.)"""
    from verticality.core import so3

    n = 50
    off_deg = [{"a": 1.0, "b": 2.0}, {"a": 1.0, "b": 2.0}, {"a": 2.5, "b": 1.5}]

    def case(i):
        return tv.Case("ABC"[i], f"{i}/0", 100.0, np.full((n, 3), float(i)), np.zeros((n, 3)),
                       np.tile([1.0, 0.0, 0.0, 0.0], (n, 1)), np.ones(n, bool))

    def runner(options):
        def run(name, gyr, acc, dt):
            deg = off_deg[int(gyr[0, 0])][options["v"]] if options else 2.0
            q = np.asarray(so3.quat_from_matrix(so3.rot_x(np.radians(deg))))
            return np.tile(q, (n, 1)), None, np.full(n, 1.0)
        return run

    out = tv.leave_one_class_out([case(i) for i in range(3)], {"a": {"v": "a"}, "b": {"v": "b"}},
                                 runner=runner)
    assert {c: r["variant"] for c, r in out["chosen"].items()} == {"A": "a", "B": "a", "C": "a"}
    assert out["chosen"]["C"]["best_here"] == "b"
    np.testing.assert_allclose(out["chosen"]["C"]["ratios"][100.0], 1.25, rtol=1e-6)
    np.testing.assert_allclose(out["ratios"]["b"][("A", 100.0)], 1.0, rtol=1e-6)
