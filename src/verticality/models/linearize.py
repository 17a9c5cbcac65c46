"""Linearization of a nonlinear model at an operating point by autodiff (F eq. 4.10).

F §4.4.2 designs its Luenberger observer and Kalman filter on the constant matrices

    A = ∂f/∂x,  B = ∂f/∂u,  C = ∂h/∂x,  D = ∂h/∂u     at x = x0 (upright, still), u = u0 (ᴴa = 0),

of a model ``ẋ = f(x, u, p)``, ``y = h(x, u, p)``. Here they come from ``jax.jacfwd`` on the one
nonlinear definition of the model, so the observer's internal model and the simulated truth can
never drift apart. States, inputs and outputs may be arrays or pytrees (NamedTuples); they are
flattened in ``jax.flatten_util.ravel_pytree`` order, which is the order of the NamedTuple fields.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from jax.flatten_util import ravel_pytree

from verticality.errors import InputError


class LinearModel(NamedTuple):
    """Continuous-time ``ẋ = A x + B u``, ``y = C x + D u`` (deviations from the operating point)."""

    A: jnp.ndarray
    B: jnp.ndarray
    C: jnp.ndarray
    D: jnp.ndarray


def linearize(f: Callable, h: Callable, x0, u0, p=None) -> LinearModel:
    """A, B, C, D of F eq. 4.10 by forward-mode autodiff of ``f(x, u, p)`` and ``h(x, u, p)``.

    ``x0`` and ``u0`` are the operating point (arrays or pytrees, e.g. NamedTuples); ``p`` is passed
    through unchanged. Returns the Jacobians of the flattened maps as float64 arrays.
    """
    x0_flat, unravel_x = ravel_pytree(x0)
    u0_flat, unravel_u = ravel_pytree(u0)
    if x0_flat.size == 0:
        raise InputError("linearize: the state x0 is empty")

    def f_flat(xf, uf):
        return ravel_pytree(f(unravel_x(xf), unravel_u(uf), p))[0]

    def h_flat(xf, uf):
        return jnp.atleast_1d(ravel_pytree(h(unravel_x(xf), unravel_u(uf), p))[0])

    fx = f_flat(x0_flat, u0_flat)
    if fx.shape != x0_flat.shape:
        raise InputError(f"linearize: f returns {fx.size} derivatives for {x0_flat.size} states")
    A, B = jax.jacfwd(f_flat, argnums=(0, 1))(x0_flat, u0_flat)
    C, D = jax.jacfwd(h_flat, argnums=(0, 1))(x0_flat, u0_flat)
    nx, nu = x0_flat.size, u0_flat.size
    return LinearModel(jnp.reshape(A, (nx, nx)), jnp.reshape(B, (nx, nu)),
                       jnp.reshape(C, (-1, nx)), jnp.reshape(D, (-1, nu)))


def to_statespace(model: LinearModel, *, dt=None, **kw):
    """The model as a ``control.StateSpace`` (continuous, or discrete with sample time ``dt``)."""
    import control

    args = [np.asarray(m, dtype=float) for m in model]
    return control.ss(*args, dt, **kw) if dt is not None else control.ss(*args, **kw)


def from_statespace(sys) -> LinearModel:
    """A :class:`LinearModel` from a ``control.StateSpace`` (continuous-time)."""
    return LinearModel(*(jnp.asarray(np.asarray(m, dtype=float)) for m in (sys.A, sys.B, sys.C, sys.D)))


def discretize_zoh(model: LinearModel, dt: float) -> tuple[jnp.ndarray, jnp.ndarray]:
    """Zero-order-hold discretization ``(A_d, B_d)`` by one matrix exponential (JAX, jit-safe)."""
    nx, nu = model.B.shape
    M = jnp.zeros((nx + nu, nx + nu)).at[:nx, :nx].set(model.A).at[:nx, nx:].set(model.B)
    E = jax.scipy.linalg.expm(M * dt)
    return E[:nx, :nx], E[:nx, nx:]
