"""Multi-segment body on inclined ground (models/body.py, T Fig. 1, eq. 4, 16): model values,
T eq. 16 through the one linearization, energy, sensors."""

import control
import jax
import jax.numpy as jnp
import numpy as np

from verticality.models.base import step_rk4
from verticality.models.body import (
    TWO_SEGMENT_INPUTS,
    TWO_SEGMENT_OUTPUTS,
    TWO_SEGMENT_STATES,
    GroundInput,
    LeanState,
    SingleSegmentBody,
    TwoSegmentBody,
    upright,
)
from verticality.models.linearize import linearize, to_statespace

BODY = TwoSegmentBody()


def _fd_jacobian(fun, z0, eps=1e-6):
    cols = []
    for i in range(z0.size):
        e = np.zeros(z0.size)
        e[i] = eps
        cols.append((np.asarray(fun(z0 + e)) - np.asarray(fun(z0 - e))) / (2 * eps))
    return np.stack(cols, axis=1)


def _split(z):
    return jnp.asarray(z[:4]), GroundInput(jnp.asarray(z[4:6]), jnp.asarray(z[6:]))


def test_linearization_matches_finite_differences_of_nonlinear_model():
    lin = linearize(BODY, *upright())
    A, B, C, D = (np.asarray(m) for m in lin)
    assert B.shape == (4, 5) and D.shape == (6, 5)  # inputs (τ2, τ3, θ1, θ̇1, θ̈1): T's B and N

    z0 = np.zeros(9)
    Jf = _fd_jacobian(lambda z: BODY.dynamics(*_split(z)), z0)
    Jh = _fd_jacobian(lambda z: BODY.output(*_split(z)), z0)
    np.testing.assert_allclose(np.hstack([A, B]), Jf, atol=1e-7)
    np.testing.assert_allclose(np.hstack([C, D]), Jh, atol=1e-7)
    # T eq. 16 structure: [[0, I], [M⁻¹K, 0]], the ground enters via θ1 and θ̈1 only (no damping).
    N = B[:, 2:]
    np.testing.assert_allclose(A[:2], np.hstack([np.zeros((2, 2)), np.eye(2)]))
    np.testing.assert_allclose(A[2:, 2:], 0.0, atol=1e-12)
    np.testing.assert_allclose(N[2:, 1], 0.0, atol=1e-12)
    np.testing.assert_allclose(N[2:, 2], [-1.0, 0.0], atol=1e-12)
    # Upright is unstable without control (inverted pendulum): a positive real eigenvalue.
    assert np.linalg.eigvals(A).real.max() > 1.0


def test_linearization_away_from_upright_is_not_the_same():
    """The finite-difference check must be able to fail: at 0.3 rad the Jacobian differs."""
    lin = linearize(BODY, *upright())
    u0 = GroundInput(jnp.zeros(2), jnp.zeros(3))
    J = _fd_jacobian(lambda x: BODY.dynamics(jnp.asarray(x), u0), np.array([0.3, -0.2, 0.5, 0.1]))
    assert np.abs(J - np.asarray(lin.A)).max() > 0.1


def test_energy_is_conserved_without_torque_on_still_ground():
    a0 = jnp.array([0.03, -0.02, 0.0, 0.0])
    u = GroundInput(jnp.zeros(2), jnp.zeros(3))

    def step(x, _):
        return step_rk4(BODY, x, u, 1e-3), x

    xT, _ = jax.lax.scan(step, a0, jnp.arange(600))

    def E(x):
        return BODY.energy(jnp.array([x[0], x[0] + x[1]]), jnp.array([x[2], x[2] + x[3]]))

    E0, E1 = float(E(a0)), float(E(xT))
    assert abs(np.asarray(xT[:2])).max() > 0.1  # it did fall noticeably
    assert abs(E1 - E0) < 1e-8 * abs(E0)


def test_still_tilted_body_reads_gravity_component():
    # Static lean: the accelerometer reads g sin φ, gyro 0 (T eq. 5 without the noise).
    single = SingleSegmentBody()
    w, a = single.sensors(jnp.radians(5.0), 0.0, 0.0)
    assert float(w) == 0.0
    np.testing.assert_allclose(a, 9.81 * np.sin(np.radians(5.0)), rtol=1e-14)
    # the model's output is the same reading with φ̈ from its dynamics; a holding torque: φ̈ = 0
    phi = jnp.radians(5.0)
    tau_hold = -single.m_kg * single.g_m_s2 * single.com_m * jnp.sin(phi)
    x = LeanState(phi, jnp.asarray(0.0))
    np.testing.assert_allclose(single.dynamics(x, tau_hold), [0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(single.output(x, tau_hold), [0.0, 9.81 * np.sin(np.radians(5.0))],
                               atol=1e-12)
    # without it the body falls forward and the accelerometer also feels −h φ̈
    assert float(single.output(x, 0.0)[1]) < float(a) - 0.1
    # Two segments on a 2° ramp with joints at rest and the body held still: ω = θ̇1 = 0 and
    # a_x = g sin(θ1 + θ2 + θ3) minus the acceleration due to gravity torque (u cancels it here).
    x = jnp.array([0.01, 0.02, 0.0, 0.0])
    d = jnp.array([np.radians(2.0), 0.0, 0.0])
    phi = float(d[0] + x[0] + x[1])
    m1c1 = BODY.m_legs_kg * BODY.c_legs_m + BODY.m_trunk_kg * BODY.L2_m
    u_hold = -jnp.array([9.81 * (m1c1 * np.sin(float(d[0] + x[0]))
                                 + BODY.m_trunk_kg * BODY.c_trunk_m * np.sin(phi)),
                         9.81 * BODY.m_trunk_kg * BODY.c_trunk_m * np.sin(phi)])
    xdot = BODY.dynamics(x, GroundInput(u_hold, d))
    np.testing.assert_allclose(xdot, 0.0, atol=1e-12)
    y = BODY.output(x, GroundInput(u_hold, d))
    np.testing.assert_allclose(y[5], 9.81 * np.sin(phi), rtol=1e-12)


def test_statespace_export():
    sys = to_statespace(linearize(BODY, *upright()), inputs=list(TWO_SEGMENT_INPUTS),
                        outputs=list(TWO_SEGMENT_OUTPUTS), states=list(TWO_SEGMENT_STATES))
    assert isinstance(sys, control.StateSpace)
    assert sys.ninputs == 5 and sys.noutputs == 6 and sys.nstates == 4
    assert sys.input_labels[2] == "theta1" and sys.output_labels[5] == "a_x"


def test_body_parameters_are_leaves():
    """A parameter is a traced leaf: the linearization differentiates with respect to it."""
    dA = jax.jacfwd(lambda m: linearize(TwoSegmentBody(m_trunk_kg=m), *upright()).A)(51.0)
    assert np.abs(np.asarray(dA)).max() > 0.0
