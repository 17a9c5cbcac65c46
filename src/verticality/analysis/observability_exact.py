"""Exact (rational-arithmetic) generic-rank test with sympy, for small rational models.

The cross-check of the numerical tool (:mod:`observability`): Lie derivatives are built
symbolically with the inputs' derivatives as new symbols (``u_k`` for ``u^(k)``), the Jacobian with
respect to the states and unknown constants is evaluated at a random rational point, and its rank is
exact. Feasible only for a handful of states (the expressions grow with each derivative).
"""

from __future__ import annotations

import random
from collections.abc import Sequence

import sympy as sp


def lie_derivatives(f: Sequence, h: Sequence, states: Sequence, inputs: Sequence = (),
                    order: int = 3) -> tuple[list, list]:
    """Rows ``h, ḣ, …`` up to ``order`` and the input-derivative symbols used
    (``u`` → ``u_1, u_2…``)."""
    states = list(states)
    chains = {u: [u] + [sp.Symbol(f"{u.name}_{k}") for k in range(1, order + 1)] for u in inputs}
    out, cur = [], [sp.sympify(e) for e in h]
    for k in range(order + 1):
        out.append(cur)
        if k == order:
            break
        nxt = []
        for e in cur:
            d = sum(sp.diff(e, x) * fx for x, fx in zip(states, f, strict=True))
            for chain in chains.values():
                d += sum(sp.diff(e, chain[j]) * chain[j + 1] for j in range(order))
            nxt.append(sp.expand(d) if e.is_polynomial() else sp.simplify(d))
        cur = nxt
    return out, [s for c in chains.values() for s in c]


def exact_rank(f, h, states, unknowns=(), inputs=(), order: int = 3, seed: int = 0) -> list[int]:
    """Exact rank of the observability matrix for orders 0..order at a random rational point.

    ``f`` gives ``ẋ`` for each state; unknown constants are appended with zero derivative.
    """
    variables = list(states) + list(unknowns)
    field = list(f) + [0] * len(unknowns)
    rows, input_syms = lie_derivatives(field, h, variables, inputs, order)
    rng = random.Random(seed)
    point = {s: sp.Rational(rng.randint(1, 97), rng.randint(1, 13))
             for s in variables + input_syms}
    ranks, acc = [], []
    for block in rows:
        acc += [[sp.diff(e, v).subs(point) for v in variables] for e in block]
        ranks.append(sp.Matrix(acc).rank())
    return ranks
