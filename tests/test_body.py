"""Multi-segment body on inclined ground (models/body.py, T Fig. 1, eq. 4, 16)."""

import control
import jax
import jax.numpy as jnp
import numpy as np

from verticality.integrate import rk4_step
from verticality.models.body import (
    SingleSegmentParams,
    TwoSegmentParams,
    energy,
    linearize,
    single_sensors,
    to_statespace,
    two_segment_dynamics,
    two_segment_outputs,
)

P = TwoSegmentParams()


def _fd_jacobian(fun, z0, eps=1e-6):
    cols = []
    for i in range(z0.size):
        e = np.zeros(z0.size)
        e[i] = eps
        cols.append((np.asarray(fun(z0 + e)) - np.asarray(fun(z0 - e))) / (2 * eps))
    return np.stack(cols, axis=1)


def test_linearization_matches_finite_differences_of_nonlinear_model():
    lin = linearize(P)

    def f(z):
        return two_segment_dynamics(0.0, jnp.asarray(z[:4]), jnp.asarray(z[4:6]), jnp.asarray(z[6:]), P)

    def h(z):
        return two_segment_outputs(0.0, jnp.asarray(z[:4]), jnp.asarray(z[4:6]), jnp.asarray(z[6:]), P)

    z0 = np.zeros(9)
    Jf, Jh = _fd_jacobian(f, z0), _fd_jacobian(h, z0)
    np.testing.assert_allclose(np.hstack([lin.A, lin.B, lin.N]), Jf, atol=1e-7)
    np.testing.assert_allclose(np.hstack([lin.C, lin.D, lin.E]), Jh, atol=1e-7)
    # T eq. 16 structure: [[0, I], [M⁻¹K, 0]], the ground enters via θ1 and θ̈1 only (no damping).
    np.testing.assert_allclose(lin.A[:2], np.hstack([np.zeros((2, 2)), np.eye(2)]))
    np.testing.assert_allclose(lin.A[2:, 2:], 0.0, atol=1e-12)
    np.testing.assert_allclose(lin.N[2:, 1], 0.0, atol=1e-12)
    np.testing.assert_allclose(lin.N[2:, 2], [-1.0, 0.0], atol=1e-12)
    # Upright is unstable without control (inverted pendulum): a positive real eigenvalue.
    assert np.linalg.eigvals(lin.A).real.max() > 1.0


def test_linearization_away_from_upright_is_not_the_same():
    """The finite-difference check must be able to fail: at 0.3 rad the Jacobian differs."""
    lin = linearize(P)

    def f(z):
        return two_segment_dynamics(0.0, jnp.asarray(z[:4]), jnp.zeros(2), jnp.zeros(3), P)

    J = _fd_jacobian(f, np.array([0.3, -0.2, 0.5, 0.1]))
    assert np.abs(J - lin.A).max() > 0.1


def test_energy_is_conserved_without_torque_on_still_ground():
    a0 = jnp.array([0.03, -0.02, 0.0, 0.0])

    def f(t, x):
        return two_segment_dynamics(t, x, jnp.zeros(2), jnp.zeros(3), P)

    def step(x, i):
        return rk4_step(f, i * 1e-3, x, 1e-3), x

    xT, xs = jax.lax.scan(step, a0, jnp.arange(600))

    def E(x):
        return energy(jnp.array([x[0], x[0] + x[1]]), jnp.array([x[2], x[2] + x[3]]), P)

    E0, E1 = float(E(a0)), float(E(xT))
    assert abs(np.asarray(xT[:2])).max() > 0.1  # it did fall noticeably
    assert abs(E1 - E0) < 1e-8 * abs(E0)


def test_still_tilted_body_reads_gravity_component():
    # Static lean: the accelerometer reads g sin φ, gyro 0 (T eq. 5 without the noise).
    w, a = single_sensors(jnp.radians(5.0), 0.0, 0.0, SingleSegmentParams())
    assert float(w) == 0.0
    np.testing.assert_allclose(a, 9.81 * np.sin(np.radians(5.0)), rtol=1e-14)
    # Two segments on a 2° ramp with joints at rest and the body held still: ω = θ̇1 = 0 and
    # a_x = g sin(θ1 + θ2 + θ3) minus the acceleration due to gravity torque (u cancels it here).
    x = jnp.array([0.01, 0.02, 0.0, 0.0])
    d = jnp.array([np.radians(2.0), 0.0, 0.0])
    phi = float(d[0] + x[0] + x[1])
    m1c1 = P.m_legs_kg * P.c_legs_m + P.m_trunk_kg * P.L2_m
    u_hold = -jnp.array([9.81 * (m1c1 * np.sin(float(d[0] + x[0])) + P.m_trunk_kg * P.c_trunk_m * np.sin(phi)),
                         9.81 * P.m_trunk_kg * P.c_trunk_m * np.sin(phi)])
    xdot = two_segment_dynamics(0.0, x, u_hold, d, P)
    np.testing.assert_allclose(xdot, 0.0, atol=1e-12)
    y = two_segment_outputs(0.0, x, u_hold, d, P)
    np.testing.assert_allclose(y[5], 9.81 * np.sin(phi), rtol=1e-12)


def test_statespace_export():
    sys = to_statespace(linearize(P))
    assert isinstance(sys, control.StateSpace)
    assert sys.ninputs == 5 and sys.noutputs == 6 and sys.nstates == 4
