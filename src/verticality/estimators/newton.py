"""Moving-window Newton observer of Moraal & Grizzle (1995), generic over any discrete model.

F §4.3.1 eq. 4.1–4.5, P11 §V.B. For a discrete system (F 4.1–4.2)

    x_{k+1} = F(x_k, u_{k+1}),        y_k = H(x_k, u_k),

the observer keeps the last N samples (y, u), and solves the observability equations (F 4.3)

    Y_k − H_T(ξ, U_k) = 0,   H_T(ξ, U) = (H(ξ), H(F(ξ)), …, H(F∘…∘F(ξ)))   (N blocks)

for the state ξ at the start of the window by d Newton iterations (F 4.4), then carries the solution
forward through the window to the present sample (F 4.5). Done better than the papers did it:

- **Exact Jacobian** ∂H_T/∂ξ by forward-mode autodiff (the papers used finite differences): the
  per-sample Jacobians ∂F/∂x, ∂H/∂x by ``jax.jacfwd`` at every sample of the window at once
  (``vmap``), chained along the window (Φ_k = ∂F/∂x_k·Φ_{k−1}, rows ∂H/∂x_k·Φ_k); equal to
  ``jacfwd`` through the whole window to rounding, at about half its cost on CPU.
- **Damped least squares** (Levenberg–Marquardt) instead of the inverse in F 4.4: the map may be
  non-square (N·p ≠ n) or ill-conditioned. Columns of the Jacobian are scaled to unit norm (states of
  different units), the step is ``δ = V diag(s/(s²+μ²)) Uᵀ r`` from a thin SVD, and the damping μ² is
  adapted (÷3 when the cost falls, ×8 and the step rejected when it rises). With a well-conditioned
  square map and μ → 0 this is exactly Newton's step (F 4.4).
- **Warm start**: the observer keeps its estimated trajectory over the window; the first guess of
  a new window is the previous solution carried forward (or the model prediction before any solve).
  That carried trajectory is the model's rollout from the guess, so the first linearization reuses
  it (``NewtonState.rollout`` counts its consistent entries; a non-finite prediction resets it and
  the window is then rolled out again).
- **Flags**: ``rank_deficient`` (scaled s_min/s_max < ``rcond``; the estimate stays finite, along
  unobservable directions it keeps the warm start), ``converged`` (an accepted step changed the
  predicted outputs by less than ``step_tol`` within d iterations, and the window is not
  rank-deficient), ``iterations`` used (d is a maximum: iterations stop once converged),
  ``residual_rms`` of the window at the solution, ``measured`` (y had no NaN).
- A NaN in y means "no measurement": that sample's rows get zero weight; a window with too few
  measurements is rank-deficient and flagged; nothing turns a finite estimate into NaN (a non-finite
  candidate is rejected, a non-finite prediction keeps the previous estimate).

Sample semantics (``step(state, u, y, dt)``): ``u`` is the input that drove the system from the
previous sample to this one (for a sampled continuous plant: the block of fast-rate inputs over the
interval), and ``y`` the measurement at this sample; the model's ``transition(x, u)`` maps the state
at the previous sample to the state at this one, and ``output(x, u)`` gives y. ``dt`` is accepted
for the common estimator API but the sample spacing belongs to the discrete model. State and
input may be any pytrees (flattened with ``ravel_pytree``); y is flattened to a vector.

API (estimators/base.py): ``obs = make(transition, output, u_template, NewtonConfig(...))``, then
``obs.init(x0, P0=None)``, ``obs.step(state, u, y, dt)``, ``obs.run(state, us, ys, dts)`` (lax.scan),
and ``obs.solve(xi0, us, ys, mask)`` for one window.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
from jax.flatten_util import ravel_pytree

from verticality.errors import InputError


class NewtonConfig(NamedTuple):
    window: int = 24  # N samples in the window
    iterations: int = 5  # d Newton iterations per window (F 4.4)
    every: int = 1  # solve every `every` samples (predict only in between)
    damping: float = 1e-6  # initial LM damping μ², relative to the scaled Jacobian (unit columns)
    damping_min: float = 1e-15
    rcond: float = 1e-9  # scaled s_min/s_max below this: rank-deficient window
    step_tol: float = 1e-10  # stop once a step changes the predicted outputs by less (RMS, relative)


class NewtonState(NamedTuple):
    x_hat: jnp.ndarray  # (n,) flat estimate at the present sample
    xs_window: jnp.ndarray  # (N, n) estimated trajectory over the window (warm start)
    ys: jnp.ndarray  # (N, p) measurements, NaN replaced by 0
    mask: jnp.ndarray  # (N, p) 1 where measured
    us: Any  # input pytree with leading axis N
    count: jnp.ndarray  # samples received
    since_solve: jnp.ndarray
    last: Any  # NewtonOutput of the last solve (diagnostics carried between solves)
    rollout: Any = None  # trailing entries of xs_window that are the model's rollout (N: all)


class NewtonOutput(NamedTuple):
    x_hat: jnp.ndarray  # (n,) flat estimate at the present sample
    solved: jnp.ndarray  # a window was solved at this sample
    converged: jnp.ndarray
    rank_deficient: jnp.ndarray
    residual_rms: jnp.ndarray  # RMS of the measured residuals of the last solved window
    cond: jnp.ndarray  # scaled condition number s_max/s_min of the last solved window
    iterations: jnp.ndarray  # Newton iterations used by the last solve
    measured: jnp.ndarray  # this sample's y was finite


class WindowSolution(NamedTuple):
    xi: jnp.ndarray  # (n,) state at the window start
    xs: jnp.ndarray  # (N, n) trajectory through the window; xs[-1] is the present
    residual_rms: jnp.ndarray
    cond: jnp.ndarray
    rank_deficient: jnp.ndarray
    converged: jnp.ndarray
    iterations: jnp.ndarray  # Newton iterations (Jacobian passes after the first) used


class NewtonObserver(NamedTuple):
    init: Callable
    step: Callable
    run: Callable
    solve: Callable  # solve(xi0, us_window, ys_window, mask_window) -> WindowSolution
    observability_map: Callable  # (xi, us_window) -> (Y_pred (N·p,), xs (N, n))
    unravel: Callable  # flat state -> state pytree


def _check_config(cfg: NewtonConfig) -> None:
    if int(cfg.window) < 1:
        raise InputError(f"Newton observer: window must be >= 1, got {cfg.window}")
    if int(cfg.iterations) < 1:
        raise InputError(f"Newton observer: iterations must be >= 1, got {cfg.iterations}")
    if int(cfg.every) < 1:
        raise InputError(f"Newton observer: every must be >= 1, got {cfg.every}")
    if not cfg.damping > 0 or not cfg.damping_min > 0:
        raise InputError("Newton observer: damping and damping_min must be > 0")


def make(transition: Callable, output: Callable, u_template: Any, x_template: Any,
         config: NewtonConfig | None = None) -> NewtonObserver:
    """Build the observer for ``x_{k+1} = transition(x_k, u_{k+1})``, ``y_k = output(x_k, u_k)``.

    ``x_template`` and ``u_template`` fix the pytree structure and shapes of state and input.
    """
    config = NewtonConfig() if config is None else config
    _check_config(config)
    N, d = int(config.window), int(config.iterations)
    x_flat0, unravel = ravel_pytree(x_template)
    n = x_flat0.shape[0]

    def f_flat(xf, u):
        return ravel_pytree(transition(unravel(xf), u))[0]

    def h_flat(xf, u):
        return jnp.ravel(jnp.asarray(output(unravel(xf), u), dtype=float))

    p = jax.eval_shape(h_flat, x_flat0, u_template).shape[0]

    def observability_map(xi, us):
        """H_T of F §4.3.1: predicted outputs over the window from ξ, and the trajectory."""
        u0 = jax.tree_util.tree_map(lambda a: a[0], us)
        rest = jax.tree_util.tree_map(lambda a: a[1:], us)

        def body(x, u):
            x1 = f_flat(x, u)
            return x1, (h_flat(x1, u), x1)

        _, (ys_rest, xs_rest) = jax.lax.scan(body, xi, rest)
        Y = jnp.concatenate([h_flat(xi, u0)[None], ys_rest], axis=0).reshape(-1)
        xs = jnp.concatenate([xi[None], xs_rest], axis=0)
        return Y, xs

    jac_f = jax.jacfwd(f_flat)
    jac_h = jax.jacfwd(h_flat)

    def solve(xi0, us, ys, mask, xs0=None):
        """Up to d damped Gauss–Newton (Levenberg–Marquardt) iterations on one window (F 4.3–4.4).

        ``xs0``, if given, must be the model's trajectory from ``xi0`` through the window
        (``observability_map(xi0, us)[1]``, e.g. the observer's carried warm start): the first
        linearization then reuses it instead of rolling the window out again.

        Each iteration costs one pass through the window for the outputs and the trajectory at the
        candidate, then the exact Jacobian by the chain rule: the per-sample transition Jacobians
        (``jax.jacfwd`` of the model, all samples at once under ``vmap``) multiplied along the
        window (the same exact derivative as ``jacfwd`` through the whole window, to rounding, at
        about half the cost on CPU). A candidate that does not lower the cost is rejected (the
        damping grows, the stored Jacobian is reused). Iterations stop
        early once the next proposed step would change the predicted outputs by less than
        ``step_tol`` (RMS, relative to 1 + RMS of the measurements): that is the convergence flag;
        d is the maximum number of iterations, as in F 4.4.
        """
        ys_flat = jnp.reshape(ys, -1)
        w = jnp.reshape(mask, -1).astype(float)
        m = jnp.maximum(jnp.sum(w), 1.0)
        y_scale = 1.0 + jnp.sqrt(jnp.sum((w * ys_flat) ** 2) / m)

        rest = jax.tree_util.tree_map(lambda a: a[1:], us)

        def evaluate(xi, xs_known=None):
            if xs_known is None:
                Y, xs = observability_map(xi, us)
            else:
                xs = xs_known
                Y = jax.vmap(h_flat)(xs, us).reshape(-1)
            A = jax.vmap(jac_f)(xs[:-1], rest)
            C = jax.vmap(jac_h)(xs, us)

            def chain(P, a):
                P1 = jnp.sum(a[:, :, None] * P[None, :, :], axis=1)
                return P1, P1

            eye = jnp.eye(n)
            _, Ps = jax.lax.scan(chain, eye, A)
            Phi = jnp.concatenate([eye[None], Ps], axis=0)
            J = jnp.sum(C[:, :, :, None] * Phi[:, None, :, :], axis=2).reshape(N * p, n)
            r = w * (ys_flat - Y)
            cost = jnp.sum(r * r)
            ok = jnp.isfinite(cost) & jnp.all(jnp.isfinite(xs)) & jnp.all(jnp.isfinite(J))
            Jw = jnp.where(jnp.isfinite(J), w[:, None] * J, 0.0)
            col = jnp.linalg.norm(Jw, axis=0)
            # tiny floors stay well above the denormals (XLA flushes those to zero)
            scale = jnp.maximum(col, 1e-12 * jnp.maximum(jnp.max(col), 1e-100))
            Us, s, Vt = jnp.linalg.svd(Jw / scale, full_matrices=False)
            smax = jnp.maximum(jnp.max(s), 1e-100)
            deficient = (s.shape[0] < n) | (jnp.min(s) <= config.rcond * smax)
            cond = smax / jnp.maximum(jnp.min(s), 1e-100)
            lin = (Us, s, Vt, scale, jnp.where(jnp.isfinite(r), r, 0.0))
            return ok, jnp.where(ok, cost, jnp.inf), xs, lin, deficient, cond

        ok0, cost0, xs0, lin0, def0, cond0 = evaluate(xi0, xs0)

        def proposal(lin, mu2):
            Us, s, Vt, scale, r = lin
            smax = jnp.maximum(jnp.max(s), 1e-100)
            gain = s / (s * s + jnp.maximum(mu2, config.damping_min) * smax * smax)
            gain = jnp.where(s > config.rcond * smax, gain, 0.0)  # truncate unobservable directions
            coef = gain * (Us.T @ r)
            dy_rms = jnp.sqrt(jnp.sum((s * coef) ** 2) / m)  # predicted change of the outputs
            return (Vt.T @ coef) / scale, (dy_rms <= config.step_tol * y_scale) | ~jnp.isfinite(dy_rms)

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
            cand = c.xi + c.delta
            okc, costc, xsc, linc, defc, condc = evaluate(cand)
            acc = okc & (costc <= c.cost)
            sel = lambda a, b: jax.tree_util.tree_map(lambda u, v: jnp.where(acc, u, v), a, b)  # noqa: E731
            lin = sel(linc, c.lin)
            mu2 = jnp.where(acc, jnp.maximum(c.mu2 / 3.0, config.damping_min), c.mu2 * 8.0)
            delta, small = proposal(lin, mu2)
            return Carry(i=c.i + 1, xi=jnp.where(acc, cand, c.xi), xs=jnp.where(acc, xsc, c.xs),
                         cost=jnp.where(acc, costc, c.cost), lin=lin, mu2=mu2, delta=delta,
                         small=small, deficient=jnp.where(acc, defc, c.deficient),
                         cond=jnp.where(acc, condc, c.cond))

        mu2_0 = jnp.asarray(config.damping, dtype=float)
        delta0, small0 = proposal(lin0, mu2_0)
        c = jax.lax.while_loop(cond_fun, body, Carry(
            i=jnp.asarray(0), xi=xi0, xs=xs0, cost=cost0, lin=lin0, mu2=mu2_0, delta=delta0,
            small=small0 & ok0, deficient=def0, cond=cond0))
        rms = jnp.sqrt(jnp.where(jnp.isfinite(c.cost), c.cost, 0.0) / m)
        finite = jnp.all(jnp.isfinite(c.xs)) & jnp.all(jnp.isfinite(c.xi))
        xi = jnp.where(finite, c.xi, xi0)
        xs = jnp.where(finite, c.xs, jnp.where(jnp.all(jnp.isfinite(xs0)), xs0, jnp.tile(xi0, (N, 1))))
        return WindowSolution(xi=xi, xs=xs, residual_rms=rms, cond=c.cond,
                              rank_deficient=c.deficient, converged=c.small & ~c.deficient & finite,
                              iterations=c.i)

    def init(x0, P0=None):
        """Observer state with estimate ``x0`` (pytree like ``x_template``); ``P0`` is unused."""
        del P0
        xf = ravel_pytree(x0)[0].astype(float)
        if xf.shape != (n,):
            raise InputError(f"Newton observer: x0 has {xf.shape[0]} components, model has {n}")
        us = jax.tree_util.tree_map(
            lambda a: jnp.zeros((N,) + jnp.shape(a), dtype=jnp.result_type(a, float)), u_template)
        last = NewtonOutput(x_hat=xf, solved=jnp.asarray(False), converged=jnp.asarray(False),
                            rank_deficient=jnp.asarray(False), residual_rms=jnp.asarray(0.0),
                            cond=jnp.asarray(1.0), iterations=jnp.asarray(0), measured=jnp.asarray(False))
        return NewtonState(x_hat=xf, xs_window=jnp.tile(xf, (N, 1)), ys=jnp.zeros((N, p)),
                           mask=jnp.zeros((N, p)), us=us, count=jnp.asarray(0),
                           since_solve=jnp.asarray(0), last=last, rollout=jnp.asarray(1))

    def step(state: NewtonState, u, y, dt=None):
        """One sample: predict (F 4.1), push (u, y), every `every` samples solve and carry forward."""
        del dt
        y = jnp.reshape(jnp.asarray(y, dtype=float), (p,))
        finite_y = jnp.isfinite(y)
        x_pred = f_flat(state.x_hat, u)
        pred_ok = jnp.all(jnp.isfinite(x_pred))
        x_pred = jnp.where(pred_ok, x_pred, state.x_hat)
        # the window stays the model's rollout from its first entry while predictions are pushed
        # (x_hat is always the window's last entry); a replaced non-finite prediction breaks it
        prev = jnp.asarray(1) if state.rollout is None else state.rollout
        rollout = jnp.where(pred_ok, jnp.minimum(prev + 1, N), 1)
        push = lambda buf, new: jnp.concatenate([buf[1:], jnp.asarray(new, buf.dtype)[None]], axis=0)  # noqa: E731
        us = jax.tree_util.tree_map(push, state.us, u)
        ys = push(state.ys, jnp.where(finite_y, y, 0.0))
        mask = push(state.mask, finite_y.astype(float))
        xs_window = push(state.xs_window, x_pred)
        count = state.count + 1
        since = state.since_solve + 1
        do_solve = (count >= N) & (since >= int(config.every))

        def solved(_):
            # warm start: the carried window is already the rollout from its first entry (reuse
            # it), unless a non-finite prediction broke it (roll the window out again)
            xs_start = jax.lax.cond(rollout >= N, lambda: xs_window,
                                    lambda: observability_map(xs_window[0], us)[1])
            sol = solve(xs_window[0], us, ys, mask, xs_start)
            out = NewtonOutput(x_hat=sol.xs[-1], solved=jnp.asarray(True),
                               converged=sol.converged, rank_deficient=sol.rank_deficient,
                               residual_rms=sol.residual_rms, cond=sol.cond,
                               iterations=sol.iterations, measured=jnp.all(finite_y))
            # the solution is a rollout (of the accepted ξ, or of the warm start) unless the solve
            # fell back to a constant window, which needs a non-finite warm-start rollout
            return sol.xs, out, jnp.where(jnp.all(jnp.isfinite(xs_start)), N, 1)

        def predicted(_):
            return xs_window, state.last._replace(x_hat=x_pred, solved=jnp.asarray(False),
                                                  measured=jnp.all(finite_y)), rollout

        xs_new, out, rollout_new = jax.lax.cond(do_solve, solved, predicted, None)
        new_state = NewtonState(x_hat=out.x_hat, xs_window=xs_new, ys=ys, mask=mask, us=us,
                                count=count, since_solve=jnp.where(do_solve, 0, since),
                                last=out, rollout=rollout_new)
        return new_state, out

    def run(state: NewtonState, us, ys, dts=None):
        """``step`` over a sequence under ``lax.scan``; returns (states, outputs) stacked."""

        def body(s, uy):
            s2, out = step(s, uy[0], uy[1])
            return s2, (s2, out)

        _, (states, outs) = jax.lax.scan(body, state, (us, ys))
        return states, outs

    return NewtonObserver(init=init, step=step, run=run, solve=solve,
                          observability_map=observability_map, unravel=unravel)
