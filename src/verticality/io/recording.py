"""An IMU recording from a file, whatever its format: an IMU CSV (our layout, EuRoC / TUM-VI, or
any header with a column mapping; :func:`verticality.io.imu.read_imu_csv`) or a BROAD-layout HDF5
file (:func:`verticality.io.broad.load_trial`), with the unit checks of
:func:`verticality.io.imu.check_units`. What ``verticality estimate`` reads.
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path
from typing import NamedTuple

import numpy as np

from verticality.core.errors import InputError
from verticality.io import broad, imu, imu_layout
from verticality.io.paths import check_input_file


class ImuInput(NamedTuple):
    t_s: np.ndarray  # (N,)
    gyr_rad_s: np.ndarray  # (N, 3)
    acc_m_s2: np.ndarray  # (N, 3)
    dt_s: np.ndarray  # (N,) dt[k] = t[k] − t[k−1], the first one the median step
    t_origin: str | None  # e.g. "1403636579758555392 ns" when t_s is relative to that stamp


def parse_units(units: Iterable[str]) -> tuple[str | None, str | None]:
    """``(gyr_units, acc_units)`` from a list of unit names (the CLI's ``--units deg/s g``), each
    a gyro unit (:data:`verticality.io.imu.GYR_UNITS`) or an accelerometer unit
    (:data:`~verticality.io.imu.ACC_UNITS`); None for a sensor whose unit is not given."""
    gyr_u = acc_u = None
    for u in units:
        if u in imu.GYR_UNITS:
            gyr_u = u
        elif u in imu.ACC_UNITS:
            acc_u = u
        else:
            raise InputError(f"unknown unit {u!r}; use {', '.join(imu.GYR_UNITS)} for the gyro "
                             f"and {', '.join(imu.ACC_UNITS)} for the accelerometer")
    return gyr_u, acc_u


def load_imu(path, units: Iterable[str] = (), columns: str | dict[str, str] | None = None,
             time_unit: str | None = None) -> ImuInput:
    """Time, gyro, accelerometer and steps of the recording in ``path``: a BROAD HDF5 file (told
    by its signature, whatever its extension) or an IMU CSV. ``units`` as for
    :func:`parse_units`; ``columns`` (the ``--columns`` text ``t=NAME,...`` or a mapping) and
    ``time_unit`` describe CSV files only and are refused with an HDF5 file. A CSV needs at least
    two rows (a time step)."""
    path = Path(path)
    check_input_file(path)
    gyr_u, acc_u = parse_units(units)
    if broad.is_broad_file(path):
        given = [o for o, v in (("--columns", columns), ("--time-unit", time_unit))
                 if v is not None]
        if given:
            verb = "apply" if len(given) > 1 else "applies"
            raise InputError(f"{path}: {' and '.join(given)} {verb} to CSV input only, not to a "
                             "BROAD HDF5 file")
        trial = broad.load_trial(path)
        gyr, acc = imu.check_units(trial.gyr_rad_s, trial.acc_m_s2, gyr_units=gyr_u,
                                   acc_units=acc_u, source=str(path), dt_s=trial.dt_s)
        t = trial.t_s
        return ImuInput(t, gyr, acc, np.full(t.shape, trial.dt_s), None)
    mapping = imu_layout.parse_columns_spec(columns) if isinstance(columns, str) else columns
    rec = imu.read_imu_csv(path, gyr_units=gyr_u, acc_units=acc_u, columns=mapping,
                           time_unit=time_unit)
    if rec.t_s.size < 2:
        raise InputError(f"{path}: one data row; the filter needs at least two (a time step)")
    origin = None if rec.t0_stamp is None else f"{rec.t0_stamp} {rec.time_unit}"
    return ImuInput(rec.t_s, rec.gyr_rad_s, rec.acc_m_s2, rec.dt_s, origin)
