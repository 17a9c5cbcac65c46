"""Luenberger observer on a linear(ized) model (F eq. 4.10), gain by pole placement.

    dx̂/dt = A x̂ + B u + L (y − C x̂ − D u)                                  (F 4.10)

``A, B, C, D`` typically come from :func:`verticality.models.linearize.linearize` at upright; ``L``
from :func:`design` (``control.place`` on the dual pair, so that ``eig(A − L C)`` are the requested
poles). Between samples ``u`` and ``y`` are held (zero-order hold) and the observer ODE is
integrated exactly by one matrix exponential per step, so the discrete observer has its poles at
``exp(p·dt)`` for any ``dt``. A NaN in ``y`` (any component) means no measurement: that step
predicts with ``A, B`` only and is flagged.

API (estimators/base.py): the design is the first argument, then the common ``init``/``step``/``run``::

    obs = design(model, poles)
    state = init(x0)                       # P0 accepted and ignored (no covariance here)
    state, out = step(obs, state, u, y, dt)
    states, outs = run(obs, state, us, ys, dts)
    est = bind(obs)                        # est.init / est.step(state, u, y, dt) / est.run(...)
"""

from __future__ import annotations

from types import SimpleNamespace
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from verticality.errors import InputError
from verticality.models.linearize import LinearModel


class Luenberger(NamedTuple):
    """Observer design: the model and its gain ``L`` (n_x × n_y)."""

    A: jnp.ndarray
    B: jnp.ndarray
    C: jnp.ndarray
    D: jnp.ndarray
    L: jnp.ndarray


class LuenbergerState(NamedTuple):
    x_hat: jnp.ndarray


class LuenbergerOut(NamedTuple):
    x_hat: jnp.ndarray
    innovation: jnp.ndarray  # y − C x̂ − D u before the step (zeros when no measurement)
    measured: jnp.ndarray  # bool: False when y had a NaN and the step only predicted


def design(model: LinearModel, poles) -> Luenberger:
    """Place the poles of ``A − L C`` at ``poles`` (python-control ``place`` on the dual system)."""
    import control

    A, C = np.asarray(model.A, float), np.asarray(model.C, float)
    poles = np.atleast_1d(np.asarray(poles))
    if poles.shape != (A.shape[0],):
        raise InputError(f"Luenberger design: need {A.shape[0]} poles, got {poles.size}")
    if np.any(np.real(poles) >= 0):
        raise InputError("Luenberger design: observer poles must have negative real parts")
    if np.linalg.matrix_rank(control.obsv(A, C)) < A.shape[0]:
        raise InputError("Luenberger design: (A, C) is not observable")
    L = np.asarray(control.place(A.T, C.T, poles)).T
    return Luenberger(*(jnp.asarray(m, dtype=float) for m in model), jnp.asarray(L))


def poles(obs: Luenberger) -> np.ndarray:
    """Eigenvalues of ``A − L C`` (continuous time)."""
    return np.linalg.eigvals(np.asarray(obs.A - obs.L @ obs.C))


def init(x0, P0=None) -> LuenbergerState:
    """Initial estimate ``x0`` (``P0`` is accepted for API uniformity and ignored)."""
    x0 = jnp.asarray(x0, dtype=float)
    if x0.ndim != 1:
        raise InputError(f"Luenberger init: x0 must be a vector, got shape {x0.shape}")
    return LuenbergerState(x0)


def step(obs: Luenberger, state: LuenbergerState, u, y, dt):
    """Advance the estimate by ``dt`` with ``u`` and ``y`` held (exact ZOH integration of F 4.10)."""
    nx, nu = obs.B.shape
    ny = obs.C.shape[0]
    u = jnp.reshape(jnp.asarray(u, dtype=float), (nu,))
    y = jnp.reshape(jnp.asarray(y, dtype=float), (ny,))
    measured = jnp.all(jnp.isfinite(y))
    y0 = jnp.where(measured, y, 0.0)
    Lm = jnp.where(measured, obs.L, 0.0)
    innovation = jnp.where(measured, y0 - obs.C @ state.x_hat - obs.D @ u, 0.0)
    # ẋ̂ = (A − L C) x̂ + (B − L D) u + L y, inputs held: one expm of the augmented matrix.
    n_in = nu + ny
    M = jnp.zeros((nx + n_in, nx + n_in))
    M = M.at[:nx, :nx].set(obs.A - Lm @ obs.C)
    M = M.at[:nx, nx:nx + nu].set(obs.B - Lm @ obs.D)
    M = M.at[:nx, nx + nu:].set(Lm)
    E = jax.scipy.linalg.expm(M * dt)
    x_new = E[:nx, :nx] @ state.x_hat + E[:nx, nx:] @ jnp.concatenate([u, y0])
    # Never turn a finite estimate into NaN (e.g. a NaN in u): keep the old one.
    x_new = jnp.where(jnp.all(jnp.isfinite(x_new)), x_new, state.x_hat)
    return LuenbergerState(x_new), LuenbergerOut(x_new, innovation, measured)


@jax.jit
def run(obs: Luenberger, state: LuenbergerState, us, ys, dts):
    """:func:`step` over a sequence (``us``: (T, n_u), ``ys``: (T, n_y), ``dts``: (T,)) by ``lax.scan``."""

    def body(s, inp):
        u, y, dt = inp
        return step(obs, s, u, y, dt)

    return jax.lax.scan(body, state, (us, ys, dts))


def bind(obs: Luenberger) -> SimpleNamespace:
    """The observer with the design bound: ``init(x0, P0)``, ``step(state, u, y, dt)``, ``run(...)``."""
    return SimpleNamespace(
        init=init,
        step=lambda state, u, y, dt: step(obs, state, u, y, dt),
        run=lambda state, us, ys, dts: run(obs, state, us, ys, dts),
        design=obs,
    )
