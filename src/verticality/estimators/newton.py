"""Moving-window Newton observer of Moraal & Grizzle (1995), generic over any discrete model.

F §4.3.1 eq. 4.1–4.5, P11 §V.B. For a discrete model (F 4.1–4.2; a
:class:`~verticality.models.base.DiscreteModel` value)

    x_{k+1} = F(x_k, u_{k+1}, dt),        y_k = H(x_k, u_k),

the observer keeps the last N samples (y, u), and solves the observability equations (F 4.3)

    Y_k − H_T(ξ, U_k) = 0,   H_T(ξ, U) = (H(ξ), H(F(ξ)), …, H(F∘…∘F(ξ)))   (N blocks)

for the state ξ at the start of the window by d Newton iterations (F 4.4), then carries the solution
forward through the window to the present sample (F 4.5). The unknown is a state on the model's
manifold: the Newton step δ lives in the model's tangent coordinates, ``ξ ← ξ ⊞ δ``
(``model.retract``), and every Jacobian is taken with respect to such a δ (through
``model.retract`` and ``model.difference``); on a vector space this is the usual arithmetic
(``ξ + δ``, the plain Jacobian), on SO(3) it is the right perturbation ``R exp([δ]×)``. Done better
than the papers did it:

- **Exact Jacobian** ∂H_T/∂δ by forward-mode autodiff (the papers used finite differences): the
  per-sample transition Jacobians ∂(F(x ⊞ δ) ⊟ F(x))/∂δ come out of the window's rollout itself
  (``jax.jacfwd`` of each transition with the next state as its auxiliary output: one forward pass
  gives the trajectory and its tangents, so the model is evaluated once per sub-step, not once for
  the rollout and again for the Jacobian), the output Jacobians ∂H(x ⊞ δ)/∂δ at every sample at
  once (``vmap``); they are chained along the window (Φ_k = A_k·Φ_{k−1}, rows C_k·Φ_k). Equal to
  ``jacfwd`` through the whole window to rounding.
- **Damped least squares** (Levenberg–Marquardt) instead of the inverse in F 4.4: the map may be
  non-square (N·p ≠ n) or ill-conditioned. Columns of the Jacobian are scaled to unit norm (states
  of different units), the step is ``δ = V diag(s/(s²+μ²)) Uᵀ r`` from a thin SVD, and the damping
  μ² is adapted (÷3 when the cost falls, ×8 and the step rejected when it rises). With a
  well-conditioned square map and μ → 0 this is exactly Newton's step (F 4.4).
- **Warm start**: the observer keeps its estimated trajectory over the window; the first guess of
  a new window is the previous solution carried forward (or the model prediction before any solve).
  The first linearization rolls the window out from that guess again (the rollout gives the
  Jacobian too, so reusing the carried trajectory would save nothing, and a branch on whether it
  can be reused costs both branches under ``vmap``).
- **Flags**: ``rank_deficient`` (scaled s_min/s_max < ``rcond``; the estimate stays finite, along
  unobservable directions it keeps the warm start), ``converged`` (an accepted step changed the
  predicted outputs by less than ``step_tol`` within d iterations, and the window is not
  rank-deficient), ``iterations`` used (d is a maximum: iterations stop once converged),
  ``residual_rms`` of the window at the solution, ``measured`` (per component of y).
- A NaN in y means "no measurement": that component's rows get zero weight; a y with no finite
  component is not solved on (the step is :meth:`NewtonObserver.predict`); a window with too few
  measurements is rank-deficient and flagged; nothing turns a finite estimate into NaN (a
  non-finite candidate is rejected, a non-finite prediction keeps the previous estimate).

Sample semantics (``step(state, u, y, dt)``, :mod:`verticality.estimators.base`): ``u`` is the input
that drove the system from the previous sample to this one (for a sampled continuous plant: the
block of fast-rate inputs over the interval), ``dt`` the time since the previous sample (handed to
``model.transition``) and ``y`` the measurement at this sample; ``model.output(x, u)`` gives y.
State and input may be any pytrees; y is flattened to a vector.

    obs = NewtonObserver(model, u_template, NewtonConfig(window=24, iterations=5))
    state = obs.init(x0)
    state, out = obs.step(state, u, y, dt)
    state, outs = obs.run(state, us, ys, dts)
    sol = obs.solve(xi0, us_window, ys_window, mask_window, dt)      # one window
"""

from __future__ import annotations

from typing import Any, NamedTuple

import jax
import jax.numpy as jnp

from verticality.core.errors import InputError
from verticality.estimators.base import all_finite, keep_finite, scan_steps
from verticality.models.base import model_dataclass, static_field


class NewtonConfig(NamedTuple):
    window: int = 24  # N samples in the window
    iterations: int = 5  # d Newton iterations per window (F 4.4)
    every: int = 1  # solve every `every` samples (predict only in between)
    damping: float = 1e-6  # initial LM damping μ², relative to the scaled Jacobian (unit columns)
    damping_min: float = 1e-15
    rcond: float = 1e-9  # scaled s_min/s_max below this: rank-deficient window
    # stop once a step changes the predicted outputs by less (RMS, relative)
    step_tol: float = 1e-10


class NewtonState(NamedTuple):
    x_hat: Any  # estimate at the present sample (a model state)
    # estimated trajectory over the window (model states, leading axis N; warm start)
    xs_window: Any
    ys: jnp.ndarray  # (N, p) measurements, NaN replaced by 0
    mask: jnp.ndarray  # (N, p) 1 where measured
    us: Any  # input pytree with leading axis N
    count: jnp.ndarray  # samples received
    since_solve: jnp.ndarray
    last: Any  # NewtonOutput of the last solve (diagnostics carried between solves)


class NewtonOutput(NamedTuple):
    x_hat: Any  # estimate at the present sample (a model state)
    solved: jnp.ndarray  # a window was solved at this sample
    converged: jnp.ndarray
    rank_deficient: jnp.ndarray
    residual_rms: jnp.ndarray  # RMS of the measured residuals of the last solved window
    cond: jnp.ndarray  # scaled condition number s_max/s_min of the last solved window
    iterations: jnp.ndarray  # Newton iterations used by the last solve
    measured: jnp.ndarray  # (p,) bool: this sample's y components that were finite


class WindowSolution(NamedTuple):
    xi: Any  # state at the window start
    xs: Any  # trajectory through the window (leading axis N); its last entry is the present
    residual_rms: jnp.ndarray
    cond: jnp.ndarray
    rank_deficient: jnp.ndarray
    converged: jnp.ndarray
    iterations: jnp.ndarray  # Newton iterations (Jacobian passes after the first) used


def _tmap(f, *trees):
    return jax.tree_util.tree_map(f, *trees)


def _select(pred, a, b):
    return _tmap(lambda u, v: jnp.where(pred, u, v), a, b)


def _index(tree, i):
    return _tmap(lambda a: a[i], tree)


def _push(buf, new):
    return _tmap(lambda b, n: jnp.concatenate([b[1:], jnp.asarray(n, b.dtype)[None]], axis=0),
                 buf, new)


@model_dataclass
class NewtonObserver:
    """The observer on the discrete model ``model`` (``transition``, ``output``, ``retract``,
    ``difference``); ``u_template`` fixes the structure and shapes of one sample's input (the
    window buffer of inputs starts as zeros like it); ``config`` the window and the solver
    settings (validated on construction)."""

    model: Any
    u_template: Any
    config: NewtonConfig = static_field(NewtonConfig())

    def __post_init__(self):
        cfg = self.config
        if int(cfg.window) < 1:
            raise InputError(f"Newton observer: window must be >= 1, got {cfg.window}")
        if int(cfg.iterations) < 1:
            raise InputError(f"Newton observer: iterations must be >= 1, got {cfg.iterations}")
        if int(cfg.every) < 1:
            raise InputError(f"Newton observer: every must be >= 1, got {cfg.every}")
        if not cfg.damping > 0 or not cfg.damping_min > 0:
            raise InputError("Newton observer: damping and damping_min must be > 0")

    # ------------------------------------------------------------------ model in flat form

    def _h(self, x, u):
        return jnp.ravel(jnp.asarray(self.model.output(x, u), dtype=jnp.float64))

    def _n_outputs(self, x) -> int:
        return jax.eval_shape(self._h, x, self.u_template).shape[0]

    def _transition_jac(self, x, u, dt):
        """``(F(x), A)`` with A = ∂(F(x ⊞ δ) ⊟ F(x))/∂δ at δ = 0 (the tangent transition matrix),
        from one forward-mode pass: F(x) is the pass's primal (auxiliary output), not a second
        evaluation."""
        zero = jnp.zeros_like(self.model.difference(x, x))

        def f(d):
            x1 = self.model.transition(self.model.retract(x, d), u, dt)
            return self.model.difference(x1, jax.lax.stop_gradient(x1)), x1

        A, x1 = jax.jacfwd(f, has_aux=True)(zero)
        return x1, A

    def _jac_h(self, x, u):
        zero = jnp.zeros_like(self.model.difference(x, x))
        return jax.jacfwd(lambda d: self._h(self.model.retract(x, d), u))(zero)

    # ------------------------------------------------------------------ one window

    def rollout(self, xi, us, dt):
        """The window rolled out from ξ: the predicted outputs H_T(ξ, U) (flat, (N·p,)), the
        trajectory (model states with a leading axis N) and the N − 1 tangent transition matrices
        A_k along it (:meth:`_transition_jac`), all from one pass. Callers that use only the first
        two get the plain rollout: under ``jit`` the unused tangents are dead code."""
        u0 = _index(us, 0)
        rest = _tmap(lambda a: a[1:], us)

        def body(x, u):
            x1, A = self._transition_jac(x, u, dt)
            return x1, (self._h(x1, u), x1, A)

        _, (ys_rest, xs_rest, A) = jax.lax.scan(body, xi, rest)
        Y = jnp.concatenate([self._h(xi, u0)[None], ys_rest], axis=0).reshape(-1)
        xs = _tmap(lambda a, b: jnp.concatenate([a[None], b], axis=0), xi, xs_rest)
        return Y, xs, A

    def observability_map(self, xi, us, dt):
        """H_T of F §4.3.1: the predicted outputs over the window from ξ (flat, (N·p,)), and the
        trajectory (model states with a leading axis N)."""
        Y, xs, _ = self.rollout(xi, us, dt)
        return Y, xs

    def solve(self, xi0, us, ys, mask, dt) -> WindowSolution:
        """Up to d damped Gauss–Newton (Levenberg–Marquardt) iterations on one window (F 4.3–4.4).

        Each iteration costs one forward-mode pass through the window (:meth:`rollout`: the
        outputs, the trajectory and the per-sample tangent transition matrices at the candidate),
        then the exact Jacobian by the chain rule along the window (the same exact derivative as
        ``jacfwd`` through the whole window, to rounding). A candidate that does not lower the cost
        is rejected (the damping grows, the stored Jacobian is reused). Iterations stop early once
        the next proposed step would change the predicted outputs by less than ``step_tol`` (RMS,
        relative to 1 + RMS of the measurements): that is the convergence flag; d is the maximum
        number of iterations, as in F 4.4.
        """
        cfg = self.config
        N, d = int(cfg.window), int(cfg.iterations)
        n = int(jnp.size(self.model.difference(xi0, xi0)))
        p = self._n_outputs(xi0)
        ys_flat = jnp.reshape(ys, -1)
        w = jnp.reshape(mask, -1).astype(float)
        m = jnp.maximum(jnp.sum(w), 1.0)
        y_scale = 1.0 + jnp.sqrt(jnp.sum((w * ys_flat) ** 2) / m)

        def evaluate(xi):
            Y, xs, A = self.rollout(xi, us, dt)
            C = jax.vmap(self._jac_h)(xs, us)

            def chain(P, a):
                P1 = jnp.sum(a[:, :, None] * P[None, :, :], axis=1)
                return P1, P1

            eye = jnp.eye(n)
            _, Ps = jax.lax.scan(chain, eye, A)
            Phi = jnp.concatenate([eye[None], Ps], axis=0)
            J = jnp.sum(C[:, :, :, None] * Phi[:, None, :, :], axis=2).reshape(N * p, n)
            r = w * (ys_flat - Y)
            cost = jnp.sum(r * r)
            ok = jnp.isfinite(cost) & all_finite(xs) & jnp.all(jnp.isfinite(J))
            Jw = jnp.where(jnp.isfinite(J), w[:, None] * J, 0.0)
            col = jnp.linalg.norm(Jw, axis=0)
            # tiny floors stay well above the denormals (XLA flushes those to zero)
            scale = jnp.maximum(col, 1e-12 * jnp.maximum(jnp.max(col), 1e-100))
            Us, s, Vt = jnp.linalg.svd(Jw / scale, full_matrices=False)
            smax = jnp.maximum(jnp.max(s), 1e-100)
            deficient = (s.shape[0] < n) | (jnp.min(s) <= cfg.rcond * smax)
            cond = smax / jnp.maximum(jnp.min(s), 1e-100)
            lin = (Us, s, Vt, scale, jnp.where(jnp.isfinite(r), r, 0.0))
            return ok, jnp.where(ok, cost, jnp.inf), xs, lin, deficient, cond

        ok0, cost0, xs_0, lin0, def0, cond0 = evaluate(xi0)

        def proposal(lin, mu2):
            Us, s, Vt, scale, r = lin
            smax = jnp.maximum(jnp.max(s), 1e-100)
            gain = s / (s * s + jnp.maximum(mu2, cfg.damping_min) * smax * smax)
            gain = jnp.where(s > cfg.rcond * smax, gain, 0.0)  # truncate unobservable directions
            coef = gain * (Us.T @ r)
            dy_rms = jnp.sqrt(jnp.sum((s * coef) ** 2) / m)  # predicted change of the outputs
            return (Vt.T @ coef) / scale, (dy_rms <= cfg.step_tol * y_scale) | ~jnp.isfinite(dy_rms)

        class Carry(NamedTuple):
            i: Any
            xi: Any
            xs: Any
            cost: Any
            lin: Any
            mu2: Any
            delta: Any
            small: Any
            deficient: Any
            cond: Any

        def cond_fun(c):
            return (c.i < d) & ~c.small

        def body(c):
            cand = self.model.retract(c.xi, c.delta)
            okc, costc, xsc, linc, defc, condc = evaluate(cand)
            acc = okc & (costc <= c.cost)
            lin = _select(acc, linc, c.lin)
            mu2 = jnp.where(acc, jnp.maximum(c.mu2 / 3.0, cfg.damping_min), c.mu2 * 8.0)
            delta, small = proposal(lin, mu2)
            return Carry(i=c.i + 1, xi=_select(acc, cand, c.xi), xs=_select(acc, xsc, c.xs),
                         cost=jnp.where(acc, costc, c.cost), lin=lin, mu2=mu2, delta=delta,
                         small=small, deficient=jnp.where(acc, defc, c.deficient),
                         cond=jnp.where(acc, condc, c.cond))

        mu2_0 = jnp.asarray(cfg.damping, dtype=float)
        delta0, small0 = proposal(lin0, mu2_0)
        c = jax.lax.while_loop(cond_fun, body, Carry(
            i=jnp.asarray(0), xi=xi0, xs=xs_0, cost=cost0, lin=lin0, mu2=mu2_0, delta=delta0,
            small=small0 & ok0, deficient=def0, cond=cond0))
        rms = jnp.sqrt(jnp.where(jnp.isfinite(c.cost), c.cost, 0.0) / m)
        finite = all_finite(c.xs) & all_finite(c.xi)
        xi = _select(finite, c.xi, xi0)
        constant = _tmap(lambda a: jnp.broadcast_to(a, (N,) + jnp.shape(a)), xi0)
        xs = _select(finite, c.xs, _select(all_finite(xs_0), xs_0, constant))
        return WindowSolution(xi=xi, xs=xs, residual_rms=rms, cond=c.cond,
                              rank_deficient=c.deficient, converged=c.small & ~c.deficient & finite,
                              iterations=c.i)

    # ------------------------------------------------------------------ estimator interface

    def init(self, x0, P0=None) -> NewtonState:
        """Observer state with estimate ``x0`` (a model state); ``P0`` is unused."""
        del P0
        N = int(self.config.window)
        x0 = _tmap(lambda a: jnp.asarray(a, dtype=jnp.result_type(a, float)), x0)
        try:
            x1 = jax.eval_shape(lambda x, u: self.model.transition(x, u, 1.0), x0, self.u_template)
            p = self._n_outputs(x0)
        except (AttributeError, TypeError, ValueError, IndexError) as exc:
            raise InputError(f"Newton observer: x0 does not fit the model ({exc})") from None
        shapes = lambda t: [(jnp.shape(a)) for a in jax.tree_util.tree_leaves(t)]  # noqa: E731
        if (jax.tree_util.tree_structure(x1) != jax.tree_util.tree_structure(x0)
                or shapes(x1) != shapes(x0)):
            raise InputError(f"Newton observer: x0 {shapes(x0)} is not a state of the model, "
                             f"whose transition returns {shapes(x1)}")
        us = _tmap(lambda a: jnp.zeros((N,) + jnp.shape(a), dtype=jnp.result_type(a, float)),
                   self.u_template)
        last = NewtonOutput(x_hat=x0, solved=jnp.asarray(False), converged=jnp.asarray(False),
                            rank_deficient=jnp.asarray(False), residual_rms=jnp.asarray(0.0),
                            cond=jnp.asarray(1.0), iterations=jnp.asarray(0),
                            measured=jnp.zeros(p, dtype=bool))
        xs = _tmap(lambda a: jnp.broadcast_to(a, (N,) + jnp.shape(a)), x0)
        return NewtonState(x_hat=x0, xs_window=xs, ys=jnp.zeros((N, p)), mask=jnp.zeros((N, p)),
                           us=us, count=jnp.asarray(0), since_solve=jnp.asarray(0), last=last)

    def _predicted(self, state: NewtonState, u, y, dt):
        """Predict (F 4.1) and push (u, y) into the window: the step without a solve."""
        y = jnp.reshape(jnp.asarray(y, dtype=float), state.ys.shape[1:])
        finite_y = jnp.isfinite(y)
        x_pred, _ = keep_finite(self.model.transition(state.x_hat, u, dt), state.x_hat)
        out = state.last._replace(x_hat=x_pred, solved=jnp.asarray(False), measured=finite_y)
        return NewtonState(x_hat=x_pred, xs_window=_push(state.xs_window, x_pred),
                           ys=_push(state.ys, jnp.where(finite_y, y, 0.0)),
                           mask=_push(state.mask, finite_y.astype(float)), us=_push(state.us, u),
                           count=state.count + 1, since_solve=state.since_solve + 1, last=out)

    def predict(self, state: NewtonState, u, dt) -> NewtonState:
        """The time update alone: the model's prediction, (u, no measurement) pushed, no solve."""
        return self._predicted(state, u, jnp.full(state.ys.shape[1:], jnp.nan), dt)

    def step(self, state: NewtonState, u, y, dt):
        """One sample: predict (F 4.1), push (u, y), every `every` samples (with some component
        of y measured) solve the window and carry its solution forward (F 4.3–4.5)."""
        N = int(self.config.window)
        pred = self._predicted(state, u, y, dt)
        do_solve = ((pred.count >= N) & (pred.since_solve >= int(self.config.every))
                    & jnp.any(pred.last.measured))

        def solved(_):
            # warm start: the first entry of the carried window
            sol = self.solve(_index(pred.xs_window, 0), pred.us, pred.ys, pred.mask, dt)
            out = NewtonOutput(x_hat=_index(sol.xs, -1), solved=jnp.asarray(True),
                               converged=sol.converged, rank_deficient=sol.rank_deficient,
                               residual_rms=sol.residual_rms, cond=sol.cond,
                               iterations=sol.iterations, measured=pred.last.measured)
            return pred._replace(x_hat=out.x_hat, xs_window=sol.xs, since_solve=jnp.asarray(0),
                                 last=out)

        new_state = jax.lax.cond(do_solve, solved, lambda _: pred, None)
        return new_state, new_state.last

    def run(self, state: NewtonState, us, ys, dts):
        """:meth:`step` over a sequence (``lax.scan``): ``(final_state, stacked outputs)``."""
        return scan_steps(self.step, state, us, ys, dts)
