"""The tilt filter sample by sample, for real-time loops: :class:`Stream`, with the same output
type as :func:`verticality.tilt.estimate` (one sample of a
:class:`~verticality.tilt.output.TiltEstimate`).

It runs the plain-Python implementation (:class:`verticality.tilt.stream.Stream`: scalar ``math``
per sample, NumPy at each Kalman update: cheaper per sample than a jitted JAX call, which pays
a dispatch each time; docs/tilt.md, "Python API"), which is tested against the filter's core to
1e-9; this class adds the time (stamps or a fixed period) and the output type.
"""

from __future__ import annotations

import math

import numpy as np

from verticality.core.errors import InputError
from verticality.tilt import stream
from verticality.tilt.clock import Clock
from verticality.tilt.flags import accelerometer_used
from verticality.tilt.output import TiltEstimate
from verticality.tilt.params import DEFAULT_PARAMS, TiltParams
from verticality.tilt.stamps import stamp_seconds


class Stream:
    """Sample-by-sample tilt filter::

        s = tilt.Stream(period_s=0.01)                 # the sensor's sampling period
        est = s.step(gyr_rad_s, acc_m_s2)              # every sample a period after the last
        est = s.step(gyr_rad_s, acc_m_s2, t_s)         # or at its time stamp (s)

    ``step`` returns one sample of a :class:`~verticality.tilt.output.TiltEstimate` (scalars and
    (3,), (4,), (10,) arrays): the same numbers as :func:`verticality.tilt.estimate` over the same
    samples (to ~1e-9). ``period_s`` is the sensor's nominal sampling period (s), as VQF takes
    it: the step of every sample given without a time stamp, and the first sample's step (the
    first sample only initializes the tilt, its step enters no integration). Without
    ``period_s`` every sample needs its time stamp and the first one is given the longest step
    that is not a gap (``params.gap_flag_s``), which enters nothing but a clipped first sample's
    excess. The stamps are read as :func:`verticality.tilt.estimate` reads them
    (:mod:`verticality.tilt.clock`): a step beyond a gap across which the readings go on is a
    clock jump (one sample at the nominal step, flag ``CLOCK_JUMP``), else a gap (``DT_GAP``); a
    time stamp that does not go forward skips its sample (flag ``BAD_DT``) unless the readings
    show a clock set back.

    ``params``, ``block``, ``gyr_range_rad_s``, ``acc_range_m_s2`` (full-scale readings: a stream
    cannot infer them from flat tops), ``x0`` and ``P0`` as :class:`~verticality.tilt.TiltFilter`
    and :func:`~verticality.tilt.estimate` take them; by default an update every
    ``params.update_s`` at ``period_s``, or at the first step after the initialization."""

    def __init__(self, period_s=None, *, params: TiltParams = DEFAULT_PARAMS,
                 block: int | None = None, gyr_range_rad_s=None, acc_range_m_s2=None, x0=None,
                 P0=None):
        if period_s is not None and not (isinstance(period_s, (int, float, np.floating))
                                         and math.isfinite(period_s) and period_s > 0):
            raise InputError(f"period_s must be one positive, finite number of seconds; got "
                             f"{period_s!r}")
        self.period_s = None if period_s is None else float(period_s)
        self.params = params
        self.filter = stream.Stream(params, block, P0, x0, gyr_range_rad_s, acc_range_m_s2,
                                    period_s=self.period_s)
        self.clock = Clock(params)  # how the stamps are read (tilt.clock)
        self.t_s = None  # the time of the last sample taken
        self.t_prev = None  # the previous sample's time (its stamp, or the period's clock)
        # a period's clock counts samples from the last time stamp (t0 + k period, as the batch
        # run's k × period_s: no sum of rounded steps)
        self.t0_s, self.k = 0.0, -1
        self.calib_var = (params.acc_calib_m_s2 / params.g_m_s2) ** 2

    def step(self, gyr_rad_s, acc_m_s2, t_s=None) -> TiltEstimate:
        """One sample: gyro (3,) rad/s, accelerometer (3,) m/s² (any sequence of three numbers:
        a list, an array, a pandas row; NaN: missing), at time ``t_s`` (s, or a date-time:
        :mod:`verticality.tilt.stamps`), or a period after the last sample when ``t_s`` is None
        (``period_s`` needed). The stamps are read by the rule of :mod:`verticality.tilt.clock`,
        as ``tilt.estimate`` and ``verticality stream`` read them: a step beyond a gap is a clock
        jump (flag ``CLOCK_JUMP``: one sample at the nominal step) when the readings go on across
        it, else a gap (``DT_GAP``, re-acquired after it); a stamp that does not follow the last
        by a usable step skips its sample (``BAD_DT``) and leaves the clock where it was, unless
        the readings go on (a clock jump); when the next one follows it, the clock was set and is
        followed from there."""
        gyr, acc = three(gyr_rad_s, "gyr_rad_s"), three(acc_m_s2, "acc_m_s2")
        if t_s is None:
            if self.period_s is None:
                raise InputError("Stream.step: give the sample's time t_s, or create the stream "
                                 "with period_s")
            self.k += 1
            t = self.t0_s + self.k * self.period_s
            if self.t_prev is None:
                self.clock.first(gyr, acc)
            else:
                self.clock.follow(self.period_s, gyr, acc)
            self.t_s = self.t_prev = t  # (the period's clock goes on from the last stamp)
            return self.step_dt(gyr, acc, self.period_s, t)
        t = stamp_seconds(t_s)
        if self.t_prev is None:
            dt, var, flags = (self.params.gap_flag_s if self.period_s is None
                              else self.period_s), 0.0, 0
            self.clock.first(gyr, acc)
        else:
            dt, var, flags, _ = self.clock.step(t - self.t_prev, gyr, acc)
        est = self.step_dt(gyr, acc, dt, t, var, flags)
        self.t_prev = t
        t_last = t - self.clock.ahead  # the time taken (a skipped stamp does not move it)
        if t_last != self.t_s:
            self.t_s = self.t0_s = t_last
            self.k = 0
        return est

    def step_dt(self, gyr_rad_s, acc_m_s2, dt_s, t_s=math.nan, tilt_var_rad2=0.0,
                flags=0) -> TiltEstimate:
        """One sample given its step ``dt_s`` from the previous one (non-finite or ≤ 0: skipped,
        flag ``BAD_DT``), for a reader that judges the time stamps itself (``verticality
        stream``, with a :class:`~verticality.tilt.clock.Clock`); ``t_s`` only labels the
        output; ``tilt_var_rad2``, ``flags``: what the step adds (the clock's). The stream's
        clock (:meth:`step`) is not moved."""
        f = self.filter
        roll, pitch, up, q, bias, flags = f.step(gyr_rad_s, acc_m_s2, dt_s, tilt_var_rad2, flags)
        # the variances a sample reports (as tilt.core.output_var): the block-start P with what
        # dropouts and gaps have added to the tilt since, or the initialization's before it
        var = f.P.diagonal().copy()
        widen = f.qmiss if f.initialized else self.params.init_tilt_rad ** 2
        var[0] += widen
        var[1] += widen
        sigma = math.sqrt(var[0] + var[1] + self.calib_var)
        return TiltEstimate(t_s, roll, pitch, np.array(up), np.array(q), np.array(bias), sigma,
                            var, flags, accelerometer_used(flags))


def three(values, name: str) -> tuple[float, float, float]:
    """``values`` (any sequence of three numbers, by position: a list, an array of shape (3,) or
    (1, 3), a pandas row) as three floats, else a one-line :class:`InputError`."""
    if (type(values) in (list, tuple) and len(values) == 3) or (
            type(values) is np.ndarray and values.shape == (3,)):  # the common cases, quickly
        try:
            return float(values[0]), float(values[1]), float(values[2])
        except (TypeError, ValueError):
            pass
    try:
        arr = np.asarray(values, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError):
        arr = None
    if arr is None or arr.size != 3:
        shown = type(values).__name__ if arr is None else f"{arr.size} numbers"
        raise InputError(f"Stream.step: {name} must be three numbers (x, y, z); got {shown}")
    return float(arr[0]), float(arr[1]), float(arr[2])
