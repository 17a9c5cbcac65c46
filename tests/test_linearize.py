"""Linearization of model values by autodiff (F 4.10): finite differences, analytic entries, a
rotation state in tangent coordinates, the control.StateSpace export."""

from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import scipy.signal

from verticality.core import so3
from verticality.core.errors import InputError
from verticality.models import planar
from verticality.models.base import EuclideanState, model_dataclass
from verticality.models.linearize import (
    LinearModel,
    discretize_zoh,
    from_statespace,
    linearize,
    select_inputs,
    to_statespace,
)
from verticality.simulation.separation_loop import linear_model, plant


def _fd_jac(fun, z0, eps=1e-6):
    z0 = np.asarray(z0, float)
    cols = []
    for i in range(z0.size):
        dz = np.zeros_like(z0)
        dz[i] = eps
        cols.append((np.asarray(fun(z0 + dz)) - np.asarray(fun(z0 - dz))) / (2 * eps))
    return np.stack(cols, axis=-1)


def _planar(v):
    return planar.PlanarState(*(jnp.asarray(a) for a in v))


def test_matches_finite_differences_away_from_upright():
    model = plant()
    x0 = np.array([0.3, -2.0, 0.7, 1.5])
    u0 = np.array([0.2, 1.3, -0.4])

    def f(x, u):
        return np.stack(model.dynamics(_planar(x), planar.HeadInput(*(jnp.asarray(a) for a in u))))

    def h(x, u):
        return np.asarray(model.output(_planar(x)))

    m = linearize(model, _planar(x0), planar.HeadInput(*(jnp.asarray(a) for a in u0)))
    np.testing.assert_allclose(m.A, _fd_jac(lambda x: f(x, u0), x0), rtol=1e-6, atol=1e-4)
    np.testing.assert_allclose(m.B, _fd_jac(lambda u: f(x0, u), u0), rtol=1e-6, atol=1e-4)
    np.testing.assert_allclose(m.C, _fd_jac(lambda x: h(x, u0), x0), atol=1e-8)
    assert np.all(np.asarray(m.D) == 0.0)
    # and it is not trivially the upright matrix: the cos(θ_S) factor changed entries.
    assert not np.allclose(m.A, linear_model().A)
    assert np.abs(np.asarray(m.B[:, 2])).max() > 1.0  # ᴴa_z drives the tilted pendulum


def test_upright_entries_are_the_thesis_ratios():
    m = linear_model()
    A, B = np.asarray(m.A), np.asarray(m.B)
    assert B.shape == (4, 2)  # the observer's known inputs: τ and ᴴa_h
    assert A[1, 0] == pytest.approx(-3943.8)
    assert A[1, 1] == pytest.approx(-125.6)
    assert A[1, 3] == pytest.approx(125.6)
    assert B[3, 0] == pytest.approx(1.0 / 1e-4)
    assert B[1, 1] == pytest.approx(-3943.8 / 9.81)  # −1/l
    np.testing.assert_allclose(np.asarray(m.C), [[1.0, 0.0, -1.0, 0.0]])


def test_pytree_states_and_statespace_roundtrip():
    p = planar.PlanarHead()
    x0 = _planar([0.0] * 4)
    u0 = planar.PlanarInput(jnp.asarray(0.0), jnp.asarray(0.0), jnp.asarray(0.0))
    m = linearize(p, x0, u0)
    assert m.A.shape == (4, 4) and m.B.shape == (4, 3) and m.C.shape == (1, 4)
    assert float(m.A[1, 0]) == pytest.approx(-p.m_kg * p.l_m * p.g_m_s2 / p.J_kg_m2)
    sys = to_statespace(m, inputs=["tau", "a_h", "a_z"])
    assert sys.input_labels == ["tau", "a_h", "a_z"]
    back = from_statespace(sys)
    for a, b in zip(m, back, strict=True):
        np.testing.assert_allclose(a, b)
    sel = select_inputs(m, [2, 0])
    np.testing.assert_array_equal(np.asarray(sel.B), np.asarray(m.B)[:, [2, 0]])


class HeadState(NamedTuple):
    R_I_H: jnp.ndarray
    omega_H_rad_s: jnp.ndarray


@model_dataclass
class FreeHead:
    """A free rigid head (Euler's equation) on SO(3), seen through gravity in the head frame."""

    J: Any

    def dynamics(self, x, tau):
        w = x.omega_H_rad_s
        return HeadState(x.R_I_H @ so3.hat(w), (tau - jnp.cross(w, self.J * w)) / self.J)

    def output(self, x, tau):
        return x.R_I_H.T @ jnp.array([0.0, 0.0, 1.0])

    def retract(self, x, dx):
        return HeadState(x.R_I_H @ so3.exp(dx[:3]), x.omega_H_rad_s + dx[3:])

    def difference(self, x1, x0):
        return jnp.concatenate([so3.log(x0.R_I_H.T @ x1.R_I_H),
                                x1.omega_H_rad_s - x0.omega_H_rad_s])

    def project(self, x):
        return HeadState(so3.orthonormalize(x.R_I_H), x.omega_H_rad_s)


def test_rotation_state_is_linearized_in_tangent_coordinates():
    """A 3-D head: 6 tangent coordinates (not the 12 of R and ω); the linear model predicts the
    tangent error of a short nonlinear flow from a perturbed start."""
    head = FreeHead(jnp.array([0.1, 0.12, 0.15]))
    x0 = HeadState(so3.exp(jnp.array([0.3, -0.2, 0.1])), jnp.array([0.5, -0.3, 0.8]))
    tau0 = jnp.array([0.01, 0.0, -0.02])
    m = linearize(head, x0, tau0)
    assert m.A.shape == (6, 6) and m.B.shape == (6, 3) and m.C.shape == (3, 6)
    # analytic blocks at any point: δθ̇ = −[ω]× δθ + δω, δω̇ = ∂(Euler)/∂ω δω + J⁻¹ δτ
    np.testing.assert_allclose(m.A[:3, :3], -np.asarray(so3.hat(x0.omega_H_rad_s)), atol=1e-12)
    np.testing.assert_allclose(m.A[:3, 3:], np.eye(3), atol=1e-12)
    np.testing.assert_allclose(m.B[3:], np.diag(1.0 / np.asarray(head.J)), atol=1e-12)
    # C: gravity in the head frame under R exp([δ]×): ∂(exp(−[δ]×) g_H)/∂δ = [g_H]×
    g_H = np.asarray(x0.R_I_H).T @ np.array([0.0, 0.0, 1.0])
    np.testing.assert_allclose(m.C[:, :3], np.asarray(so3.hat(jnp.asarray(g_H))), atol=1e-12)
    # first-order agreement with the nonlinear flow, in tangent coordinates
    dx = 1e-6 * np.array([1.0, -2.0, 0.5, 3.0, 1.0, -1.0])
    h = 1e-3

    def flow(x):
        k = head.dynamics(x, tau0)
        return head.project(HeadState(x.R_I_H + h * k.R_I_H, x.omega_H_rad_s + h * k.omega_H_rad_s))

    x1 = jax.jit(flow)(head.retract(x0, jnp.asarray(dx)))
    ref = jax.jit(flow)(x0)
    d1 = np.asarray(head.difference(x1, ref))
    pred = (np.eye(6) + h * np.asarray(m.A)) @ dx
    np.testing.assert_allclose(d1, pred, rtol=0, atol=1e-3 * np.abs(dx).max())


def test_zoh_matches_scipy():
    m = linear_model()
    Ad, Bd = discretize_zoh(m, 1e-3)
    ref = scipy.signal.cont2discrete(tuple(np.asarray(v) for v in m), 1e-3, method="zoh")
    np.testing.assert_allclose(Ad, ref[0], rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(Bd, ref[1], rtol=1e-9, atol=1e-12)


@model_dataclass
class Truncating(EuclideanState):
    def dynamics(self, x, u):
        return x[:1]

    def output(self, x, u):
        return x[0]


def test_bad_model_is_an_input_error():
    with pytest.raises(InputError, match="derivatives"):
        linearize(Truncating(), jnp.zeros(3), jnp.zeros(1))
    with pytest.raises(InputError, match="empty"):
        linearize(Truncating(), jnp.zeros(0), jnp.zeros(1))
    assert isinstance(linear_model(), LinearModel)
