"""Liquid inclinometer: F §4.4.3 ratios, F 5.1–5.3 pendulum (the planar pendulum), F §5.2
identified model."""

import jax.numpy as jnp
import numpy as np
import pytest

from verticality.core.errors import InputError
from verticality.models import inclinometer as incl
from verticality.models import planar
from verticality.models.planar import FrameMotion, PendulumState
from verticality.models.platform import f44_platform


def _frame(theta=0.0, omega=0.0, a_h=0.0, a_z=0.0):
    return FrameMotion(*(jnp.asarray(v) for v in (theta, omega, a_h, a_z)))


def test_f44_vial_is_critically_damped_at_10_hz():
    p = incl.pendulum_from_ratios()
    g_over_l = p.g_m_s2 / p.l_m
    beta_over_ml2 = p.beta_Nms / (p.m_kg * p.l_m**2)
    wn = incl.natural_frequency_rad_s(g_over_l)
    assert wn / (2 * np.pi) == pytest.approx(10.0, rel=1e-3)
    assert incl.damping_ratio(beta_over_ml2, g_over_l) == pytest.approx(1.0, rel=2e-3)
    with pytest.raises(InputError):
        incl.pendulum_from_ratios(-1.0)


def test_identified_poles_and_unit_dc_gain():
    p = incl.IdentifiedInclinometer()
    np.testing.assert_allclose(np.sort(np.roots([p.J_s, p.b_s, p.k_s]).real), [-235.82, -15.913],
                               rtol=1e-3)
    psi = 0.3
    x = incl.IdentifiedInclinometerState(jnp.asarray(psi), jnp.asarray(0.0))
    d = p.dynamics(x, _frame(theta=psi))
    assert float(d.ydot_rad_s) == 0.0 and float(d.y_rad) == 0.0
    # under acceleration it settles at the apparent tilt, not at the tilt
    d = p.dynamics(x, _frame(theta=psi, a_h=1.0))
    assert float(d.ydot_rad_s) > 0.0
    assert float(p.output(x)[0]) == psi
    pend = incl.identified_as_pendulum(p)
    assert pend.g_m_s2 / pend.l_m == pytest.approx(p.k_s / p.J_s)
    assert pend.beta_Nms / pend.J_kg_m2 == pytest.approx(p.b_s / p.J_s)
    with pytest.raises(InputError):
        incl.identified_as_pendulum(incl.IdentifiedInclinometer(J_s=0.0))


def test_pendulum_rest_under_acceleration_and_the_one_pendulum_equation():
    p = incl.pendulum_from_ratios()
    a_h, a_z = 2.0, -1.0
    phi_rest = float(planar.rest_angle(a_h, a_z))
    x = PendulumState(jnp.asarray(phi_rest), jnp.asarray(0.0))
    d = p.dynamics(x, _frame(a_h=a_h, a_z=a_z))
    assert abs(float(d.omega_rad_s)) < 1e-9
    # a still, tilted vial at rest reads (minus) the apparent tilt θ + atan(a_h/(g+a_z))
    theta = 0.2
    assert -float(p.output(x, _frame(theta, 0.0, a_h, a_z))[0]) == pytest.approx(
        float(incl.apparent_tilt(theta, a_h, a_z)), abs=1e-12)
    assert float(incl.apparent_tilt(0.0, a_h, a_z)) == pytest.approx(-phi_rest)
    # F 5.2 per unit inertia (module docstring) is this pendulum: −(g/l + a_z/l) sin φ − …
    gl, bl = incl.F44_G_OVER_L_S2, incl.F44_BETA_OVER_ML2_S
    phi, w, W = 0.3, -1.2, 0.7
    per_inertia = (-(gl + gl / p.g_m_s2 * a_z) * np.sin(phi) - gl / p.g_m_s2 * a_h * np.cos(phi)
                   - bl * (w - W))
    ours = p.dynamics(PendulumState(jnp.asarray(phi), jnp.asarray(w)), _frame(0.1, W, a_h, a_z))
    assert float(ours.omega_rad_s) == pytest.approx(per_inertia, rel=1e-12)
    # ... and the pendulum of F §4.4's platform (the planar head carries the same one)
    head = f44_platform()
    xs = planar.PlanarState(*(jnp.asarray(v) for v in (phi, w, 0.1, W)))
    a_head = head.dynamics(xs, planar.PlanarInput(jnp.asarray(0.0), jnp.asarray(a_h),
                                                  jnp.asarray(a_z)))
    assert float(a_head.omega_S_rad_s) == float(ours.omega_rad_s)


def test_small_oscillation_frequency():
    p = incl.pendulum_from_ratios(beta_over_ml2_s=0.0)
    eps = 1e-6
    d = p.dynamics(PendulumState(jnp.asarray(eps), jnp.asarray(0.0)), _frame())
    assert -float(d.omega_rad_s) / eps == pytest.approx(incl.F44_G_OVER_L_S2, rel=1e-9)
    with pytest.raises(InputError):
        incl.natural_frequency_rad_s(-1.0)
