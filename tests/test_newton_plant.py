"""The Lissajous plant and the Newton observer's sub-stepped model (models/lissajous_plant.py,
models/ramp_discretized.py): one model value, discretized."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from verticality.core.errors import InputError
from verticality.models import lissajous_plant as lp
from verticality.models.base import step_rk4
from verticality.models.planar import HeadInput, PlanarState
from verticality.simulation import trajectories as tr

P = lp.p11_head()


def _state(v):
    return PlanarState(*(jnp.asarray(a) for a in v))


def test_substepped_model_integrates_the_head_exactly():
    """Ramp inputs with the block's mean and first moment: the head's double integrator sees the
    exact velocity and position increments of the 25 held 1 ms torques."""
    rng = np.random.default_rng(1)
    tau = rng.normal(size=25) * 0.5
    u = HeadInput(jnp.asarray(tau), jnp.zeros(25), jnp.zeros(25))
    x0 = _state([0.0, 0.0, 0.05, 0.3])
    x1 = jax.jit(lambda x: lp.observer_model(P, 5).transition(x, u, 0.025))(x0)
    dt = 1e-3
    w, th = 0.3, 0.05
    for tk in tau:  # exact for piecewise-constant torque
        th += w * dt + 0.5 * tk / P.K_kg_m2 * dt**2
        w += tk / P.K_kg_m2 * dt
    np.testing.assert_allclose(float(x1.omega_H_rad_s), w, rtol=0, atol=1e-12)
    np.testing.assert_allclose(float(x1.theta_H_rad), th, rtol=0, atol=1e-12)
    # holding the sub-step means instead (no ramp) misses part of the position increment
    held = lp.observer_model(P, 5).transition(x0, u._replace(tau_Nm=jnp.repeat(
        jnp.asarray(tau).reshape(5, 5).mean(axis=1), 5)), 0.025)
    assert abs(float(held.theta_H_rad) - th) > 1e-9


def test_one_substep_per_sample_is_the_plant_step():
    rng = np.random.default_rng(2)
    u = HeadInput(*(jnp.asarray(rng.normal(size=5)) for _ in range(3)))
    x0 = _state([0.1, -0.2, 0.3, 0.4])
    xb = lp.observer_model(P, 5).transition(x0, u, 5e-3)
    xp = x0
    for i in range(5):
        xp = step_rk4(lp.plant(P), xp, jax.tree_util.tree_map(lambda a, i=i: a[i], u), 1e-3)
    np.testing.assert_allclose(np.stack(xb), np.stack(xp), rtol=0, atol=1e-15)
    with pytest.raises(InputError, match="multiple"):
        lp.observer_model(P, 4).transition(x0, u, 5e-3)


def test_pendulum_rests_at_the_gravito_inertial_angle():
    """Constant head-frame acceleration on an upright head: the reading settles at atan2(−a, g)."""
    u = HeadInput(jnp.zeros(25), jnp.full(25, 1.5), jnp.zeros(25))
    model = lp.observer_model(P, 5)
    f = jax.jit(lambda x: jax.lax.fori_loop(0, 400, lambda i, x: model.transition(x, u, 0.025), x))
    x = f(_state([0.0, 0.0, 0.0, 0.0]))
    np.testing.assert_allclose(float(model.output(x, u)[0]), float(np.arctan2(-1.5, P.g_m_s2)),
                               atol=1e-9)


def test_p11_parameters():
    assert P.m_kg == 0.05 and P.l_m == 0.1 and P.beta_Nms == 0.005
    np.testing.assert_allclose(P.J_kg_m2, 0.05 * 0.01)
    np.testing.assert_allclose(P.K_kg_m2, 100 * P.J_kg_m2)
    q = lp.p11_head(1.1)
    np.testing.assert_allclose([q.m_kg, q.beta_Nms, q.J_kg_m2, q.K_kg_m2],
                               [0.055, 0.0055, 0.055 * 0.01, 100 * 0.055 * 0.01])


def test_planar_trunk_is_the_lissajous_trajectory():
    """One Lissajous: the planar view's accelerations and tilt derivatives are the closed forms of
    P11's (x, z, Θ)(t), and equal the 3-D trajectory's a_I (y, z) and roll rate/acceleration."""
    t = np.array([0.0, 0.37, 1.7, 4.2])
    s = lp.trunk(t)
    A, w1, w2, w3 = 0.25, 0.5 * np.pi, np.pi, 2 * np.pi
    np.testing.assert_allclose(s.a_h_I_m_s2, -A * w1**2 * np.sin(w1 * t), rtol=1e-14, atol=1e-15)
    np.testing.assert_allclose(s.a_z_I_m_s2, -A * w2**2 * np.sin(w2 * t), rtol=1e-14, atol=1e-15)
    np.testing.assert_allclose(s.Theta_rad, A * np.pi * np.sin(w3 * t), rtol=1e-14, atol=1e-15)
    np.testing.assert_allclose(s.Theta_dot_rad_s, A * np.pi * w3 * np.cos(w3 * t), rtol=1e-14)
    np.testing.assert_allclose(s.Theta_ddot_rad_s2, -A * np.pi * w3**2 * np.sin(w3 * t), rtol=1e-14,
                               atol=1e-14)
    m = tr.sample(tr.lissajous(), t)
    np.testing.assert_allclose(np.asarray(m.a_I_m_s2)[:, 1], s.a_h_I_m_s2, atol=1e-14)
    np.testing.assert_allclose(np.asarray(m.a_I_m_s2)[:, 2], s.a_z_I_m_s2, atol=1e-14)
    np.testing.assert_allclose(np.asarray(m.omega_B_rad_s)[:, 0], s.Theta_dot_rad_s, atol=1e-14)
    np.testing.assert_allclose(np.asarray(m.omegadot_B_rad_s2)[:, 0], s.Theta_ddot_rad_s2,
                               atol=1e-13)
