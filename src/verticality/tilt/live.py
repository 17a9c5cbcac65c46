"""Live tilt estimation on a stream of IMU CSV rows (``verticality stream``): one estimate row out
per row in, flushed at once, so that a logger, a serial reader or a robot's driver can be piped
through it.

The filter is :class:`verticality.tilt.Stream`, the plain-Python implementation (equal to the
batch run to 1e-9; a jitted JAX call per sample would be too slow for 1 kHz), given each row's
step as the time stamps and readings say (:class:`~verticality.tilt.clock.Clock`, the rule
``tilt.estimate`` follows: a clock jump, a gap, a stamp that is skipped). The rows are read
by :class:`~verticality.io.imu_rows.RowReader`: the first second (at most 500 rows) is held back
and read and checked as ``verticality estimate`` reads a whole file
(:func:`verticality.io.imu.recording_from_rows`: layout, time unit, units, increasing time); then
rows pass one by one, and a row that cannot be read (cells that are not numbers, the wrong number
of cells, a line that is not UTF-8 text or longer than any row) is written with its samples
flagged and named on the warning stream.
"""

from __future__ import annotations

import math
from typing import TextIO

import numpy as np

from verticality.io import imu, imu_layout
from verticality.io import lines as text_lines
from verticality.io.imu_rows import RowReader
from verticality.tilt.clock import SKIP, Clock
from verticality.tilt.realtime import Stream


def stream_estimates(fh: TextIO, out: TextIO, err: TextIO, source: str = "stdin",
                     columns: dict[str, str] | None = None, time_unit: str | None = None,
                     gyr_units: str | None = None, acc_units: str | None = None,
                     sigma: bool = False) -> None:
    """Read IMU CSV rows from ``fh`` (a header line, then data rows; any layout
    :func:`verticality.io.imu.read_imu_csv` reads, ``columns`` and ``time_unit`` as there) and
    write the estimate CSV (``io.imu.estimate_header``; with ``sigma`` the tilt's σ column) to
    ``out``, one row per data row, flushed after each. Notes and warnings go to ``err``. A problem
    in the first second raises :class:`~verticality.core.errors.InputError` before any row is
    written."""
    # (the line bounded and checked; a byte-order mark dropped, as files are read)
    header = text_lines.header_line(fh, source).removeprefix("\ufeff")
    lay = imu_layout.locate(header, columns, time_unit, source)
    reader = RowReader(lay, source, warn_to=err, columns=columns, time_unit=time_unit)
    rows, numbers = reader.read_head(fh)  # (a header among them: read in its order)
    head = imu.recording_from_rows(rows, numbers, reader.lay, source, gyr_units, acc_units)
    reader.set_origin(head.t0_stamp, imu.GYR_UNITS[gyr_units or "rad/s"],
                      imu.ACC_UNITS[acc_units or "m/s2"])
    out.write(imu.estimate_header(sigma) + "\n")
    out.flush()
    if head.t0_stamp is not None:
        print(f"t is in seconds from the input's first time stamp, {head.t0_stamp} "
              f"{head.time_unit}", file=err)
    s = Stream(period_s=float(np.median(head.dt_s)) if head.dt_s.size else None)
    fmt = imu.estimate_row_format(sigma)

    def emit(t_s, g, a, dt, var=0.0, flags=0):
        e = s.step_dt(g, a, dt, t_s, var, flags)
        up = e.up_S
        row = (e.t_s, e.roll_rad, e.pitch_rad, -up[0], -up[1], -up[2], *e.bias_S_rad_s, e.flags)
        if sigma:
            row += (e.sigma_rad,)
        out.write(fmt % row + "\n")
        out.flush()

    clock = Clock(s.params)
    clock.first(head.gyr_rad_s[0], head.acc_m_s2[0])
    emit(float(head.t_s[0]), head.gyr_rad_s[0], head.acc_m_s2[0], float(head.dt_s[0]))
    for k in range(1, head.t_s.size):
        emit(float(head.t_s[k]), head.gyr_rad_s[k], head.acc_m_s2[k],
             *clock.step(float(head.dt_s[k]), head.gyr_rad_s[k], head.acc_m_s2[k])[:3])
    t_prev = float(head.t_s[-1])  # the last finite stamp
    for line in reader.lines(fh):
        t_s, g, a = (reader.sample(line.text.strip()) if line.problem is None
                     else reader.unreadable(line.problem))
        dt, var, flags, kind = clock.step(t_s - t_prev, g, a)
        if kind == SKIP and math.isfinite(t_s):
            reader.warn(f"time {t_s:.9g} s does not follow {t_prev:.9g} s by a usable step")
        if math.isfinite(t_s):
            t_prev = t_s
        emit(t_s, g, a, dt, var, flags)
    reader.summary()
