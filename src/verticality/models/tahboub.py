"""Tahboub's single-segment linear otolith–canal model (T §II.A, eq. 1–8, 20–22).

States ``x_v = (φ, ω, ω_drift)``: head (trunk) orientation in space [rad], its angular velocity
[rad/s] and the canal (gyro) drift [rad/s]. Measurements, in this order (docs/reproduction.md):
``y_v = (ω_g, a_xa)`` — gyro / canal angular velocity (T eq. 1) and tangential otolith /
accelerometer reading (T eq. 5, ``a_xa = g φ + v_a``; the body's own angular acceleration term of
T eq. 4 is left to the measurement noise, as the paper does).

    F_v = [[0, 1, 0], [0, 0, 0], [0, 0, 0]]           (T eq. 7)
    H_v = [[0, 1, 1], [g, 0, 0]]                       (T eq. 8, rows ordered as y_v)
    Q = diag(0, δ_ω, δ_drift),  R = diag(δ_c, δ_a)     (T eq. 12–13; published values eq. 20–21)

Q and R are intensities of continuous white noise (the reading under which T eq. 10 holds). The
published steady-state gain (T eq. 22) is kept beside the model it was computed for, so that the
estimator, the experiments and the report compare with one value.
"""

from __future__ import annotations

import numpy as np

from verticality.core.constants import G_M_S2

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
