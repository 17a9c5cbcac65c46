"""Layouts of IMU CSV files: which column is which, and in what time unit.

:func:`verticality.io.imu.read_imu_csv` reads our own header (``t,gyr_x,gyr_y,gyr_z,acc_x,acc_y,
acc_z``), an EuRoC / TUM-VI (ASL) IMU file recognized from its header, or any header with a
mapping of our seven names to the file's (CLI ``--columns``). This module holds the pieces: header
names, the column mapping and its refusals, and time stamps (their unit, exact integer parsing,
the conversion to seconds and the plausibility of the steps). Everything refused raises a one-line
:class:`InputError`.
"""

from __future__ import annotations

import re
from typing import NamedTuple

import numpy as np

from verticality.core.errors import InputError

IMU_COLUMNS = ("t", "gyr_x", "gyr_y", "gyr_z", "acc_x", "acc_y", "acc_z")
# time units of a file's time column: stamps per second (integers, so that ns stamps convert
# exactly)
TIME_UNITS = {"s": 1, "ms": 1_000, "us": 1_000_000, "ns": 1_000_000_000}
# units written in brackets after a time column's name, e.g. "timestamp [ns]"
HEADER_TIME_UNITS = {"s": "s", "sec": "s", "ms": "ms", "us": "us", "µs": "us", "μs": "us",
                     "ns": "ns"}
# EuRoC MAV / TUM-VI (ASL format) IMU file: our name -> the file's header name
EUROC_COLUMNS = {"t": "timestamp [ns]",
                 "gyr_x": "w_RS_S_x [rad s^-1]", "gyr_y": "w_RS_S_y [rad s^-1]",
                 "gyr_z": "w_RS_S_z [rad s^-1]",
                 "acc_x": "a_RS_S_x [m s^-2]", "acc_y": "a_RS_S_y [m s^-2]",
                 "acc_z": "a_RS_S_z [m s^-2]"}
COLUMNS_EXAMPLE = "t=timestamp,gyr_x=wx,gyr_y=wy,gyr_z=wz,acc_x=ax,acc_y=ay,acc_z=az"
_BRACKET_UNIT = re.compile(r"^(.*?)\s*\[([^\[\]]*)\]$")
_INTEGER = re.compile(r"^[+-]?\d+$")
MIN_STEP_S, MAX_STEP_S = 1e-5, 1.0  # median sample step of an IMU: between 100 kHz and 1 Hz
# Times read as seconds because no unit was stated: a median step above this (below 10 Hz, so that
# the tilt filter would take every step for a gap) or a first stamp beyond MAX_EPOCH_S (after the
# year 5000) is refused as most likely ms, µs or ns, naming --time-unit s for real seconds.
SLOW_STEP_S = 0.1 + 1e-6
MAX_EPOCH_S = 1e11


def header_name(cell: str) -> str:
    """A header cell's name as compared: surrounding whitespace and one leading ``#`` removed
    (EuRoC writes ``#timestamp [ns]``; TUM-VI sometimes adds spaces or drops the ``#``)."""
    name = cell.strip()
    return name[1:].strip() if name.startswith("#") else name


def split_bracket_unit(name: str) -> tuple[str, str | None]:
    """``"timestamp [ns]"`` → ``("timestamp", "ns")``; a name without a trailing ``[...]`` →
    ``(name, None)``."""
    m = _BRACKET_UNIT.match(name)
    return (m.group(1), m.group(2).strip()) if m else (name, None)


def _short_list(names, limit: int = 12, width: int = 40) -> str:
    """Comma-separated names for a one-line message: at most ``limit`` names, each cut at
    ``width`` characters."""
    shown = [n if len(n) <= width else n[:width - 1] + "…" for n in names[:limit]]
    more = f", … ({len(names) - limit} more)" if len(names) > limit else ""
    return ", ".join(repr(n) for n in shown) + more


def parse_columns_spec(text: str) -> dict[str, str]:
    """``"t=timestamp,gyr_x=wx,..."`` (the CLI's ``--columns``) → ``{"t": "timestamp", ...}``.

    Only the syntax is checked here (every item ``NAME=COLUMN`` with one ``=``, no name twice), so
    a file column whose name holds ``,`` or ``=`` cannot be named this way; which names are allowed
    and whether the columns exist is checked by :func:`resolve_columns`."""
    spec: dict[str, str] = {}
    items = text.split(",")
    for item in items:
        key, sep, value = item.partition("=")
        key, value = key.strip(), value.strip()
        if not sep or not key or not value or "=" in value:
            raise InputError(f"--columns: {item.strip()!r} is not NAME=COLUMN; expected e.g. "
                             f"--columns {COLUMNS_EXAMPLE}")
        if key in spec:
            raise InputError(f"--columns: {key} is given twice")
        spec[key] = value
    return spec


def _matches(names: list[str], wanted: str) -> list[int]:
    """Indices of the header names equal to ``wanted``; when none is, of those whose name without
    a trailing bracketed unit is (so ``timestamp`` finds ``timestamp [ns]``)."""
    wanted = header_name(str(wanted))
    exact = [i for i, n in enumerate(names) if n == wanted]
    if exact:
        return exact
    return [i for i, n in enumerate(names) if split_bracket_unit(n)[0] == wanted]


def resolve_columns(names: list[str], columns: dict[str, str], source: str = "input",
                    ) -> dict[str, int]:
    """Map our seven names to column indices of a header (``names`` as from :func:`header_name`).

    ``columns`` maps each of ``t, gyr_x, gyr_y, gyr_z, acc_x, acc_y, acc_z`` to a header name;
    unknown or missing keys, names not in the header (or matching several columns), and one file
    column used for two of ours are refused with an :class:`InputError` naming them."""
    unknown = [k for k in columns if k not in IMU_COLUMNS]
    if unknown:
        raise InputError(f"{source}: unknown column name(s) {', '.join(map(str, unknown))} in "
                         f"--columns; use {','.join(IMU_COLUMNS)}")
    absent = [k for k in IMU_COLUMNS if k not in columns]
    if absent:
        raise InputError(f"{source}: --columns must map all of {','.join(IMU_COLUMNS)}; "
                         f"{', '.join(absent)} missing")
    index: dict[str, int] = {}
    not_found = []
    for key in IMU_COLUMNS:
        hits = _matches(names, columns[key])
        if len(hits) > 1:
            raise InputError(f"{source}: --columns {key}={columns[key]} matches {len(hits)} file "
                             f"columns ({_short_list([names[i] for i in hits])}); give the full "
                             "name with its [unit]")
        if not hits:
            not_found.append(f"{key}={columns[key]}")
        else:
            index[key] = hits[0]
    if not_found:
        raise InputError(f"{source}: column(s) not in the file: {', '.join(not_found)}; the file "
                         f"has {_short_list(names)}")
    by_file_column: dict[int, list[str]] = {}
    for key, i in index.items():
        by_file_column.setdefault(i, []).append(key)
    shared = [(names[i], keys) for i, keys in by_file_column.items() if len(keys) > 1]
    if shared:
        name, keys = shared[0]
        raise InputError(f"{source}: file column {name!r} is used for {' and '.join(keys)}; "
                         "each of ours needs its own column")
    return index


def default_columns(names: list[str], source: str = "input") -> dict[str, int]:
    """Column indices for a header without a user mapping: our own names
    (``t,gyr_x,...,acc_z``), else the EuRoC / TUM-VI names; else a one-line :class:`InputError`
    listing what the file has and suggesting ``--columns``."""
    for layout in ({k: k for k in IMU_COLUMNS}, EUROC_COLUMNS):
        if all(_matches(names, v) for v in layout.values()):
            return resolve_columns(names, layout, source)
    missing = [c for c in IMU_COLUMNS if not _matches(names, c)]
    raise InputError(f"{source}: missing column(s) {', '.join(missing)}; expected header "
                     f"{','.join(IMU_COLUMNS)} or EuRoC/TUM-VI; the file has "
                     f"{_short_list(names)}; map yours with --columns {COLUMNS_EXAMPLE}")


def stated_time_unit(header_unit: str | None, time_unit: str | None, source: str = "input",
                     ) -> str | None:
    """The time unit to use: ``time_unit`` (the caller's), else the one in the time column's
    header (``[ns]``), else None (not stated); a caller's unit that contradicts the header's is
    refused."""
    if time_unit is not None and time_unit not in TIME_UNITS:
        raise InputError(f"unknown time unit {time_unit!r}; use one of {', '.join(TIME_UNITS)}")
    if header_unit is not None and time_unit is not None and header_unit != time_unit:
        raise InputError(f"{source}: the time column's header says [{header_unit}] but "
                         f"--time-unit {time_unit} was given; drop --time-unit or fix the header")
    return time_unit if time_unit is not None else header_unit


def is_integer_cell(cell: str) -> bool:
    """Whether a (stripped) time cell is an integer, as :func:`parse_time_cells` tells them."""
    return bool(_INTEGER.match(cell))


def parse_time_cells(cells: list[str], line_numbers: list[int], source: str = "input",
                     label: str = "t") -> np.ndarray:
    """Time cells → int64 when every cell is an integer (ns stamps ~1.4e18 do not survive float64:
    its spacing there is 256 ns), else float64. Empty or non-numeric cells, and integers beyond
    int64, are refused naming their lines."""
    if cells and all(_INTEGER.match(c) for c in cells):
        try:
            return np.array([int(c) for c in cells], dtype=np.int64)
        except OverflowError:
            raise InputError(f"{source}: column {label} has integers beyond int64") from None
    values = np.empty(len(cells), dtype=np.float64)
    for k, c in enumerate(cells):
        try:
            values[k] = float(c)
        except ValueError:
            values[k] = np.nan
    bad = np.flatnonzero(~np.isfinite(values))
    if bad.size:
        raise InputError(f"{source}: column {label} has empty or non-numeric cells at lines "
                         f"{[line_numbers[k] for k in bad[:5]]}")
    return values


def check_time_steps(t_raw: np.ndarray, line_numbers: list[int], unit: str | None,
                     source: str = "input", label: str = "t") -> None:
    """Refuse times that decrease (naming the first bad line), and a median step that is no IMU's
    rate. A repeated stamp (a step of 0: a coarse or jittery clock) is read: the tilt filter skips
    that row's readings, having no time to integrate them over, and flags it (``BAD_DT``).

    ``unit`` None (not stated): a median step above ``SLOW_STEP_S`` is refused, since as seconds
    that is below 10 Hz (every step a gap for the tilt filter) and the stamps are most likely ms
    (at 2 kHz: 0.5 ms steps), µs or ns; so is a first stamp beyond ``MAX_EPOCH_S`` (ms since 1970
    read as seconds). A stated unit: the median step in seconds must be
    at least ``MIN_STEP_S`` (100 kHz) and, unless the unit is seconds, below ``MAX_STEP_S`` (1 Hz),
    which catches a wrong ``--time-unit`` (ns stamps read as ms give 5000 s steps); stating ``s``
    is how a really slow recording is read."""
    steps = np.diff(t_raw)
    if np.any(steps < 0):
        bad = int(np.flatnonzero(steps < 0)[0]) + 1
        raise InputError(f"{source}: time {label} must not decrease (line "
                         f"{line_numbers[bad]})")
    if not steps.size:
        return
    med = float(np.median(steps))
    if med <= 0:
        raise InputError(f"{source}: time {label} repeats in most rows (the median step is 0): "
                         "no sampling rate can be read from it")
    if unit is None:
        if med > SLOW_STEP_S:
            raise InputError(f"{source}: median time step is {med:.6g}, which as seconds would be "
                             f"{1.0 / med:.3g} Hz, below 10 Hz: pass --time-unit ms|us|ns (or "
                             "time_unit=...) to state the unit (--time-unit s if it really is "
                             "seconds)")
        if abs(float(t_raw[0])) > MAX_EPOCH_S:
            raise InputError(f"{source}: the first time stamp is {float(t_raw[0]):.6g}, which as "
                             "seconds since 1970 would be after the year 5000: pass --time-unit "
                             "ms|us|ns (or time_unit=...) to state the unit (--time-unit s if it "
                             "really is seconds)")
        return
    med_s = med / TIME_UNITS[unit]
    if med_s < MIN_STEP_S or (unit != "s" and med_s >= MAX_STEP_S):
        raise InputError(f"{source}: with time in {unit} the median step is {med_s:.6g} s "
                         f"({1.0 / med_s:.6g} Hz), not an IMU's rate: check --time-unit (or the "
                         "time column's [unit])")


def time_to_seconds(t_raw: np.ndarray, unit: str, origin=None) -> tuple[np.ndarray,
                                                                         int | float | None]:
    """``(t_s, t0_stamp)`` from stamps in ``unit``.

    Seconds are kept as written (``t0_stamp`` None). Stamps in ms, µs or ns are made relative to
    the first one before the conversion: the subtraction is exact for integer stamps (int64), and
    one division by the exact count of stamps per second rounds once, so ``dt`` is exact to well
    below 1e-9 s. Adding the first stamp back in float64 seconds would quantize times near 1.4e9 s
    to 2.4e-7 s, hence the relative time; ``t0_stamp`` (the file's first stamp) restores it."""
    if unit == "s":
        return t_raw.astype(np.float64), None
    t0 = t_raw[0].item() if origin is None else origin  # a later piece: the file's first stamp
    rel = t_raw - t0
    return rel.astype(np.float64) / TIME_UNITS[unit], t0


class Layout(NamedTuple):
    """Where our seven quantities are in a file and the unit of its time column."""

    index: dict  # our name -> column index
    n_columns: int  # columns in the header
    time_unit: str | None  # stated by the caller or the header; None: not stated (seconds)
    time_label: str  # "t", or "t (timestamp [ns])" when the file names it otherwise


def locate(header_line: str, columns: dict[str, str] | None = None, time_unit: str | None = None,
           source: str = "input") -> Layout:
    """The :class:`Layout` of a file from its header line: our own names or EuRoC / TUM-VI when
    ``columns`` is None, else the caller's mapping; the time unit from ``time_unit`` or the time
    column's ``[unit]`` (they must agree)."""
    names = [header_name(c) for c in header_line.split(",")]
    index = default_columns(names, source) if columns is None else \
        resolve_columns(names, dict(columns), source)
    t_name = names[index["t"]]
    header_unit = HEADER_TIME_UNITS.get(split_bracket_unit(t_name)[1] or "")
    return Layout(index, len(names), stated_time_unit(header_unit, time_unit, source),
                  "t" if t_name == "t" else f"t ({t_name})")
