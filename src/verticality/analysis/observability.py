"""Local (generic-rank) observability and identifiability of analytic models ẋ = f(x, u, θ), y = h(x, u, θ).

The test (Hermann & Krener 1977; the algebraic form used by Sedoglavic, F §3.1.2) asks whether the
differentials of the outputs and of their time derivatives, ``d y, d ẏ, …, d y^(k)``, span the
differential of a quantity of interest ``q(x, θ)``. Along a solution, ``y^(k)`` is the k-th Lie
derivative of ``h`` along the extended vector field in which

- the *state* ``x`` follows ``f`` (state feedback is simply part of ``f``),
- the *unknown constants* ``θ`` (parameters, constant unknown inputs) are states with ``θ̇ = 0``,
- the *known inputs* ``u`` enter with their time derivatives ``u, u̇, ü, …`` as free variables.

How it is computed. Instead of building the Lie derivatives symbolically, the output derivatives at
a point are obtained in Taylor mode (``jax.experimental.jet``): the Taylor coefficients of the
solution ``x(t)`` are generated order by order (``x^(k+1) = [f(x(t), u(t))]^(k)``), the input's
derivatives being random numbers, and ``y^(0..K)`` follow from one more ``jet`` of ``h``. The
observability matrix ``O_K = ∂(y, …, y^(K)) / ∂z`` is the forward-mode Jacobian (``jax.jacfwd``) of that
map with respect to local coordinates ``z`` of the (extended) state. The cost is polynomial in K,
where nested ``jvp`` would be exponential.

Manifolds. A state declared ``"so3"`` is a rotation matrix; its local coordinates are
``R = R₀ exp(hat(δ))`` (δ ∈ R³, differentiated at δ = 0), so the rank is taken on the tangent space of
SO(3) and the orthonormality constraint is respected. ``chart="ambient"`` instead treats the nine
entries as free variables (no orthonormality) and evaluates at random *generic* matrices: the
formulation of a rational-model tool given rotation-matrix entries as states.

Rank. Rows are normalised (the row space does not change), then the numerical rank is the number
of singular values above ``rtol · σ_max`` (default ``rtol = 1e-8``); the *gap* ``σ_r / σ_{r+1}`` is
reported so a reader can see how clear the decision was. A quantity ``q`` is observable when each
row of ``∂q/∂z`` lies in the row space of ``O_K``: its relative distance to that space (the
*residual*) is below ``qtol`` (default ``1e-6``). The generic rank is the maximum over several random
points; a point where the rank is lower sits on a singular set and is reported.

Limits: this is a *local*, *generic* test: "observable" means locally (weakly) observable at almost
every point; it says nothing about global uniqueness, and a property that holds only on a thin set
of states (e.g. at an equilibrium) is not seen.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jax.experimental.jet import jet

from verticality import so3
from verticality.analysis.observability_taylor import taylor
from verticality.errors import InputError

SO3 = "so3"
DEFAULT_RTOL = 1e-8
DEFAULT_QTOL = 1e-6


# ---------------------------------------------------------------------------------------------
# Problem description
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Problem:
    """An observability problem.

    ``f(x, u, theta) -> dict`` (same keys as ``x``) and ``h(x, u, theta) -> (p,)`` take dicts of arrays:
    ``x`` the states (``states`` maps each name to a shape tuple or to ``"so3"`` for a rotation
    matrix), ``theta`` the unknown constants (``unknowns``: name → shape), ``u`` the known inputs
    (``inputs``: name → shape). ``quantities`` maps a name to ``q(x, theta) -> array``, the functions
    whose observability is asked (each unknown constant is added automatically as ``"theta:<name>"``).
    ``sample(rng)`` optionally draws a point ``(x, theta)`` (NumPy arrays) from a
    ``numpy.random.Generator`` (default: uniform random rotations, standard-normal vectors).
    """

    f: Callable[[dict, dict, dict], dict]
    h: Callable[[dict, dict, dict], Any]
    states: Mapping[str, Any]
    unknowns: Mapping[str, tuple] = field(default_factory=dict)
    inputs: Mapping[str, tuple] = field(default_factory=dict)
    quantities: Mapping[str, Callable[[dict, dict], Any]] = field(default_factory=dict)
    sample: Callable[[np.random.Generator], tuple[dict, dict]] | None = None
    input_scale: float = 1.0

    def __post_init__(self):
        for name, spec in self.states.items():
            if not (spec == SO3 or isinstance(spec, tuple)):
                raise InputError(f"state {name!r}: shape tuple or 'so3' expected, got {spec!r}")
        clash = set(self.states) & set(self.unknowns)
        if clash:
            raise InputError(f"names used both as state and unknown: {sorted(clash)}")


def _shape(spec):
    return (3, 3) if spec == SO3 else tuple(spec)


class _Layout:
    """Flat ambient vector X = [states..., unknowns...] and the local coordinates z."""

    def __init__(self, problem: Problem, chart: str):
        if chart not in ("tangent", "ambient"):
            raise InputError(f"chart must be 'tangent' or 'ambient', got {chart!r}")
        self.chart = chart
        self.blocks = []  # (name, kind, shape, ambient slice, coordinate slice)
        a = c = 0
        for name, spec in list(problem.states.items()) + [
            (k, tuple(v)) for k, v in problem.unknowns.items()
        ]:
            shape = _shape(spec)
            size = int(np.prod(shape)) if shape else 1
            kind = SO3 if spec == SO3 else "vector"
            dim = 3 if (kind == SO3 and chart == "tangent") else size
            self.blocks.append((name, kind, shape, slice(a, a + size), slice(c, c + dim)))
            a += size
            c += dim
        self.n_ambient, self.n_coords = a, c
        self.n_states = len(problem.states)
        self.input_blocks = []
        b = 0
        for name, shape in problem.inputs.items():
            shape = tuple(shape)
            size = int(np.prod(shape)) if shape else 1
            self.input_blocks.append((name, shape, slice(b, b + size)))
            b += size
        self.n_inputs = b

    def coordinate_labels(self) -> list[str]:
        labels = []
        for name, kind, shape, _, cs in self.blocks:
            n = cs.stop - cs.start
            if kind == SO3 and self.chart == "tangent":
                labels += [f"{name}.δ{ax}" for ax in "xyz"]
            elif n == 1 and not shape:
                labels.append(name)
            else:
                labels += [f"{name}[{','.join(map(str, idx))}]" for idx in np.ndindex(*shape)]
        return labels

    def unpack(self, X) -> tuple[dict, dict]:
        x, th = {}, {}
        for i, (name, _, shape, s, _) in enumerate(self.blocks):
            (x if i < self.n_states else th)[name] = X[s].reshape(shape)
        return x, th

    def pack(self, x: Mapping, th: Mapping):
        parts = []
        for i, (name, _, _, _, _) in enumerate(self.blocks):
            v = x[name] if i < self.n_states else th[name]
            parts.append(jnp.ravel(jnp.asarray(v, dtype=jnp.float64)))
        return jnp.concatenate(parts) if parts else jnp.zeros(0)

    def unpack_u(self, U) -> dict:
        return {name: U[s].reshape(shape) for name, shape, s in self.input_blocks}

    def chart_map(self, X0):
        """z ↦ X: R = R₀ exp(hat δ) for SO(3) blocks in the tangent chart, X₀ + z otherwise."""

        def phi(z):
            parts = []
            for _, kind, _shp, s, cs in self.blocks:
                if kind == SO3 and self.chart == "tangent":
                    R = X0[s].reshape(3, 3) @ so3.exp(z[cs])
                    parts.append(R.ravel())
                else:
                    parts.append(X0[s] + z[cs])
            return jnp.concatenate(parts)

        return phi


# ---------------------------------------------------------------------------------------------
# Output derivatives in Taylor mode
# ---------------------------------------------------------------------------------------------


def _flat_fields(problem: Problem, lay: _Layout):
    def F(X, U):
        x, th = lay.unpack(X)
        u = lay.unpack_u(U)
        dx = problem.f(x, u, th)
        parts = [jnp.ravel(jnp.asarray(dx[name], dtype=jnp.float64)) for name in problem.states]
        parts.append(jnp.zeros(lay.n_ambient - sum(p.size for p in parts)))
        return jnp.concatenate(parts)

    def H(X, U):
        x, th = lay.unpack(X)
        return jnp.ravel(jnp.asarray(problem.h(x, lay.unpack_u(U), th), dtype=jnp.float64))

    return F, H


def output_derivatives_jet(F, H, X0, Useries, order: int):
    """``(y, ẏ, …, y^(order))`` at ``X0`` for ``Ẋ = F(X, u(t))``, ``y = H(X, u(t))``.

    ``Useries[k]`` is ``u^(k)(0)`` (shape (order + 1, n_u)). Returns shape (order + 1, p).

    Taylor coefficients (derivative convention) of the solution are generated by a fixed-size
    ``jet`` of ``F`` inside ``lax.fori_loop``: the k-th output coefficient of ``jet`` depends only on the
    input coefficients up to k, so with the unknown higher coefficients left at zero, iteration k
    reads ``x^(k+1) = [F(x(t), u(t))]^(k)`` exactly. One trace of order ``order`` serves all iterations.
    """
    U0 = Useries[0]
    if order == 0:
        return H(X0, U0)[None]
    useries = [Useries[j] for j in range(1, order + 1)]
    d0 = jnp.zeros((order, X0.shape[0]), dtype=X0.dtype)  # rows: x', x'', ..., x^(order)

    def body(k, d):
        _, series = jet(F, (X0, U0), (list(d), useries))
        return d.at[k].set(jnp.stack(series)[k - 1])

    d = d0.at[0].set(F(X0, U0))
    d = jax.lax.fori_loop(1, order, body, d)
    y0, ys = jet(H, (X0, U0), (list(d), useries))
    return jnp.stack([y0] + list(ys))


def output_derivatives(F, H, X0, Useries, order: int):
    """Normalised Taylor coefficients ``y^(k)(0)/k!``, k = 0..order (shape (order + 1, p)).

    Same as :func:`output_derivatives_jet` up to the factors k! (irrelevant for a rank), computed
    with the vectorised Taylor interpreter of :mod:`observability_taylor` (compile time linear in
    ``order``). ``Useries[k]`` is the k-th normalised coefficient of the known inputs.
    """
    U0 = Useries[0]
    if order == 0:
        return H(X0, U0)[None]
    us = Useries[1:]

    def body(k, c):
        Fk = taylor(F, (X0, U0), (c, us))
        return c.at[k].set(Fk[k] / (k + 1))

    c = jnp.zeros((order, X0.shape[0]), dtype=X0.dtype).at[0].set(F(X0, U0))
    c = jax.lax.fori_loop(1, order, body, c)
    return taylor(H, (X0, U0), (c, us))


# ---------------------------------------------------------------------------------------------
# Rank and results
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class QuantityResult:
    name: str
    observable: bool
    derivatives_needed: int | None  # smallest k with q in span(dy..dy^(k)); None if never
    residual: float  # relative distance of dq to the row space of O_K (max over rows and points)


@dataclass(frozen=True)
class ObservabilityResult:
    """Outcome of :func:`analyze`.

    ``rank_by_order[k]`` is the generic rank of ``O_k`` (outputs and derivatives up to order k);
    ``null_space`` has the unobservable directions (columns, in the coordinates ``labels``) at the
    first point; ``gap`` is ``σ_r/σ_{r+1}`` of the final matrix (inf when full rank).
    """

    n_coords: int
    labels: list[str]
    rank: int
    rank_by_order: list[int]
    orders_used: int
    saturated_at: int  # smallest order k at which O_k reaches the final rank
    ranks_at_points: list[int]
    gap: float
    singular_values: np.ndarray
    null_space: np.ndarray
    quantities: dict[str, QuantityResult]
    chart: str
    rtol: float
    qtol: float
    stalled: bool = True  # the rank did not grow at the last order used (saturation reached)
    point: tuple[dict, dict] | None = None  # (x, theta) of the point whose null space is reported

    def in_null_space(self, v, tol: float = 1e-6) -> bool:
        """Whether the direction ``v`` (in the coordinates ``labels``) is unobservable."""
        v = np.asarray(v, dtype=float)
        if not np.any(v):
            return False
        v = v / np.linalg.norm(v)
        N = self.null_space
        rem = v - N @ (N.T @ v) if N.size else v
        return bool(np.linalg.norm(rem) < tol)

    @property
    def observable(self) -> bool:
        return self.rank == self.n_coords

    def describe_null_space(self, top: int = 4, threshold: float = 0.05) -> list[str]:
        """One line per unobservable direction: its largest components."""
        out = []
        N = sparse_basis(self.null_space)
        for j in range(N.shape[1]):
            v = N[:, j]
            idx = [i for i in np.argsort(-np.abs(v)) if abs(v[i]) > threshold][:top]
            out.append(" ".join(f"{v[i]:+.2f}·{self.labels[i]}" for i in idx))
        return out


def sparse_basis(N: np.ndarray) -> np.ndarray:
    """A basis of span(N) in reduced column-echelon form (readable directions), unit columns."""
    if N.size == 0:
        return N
    Q = N.copy()
    m, r = Q.shape
    M = Q.T.copy()  # rows span the space
    piv_row = 0
    for col in range(m):
        if piv_row >= r:
            break
        p = piv_row + int(np.argmax(np.abs(M[piv_row:, col])))
        if abs(M[p, col]) < 1e-9:
            continue
        M[[piv_row, p]] = M[[p, piv_row]]
        M[piv_row] /= M[piv_row, col]
        for i in range(r):
            if i != piv_row:
                M[i] -= M[i, col] * M[piv_row]
        piv_row += 1
    M = M / np.linalg.norm(M, axis=1, keepdims=True)
    return M.T


def _normalize_rows(A: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(A, axis=1, keepdims=True)
    keep = n[:, 0] > 0
    return A[keep] / n[keep]


def numerical_rank(A: np.ndarray, rtol: float = DEFAULT_RTOL) -> tuple[int, float, np.ndarray]:
    """Rank of ``A`` after row normalisation: singular values above ``rtol·σ_max``; and the gap."""
    A = _normalize_rows(np.asarray(A, dtype=float))
    if A.size == 0:
        return 0, math.inf, np.zeros(0)
    s = np.linalg.svd(A, compute_uv=False)
    r = int(np.sum(s > rtol * s[0])) if s[0] > 0 else 0
    gap = math.inf if r >= len(s) or s[r] == 0 else (s[r - 1] / s[r] if r > 0 else 0.0)
    return r, gap, s


def _residual(Vr: np.ndarray, G: np.ndarray) -> float:
    """Largest relative distance of the rows of G to span of the columns of Vr (orthonormal)."""
    worst = 0.0
    for g in np.atleast_2d(G):
        n = np.linalg.norm(g)
        if n == 0:
            continue
        g = g / n
        rem = g - Vr @ (Vr.T @ g)
        worst = max(worst, float(np.linalg.norm(rem)))
    return worst


def random_rotation(rng: np.random.Generator) -> np.ndarray:
    """A rotation matrix drawn uniformly on SO(3) (normalised Gaussian quaternion), NumPy."""
    w, x, y, z = rng.standard_normal(4)
    n = math.sqrt(w * w + x * x + y * y + z * z)
    w, x, y, z = w / n, x / n, y / n, z / n
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])


def default_sample(problem: Problem, rng: np.random.Generator) -> tuple[dict, dict]:
    """Random rotations for SO(3) states, standard normal entries otherwise."""
    x = {name: random_rotation(rng) if spec == SO3 else rng.standard_normal(_shape(spec))
         for name, spec in problem.states.items()}
    th = {name: rng.standard_normal(tuple(shape)) for name, shape in problem.unknowns.items()}
    return x, th


_COMPILED: dict = {}


def _compiled(problem: Problem, lay: _Layout, order: int):
    """jit(vmap(point ↦ (O, {q: ∂q/∂z}))), cached per (problem, order, chart)."""
    key = (id(problem), order, lay.chart)
    hit = _COMPILED.get(key)
    if hit is not None and hit[0] is problem:
        return hit[1]
    F, H = _flat_fields(problem, lay)

    def one(X0, U):
        phi = lay.chart_map(X0)
        z0 = jnp.zeros(lay.n_coords)
        O = jax.jacfwd(lambda z: output_derivatives(F, H, phi(z), U, order))(z0)
        grads = {}
        for qname, q in problem.quantities.items():
            def qz(z, q=q):
                xx, th = lay.unpack(phi(z))
                return jnp.ravel(jnp.asarray(q(xx, th), dtype=jnp.float64))

            grads[qname] = jax.jacfwd(qz)(z0)
        return O, grads

    fn = jax.jit(jax.vmap(one))
    _COMPILED[key] = (problem, fn)
    return fn


def observability_matrix(problem: Problem, order: int, *, chart: str = "tangent", seed: int = 0,
                         points: int = 1, fixed: Mapping[str, Any] | None = None,
                         zero_inputs: tuple[str, ...] = ()):
    """Observability matrices at ``points`` random points.

    Returns ``(O, grads, layout, keep, X0s)``: ``O`` (points, order+1, p, n_coords) holds the normalised
    coefficients ``∂(y^(k)/k!)/∂z``; ``grads[q]`` (points, dim q, n_coords) the gradients of the
    quantities; ``keep`` the boolean mask of the coordinates that are unknown (the columns of the
    ``fixed`` constants are to be dropped by the caller); ``X0s`` the ambient points.
    """
    fixed = dict(fixed or {})
    for name in fixed:
        if name not in problem.unknowns:
            raise InputError(f"fixed: {name!r} is not an unknown constant of the problem")
    for name in zero_inputs:
        if name not in problem.inputs:
            raise InputError(f"zero_inputs: {name!r} is not an input of the problem")
    lay = _Layout(problem, chart)
    rng = np.random.default_rng(seed)
    X0s, Us = [], []
    for _ in range(points):
        x, th = (problem.sample or (lambda r: default_sample(problem, r)))(rng)
        x = {k: np.asarray(v, dtype=float) for k, v in x.items()}
        for name, spec in problem.states.items():
            if spec == SO3 and chart == "ambient":  # a generic (non-orthogonal) matrix
                x[name] = x[name] + 0.5 * rng.standard_normal((3, 3))
        th = {k: np.broadcast_to(np.asarray(fixed.get(k, v), dtype=float), problem.unknowns[k])
              for k, v in th.items()}
        X0s.append(np.asarray(lay.pack(x, th)))
        U = problem.input_scale * rng.standard_normal((order + 1, lay.n_inputs))
        for name, _, sl in lay.input_blocks:
            if name in zero_inputs:
                U[:, sl] = 0.0
        Us.append(U)
    O, grads = _compiled(problem, lay, order)(jnp.asarray(np.stack(X0s)), jnp.asarray(np.stack(Us)))
    keep = np.ones(lay.n_coords, dtype=bool)
    for name, _, _, _, cs in lay.blocks:
        if name in fixed:
            keep[cs] = False
    return (np.asarray(O), {k: np.asarray(v) for k, v in grads.items()}, lay, keep,
            np.stack(X0s))


def _n_outputs(problem: Problem, lay: _Layout) -> int:
    F, H = _flat_fields(problem, lay)
    X = jax.ShapeDtypeStruct((lay.n_ambient,), jnp.float64)
    U = jax.ShapeDtypeStruct((lay.n_inputs,), jnp.float64)
    return int(jax.eval_shape(H, X, U).shape[0])


def analyze(problem: Problem, *, order: int | None = None, chart: str = "tangent", points: int = 3,
            seed: int = 0, rtol: float = DEFAULT_RTOL, qtol: float = DEFAULT_QTOL,
            fixed: Mapping[str, Any] | None = None, zero_inputs: tuple[str, ...] = ()
            ) -> ObservabilityResult:
    """Generic-rank observability test of ``problem``; see the module docstring.

    ``order`` is the highest output derivative used. By default it starts at ``⌈n/p⌉ + 1`` (n local
    coordinates, p outputs) and doubles while the rank still grows at the last order; the rank of
    the (generic) observability filtration never grows again once it has stalled for one order.
    ``fixed`` gives known values to some of ``problem.unknowns`` (they are then not unknown: their
    columns are dropped); ``zero_inputs`` names known inputs that are identically zero. Both let one
    compiled problem serve several cases.
    """
    fixed = dict(fixed or {})
    lay = _Layout(problem, chart)
    auto = order is None
    if auto:
        p_out = _n_outputs(problem, lay)
        order = min(lay.n_coords, -(-lay.n_coords // max(p_out, 1)) + 1)
    if order < 0:
        raise InputError(f"order must be >= 0, got {order}")
    while True:
        O, grads, lay, keep, X0s = observability_matrix(problem, order, chart=chart, seed=seed,
                                                   points=points, fixed=fixed,
                                                   zero_inputs=zero_inputs)
        O = O[..., keep]
        n = int(keep.sum())
        last = [numerical_rank(O[i].reshape(-1, n), rtol)[0] for i in range(points)]
        prev = [numerical_rank(O[i, :order].reshape(-1, n), rtol)[0] for i in range(points)]
        if not auto or order == 0 or last == prev or max(last) == n or order >= lay.n_coords:
            break
        order = min(lay.n_coords, 2 * order)
    labels = [lab for lab, k in zip(lay.coordinate_labels(), keep, strict=True) if k]
    ranks_at_points, by_order_pts, svals, gaps, nulls, bases = [], [], [], [], [], []
    for i in range(points):
        by_order, basis_by_order = [], []
        for k in range(order + 1):
            A = _normalize_rows(O[i, : k + 1].reshape(-1, n))
            r, gap, s = numerical_rank(A, rtol)
            _, _, Vt = np.linalg.svd(A)
            by_order.append(r)
            basis_by_order.append(Vt[:r].T)
        by_order_pts.append(by_order)
        bases.append(basis_by_order)
        ranks_at_points.append(by_order[-1])
        svals.append(s)
        gaps.append(gap)
        nulls.append(Vt[by_order[-1]:].T)
    rank = max(ranks_at_points)
    best = [i for i in range(points) if ranks_at_points[i] == rank]
    rank_by_order = [max(by_order_pts[i][k] for i in best) for k in range(order + 1)]
    saturated_at = next(k for k in range(order + 1) if rank_by_order[k] == rank)

    qgrads = {q: g[..., keep] for q, g in grads.items()}
    for name in problem.unknowns:
        if name in fixed:
            continue
        blk = [b for b in lay.blocks if b[0] == name][0]
        G = np.zeros((blk[4].stop - blk[4].start, lay.n_coords))
        G[:, blk[4]] = np.eye(G.shape[0])
        qgrads[f"theta:{name}"] = np.broadcast_to(G[:, keep], (points,) + G[:, keep].shape)
    quantities: dict[str, QuantityResult] = {}
    for qname, G in qgrads.items():
        residual = max(_residual(bases[i][-1], G[i]) for i in best)
        needed = next((k for k in range(order + 1)
                       if all(_residual(bases[i][k], G[i]) <= qtol for i in best)), None)
        quantities[qname] = QuantityResult(qname, residual <= qtol, needed, residual)
    return ObservabilityResult(
        n_coords=n, labels=labels, rank=rank, rank_by_order=rank_by_order, orders_used=order,
        saturated_at=saturated_at, ranks_at_points=ranks_at_points, gap=float(gaps[best[0]]),
        singular_values=svals[best[0]], null_space=nulls[best[0]], quantities=quantities,
        chart=chart, rtol=rtol, qtol=qtol, stalled=rank_by_order[-1] == rank_by_order[-2]
        if order > 0 else True,
        point=tuple({k: np.asarray(v) for k, v in d.items()} for d in lay.unpack(X0s[best[0]])),
    )
