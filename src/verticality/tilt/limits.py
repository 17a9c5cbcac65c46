"""Sensors at their limits, found in a recording before the tilt filter runs
(:func:`verticality.tilt.estimate`, :func:`~verticality.tilt.smooth`):
clipped (saturated) gyro and accelerometer axes, and held rows (a logger faster than its sensor
repeats the sensor's last reading). NumPy, on the host; the filter receives the result as per-sample
inputs (:class:`Limits`).

**Clipping.** A sensor at the end of its range reads its full-scale value whatever the true value
beyond it. A reading is clipped when a component is at or beyond the range the user gives
(``gyr_range_rad_s``, ``acc_range_m_s2``: the full-scale reading, a scalar or one per axis), or,
when no range is given, at a level inferred from the recording's flat tops: on each axis and side,
the recording's extreme value when it is read by a run of at least :data:`MIN_RUN` consecutive
identical samples (held rows not counted: they repeat every channel) and lies beyond the smallest
range of common parts (:data:`GYR_FLOOR_RAD_S`, :data:`ACC_FLOOR_M_S2`). ``MIN_RUN`` = 4: a noisy
sensor rarely reads the same value twice in a row at its extreme (on the twelve BROAD trials,
286 Hz, every axis's extreme on either side is read by runs of at most 2), while a motion beyond a
range reads its full scale for as long as it lasts (tens of samples at 100 Hz for a rotation that
peaks 50 % above the range); 4 is twice the longest run seen on clean data. The floors keep a dead
or constant axis (all zeros, a level sensor's steady 1 g) from counting as clipped.

**A plateau after calibration.** A sensor clips in its own raw axes, at its converter's end codes
(a 16-bit part reads −32768 … +32767: the limits differ by sign, and by the offset the
calibration removes), and the file often holds the readings *after* a calibration
``y = C⁻¹ (r − b)`` (scale, cross-axis and offset estimates). While raw axis i sits at its end
code, ``a · y`` is constant, ``a`` the i-th row of ``C`` (within a few degrees of axis i: cross-axis
terms are ±1–2 %), while the other raw axes move; so in the file the plateau is a *plane*, not a
flat top: the calibrated axis wanders by the cross-axis terms times the other axes' motion (1e-3
of full scale is typical) and no two samples need be equal. When the sensing element's noise is
added before the converter saturates (digital MEMS parts), the raw plateau is exact, and along
``a`` the file's plateau is flat to its rounding, far below the noise. :func:`inferred_clipping`
looks for exactly that, per axis and side: the extreme of ``a · y`` read by :data:`MIN_RUN`
consecutive samples within :data:`PLANE_TOL` (1/16) of the recording's own noise σ along ``a``
(:func:`noise_std`, from the second differences) plus the storage step (:func:`_resolution`),
``a`` either the axis itself (the flat top above, read exactly as before) or a raw axis
direction recovered from the plateau: every step between two consecutive plateau samples lies
in the plane, so two such steps span it (:func:`_raw_axis_candidates`, within
:data:`PLANE_TILT_RAD` of the axis), refitted to all the samples at its extreme
(:func:`_refined`). A clean peak reads noise: a sample within σ/16 of the recording's extreme is
rare, four in a row rarer still. A recovered direction must also be fixed by its plateau (two
runs, or a lone run of :data:`PLANE_LONE_RUN` samples spread across a line by
:data:`PLANE_SPREAD` σ): a recording upsampled by linear interpolation holds runs of collinear
samples, and every plane through their line holds them flat (found on BROAD resampled to
1000 Hz). What cannot be recovered: a plateau shorter than ``MIN_RUN`` samples on every visit (a
brief clip at 50 Hz), a plateau whose noise comes after the clipping (an analog front end that
saturates before the converter: the plateau then reads noise like a peak), and a file whose axes
were rotated into another frame (the plane is then far from every axis). The given range
(``gyr_range_rad_s``) covers the first two.

What the filter does with a clipped reading, by physics: its true value lies *beyond* the clip
level (a one-sided constraint, neither a point value nor a missing one), and a signal passes a
range in a smooth peak whose way in and out the unclipped samples either side of the run show.
So each clipped run's peak is fitted from its flanks (:func:`peak_excess`), its excess added to
the clipped readings (:meth:`Limits.readings`), and what is left of the excess is an unknown
constant over the run (one motion, not white noise) of σ from the fit (:data:`EXCESS_SPREAD` of
its integral and the flanks' noise); a run whose peak cannot be fitted keeps the bound σ =
:data:`EXCESS_FRACTION` × the clip level and nothing added (a motion that clips a sensor
typically exceeds its range by a fraction of it: a ±7 rad/s gyro on a 10–12 rad/s rotation,
40–70 %). After ``t`` s of clipping on an axis the unknown constant has integrated to variance
``(σ t)²``; each sample adds its increment ``σ² (t_k² − t_{k−1}²)`` (:func:`clip_variance`):

* for a clipped gyro axis, to the tilt variance (:attr:`Limits.tilt_var_rad2`, added where the
  filter adds a gyro dropout's; the projection of the axis on the horizontal is at most 1, so
  adding it to both tilt variances is conservative). The widened σ lets the accelerometer pull
  the tilt back;
* for a clipped accelerometer axis (its other axes are right), to both horizontal velocity
  variances (:attr:`Limits.vel_var_m2_s2`, the velocity's process noise). Dropping the sample
  instead would treat a reading known to be beyond the range as an unknown of the size of an
  ordinary motion's: on a shake that clips more on one side than the other the velocity would
  then miss the clipped side's impulse, biased, and the tilt would follow (a synthetic fast
  translation read by a ±4 g accelerometer, 4 % of its samples clipped: 2.16° dropped, 0.57°
  kept).

A recording without a clipped sample is filtered exactly as read (the readings handed on are the
arrays given). A clip that only the log reports, on readings that do not sit at the level (a
sensor's averaged samples, of whose raw samples some clipped), has no peak to fit and keeps the
bound. A stream (:class:`verticality.tilt.stream.Stream`) cannot see a run's end and
keeps the bound (``find_limits(..., fit_peaks=False)``).

Either way the sample is flagged ``CLIPPED``.

**Held rows.** A row whose six channels equal the previous row's bit for bit is a repeat of the
sensor's last reading (a real noisy sensor essentially never reads the same six values twice). It
is flagged ``HELD`` and otherwise filtered as any row: the filter integrates the gyro and the
specific force over each row's Δt (a zero-order hold of the true signal, integrated over the true
time), and the accelerometer enters only through its Δt-weighted integral over a block, not as one
update per row, so a held accelerometer value counts for the time it was held, exactly as the one
sensor sample it repeats would (its noise variance, too, is the density times that time): nothing
is counted twice.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from verticality.core.constants import G_M_S2
from verticality.core.errors import InputError
from verticality.tilt.flags import CLIPPED, HELD
from verticality.tilt.params import MAX_ACC_M_S2, MAX_RATE_RAD_S

MIN_RUN = 4  # consecutive identical (non-held) samples at an extreme that make it a clip level
GYR_FLOOR_RAD_S = 2.0  # the smallest common gyro range is ±125 °/s ≈ 2.18 rad/s
ACC_FLOOR_M_S2 = 1.5 * G_M_S2  # the smallest common accelerometer range is ±2 g
EXCESS_FRACTION = 0.5  # σ of a clipped run's excess where no peak is fitted, × the clip level
EXCESS_SPREAD = 0.5  # σ of a fitted peak's excess (its integral over the run), × that integral
FLANK_MIN = 2  # unclipped samples needed on each side of a clipped run to fit its peak
FLANK_MAX = 8  # the most samples of each flank the fit uses
# a motion's peak is fuller than the parabola through its flanks (a swing's is a sinusoid's top:
# on the saturation classes the parabola finds 0.87-0.92 of the excess, the chords' bound 1.5-2
# times it): the peak is taken this share of the way from the parabola to that bound
PEAK_CHORD_SHARE = 0.125
PLANE_TOL = 1.0 / 16.0  # a plateau's spread along its raw axis, as a fraction of the noise σ
PLANE_BAND = 0.05  # the share of the extreme within which a calibrated plateau wanders
PLANE_TILT_RAD = 0.1  # the largest angle between a raw axis and its calibrated axis
PLANE_TRIALS = 128  # pairs of plateau steps tried per axis and side
PLANE_KEEP = 4  # raw axis directions evaluated per axis and side
PLANE_SPREAD = 3.0  # a lone plateau run's spread across a line, in noise σ, that fixes its plane
PLANE_LONE_RUN = 2 * MIN_RUN  # the samples a lone plateau run needs to fix its plane


class Limits(NamedTuple):
    """What the sensors' limits mean for each sample of a recording (:func:`find_limits`)."""

    gyr_clipped: np.ndarray  # (N, 3) bool: the gyro component is at its clip level
    acc_clipped: np.ndarray  # (N,) bool: an accelerometer component is at its clip level
    held: np.ndarray  # (N,) bool: the row repeats the previous one bit for bit
    tilt_var_rad2: np.ndarray  # (N,) the tilt variance the clipped gyro axes add at the sample
    vel_var_m2_s2: np.ndarray  # (N,) the velocity variance the clipped accelerometer axes add
    flags: np.ndarray  # (N,) int32: CLIPPED and HELD
    gyr_excess_rad_s: np.ndarray  # (N, 3) the fitted excess of each clipped gyro reading, else 0
    acc_excess_m_s2: np.ndarray  # (N, 3) likewise for the accelerometer

    def run_args(self, rows=slice(None)) -> dict:
        """The filter's per-sample arguments for the samples ``rows`` (``tilt_batch.run``'s
        ``tilt_var``, ``vel_var`` and ``flags``)."""
        return {"tilt_var": self.tilt_var_rad2[rows], "vel_var": self.vel_var_m2_s2[rows],
                "flags": self.flags[rows]}

    def readings(self, gyr, acc, rows=slice(None)):
        """``(gyr, acc)`` of the samples ``rows`` as the filter takes them: each clipped reading
        plus its fitted excess (:func:`peak_excess`); the arrays given, untouched, where nothing
        is added (a recording without clipping is filtered exactly as read)."""
        out = []
        for x, e in ((gyr, self.gyr_excess_rad_s), (acc, self.acc_excess_m_s2)):
            e = e[rows]
            out.append(np.where(e != 0, x + e, x) if e.any() else x)
        return out[0], out[1]


def datasheet_ranges(gyr_range_deg_s=None, acc_range_g=None) -> dict:
    """Full-scale ranges as a datasheet gives them, the gyro's in °/s and the accelerometer's in g
    (``None``: not given, inferred from the recording), as :func:`find_limits`' ranges in SI units
    (``gyr_range_rad_s``, ``acc_range_m_s2``; the keyword arguments of the tilt filter)."""
    return {"gyr_range_rad_s": None if gyr_range_deg_s is None else math.radians(gyr_range_deg_s),
            "acc_range_m_s2": None if acc_range_g is None else acc_range_g * G_M_S2}


def held_rows(gyr, acc, prev=None) -> np.ndarray:
    """(N,) bool: row k's six channels equal row k−1's bit for bit (a row with a NaN is never
    held: a missing reading is no repeated one). ``prev`` (6,): the row before the first (gyro,
    accelerometer), when the recording is read in pieces; else the first row is never held."""
    gyr = np.asarray(gyr, dtype=np.float64)
    acc = np.asarray(acc, dtype=np.float64)
    if prev is not None:
        prev = np.asarray(prev, dtype=np.float64)
        gyr = np.concatenate([prev[None, :3], gyr])
        acc = np.concatenate([prev[None, 3:], acc])
    n = gyr.shape[0]
    # candidates by two channels (a quantized gyro at rest repeats itself, but rarely together
    # with the accelerometer), then all six, bit for bit
    k = np.flatnonzero((gyr[1:, 0] == gyr[:-1, 0]) & (acc[1:, 2] == acc[:-1, 2])) + 1
    if k.size:  # (the candidate rows only: a copy of whole recordings costs more than the test)
        now = np.concatenate([gyr[k], acc[k]], axis=1).view(np.int64)
        before = np.concatenate([gyr[k - 1], acc[k - 1]], axis=1).view(np.int64)
        k = k[np.all(now == before, axis=1)]
    held = np.zeros(n, dtype=bool)
    held[k] = True
    return held[1:] if prev is not None else held


def _longest_run(at) -> int:
    """The longest run of True in the bool vector ``at`` (from the indices where it holds: few,
    at a recording's extreme)."""
    k = np.flatnonzero(at)
    if k.size == 0:
        return 0
    breaks = np.flatnonzero(np.diff(k) != 1)
    edges = np.concatenate([[-1], breaks, [k.size - 1]])
    return int(np.max(np.diff(edges)))


def inferred_levels(x, held, floor: float, min_run: int = MIN_RUN):
    """Clip levels of each axis of ``x`` (N, 3) inferred from flat tops: ``(lo (3,), hi (3,))``,
    the axis's extreme value on each side when it is beyond ``floor`` in size and read by a run of
    at least ``min_run`` consecutive identical samples (rows where ``held`` are left out), else
    ∓inf (no clipping seen on that side)."""
    lo, hi = np.full(3, -np.inf), np.full(3, np.inf)
    if x.shape[0] == 0:
        return lo, hi
    # one axis per contiguous row (one transposing copy: NumPy reduces and compares strided
    # columns several times slower)
    rows = np.ascontiguousarray((x[~held] if held.any() else x).T)
    for i, col in enumerate(rows):
        top, bottom = col.max(), col.min()
        if not (np.isfinite(top) and np.isfinite(bottom)):  # a NaN or ±inf sample: finite only
            ok = np.isfinite(col)
            top = np.max(col, where=ok, initial=-np.inf)
            bottom = np.min(col, where=ok, initial=np.inf)
        for level, out, sign in ((top, hi, 1.0), (bottom, lo, -1.0)):
            # (the run test only for an extreme beyond the floor, read by at least min_run
            # samples: a clean recording reaches its extremes once or twice)
            if sign * level > floor:
                at = col == level
                if np.count_nonzero(at) >= min_run and _longest_run(at) >= min_run:
                    out[i] = level
    return lo, hi


def noise_std(x) -> np.ndarray:
    """(3,) the white noise of each axis of ``x`` (N, 3), from the recording alone: the median
    absolute second difference (white noise of σ gives differences of σ√6; a motion sampled well
    above its own frequencies adds little to them, and the median ignores the samples where it
    does) over 0.6745√6. NaN samples and second differences of 0 (to rounding) are left out: a
    recording upsampled by linear interpolation has second differences only at its knots, where
    they are its noise's, and a quantized quiet sensor only where it steps by a code; 0 for an
    axis with no second difference at all."""
    return _noise_std_columns(np.ascontiguousarray(np.asarray(x, dtype=np.float64).T))


def _noise_std_columns(cols, lows=None, highs=None) -> np.ndarray:
    """:func:`noise_std` of the axes given as contiguous rows ``cols`` (3, N): NumPy reduces and
    compares a contiguous row several times faster than a strided column, and the same values
    give the same medians. ``lows``, ``highs``: each row's minimum and maximum when the caller has
    them."""
    out = np.zeros(cols.shape[0])
    if cols.shape[1] == 0:
        return out
    lows = cols.min(axis=1) if lows is None else lows
    highs = cols.max(axis=1) if highs is None else highs
    for i, c in enumerate(cols):
        d2 = np.multiply(c[1:-1], 2.0)  # |c[2:] − 2 c[1:−1] + c[:−2]|, in one buffer
        np.subtract(c[2:], d2, out=d2)
        np.add(d2, c[:-2], out=d2)
        np.abs(d2, out=d2)
        # (0 to the rounding of the values: 1e-10 of the largest finite one)
        lo, hi = lows[i], highs[i]
        top = (max(hi, -lo) if np.isfinite(lo) and np.isfinite(hi)
               else np.max(np.abs(c), where=np.isfinite(c), initial=0.0))
        col = d2[d2 > 1e-10 * top]  # (a NaN is not above it)
        if col.size and not np.isfinite(col.max()):
            col = col[np.isfinite(col)]
        if col.size:
            # (col is a temporary of its own: partitioned in place, the same median)
            out[i] = np.median(col, overwrite_input=True) / (0.6745 * math.sqrt(6.0))
    return out


def _resolution(col) -> float:
    """The step at which the values of ``col`` are stored, or 0 when they are on no grid: the
    smallest gap between distinct values (read on a sample of them) when nearly every gap is a
    whole multiple of it (a file written with few digits, or quantized codes); a calibrated
    plateau is then rounded by that much."""
    u = np.unique(col[np.isfinite(col)][:: max(1, col.size // 20000)])
    gaps = np.diff(u)
    if gaps.size < 10 or gaps.min() <= 0:
        return 0.0
    m = gaps / gaps.min()
    return float(gaps.min()) if np.mean(np.abs(m - np.round(m)) < 0.01) > 0.99 else 0.0


def _long_runs(at, min_run):
    """The True entries of ``at`` that lie in runs of at least ``min_run``, and how many such
    runs there are."""
    k = np.flatnonzero(at)
    out = np.zeros(at.shape, dtype=bool)
    if k.size < min_run:
        return out, 0
    starts = np.concatenate([[0], np.flatnonzero(np.diff(k) != 1) + 1])
    ends = np.concatenate([starts[1:], [k.size]])
    long = (ends - starts) >= min_run
    for a, b in zip(starts[long], ends[long], strict=True):
        out[k[a]:k[b - 1] + 1] = True
    return out, int(np.count_nonzero(long))


def _plateau_found(x, p, level, tol, sign, ok, sd, axis_itself):
    """``(at, found)``: the samples at the level (``sign·p ≥ sign·level − tol``, rows ``ok``) and
    whether they make a plateau: a run of :data:`MIN_RUN` of them; for a recovered raw axis
    (``axis_itself`` False) the runs must also fix the plane, which samples on one line cannot
    (a recording upsampled by linear interpolation holds runs of collinear samples, and every
    plane through their line holds them "flat"; two such segments meet at a knot, and a plane
    holds them both): two runs or more, or one of at least :data:`PLANE_LONE_RUN` samples (more
    segments than any plane holds by chance) whose samples spread across a line by more than
    :data:`PLANE_SPREAD` times the noise."""
    at = (sign * p >= sign * level - tol) & ok
    runs, count = _long_runs(at, MIN_RUN)
    if count == 0:
        return at, False
    if axis_itself or count >= 2:
        return at, True
    if np.count_nonzero(runs) < PLANE_LONE_RUN:
        return at, False
    pts = x[runs] - x[runs].mean(axis=0)
    across = np.linalg.svd(pts, compute_uv=False)[1] / math.sqrt(pts.shape[0])
    return at, bool(across > PLANE_SPREAD * math.sqrt(float(np.sum(sd**2))))


def _raw_axis_candidates(x, i, sign, band, tol, rng, trials=PLANE_TRIALS):
    """Directions ``a`` (unit, within :data:`PLANE_TILT_RAD` of axis ``i``) along which the
    samples of ``x`` near axis ``i``'s extreme on side ``sign`` may be flat: each spanned by
    the steps between two pairs of consecutive samples in the band (``band`` (N,) bool), then
    refitted to every step it leaves within ``tol`` (the smallest singular direction of those
    steps). A raw axis clipped under a calibration holds ``a · x`` constant, so every step along
    its plateau is orthogonal to ``a``; ordered by how many steps each explains."""
    k = np.flatnonzero(band[:-1] & band[1:])
    if k.size < 2:
        return []
    steps = x[k + 1] - x[k]
    size = np.linalg.norm(steps, axis=1)
    # a step along a plateau is orthogonal to a raw axis within PLANE_TILT_RAD of axis i: its
    # component along i is at most tan(PLANE_TILT_RAD) of the rest (plus the tolerance)
    other = np.sqrt(np.maximum(size**2 - steps[:, i] ** 2, 0.0))
    flat = (size > 0) & (np.abs(steps[:, i]) <= math.tan(PLANE_TILT_RAD) * other + tol)
    k, steps = k[flat], steps[flat]
    if k.size < 2:
        return []
    run = np.cumsum(np.concatenate([[0], np.diff(k) > 1]))  # the band run each step is in
    # (within a run the steps are consecutive rows: k[j] − k[j1] = j − j1 there)
    run_start = np.searchsorted(run, run, side="left")
    run_end = np.searchsorted(run, run, side="right")
    pairs = []
    while trials > 0:
        j1 = int(rng.integers(k.size))
        # the second step from another run, or from the same run at least MIN_RUN steps away
        # (half the trials each): two neighbouring steps at a high rate are nearly parallel,
        # and their cross product is mostly noise; a lone plateau needs two of its own steps.
        # Drawn as rng.choice(pool) draws (an index into the pool, which is sorted), the pool
        # counted rather than listed
        rs, re = int(run_start[j1]), int(run_end[j1])
        if trials % 2:  # the steps of the other runs: [0, rs) and [re, K)
            base, cut, size = 0, rs, k.size - (re - rs)
            jump = re - rs
        else:  # the same run's, MIN_RUN away: [rs, j1 − MIN_RUN] and [j1 + MIN_RUN, re)
            base, cut = rs, max(0, j1 - MIN_RUN + 1 - rs)
            size = cut + max(0, re - (j1 + MIN_RUN))
            jump = j1 + MIN_RUN - rs - cut
        trials -= 1
        if size == 0:
            continue
        r = int(rng.integers(size))
        pairs.append((j1, base + (r if r < cut else r + jump)))
    found = []
    if pairs:
        j1s, j2s = np.array(pairs).T
        cross = np.cross(steps[j1s], steps[j2s])
        # (a direction further than PLANE_TILT_RAD from the axis by a clear margin is left out
        # here; the others are tested exactly as one vector each)
        approx = np.sqrt(np.sum(cross * cross, axis=1))
        near = np.abs(cross[:, i]) >= (1.0 - 1e-9) * math.cos(PLANE_TILT_RAD) * approx
        for a in cross[near & (approx > 0)]:
            norm = np.linalg.norm(a)
            if norm == 0:
                continue
            a = a / norm * np.sign(a[i])
            if a[i] < math.cos(PLANE_TILT_RAD):
                continue
            inl = np.abs(steps @ a) <= tol
            if np.count_nonzero(inl) >= 3:
                a = np.linalg.svd(steps[inl], full_matrices=False)[2][-1]
                a = a * np.sign(a[i])
                inl = np.abs(steps @ a) <= tol
            found.append((int(np.count_nonzero(inl)), a))
    found.sort(key=lambda f: -f[0])
    out = []
    for _, a in found:  # distinct directions only
        if all(np.linalg.norm(a - b) > 1e-9 for b in out):
            out.append(a)
        if len(out) == PLANE_KEEP:
            break
    return out


def _refined(x, a, i, sign, ok, tol_of, rounds: int = 3):
    """``a`` refitted to the samples at its extreme: the normal of the plane through them (the
    smallest singular direction of the centred samples within ``tol_of(a)`` of the extreme of
    ``a · x``), while it stays within :data:`PLANE_TILT_RAD` of axis ``i`` and holds more of
    them. A direction spanned by two steps is as good as those steps; the plateau's samples
    all together fix it to their rounding."""
    count = 0
    for _ in range(rounds):
        p = x @ a
        lvl = np.max(sign * p, where=ok, initial=-np.inf) * sign
        at = (sign * p >= sign * lvl - tol_of(a)) & ok
        if np.count_nonzero(at) <= count or np.count_nonzero(at) < 3:
            break
        count = np.count_nonzero(at)
        pts = x[at] - x[at].mean(axis=0)
        b = np.linalg.svd(pts, full_matrices=False)[2][-1]
        b = b * np.sign(b[i])
        if b[i] < math.cos(PLANE_TILT_RAD):
            break
        a = b
    return a


def inferred_clipping(x, held, floor: float):
    """Clipped samples of ``x`` (N, 3) inferred from the recording alone: ``(clipped (N, 3)
    bool, level (N, 3) the clip level's size where clipped, else 0)`` (module doc, "A plateau
    after calibration"). On each axis and side, the extreme of the projection ``a · x`` read by a
    run of at least :data:`MIN_RUN` consecutive samples within a tolerance the recording's noise
    sets (:data:`PLANE_TOL` × its σ along ``a``, :func:`noise_std`, plus the storage's rounding),
    ``a`` the axis itself (a flat top, read exactly: :func:`inferred_levels`'s detector) or a raw
    axis direction recovered from the plateau (:func:`_raw_axis_candidates`); beyond ``floor`` in
    size. Rows where ``held`` do not count towards a run."""
    n = x.shape[0]
    clipped = np.zeros((n, 3), dtype=bool)
    level = np.zeros((n, 3))
    if n < MIN_RUN:
        return clipped, level
    # one axis per contiguous row (one transposing copy: NumPy reduces and compares strided
    # columns several times slower); a recording whose every value is finite and no row held (the
    # usual one) skips the masks
    cols = np.ascontiguousarray(x.T)
    highs, lows = cols.max(axis=1), cols.min(axis=1)  # (NaN where an axis holds one)
    all_finite = bool(np.all(np.isfinite(highs)) and np.all(np.isfinite(lows)))
    finite = None if all_finite else np.all(np.isfinite(x), axis=1)
    ok = finite & ~held if finite is not None else (~held if held.any() else None)
    if ok is not None and not ok.any():
        return clipped, level
    sides = []  # (axis, extreme, sign) beyond the floor: only these are searched
    for i, col in enumerate(cols):
        if ok is None:
            top, bottom = highs[i], lows[i]
        else:
            top = np.max(col, where=ok, initial=-np.inf)
            bottom = np.min(col, where=ok, initial=np.inf)
        sides += [(i, ext, sign) for ext, sign in ((top, 1.0), (bottom, -1.0))
                  if sign * ext > floor]
    if not sides:
        return clipped, level
    finite = np.ones(n, dtype=bool) if finite is None else finite
    xo = x if ok is None else np.where(ok[:, None], x, 0.0)
    ok = np.ones(n, dtype=bool) if ok is None else ok
    sd = _noise_std_columns(cols, lows, highs)
    res = max(_resolution(c) for c in cols)
    for i, ext, sign in sides:
        col = cols[i]
        rng = np.random.default_rng(i * 2 + (sign > 0))  # the same answer on every run
        base_tol = PLANE_TOL * sd[i] + res
        band = ok & (sign * col >= sign * ext - PLANE_BAND * abs(ext) - base_tol)
        plane_tol = PLANE_TOL * float(np.sqrt(np.sum(sd**2))) + 2.0 * res
        # the axis itself: a flat top is exact in the stored values, so no tolerance (a recording
        # upsampled by linear interpolation holds near-flat segments at its peaks, within σ/16 of
        # their top): the samples at the extreme, a plateau when MIN_RUN of them are consecutive
        at = (col >= ext if sign > 0 else col <= ext) & ok
        best = (at, abs(ext)) if _long_runs(at, MIN_RUN)[1] else None
        # a recovered raw axis mixes three stored values, each rounded, and must be fixed by its
        # plateau (_plateau_found)
        for a in _raw_axis_candidates(xo, i, sign, band, plane_tol, rng):
            def tol_of(a):
                return PLANE_TOL * float(np.sqrt(np.sum((a * sd) ** 2))) + 2 * res

            a = _refined(xo, a, i, sign, ok, tol_of)
            p = xo @ a
            lvl = np.max(sign * p, where=ok, initial=-np.inf) * sign
            tol = tol_of(a)
            at, found = _plateau_found(xo, p, lvl, tol, sign, ok, sd, False)
            if found and (best is None or np.count_nonzero(at) > np.count_nonzero(best[0])):
                best = (at | ((sign * p >= sign * lvl - tol) & finite), abs(lvl))
        if best is not None and best[1] > floor:
            clipped[:, i] |= best[0]
            level[:, i] = np.where(best[0], best[1], level[:, i])
    return clipped, level


def _range(value, name: str) -> np.ndarray:
    try:
        r = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        r = None
    if r is not None and r.ndim <= 1 and r.size in (1, 3):
        r = np.broadcast_to(r, (3,))
    else:
        r = None
    if r is None or not np.all(r > 0):  # (NaN fails too)
        raise InputError(f"{name} must be a positive full-scale reading, one or one per axis; "
                         f"got {value!r}")
    return r.copy()


def _clipped(x, held, given, name, floor, infer):
    """``(clipped (N, 3) bool, level (N, 3))``: the components at or beyond the given range, or
    inferred from the recording (:func:`inferred_clipping`), or none; the clip level's size where
    clipped, else 0."""
    none = np.zeros(x.shape, dtype=bool), np.zeros(x.shape)
    if given is not None:
        r = _range(given, name)
        finite = np.isfinite(x)
        top = (x >= r) & finite
        clipped = top | ((x <= -r) & finite)
        return clipped, np.where(clipped, np.broadcast_to(r, x.shape), 0.0)
    if infer and x.ndim == 2 and x.shape[0]:
        return inferred_clipping(x, held, floor)
    return none


def _reported_level(x, given, name, floor) -> np.ndarray:
    """(N, 3) the clip level of a component that a log reports clipped: the range where it is
    given, else the reading's own size, at least ``floor`` (the true value lies beyond the
    reading)."""
    if given is not None:
        return np.broadcast_to(_range(given, name), x.shape)
    with np.errstate(invalid="ignore"):
        return np.maximum(np.abs(np.nan_to_num(x)), floor)


def clip_variance(clipped, sigma_rad_s, dts) -> np.ndarray:
    """(N,) the tilt variance (rad²) each sample adds for the unknown excess of its clipped gyro
    axes: per axis, an unknown constant rate of standard deviation ``sigma_rad_s`` (N, 3) over each
    clipped run, ``σ² (t_k² − t_{k−1}²)`` with ``t_k`` the run's duration to sample k (Σ Δt;
    ``dts`` (N,), non-positive or non-finite steps count as 0), summed over the axes."""
    d = np.where(np.isfinite(dts) & (dts > 0), dts, 0.0)
    out = np.zeros(clipped.shape[0])
    for i in range(clipped.shape[1]):
        c = clipped[:, i]
        if not c.any():
            continue
        t = np.cumsum(np.where(c, d, 0.0))
        start = np.maximum.accumulate(np.where(c, 0.0, t))  # t at the end of the last unclipped
        run = np.where(c, t - start, 0.0)  # the run's duration to each sample
        prev = np.concatenate([[0.0], run[:-1]])
        out += np.where(c, sigma_rad_s[:, i] ** 2 * (run * run - prev * prev), 0.0)
    return out


def _runs(c):
    """``(starts, ends)`` (inclusive) of the runs of True in the bool vector ``c``."""
    k = np.flatnonzero(c)
    if k.size == 0:
        return k, k
    breaks = np.flatnonzero(np.diff(k) != 1)
    return (np.concatenate([k[:1], k[breaks + 1]]), np.concatenate([k[breaks], k[-1:]]))


def _flank(ok, edge: int, step: int, count: int, t, reach: float) -> list:
    """Up to ``count`` rows where ``ok`` is 1, from ``edge`` outwards (``step`` ±1): rows where it
    is 0 are passed over, a row where it is −1 (clipped) or beyond ``reach`` s of ``edge`` ends
    the flank."""
    out = []
    k, n = edge, ok.shape[0]
    while len(out) < count and 0 <= k < n and ok[k] >= 0 and abs(t[k] - t[edge]) <= reach:
        if ok[k] > 0:
            out.append(k)
        k += step
    return out


def _flank_count(a: int, b: int) -> int:
    """The samples of each flank a clipped run ``a``…``b`` is fitted with (:func:`peak_excess`)."""
    return int(min(FLANK_MAX, max(FLANK_MIN, (b - a + 1) // 4)))


def _events(starts, ends):
    """The clipped runs of one axis grouped into peaks: runs whose gap is no longer than a flank
    (:func:`_flank_count`) are one peak whose noise crossed the level on its way (a noisy signal
    near the level reads clipped, then not, then clipped again). Yields ``(a, b)``."""
    j = 0
    while j < starts.size:
        a, b = int(starts[j]), int(ends[j])
        j += 1
        while j < starts.size and starts[j] - b - 1 <= _flank_count(a, b):
            b = int(ends[j])
            j += 1
        yield a, b


def peak_excess(x, clipped, dts, level, usable=None, sd=None):
    """The excess of each clipped reading of ``x`` (N, 3) beyond its reading, fitted from the
    samples either side of its clipped run: ``(excess (N, 3), sigma (N, 3))``, the excess signed
    as the clip (0 where not clipped or not fitted) and the standard deviation of the unknown
    constant rate that is left over each run (for :func:`clip_variance`). ``clipped`` (N, 3)
    bool, ``dts`` (N,) the steps (non-positive or non-finite: skipped), ``level`` (N, 3) the clip
    level's size (for a run not fitted), ``usable`` (N,) bool the rows a fit may use (not held),
    ``sd`` (3,) the readings' white noise (default :func:`noise_std`).

    A signal beyond a range passes it in a smooth peak: on each run (runs apart by less than a
    flank are one peak, :func:`_events`), a parabola is fitted to the unclipped samples either
    side (up to :data:`FLANK_MAX` on each, a quarter of the run's length, at least
    :data:`FLANK_MIN`) and to the unclipped samples within, and kept below the lines fitted to
    each flank (a concave peak lies below the extension of its chords: the bound of a peak that
    enters and leaves as fast as its flanks say, twice the parabola's height). The truth lies
    between the two: a motion's peak (a swing's, a sinusoid's top) is fuller than the parabola
    through its flanks, so the peak is taken :data:`PEAK_CHORD_SHARE` of the way from the
    parabola to the chords' bound. The excess is that peak minus the reading, never below 0 (the
    true value is beyond the level: a one-sided constraint). Its integral over the run is what
    the filter would otherwise miss (a rotation for the gyro, a velocity for the accelerometer);
    that integral is left uncertain by :data:`EXCESS_SPREAD` of itself and by the flanks' noise
    through the fit.
    A run whose flanks are missing (the recording's ends, another clipped run next to it), not
    concave, or that does not rise into the clip and fall out of it gets no excess and σ =
    :data:`EXCESS_FRACTION` × its level (the model without the fit)."""
    x = np.asarray(x, dtype=np.float64)
    n = x.shape[0]
    d = np.where(np.isfinite(dts) & (dts > 0), dts, 0.0)
    t = np.cumsum(d)
    excess, sigma = np.zeros(x.shape), np.zeros(x.shape)
    if not clipped.any():
        return excess, sigma
    sd = noise_std(x) if sd is None else sd
    step = float(np.median(d[d > 0])) if np.any(d > 0) else 0.0
    usable = np.ones(n, dtype=bool) if usable is None else usable
    for i in range(x.shape[1]):
        col, c = x[:, i], clipped[:, i]
        # per row: 1 a fit may use it, 0 it is passed over (held, missing, no time), −1 clipped
        ok = np.where(c, -1, np.where(usable & np.isfinite(col) & (d > 0), 1, 0))
        for a, b in _events(*_runs(c)):
            e, s_rate = _run_excess(col, a, b, t, d, ok, step, sd[i])
            at = slice(a, b + 1)
            if e is None:  # not fitted
                sigma[at, i] = np.where(c[at], EXCESS_FRACTION * level[at, i], 0.0)
            else:
                excess[at, i] = e
                sigma[at, i] = np.where(c[at], s_rate, 0.0)
    return excess, sigma


def _run_excess(col, a: int, b: int, t, d, ok, step: float, sd: float):
    """The fitted excess (signed, 0 on the unclipped rows) of the peak ``a``…``b`` of one axis
    and the σ of the constant rate left over its clipped rows (:func:`peak_excess`), or ``(None,
    None)``."""
    count = _flank_count(a, b)
    reach = 2.0 * (count + 1) * step  # (a flank does not cross a gap in the time stamps)
    left = _flank(ok, a - 1, -1, count, t, reach)[::-1]
    right = _flank(ok, b + 1, 1, count, t, reach)
    if len(left) < FLANK_MIN or len(right) < FLANK_MIN:
        return None, None
    rows = np.arange(a, b + 1)
    clip = ok[a:b + 1] < 0
    run = col[a:b + 1]
    fin = clip & np.isfinite(run)
    if not fin.any():
        return None, None
    sign = 1.0 if np.sum(run[fin]) >= 0 else -1.0
    idx = np.concatenate([left, rows[ok[a:b + 1] > 0], right]).astype(int)
    span = max(t[right[-1]] - t[left[0]], 1e-12)
    tc = 0.5 * (t[left[0]] + t[right[-1]])
    u = (t[idx] - tc) / span  # (scaled: the normal equations stay well conditioned)
    y = sign * col[idx]
    X = np.stack([np.ones_like(u), u, u * u], axis=1)
    XtX = X.T @ X
    if abs(np.linalg.det(XtX)) < 1e-12:
        return None, None
    c = np.linalg.solve(XtX, X.T @ y)
    nl, nr = len(left), len(right)
    line_l = np.polyfit(u[:nl], y[:nl], 1)
    line_r = np.polyfit(u[-nr:], y[-nr:], 1)
    if not (c[2] < 0 and line_l[0] > 0 and line_r[0] < 0):
        return None, None
    ur = (t[a:b + 1] - tc) / span
    lines = np.minimum(np.polyval(line_l, ur), np.polyval(line_r, ur))
    peak = np.minimum(c[0] + c[1] * ur + c[2] * ur * ur, lines)
    peak = peak + PEAK_CHORD_SHARE * (lines - peak)
    e = np.where(fin, np.maximum(peak - sign * np.where(fin, run, 0.0), 0.0), 0.0)
    w = np.where(clip, d[a:b + 1], 0.0)
    duration = float(np.sum(w))
    if duration <= 0:
        return None, None
    integral = float(np.sum(e * w))
    g = np.array([duration, float(np.sum(w * ur)), float(np.sum(w * ur * ur))])
    noise_var = float(g @ np.linalg.solve(XtX, g)) * sd * sd
    return sign * e, math.sqrt((EXCESS_SPREAD * integral) ** 2 + noise_var) / duration


def known_mask(mask, n: int, name: str) -> np.ndarray | None:
    """A per-sample, per-axis clip mask given by the caller as (N, 3) bool (None: none given),
    else a one-line ``InputError``."""
    if mask is None:
        return None
    m = np.asarray(mask)
    if m.shape != (n, 3) or m.dtype.kind not in "bui":
        raise InputError(f"{name} must be (N, 3) booleans, one per sample and axis, N = {n}; got "
                         f"shape {m.shape} of {m.dtype}")
    return m.astype(bool)


def _in_range(x, limit: float):
    """``x`` with its components at or beyond ``limit`` in size set to NaN: ``x`` itself when
    every component is finite and within it (two reductions, no copy: the usual recording)."""
    if x.size and x.max() < limit and x.min() > -limit:  # (False with a NaN)
        return x
    with np.errstate(invalid="ignore"):
        return np.where(np.abs(x) < limit, x, np.nan)


def find_limits(gyr_rad_s, acc_m_s2, dt_s, gyr_range_rad_s=None, acc_range_m_s2=None,
                infer: bool = True, prev=None, gyr_clipped=None, acc_clipped=None,
                fit_peaks: bool = True) -> Limits:
    """The clipped and held samples of a recording (module doc): gyro (N, 3) rad/s, accelerometer
    (N, 3) m/s², ``dt_s`` scalar or (N,). ``gyr_range_rad_s``, ``acc_range_m_s2``: the sensor's
    full-scale readings (scalar or (3,)); a component at or beyond them is clipped. Without them
    the levels are inferred from flat tops when ``infer`` (else nothing is clipped on that
    sensor). ``prev``: the row before the first, for a recording read in pieces
    (:func:`held_rows`; the levels are then inferred per piece, and a clipped run that spans two
    pieces restarts its unknown excess at the second). ``gyr_clipped``, ``acc_clipped``: (N, 3)
    bool, the components a log says clipped (a flight controller's per-sample clip bits: its
    samples are averages that never sit at full scale), clipped in addition to those found here,
    with the range as the level of their excess where it is known, else the reading's size (at
    least the smallest common range). ``fit_peaks=False``: no run's peak is fitted, every run
    gets σ = :data:`EXCESS_FRACTION` × its level and no excess (what a stream, which cannot see
    a run's end, does: :class:`verticality.tilt.stream.Stream`)."""
    gyr = np.asarray(gyr_rad_s, dtype=np.float64)
    acc = np.asarray(acc_m_s2, dtype=np.float64)
    n = gyr.shape[0]
    g_known = known_mask(gyr_clipped, n, "gyr_clipped")
    a_known = known_mask(acc_clipped, n, "acc_clipped")
    dts = np.broadcast_to(np.asarray(dt_s, dtype=np.float64), (n,))
    held = held_rows(gyr, acc, prev)
    # a reading beyond any sensor's physical range is corrupt, not clipped: the filter takes it
    # as missing (OUT_OF_RANGE), and the search for plateaus does not see it
    gyr_read, acc_read = _in_range(gyr, MAX_RATE_RAD_S), _in_range(acc, MAX_ACC_M_S2)
    gyr_clipped, g_level = _clipped(gyr_read, held, gyr_range_rad_s, "gyr_range_rad_s",
                                    GYR_FLOOR_RAD_S, infer)
    a_axes, a_level = _clipped(acc_read, held, acc_range_m_s2, "acc_range_m_s2", ACC_FLOOR_M_S2,
                               infer)
    # a clip the log reports on a reading that does not sit at its level (the average of raw
    # samples of which some clipped) shows no peak to fit: it keeps the bound
    g_seen, a_seen = gyr_clipped, a_axes
    if g_known is not None:  # clips the log reports (module doc)
        reported = _reported_level(gyr, gyr_range_rad_s, "gyr_range_rad_s", GYR_FLOOR_RAD_S)
        g_level = np.where(g_known & ~gyr_clipped, reported, g_level)
        gyr_clipped = gyr_clipped | g_known
    if a_known is not None:
        reported = _reported_level(acc, acc_range_m_s2, "acc_range_m_s2", ACC_FLOOR_M_S2)
        a_level = np.where(a_known & ~a_axes, reported, a_level)
        a_axes = a_axes | a_known
    acc_clipped = np.any(a_axes, axis=1)
    vel_var, a_excess = np.zeros(n), np.zeros(acc.shape)
    if acc_clipped.any():
        a_excess, sigma = (peak_excess(acc_read, a_seen, dts, a_level, ~held) if fit_peaks
                           else (a_excess, EXCESS_FRACTION * a_level))
        sigma = np.where(a_axes & ~a_seen, EXCESS_FRACTION * a_level, sigma)
        vel_var = clip_variance(a_axes, sigma, dts)
    flags = np.where(held, np.int32(HELD), np.int32(0))
    var, g_excess = np.zeros(n), np.zeros(gyr.shape)
    if gyr_clipped.any():
        g_excess, sigma = (peak_excess(gyr_read, g_seen, dts, g_level, ~held) if fit_peaks
                           else (g_excess, EXCESS_FRACTION * g_level))
        sigma = np.where(gyr_clipped & ~g_seen, EXCESS_FRACTION * g_level, sigma)
        var = clip_variance(gyr_clipped, sigma, dts)
        flags |= np.where(gyr_clipped.any(axis=1), np.int32(CLIPPED), np.int32(0))
    if acc_clipped.any():
        flags |= np.where(acc_clipped, np.int32(CLIPPED), np.int32(0))
    return Limits(gyr_clipped, acc_clipped, held, var, vel_var, flags, g_excess, a_excess)
