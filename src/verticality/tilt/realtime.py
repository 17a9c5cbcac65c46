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
from verticality.tilt.flags import accelerometer_used
from verticality.tilt.output import TiltEstimate
from verticality.tilt.params import DEFAULT_PARAMS, MAX_DT_S, TiltParams


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
    excess. A time stamp that does not go forward skips its sample (flag ``BAD_DT``).

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
        self.t_s = None  # the time of the last sample
        # a period's clock counts samples from the last time stamp (t0 + k period, as the batch
        # run's k × period_s: no sum of rounded steps)
        self.t0_s, self.k = 0.0, -1
        self.calib_var = (params.acc_calib_m_s2 / params.g_m_s2) ** 2

    def step(self, gyr_rad_s, acc_m_s2, t_s=None) -> TiltEstimate:
        """One sample: gyro (3,) rad/s, accelerometer (3,) m/s² (NaN: missing), at time ``t_s``
        (s), or a period after the last sample when ``t_s`` is None (``period_s`` needed)."""
        if t_s is None:
            if self.period_s is None:
                raise InputError("Stream.step: give the sample's time t_s, or create the stream "
                                 "with period_s")
            self.k += 1
            t = self.t0_s + self.k * self.period_s
            dt = self.period_s
        else:
            t = float(t_s)
            if not math.isfinite(t):
                raise InputError(f"Stream.step: t_s must be a finite time in seconds; got {t_s!r}")
            if self.t_s is None:
                dt = self.params.gap_flag_s if self.period_s is None else self.period_s
            else:
                dt = t - self.t_s
        est = self.step_dt(gyr_rad_s, acc_m_s2, dt, t)
        if self.t_s is None or 0.0 < dt < MAX_DT_S:  # a skipped stamp does not move the clock
            self.t_s = t
            if t_s is not None:
                self.t0_s, self.k = t, 0
        return est

    def step_dt(self, gyr_rad_s, acc_m_s2, dt_s, t_s=math.nan) -> TiltEstimate:
        """One sample given its step ``dt_s`` from the previous one (non-finite or ≤ 0: skipped,
        flag ``BAD_DT``), for a reader that judges the time stamps itself (``verticality
        stream``); ``t_s`` only labels the output. The stream's clock (:meth:`step`) is not
        moved."""
        f = self.filter
        roll, pitch, up, q, bias, flags = f.step(gyr_rad_s, acc_m_s2, dt_s)
        # the variances a sample reports (as tilt.core.output_var): the block-start P with what
        # dropouts and gaps have added to the tilt since, or the initialization's before it
        var = f.P.diagonal().copy()
        widen = f.qmiss if f.initialized else self.params.init_tilt_rad ** 2
        var[0] += widen
        var[1] += widen
        sigma = math.sqrt(var[0] + var[1] + self.calib_var)
        return TiltEstimate(t_s, roll, pitch, np.array(up), np.array(q), np.array(bias), sigma,
                            var, flags, accelerometer_used(flags))
