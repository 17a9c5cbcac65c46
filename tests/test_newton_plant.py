"""The Lissajous plant and the Newton observer's sub-stepped model (models/lissajous_plant.py)."""

import jax
import jax.numpy as jnp
import numpy as np

from verticality.models import lissajous_plant as lp
from verticality.models.planar import PlanarState

P = lp.p11_params()


def test_substepped_model_integrates_the_head_exactly():
    """Ramp inputs with the block's mean and first moment: the head's double integrator sees the
    exact velocity and position increments of the 25 held 1 ms torques."""
    rng = np.random.default_rng(1)
    tau = rng.normal(size=25) * 0.5
    u = lp.HeadInput(jnp.asarray(tau), jnp.zeros(25), jnp.zeros(25))
    x0 = jnp.array([0.0, 0.0, 0.05, 0.3])
    x1 = jax.jit(lambda x: lp.block_transition_flat(x, u, P, 0.025, 5))(x0)
    dt = 1e-3
    w, th = 0.3, 0.05
    for tk in tau:  # exact for piecewise-constant torque
        th += w * dt + 0.5 * tk / P.K_kg_m2 * dt**2
        w += tk / P.K_kg_m2 * dt
    np.testing.assert_allclose(float(x1[3]), w, rtol=0, atol=1e-12)
    np.testing.assert_allclose(float(x1[2]), th, rtol=0, atol=1e-12)


def test_one_substep_per_sample_is_the_plant_step():
    rng = np.random.default_rng(2)
    u = lp.HeadInput(*(jnp.asarray(rng.normal(size=5)) for _ in range(3)))
    x0 = PlanarState(jnp.asarray(0.1), jnp.asarray(-0.2), jnp.asarray(0.3), jnp.asarray(0.4))
    xb = lp.block_transition_flat(jnp.stack(x0), u, P, 5e-3, 5)
    xp = x0
    for i in range(5):
        xp = lp.step(xp, jax.tree_util.tree_map(lambda a, i=i: a[i], u), P, 1e-3)
    np.testing.assert_allclose(np.asarray(xb), np.asarray(jnp.stack(xp)), rtol=0, atol=1e-14)


def test_pendulum_rests_at_the_gravito_inertial_angle():
    """Constant head-frame acceleration on an upright head: the reading settles at atan2(−a, g)."""
    u = lp.HeadInput(jnp.zeros(25), jnp.full(25, 1.5), jnp.zeros(25))
    f = jax.jit(lambda x: jax.lax.fori_loop(0, 400, lambda i, x: lp.block_transition_flat(
        x, u, P, 0.025, 5), x))
    x = f(jnp.zeros(4))
    np.testing.assert_allclose(float(x[0] - x[2]), float(np.arctan2(-1.5, P.g_m_s2)), atol=1e-9)


def test_p11_parameters_and_trajectory():
    assert P.m_kg == 0.05 and P.l_m == 0.1 and P.beta_Nms == 0.005
    np.testing.assert_allclose(P.J_kg_m2, 0.05 * 0.01)
    np.testing.assert_allclose(P.K_kg_m2, 100 * P.J_kg_m2)
    q = lp.p11_params(1.1)
    np.testing.assert_allclose([q.m_kg, q.beta_Nms, q.J_kg_m2, q.K_kg_m2],
                               [0.055, 0.0055, 0.055 * 0.01, 100 * 0.055 * 0.01])
    # Θ(t) = 0.25π sin 2πt: derivatives by autodiff agree with the closed forms
    t = 0.37
    th = lambda s: lp.lissajous(s).Theta_rad  # noqa: E731
    np.testing.assert_allclose(float(jax.grad(th)(t)), float(lp.lissajous(t).Theta_dot_rad_s))
    np.testing.assert_allclose(float(jax.grad(jax.grad(th))(t)), float(lp.lissajous(t).Theta_ddot_rad_s2))
