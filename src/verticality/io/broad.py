"""BROAD recordings (HDF5) and the official BROAD inclination metric.

BROAD: D. Laidig, M. Caruso, A. Cereatti, T. Seel, "BROAD — A Benchmark for Robust Inertial
Orientation Estimation", Data 2021, 6(7), 72 (CC BY 4.0). Each file holds ``imu_gyr`` (N,3) rad/s,
``imu_acc`` (N,3) m/s², ``imu_mag`` (N,3) µT in the sensor frame; ``opt_quat`` (N,4) scalar-first
orientation of the IMU w.r.t. an East-North-Up frame (NaN rows during optical dropouts);
``opt_pos`` (N,3) m; ``movement`` (N,) bool; attribute ``sampling_rate`` in Hz.

Official metric (BROAD example code): error quaternion ``e = q_est ⊗ q_opt⁻¹``; inclination error
``2·arccos(sqrt(e_w² + e_z²))``; RMS over the samples with ``movement`` true (NaN rows skipped).
The heading of the estimate does not enter (a rotation of ``q_est`` about the vertical leaves
``e_w² + e_z²`` unchanged), so 6D estimates need no heading alignment.
"""

from __future__ import annotations

from pathlib import Path
from typing import NamedTuple

import numpy as np

from verticality.core import so3
from verticality.core.errors import InputError
from verticality.io.paths import check_input_file


class BroadTrial(NamedTuple):
    name: str
    gyr_rad_s: np.ndarray  # (N, 3)
    acc_m_s2: np.ndarray  # (N, 3)
    mag_uT: np.ndarray | None  # (N, 3) or None
    quat_E_S_opt: np.ndarray  # (N, 4) wxyz, NaN rows during dropouts
    movement: np.ndarray  # (N,) bool
    sampling_rate_hz: float

    @property
    def dt_s(self) -> float:
        return 1.0 / self.sampling_rate_hz

    @property
    def t_s(self) -> np.ndarray:
        return np.arange(self.gyr_rad_s.shape[0]) / self.sampling_rate_hz


def is_broad_file(path: Path) -> bool:
    """True when ``path`` is an HDF5 file (by signature), whatever its extension."""
    try:
        with open(path, "rb") as fh:
            return fh.read(8) == b"\x89HDF\r\n\x1a\n"
    except OSError:
        return False


def load_trial(path) -> BroadTrial:
    """Read one BROAD-layout HDF5 file; missing datasets raise :class:`InputError`."""
    import h5py

    path = Path(path)
    check_input_file(path)
    try:
        f = h5py.File(path, "r")
    except OSError as exc:
        raise InputError(f"{path}: not a readable HDF5 file ({exc})") from None
    try:
        with f:
            return _read_trial(f, path)
    except InputError:
        raise
    except (KeyError, OSError, RuntimeError, ValueError, TypeError, AttributeError) as exc:
        # the file opens but an object in it does not (a damaged object header, a truncated
        # dataset): h5py raises KeyError or OSError naming the HDF5 library's reason
        reason = " ".join(str(exc).split())[:120]
        raise InputError(f"{path}: a damaged HDF5 file (opens, but {reason or type(exc).__name__})"
                         ) from None


def _read_trial(f, path: Path) -> BroadTrial:
    """:func:`load_trial` on the open HDF5 file ``f``."""
    missing = [k for k in ("imu_gyr", "imu_acc") if k not in f]
    if missing:
        raise InputError(f"{path}: missing dataset(s) {', '.join(missing)} (BROAD layout expected)")
    check_declared_sizes(f, path)  # from the file's metadata, before anything is read
    gyr = _dataset(f, "imu_gyr", path)
    acc = _dataset(f, "imu_acc", path)
    n = gyr.shape[0]
    mag = _dataset(f, "imu_mag", path) if "imu_mag" in f else None
    quat = (_dataset(f, "opt_quat", path) if "opt_quat" in f
            else np.full((n, 4), np.nan))
    movement = (_dataset(f, "movement", path, bool) if "movement" in f
                else np.ones(n, dtype=bool))
    if "sampling_rate" not in f.attrs:
        raise InputError(f"{path}: attribute sampling_rate is missing (BROAD layout expected)")
    rate = sampling_rate_hz(f.attrs["sampling_rate"], path)
    return BroadTrial(path.stem, gyr, acc, mag, quat, movement, rate)


# the datasets of a trial, their columns, and the bytes each row of them takes once read
SHAPES = {"imu_gyr": 3, "imu_acc": 3, "imu_mag": 3, "opt_quat": 4, "movement": None}


def check_declared_sizes(f, path) -> int:
    """The number of samples N of the open HDF5 file ``f``, every dataset's shape checked as the
    file declares it, before any is read: ``imu_gyr`` and ``imu_acc`` (N, 3), ``imu_mag``
    (N, 3), ``opt_quat`` (N, 4), ``movement`` (N,); and the trial, read whole as float64 (and the
    filter's output beside it), within :data:`verticality.core.sizing.MAX_WORK_BYTES`: a file that
    declares 10¹² rows is refused in one line, not read into a MemoryError."""
    from verticality.core.sizing import check_work_size

    shapes = {}
    for name in SHAPES:
        if name not in f:
            continue
        obj = f[name]
        shape = getattr(obj, "shape", None)
        if shape is None:  # a group, a link to nothing
            raise InputError(f"{path}: {name} is not a dataset")
        shapes[name] = tuple(int(v) for v in shape)
    n = shapes["imu_gyr"][0] if shapes["imu_gyr"] else 0
    for name, cols in SHAPES.items():
        want = (n,) if cols is None else (n, cols)
        if name in shapes and shapes[name] != want:
            raise InputError(f"{path}: dataset {name} has shape {shapes[name]}; a trial of "
                             f"{n} samples needs {want} (imu_gyr and imu_acc (N, 3), imu_mag "
                             "(N, 3), opt_quat (N, 4), movement (N,))")
    # per sample: the datasets as float64 (the quaternions filled in when absent) and the
    # filter's output and variances beside them
    check_work_size(n, 8 * (3 + 3 + 3 + 4 + 1) + BYTES_OUT_PER_SAMPLE,
                    f"samples declared by {path}", "this recording is too large to read at once")
    return n


BYTES_OUT_PER_SAMPLE = 8 * (1 + 2 + 3 + 4 + 3 + 1 + 10) + 8  # t, angles, up, q, bias, σ, var, …


def _dataset(f, name: str, path, dtype=np.float64) -> np.ndarray:
    """Dataset ``name`` of the open HDF5 file ``f`` as an array of ``dtype``; one that does not
    convert (text, a compound type, a group) is refused naming it."""
    try:
        return np.asarray(f[name], dtype=dtype)
    except (TypeError, ValueError, OSError, AttributeError) as exc:
        raise InputError(f"{path}: dataset {name} is not numeric ({str(exc)[:60]})") from None


def sampling_rate_hz(value, source="input") -> float:
    """The ``sampling_rate`` attribute as a positive number of Hz: one number (or a one-element
    array, or its text); anything else (empty, text that is not a number, several values, not
    finite, not positive) is refused naming the value."""
    arr = np.asarray(value)
    if arr.size != 1:
        raise InputError(f"{source}: sampling_rate must be one positive number (Hz), got "
                         f"{arr.size} values")
    item = arr.reshape(-1)[0]
    if isinstance(item, bytes):
        item = item.decode("utf-8", "replace")
    try:
        rate = float(item)
    except (TypeError, ValueError):
        raise InputError(f"{source}: sampling_rate must be a positive number (Hz), got "
                         f"{str(item)[:40]!r}") from None
    if not (np.isfinite(rate) and rate > 0):
        raise InputError(f"{source}: sampling_rate must be a positive number (Hz), got {rate}")
    return rate


def list_trials(directory) -> list[Path]:
    """The ``*.hdf5`` / ``*.h5`` files of a BROAD folder, sorted by name."""
    directory = Path(directory)
    if not directory.is_dir():
        raise InputError(f"{directory}: not a directory (expected a folder of BROAD .hdf5 files)")
    files = sorted(p for p in directory.iterdir() if p.suffix.lower() in (".hdf5", ".h5"))
    if not files:
        raise InputError(f"{directory}: no .hdf5 files found")
    return files


def inclination_error_deg(quat_est_wxyz, quat_ref_wxyz) -> np.ndarray:
    """Official BROAD inclination error per sample (deg): ``e = q_est ⊗ q_ref⁻¹``,
    ``2·arccos(sqrt(e_w² + e_z²))``. Quaternions are normalized first; NaN rows give NaN."""
    qe = np.asarray(quat_est_wxyz, dtype=np.float64)
    qr = np.asarray(quat_ref_wxyz, dtype=np.float64)
    qe = qe / np.linalg.norm(qe, axis=-1, keepdims=True)
    qr = qr / np.linalg.norm(qr, axis=-1, keepdims=True)
    qr_inv = np.asarray(so3.quat_conjugate(qr))  # the inverse of a unit quaternion
    e = np.stack(so3.quat_multiply_components(tuple(np.moveaxis(qe, -1, 0)),
                                              tuple(np.moveaxis(qr_inv, -1, 0))), axis=-1)
    c = np.sqrt(e[..., 0] ** 2 + e[..., 3] ** 2)
    return np.degrees(2.0 * np.arccos(np.clip(c, -1.0, 1.0)))


def inclination_rmse_deg(quat_est_wxyz, trial: BroadTrial) -> float:
    """RMS of :func:`inclination_error_deg` over ``movement`` samples with a valid reference."""
    err = inclination_error_deg(quat_est_wxyz, trial.quat_E_S_opt)
    sel = trial.movement & np.isfinite(err)
    if not np.any(sel):
        raise InputError(f"{trial.name}: no movement samples with a valid optical reference")
    return float(np.sqrt(np.mean(err[sel] ** 2)))
