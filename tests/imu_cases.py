"""Synthetic IMU recordings with known truth, shared by the tilt-filter tests."""

import numpy as np

from verticality import so3

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


def fast_roll(n=2000, dt=0.01, peak=12.0, width_s=0.1, centers_s=(5.0, 10.0, 15.0), seed=3):
    """A level sensor turned about its x axis (horizontal at the start) by pulses of rate
    ``peak`` (rad/s, Gaussian in time of standard deviation ``width_s``, alternating in sign,
    centred at ``centers_s``), still in between: ``(gyr (n, 3), acc (n, 3), true up_S (n, 3))``
    with white noise on both sensors (the true rate and specific force, before any clipping).
    Gyro sample k is the mean rate over its interval (t_{k−1}, t_k], as the filter integrates it
    (an integrating gyro), so that the discretization of the simulated rate adds no error."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * dt
    angle = np.zeros(n)
    from math import erf, sqrt

    for j, c in enumerate(centers_s):
        s = peak * (-1) ** j
        angle += s * width_s * sqrt(np.pi / 2) * (1 + np.vectorize(erf)((t - c) / (width_s * sqrt(2))))
    R = np.asarray(so3.exp(np.outer(angle, [1.0, 0.0, 0.0])))
    acc = G * up_S(R) + rng.normal(0, 0.02, (n, 3))
    mean_rate = np.diff(angle, prepend=angle[0]) / dt
    gyr = np.column_stack([mean_rate, np.zeros(n), np.zeros(n)]) + rng.normal(0, 1e-3, (n, 3))
    return gyr, acc, up_S(R)
