"""Observability matrix of the medial otolith model: Taylor interpreter vs ``jax.experimental.jet``.

Both compute ∂(y, ẏ, …, y^(K))/∂z at one random point (K = 6, 12 tangent coordinates + 7 unknown
constants); the time includes tracing and XLA compilation, which dominate. Prints the ratio.
Run: ``python benchmarks/bench_observability.py``.
"""

from __future__ import annotations

import math
import time

import jax
import jax.numpy as jnp
import numpy as np

from verticality.analysis import observability as ob
from verticality.analysis.otolith_observability import build_problem

K = 6


def timed(deriv, prob, lay, X0, U):
    F, H = ob.flat_fields(prob, lay)
    phi = lay.chart_map(X0)
    fn = jax.jit(lambda X0, U: jax.jacfwd(lambda z: deriv(F, H, phi(z), U, K))(
        jnp.zeros(lay.n_coords)))
    t0 = time.perf_counter()
    O = np.asarray(fn(X0, U))
    t1 = time.perf_counter()
    np.asarray(fn(X0, U))
    t2 = time.perf_counter()
    return O, t1 - t0, t2 - t1


def main():
    prob = build_problem("medial")
    lay = ob.layout(prob, "tangent")
    rng = np.random.default_rng(0)
    x, th = prob.sample(rng)
    X0 = jnp.asarray(lay.pack(x, th))
    U = jnp.asarray(rng.standard_normal((K + 1, lay.n_inputs)))
    fact = jnp.array([math.factorial(k) for k in range(K + 1)])[:, None]
    O1, c1, r1 = timed(ob.output_derivatives, prob, lay, X0, U)
    O2, c2, r2 = timed(lambda F, H, X, U_, k: ob.output_derivatives_jet(F, H, X, U_ * fact, k),
                       prob, lay, X0, U)
    same = np.allclose(O1 * fact[..., None], O2, rtol=1e-8, atol=1e-8 * np.abs(O2).max())
    print(f"order {K}, {lay.n_coords} coordinates; results agree: {same}")
    print(f"taylor interpreter: first call {c1:7.2f} s, second {r1 * 1e3:7.2f} ms")
    print(f"jax jet           : first call {c2:7.2f} s, second {r2 * 1e3:7.2f} ms")
    print(f"ratio jet / taylor (first call, compile included): {c2 / c1:5.2f}")
    print(f"ratio jet / taylor (compiled call):                {r2 / max(r1, 1e-12):5.2f}")


if __name__ == "__main__":
    main()
