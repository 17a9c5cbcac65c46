"""How the package asks XLA to compile a kernel, by what the kernel is for.

A kernel costs its compilation once and its run each time it is called. XLA's CPU backend
optimizes the machine code it emits (LLVM at its default level) at a price in compile time that
pays only over many or long runs. Most kernels of the package are of that kind: the tilt filter
runs over every recording a user gives it, the closed loops and sweeps over seconds to minutes of
simulated time. Some are built to be evaluated a handful of times on a few points: the towers of
derivatives of the observability analysis and the linearizations of the model checks, where the
compiled program is large (nested forward-mode derivatives) and its run takes microseconds. For
those the optimization is pure cost, so they are compiled at backend level 0.

Measured on the 2-core machine (docs/development.md, "Compile time"): the observability
experiment's derivative towers compile about twice as fast at level 0, the results equal to
rounding (≤ 1e-15 relative); the tilt filter at level 0 would compile 2.3× faster but run 1.65×
slower (37.9 against 22.9 ms for 200 s at 100 Hz), so it keeps the default.
"""

from __future__ import annotations

import functools

import jax

# XLA's backend (LLVM) optimization level 0 for kernels evaluated a few times on small inputs.
EVALUATED_ONCE = {"xla_backend_optimization_level": 0}


def jit_evaluated_once(fun=None, **jit_kwargs):
    """``jax.jit`` for a kernel evaluated a few times on small inputs (a derivative tower, a
    linearization at a point): compiled at XLA's backend optimization level 0
    (:data:`EVALUATED_ONCE`). Used as ``jit_evaluated_once(f, static_argnums=...)`` or as a
    decorator, with or without keyword arguments."""
    if fun is None:
        return functools.partial(jit_evaluated_once, **jit_kwargs)
    return jax.jit(fun, compiler_options=EVALUATED_ONCE, **jit_kwargs)
