"""3-D otolith–canal tilt filter for recorded IMU data (gyroscope = canals, accelerometer = otoliths).

Tahboub's stand-alone filter (T eq. 1–13) fuses, in one plane, a gyro reading
``ω_g = ω + ω_drift + v_c`` (T eq. 1) whose drift is a random walk ``ω̇_drift = v_drift`` (T eq. 2)
with an accelerometer read as a noisy inclinometer ``a_xa = g φ + v_a`` (T eq. 5): the inertial
part of the specific force (T eq. 4) "is handled as a high-frequency noise". This module is its
3-D generalization as an error-state extended Kalman filter:

* nominal state: the orientation quaternion ``q_E_S`` (sensor → Earth, z up; its heading is
  carried along but unobservable and irrelevant), the gyro bias ``b_S`` (rad/s, T eq. 2 drift) and
  the horizontal velocity ``v_E`` (m/s) obtained by integrating the specific force rotated to Earth;
* error state (7): tilt error ``δ = (δx, δy)`` about Earth's horizontal axes
  (``R_true = exp([δ, 0]) R_est``), velocity error ``ṽ`` (2), bias error ``b̃ = b_true − b̂`` (3);
* prediction: strapdown ``q ← q ⊗ exp((ω_g − b̂) Δt)`` with the true Δt of every sample;
  ``δ̇ = −Π R b̃`` (3-D T eq. 7 with the drift subtracted), ``ṽ̇ = g J δ`` (a tilt error leaks gravity
  into the integrated velocity), bias random walk (T eq. 2, 12);
* gravito-inertial ambiguity (T §I: the otolith cannot tell tilt from translation): T eq. 4–5 treat
  the inertial part as high-frequency noise because body accelerations "tend to be periodic and for
  short time". Taken as a model: the velocity they produce stays small, pseudo-measurement
  ``0 = v + n_v`` (``n_v`` ≈ 0 at rest). This observes the tilt through ``ṽ̇ = g J δ`` and rejects
  translations with second-order attenuation; Joseph-form updates;
* rest (T eq. 1 with ω = 0): when gyro and accelerometer are quiet for 1.5 s the gyro measures the
  bias directly;
* pre-integration: the gyro rotation and the specific force (in the block-start frame) are summed
  sample by sample; the Kalman prediction and updates run every ``block`` samples. All noises are
  spectral densities (``q = S Δt``, ``r = S / T``), so one parameter set serves every sampling rate.

API (one estimator API for the project)::

    state = init(x0, P0)                      # x0 = (q_E_S wxyz, b_S) ; P0 (7, 7)
    state, out = step(state, u, y, dt)        # u = gyr (3,) rad/s, y = acc (3,) m/s²
    state, outs = scan(state, us, ys, dts)    # the same step under jax.lax.scan
    out = run(gyr_rad_s, acc_m_s2, dt_s)      # arrays (N, 3); dt_s scalar or (N,)

``out`` is a :class:`TiltOutput` (roll, pitch, gravity direction, quaternion, bias, covariance,
flags). A NaN in ``y`` means "no accelerometer": predict only (flag ``ACC_MISSING``); a NaN gyro
sample propagates the covariance with ``omega_missing_rad_s`` as the unknown rate (flag
``GYR_MISSING``); a non-finite or non-positive Δt skips the sample (flag ``BAD_DT``). A Δt above
``gap_flag_s`` (a gap in the recording) is used as it is, the sample's rate integrated over the
whole gap, and the sample is flagged ``DT_GAP``: motion inside the gap that this rate does not
describe is not seen. The gap then counts as a gyro dropout, and after ``reacquire_s`` the tilt is
re-acquired from the mean specific force (flag ``REACQUIRED``; the samples in between are flagged
``REACQUIRING``; docs/tilt.md). The initialization from the accelerometer is treated the same
way (the first sample may hold an inertial acceleration): wide tilt variance (``init_tilt_rad``),
re-acquired after ``reacquire_s``. Nothing turns a finite estimate into NaN.
"""

from __future__ import annotations

from functools import partial
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from verticality.estimators import tilt_kernels

G_M_S2 = 9.81

# Flag bits of TiltOutput.flags
ACC_MISSING = 1  # accelerometer sample non-finite: predict only
GYR_MISSING = 2  # gyroscope sample non-finite: orientation held, covariance inflated
BAD_DT = 4  # Δt non-finite or <= 0: sample skipped entirely
ACC_DISTURBED = 8  # inertial acceleration estimate large: accelerometer strongly down-weighted
INIT = 16  # the sample that initialized the filter from the accelerometer
DT_GAP = 32  # Δt above gap_flag_s: a gap in the recording (motion inside it is not seen)
REACQUIRED = 64  # the tilt was re-acquired from the accelerometer after a gap or the start
REACQUIRING = 128  # from a gap (or the start) to its re-acquisition: the estimate may be off
FLAG_NAMES = {ACC_MISSING: "accelerometer missing", GYR_MISSING: "gyro missing",
              BAD_DT: "bad time step", ACC_DISTURBED: "accelerometer disturbed",
              INIT: "initialization", DT_GAP: "gap in the time stamps",
              REACQUIRED: "tilt re-acquired", REACQUIRING: "re-acquiring"}


class TiltParams(NamedTuple):
    """One parameter set for all recordings (physically motivated; see docs/tilt.md).

    Spectral densities, so that the filter behaves the same at any sampling rate:
    ``gyr_noise`` gyro white noise (rad/s/√Hz, T's δ_c); ``bias_walk`` gyro bias random walk
    (rad/s/√s, T's δ_drift, eq. 2); ``acc_noise`` accelerometer white noise entering the integrated
    velocity (m/s²/√Hz, T's δ_a). Velocity prior: ``vel_m_s`` typical speed of the motion with
    correlation time ``vel_corr_s``; ``vel_rest_m_s`` at rest. ``acc_missing_m_s2``: unknown
    acceleration assumed while the accelerometer drops out; ``acc_tau_s``: low-pass of ``(|f|−g)²``
    used for the ACC_DISTURBED flag. ``omega_missing_rad_s``: unknown rate assumed while the gyro
    drops out. ``gap_flag_s``: a step Δt above it is a gap in the recording (flag ``DT_GAP``):
    the rotation inside it is unknown (``omega_missing_rad_s`` over the gap); after it the filter
    averages the specific force for ``reacquire_s`` and re-acquires the tilt from that mean
    (flag ``REACQUIRED``). ``init_tilt_rad``: when the accelerometer initializes the filter (no
    ``x0``), the tilt standard deviation added for that sample's unknown inertial acceleration;
    the tilt is then re-acquired after ``reacquire_s`` as after a gap, so a start in motion is
    caught (flag ``REACQUIRING`` until then).
    ``acc_calib_m_s2``: the accelerometer's calibration error (bias, scale, misalignment), which
    gravity alone cannot reveal; it does not change the estimate, only the reported uncertainty
    (:func:`tilt_sigma_rad`).
    ``acc_disturbed_m_s2``: flag threshold on the disturbance estimate. ``gyr_scale_noise`` (√s):
    gyro errors that grow with the rate (scale factor, axis misalignment), process noise density
    ``(k |ω|)²``. Rest (T eq. 1 with ω = 0, so the canal signal is the drift): when for
    ``rest_min_s`` every block has gyro deviation below ``rest_gyr_rad_s`` and accelerometer
    deviation below ``rest_acc_m_s2``, the block-mean gyro measures the bias, with the residual
    motion ``rest_motion_rad_s`` as extra noise.
    """

    gyr_noise: float = 1e-3
    bias_walk: float = 1e-4
    acc_noise: float = 0.05
    vel_m_s: float = 0.5
    vel_corr_s: float = 1.0
    vel_rest_m_s: float = 0.01
    acc_missing_m_s2: float = 5.0
    acc_tau_s: float = 0.5
    gyr_scale_noise: float = 0.005
    rest_gyr_rad_s: float = 0.035
    rest_acc_m_s2: float = 0.5
    rest_min_s: float = 1.5
    rest_motion_rad_s: float = 0.002
    omega_missing_rad_s: float = 1.0
    acc_disturbed_m_s2: float = 1.0
    g_m_s2: float = G_M_S2
    gap_flag_s: float = 0.1
    reacquire_s: float = 1.0
    init_tilt_rad: float = 1.0
    acc_calib_m_s2: float = 0.05


DEFAULT_PARAMS = TiltParams()
DEFAULT_P0 = np.diag([0.05**2, 0.05**2, 0.1**2, 0.1**2, 0.01**2, 0.01**2, 0.01**2])
BLOCK = 32  # samples per Kalman update (the canal signal is integrated in between)


class TiltState(NamedTuple):
    """Filter state. ``quat_E_S``, ``bias_S_rad_s`` and ``P`` hold at the start of the current
    block; the ``blk_*`` fields accumulate the samples of the block (pre-integration)."""

    quat_E_S: jax.Array  # (4,) wxyz at the block start
    bias_S_rad_s: jax.Array  # (3,)
    vel_E_m_s: jax.Array  # (2,) horizontal velocity in Earth (m/s), kept bounded
    P: jax.Array  # (7, 7) covariance of (δx, δy, ṽx, ṽy, b̃x, b̃y, b̃z)
    acc_dev_var: jax.Array  # () low-passed (|f| - g)² (m²/s⁴)
    initialized: jax.Array  # () bool
    blk_dquat: jax.Array  # (4,) raw gyro rotation since the block start
    blk_tau: jax.Array  # () s integrated by a valid gyro in this block
    blk_f: jax.Array  # (3,) Σ f (block-start sensor frame) Δt over valid accelerometer samples
    blk_t_acc: jax.Array  # () Σ Δt over valid accelerometer samples
    blk_dev2: jax.Array  # () Σ (|f| - g)² Δt
    blk_w2: jax.Array  # () Σ |ω|² Δt
    blk_t: jax.Array  # () Σ Δt (valid Δt)
    blk_qmiss: jax.Array  # () Σ (ω_missing Δt)² over gyro dropouts
    blk_gsum: jax.Array  # (3,) Σ gyr Δt over valid gyro samples
    blk_asum: jax.Array  # (3,) Σ f Δt (sensor frame) over valid accelerometer samples
    blk_a2: jax.Array  # () Σ |f|² Δt over valid accelerometer samples
    rest_s: jax.Array  # () time at rest so far (s)
    reacquire: jax.Array  # () bool: after a gap, averaging the specific force to re-acquire
    reacq_f_E: jax.Array  # (3,) Σ R f Δt (Earth, as estimated) since the gap
    reacq_t: jax.Array  # () Σ Δt of the accelerometer samples in reacq_f_E
    blk_gap: jax.Array  # () number of gap samples (Δt > gap_flag_s) in this block
    blk_count: jax.Array  # () int samples in the block


class TiltOutput(NamedTuple):
    roll_rad: jax.Array
    pitch_rad: jax.Array
    up_S: jax.Array  # (3,) unit vector "up" (opposite to gravity) in the sensor frame
    quat_E_S: jax.Array  # (4,) wxyz, heading arbitrary
    bias_S_rad_s: jax.Array  # (3,)
    var: jax.Array  # (7,) variances of (δx, δy [rad²], ṽx, ṽy [m²/s²], b̃x, b̃y, b̃z [rad²/s²])
    flags: jax.Array  # int32 bit set


def tilt_sigma_rad(var, params: TiltParams = DEFAULT_PARAMS) -> np.ndarray:
    """Standard deviation of the tilt (rad) from a :class:`TiltOutput`'s ``var`` ((..., 7)): the
    RMS angle between the true and the estimated vertical, ``sqrt(var_δx + var_δy + (c/g)²)``.
    The first two terms are the filter's covariance of its tilt error (frame-free: the trace does
    not depend on the heading); ``c = params.acc_calib_m_s2`` adds the accelerometer's calibration
    error, a systematic error that the filter cannot average out and that sets the error at rest
    (docs/tilt.md, "The uncertainty")."""
    v = np.asarray(var, dtype=np.float64)
    return np.sqrt(v[..., 0] + v[..., 1] + (params.acc_calib_m_s2 / params.g_m_s2) ** 2)


# --- small quaternion helpers, written out so that XLA fuses them (batched over leading axes) ---

def _qmul(p, q):
    pw, px, py, pz = p[..., 0], p[..., 1], p[..., 2], p[..., 3]
    qw, qx, qy, qz = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return jnp.stack([pw * qw - px * qx - py * qy - pz * qz,
                      pw * qx + px * qw + py * qz - pz * qy,
                      pw * qy - px * qz + py * qw + pz * qx,
                      pw * qz + px * qy - py * qx + pz * qw], axis=-1)


def _qexp(v):
    """Quaternion of the rotation vector v (rad), batched; smooth near 0."""
    th2 = jnp.sum(v * v, axis=-1)
    small = th2 < 1e-12
    th = jnp.sqrt(jnp.where(small, 1.0, th2))
    k = jnp.where(small, 0.5 - th2 / 48.0, jnp.sin(0.5 * th) / th)
    c = jnp.where(small, 1.0 - th2 / 8.0, jnp.cos(0.5 * th))
    return jnp.concatenate([c[..., None], k[..., None] * v], axis=-1)


def _qnormalize(q):
    return q / jnp.sqrt(jnp.sum(q * q, axis=-1, keepdims=True))


def _qrotate(q, v):
    """R(q) v for unit q, batched."""
    w = q[..., :1]
    u = q[..., 1:]
    t = 2.0 * jnp.cross(u, v)
    return v + w * t + jnp.cross(u, t)


_rotmat = tilt_kernels.rotmat


def quat_from_acc(acc_m_s2):
    """Quaternion ``q_E_S`` with zero heading whose up axis matches the accelerometer direction
    (the minimal rotation taking the measured specific-force direction to e3)."""
    a = jnp.asarray(acc_m_s2, dtype=jnp.float64)
    n = jnp.linalg.norm(a)
    u = jnp.where(n > 0, a / jnp.where(n > 0, n, 1.0), jnp.array([0.0, 0.0, 1.0]))
    w = 1.0 + u[2]
    v = jnp.stack([u[1], -u[0], 0.0])
    flip = w < 1e-9  # upside down: rotate by pi about x
    q = jnp.where(flip, jnp.array([0.0, 1.0, 0.0, 0.0]), jnp.concatenate([w[None], v]))
    return q / jnp.linalg.norm(q)


def _quat_from_acc_np(a):
    """NumPy twin of :func:`quat_from_acc` (host side of :func:`run`)."""
    a = np.asarray(a, dtype=np.float64)
    n = np.sqrt(a @ a)
    u = a / n if n > 0 else np.array([0.0, 0.0, 1.0])
    w = 1.0 + u[2]
    q = np.array([0.0, 1.0, 0.0, 0.0]) if w < 1e-9 else np.array([w, u[1], -u[0], 0.0])
    return q / np.sqrt(q @ q)


_DEFAULT_INIT = []


def _default_init() -> TiltState:
    """``init()`` as NumPy arrays, built once (the states are immutable)."""
    if not _DEFAULT_INIT:
        _DEFAULT_INIT.append(jax.tree_util.tree_map(np.asarray, init()))
    return _DEFAULT_INIT[0]


def _zero_block():
    z = jnp.array(0.0)
    return dict(blk_dquat=jnp.array([1.0, 0.0, 0.0, 0.0]), blk_tau=z, blk_f=jnp.zeros(3),
                blk_t_acc=z, blk_dev2=z, blk_w2=z, blk_t=z, blk_qmiss=z, blk_gsum=jnp.zeros(3),
                blk_asum=jnp.zeros(3), blk_a2=z, blk_gap=z,
                blk_count=jnp.array(0, dtype=jnp.int32))


def init(x0=None, P0=None) -> TiltState:
    """Initial state. ``x0 = (quat_E_S wxyz, bias_S rad/s)``, or None: then the first finite
    accelerometer sample initializes the tilt (heading 0, zero bias, flag ``INIT``)."""
    P0 = jnp.asarray(DEFAULT_P0 if P0 is None else P0, dtype=jnp.float64)
    if P0.shape != (7, 7):
        raise ValueError(f"P0 must be (7, 7) for (δx, δy, ṽx, ṽy, b̃x, b̃y, b̃z); got {P0.shape}")
    if x0 is None:
        q0, b0, initialized = jnp.array([1.0, 0.0, 0.0, 0.0]), jnp.zeros(3), jnp.array(False)
    else:
        q0 = _qnormalize(jnp.asarray(x0[0], dtype=jnp.float64))
        b0 = jnp.asarray(x0[1], dtype=jnp.float64)
        initialized = jnp.array(True)
    return TiltState(q0, b0, jnp.zeros(2), P0, jnp.array(0.0), initialized, rest_s=jnp.array(0.0),
                     reacquire=jnp.array(False), reacq_f_E=jnp.zeros(3), reacq_t=jnp.array(0.0),
                     **_zero_block())


_sample_masks = tilt_kernels.masks


def _kf_update(P, H, z, r):
    """Kalman update of the error state for a linear measurement ``z = H x + n``, ``n ~ N(0, r I)``
    (2 or 3 rows); Joseph form, symmetrized. Returns (dx, P)."""
    m = H.shape[0]
    PHt = P @ H.T
    S = H @ PHt + r * jnp.eye(m)
    if m == 2:
        det = S[0, 0] * S[1, 1] - S[0, 1] * S[1, 0]
        S_inv = jnp.stack([jnp.stack([S[1, 1], -S[0, 1]]), jnp.stack([-S[1, 0], S[0, 0]])]) / det
    else:
        S_inv = _inv3(S)
    K = PHt @ S_inv
    IKH = jnp.eye(P.shape[0]) - K @ H
    P = IKH @ P @ IKH.T + r * (K @ K.T)
    return K @ z, 0.5 * (P + P.T)


_J = np.array([[0.0, 1.0], [-1.0, 0.0]])  # (δ × e3)_{x,y} = J δ
_H_VEL = np.hstack([np.zeros((2, 2)), np.eye(2), np.zeros((2, 3))])
_H_BIAS = np.hstack([np.zeros((3, 4)), np.eye(3)])
_H_TILT = np.hstack([np.eye(2), np.zeros((2, 5))])

tilt_error_from_force = tilt_kernels.tilt_error_from_force
reset_velocity = tilt_kernels.reset_velocity
widen_tilt = tilt_kernels.widen_tilt


def _block_update(state: TiltState, params: TiltParams):
    """Kalman prediction over the block and the otolith updates (T eq. 7–13 in 3-D).
    Returns (new state with empty block, disturbed flag, re-acquired flag)."""
    p = params
    g = p.g_m_s2
    b = state.bias_S_rad_s
    q0 = state.quat_E_S
    q_end = _qnormalize(_qmul(_qmul(q0, state.blk_dquat), _qexp(-b * state.blk_tau)))
    R = _rotmat(q_end)
    T = state.blk_t
    t_acc = state.blk_t_acc
    has_acc = t_acc > 0
    t_acc_s = jnp.where(has_acc, t_acc, 1.0)

    # velocity prediction with the measured specific force rotated to Earth (block-start frame)
    f_E_sum = _qrotate(q0, state.blk_f)  # Σ R f Δt
    vel = state.vel_E_m_s + f_E_sum[:2]

    # error-state prediction: δ̇ = −Π R b̃ ; ṽ̇ = g J δ ; ḃ = w_drift (T eq. 2, 7, 12)
    A = -T * R[:2, :]
    gJ = g * _J
    F = jnp.eye(7)
    F = F.at[:2, 4:].set(A)
    F = F.at[2:4, :2].set(T * gJ)
    F = F.at[2:4, 4:].set(0.5 * T * gJ @ A)
    q_gyr = (p.gyr_noise**2 * state.blk_tau + p.gyr_scale_noise**2 * state.blk_w2
             + state.blk_qmiss)
    q_vel = p.acc_noise**2 * t_acc + (p.acc_missing_m_s2 * (T - t_acc)) ** 2
    Q = jnp.diag(jnp.stack([q_gyr, q_gyr, q_vel, q_vel] + [p.bias_walk**2 * T] * 3))
    P = F @ state.P @ F.T + Q

    # size of the inertial acceleration seen by the norm (for the ACC_DISTURBED flag only)
    dev2 = state.blk_dev2 / t_acc_s
    alpha = 1.0 - jnp.exp(-t_acc / p.acc_tau_s)
    acc_dev_var = jnp.where(has_acc, state.acc_dev_var + alpha * (dev2 - state.acc_dev_var),
                            state.acc_dev_var)
    disturbed = has_acc & (acc_dev_var > p.acc_disturbed_m_s2**2)

    # rest detection: the canal signal is the drift alone (T eq. 1 with ω = 0)
    tau = state.blk_tau
    has_gyr = tau > 0
    tau_s = jnp.where(has_gyr, tau, 1.0)
    g_mean = state.blk_gsum / tau_s
    g_var = jnp.maximum(state.blk_w2 / jnp.where(T > 0, T, 1.0) - g_mean @ g_mean, 0.0)
    a_mean = state.blk_asum / t_acc_s
    a_var = jnp.maximum(state.blk_a2 / t_acc_s - a_mean @ a_mean, 0.0)
    gd = g_mean - b
    gap = state.blk_gap > 0  # unknown motion in this block
    collecting = state.reacquire & ~gap  # a block after a gap: the tilt error is unknown
    quiet = (has_gyr & has_acc & (g_var < p.rest_gyr_rad_s**2) & (gd @ gd < p.rest_gyr_rad_s**2)
             & (a_var < p.rest_acc_m_s2**2) & ~gap)
    rest_s = jnp.where(quiet, state.rest_s + T, 0.0)
    at_rest = rest_s >= p.rest_min_s

    # otolith update: accelerations are short and periodic (T §I), so the velocity they produce
    # stays small: pseudo-measurement 0 = v + n_v (n_v ~ 0 at rest). Since v integrates the
    # specific force rotated by the estimate, its error grows as g J δ: this observes the tilt
    # (T eq. 5) with the inertial part integrated out rather than taken as white noise.
    s_vel = jnp.where(at_rest, p.vel_rest_m_s**2, p.vel_m_s**2) * p.vel_corr_s
    dx1, P1 = _kf_update(P, _H_VEL, -vel, s_vel / t_acc_s)
    # after a gap the tilt error can be large, beyond the small-angle velocity update: the
    # specific force is summed in Earth (as estimated; the gyro alone carries the estimate, so
    # its error stays put) for reacquire_s, then its mean measures the tilt error directly
    # (T eq. 5, exact angle). Its inertial part is Δv / T, with |Δv| ~ √2 vel_m_s (velocity prior;
    # vel_rest_m_s if every block since the gap was quiet).
    f_sum = jnp.where(collecting, state.reacq_f_E + f_E_sum, 0.0)
    t_sum = jnp.where(collecting, state.reacq_t + t_acc, 0.0)
    reacq = collecting & (t_sum >= p.reacquire_s)
    v_r = jnp.where(rest_s >= t_sum, p.vel_rest_m_s, p.vel_m_s)
    r_tilt = 2.0 * (v_r / (g * jnp.where(reacq, t_sum, 1.0))) ** 2
    dxr, Pr = _kf_update(P, _H_TILT, tilt_error_from_force(f_sum), r_tilt)
    use_vel = has_acc & ~gap & ~collecting
    dx = jnp.where(use_vel, dx1, jnp.where(reacq, dxr, 0.0))
    P = jnp.where(use_vel, P1, jnp.where(reacq, Pr, P))
    forget = gap | collecting  # the velocity integrated across the gap means nothing
    P = jnp.where(forget, reset_velocity(P, p.vel_m_s**2), P)
    still = gap | (collecting & ~reacq)
    # rest: the block-mean gyro measures the bias
    r_b = p.gyr_noise**2 / tau_s + p.rest_motion_rad_s**2
    dx3, P3 = _kf_update(P, _H_BIAS, g_mean - (b + dx[4:]), r_b)
    dx = dx + jnp.where(at_rest, dx3, 0.0)
    P = jnp.where(at_rest, P3, P)

    q_new = _qnormalize(_qmul(_qexp(jnp.stack([dx[0], dx[1], 0.0])), q_end))
    new = state._replace(quat_E_S=q_new, bias_S_rad_s=b + dx[4:],
                         vel_E_m_s=jnp.where(forget, 0.0, vel + dx[2:4]), P=P,
                         acc_dev_var=acc_dev_var, rest_s=rest_s,
                         reacquire=still, reacq_f_E=jnp.where(still, f_sum, 0.0),
                         reacq_t=jnp.where(still, t_sum, 0.0), **_zero_block())
    return new, disturbed, reacq


def _inv3(S):
    """Inverse of a symmetric positive definite 3x3 matrix by cofactors."""
    a, b, c = S[0, 0], S[0, 1], S[0, 2]
    d, e, f = S[1, 1], S[1, 2], S[2, 2]
    cof = jnp.stack([jnp.stack([d * f - e * e, c * e - b * f, b * e - c * d]),
                     jnp.stack([c * e - b * f, a * f - c * c, b * c - a * e]),
                     jnp.stack([b * e - c * d, b * c - a * e, a * d - b * b])])
    det = a * (d * f - e * e) + b * (c * e - b * f) + c * (b * e - c * d)
    return cof / det


def _outputs(quat, bias, P, flags) -> TiltOutput:
    w, x, y, z = quat[..., 0], quat[..., 1], quat[..., 2], quat[..., 3]
    up = jnp.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], axis=-1)
    roll = jnp.arctan2(up[..., 1], up[..., 2])
    pitch = jnp.arctan2(-up[..., 0], jnp.sqrt(up[..., 1] ** 2 + up[..., 2] ** 2))
    return TiltOutput(roll, pitch, up, quat, bias, jnp.diagonal(P, axis1=-2, axis2=-1), flags)


def _flags(dt_ok, gyr_ok, acc_ok, init_now=False, disturbed=False, gap=False, reacq=False,
           reacquiring=False):
    return (tilt_kernels.flags(dt_ok, gyr_ok, acc_ok, disturbed, gap, reacq, reacquiring)
            | jnp.where(init_now, INIT, 0))


def step(state: TiltState, u, y, dt, params: TiltParams = DEFAULT_PARAMS, block: int = BLOCK):
    """One sample: ``u`` gyro (3,) rad/s, ``y`` accelerometer (3,) m/s², ``dt`` s since the
    previous sample. The gyro rotation and the accelerometer are pre-integrated, and every
    ``block`` samples the Kalman prediction and update run. Returns ``(state, TiltOutput)``."""
    p = params
    gyr = jnp.asarray(u, dtype=jnp.float64)
    acc = jnp.asarray(y, dtype=jnp.float64)
    dt = jnp.asarray(dt, dtype=jnp.float64)
    dt_ok, gyr_ok, acc_ok, acc_n2 = _sample_masks(gyr, acc, dt)
    dts = jnp.where(dt_ok, dt, 0.0)
    gyr0 = jnp.where(gyr_ok, gyr, 0.0)
    acc0 = jnp.where(acc_ok, acc, 0.0)

    # accumulate the sample into the block (pre-integration), branch-free
    st = state
    dq = _qmul(st.blk_dquat, _qexp(gyr0 * dts))
    wa = jnp.where(acc_ok, dts, 0.0)
    dev2 = (jnp.sqrt(acc_n2) - p.g_m_s2) ** 2
    gap = dts > p.gap_flag_s  # the gyro sample does not describe the rotation inside a gap
    acc_state = st._replace(
        blk_dquat=dq, blk_tau=st.blk_tau + jnp.where(gyr_ok, dts, 0.0),
        blk_f=st.blk_f + _qrotate(dq, acc0) * wa, blk_t_acc=st.blk_t_acc + wa,
        blk_dev2=st.blk_dev2 + dev2 * wa, blk_w2=st.blk_w2 + (gyr0 @ gyr0) * dts,
        blk_t=st.blk_t + dts,
        blk_qmiss=st.blk_qmiss + jnp.where(gyr_ok & ~gap, 0.0, (p.omega_missing_rad_s * dts) ** 2),
        blk_gsum=st.blk_gsum + gyr0 * dts, blk_asum=st.blk_asum + acc0 * wa,
        blk_a2=st.blk_a2 + acc_n2 * wa, blk_gap=st.blk_gap + jnp.where(gap, 1.0, 0.0),
        blk_count=st.blk_count + 1)
    # before initialization: the first usable accelerometer sample sets the tilt, to be
    # re-acquired after reacquire_s (the sample may hold an inertial acceleration)
    init_now = ~st.initialized & acc_ok
    init_state = st._replace(quat_E_S=jnp.where(init_now, quat_from_acc(acc0), st.quat_E_S),
                             initialized=init_now, reacquire=init_now,
                             P=jnp.where(init_now, widen_tilt(st.P, p.init_tilt_rad), st.P))
    state = jax.tree_util.tree_map(lambda x, y: jnp.where(st.initialized, x, y), acc_state,
                                   init_state)
    state, disturbed, reacq = jax.lax.cond(state.initialized & (state.blk_count >= block),
                                           lambda s: _block_update(s, p),
                                           lambda s: (s, jnp.array(False), jnp.array(False)),
                                           state)
    at_start = state.blk_count == 0
    quat = jnp.where(at_start, state.quat_E_S, _qnormalize(_qmul(
        _qmul(state.quat_E_S, state.blk_dquat), _qexp(-state.bias_S_rad_s * state.blk_tau))))
    # before initialization there is no estimate: the variance reported is the initialization's
    # (as run reports it), not P0's; within a block, the tilt variance that gyro dropouts and gaps
    # have added since its start (it enters P at the block's update; without it the samples after
    # a gap would show the variance from before it)
    P_out = jnp.where(state.initialized, state.P, widen_tilt(state.P, p.init_tilt_rad))
    P_out = tilt_kernels.add_tilt_variance(P_out, state.blk_qmiss)
    out = _outputs(quat, state.bias_S_rad_s, P_out,
                   _flags(dt_ok, gyr_ok, acc_ok, init_now, disturbed, gap, reacq,
                          state.reacquire | (state.blk_gap > 0)))
    return state, out


step_jit = jax.jit(step, static_argnames=("block",))


class Stepper(NamedTuple):
    """Real-time form of :func:`step` (see :func:`make_step`): the state travels as one flat
    float64 vector (:func:`verticality.estimators.tilt_kernels.stream_step`) and the output as
    ``[roll, pitch, up(3), quat(4), bias(3), flags]``, so that a call costs little more than
    JAX's dispatch."""

    init: object  # () -> packed state
    step: object  # (z, gyr(3,), acc(3,), dt) -> (z, out(13,))
    step_packed: object  # (z, sample(7,) = [gyr, acc, dt]) -> (z, out(13,)), one argument less
    unpack: object  # z -> TiltState


def make_step(params: TiltParams = DEFAULT_PARAMS, block: int = BLOCK, x0=None, P0=None
              ) -> Stepper:
    """A jitted per-sample step for Python loops (parameters baked in as constants); the same
    numbers as :func:`step` (tested)."""
    template = init(x0, P0)
    z0 = np.asarray(tilt_kernels.stream_init(pack_state(template), bool(template.initialized)))

    @jax.jit
    def step_packed(z, sample):
        return tilt_kernels.stream_step(z, sample, params, block)

    def step_(z, gyr, acc, dt):
        return step_packed(z, np.concatenate([np.asarray(gyr, dtype=np.float64),
                                              np.asarray(acc, dtype=np.float64),
                                              [float(dt)]]))

    def unpack(z):
        z = np.asarray(z)
        nx, ns = tilt_kernels.NX, tilt_kernels.NS
        st = unpack_state(z[:nx], template)
        sm = z[nx:nx + ns]
        return st._replace(
            initialized=np.bool_(z[nx + ns + 1] > 0.5), blk_dquat=sm[0:4], blk_tau=sm[4],
            blk_f=sm[5:8], blk_t_acc=sm[8], blk_dev2=sm[9], blk_w2=sm[10], blk_t=sm[11],
            blk_qmiss=sm[12], blk_gsum=sm[13:16], blk_asum=sm[16:19], blk_a2=sm[19], blk_gap=sm[20],
            blk_count=np.int32(round(z[nx + ns])))

    return Stepper(lambda: jnp.asarray(z0), step_, step_packed, unpack)


@partial(jax.jit, static_argnames=("block",))
def scan(state: TiltState, us, ys, dts, params: TiltParams = DEFAULT_PARAMS, block: int = BLOCK):
    """:func:`step` over a recording under ``jax.lax.scan`` (sample by sample; the reference for
    the faster, equivalent :func:`run`). ``us``, ``ys`` (N, 3), ``dts`` (N,)."""
    def body(s, x):
        return step(s, x[0], x[1], x[2], params, block)

    return jax.lax.scan(body, state, (us, ys, dts))


def pack_state(state: TiltState):
    """The filter part of a block-boundary ``state`` as the flat vector of
    :mod:`verticality.estimators.tilt_kernels` (q, b, v, P, acc_dev_var, rest_s, reacquire,
    reacq_f_E, reacq_t)."""
    return np.concatenate([np.asarray(state.quat_E_S), np.asarray(state.bias_S_rad_s),
                           np.asarray(state.vel_E_m_s), np.reshape(np.asarray(state.P), -1),
                           [float(state.acc_dev_var), float(state.rest_s),
                            float(bool(state.reacquire))], np.asarray(state.reacq_f_E),
                           [float(state.reacq_t)]])


def unpack_state(x, template: TiltState) -> TiltState:
    """Inverse of :func:`pack_state` (block fields empty, ``initialized`` from ``template``)."""
    x = np.asarray(x)
    return template._replace(quat_E_S=x[0:4], bias_S_rad_s=x[4:7], vel_E_m_s=x[7:9],
                             P=x[9:58].reshape(7, 7), acc_dev_var=x[58], rest_s=x[59],
                             reacquire=np.bool_(x[60] > 0.5), reacq_f_E=x[61:64],
                             reacq_t=x[64],
                             **{f: getattr(_default_init(), f) for f in TiltState._fields
                                if f.startswith("blk_")})


CHUNK_BLOCKS = 256
GAP_CHUNK_BLOCKS = 32  # chunks with gap handling are short: it costs ~1.4x per sample


def run(gyr_rad_s, acc_m_s2, dt_s, params: TiltParams = DEFAULT_PARAMS,
        state: TiltState | None = None, block: int = BLOCK, return_state: bool = False):
    """Filter a whole recording: gyro (N, 3) rad/s, accelerometer (N, 3) m/s², ``dt_s`` a scalar
    sampling period or (N,) per-sample steps (``dt_s[k]`` is the time from sample k−1 to k).
    Returns a :class:`TiltOutput` of NumPy arrays (and the final state if ``return_state``;
    a trailing partial block is closed, i.e. its update is applied). Gives the
    outputs of :func:`step` applied sample by sample (to rounding), but vectorizes the per-sample
    work and runs lax.scan over blocks only, in chunks of fixed shape (one compilation).

    Example::

        from verticality.estimators import tilt
        out = tilt.run(gyr, acc, 1 / 285.7)
        out.roll_rad, out.pitch_rad, out.up_S, out.bias_S_rad_s, out.flags
    """
    gyr = np.asarray(gyr_rad_s, dtype=np.float64)
    acc = np.asarray(acc_m_s2, dtype=np.float64)
    if gyr.ndim != 2 or gyr.shape[1] != 3 or acc.shape != gyr.shape:
        raise ValueError(f"gyr and acc must both have shape (N, 3); got {gyr.shape}, {acc.shape}")
    n = gyr.shape[0]
    dts = np.broadcast_to(np.asarray(dt_s, dtype=np.float64), (n,)).copy()
    if state is None:
        state = _default_init()
    res = TiltOutput(np.zeros(n), np.zeros(n), np.zeros((n, 3)), np.zeros((n, 4)),
                     np.zeros((n, 3)), np.zeros((n, 7)), np.zeros(n, dtype=np.int32))

    def put(k0, o):
        for dst, src in zip(res, o, strict=True):
            dst[k0:k0 + len(src)] = np.asarray(src)

    k = 0
    if not bool(state.initialized):
        # samples before the first usable accelerometer sample: no estimate yet (flagged); that
        # sample initializes the tilt (as step does, without a scan of variable length)
        found, lo, span = False, 0, 256
        while not found and lo < n:  # look in growing windows (usually the first sample)
            hi = min(n, lo + span)
            dt_ok, ok = _usable_np(acc[:hi], dts[:hi])
            found = bool(ok.any())
            lo, span = hi, 4 * span
        k = int(np.argmax(ok)) + 1 if found else n
        gyr_fin = np.all(np.isfinite(gyr[:k]), axis=1)
        flags = (np.where(ok[:k] | ~dt_ok[:k], 0, ACC_MISSING)
                 | np.where((gyr_fin & dt_ok[:k]) | ~dt_ok[:k], 0, GYR_MISSING)
                 | np.where(dt_ok[:k], 0, BAD_DT)
                 | np.where(dt_ok[:k] & (dts[:k] > params.gap_flag_s), DT_GAP, 0)).astype(np.int32)
        quat = np.tile(np.asarray(state.quat_E_S), (k, 1))
        # no estimate before the initialization: those samples report its variance (as step)
        P_init = np.asarray(widen_tilt(state.P, params.init_tilt_rad))
        var = np.tile(np.diagonal(P_init), (k, 1))
        if found:
            q0 = _quat_from_acc_np(acc[k - 1])
            quat[-1] = np.asarray(q0)
            flags[-1] |= INIT | REACQUIRING
            state = state._replace(quat_E_S=q0, initialized=np.bool_(True),
                                   reacquire=np.bool_(True), reacq_f_E=np.zeros(3),
                                   reacq_t=np.float64(0.0),
                                   P=P_init)
        put(0, _outputs_np(quat, np.tile(np.asarray(state.bias_S_rad_s), (k, 1)), var, flags))
    if int(state.blk_count) != 0:  # finish the current block sample by sample
        for j in range(k, min(n, k + block - int(state.blk_count))):
            state, o = step_jit(state, gyr[j], acc[j], dts[j], params, block)
            put(j, jax.tree_util.tree_map(lambda x: np.asarray(x)[None], o))
            k = j + 1
    k_chunks = k
    if k < n:
        # dispatch every chunk first (asynchronous, the state stays on the device), then copy
        # the outputs: the host copies overlap the device work of the later chunks
        x = pack_state(state)
        p_vec = jax.device_put(np.asarray(params, dtype=np.float64))  # once per recording
        # the kernel without gap handling serves chunks with no gap and no re-acquisition in
        # them (the same numbers, faster)
        need = _blocks_needing_gaps(dts, acc, k, block, params, bool(state.reacquire),
                                    float(state.reacq_t))
        pending, j = [], 0
        while k < n:
            # a gap or a re-acquisition (after a gap, and after the initialization) within a
            # chunk's reach: short chunks with gap handling until it is past; and for a tail of
            # at most half a long chunk (less padding)
            gaps = bool(need[j:j + CHUNK_BLOCKS].any()) or 2 * (n - k) <= CHUNK_BLOCKS * block
            size = (GAP_CHUNK_BLOCKS if gaps else CHUNK_BLOCKS) * block
            # the chunk's samples as [gyr, acc, dt] rows (packed chunk by chunk, while the
            # device works on the previous one); the last chunk padded with skipped samples
            # (dt = NaN: BAD_DT) so that every chunk has one of the two compiled shapes
            m = min(size, n - k)
            data = np.empty((size, 7))
            data[:m, 0:3] = gyr[k:k + m]
            data[:m, 3:6] = acc[k:k + m]
            data[:m, 6] = dts[k:k + m]
            if m < size:
                data[m:, 0:6] = 0.0
                data[m:, 6] = np.nan
            x, outs = tilt_kernels.run_chunk(x, data, p_vec, block, params._fields, gaps=gaps)
            pending.append((k, m, size, outs))
            k += m
            j += size // block
        for k0, m, size, outs in pending:
            if m == size:
                _put_chunk(res, k0, outs, block)
            else:  # the padded last chunk: through a temporary
                tmp = TiltOutput(np.empty(size), np.empty(size), np.empty((size, 3)),
                                 np.empty((size, 4)), np.empty((size, 3)), np.empty((size, 7)),
                                 np.empty(size, dtype=np.int32))
                _put_chunk(tmp, 0, outs, block)
                for dst, src in zip(res, tmp, strict=True):
                    dst[k0:k0 + m] = src[:m]
        _add_dropout_variance(res.var, gyr, dts, k_chunks, block, params)
        if return_state:
            state = unpack_state(x, state)
    return (res, state) if return_state else res


def _add_dropout_variance(var, gyr, dts, k0, block, params):
    """Within each block from sample ``k0`` on (``k0`` at a block boundary), add to the tilt
    variances the part that gyro dropouts and gaps have added since the block's start, as
    :func:`step` reports it (the kernels give the block-start variances; the block's last sample
    already has the updated ones). In place; nothing to do on a recording without dropouts."""
    if np.isfinite(np.sum(gyr[k0:])) and not np.any(dts[k0:] > params.gap_flag_s):
        return  # every gyro sample finite (a finite sum says so) and no gap: the usual case
    dt_ok = np.isfinite(dts[k0:]) & (dts[k0:] > 0)
    dts0 = np.where(dt_ok, dts[k0:], 0.0)
    lost = dt_ok & ~(np.all(np.isfinite(gyr[k0:]), axis=1) & (dts0 <= params.gap_flag_s))
    m = dts0.shape[0]
    q = np.zeros(-(-m // block) * block)
    q[:m] = np.where(lost, (params.omega_missing_rad_s * dts0) ** 2, 0.0)
    q = np.cumsum(q.reshape(-1, block), axis=1)
    q[:, -1] = 0.0
    var[k0:, 0:2] += q.reshape(-1)[:m, None]


def _usable_np(acc, dts):
    """(dt_ok, acc_ok) per sample on the host, as ``tilt_kernels.masks``: a finite positive Δt;
    and with it a finite, non-zero accelerometer sample."""
    dt_ok = np.isfinite(dts) & (dts > 0)
    fin = np.all(np.isfinite(acc), axis=1)
    return dt_ok, dt_ok & fin & (np.sum(np.where(fin[:, None], acc, 0.0) ** 2, axis=1) > 1e-6)


def _blocks_needing_gaps(dts, acc, k, block, params, pending, t_sum):
    """Per block from sample ``k`` on (``k`` at a block boundary): True where the block holds a gap
    or starts while the tilt is to be re-acquired after a gap: there the
    batch kernel needs its gap handling. A host twin of the kernel's flag from the data alone (the
    gap samples and each block's accelerometer time); it holds the flag one block longer than the
    kernel, so that rounding in the sums cannot make it clear first."""
    n = dts.shape[0]
    nb = -(-(n - k) // block)
    need = np.zeros(nb, dtype=bool)
    is_gap = np.isfinite(dts[k:]) & (dts[k:] > params.gap_flag_s)
    gap_blocks = np.unique(np.flatnonzero(is_gap) // block)
    j = 0
    while j < nb:
        if not pending:  # jump to the next block with a gap
            i = int(np.searchsorted(gap_blocks, j))
            if i == gap_blocks.size:
                break
            j, pending, t_sum = int(gap_blocks[i]), True, 0.0
            need[j] = True
            j += 1
            continue
        # pending from block j: the accelerometer time of the next blocks, a window at a time
        hi_b = min(nb, j + 64)
        lo, hi = k + j * block, min(n, k + hi_b * block)
        _, ok = _usable_np(acc[lo:hi], dts[lo:hi])
        w = np.zeros((hi_b - j) * block)
        w[:hi - lo] = np.where(ok, dts[lo:hi], 0.0)
        t_blk = t_sum + np.cumsum(w.reshape(-1, block).sum(axis=1))
        g = int(np.searchsorted(gap_blocks, j))
        g = int(gap_blocks[g]) if g < gap_blocks.size and gap_blocks[g] < hi_b else hi_b
        done = np.flatnonzero(t_blk[:g - j] >= params.reacquire_s)
        if done.size:  # the kernel re-acquires at block c
            c = j + int(done[0])
            need[j:min(nb, c + 2)] = True
            pending, j = False, c + 1
        elif g < hi_b:  # a gap first: pending again from the block after it
            need[j:g + 1] = True
            t_sum, j = 0.0, g + 1
        else:
            need[j:hi_b] = True
            t_sum, j = float(t_blk[-1]), hi_b
    return need


def _put_chunk(res: TiltOutput, k0: int, outs, block: int):
    """Write the outputs of one ``tilt_kernels.run_chunk`` (all its samples) into ``res`` from
    sample ``k0`` on: one transposing copy per field, bias and variances broadcast per block."""
    soa, rows, fl = (np.asarray(o) for o in outs)
    nb = soa.shape[2]
    n = nb * block

    def dst(a):  # (n, ...) rows of a from k0 as a (nb, block, ...) view
        return a[k0:k0 + n].reshape((nb, block) + a.shape[1:], copy=False)

    dst(res.quat_E_S)[...] = soa[0:4].T
    dst(res.up_S)[...] = soa[4:7].T
    dst(res.roll_rad)[...] = soa[7].T
    dst(res.pitch_rad)[...] = soa[8].T
    for a, start, end in ((res.bias_S_rad_s, rows[:, 4:7], rows[:, 18:21]),
                          (res.var, rows[:, 7:14], rows[:, 21:28])):
        v = dst(a)
        v[:, :-1] = start[:, None, :]
        v[:, -1] = end
    fl_dst = dst(res.flags)
    fl_dst[...] = fl.T
    # REACQUIRING: from a gap to the block that re-acquires (rare; tilt_kernels leaves it to us)
    pend_start, pend_end = rows[:, 30] > 0.5, rows[:, 31] > 0.5
    rare = np.flatnonzero(pend_start | pend_end)
    if rare.size:
        # a block pending at its start is flagged from its first sample; one that only turns
        # pending (it holds a gap) from its gap on; the last sample as the state after the update
        first = np.where(pend_start[rare], 0, np.argmax((fl[:, rare] & DT_GAP) > 0, axis=0))
        k = np.arange(block)[None, :]
        on = (k >= first[:, None]) & (k < block - 1)
        on[:, -1] = pend_end[rare]
        fl_dst[rare] |= np.where(on, REACQUIRING, 0).astype(fl_dst.dtype)


def _angles_np(res: TiltOutput):
    """Fill roll, pitch and up of ``res`` from its quaternions (in place)."""
    q = res.quat_E_S
    w, x, y, z = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    up = res.up_S
    up[:, 0] = 2 * (x * z - w * y)
    up[:, 1] = 2 * (y * z + w * x)
    up[:, 2] = 1 - 2 * (x * x + y * y)
    res.roll_rad[:] = np.arctan2(up[:, 1], up[:, 2])
    res.pitch_rad[:] = np.arctan2(-up[:, 0], np.sqrt(up[:, 1] ** 2 + up[:, 2] ** 2))


def _outputs_np(quat, bias, var, flags) -> TiltOutput:
    """NumPy twin of :func:`_outputs` (host side of :func:`run`)."""
    k = quat.shape[0]
    res = TiltOutput(np.zeros(k), np.zeros(k), np.zeros((k, 3)), quat, bias, var, flags)
    _angles_np(res)
    return res
