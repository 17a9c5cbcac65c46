"""Medial and lateral models (F 2.3–2.19) and their planar forms (models/vestibular.py)."""

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from verticality import so3
from verticality.experiments import model_checks as mc
from verticality.models import pendulum, planar
from verticality.models import vestibular as V
from verticality.models.kinematics import RigidMotion, from_functions, still
from verticality.params import LATERAL_R_M, P13_HEAD, P13_PENDULUM

motion_of = from_functions


DT = 1e-3


_AXIS = jnp.array([0.6, 0.48, 0.64])


def _motion(t):
    """Closed-form head motion: rotation 0.5 sin 2t about a fixed tilted axis, centre shaking."""
    th, thd, thdd = 0.5 * jnp.sin(2 * t), 1.0 * jnp.cos(2 * t), -2.0 * jnp.sin(2 * t)
    a = jnp.stack([-1.8 * jnp.sin(3 * t), -0.9 * jnp.cos(3 * t), -1.25 * jnp.sin(5 * t)])
    return RigidMotion(so3.exp(_AXIS * th), _AXIS * thd, _AXIS * thdd, a)


def test_closed_form_motion_is_consistent():
    """ω of the test motion is vee(RᵀṘ) and ω̇ its derivative (so the checks below mean something)."""
    t = 0.3
    m = _motion(t)
    ref = motion_of(lambda s: jnp.stack([0.2 * jnp.sin(3 * s), 0.1 * jnp.cos(3 * s), 0.05 * jnp.sin(5 * s)]),
                    lambda s: _motion(s).R_I_B, t)
    for x, y in zip(m, ref, strict=True):
        np.testing.assert_allclose(x, y, atol=1e-12)


N = 1000


@functools.lru_cache(maxsize=1)
def _table():
    return V.tabulate(_motion, DT, N)


@functools.lru_cache(maxsize=1)
def _lateral_vs_medial():
    n = N
    table = _table()

    @jax.jit
    def run(table):
        p = P13_PENDULUM
        head0 = table.motion(0.0)
        _, med = V.simulate(V.driven(V.medial_dynamics, table.motion, p),
                            V.medial_rest_state(head0, p), DT, n, project=V.medial_project)

        def lateral(r):
            return V.simulate(V.driven(V.lateral_dynamics, table.motion, p, r),
                              V.lateral_rest_state(head0, p, r), DT, n,
                              project=V.lateral_project)[1]

        return med, jax.vmap(lateral)(jnp.array([0.0, LATERAL_R_M]))

    return jax.tree_util.tree_map(np.asarray, run(table))


def test_lateral_with_r0_equals_medial():
    med, lat = _lateral_vs_medial()
    for side in (lat.left, lat.right):
        assert np.max(np.abs(side.R_I_S[0] - med.pendulum.R_I_S)) <= 1e-12
        assert np.max(np.abs(side.omega_S_rad_s[0] - med.pendulum.omega_S_rad_s)) <= 1e-12


def test_lateral_pendula_differ_under_rotation():
    med, lat = _lateral_vs_medial()
    d_left = np.max(np.abs(lat.left.R_I_S[1] - med.pendulum.R_I_S))
    d_lr = np.max(np.abs(lat.left.R_I_S[1] - lat.right.R_I_S[1]))
    assert d_left > 1e-4 and d_lr > 1e-4


def test_tabulated_motion_matches_direct_evaluation():
    table = _table()
    direct_fn = jax.jit(_motion)
    for t in (0.0, 0.0035, 0.5, N * DT):
        direct, tab = direct_fn(t), table.motion(t)
        for a, b in zip(direct, tab, strict=True):
            np.testing.assert_allclose(a, b, atol=1e-13)


@pytest.mark.parametrize("which", ["medial", "lateral"])
def test_planar_equals_3d_restricted_to_plane(which):
    fn = mc._run_planar_medial if which == "medial" else mc._run_planar_lateral
    yp, y3 = (np.asarray(a) for a in fn(2000))
    assert np.max(np.abs(yp - y3)) < 1e-7
    assert np.ptp(yp[:, 0]) > 0.1  # the test motion is not trivial


def test_planar_lateral_pivot_acceleration_signs():
    """Left pivot (+r on y) sees the centripetal −r ω² along y and +r ω̇ along z (head level)."""
    pp = planar.PlanarParams()
    x = V.PlanarLateralState(*(jnp.asarray(v) for v in (0.0, 0.0, 0.0, 0.0, 0.0, 2.0)))
    u = planar.PlanarInput(jnp.asarray(0.0), jnp.asarray(0.0), jnp.asarray(0.0))
    r = 0.05
    aL = V._planar_pivot_acceleration_I(1.0, x, u, 3.0, r, 1.0, 1.0)
    aR = V._planar_pivot_acceleration_I(-1.0, x, u, 3.0, r, 1.0, 1.0)
    np.testing.assert_allclose(aL, (-r * 4.0, r * 3.0), atol=1e-15)
    np.testing.assert_allclose(aR, (r * 4.0, -r * 3.0), atol=1e-15)
    # F 2.19 (simplified): only the centripetal term
    aF = V._planar_pivot_acceleration_I(1.0, x, u, 3.0, r, 0.0, 1.0)
    np.testing.assert_allclose(aF, (-r * 4.0, 0.0), atol=1e-15)
    assert float(V.planar_lateral_dynamics(x, u, pp).omega_L_rad_s) != 0.0


def test_free_head_torque_free_motion_conserves_momentum_and_energy():
    hp = P13_HEAD._replace(J_H=jnp.array([0.1, 0.125, 0.16]))
    h0 = V.HeadState(so3.rot_x(0.3), jnp.array([1.0, 2.0, -0.5]))
    hf, _ = jax.jit(lambda h: V.simulate(lambda t, h: V.head_dynamics(h, jnp.zeros(3), hp), h, DT, 1000,
                                         project=V._project_head))(h0)
    L0 = h0.R_I_H @ (hp.J_H * h0.omega_H_rad_s)
    L1 = hf.R_I_H @ (hp.J_H * hf.omega_H_rad_s)
    np.testing.assert_allclose(L1, L0, atol=1e-10)
    E = lambda h: 0.5 * jnp.sum(hp.J_H * h.omega_H_rad_s**2)  # noqa: E731
    assert abs(E(hf) - E(h0)) < 1e-10
    assert np.max(np.abs(hf.omega_H_rad_s - h0.omega_H_rad_s)) > 0.1  # gyroscopic coupling acts


def test_free_head_drive_equals_kinematic_drive():
    """A free head's pendulum sees exactly the RigidMotion built from the head's state and input."""
    p, hp = P13_PENDULUM, P13_HEAD
    h = V.HeadState(so3.rot_y(0.2), jnp.array([0.3, -0.2, 0.1]))
    u = V.HeadInput(jnp.array([0.01, 0.02, -0.03]), jnp.array([1.0, 0.0, -2.0]))
    xs = pendulum.PendulumState(so3.rot_x(0.1), jnp.array([0.5, 0.0, 0.2]))
    free = V.lateral_dynamics(V.LateralState(xs, xs, h), u, p, hp=hp)
    kin = V.lateral_dynamics(V.LateralState(xs, xs), V.free_head_motion(h, u, hp), p)
    for a, b in zip(jax.tree_util.tree_leaves((free.left, free.right)),
                    jax.tree_util.tree_leaves((kin.left, kin.right)), strict=True):
        np.testing.assert_allclose(a, b, atol=1e-15)
    assert kin.head is None and free.head is not None


def test_still_tilted_head_outputs():
    p = P13_PENDULUM
    R = so3.rot_x(0.3)
    x = V.lateral_rest_state(still(R), p)
    phi = np.asarray(V.lateral_outputs(x, R))
    np.testing.assert_allclose(phi, [-0.3, 0.0, -0.3, 0.0], atol=1e-12)
    xm = V.medial_rest_state(still(so3.rot_y(0.3)), p)
    np.testing.assert_allclose(V.medial_outputs(xm, so3.rot_y(0.3)), [0.0, 0.3], atol=1e-12)


def test_mismatched_drive_is_refused():
    p = P13_PENDULUM
    xs = pendulum.PendulumState(jnp.eye(3), jnp.zeros(3))
    with pytest.raises(ValueError, match="free head"):
        V.medial_dynamics(V.MedialState(xs), V.HeadInput(jnp.zeros(3), jnp.zeros(3)), p, P13_HEAD)
    with pytest.raises(ValueError, match="head=None"):
        V.medial_dynamics(V.MedialState(xs, V.HeadState(jnp.eye(3), jnp.zeros(3))), still(), p)
    with pytest.raises(ValueError, match="multiple"):
        V.simulate(lambda t, x: x, jnp.zeros(1), DT, 10, every=3)
