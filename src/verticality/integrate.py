"""Fixed-step integration of pytree states, with a projection back onto the state manifold.

RK4 is applied to the flat (embedding) coordinates of every leaf; a model-supplied ``project``
then maps the result back onto its manifold (rotation matrices onto SO(3)). The projection error
is of the order of the RK4 local error, so the scheme keeps 4th order and rotation matrices stay
orthonormal to rounding (tested over 60 s at 1 ms).
"""

from __future__ import annotations

from collections.abc import Callable

import jax


def _axpy(a, x, y):
    return jax.tree_util.tree_map(lambda xi, yi: yi + a * xi, x, y)


def rk4_step(f: Callable, t, x, h, *args, project: Callable | None = None):
    """One classical Runge–Kutta step of ``x' = f(t, x, *args)`` with step ``h``."""
    k1 = f(t, x, *args)
    k2 = f(t + 0.5 * h, _axpy(0.5 * h, k1, x), *args)
    k3 = f(t + 0.5 * h, _axpy(0.5 * h, k2, x), *args)
    k4 = f(t + h, _axpy(h, k3, x), *args)
    x_next = jax.tree_util.tree_map(
        lambda xi, a, b, c, d: xi + (h / 6.0) * (a + 2.0 * b + 2.0 * c + d), x, k1, k2, k3, k4
    )
    return project(x_next) if project is not None else x_next


def euler_step(f: Callable, t, x, h, *args, project: Callable | None = None):
    """One explicit Euler step (used by discrete-time observer models that the papers define so)."""
    x_next = _axpy(h, f(t, x, *args), x)
    return project(x_next) if project is not None else x_next
