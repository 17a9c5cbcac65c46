"""F 3.10–3.18 (analysis/ambiguity.py) against the project's own pendulum model values."""

from __future__ import annotations

import itertools
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from verticality.analysis import ambiguity as am
from verticality.core import so3
from verticality.models.base import simulate
from verticality.models.kinematics import RigidMotion
from verticality.models.params import G_M_S2, P13_PENDULUM
from verticality.models.pendulum import Pendulum, PendulumState
from verticality.models.planar import FrameMotion, PlanarPendulum, head_frame_to_inertial
from verticality.models.planar import PendulumState as PlanarPendulumState

G = G_M_S2
TILTS_DEG = (-60.0, -30.0, 0.0, 20.0, 45.0, 60.0)
ACCS_G = (-1.0, -0.4, 0.0, 0.5, 1.0)
VERTICAL_G = (-0.3, 0.0, 0.3)


def _grid_3d():
    """Tilts ≤ 60° about both axes × head accelerations ≤ 1 g per horizontal axis, keeping the
    points where the pendulum hangs below the head's horizontal plane (f_z ≥ 0.1 g, else the
    otolith angle is not defined by a steady state of the F 2.8–2.9 reading)."""
    rows = []
    for tx, ty, ax, ay, az in itertools.product(TILTS_DEG, TILTS_DEG[::2], ACCS_G, ACCS_G[::2],
                                                VERTICAL_G):
        a = np.array([ax, ay, az]) * G
        if np.linalg.norm(a) > G * (1 + 1e-12):
            continue
        txr, tyr = math.radians(tx), math.radians(ty)
        f = np.asarray(am.specific_force_H(a, txr, tyr))
        if f[2] < 0.1 * G:
            continue
        rows.append((txr, tyr, *a))
    return np.array(rows)


def _head_rotation(theta_x, theta_y):
    """An R_IH with the tilt angles (Θ_x, Θ_y) of F 3.8–3.9 (and a yaw, which must not matter)."""
    u = am.up_H(theta_x, theta_y)  # row 3 of R_IH
    x = jnp.cross(jnp.array([0.0, 1.0, 0.0]), u)
    x = x / jnp.linalg.norm(x)
    y = jnp.cross(u, x)
    R_I_H = jnp.stack([x, y, u])  # rows: an orthonormal frame with row 3 = u
    return so3.exp(jnp.array([0.0, 0.0, 0.7])) @ R_I_H


@jax.jit
@jax.vmap
def _model_steady_state(row):
    """Otolith angles of the 3-D pendulum model value at its equilibrium on a still head with the
    tilt and head-frame acceleration of ``row``: Newton on the model's own ω̇ (zero ω) over the
    pendulum tilt R_HS = exp((α, β, 0)) (the smallest rotation from the head,
    docs/conventions.md)."""
    tx, ty, a_H = row[0], row[1], row[2:]
    R_I_H = _head_rotation(tx, ty)
    pend = Pendulum(P13_PENDULUM)
    u = RigidMotion(R_I_H, jnp.zeros(3), jnp.zeros(3), R_I_H @ a_H)

    def state(ab):
        return PendulumState(R_I_H @ so3.exp(jnp.array([ab[0], ab[1], 0.0])), jnp.zeros(3))

    def residual(ab):
        return pend.dynamics(state(ab), u).omega_S_rad_s[:2]

    def newton(ab, _):  # damped: steps of at most 0.2 rad, towards the hanging equilibrium
        step = jnp.linalg.solve(jax.jacfwd(residual)(ab), residual(ab))
        return ab - step * jnp.minimum(1.0, 0.2 / (jnp.max(jnp.abs(step)) + 1e-300)), None

    # two starts, the pendulum along the head's axis and hanging along gravity alone (the smallest
    # rotation taking the head's z axis to the world's up); keep the stable root
    up = R_I_H[2]
    axis = jnp.cross(jnp.array([0.0, 0.0, 1.0]), up)
    n = jnp.linalg.norm(axis)
    ab_world = (axis / jnp.where(n > 0, n, 1.0) * jnp.arccos(jnp.clip(up[2], -1.0, 1.0)))[:2]

    def solve(ab0):
        ab = jax.lax.scan(newton, ab0, None, length=60)[0]
        return ab, jnp.all(jnp.linalg.eigvals(jax.jacfwd(residual)(ab)).real < 0)

    ab_a, stable_a = solve(jnp.zeros(2))
    ab_b, stable_b = solve(ab_world)
    ab = jnp.where(stable_a, ab_a, ab_b)
    x = state(ab)
    return (pend.output(x, u), jnp.max(jnp.abs(pend.dynamics(x, u).omega_S_rad_s)),
            so3.tilt_angles(R_I_H), stable_a | stable_b)


def test_exact_forms_equal_the_pendulum_model_steady_state():
    rows = _grid_3d()
    assert len(rows) > 200
    phi_model, resid, tilt, stable = (np.asarray(v) for v in _model_steady_state(jnp.asarray(rows)))
    assert np.max(resid) < 1e-9  # a steady state of the model: no angular acceleration
    assert np.all(stable)  # the hanging one (the inverted pendulum is the other steady state)
    np.testing.assert_allclose(tilt, rows[:, :2], atol=1e-12)
    phi = np.asarray(am.otolith_angles(rows[:, 2:], rows[:, 0], rows[:, 1]))
    assert np.max(np.abs(phi - phi_model)) <= 1e-9
    a = np.asarray(am.head_acceleration(phi_model[:, 0], phi_model[:, 1], rows[:, 4], rows[:, 0],
                                        rows[:, 1]))
    assert np.max(np.abs(a - rows[:, 2:])) <= 1e-9
    th = np.asarray(am.head_tilt(phi_model[:, 0], phi_model[:, 1], rows[:, 2:]))
    assert np.max(np.abs(th - rows[:, :2])) <= 1e-9


def test_planar_exact_forms_equal_the_planar_pendulum_steady_state():
    pend = PlanarPendulum()
    th, ah, az = np.meshgrid(np.radians(np.linspace(-60, 60, 13)), np.linspace(-G, G, 11),
                             np.array([-0.3, 0.0, 0.3]) * G, indexing="ij")
    th, ah, az = th.ravel(), ah.ravel(), az.ravel()
    keep = az + G * np.cos(th) > 0.1 * G
    th, ah, az = th[keep], ah[keep], az[keep]

    def steady(theta_H, a_h, a_z):
        a_h_I, a_z_I = head_frame_to_inertial(a_h, a_z, theta_H)
        frame = FrameMotion(theta_H, 0.0, a_h_I, a_z_I)

        def acc(theta_S):
            return pend.dynamics(PlanarPendulumState(theta_S, 0.0), frame).omega_rad_s

        def newton(s, _):  # damped
            step = acc(s) / jax.grad(acc)(s)
            return s - jnp.clip(step, -0.2, 0.2), None

        # two starts (hanging straight down, along the head's axis); keep the stable root
        s0 = jax.lax.scan(newton, jnp.asarray(0.0), None, length=60)[0]
        s1 = jax.lax.scan(newton, jnp.asarray(theta_H, float), None, length=60)[0]
        s = jnp.where(jax.grad(acc)(s0) < 0, s0, s1)
        return pend.output(PlanarPendulumState(s, 0.0), frame)[0], acc(s), jax.grad(acc)(s)

    r_model, resid, slope = (np.asarray(v) for v in jax.jit(jax.vmap(steady))(th, ah, az))
    assert np.max(np.abs(resid)) < 1e-9
    assert np.all(slope < 0)  # the stable (hanging) steady state
    d = np.asarray(am.planar_reading(ah, az, th)) - r_model
    assert np.max(np.abs(np.angle(np.exp(1j * d)))) <= 1e-9  # θ_S and θ_S + 2π are one state
    assert np.max(np.abs(am.planar_head_acceleration(r_model, az, th) - ah)) <= 1e-9
    unique = np.hypot(ah, az) < G  # the tilt is unique only for |a| < g (head_tilt)
    assert np.max(np.abs(am.planar_head_tilt(r_model, ah, az) - th)[unique]) <= 1e-9


def test_round_trips():
    rng = np.random.default_rng(18)
    n = 2000
    tilt = rng.uniform(-math.radians(60), math.radians(60), (n, 2))
    a = rng.uniform(-1, 1, (n, 3)) * np.array([G, G, 0.3 * G])
    f_z = np.asarray(am.specific_force_H(a, tilt[:, 0], tilt[:, 1]))[:, 2]
    ok = f_z > 0.1 * G
    tilt, a = tilt[ok], a[ok]
    phi = am.otolith_angles(a, tilt[:, 0], tilt[:, 1])
    back = np.asarray(am.head_acceleration(phi[:, 0], phi[:, 1], a[:, 2], tilt[:, 0], tilt[:, 1]))
    assert np.max(np.abs(back - a)) <= 1e-12 * G * 10
    # acceleration → angles → acceleration, relative to the acceleration's scale
    assert np.max(np.abs(back - a) / G) <= 1e-12
    small = np.linalg.norm(a, axis=1) < 0.99 * G
    t_back = np.asarray(am.head_tilt(phi[small, 0], phi[small, 1], a[small]))
    assert np.max(np.abs(t_back - tilt[small])) <= 1e-12
    # planar
    r = am.planar_reading(a[:, 1], a[:, 2], tilt[:, 0])
    ok = a[:, 2] + G * np.cos(tilt[:, 0]) > 0.1 * G
    assert (np.max(np.abs(am.planar_head_acceleration(r, a[:, 2], tilt[:, 0]) - a[:, 1])[ok]) / G
            <= 1e-12)


@pytest.mark.parametrize("theta_deg", [0.0, 20.0])
def test_small_angle_forms_agree_to_second_order(theta_deg):
    """F 3.12/3.17–3.18 against the exact forms: the error is O(ε²) (halving ε quarters it or
    better) with the pendulum angle, the other tilt and the vertical acceleration all O(ε)."""
    errs = []
    for eps in (0.02, 0.01, 0.005):
        phi_x, phi_y = 0.7 * eps, -1.1 * eps
        a_z = 0.5 * eps * G
        tx, ty = math.radians(theta_deg) + 0.3 * eps, -0.8 * eps
        exact = np.asarray(am.head_acceleration(phi_x, phi_y, a_z, tx, ty))
        small = np.asarray(am.head_acceleration(phi_x, phi_y, a_z, tx, ty, small_angle=True))
        # F 3.17–3.18 treat each plane alone: with a large tilt about x only the in-plane
        # component (a_y) is second order (a_x is off by g (φ_y + Θ_y)(1 − cos Θ_x), first order)
        comps = slice(None) if theta_deg == 0.0 else slice(1, 3)
        errs.append(np.max(np.abs(exact - small)[comps]))
        # the planar F 3.17 and the inverse direction as well
        a_h = -G * math.sin(tx) + eps * G  # a small reading on a tilted head
        r_exact = am.planar_reading(a_h, a_z, tx)
        r_small = am.planar_reading(a_h, a_z, tx, small_angle=True)
        errs[-1] = max(errs[-1], float(abs(r_exact - r_small)) * G)
        assert errs[-1] <= 3.0 * G * eps**2
    assert errs[1] <= 0.3 * errs[0] and errs[2] <= 0.3 * errs[1]
    # F 3.12: upright, a_z = 0: a ≈ −g φ (the model's sign), to third order
    phi = 0.01
    assert abs(am.head_acceleration(0.0, phi, small_angle=True)[0] + G * phi) < G * phi**3
    assert abs(am.head_acceleration(0.0, phi)[0] + G * math.tan(phi)) < 1e-12


def test_still_upright_head_reads_zero_acceleration():
    pend = Pendulum(P13_PENDULUM)
    still = RigidMotion(jnp.eye(3), jnp.zeros(3), jnp.zeros(3), jnp.zeros(3))
    x0 = pend.rest_state(still)
    x1 = simulate(pend, x0, lambda t: still, 1e-3, 500)[0]
    for x in (x0, x1):
        phi = pend.output(x, still)
        a = np.asarray(am.head_acceleration(phi[0], phi[1]))
        assert np.max(np.abs(a)) < 1e-12
    # a tilted still head read under the upright assumption: g tan Θ, the ambiguity itself
    tilt = math.radians(10.0)
    err = float(am.upright_assumption_error_m_s2(tilt, 0.0))
    assert err == pytest.approx(G * math.tan(tilt), rel=1e-12)


def test_planar_equals_3d_restricted_to_the_plane():
    th = np.radians(np.linspace(-50, 50, 11))[:, None]
    ah = np.linspace(-0.8, 0.8, 7)[None, :] * G
    az = 0.2 * G
    # coronal plane: rotations about x, h = y
    a3 = np.stack(np.broadcast_arrays(0.0 * ah, ah, az + 0.0 * ah), -1)
    phi = np.asarray(am.otolith_angles(a3, th, 0.0))
    r = np.asarray(am.planar_reading(ah, az, th))
    np.testing.assert_allclose(phi[..., 0], r, atol=1e-14)
    np.testing.assert_allclose(phi[..., 1], 0.0, atol=1e-14)
    a_back = np.asarray(am.head_acceleration(phi[..., 0], phi[..., 1], az, th, 0.0))
    np.testing.assert_allclose(a_back[..., 1], am.planar_head_acceleration(r, az, th), atol=1e-12)
    for small in (False, True):
        np.testing.assert_allclose(
            np.asarray(am.head_acceleration(r, 0.0, az, th, 0.0, small_angle=small))[..., 1],
            am.planar_head_acceleration(r, az, th, small_angle=small), atol=1e-12)
    # sagittal plane: rotations about y, h = −x (models/planar.py), via sagittal_to_planar
    a3 = np.stack(np.broadcast_arrays(ah, 0.0 * ah, az + 0.0 * ah), -1)
    phi = np.asarray(am.otolith_angles(a3, 0.0, th))
    r, th_p, ah_p = am.sagittal_to_planar(phi[..., 1], th, ah)
    np.testing.assert_allclose(r, am.planar_reading(ah_p, az, th_p), atol=1e-14)
    np.testing.assert_allclose(phi[..., 0], 0.0, atol=1e-14)
    np.testing.assert_allclose(
        -np.asarray(am.planar_head_acceleration(r, az, th_p, small_angle=True)),
        np.asarray(am.head_acceleration(0.0, phi[..., 1], az, 0.0, th, small_angle=True))[..., 0],
        atol=1e-12)


def test_printed_equations_hold_with_the_stated_sign_conventions():
    """F 3.14 and 3.16 as printed, with φ_F = −φ_y, Θ_F = −Θ_y and a_z,F = −a_z (module doc)."""
    ty, ax, az = math.radians(12.0), 2.5, 1.2
    phi_y = float(am.otolith_angles(np.array([ax, 0.0, az]), 0.0, ty)[1])
    phi_F, theta_F, az_F = -phi_y, -ty, -az
    assert az_F * math.sin(phi_F) + ax * math.cos(phi_F) == pytest.approx(
        G * math.sin(phi_F + theta_F), abs=1e-12)
    phi0 = float(am.otolith_angles(np.array([ax, 0.0, az]))[1])
    assert ax == pytest.approx((G - (-az)) * math.tan(-phi0), abs=1e-12)
    # and with a_z up as printed, (g − a_z) is wrong
    assert abs(ax - (G - az) * math.tan(-phi0)) > 0.5
