"""Tilt from an IMU: the 3-D otolith–canal filter (gyroscope = canals, accelerometer = otoliths),
its offline smoother, its real-time form, the estimation of recordings and folders, and the
evaluations on BROAD and on synthetic recordings (docs/tilt.md).

The API, one output type for all three (:class:`TiltEstimate`: time, roll, pitch, the "up" vector
in the sensor frame, quaternion, gyro bias, the tilt's σ from the run's own parameters, variances,
flags)::

    from verticality import tilt
    est = tilt.estimate(gyr_rad_s, acc_m_s2, t_s)             # causal; or period_s=0.01
    est = tilt.smooth(gyr_rad_s, acc_m_s2, period_s=0.01)     # offline (RTS smoother)
    s = tilt.Stream(period_s=0.01)                            # sample by sample
    one = s.step(gyr_rad_s[0], acc_m_s2[0])                   # one sample of a TiltEstimate
    est.flags & tilt.REACQUIRING                              # the flag bits (tilt.flags)

Robotics logs (PX4 ULog, ROS 1 and ROS 2 bags, MCAP; the ``logs`` extra; docs/logs.md)::

    rec = tilt.read_log("flight.ulg")         # samples, clip bits, breaks, the log's estimate
    est = tilt.estimate_log(rec)              # or tilt.estimate(**rec.estimate_args())
    tilt.compare_log(rec, est).lines          # ours beside the log's own estimate

Options are keyword-only: ``params=tilt.TiltParams(...)``, ``gyr_range_rad_s=``,
``acc_range_m_s2=``, ``detect_clipping=``, ``gyr_clipped=``, ``acc_clipped=``.
:class:`TiltFilter` is the filter under the project's estimator interface (``init``/``step``/
``run``, raw per-sample outputs).
"""

from verticality.io.logs import LogRecording, read_log
from verticality.tilt import flags
from verticality.tilt.estimator import TiltFilter, estimate, smooth
from verticality.tilt.flags import (
    ACC_DISTURBED,
    ACC_MISSING,
    BAD_DT,
    CLIPPED,
    CLOCK_JUMP,
    DT_GAP,
    FLAG_NAMES,
    GYR_MISSING,
    HELD,
    INIT,
    LOG_BREAK,
    OUT_OF_RANGE,
    REACQUIRED,
    REACQUIRING,
)
from verticality.tilt.logs import compare_log, estimate_log
from verticality.tilt.output import TiltEstimate, tilt_sigma_rad
from verticality.tilt.params import DEFAULT_PARAMS, TiltParams, block_samples
from verticality.tilt.realtime import Stream

__all__ = ["estimate", "smooth", "Stream", "read_log", "estimate_log", "compare_log",
           "LogRecording", "TiltEstimate", "TiltFilter", "TiltParams",
           "DEFAULT_PARAMS", "block_samples", "tilt_sigma_rad", "flags", "ACC_MISSING",
           "GYR_MISSING", "BAD_DT",
           "ACC_DISTURBED", "INIT", "DT_GAP", "REACQUIRED", "REACQUIRING", "OUT_OF_RANGE",
           "CLIPPED", "HELD", "LOG_BREAK", "CLOCK_JUMP", "FLAG_NAMES"]
