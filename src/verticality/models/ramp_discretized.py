"""Discretization of a continuous model fed a block of fast-rate inputs, one ramp per sub-step.

:class:`verticality.models.base.Discretized` holds one input per RK4 sub-step. When the inputs
are recorded at a faster rate than the sub-steps (P11's observer: inputs at 1 kHz, 5 sub-steps
per 25 ms sample), holding their mean loses the first moment: the head's double integrator then
misses part of its position increment. :class:`RampDiscretized` gives each sub-step its share of
the held fast-rate inputs as a ramp with the same mean and the same first moment about the
sub-step's centre, evaluated by the shared RK4 (:func:`verticality.core.integrate.rk4_step_staged`,
the input at the start, middle and end of the sub-step). For a double integrator driven by the input
this is exact (the velocity and position increments of the held inputs); for the rest of a model
it is second order in the sub-step.
"""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp

from verticality.core.errors import InputError
from verticality.core.integrate import rk4_step_staged
from verticality.models.base import OnModel, model_dataclass, static_field


def ramp_moments(u_block, substeps: int):
    """``(mean, ramp)`` per sub-step of a block of held fast-rate inputs (leading axis: fast
    samples, a multiple of ``substeps``): the ramp ``mean + ramp·(s − ½)``, s ∈ [0, 1] across the
    sub-step, has the block's mean and first moment about the sub-step's centre."""
    n_fast = jax.tree_util.tree_leaves(u_block)[0].shape[0]
    if n_fast % substeps:
        raise InputError(f"input block of {n_fast} samples is not a multiple of "
                         f"{substeps} sub-steps")
    k = n_fast // substeps
    # sample centres in units of the sub-step, relative to its centre: (j + 1/2)/k − 1/2
    c = (jnp.arange(k) + 0.5) / k - 0.5
    u_mean = jax.tree_util.tree_map(lambda a: a.reshape(substeps, k).mean(axis=1), u_block)
    # ramp amplitude du with ∫ du·s·ds (s ∈ [−½, ½]) = mean of a·c, i.e. du = 12·mean(a·c)
    u_ramp = jax.tree_util.tree_map(lambda a: 12.0 * (a.reshape(substeps, k) * c).mean(axis=1),
                                    u_block)
    return u_mean, u_ramp


@model_dataclass
class RampDiscretized(OnModel):
    """The discrete model ``F(x, u_block, dt)`` of a continuous ``model`` over one sample of
    length ``dt``: ``substeps`` RK4 steps of ``dt / substeps``, each fed its fast-rate inputs as a
    ramp (module docstring) under ``lax.scan`` (XLA compiles one RK4 step well; a chain of
    unrolled steps gets fused with duplicated work). ``output``, ``retract``, ``difference`` and
    ``project`` are the model's."""

    model: Any
    substeps: int = static_field(1)

    def transition(self, x, u_block, dt):
        u_mean, u_ramp = ramp_moments(u_block, self.substeps)
        h = dt / self.substeps

        def f(w, xx):
            return self.model.dynamics(xx, w), None

        def body(xx, u_mr):
            mean, ramp = u_mr
            ends = jax.tree_util.tree_map(lambda a, b: jnp.stack([a - 0.5 * b, a, a + 0.5 * b]),
                                          mean, ramp)
            return rk4_step_staged(f, ends, xx, h, project=self.model.project)[0], None

        return jax.lax.scan(body, x, (u_mean, u_ramp))[0]
