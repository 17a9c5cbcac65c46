"""Linearization of a model value at an operating point by autodiff (F eq. 4.10, T eq. 16).

F §4.4.2 designs its Luenberger observer and Kalman filter, and T §II.B its disturbance observer,
on the constant matrices

    A = ∂f/∂x,  B = ∂f/∂u,  C = ∂h/∂x,  D = ∂h/∂u     at x = x0, u = u0,

of a model ``ẋ = f(x, u)``, ``y = h(x, u)``. Here they come from ``jax.jacfwd`` on the model value
itself (``model.dynamics``, ``model.output``; :mod:`verticality.models.base`), so an observer's
internal model and the simulated truth can never drift apart.

The state is perturbed in the model's tangent coordinates about the nominal motion through the
operating point, ``x(t) = x_nom(t) ⊞ δ(t)`` (``model.retract``; ``x_nom(0) = x0``, ``ẋ_nom =
f(x_nom, u0)``), so that ``δ = x ⊟ x_nom`` (``model.difference``) obeys

    δ̇ = ∂(x ⊟ x_nom)/∂x · f(x, u) + ∂(x ⊟ x_nom)/∂x_nom · f(x_nom, u0),
    A = ∂δ̇/∂δ,  B = ∂δ̇/∂u,  C = ∂h(x0 ⊞ δ, u)/∂δ,  D = ∂h/∂u          at δ = 0, u = u0,

the linear time-varying model's matrices at the operating point (at an equilibrium the nominal
motion is still). On a vector space (``EuclideanState``) this is the plain Jacobian of ``f`` in
``ravel_pytree`` order (the order of a NamedTuple's fields); for a rotation-matrix state (a 3-D
head, ``R ⊞ δ = R exp([δ]×)``) the three tangent coordinates replace the nine matrix entries and
the attitude block is the error-state one, ``δθ̇ = −[ω]× δθ + δω``. Inputs and outputs may be any
pytrees; they are flattened in ``ravel_pytree`` order.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from jax.flatten_util import ravel_pytree

from verticality.core.errors import InputError
from verticality.core.integrate import zoh


class LinearModel(NamedTuple):
    """Continuous-time ``ẋ = A x + B u``, ``y = C x + D u`` (deviations from the operating
    point)."""

    A: jnp.ndarray
    B: jnp.ndarray
    C: jnp.ndarray
    D: jnp.ndarray


def linearize(model, x0, u0) -> LinearModel:
    """A, B, C, D of ``model`` (a :class:`~verticality.models.base.Model` value) at ``(x0, u0)``
    by forward-mode autodiff in the tangent coordinates of ``model.retract``/``difference``
    (module docstring). Returns float64 arrays: A (n, n), B (n, m), C (p, n), D (p, m), with n the
    tangent dimension, m the size of the flattened input and p of the flattened output."""
    dx0 = model.difference(x0, x0)
    n = int(jnp.size(dx0))
    if n == 0:
        raise InputError("linearize: the state x0 is empty")
    u0_flat, unravel_u = ravel_pytree(u0)
    xdot0 = model.dynamics(x0, u0)
    n_x, n_f = ravel_pytree(x0)[0].size, ravel_pytree(xdot0)[0].size
    if n_f != n_x:
        raise InputError(f"linearize: the model's dynamics returns {n_f} derivatives for a state "
                         f"of {n_x} components")
    zero = jnp.zeros(n, dtype=jnp.result_type(dx0, float))

    def tangent_rate(d, uf):
        x = model.retract(x0, d)
        xdot = model.dynamics(x, unravel_u(uf))
        return jax.jvp(model.difference, (x, x0), (xdot, xdot0))[1]

    def out(d, uf):
        return jnp.atleast_1d(ravel_pytree(model.output(model.retract(x0, d), unravel_u(uf)))[0])

    A, B = jax.jacfwd(tangent_rate, argnums=(0, 1))(zero, u0_flat)
    C, D = jax.jacfwd(out, argnums=(0, 1))(zero, u0_flat)
    m = u0_flat.size
    return LinearModel(jnp.reshape(A, (n, n)), jnp.reshape(B, (n, m)),
                       jnp.reshape(C, (-1, n)), jnp.reshape(D, (-1, m)))


def select_inputs(model: LinearModel, columns) -> LinearModel:
    """The linear model restricted to some of its inputs (columns of B and D), e.g. the known
    inputs of an observer when the model also has inputs held at zero."""
    idx = np.asarray(columns, dtype=int)
    return LinearModel(model.A, model.B[:, idx], model.C, model.D[:, idx])


def to_statespace(model: LinearModel, *, dt=None, **kw):
    """The model as a ``control.StateSpace`` (continuous, or discrete with sample time ``dt``);
    ``kw`` (``inputs=``, ``outputs=``, ``states=`` names) goes to ``control.ss``."""
    import control

    args = [np.asarray(m, dtype=float) for m in model]
    return control.ss(*args, dt, **kw) if dt is not None else control.ss(*args, **kw)


def from_statespace(sys) -> LinearModel:
    """A :class:`LinearModel` from a ``control.StateSpace`` (continuous-time)."""
    return LinearModel(*(jnp.asarray(np.asarray(m, dtype=float))
                         for m in (sys.A, sys.B, sys.C, sys.D)))


def discretize_zoh(model: LinearModel, dt: float) -> tuple[jnp.ndarray, jnp.ndarray]:
    """Zero-order-hold discretization ``(A_d, B_d)`` (:func:`verticality.core.integrate.zoh`)."""
    return zoh(jnp.asarray(model.A), jnp.asarray(model.B), dt)
