"""IMU CSV data rows: parsing a file's rows at once (a fast and a general parser), and reading a
stream row by row (``verticality stream``): the held-back first second, then one sample per row,
unreadable rows named and counted rather than dropped.

The layout (which column is which, the time unit) is :mod:`verticality.io.imu_layout`'s; the
checks of a whole recording are :func:`verticality.io.imu.recording_from_rows`.
"""

from __future__ import annotations

import math
from collections.abc import Iterator

import numpy as np

from verticality.core.errors import InputError
from verticality.io import imu_layout as layout
from verticality.io import lines as text_lines
from verticality.io.lines import Line

HEAD_S = 1.0  # a stream's first second is held back and checked as a file is
HEAD_ROWS = 500  # ... at most this many rows ...
HEAD_CHARS = 2**22  # ... and this much of their text
WARN_ROWS = 5  # unreadable rows named one by one, then counted


def parse_clean_rows(rows: list[str], lay) -> tuple[np.ndarray, np.ndarray] | None:
    """The fast path of :func:`verticality.io.imu.read_imu_csv` (NumPy's C parser, instead of
    :func:`parse_rows`' Python loop over rows; docs/tilt.md, "Command line"): ``(data, t_raw)``
    when every cell is a number (``nan`` included) and every row has the header's number of columns,
    with the values :func:`parse_rows` would give; None otherwise (empty cells, text, ragged rows, a
    time column that is not all finite), and then :func:`parse_rows` reads the file, with its
    messages."""
    try:
        data = np.loadtxt(rows, delimiter=",", comments="#", dtype=np.float64, ndmin=2)
    except ValueError:
        return None
    k = lay.index["t"]
    if data.shape[1] != lay.n_columns or not np.all(np.isfinite(data[:, k])):
        return None
    t = data[:, k]
    if not np.all(t == np.round(t)):  # some stamp is not an integer: float64, as parse_rows
        return data, t
    try:  # integer stamps stay exact (ns since 1970 do not survive float64)
        t_int = np.loadtxt(rows, delimiter=",", comments="#", dtype=np.int64, usecols=k, ndmin=1)
    except (ValueError, OverflowError):  # "5.0", "1e3", beyond int64: parse_rows decides
        return None
    return data, t_int


def parse_rows(rows: list[str], line_numbers: list[int], lay, source: str):
    """``(data, t_raw)`` of data rows of any form: empty and non-numeric cells become NaN (the
    time column's are refused, naming their lines), ragged rows are refused naming the first."""
    for row, line_no in zip(rows, line_numbers, strict=True):
        n_cells = len(row.split("#", 1)[0].split(","))
        if n_cells != lay.n_columns:
            raise InputError(f"{source}: line {line_no}: {n_cells} values, but the header has "
                             f"{lay.n_columns} columns")
    try:
        data = np.genfromtxt(rows, delimiter=",", dtype=np.float64, filling_values=np.nan,
                             invalid_raise=True, ndmin=2)
    except ValueError as exc:
        raise InputError(f"{source}: malformed CSV ({str(exc).splitlines()[0]})") from None
    if data.size == 0:
        raise InputError(f"{source}: no data rows")
    if data.shape[1] != lay.n_columns:
        raise InputError(f"{source}: {data.shape[1]} values per row but {lay.n_columns} header "
                         "columns")
    t_cells = [r.split("#", 1)[0].split(",")[lay.index["t"]].strip() for r in rows]
    return data, layout.parse_time_cells(t_cells, line_numbers, source, lay.time_label)



def parse_number(cell: str) -> float:
    """A cell as a float; NaN when it is not a number (as the file parsers make it)."""
    try:
        return float(cell)
    except ValueError:
        return math.nan


class RowReader:
    """Reads the data rows of an IMU CSV stream with layout ``lay`` one by one: the cells of the
    layout's columns as floats (a cell that is not a number is NaN, as the file parser makes it),
    the time in seconds. Unreadable rows and times that do not increase are named on ``warn_to``
    (a text stream; the first :data:`WARN_ROWS`) and counted. ``line_no`` is the number of the
    last line read.

    A header line among the rows (two logs joined, a logger restarted with other columns) is
    recognized (no cell a number, and its names locate as a header with the ``columns`` and
    ``time_unit`` the stream was opened with): its row is written flagged, named on ``warn_to``,
    and the rows after it are read in its column order, never in the old one. A header that
    changes the time unit stops the stream (:class:`InputError`): the stamps before and after it
    cannot be put on one clock. A header right after the first, before any data row, replaces
    it (named, no row written for it)."""

    def __init__(self, lay: layout.Layout, source: str = "input", warn_to=None,
                 columns: dict[str, str] | None = None, time_unit: str | None = None):
        self.source, self.warn_to = source, warn_to
        self.columns, self.time_unit = columns, time_unit
        self._use(lay)
        self.bad = 0
        self.line_no = 1  # the header
        self.pending: tuple[Line, int] | None = None  # a line read, to be given again
        self.origin, self.gyr_scale, self.acc_scale = None, 1.0, 1.0

    def _use(self, lay: layout.Layout) -> None:
        self.lay = lay
        self.k_t = lay.index["t"]
        self.cols = [lay.index[c] for c in layout.IMU_COLUMNS[1:]]
        self.per_s = layout.TIME_UNITS[lay.time_unit or "s"]  # stamps per second

    def header(self, text: str) -> layout.Layout | None:
        """The layout of ``text`` if it is a header line (see the class doc), else None."""
        cells = text.split("#", 1)[0].split(",")
        if any(not math.isnan(parse_number(c)) or c.strip().lower() in ("nan", "+nan", "-nan")
               for c in cells):
            return None
        try:
            return layout.locate(text, self.columns, self.time_unit, self.source)
        except InputError:
            return None

    def switch(self, lay: layout.Layout) -> None:
        """Read the rows from here on in ``lay``'s order (a header line just read)."""
        if (lay.time_unit or "s") != (self.lay.time_unit or "s"):
            raise InputError(f"{self.source}: line {self.line_no}: a new header changes the time "
                             f"unit from {self.lay.time_unit or 's'} to {lay.time_unit or 's'}; "
                             "the stamps cannot be put on one clock: split the stream there")
        self.bad += 1
        if self.warn_to is not None:
            order = ",".join(sorted(lay.index, key=lay.index.get))
            print(f"warning: {self.source} line {self.line_no}: a new header; the rows after it "
                  f"are read in its column order ({order})", file=self.warn_to)
        self._use(lay)

    def lines(self, fh) -> Iterator[Line]:
        """The data lines of ``fh`` from where it stands (blank and ``#`` lines skipped, as files
        are read), counting ``line_no``, each read with a bound
        (:func:`verticality.io.lines.read_line`): a line too long or not UTF-8 text comes with its
        problem."""
        if self.pending is not None:
            line, self.line_no = self.pending
            self.pending = None
            yield line
        while (line := text_lines.read_line(fh, skip_rest=True)) is not None:
            self.line_no += 1
            text = line.text.strip()
            if text and not text.startswith("#"):
                yield line

    def read_head(self, fh, head_s: float = HEAD_S, head_rows: int = HEAD_ROWS
                  ) -> tuple[list[str], list[int]]:
        """The rows of the first ``head_s`` seconds (at most ``head_rows``, at most
        :data:`HEAD_CHARS` characters) and their line numbers, to be read and checked as a file
        (:func:`verticality.io.imu.recording_from_rows`) before the first output row; a line that
        cannot be read there is refused, as in a file."""
        rows, numbers, first_t, chars = [], [], None, 0
        for line in self.lines(fh):
            text = text_lines.check_line(line, self.source, self.line_no)
            lay = self.header(text.strip())
            if lay is not None:
                if rows:  # the head ends before it: the rows after it are read in its order
                    self.pending = (line, self.line_no)
                    break
                self.switch(lay)  # a header again before any data row: it replaces the first
                continue
            rows.append(text)
            numbers.append(self.line_no)
            chars += len(text)
            t_cell = self._time_cell(text)
            if first_t is None:
                first_t = t_cell
            if len(rows) >= head_rows or chars >= HEAD_CHARS or (
                    t_cell is not None and first_t is not None
                    and self._seconds(t_cell, first_t) >= head_s):
                break
        if not rows:
            raise InputError(f"{self.source}: no data rows")
        return rows, numbers

    def _time_cell(self, line: str):
        cells = line.split("#", 1)[0].split(",")
        return cells[self.k_t].strip() if len(cells) == self.lay.n_columns else None

    def _seconds(self, cell: str, first: str) -> float:
        """Time since ``first`` in seconds, for the head's length."""
        try:
            return (float(cell) - float(first)) / self.per_s
        except ValueError:
            return 0.0

    def set_origin(self, origin, gyr_scale: float = 1.0, acc_scale: float = 1.0):
        """The first stamp (None for seconds, which are kept as written; else the
        ``ImuRecording.t0_stamp`` of the head) and the unit conversions of the head."""
        self.origin, self.gyr_scale, self.acc_scale = origin, gyr_scale, acc_scale

    def sample(self, text: str) -> tuple[float, np.ndarray, np.ndarray]:
        """``(t_s, gyr, acc)`` of the row just read: NaN where a cell is not a number, all NaN
        (and named) for a row with the wrong number of cells."""
        lay = self.header(text)
        if lay is not None:
            self.switch(lay)
            return math.nan, np.full(3, np.nan), np.full(3, np.nan)
        cells = text.split("#", 1)[0].split(",")
        if len(cells) != self.lay.n_columns:
            self.warn(f"{len(cells)} cells, the header has {self.lay.n_columns}")
            return math.nan, np.full(3, np.nan), np.full(3, np.nan)
        values = np.array([parse_number(cells[j]) for j in self.cols])
        t_cell = cells[self.k_t].strip()
        if self.origin is None:
            t_s = parse_number(t_cell)
        elif layout.is_integer_cell(t_cell):  # exact, as the file parser converts stamps
            t_s = (int(t_cell) - self.origin) / self.per_s
        else:
            t_s = (parse_number(t_cell) - self.origin) / self.per_s
        if not math.isfinite(t_s):
            self.warn(f"time {t_cell!r} is not a number")
        return t_s, values[:3] * self.gyr_scale, values[3:] * self.acc_scale

    def unreadable(self, problem: str) -> tuple[float, np.ndarray, np.ndarray]:
        """The sample of a line that cannot be read as text (too long, not UTF-8): all NaN,
        named (:meth:`warn`)."""
        self.warn(problem)
        return math.nan, np.full(3, np.nan), np.full(3, np.nan)

    def warn(self, what: str):
        """Name the row just read (the first :data:`WARN_ROWS`), count it."""
        self.bad += 1
        if self.bad <= WARN_ROWS and self.warn_to is not None:
            print(f"warning: {self.source} line {self.line_no}: {what}; written with its samples "
                  "flagged (missing or bad time step)", file=self.warn_to)

    def summary(self):
        """The count of unreadable rows beyond those named."""
        if self.bad > WARN_ROWS and self.warn_to is not None:
            print(f"warning: {self.source}: {self.bad} unreadable rows in all (the first "
                  f"{WARN_ROWS} named above), each written with its samples flagged",
                  file=self.warn_to)
