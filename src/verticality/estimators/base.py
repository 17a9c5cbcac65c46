"""The estimator interface, shared by every estimator of the project.

Every estimator (Kalman filter, Luenberger observer, extended disturbance observer, Tahboub's
otolith–canal filter, EKF, Newton observer, 3-D tilt filter) is a frozen value — its design or
model and its settings — with three methods in one argument order::

    state = est.init(x0, P0)                      # P0 may be None where there is no covariance
    state = est.predict(state, u, dt)             # the time update alone: what step does when
                                                  # every component of y is missing
    state, out = est.step(state, u, y, dt)        # one sample
    state, outs = est.run(state, us, ys, dts)     # the same step over a sequence (lax.scan):
                                                  # the final state and the stacked outputs

``u`` is the known input that drove the system from the previous sample to this one, ``y`` the
measurement at this sample, ``dt`` the time since the previous sample (a scalar, or one per sample
in ``run``). ``run`` equals ``step`` applied sample by sample.

Missing data: a NaN in ``y`` means "no measurement" for that component. The estimator predicts
without it and says so in ``out.measured`` (bool, one per component of ``y``, or one for the whole
``y`` where the estimator uses it all or nothing); a ``y`` that is all NaN gives exactly
``predict``. Nothing turns a
finite estimate into a non-finite one: a non-finite candidate state is refused and the previous
one kept (:func:`keep_finite`). The helpers below are the one implementation of these rules.

A contract test (``tests/test_estimator_contract.py``) checks every estimator against this page.
"""

from __future__ import annotations

from typing import Any, Protocol, runtime_checkable

import jax
import jax.numpy as jnp


@runtime_checkable
class Estimator(Protocol):
    def init(self, x0, P0=None) -> Any: ...

    def predict(self, state, u, dt) -> Any: ...

    def step(self, state, u, y, dt) -> tuple[Any, Any]: ...

    def run(self, state, us, ys, dts) -> tuple[Any, Any]: ...


def split_measurement(y, y_fill=0.0):
    """``(y_safe, measured)``: ``measured`` is True where ``y`` is finite; ``y_safe`` holds ``y``
    there and ``y_fill`` (a scalar or an array like ``y``, e.g. the prediction) elsewhere, so
    that no NaN enters the arithmetic."""
    y = jnp.asarray(y, dtype=jnp.float64)
    measured = jnp.isfinite(y)
    return jnp.where(measured, y, y_fill), measured


def all_finite(tree) -> jnp.ndarray:
    """True when every leaf of ``tree`` is finite (a scalar bool array, traceable)."""
    leaves = [jnp.all(jnp.isfinite(jnp.asarray(leaf))) for leaf in jax.tree_util.tree_leaves(tree)
              if jnp.issubdtype(jnp.asarray(leaf).dtype, jnp.inexact)]
    return jnp.all(jnp.stack(leaves)) if leaves else jnp.asarray(True)


def keep_finite(candidate, previous):
    """``(chosen, ok)``: ``candidate`` if all of it is finite, else ``previous`` (leaf by leaf
    structure must match); ``ok`` says which."""
    ok = all_finite(candidate)
    return jax.tree_util.tree_map(lambda a, b: jnp.where(ok, a, b), candidate, previous), ok


def scan_steps(step, state, us, ys, dts):
    """``lax.scan`` of ``step(state, u, y, dt)`` over the leading axis of ``us``, ``ys`` and
    ``dts`` (``dts`` a scalar is used for every sample; ``us`` may be None). Returns
    ``(final_state, stacked_outs)`` — the shared body of the estimators' ``run``."""
    ys = jnp.asarray(ys, dtype=jnp.float64)
    n = ys.shape[0]
    dts = jnp.broadcast_to(jnp.asarray(dts, dtype=jnp.float64), (n,))

    def body(s, inp):
        u, y, dt = inp
        return step(s, u, y, dt)

    return jax.lax.scan(body, state, (us, ys, dts))
