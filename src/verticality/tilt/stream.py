"""Plain-Python/NumPy reference implementation of the 3-D tilt filter, for real-time loops.

A jitted JAX step pays a dispatch and ~50 small XLA kernels per call on a CPU, too slow for a 1 kHz
robot loop within 5 % of a core (docs/tilt.md, "Python API"). This module runs the filter of
:mod:`verticality.tilt` (the equations of ``tilt_core.step``; the every-``block``-samples
Kalman update is ``tilt_core.block_update``) with scalar ``math`` for the per-sample
pre-integration and NumPy for the block update. It is deliberately written apart from the JAX
core, sharing nothing with it but the constants (flag bits, default parameters), as PyVQF stands
beside VQF's C++: each checks the other. tests/test_tilt_reference.py compares the two on a
BROAD slice and on synthetic recordings with NaNs in every channel, irregular Δt, gaps, dropouts
and a start in motion, to ≤ 1e-9. Use it for sample-by-sample loops; use ``TiltFilter.run`` (or
``tilt.estimate``) for recordings.
"""

from __future__ import annotations

import math
import struct

import numpy as np

from verticality.tilt.flags import (
    ACC_DISTURBED,
    ACC_MISSING,
    BAD_DT,
    CLIPPED,
    DT_GAP,
    GYR_MISSING,
    HELD,
    INIT,
    OUT_OF_RANGE,
    REACQUIRED,
    REACQUIRING,
)
from verticality.tilt.limits import EXCESS_FRACTION
from verticality.tilt.params import (
    DEFAULT_P0,
    DEFAULT_PARAMS,
    GAP_TOLERANCE_S,
    MAX_ACC_M_S2,
    MAX_DT_S,
    MAX_RATE_RAD_S,
    block_samples,
)


def _qmul(p, q):
    pw, px, py, pz = p
    qw, qx, qy, qz = q
    return (pw * qw - px * qx - py * qy - pz * qz, pw * qx + px * qw + py * qz - pz * qy,
            pw * qy - px * qz + py * qw + pz * qx, pw * qz + px * qy - py * qx + pz * qw)


def _qexp(vx, vy, vz):
    th2 = vx * vx + vy * vy + vz * vz
    if th2 < 1e-12:
        k, c = 0.5 - th2 / 48.0, 1.0 - th2 / 8.0
    else:
        th = math.sqrt(th2)
        k, c = math.sin(0.5 * th) / th, math.cos(0.5 * th)
    return (c, k * vx, k * vy, k * vz)


def _qnorm(q):
    n = math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    return (q[0] / n, q[1] / n, q[2] / n, q[3] / n)


def _rotate(q, v):
    w, ux, uy, uz = q
    tx, ty, tz = (2.0 * (uy * v[2] - uz * v[1]), 2.0 * (uz * v[0] - ux * v[2]),
                  2.0 * (ux * v[1] - uy * v[0]))
    return (v[0] + w * tx + (uy * tz - uz * ty), v[1] + w * ty + (uz * tx - ux * tz),
            v[2] + w * tz + (ux * ty - uy * tx))


def _tilt_error_from_force(f):
    """``tilt_core.tilt_error_from_force`` in plain Python."""
    n = math.sqrt(f[0] * f[0] + f[1] * f[1] + f[2] * f[2])
    u = (f[0] / n, f[1] / n, f[2] / n) if n > 0 else (0.0, 0.0, 1.0)
    s = math.hypot(u[0], u[1])
    k = math.atan2(s, u[2]) / s if s > 1e-12 else 1.0
    return np.array([k * u[1], -k * u[0]])


def _kf(P, i0, m, z, r):
    """Joseph-form update for z = x[i0:i0+m] + n, n ~ N(0, r I) (as ``tilt_core.joseph_update``)."""
    ne = P.shape[0]
    H = np.zeros((m, ne))
    H[np.arange(m), i0 + np.arange(m)] = 1.0
    PHt = P[:, i0:i0 + m]
    S = P[i0:i0 + m, i0:i0 + m] + r * np.eye(m)
    K = PHt @ np.linalg.inv(S)
    IKH = np.eye(ne) - K @ H
    P = IKH @ P @ IKH.T + r * (K @ K.T)
    return K @ z, 0.5 * (P + P.T)


def _widen_tilt(P, var_rad2):
    """A copy of ``P`` with ``var_rad2`` added to both tilt variances
    (``tilt_core.add_tilt_variance`` in NumPy)."""
    P = P.copy()
    P[0, 0] += var_rad2
    P[1, 1] += var_rad2
    return P


def _clipped(v, ranges, run_t, dt):
    """Whether the sample ``v`` (3,) has a component at or beyond its full scale ``ranges`` (None:
    no range), and the variance its unknown excess adds: per clipped axis an unknown constant of
    σ = ``EXCESS_FRACTION`` × range over the clipped run, ``σ² (t_k² − t_{k−1}²)``. ``run_t``
    (3,) each axis's run so far, updated in place."""
    clipped, var = False, 0.0
    for i in range(3):
        if ranges is not None and math.isfinite(v[i]) and abs(v[i]) >= ranges[i]:
            clipped = True
            t0 = run_t[i]
            run_t[i] = t1 = t0 + dt
            var += (EXCESS_FRACTION * ranges[i]) ** 2 * (t1 * t1 - t0 * t0)
        else:
            run_t[i] = 0.0
    return clipped, var


class Stream:
    """Sample-by-sample tilt filter: ``s = Stream()``, ``out = s.step(gyr, acc, dt)`` with
    ``out = (roll, pitch, up(3), quat(4), bias(3), flags)`` — the per-sample outputs of
    ``TiltFilter.step`` (variances in :attr:`P`, the tilt's standard deviation in
    :attr:`tilt_sigma_rad`). ``params`` is a ``TiltParams``.

    Sensors at their limits, as ``tilt.estimate`` treats them (``tilt_limits``), sample by sample:
    ``gyr_range_rad_s``, ``acc_range_m_s2`` the full-scale readings (scalar or one per axis; None:
    no clipping; a stream cannot infer them from the recording's flat tops). A gyro component at or
    beyond its range adds the variance of an unknown constant excess rate (σ = ``EXCESS_FRACTION``
    × range) over its clipped run to the tilt; an accelerometer component there is kept (the
    other components are right, the clipped one a lower bound) and the same unknown excess over its
    run widens the velocity; both flag ``CLIPPED``. A sample repeating the previous one bit for bit
    is flagged ``HELD``."""

    def __init__(self, params=None, block: int | None = None, P0=None, x0=None,
                 gyr_range_rad_s=None, acc_range_m_s2=None, period_s: float | None = None):
        self.gyr_range = None if gyr_range_rad_s is None else [
            float(v) for v in np.broadcast_to(np.asarray(gyr_range_rad_s, dtype=float), (3,))]
        self.acc_range = None if acc_range_m_s2 is None else [
            float(v) for v in np.broadcast_to(np.asarray(acc_range_m_s2, dtype=float), (3,))]
        self.clip_t = [0.0, 0.0, 0.0]  # how long each gyro axis has been clipped
        self.acc_clip_t = [0.0, 0.0, 0.0]  # and each accelerometer axis
        self.prev_bits = None  # the previous sample's six channels, as bytes
        self.gyr_prev = (math.nan, math.nan, math.nan)  # its gyro reading (a gap's start rate)
        self.p = DEFAULT_PARAMS if params is None else params
        # samples per update: given, or params.update_s at the sampling period (given, or the
        # first step integrated after the initialization)
        self.block = (block_samples(self.p, period_s) if block is None and period_s is not None
                      else block)
        self.P = np.array(DEFAULT_P0 if P0 is None else P0, dtype=np.float64)
        if x0 is None:
            self.q, self.b, self.initialized = (1.0, 0.0, 0.0, 0.0), [0.0, 0.0, 0.0], False
        else:
            self.q = _qnorm(tuple(float(c) for c in x0[0]))
            self.b, self.initialized = [float(c) for c in x0[1]], True
        self.s = [0.0, 0.0, 0.0]  # the gyro's scale-factor error per axis (reads 1 + s times)
        self.vel = np.zeros(2)
        self.acc_dev_var = 0.0
        self.rest_s = 0.0
        self.reacquire = False
        self.reacq_f_E = np.zeros(3)
        self.reacq_t = 0.0
        self.vel_inn = np.zeros(2)  # running mean of the whitened velocity innovations
        self.vel_fix = np.zeros(5)  # the tilt and bias corrections the velocity made over it
        self.speed2 = 0.0  # low-passed per-axis mean square of the velocity
        self.dv2 = 0.0  # and of its change over a block
        self.u = np.zeros(2)  # the horizontal velocity changes integrated with a leak
        self.sp2 = self.p.vel_m_s**2  # the motion's per-axis mean square speed
        self._zero()

    @property
    def tilt_sigma_rad(self) -> float:
        """Standard deviation of the tilt (rad) at the last step, ``sqrt(var_δx + var_δy +
        (acc_calib_m_s2 / g)²)`` (``tilt.tilt_sigma_rad``, the value ``TiltFilter.run`` reports
        for that sample) with what gyro dropouts and gaps have added since the block's start;
        before the initialization, when there is no estimate yet, the initialization's."""
        p = self.p
        widen = self.qmiss if self.initialized else p.init_tilt_rad**2
        P = _widen_tilt(self.P, widen)
        return math.sqrt(P[0, 0] + P[1, 1] + (p.acc_calib_m_s2 / p.g_m_s2) ** 2)

    def _zero(self):
        self.dq = (1.0, 0.0, 0.0, 0.0)
        self.tau = self.t_acc = self.dev2 = self.w2 = self.t = self.qmiss = self.a2 = 0.0
        self.vmiss = 0.0
        self.gap = 0
        self.f = [0.0, 0.0, 0.0]
        self.gsum = [0.0, 0.0, 0.0]
        self.asum = [0.0, 0.0, 0.0]
        self.count = 0

    def step(self, gyr, acc, dt, tilt_var=0.0, flags=0):
        """One sample; ``tilt_var`` (rad²) and ``flags``: what its time step adds (a clock
        jump's, :mod:`verticality.tilt.clock`), as ``tilt_core.step`` takes them."""
        p = self.p
        gx, gy, gz = float(gyr[0]), float(gyr[1]), float(gyr[2])
        ax, ay, az = float(acc[0]), float(acc[1]), float(acc[2])
        gyr3, acc3 = (gx, gy, gz), (ax, ay, az)
        dt = float(dt)
        dt_ok = 0.0 < dt < MAX_DT_S
        bits = struct.pack("6d", gx, gy, gz, ax, ay, az)
        held = bits == self.prev_bits and not any(math.isnan(v) for v in (*gyr3, *acc3))
        self.prev_bits = bits
        # clipping: a component at or beyond the given full scale; the reading is kept and its
        # unknown excess widens the tilt (gyro) or the velocity (accelerometer)
        gyr_clipped, clip_var = _clipped(gyr3, self.gyr_range, self.clip_t, dt if dt_ok else 0.0)
        acc_clipped, clip_vvar = _clipped(acc3, self.acc_range, self.acc_clip_t,
                                          dt if dt_ok else 0.0)
        gyr_ok = dt_ok and abs(gx) < MAX_RATE_RAD_S and abs(gy) < MAX_RATE_RAD_S \
            and abs(gz) < MAX_RATE_RAD_S
        acc_in = abs(ax) < MAX_ACC_M_S2 and abs(ay) < MAX_ACC_M_S2 and abs(az) < MAX_ACC_M_S2
        n2 = ax * ax + ay * ay + az * az if acc_in else 0.0
        acc_ok = dt_ok and n2 > 1e-6
        dts = dt if dt_ok else 0.0
        if not gyr_ok:
            gx = gy = gz = 0.0
        if not acc_ok:
            ax = ay = az = 0.0
        init_now = False
        gap = dts > p.gap_flag_s + GAP_TOLERANCE_S
        wr = dts  # the time the rate is integrated over
        g0 = self.gyr_prev
        if (gap and gyr_ok and p.gap_rate_corr_s > 0
                and all(abs(v) < MAX_RATE_RAD_S for v in g0)):
            # the gap bridged from the rates at both its ends (the rate an Ornstein-Uhlenbeck
            # process of correlation time tau): their mean over 2 tau tanh(T / 2 tau)
            half = dts / (2.0 * p.gap_rate_corr_s)
            wr = dts * (1.0 - half * half / 3.0 if half < 1e-4 else math.tanh(half) / half)
            gx, gy, gz = 0.5 * (g0[0] + gx), 0.5 * (g0[1] + gy), 0.5 * (g0[2] + gz)
        self.gyr_prev = gyr3
        if self.initialized:
            if self.block is None and dt_ok:  # the first step integrated sets the update's length
                self.block = block_samples(p, dt)
            self.dq = dq = _qmul(self.dq, _qexp(gx * wr, gy * wr, gz * wr))
            wa = dts if acc_ok else 0.0
            if gyr_ok:
                self.tau += wr
            if gap or not gyr_ok:  # the rotation inside a gap is unknown
                self.qmiss += (p.omega_missing_rad_s * dts) ** 2
            if dt_ok:  # a clipped gyro or accelerometer axis's unknown excess, a clock jump's
                self.qmiss += clip_var + tilt_var
                self.vmiss += clip_vvar
            self.gap += gap
            r = _rotate(dq, (ax, ay, az))
            f, gs, as_ = self.f, self.gsum, self.asum
            for i, (gi, ai) in enumerate(((gx, ax), (gy, ay), (gz, az))):
                f[i] += r[i] * wa
                gs[i] += gi * wr
                as_[i] += ai * wa
            self.t_acc += wa
            self.dev2 += (math.sqrt(n2) - p.g_m_s2) ** 2 * wa
            self.w2 += (gx * gx + gy * gy + gz * gz) * wr
            self.t += dts
            self.a2 += n2 * wa
            self.count += 1
        elif acc_ok:
            init_now = True
            n = math.sqrt(n2)
            ux, uy, uz = ax / n, ay / n, az / n
            w = 1.0 + uz
            self.q = (0.0, 1.0, 0.0, 0.0) if w < 1e-9 else _qnorm((w, uy, -ux, 0.0))
            self.initialized = True
            # the sample may hold an inertial acceleration: re-acquire after reacquire_s
            self.reacquire = True
            self.P = _widen_tilt(self.P, p.init_tilt_rad**2)
        disturbed = reacq = False
        if self.initialized and self.block is not None and self.count >= self.block:
            disturbed, reacq = self._update()
        if self.count == 0:
            q = self.q
        else:
            b, s, gs = self.b, self.s, self.gsum
            q = _qnorm(_qmul(_qmul(self.q, self.dq),
                             _qexp(*(-(b[i] * self.tau + s[i] * gs[i]) for i in range(3)))))
        w, x, y, z = q
        up = (2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y))
        fl = ((0 if acc_ok or not dt_ok else ACC_MISSING)
              | (0 if gyr_ok or not dt_ok else GYR_MISSING)
              | (0 if dt_ok else BAD_DT) | (ACC_DISTURBED if disturbed else 0)
              | (INIT if init_now else 0) | (DT_GAP if gap else 0) | (REACQUIRED if reacq else 0)
              | (REACQUIRING if self.reacquire or self.gap > 0 else 0)
              | (OUT_OF_RANGE if any(abs(v) >= MAX_RATE_RAD_S for v in gyr3)
                 or any(abs(v) >= MAX_ACC_M_S2 for v in acc3) else 0)
              | (CLIPPED if gyr_clipped or acc_clipped else 0) | (HELD if held else 0) | flags)
        return (math.atan2(up[1], up[2]), math.atan2(-up[0], math.hypot(up[1], up[2])), up, q,
                tuple(self.b), fl)

    def _update(self) -> tuple[bool, bool]:
        """The block update (T eq. 2, 7–13 in 3-D) in NumPy; (disturbed, re-acquired)."""
        p = self.p
        g = p.g_m_s2
        b, s, G = np.array(self.b), np.array(self.s), np.array(self.gsum)
        # the gyro read as ω (1 + s) + b: the block's rotation corrected by b τ + s ⊙ Σ ω Δt
        q_end = _qnorm(_qmul(_qmul(self.q, self.dq), _qexp(*(-(b * self.tau + s * G)))))
        w, x, y, z = q_end
        R2 = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                       [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)]])
        T, t_acc, tau = self.t, self.t_acc, self.tau
        has_acc = t_acc > 0
        t_acc_s = t_acc if has_acc else 1.0
        f_E = _rotate(self.q, self.f)
        vel = self.vel + np.array(f_E)[:2]
        A = -T * R2
        gJ = g * np.array([[0.0, 1.0], [-1.0, 0.0]])
        A_s = -R2 * G[None, :]  # the scale errors act as the bias errors, weighted by Σ ω Δt
        F = np.eye(10)
        F[:2, 4:7], F[:2, 7:] = A, A_s
        F[2:4, :2] = T * gJ
        F[2:4, 4:7], F[2:4, 7:] = 0.5 * T * gJ @ A, 0.5 * T * gJ @ A_s
        q_gyr = p.gyr_noise**2 * tau + p.gyr_scale_noise**2 * self.w2 + self.qmiss
        q_vel = p.acc_noise**2 * t_acc + (p.acc_missing_m_s2 * (T - t_acc)) ** 2 + self.vmiss
        qb = p.bias_walk**2 * T
        P = F @ self.P @ F.T + np.diag([q_gyr, q_gyr, q_vel, q_vel, qb, qb, qb, 0.0, 0.0, 0.0])
        dev2 = self.dev2 / t_acc_s
        has_gyr = tau > 0
        tau_s = tau if has_gyr else 1.0
        g_mean = np.array(self.gsum) / tau_s
        g_var = max(self.w2 / (T if T > 0 else 1.0) - g_mean @ g_mean, 0.0)
        a_mean = np.array(self.asum) / t_acc_s
        a_var = max(self.a2 / t_acc_s - a_mean @ a_mean, 0.0)
        gap = self.gap > 0
        # the block is steady: gyro and accelerometer without variation within it
        steady = (has_gyr and has_acc and g_var < p.rest_gyr_rad_s**2
                  and a_var < p.rest_acc_m_s2**2 and not gap)
        if has_acc:
            # a steady block shows the disturbance as it is now: there the low-pass follows it
            # within acc_tau_steady_s (0: at once), not with the memory of an event that is over
            tau_d = p.acc_tau_steady_s if steady else p.acc_tau_s
            alpha = 1.0 - math.exp(-t_acc / tau_d) if tau_d > 0 else 1.0
            self.acc_dev_var += alpha * (dev2 - self.acc_dev_var)
        disturbed = has_acc and self.acc_dev_var > p.acc_disturbed_m_s2**2
        gd = g_mean - b
        collecting = self.reacquire and not gap
        # the gyro mean at rest is the bias: within rest_gyr of the estimate, or, whatever the
        # estimate (which a violent event may have corrupted), a gyro that reads no rotation
        quiet = steady and (gd @ gd < p.rest_gyr_rad_s**2
                            or g_mean @ g_mean < p.rest_gyr_raw_rad_s**2)
        self.rest_s = self.rest_s + T if quiet else 0.0
        at_rest = self.rest_s >= p.rest_min_s
        # the velocity's rest prior (the tilt) may start sooner than the bias's rest update
        still = self.rest_s >= p.rest_tilt_s
        dx = np.zeros(10)
        f_sum = self.reacq_f_E + np.array(f_E) if collecting else np.zeros(3)
        t_sum = self.reacq_t + t_acc if collecting else 0.0
        reacq = collecting and t_sum >= p.reacquire_s
        if reacq:  # after a gap: the tilt from the mean specific force since the gap
            v_r = p.vel_rest_m_s if self.rest_s >= t_sum else p.vel_m_s  # quiet since the gap
            dx, P = _kf(P, 0, 2, _tilt_error_from_force(f_sum), 2.0 * (v_r / (g * t_sum)) ** 2)
        jump = kept = False
        if has_acc and not gap and not collecting:
            s_vel = (p.vel_rest_m_s**2 if still else p.vel_m_s**2) * p.vel_corr_s
            S = P[2:4, 2:4] + (s_vel / t_acc_s) * np.eye(2)
            jump = bool(vel @ np.linalg.solve(S, vel) > p.vel_jump_nis)  # a kick: not the tilt
            # a velocity beyond the prior for longer than its correlation time: the running mean
            # of the whitened innovations, N(0, (1 − λ)/(1 + λ) I) when consistent
            lam = math.exp(-T / p.vel_corr_s)
            # the motion's own correlation time from its velocity and velocity-change moments:
            # a block changes a velocity of correlation time τ by E[Δv²] = 2 E[v²] (1 − e^(−T/τ))
            dv = np.array(f_E)[:2]
            self.speed2 = lam * self.speed2 + (1.0 - lam) * float(vel @ vel) / 2.0
            self.dv2 = lam * self.dv2 + (1.0 - lam) * float(dv @ dv) / 2.0
            share = min(max(self.dv2 / max(2.0 * self.speed2, 1e-12), 1.0 - lam),
                        1.0 - math.exp(-1.0))
            tau_motion = p.vel_corr_s if still else -T / math.log(1.0 - share)
            inn = lam * self.vel_inn + (1.0 - lam) * np.linalg.solve(np.linalg.cholesky(S), -vel)
            persist = not jump and bool(inn @ inn * (1.0 + lam) / (1.0 - lam) > p.vel_jump_nis)
            v_dist = math.sqrt(self.acc_dev_var) / (2.0 * math.pi * p.vel_disturbed_hz)
            widen = max(1.0, (v_dist / p.vel_m_s) ** 2)  # the speed a disturbance makes
            if persist:  # that window's tilt and bias corrections may be wrong: widen by them
                P = _widen_tilt(P, float(self.vel_fix[:2] @ self.vel_fix[:2]))
                P[4:7, 4:7] += np.diag(self.vel_fix[2:] ** 2)  # and the bias's
            elif not jump:
                dx, P1 = _kf(P, 2, 2, -vel,
                             widen * s_vel / t_acc_s * tau_motion / p.vel_corr_s)
                self.vel_fix = lam * self.vel_fix + np.concatenate([dx[:2], dx[4:7]])
                self.vel_inn, kept, P = inn, True, P1
            jump = jump or persist
        if not kept and (has_acc or gap or collecting):
            self.vel_inn, self.vel_fix = np.zeros(2), np.zeros(5)
        disturbed = disturbed or jump
        forget = gap or collecting or jump
        if forget:  # the velocity integrated across a gap (or a kick) means nothing
            P[2:4, :] = 0.0
            P[:, 2:4] = 0.0
            P[2, 2] = P[3, 3] = p.vel_m_s**2
        if at_rest:
            r_b = p.gyr_noise**2 / tau_s + p.rest_motion_rad_s**2
            dx3, P = _kf(P, 4, 3, g_mean - (b + dx[4:7]), r_b)
            dx = dx + dx3
        self.q = _qnorm(_qmul(_qexp(dx[0], dx[1], 0.0), q_end))
        self.b = [float(v) for v in b + dx[4:7]]
        self.s = [float(v) for v in s + dx[7:]]
        self.vel = np.zeros(2) if forget else vel + dx[2:4]
        self.P = P
        self.reacquire = gap or (collecting and not reacq)
        self.reacq_f_E = f_sum if self.reacquire else np.zeros(3)
        self.reacq_t = t_sum if self.reacquire else 0.0
        self._zero()
        return bool(disturbed), reacq
