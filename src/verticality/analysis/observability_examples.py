"""Systems with known observability answers, as small model values, used to validate
:mod:`observability`.

- :func:`linear`: ẋ = A x + B u, y = C x — the answer is the rank of the Kalman matrix [C; CA; …].
- :func:`unicycle`: position known → all observable; heading only → position unobservable.
- :func:`pendulum_from_rate`: θ̈ = −(g/l) sin θ − b θ̇ measured by θ̇ → θ observable (1 derivative).
- :func:`accelerometer`: R ∈ SO(3) driven by a known gyro rate, y = specific force in the body
  frame → tilt observable at once, yaw about gravity never.
- :func:`product_parameter`: ẋ = −a b x, y = x → a and b not identifiable, their product is.

Each is a model value of the :mod:`verticality.models.base` interface; the functions return the
observability :class:`~verticality.analysis.observability.Problem` around it.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from verticality.analysis.observability import Problem, random_rotation
from verticality.core import so3
from verticality.core.constants import G_M_S2
from verticality.models import planar
from verticality.models.base import EuclideanState, model_dataclass, static_field
from verticality.models.kinematics import rotation_difference, rotation_retract


def kalman_rank(A, C) -> int:
    A, C = np.asarray(A, float), np.asarray(C, float)
    blocks, M = [], C
    for _ in range(A.shape[0]):
        blocks.append(M)
        M = M @ A
    return int(np.linalg.matrix_rank(np.vstack(blocks)))


@model_dataclass
class Linear(EuclideanState):
    """``ẋ = A x + B u``, ``y = C x`` (no input when ``B`` is None)."""

    A: jnp.ndarray
    C: jnp.ndarray
    B: jnp.ndarray | None = None

    def dynamics(self, x, u):
        dx = self.A @ x
        return dx if self.B is None else dx + self.B @ u

    def output(self, x, u):
        return self.C @ x


def linear(A, C, B=None) -> Problem:
    A, C = jnp.asarray(A, float), jnp.asarray(C, float)
    B = None if B is None else jnp.asarray(B, float)
    inputs = {} if B is None else {"u": (B.shape[1],)}
    return Problem(model=Linear(A, C, B), state=jnp.zeros(A.shape[0]), inputs=inputs,
                   input_map=None if B is None else (lambda x, u, th: u["u"]), leaf_names=("x",))


@model_dataclass
class Unicycle(EuclideanState):
    """State ``(p_x, p_y, ψ)`` driven by a known speed and turn rate ``u = (v, w)``; the output is
    the position (``measure="position"``) or the heading (``measure="heading"``)."""

    measure: str = static_field("position")

    def dynamics(self, x, u):
        v, w = u
        psi = x[2]
        return jnp.concatenate([v * jnp.array([jnp.cos(psi), jnp.sin(psi)]), w[None]])

    def output(self, x, u):
        return x[:2] if self.measure == "position" else x[2:]


def unicycle(output: str = "position") -> Problem:
    return Problem(model=Unicycle(output), state=jnp.zeros(3), inputs={"v": (1,), "w": (1,)},
                   input_map=lambda x, u, th: (u["v"][0], u["w"][0]),
                   quantities={"position": lambda x, th: x[:2]}, leaf_names=("q",))


@model_dataclass
class RatePendulum(EuclideanState):
    """A planar pendulum (:func:`verticality.models.planar.pendulum_angular_acceleration`, still
    pivot) with state ``(θ, θ̇)``, measured by its angular velocity."""

    params: planar.PlanarHead

    def dynamics(self, x, u):
        q, w = x
        return jnp.stack([w, planar.pendulum_angular_acceleration(q, w, 0.0, 0.0, 0.0,
                                                                  self.params)])

    def output(self, x, u):
        return x[1:]


def pendulum_from_rate(g_over_l: float = G_M_S2, damping: float = 0.3) -> Problem:
    """θ̈ = −(g/l) sin θ − b θ̇: unit mass, length and inertia, ``g = g/l``, ``β = b``."""
    params = planar.PlanarHead(m_kg=1.0, l_m=1.0, J_kg_m2=1.0, beta_Nms=damping, g_m_s2=g_over_l)
    return Problem(model=RatePendulum(params), state=jnp.zeros(2), leaf_names=("q",),
                   quantities={"angle": lambda x, th: x[0]})


@model_dataclass
class Attitude:
    """Body orientation ``R_I_B`` (SO(3), right perturbations) with a known body rate ``u = ω``;
    the output is the specific force of a body at rest, in the body frame."""

    g_m_s2: float = G_M_S2

    def dynamics(self, x, u):
        return x @ so3.hat(u)

    def output(self, x, u):
        return x.T @ jnp.array([0.0, 0.0, self.g_m_s2])

    def retract(self, x, dx):
        return rotation_retract(x, dx)

    def difference(self, x1, x0):
        return rotation_difference(x1, x0)

    def project(self, x):
        return so3.orthonormalize(x)


def accelerometer() -> Problem:
    """Body orientation ``R_I_B`` with a known body rate; the output is the specific force at
    rest."""
    return Problem(
        model=Attitude(), state=jnp.eye(3), inputs={"omega": (3,)},
        input_map=lambda x, u, th: u["omega"], leaf_names=("R_I_B",),
        sample=lambda rng: (random_rotation(rng), {}),
        quantities={"tilt": lambda x, th: x.T @ jnp.array([0.0, 0.0, 1.0]),
                    "heading": lambda x, th: x[:, 0]},
    )


@model_dataclass
class Decay(EuclideanState):
    """``ẋ = −a b x``, ``y = x``."""

    a: jnp.ndarray = 1.0
    b: jnp.ndarray = 1.0

    def dynamics(self, x, u):
        return -self.a * self.b * x

    def output(self, x, u):
        return x


def product_parameter() -> Problem:
    """The decay rates ``a`` and ``b`` are the model's unknown parameters."""
    return Problem(
        model=Decay(), state=jnp.zeros(1), unknowns={"a": (1,), "b": (1,)},
        parameter_map=lambda m, th: Decay(th["a"], th["b"]), leaf_names=("x",),
        quantities={"ab": lambda x, th: th["a"] * th["b"]},
    )
