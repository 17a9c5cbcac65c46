"""Head-motion files (MOTION.csv) in; otolith responses and head-tilt estimates out.

MOTION.csv: a header row, then one row per sample with the columns

    t            s, strictly increasing
    qw,qx,qy,qz  q_I_H, scalar first (rotates head vectors into frame I), unit norm
    wx,wy,wz     head angular velocity w.r.t. I, head frame, rad/s
    ax,ay,az     linear acceleration of the head centre in frame I, m/s², gravity NOT included

Other columns are ignored; column order is free. A bad file raises
:class:`verticality.core.errors.InputError` with one line naming the line number and column.

OUT.csv: ``t,sx,sy,sz,phi_x,phi_y`` (s_H: unit vector from pivot to mass, head frame; the otolith
angles of F 2.8–2.9, rad); for several pendulums the same columns with a suffix per pendulum
(``_left``, ``_right`` for the lateral model).

``verticality stabilize`` reads a MOTION.csv as the *trunk's* motion (the head's when it is rigid
on the trunk) and writes ``t`` and ``{fixed,stabilized}_{tilt_x_true_deg, tilt_y_true_deg,
tilt_x_est_deg, tilt_y_est_deg, tilt_error_deg}`` (:func:`write_tilt_comparison_csv`).
"""

from __future__ import annotations

import csv
import math
from pathlib import Path
from typing import NamedTuple

import numpy as np

from verticality.core.errors import InputError

MOTION_COLUMNS = ("t", "qw", "qx", "qy", "qz", "wx", "wy", "wz", "ax", "ay", "az")
QUATERNION_NORM_TOL = 1e-3
"""|‖q‖ − 1| above this is refused (rounding to 6 significant digits stays far below it)."""


class MotionRecord(NamedTuple):
    t_s: np.ndarray  # (N,)
    q_I_H_wxyz: np.ndarray  # (N, 4), normalized
    omega_H_rad_s: np.ndarray  # (N, 3)
    a_I_m_s2: np.ndarray  # (N, 3)


CHUNK_ROWS = 65536  # rows parsed into an array at a time


def read_motion_csv(path) -> MotionRecord:
    """Read and validate a MOTION.csv. Errors name the data row (from 1) and the file line (the
    header is line 1) and the column. Lines are read with a bound
    (:mod:`verticality.io.lines`: one too long or not UTF-8 text is refused naming it), the rows
    kept as arrays a chunk at a time, and a file whose rows would need more memory than
    :data:`verticality.core.sizing.MAX_WORK_BYTES` is refused as it is read."""
    from verticality.core.sizing import check_work_size
    from verticality.io import lines as text_lines
    from verticality.io.paths import check_input_file

    path = check_input_file(path)
    try:
        fh = text_lines.open_text(path)
    except OSError as exc:
        raise InputError(f"cannot read {path}: {exc.strerror}") from None

    def texts():  # every line, read with a bound and checked
        for line_no, line in enumerate(text_lines.lines(fh), start=1):
            yield text_lines.check_line(line, str(path), line_no)

    with fh:
        reader = csv.reader(texts())
        try:
            header = next(reader)
        except StopIteration:
            raise InputError(f"{path}: empty file (expected a header row)") from None
        except csv.Error as exc:
            raise InputError(f"{path}: line 1: {exc}") from None
        names = [h.strip() for h in header]
        missing = [c for c in MOTION_COLUMNS if c not in names]
        if missing:
            raise InputError(f"{path}: missing column(s) {', '.join(missing)} in the header "
                             f"(line 1); expected {','.join(MOTION_COLUMNS)}")
        index = {c: names.index(c) for c in MOTION_COLUMNS}
        rows, chunks, line_chunks, n_rows = [], [], [], 0
        try:
            for line_no, row in enumerate(reader, start=2):
                if not row or all(not cell.strip() for cell in row):
                    continue  # blank line
                values = []
                for c in MOTION_COLUMNS:
                    j = index[c]
                    if j >= len(row) or not row[j].strip():
                        raise InputError(f"{path}: {_where(line_no)}, column {c}: missing value")
                    cell = row[j].strip()
                    try:
                        v = float(cell)
                    except ValueError:
                        raise InputError(
                            f"{path}: {_where(line_no)}, column {c}: not a number: "
                            f"{cell[:40]!r}") from None
                    if not math.isfinite(v):
                        raise InputError(f"{path}: {_where(line_no)}, column {c}: "
                                         f"{cell[:40]} is not finite")
                    values.append(v)
                rows.append((line_no, values))
                if len(rows) == CHUNK_ROWS:
                    n_rows += len(rows)
                    # the chunks, and their copy when joined
                    check_work_size(n_rows, 2 * 8 * (1 + len(MOTION_COLUMNS)),
                                    f"rows of {path}", "split the recording")
                    line_chunks.append(np.array([r[0] for r in rows]))
                    chunks.append(np.array([r[1] for r in rows], dtype=float))
                    rows = []
        except csv.Error as exc:
            raise InputError(f"{path}: line {reader.line_num}: {exc}") from None
    if rows:
        line_chunks.append(np.array([r[0] for r in rows]))
        chunks.append(np.array([r[1] for r in rows], dtype=float))
    if not chunks:
        raise InputError(f"{path}: no data rows after the header")
    lines = np.concatenate(line_chunks)
    data = np.concatenate(chunks)
    t = data[:, 0]
    bad = np.nonzero(np.diff(t) <= 0.0)[0]
    if bad.size:
        i = bad[0] + 1
        raise InputError(f"{path}: {_where(lines[i])}, column t: "
                         f"time {float(t[i])!r} does not increase "
                         f"(previous row has t = {float(t[i - 1])!r})")
    q = data[:, 1:5]
    norm = np.linalg.norm(q, axis=1)
    bad = np.nonzero(np.abs(norm - 1.0) > QUATERNION_NORM_TOL)[0]
    if bad.size:
        i = bad[0]
        raise InputError(f"{path}: {_where(lines[i])}, columns qw,qx,qy,qz: quaternion norm "
                         f"{norm[i]:.6g} is not 1 (tolerance {QUATERNION_NORM_TOL:g})")
    return MotionRecord(t, q / norm[:, None], data[:, 5:8], data[:, 8:11])


def window_mask(t_s: np.ndarray, start_s: float = 0.0, duration_s: float | None = None,
                source: str = "input", end_tol_s: float = 1e-9) -> np.ndarray:
    """The rows of the times ``t_s`` from ``start_s`` to ``start_s + duration_s`` seconds after the
    first (to the last when ``duration_s`` is None), as a boolean mask. A negative start, a
    non-positive duration, a window ending more than ``end_tol_s`` after the last time, and one
    holding fewer than two rows are refused (:class:`InputError`)."""
    t = np.asarray(t_s, float)
    if not (math.isfinite(start_s) and start_s >= 0.0):
        raise InputError(f"{source}: --start must be a non-negative number of seconds, "
                         f"not {start_s}")
    if duration_s is not None and not (math.isfinite(duration_s) and duration_s > 0.0):
        raise InputError(f"{source}: --duration must be a positive number of seconds, "
                         f"not {duration_s}")
    span = float(t[-1] - t[0])
    t_from = t[0] + start_s
    t_to = t[-1] if duration_s is None else t_from + duration_s
    if t_to > t[-1] + 1e-9 * max(1.0, abs(float(t[-1]))) + end_tol_s:
        raise InputError(f"{source}: the window {start_s:g} s + {duration_s:g} s ends after the "
                         f"recording ({span:.6g} s from its first row)")
    sel = (t >= t_from - 1e-9) & (t <= t_to + 1e-9)
    if np.count_nonzero(sel) < 2:
        raise InputError(f"{source}: the window from {start_s:g} s holds fewer than two rows "
                         f"(the recording spans {span:.6g} s)")
    return sel


def window(record: MotionRecord, start_s: float = 0.0, duration_s: float | None = None,
           source: str = "input") -> MotionRecord:
    """The rows of ``record`` in the :func:`window_mask` window, on the file's own clock."""
    sel = window_mask(record.t_s, start_s, duration_s, source)
    return MotionRecord(*(a[sel] for a in record))


def from_broad_trial(trial, start_s: float = 0.0, duration_s: float | None = None):
    """A BROAD trial's rigid motion as a :class:`MotionRecord` (MOTION.csv rows),
    over ``[start_s, start_s + duration_s]`` (to the end when ``duration_s`` is None):
    q = ``opt_quat`` (ENU is our frame I: z up), ω = ``imu_gyr`` (measured, with its bias and
    noise), a_I = R_I_S·``imu_acc`` + (0, 0, −g) (the specific force rotated into I, gravity
    removed). Rows without an optical reference are not filled in: a window that holds one raises
    :class:`InputError` naming it and the longest clean stretch of the trial."""
    from verticality.core import so3
    from verticality.core.constants import G_M_S2

    t = trial.t_s
    sel = window_mask(t, start_s, duration_s, trial.name, end_tol_s=0.5 / trial.sampling_rate_hz)
    q = trial.quat_E_S_opt[sel]
    ok = np.all(np.isfinite(q), axis=1)
    if not np.all(ok):
        first = np.nonzero(~ok)[0][0]
        a, b = _longest_valid_stretch(np.all(np.isfinite(trial.quat_E_S_opt), axis=1))
        raise InputError(
            f"{trial.name}: no optical reference (opt_quat NaN) at t = {t[sel][first]:.3f} s, "
            f"inside the window; the longest stretch with one is {t[a]:.3f}–{t[b - 1]:.3f} s "
            f"(choose a window inside it)")
    q = q / np.linalg.norm(q, axis=1, keepdims=True)
    R = np.asarray(so3.matrix_from_quat(q))
    a_I = np.einsum("nij,nj->ni", R, trial.acc_m_s2[sel]) - np.array([0.0, 0.0, G_M_S2])
    return MotionRecord(t[sel], q, trial.gyr_rad_s[sel], a_I)


def _longest_valid_stretch(valid: np.ndarray) -> tuple[int, int]:
    """[a, b) of the longest run of True in ``valid`` ((0, 0) when there is none)."""
    edges = np.diff(np.concatenate([[0], valid.astype(np.int8), [0]]))
    starts, stops = np.nonzero(edges == 1)[0], np.nonzero(edges == -1)[0]
    if starts.size == 0:
        return 0, 0
    k = int(np.argmax(stops - starts))
    return int(starts[k]), int(stops[k])


def broad_motion(path, start_s: float = 0.0, duration_s: float | None = None):
    """A BROAD-layout recording's window as MOTION.csv rows (:func:`from_broad_trial`), and a
    description of them; a file that is not one raises :class:`InputError`."""
    from verticality.io import broad

    path = Path(path)
    if not broad.is_broad_file(path):
        raise InputError(f"{path}: not an HDF5 file (a recording must be in the BROAD layout: "
                         "imu_gyr, imu_acc, opt_quat, sampling_rate)")
    trial = broad.load_trial(path)
    rec = from_broad_trial(trial, start_s, duration_s)
    span = rec.t_s[-1] - rec.t_s[0]
    return rec, (f"{path.name} ({span:.3f} s from {rec.t_s[0]:.3f} s at "
                 f"{trial.sampling_rate_hz:g} Hz)")


def load_motion(path, start_s: float = 0.0, duration_s: float | None = None) -> MotionRecord:
    """A MOTION.csv, or a BROAD-layout HDF5 recording converted by
    :func:`from_broad_trial`, over a window in seconds from its start."""
    from verticality.io import broad

    path = Path(path)
    if broad.is_broad_file(path):
        return from_broad_trial(broad.load_trial(path), start_s, duration_s)
    return window(read_motion_csv(path), start_s, duration_s, str(path))


def _where(line_no) -> str:
    """'row k (line n)': data rows count from 1, lines from the header (line 1)."""
    return f"row {int(line_no) - 1} (line {int(line_no)})"


def write_motion_csv(path, record: MotionRecord) -> Path:
    """Write a MOTION.csv (17 significant digits: the file reads back exactly)."""
    path = Path(path)
    data = np.column_stack([record.t_s, record.q_I_H_wxyz, record.omega_H_rad_s, record.a_I_m_s2])
    _write(path, list(MOTION_COLUMNS), data)
    return path


def otolith_columns(suffixes=("",)) -> list[str]:
    cols = ["t"]
    for sfx in suffixes:
        cols += [f"{c}{sfx}" for c in ("sx", "sy", "sz", "phi_x", "phi_y")]
    return cols


def write_otolith_csv(path, t_s, s_H, phi_rad, suffixes=("",)) -> Path:
    """Write OUT.csv. ``s_H`` (N, P, 3), ``phi_rad`` (N, P, 2) for P pendulums named by
    ``suffixes``."""
    path = Path(path)
    s_H = np.asarray(s_H, float)
    phi = np.asarray(phi_rad, float)
    blocks = [np.asarray(t_s, float)[:, None]]
    for k in range(len(suffixes)):
        blocks += [s_H[:, k, :], phi[:, k, :]]
    _write(path, otolith_columns(suffixes), np.concatenate(blocks, axis=1))
    return path


TILT_QUANTITIES = ("tilt_x_true_deg", "tilt_y_true_deg", "tilt_x_est_deg", "tilt_y_est_deg",
                   "tilt_error_deg")


def write_tilt_comparison_csv(path, t_s, series: dict) -> Path:
    """Write ``t`` and, per condition of ``series`` ({condition: {"tilt_true_deg" (N, 2),
    "tilt_est_deg" (N, 2), "tilt_error_deg" (N,)}}), the columns ``{condition}_{quantity}`` for the
    quantities of :data:`TILT_QUANTITIES` (θx, θy of P13 Fig. 2; the error is the angle between the
    true and estimated up directions)."""
    path = Path(path)
    header, blocks = ["t"], [np.asarray(t_s, float)[:, None]]
    for cond, s in series.items():
        header += [f"{cond}_{q}" for q in TILT_QUANTITIES]
        blocks += [np.asarray(s["tilt_true_deg"], float), np.asarray(s["tilt_est_deg"], float),
                   np.asarray(s["tilt_error_deg"], float)[:, None]]
    _write(path, header, np.concatenate(blocks, axis=1))
    return path


def write_columns_csv(path, columns: dict) -> Path:
    """Write ``{name: (N,) array}`` as a CSV with those column names, floats written exactly."""
    path = Path(path)
    _write(path, list(columns), np.stack([np.asarray(v, float) for v in columns.values()], axis=1))
    return path


def read_otolith_csv(path) -> dict[str, np.ndarray]:
    """OUT.csv back as {column: array} (for tests and scripts)."""
    with Path(path).open(newline="", encoding="utf-8-sig") as fh:
        reader = csv.reader(fh)
        header = next(reader)
        data = np.array([[float(v) for v in row] for row in reader if row], dtype=float)
    return {name: data[:, j] for j, name in enumerate(header)}


def _write(path: Path, header: list[str], data: np.ndarray) -> None:
    """The CSV through :func:`verticality.io.paths.write_atomic` (complete or not there, never
    through a link, its permissions kept)."""
    from verticality.io.paths import write_atomic

    def write(tmp: Path) -> None:
        with tmp.open("w", newline="") as fh:
            fh.write(",".join(header) + "\n")
            # repr: the shortest text that reads back to the same float64
            fh.writelines(",".join(map(repr, row)) + "\n" for row in data.tolist())

    try:
        write_atomic(path, write)
    except OSError as exc:
        raise InputError(f"cannot write {path}: {exc.strerror}") from None
