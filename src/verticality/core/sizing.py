"""Work sized before it is allocated: a command that would need more memory than
:data:`MAX_WORK_BYTES` (``motion --rate 1e9``, a time stamp that jumps by 10⁶ s, a stiff model
over a long recording) is refused with the size and what to change, instead of dying with a
MemoryError (or the operating system's out-of-memory kill) after minutes of work."""

from __future__ import annotations

from verticality.core.errors import InputError

MAX_WORK_BYTES = 2 * 2**30  # 2 GiB: fits a laptop beside everything else


def check_work_size(count: float, bytes_each: float, what: str, advice: str,
                    limit_bytes: float | None = None) -> float:
    """Refuse ``count`` items of ``bytes_each`` bytes when they exceed ``limit_bytes`` (default
    :data:`MAX_WORK_BYTES`): ``what`` names the items (e.g. ``"rows of 1e9 Hz over 10 s"``),
    ``advice`` the option to change (e.g. ``"lower --rate or --duration"``). Returns the size in
    bytes (to be shown)."""
    limit = MAX_WORK_BYTES if limit_bytes is None else float(limit_bytes)
    size = float(count) * float(bytes_each)
    if not size <= limit:  # also NaN
        raise InputError(f"this needs {float(count):.3g} {what} (~{size / 2**30:.3g} GiB, "
                         f"more than the {limit / 2**30:g} GiB allowed): {advice}")
    return size
