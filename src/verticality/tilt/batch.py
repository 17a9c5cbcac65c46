"""The host side of the tilt filter's batch run (``TiltFilter.run``): the samples before the
initialization, the chunks of the batch kernel (:func:`verticality.tilt.kernels.
run_chunk`), which of the two compiled kernels each chunk needs, and the result arrays.

Every number comes from the filter's core (:mod:`verticality.tilt.core`): the kernel on
the device, and on the host the same core functions run on NumPy arrays (``xp=np``) for the few
samples before the initialization and for the scheduling. The result equals the core's ``step``
applied sample by sample, to rounding (tests/test_tilt_reference.py).
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import numpy as np

from verticality.core.errors import InputError
from verticality.tilt import core
from verticality.tilt import kernels as tilt_kernels
from verticality.tilt.flags import (
    DT_GAP,
    INIT,
    REACQUIRING,
    accelerometer_used,
)
from verticality.tilt.layout import CHUNK_SAMPLE, HEAD, NE, ROW, TRANS, E, S, X
from verticality.tilt.params import MAX_RATE_RAD_S

# the kernel's chunks hold whole blocks, about this many samples at any block length (the cost
# of a call and of its host work is per chunk, the kernel's per sample and per block): long ones
# without gap handling, short ones with it (a sample costs more there; and a short chunk pads a
# recording's tail less)
CHUNK_SAMPLES = 8192
GAP_CHUNK_SAMPLES = 1024
PIECE_SAMPLES = 2**18  # a long recording is filtered piece by piece (tilt.estimate, estimate's
# streaming read), each piece ending at a block boundary (piece_cut), so that reading and writing
# in pieces gives the numbers of the in-memory run bit for bit


def chunk_blocks(block: int, gaps: bool) -> int:
    """The blocks of a chunk of the kernel with (``gaps``) or without gap handling: one shape
    per block length and kernel."""
    return max(1, (GAP_CHUNK_SAMPLES if gaps else CHUNK_SAMPLES) // block)


def _acc_ok(acc, dts):
    """``tilt_core.masks``' acc_ok: a usable accelerometer sample (its gyro argument does not
    enter acc_ok, so the accelerometer stands in for it)."""
    return core.masks(acc.T, acc.T, dts, xp=np)[2]


# the fields of a TiltOutput of n samples: (trailing shape, dtype), in TiltOutput's order
_OUTPUT_FIELDS = (((), np.float64), ((), np.float64), ((3,), np.float64), ((4,), np.float64),
                  ((3,), np.float64), ((NE,), np.float64), ((), np.int32), ((), np.bool_))


def empty_output(n: int, alloc=np.zeros) -> core.TiltOutput:
    """A :class:`~verticality.tilt.core.TiltOutput` of ``n`` samples to be filled
    (``alloc=np.empty`` when every sample will be written). Each field is a C-contiguous array
    carved from one allocation: the operating system maps one large allocation in huge pages, so
    its first writes take far fewer page faults than eight separate arrays' (docs/tilt.md,
    "Benchmark")."""
    sizes = [n * int(np.prod(shape, dtype=np.int64)) * np.dtype(dt).itemsize
             for shape, dt in _OUTPUT_FIELDS]
    buf = alloc(sum(sizes), dtype=np.uint8)
    fields, off = [], 0
    for (shape, dt), size in zip(_OUTPUT_FIELDS, sizes, strict=True):
        fields.append(buf[off:off + size].view(dt).reshape((n,) + shape))
        off += size  # (the float64 fields come first: every offset is aligned for its dtype)
    return core.TiltOutput(*fields)


class Transitions(NamedTuple):
    """The block updates of a batch run, for the offline smoother: ``start`` the sample at which
    the first updated block begins (its samples are ``start + j * block`` to ``start + (j + 1) *
    block``, the samples of a block begun before the run's first sample counted as before it),
    ``rows`` (M, ``TRANS``) one per updated block, in order."""

    start: int
    rows: np.ndarray


def run(params, block: int, state: core.TiltState, gyr_rad_s, acc_m_s2, dt_s,
        transitions: bool = False, tilt_var=None, flags=None, vel_var=None):
    """Filter a recording from ``state``: gyro (N, 3) rad/s, accelerometer (N, 3) m/s², ``dt_s`` a
    scalar or (N,) (``dt_s[k]`` the time from sample k−1 to k). Returns ``(final_state,
    TiltOutput)`` of NumPy arrays, as the core's ``step`` applied sample by sample would; with
    ``transitions`` also the block updates (:class:`Transitions`, by the kernel compiled with
    them: the same numbers). ``tilt_var``, ``vel_var``, ``flags`` (N,): each sample's extra tilt
    (rad²) and velocity (m²/s²) variances and flags from the recording's limits (``step``'s
    arguments of the same names; :class:`~verticality.tilt.limits.Limits`), None for none."""
    gyr = np.asarray(gyr_rad_s, dtype=np.float64)
    acc = np.asarray(acc_m_s2, dtype=np.float64)
    if gyr.ndim != 2 or gyr.shape[1] != 3 or acc.shape != gyr.shape:
        raise InputError(f"gyr and acc must both have shape (N, 3); got {gyr.shape}, {acc.shape}")
    n = gyr.shape[0]
    dt = np.asarray(dt_s, dtype=np.float64)
    if dt.ndim > 1 or (dt.ndim == 1 and dt.shape[0] != n):
        raise InputError(f"dt must be a scalar or have shape ({n},); got {dt.shape}")
    dts = np.broadcast_to(dt, (n,)).copy()
    tv = None if tilt_var is None else np.asarray(tilt_var, dtype=np.float64)
    vv = None if vel_var is None else np.asarray(vel_var, dtype=np.float64)
    for name, v in (("tilt_var", tv), ("vel_var", vv)):
        if v is not None and (v.shape != (n,) or not np.all(np.isfinite(v) & (v >= 0))):
            raise InputError(f"{name} must be ({n},), finite and non-negative")
    x0 = x = np.array(state.x, dtype=np.float64)
    sums = np.array(state.sums, dtype=np.float64)
    count, initialized = int(state.count), bool(state.initialized)
    k = j = 0
    if not initialized:  # the samples up to the first usable accelerometer sample, which
        j = first_usable(acc, dts)  # initializes the filter (their outputs: below)
        k, initialized = min(n, j + 1), j < n
        if initialized:
            x = core.initialize(x, acc[j], params, xp=np)
    # the chunks are dispatched first (the device works on them asynchronously); the host work
    # that does not need their outputs runs meanwhile, then their outputs are collected
    gyr_prev = np.asarray(state.gyr_prev, dtype=np.float64)
    run_ = _dispatch(params, block, x, sums, count, gyr, acc, dts, k, transitions, tv, vv,
                     gyr_prev) if k < n else None
    # every sample is written below: by the samples up to the initialization and by the chunks
    res = empty_output(n, np.empty)
    if k > 0 and not bool(state.initialized):
        _before_initialization(res, params, x0, x, j, sums, gyr, acc, dts)
    trans = Transitions(n, np.zeros((0, TRANS.size)))
    if run_ is not None:  # (the chunks flag OUT_OF_RANGE themselves)
        x, sums, count, trans = _collect(res, run_)
    if flags is not None:
        res.flags[:] |= np.asarray(flags, dtype=np.int32)
    res.measured[:] = accelerometer_used(res.flags)
    final = core.TiltState(x, sums, np.int32(count), np.bool_(initialized),
                           gyr[-1].copy() if n else gyr_prev)
    return (final, res, trans) if transitions else (final, res)


def _within(a, limit: float) -> bool:
    """Whether every component of ``a`` is below ``limit`` in size (False with a NaN: then the
    caller tests component by component): two reductions over the contiguous values, faster
    than ``tilt_core.out_of_range``'s six strided comparisons, which only a recording near its
    sensor's range needs."""
    flat = a.reshape(-1)
    return bool(flat.size == 0 or (flat.max() < limit and flat.min() > -limit))


def piece_cut(state: core.TiltState, acc, dts, block: int, final: bool) -> int:
    """How many of the next samples (``acc`` (n, 3), ``dts`` (n,)) to filter from ``state`` as one
    piece: all when ``final`` (the recording's last piece), else the most that end at a block
    boundary (the filter's block sums then empty, so the next piece starts as the one-piece run
    would go on); 0 when no boundary is in reach (the caller reads more first)."""
    n = acc.shape[0]
    if final:
        return n
    if bool(state.initialized):
        start = (block - int(state.count)) % block  # samples to the current block's end
    else:
        j = first_usable(acc, dts)
        if j >= n:
            return n  # not initialized in this piece: nothing pending, any cut is a boundary
        start = j + 1  # the initializing sample, then whole blocks
    if start > n:
        return 0
    return start + (n - start) // block * block


def first_usable(acc, dts, k0: int = 0) -> int:
    """The index of the first sample from ``k0`` on with a usable accelerometer sample (finite,
    non-zero, with a valid Δt; ``tilt_core.masks``), or ``len(acc)``: searched in growing windows
    (usually it is the first sample)."""
    n, lo, span = acc.shape[0], k0, 256
    while lo < n:
        hi = min(n, lo + span)
        ok = _acc_ok(acc[lo:hi], dts[lo:hi])
        if ok.any():
            return lo + int(np.argmax(ok))
        lo, span = hi, 4 * span
    return n


def _before_initialization(res, p, x, x_init, j, sums, gyr, acc, dts):
    """The outputs of the samples up to ``j``, the one that initializes the filter (the first
    usable accelerometer sample, ``len(acc)`` if none), as ``step`` gives them: the filter ``x``
    does not change before it, and that sample sets the tilt (``x_init``,
    ``tilt_core.initialize``)."""
    n = acc.shape[0]
    k = min(n, j + 1)
    dt_ok, gyr_ok, acc_ok, _ = core.masks(gyr[:k].T, acc[:k].T, dts[:k], xp=np)
    pending = (x[X.reacquire] > 0.5) | (sums[S.gap] > 0)
    flags = core.flag_bits(dt_ok, gyr_ok, acc_ok, gap=core.gaps_in(dts[:k], p, xp=np),
                           reacquiring=pending,
                           beyond=core.out_of_range(gyr[:k].T, acc[:k].T, xp=np), xp=np)
    var = core.output_var(x[X.P].reshape(NE, NE), False, 0.0, p, xp=np)
    quat = np.tile(x[X.q], (k, 1))
    variances = np.tile(var, (k, 1))
    if j < n:  # the initialization
        x = x_init
        quat[j] = x[X.q]
        variances[j] = core.output_var(x[X.P].reshape(NE, NE), True, 0.0, p, xp=np)
        flags[j] |= INIT | REACQUIRING
    up, roll, pitch = core.up_roll_pitch(tuple(quat.T), xp=np)
    res.quat_E_S[:k] = quat
    res.up_S[:k] = np.stack(up, axis=1)
    res.roll_rad[:k], res.pitch_rad[:k] = roll, pitch
    res.bias_S_rad_s[:k] = x[X.b]
    res.var[:k] = variances
    res.flags[:k] = flags


_HEADS: dict = {}


_NO_GYR = np.full(3, np.nan)


def chunk_head(sums0, n_update: int, nb: int, gyr_prev=None):
    """The chunk header (``HEAD``); the usual one (no sums carried in: ``sums0`` None or empty;
    every block updated; no gap at the chunk's first sample, which would need ``gyr_prev``, the
    reading before it) is put on the device once per chunk size."""
    if n_update == nb and gyr_prev is None and (sums0 is None
                                                or np.array_equal(sums0, _EMPTY_SUMS)):
        if nb not in _HEADS:
            _HEADS[nb] = jax.device_put(HEAD.pack(xp=np, sums0=_EMPTY_SUMS, n_update=nb,
                                                  gyr_prev=_NO_GYR))
        return _HEADS[nb]
    return HEAD.pack(xp=np, sums0=_EMPTY_SUMS if sums0 is None else sums0, n_update=n_update,
                     gyr_prev=_NO_GYR if gyr_prev is None else gyr_prev)


_EMPTY_SUMS = np.asarray(core.empty_sums(xp=np))


class _Dispatched(NamedTuple):
    """The chunks of a batch run in flight (:func:`_dispatch`), for :func:`_collect`."""

    x: object  # the filter after the last chunk (on the device)
    current: object  # the sums of the unfinished last block (on the device)
    pending: list  # (lo, lead, m, size, outs) per chunk
    trans: list
    transitions: bool
    k: int
    pad: int
    base: int
    nv: int
    block: int
    sums0: np.ndarray
    dropout: np.ndarray | None  # what _dropout_variance gives (None: nothing to add)


def _dispatch(p, block, x, sums0, count, gyr, acc, dts, k, transitions=False, tv=None, vv=None,
              gyr_prev=_NO_GYR):
    """Samples ``k`` to the end through the batch kernel, from the filter ``x`` and the current
    block's ``sums0`` of ``count`` samples (``gyr_prev`` the gyro reading before the run's first
    sample): every chunk dispatched (asynchronously), and the host's own part of the result that
    needs no chunk's output computed meanwhile. Returns the run in flight, which
    :func:`_collect` writes into the result."""
    n = gyr.shape[0]
    pad = count  # the block began before sample k: its samples are in sums0
    base = k - pad  # sample index of virtual position 0 (the current block's start)
    nv = pad + n - k
    # dispatch every chunk first (asynchronous, the state stays on the device), then copy the
    # outputs: the host copies overlap the device work of the later chunks
    p_vec = jax.device_put(np.asarray(p, dtype=np.float64))  # once per recording
    x0 = x
    # the kernel without gap handling serves chunks with no gap and no re-acquisition in them
    # (the same numbers, faster)
    # a re-acquisition pending at the start (after the initialization): the first block needs
    # the gap handling (blocks_needing_gaps says so too), and the first chunk is dispatched
    # before the host looks for the others' gaps
    pending0 = bool(x[X.reacquire] > 0.5)
    nb_long, nb_short = chunk_blocks(block, False), chunk_blocks(block, True)
    need = None
    pending, trans, j, v = [], [], 0, 0
    while v < nv:
        if need is None and not (v == 0 and pending0):
            need = blocks_needing_gaps(dts, acc, k, block, p, pending0, float(x0[X.reacq_t]),
                                       pad=pad, gap0=bool(sums0[S.gap] > 0))
        # a gap or a re-acquisition (after a gap, and after the initialization) within a chunk's
        # reach: short chunks with gap handling until it is past; and for a tail of at most half
        # a long chunk (less padding)
        gaps = (need is None or bool(need[j:j + nb_long].any())
                or 2 * (nv - v) <= nb_long * block)
        nb = nb_short if gaps else nb_long
        size = nb * block
        # the chunk's samples (packed chunk by chunk, while the device works on the previous
        # one); positions without a sample: the current block's samples before k, the padding
        # after the last sample
        m = min(size, nv - v)
        lead = pad if v == 0 else 0
        lo, hi = base + v + lead, base + v + m
        # the reading before the chunk's first sample, for a gap there (bridged from it): in the
        # row before that sample, or in the header when there is none
        before = gyr[lo - 1] if lo > 0 else gyr_prev
        first_gap = lo < hi and bool(core.gaps_in(dts[lo:lo + 1], p, xp=np)[0])
        data = chunk_data(nb, block, lead, gyr[lo:hi], acc[lo:hi], dts[lo:hi],
                          None if tv is None else tv[lo:hi], None if vv is None else vv[lo:hi],
                          gyr_before=before if lead else None)
        n_update = m // block if v + m == nv else nb
        head = chunk_head(sums0 if v == 0 else None, n_update, nb,
                     before if first_gap and not lead else None)
        x, current, outs = tilt_kernels.run_chunk(x, head, data, p_vec, block, p._fields,
                                                  gaps=gaps, transitions=transitions)
        if transitions:
            trans.append(outs[-1][:n_update])
            outs = outs[:-1]
        pending.append((lo, lead, m, size, outs))
        v += m
        j += nb
    dropout = _dropout_variance(gyr, acc, dts, k, pad, float(sums0[S.qmiss]), block, p, tv)
    return _Dispatched(x, current, pending, trans, transitions, k, pad, base, nv, block, sums0,
                       dropout)


def _collect(res, run_: _Dispatched):
    """Write the outputs of the dispatched chunks (:func:`_dispatch`) into ``res`` (as they
    arrive: the host's copies overlap the device's work on the later chunks). Returns the filter,
    the sums and the count after the last sample, and the :class:`Transitions` (None unless
    ``transitions``)."""
    x, current, pending, trans, transitions, k, pad, base, nv, block, sums0, dropout = run_
    for lo, lead, m, size, outs in pending:
        gap0 = bool(sums0[S.gap] > 0) if lo == k else False
        if lead == 0 and m == size:
            put_chunk(res, lo, outs, block)
        else:  # a chunk with positions without a sample: through a temporary
            tmp = empty_output(size, np.empty)
            put_chunk(tmp, 0, outs, block, gap0=gap0)
            for dst, src in zip(res, tmp, strict=True):
                dst[lo:lo + m - lead] = src[lead:m]
    if dropout is not None:
        res.var[k:, E.tilt] += dropout[:, None]
    count = nv % block
    sums = np.asarray(current) if count else _EMPTY_SUMS.copy()
    trans = (Transitions(base, np.concatenate([np.asarray(t) for t in trans]))
             if transitions else None)
    return np.asarray(x), sums, count, trans


def chunk_data(nb: int, block: int, lead: int, gyr, acc, dts, tv=None, vv=None,
               gyr_before=None):
    """A chunk's input for ``tilt_kernels.run_chunk``: (``nb * block``, ``CHUNK_SAMPLE``), a row
    per sample, from the ``m`` samples ``gyr``, ``acc`` (m, 3), ``dts``, ``tv``, ``vv`` (m,)
    (None: zeros) placed from position ``lead`` on. The positions without a sample (the ``lead``
    ones, and those after the samples) are skipped samples (dt = NaN: BAD_DT), so that every
    chunk has one of the two compiled shapes; the last ``lead`` one holds ``gyr_before``, the
    reading before the first sample (the rate before a gap there), if given."""
    size = nb * block
    m = lead + gyr.shape[0]
    rows = np.empty((size, CHUNK_SAMPLE.size))
    rows[:lead, :] = 0.0
    rows[:lead, CHUNK_SAMPLE.dt] = np.nan
    if lead and gyr_before is not None:
        rows[lead - 1, CHUNK_SAMPLE.gyr] = gyr_before
    rows[lead:m, CHUNK_SAMPLE.gyr] = gyr
    rows[lead:m, CHUNK_SAMPLE.acc] = acc
    rows[lead:m, CHUNK_SAMPLE.dt] = dts
    rows[lead:m, CHUNK_SAMPLE.tilt_var] = 0.0 if tv is None else tv
    rows[lead:m, CHUNK_SAMPLE.vel_var] = 0.0 if vv is None else vv
    if m < size:
        rows[m:, :] = 0.0
        rows[m:, CHUNK_SAMPLE.dt] = np.nan
    return rows


def _dropout_variance(gyr, acc, dts, k, pad, qmiss0, block, p, tv=None):
    """What gyro dropouts and gaps have added to the tilt variances since each block's start
    (``tilt_core.output_var``: the kernel gives the block-start variances; the block's last
    sample already has the updated ones), per sample from ``k`` on (to add to both tilt
    variances), the first block having begun ``pad`` samples before ``k`` with ``qmiss0`` in its
    sums; None when there is nothing to add (a recording without dropouts)."""
    g = gyr[k:]
    extra = tv is not None and bool(np.any(tv[k:] > 0))
    if (qmiss0 == 0.0 and not extra and _within(g, MAX_RATE_RAD_S)
            and not np.any(dts[k:] > p.gap_flag_s)):
        return None  # every gyro sample valid (a NaN fails the test), no gap, no clipping
    t = core.sample_terms(gyr[k:].T, acc[k:].T, dts[k:], p, xp=np,
                          tilt_var=tv[k:] if extra else 0.0)
    m = t.dts.shape[0]
    q = np.zeros(-(-(pad + m) // block) * block)
    q[pad:pad + m] = t.sums["qmiss"]
    q[0] += qmiss0
    q = np.cumsum(q.reshape(-1, block), axis=1)
    q[:, -1] = 0.0
    return q.reshape(-1)[pad:pad + m]


def blocks_needing_gaps(dts, acc, k, block, p, pending, t_sum, pad: int = 0,
                        gap0: bool = False):
    """Per block from sample ``k − pad`` on (a block boundary): True where the block holds a gap
    or starts while the tilt is to be re-acquired after a gap (or the start): there the batch
    kernel needs its gap handling. A host twin of the kernel's state from the data alone (the gap
    samples and each block's accelerometer time, ``tilt_core.sample_terms``); it holds the flag one
    block longer than the kernel, so that rounding in the sums cannot make it clear first, and
    ignores the accelerometer time of the ``pad`` samples of the first block before ``k`` (they
    can only delay the re-acquisition it foresees). ``pending``, ``t_sum``: the re-acquisition
    state at the first block's start; ``gap0``: the first block already holds a gap."""
    n = dts.shape[0]
    base = k - pad
    nb = -(-(n - base) // block)
    need = np.zeros(nb, dtype=bool)
    if p.gap_flag_s >= 0:  # a gap is a valid Δt above gap_flag_s: test the few candidates
        cand = np.flatnonzero(dts[k:] > p.gap_flag_s)
        gap = np.zeros(n - k, dtype=bool)
        gap[cand] = core.gaps_in(dts[k:][cand], p, xp=np)
    else:
        gap = core.gaps_in(dts[k:], p, xp=np)
    gap_blocks = np.unique(np.concatenate([[0] if gap0 else [],
                                           (np.flatnonzero(gap) + pad) // block])).astype(int)
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
        lo, hi = max(k, base + j * block), min(n, base + hi_b * block)
        ok = _acc_ok(acc[lo:hi], dts[lo:hi])
        w = np.zeros((hi_b - j) * block)
        off = lo - (base + j * block)
        w[off:off + hi - lo] = np.where(ok, dts[lo:hi], 0.0)
        t_blk = t_sum + np.cumsum(w.reshape(-1, block).sum(axis=1))
        g = int(np.searchsorted(gap_blocks, j))
        g = int(gap_blocks[g]) if g < gap_blocks.size and gap_blocks[g] < hi_b else hi_b
        done = np.flatnonzero(t_blk[:g - j] >= p.reacquire_s)
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


def put_chunk(res, k0: int, outs, block: int, gap0: bool = False):
    """Write the outputs of one ``tilt_kernels.run_chunk`` (all its samples) into ``res`` from
    sample ``k0`` on: one whole copy per per-sample field, bias and variances broadcast per block.
    ``gap0``: the chunk's first block holds a gap before the chunk."""
    quat, up, roll, pitch, fl, rows = (np.asarray(o) for o in outs)
    nb = rows.shape[0]
    n = nb * block
    sl = slice(k0, k0 + n)
    res.quat_E_S[sl], res.up_S[sl], res.roll_rad[sl], res.pitch_rad[sl] = quat, up, roll, pitch
    res.flags[sl] = fl
    for a, start, end in ((res.bias_S_rad_s, rows[:, ROW.b0], rows[:, ROW.b1]),
                          (res.var, rows[:, ROW.var0], rows[:, ROW.var1])):
        v = a[sl].reshape((nb, block) + a.shape[1:], copy=False)  # (nb, block, ...) view
        v[:, :-1] = start[:, None, :]
        v[:, -1] = end
    # REACQUIRING (x.reacquire or a gap in the block so far; rare: after a gap or the start),
    # which the kernel leaves to the host
    fl = fl.reshape(nb, block)
    pend_start, pend_end = rows[:, ROW.reacquire0] > 0.5, rows[:, ROW.reacquire1] > 0.5
    pend_start[0] |= gap0
    # a block holding a gap is pending after it (its update, if the chunk applied it, says so too)
    rare = np.flatnonzero(pend_start | pend_end | np.any(fl & DT_GAP, axis=1))
    if rare.size:
        # a block pending at its start is flagged from its first sample; one that only turns
        # pending (it holds a gap) from its gap on; the last sample as the state after the update
        first = np.where(pend_start[rare], 0, np.argmax((fl[rare] & DT_GAP) > 0, axis=1))
        kk = np.arange(block)[None, :]
        on = (kk >= first[:, None]) & (kk < block - 1)
        on[:, -1] = pend_end[rare]
        fl_dst = res.flags[sl].reshape(nb, block, copy=False)
        fl_dst[rare] |= np.where(on, REACQUIRING, 0).astype(fl_dst.dtype)
