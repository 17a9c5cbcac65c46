"""Flag bits of the 3-D tilt filter's outputs (``TiltOutput.flags``, the ``flags`` column of
``verticality estimate`` and ``verticality stream``): the one definition, used by the filter core,
its batch kernel, the plain-Python reference, the command line and docs/tilt.md.

A sample's flags are the bitwise OR of the bits below that apply to it.
"""

from __future__ import annotations

ACC_MISSING = 1  # accelerometer sample non-finite or zero: predict only
GYR_MISSING = 2  # gyroscope sample non-finite: orientation held, covariance inflated
BAD_DT = 4  # Δt non-finite or <= 0: sample skipped entirely
ACC_DISTURBED = 8  # inertial acceleration estimate large: accelerometer strongly down-weighted
INIT = 16  # the sample that initialized the filter from the accelerometer
DT_GAP = 32  # Δt above gap_flag_s: a gap in the recording (motion inside it is not seen)
REACQUIRED = 64  # the tilt was re-acquired from the accelerometer after a gap or the start
REACQUIRING = 128  # from a gap (or the start) to its re-acquisition: the estimate may be off
OUT_OF_RANGE = 256  # a gyro or accelerometer component beyond the sensor's physical range
# (tilt_params.MAX_RATE_RAD_S, MAX_ACC_M_S2; ±inf included): a corrupt sample, taken as missing
CLIPPED = 512  # a gyro or accelerometer component at the sensor's clip level (tilt_limits): a
# clipped gyro axis widens the tilt variance for its unknown excess, a clipped accelerometer axis
# the velocity variance (both readings are kept)
HELD = 1024  # the row repeats the previous row's six channels bit for bit (tilt_limits): a logger
# faster than its sensor; filtered as any row (a zero-order hold over its true Δt)
LOG_BREAK = 2048  # a robotics log marks a break before this sample (verticality.io.logs): samples
# lost (a logger drop-out), or the selected IMU changed (the filter starts afresh here)
CLOCK_JUMP = 4096  # the time stamps step by more than a gap (or back, or absurdly far) while the
# readings go on as from one sample to the next (tilt.clock): a clock set, taken as one sample at
# the nominal step, no rotation invented and no re-acquisition

FLAG_NAMES = {ACC_MISSING: "accelerometer missing", GYR_MISSING: "gyro missing",
              BAD_DT: "bad time step", ACC_DISTURBED: "accelerometer disturbed",
              INIT: "initialization", DT_GAP: "gap in the time stamps",
              REACQUIRED: "tilt re-acquired", REACQUIRING: "re-acquiring",
              OUT_OF_RANGE: "beyond the sensor's range", CLIPPED: "clipped",
              HELD: "held (repeated row)", LOG_BREAK: "break in the log",
              CLOCK_JUMP: "clock jump"}
# short identifiers of the bits (table columns such as a folder summary's ``n_<key>``)
FLAG_KEYS = {ACC_MISSING: "acc_missing", GYR_MISSING: "gyr_missing", BAD_DT: "bad_dt",
             ACC_DISTURBED: "acc_disturbed", INIT: "init", DT_GAP: "dt_gap",
             REACQUIRED: "reacquired", REACQUIRING: "reacquiring", OUT_OF_RANGE: "out_of_range",
             CLIPPED: "clipped", HELD: "held", LOG_BREAK: "log_break", CLOCK_JUMP: "clock_jump"}


def accelerometer_used(flags):
    """Whether each sample's accelerometer reading entered the filter (``TiltOutput.measured``):
    neither missing nor on a skipped sample. Works on ints and on NumPy or JAX integer arrays."""
    return (flags & (ACC_MISSING | BAD_DT)) == 0
