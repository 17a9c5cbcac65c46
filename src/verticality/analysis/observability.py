"""Local (generic-rank) observability and identifiability of a model value.

The model is a value of :mod:`verticality.models` (``dynamics(x, u)``, ``output(x, u)``,
``retract``, ``difference``), consumed unchanged. Around it a :class:`Problem` declares what the
test needs and the model does not know:

- the *unknown constants* ``θ`` (parameters, constant unknown inputs), states with ``θ̇ = 0``;
- the *known inputs* ``u``, which enter with their time derivatives ``u, u̇, ü, …`` as free
  variables;
- how they reach the model: ``input_map(x, u, θ)`` gives the model's input (state feedback is
  written here: an input that depends on ``x``), ``parameter_map(model, θ)`` puts unknown
  parameters into the model value (its leaves), ``output(model, x, u)`` replaces the model's
  output when another reading of the same state is studied;
- the *quantities* ``q(x, θ)`` whose observability is asked.

The test (Hermann & Krener 1977; the algebraic form used by Sedoglavic, F §3.1.2) asks whether the
differentials of the outputs and of their time derivatives, ``d y, d ẏ, …, d y^(k)``, span the
differential of ``q``. Along a solution, ``y^(k)`` is the k-th Lie derivative of the output along
the extended vector field (state, unknown constants, input chain).

How it is computed. Instead of building the Lie derivatives symbolically, the output derivatives at
a point are obtained in Taylor mode: the Taylor coefficients of the solution ``x(t)`` are generated
order by order (``x^(k+1) = [f(x(t), u(t))]^(k)``), the input's derivatives being random numbers,
and ``y^(0..K)`` follow from one more Taylor expansion of the output. The observability matrix
``O_K = ∂(y, …, y^(K)) / ∂z`` is the forward-mode Jacobian (``jax.jacfwd``) of that map with respect
to local coordinates ``z`` of the (extended) state. The cost is polynomial in K, where nested
``jvp`` would be exponential.

Charts. The state's leaves, flattened (``ravel_pytree``), followed by the unknown constants, are the
*ambient* vector in which the solution's Taylor series is computed. ``chart="tangent"`` (default)
takes the local coordinates from the model: ``z ↦ model.retract(x₀, z)`` (for a rotation matrix
``R₀ exp(hat δ)``, so the rank is taken on the tangent space of SO(3) and orthonormality is
respected), the unknowns ``θ₀ + z``. ``chart="ambient"`` treats every leaf entry as a free variable
and evaluates at *generic* points: the entries of a leaf that the retraction constrains (fewer
tangent directions than entries, e.g. a rotation matrix) are moved off the manifold at random — the
formulation of a rational-model tool given rotation-matrix entries as states.

Rank. Rows are normalised (the row space does not change), then the numerical rank is the number
of singular values above ``rtol · σ_max`` (default ``rtol = 1e-8``); the *gap* ``σ_r / σ_{r+1}`` is
reported so a reader can see how clear the decision was. A quantity ``q`` is observable when each
row of ``∂q/∂z`` lies in the row space of ``O_K``: its relative distance to that space (the
*residual*) is below ``qtol`` (default ``1e-6``). The generic rank is the maximum over several
random points; a point where the rank is lower sits on a singular set and is reported.

Limits: this is a *local*, *generic* test: "observable" means locally (weakly) observable at almost
every point; it says nothing about global uniqueness, and a property that holds only on a thin set
of states (e.g. at an equilibrium) is not seen.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jax.experimental.jet import jet

from verticality.analysis.observability_taylor import taylor
from verticality.core import so3
from verticality.core.compiling import jit_evaluated_once
from verticality.core.errors import InputError

DEFAULT_RTOL = 1e-8
DEFAULT_QTOL = 1e-6
AMBIENT_SPREAD = 0.5
"""Standard deviation of the random entries added to a constrained leaf in the ambient chart."""


# ---------------------------------------------------------------------------------------------
# Problem description
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Problem:
    """An observability problem around one model value (see the module docstring).

    ``model``: a model value (``dynamics(x, u)``, ``output(x, u)``, ``retract(x, dx)``,
    ``difference(x1, x0)``). ``state``: an example state, which fixes the state's pytree structure
    and shapes. ``unknowns``: name → shape of the unknown constants ``θ`` (a dict of arrays).
    ``inputs``: name → shape of the known inputs ``u`` (a dict of arrays).
    ``input_map(x, u, θ)``: the model's input (default: the dict ``u``).
    ``parameter_map(model, θ)``: the model with its unknown parameters put in (default: the model).
    ``output(model, x, u_model)``: the measured output (default: ``model.output(x, u_model)``).
    ``quantities``: name → ``q(x, θ)``, the functions whose observability is asked (each unknown
    constant is added automatically as ``"theta:<name>"``). ``sample(rng)`` draws a point ``(x, θ)``
    from a ``numpy.random.Generator`` (default: standard-normal leaves, for states on a vector
    space; a model on a manifold gives its own). ``leaf_names``: a name per leaf of the state, in
    flattening order, for the coordinate labels (default: the leaves' pytree paths).
    ``input_scale``: standard deviation of the inputs' random Taylor coefficients.
    """

    model: Any
    state: Any
    unknowns: Mapping[str, tuple] = field(default_factory=dict)
    inputs: Mapping[str, tuple] = field(default_factory=dict)
    input_map: Callable[[Any, dict, dict], Any] | None = None
    parameter_map: Callable[[Any, dict], Any] | None = None
    output: Callable[[Any, Any, Any], Any] | None = None
    quantities: Mapping[str, Callable[[Any, dict], Any]] = field(default_factory=dict)
    sample: Callable[[np.random.Generator], tuple[Any, dict]] | None = None
    leaf_names: Sequence[str] | None = None
    input_scale: float = 1.0

    def __post_init__(self):
        for part in ("dynamics", "output", "retract", "difference"):
            if not callable(getattr(self.model, part, None)):
                raise InputError(f"model: a model value with {part}() expected, got "
                                 f"{type(self.model).__name__}")
        for kind, specs in (("unknown", self.unknowns), ("input", self.inputs)):
            for name, shape in specs.items():
                if not (isinstance(shape, tuple) and all(isinstance(n, int) for n in shape)):
                    raise InputError(f"{kind} {name!r}: a shape tuple expected, got {shape!r}")
        n_leaves = len(jax.tree_util.tree_leaves(self.state))
        if self.leaf_names is not None and len(self.leaf_names) != n_leaves:
            raise InputError(f"leaf_names: {n_leaves} names expected (one per leaf of the state), "
                             f"got {len(self.leaf_names)}")

    def model_for(self, theta: dict):
        """The model value with the unknown constants ``theta`` put in."""
        return self.model if self.parameter_map is None else self.parameter_map(self.model, theta)

    def model_input(self, x, u: dict, theta: dict):
        return u if self.input_map is None else self.input_map(x, u, theta)

    def vector_field(self, x, u: dict, theta: dict):
        """``ẋ`` of the state (same pytree structure as ``x``)."""
        return self.model_for(theta).dynamics(x, self.model_input(x, u, theta))

    def measurement(self, x, u: dict, theta: dict):
        """The measured output, a flat array."""
        model = self.model_for(theta)
        um = self.model_input(x, u, theta)
        y = model.output(x, um) if self.output is None else self.output(model, x, um)
        return jnp.ravel(jnp.asarray(y, dtype=jnp.float64))


def flat(tree):
    """The leaves of ``tree`` ravelled and concatenated (``ravel_pytree``'s order)."""
    return jnp.concatenate([jnp.ravel(leaf) for leaf in jax.tree_util.tree_leaves(tree)])


def _size(shape) -> int:
    return int(np.prod(shape)) if shape else 1


def _path_name(path) -> str:
    parts = []
    for key in path:
        for attr in ("name", "key", "idx"):
            if hasattr(key, attr):
                parts.append(str(getattr(key, attr)))
                break
    return ".".join(parts) or "x"


def _entry_labels(name: str, shape) -> list[str]:
    if not shape:
        return [name]
    return [f"{name}[{','.join(map(str, idx))}]" for idx in np.ndindex(*shape)]


class Layout:
    """The ambient vector ``X = [state leaves (ravelled)…, unknowns…]`` and the coordinates ``z``.

    Built from the problem's example state: which tangent coordinates move which leaf is read from
    the Jacobian of ``z ↦ ravel(model.retract(state, z))`` at ``z = 0`` (each tangent column is
    given to the leaf it moves most), so labels and the ambient chart's constrained leaves come from
    the model's own retraction.
    """

    def __init__(self, problem: Problem, chart: str):
        if chart not in ("tangent", "ambient"):
            raise InputError(f"chart must be 'tangent' or 'ambient', got {chart!r}")
        self.chart = chart
        self.problem = problem
        state = jax.tree_util.tree_map(lambda a: jnp.asarray(a, dtype=jnp.float64), problem.state)
        paths_leaves, self.treedef = jax.tree_util.tree_flatten_with_path(state)
        names = (list(problem.leaf_names) if problem.leaf_names is not None
                 else [_path_name(p) for p, _ in paths_leaves])
        shapes = [tuple(np.shape(leaf)) for _, leaf in paths_leaves]
        starts = np.cumsum([0] + [_size(s) for s in shapes])
        self.n_state = int(starts[-1])
        self.n_tangent = n_t = int(np.size(jax.eval_shape(problem.model.difference, state, state)))
        self._retract_jacobian = jit_evaluated_once(lambda x: jax.jacfwd(
            lambda z: flat(problem.model.retract(x, z)))(jnp.zeros(n_t)))
        J = np.asarray(self._retract_jacobian(state))
        owner = [int(np.argmax([np.linalg.norm(J[starts[i]:starts[i + 1], j])
                                for i in range(len(shapes))])) for j in range(self.n_tangent)]
        # leaves: (name, shape, ambient slice, tangent column indices)
        self.leaves = [(names[i], shapes[i], slice(int(starts[i]), int(starts[i + 1])),
                        [j for j in range(self.n_tangent) if owner[j] == i])
                       for i in range(len(shapes))]
        self.constrained = [len(cols) < _size(shape) for _, shape, _, cols in self.leaves]
        self.unknown_blocks = []  # (name, shape, ambient slice)
        a = self.n_state
        for name, shape in problem.unknowns.items():
            self.unknown_blocks.append((name, tuple(shape), slice(a, a + _size(shape))))
            a += _size(shape)
        self.n_ambient = a
        n_x = self.n_tangent if chart == "tangent" else self.n_state
        self.unknown_coords = {name: slice(n_x + s.start - self.n_state,
                                           n_x + s.stop - self.n_state)
                               for name, _, s in self.unknown_blocks}
        self.n_coords = n_x + a - self.n_state
        self.input_blocks = []
        b = 0
        for name, shape in problem.inputs.items():
            self.input_blocks.append((name, tuple(shape), slice(b, b + _size(shape))))
            b += _size(shape)
        self.n_inputs = b

    def coordinate_labels(self) -> list[str]:
        labels = [""] * (self.n_tangent if self.chart == "tangent" else self.n_state)
        for name, shape, amb, cols in self.leaves:
            if self.chart == "ambient":
                labels[amb] = _entry_labels(name, shape)
            elif len(cols) == _size(shape):
                for j, lab in zip(cols, _entry_labels(name, shape), strict=True):
                    labels[j] = lab
            else:
                axes = "xyz" if len(cols) == 3 else [str(k) for k in range(len(cols))]
                for j, ax in zip(cols, axes, strict=True):
                    labels[j] = f"{name}.δ{ax}"
        for name, shape, _ in self.unknown_blocks:
            labels += _entry_labels(name, shape)
        return labels

    def unpack(self, X) -> tuple[Any, dict]:
        """``(x, θ)`` from an ambient vector (NumPy or JAX)."""
        x = jax.tree_util.tree_unflatten(self.treedef, [X[s].reshape(shape)
                                                        for _, shape, s, _ in self.leaves])
        th = {name: X[s].reshape(shape) for name, shape, s in self.unknown_blocks}
        return x, th

    def pack(self, x, th: Mapping, xp=jnp):
        """The ambient vector of ``(x, θ)`` (``xp``: ``jax.numpy``, or ``numpy`` on the host)."""
        parts = [xp.ravel(xp.asarray(leaf, dtype=xp.float64))
                 for leaf in jax.tree_util.tree_leaves(x)]
        parts += [xp.ravel(xp.asarray(th[name], dtype=xp.float64))
                  for name, _, _ in self.unknown_blocks]
        return xp.concatenate(parts)

    def unpack_u(self, U) -> dict:
        return {name: U[s].reshape(shape) for name, shape, s in self.input_blocks}

    def chart_map(self, X0):
        """z ↦ X: the model's retraction of the state and ``θ₀ + z`` (tangent chart); ``X₀ + z``
        (ambient chart)."""
        if self.chart == "ambient":
            return lambda z: X0 + z
        x0 = self.unpack(X0)[0]
        model = self.problem.model

        def phi(z):
            x = model.retract(x0, z[: self.n_tangent])
            return jnp.concatenate([flat(x), X0[self.n_state:] + z[self.n_tangent:]])

        return phi

    def chart_jacobian(self, X0) -> np.ndarray:
        """``∂X/∂z`` of :meth:`chart_map` at ``z = 0`` (n_ambient × n_coords)."""
        if self.chart == "ambient":
            return np.eye(self.n_ambient)
        J = np.zeros((self.n_ambient, self.n_coords))
        J[: self.n_state, : self.n_tangent] = np.asarray(self._retract_jacobian(self.unpack(X0)[0]))
        J[self.n_state:, self.n_tangent:] = np.eye(self.n_ambient - self.n_state)
        return J

    def coordinate_mask(self, names) -> np.ndarray:
        """Boolean mask of the coordinates of the unknown constants ``names``."""
        mask = np.zeros(self.n_coords, dtype=bool)
        for name in names:
            mask[self.unknown_coords[name]] = True
        return mask

# ---------------------------------------------------------------------------------------------
# Output derivatives in Taylor mode
# ---------------------------------------------------------------------------------------------


def flat_fields(problem: Problem, lay: Layout):
    """``(F, H)`` on the ambient vector: ``Ẋ = F(X, U)`` (the unknowns' rows zero), ``y = H(X, U)``
    with ``U`` the flat known inputs."""

    def F(X, U):
        x, th = lay.unpack(X)
        dx = flat(problem.vector_field(x, lay.unpack_u(U), th))
        return jnp.concatenate([dx, jnp.zeros(lay.n_ambient - lay.n_state, dtype=dx.dtype)])

    def H(X, U):
        x, th = lay.unpack(X)
        return problem.measurement(x, lay.unpack_u(U), th)

    return F, H


def output_derivatives_jet(F, H, X0, Useries, order: int):
    """``(y, ẏ, …, y^(order))`` at ``X0`` for ``Ẋ = F(X, u(t))``, ``y = H(X, u(t))``.

    ``Useries[k]`` is ``u^(k)(0)`` (shape (order + 1, n_u)). Returns shape (order + 1, p).

    Taylor coefficients (derivative convention) of the solution are generated by a fixed-size
    ``jet`` of ``F`` inside ``lax.fori_loop``: the k-th output coefficient of ``jet`` depends only
    on the input coefficients up to k, so with the unknown higher coefficients left at zero,
    iteration k reads ``x^(k+1) = [F(x(t), u(t))]^(k)`` exactly. One trace of order ``order`` serves
    all iterations.
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
    point: tuple[Any, dict] | None = None  # (x, theta) of the point whose null space is reported

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
    return np.asarray(so3.matrix_from_unit_quat(np.array([w, x, y, z]) / n))


def default_sample(problem: Problem, rng: np.random.Generator) -> tuple[Any, dict]:
    """Standard-normal entries for every leaf of the state, then for every unknown constant."""
    x = jax.tree_util.tree_map(lambda a: rng.standard_normal(np.shape(a)), problem.state)
    th = {name: rng.standard_normal(tuple(shape)) for name, shape in problem.unknowns.items()}
    return x, th


_LAYOUTS: dict = {}


def layout(problem: Problem, chart: str = "tangent") -> Layout:
    """The coordinates of ``problem`` in ``chart`` (cached per problem and chart)."""
    key = (id(problem), chart)
    hit = _LAYOUTS.get(key)
    if hit is None or hit[0] is not problem:
        hit = _LAYOUTS[key] = (problem, Layout(problem, chart))
    return hit[1]


_COMPILED: dict = {}


def _compiled(problem: Problem, lay: Layout, order: int):
    """jit(vmap(point ↦ (O, {q: ∂q/∂z}))), cached per (problem, order, chart)."""
    key = (id(problem), order, lay.chart)
    hit = _COMPILED.get(key)
    if hit is not None and hit[0] is problem:
        return hit[1]
    F, H = flat_fields(problem, lay)

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

    fn = jit_evaluated_once(jax.vmap(one))
    _COMPILED[key] = (problem, fn)
    return fn


def observability_matrix(problem: Problem, order: int, *, chart: str = "tangent", seed: int = 0,
                         points: int = 1, fixed: Mapping[str, Any] | None = None,
                         zero_inputs: tuple[str, ...] = ()):
    """Observability matrices at ``points`` random points.

    Returns ``(O, grads, layout, keep, X0s)``: ``O`` (points, order+1, p, n_coords) holds the
    normalised coefficients ``∂(y^(k)/k!)/∂z``; ``grads[q]`` (points, dim q, n_coords) the gradients
    of the quantities; ``keep`` the boolean mask of the coordinates that are unknown (the columns of
    the ``fixed`` constants are to be dropped by the caller); ``X0s`` the ambient points.
    """
    fixed = dict(fixed or {})
    for name in fixed:
        if name not in problem.unknowns:
            raise InputError(f"fixed: {name!r} is not an unknown constant of the problem")
    for name in zero_inputs:
        if name not in problem.inputs:
            raise InputError(f"zero_inputs: {name!r} is not an input of the problem")
    lay = layout(problem, chart)
    rng = np.random.default_rng(seed)
    X0s, Us = [], []
    for _ in range(points):
        x, th = (problem.sample or (lambda r: default_sample(problem, r)))(rng)
        X = lay.pack(x, th, xp=np)
        if chart == "ambient":  # constrained leaves (rotation matrices): a generic point off them
            for (_, shape, s, _), constrained in zip(lay.leaves, lay.constrained, strict=True):
                if constrained:
                    X[s] += AMBIENT_SPREAD * rng.standard_normal(shape).ravel()
        for name, shape, s in lay.unknown_blocks:
            if name in fixed:
                X[s] = np.broadcast_to(np.asarray(fixed[name], dtype=float), shape).ravel()
        X0s.append(X)
        U = problem.input_scale * rng.standard_normal((order + 1, lay.n_inputs))
        for name, _, sl in lay.input_blocks:
            if name in zero_inputs:
                U[:, sl] = 0.0
        Us.append(U)
    O, grads = _compiled(problem, lay, order)(jnp.asarray(np.stack(X0s)), jnp.asarray(np.stack(Us)))
    keep = ~lay.coordinate_mask(fixed)
    return (np.asarray(O), {k: np.asarray(v) for k, v in grads.items()}, lay, keep,
            np.stack(X0s))


def _n_outputs(problem: Problem, lay: Layout) -> int:
    _, H = flat_fields(problem, lay)
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
    lay = layout(problem, chart)
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
        cs = lay.unknown_coords[name]
        G = np.zeros((cs.stop - cs.start, lay.n_coords))
        G[:, cs] = np.eye(G.shape[0])
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
        point=lay.unpack(X0s[best[0]]),
    )


_DIRECTIONS: dict = {}


def _curve_velocities(problem: Problem, chart: str, curves: tuple):
    """jit(X₀ ↦ the velocities of the ambient point along each curve, as columns), cached per
    (problem, chart, curves)."""
    key = (id(problem), chart, curves)
    hit = _DIRECTIONS.get(key)
    if hit is not None and hit[0] is problem:
        return hit[1]
    lay = layout(problem, chart)

    def velocities(X0):
        x0, th0 = lay.unpack(X0)

        def velocity(curve):
            def ambient(eps):
                x, th = curve(problem.model, x0, th0, eps)
                return lay.pack(x, {**th0, **th})

            return jax.jvp(ambient, (0.0,), (1.0,))[1]

        return jnp.stack([velocity(curve) for curve in curves], axis=1)

    fn = jit_evaluated_once(velocities)
    _DIRECTIONS[key] = (problem, fn)
    return fn


def curve_directions(problem: Problem, result: ObservabilityResult,
                     curves: Mapping[str, Callable]) -> dict[str, np.ndarray]:
    """The velocity at ``ε = 0`` of each curve through ``result.point``, in the result's coordinates
    (``result.labels``, the chart of the result).

    A curve ``curve(model, x, θ, ε) -> (x(ε), θ(ε))`` moves the point ``(x, θ)`` (``θ(ε)`` may hold
    only the unknowns it moves), e.g. a one-parameter group acting on states and unknowns. With the
    tangent chart, the velocity of the ambient point is mapped back through the model's retraction
    (least squares on its Jacobian, which has full column rank), so a symmetry of the model becomes
    the direction that :meth:`ObservabilityResult.in_null_space` tests. Pass module-level functions:
    the compiled form is cached per problem and curves.
    """
    lay = layout(problem, result.chart)
    X0 = lay.pack(*result.point, xp=np)
    dX = np.asarray(_curve_velocities(problem, result.chart, tuple(curves.values()))(X0))
    V = np.linalg.lstsq(lay.chart_jacobian(X0), dX, rcond=None)[0]
    index = {lab: i for i, lab in enumerate(lay.coordinate_labels())}
    rows = [index[lab] for lab in result.labels]
    return {name: V[rows, k] for k, name in enumerate(curves)}
