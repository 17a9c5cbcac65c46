"""``verticality stream [INPUT] [--sigma] [--units ...] [--columns ...] [--time-unit ...]``.

Live tilt estimation on a pipe: IMU CSV rows in (standard input, or a file), one estimate row out
per input row on standard output, flushed at once, so that a logger, a serial reader or a robot's
driver can be piped through it. The same layouts as ``estimate`` (ours, EuRoC / TUM-VI,
``--columns``), the same output columns, and the same filter in its sample-by-sample form
(``tilt_stream.Stream``, equal to ``tilt.run``).

The first second (at most 500 rows) is held back and checked as ``estimate`` checks a whole file
(layout, time unit, units, increasing time); then rows pass one by one. A row that cannot be read
(wrong number of cells, a time that is not a number) is not dropped: it is written with its
samples flagged missing and named on standard error.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np

from verticality.errors import InputError

HEAD_S = 1.0  # held back and checked before the first output row
HEAD_ROWS = 500
WARN_ROWS = 5  # unreadable rows named one by one, then counted


def register(sub):
    from verticality.commands.estimate import add_layout_options

    p = sub.add_parser("stream", help="live tilt estimates on a pipe: IMU CSV rows in, one "
                                      "estimate row out per row, flushed")
    p.add_argument("input", nargs="?", type=Path, default=None, metavar="INPUT",
                   help="IMU CSV to read row by row (default: standard input)")
    p.add_argument("--sigma", action="store_true",
                   help="also write a last column tilt_sigma_rad (the tilt's standard deviation)")
    add_layout_options(p)
    p.set_defaults(func=run)


def run(args) -> int:
    from verticality.commands.estimate import _parse_units
    from verticality.io import imu_layout

    gyr_u, acc_u = _parse_units(args.units)
    mapping = imu_layout.parse_columns_spec(args.columns) if args.columns is not None else None
    if args.input is not None and not args.input.is_file():
        raise InputError(f"{args.input}: no such file")
    source = "stdin" if args.input is None else str(args.input)
    fh = sys.stdin if args.input is None else open(args.input, encoding="utf-8-sig")  # noqa: SIM115
    try:
        return _stream(fh, source, mapping, args.time_unit, gyr_u, acc_u, args.sigma)
    except BrokenPipeError:  # the reader went away (`| head`): stop quietly
        import os

        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    finally:
        if fh is not sys.stdin:
            fh.close()


def _stream(fh, source, mapping, time_unit, gyr_u, acc_u, sigma: bool) -> int:
    from verticality.estimators.tilt_stream import Stream
    from verticality.io import imu, imu_layout

    header = fh.readline().removeprefix("\ufeff")  # a byte-order mark, as files are read
    lay = imu_layout.locate(header.rstrip("\r\n"), mapping, time_unit, source)
    reader = _RowReader(lay, source)
    head, numbers, line_no, t_span = [], [], 1, 0.0
    first_t = None
    for line in fh:
        line_no += 1
        text = line.strip()
        if not text or text.startswith("#"):
            continue
        head.append(line.rstrip("\r\n"))
        numbers.append(line_no)
        t_cell = reader.time_cell(head[-1])
        if first_t is None and t_cell is not None:
            first_t = t_cell
        if t_cell is not None and first_t is not None:
            t_span = reader.seconds(t_cell, first_t)
        if len(head) >= HEAD_ROWS or t_span >= HEAD_S:
            break
    if not head:
        raise InputError(f"{source}: no data rows")
    # the head is read and checked exactly as `estimate` reads a file
    fast = imu._parse_clean_rows(head, lay)
    data, t_raw = fast if fast is not None else imu._parse_rows(head, numbers, lay, source)
    imu_layout.check_time_steps(t_raw, numbers, lay.time_unit, source, lay.time_label)
    unit = lay.time_unit or "s"
    t_head, t0 = imu_layout.time_to_seconds(t_raw, unit)
    idx = lay.index
    gyr = data[:, [idx["gyr_x"], idx["gyr_y"], idx["gyr_z"]]]
    acc = data[:, [idx["acc_x"], idx["acc_y"], idx["acc_z"]]]
    dt_head = imu.dt_from_t(t_head)
    gyr, acc = imu.check_units(gyr, acc, gyr_units=gyr_u, acc_units=acc_u, source=source,
                               dt_s=dt_head)
    reader.set_origin(t_raw[0].item() if unit != "s" else None,
                      imu.GYR_UNITS[gyr_u or "rad/s"], imu.ACC_UNITS[acc_u or "m/s2"])
    out = sys.stdout
    columns = imu.ESTIMATE_COLUMNS + ((imu.SIGMA_COLUMN,) if sigma else ())
    out.write(",".join(columns) + "\n")
    out.flush()
    if t0 is not None:
        print(f"t is in seconds from the input's first time stamp, {t0} {unit}", file=sys.stderr)
    s = Stream()
    fmt = ",".join(["%.17g"] * 9) + ",%d" + (",%.17g" if sigma else "")

    def emit(t_s, g, a, dt):
        roll, pitch, up, _, bias, flags = s.step(g, a, dt)
        row = (t_s, roll, pitch, -up[0], -up[1], -up[2], *bias, flags)
        if sigma:
            row += (s.tilt_sigma_rad,)
        out.write(fmt % row + "\n")
        out.flush()

    for k in range(t_head.size):
        emit(float(t_head[k]), gyr[k], acc[k], float(dt_head[k]))
    t_last = float(t_head[-1])
    for line in fh:
        line_no += 1
        text = line.strip()
        if not text or text.startswith("#"):
            continue
        t_s, g, a = reader.sample(text, line_no)
        dt = t_s - t_last if math.isfinite(t_s) else math.nan
        if dt > 0:
            t_last = t_s
        elif dt <= 0:
            reader.warn(line_no, f"time {t_s:.9g} s does not follow {t_last:.9g} s")
        emit(t_s, g, a, dt)
    reader.summary()
    return 0


class _RowReader:
    """Cells of one data row after the head: the layout's columns as floats (a cell that is not a
    number is NaN, as the file parser makes it), the time in seconds; unreadable rows and times
    that do not increase are named on standard error (the first few) and counted."""

    def __init__(self, lay, source: str):
        from verticality.io import imu_layout

        self.lay, self.source = lay, source
        self.k_t = lay.index["t"]
        self.cols = [lay.index[c] for c in imu_layout.IMU_COLUMNS[1:]]
        self.bad = 0
        self.per_s = imu_layout.TIME_UNITS[lay.time_unit or "s"]  # stamps per second
        self.is_integer = imu_layout.is_integer_cell
        self.origin, self.gyr_scale, self.acc_scale = None, 1.0, 1.0

    def time_cell(self, line: str):
        cells = line.split("#", 1)[0].split(",")
        return cells[self.k_t].strip() if len(cells) == self.lay.n_columns else None

    def seconds(self, cell: str, first: str) -> float:
        """Time since ``first`` in seconds, for the head's length."""
        try:
            return (float(cell) - float(first)) / self.per_s
        except ValueError:
            return 0.0

    def set_origin(self, origin, gyr_scale: float, acc_scale: float):
        """The first stamp (None for seconds, kept as written) and the unit conversions."""
        self.origin, self.gyr_scale, self.acc_scale = origin, gyr_scale, acc_scale

    def sample(self, text: str, line_no: int):
        cells = text.split("#", 1)[0].split(",")
        if len(cells) != self.lay.n_columns:
            self.warn(line_no, f"{len(cells)} cells, the header has {self.lay.n_columns}")
            return math.nan, np.full(3, np.nan), np.full(3, np.nan)
        values = np.array([_number(cells[j]) for j in self.cols])
        t_cell = cells[self.k_t].strip()
        if self.origin is None:
            t_s = _number(t_cell)
        elif self.is_integer(t_cell):  # exact, as the file parser converts stamps
            t_s = (int(t_cell) - self.origin) / self.per_s
        else:
            t_s = (_number(t_cell) - self.origin) / self.per_s
        if not math.isfinite(t_s):
            self.warn(line_no, f"time {t_cell!r} is not a number")
        return t_s, values[:3] * self.gyr_scale, values[3:] * self.acc_scale

    def warn(self, line_no: int, what: str):
        self.bad += 1
        if self.bad <= WARN_ROWS:
            print(f"warning: {self.source} line {line_no}: {what}; written with its samples "
                  "flagged (missing or bad time step)", file=sys.stderr)

    def summary(self):
        if self.bad > WARN_ROWS:
            print(f"warning: {self.source}: {self.bad} unreadable rows in all (the first "
                  f"{WARN_ROWS} named above), each written with its samples flagged",
                  file=sys.stderr)


def _number(cell: str) -> float:
    try:
        return float(cell)
    except ValueError:
        return math.nan
