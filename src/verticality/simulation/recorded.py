"""A recorded trunk motion (a MOTION.csv) as a
:class:`verticality.simulation.trajectories.Trajectory`, so the closed-loop simulator can put the
gimbal head on a trunk that moved the way the user's robot did.

The simulator needs the trunk's R_I_T, ω_T, ω̇_T and the centre's acceleration a_I at any time, and
derives them by forward-mode autodiff from a position and an Euler-angle function. From the
samples (t_k, q_k, ω_k, a_k):

- **Orientation**: (roll, pitch, yaw) of each q_k (R = Rz(yaw) Ry(pitch) Rx(roll)), roll and yaw
  unwrapped, and their rates from ω_k (ω = E(rpy)·d(rpy)/dt inverted). Between samples a cubic
  Hermite interpolant: R and ω are continuous and equal the file's at every sample, ω̇ is linear
  within an interval (it may jump at a sample).
- **Acceleration**: linear between samples (a_k exactly at every sample); the position is its exact
  double integral, starting at rest at the origin. Only its second derivative enters the physics
  (the position is relative and only for display).

Refused with :class:`verticality.core.errors.InputError`: fewer than two rows, and a trunk pitch
within ``PITCH_LIMIT_DEG`` of ±90° (the Euler angles are singular there). Times are shifted so the
trajectory starts at t = 0 (``events["t0_s"]`` keeps the file's first time).
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np

from verticality.core import so3
from verticality.core.errors import InputError
from verticality.simulation.trajectories import Trajectory

PITCH_LIMIT_DEG = 85.0


def rpy_rates(rpy_rad: np.ndarray, omega_B_rad_s: np.ndarray) -> np.ndarray:
    """d(roll, pitch, yaw)/dt from the body-frame ω, row by row (inverse of
    :func:`verticality.simulation.trajectories.omega_from_rpy_rates`; |pitch| < 90°)."""
    phi, theta = rpy_rad[:, 0], rpy_rad[:, 1]
    sf, cf = np.sin(phi), np.cos(phi)
    tt, ct = np.tan(theta), np.cos(theta)
    wx, wy, wz = omega_B_rad_s[:, 0], omega_B_rad_s[:, 1], omega_B_rad_s[:, 2]
    dpsi = (sf * wy + cf * wz) / ct
    return np.stack([wx + tt * (sf * wy + cf * wz), cf * wy - sf * wz, dpsi], axis=1)


RATE_MISMATCH_WINDOW_S = 0.2
RATE_MISMATCH_WARN_RAD = 0.1
"""Over any 0.2 s, the rotation of q and the integral of ω may disagree by this much before a
warning (gyro bias of 0.01 rad/s adds 0.002 rad, optical noise of 0.2° about 0.007 rad)."""


def rate_mismatch(t_s, q_wxyz, omega_rad_s, window_s: float = RATE_MISMATCH_WINDOW_S):
    """How far the file's ω disagrees with its own q: per interval, e_k = log(q_k⁻¹ q_k+1) −
    (ω_k + ω_k+1)/2·Δt_k (body frame, both to second order in Δt), summed over windows of
    ``window_s``. Returns (largest |Σ e| in rad, the time its window starts)."""
    t = np.asarray(t_s, float)
    q = jnp.asarray(q_wxyz, jnp.float64)
    dq = so3.quat_multiply(so3.quat_conjugate(q[:-1]), q[1:])
    w = np.asarray(omega_rad_s, float)
    e = np.asarray(so3.quat_log(dq)) - 0.5 * (w[:-1] + w[1:]) * np.diff(t)[:, None]
    m = max(1, int(round(window_s / max(float(np.median(np.diff(t))), 1e-12))))
    c = np.concatenate([np.zeros((1, 3)), np.cumsum(e, axis=0)])
    m = min(m, e.shape[0])
    mag = np.linalg.norm(c[m:] - c[:-m], axis=1)
    k = int(np.argmax(mag))
    return float(mag[k]), float(t[k])


def _interval(t_knots, t):
    """Index k of the interval [t_k, t_k+1] holding t (clamped to the first and last) and
    t − t_k."""
    k = jnp.clip(jnp.searchsorted(t_knots, t, side="right") - 1, 0, t_knots.shape[0] - 2)
    return k, t - t_knots[k]


def _hermite(t_knots, y, dy):
    """C¹ cubic Hermite interpolant of values ``y`` (N, d) with slopes ``dy`` (N, d)."""
    t_knots, y, dy = (jnp.asarray(a, jnp.float64) for a in (t_knots, y, dy))

    def f(t):
        k, tau = _interval(t_knots, t)
        h = t_knots[k + 1] - t_knots[k]
        s = tau / h
        h00, h10 = 2 * s**3 - 3 * s**2 + 1, s**3 - 2 * s**2 + s
        h01, h11 = -2 * s**3 + 3 * s**2, s**3 - s**2
        return h00 * y[k] + h10 * h * dy[k] + h01 * y[k + 1] + h11 * h * dy[k + 1]

    return f


def _position_of_linear_acceleration(t_knots, a):
    """Position whose second derivative is the piecewise-linear interpolant of ``a`` (N, 3),
    starting at rest at the origin (exact double integral, knot values by cumulative sums)."""
    t_knots = np.asarray(t_knots, float)
    a = np.asarray(a, float)
    h = np.diff(t_knots)[:, None]
    v = np.concatenate([np.zeros((1, 3)), np.cumsum(h * (a[:-1] + a[1:]) / 2.0, axis=0)])
    dp = h * v[:-1] + h**2 * (2.0 * a[:-1] + a[1:]) / 6.0
    p = np.concatenate([np.zeros((1, 3)), np.cumsum(dp, axis=0)])
    t_j, a_j, v_j, p_j = (jnp.asarray(x, jnp.float64) for x in (t_knots, a, v, p))

    def position(t):
        k, tau = _interval(t_j, t)
        h_k = t_j[k + 1] - t_j[k]
        jerk = (a_j[k + 1] - a_j[k]) / h_k
        return p_j[k] + v_j[k] * tau + a_j[k] * tau**2 / 2.0 + jerk * tau**3 / 6.0

    return position


def record_of(traj: Trajectory, t_s):
    """The rows of a MOTION.csv (:class:`verticality.io.motion.MotionRecord`) of ``traj`` at the
    times ``t_s``: the inverse of :func:`from_record` at the samples."""
    from verticality.io.motion import MotionRecord
    from verticality.simulation.trajectories import sample

    t = np.asarray(t_s, float)
    m = sample(traj, t)
    q = np.asarray(so3.quat_from_matrix(m.R_I_B))
    return MotionRecord(t, q, np.asarray(m.omega_B_rad_s), np.asarray(m.a_I_m_s2))


DEFAULT_RATE_HZ = 1000.0
"""Rows per second of a built-in trajectory written as a MOTION.csv (`verticality motion`)."""


def built_in_motion(name: str, rate_hz: float | None = None, start_s: float = 0.0,
                    duration_s: float | None = None):
    """The MOTION.csv rows of the built-in trajectory ``name`` (the head rigid on the trunk) from
    ``start_s`` for ``duration_s`` seconds (to its end by default) at ``rate_hz`` (default
    :data:`DEFAULT_RATE_HZ`), and a description of them. Bad settings raise :class:`InputError`."""
    from verticality.simulation.trajectories import BY_NAME

    for option, value in (("duration", duration_s), ("rate", rate_hz)):
        if value is not None and not (math.isfinite(value) and value > 0):
            raise InputError(f"--{option} must be a positive number, not {value}")
    if not start_s >= 0.0:
        raise InputError(f"--start must be a non-negative number, not {start_s}")
    if name not in BY_NAME:
        raise InputError(f"unknown trajectory {name!r}; choose from {', '.join(sorted(BY_NAME))}")
    traj = BY_NAME[name]()
    rate = DEFAULT_RATE_HZ if rate_hz is None else rate_hz
    duration = (traj.duration_s - start_s) if duration_s is None else duration_s
    if not duration > 0:
        raise InputError(f"--start {start_s:g} is at or after the end of `{name}` "
                         f"({traj.duration_s:g} s)")
    from verticality.core.sizing import check_work_size

    check_work_size(duration * rate + 1, 11 * 8 * 4, f"rows ({duration:g} s at {rate:g} Hz)",
                    "lower --rate or --duration")
    n = int(round(duration * rate)) + 1
    rec = record_of(traj, start_s + np.arange(n) / rate)
    return rec, f"`{name}` ({duration:g} s from {start_s:g} s at {rate:g} Hz)"


def from_record(t_s, q_I_T_wxyz, omega_T_rad_s, a_I_m_s2, name: str = "recorded") -> Trajectory:
    """The trunk trajectory through the samples (see the module docstring)."""
    t = np.asarray(t_s, float)
    q = np.asarray(q_I_T_wxyz, float)
    w = np.asarray(omega_T_rad_s, float)
    a = np.asarray(a_I_m_s2, float)
    n = t.shape[0]
    if n < 2:
        raise InputError(f"a recorded motion needs at least two rows, got {n}")
    if q.shape != (n, 4) or w.shape != (n, 3) or a.shape != (n, 3):
        raise InputError(f"shapes disagree: t {t.shape}, q {q.shape}, ω {w.shape}, a {a.shape}")
    if not np.all(np.diff(t) > 0.0):
        raise InputError("the times must increase strictly")
    rpy = np.array(jax.vmap(lambda qi: so3.rpy_from_matrix(so3.matrix_from_quat(qi)))(
        jnp.asarray(q)))
    pitch_deg = np.degrees(np.abs(rpy[:, 1]))
    bad = np.nonzero(pitch_deg > PITCH_LIMIT_DEG)[0]
    if bad.size:
        raise InputError(f"row {bad[0] + 1}: the trunk pitches to {pitch_deg[bad[0]]:.1f}°, beyond "
                         f"±{PITCH_LIMIT_DEG:g}° "
                         "(the Euler-angle interpolation is singular at 90°)")
    rpy[:, 0] = np.unwrap(rpy[:, 0])
    rpy[:, 2] = np.unwrap(rpy[:, 2])
    t0 = float(t[0])
    t_rel = t - t0
    rpy_fn = _hermite(t_rel, rpy, rpy_rates(rpy, w))
    position_fn = _position_of_linear_acceleration(t_rel, a)
    duration = float(t_rel[-1])
    if not math.isfinite(duration) or duration <= 0.0:
        raise InputError(f"the recording spans {duration!r} s")
    return Trajectory(position_fn, rpy_fn, duration, name, events={"t0_s": t0})
