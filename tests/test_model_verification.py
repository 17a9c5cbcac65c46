"""`model-verification`: F §2.2's medial and lateral models with the head stabilized from a tilt
(Figs. 2.4–2.5), F's qualitative findings asserted on a quick run."""

import math

import numpy as np
import pytest

from verticality.experiments import model_verification as M
from verticality.models.params import G_M_S2


def test_otolith_is_critically_damped_at_300_hz():
    p = M.pendulum_params()
    J = float(p.J_pivot_S[0])
    w = math.sqrt(p.m_kg * G_M_S2 * p.l_m / J)
    np.testing.assert_allclose(w / (2 * math.pi), 300.0, rtol=1e-12)
    np.testing.assert_allclose(p.beta_Nms / (2 * J * w), 1.0, rtol=1e-12)  # damping ratio
    kp, kd = M.stabilizer_gains(10.0)
    # critically damped at upright: J s² + K_d s + 2 K_p = J (s + 10)²
    np.testing.assert_allclose([kd / 0.0174, 2 * kp / 0.0174], [20.0, 100.0], rtol=1e-12)


@pytest.fixture(scope="module")
def quick():
    return M.run(quick=True).metrics


def test_fs_findings_hold(quick):
    """(A) sagittal: left = right; (B) lateral: they differ while the head turns, not at rest;
    (C) yaw: they differ in both planes; Fig. 2.5 differs more than the tilts it combines; the
    medial pendulum is close to the lateral pair's mean; the head ends upright."""
    assert all(c["pass"] for c in quick["checks"].values()), quick["checks"]
    cases = quick["cases"]
    assert max(cases["sagittal"]["left_minus_right_max_rad"].values()) == 0.0
    lat = cases["lateral"]
    assert lat["left_minus_right_max_rad"]["x"] > 1e-2 and lat["left_minus_right_max_rad"]["y"] == 0
    # the medial pendulum's yaw output stays zero: all the yaw motion is the pivots' offset
    assert cases["yaw"]["medial_minus_lateral_mean_max_rad"] < 1e-9
    for c in cases.values():
        assert 0.2 < c["head_settling_time_s"] < 1.0  # 10 rad/s loop: ~0.48 s to 5 %


def test_left_right_difference_grows_with_the_stabilizers_bandwidth(quick):
    """F calls the difference negligible against the pendula's motion; it is set by the head's
    angular acceleration (±r·ω̇_H at the pivots), so it grows with the loop's bandwidth."""
    by = quick["left_minus_right_over_motion_by_loop_rad_s"]
    vals = [by[k] for k in ("2.5", "5", "10", "20")]
    assert all(a < b for a, b in zip(vals, vals[1:], strict=False))
    assert vals[0] < 0.05 < vals[2]
