"""Linear Kalman filtering: discrete time-varying filter, steady-state gains, continuous observers.

The plant is given in continuous time (T eq. 7–10 style)::

    ẋ = A x + B u + w,      E[w wᵀ] = Q δ(t − s)      (Q: process-noise intensity)
    y = C x + D u + v,      v sampled every dt with covariance R / dt (R: measurement intensity)

so that the continuous algebraic Riccati equation (T eq. 10–11) and the sampled filter describe the
same plant and, as ``dt → 0``, the discrete steady-state gain ``K_d`` tends to ``L_c dt``.

* :func:`van_loan` — exact zero-order-hold discretization of (A, B) and of the process noise Q.
* :func:`continuous_steady_gain` — ``L = P Cᵀ R⁻¹`` with P from the CARE (T eq. 10–11), SciPy.
* :func:`discrete_steady_gain` — the steady-state gain of the sampled filter from the DARE, SciPy.
* :class:`KalmanFilter` — time-varying discrete filter (predict with Van Loan, Joseph update).
* :class:`SteadyStateKalmanFilter` — the same filter with its converged (DARE) gain, for one dt.
* :class:`ContinuousObserver` — ``x̂' = A x̂ + B u + L (y − C x̂ − D u)`` (T eq. 9 and 19) with a
  fixed gain L (steady-state Kalman gain, or a pole-placement gain), discretized exactly with the
  measurement held over the sample (zero-order hold).

Both estimators follow the project API ``init(x0, P0)``, ``step(state, u, y, dt)``,
``run(state, us, ys, dts)`` (``jax.lax.scan``). A NaN in a component of ``y`` means that component
was not measured: its innovation is dropped (predict only for it) and ``out.missing`` flags it.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
import scipy.linalg

from verticality.errors import InputError


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
    """Exact discretization over ``dt`` (JAX; C. F. Van Loan 1978).

    Returns ``(Phi, Gamma, Qd)``: ``Phi = e^{A dt}``, ``Gamma = ∫₀^dt e^{A s} ds B`` (input held),
    ``Qd = ∫₀^dt e^{A s} Q e^{Aᵀ s} ds`` — from one matrix exponential each of the block matrices
    ``[[A, B], [0, 0]]`` and ``[[−A, Q], [0, Aᵀ]]``.
    """
    A = jnp.asarray(A)
    n, m = A.shape[0], B.shape[1]
    top = jnp.concatenate([A, B], axis=1)
    M = jnp.concatenate([top, jnp.zeros((m, n + m))], axis=0)
    E = jax.scipy.linalg.expm(M * dt)
    Phi, Gamma = E[:n, :n], E[:n, n:]
    V = jnp.block([[-A, Q], [jnp.zeros((n, n)), A.T]])
    F = jax.scipy.linalg.expm(V * dt)
    Qd = Phi @ F[:n, n:]
    return Phi, Gamma, 0.5 * (Qd + Qd.T)


def zoh(M, N, dt):
    """``(e^{M dt}, ∫₀^dt e^{M s} ds N)`` for ``ẋ = M x + N v`` with v held over the step."""
    n, m = M.shape[0], N.shape[1]
    top = jnp.concatenate([M, N], axis=1)
    E = jax.scipy.linalg.expm(jnp.concatenate([top, jnp.zeros((m, n + m))], axis=0) * dt)
    return E[:n, :n], E[:n, n:]


# --------------------------------------------------------------------------- steady-state gains


def continuous_steady_gain(A, C, Q, R):
    """Steady-state Kalman–Bucy gain (T eq. 10–11): ``(L, P)`` with ``A P + P Aᵀ + Q − P Cᵀ R⁻¹ C P = 0``.

    Solved with :func:`scipy.linalg.solve_continuous_are` on the dual (control) problem.
    """
    A, _, C, _, Q, R = check_system(A, None, C, None, Q, R)
    try:
        P = scipy.linalg.solve_continuous_are(A.T, C.T, Q, R)
    except (np.linalg.LinAlgError, ValueError) as exc:
        raise InputError(f"continuous Riccati equation has no stabilizing solution: {exc}") from None
    L = scipy.linalg.solve(R, C @ P, assume_a="pos").T
    return L, P


def discrete_steady_gain(Phi, C, Qd, Rd):
    """Steady-state gain of the sampled filter: ``(K, P_prior, P_post)`` from the DARE.

    ``P_prior`` solves ``P = Φ P Φᵀ − Φ P Cᵀ (C P Cᵀ + R)⁻¹ C P Φᵀ + Q``; ``K = P Cᵀ (C P Cᵀ + R)⁻¹``
    is the measurement-update gain of :class:`KalmanFilter` once it has converged.
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


# --------------------------------------------------------------------------- helpers for missing y


def _mask(y):
    y = jnp.asarray(y, dtype=float)
    ok = jnp.isfinite(y)
    return jnp.where(ok, y, 0.0), ok


# --------------------------------------------------------------------------- time-varying filter


class KFState(NamedTuple):
    x: jnp.ndarray
    P: jnp.ndarray
    k: jnp.ndarray  # sample counter


class KFOut(NamedTuple):
    x: jnp.ndarray  # posterior estimate
    P: jnp.ndarray  # posterior covariance
    K: jnp.ndarray  # gain used (zero columns for missing measurements)
    innovation: jnp.ndarray  # y − ŷ⁻ (0 where missing)
    missing: jnp.ndarray  # bool per measurement component


class KalmanFilter(NamedTuple):
    """Time-varying discrete Kalman filter on a continuous plant (see the module docstring).

    Build with :meth:`create` (validates). ``step`` predicts over ``dt`` with the input held
    (Van Loan), then updates with ``y`` (Joseph form, symmetrized).
    """

    A: jnp.ndarray
    B: jnp.ndarray
    C: jnp.ndarray
    D: jnp.ndarray
    Q: jnp.ndarray  # process-noise intensity
    R: jnp.ndarray  # measurement-noise intensity (per-sample covariance R / dt)

    @classmethod
    def create(cls, A, B=None, C=None, D=None, Q=None, R=None) -> KalmanFilter:
        if Q is None or R is None or C is None:
            raise InputError("KalmanFilter needs C, Q and R")
        A, B, C, D, Q, R = check_system(A, B, C, D, Q, R)
        return cls(*(jnp.asarray(M) for M in (A, B, C, D, Q, R)))

    def init(self, x0, P0) -> KFState:
        return KFState(jnp.asarray(x0, float), jnp.asarray(P0, float), jnp.asarray(0))

    def discretize(self, dt):
        """Sample-time matrices ``(Φ, Γ, Q_d, dt)`` (Van Loan); reused by :meth:`step_discrete`."""
        return (*van_loan(self.A, self.B, self.Q, dt), dt)

    def step(self, state: KFState, u, y, dt):
        return self.step_discrete(state, u, y, self.discretize(dt))

    def step_discrete(self, state: KFState, u, y, disc):
        Phi, Gamma, Qd, dt = disc
        u = jnp.atleast_1d(jnp.asarray(u, float))
        x = Phi @ state.x + Gamma @ u
        P = Phi @ state.P @ Phi.T + Qd
        y0, ok = _mask(y)
        okf = ok.astype(float)
        Cm = self.C * okf[:, None]
        Rd = self.R / dt
        # Missing components: zero row of C, unit variance, no correlation -> zero gain column.
        Rm = Rd * jnp.outer(okf, okf) + jnp.diag(1.0 - okf)
        innov = okf * (y0 - self.C @ x - self.D @ u)
        S = Cm @ P @ Cm.T + Rm
        S = 0.5 * (S + S.T)
        cho = jax.scipy.linalg.cho_factor(S)
        K = jax.scipy.linalg.cho_solve(cho, Cm @ P).T
        x = x + K @ innov
        I_KC = jnp.eye(P.shape[0]) - K @ Cm
        P = I_KC @ P @ I_KC.T + K @ Rm @ K.T
        P = 0.5 * (P + P.T)
        return KFState(x, P, state.k + 1), KFOut(x, P, K, innov, ~ok)

    def run(self, state: KFState, us, ys, dts):
        return _scan(self, state, us, ys, dts)


# --------------------------------------------------------------------------- steady-state discrete


class SteadyStateKalmanFilter(NamedTuple):
    """The discrete filter with its converged gain ``K`` (from the DARE) and no covariance.

    Valid for the sample time it was built for (:meth:`create` takes ``dt``); ``step`` predicts
    with Van Loan over the given dt and updates with K — equal to :class:`KalmanFilter` once that
    has converged at the same dt. ``P`` is the (constant) steady-state posterior covariance.
    """

    A: jnp.ndarray
    B: jnp.ndarray
    C: jnp.ndarray
    D: jnp.ndarray
    K: jnp.ndarray
    P: jnp.ndarray

    @classmethod
    def create(cls, A, B=None, C=None, D=None, Q=None, R=None, dt=None) -> SteadyStateKalmanFilter:
        if Q is None or R is None or C is None or dt is None or not dt > 0:
            raise InputError("SteadyStateKalmanFilter needs C, Q, R and a positive dt")
        A, B, C, D, Q, R = check_system(A, B, C, D, Q, R)
        Phi, _, Qd = van_loan(jnp.asarray(A), jnp.asarray(B), jnp.asarray(Q), float(dt))
        K, _, P = discrete_steady_gain(np.asarray(Phi), C, np.asarray(Qd), R / dt)
        return cls(*(jnp.asarray(M) for M in (A, B, C, D, K, P)))

    def init(self, x0, P0=None) -> KFState:
        return KFState(jnp.asarray(x0, float), self.P, jnp.asarray(0))

    def discretize(self, dt):
        return zoh(self.A, self.B, dt)

    def step(self, state: KFState, u, y, dt):
        return self.step_discrete(state, u, y, self.discretize(dt))

    def step_discrete(self, state: KFState, u, y, disc):
        Phi, Gamma = disc
        u = jnp.atleast_1d(jnp.asarray(u, float))
        x = Phi @ state.x + Gamma @ u
        y0, ok = _mask(y)
        K = self.K * ok.astype(float)[None, :]
        innov = ok * (y0 - self.C @ x - self.D @ u)
        x = x + K @ innov
        return KFState(x, self.P, state.k + 1), KFOut(x, self.P, K, innov, ~ok)

    def run(self, state: KFState, us, ys, dts):
        return _scan(self, state, us, ys, dts)


# --------------------------------------------------------------------------- fixed-gain observer


class ObsState(NamedTuple):
    x: jnp.ndarray
    k: jnp.ndarray


class ObsOut(NamedTuple):
    x: jnp.ndarray
    innovation: jnp.ndarray
    missing: jnp.ndarray


class ContinuousObserver(NamedTuple):
    """``x̂' = A x̂ + B u + L (y − C x̂ − D u)`` (T eq. 9 with the Kalman gain, T eq. 19 with a
    pole-placement gain), integrated exactly over each sample with u and y held (zero-order hold).
    """

    A: jnp.ndarray
    B: jnp.ndarray
    C: jnp.ndarray
    D: jnp.ndarray
    L: jnp.ndarray

    @classmethod
    def create(cls, A, B=None, C=None, D=None, L=None) -> ContinuousObserver:
        if C is None or L is None:
            raise InputError("ContinuousObserver needs C and L")
        A, B, C, D, _, _ = check_system(A, B, C, D)
        L = _as2d("L", L, rows=A.shape[0], cols=C.shape[0])
        return cls(*(jnp.asarray(M) for M in (A, B, C, D, L)))

    def poles(self) -> np.ndarray:
        """Eigenvalues of the error dynamics ``A − L C``."""
        return np.linalg.eigvals(np.asarray(self.A - self.L @ self.C))

    def init(self, x0, P0=None) -> ObsState:
        return ObsState(jnp.asarray(x0, float), jnp.asarray(0))

    def _zoh(self, ok, dt):
        Lm = self.L * ok.astype(float)[None, :]
        M = self.A - Lm @ self.C
        N = jnp.concatenate([self.B - Lm @ self.D, Lm], axis=1)
        return zoh(M, N, dt)

    def discretize(self, dt):
        """``(Φ, Γ, dt)`` with every measurement present; recomputed for a sample with NaNs."""
        return (*self._zoh(jnp.ones(self.C.shape[0], bool), dt), dt)

    def step(self, state: ObsState, u, y, dt):
        return self.step_discrete(state, u, y, self.discretize(dt))

    def step_discrete(self, state: ObsState, u, y, disc):
        Phi_full, Gamma_full, dt = disc
        u = jnp.atleast_1d(jnp.asarray(u, float))
        y0, ok = _mask(y)
        Phi, Gamma = jax.lax.cond(jnp.all(ok), lambda: (Phi_full, Gamma_full),
                                  lambda: self._zoh(ok, dt))
        x = Phi @ state.x + Gamma @ jnp.concatenate([u, y0])
        innov = ok * (y0 - self.C @ state.x - self.D @ u)
        return ObsState(x, state.k + 1), ObsOut(x, innov, ~ok)

    def run(self, state: ObsState, us, ys, dts):
        return _scan(self, state, us, ys, dts)


def _scan(est, state, us, ys, dts):
    """``lax.scan`` of ``est.step``; with one scalar dt the discretization is computed once."""
    ys = jnp.asarray(ys, float)
    if ys.ndim != 2:
        raise InputError(f"ys must be (samples, measurements), got shape {ys.shape}")
    n = ys.shape[0]
    us = jnp.zeros((n, est.B.shape[1])) if us is None else jnp.asarray(us, float).reshape(n, -1)
    if np.ndim(dts) == 0:
        if not float(dts) > 0:
            raise InputError(f"dt must be positive, got {dts}")
        return _run_fixed(est, state, us, ys, jnp.asarray(dts, float))
    dts = jnp.asarray(dts, float)
    if dts.shape != (n,):
        raise InputError(f"dts must be a scalar or have {n} entries, got shape {dts.shape}")
    return _run_varying(est, state, us, ys, dts)


@jax.jit
def _run_fixed(est, state, us, ys, dt):
    disc = est.discretize(dt)

    def body(s, inp):
        u, y = inp
        return est.step_discrete(s, u, y, disc)

    return jax.lax.scan(body, state, (us, ys))


@jax.jit
def _run_varying(est, state, us, ys, dts):
    def body(s, inp):
        u, y, dt = inp
        return est.step(s, u, y, dt)

    return jax.lax.scan(body, state, (us, ys, dts))
