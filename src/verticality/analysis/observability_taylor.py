"""Truncated Taylor arithmetic on jaxprs, vectorised over the series axis.

``jax.experimental.jet`` writes every product of two series as a Python double loop, so the traced
program grows as K² with the order K and XLA compile time dominates an observability test. This
interpreter evaluates a function's jaxpr on *normalised* Taylor coefficients ``c_k = x^(k)(0)/k!``
stored as arrays with a leading axis of length K + 1:

- values that carry no series (constants, parameters) stay plain arrays: the affine primitives then
  act only on the coefficient they touch, products with them broadcast;
- structural and linear primitives (slices, reshapes, concatenation, sums, transposes, ``select``
  with a constant predicate, …) are mapped over the series axis with ``vmap``;
- the product of two series (``mul``, ``dot_general``) is the Cauchy product, one ``einsum`` with
  the 0/1 tensor ``T[i, j, k] = [i + j = k]``;
- quotient, ``sin``/``cos``, ``exp``, ``sqrt`` and ``atan2`` use the classical recurrences
  (Griewank & Walther, *Evaluating Derivatives*, ch. 13), a loop of K small steps.

Equations no output depends on are skipped. An unsupported primitive raises
``NotImplementedError`` naming it.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
from jax import lax
from jax.extend import core as jcore


class _S:
    """A Taylor series: ``c`` has shape (K + 1, *shape)."""

    __slots__ = ("c",)

    def __init__(self, c):
        self.c = c


def _cauchy_tensor(K1: int):
    T = np.zeros((K1, K1, K1))
    for i in range(K1):
        for j in range(K1 - i):
            T[i, j, i + j] = 1.0
    return jnp.asarray(T)


def _promote(v, K1):
    if isinstance(v, _S):
        return v.c
    v = jnp.asarray(v)
    return jnp.concatenate([v[None], jnp.zeros((K1 - 1,) + v.shape, v.dtype)], axis=0)


def _mul_ss(a, b, K1):
    return jnp.einsum("ijk,i...,j...->k...", _cauchy_tensor(K1), a, b)


def _div_ss(a, b, K1):
    """q = a / b by q_k = (a_k − Σ_{j=1..k} b_j q_{k−j}) / b_0."""
    q = []
    for k in range(K1):
        acc = a[k]
        for j in range(1, k + 1):
            acc = acc - b[j] * q[k - j]
        q.append(acc / b[0])
    return jnp.stack(q)


def _deriv(c, K1):
    """Normalised series of the time derivative (last coefficient unknown → 0)."""
    k = jnp.arange(1, K1).reshape((-1,) + (1,) * (c.ndim - 1))
    return jnp.concatenate([c[1:] * k, jnp.zeros_like(c[:1])], axis=0)


def _integrate(d, c0, K1):
    k = jnp.arange(1, K1).reshape((-1,) + (1,) * (d.ndim - 1))
    return jnp.concatenate([c0[None], d[:-1] / k], axis=0)


def _sincos(x, K1):
    s, c = [jnp.sin(x[0])], [jnp.cos(x[0])]
    for k in range(1, K1):
        ds = sum(j * x[j] * c[k - j] for j in range(1, k + 1)) / k
        dc = -sum(j * x[j] * s[k - j] for j in range(1, k + 1)) / k
        s.append(ds)
        c.append(dc)
    return jnp.stack(s), jnp.stack(c)


def _exp(x, K1):
    e = [jnp.exp(x[0])]
    for k in range(1, K1):
        e.append(sum(j * x[j] * e[k - j] for j in range(1, k + 1)) / k)
    return jnp.stack(e)


def _sqrt(x, K1):
    s = [jnp.sqrt(x[0])]
    for k in range(1, K1):
        acc = x[k] - sum(s[j] * s[k - j] for j in range(1, k))
        s.append(acc / (2.0 * s[0]))
    return jnp.stack(s)


_LINEAR = {
    "add", "sub", "neg", "add_any", "reshape", "squeeze", "expand_dims", "broadcast_in_dim",
    "transpose", "slice", "concatenate", "reduce_sum", "convert_element_type", "copy", "rev",
    "pad", "select_n", "gather", "dynamic_slice", "dynamic_update_slice", "cumsum", "real",
    "copy_p", "split", "reduce_precision", "stack", "unstack", "reshard",
}
# operand positions that are indices / predicates (never series)
_INDEX_ARGS = {"select_n": (0,), "gather": (1,), "dynamic_slice": "rest",
               "dynamic_update_slice": "rest2"}
_PRIMAL_ONLY = {
    "lt", "le", "gt", "ge", "eq", "ne", "and", "or", "not", "sign", "iota", "floor", "ceil",
    "round", "is_finite", "stop_gradient", "argmax", "argmin",
}


def _index_positions(name, n):
    spec = _INDEX_ARGS.get(name, ())
    if spec == "rest":
        return tuple(range(1, n))
    if spec == "rest2":
        return tuple(range(2, n))
    return spec


def _primal(v):
    return v.c[0] if isinstance(v, _S) else v


def _live_eqns(jaxpr):
    """The equations that an output depends on (or that have effects), in order: dead code (e.g. an
    input a model's output ignores) is never expanded into series."""
    live = {v for v in jaxpr.outvars if not isinstance(v, jcore.Literal)}
    keep = []
    for eqn in reversed(jaxpr.eqns):
        if eqn.effects or any(v in live for v in eqn.outvars):
            keep.append(eqn)
            live.update(v for v in eqn.invars if not isinstance(v, jcore.Literal))
    return keep[::-1]


def _eval_jaxpr(jaxpr, consts, args, K1):
    env = {}

    def read(v):
        if isinstance(v, jcore.Literal):
            return v.val
        return env[v]

    for v, c in zip(jaxpr.constvars, consts, strict=True):
        env[v] = c
    for v, a in zip(jaxpr.invars, args, strict=True):
        env[v] = a
    for eqn in _live_eqns(jaxpr):
        ins = [read(v) for v in eqn.invars]
        outs = _apply(eqn.primitive, ins, eqn.params, K1)
        if not eqn.primitive.multiple_results:
            outs = [outs]
        for v, o in zip(eqn.outvars, outs, strict=True):
            env[v] = o
    return [read(v) for v in jaxpr.outvars]


def _apply(prim, ins, params, K1):
    name = prim.name
    if not any(isinstance(v, _S) for v in ins):
        return prim.bind(*ins, **params)
    if name in ("pjit", "jit", "closed_call", "core_call"):
        closed = params["jaxpr"]
        return _eval_jaxpr(closed.jaxpr, closed.consts, ins, K1)
    if name == "custom_jvp_call":
        closed = params["call_jaxpr"]
        return _eval_jaxpr(closed.jaxpr, closed.consts, ins, K1)
    if name == "custom_vjp_call":
        closed = params.get("call_jaxpr") or params["fun_jaxpr"]
        return _eval_jaxpr(closed.jaxpr, closed.consts, ins, K1)
    if name in _PRIMAL_ONLY:
        return prim.bind(*[_primal(v) for v in ins], **params)
    if name in _LINEAR:
        idx = _index_positions(name, len(ins))
        ops, axes = [], []
        for i, v in enumerate(ins):
            if i in idx:
                if isinstance(v, _S):
                    raise NotImplementedError(f"{name}: a series as index/predicate operand")
                ops.append(v)
                axes.append(None)
            else:
                ops.append(_promote(v, K1))
                axes.append(0)
        out = jax.vmap(lambda *o: prim.bind(*o, **params), in_axes=tuple(axes))(*ops)
        if prim.multiple_results:
            return [_S(o) for o in out]
        return _S(out)
    if name == "mul":
        a, b = ins
        if not isinstance(a, _S):
            return _S(a * b.c)
        if not isinstance(b, _S):
            return _S(a.c * b)
        return _S(_mul_ss(a.c, b.c, K1))
    if name == "integer_pow":
        n = params["y"]
        if n < 0:
            return _apply(lax.div_p, [1.0, _apply(lax.integer_pow_p, ins, {"y": -n}, K1)], {}, K1)
        out = _S(_promote(jnp.ones_like(_primal(ins[0])), K1))
        for _ in range(n):
            out = _S(_mul_ss(out.c, ins[0].c, K1))
        return out
    if name == "square":
        return _S(_mul_ss(ins[0].c, ins[0].c, K1))
    if name == "div":
        a, b = ins
        if not isinstance(b, _S):
            return _S(a.c / b)
        return _S(_div_ss(_promote(a, K1), b.c, K1))
    if name == "dot_general":
        a, b = ins

        def dot(x, y):
            return prim.bind(x, y, **params)

        if not isinstance(a, _S):
            return _S(jax.vmap(dot, in_axes=(None, 0))(a, b.c))
        if not isinstance(b, _S):
            return _S(jax.vmap(dot, in_axes=(0, None))(a.c, b))
        pairs = jax.vmap(jax.vmap(dot, in_axes=(None, 0)), in_axes=(0, None))(a.c, b.c)
        return _S(jnp.einsum("ijk,ij...->k...", _cauchy_tensor(K1), pairs))
    if name in ("sin", "cos"):
        s, c = _sincos(ins[0].c, K1)
        return _S(s if name == "sin" else c)
    if name == "exp":
        return _S(_exp(ins[0].c, K1))
    if name == "sqrt":
        return _S(_sqrt(ins[0].c, K1))
    if name == "abs":
        return _S(jnp.sign(ins[0].c[0]) * ins[0].c)
    if name == "atan2":
        y, x = (_promote(v, K1) for v in ins)
        num = _mul_ss(x, _deriv(y, K1), K1) - _mul_ss(y, _deriv(x, K1), K1)
        den = _mul_ss(x, x, K1) + _mul_ss(y, y, K1)
        return _S(_integrate(_div_ss(num, den, K1), jnp.arctan2(y[0], x[0]), K1))
    raise NotImplementedError(f"no Taylor rule for primitive {name!r}")


def taylor(fun, primals, series):
    """Normalised Taylor coefficients of ``fun`` along the curves given by ``series``.

    ``primals`` are arrays (the coefficient 0); ``series[i]`` has shape (K, *primals[i].shape) with
    the coefficients 1..K of input i (``None`` for an input that is constant in t). Returns an
    array (K + 1, *out.shape) of the normalised coefficients of ``fun`` (one output array).
    """
    K = next(s.shape[0] for s in series if s is not None)
    K1 = K + 1
    closed = jax.make_jaxpr(fun)(
        *[jax.ShapeDtypeStruct(jnp.shape(p), jnp.result_type(p)) for p in primals]
    )
    args = []
    for p, s in zip(primals, series, strict=True):
        p = jnp.asarray(p)
        args.append(p if s is None else _S(jnp.concatenate([p[None], s], axis=0)))
    (out,) = _eval_jaxpr(closed.jaxpr, closed.consts, args, K1)
    return _promote(out, K1)
