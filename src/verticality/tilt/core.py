"""The core of the 3-D otolith–canal tilt filter (:mod:`verticality.tilt`), written
once: the per-sample pre-integration, the block update (prediction, velocity pseudo-measurement,
re-acquisition after a gap or the start, rest/bias update), the initialization from the
accelerometer, the sample's validity and flags, and the per-sample step built from them.

Three paths run these functions: the per-sample :func:`step` (and the real-time stepper
``tilt.make_step``, which wraps it), and the batch kernel
(:func:`verticality.tilt.kernels.run_chunk`), which applies the same per-sample terms
and the same block update to many blocks at once. The filter lives in flat vectors whose fields
are named in :mod:`verticality.tilt.layout` (``X`` the filter, ``S`` the block sums,
``C`` the per-block inputs, ``E`` the error state). The plain-Python
:class:`~verticality.tilt.stream.Stream` is an independent reference implementation of
the same filter, tested against this core (tests/test_tilt_reference.py).

Functions that the host side of the batch run also needs on NumPy arrays (sample validity, flags,
the initialization, the output angles) take ``xp`` (``jax.numpy`` or ``numpy``): one code for both.

The model (T eq. 1–13 in 3-D; docs/tilt.md): nominal state ``q_E_S``, gyro bias ``b_S``,
horizontal velocity ``v_E``, gyro scale-factor error ``s`` (the gyro reads ``(1 + s) ω + b``);
error state (10) tilt ``δ`` (``R_true = exp([δ, 0]) R_est``), velocity ``ṽ``, bias ``b̃``, scale
``s̃``; prediction ``δ̇ = −Π R (b̃ + s̃ ⊙ ω)``, ``ṽ̇ = g J δ``, bias random walk (T eq. 2, 7, 12),
constant scale;
the velocity pseudo-measurement ``0 = v + n_v`` (T §I, eq. 4–5: accelerations are short and
periodic, so the velocity they produce stays small); Joseph-form updates.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from verticality.core import so3
from verticality.tilt.flags import (
    ACC_DISTURBED,
    ACC_MISSING,
    BAD_DT,
    DT_GAP,
    GYR_MISSING,
    INIT,
    OUT_OF_RANGE,
    REACQUIRED,
    REACQUIRING,
)
from verticality.tilt.layout import NE, C, E, S, X
from verticality.tilt.params import (
    GAP_TOLERANCE_S,
    MAX_ACC_M_S2,
    MAX_DT_S,
    MAX_RATE_RAD_S,
)


class TiltState(NamedTuple):
    """The filter state: ``x`` the filter at the start of the current block and ``sums`` the
    block's samples so far (flat vectors, fields named in :mod:`~verticality.estimators.
    tilt_layout`: ``X`` and ``S``), ``count`` the samples in the block, ``initialized`` whether an
    accelerometer sample (or ``x0``) has set the tilt, ``gyr_prev`` the last sample's gyro
    reading (the rate before a gap). Read the fields through the properties."""

    x: jax.Array  # (X.size,)
    sums: jax.Array  # (S.size,)
    count: jax.Array  # () int32
    initialized: jax.Array  # () bool
    gyr_prev: jax.Array  # (3,) the previous sample's gyro reading (NaN before the first): the
    #                      rate at a gap's start (bridge_share)

    @property
    def quat_E_S(self):
        """(4,) wxyz sensor → Earth at the block start (heading arbitrary)."""
        return self.x[..., X.q]

    @property
    def bias_S_rad_s(self):
        return self.x[..., X.b]

    @property
    def gyr_scale(self):
        """(3,) the gyro's scale-factor error per axis: it reads ``(1 + s) ω + b``."""
        return self.x[..., X.s]

    @property
    def vel_E_m_s(self):
        """(2,) horizontal velocity in Earth (m/s), kept bounded by the pseudo-measurement."""
        return self.x[..., X.v]

    @property
    def P(self):
        """(10, 10) covariance of the error state (δx, δy, ṽx, ṽy, b̃x, b̃y, b̃z, s̃x, s̃y, s̃z) at
        the block start."""
        return self.x[..., X.P].reshape(self.x.shape[:-1] + (NE, NE))

    @property
    def rest_s(self):
        return self.x[..., X.rest_s]

    @property
    def reacquire(self):
        """Whether the tilt is to be re-acquired (after a gap or the start)."""
        return self.x[..., X.reacquire] > 0.5


class TiltOutput(NamedTuple):
    roll_rad: jax.Array
    pitch_rad: jax.Array
    up_S: jax.Array  # (3,) unit vector "up" (opposite to gravity) in the sensor frame
    quat_E_S: jax.Array  # (4,) wxyz, heading arbitrary
    bias_S_rad_s: jax.Array  # (3,)
    var: jax.Array  # (10,) variances of (δx, δy [rad²], ṽx, ṽy [m²/s²], b̃x, b̃y, b̃z [rad²/s²],
    #                 s̃x, s̃y, s̃z)
    flags: jax.Array  # int32 bit set (verticality.tilt.flags)
    measured: jax.Array  # bool: the accelerometer sample entered the filter


# --- the sample: validity, flags, per-sample terms of the pre-integration ---

def valid_dt(dt):
    """Whether a sample's Δt can be used: positive and below ``MAX_DT_S`` (so finite; else the
    sample is skipped). NumPy or JAX arrays."""
    return (dt > 0) & (dt < MAX_DT_S)


def is_gap(dts, p):
    """Whether a sample's valid Δt (``dts``, 0 where not valid) spans a gap in the recording:
    longer than ``gap_flag_s`` by more than the rounding of a regular clock
    (``GAP_TOLERANCE_S``)."""
    return dts > p.gap_flag_s + GAP_TOLERANCE_S


def gaps_in(dt, p, xp=jnp):
    """Which samples of raw steps ``dt`` span a gap in the recording (a valid Δt above
    ``gap_flag_s``; flag DT_GAP)."""
    return is_gap(xp.where(valid_dt(dt), dt, 0.0), p)


def gyr_in_range(g, xp=jnp):
    """Whether gyro readings ``g`` (component axis first, as :func:`masks`) are readings: every
    component finite and below ``MAX_RATE_RAD_S`` (their time step not judged)."""
    return ((xp.abs(g[0]) < MAX_RATE_RAD_S) & (xp.abs(g[1]) < MAX_RATE_RAD_S)
            & (xp.abs(g[2]) < MAX_RATE_RAD_S))


def bridge_share(dts, tau_s, xp=jnp):
    """The share ``2τ tanh(T / 2τ) / T`` of a gap of ``T = dts`` s that the rates at its two ends
    carry (docs/tilt.md, "Gaps."): the angular rate inside the gap taken as a stationary
    Ornstein–Uhlenbeck process of correlation time ``τ = tau_s`` known at both ends (ω0 before,
    ω1 after), its integral over the gap has the conditional mean ``(ω0 + ω1) τ tanh(T / 2τ)``,
    i.e. the ends' mean rate over ``T`` times this share: 1 for ``T ≪ τ`` (the trapezoid; also
    ``τ = inf``), ``2τ / T`` for ``T ≫ τ``."""
    tau = xp.where(tau_s > 0, tau_s, 1.0)
    x = dts / (2.0 * tau)  # 0 for tau_s = inf
    small = x < 1e-4
    xs = xp.where(small, 1.0, x)
    return xp.where(small, 1.0 - x * x / 3.0, xp.tanh(xs) / xs)


def masks(g, a, dt, xp=jnp):
    """``(dt_ok, gyr_ok, acc_ok, |acc|²)`` of samples: ``g``, ``a`` vectors with the component
    axis first (arrays (3, ...) or tuples of three arrays), ``dt`` (...): a valid Δt
    (:func:`valid_dt`); with it a gyro whose components are finite and below ``MAX_RATE_RAD_S``;
    with it a non-zero accelerometer whose components are finite and below ``MAX_ACC_M_S2``
    (``|acc|²`` is 0 where they are not)."""
    dt_ok = valid_dt(dt)
    gyr_ok = gyr_in_range(g, xp) & dt_ok
    acc_in = ((xp.abs(a[0]) < MAX_ACC_M_S2) & (xp.abs(a[1]) < MAX_ACC_M_S2)
              & (xp.abs(a[2]) < MAX_ACC_M_S2))
    a = _each(lambda c: xp.where(acc_in, c, 0.0), a)
    acc_n2 = a[0] * a[0] + a[1] * a[1] + a[2] * a[2]
    acc_ok = dt_ok & (acc_n2 > 1e-6)
    return dt_ok, gyr_ok, acc_ok, acc_n2


def out_of_range(g, a, xp=jnp):
    """Whether samples (``g``, ``a`` with the component axis first, as :func:`masks`) hold a gyro
    or accelerometer component at or beyond the sensor's physical range (``MAX_RATE_RAD_S``,
    ``MAX_ACC_M_S2``; ±inf included, NaN not: NaN is a missing sample): flag OUT_OF_RANGE."""
    return ((xp.abs(g[0]) >= MAX_RATE_RAD_S) | (xp.abs(g[1]) >= MAX_RATE_RAD_S)
            | (xp.abs(g[2]) >= MAX_RATE_RAD_S) | (xp.abs(a[0]) >= MAX_ACC_M_S2)
            | (xp.abs(a[1]) >= MAX_ACC_M_S2) | (xp.abs(a[2]) >= MAX_ACC_M_S2))


def flag_bits(dt_ok, gyr_ok, acc_ok, disturbed=False, gap=False, reacquired=False,
              reacquiring=False, init=False, beyond=False, xp=jnp):
    """The flags of samples (int32) from their validity and the filter's events (``beyond``:
    :func:`out_of_range`)."""
    f = (xp.where(beyond, OUT_OF_RANGE, 0) | xp.where(acc_ok | ~dt_ok, 0, ACC_MISSING)
         | xp.where(gyr_ok | ~dt_ok, 0, GYR_MISSING)
         | xp.where(dt_ok, 0, BAD_DT) | xp.where(disturbed, ACC_DISTURBED, 0)
         | xp.where(gap, DT_GAP, 0) | xp.where(reacquired, REACQUIRED, 0)
         | xp.where(reacquiring, REACQUIRING, 0) | xp.where(init, INIT, 0))
    return f.astype(xp.int32)


class SampleTerms(NamedTuple):
    """What one sample (or an array of samples) brings to its block (see :func:`sample_terms`)."""

    dt_ok: jax.Array
    gyr_ok: jax.Array
    acc_ok: jax.Array
    gap: jax.Array  # Δt above gap_flag_s: a gap in the recording
    dts: jax.Array  # Δt of a sample with a valid Δt, else 0
    rot: jax.Array  # (3, ...) gyro rotation vector ω Δt of a valid gyro sample, else 0
    acc: jax.Array  # (3, ...) accelerometer of a valid accelerometer sample (m/s²), else 0
    # (rot and acc, and the vector sums, as tuples of components when the sample was given so)
    wa: jax.Array  # Δt of a valid accelerometer sample, else 0
    sums: dict  # the sample's term of each additive block sum (every S field but dquat and f)


def _each(fn, v):
    """``fn`` of a vector given as a tuple of component arrays (component by component), or as an
    array with the component axis first (at once)."""
    return tuple(fn(c) for c in v) if isinstance(v, tuple) else fn(v)


def sample_terms(g, a, dt, p, xp=jnp, gaps: bool = True, tilt_var=0.0,
                 vel_var=0.0, g_prev=None) -> SampleTerms:
    """The per-sample part of the pre-integration: ``g`` (rad/s) and ``a`` (m/s²) vectors with the
    component axis first (arrays (3, ...), or tuples of three arrays), ``dt`` (s) of shape (...):
    the samples' validity and their term in each block sum (``S``; the vector ones in the form of
    ``g``). A block sum is the sum of its samples' terms; ``dquat`` and ``f`` are sequential
    (:func:`preintegrate`). ``gaps=False``: the caller guarantees that no sample is a gap (the
    batch kernel without gap handling). The batch kernel passes tuples, the per-sample step arrays:
    the same arithmetic, each compiled the faster way (XLA runs few large kernels best, and a
    single sample's few small ones as vectors). ``tilt_var`` (rad², scalar or (...)): a tilt
    variance the sample adds besides its own terms (a clipped gyro axis's unknown excess,
    :mod:`~verticality.tilt.limits`), summed with the dropouts' in ``qmiss``;
    ``vel_var`` (m²/s²) likewise the velocity variance of a clipped accelerometer axis's unknown
    excess (``vmiss``). ``g_prev`` (like ``g``): each sample's previous gyro reading; a gap whose
    both ends read the rate (``gap_rate_corr_s`` > 0) is bridged: the mean of the two rates over
    the share of the gap that they carry (:func:`bridge_share`), which is also the gyro time the
    bias acts over; otherwise (None, or an end without a reading) the rate after the gap over the
    whole gap."""
    dt_ok, gyr_ok, acc_ok, acc_n2 = masks(g, a, dt, xp)
    dts = xp.where(dt_ok, dt, 0.0)
    wa = xp.where(acc_ok, dts, 0.0)  # Δt of a valid accelerometer sample
    wg = xp.where(gyr_ok, dts, 0.0)  # Δt of a valid gyro sample
    g0 = _each(lambda c: xp.where(gyr_ok, c, 0.0), g)
    a0 = _each(lambda c: xp.where(acc_ok, c, 0.0), a)
    # the gyro sample does not describe the rotation inside a gap: it counts as a dropout
    gap = is_gap(dts, p) if gaps else xp.zeros_like(dt_ok)
    wr = dts  # the time the sample's rate is integrated over
    if gaps and g_prev is not None:
        bridged = gap & gyr_ok & gyr_in_range(g_prev, xp) & (p.gap_rate_corr_s > 0)
        wb = dts * bridge_share(dts, p.gap_rate_corr_s, xp)
        g0 = tuple(xp.where(bridged, 0.5 * (gp + c), c) for gp, c in zip(g_prev, g0, strict=True))
        g0 = g0 if isinstance(g, tuple) else xp.stack(g0)
        wr = xp.where(bridged, wb, dts)
        wg = xp.where(bridged, wb, wg)
    rot = _each(lambda c: c * wr, g0)
    dev2 = (xp.sqrt(acc_n2) - p.g_m_s2) ** 2
    sums = dict(tau=wg, t_acc=wa, dev2=dev2 * wa,
                w2=(g0[0] * g0[0] + g0[1] * g0[1] + g0[2] * g0[2]) * wr, t=dts,
                qmiss=(xp.where(gyr_ok & ~gap, 0.0, (p.omega_missing_rad_s * dts) ** 2)
                       + xp.where(dt_ok, tilt_var, 0.0)),
                gsum=rot, asum=_each(lambda c: c * wa, a0), a2=acc_n2 * wa,
                gap=gap.astype(xp.float64), vmiss=xp.where(dt_ok, vel_var, 0.0))
    return SampleTerms(dt_ok, gyr_ok, acc_ok, gap, dts, rot, a0, wa, sums)


def preintegrate(dq, f, e, acc, wa):
    """One sample of a block's sequential pre-integration, on component tuples: the raw gyro
    rotation since the block start ``dq ⊗ e`` (``e`` the sample's rotation), and ``f`` plus the
    accelerometer sample rotated to the block-start frame times its Δt ``wa``."""
    dq = so3.quat_multiply_components(dq, e)
    r = so3.quat_rotate_components(dq, acc)
    return dq, tuple(f[i] + r[i] * wa for i in range(3))


def empty_sums(xp=jnp):
    """The sums of a block without samples (``S``)."""
    z = 0.0
    return S.pack(xp=xp, dquat=(1.0, z, z, z), tau=z, f=(z, z, z), t_acc=z, dev2=z, w2=z, t=z,
                  qmiss=z, gsum=(z, z, z), asum=(z, z, z), a2=z, gap=z, vmiss=z)


def accumulate(sums, terms: SampleTerms):
    """``sums`` (``S``) with one sample added (:func:`sample_terms`, :func:`preintegrate`)."""
    dq, f = preintegrate(tuple(sums[S.dquat]), tuple(sums[S.f]),
                         so3.quat_exp_components(*terms.rot), tuple(terms.acc), terms.wa)
    return S.pack(dquat=dq, f=f, **{k: sums[getattr(S, k)] + v for k, v in terms.sums.items()})


# --- the initialization and the covariance helpers ---

_TILT_DIAG = np.diag([1.0 if i in range(E.tilt.start, E.tilt.stop) else 0.0 for i in range(NE)])
_KEEP_VEL = np.array([0.0 if i in range(E.vel.start, E.vel.stop) else 1.0 for i in range(NE)])


def add_tilt_variance(P, var_rad2, xp=jnp):
    """Covariance ``P`` (..., 10, 10) with ``var_rad2`` (scalar or (...,)) added to both tilt
    variances."""
    return P + xp.asarray(var_rad2)[..., None, None] * _TILT_DIAG


def add_fix_variance(P, fix):
    """Covariance ``P`` (10, 10) with the corrections ``fix`` (5,: tilt (2,) rad, bias (3,) rad/s)
    that may not be real added as variance: ``|fix_tilt|²`` to both tilt variances, ``fix_b²`` to
    each bias variance."""
    t2 = sum_sq(fix[:2])
    z = jnp.zeros_like(t2)
    # (a diagonal added element-wise: no scatter, so that it fuses in the batch kernel's scan)
    return P + jnp.diag(jnp.stack([t2, t2, z, z, fix[2] * fix[2], fix[3] * fix[3],
                                   fix[4] * fix[4], z, z, z]))


def widen_tilt(P, sigma_rad, xp=jnp):
    """Covariance ``P`` (10, 10) with ``sigma_rad²`` added to both tilt variances (the accelerometer
    sample that initializes the filter may hold an inertial acceleration of unknown size)."""
    return add_tilt_variance(P, sigma_rad**2, xp)


def reset_velocity(P, var_m2_s2):
    """Covariance ``P`` (10, 10) with the velocity error forgotten: its rows and columns zeroed and
    its variance set to ``var_m2_s2`` (after a gap the integrated velocity means nothing)."""
    return P * _KEEP_VEL[:, None] * _KEEP_VEL[None, :] + jnp.diag(var_m2_s2 * (1.0 - _KEEP_VEL))


def quat_from_acc(acc_m_s2, xp=jnp):
    """Quaternion ``q_E_S`` with zero heading whose up axis matches the accelerometer direction
    (the minimal rotation taking the measured specific-force direction to e3; π about x when it
    points down; the identity for a zero vector)."""
    a = xp.asarray(acc_m_s2, dtype=xp.float64)
    n = xp.sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2])
    u = xp.where(n > 0, a / xp.where(n > 0, n, 1.0), xp.asarray([0.0, 0.0, 1.0]))
    w = 1.0 + u[2]
    q = xp.where(w < 1e-9, xp.asarray([0.0, 1.0, 0.0, 0.0]),
                 xp.stack([w, u[1], -u[0], xp.zeros_like(w)]))
    return q / xp.sqrt(xp.sum(q * q))


def initialize(x, acc_m_s2, p, xp=jnp):
    """The filter ``x`` (``X``) after the accelerometer sample ``acc_m_s2`` initializes it: the
    tilt from that sample (heading 0), the tilt variance widened by ``init_tilt_rad`` (the sample
    may hold an inertial acceleration), and the tilt to be re-acquired after ``reacquire_s`` (as
    after a gap, so that a start in motion is caught)."""
    P = widen_tilt(x[X.P].reshape(NE, NE), p.init_tilt_rad, xp)
    return X.pack(xp=xp, q=quat_from_acc(acc_m_s2, xp), b=x[X.b], s=x[X.s], v=x[X.v],
                  P=P.reshape(-1), acc_dev_var=x[X.acc_dev_var], rest_s=x[X.rest_s], reacquire=1.0,
                  reacq_f_E=xp.zeros(3), reacq_t=0.0, vel_inn=xp.zeros(2), vel_fix=xp.zeros(5),
                  speed_var=x[X.speed_var], dv_var=x[X.dv_var])


# --- the block update ---

def block_inputs(s, p):
    """The part of the block update that depends on the block sums ``s`` (..., ``S``) only, not on
    the filter state (any leading shape: the batch kernel computes it for all the blocks of a
    chunk before the sequential scan). Returns (..., ``C``)."""
    tau, t_acc, w2, T = s[..., S.tau], s[..., S.t_acc], s[..., S.w2], s[..., S.t]
    has_acc = t_acc > 0
    t_acc_s = jnp.where(has_acc, t_acc, 1.0)
    q_gyr = p.gyr_noise**2 * tau + p.gyr_scale_noise**2 * w2 + s[..., S.qmiss]
    q_vel = p.acc_noise**2 * t_acc + (p.acc_missing_m_s2 * (T - t_acc)) ** 2 + s[..., S.vmiss]
    has_gyr = tau > 0
    tau_s = jnp.where(has_gyr, tau, 1.0)
    g_mean = s[..., S.gsum] / tau_s[..., None]
    # rest detection: the canal signal is the drift alone (T eq. 1 with ω = 0)
    g_var = jnp.maximum(w2 / jnp.where(T > 0, T, 1.0) - jnp.sum(g_mean * g_mean, -1), 0.0)
    a_mean = s[..., S.asum] / t_acc_s[..., None]
    a_var = jnp.maximum(s[..., S.a2] / t_acc_s - jnp.sum(a_mean * a_mean, -1), 0.0)
    gap = s[..., S.gap] > 0
    # the block is steady: gyro and accelerometer without variation within it (the rest
    # detector's per-block test without its bias condition)
    steady = (has_gyr & has_acc & (g_var < p.rest_gyr_rad_s**2) & (a_var < p.rest_acc_m_s2**2)
              & ~gap)
    # a steady block shows the disturbance as it is now: there the low-pass of (|f| − g)² follows
    # it within acc_tau_steady_s (0: at once), not with the memory of an event that is over
    tau_d = jnp.where(steady, p.acc_tau_steady_s, p.acc_tau_s)
    alpha = jnp.where(tau_d > 0, 1.0 - jnp.exp(-t_acc / jnp.where(tau_d > 0, tau_d, 1.0)), 1.0)
    # a steady block whose gyro reads no rotation is still, whatever the bias estimate (which a
    # violent event may have corrupted); the other quiet test, the mean within rest_gyr of the
    # estimate, needs the filter state (block_update)
    still0 = steady & (jnp.sum(g_mean * g_mean, -1) < p.rest_gyr_raw_rad_s**2)
    return C.pack(dquat=s[..., S.dquat], tau=tau, f=s[..., S.f], T=T, has_acc=has_acc,
                  q_gyr=q_gyr, q_vel=q_vel, qb=p.bias_walk**2 * T,
                  alpha=alpha, dev2=s[..., S.dev2] / t_acc_s,
                  g_mean=g_mean, steady=steady, still0=still0,
                  r_vel=(p.vel_m_s**2 * p.vel_corr_s) / t_acc_s,
                  r_vel_rest=(p.vel_rest_m_s**2 * p.vel_corr_s) / t_acc_s,
                  r_b=p.gyr_noise**2 / tau_s + p.rest_motion_rad_s**2, gap=gap, t_acc=t_acc,
                  gsum=s[..., S.gsum], lam=jnp.exp(-T / p.vel_corr_s))


_J = np.array([[0.0, 1.0], [-1.0, 0.0]])  # (δ × e3)_{x,y} = J δ


def transition_coefficients(R, T, g, G):
    """The entries of the block's error transition (:func:`error_transition`) that are neither 0
    nor 1, as nested lists of scalars (rows, then columns): ``AA`` (2 × 6) ``= [A, A_s]``, how the
    bias and scale errors move the tilt error, and ``BB`` (2 × 6) ``= ½ T g J [A, A_s]``, how they
    move the velocity error; ``R`` (3 × 3, or its first two rows). Scalars, not arrays, so that
    :func:`propagate_covariance` fuses in the batch kernel's scan (a concatenate would not)."""
    AA = tuple([-T * R[i, k] for k in range(3)] + [-R[i, k] * G[k] for k in range(3)]
               for i in range(2))
    BB = ([0.5 * T * (AA[1][k] * g) for k in range(6)],
          [0.5 * T * (-AA[0][k] * g) for k in range(6)])
    return AA, BB


def error_transition(R, T, g, G):
    """The error-state transition ``F`` (10 × 10) of a block of length ``T`` (s) whose orientation
    at its end is ``R`` (3 × 3, or its first two rows) and whose raw gyro rotation is
    ``G = Σ ω Δt`` (3,): the gyro reads ``(1 + s) ω + b``, so a scale error ``s̃`` acts as a bias
    error ``s̃ ⊙ ω``; the continuous error dynamics ``δ̇ = −Π R (b̃ + s̃ ⊙ ω)``, ``ṽ̇ = g J δ``,
    ``ḃ̃ = 0``, ``s̃̇ = 0`` over ``T`` with ``R`` held, ``F = exp(F_c T)`` (exact: ``F_c³ = 0``)::

        δ ← δ + A b̃ + A_s s̃             A = −T Π R,  A_s = −Π R diag(G)
        ṽ ← ṽ + T g J δ + ½ T g J (A b̃ + A_s s̃)
        b̃ ← b̃,  s̃ ← s̃

    (:func:`transition_coefficients`). Checked against ``jax.jacfwd`` of the error flow
    (tests/test_tilt.py)."""
    AA, BB = transition_coefficients(R, T, g, G)
    z2 = jnp.zeros((2, 2))
    return jnp.concatenate([
        jnp.concatenate([jnp.eye(2), z2, jnp.stack([jnp.stack(r) for r in AA])], axis=1),
        jnp.concatenate([T * g * _J, jnp.eye(2), jnp.stack([jnp.stack(r) for r in BB])], axis=1),
        jnp.concatenate([jnp.zeros((6, 4)), jnp.eye(6)], axis=1)], axis=0)


def propagate_covariance(P, R, T, g, G):
    """``F P Fᵀ`` for the block's error transition ``F`` (:func:`error_transition` of the same
    ``R``, ``T``, ``g``, ``G``) and a covariance ``P`` (10 × 10), from ``F``'s structure: only its
    tilt and velocity rows differ from the identity, so ``F P`` changes ``P``'s first four rows and
    ``(F P) Fᵀ`` its first four columns, each a short sum of rows (columns) of ``P``. Written
    element-wise (no ``dot`` and no reduction), so that it fuses with its neighbours in the batch
    kernel's scan over blocks: the dense product's numbers but for the order of the sums."""
    AA, BB = transition_coefficients(R, T, g, G)
    Tg = T * g

    def rows(M, get):  # the first four rows (columns) of F M (M Fᵀ) from M's rows (columns)
        r0 = get(M, 0) + sum(AA[0][k] * get(M, 4 + k) for k in range(6))
        r1 = get(M, 1) + sum(AA[1][k] * get(M, 4 + k) for k in range(6))
        r2 = Tg * get(M, 1) + get(M, 2) + sum(BB[0][k] * get(M, 4 + k) for k in range(6))
        r3 = -Tg * get(M, 0) + get(M, 3) + sum(BB[1][k] * get(M, 4 + k) for k in range(6))
        return r0, r1, r2, r3

    FP = jnp.concatenate([jnp.stack(rows(P, lambda M, i: M[i])), P[4:]], axis=0)
    cols = rows(FP, lambda M, i: M[:, i])
    return jnp.concatenate([jnp.stack(cols, axis=1), FP[:, 4:]], axis=1)


def sum_sq(v):
    """``Σ v_i²`` of a short vector (2 or 3,), written out: no reduction, which would end a fused
    kernel in the batch kernel's scan over blocks."""
    out = v[0] * v[0]
    for i in range(1, v.shape[0]):
        out = out + v[i] * v[i]
    return out


def unit(q):
    """``q`` (4,) divided by its norm: ``so3.quat_normalize`` with the norm from :func:`sum_sq`
    (no reduction: it fuses in the batch kernel's scan over blocks)."""
    return q / jnp.sqrt(sum_sq(q))


def disturbed_velocity_scale(acc_dev_var, p):
    """How much the velocity pseudo-measurement's variance grows under a disturbance: the speed
    prior becomes the larger of ``vel_m_s`` and the speed an inertial acceleration of mean square
    ``acc_dev_var`` (m²/s⁴) makes at ``vel_disturbed_hz``, ``a_rms / (2π f)``."""
    w = 2.0 * math.pi * p.vel_disturbed_hz
    return jnp.maximum(1.0, acc_dev_var / (w * w * p.vel_m_s**2))


def innovation_nis(P, rows: slice, z, r):
    """The normalized innovation squared ``zᵀ S⁻¹ z``, ``S = P[rows, rows] + r I``, of a
    2-row measurement (χ² with 2 degrees of freedom when the filter is consistent)."""
    i0 = rows.start
    a, b = P[i0, i0] + r, P[i0, i0 + 1]
    d = P[i0 + 1, i0 + 1] + r
    return (d * z[0] * z[0] - 2.0 * b * z[0] * z[1] + a * z[1] * z[1]) / (a * d - b * b)


def whiten2(P, rows: slice, z, r):
    """The innovation ``z`` of a 2-row measurement whitened by its covariance ``S = P[rows, rows]
    + r I`` (``L⁻¹ z``, ``L`` the Cholesky factor of ``S``): N(0, I) when the filter is
    consistent."""
    i0 = rows.start
    l11 = jnp.sqrt(P[i0, i0] + r)
    l21 = P[i0 + 1, i0] / l11
    l22 = jnp.sqrt(P[i0 + 1, i0 + 1] + r - l21 * l21)
    w0 = z[0] / l11
    return jnp.stack([w0, (z[1] - l21 * w0) / l22])


def joseph_update(P, rows: slice, z, r):
    """Kalman update of the error state for ``z = dx[rows] + n``, ``n ~ N(0, r I)`` (2 or 3 rows
    selected), Joseph form, symmetrized; written element-wise (no ``dot``), so that the scan over
    blocks compiles to few fused kernels. Returns ``(dx, P)``."""
    i0, m = rows.start, rows.stop - rows.start
    PHt = P[:, i0:i0 + m]  # (NE, m)
    Sm = P[i0:i0 + m, i0:i0 + m] + r * jnp.eye(m)
    if m == 2:
        det = Sm[0, 0] * Sm[1, 1] - Sm[0, 1] * Sm[1, 0]
        Si = jnp.stack([jnp.stack([Sm[1, 1], -Sm[0, 1]]), jnp.stack([-Sm[1, 0], Sm[0, 0]])]) / det
    else:
        a, b, c = Sm[0, 0], Sm[0, 1], Sm[0, 2]
        d, e, f = Sm[1, 1], Sm[1, 2], Sm[2, 2]
        cof = jnp.stack([jnp.stack([d * f - e * e, c * e - b * f, b * e - c * d]),
                         jnp.stack([c * e - b * f, a * f - c * c, b * c - a * e]),
                         jnp.stack([b * e - c * d, b * c - a * e, a * d - b * b])])
        Si = cof / (a * (d * f - e * e) + b * (c * e - b * f) + c * (b * e - c * d))
    K = sum(PHt[:, j:j + 1] * Si[j][None, :] for j in range(m))  # (NE, m)
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


def block_prediction(x, c):
    """The nominal prediction over a block: ``(q_end, f_E, vel)``, the orientation at the block's
    end ``q0 ⊗ dquat ⊗ exp(−(b τ + s ⊙ G))`` (strapdown with the bias- and scale-corrected gyro,
    T eq. 1, 7), the
    block's specific force rotated to Earth ``Σ R f Δt`` and the velocity ``v + Π f_E``."""
    q0 = x[X.q]
    q_end = so3.quat_multiply(so3.quat_multiply(q0, c[C.dquat]),
                              jnp.stack(so3.quat_exp_components(
                                  *(-(x[X.b] * c[C.tau] + x[X.s] * c[C.gsum])))))
    q_end = unit(q_end)
    f_E = jnp.stack(so3.quat_rotate_components(tuple(q0), tuple(c[C.f])))
    return q_end, f_E, x[X.v] + f_E[:2]


class BlockTransition(NamedTuple):
    """What a block update did to the error state, for the offline smoother
    (:mod:`verticality.tilt.smoother`): the block as a linear-Gaussian step
    ``x_prior = F x_start + w`` followed by the measurement updates, ``x_new = x_prior ⊕ dx``.

    A velocity reset (a kick, a persistent velocity, a gap) replaces the velocity by a fresh
    unknown: ``F``'s velocity rows are zeroed there and ``P_prior`` holds the reset velocity
    variance, so that nothing after the reset is carried back into the velocity before it.
    ``split``: the block is a gap, collects the specific force for a re-acquisition, or
    re-acquires; its update is no linear step of the error (the re-acquisition measures the tilt
    with the sum of several blocks), so the smoothing does not cross into it."""

    F: jax.Array  # (10, 10) the error transition over the block (velocity rows zeroed on a reset)
    P_prior: jax.Array  # (10, 10) the covariance before the block's measurement updates
    dx: jax.Array  # (10,) the correction the updates applied (x_new ⊖ x_prior)
    split: jax.Array  # () bool


def block_update(x, c, p, gaps: bool = True, summed: bool = True):
    """Kalman prediction over a block and the otolith/rest updates (T eq. 2, 7–13 in 3-D): the
    filter ``x`` (``X``) at the block start and the block's inputs ``c`` (``C``,
    :func:`block_inputs`) give ``(x_new, disturbed, reacquired, transition)``
    (:class:`BlockTransition`, for the smoother; unused by the filter, it costs nothing there:
    XLA drops what no output needs).

    ``gaps=False`` leaves out the handling of gaps and re-acquisitions (for a block with no gap
    while no re-acquisition is pending: the results are then the same, and the batch kernel's
    scan is cheaper without the branches; docs/tilt.md, "Two batch kernels"). ``summed``: the new
    state vector as a sum of padded fields (``Packed.pack``'s ``summed``: fewer kernels where
    XLA runs each fused kernel as a task of its own, the per-sample ``step``) or as a
    concatenate (fewer operations where the whole scan is compiled into one kernel, the batch
    kernel: the sum evaluates every field at every element); the same numbers."""
    g = p.g_m_s2
    b, P0 = x[X.b], x[X.P].reshape(NE, NE)
    reacquire0 = x[X.reacquire] > 0.5
    T, has_acc, t_acc = c[C.T], c[C.has_acc] > 0.5, c[C.t_acc]
    gap = c[C.gap] > 0.5
    collecting = reacquire0 & ~gap  # a block after a gap (or the start): the tilt error is unknown

    q_end, f_E, vel = block_prediction(x, c)
    R = so3.matrix_from_unit_quat(q_end)[:2]
    F = error_transition(R, T, g, c[C.gsum])  # (for the smoother; the filter needs F P Fᵀ only)
    z = jnp.zeros_like(c[C.qb])  # the scale factors are constants (no process noise)
    Qd = jnp.stack([c[C.q_gyr], c[C.q_gyr], c[C.q_vel], c[C.q_vel], c[C.qb], c[C.qb], c[C.qb],
                    z, z, z])
    P = propagate_covariance(P0, R, T, g, c[C.gsum]) + jnp.diag(Qd)

    # size of the inertial acceleration seen by the norm (for the ACC_DISTURBED flag only)
    acc_dev_var0 = x[X.acc_dev_var]
    acc_dev_var = jnp.where(has_acc, acc_dev_var0 + c[C.alpha] * (c[C.dev2] - acc_dev_var0),
                            acc_dev_var0)
    disturbed = has_acc & (acc_dev_var > p.acc_disturbed_m_s2**2)

    # rest (T eq. 1 with ω = 0): a steady block whose gyro mean is within rest_gyr of the bias
    # estimate, or reads no rotation at all (block_inputs)
    gd = c[C.g_mean] - b
    quiet = (c[C.still0] > 0.5) | ((c[C.steady] > 0.5) & (sum_sq(gd) < p.rest_gyr_rad_s**2))
    rest_s = jnp.where(quiet, x[X.rest_s] + T, 0.0)
    at_rest = rest_s >= p.rest_min_s  # the bias's rest update
    # the velocity's rest prior (the tilt) may start sooner than the bias's rest update
    rest_vel = rest_s >= p.rest_tilt_s

    # otolith update: accelerations are short and periodic (T §I), so the velocity they produce
    # stays small: pseudo-measurement 0 = v + n_v (n_v ~ 0 at rest). Since v integrates the
    # specific force rotated by the estimate, its error grows as g J δ: this observes the tilt
    # (T eq. 5) with the inertial part integrated out rather than taken as white noise.
    r_v0 = jnp.where(rest_vel, c[C.r_vel_rest], c[C.r_vel])
    # the motion's own correlation time τ (docs/tilt.md, "The filter (choices)"): a velocity of
    # correlation time τ changes over a block of length T by E[Δv²] = 2 E[v²] (1 − e^(−T/τ)) per
    # axis; the low-passed (over vel_corr_s) mean squares of the predicted velocity and of the
    # block's change (its horizontal specific force in Earth) give τ, which replaces vel_corr_s
    # in the noise while moving: never longer (a tilt error's ramp, a slow motion keep the
    # prior) and never shorter than the block (the block is one measurement; an oscillation
    # slower than it has a lag-T correlation near or below zero, which no exponential fits)
    lam = c[C.lam]
    dv = f_E[:2]
    eligible = has_acc & ~gap & ~collecting  # a velocity update may run
    speed_var = jnp.where(eligible, lam * x[X.speed_var] + (1 - lam) * 0.5 * sum_sq(vel),
                          x[X.speed_var])
    dv_var = jnp.where(eligible, lam * x[X.dv_var] + (1 - lam) * 0.5 * sum_sq(dv), x[X.dv_var])
    rho = jnp.clip(dv_var / jnp.maximum(2.0 * speed_var, 1e-12), 1.0 - lam, 1.0 - math.exp(-1.0))
    tau_motion = -T / jnp.log1p(-rho)
    r_v = r_v0 * disturbed_velocity_scale(acc_dev_var, p) * jnp.where(
        rest_vel, 1.0, tau_motion / p.vel_corr_s)
    # a velocity far beyond what its covariance allows under the undisturbed prior (a kick that
    # leaves the sensor moving) is not the tilt's doing: it is forgotten, not turned into tilt
    jump = eligible & (innovation_nis(P, E.vel, vel, r_v0) > p.vel_jump_nis)
    # a velocity that stays beyond the prior for longer than its correlation time (a kick too
    # small for the one-block test): the running mean of the whitened innovations over
    # ~vel_corr_s (N(0, (1 − λ)/(1 + λ) I) when the filter is consistent) against the same χ²
    inn = lam * x[X.vel_inn] + (1.0 - lam) * whiten2(P, E.vel, -vel, r_v0)
    persist = eligible & ~jump & (sum_sq(inn) * (1.0 + lam) / (1.0 - lam) > p.vel_jump_nis)
    dx1, P1 = joseph_update(P, E.vel, -vel, r_v)
    fix = x[X.vel_fix]  # the tilt and bias corrections the velocity made over the window
    jump = jump | persist
    use = has_acc & ~jump
    dx = jnp.where(use, dx1, 0.0)
    # the tilt and bias corrections that velocity made over the window may not be the tilt's
    # and the bias's doing; which part is, the filter cannot tell: their sizes are added to the
    # tilt's and the bias's variances (undoing them would also undo the real corrections among
    # them). The bias matters: a bias the kicks made wrong drifts the tilt while the velocity,
    # forgotten block after block, can no longer show it
    P = jnp.where(persist, add_fix_variance(P, fix), P)
    P = jnp.where(jump, reset_velocity(P, p.vel_m_s**2), P)
    keep = eligible & ~jump
    reset = has_acc | gap | collecting
    inn = jnp.where(keep, inn, jnp.where(reset, 0.0, x[X.vel_inn]))
    fix = jnp.where(keep, lam * fix + jnp.concatenate([dx1[E.tilt], dx1[E.bias]]),
                    jnp.where(reset, 0.0, fix))
    vel = jnp.where(jump, 0.0, vel)
    vel_prior = vel  # the velocity before the updates (after a reset)
    disturbed = disturbed | jump

    def rest_update(dx, P):  # rest: the block-mean gyro measures the bias
        dx3, P3 = joseph_update(P, E.bias, c[C.g_mean] - (b + dx[E.bias]), c[C.r_b])
        return dx + dx3, P3

    P_pred = P

    def rare(args):
        """At rest, or after a gap (exclusive: rest needs no gap in sight); one ``lax.cond``
        keeps the common moving block free of both. After a gap (or the start) the tilt error can
        be large, beyond the small-angle velocity update: the specific force is summed in Earth
        (as estimated; the gyro alone carries the estimate, so its error stays put) for
        reacquire_s, then its mean measures the tilt error directly (T eq. 5, exact angle). Its
        inertial part is Δv / T, with |Δv| ~ √2 vel_m_s (vel_rest_m_s if every block since the
        gap was quiet)."""
        dx, P = args
        forget = gap | collecting  # no velocity update; the velocity is forgotten
        f_sum = jnp.where(collecting, x[X.reacq_f_E] + f_E, 0.0)
        t_sum = jnp.where(collecting, x[X.reacq_t] + t_acc, 0.0)
        reacq = collecting & (t_sum >= p.reacquire_s)
        still = gap | (collecting & ~reacq)
        dx = jnp.where(forget, 0.0, dx)
        P = jnp.where(forget, P_pred, P)
        v_r = jnp.where(rest_s >= t_sum, p.vel_rest_m_s, p.vel_m_s)  # quiet since the gap
        dxr, Pr = joseph_update(P, E.tilt, tilt_error_from_force(f_sum),
                                2.0 * (v_r / (g * jnp.where(reacq, t_sum, 1.0))) ** 2)
        dx = jnp.where(reacq, dxr, dx)
        P = jnp.where(reacq, Pr, P)
        P = jnp.where(forget, reset_velocity(P, p.vel_m_s**2), P)
        dx_r, P_r = rest_update(dx, P)
        dx, P = jnp.where(at_rest, dx_r, dx), jnp.where(at_rest, P_r, P)
        return (dx, P, jnp.where(forget, 0.0, vel + dx[E.vel]), jnp.where(still, 1.0, 0.0),
                jnp.where(still, f_sum, 0.0), jnp.where(still, t_sum, 0.0), reacq)

    def common(args):
        dx, P = args
        return dx, P, vel + dx[E.vel], 0.0, jnp.zeros(3), 0.0, jnp.array(False)

    if gaps:
        dx, P, vel, pending, reacq_f_E, reacq_t, reacq = jax.lax.cond(
            at_rest | gap | reacquire0, rare, common, (dx, jnp.where(use, P1, P)))
    else:  # no gap in sight: the rest update alone, under lax.cond (no cost while moving)
        dx, P = jax.lax.cond(at_rest, lambda a: rest_update(*a), lambda a: a,
                             (dx, jnp.where(use, P1, P)))
        vel, pending, reacq_f_E, reacq_t, reacq = (vel + dx[E.vel], 0.0, jnp.zeros(3), 0.0,
                                                   jnp.array(False))

    q_new = so3.quat_multiply(jnp.stack(so3.quat_exp_components(dx[0], dx[1], 0.0)), q_end)
    q_new = unit(q_new)
    x_new = X.pack(summed=summed, q=q_new, b=b + dx[E.bias], s=x[X.s] + dx[E.scale], v=vel,
                   P=P.reshape(-1), acc_dev_var=acc_dev_var,
                   rest_s=rest_s, reacquire=pending, reacq_f_E=reacq_f_E, reacq_t=reacq_t,
                   vel_inn=inn, vel_fix=fix, speed_var=speed_var, dv_var=dv_var)
    vel_reset = jump | gap | collecting
    transition = BlockTransition(jnp.where(vel_reset, F * _KEEP_VEL[:, None], F), P_pred,
                                 dx.at[E.vel].set(vel - vel_prior),
                                 gap | collecting | reacq)
    return x_new, disturbed, reacq, transition


def close_block(x, sums, p):
    """The block update at the end of a block whose sums are ``sums`` (``S``), without the gap
    handling unless a gap or a re-acquisition is in sight (the same numbers, faster)."""
    c = block_inputs(sums, p)
    return jax.lax.cond((x[X.reacquire] > 0.5) | (sums[S.gap] > 0),
                        lambda c: block_update(x, c, p, True),
                        lambda c: block_update(x, c, p, False), c)


# --- the outputs of a sample ---

def sample_quat(q0, dq, b, tau, s, G, qexp=so3.quat_exp_components):
    """``q_E_S`` at a sample inside a block, on component tuples, before normalization:
    ``q0 ⊗ dq ⊗ exp(−(b τ + s ⊙ G))`` (``q0``, ``b``, ``s`` the block-start estimate, ``dq``,
    ``tau``, ``G`` the block's sums so far: raw rotation, gyro time and Σ ω Δt). ``qexp`` the
    quaternion exponential on components (the batch kernel passes its faster one); the caller
    normalizes (component-wise in the batch kernel, as one vector in :func:`step`: fewer kernels per
    call)."""
    qb = qexp(*(-(b[i] * tau + s[i] * G[i]) for i in range(3)))
    return so3.quat_multiply_components(so3.quat_multiply_components(q0, dq), qb)


def up_roll_pitch(q, xp=jnp, atan2=None):
    """``(up_S, roll, pitch)`` of ``q_E_S`` given as components: the unit up vector in the sensor
    frame (the third row of ``R(q)``, a component tuple) and the ZYX roll and pitch
    (:func:`verticality.core.so3.roll_pitch_from_up`'s formula). ``atan2`` defaults to ``xp``'s."""
    w, x, y, z = q
    up = (2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y))
    atan2 = xp.arctan2 if atan2 is None else atan2
    return up, atan2(up[1], up[2]), atan2(-up[0], xp.sqrt(up[1] * up[1] + up[2] * up[2]))


def output_var(P, initialized, qmiss, p, xp=jnp):
    """The variances a sample reports (``TiltOutput.var``): the diagonal of the block-start ``P``
    with what gyro dropouts and gaps have added to the tilt since the block's start (``qmiss``:
    it enters ``P`` at the block's update, but shows from its sample on); before the
    initialization, when there is no estimate, the initialization's."""
    P = xp.where(initialized, P, widen_tilt(P, p.init_tilt_rad, xp))
    return xp.diagonal(add_tilt_variance(P, qmiss, xp), axis1=-2, axis2=-1)


# --- the per-sample step ---

def step(state: TiltState, gyr, acc, dt, p, block: int, tilt_var=0.0, flags=0, vel_var=0.0):
    """One sample: gyro ``gyr`` (3,) rad/s, accelerometer ``acc`` (3,) m/s², ``dt`` s since the
    previous sample. The sample is pre-integrated into the block; at the block's end the block
    update runs. Before the initialization, the first usable accelerometer sample sets the tilt
    (flag INIT), to be re-acquired after reacquire_s. ``tilt_var``, ``vel_var``, ``flags``: the
    sample's extra tilt (rad²) and velocity (m²/s²) variances and flags from the recording's limits
    (:class:`~verticality.tilt.limits.Limits`; none by default). Returns
    ``(state, TiltOutput)``."""
    gyr = jnp.asarray(gyr, dtype=jnp.float64)
    acc = jnp.asarray(acc, dtype=jnp.float64)
    dt = jnp.asarray(dt, dtype=jnp.float64)
    t = sample_terms(gyr, acc, dt, p, tilt_var=tilt_var, vel_var=vel_var,
                     g_prev=jnp.asarray(state.gyr_prev, dtype=jnp.float64))
    init_now = ~state.initialized & t.acc_ok
    x = jnp.where(init_now, initialize(state.x, t.acc, p), state.x)
    sums = jnp.where(state.initialized, accumulate(state.sums, t), state.sums)
    count = jnp.where(state.initialized, state.count + 1, state.count)
    initialized = state.initialized | init_now

    def close(args):
        x, sums, count = args
        xn, disturbed, reacq, _ = close_block(x, sums, p)
        return xn, empty_sums(), jnp.zeros_like(count), disturbed, reacq

    x, sums, count, disturbed, reacq = jax.lax.cond(
        initialized & (count >= block), close,
        lambda a: (*a, jnp.array(False), jnp.array(False)), (x, sums, count))
    q = so3.quat_normalize(jnp.stack(sample_quat(tuple(x[X.q]), tuple(sums[S.dquat]), x[X.b],
                                                  sums[S.tau], x[X.s], sums[S.gsum])))
    q = jnp.where(count == 0, x[X.q], q)
    up, roll, pitch = up_roll_pitch(tuple(q))
    flags = flag_bits(t.dt_ok, t.gyr_ok, t.acc_ok, disturbed, t.gap, reacq,
                      (x[X.reacquire] > 0.5) | (sums[S.gap] > 0), init_now,
                      out_of_range(gyr, acc)) | jnp.asarray(flags, dtype=jnp.int32)
    var = output_var(x[X.P].reshape(NE, NE), initialized, sums[S.qmiss], p)
    out = TiltOutput(roll, pitch, jnp.stack(up), q, x[X.b], var, flags, t.acc_ok)
    return TiltState(x, sums, count, initialized, gyr), out
