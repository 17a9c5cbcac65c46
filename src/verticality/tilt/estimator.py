"""3-D otolith–canal tilt filter for recorded IMU data (gyroscope = canals,
accelerometer = otoliths).

Tahboub's stand-alone filter (T eq. 1–13) fuses, in one plane, a gyro reading
``ω_g = ω + ω_drift + v_c`` (T eq. 1) whose drift is a random walk ``ω̇_drift = v_drift`` (T eq. 2)
with an accelerometer read as a noisy inclinometer ``a_xa = g φ + v_a`` (T eq. 5): the inertial
part of the specific force (T eq. 4) "is handled as a high-frequency noise". This is its
3-D generalization as an error-state extended Kalman filter:

* nominal state: the orientation quaternion ``q_E_S`` (sensor → Earth, z up; its heading is
  carried along but unobservable and irrelevant), the gyro bias ``b_S`` (rad/s, T eq. 2 drift) and
  the horizontal velocity ``v_E`` (m/s) obtained by integrating the specific force rotated to Earth;
* error state (7): tilt error ``δ = (δx, δy)`` about Earth's horizontal axes
  (``R_true = exp([δ, 0]) R_est``), velocity error ``ṽ`` (2), bias error ``b̃ = b_true − b̂`` (3);
* prediction: strapdown ``q ← q ⊗ exp((ω_g − b̂) Δt)`` with the true Δt of every sample;
  ``δ̇ = −Π R b̃`` (3-D T eq. 7 with the drift subtracted), ``ṽ̇ = g J δ`` (a tilt error leaks
  gravity into the integrated velocity), bias random walk (T eq. 2, 12);
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

The estimator (the project's interface, :mod:`verticality.estimators.base`)::

    filt = TiltFilter(params, block)              # both optional
    state = filt.init(x0, P0)                     # x0 = (q_E_S wxyz, b_S) or None ; P0 (10, 10)
    state = filt.predict(state, gyr, dt)          # = step with the accelerometer missing
    state, out = filt.step(state, gyr, acc, dt)   # gyr (3,) rad/s, acc (3,) m/s², dt s
    state, outs = filt.run(state, gyrs, accs, dts)  # (N, 3), (N, 3), scalar or (N,): the fast
                                                     # batch path, equal to repeated step

``out`` is the core's raw :class:`~verticality.tilt.core.TiltOutput` (roll, pitch, gravity
direction, quaternion, bias, variances, flags, ``measured``: the accelerometer sample was used).
A whole recording from the start is ``estimate(gyr, acc, t_s)`` (or ``period_s=``), offline
``smooth``: both return the package's one output type,
:class:`~verticality.tilt.output.TiltEstimate` (the fields above, the time and the tilt's σ from
the run's parameters). A NaN in ``acc`` means "no accelerometer":
predict only (flag ``ACC_MISSING``); a NaN gyro sample propagates the covariance with
``omega_missing_rad_s`` as the unknown rate (flag ``GYR_MISSING``); a non-finite or non-positive
Δt skips the sample (flag ``BAD_DT``). A Δt above ``gap_flag_s`` (a gap in the recording) is used
as it is, the sample's rate integrated over the whole gap, and the sample is flagged ``DT_GAP``:
motion inside the gap that this rate does not describe is not seen. The gap then counts as a gyro
dropout, and after ``reacquire_s`` the tilt is re-acquired from the mean specific force (flag
``REACQUIRED``; the samples in between are flagged ``REACQUIRING``; docs/tilt.md). The
initialization from the accelerometer is treated the same way (the first sample may hold an
inertial acceleration): wide tilt variance (``init_tilt_rad``), re-acquired after ``reacquire_s``.
Nothing turns a finite estimate into NaN.

The filter is written once, in :mod:`~verticality.tilt.core` (per-sample step, block update);
:mod:`~verticality.tilt.kernels` runs it on many blocks at once for ``run``; :class:`Stepper`
wraps the per-sample step for Python loops in JAX, and the plain-Python
:class:`~verticality.tilt.stream.Stream` is its independent reference implementation for
real-time loops (wrapped by :class:`verticality.tilt.Stream`).
"""

from __future__ import annotations

import dataclasses
import functools

import jax
import jax.numpy as jnp
import numpy as np

from verticality.core.errors import InputError
from verticality.models.base import model_dataclass, static_field
from verticality.tilt import batch as tilt_batch
from verticality.tilt import clock as tilt_clock
from verticality.tilt import core as tilt_core
from verticality.tilt import limits as tilt_limits
from verticality.tilt import smoother as tilt_smoother
from verticality.tilt.core import TiltOutput, TiltState
from verticality.tilt.layout import NE, OUT, SAMPLE, X, Z
from verticality.tilt.output import TiltEstimate, estimate_of, time_axis
from verticality.tilt.params import BLOCK, DEFAULT_P0, DEFAULT_PARAMS, TiltParams, block_samples

__all__ = ["TiltFilter", "Stepper", "estimate", "smooth", "estimate_steps", "smooth_steps",
           "recording_limits", "judged_steps", "with_clock", "run_in_pieces",
           "concatenate_outputs", "make_step"]

_NO_ACC = np.full(3, np.nan)


@model_dataclass
class TiltFilter:
    """The 3-D tilt filter as a value: its parameters and the number of samples per Kalman update.
    Methods follow the project's estimator interface (module doc)."""

    params: TiltParams = DEFAULT_PARAMS
    block: int = static_field(BLOCK)

    def init(self, x0=None, P0=None) -> TiltState:
        """The initial state (NumPy arrays). ``x0 = (quat_E_S wxyz, bias_S rad/s)``, or None: then
        the first usable accelerometer sample initializes the tilt (heading 0, zero bias, flag
        ``INIT``) and it is re-acquired after ``reacquire_s``. ``P0`` (10, 10) the covariance of
        (δx, δy, ṽx, ṽy, b̃x, b̃y, b̃z, s̃x, s̃y, s̃z); default :data:`DEFAULT_P0`."""
        P0 = np.asarray(DEFAULT_P0 if P0 is None else P0, dtype=np.float64)
        if P0.shape != (NE, NE):
            raise InputError("P0 must be (10, 10) for (δx, δy, ṽx, ṽy, b̃x, b̃y, b̃z, s̃x, s̃y, s̃z); "
                             f"got {P0.shape}")
        if x0 is None:
            q0, b0, initialized = np.array([1.0, 0.0, 0.0, 0.0]), np.zeros(3), False
        else:
            q0 = np.asarray(x0[0], dtype=np.float64)
            b0 = np.asarray(x0[1], dtype=np.float64)
            if q0.shape != (4,) or b0.shape != (3,) or not np.all(np.isfinite(q0)) \
                    or not np.all(np.isfinite(b0)) or not np.any(q0 != 0):
                raise InputError("x0 must be (quat_E_S (4,) wxyz, non-zero, bias_S_rad_s (3,)), "
                                 "finite")
            q0, initialized = q0 / np.sqrt(np.sum(q0 * q0)), True
        x = X.pack(xp=np, q=q0, b=b0, s=np.zeros(3), v=np.zeros(2), P=P0.reshape(-1),
                   acc_dev_var=0.0, rest_s=0.0, reacquire=0.0, reacq_f_E=np.zeros(3), reacq_t=0.0,
                   vel_inn=np.zeros(2), vel_fix=np.zeros(5), speed_var=0.0, dv_var=0.0)
        return TiltState(x, _EMPTY_SUMS, np.int32(0), np.bool_(initialized), np.full(3, np.nan))

    def predict(self, state: TiltState, gyr, dt) -> TiltState:
        """The sample without its accelerometer: exactly :meth:`step` with ``acc`` all NaN."""
        return _step(self, state, gyr, _NO_ACC, dt)[0]

    def step(self, state: TiltState, gyr, acc, dt) -> tuple[TiltState, TiltOutput]:
        """One sample: ``gyr`` (3,) rad/s, ``acc`` (3,) m/s², ``dt`` s since the previous one
        (``tilt_core.step``, jitted)."""
        return _step(self, state, gyr, acc, dt)

    def run(self, state: TiltState, gyrs, accs, dts) -> tuple[TiltState, TiltOutput]:
        """:meth:`step` over a recording (``gyrs``, ``accs`` (N, 3), ``dts`` scalar or (N,), the
        time from sample k−1 to k), by the batch kernel: the per-sample work vectorized, a
        ``lax.scan`` over blocks only, in chunks of two fixed shapes. Returns the final state (as
        repeated :meth:`step` leaves it, a block in progress included) and the outputs as NumPy
        arrays."""
        return tilt_batch.run(self.params, self.block, state, gyrs, accs, dts)


_step = jax.jit(lambda f, s, g, a, d: tilt_core.step(s, g, a, d, f.params, f.block))
_EMPTY_SUMS = np.asarray(tilt_core.empty_sums(xp=np))


def recording_limits(gyr, acc, dt, gyr_range_rad_s=None, acc_range_m_s2=None,
                     detect_clipping: bool = True, prev=None, gyr_clipped=None,
                     acc_clipped=None):
    """The clipped and held samples of a recording (:func:`verticality.tilt.limits.find_limits`;
    ``prev`` the row before the first when it is read in pieces), or None when its shapes are wrong
    (the filter's own checks then say so). ``detect_clipping=False``: no clipping found from the
    readings, given ranges or not (held rows are still flagged; ``gyr_clipped``, ``acc_clipped``,
    the components a log says clipped, still count)."""
    n = gyr.shape[0] if gyr.ndim == 2 and gyr.shape[1:] == (3,) else -1
    if n < 0 or acc.shape != gyr.shape or dt.ndim > 1 or (dt.ndim == 1 and dt.shape[0] != n):
        return None
    if not detect_clipping:
        gyr_range_rad_s = acc_range_m_s2 = None
    lim = tilt_limits.find_limits(gyr, acc, dt, gyr_range_rad_s, acc_range_m_s2,
                                  infer=detect_clipping, prev=prev, gyr_clipped=gyr_clipped,
                                  acc_clipped=acc_clipped)
    return lim


def estimate(gyr_rad_s, acc_m_s2, t_s=None, *, period_s=None,
             params: TiltParams = DEFAULT_PARAMS, block: int | None = None, gyr_range_rad_s=None,
             acc_range_m_s2=None, detect_clipping: bool = True, gyr_clipped=None,
             acc_clipped=None) -> TiltEstimate:
    """Filter a whole recording from the start (no prior state): gyro (N, 3) rad/s,
    accelerometer (N, 3) m/s², and its time: the time stamps ``t_s`` (N,) s, or a fixed sampling
    period ``period_s`` (s) (:func:`~verticality.tilt.output.time_axis`). Returns a
    :class:`~verticality.tilt.output.TiltEstimate` of NumPy arrays, σ from ``params``.

    Sensors at their limits (:mod:`~verticality.tilt.limits`): ``gyr_range_rad_s``,
    ``acc_range_m_s2`` the sensor's full-scale readings (scalar or one per axis); a component at
    or beyond them is clipped (flag ``CLIPPED``): a clipped gyro axis widens the tilt variance for
    its unknown excess, a clipped accelerometer axis the velocity variance. Without them the clip
    levels are inferred from the recording's flat tops; ``detect_clipping=False`` turns clipping
    off. ``gyr_clipped``, ``acc_clipped`` ((N, 3) bool): components known to have clipped (a
    log's clip bits, :func:`verticality.tilt.read_log`), treated as clipped whatever their value.
    Rows that repeat the previous row bit for bit are flagged ``HELD``. ``block``: samples per
    Kalman update; default ``params.update_s`` at the recording's sampling period.

    Example::

        from verticality import tilt
        out = tilt.estimate(gyr, acc, period_s=1 / 285.7)   # or tilt.estimate(gyr, acc, t_s)
        out.roll_rad, out.pitch_rad, out.up_S, out.sigma_rad, out.flags
    """
    gyr, acc = _arrays(gyr_rad_s, acc_m_s2)
    t, dt = time_axis(gyr.shape[0], t_s, period_s)
    out = estimate_steps(gyr, acc, dt, params, block, gyr_range_rad_s, acc_range_m_s2,
                         detect_clipping, gyr_clipped, acc_clipped)
    return estimate_of(out, t, params)


def smooth(gyr_rad_s, acc_m_s2, t_s=None, *, period_s=None,
           params: TiltParams = DEFAULT_PARAMS, block: int | None = None, gyr_range_rad_s=None,
           acc_range_m_s2=None, detect_clipping: bool = True, gyr_clipped=None,
           acc_clipped=None) -> TiltEstimate:
    """The offline estimate of a whole recording: the filter (:func:`estimate`, the same
    arguments, the sensors' limits included) followed by a Rauch–Tung–Striebel backward pass over
    its error state (:mod:`~verticality.tilt.smoother`), so that every sample's tilt uses the
    samples after it as well as those before. The same output type, fields, row count and flags
    as :func:`estimate`; ``var`` and ``sigma_rad`` are the smoothed ones. A gap in the time
    stamps, and the re-acquisition after it (or after the start), splits the smoothing: nothing
    after a gap changes the estimate before it. The whole recording is held in memory: a
    recording beyond :data:`verticality.core.sizing.MAX_WORK_BYTES` is refused (``InputError``).

    Example::

        out = tilt.smooth(gyr, acc, period_s=1 / 285.7)
        out.roll_rad, out.pitch_rad, out.sigma_rad
    """
    gyr, acc = _arrays(gyr_rad_s, acc_m_s2)
    t, dt = time_axis(gyr.shape[0], t_s, period_s)
    out = smooth_steps(gyr, acc, dt, params, block, gyr_range_rad_s, acc_range_m_s2,
                       detect_clipping, gyr_clipped, acc_clipped)
    return estimate_of(out, t, params)


def _arrays(gyr_rad_s, acc_m_s2):
    """The gyro and accelerometer as float64 (N, 3) arrays of one length, else a one-line
    ``InputError``."""
    gyr = np.asarray(gyr_rad_s, dtype=np.float64)
    acc = np.asarray(acc_m_s2, dtype=np.float64)
    if gyr.ndim != 2 or gyr.shape[1:] != (3,) or acc.shape != gyr.shape:
        raise InputError(f"gyr_rad_s and acc_m_s2 must both have shape (N, 3); got {gyr.shape} "
                         f"and {acc.shape}")
    return gyr, acc


def estimate_steps(gyr, acc, dt_s, params: TiltParams = DEFAULT_PARAMS, block: int | None = None,
                   gyr_range_rad_s=None, acc_range_m_s2=None, detect_clipping: bool = True,
                   gyr_clipped=None, acc_clipped=None):
    """:func:`estimate` given the steps ``dt_s`` (a scalar, or (N,): ``dt_s[k]`` the time from
    sample k−1 to k, non-finite where a reader found no usable time stamp: that sample is skipped
    and flagged ``BAD_DT``), for readers of files that judge the time stamps themselves
    (:mod:`verticality.tilt.files`). ``block``: samples per Kalman update; default
    ``params.update_s`` over the sampling period (:func:`~verticality.tilt.params.block_samples`).
    Returns the core's raw ``TiltOutput`` (NumPy arrays)."""
    gyr = np.asarray(gyr, dtype=np.float64)
    acc = np.asarray(acc, dtype=np.float64)
    n = gyr.shape[0] if gyr.ndim == 2 else 0
    dt, judged = judged_steps(gyr, acc, dt_s, params)
    block = block_samples(params, dt) if block is None else block
    filt = TiltFilter(params, block)
    lim = with_clock(recording_limits(gyr, acc, dt, gyr_range_rad_s, acc_range_m_s2,
                                      detect_clipping, gyr_clipped=gyr_clipped,
                                      acc_clipped=acc_clipped), judged)
    if lim is None:
        return filt.run(filt.init(), gyr, acc, dt)[1]
    if n <= tilt_batch.PIECE_SAMPLES:
        return tilt_batch.run(params, block, filt.init(), *lim.readings(gyr, acc), dt,
                              **lim.run_args())[1]
    return concatenate_outputs(list(run_in_pieces(filt, filt.init(), gyr, acc,
                                                  np.broadcast_to(dt, (n,)), limits=lim)))


def smooth_steps(gyr, acc, dt_s, params: TiltParams = DEFAULT_PARAMS, block: int | None = None,
                 gyr_range_rad_s=None, acc_range_m_s2=None, detect_clipping: bool = True,
                 gyr_clipped=None, acc_clipped=None):
    """:func:`smooth` given the steps ``dt_s`` (as :func:`estimate_steps`); the core's raw
    ``TiltOutput`` with the smoothed variances."""
    gyr = np.asarray(gyr, dtype=np.float64)
    tilt_smoother.check_size(gyr.shape[0] if gyr.ndim else 0)
    acc = np.asarray(acc, dtype=np.float64)
    dt_s, judged = judged_steps(gyr, acc, dt_s, params)
    block = block_samples(params, dt_s) if block is None else block
    filt = TiltFilter(params, block)
    lim = with_clock(recording_limits(gyr, acc, dt_s, gyr_range_rad_s, acc_range_m_s2,
                                      detect_clipping, gyr_clipped=gyr_clipped,
                                      acc_clipped=acc_clipped), judged)
    extra = {} if lim is None else lim.run_args()
    if lim is not None:
        gyr, acc = lim.readings(gyr, acc)
    final, out, trans = tilt_batch.run(params, block, filt.init(), gyr, acc, dt_s,
                                       transitions=True, **extra)
    dts = np.broadcast_to(dt_s, gyr.shape[:1])
    return tilt_smoother.smoothed_output(out, trans, final.P, dts, block)


def judged_steps(gyr, acc, dt_s, params: TiltParams = DEFAULT_PARAMS):
    """``(steps, judged)``: the steps ``dt_s`` (scalar or (N,)) as the filter takes them, with the
    time stamps' clock jumps told from their gaps by the readings
    (:func:`verticality.tilt.clock.judge_steps`; ``judged`` its result, or None when every step
    is taken as given: then ``steps`` is ``dt_s`` as a float64 array, bit for bit)."""
    dt = np.asarray(dt_s, dtype=np.float64)
    judged = None
    if dt.ndim == 1 and gyr.ndim == 2 and gyr.shape == acc.shape == (dt.shape[0], 3):
        judged = tilt_clock.judge_steps(dt, gyr, acc, params)
    return (dt, None) if judged is None else (judged.dt_s, judged)


def with_clock(lim: tilt_limits.Limits | None, judged) -> tilt_limits.Limits | None:
    """The recording's limits (:func:`recording_limits`) with the tilt variance and flags of the
    clock jumps and gaps added (``judged``: :func:`judged_steps`' second value; None or nothing
    to add: ``lim``)."""
    if lim is None or judged is None or not (np.any(judged.flags)
                                             or np.any(judged.tilt_var_rad2)):
        return lim
    return lim._replace(tilt_var_rad2=lim.tilt_var_rad2 + judged.tilt_var_rad2,
                        flags=lim.flags | judged.flags)


def run_in_pieces(filt: TiltFilter, state: TiltState, gyr, acc, dts, piece: int | None = None,
                  limits: tilt_limits.Limits | None = None):
    """The outputs of ``filt.run`` over a long recording, piece by piece (each of at most
    ``piece`` samples ending at a block boundary, :func:`~verticality.tilt.batch.piece_cut`): a
    generator of raw :class:`~verticality.tilt.core.TiltOutput` pieces, as ``estimate`` and the
    streaming read of ``verticality estimate`` filter; ``piece`` default
    ``tilt_batch.PIECE_SAMPLES``).
    Equal to one ``run`` over the whole to rounding (the batch kernel's chunks differ), and bit
    for bit to any other reading in the same pieces. ``limits``: the recording's clipped and held
    samples (:func:`recording_limits`)."""
    piece = tilt_batch.PIECE_SAMPLES if piece is None else piece
    n, k = gyr.shape[0], 0
    while k < n:
        hi = min(n, k + piece)
        m = tilt_batch.piece_cut(state, acc[k:hi], dts[k:hi], filt.block, final=hi == n)
        m = m or hi - k  # no block boundary within a piece (piece < block): take it whole
        sl = slice(k, k + m)
        g, a = (gyr[sl], acc[sl]) if limits is None else limits.readings(gyr[sl], acc[sl], sl)
        extra = {} if limits is None else limits.run_args(sl)
        state, out = tilt_batch.run(filt.params, filt.block, state, g, a, dts[sl], **extra)
        yield out
        k += m


def concatenate_outputs(outs) -> TiltOutput:
    """One raw :class:`~verticality.tilt.core.TiltOutput` of consecutive pieces."""
    return TiltOutput(*(np.concatenate(parts) for parts in zip(*outs, strict=True)))


# --- the real-time form in JAX: the state and the sample as flat vectors ---

def _state_of(z) -> TiltState:
    return TiltState(z[Z.x], z[Z.sums], jnp.round(z[Z.count]).astype(jnp.int32),
                     z[Z.initialized] > 0.5, z[Z.gyr_prev])


def _step_packed(filt, z, sample):
    s, o = tilt_core.step(_state_of(z), sample[SAMPLE.gyr], sample[SAMPLE.acc], sample[SAMPLE.dt],
                          filt.params, filt.block)
    return (Z.pack(x=s.x, sums=s.sums, count=s.count, initialized=s.initialized,
                   gyr_prev=s.gyr_prev),
            OUT.pack(roll=o.roll_rad, pitch=o.pitch_rad, up=o.up_S, quat=o.quat_E_S,
                     bias=o.bias_S_rad_s, flags=o.flags))


@dataclasses.dataclass(frozen=True)
class Stepper:
    """Real-time form of :meth:`TiltFilter.step` for Python loops in JAX (:func:`make_step`): the
    state travels as one flat float64 vector (``tilt_layout.Z``) and the output as
    ``[roll, pitch, up(3), quat(4), bias(3), flags]`` (``tilt_layout.OUT``), so that a call costs
    little more than JAX's dispatch. The same numbers as ``step`` (tested)."""

    filter: TiltFilter
    z0: np.ndarray = dataclasses.field(compare=False, repr=False)
    # the step jitted once per stepper, the filter's parameters baked in as constants (a static
    # argument instead would be hashed on every call)
    _jitted: object = dataclasses.field(init=False, compare=False, repr=False)

    def __post_init__(self):
        object.__setattr__(self, "_jitted", jax.jit(functools.partial(_step_packed, self.filter)))

    def init(self):
        """The packed initial state."""
        return jnp.asarray(self.z0)

    def step(self, z, gyr, acc, dt):
        """``(z, out)`` after one sample ``gyr`` (3,), ``acc`` (3,), ``dt``."""
        sample = np.empty(SAMPLE.size)  # (faster than SAMPLE.pack, for a per-sample call)
        sample[SAMPLE.gyr], sample[SAMPLE.acc], sample[SAMPLE.dt] = gyr, acc, dt
        return self._jitted(z, sample)

    def step_packed(self, z, sample):
        """:meth:`step` with the sample as one vector ``[gyr, acc, dt]`` (one argument less)."""
        return self._jitted(z, sample)

    def unpack(self, z) -> TiltState:
        """The packed state as a :class:`TiltState` (NumPy arrays)."""
        return jax.tree_util.tree_map(np.asarray, _state_of(np.asarray(z)))


def make_step(params: TiltParams = DEFAULT_PARAMS, block: int | None = None, x0=None, P0=None,
              period_s: float | None = None) -> Stepper:
    """The real-time stepper of the filter with ``params``, started from
    ``TiltFilter.init(x0, P0)``, updating every ``block`` samples or, by default, every
    ``params.update_s`` at the sampling period ``period_s`` (one of them is needed)."""
    if block is None:
        if period_s is None:
            raise InputError("make_step needs the sampling period (period_s=…) or block=…")
        block = block_samples(params, period_s)
    filt = TiltFilter(params, block)
    s = filt.init(x0, P0)
    return Stepper(filt, Z.pack(xp=np, x=s.x, sums=s.sums, count=s.count,
                                initialized=s.initialized, gyr_prev=s.gyr_prev))
