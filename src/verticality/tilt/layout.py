"""The flat vectors of the 3-D tilt filter, field by field: one layout per vector, used by every
reader (``v[X.P]``, ``v[..., S.tau]``) and every writer (``X.pack(q=..., b=..., ...)``), so that no
code holds an offset.

The kernels keep the filter in flat float64 vectors (a ``lax.scan`` carry, a chunk's rows, the
real-time stepper's state), because XLA on a CPU runs one flat vector faster than a tree of small
arrays. The layouts:

* :data:`E` the error state (7): tilt error ``δ`` about Earth's horizontal axes, horizontal
  velocity error ``ṽ``, gyro bias error ``b̃``; the rows and columns of ``P``.
* :data:`X` the filter at a block boundary (``TiltState.x``): ``q`` = ``q_E_S`` (wxyz), ``b`` the
  gyro bias (rad/s), ``v`` the horizontal velocity ``v_E`` (m/s), ``P`` (10 × 10, row-major), the
  low-passed ``(|f| − g)²`` ``acc_dev_var``, the time at rest ``rest_s``, and the re-acquisition
  after a gap or the start: ``reacquire`` (1.0 while pending), ``reacq_f_E`` (Σ R f Δt since the
  gap, Earth) and ``reacq_t`` (its Σ Δt); the persistence test's running mean of the whitened
  velocity innovations ``vel_inn`` and the tilt and bias corrections the velocity made over it
  ``vel_fix`` (5); the low-passed per-axis mean squares of the velocity ``speed_var`` and of its
  change over a block ``dv_var`` (m²/s², the motion's correlation time).
* :data:`S` the sums of the samples of the current block (``TiltState.sums``, the per-sample
  pre-integration): ``dquat`` the raw gyro rotation since the block start, ``tau`` the time
  integrated by a valid gyro, ``f`` Σ f Δt (block-start sensor frame) over valid accelerometer
  samples, ``t_acc`` their Σ Δt, ``dev2`` Σ (|f| − g)² Δt, ``w2`` Σ |ω|² Δt, ``t`` Σ Δt, ``qmiss``
  Σ (ω_missing Δt)² over gyro dropouts and gaps, ``gsum`` Σ ω Δt, ``asum`` Σ f Δt (sensor frame),
  ``a2`` Σ |f|² Δt, ``gap`` the number of gap samples, ``vmiss`` the velocity variance of clipped
  accelerometer samples (m²/s²).
* :data:`C` the per-block inputs of the block update that do not depend on the filter state
  (computed for all the blocks of a chunk before the scan over blocks): among them ``steady``
  (neither sensor varies within the block) and ``still0`` (steady with a gyro that reads no
  rotation), the rest tests' state-free parts.
* :data:`Z` the real-time stepper's state: ``x``, ``sums``, ``count`` (samples in the block),
  ``initialized`` (1.0 or 0.0), ``gyr_prev`` (the last gyro reading).
* :data:`SAMPLE` one sample ``[gyr (3), acc (3), dt]`` (the stepper's input).
* :data:`CHUNK_SAMPLE` a batch chunk's sample: a :data:`SAMPLE` (same offsets), ``tilt_var`` and
  ``vel_var``, the tilt (rad²) and velocity (m²/s²) variances the sample adds besides its own
  terms (clipped gyro and accelerometer axes, :mod:`~verticality.tilt.limits`); a row of the
  chunk's input.
* :data:`OUT` the stepper's output ``[roll, pitch, up (3), quat (4), bias (3), flags]``.
* :data:`ROW` the batch kernel's row per block: the state at its start (``q0``, ``b0``, ``var0``
  the diagonal of ``P``) and after its update (``q1``, ``b1``, ``var1``), whether the update found
  the accelerometer disturbed and re-acquired the tilt, and ``reacquire`` before and after.
* :data:`TRANS` the batch kernel's row per block for the offline smoother: the covariance at the
  block's start ``P0`` and the block's :class:`~verticality.tilt.core.BlockTransition`
  (``F``, ``P_prior``, ``dx``, ``split``; matrices row-major).
* :data:`HEAD` the batch kernel's chunk header: the sums the chunk's first block starts from,
  the number of blocks whose update the chunk applies and the gyro reading before the chunk's
  first sample (a gap's rate before it; NaN where no gap starts the chunk).
"""

from __future__ import annotations

import jax.numpy as jnp


class Packed:
    """Named fields of a flat vector: ``(name, size)`` pairs in order, ``size`` None for a scalar.

    Each name is an attribute holding its index: an int for a scalar field, a slice otherwise
    (read ``v[L.name]`` or ``v[..., L.name]``; along the leading axis ``v[L.name]`` too).
    :meth:`pack` writes a vector from all its fields by name."""

    def __init__(self, fields):
        self.fields = tuple(fields)
        offset = 0
        for name, size in self.fields:
            if name in ("fields", "size", "pack") or name.startswith("_"):
                raise ValueError(f"field name {name!r} is reserved")
            setattr(self, name, offset if size is None else slice(offset, offset + size))
            offset += 1 if size is None else size
        self.size = offset

    def pack(self, xp=jnp, axis: int = -1, summed: bool = False, **values):
        """The vector (or, with leading axes, the stack of vectors along ``axis``) holding
        ``values``: every field by name; a vector field as an array with its size along ``axis``
        or as a tuple of its components; scalars are cast to float64. ``xp`` is ``jax.numpy`` or
        ``numpy``. ``summed``: the vector as the sum of its fields each padded with zeros (the
        same values but for the sign of a zero; in a ``lax.scan`` body XLA fuses it with the
        fields' computation, where it runs a concatenate as a kernel of its own)."""
        names = [n for n, _ in self.fields]
        if set(values) != set(names):
            missing = [n for n in names if n not in values]
            extra = [n for n in values if n not in names]
            raise ValueError(f"pack: missing {missing}, unknown {extra}")
        parts = []
        for name, size in self.fields:
            v = values[name]
            if size is None:
                v = xp.expand_dims(xp.asarray(v, dtype=xp.float64), axis)
            elif isinstance(v, tuple | list):
                if len(v) != size:
                    raise ValueError(f"pack: {name} has {len(v)} components, expected {size}")
                v = xp.stack([xp.asarray(c, dtype=xp.float64) for c in v], axis=axis)
            else:
                v = xp.asarray(v, dtype=xp.float64)
                if v.shape[axis] != size:
                    raise ValueError(f"pack: {name} has size {v.shape[axis]}, expected {size}")
            parts.append(v)
        if not summed:
            return xp.concatenate(parts, axis=axis)
        # each part padded with zeros to the full length, the parts added: element-wise, so that
        # XLA fuses it with the parts' own computation (a concatenate is a kernel of its own, and
        # so is each of its operands)
        out, offset = None, 0
        for v in parts:
            widths = [(0, 0)] * v.ndim
            widths[axis] = (offset, self.size - offset - v.shape[axis])
            offset += v.shape[axis]
            v = xp.pad(v, widths)
            out = v if out is None else out + v
        return out


NE = 10  # error-state dimension
E = Packed([("tilt", 2), ("vel", 2), ("bias", 3), ("scale", 3)])
X = Packed([("q", 4), ("b", 3), ("v", 2), ("P", NE * NE), ("acc_dev_var", None),
            ("rest_s", None), ("reacquire", None), ("reacq_f_E", 3), ("reacq_t", None),
            ("vel_inn", 2), ("vel_fix", 5), ("speed_var", None), ("dv_var", None),
            ("s", 3)])
P_DIAG = slice(X.P.start, X.P.stop, NE + 1)  # the diagonal of the packed P
S = Packed([("dquat", 4), ("tau", None), ("f", 3), ("t_acc", None), ("dev2", None),
            ("w2", None), ("t", None), ("qmiss", None), ("gsum", 3), ("asum", 3), ("a2", None),
            ("gap", None), ("vmiss", None)])
C = Packed([("dquat", 4), ("tau", None), ("f", 3), ("T", None), ("has_acc", None),
            ("q_gyr", None), ("q_vel", None), ("qb", None), ("alpha", None), ("dev2", None),
            ("g_mean", 3), ("steady", None), ("still0", None), ("r_vel", None),
            ("r_vel_rest", None), ("r_b", None), ("gap", None), ("t_acc", None), ("gsum", 3),
            ("lam", None)])
Z = Packed([("x", X.size), ("sums", S.size), ("count", None), ("initialized", None),
            ("gyr_prev", 3)])
SAMPLE = Packed([("gyr", 3), ("acc", 3), ("dt", None)])
CHUNK_SAMPLE = Packed([("gyr", 3), ("acc", 3), ("dt", None), ("tilt_var", None),
                       ("vel_var", None)])
OUT = Packed([("roll", None), ("pitch", None), ("up", 3), ("quat", 4), ("bias", 3),
              ("flags", None)])
ROW = Packed([("q0", 4), ("b0", 3), ("s0", 3), ("var0", NE), ("q1", 4), ("b1", 3), ("var1", NE),
              ("disturbed", None), ("reacquired", None), ("reacquire0", None),
              ("reacquire1", None)])
TRANS = Packed([("P0", NE * NE), ("F", NE * NE), ("P_prior", NE * NE), ("dx", NE),
                ("split", None)])
HEAD = Packed([("sums0", S.size), ("n_update", None), ("gyr_prev", 3)])
