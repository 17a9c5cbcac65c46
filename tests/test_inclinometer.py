"""Liquid inclinometer: F §4.4.3 ratios, F 5.1–5.3 pendulum, F §5.2 identified model."""

import jax.numpy as jnp
import numpy as np
import pytest

from verticality.errors import InputError
from verticality.models import inclinometer as incl
from verticality.models import planar
from verticality.models.platform import f44_params


def test_f44_vial_is_critically_damped_at_10_hz():
    p = incl.PendulumInclinometerParams()
    wn = incl.natural_frequency_rad_s(p.g_over_l_s2)
    assert wn / (2 * np.pi) == pytest.approx(10.0, rel=1e-3)
    assert incl.damping_ratio(p.beta_over_ml2_s, p.g_over_l_s2) == pytest.approx(1.0, rel=2e-3)


def test_identified_poles_and_unit_dc_gain():
    p = incl.IdentifiedInclinometerParams()
    np.testing.assert_allclose(np.sort(np.roots([p.J_s, p.b_s, p.k_s]).real), [-235.82, -15.913], rtol=1e-3)
    psi = 0.3
    d = incl.identified_dynamics(incl.IdentifiedInclinometerState(jnp.asarray(psi), jnp.asarray(0.0)), psi, p)
    assert float(d.ydot_rad_s) == 0.0 and float(d.y_rad) == 0.0
    pend = incl.identified_as_pendulum(p)
    assert pend.g_over_l_s2 == pytest.approx(p.k_s / p.J_s)
    with pytest.raises(InputError):
        incl.identified_as_pendulum(p._replace(J_s=0.0))


def test_pendulum_rest_under_acceleration_and_cross_check_with_planar():
    p = incl.PendulumInclinometerParams()
    a_h, a_z = 2.0, -1.0
    phi_rest = float(planar.rest_angle(a_h, a_z))
    x = incl.PendulumInclinometerState(jnp.asarray(phi_rest), jnp.asarray(0.0))
    d = incl.pendulum_dynamics(x, incl.PendulumInclinometerInput(0.0, a_h, a_z), p)
    assert abs(float(d.omega_rad_s)) < 1e-9
    # a still, tilted vial at rest reads (minus) the apparent tilt θ + atan(a_h/(g+a_z))
    theta = 0.2
    assert -float(incl.pendulum_reading(x, theta)) == pytest.approx(
        float(incl.apparent_tilt(theta, a_h, a_z)), abs=1e-12)
    assert float(incl.apparent_tilt(0.0, a_h, a_z)) == pytest.approx(-phi_rest)
    # the same equation as the planar model with F §4.4's ratios
    pp = f44_params()
    xs = (0.3, -1.2, 0.1, 0.7)
    ref = planar.pendulum_angular_acceleration(xs[0], xs[1], xs[3], a_h, a_z, pp)
    ours = incl.pendulum_dynamics(incl.PendulumInclinometerState(jnp.asarray(xs[0]), jnp.asarray(xs[1])),
                                  incl.PendulumInclinometerInput(xs[3], a_h, a_z), p).omega_rad_s
    assert float(ours) == pytest.approx(float(ref), rel=1e-12)


def test_small_oscillation_frequency():
    p = incl.PendulumInclinometerParams(beta_over_ml2_s=0.0)
    eps = 1e-6
    x = incl.PendulumInclinometerState(jnp.asarray(eps), jnp.asarray(0.0))
    d = incl.pendulum_dynamics(x, incl.PendulumInclinometerInput(0.0, 0.0, 0.0), p)
    assert -float(d.omega_rad_s) / eps == pytest.approx(p.g_over_l_s2, rel=1e-9)
    with pytest.raises(InputError):
        incl.natural_frequency_rad_s(-1.0)
