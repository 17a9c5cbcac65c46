"""Tahboub's stand-alone otolith–canal Kalman filter (T §II.A, eq. 1–13, 20–22).

States ``x_v = (φ, ω, ω_drift)``: head (trunk) orientation in space [rad], its angular velocity
[rad/s] and the canal (gyro) drift [rad/s]. Measurements, in this order (docs/reproduction.md):
``y_v = (ω_g, a_xa)`` — gyro / canal angular velocity (T eq. 1) and tangential otolith /
accelerometer reading (T eq. 5, ``a_xa = g φ + v_a``; the body's own angular acceleration term of
T eq. 4 is left to the measurement noise, as the paper does).

    F_v = [[0, 1, 0], [0, 0, 0], [0, 0, 0]]           (T eq. 7)
    H_v = [[0, 1, 1], [g, 0, 0]]                       (T eq. 8, rows ordered as y_v)
    Q = diag(0, δ_ω, δ_drift),  R = diag(δ_c, δ_a)     (T eq. 12–13; published values eq. 20–21)

Three forms share these matrices (estimators of :mod:`verticality.estimators.kalman`):

* :func:`steady_state_filter` — T eq. 9: the continuous filter with the static gain of the CARE
  (T eq. 10–11; for eq. 20–21 it reproduces eq. 22), discretized exactly per sample;
* :func:`time_varying_filter` — the discrete Kalman filter with covariance propagation (Van Loan Q,
  measurement covariance R/dt);
* :func:`discrete_steady_state_filter` — that filter's converged gain (DARE) at one sample time,
  identical to the time-varying filter after convergence; as dt → 0 its gain tends to ``L_KF dt``.

Q and R are intensities of continuous white noise (the reading under which T eq. 10 holds).
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

STATE_NAMES = ("phi_rad", "omega_rad_s", "omega_drift_rad_s")
MEASUREMENT_NAMES = ("omega_g_rad_s", "a_xa_m_s2")

TAHBOUB_Q = np.diag([0.0, 1e-1, 1e-6])  # T eq. 20
TAHBOUB_R = np.diag([1e-5, 10.0])  # T eq. 21, order (omega_g, a_xa)
TAHBOUB_GAIN_PUBLISHED = np.array(  # T eq. 22
    [[9.9e-1, 8.0e-3], [9.9e1, 3.2e-4], [1.0e-3, -3.1e-4]]
)


def matrices(g_m_s2: float = G_M_S2):
    """``(F_v, H_v)`` of T eq. 7–8 (H rows in the order ``(ω_g, a_xa)``)."""
    F = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    H = np.array([[0.0, 1.0, 1.0], [g_m_s2, 0.0, 0.0]])
    return F, H


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
