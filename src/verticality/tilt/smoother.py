"""The offline smoother of the 3-D tilt filter (``tilt.smooth``): a Rauch–Tung–Striebel backward
pass over the block filter's error state.

The forward pass is the filter itself (``tilt_batch.run`` with ``transitions``: the same block
update, :func:`verticality.tilt.core.block_update`, which also reports each block as a
linear-Gaussian step, :class:`~verticality.tilt.core.BlockTransition`). Per block
``j`` it gives the covariance at its start ``P0_j`` (the filtered ``P⁺`` of the block before), the
error transition ``F_j``, the covariance before its measurement updates ``P⁻_j`` and the
correction ``dx_j`` the updates applied. Backward, with ``e_j`` the smoothed error at the start of
block ``j`` (``x^s = x⁺ ⊕ e``) and ``e'_j = e_{j+1}`` the one at its end::

    C_j  = P0_j F_jᵀ (P⁻_j)⁻¹
    e_j  = C_j (e'_j + dx_j)                    (x^s ⊖ x⁻ = e' + dx: the tilt parts of e' and dx
                                                 are horizontal, their composition's error is
                                                 vertical, the heading)
    P^s_j = P0_j + C_j (P^s'_j − P⁻_j) C_jᵀ

from ``e = 0``, ``P^s = P⁺`` after the last updated block (the filter's final estimate is the
smoothed one). Where a block is a gap, collects the specific force for a re-acquisition or
re-acquires (``split``), ``C = 0``: the recording is smoothed in independent segments, and nothing
after a gap changes the estimate before it. A velocity reset (``BlockTransition``) zeroes ``F``'s
velocity rows, so ``C``'s velocity columns vanish there: the smoothed velocity after a reset says
nothing about the velocity before it.

Samples inside a block: the filter's sample (the block-start estimate carried by the gyro,
``tilt_core.sample_quat``) corrected by the smoothed error interpolated linearly in time between
the block's smoothed ends (``e_j`` at its start, ``e'_j + dx_j`` at its end, relative to the
gyro-carried prediction); within a block the error's change is the bias error times the time
(``F``), linear to first order. The bias likewise; the variances are interpolated the same way
(plus what gyro dropouts add within the block, as the filter reports them). Inside a split block
the filter's samples are kept; its last sample carries the smoothed block end.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from verticality.core import sizing, so3
from verticality.tilt import core
from verticality.tilt.batch import Transitions
from verticality.tilt.kernels import atan2, quat_exp_batched
from verticality.tilt.layout import NE, TRANS, E

# memory per sample of a smoothing run (the inputs, the filter's outputs smoothed in place, the
# per-block transitions, the device's copies): the peak resident size grew by ~490 bytes per
# sample from 10⁶ to 2·10⁶ samples; with a margin (2 GiB: ~2.7·10⁶ samples, 2.6 h at 285 Hz)
BYTES_PER_SAMPLE = 800


def check_size(n: int) -> None:
    """Refuse a recording of ``n`` samples whose smoothing would need more memory than
    :data:`verticality.core.sizing.MAX_WORK_BYTES` (the smoother holds the whole recording)."""
    sizing.check_work_size(n, BYTES_PER_SAMPLE, "samples held at once by the offline smoother",
                           "smooth the recording in parts (cut it where the IMU rests or at a "
                           "gap), or use the causal filter (estimate without --offline), which "
                           "reads and filters the recording piece by piece")


def matmul(a, b):
    """``a @ b`` of (..., n, k) and (..., k, m) stacks, element-wise (XLA on a CPU runs a
    broadcast product and a sum over 10 × 10 matrices faster than a dot)."""
    return jnp.sum(a[..., :, :, None] * b[..., None, :, :], axis=-2)


def solve_spd(A, B):
    """``A⁻¹ B`` for stacks of symmetric positive-definite ``A`` (M, n, n) and ``B`` (M, n, m):
    Gaussian elimination without pivoting (stable for a positive-definite matrix), unrolled over
    the few rows, each step element-wise over the stack."""
    A, B = jnp.asarray(A), jnp.asarray(B)
    n, m = A.shape[-1], B.shape[-1]
    a = [[A[:, i, j] for j in range(n)] for i in range(n)]
    b = [[B[:, i, j] for j in range(m)] for i in range(n)]
    for k in range(n):
        for i in range(k + 1, n):
            f = a[i][k] / a[k][k]
            a[i] = [a[i][j] - f * a[k][j] if j > k else a[i][j] for j in range(n)]
            b[i] = [b[i][j] - f * b[k][j] for j in range(m)]
    x = [None] * n
    for i in reversed(range(n)):
        x[i] = [(b[i][j] - sum(a[i][k] * x[k][j] for k in range(i + 1, n))) / a[i][i]
                for j in range(m)]
    return jnp.stack([jnp.stack(row, axis=-1) for row in x], axis=-2)


def rts_gains(P0, F, P_prior, split):
    """The smoother gains ``C = P0 Fᵀ (P⁻)⁻¹`` of a stack of blocks ((M, 10, 10) each; ``split``
    (M,) bool: ``C = 0``). ``P⁻`` and ``P0`` are symmetric: ``C = ((P⁻)⁻¹ F P0)ᵀ``. A gain that
    is not finite (a covariance singular to rounding) splits there too: nothing finite becomes
    non-finite."""
    C = jnp.swapaxes(solve_spd(P_prior, matmul(F, P0)), -1, -2)
    cut = split | ~jnp.all(jnp.isfinite(C), axis=(-2, -1))
    return jnp.where(cut[:, None, None], 0.0, C)


def rts_backward(P0, F, P_prior, dx, split, P_end):
    """The backward pass (module doc) over M blocks: ``P0``, ``F``, ``P_prior`` (M, 10, 10), ``dx``
    (M, 10), ``split`` (M,) bool, ``P_end`` (10, 10) the filtered covariance after the last block.
    Returns ``(e, Ps)``: the smoothed error (M, 10) and covariance (M, 10, 10) at each block's start
    (a reverse ``lax.scan``)."""
    C = rts_gains(P0, F, P_prior, split)

    def back(carry, blk):
        e_end, Ps_end = carry
        Cj, P0j, Ppj, dxj = blk
        e = jnp.sum(Cj * (e_end + dxj)[None, :], axis=1)
        Ps = P0j + matmul(matmul(Cj, Ps_end - Ppj), Cj.T)
        Ps = 0.5 * (Ps + Ps.T)
        return (e, Ps), (e, Ps)

    _, (e, Ps) = jax.lax.scan(back, (jnp.zeros(NE), P_end), (C, P0, P_prior, dx), reverse=True,
                              unroll=16)
    return e, Ps


def _diag(P):
    return jnp.diagonal(P, axis1=-2, axis2=-1)


@jax.jit
def _smooth_ends(rows, P_end):
    """Per block (``rows`` (M, ``TRANS``), ``P_end`` (10, 10)): what its samples need (``ENDS``
    (M, 6 NE + 1), see :func:`_smooth_samples`): the error corrections at its start ``e``, at its
    end relative to the gyro-carried prediction ``e' + dx`` and at its last sample ``e'``; the
    smoothed variances minus the filtered ones at its start and end, and the smoothed ones at its
    end; ``split``."""
    m = rows.shape[0]
    P0 = rows[:, TRANS.P0].reshape(m, NE, NE)
    dx = rows[:, TRANS.dx]
    split = rows[:, TRANS.split] > 0.5
    e, Ps = rts_backward(P0, rows[:, TRANS.F].reshape(m, NE, NE),
                         rows[:, TRANS.P_prior].reshape(m, NE, NE), dx, split, P_end)
    e_end = jnp.concatenate([e[1:], jnp.zeros((1, NE))])
    var_end = jnp.concatenate([_diag(Ps)[1:], _diag(P_end)[None]])
    var0 = _diag(P0)
    return jnp.concatenate([e, e_end + dx, e_end, _diag(Ps) - var0, var_end - var0, var_end,
                            split[:, None].astype(jnp.float64)], axis=1)


@jax.jit
def _smooth_samples(ends, quat, bias, var, dts):
    """The smoothed samples of a chunk of whole blocks: ``ends`` (M, 6 NE + 1) from
    :func:`_smooth_ends`, the filter's ``quat`` (M, block, 4), ``bias`` (M, block, 3), ``var``
    (M, block, NE) and the valid steps ``dts`` (M, block) (0 where a sample's Δt is not valid).
    Returns the smoothed ``(quat, up, roll, pitch, bias, var)`` in the same layout."""
    block = dts.shape[1]
    e0, e1, e_last, v0, v1, v_last = (ends[:, None, i * NE:(i + 1) * NE] for i in range(6))
    split = ends[:, None, None, 6 * NE] > 0.5
    T = jnp.sum(dts, axis=1, keepdims=True)
    w = (jnp.cumsum(dts, axis=1) / jnp.where(T > 0, T, 1.0))[..., None]  # (M, block, 1)
    last = (jnp.arange(block) == block - 1)[None, :, None]
    corr = jnp.where(last, e_last, jnp.where(split, 0.0, (1.0 - w) * e0 + w * e1))
    dq = quat_exp_batched(corr[..., 0], corr[..., 1], jnp.zeros_like(corr[..., 0]))
    q = so3.quat_normalize_components(so3.quat_multiply_components(
        dq, tuple(quat[..., i] for i in range(4))))
    up, roll, pitch = core.up_roll_pitch(q, atan2=atan2)
    var_s = jnp.where(last, v_last, jnp.where(split, var, var + (1.0 - w) * v0 + w * v1))
    return (jnp.stack(q, axis=-1), jnp.stack(up, axis=-1), roll, pitch,
            bias + corr[..., E.bias], jnp.maximum(var_s, 0.0))


CHUNK_BLOCKS = 1024  # blocks per call of the per-sample pass (one compiled shape)


def _padded_blocks(m: int) -> int:
    """The number of blocks the compiled backward pass runs for ``m``: the next power of two (a
    few compiled shapes serve every recording)."""
    return 1 << max(0, (m - 1).bit_length())


def smoothed_output(out: core.TiltOutput, trans: Transitions, P_end, dts,
                    block: int) -> core.TiltOutput:
    """The filter's output ``out`` (NumPy, from the recording's start) smoothed with the run's
    block updates ``trans`` (``tilt_batch.run(..., transitions=True)``), ``P_end`` (10, 10) the
    final filtered covariance, ``dts`` (N,) the steps. The samples before the first updated
    block (up to the initialization) and after the last (the unfinished block) are the filter's:
    there the smoothed estimate is the filtered one. Flags and ``measured`` are the filter's.
    ``out`` is smoothed in place (and returned)."""
    m = trans.rows.shape[0]
    if m == 0:
        return out
    mp = _padded_blocks(m)
    rows = np.zeros((mp, TRANS.size))
    rows[:m] = trans.rows
    eye = np.eye(NE).reshape(-1)  # padding: split blocks with the final covariance
    rows[m:, TRANS.P0] = np.asarray(P_end).reshape(-1)
    rows[m:, TRANS.F] = eye
    rows[m:, TRANS.P_prior] = eye
    rows[m:, TRANS.split] = 1.0
    ends = np.asarray(_smooth_ends(rows, np.asarray(P_end, dtype=np.float64)))
    ends = np.concatenate([ends, np.zeros((-mp % CHUNK_BLOCKS, ends.shape[1]))])  # whole chunks
    d = np.asarray(dts, dtype=np.float64)
    d = np.where(core.valid_dt(d), d, 0.0)
    fields = (out.quat_E_S, out.up_S, out.roll_rad, out.pitch_rad, out.bias_S_rad_s, out.var)
    pending = []
    for j in range(0, m, CHUNK_BLOCKS):  # dispatch every chunk, then copy (overlapping)
        nb = min(CHUNK_BLOCKS, m - j)
        lo = trans.start + j * block
        ins = []
        for a, fill in ((out.quat_E_S, (1.0, 0.0, 0.0, 0.0)), (out.bias_S_rad_s, 0.0),
                        (out.var, 0.0), (d, 0.0)):
            z = np.empty((CHUNK_BLOCKS * block,) + a.shape[1:])
            z[:nb * block] = a[lo:lo + nb * block]
            z[nb * block:] = fill
            ins.append(z.reshape((CHUNK_BLOCKS, block) + a.shape[1:]))
        pending.append((lo, nb, _smooth_samples(ends[j:j + CHUNK_BLOCKS], *ins)))
    for lo, nb, res in pending:
        for dst, src in zip(fields, res, strict=True):
            src = np.asarray(src)
            dst[lo:lo + nb * block] = src.reshape((-1,) + src.shape[2:])[:nb * block]
    return out
