"""F ch. 5 gimbal model and the `platform` experiment's linear design."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from verticality.experiments import platform as exp
from verticality.models import platform as pf
from verticality.models.params import G_M_S2
from verticality.simulation import platform_loop


def _axis_state(v):
    return pf.AxisState(*(jnp.asarray(a) for a in v))


def test_identified_axes_and_base_drag():
    assert ((pf.PITCH.J_kg_m2, pf.PITCH.b_Nms, pf.ROLL.J_kg_m2, pf.ROLL.b_Nms)
            == (0.008, 1.35, 0.0006, 0.137))
    x = _axis_state([0.0, 0.0, 0.0, 0.0])
    d = pf.PITCH.dynamics(x, pf.AxisInput(0.0, 0.0, 2.0))
    assert float(d.omega_rad_s) == pytest.approx(1.35 * 2.0 / 0.008)
    # a still platform under acceleration: the reading is driven towards atan(a/g)
    d = pf.ROLL.dynamics(x, pf.AxisInput(0.0, 1.0, 0.0))
    assert float(d.ydot_rad_s) == pytest.approx(5.629 * np.arctan2(1.0, 9.81) / 0.0015)
    assert float(pf.ROLL.output(_axis_state([0.3, 0.0, 0.2, 0.0]))[0]) == 0.2


def test_base_drag_share_splits_the_identified_damping():
    """``J ω̇ = u − b (ω − s ω_base)``: the base drags the platform through s·b, the whole
    identified b still damps the platform's own rate."""
    x = _axis_state([0.0, 0.5, 0.0, 0.0])
    for share in (0.0, 0.1, 1.0):
        p = pf.PlatformAxis(J_kg_m2=0.008, b_Nms=1.35, base_drag_share=share)
        d = p.dynamics(x, pf.AxisInput(0.2, 0.0, 2.0))
        assert float(d.omega_rad_s) == pytest.approx((0.2 - 1.35 * (0.5 - share * 2.0)) / 0.008)


def test_accelerometer_offset_and_lever_arm_enter_the_reading():
    """The platform accelerometer's constant offset adds to its reading; a sensor d below the
    pivot also reads the platform's angular acceleration, d·ω̇ along its axis (same noise draw)."""
    key = jax.random.PRNGKey(3)
    f0 = float(platform_loop.accelerometer_reading(key, 0.1, 0.3, 1.0, 4.0))
    biased = float(platform_loop.accelerometer_reading(key, 0.1, 0.3, 1.0, 4.0, bias_m_s2=0.01))
    assert biased - f0 == pytest.approx(0.01, abs=1e-12)
    low = float(platform_loop.accelerometer_reading(key, 0.1, 0.3, 1.0, 4.0, below_pivot_m=0.005))
    assert abs(low - f0) == pytest.approx(0.005 * 4.0, rel=1e-9)
    # at the pivot the angular acceleration does not enter
    assert float(platform_loop.accelerometer_reading(key, 0.1, 0.3, 1.0, 0.0)) == f0


def test_f44_platform_ratios():
    p = pf.f44_platform()
    assert p.g_m_s2 / p.l_m == pytest.approx(3943.8)
    assert p.beta_Nms / (p.m_kg * p.l_m**2) == pytest.approx(125.6)
    assert p.K_kg_m2 == 1e-4


@pytest.mark.parametrize("axis", ["pitch", "roll"])
def test_linear_loops(axis):
    p = exp.AXES[axis]
    obs = platform_loop.observer_for(p)
    assert obs.B.shape == (4, 2)  # u and a_h: the base rate is unknown to the observer
    np.testing.assert_allclose(np.sort(obs.poles().real), np.sort(platform_loop.OBSERVER_POLES),
                               rtol=1e-6)
    A, B, C = (np.asarray(v) for v in (obs.A, obs.B[:, :1], obs.C))
    kp, kd = exp.GAINS[axis]
    inc = p.inclinometer
    # analytic linearization: θ̈ = (u − b θ̇)/J, ÿ = (k_s(θ + a/g) − b_s ẏ − k_s y)/J_s
    assert A[1, 1] == pytest.approx(-p.b_Nms / p.J_kg_m2)
    assert A[3, 0] == pytest.approx(inc.k_s / inc.J_s)
    assert float(obs.B[3, 1]) == pytest.approx(inc.k_s / inc.J_s / inc.g_m_s2)
    state = np.array([[kp, kd, 0.0, 0.0]])
    assert np.linalg.eigvals(A - B @ state).real.max() < 0
    K = state
    L = np.asarray(obs.L)
    big = np.block([[A, -B @ K], [L @ C, A - B @ K - L @ C]])
    assert np.linalg.eigvals(big).real.max() < 0


def test_roll_sensor_fed_continuous_loop_is_unstable():
    p = exp.AXES["roll"]
    obs = platform_loop.observer_for(p)
    A, B = np.asarray(obs.A), np.asarray(obs.B[:, :1])
    kp, kd = exp.GAINS["roll"]
    assert np.linalg.eigvals(A - B @ np.array([[0.0, 0.0, kp, kd]])).real.max() > 0


def test_instability_criterion():
    t = np.arange(0, 10, 3e-3)
    assert exp.is_unstable(t, 0.01 * np.exp(t), 5.0)
    assert not exp.is_unstable(t, 0.05 * np.sin(3 * t), 5.0)


def test_the_platform_accelerometer_reads_the_specific_force_along_the_platform():
    """F §5.2's accelerometer (sensors.accelerometer on the tilted platform): a_h cos θ + g sin θ,
    the tilt entering with the inclinometer's sign (ψ = θ + atan2(a_h, g))."""
    key = jax.random.PRNGKey(0)
    for theta, a in ((0.0, 2.0), (0.3, 0.0), (-0.2, 1.5)):
        f = float(platform_loop.accelerometer_reading(key, theta, 0.7, a))
        expected = a * np.cos(theta) + G_M_S2 * np.sin(theta)
        assert abs(f - expected) < 5 * platform_loop.SIGMA_ACC_M_S2
    # a still platform tilted by θ: the accelerometer's tilt and the inclinometer's agree
    f0 = np.mean([float(platform_loop.accelerometer_reading(k, 0.2, 0.0, 0.0))
                  for k in jax.random.split(key, 200)])
    assert abs(np.arcsin(f0 / G_M_S2) - 0.2) < 2e-3
