"""Fast kernels of the tilt filter (:mod:`verticality.estimators.tilt`): the same equations as
``tilt.step`` / ``tilt._block_update``, rearranged so that XLA on a CPU runs them quickly.

* :func:`block_update_packed` — the Kalman prediction and otolith/rest updates of one block (T eq.
  2, 7–13 in 3-D) on a packed flat state, written with element-wise and broadcast operations only
  (no ``dot``; the Joseph form with a selector ``H`` is expanded by hand), so that the body of the
  ``lax.scan`` over blocks compiles to a few fused kernels instead of ~90 small ones.
* :func:`run_chunk` — a fixed-size chunk of samples: the per-sample pre-integration is a short
  sequential ``lax.scan`` over the ``block`` samples of a block, vectorized across all blocks at
  once (structure-of-arrays layout), the quaternion exponential is a Taylor polynomial with an
  exact fallback (``lax.cond`` on the whole chunk, so the fallback costs nothing when unused), then
  the state-independent part of every block update at once (:func:`block_inputs`), then one
  ``lax.scan`` over the blocks (:func:`block_update_core`; the rest update under ``lax.cond``),
  then the per-sample quaternion, up, roll and pitch (:func:`atan2`, a vectorizable arctan2) and
  flags; the host writes them, and the per-block bias and variances, into the result arrays.

Packed state (float64, length :data:`NX`): ``q_E_S`` (4, wxyz), ``b_S`` (3), ``v_E`` (2),
``P`` (49, row-major 7×7), ``acc_dev_var``, ``rest_s``, ``reacquire`` (1.0 or 0.0),
``reacq_f_E`` (3), ``reacq_t``. Packed block
sums (length :data:`NS`): ``dquat`` (4), ``tau``, ``f`` (3), ``t_acc``, ``dev2``, ``w2``, ``t``,
``qmiss``, ``gsum`` (3), ``asum`` (3), ``a2``, ``gap`` — the ``blk_*`` fields of
``tilt.TiltState``.
"""

from __future__ import annotations

import math
from types import SimpleNamespace

import jax
import jax.numpy as jnp

NX = 65
NS = 21
SMALL_TH2 = 0.04  # |rotation|² (rad²) below which the Taylor exponential is used (error < 1e-27)

# flag bits (same values as in tilt)
ACC_MISSING, GYR_MISSING, BAD_DT, ACC_DISTURBED, DT_GAP, REACQUIRED, REACQUIRING = (
    1, 2, 4, 8, 32, 64, 128)


def qmul_c(p, q):
    """Quaternion product on component tuples (w, x, y, z) of arrays."""
    pw, px, py, pz = p
    qw, qx, qy, qz = q
    return (pw * qw - px * qx - py * qy - pz * qz,
            pw * qx + px * qw + py * qz - pz * qy,
            pw * qy - px * qz + py * qw + pz * qx,
            pw * qz + px * qy - py * qx + pz * qw)


def qexp_taylor_c(vx, vy, vz):
    """Quaternion of the rotation vector (vx, vy, vz) for |v|² < :data:`SMALL_TH2`: the series of
    cos(θ/2) and sin(θ/2)/θ to θ⁸ (truncation error < 1e-27; no sqrt, sin or cos)."""
    x2 = 0.25 * (vx * vx + vy * vy + vz * vz)  # (θ/2)²
    c = 1.0 + x2 * (-1.0 / 2 + x2 * (1.0 / 24 + x2 * (-1.0 / 720 + x2 * (1.0 / 40320))))
    s = 0.5 * (1.0 + x2 * (-1.0 / 6 + x2 * (1.0 / 120 + x2 * (-1.0 / 5040 + x2 * (1.0 / 362880)))))
    return c, s * vx, s * vy, s * vz


def qexp_exact_c(vx, vy, vz):
    """Quaternion of the rotation vector, exact (the formula of ``tilt._qexp``)."""
    th2 = vx * vx + vy * vy + vz * vz
    small = th2 < 1e-12
    th = jnp.sqrt(jnp.where(small, 1.0, th2))
    k = jnp.where(small, 0.5 - th2 / 48.0, jnp.sin(0.5 * th) / th)
    c = jnp.where(small, 1.0 - th2 / 8.0, jnp.cos(0.5 * th))
    return c, k * vx, k * vy, k * vz


def qexp_c(vx, vy, vz):
    """Batched quaternion exponential: Taylor when every rotation of the batch is small (the IMU
    case: |ω|Δt ≪ 0.2 rad), the exact formula otherwise (decided once for the whole batch)."""
    th2 = vx * vx + vy * vy + vz * vz
    return jax.lax.cond(jnp.all(th2 < SMALL_TH2), qexp_taylor_c, qexp_exact_c, vx, vy, vz)


def _qnorm_c(q):
    n = jnp.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    return tuple(c / n for c in q)


def _qexp_vec(v):
    """``tilt._qexp`` on a (3,) vector (used once per block, exact)."""
    return jnp.stack(qexp_exact_c(v[0], v[1], v[2]))


def _qmul_vec(p, q):
    return jnp.stack(qmul_c(tuple(p), tuple(q)))


def rotmat(q):
    """Rotation matrix of a unit quaternion (w, x, y, z), no normalization (the filter keeps q unit)."""
    w, x, y, z = q[0], q[1], q[2], q[3]
    return jnp.stack([
        jnp.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)]),
        jnp.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)]),
        jnp.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]),
    ])


def _qrotate_vec(q, v):
    w, u = q[0], q[1:]
    t = 2.0 * jnp.cross(u, v)
    return v + w * t + jnp.cross(u, t)


def _joseph_selector(P, i0, m, z, r):
    """Kalman update for ``z = x[i0:i0+m] + n``, ``n ~ N(0, r I)``, m = 2 or 3, Joseph form,
    symmetrized; element-wise (identical algebra to ``tilt._kf_update`` with a selector H)."""
    PHt = P[:, i0:i0 + m]  # (7, m)
    S = P[i0:i0 + m, i0:i0 + m] + r * jnp.eye(m)
    if m == 2:
        det = S[0, 0] * S[1, 1] - S[0, 1] * S[1, 0]
        Si = jnp.stack([jnp.stack([S[1, 1], -S[0, 1]]), jnp.stack([-S[1, 0], S[0, 0]])]) / det
    else:
        a, b, c = S[0, 0], S[0, 1], S[0, 2]
        d, e, f = S[1, 1], S[1, 2], S[2, 2]
        cof = jnp.stack([jnp.stack([d * f - e * e, c * e - b * f, b * e - c * d]),
                         jnp.stack([c * e - b * f, a * f - c * c, b * c - a * e]),
                         jnp.stack([b * e - c * d, b * c - a * e, a * d - b * b])])
        Si = cof / (a * (d * f - e * e) + b * (c * e - b * f) + c * (b * e - c * d))
    K = sum(PHt[:, j:j + 1] * Si[j][None, :] for j in range(m))  # (7, m)
    dx = sum(K[:, j] * z[j] for j in range(m))
    M = P - sum(K[:, j:j + 1] * P[i0 + j][None, :] for j in range(m))  # (I − K H) P
    Pn = (M - sum(M[:, i0 + j:i0 + j + 1] * K[:, j][None, :] for j in range(m))
          + r * sum(K[:, j:j + 1] * K[:, j][None, :] for j in range(m)))
    return dx, 0.5 * (Pn + Pn.T)


def tilt_error_from_force(f_E):
    """The tilt error ``δ`` (2,) that turns the specific force ``f_E`` (3,), expressed in Earth
    with the estimated orientation, back to vertical: ``exp([δ, 0]) f_E ∥ e3`` (exact, any angle
    below π; T eq. 5 without the small-angle approximation). Zero for a zero force."""
    n = jnp.sqrt(jnp.sum(f_E * f_E))
    u = f_E / jnp.where(n > 0, n, 1.0)
    s = jnp.sqrt(u[0] * u[0] + u[1] * u[1])
    k = jnp.where(s > 1e-12, jnp.arctan2(s, u[2]) / jnp.where(s > 1e-12, s, 1.0), 1.0)
    return k * jnp.stack([u[1], -u[0]])


def reset_velocity(P, var_m2_s2):
    """Covariance ``P`` (7, 7) with the velocity error forgotten: its rows and columns zeroed and
    its variance set to ``var_m2_s2`` (after a gap the integrated velocity means nothing)."""
    keep = jnp.array([1.0, 1.0, 0.0, 0.0, 1.0, 1.0, 1.0])
    return P * keep[:, None] * keep[None, :] + jnp.diag(var_m2_s2 * (1.0 - keep))


def add_tilt_variance(P, var_rad2):
    """Covariance ``P`` (7, 7) with ``var_rad2`` added to both tilt variances."""
    return P + jnp.diag(jnp.array([1.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0]) * var_rad2)


def widen_tilt(P, sigma_rad):
    """Covariance ``P`` (7, 7) with ``sigma_rad²`` added to both tilt variances (the accelerometer
    sample that initializes the filter may hold an inertial acceleration of unknown size)."""
    return add_tilt_variance(P, sigma_rad**2)


NB = 24  # length of the per-block inputs of :func:`block_update_core` (see :func:`block_inputs`)


def block_inputs(s, p):
    """The part of ``tilt._block_update`` that depends on the block sums only, not on the filter
    state: ``s`` (..., NS) packed block sums (any leading shape, so that :func:`run_chunk`
    computes it for all the blocks of a chunk at once, outside the sequential scan). Returns
    (..., :data:`NB`): ``dquat`` (4), ``tau``, ``f`` (3), ``T``, ``has_acc``, ``Qd`` gyro,
    velocity and bias terms (3), ``alpha``, ``dev2``, ``g_mean`` (3), ``quiet`` without the
    bias test, the velocity-update noise (moving, at rest), the rest-update noise, whether the
    block holds a gap, and ``t_acc``."""
    dquat, tau, f = s[..., 0:4], s[..., 4], s[..., 5:8]
    t_acc, dev2s, w2, T, qmiss = s[..., 8], s[..., 9], s[..., 10], s[..., 11], s[..., 12]
    gsum, asum, a2, gap = s[..., 13:16], s[..., 16:19], s[..., 19], s[..., 20] > 0
    has_acc = t_acc > 0
    t_acc_s = jnp.where(has_acc, t_acc, 1.0)
    q_gyr = p.gyr_noise**2 * tau + p.gyr_scale_noise**2 * w2 + qmiss
    q_vel = p.acc_noise**2 * t_acc + (p.acc_missing_m_s2 * (T - t_acc)) ** 2
    qb = p.bias_walk**2 * T
    dev2 = dev2s / t_acc_s
    alpha = 1.0 - jnp.exp(-t_acc / p.acc_tau_s)
    has_gyr = tau > 0
    tau_s = jnp.where(has_gyr, tau, 1.0)
    g_mean = gsum / tau_s[..., None]
    g_var = jnp.maximum(w2 / jnp.where(T > 0, T, 1.0) - jnp.sum(g_mean * g_mean, -1), 0.0)
    a_mean = asum / t_acc_s[..., None]
    a_var = jnp.maximum(a2 / t_acc_s - jnp.sum(a_mean * a_mean, -1), 0.0)
    quiet0 = (has_gyr & has_acc & (g_var < p.rest_gyr_rad_s**2) & (a_var < p.rest_acc_m_s2**2)
              & ~gap)
    r_vel = (p.vel_m_s**2 * p.vel_corr_s) / t_acc_s
    r_vel_rest = (p.vel_rest_m_s**2 * p.vel_corr_s) / t_acc_s
    r_b = p.gyr_noise**2 / tau_s + p.rest_motion_rad_s**2
    one = lambda c: c[..., None].astype(jnp.float64)  # noqa: E731
    return jnp.concatenate([dquat, one(tau), f, one(T), one(has_acc), one(q_gyr), one(q_vel),
                            one(qb), one(alpha), one(dev2), g_mean, one(quiet0), one(r_vel),
                            one(r_vel_rest), one(r_b), one(gap), one(t_acc)], axis=-1)


def block_update_packed(x, s, p):
    """``tilt._block_update`` on packed vectors: ``x`` (NX,) state at the block start, ``s`` (NS,)
    block sums, ``p`` TiltParams. Returns ``(x_new, disturbed, reacquired)``."""
    return block_update_core(x, block_inputs(s, p), p)


def block_update_core(x, c, p, gaps: bool = True):
    """:func:`block_update_packed` from the per-block inputs ``c`` (NB,) of :func:`block_inputs`:
    the part of the block update that depends on the filter state (the body of the scan).
    ``gaps=False`` leaves out the handling of gaps (for a stretch with no gap since the state was
    last without one: then the results are the same, and the scan runs ~1.4x faster)."""
    g = p.g_m_s2
    q0, b, vel0 = x[0:4], x[4:7], x[7:9]
    P0 = x[9:58].reshape(7, 7)
    acc_dev_var0, rest0, reacquire0 = x[58], x[59], x[60] > 0.5
    reacq_f0, reacq_t0 = x[61:64], x[64]
    dquat, tau, f, T = c[0:4], c[4], c[5:8], c[8]
    has_acc, q_gyr, q_vel, qb, alpha, dev2 = c[9] > 0.5, c[10], c[11], c[12], c[13], c[14]
    g_mean, quiet0, r_vel, r_vel_rest, r_b = c[15:18], c[18] > 0.5, c[19], c[20], c[21]
    gap, t_acc = c[22] > 0.5, c[23]
    collecting = reacquire0 & ~gap

    q_end = _qmul_vec(_qmul_vec(q0, dquat), _qexp_vec(-b * tau))
    q_end = q_end / jnp.sqrt(jnp.sum(q_end * q_end))
    R = rotmat(q_end)
    f_E = _qrotate_vec(q0, f)
    vel = vel0 + f_E[:2]

    # F = I + E; E: δ ← −T R[:2] b̃ ; ṽ ← T gJ δ + 0.5 T gJ A b̃
    A = -T * R[:2, :]  # (2, 3)
    gJA = jnp.stack([A[1], -A[0]]) * g  # g J A, J = [[0, 1], [-1, 0]]
    z2 = jnp.zeros((2, 2))
    F = jnp.concatenate([
        jnp.concatenate([jnp.eye(2), z2, A], axis=1),
        jnp.concatenate([T * g * jnp.array([[0.0, 1.0], [-1.0, 0.0]]), jnp.eye(2), 0.5 * T * gJA],
                        axis=1),
        jnp.concatenate([jnp.zeros((3, 4)), jnp.eye(3)], axis=1)], axis=0)
    Qd = jnp.stack([q_gyr, q_gyr, q_vel, q_vel, qb, qb, qb])
    FP = jnp.sum(F[:, :, None] * P0[None, :, :], axis=1)
    P = jnp.sum(FP[:, None, :] * F[None, :, :], axis=2) + jnp.diag(Qd)

    acc_dev_var = jnp.where(has_acc, acc_dev_var0 + alpha * (dev2 - acc_dev_var0), acc_dev_var0)
    disturbed = has_acc & (acc_dev_var > p.acc_disturbed_m_s2**2)

    gd = g_mean - b
    quiet = quiet0 & (jnp.sum(gd * gd) < p.rest_gyr_rad_s**2)
    rest_s = jnp.where(quiet, rest0 + T, 0.0)
    at_rest = rest_s >= p.rest_min_s

    dx1, P1 = _joseph_selector(P, 2, 2, -vel, jnp.where(at_rest, r_vel_rest, r_vel))
    dx = jnp.where(has_acc, dx1, 0.0)

    def rest_update(dx, P):  # the block-mean gyro measures the bias
        dx3, P3 = _joseph_selector(P, 4, 3, g_mean - (b + dx[4:]), r_b)
        return dx + dx3, P3

    def rare(args):
        """At rest, or after a gap (exclusive: rest needs no gap in sight); one ``lax.cond``
        keeps the common moving block free of both. After a gap the tilt is re-acquired from the
        mean specific force (``tilt._block_update``)."""
        dx, P = args
        forget = gap | collecting  # no velocity update; the velocity is forgotten
        f_sum = jnp.where(collecting, reacq_f0 + f_E, 0.0)
        t_sum = jnp.where(collecting, reacq_t0 + t_acc, 0.0)
        reacq = collecting & (t_sum >= p.reacquire_s)
        still = gap | (collecting & ~reacq)
        dx = jnp.where(forget, 0.0, dx)
        P = jnp.where(forget, P_pred, P)
        v_r = jnp.where(rest_s >= t_sum, p.vel_rest_m_s, p.vel_m_s)  # quiet since the gap
        dxr, Pr = _joseph_selector(P, 0, 2, tilt_error_from_force(f_sum),
                                   2.0 * (v_r / (g * jnp.where(reacq, t_sum, 1.0))) ** 2)
        dx = jnp.where(reacq, dxr, dx)
        P = jnp.where(reacq, Pr, P)
        P = jnp.where(forget, reset_velocity(P, p.vel_m_s**2), P)
        dx_r, P_r = rest_update(dx, P)
        dx, P = jnp.where(at_rest, dx_r, dx), jnp.where(at_rest, P_r, P)
        tail = jnp.concatenate([jnp.where(still, 1.0, 0.0)[None], jnp.where(still, f_sum, 0.0),
                                jnp.where(still, t_sum, 0.0)[None]])
        return dx, P, jnp.where(forget, 0.0, vel + dx[2:4]), tail, reacq

    def common(args):
        dx, P = args
        return dx, P, vel + dx[2:4], jnp.zeros(5), jnp.array(False)

    P_pred = P
    if gaps:
        dx, P, vel, tail, reacq = jax.lax.cond(at_rest | gap | reacquire0, rare, common,
                                               (dx, jnp.where(has_acc, P1, P)))
    else:  # no gap in sight: the rest update alone, under lax.cond (no cost while moving)
        dx, P = jax.lax.cond(at_rest, lambda a: rest_update(*a), lambda a: a,
                             (dx, jnp.where(has_acc, P1, P)))
        vel, tail, reacq = vel + dx[2:4], jnp.zeros(NX - 60), jnp.array(False)

    q_new = _qmul_vec(_qexp_vec(jnp.stack([dx[0], dx[1], 0.0])), q_end)
    q_new = q_new / jnp.sqrt(jnp.sum(q_new * q_new))
    x_new = jnp.concatenate([q_new, b + dx[4:], vel, P.reshape(-1),
                             jnp.stack([acc_dev_var, rest_s]), tail])
    return x_new, disturbed, reacq


# atan(t) on [0, 0.66] as t + t z P(z)/Q(z), z = t² (Cephes' rational approximation, relative
# error < 2.3e-16); the reduction (t − 1)/(t + 1) covers t in (0.66, 1]
_ATAN_P = (-8.750608600031904122785e-1, -1.615753718733365076637e1, -7.500855792314704667340e1,
           -1.228866684490136173410e2, -6.485021904942025371773e1)
_ATAN_Q = (2.485846490142306297962e1, 1.650270098316988542046e2, 4.328810604912902668951e2,
           4.853903996359136964868e2, 1.945506571482613964425e2)


def atan2(y, x):
    """``jnp.arctan2`` to within 4.5e-16 rad (max over 2·10⁶ random pairs, signed zeros and axes
    included), element-wise with one division and no branches, so that XLA vectorizes it (~4x
    faster than XLA's ``atan2`` on a CPU)."""
    ax, ay = jnp.abs(x), jnp.abs(y)
    hi, lo = jnp.maximum(ax, ay), jnp.minimum(ax, ay)
    t = lo / jnp.where(hi > 0, hi, 1.0)  # in [0, 1]
    big = t > 0.66
    u = jnp.where(big, (t - 1.0) / (t + 1.0), t)
    z = u * u
    pp, qq = _ATAN_P, _ATAN_Q
    num = (((pp[0] * z + pp[1]) * z + pp[2]) * z + pp[3]) * z + pp[4]
    den = ((((z + qq[0]) * z + qq[1]) * z + qq[2]) * z + qq[3]) * z + qq[4]
    r = u + u * (z * num / den)
    r = jnp.where(big, 0.25 * math.pi + r, r)  # atan t = π/4 + atan u
    r = jnp.where(ay > ax, 0.5 * math.pi - r, r)
    r = jnp.where(jnp.signbit(x), math.pi - r, r)
    return jnp.where(jnp.signbit(y), -r, r)


def masks_c(g, a, dt):
    """(dt_ok, gyr_ok, acc_ok, |acc|²) of each sample from component arrays ``g``, ``a`` (3-tuples,
    any layout): finite positive dt, finite gyro, finite non-zero accelerometer."""
    dt_ok = jnp.isfinite(dt) & (dt > 0)
    gyr_ok = jnp.isfinite(g[0]) & jnp.isfinite(g[1]) & jnp.isfinite(g[2]) & dt_ok
    acc_fin = jnp.isfinite(a[0]) & jnp.isfinite(a[1]) & jnp.isfinite(a[2])
    acc_n2 = jnp.where(acc_fin, a[0] * a[0] + a[1] * a[1] + a[2] * a[2], 0.0)
    acc_ok = dt_ok & (acc_n2 > 1e-6)
    return dt_ok, gyr_ok, acc_ok, acc_n2


def masks(gyr, acc, dt):
    """:func:`masks_c` of ``gyr``, ``acc`` (..., 3)."""
    return masks_c(tuple(gyr[..., i] for i in range(3)), tuple(acc[..., i] for i in range(3)), dt)


def flags(dt_ok, gyr_ok, acc_ok, disturbed, gap=False, reacq=False, reacquiring=False):
    f = (jnp.where(acc_ok | ~dt_ok, 0, ACC_MISSING) | jnp.where(gyr_ok | ~dt_ok, 0, GYR_MISSING)
         | jnp.where(dt_ok, 0, BAD_DT) | jnp.where(disturbed, ACC_DISTURBED, 0)
         | jnp.where(gap, DT_GAP, 0) | jnp.where(reacq, REACQUIRED, 0)
         | jnp.where(reacquiring, REACQUIRING, 0))
    return f.astype(jnp.int32)


def _run_chunk(x, data, params, block: int, names: tuple = (), gaps: bool = True):
    """Filter a chunk of ``n = nb * block`` samples from a block boundary of an initialized packed
    state ``x``: ``data`` (n, 7) = [gyr (3), acc (3), dt] per sample (one array: one host-to-device
    transfer per chunk). Returns ``(x, (soa, rows, flags))``:
    ``soa`` (9, block, nb) quaternion (4), up (3), roll, pitch of sample ``k`` of block ``j`` at
    ``[:, k, j]``; ``rows`` (nb, 32) per block: state at the start (q 4, b 3, diag P 7), after
    the update (the same 14), the disturbed and the re-acquired flags, and ``reacquire`` at the
    start and after the update (from which the host sets the REACQUIRING flag bit); ``flags``
    (block, nb) int32. The bias and variances of a sample are the block's start values, except
    at its last sample (the updated ones)."""
    # ``params``: a TiltParams, or its values as one vector with ``names`` its fields (one
    # argument: passing it costs less than passing 16 scalars)
    p = SimpleNamespace(**dict(zip(names, params, strict=True))) if names else params
    n = data.shape[0]
    nb = n // block
    # structure of arrays (one transpose): sample k of every block in one contiguous row
    ds = data.reshape(nb, block, 7).transpose(2, 1, 0)  # (7, block, nb)
    dt_ok_b, gyr_ok_b, acc_ok_b, acc_n2 = masks_c(ds[0:3], ds[3:6], ds[6])
    dts_b = jnp.where(dt_ok_b, ds[6], 0.0)
    wg_b = jnp.where(gyr_ok_b, dts_b, 0.0)  # Δt of a valid gyro sample
    wa_b = jnp.where(acc_ok_b, dts_b, 0.0)  # Δt of a valid accelerometer sample
    gx, gy, gz = (jnp.where(gyr_ok_b, ds[i], 0.0) for i in range(3))
    ax, ay, az = (jnp.where(acc_ok_b, ds[3 + i], 0.0) for i in range(3))
    e = qexp_c(gx * dts_b, gy * dts_b, gz * dts_b)
    # without gap handling the host guarantees that the chunk holds no gap
    gap_b = dts_b > p.gap_flag_s if gaps else jnp.zeros_like(dt_ok_b)

    # pre-integration: B sequential steps, each over all nb blocks at once
    def pre(c, k):
        dq, fx, fy, fz = c
        dq = qmul_c(dq, tuple(ei[k] for ei in e))
        w, u = dq[0], dq[1:]
        v = (ax[k], ay[k], az[k])
        t = (2.0 * (u[1] * v[2] - u[2] * v[1]), 2.0 * (u[2] * v[0] - u[0] * v[2]),
             2.0 * (u[0] * v[1] - u[1] * v[0]))
        r = tuple(v[i] + w * t[i] + (u[(i + 1) % 3] * t[(i + 2) % 3] - u[(i + 2) % 3] * t[(i + 1) % 3])
                  for i in range(3))
        wk = wa_b[k]
        return (dq, fx + r[0] * wk, fy + r[1] * wk, fz + r[2] * wk), jnp.stack(dq)

    one, zero = jnp.ones(nb), jnp.zeros(nb)
    (dq_end, fx, fy, fz), dq_all = jax.lax.scan(pre, ((one, zero, zero, zero), zero, zero, zero),
                                                jnp.arange(block))  # dq_all (block, 4, nb)
    tau_b = jnp.cumsum(wg_b, axis=0)
    dev2 = (jnp.sqrt(acc_n2) - p.g_m_s2) ** 2
    gg = gx * gx + gy * gy + gz * gz
    sums = jnp.stack([dq_end[0], dq_end[1], dq_end[2], dq_end[3], tau_b[-1], fx, fy, fz,
                      jnp.sum(wa_b, 0), jnp.sum(dev2 * wa_b, 0), jnp.sum(gg * dts_b, 0),
                      jnp.sum(dts_b, 0),
                      jnp.sum(jnp.where(gyr_ok_b & ~gap_b, 0.0,
                                        (p.omega_missing_rad_s * dts_b) ** 2), 0),
                      jnp.sum(gx * dts_b, 0), jnp.sum(gy * dts_b, 0), jnp.sum(gz * dts_b, 0),
                      jnp.sum(ax * wa_b, 0), jnp.sum(ay * wa_b, 0), jnp.sum(az * wa_b, 0),
                      jnp.sum(acc_n2 * wa_b, 0), jnp.sum(gap_b, 0).astype(jnp.float64)],
                     axis=1)  # (nb, NS)

    def body(xc, c):
        xn, disturbed, reacq = block_update_core(xc, c, p, gaps)
        diag = lambda v: v[9:58:8]  # noqa: E731  diagonal of the packed P
        pend = (jnp.stack([xc[60], xn[60]]) if gaps  # (reading them costs ~30 % when no gap)
                else jnp.zeros(2))
        row = jnp.concatenate([xc[0:7], diag(xc), xn[0:7], diag(xn), disturbed[None],
                               reacq[None], pend])
        return xn, row

    x, rows = jax.lax.scan(body, x, block_inputs(sums, p))  # rows (nb, 32)
    q0 = tuple(rows[:, i] for i in range(4))
    b0 = rows[:, 4:7]
    # per-sample quaternion: q0 ⊗ dq_k ⊗ exp(−b0 τ_k), normalized; the block's last sample
    # carries the updated estimate
    qb = qexp_c(-b0[:, 0] * tau_b, -b0[:, 1] * tau_b, -b0[:, 2] * tau_b)
    dq = tuple(dq_all[:, i] for i in range(4))
    q = _qnorm_c(qmul_c(qmul_c(q0, dq), qb))  # each (block, nb)
    last = jnp.arange(block)[:, None] == block - 1
    q = tuple(jnp.where(last, rows[:, 14 + i], q[i]) for i in range(4))
    w, qx, qy, qz = q
    upx = 2 * (qx * qz - w * qy)
    upy = 2 * (qy * qz + w * qx)
    upz = 1 - 2 * (qx * qx + qy * qy)
    roll = atan2(upy, upz)
    pitch = atan2(-upx, jnp.sqrt(upy * upy + upz * upz))

    dist = jnp.zeros((block, nb), dtype=bool).at[-1].set(rows[:, 28] > 0.5)
    reacq = jnp.zeros((block, nb), dtype=bool).at[-1].set(rows[:, 29] > 0.5) if gaps else False
    # REACQUIRING (rare: after a gap) is set by the host from rows[:, 30:32] (tilt._put_chunk);
    # computing it here costs a third of the chunk's time (XLA's fusion of it)
    fl = flags(dt_ok_b, gyr_ok_b, acc_ok_b, dist, gap_b, reacq)  # (block, nb), like soa
    # the host writes these straight into the sample-major result arrays (a transposing copy
    # there is cheaper than XLA's transpose here, and bias/var need no per-sample array at all)
    return x, (jnp.stack([w, qx, qy, qz, upx, upy, upz, roll, pitch]), rows, fl)



# one compilation for every parameter value (``tilt.run`` puts the parameters on the device once
# per recording, so that a call transfers only its chunk)
run_chunk = jax.jit(_run_chunk, static_argnames=("block", "names", "gaps"))

NZ = NX + NS + 2  # streaming state: filter (NX), block sums (NS), block count, initialized


def stream_init(x, initialized):
    """Packed streaming state from a packed block-boundary filter state ``x`` (NX,)."""
    s0 = jnp.zeros(NS).at[0].set(1.0)
    return jnp.concatenate([jnp.asarray(x, dtype=jnp.float64), s0,
                            jnp.array([0.0, 1.0 if initialized else 0.0])])


def stream_step(z, sample, params, block: int):
    """``tilt.step`` on the packed streaming state ``z`` (NZ,) with ``sample`` = (gyr(3), acc(3),
    dt): returns ``(z, out)`` with ``out`` = [roll, pitch, up(3), quat(4), bias(3), flags]."""
    p = params
    gyr, acc, dt = sample[0:3], sample[3:6], sample[6]
    dt_ok, gyr_ok, acc_ok, acc_n2 = masks(gyr, acc, dt)
    dts = jnp.where(dt_ok, dt, 0.0)
    gyr0 = jnp.where(gyr_ok, gyr, 0.0)
    acc0 = jnp.where(acc_ok, acc, 0.0)
    x, s = z[:NX], z[NX:NX + NS]
    count, initialized = z[NX + NS], z[NX + NS + 1] > 0.5
    dq = _qmul_vec(s[0:4], _qexp_vec(gyr0 * dts))
    wa = jnp.where(acc_ok, dts, 0.0)
    wg = jnp.where(gyr_ok, dts, 0.0)
    dev2 = (jnp.sqrt(acc_n2) - p.g_m_s2) ** 2
    gap = dts > p.gap_flag_s
    s_acc = jnp.concatenate([
        dq, s[4:5] + wg, s[5:8] + _qrotate_vec(dq, acc0) * wa, s[8:9] + wa,
        s[9:10] + dev2 * wa, s[10:11] + jnp.sum(gyr0 * gyr0) * dts, s[11:12] + dts,
        s[12:13] + jnp.where(gyr_ok & ~gap, 0.0, (p.omega_missing_rad_s * dts) ** 2),
        s[13:16] + gyr0 * dts, s[16:19] + acc0 * wa, s[19:20] + acc_n2 * wa,
        s[20:21] + jnp.where(gap, 1.0, 0.0)])
    # before initialization: the first usable accelerometer sample sets the tilt, to be
    # re-acquired after reacquire_s (``tilt.step``)
    init_now = ~initialized & acc_ok
    a = acc0 / jnp.sqrt(jnp.where(acc_n2 > 0, acc_n2, 1.0))
    w = 1.0 + a[2]
    q_init = jnp.where(w < 1e-9, jnp.array([0.0, 1.0, 0.0, 0.0]),
                       jnp.stack([w, a[1], -a[0], 0.0]))
    q_init = q_init / jnp.sqrt(jnp.sum(q_init * q_init))
    x_init = jnp.concatenate([q_init, x[4:9], widen_tilt(x[9:58].reshape(7, 7),
                                                         p.init_tilt_rad).reshape(-1),
                              x[58:60], jnp.array([1.0, 0.0, 0.0, 0.0, 0.0])])
    x = jnp.where(init_now, x_init, x)
    s = jnp.where(initialized, s_acc, s)
    count = jnp.where(initialized, count + 1, count)
    initialized = initialized | init_now

    def close(args):
        x, s = args
        c = block_inputs(s, p)
        # the update without gap handling unless a gap is in sight (as run_chunk does)
        xn, disturbed, reacq = jax.lax.cond(
            (x[60] > 0.5) | (s[20] > 0), lambda c: block_update_core(x, c, p, True),
            lambda c: block_update_core(x, c, p, False), c)
        return xn, jnp.zeros(NS).at[0].set(1.0), disturbed, reacq

    x, s, disturbed, reacq = jax.lax.cond(initialized & (count >= block), close,
                                          lambda a: (a[0], a[1], jnp.array(False), jnp.array(False)),
                                          (x, s))
    count = jnp.where(count >= block, 0.0, count)
    q = _qmul_vec(_qmul_vec(x[0:4], s[0:4]), _qexp_vec(-x[4:7] * s[4]))
    q = jnp.where(count == 0, x[0:4], q / jnp.sqrt(jnp.sum(q * q)))
    w, qx, qy, qz = q[0], q[1], q[2], q[3]
    up = jnp.stack([2 * (qx * qz - w * qy), 2 * (qy * qz + w * qx), 1 - 2 * (qx * qx + qy * qy)])
    roll = jnp.arctan2(up[1], up[2])
    pitch = jnp.arctan2(-up[0], jnp.sqrt(up[1] ** 2 + up[2] ** 2))
    fl = (flags(dt_ok, gyr_ok, acc_ok, disturbed, gap, reacq, (x[60] > 0.5) | (s[20] > 0))
          | jnp.where(init_now, 16, 0))
    z = jnp.concatenate([x, s, jnp.stack([count, initialized.astype(jnp.float64)])])
    out = jnp.concatenate([jnp.stack([roll, pitch]), up, q, x[4:7], fl.astype(jnp.float64)[None]])
    return z, out
