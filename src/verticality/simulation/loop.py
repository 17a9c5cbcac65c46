"""One sampled closed loop: plant, sensors, estimator and controller, stepped sample by sample.

Per sample k (the plant state ``x`` and the estimator state ``est`` at the sample's start):

1. ``read(x, k)``: the sensors' readings ``y`` (noise drawn by k from the run's own draws);
2. ``correct(est, y, k)``: the estimator's steps that use the reading but not this sample's
   control (a Kalman filter or EKF predicting with the previous control and updating with ``y``);
3. ``control(est, y, k)``: the control ``u``, held over the sample;
4. ``predict(est, u, y, k)``: the estimator's steps that use this sample's control (a Luenberger
   observer stepped with ``u`` and ``y``; the previous control or reading kept for the next
   sample);
5. ``advance(x, u, k)``: the plant over the sample, by RK4 sub-steps with the control held
   (:func:`rk4_held`, :func:`rk4_staged_substeps`);
6. ``record(x, est, y, u, k)``: what the run keeps of the sample (``est`` after step 2).

The plant's state and the estimator's are pytrees of the caller's; a step an estimator does not
have is :func:`unchanged`. The loops of the planar experiments (`separation`, `platform`,
`ambiguity-*`, `ground-*`) are :class:`LoopParts` of their own modules run by :func:`run`.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp

from verticality.core.integrate import rk4_step, rk4_step_staged


class LoopParts(NamedTuple):
    """The callables of one closed loop (module docstring for their order and arguments)."""

    read: Callable[[Any, Any], Any]
    correct: Callable[[Any, Any, Any], Any]
    control: Callable[[Any, Any, Any], Any]
    predict: Callable[[Any, Any, Any, Any], Any]
    advance: Callable[[Any, Any, Any], Any]
    record: Callable[[Any, Any, Any, Any, Any], Any]


def unchanged(est, *_):
    """An estimator step that leaves the state as it is."""
    return est


def run(parts: LoopParts, x0, est0, n_samples: int):
    """``n_samples`` samples of the loop ``parts`` from ``(x0, est0)``; returns the final
    ``(x, est)`` and the stacked records."""

    def sample(carry, k):
        x, est = carry
        y = parts.read(x, k)
        est = parts.correct(est, y, k)
        u = parts.control(est, y, k)
        est_next = parts.predict(est, u, y, k)
        x_next = parts.advance(x, u, k)
        return (x_next, est_next), parts.record(x, est, y, u, k)

    return jax.lax.scan(sample, (x0, est0), jnp.arange(n_samples))


def rk4_held(f: Callable, t0_s, x, u, h_s, substeps: int):
    """``substeps`` RK4 steps of ``x' = f(t, x, u)`` of ``h_s`` each from ``t0_s``, ``u`` held
    (the time ``t0_s + i·h_s`` of sub-step i; ``f`` evaluates the exogenous inputs at t)."""

    def sub(i, xx):
        return rk4_step(f, t0_s + i * h_s, xx, h_s, u)

    return jax.lax.fori_loop(0, substeps, sub, x)


def rk4_staged_substeps(f: Callable, stages: Callable, x, h_s, substeps: int):
    """``substeps`` RK4 steps of ``h_s`` of ``x' = f(w, x)[0]`` with the input ``w`` given at
    the stages of each sub-step: ``stages(i)`` is sub-step i's start, middle and end
    (:func:`verticality.core.integrate.rk4_step_staged`)."""

    def sub(xx, i):
        return rk4_step_staged(f, stages(i), xx, h_s)[0], None

    return jax.lax.scan(sub, x, jnp.arange(substeps))[0]
