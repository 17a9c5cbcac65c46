"""Synthetic IMU recordings with known truth, shared by the tilt-filter tests."""

import numpy as np

from verticality.core import so3
from verticality.tilt.evaluation.faults import fast_roll  # noqa: F401  (shared)

G = 9.81


def up_S(R_E_S):
    """The unit "up" in the sensor frame: the third row of R_E_S."""
    return np.asarray(R_E_S)[..., 2, :]


def tumbling(bias, n, dt=0.01, rate=0.4, seed=1):
    """Constant rotation about the sensor x axis, which starts 25° off the vertical plane, with a
    gyro ``bias`` and white noise: ``(gyr (n, 3), acc (n, 3), true up_S (n, 3))``."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * dt
    R0 = np.asarray(so3.rot_y(np.radians(25.0)))
    R = np.einsum("ij,njk->nik", R0, np.asarray(so3.exp(np.outer(t, [rate, 0.0, 0.0]))))
    acc = G * up_S(R) + rng.normal(0, 0.02, (n, 3))
    gyr = np.array([rate, 0.0, 0.0]) + bias + rng.normal(0, 1e-3, (n, 3))
    return gyr, acc, up_S(R)
