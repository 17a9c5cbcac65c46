"""The model interface: a model is a value.

A model — a damped pendulum, a free head, a head with its otoliths, a head on a gimbal over a
trunk, a planar platform, a liquid inclinometer, a multi-segment body — is one frozen pytree that
carries its parameters and its functions. It is defined once in :mod:`verticality.models` and
handed, unchanged, to every algorithm: the simulator integrates ``dynamics``, the EKF and the
Newton observer discretize it (:class:`Discretized`), :func:`verticality.models.linearize.linearize`
differentiates it into ``control.StateSpace``, the observability analysis differentiates it, and the
model checks exercise it. No algorithm re-derives a model.

The interface (:class:`Model`)::

    model.dynamics(x, u) -> ẋ          continuous time; ẋ has x's pytree structure
                                        (for a rotation matrix R of the state: Ṙ = R [ω]×)
    model.output(x, u) -> y             what the model's sensors read, a flat array (p,)
    model.retract(x, dx) -> x ⊞ dx      dx a flat tangent vector (n,) (right, body-frame
                                        perturbation R exp([δ]×) for rotations)
    model.difference(x1, x0) -> dx      x1 ⊟ x0, the inverse of ``retract``: retract(x0, dx) = x1
    model.project(x) -> x               back onto the state manifold after an integration step
                                        (rotation matrices onto SO(3)); identity on vector spaces

``u`` is any pytree (a torque, an acceleration, a
:class:`~verticality.models.kinematics.RigidMotion` of a driving body). Parameters are the model's
pytree leaves, so a model can be passed into jitted functions, batched with ``vmap`` over parameter
values and differentiated with respect to them. Switches that change the structure of a computation
are static fields (``model_dataclass``).

Models are frozen dataclasses registered as pytrees (:func:`model_dataclass`); models on a vector
space inherit :class:`EuclideanState` for ``retract``/``difference``/``project``. Composite models
(a head carrying pendula, a head on a gimbal) hold their component model values as fields and call
their functions; they never re-write a component's equations.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any, Protocol, runtime_checkable

import jax
import jax.numpy as jnp
from jax.flatten_util import ravel_pytree

from verticality.core.errors import InputError
from verticality.core.integrate import euler_step, rk4_step


@runtime_checkable
class Model(Protocol):
    """A continuous-time model ``ẋ = f(x, u)``, ``y = h(x, u)`` on a manifold (see the module
    doc)."""

    def dynamics(self, x, u): ...

    def output(self, x, u): ...

    def retract(self, x, dx): ...

    def difference(self, x1, x0): ...

    def project(self, x): ...


@runtime_checkable
class DiscreteModel(Protocol):
    """A discrete-time model ``x_{k+1} = F(x_k, u, dt)``, ``y_k = h(x_k, u)`` (EKF, Newton
    observer)."""

    def transition(self, x, u, dt): ...

    def output(self, x, u): ...

    def retract(self, x, dx): ...

    def difference(self, x1, x0): ...


def model_dataclass(cls=None, /):
    """Class decorator: a frozen dataclass registered as a JAX pytree.

    Fields are pytree children (traced, batchable) unless declared with
    ``dataclasses.field(metadata={"static": True})``, which makes them part of the tree structure
    (hashable settings that select a computation, e.g. the number of integration sub-steps)."""

    def wrap(c):
        c = dataclasses.dataclass(frozen=True)(c)
        fields = dataclasses.fields(c)
        data = [f.name for f in fields if not f.metadata.get("static", False)]
        meta = [f.name for f in fields if f.metadata.get("static", False)]
        return jax.tree_util.register_dataclass(c, data_fields=data, meta_fields=meta)

    return wrap if cls is None else wrap(cls)


def static_field(default=dataclasses.MISSING):
    """A :func:`model_dataclass` field that is part of the tree structure, not a traced leaf."""
    return dataclasses.field(default=default, metadata={"static": True})


class EuclideanState:
    """``retract``/``difference``/``project`` for states that are plain arrays or pytrees of arrays
    (a vector space): ``x ⊞ dx = x + dx`` in ``ravel_pytree`` order."""

    def retract(self, x, dx):
        flat, unravel = ravel_pytree(x)
        return unravel(flat + dx)

    def difference(self, x1, x0):
        return ravel_pytree(x1)[0] - ravel_pytree(x0)[0]

    def project(self, x):
        return x


def step_rk4(model: Model, x, u, h):
    """One classical RK4 step of ``model.dynamics`` with ``u`` held, then ``model.project``."""
    return rk4_step(lambda t, xx: model.dynamics(xx, u), 0.0, x, h, project=model.project)


def step_euler(model: Model, x, u, h):
    """One forward-Euler step ``x + h·f(x, u)`` of ``model.dynamics`` with ``u`` held, then
    ``model.project`` (the discretization P11 §V.C gives its observer's model)."""
    return euler_step(lambda t, xx: model.dynamics(xx, u), 0.0, x, h, project=model.project)


#: the one-step schemes a :class:`Discretized` model may use
STEPS = {"rk4": step_rk4, "euler": step_euler}


class OnModel:
    """For a value that wraps another model value ``self.model`` — a discretization, another kind
    of input, another integration — and keeps its state: the output and the state's manifold
    (``retract``, ``difference``, ``project``) are the wrapped model's. A wrapper overrides what it
    changes."""

    def output(self, x, u=None):
        return self.model.output(x, u)

    def retract(self, x, dx):
        return self.model.retract(x, dx)

    def difference(self, x1, x0):
        return self.model.difference(x1, x0)

    def project(self, x):
        return self.model.project(x)


@model_dataclass
class Discretized(OnModel):
    """The discrete-time model of a continuous :class:`Model` (the EKF's and Newton observer's
    ``F``): over one sample of length ``dt`` it takes ``n`` RK4 sub-steps of ``dt / n``, sub-step
    ``i`` with input ``u[i]`` held (``u`` a pytree whose leaves have a leading axis ``n``: the input
    averaged over each sub-interval), under ``lax.scan``. ``output``, ``retract`` and
    ``difference`` are the model's. ``single_input=True``: ``u`` is one input held over the whole
    sample with ``substeps`` sub-steps. ``scheme="euler"``: forward-Euler sub-steps
    ``x + h·f(x, u)`` instead of RK4 (P11 §V.C's discretization, first order: the same model
    value, a coarser internal model of it)."""

    model: Any
    substeps: int = static_field(1)
    single_input: bool = static_field(False)
    scheme: str = static_field("rk4")

    def __post_init__(self):
        if self.scheme not in STEPS:
            raise InputError(f"Discretized: scheme must be one of {sorted(STEPS)}, "
                             f"got {self.scheme!r}")

    def transition(self, x, u, dt):
        if self.single_input:
            u = jax.tree_util.tree_map(lambda a: jnp.broadcast_to(a, (self.substeps,)
                                                                  + jnp.shape(a)),
                                       u)
        n = jax.tree_util.tree_leaves(u)[0].shape[0]
        h = dt / n
        step = STEPS[self.scheme]

        def body(xx, uu):
            return step(self.model, xx, uu, h), None

        return jax.lax.scan(body, x, u)[0]


def tangent_dim(model, x) -> int:
    """Dimension of the tangent space at ``x`` (the size of ``model.difference(x, x)``)."""
    return int(jnp.size(model.difference(x, x)))


def simulate(model: Model, x0, u_of_t: Callable, dt_s: float, n_steps: int, t0_s: float = 0.0):
    """Integrate ``model.dynamics`` with fixed-step RK4 from ``x0`` for ``n_steps`` steps of
    ``dt_s``, the input ``u_of_t(t)`` evaluated at each step's start and held. Returns
    ``(x_final, xs)`` with ``xs`` the states after each step (leading axis ``n_steps``)."""

    def body(x, k):
        x = step_rk4(model, x, u_of_t(t0_s + k * dt_s), dt_s)
        return x, x

    return jax.lax.scan(body, x0, jnp.arange(n_steps))
