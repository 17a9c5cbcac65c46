"""verticality.core.compiling: the kernels evaluated once compile at XLA's backend level 0 and give
the default compilation's numbers to rounding, in each form the package uses."""

import jax
import jax.numpy as jnp
import numpy as np

from verticality.core import so3
from verticality.core.compiling import EVALUATED_ONCE, jit_evaluated_once


def _tower(x, n):
    """The first ``n`` derivatives of a scalar function of a rotation vector, flattened (the kind
    of program the observability analysis compiles: nested forward-mode derivatives)."""
    def f(v):
        return jnp.dot(so3.exp(v) @ jnp.array([0.0, 0.0, 1.0]), jnp.sin(v))

    out, g = [jnp.ravel(f(x))], f
    for _ in range(n):
        g = jax.jacfwd(g)
        out.append(jnp.ravel(g(x)))
    return jnp.concatenate(out)


def test_the_option_is_xlas_and_the_numbers_are_the_default_compilations():
    assert EVALUATED_ONCE == {"xla_backend_optimization_level": 0}
    x = jnp.array([0.3, -0.2, 0.1])
    ref = np.asarray(jax.jit(_tower, static_argnums=1)(x, 3))
    assert ref.shape == (1 + 3 + 9 + 27,)
    for fn in (jit_evaluated_once(_tower, static_argnums=1),
               jit_evaluated_once(static_argnums=1)(_tower),
               jit_evaluated_once(static_argnames=("n",))(_tower)):
        np.testing.assert_allclose(np.asarray(fn(x, n=3)), ref, rtol=1e-13, atol=1e-15)
    # XLA refuses an option it does not know when it compiles: so the one above is a real option
    bad = jax.jit(_tower, static_argnums=1, compiler_options={"xla_no_such_option": 0})
    try:
        bad(x, 1)
    except Exception as e:  # noqa: BLE001 (XLA's error type is not public)
        assert "xla_no_such_option" in str(e)
    else:
        raise AssertionError("XLA accepted an unknown compiler option")


def test_as_a_bare_decorator():
    @jit_evaluated_once
    def sq(v):
        return v * v

    assert float(sq(3.0)) == 9.0
