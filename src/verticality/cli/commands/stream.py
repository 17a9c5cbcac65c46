"""``verticality stream [INPUT] [--sigma] [--units ...] [--columns ...] [--time-unit ...]``.

Live tilt estimation on a pipe: IMU CSV rows in (standard input, or a file), one estimate row out
per input row on standard output, flushed at once (:func:`verticality.tilt.live.
stream_estimates`). The same layouts as ``estimate`` (ours, EuRoC / TUM-VI, ``--columns``), the
same output columns, and the same filter in its sample-by-sample form. The first second (at most
500 rows) is held back and checked as ``estimate`` checks a whole file; then rows pass one by
one; a row that cannot be read (also a line that is not UTF-8 text or longer than any row) is
written with its samples flagged and named on standard error.
"""

from __future__ import annotations

import sys
from pathlib import Path

from verticality.core.errors import InputError


def register(sub):
    from verticality.cli.commands.estimate import add_layout_options

    p = sub.add_parser("stream", help="live tilt estimates on a pipe: IMU CSV rows in, one "
                                      "estimate row out per row, flushed")
    p.add_argument("input", nargs="?", type=Path, default=None, metavar="INPUT",
                   help="IMU CSV to read row by row (default: standard input)")
    p.add_argument("--sigma", action="store_true",
                   help="also write a last column tilt_sigma_rad (the tilt's standard deviation)")
    add_layout_options(p)
    p.set_defaults(func=run)


def run(args) -> int:
    from verticality.io import imu_layout
    from verticality.io import lines as text_lines
    from verticality.io.paths import check_input_file
    from verticality.io.recording import parse_units
    from verticality.tilt.live import stream_estimates

    gyr_u, acc_u = parse_units(args.units)
    mapping = imu_layout.parse_columns_spec(args.columns) if args.columns is not None else None
    if args.input is not None:
        check_input_file(args.input, regular=False)  # a named pipe too
        from verticality.io.logs import is_log

        if is_log(args.input):  # a recorded log is read whole: it is no stream of rows
            raise InputError(f"{args.input}: a robotics log (PX4 ULog, ROS bag, MCAP); stream "
                             "reads IMU CSV rows: use verticality estimate LOG --out OUT.csv")
    source = "stdin" if args.input is None else str(args.input)
    # read as bytes, each line decoded on its own: a line that is not UTF-8 is one flagged row
    fh = text_lines.text_of(sys.stdin) if args.input is None else text_lines.open_text(args.input)
    try:
        stream_estimates(fh, sys.stdout, sys.stderr, source, mapping, args.time_unit, gyr_u, acc_u,
                         args.sigma)
        return 0
    except BrokenPipeError:  # the reader went away (`| head`): stop quietly
        import os

        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    finally:
        if args.input is not None:
            fh.close()
        elif fh is not sys.stdin:
            fh.detach()  # standard input stays open
