"""IMU recordings in CSV: ``t,gyr_x,gyr_y,gyr_z,acc_x,acc_y,acc_z`` (s, rad/s, m/s²), and the
estimate CSV ``t,roll_rad,pitch_rad,gx,gy,gz,bias_x,bias_y,bias_z,flags`` written by
``verticality estimate``.

Unit checks: a recording whose accelerometer norm has a median near 1 looks like it is in g; a gyro
looks like deg/s when it exceeds 35 rad/s (≈ 2000 deg/s, the largest common MEMS range) in more
than 1 % of the samples, or when it turns the accelerometer direction ~57x faster than that
direction actually turns (:func:`looks_like_deg_s`). Such data are refused with an
:class:`InputError` unless the caller states the units (``gyr_units="deg/s"``, ``acc_units="g"``),
which converts them. NaN cells are kept (the filter skips and flags them).

Other layouts (:func:`read_imu_csv`, the pieces in :mod:`verticality.io.imu_layout`): EuRoC /
TUM-VI (ASL) IMU files are recognized from their header; any other header is read when the caller
maps our seven names to the file's (``columns={"t": "timestamp", ...}``, CLI ``--columns``). Time
stamps in ms, µs or ns (``time_unit``, or a ``[ns]``-style unit on the time column's header) are
converted to seconds relative to the first stamp, exactly for integer stamps.
"""

from __future__ import annotations

from pathlib import Path
from typing import NamedTuple

import numpy as np

from verticality.core.constants import G_M_S2
from verticality.core.errors import InputError
from verticality.io import imu_layout as layout
from verticality.io import imu_rows
from verticality.io import lines as text_lines
from verticality.io.paths import check_input_file

IMU_COLUMNS = layout.IMU_COLUMNS
ESTIMATE_COLUMNS = ("t", "roll_rad", "pitch_rad", "gx", "gy", "gz", "bias_x", "bias_y", "bias_z",
                    "flags")
SIGMA_COLUMN = "tilt_sigma_rad"  # appended when the filter reports its uncertainty
GYR_UNITS = {"rad/s": 1.0, "deg/s": np.pi / 180.0}
ACC_UNITS = {"m/s2": 1.0, "m/s^2": 1.0, "g": G_M_S2}
MAX_PLAUSIBLE_RATE_RAD_S = 35.0  # ~2000 deg/s: the largest range of common MEMS gyros
# At rest a gyro reads its bias. MEMS turn-on offsets reach ±20 °/s (0.35 rad/s) on the cheapest
# parts; a rest rate above this is none, but a deg/s reading (a bias of 0.5 °/s read as 0.5 rad/s
# is a 29 °/s "bias" that tilts the estimate by tens of degrees within seconds).
MAX_REST_RATE_RAD_S = 0.5
REST_WINDOW_S = 0.5  # the still stretches: windows this long ...
REST_ACC_STD_M_S2 = 0.1  # ... whose accelerometer varies by less than this (per axis, RMS) ...
REST_ACC_NORM_M_S2 = 1.0  # ... with a norm within this of g ...
REST_GYR_STD_RAD_S = 0.5  # ... and a gyro steadier than this (a bias is constant; a turn is not)
REST_MIN_S = 1.0  # ... at least this long in all


class ImuRecording(NamedTuple):
    t_s: np.ndarray  # (N,)
    gyr_rad_s: np.ndarray  # (N, 3)
    acc_m_s2: np.ndarray  # (N, 3)
    # When the file's time was in ms, µs or ns, t_s starts at 0 and t0_stamp is the file's first
    # stamp as written (an int for integer stamps), in unit time_unit; else None and "s".
    t0_stamp: int | float | None = None
    time_unit: str = "s"

    @property
    def dt_s(self) -> np.ndarray:
        """Per-sample steps: ``dt[k] = t[k] − t[k−1]``, the first one the median step."""
        return dt_from_t(self.t_s)


def dt_from_t(t_s) -> np.ndarray:
    t = np.asarray(t_s, dtype=np.float64)
    if t.size < 2:
        return np.full(t.shape, np.nan)
    d = np.diff(t)
    first = np.nanmedian(d) if np.any(np.isfinite(d)) else np.nan
    return np.concatenate([[first], d])


def check_units(gyr, acc, *, gyr_units: str | None = None, acc_units: str | None = None,
                source: str = "input", dt_s=None) -> tuple[np.ndarray, np.ndarray]:
    """Convert to rad/s and m/s² when units are given; otherwise refuse data that look like deg/s
    or g (one-line :class:`InputError` naming the fix)."""
    gyr = np.asarray(gyr, dtype=np.float64)
    acc = np.asarray(acc, dtype=np.float64)
    if gyr_units is not None:
        if gyr_units not in GYR_UNITS:
            raise InputError(f"unknown gyro unit {gyr_units!r}; use one of {', '.join(GYR_UNITS)}")
        gyr = gyr * GYR_UNITS[gyr_units]
    if acc_units is not None:
        if acc_units not in ACC_UNITS:
            raise InputError(f"unknown accelerometer unit {acc_units!r}; use one of "
                             f"{', '.join(ACC_UNITS)}")
        acc = acc * ACC_UNITS[acc_units]
    with np.errstate(over="ignore", invalid="ignore"):  # 1e308: its norm is inf, left out
        acc_norm = np.linalg.norm(acc, axis=1)
    acc_norm = acc_norm[np.isfinite(acc_norm)]
    if acc_norm.size == 0:
        raise InputError(f"{source}: no finite accelerometer sample")
    med = float(np.median(acc_norm))
    if acc_units is None and 0.5 < med < 2.0:
        raise InputError(f"{source}: accelerometer norm is about {med:.2f}: this looks like g, "
                         "not m/s²; pass --units g (or acc_units='g') to convert")
    if not 5.0 < med < 20.0:
        raise InputError(f"{source}: median accelerometer norm {med:.3g} m/s² is not near "
                         f"{G_M_S2}: wrong units or not a specific-force recording")
    rate = np.abs(gyr[np.all(np.isfinite(gyr), axis=1)])
    if gyr_units is None and rate.size and np.mean(rate > MAX_PLAUSIBLE_RATE_RAD_S) > 0.01:
        raise InputError(f"{source}: gyro rates above {MAX_PLAUSIBLE_RATE_RAD_S:.0f} rad/s in "
                         "more than 1% of samples: this looks like deg/s; pass --units deg/s "
                         "(or gyr_units='deg/s') to convert, or --units rad/s if the sensor "
                         "really spun that fast")
    if gyr_units is None and dt_s is not None:
        check_gyro_units_in_motion(gyr, acc, dt_s, source)
    return gyr, acc


def check_gyro_units_in_motion(gyr, acc, dt_s, source: str = "input") -> None:
    """Refuse a gyro (as rad/s) that looks like deg/s from how it moves with the accelerometer
    over steps ``dt_s`` (s): the accelerometer direction turns as the gyro would in deg/s
    (:func:`looks_like_deg_s`), or while the accelerometer is still the gyro reads more than any
    turn-on bias (:func:`rest_rate_rad_s`). The messages name ``--units deg/s`` and the override
    ``--units rad/s``."""
    if looks_like_deg_s(gyr, acc, dt_s):
        raise InputError(f"{source}: the accelerometer direction turns as the gyro would in "
                         "deg/s, not rad/s; pass --units deg/s (or gyr_units='deg/s') to "
                         "convert, or --units rad/s to keep rad/s")
    rest = rest_rate_rad_s(gyr, acc, dt_s)
    if rest is not None and rest > MAX_REST_RATE_RAD_S:
        raise InputError(f"{source}: while the accelerometer is still the gyro reads "
                         f"{rest:.3g} rad/s, beyond any gyro's turn-on bias "
                         f"({MAX_REST_RATE_RAD_S:g} rad/s): this looks like deg/s; pass "
                         "--units deg/s (or gyr_units='deg/s') to convert, or --units rad/s "
                         "if the sensor really turned about the vertical")


def rest_rate_rad_s(gyr, acc, dt_s) -> float | None:
    """The gyro's reading at rest, which is its bias: the median of ``|mean ω|`` over the still
    stretches (windows of ``REST_WINDOW_S`` whose accelerometer varies by less than
    ``REST_ACC_STD_M_S2`` RMS per axis with a norm within ``REST_ACC_NORM_M_S2`` of g, whose gyro
    varies by less than ``REST_GYR_STD_RAD_S``, every sample finite); None when they last less
    than ``REST_MIN_S`` in all. The accelerometer decides what is still (the gyro only excludes
    turns), so a gyro in the wrong unit cannot hide its rest."""
    dts = np.broadcast_to(np.asarray(dt_s, dtype=np.float64), gyr.shape[:1])
    dt = float(np.nanmedian(dts)) if np.any(np.isfinite(dts)) else np.nan
    if not np.isfinite(dt) or dt <= 0:
        return None
    w = max(5, int(round(REST_WINDOW_S / dt)))
    nw = gyr.shape[0] // w
    if nw * w * dt < REST_MIN_S:
        return None
    g = gyr[:nw * w].reshape(nw, w, 3)
    a = acc[:nw * w].reshape(nw, w, 3)
    with np.errstate(over="ignore", invalid="ignore"):
        finite = np.all(np.isfinite(g), axis=(1, 2)) & np.all(np.isfinite(a), axis=(1, 2))
        a_std = np.sqrt(np.mean(np.var(a, axis=1), axis=1))
        a_norm = np.linalg.norm(np.mean(a, axis=1), axis=1)
        g_std = np.sqrt(np.mean(np.var(g, axis=1), axis=1))
        still = (finite & (a_std < REST_ACC_STD_M_S2) & (g_std < REST_GYR_STD_RAD_S)
                 & (np.abs(a_norm - G_M_S2) < REST_ACC_NORM_M_S2))
        if np.count_nonzero(still) * w * dt < REST_MIN_S:
            return None
        return float(np.median(np.linalg.norm(np.mean(g[still], axis=1), axis=1)))


def _direction_residual(gyr, acc, dt, starts, w, scale):
    """Median angle (rad) between the accelerometer direction after ``w`` samples and the one
    predicted by turning the initial direction with ``scale × gyr`` (u̇ = u × ω)."""
    u = acc[starts] / np.linalg.norm(acc[starts], axis=1, keepdims=True)
    for j in range(w):
        u = u + np.cross(u, scale * gyr[starts + j + 1]) * dt
        u = u / np.linalg.norm(u, axis=1, keepdims=True)
    v = acc[starts + w] / np.linalg.norm(acc[starts + w], axis=1, keepdims=True)
    return float(np.median(np.arccos(np.clip(np.sum(u * v, 1), -1.0, 1.0))))


def _scale_residuals(gyr, acc, dt_s, window_s: float, time_scale: float, scales):
    """:func:`_direction_residual` for each gyro scale of ``scales`` over the windows of
    ``window_s`` seconds (``time_scale`` × the median step each) where the accelerometer direction
    turns by more than 3°; None when there are fewer than 5 such windows."""
    dts = np.broadcast_to(np.asarray(dt_s, dtype=np.float64), gyr.shape[:1])
    dt = float(np.nanmedian(dts)) if np.any(np.isfinite(dts)) else np.nan
    n = gyr.shape[0]
    if not np.isfinite(dt) or dt <= 0:
        return None
    w = max(2, int(round(window_s / (dt * time_scale))))
    if n < 2 * w + 2:
        return None
    with np.errstate(over="ignore", invalid="ignore"):
        ok = (np.all(np.isfinite(gyr), 1) & np.all(np.isfinite(acc), 1)
              & (np.linalg.norm(acc, axis=1) > 0))
    starts = np.arange(0, n - w - 1, max(1, w // 2))
    good = np.array([ok[s:s + w + 1].all() for s in starts], dtype=bool)
    starts = starts[good]
    if starts.size == 0:
        return None
    a0 = acc[starts] / np.linalg.norm(acc[starts], axis=1, keepdims=True)
    a1 = acc[starts + w] / np.linalg.norm(acc[starts + w], axis=1, keepdims=True)
    turned = np.arccos(np.clip(np.sum(a0 * a1, 1), -1.0, 1.0)) > np.radians(3.0)
    starts = starts[turned]
    if starts.size < 5:
        return None
    return [_direction_residual(gyr, acc, dt, starts, w, scale) for scale in scales]


def looks_like_deg_s(gyr, acc, dt_s, window_s: float = 0.3) -> bool:
    """True when the accelerometer direction is explained much better by the gyro read as deg/s
    than as rad/s (model comparison over windows where the direction turns by > 3°)."""
    e = _scale_residuals(gyr, acc, dt_s, window_s, 1.0, (1.0, np.pi / 180.0))
    return e is not None and e[1] < 0.5 * e[0]


def looks_like_ms(gyr, acc, dt_s, window_s: float = 0.3) -> bool:
    """True when time steps ``dt_s`` read as seconds are milliseconds: the accelerometer direction
    is explained much better by the gyro turning it over ``dt / 1000`` than over ``dt`` (as rad/s
    or deg/s), over windows of ``window_s`` real seconds if the steps are ms."""
    e = _scale_residuals(gyr, acc, dt_s, window_s, 1e-3, (1e-3, 1.0, np.pi / 180.0))
    return e is not None and e[0] < 0.5 * min(e[1], e[2])


PIECE_ROWS = 2**18  # rows read and checked at a time ...
PIECE_CHARS = 2**26  # ... and at most this much of their text (rows of many columns)


class ImuPiece(NamedTuple):
    """Consecutive rows of an IMU file, read and checked (:func:`iter_imu_csv`): ``dt_s[k]`` the
    step from the row before (the first row of the file: the first piece's median step)."""

    t_s: np.ndarray
    gyr_rad_s: np.ndarray
    acc_m_s2: np.ndarray
    dt_s: np.ndarray
    t0_stamp: int | float | None
    time_unit: str


def read_imu_csv(path, *, gyr_units: str | None = None, acc_units: str | None = None,
                 columns: dict[str, str] | None = None, time_unit: str | None = None,
                 ) -> ImuRecording:
    """Read an IMU CSV: our header ``t,gyr_x,gyr_y,gyr_z,acc_x,acc_y,acc_z`` (column order free,
    extra columns ignored; empty or ``nan`` cells become NaN), an EuRoC / TUM-VI IMU file
    (recognized from its header), or any header with ``columns`` mapping our seven names to the
    file's.

    Header names are compared after stripping whitespace and a leading ``#``; a mapped name
    without a unit also finds a header name with a trailing bracketed unit (``timestamp`` finds
    ``timestamp [ns]``), unless another column has exactly that name. The time unit is
    ``time_unit`` (``s``, ``ms``, ``us``, ``ns``) or a unit in brackets on the time column's
    header (EuRoC: ``[ns]``); they must agree. Without either, times are seconds and a median step
    above 0.1 is refused. Times in ms, µs or ns give ``t_s`` relative to the first stamp, which is
    kept in ``t0_stamp`` (:func:`verticality.io.imu_layout.time_to_seconds`); times in seconds are
    kept as written. Gyro and accelerometer go through :func:`check_units` whatever the layout.
    The pieces of :func:`iter_imu_csv`, joined."""
    pieces = list(iter_imu_csv(path, gyr_units=gyr_units, acc_units=acc_units, columns=columns,
                               time_unit=time_unit))
    first = pieces[0]
    return ImuRecording(*(np.concatenate([getattr(p, f) for p in pieces])
                          for f in ("t_s", "gyr_rad_s", "acc_m_s2")),
                        first.t0_stamp, first.time_unit)


def iter_imu_csv(path, *, gyr_units: str | None = None, acc_units: str | None = None,
                 columns: dict[str, str] | None = None, time_unit: str | None = None,
                 piece_rows: int = PIECE_ROWS):
    """The rows of an IMU CSV (as :func:`read_imu_csv` reads them) as :class:`ImuPiece` values of
    at most ``piece_rows`` rows, each read and checked before it is given (time steps across the
    pieces too), so that a long file never sits in memory whole: a piece also ends at
    :data:`PIECE_CHARS` characters of text, and no line is read beyond
    :data:`verticality.io.lines.MAX_LINE_CHARS`. A refusal names its line (a line too long or
    not UTF-8 text among them; a ``#`` comment line is skipped whatever it holds)."""
    path = check_input_file(path)
    source = str(path)
    with text_lines.open_text(path) as fh:
        header = text_lines.header_line(fh, source).rstrip("\r\n")
        lay = layout.locate(header, columns, time_unit, source)
        line_no, prev = 1, None
        while True:
            rows, numbers, chars = [], [], 0
            while (line := text_lines.read_line(fh)) is not None:
                line_no += 1
                text = line.text.strip()
                if text and not text.startswith("#"):  # (a comment may be in any encoding)
                    rows.append(text_lines.check_line(line, source, line_no))
                    numbers.append(line_no)
                    chars += len(line.text)
                    if len(rows) >= piece_rows or chars >= PIECE_CHARS:
                        break
            if not rows:
                if prev is None:
                    raise InputError(f"{path}: no data rows")
                return
            piece, t_last_raw = _piece_from_rows(rows, numbers, lay, source, gyr_units, acc_units,
                                                 prev)
            prev = (t_last_raw, numbers[-1], piece.t0_stamp, float(piece.t_s[-1]))
            yield piece


def recording_from_rows(rows: list[str], line_numbers: list[int], lay: layout.Layout,
                        source: str = "input", gyr_units: str | None = None,
                        acc_units: str | None = None) -> ImuRecording:
    """The :class:`ImuRecording` of data rows (their 1-based ``line_numbers``, for messages) of a
    file with layout ``lay``, read and checked as :func:`read_imu_csv` reads a file.
    ``verticality stream`` reads its first second with it."""
    piece = _piece_from_rows(rows, line_numbers, lay, source, gyr_units, acc_units, None)[0]
    return ImuRecording(piece.t_s, piece.gyr_rad_s, piece.acc_m_s2, piece.t0_stamp,
                        piece.time_unit)


def _piece_from_rows(rows, line_numbers, lay, source, gyr_units, acc_units, prev):
    """``(ImuPiece, last raw stamp)`` of data rows: cells parsed (:func:`verticality.io.imu_rows.
    parse_clean_rows`, else :func:`~verticality.io.imu_rows.parse_rows`), time steps checked (from
    the previous piece's last stamp, ``prev = (raw stamp, line, t0_stamp, t_s)``, None for the
    first) and converted to seconds, units checked (:func:`check_units`)."""
    fast = imu_rows.parse_clean_rows(rows, lay)
    if fast is not None:
        data, t_raw = fast
    else:
        data, t_raw = imu_rows.parse_rows(rows, line_numbers, lay, source)
    unit = lay.time_unit or "s"
    if prev is None:
        layout.check_time_steps(t_raw, line_numbers, lay.time_unit, source, lay.time_label)
        t_s, t0 = layout.time_to_seconds(t_raw, unit)
        dt_s = dt_from_t(t_s)
    else:
        raw_prev, line_prev, t0, t_s_prev = prev
        if np.result_type(t_raw, np.asarray(raw_prev)) != t_raw.dtype:
            t_raw = t_raw.astype(np.float64)
        layout.check_time_steps(np.concatenate([[raw_prev], t_raw]).astype(t_raw.dtype),
                                [line_prev, *line_numbers], lay.time_unit, source, lay.time_label)
        t_s = layout.time_to_seconds(t_raw, unit, origin=t0)[0]
        dt_s = np.diff(t_s, prepend=t_s_prev)
    gyr = data[:, [lay.index[k] for k in ("gyr_x", "gyr_y", "gyr_z")]]
    acc = data[:, [lay.index[k] for k in ("acc_x", "acc_y", "acc_z")]]
    gyr, acc = check_units(gyr, acc, gyr_units=gyr_units, acc_units=acc_units, source=source)
    if lay.time_unit is None and looks_like_ms(gyr, acc, dt_s):  # first: the time is the ruler
        raise InputError(f"{source}: the accelerometer direction turns as the gyro would if the "
                         "time steps were ms, not s; pass --time-unit ms (or time_unit='ms') to "
                         "convert, or --time-unit s to keep seconds")
    if gyr_units is None:
        check_gyro_units_in_motion(gyr, acc, dt_s, source)
    return ImuPiece(t_s, gyr, acc, dt_s, t0, unit), t_raw[-1]


def write_imu_csv(path, rec: ImuRecording) -> Path:
    path = Path(path)
    data = np.column_stack([rec.t_s, rec.gyr_rad_s, rec.acc_m_s2])
    np.savetxt(path, data, delimiter=",", header=",".join(IMU_COLUMNS), comments="", fmt="%.17g")
    return path


def write_estimate_csv(path, t_s, out, tilt_sigma_rad=None) -> Path:
    """Write a :class:`verticality.tilt.TiltEstimate` (or any object with roll_rad,
    pitch_rad, up_S, bias_S_rad_s, flags) as ``t,roll_rad,pitch_rad,gx,gy,gz,bias_x,bias_y,bias_z,
    flags``; ``(gx, gy, gz)`` is the unit gravity direction (down) in the sensor frame. With
    ``tilt_sigma_rad`` (N,) a last column ``tilt_sigma_rad`` holds the tilt's standard deviation
    (``TiltEstimate.sigma_rad``); filters that report none (the peers) are written without it."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    sigma = tilt_sigma_rad is not None
    path.write_text(estimate_header(sigma) + "\n" + estimate_rows(t_s, out, tilt_sigma_rad),
                    encoding="utf-8")
    return path


def estimate_rows(t_s, out, tilt_sigma_rad=None) -> str:
    """The data rows of :func:`write_estimate_csv` as text (each ending in a newline)."""
    grav = -np.asarray(out.up_S)
    data = np.column_stack([np.asarray(t_s), np.asarray(out.roll_rad), np.asarray(out.pitch_rad),
                            grav, np.asarray(out.bias_S_rad_s)])
    if data.shape[0] == 0:
        return ""
    sigma = tilt_sigma_rad is not None
    flags = np.asarray(out.flags).astype(np.int64)
    fmt = estimate_row_format(sigma)
    cells = np.empty((data.shape[0], data.shape[1] + 1 + sigma),
                     dtype=object)  # Python floats and ints, one %-format per row
    cells[:, :data.shape[1]] = data
    cells[:, data.shape[1]] = flags
    if sigma:
        cells[:, -1] = np.asarray(tilt_sigma_rad, dtype=np.float64)
    return "\n".join(fmt % tuple(row) for row in cells.tolist()) + "\n"


def estimate_header(sigma: bool = False) -> str:
    """The estimate CSV's header line (without the newline); ``sigma``: with the σ column."""
    return ",".join(ESTIMATE_COLUMNS + ((SIGMA_COLUMN,) if sigma else ()))


def estimate_row_format(sigma: bool = False) -> str:
    """The %-format of one estimate row: ``t, roll, pitch, gx, gy, gz, bias (3)`` as ``%.17g``
    (every float64 round-trips), ``flags`` as ``%d``, then σ when ``sigma``."""
    return ",".join(["%.17g"] * 9) + ",%d" + (",%.17g" if sigma else "")


class EstimateTable(NamedTuple):
    t_s: np.ndarray
    roll_rad: np.ndarray
    pitch_rad: np.ndarray
    gravity_S: np.ndarray  # (N, 3)
    bias_S_rad_s: np.ndarray  # (N, 3)
    flags: np.ndarray  # (N,) int
    tilt_sigma_rad: np.ndarray | None = None  # (N,), None when the file has no such column


def read_estimate_csv(path) -> EstimateTable:
    """Read what :func:`write_estimate_csv` wrote (with or without the ``tilt_sigma_rad``
    column)."""
    path = Path(path)
    check_input_file(path)
    with text_lines.open_text(path) as fh:
        header = tuple(text_lines.header_line(fh, str(path)).strip().split(","))
    if header not in (ESTIMATE_COLUMNS, ESTIMATE_COLUMNS + (SIGMA_COLUMN,)):
        raise InputError(f"{path}: expected header {','.join(ESTIMATE_COLUMNS)}"
                         f"[,{SIGMA_COLUMN}]")
    data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    sigma = data[:, 10] if len(header) > len(ESTIMATE_COLUMNS) else None
    return EstimateTable(data[:, 0], data[:, 1], data[:, 2], data[:, 3:6], data[:, 6:9],
                         data[:, 9].astype(int), sigma)
