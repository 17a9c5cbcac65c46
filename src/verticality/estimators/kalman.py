"""Linear Kalman filtering: discrete time-varying filter, steady-state gains, continuous observers.

The plant is given in continuous time (T eq. 7–10 style)::

    ẋ = A x + B u + w,      E[w wᵀ] = Q δ(t − s)      (Q: process-noise intensity)
    y = C x + D u + v,      v sampled every dt with covariance R / dt (R: measurement intensity)

so that the continuous algebraic Riccati equation (T eq. 10–11) and the sampled filter describe the
same plant and, as ``dt → 0``, the discrete steady-state gain ``K_d`` tends to ``L_c dt``.

* :func:`van_loan` — exact zero-order-hold discretization of (A, B) and of the process noise Q.
* :func:`continuous_steady_gain` — ``L = P Cᵀ R⁻¹`` with P from the CARE (T eq. 10–11), SciPy.
* :func:`discrete_steady_gain` — the steady-state gain of the sampled filter from the DARE, SciPy.
* :class:`KalmanFilter` (:func:`kalman_filter`) — time-varying discrete filter (predict with Van
  Loan, Joseph update).
* :class:`SteadyStateKalmanFilter` (:func:`steady_state_kalman_filter`) — the same filter with its
  converged (DARE) gain, for one dt.
* :class:`ContinuousObserver` (:func:`continuous_observer`) —
  ``x̂' = A x̂ + B u + L (y − C x̂ − D u)`` (T eq. 9 and 19, F eq. 4.10) with a fixed gain L
  (steady-state Kalman gain, or a pole-placement gain: :mod:`verticality.estimators.luenberger`,
  :mod:`verticality.estimators.disturbance`), integrated exactly over each sample with u and y held
  (zero-order hold).

The estimators are frozen values with the interface of :mod:`verticality.estimators.base`
(``init``, ``predict``, ``step``, ``run``); the functions above validate and build them. A NaN in a
component of ``y`` means that component was not measured: its innovation is dropped (its gain
column is zero) and ``out.measured`` says so, per component; with no component measured the step
is ``predict``.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
import scipy.linalg

from verticality.core.errors import InputError
from verticality.core.integrate import zoh
from verticality.estimators.base import keep_finite, scan_steps, split_measurement
from verticality.models.base import model_dataclass


def _as2d(name: str, M, rows: int | None = None, cols: int | None = None) -> np.ndarray:
    M = np.atleast_2d(np.asarray(M, dtype=float))
    if M.ndim != 2:
        raise InputError(f"{name} must be a matrix, got shape {M.shape}")
    if rows is not None and M.shape[0] != rows or cols is not None and M.shape[1] != cols:
        raise InputError(f"{name} has shape {M.shape}, expected ({rows}, {cols})")
    if not np.all(np.isfinite(M)):
        raise InputError(f"{name} contains NaN or inf")
    return M


def _check_psd(name: str, M: np.ndarray, strict: bool) -> None:
    if not np.allclose(M, M.T, atol=1e-12 * max(1.0, np.abs(M).max())):
        raise InputError(f"{name} must be symmetric")
    w = np.linalg.eigvalsh(M)
    if (strict and w.min() <= 0.0) or w.min() < -1e-12 * max(1.0, np.abs(w).max()):
        kind = "positive definite" if strict else "positive semidefinite"
        raise InputError(f"{name} must be {kind} (smallest eigenvalue {w.min():.3g})")


def check_system(A, B=None, C=None, D=None, Q=None, R=None):
    """Validate shapes and definiteness; return NumPy (A, B, C, D, Q, R) with defaults filled in.

    B defaults to a zero (n, 1) input matrix, D to zeros; Q must be PSD and R positive definite.
    """
    A = _as2d("A", A)
    n = A.shape[0]
    if A.shape != (n, n):
        raise InputError(f"A must be square, got shape {A.shape}")
    B = np.zeros((n, 1)) if B is None else _as2d("B", B, rows=n)
    if C is None:
        raise InputError("the measurement matrix C is required")
    C = _as2d("C", C, cols=n)
    p, m = C.shape[0], B.shape[1]
    D = np.zeros((p, m)) if D is None else _as2d("D", D, rows=p, cols=m)
    out = [A, B, C, D]
    if Q is not None:
        Q = _as2d("Q", Q, rows=n, cols=n)
        _check_psd("Q", Q, strict=False)
    if R is not None:
        R = _as2d("R", R, rows=p, cols=p)
        _check_psd("R", R, strict=True)
    return (*out, Q, R)


# --------------------------------------------------------------------------- discretization


def van_loan(A, B, Q, dt):
    """Exact discretization over ``dt`` (JAX; Van Loan 1978).

    Returns ``(Phi, Gamma, Qd)``: ``Phi = e^{A dt}``, ``Gamma = ∫₀^dt e^{A s} ds B`` (input held,
    :func:`verticality.core.integrate.zoh`), ``Qd = ∫₀^dt e^{A s} Q e^{Aᵀ s} ds`` — from one matrix
    exponential of the block matrix ``[[−A, Q], [0, Aᵀ]]``.
    """
    A = jnp.asarray(A)
    n = A.shape[0]
    Phi, Gamma = zoh(A, jnp.asarray(B), dt)
    V = jnp.block([[-A, Q], [jnp.zeros((n, n)), A.T]])
    F = jax.scipy.linalg.expm(V * dt)
    Qd = Phi @ F[:n, n:]
    return Phi, Gamma, 0.5 * (Qd + Qd.T)


# --------------------------------------------------------------------------- steady-state gains


def continuous_steady_gain(A, C, Q, R):
    """Steady-state Kalman–Bucy gain (T eq. 10–11): ``(L, P)`` with
    ``A P + P Aᵀ + Q − P Cᵀ R⁻¹ C P = 0``.

    Solved with :func:`scipy.linalg.solve_continuous_are` on the dual (control) problem.
    """
    A, _, C, _, Q, R = check_system(A, None, C, None, Q, R)
    try:
        P = scipy.linalg.solve_continuous_are(A.T, C.T, Q, R)
    except (np.linalg.LinAlgError, ValueError) as exc:
        raise InputError("continuous Riccati equation has no stabilizing solution: "
                         f"{exc}") from None
    L = scipy.linalg.solve(R, C @ P, assume_a="pos").T
    return L, P


def discrete_steady_gain(Phi, C, Qd, Rd):
    """Steady-state gain of the sampled filter: ``(K, P_prior, P_post)`` from the DARE.

    ``P_prior`` solves ``P = Φ P Φᵀ − Φ P Cᵀ (C P Cᵀ + R)⁻¹ C P Φᵀ + Q``;
    ``K = P Cᵀ (C P Cᵀ + R)⁻¹`` is the measurement-update gain of :class:`KalmanFilter` once it has
    converged.
    """
    Phi, _, C, _, Qd, Rd = check_system(Phi, None, C, None, Qd, Rd)
    try:
        P = scipy.linalg.solve_discrete_are(Phi.T, C.T, Qd, Rd)
    except (np.linalg.LinAlgError, ValueError) as exc:
        raise InputError(f"discrete Riccati equation has no stabilizing solution: {exc}") from None
    S = C @ P @ C.T + Rd
    K = scipy.linalg.solve(S, C @ P, assume_a="pos").T
    I_KC = np.eye(P.shape[0]) - K @ C
    P_post = I_KC @ P @ I_KC.T + K @ Rd @ K.T
    return K, P, 0.5 * (P_post + P_post.T)


# --------------------------------------------------------------------------- shared pieces


class KFState(NamedTuple):
    x: jnp.ndarray
    P: jnp.ndarray
    k: jnp.ndarray  # sample counter


class KFOut(NamedTuple):
    x: jnp.ndarray  # posterior estimate
    P: jnp.ndarray  # posterior covariance
    K: jnp.ndarray  # gain used (zero columns for missing measurements)
    innovation: jnp.ndarray  # y − ŷ⁻ (0 where missing)
    measured: jnp.ndarray  # bool per measurement component


class ObsState(NamedTuple):
    x: jnp.ndarray
    k: jnp.ndarray


class ObsOut(NamedTuple):
    x: jnp.ndarray
    innovation: jnp.ndarray  # y − C x̂ − D u at the start of the sample (0 where missing)
    measured: jnp.ndarray  # bool per measurement component


def _input(u, m):
    return jnp.reshape(jnp.asarray(u, dtype=jnp.float64), (m,))


def _run(est, state, us, ys, dts):
    """``run`` of the linear estimators: with one scalar dt the discretization is computed once
    (``est.discretize``, then ``est.step_discrete`` per sample), else per sample (``est.step``)."""
    ys = jnp.asarray(ys, dtype=jnp.float64)
    if ys.ndim != 2 or ys.shape[1] != est.C.shape[0]:
        raise InputError(f"ys must be (samples, {est.C.shape[0]}), got shape {ys.shape}")
    n, m = ys.shape[0], est.B.shape[1]
    us = jnp.zeros((n, m)) if us is None else jnp.asarray(us, dtype=jnp.float64).reshape(n, m)
    if np.ndim(dts) == 0:
        if not isinstance(dts, jax.core.Tracer) and not float(dts) > 0:
            raise InputError(f"dt must be positive, got {dts}")
        return _run_fixed(est, state, us, ys, jnp.asarray(dts, dtype=jnp.float64))
    dts = jnp.asarray(dts, dtype=jnp.float64)
    if dts.shape != (n,):
        raise InputError(f"dts must be a scalar or have {n} entries, got shape {dts.shape}")
    return _run_varying(est, state, us, ys, dts)


@jax.jit
def _run_fixed(est, state, us, ys, dt):
    disc = est.discretize(dt)
    return scan_steps(lambda s, u, y, _: est.step_discrete(s, u, y, disc), state, us, ys, dt)


@jax.jit
def _run_varying(est, state, us, ys, dts):
    return scan_steps(est.step, state, us, ys, dts)


# --------------------------------------------------------------------------- time-varying filter


@model_dataclass
class KalmanFilter:
    """Time-varying discrete Kalman filter on a continuous plant (see the module docstring).

    Build with :func:`kalman_filter` (validates). ``step`` predicts over ``dt`` with the input held
    (Van Loan), then updates with ``y`` (Joseph form, symmetrized).
    """

    A: Any
    B: Any
    C: Any
    D: Any
    Q: Any  # process-noise intensity
    R: Any  # measurement-noise intensity (per-sample covariance R / dt)

    def init(self, x0, P0) -> KFState:
        return KFState(jnp.asarray(x0, dtype=jnp.float64), jnp.asarray(P0, dtype=jnp.float64),
                       jnp.asarray(0))

    def discretize(self, dt):
        """Sample-time matrices ``(Φ, Γ, Q_d, dt)`` (Van Loan); reused by :meth:`step_discrete`."""
        return (*van_loan(self.A, self.B, self.Q, dt), dt)

    def _predict(self, state: KFState, u, disc) -> KFState:
        Phi, Gamma, Qd, _ = disc
        u = _input(u, self.B.shape[1])
        return KFState(Phi @ state.x + Gamma @ u, Phi @ state.P @ Phi.T + Qd, state.k + 1)

    def predict(self, state: KFState, u, dt) -> KFState:
        return self._predict(state, u, self.discretize(dt))

    def step(self, state: KFState, u, y, dt):
        return self.step_discrete(state, u, y, self.discretize(dt))

    def step_discrete(self, state: KFState, u, y, disc):
        dt = disc[3]
        pred = self._predict(state, u, disc)
        u = _input(u, self.B.shape[1])
        y0, ok = split_measurement(y)
        okf = ok.astype(jnp.float64)
        Cm = self.C * okf[:, None]
        Rd = self.R / dt
        # Missing components: zero row of C, unit variance, no correlation -> zero gain column.
        Rm = Rd * jnp.outer(okf, okf) + jnp.diag(1.0 - okf)
        innov = okf * (y0 - self.C @ pred.x - self.D @ u)
        S = Cm @ pred.P @ Cm.T + Rm
        S = 0.5 * (S + S.T)
        cho = jax.scipy.linalg.cho_factor(S)
        K = jax.scipy.linalg.cho_solve(cho, Cm @ pred.P).T
        x = pred.x + K @ innov
        I_KC = jnp.eye(pred.P.shape[0]) - K @ Cm
        P = I_KC @ pred.P @ I_KC.T + K @ Rm @ K.T
        P = 0.5 * (P + P.T)
        any_ok = jnp.any(ok)
        x, P = jnp.where(any_ok, x, pred.x), jnp.where(any_ok, P, pred.P)
        (x, P), _ = keep_finite((x, P), (state.x, state.P))
        return KFState(x, P, pred.k), KFOut(x, P, K, innov, ok)

    def run(self, state: KFState, us, ys, dts):
        return _run(self, state, us, ys, dts)


def kalman_filter(A, B=None, C=None, D=None, Q=None, R=None) -> KalmanFilter:
    """A :class:`KalmanFilter` for the continuous plant (A, B, C, D) with noise intensities Q, R."""
    if Q is None or R is None or C is None:
        raise InputError("a Kalman filter needs C, Q and R")
    A, B, C, D, Q, R = check_system(A, B, C, D, Q, R)
    return KalmanFilter(*(jnp.asarray(M) for M in (A, B, C, D, Q, R)))


# --------------------------------------------------------------------------- steady-state discrete


@model_dataclass
class SteadyStateKalmanFilter:
    """The discrete filter with its converged gain ``K`` (from the DARE) and no covariance.

    Valid for the sample time it was built for (:func:`steady_state_kalman_filter` takes ``dt``);
    ``step`` predicts with the zero-order hold over the given dt and updates with K — equal to
    :class:`KalmanFilter` once that has converged at the same dt. ``P`` is the (constant)
    steady-state posterior covariance.
    """

    A: Any
    B: Any
    C: Any
    D: Any
    K: Any
    P: Any

    def init(self, x0, P0=None) -> KFState:
        return KFState(jnp.asarray(x0, dtype=jnp.float64), self.P, jnp.asarray(0))

    def discretize(self, dt):
        return zoh(self.A, self.B, dt)

    def _predict(self, state: KFState, u, disc) -> KFState:
        Phi, Gamma = disc
        return KFState(Phi @ state.x + Gamma @ _input(u, self.B.shape[1]), self.P, state.k + 1)

    def predict(self, state: KFState, u, dt) -> KFState:
        return self._predict(state, u, self.discretize(dt))

    def step(self, state: KFState, u, y, dt):
        return self.step_discrete(state, u, y, self.discretize(dt))

    def step_discrete(self, state: KFState, u, y, disc):
        pred = self._predict(state, u, disc)
        u = _input(u, self.B.shape[1])
        y0, ok = split_measurement(y)
        K = self.K * ok.astype(jnp.float64)[None, :]
        innov = ok * (y0 - self.C @ pred.x - self.D @ u)
        x = jnp.where(jnp.any(ok), pred.x + K @ innov, pred.x)
        x, _ = keep_finite(x, state.x)
        return KFState(x, self.P, pred.k), KFOut(x, self.P, K, innov, ok)

    def run(self, state: KFState, us, ys, dts):
        return _run(self, state, us, ys, dts)


def steady_state_kalman_filter(A, B=None, C=None, D=None, Q=None, R=None,
                               dt=None) -> SteadyStateKalmanFilter:
    """The :class:`SteadyStateKalmanFilter` of the plant for the sample time ``dt``."""
    if Q is None or R is None or C is None or dt is None or not dt > 0:
        raise InputError("a steady-state Kalman filter needs C, Q, R and a positive dt")
    A, B, C, D, Q, R = check_system(A, B, C, D, Q, R)
    Phi, _, Qd = van_loan(jnp.asarray(A), jnp.asarray(B), jnp.asarray(Q), float(dt))
    K, _, P = discrete_steady_gain(np.asarray(Phi), C, np.asarray(Qd), R / dt)
    return SteadyStateKalmanFilter(*(jnp.asarray(M) for M in (A, B, C, D, K, P)))


# --------------------------------------------------------------------------- fixed-gain observer


@model_dataclass
class ContinuousObserver:
    """``x̂' = A x̂ + B u + L (y − C x̂ − D u)`` (T eq. 9 with the Kalman gain, T eq. 19 and F eq.
    4.10 with a pole-placement gain), integrated exactly over each sample with u and y held
    (zero-order hold): the estimate after the step is x̂ at the end of the sample. A missing
    component of y has its column of L zeroed for that sample; ``predict`` is the observer with
    every column zeroed (``ẋ̂ = A x̂ + B u``).
    """

    A: Any
    B: Any
    C: Any
    D: Any
    L: Any

    def poles(self) -> np.ndarray:
        """Eigenvalues of the error dynamics ``A − L C``."""
        return np.linalg.eigvals(np.asarray(self.A - self.L @ self.C))

    def init(self, x0, P0=None) -> ObsState:
        x0 = jnp.asarray(x0, dtype=jnp.float64)
        if x0.shape != (self.A.shape[0],):
            raise InputError(f"x0 must be a vector of {self.A.shape[0]} states, "
                             f"got shape {x0.shape}")
        return ObsState(x0, jnp.asarray(0))

    def _zoh(self, ok, dt):
        # ẋ̂ = (A − L C) x̂ + (B − L D) u + L y, inputs held: one expm of the augmented matrix
        Lm = self.L * ok.astype(jnp.float64)[None, :]
        M = self.A - Lm @ self.C
        N = jnp.concatenate([self.B - Lm @ self.D, Lm], axis=1)
        return zoh(M, N, dt)

    def discretize(self, dt):
        """``(Φ, Γ, dt)`` with every measurement present; recomputed for a sample with NaNs."""
        return (*self._zoh(jnp.ones(self.C.shape[0], bool), dt), dt)

    def _advance(self, state: ObsState, u, y0, ok, Phi, Gamma):
        u = _input(u, self.B.shape[1])
        x = Phi @ state.x + Gamma @ jnp.concatenate([u, y0])
        x, _ = keep_finite(x, state.x)
        innov = ok * (y0 - self.C @ state.x - self.D @ u)
        return ObsState(x, state.k + 1), ObsOut(x, innov, ok)

    def predict(self, state: ObsState, u, dt) -> ObsState:
        ok = jnp.zeros(self.C.shape[0], bool)
        return self._advance(state, u, jnp.zeros(self.C.shape[0]), ok, *self._zoh(ok, dt))[0]

    def step(self, state: ObsState, u, y, dt):
        y0, ok = split_measurement(y)
        return self._advance(state, u, y0, ok, *self._zoh(ok, dt))

    def step_discrete(self, state: ObsState, u, y, disc):
        Phi_full, Gamma_full, dt = disc
        y0, ok = split_measurement(y)
        Phi, Gamma = jax.lax.cond(jnp.all(ok), lambda: (Phi_full, Gamma_full),
                                  lambda: self._zoh(ok, dt))
        return self._advance(state, u, y0, ok, Phi, Gamma)

    def run(self, state: ObsState, us, ys, dts):
        return _run(self, state, us, ys, dts)


def continuous_observer(A, B=None, C=None, D=None, L=None) -> ContinuousObserver:
    """A :class:`ContinuousObserver` with the gain ``L`` (validated shapes, finite entries)."""
    if C is None or L is None:
        raise InputError("a continuous observer needs C and L")
    A, B, C, D, _, _ = check_system(A, B, C, D)
    L = _as2d("L", L, rows=A.shape[0], cols=C.shape[0])
    return ContinuousObserver(*(jnp.asarray(M) for M in (A, B, C, D, L)))
