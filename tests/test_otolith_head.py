"""The head and its otoliths as model values (models/head.py, pendulum.Pendulum, otolith_head.py),
checked against physics that does not go through them: rest, conservation laws, the planar model,
and the composition of their component values."""

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from verticality.core import so3
from verticality.models import base, planar
from verticality.models import otolith_head as oh
from verticality.models.head import FreeHead, HeadInput, HeadState
from verticality.models.kinematics import RigidMotion, still
from verticality.models.params import (
    G_M_S2,
    LATERAL_R_M,
    P13_EKF_HEAD,
    P13_EKF_PENDULUM,
    P13_HEAD,
    P13_PENDULUM,
    HeadParams,
    lateral_pendulums,
)
from verticality.models.pendulum import Pendulum, PendulumState

RNG = np.random.default_rng(7)


def _random_state(n_pendula, rng=RNG):
    def pend():
        return PendulumState(so3.exp(jnp.asarray(rng.normal(size=3))),
                             jnp.asarray(rng.normal(size=3)))

    head = HeadState(so3.exp(jnp.asarray(rng.normal(size=3))), jnp.asarray(rng.normal(size=3)))
    return oh.OtolithHeadState(tuple(pend() for _ in range(n_pendula)), head)


def _random_input(rng=RNG):
    return HeadInput(jnp.asarray(0.1 * rng.normal(size=3)), jnp.asarray(3.0 * rng.normal(size=3)))


def test_models_follow_the_interface():
    for m in (oh.medial(P13_PENDULUM, P13_HEAD), oh.lateral(P13_PENDULUM, P13_HEAD, gyro=True),
              FreeHead(P13_HEAD), Pendulum(P13_PENDULUM), oh.Otoliths((Pendulum(P13_PENDULUM),))):
        assert isinstance(m, base.Model)


@pytest.mark.parametrize("kind", ["medial", "lateral"])
def test_value_is_the_composition_of_its_components(kind):
    """ẋ of the head–otolith value: the free head's F 2.3–2.4 and each pendulum under the head's
    RigidMotion built by hand from the state and the input."""
    hp = P13_HEAD._replace(J_H=jnp.array([0.1, 0.125, 0.16]))
    m = oh.medial(P13_PENDULUM, hp) if kind == "medial" else oh.lateral(P13_PENDULUM, hp)
    for _ in range(3):
        x = _random_state(len(m.pendula))
        u = _random_input()
        dx = m.dynamics(x, u)
        w, J = x.head.omega_H_rad_s, hp.J_H
        wdot = (u.tau_H_Nm - jnp.cross(w, J * w)) / J
        np.testing.assert_allclose(dx.head.omega_H_rad_s, wdot, rtol=1e-13)
        np.testing.assert_allclose(dx.head.R_I_H, x.head.R_I_H @ so3.hat(w), rtol=1e-13)
        motion = RigidMotion(x.head.R_I_H, w, wdot, u.a_I_m_s2)
        for p, xp, dp in zip(m.pendula, x.pendula, dx.pendula, strict=True):
            ref = p.dynamics(xp, motion)
            for a, b in zip(dp, ref, strict=True):
                np.testing.assert_allclose(a, b, rtol=1e-13, atol=1e-15)


def test_rest_is_an_equilibrium_of_the_medial_and_lateral_models():
    for m in (oh.medial(P13_PENDULUM, P13_HEAD), oh.lateral(P13_PENDULUM, P13_HEAD)):
        R = so3.exp(jnp.array([0.2, -0.3, 0.5]))
        x = m.rest_state(still(R))
        dx = m.dynamics(x, HeadInput(jnp.zeros(3), jnp.zeros(3)))
        for d in dx.pendula:
            assert np.max(np.abs(d.omega_S_rad_s)) < 1e-12
        assert np.max(np.abs(dx.head.omega_H_rad_s)) == 0.0


def test_still_tilted_head_reads_minus_tilt_and_the_gyro():
    m = oh.lateral(P13_PENDULUM, P13_HEAD, gyro=True)
    x = m.rest_state(still(so3.rot_x(0.3)))
    np.testing.assert_allclose(m.output(x), [-0.3, 0.0, -0.3, 0.0, 0.0, 0.0, 0.0], atol=1e-12)
    assert m.angle_outputs == (0, 1, 2, 3)
    assert oh.medial(P13_PENDULUM, P13_HEAD).output(x._replace(pendula=x.pendula[:1])).shape == (2,)


def test_torque_free_head_conserves_momentum_and_energy():
    """Torque-free free head (gyroscopic term on): R_IH J ω and ½ωᵀJω are constants of motion."""
    head = FreeHead(P13_HEAD._replace(J_H=jnp.array([0.1, 0.125, 0.16])))
    h0 = HeadState(so3.rot_x(0.3), jnp.array([1.0, 2.0, -0.5]))
    u = HeadInput(jnp.zeros(3), jnp.zeros(3))
    hf, _ = jax.jit(lambda h: base.simulate(head, h, lambda t: u, 1e-3, 1000))(h0)
    J = head.params.J_H
    np.testing.assert_allclose(hf.R_I_H @ (J * hf.omega_H_rad_s), h0.R_I_H @ (J * h0.omega_H_rad_s),
                               atol=1e-10)
    E = lambda h: 0.5 * jnp.sum(J * h.omega_H_rad_s**2)  # noqa: E731
    assert abs(E(hf) - E(h0)) < 1e-10
    assert np.max(np.abs(hf.omega_H_rad_s - h0.omega_H_rad_s)) > 0.1  # the gyroscopic term acts
    np.testing.assert_allclose(head.torque(h0.omega_H_rad_s, head.angular_acceleration(
        h0.omega_H_rad_s, jnp.array([0.1, -0.2, 0.3]))), [0.1, -0.2, 0.3], rtol=1e-12)


def test_pendulum_on_free_head_dissipates_through_damping_only():
    """A still head (no torque, no acceleration): the pendulum's energy changes at −β|ω_S − ω_H|²
    (ω_H = 0), by forward-mode differentiation along the value's vector field."""
    m = oh.medial(P13_PENDULUM, P13_HEAD)
    x = _random_state(1)
    x = x._replace(head=x.head._replace(omega_H_rad_s=jnp.zeros(3)))
    u = HeadInput(jnp.zeros(3), jnp.zeros(3))
    dx = m.dynamics(x, u)
    _, dE = jax.jvp(lambda y: m.pendula[0].energy_J(y.pendula[0]), (x,), (dx,))
    w = np.asarray(x.pendula[0].omega_S_rad_s)
    np.testing.assert_allclose(float(dE), -P13_PENDULUM.beta_Nms * w @ w, rtol=1e-12)


def _planar_params(p, hp):
    return planar.PlanarHead(m_kg=p.m_kg, l_m=p.l_m, J_kg_m2=p.J_pivot_S[0], beta_Nms=p.beta_Nms,
                               K_kg_m2=hp.J_H[0], g_m_s2=G_M_S2)


def test_medial_restricted_to_the_coronal_plane_is_the_planar_model():
    """In the y–z plane (rotations about x) the 3-D value's rates equal the planar model's
    (F p. 36), which is written independently in :mod:`verticality.models.planar`."""
    p, hp = P13_PENDULUM, P13_HEAD
    m = oh.medial(p, hp)
    pp = _planar_params(p, hp)
    ex = jnp.array([1.0, 0.0, 0.0])
    for _ in range(5):
        th_s, w_s, th_h, w_h, tau, ah, az = RNG.normal(size=7)
        x = oh.OtolithHeadState((PendulumState(so3.rot_x(th_s), w_s * ex),),
                                HeadState(so3.rot_x(th_h), w_h * ex))
        dx = m.dynamics(x, HeadInput(tau * ex, jnp.array([0.0, ah, az])))
        ref = pp.dynamics(planar.PlanarState(th_s, w_s, th_h, w_h),
                                 planar.PlanarInput(tau, ah, az))
        np.testing.assert_allclose(dx.pendula[0].omega_S_rad_s, [ref.omega_S_rad_s, 0, 0],
                                   rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(dx.head.omega_H_rad_s, [ref.omega_H_rad_s, 0, 0], rtol=1e-13)


def test_lateral_with_zero_offset_is_two_medial_pendula():
    x = _random_state(2)
    u = _random_input()
    lat = oh.lateral(P13_PENDULUM, P13_HEAD, r_m=0.0).dynamics(x, u)
    med = oh.medial(P13_PENDULUM, P13_HEAD)
    for i in range(2):
        ref = med.dynamics(x._replace(pendula=x.pendula[i:i + 1]), u).pendula[0]
        for a, b in zip(lat.pendula[i], ref, strict=True):
            np.testing.assert_array_equal(a, b)
    left, right = oh.lateral(P13_PENDULUM, P13_HEAD).pendula
    np.testing.assert_array_equal(left.params.pivot_H_m, [0.0, LATERAL_R_M, 0.0])
    np.testing.assert_array_equal(right.params.pivot_H_m, [0.0, -LATERAL_R_M, 0.0])


def test_retract_and_difference_are_inverse():
    m = oh.lateral(P13_PENDULUM, P13_HEAD, gyro=True)
    x = _random_state(2)
    dx = jnp.asarray(0.3 * RNG.normal(size=18))
    np.testing.assert_allclose(m.difference(m.retract(x, dx), x), dx, atol=1e-12)
    assert base.tangent_dim(m, x) == 18
    xp = m.project(m.retract(x, dx))
    for R in (xp.pendula[0].R_I_S, xp.pendula[1].R_I_S, xp.head.R_I_H):
        assert float(so3.orthonormality_error(R)) < 1e-13


def test_parameters_are_leaves():
    """A value goes through jit and vmap: its parameters are traced (one compile for both)."""
    models = [oh.medial(P13_PENDULUM, P13_HEAD, gyro=True),
              oh.medial(P13_EKF_PENDULUM, P13_EKF_HEAD, gyro=True)]
    stacked = jax.tree_util.tree_map(lambda *a: jnp.stack(a), *models)
    x = _random_state(1)
    u = _random_input()
    out = jax.jit(jax.vmap(lambda m: m.dynamics(x, u).pendula[0].omega_S_rad_s))(stacked)
    for i, m in enumerate(models):
        np.testing.assert_allclose(out[i], m.dynamics(x, u).pendula[0].omega_S_rad_s, rtol=1e-14)
    assert not np.allclose(out[0], out[1])


def test_head_frame_acceleration_adapter_rotates_the_input():
    m = oh.medial(P13_PENDULUM, HeadParams())
    adapted = oh.HeadFrameAcceleration(m)
    x = _random_state(1)
    u = _random_input()
    a_H = x.head.R_I_H.T @ u.a_I_m_s2
    d1 = adapted.dynamics(x, oh.HeadFrameInput(u.tau_H_Nm, a_H))
    d0 = m.dynamics(x, u)
    for a, b in zip(jax.tree_util.tree_leaves(d1), jax.tree_util.tree_leaves(d0), strict=True):
        np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-14)


# ------------------------------------------------------------------ driven by a head motion
DT = 1e-3
N = 1000
_AXIS = jnp.array([0.6, 0.48, 0.64])


def _motion(t):
    """Closed-form head motion: rotation 0.5 sin 2t about a fixed tilted axis, centre shaking."""
    th, thd, thdd = 0.5 * jnp.sin(2 * t), 1.0 * jnp.cos(2 * t), -2.0 * jnp.sin(2 * t)
    a = jnp.stack([-1.8 * jnp.sin(3 * t), -0.9 * jnp.cos(3 * t), -1.25 * jnp.sin(5 * t)])
    return RigidMotion(so3.exp(_AXIS * th), _AXIS * thd, _AXIS * thdd, a)


def _rk4(model, x0, u_of_t, n, dt=DT):
    """RK4 with the input evaluated at every stage time (a time-varying drive); states after each
    step."""
    from verticality.core.integrate import rk4_step

    def body(x, k):
        x = rk4_step(lambda t, xx: model.dynamics(xx, u_of_t(t)), k * dt, x, dt,
                     project=model.project)
        return x, x

    return jax.lax.scan(body, x0, jnp.arange(n))


def test_closed_form_motion_is_consistent():
    """ω of the test motion is vee(RᵀṘ) and ω̇ its derivative (so the checks below mean
    something)."""
    from verticality.models.kinematics import from_functions

    t = 0.3
    m = _motion(t)
    ref = from_functions(lambda s: jnp.stack([0.2 * jnp.sin(3 * s), 0.1 * jnp.cos(3 * s),
                                              0.05 * jnp.sin(5 * s)]),
                         lambda s: _motion(s).R_I_B, t)
    for x, y in zip(m, ref, strict=True):
        np.testing.assert_allclose(x, y, atol=1e-12)


@functools.lru_cache(maxsize=1)
def _table():
    from verticality.models.kinematics import tabulate

    return tabulate(_motion, DT, N)


@functools.lru_cache(maxsize=1)
def _lateral_vs_medial():
    @jax.jit
    def run(table):
        med = oh.Otoliths((Pendulum(P13_PENDULUM),))
        head0 = table.motion(0.0)
        _, xm = _rk4(med, med.rest_state(head0), table.motion, N)

        def lateral(r):
            lat = oh.Otoliths(tuple(Pendulum(p) for p in lateral_pendulums(P13_PENDULUM, r)))
            return _rk4(lat, lat.rest_state(head0), table.motion, N)[1]

        return xm, jax.vmap(lateral)(jnp.array([0.0, LATERAL_R_M]))

    return jax.tree_util.tree_map(np.asarray, run(_table()))


def test_lateral_pendula_differ_under_rotation():
    (med,), (left, right) = _lateral_vs_medial()
    assert np.max(np.abs(left.R_I_S[1] - med.R_I_S)) > 1e-4
    assert np.max(np.abs(left.R_I_S[1] - right.R_I_S[1])) > 1e-4


def test_tabulated_motion_matches_direct_evaluation():
    table = _table()
    direct_fn = jax.jit(_motion)
    for t in (0.0, 0.0035, 0.5, N * DT):
        for a, b in zip(direct_fn(t), table.motion(t), strict=True):
            np.testing.assert_allclose(a, b, atol=1e-13)


def test_free_head_drive_equals_kinematic_drive():
    """A free head's pendula see exactly the RigidMotion built from the head's state and input."""
    hp = P13_HEAD
    h = HeadState(so3.rot_y(0.2), jnp.array([0.3, -0.2, 0.1]))
    u = HeadInput(jnp.array([0.01, 0.02, -0.03]), jnp.array([1.0, 0.0, -2.0]))
    xs = PendulumState(so3.rot_x(0.1), jnp.array([0.5, 0.0, 0.2]))
    m = oh.lateral(P13_PENDULUM, hp)
    free = m.dynamics(oh.OtolithHeadState((xs, xs), h), u)
    kin = m.otoliths.dynamics((xs, xs), FreeHead(hp).motion(h, u))
    for a, b in zip(jax.tree_util.tree_leaves(free.pendula), jax.tree_util.tree_leaves(kin),
                    strict=True):
        np.testing.assert_allclose(a, b, atol=1e-15)


# ------------------------------------------------------------------ the coronal plane (F 2.19)
TH_S0, W_S0, TH_H0, W_H0, TH_R0 = 0.3, -0.5, 0.1, 0.05, -0.2


def test_planar_lateral_pivot_acceleration_signs():
    """Left pivot (+r on y) sees the centripetal −r ω² along y and +r ω̇ along z (head level)."""
    r = 0.05
    m = oh.PlanarLateral(planar.PlanarHead(), r)
    x = oh.PlanarLateralState(*(jnp.asarray(v) for v in (0.0, 0.0, 0.0, 0.0, 0.0, 2.0)))
    u = planar.PlanarInput(jnp.asarray(0.0), jnp.asarray(0.0), jnp.asarray(0.0))
    np.testing.assert_allclose(m.pivot_acceleration_I(1.0, x, u, 3.0), (-r * 4.0, r * 3.0),
                               atol=1e-15)
    np.testing.assert_allclose(m.pivot_acceleration_I(-1.0, x, u, 3.0), (r * 4.0, -r * 3.0),
                               atol=1e-15)
    # F 2.19 (simplified): only the centripetal term
    f219 = oh.PlanarLateral(planar.PlanarHead(), r, euler=0.0)
    np.testing.assert_allclose(f219.pivot_acceleration_I(1.0, x, u, 3.0), (-r * 4.0, 0.0),
                               atol=1e-15)
    assert float(m.dynamics(x, u).omega_L_rad_s) != 0.0
    np.testing.assert_allclose(m.output(x._replace(theta_L_rad=jnp.asarray(0.2))), [0.2, 0.0])
