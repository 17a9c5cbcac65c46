"""The canal model values (models/canal.py): frequency response against the transfer function, by
linearization (→ control.StateSpace) and by simulating a sinusoid; the high-pass step response."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from verticality.core.errors import InputError
from verticality.models import canal
from verticality.models.base import simulate
from verticality.models.linearize import linearize, to_statespace

CANALS = {
    "torsion": canal.torsion_pendulum(5.7, 0.005),
    "torsion-F1.3": canal.torsion_pendulum_from_coefficients(1.0, 10.0, 1.0),
    "high-pass": canal.high_pass(5.7),
    "adapting": canal.high_pass(5.7, 80.0),
}
FREQS_HZ = np.array([0.002, 0.01, 0.03, 0.1, 0.3, 1.0, 3.0, 10.0])


@pytest.mark.parametrize("name", CANALS)
def test_linearized_model_is_the_transfer_function(name):
    model = CANALS[name]
    lin = linearize(model, model.rest_state(), jnp.zeros(3))
    sys = to_statespace(lin)
    s = 2j * np.pi * FREQS_HZ
    h = np.array([np.asarray(sys(si))[0, 0] for si in s])  # canal x responds to ω_x
    np.testing.assert_allclose(h, canal.transfer_function(model, s), rtol=1e-9, atol=1e-12)
    # the three canals are independent: ω_x does not reach canal y
    assert abs(np.asarray(sys(s[3]))[1, 0]) < 1e-12


@pytest.mark.parametrize("name", ["torsion", "adapting"])
def test_simulated_sinusoid_has_the_transfer_functions_gain_and_phase(name):
    model = CANALS[name]
    f_hz, dt = 0.05, 0.01
    n = int(round(200 / f_hz / 10 / dt))  # ten periods
    w0 = 2 * np.pi * f_hz

    def u(t):
        return jnp.array([0.0, 0.0, jnp.sin(w0 * t)])

    h = 5e-4 if name == "torsion" else dt  # the torsion pendulum's short pole needs a fine step
    steps = int(round(n * dt / h))
    _, xs = jax.jit(lambda: simulate(model, model.rest_state(), u, h, steps))()
    t = (np.arange(steps) + 1) * h
    y = np.array(jax.vmap(lambda x, tt: model.output(x, u(tt)))(xs, jnp.asarray(t)))[:, 2]
    last = t >= t[-1] - 2 / f_hz  # the last two periods: the transient of τ = 5.7 s is gone
    basis = np.column_stack([np.sin(w0 * t[last]), np.cos(w0 * t[last])])
    (c_sin, c_cos), *_ = np.linalg.lstsq(basis, y[last], rcond=None)
    expected = canal.transfer_function(model, 1j * w0)
    np.testing.assert_allclose(c_sin + 1j * c_cos, expected, rtol=2e-3)


def test_high_pass_step_decays_with_tau():
    model = canal.high_pass(5.7)
    _, xs = simulate(model, model.rest_state(), lambda t: jnp.array([1.0, 0.0, 0.0]), 0.01, 1000)
    y = np.array(jax.vmap(lambda x: model.output(x, jnp.array([1.0, 0.0, 0.0])))(xs))[:, 0]
    t = (np.arange(1000) + 1) * 0.01
    np.testing.assert_allclose(y, np.exp(-t / 5.7), rtol=1e-8)


def test_bad_time_constants_are_refused():
    with pytest.raises(InputError):
        canal.high_pass(-1.0)
    with pytest.raises(InputError):
        canal.torsion_pendulum(0.1, 1.0)
