"""Systems with known observability answers, used to validate :mod:`observability`.

- :func:`linear`: ẋ = A x + B u, y = C x — the answer is the rank of the Kalman matrix [C; CA; …].
- :func:`unicycle`: position known → all observable; heading only → position unobservable.
- :func:`pendulum_from_rate`: θ̈ = −(g/l) sin θ − b θ̇ measured by θ̇ → θ observable (1 derivative).
- :func:`accelerometer`: R ∈ SO(3) driven by a known gyro rate, y = specific force in the body
  frame → tilt observable at once, yaw about gravity never.
- :func:`product_parameter`: ẋ = −a b x, y = x → a and b not identifiable, their product is.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from verticality import so3
from verticality.analysis.observability import SO3, Problem
from verticality.params import G_M_S2


def kalman_rank(A, C) -> int:
    A, C = np.asarray(A, float), np.asarray(C, float)
    blocks, M = [], C
    for _ in range(A.shape[0]):
        blocks.append(M)
        M = M @ A
    return int(np.linalg.matrix_rank(np.vstack(blocks)))


def linear(A, C, B=None) -> Problem:
    A, C = jnp.asarray(A, float), jnp.asarray(C, float)
    n = A.shape[0]
    inputs = {} if B is None else {"u": (jnp.asarray(B).shape[1],)}

    def f(x, u, th):
        dx = A @ x["x"]
        return {"x": dx if B is None else dx + jnp.asarray(B, float) @ u["u"]}

    return Problem(f=f, h=lambda x, u, th: C @ x["x"], states={"x": (n,)}, inputs=inputs)


def unicycle(output: str = "position") -> Problem:
    """(p_x, p_y, ψ) driven by known speed v and turn rate w."""

    def f(x, u, th):
        psi = x["psi"][0]
        return {"p": u["v"][0] * jnp.array([jnp.cos(psi), jnp.sin(psi)]), "psi": u["w"]}

    h = (lambda x, u, th: x["p"]) if output == "position" else (lambda x, u, th: x["psi"])
    return Problem(f=f, h=h, states={"p": (2,), "psi": (1,)}, inputs={"v": (1,), "w": (1,)},
                   quantities={"position": lambda x, th: x["p"]})


def pendulum_from_rate(g_over_l: float = 9.81, damping: float = 0.3) -> Problem:
    def f(x, u, th):
        q, w = x["q"]
        return {"q": jnp.array([w, -g_over_l * jnp.sin(q) - damping * w])}

    return Problem(f=f, h=lambda x, u, th: x["q"][1:], states={"q": (2,)},
                   quantities={"angle": lambda x, th: x["q"][0]})


def accelerometer() -> Problem:
    """Body orientation ``R_I_B`` with a known body rate; the output is the specific force at rest."""
    up = jnp.array([0.0, 0.0, G_M_S2])
    return Problem(
        f=lambda x, u, th: {"R_I_B": x["R_I_B"] @ so3.hat(u["omega"])},
        h=lambda x, u, th: x["R_I_B"].T @ up,
        states={"R_I_B": SO3}, inputs={"omega": (3,)},
        quantities={"tilt": lambda x, th: x["R_I_B"].T @ jnp.array([0.0, 0.0, 1.0]),
                    "heading": lambda x, th: x["R_I_B"][:, 0]},
    )


def product_parameter() -> Problem:
    return Problem(
        f=lambda x, u, th: {"x": -th["a"] * th["b"] * x["x"]},
        h=lambda x, u, th: x["x"], states={"x": (1,)}, unknowns={"a": (1,), "b": (1,)},
        quantities={"ab": lambda x, th: th["a"] * th["b"]},
    )
