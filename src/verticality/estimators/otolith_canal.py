"""Tahboub's stand-alone otolith–canal Kalman filter (T §II.A, eq. 1–13, 20–22).

The model — states ``(φ, ω, ω_drift)``, measurements ``(ω_g, a_xa)``, F_v, H_v of T eq. 7–8, Q and
R of T eq. 20–21 and the published gain of eq. 22 — is :mod:`verticality.models.tahboub`.

Three forms share these matrices (estimators of :mod:`verticality.estimators.kalman`):

* :func:`steady_state_filter` — T eq. 9: the continuous filter with the static gain of the CARE
  (T eq. 10–11; for eq. 20–21 it reproduces eq. 22), discretized exactly per sample;
* :func:`time_varying_filter` — the discrete Kalman filter with covariance propagation (Van Loan Q,
  measurement covariance R/dt);
* :func:`discrete_steady_state_filter` — that filter's converged gain (DARE) at one sample time,
  identical to the time-varying filter after convergence; as dt → 0 its gain tends to ``L_KF dt``.
"""

from __future__ import annotations

import numpy as np

from verticality.core.constants import G_M_S2
from verticality.estimators.kalman import (
    ContinuousObserver,
    KalmanFilter,
    SteadyStateKalmanFilter,
    continuous_observer,
    continuous_steady_gain,
    kalman_filter,
    steady_state_kalman_filter,
)
from verticality.models.tahboub import TAHBOUB_Q, TAHBOUB_R, matrices


def steady_state_gain(Q=TAHBOUB_Q, R=TAHBOUB_R, g_m_s2: float = G_M_S2) -> np.ndarray:
    """Static Kalman gain ``L_KF`` (3×2) of T eq. 10–11; T eq. 22 for the default Q, R."""
    F, H = matrices(g_m_s2)
    L, _ = continuous_steady_gain(F, H, Q, R)
    return L


def steady_state_filter(Q=TAHBOUB_Q, R=TAHBOUB_R, g_m_s2: float = G_M_S2) -> ContinuousObserver:
    """T eq. 9 with the static gain: ``x̂' = F x̂ + L (y − H x̂)``; input u is unused (1-D zero)."""
    F, H = matrices(g_m_s2)
    return continuous_observer(F, np.zeros((3, 1)), H, None, steady_state_gain(Q, R, g_m_s2))


def time_varying_filter(Q=TAHBOUB_Q, R=TAHBOUB_R, g_m_s2: float = G_M_S2) -> KalmanFilter:
    """The same plant as a time-varying discrete Kalman filter (covariance propagated)."""
    F, H = matrices(g_m_s2)
    return kalman_filter(F, np.zeros((3, 1)), H, None, Q, R)


def discrete_steady_state_filter(dt_s: float, Q=TAHBOUB_Q, R=TAHBOUB_R,
                                 g_m_s2: float = G_M_S2) -> SteadyStateKalmanFilter:
    """The sampled filter with its steady-state (DARE) gain for sample time ``dt_s``."""
    F, H = matrices(g_m_s2)
    return steady_state_kalman_filter(F, np.zeros((3, 1)), H, None, Q, R, dt_s)
