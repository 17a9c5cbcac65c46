"""Validation of the generic observability tool on systems with known answers."""

import math

import jax.numpy as jnp
import numpy as np
import pytest
import sympy as sp
from jax.experimental.jet import jet

from verticality.analysis import observability as ob
from verticality.analysis import observability_examples as ex
from verticality.analysis.observability_exact import exact_rank
from verticality.analysis.observability_taylor import taylor
from verticality.core.errors import InputError
from verticality.models.base import EuclideanState, model_dataclass


def _random_linear(seed, n=5, unobs=2):
    """A linear system with an unobservable subspace of dimension ``unobs`` (hidden by a basis
    change)."""
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((n, n)) * 0.5
    A[: n - unobs, n - unobs :] = 0.0  # the last states do not feed the observed block
    C = np.zeros((1, n))
    C[0, : n - unobs] = rng.standard_normal(n - unobs)
    T = rng.standard_normal((n, n)) + 2 * np.eye(n)
    Ti = np.linalg.inv(T)
    return T @ A @ Ti, C @ Ti


@pytest.mark.parametrize("seed,unobs", [(0, 2), (1, 0)])
def test_linear_matches_kalman_rank(seed, unobs):
    A, C = _random_linear(seed, unobs=unobs)
    res = ob.analyze(ex.linear(A, C, B=np.ones((5, 1))), points=2)
    assert res.rank == ex.kalman_rank(A, C) == 5 - unobs
    assert res.null_space.shape[1] == unobs
    if unobs:  # the null space is A-invariant and annihilated by C
        N = res.null_space
        assert np.allclose(C @ N, 0.0, atol=1e-8)
        P = N @ N.T
        assert np.allclose(P @ (A @ N), A @ N, atol=1e-6)


def test_unicycle():
    pos = ob.analyze(ex.unicycle("position"), points=2)
    assert pos.observable and pos.saturated_at == 1  # heading from the velocity direction
    head = ob.analyze(ex.unicycle("heading"), points=2)
    assert head.rank == 1 and not head.quantities["position"].observable


def test_pendulum_angle_from_rate():
    res = ob.analyze(ex.pendulum_from_rate(), points=2)
    q = res.quantities["angle"]
    assert res.observable and q.observable and q.derivatives_needed == 1


def test_accelerometer_tilt_but_never_yaw():
    res = ob.analyze(ex.accelerometer(), points=3)
    assert res.rank == 2 and res.n_coords == 3
    assert res.quantities["tilt"].observable and res.quantities["tilt"].derivatives_needed == 0
    assert not res.quantities["heading"].observable
    x, _ = res.point  # the unobservable direction is yaw about gravity: δ = Rᵀ e3
    assert res.in_null_space(x.T @ np.array([0.0, 0.0, 1.0]))


def test_product_parameter_not_identifiable():
    res = ob.analyze(ex.product_parameter(), points=2)
    assert not res.quantities["theta:a"].observable
    assert not res.quantities["theta:b"].observable
    assert res.quantities["ab"].observable
    assert res.rank == 2 and res.n_coords == 3


@model_dataclass
class _Chained(EuclideanState):
    """ẋ = v, ẏ = v p, ṗ = w; y = (x, y): a rational unicycle."""

    def dynamics(self, q, u):
        return jnp.array([u["v"][0], u["v"][0] * q[2], u["w"][0]])

    def output(self, q, u):
        return q[:2]


def test_numeric_rank_equals_exact_sympy_rank():
    x, y, p, v, w, a, b, z = sp.symbols("x y p v w a b z")
    exact_uni = exact_rank([v, v * p, w], [x, y], [x, y, p], inputs=[v, w], order=2)
    num_uni = ob.analyze(ob.Problem(model=_Chained(), state=jnp.zeros(3),
                                    inputs={"v": (1,), "w": (1,)}), order=2, points=2)
    assert num_uni.rank_by_order == exact_uni
    exact_prod = exact_rank([-a * b * z], [z], [z], unknowns=[a, b], order=3)
    num_prod = ob.analyze(ex.product_parameter(), order=3, points=2)
    assert num_prod.rank_by_order == exact_prod


def test_taylor_interpreter_matches_jet():
    prob = ex.accelerometer()
    lay = ob.layout(prob, "tangent")
    F, H = ob.flat_fields(prob, lay)
    rng = np.random.default_rng(3)
    X0 = jnp.asarray(ob.random_rotation(rng).ravel())
    K = 4
    U = jnp.asarray(rng.standard_normal((K + 1, 3)))
    fact = jnp.array([math.factorial(k) for k in range(K + 1)])[:, None]
    ours = ob.output_derivatives(F, H, X0, U, K) * fact
    ref = ob.output_derivatives_jet(F, H, X0, U * fact, K)
    assert np.allclose(ours, ref, rtol=1e-10, atol=1e-10)
    # and the elementary recurrences (sin, atan2, division) against jet directly
    fun = lambda t: jnp.arctan2(jnp.sin(t) + 2.0, t * t + 1.0) / (1.5 + jnp.cos(t))  # noqa: E731
    c = taylor(fun, (jnp.array(0.3),), (jnp.array([1.0, 0.0, 0.0, 0.0]),))
    _, s = jet(fun, (0.3,), ([1.0, 0.0, 0.0, 0.0],))
    assert np.allclose(np.asarray(c[1:]) * np.array([1, 2, 6, 24]), np.asarray(s), rtol=1e-10)


def test_ambient_chart_counts_free_entries():
    res = ob.analyze(ex.accelerometer(), chart="ambient", points=2)
    assert res.n_coords == 9 and res.rank == 3  # only the third row of R is seen
    assert res.labels[5] == "R_I_B[1,2]"
    x, _ = res.point  # a generic matrix, off SO(3)
    assert np.linalg.norm(x.T @ x - np.eye(3)) > 0.1


def test_layout_reads_the_model_retraction():
    """Tangent coordinates and labels come from the model's own retract: three per rotation."""
    lay = ob.layout(ex.accelerometer(), "tangent")
    assert lay.n_coords == 3 and lay.constrained == [True]
    assert lay.coordinate_labels() == ["R_I_B.δx", "R_I_B.δy", "R_I_B.δz"]
    lay = ob.layout(ex.product_parameter(), "tangent")
    assert lay.coordinate_labels() == ["x[0]", "a[0]", "b[0]"] and lay.constrained == [False]


def test_curve_direction_of_yaw_is_the_null_space():
    """Turning the body about gravity (R → Rz(ε) R) is the accelerometer's hidden direction,
    found through the model's retraction; a roll is not hidden."""
    from verticality.core import so3

    prob = ex.accelerometer()
    res = ob.analyze(prob, points=2)
    x, _ = res.point
    d = ob.curve_directions(prob, res, {"yaw": lambda model, x, th, e: (so3.rot_z(e) @ x, {}),
                                        "roll": lambda model, x, th, e: (so3.rot_x(e) @ x, {})})
    assert np.allclose(d["yaw"], x.T @ np.array([0.0, 0.0, 1.0]), atol=1e-12)
    assert res.in_null_space(d["yaw"])
    assert not res.in_null_space(d["roll"])


def test_unknown_model_parameters_enter_through_the_parameter_map():
    prob = ex.product_parameter()
    x = jnp.array([2.0])
    th = {"a": jnp.array([3.0]), "b": jnp.array([0.5])}
    assert np.allclose(prob.vector_field(x, {}, th), -3.0)
    model = prob.model_for(th)
    assert model.a is th["a"] and model.b is th["b"] and prob.model.a == 1.0


def test_bad_input_is_a_clear_error():
    with pytest.raises(InputError):
        ob.Problem(model=lambda x, u: x, state=jnp.zeros(2))  # not a model value
    with pytest.raises(InputError):
        ob.Problem(model=ex.Decay(), state=jnp.zeros(1), unknowns={"a": 1})
    with pytest.raises(InputError):
        ob.Problem(model=ex.Decay(), state=jnp.zeros(1), leaf_names=("x", "y"))
    with pytest.raises(InputError):
        ob.analyze(ex.product_parameter(), fixed={"c": 1.0})
    with pytest.raises(InputError):
        ob.analyze(ex.product_parameter(), chart="euler")
