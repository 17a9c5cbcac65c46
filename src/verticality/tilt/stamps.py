"""Time stamps as the filter takes them: seconds. Numbers are seconds already; date-times (NumPy
``datetime64``, pandas ``DatetimeIndex`` / ``Timestamp`` / a ``datetime64`` Series, time-zone
aware or not, Python ``datetime``) become seconds since 1970-01-01 UTC (a naive date-time is
taken as UTC, as NumPy takes it), durations (``timedelta64``, pandas ``TimedeltaIndex`` /
``Timedelta``, Python ``timedelta``) seconds; the steps between date-times are taken from their
integer nanoseconds, exactly. Anything else (text, a missing stamp ``NaT``, objects) is refused in
one line, never read as a number it is not (nanoseconds read as seconds would make every step a
bad one). pandas is not needed: its objects are recognized by what they offer."""

from __future__ import annotations

import datetime as _dt
import math

import numpy as np

from verticality.core.errors import InputError

_EPOCH = _dt.datetime(1970, 1, 1)
_NAT = np.iinfo(np.int64).min


def _ns_array(values, kind: str) -> np.ndarray:
    """Date-times (``kind`` "M") or durations ("m") as int64 nanoseconds (UTC for a time zone)."""
    unit = "datetime64[ns]" if kind == "M" else "timedelta64[ns]"
    try:
        if hasattr(values, "to_numpy"):  # pandas: a time zone's stamps come out in UTC
            arr = values.to_numpy(dtype=unit)
        else:
            arr = np.asarray(values).astype(unit)
    except (TypeError, ValueError, OverflowError) as exc:
        raise InputError(f"t_s: date-times that do not convert to nanoseconds "
                         f"({' '.join(str(exc).split())[:80]})") from None
    return np.asarray(arr).view(np.int64)


def _object_ns(value) -> int | None:
    """One Python or pandas date-time or duration as integer nanoseconds (see the module); None
    for anything else."""
    for method in ("to_datetime64", "to_timedelta64"):  # pandas Timestamp / Timedelta
        if hasattr(value, method):
            value = getattr(value, method)()
            break
    if isinstance(value, np.datetime64 | np.timedelta64):
        unit = "datetime64[ns]" if isinstance(value, np.datetime64) else "timedelta64[ns]"
        ns = int(np.asarray(value).astype(unit).view(np.int64))
        if ns == _NAT:
            raise InputError("t_s: a missing time stamp (NaT); give every sample its time")
        return ns
    if isinstance(value, _dt.datetime):
        if value.tzinfo is not None:
            value = value.astimezone(_dt.UTC).replace(tzinfo=None)
        return (value - _EPOCH) // _dt.timedelta(microseconds=1) * 1000
    if isinstance(value, _dt.timedelta):
        return value // _dt.timedelta(microseconds=1) * 1000
    if isinstance(value, _dt.date):
        return (_dt.datetime(value.year, value.month, value.day) - _EPOCH).days * 86_400 * 10**9
    return None


def _object_seconds(value) -> float:
    """One time stamp of any kind as seconds (see the module)."""
    ns = _object_ns(value)
    if ns is not None:
        return ns / 1e9
    if isinstance(value, bool | np.bool_ | str | bytes):
        raise InputError(f"t_s: {value!r} is not a time; give seconds or date-times")
    try:
        return float(value)
    except (TypeError, ValueError):
        raise InputError(f"t_s: {type(value).__name__} {str(value)[:40]!r} is not a time; give "
                         "seconds or date-times") from None


def stamp_seconds(value) -> float:
    """One time stamp as seconds (see the module); not finite: refused."""
    t = value if type(value) is float else _object_seconds(value)
    if not math.isfinite(t):
        raise InputError(f"t_s must be a finite time in seconds; got {value!r}")
    return t


def stamps_seconds(t_s) -> tuple[np.ndarray, np.ndarray | None]:
    """``(seconds, ns)``: the time stamps ``t_s`` as float64 seconds, and for date-times or
    durations also their int64 nanoseconds (else None), from which steps are exact."""
    kind = getattr(getattr(t_s, "dtype", None), "kind", None)
    if kind not in ("M", "m"):
        arr = np.asarray(t_s)
        kind = arr.dtype.kind
        t_s = arr
    if kind in ("M", "m"):
        ns = _ns_array(t_s, kind).reshape(-1) if np.ndim(t_s) else _ns_array(t_s, kind)
        bad = ns == _NAT
        if np.any(bad):
            raise InputError(f"t_s holds {int(np.sum(bad))} missing time stamp(s) (NaT; first at "
                             f"index {int(np.flatnonzero(bad)[0])}); give every sample its time")
        return ns / 1e9, ns
    if kind == "O":
        flat = np.asarray(t_s).reshape(-1)
        ns = [_object_ns(v) for v in flat]
        if flat.size and all(v is not None for v in ns):  # date-times: their steps exact
            ns_arr = np.array(ns, dtype=np.int64).reshape(np.shape(t_s))
            return ns_arr / 1e9, ns_arr
        return np.array([_object_seconds(v) for v in flat],
                        dtype=np.float64).reshape(np.shape(t_s)), None
    if kind in ("U", "S", "b", "V"):
        raise InputError(f"t_s: time stamps of type {np.asarray(t_s).dtype} are not times; give "
                         "numbers (seconds) or date-times")
    try:
        return np.asarray(t_s, dtype=np.float64), None
    except (TypeError, ValueError) as exc:
        raise InputError(f"t_s: not numbers ({str(exc)[:60]}); give seconds or date-times"
                         ) from None


def steps_from_ns(ns: np.ndarray) -> np.ndarray:
    """The steps (s) between integer-nanosecond stamps, exact; the first one the median step (as
    :func:`verticality.io.imu.dt_from_t` takes it)."""
    if ns.size < 2:
        return np.full(ns.shape, np.nan)
    d = np.diff(ns).astype(np.float64) / 1e9
    return np.concatenate([[np.median(d)], d])
