"""The 3-D damped spherical pendulum on a moving pivot (models/pendulum.py; F 2.5, 2.11)."""

import functools

import jax
import jax.numpy as jnp
import numpy as np

from verticality.core import so3
from verticality.models import base, pendulum
from verticality.models.kinematics import RigidMotion, from_functions, still
from verticality.models.params import G_M_S2, P13_PENDULUM

motion_of = from_functions


DT = 1e-3
N = 2000  # 2 s per run: one compiled batch serves every simulation below


@functools.partial(jax.jit, static_argnames=("n",))
def _batch(R_I_S0, omega_S0, a_I, beta, n=N):
    """Medial pendulum in a still, level head with centre acceleration a_I; full states."""

    def one(R0, w0, a, b):
        model = pendulum.Pendulum(P13_PENDULUM._replace(beta_Nms=b))
        head = RigidMotion(jnp.eye(3), jnp.zeros(3), jnp.zeros(3), a)
        x0 = pendulum.PendulumState(R0, w0)
        xf, xs = base.simulate(model, x0, lambda t: head, DT, n)
        return xs, xf

    return jax.vmap(one)(R_I_S0, omega_S0, a_I, beta)


def _cases():
    p = P13_PENDULUM
    beta_crit = 2.0 * float(p.J_pivot_S[0]) * np.sqrt(G_M_S2 / p.l_m)  # critical damping
    z = jnp.zeros(3)
    return [  # R_IS0, omega0, a_I, beta
        (so3.rot_x(0.01), z, z, 0.0),  # small oscillation
        (so3.exp(jnp.array([0.5, 0.3, 0.0])), jnp.array([1.0, 0.0, 5.0]), z, 0.0),  # 3-D, energy
        (jnp.eye(3), z, jnp.array([3.0, 0.0, 0.0]), beta_crit),  # constant acceleration
        (jnp.eye(3), z, jnp.array([0.0, -2.0, 0.0]), beta_crit),
    ]


@functools.lru_cache(maxsize=1)
def _results():
    cases = _cases()
    args = [jnp.stack([c[i] for c in cases]) for i in range(3)] + [jnp.array([c[3] for c in cases])]
    xs, xf = _batch(*args)
    return jax.tree_util.tree_map(np.asarray, xs), jax.tree_util.tree_map(np.asarray, xf)


def test_energy_conserved_undamped_3d():
    xs, _ = _results()
    p = P13_PENDULUM
    E = np.asarray(jax.vmap(lambda R, w: pendulum.energy_J(pendulum.PendulumState(R, w), p))(
        xs.R_I_S[1], xs.omega_S_rad_s[1]))
    scale = E[0] + p.m_kg * G_M_S2 * p.l_m  # energy above the minimum
    assert np.max(np.abs(E - E[0])) / scale < 1e-6
    # the motion really is 3-D (both swing axes move); the spin about the symmetry axis of this
    # axisymmetric pendulum is a constant of motion (Lagrange top), which the integrator keeps
    w = xs.omega_S_rad_s[1]
    assert np.ptp(w[:, 0]) > 0.5 and np.ptp(w[:, 1]) > 0.5
    assert np.ptp(w[:, 2]) < 1e-9


def test_rest_state_is_equilibrium():
    p = P13_PENDULUM
    head = RigidMotion(so3.exp(jnp.array([0.2, -0.1, 0.4])), jnp.zeros(3), jnp.zeros(3),
                       jnp.array([1.0, 2.0, -0.5]))
    x = pendulum.rest_state(head, p)
    assert np.max(np.abs(pendulum.angular_acceleration(x, head, p))) < 1e-12


def test_pivot_acceleration_matches_second_derivative_of_pivot_position():
    """F 2.11's Euler and centripetal terms: a_P = d²/dt² (p_C + R_IH r) by autodiff."""
    r = jnp.array([0.01, 0.05, -0.02])
    pos = lambda t: jnp.stack([0.3 * jnp.sin(t), 0.1 * t**2, jnp.cos(2 * t)])  # noqa: E731
    R = lambda t: so3.exp(jnp.stack([0.4 * jnp.sin(1.3 * t), 0.7 * t, -0.2 * t**2]))  # noqa: E731
    t = 0.7
    head = motion_of(pos, R, t)
    p = P13_PENDULUM._replace(pivot_H_m=r)
    pivot = lambda s: pos(s) + R(s) @ r  # noqa: E731
    vel = lambda s: jax.jvp(pivot, (s,), (1.0,))[1]  # noqa: E731
    acc = jax.jvp(vel, (t,), (1.0,))[1]
    np.testing.assert_allclose(pendulum.pivot_acceleration_I(head, p), acc, atol=1e-12)
    # simplified form (F 2.12): the Euler term is dropped, the centripetal one kept
    ps = p.simplified()
    euler_I = head.R_I_B @ jnp.cross(head.omegadot_B_rad_s2, r)
    np.testing.assert_allclose(pendulum.pivot_acceleration_I(head, ps), acc - euler_I, atol=1e-12)


def test_simplified_drops_gyroscopic_term():
    p = P13_PENDULUM
    x = pendulum.PendulumState(so3.rot_x(0.3), jnp.array([1.0, -2.0, 4.0]))
    head = still()
    full = pendulum.angular_acceleration(x, head, p)
    simp = pendulum.angular_acceleration(x, head, p.simplified())
    w, J = x.omega_S_rad_s, p.J_pivot_S
    np.testing.assert_allclose(simp - full, jnp.cross(w, J * w) / J, rtol=1e-12)
    assert np.max(np.abs(simp - full)) > 1.0


