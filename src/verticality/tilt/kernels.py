"""The batch kernel of the 3-D tilt filter: :func:`run_chunk` filters a chunk of samples with the
core's functions (:mod:`verticality.tilt.core`: the per-sample terms, the
pre-integration, the block update, the output angles), arranged so that XLA on a CPU runs them
quickly:

* the per-sample pre-integration is a short sequential ``lax.scan`` over the ``block`` samples of
  a block, vectorized across all the blocks of the chunk at once (structure of arrays); the
  additive block sums are reductions over the block axis;
* the per-sample quaternion exponential is a Taylor polynomial (:func:`quat_exp_taylor`) with the
  exact ``so3.quat_exp_components`` as fallback, chosen for the whole chunk by one ``lax.cond``
  (:func:`quat_exp_batched`), so the fallback costs nothing when unused;
* the state-independent part of every block update (``tilt_core.block_inputs``) runs for all the
  blocks before the sequential ``lax.scan`` over the blocks (``tilt_core.block_update``, written
  element-wise, with the rest update and the gap handling under ``lax.cond``);
* the per-sample quaternion, up, roll and pitch (:func:`atan2`, a vectorizable arctan2) and flags
  leave the device sample-major, as the result arrays, which the host fills with whole copies,
  and the per-block bias and variances (:mod:`verticality.tilt.batch`);
* the chunk is compiled into a single kernel where XLA can (:func:`run_chunk`).
"""

from __future__ import annotations

import functools
import math
from types import SimpleNamespace

import jax
import jax.numpy as jnp
import numpy as np

from verticality.core import so3
from verticality.tilt import core
from verticality.tilt.layout import CHUNK_SAMPLE, HEAD, P_DIAG, ROW, TRANS, S, X

SMALL_TH2 = 0.04  # |rotation|² (rad²) below which the Taylor exponential is used (error < 1e-27)


def quat_exp_taylor(vx, vy, vz):
    """Quaternion of the rotation vector (vx, vy, vz) for |v|² < :data:`SMALL_TH2`: the series of
    cos(θ/2) and sin(θ/2)/θ to θ⁸ (truncation error < 1e-27; no sqrt, sin or cos). Tested against
    ``so3.quat_exp_components``."""
    x2 = 0.25 * (vx * vx + vy * vy + vz * vz)  # (θ/2)²
    c = 1.0 + x2 * (-1.0 / 2 + x2 * (1.0 / 24 + x2 * (-1.0 / 720 + x2 * (1.0 / 40320))))
    s = 0.5 * (1.0 + x2 * (-1.0 / 6 + x2 * (1.0 / 120 + x2 * (-1.0 / 5040 + x2 * (1.0 / 362880)))))
    return c, s * vx, s * vy, s * vz


def quat_exp_batched(vx, vy, vz):
    """Batched quaternion exponential on components: the Taylor series when every rotation of the
    batch is small (the IMU case: |ω|Δt ≪ 0.2 rad), the exact formula otherwise (decided once for
    the whole batch)."""
    th2 = vx * vx + vy * vy + vz * vz
    return jax.lax.cond(jnp.all(th2 < SMALL_TH2), quat_exp_taylor, so3.quat_exp_components,
                        vx, vy, vz)


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


# the block sums that are reductions over the block's samples (not the sequential dquat and f,
# nor tau, a cumulative sum): sums0 adds to them
_REDUCED = np.ones(S.size, dtype=bool)
for _sl in (S.dquat, S.f, S.tau):
    _REDUCED[_sl] = False


def _run_chunk(x, head, data, params, block: int, names: tuple = (), gaps: bool = True,
               transitions: bool = False, summed: bool = True):
    """Filter a chunk of ``n = nb * block`` samples that starts at a block boundary of the
    initialized filter ``x`` (``X``). ``data`` (n, ``CHUNK_SAMPLE``): a row per sample, [gyr (3),
    acc (3), dt, tilt_var, vel_var] (one array: one host-to-device transfer per chunk;
    :func:`verticality.tilt.batch.chunk_data`). ``head`` (``HEAD``): ``sums0``, the sums
    the first block starts from (the samples of a block begun before the chunk; they stand in for
    as many leading samples of ``data``, which the caller fills with skipped samples, dt = NaN),
    ``n_update``, the number of leading blocks whose update is applied: a block after them is
    the current, unfinished block, whose sums are returned; and ``gyr_prev``, the gyro reading
    before the chunk's first row (the rate before a gap there; each other row's is the row
    before it).

    Returns ``(x, sums, (quat, up, roll, pitch, flags, rows))``: the filter after ``n_update``
    blocks; the sums of block ``n_update`` (of the last block when all are updated); per sample,
    in the result's layout, ``quat`` (n, 4), ``up`` (n, 3), ``roll``, ``pitch`` (n,) and ``flags``
    (n,) int32 (``OUT_OF_RANGE`` included, ``REACQUIRING`` not: the host sets it from the rows,
    the rare case); ``rows`` (nb, ``ROW``) per block. A sample's bias and variances are its
    block's start values, except at its last sample (the updated ones): the host writes them
    from the rows.
    ``gaps=False``: the caller guarantees that no gap and no re-acquisition is in the chunk.
    ``transitions``: the outputs also hold ``trans`` (nb, ``TRANS``), each block's covariance at
    its start and its ``tilt_core.BlockTransition`` (for the offline smoother; a separately
    compiled kernel, so the filter's own kernels are untouched). ``summed``: the block update's
    form of its new state (``tilt_core.block_update``; False where the chunk is one kernel)."""
    # ``params``: a TiltParams, or its values as one vector with ``names`` its fields (one
    # argument: passing it costs less than passing 20 scalars)
    p = SimpleNamespace(**dict(zip(names, params, strict=True))) if names else params
    nb = data.shape[0] // block
    # structure of arrays (CHUNK_SAMPLE, block, nb): sample k of every block in a row
    ds = data.reshape(nb, block, CHUNK_SAMPLE.size).transpose(2, 1, 0)
    sums0 = head[HEAD.sums0]
    gyr = tuple(ds[CHUNK_SAMPLE.gyr])
    # each sample's previous gyro reading (the rate before a gap): the row before, the header's
    # for the chunk's first (only the kernel with gap handling bridges gaps)
    g_prev = tuple(jnp.concatenate([jnp.concatenate([head[HEAD.gyr_prev][i:i + 1], c[-1, :-1]])
                                    [None, :], c[:-1]], axis=0)
                   for i, c in enumerate(gyr)) if gaps else None
    t = core.sample_terms(gyr, tuple(ds[CHUNK_SAMPLE.acc]),
                          ds[CHUNK_SAMPLE.dt], p, gaps=gaps, tilt_var=ds[CHUNK_SAMPLE.tilt_var],
                          vel_var=ds[CHUNK_SAMPLE.vel_var], g_prev=g_prev)
    # (component arrays (block, nb): XLA's faster form here)
    e = quat_exp_batched(*t.rot)

    # pre-integration: block sequential steps, each over all nb blocks at once; the first block
    # continues from sums0. The running sums of tau and gsum (the per-sample quaternion needs
    # them) are carried along: cheaper than XLA's cumulative sums (reduce-windows)
    def pre(c, k):
        dq, f = core.preintegrate(c[0], c[1], tuple(ei[k] for ei in e),
                                  tuple(ai[k] for ai in t.acc), t.wa[k])
        run = tuple(r + a[k] for r, a in zip(c[2], (t.sums["tau"],) + tuple(t.sums["gsum"]),
                                             strict=True))
        return (dq, f, run), jnp.stack(dq + run)

    first = jnp.arange(nb) == 0
    start = tuple(tuple(jnp.where(first, sums0[sl][i], v) for i, v in enumerate(vals))
                  for sl, vals in ((S.dquat, (1.0, 0.0, 0.0, 0.0)), (S.f, (0.0, 0.0, 0.0))))
    zero = jnp.zeros(nb)
    (dq_end, f_end, _), steps = jax.lax.scan(pre, start + ((zero,) * 4,), jnp.arange(block))
    dq_all = steps[:, :4]  # (block, 4, nb)
    tau_b = steps[:, 4] + jnp.where(first, sums0[S.tau], 0.0)
    gsum_b = tuple(steps[:, 5 + i] + jnp.where(first, sums0[S.gsum][i], 0.0) for i in range(3))
    reduced = {k: (tuple(jnp.sum(c, 0) for c in v) if isinstance(v, tuple) else jnp.sum(v, 0))
               for k, v in t.sums.items() if k != "tau"}
    sums = S.pack(dquat=dq_end, tau=tau_b[-1], f=f_end, **reduced)  # (nb, S)
    sums = sums + jnp.where(first[:, None] & _REDUCED, sums0, 0.0)

    def body(xc, cj):
        c, j = cj
        xn, disturbed, reacq, tr = core.block_update(xc, c, p, gaps, summed=summed)
        xn = jnp.where(j < head[HEAD.n_update], xn, xc)
        # (only the kernel with gap handling reads the re-acquisition state: the other has no use
        # for it and would pay for the reads; docs/tilt.md, "Two batch kernels")
        pend = (xc[X.reacquire], xn[X.reacquire]) if gaps else (0.0, 0.0)
        row = ROW.pack(q0=xc[X.q], b0=xc[X.b], s0=xc[X.s], var0=xc[P_DIAG], q1=xn[X.q], b1=xn[X.b],
                       var1=xn[P_DIAG], disturbed=disturbed, reacquired=reacq,
                       reacquire0=pend[0], reacquire1=pend[1])
        if transitions:
            row = (row, TRANS.pack(P0=xc[X.P], F=tr.F.reshape(-1), P_prior=tr.P_prior.reshape(-1),
                                   dx=tr.dx, split=tr.split))
        return xn, row

    x, rows = jax.lax.scan(body, x, (core.block_inputs(sums, p), jnp.arange(nb)))
    rows, trans = rows if transitions else (rows, None)
    # per-sample quaternion: q0 ⊗ dq_k ⊗ exp(−b0 τ_k), normalized; the block's last sample
    # carries the updated estimate
    q0 = tuple(rows[:, ROW.q0][:, i] for i in range(4))
    b0 = tuple(rows[:, ROW.b0][:, i] for i in range(3))
    s0 = tuple(rows[:, ROW.s0][:, i] for i in range(3))
    q = so3.quat_normalize_components(core.sample_quat(
        q0, tuple(dq_all[:, i] for i in range(4)), b0, tau_b, s0, gsum_b,
        qexp=quat_exp_batched))  # (block, nb)
    last = jnp.arange(block)[:, None] == block - 1
    q = tuple(jnp.where(last, rows[:, ROW.q1][:, i], q[i]) for i in range(4))
    up, roll, pitch = core.up_roll_pitch(q, atan2=atan2)

    dist = jnp.zeros((block, nb), dtype=bool).at[-1].set(rows[:, ROW.disturbed] > 0.5)
    reacq = (jnp.zeros((block, nb), dtype=bool).at[-1].set(rows[:, ROW.reacquired] > 0.5)
             if gaps else False)
    g, a = gyr, tuple(ds[CHUNK_SAMPLE.acc])
    fl = core.flag_bits(t.dt_ok, t.gyr_ok, t.acc_ok, dist, t.gap, reacq,
                        beyond=core.out_of_range(g, a))  # (block, nb)
    current = sums[jnp.minimum(head[HEAD.n_update].astype(jnp.int32), nb - 1)]

    def by_sample(v):  # (block, nb) per sample, or a tuple of them → (n,) or (n, len) rows
        v = jnp.stack(v, axis=-1) if isinstance(v, tuple) else v
        return v.swapaxes(0, 1).reshape((nb * block,) + v.shape[2:])

    # sample-major, as the result arrays: the host copies them whole (bias and variances need no
    # per-sample array: the host writes them per block from the rows)
    outs = (by_sample(q), by_sample(up), by_sample(roll), by_sample(pitch), by_sample(fl), rows)
    return x, current, (outs + (trans,) if transitions else outs)


# XLA's CPU backend runs a computation as a sequence of fused kernels, each a task of its own that
# costs ~100 ns to start whatever it computes: in the scan over blocks the block update's ~45
# kernels, not its arithmetic, set the time. A call whose frontend attributes say so
# (``xla_cpu_small_call``, which XLA itself puts on small while loops, with ``inlineable`` false
# so that it stays a call) is compiled into a single kernel instead, loops included: the whole
# chunk then costs its arithmetic alone. Such a kernel cannot hold the library's reductions
# (YNNPACK fusions), which the compile options turn off; the numbers are the same to rounding
# (docs/tilt.md, "Benchmark")
_ONE_KERNEL_ATTRIBUTES = {"inlineable": "false", "xla_cpu_small_call": "true"}
_ONE_KERNEL_OPTIONS = {"xla_cpu_experimental_ynn_fusion_type": ""}
_STATIC = ("block", "names", "gaps", "transitions")


def _run_chunk_one_kernel(x, head, data, params, block: int, names: tuple = (),
                          gaps: bool = True, transitions: bool = False):
    """:func:`_run_chunk` as one call that XLA compiles into a single kernel."""
    from jax.experimental.xla_metadata import set_xla_metadata

    chunk = jax.jit(functools.partial(_run_chunk, block=block, names=names, gaps=gaps,
                                      transitions=transitions, summed=False))
    return set_xla_metadata(chunk(x, head, data, params), **_ONE_KERNEL_ATTRIBUTES)


# one compilation for every parameter value (the host puts the parameters on the device once per
# recording, so that a call transfers only its chunk)
_run_chunk_jit = jax.jit(_run_chunk, static_argnames=_STATIC)
try:
    _run_chunk_one_kernel_jit = jax.jit(_run_chunk_one_kernel, static_argnames=_STATIC,
                                        compiler_options=_ONE_KERNEL_OPTIONS)
except TypeError:  # a JAX without per-function compile options: the fused kernels only
    _run_chunk_one_kernel_jit = None
_COMPILED: dict = {}  # which of the two each compiled shape uses


def run_chunk(x, head, data, params, block: int, names: tuple = (), gaps: bool = True,
              transitions: bool = False):
    """:func:`_run_chunk` compiled (once per ``block``, chunk shape and static argument): as a
    single kernel where this JAX and XLA can build one (see above), else as XLA's fused kernels
    (the same numbers to rounding)."""
    key = (block, names, gaps, transitions, data.shape)
    fn = _COMPILED.get(key)
    if fn is None:
        fn = _run_chunk_jit
        if _run_chunk_one_kernel_jit is not None:
            try:
                out = _run_chunk_one_kernel_jit(x, head, data, params, block, names, gaps=gaps,
                                                transitions=transitions)
                _COMPILED[key] = _run_chunk_one_kernel_jit
                return out
            except Exception:  # noqa: BLE001 — an older JAX or XLA: the fused kernels below
                pass
        _COMPILED[key] = fn
    return fn(x, head, data, params, block, names, gaps=gaps, transitions=transitions)
