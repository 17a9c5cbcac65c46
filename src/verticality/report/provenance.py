"""Where a set of results comes from: package and library versions, git commit, machine, date, mode.

:func:`collect` is called once by ``verticality reproduce`` and its dict stored in ``results.json``
under ``"provenance"``, so that a report rebuilt later still says how the numbers were made.
"""

from __future__ import annotations

import datetime as _dt
import os
import platform
import subprocess
from importlib import metadata
from pathlib import Path
from typing import Any

#: Libraries whose versions can change a number; reported in this order.
LIBRARIES = ("jax", "jaxlib", "numpy", "scipy", "matplotlib", "control", "sympy")


def library_versions(names: tuple[str, ...] = LIBRARIES) -> dict[str, str | None]:
    """Installed version of each distribution in ``names`` (None when it is not installed)."""
    out: dict[str, str | None] = {}
    for name in names:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = None
    return out


def git_commit(path: Path | None = None) -> dict[str, Any] | None:
    """``{"commit", "dirty"}`` of the git work tree holding ``path`` (default: this package's
    source), or None when it is not in a work tree or git is not installed."""
    where = Path(path) if path is not None else Path(__file__).resolve().parent
    try:
        head = subprocess.run(["git", "-C", str(where), "rev-parse", "HEAD"], capture_output=True,
                              text=True, timeout=10, check=False)
        if head.returncode != 0:
            return None
        status = subprocess.run(["git", "-C", str(where), "status", "--porcelain",
                                 "--untracked-files=no"], capture_output=True, text=True,
                                timeout=10, check=False)
    except (OSError, subprocess.SubprocessError):
        return None
    return {"commit": head.stdout.strip(),
            "dirty": bool(status.stdout.strip()) if status.returncode == 0 else None}


def machine() -> dict[str, Any]:
    """The computer the numbers were made on (no host name)."""
    return {"system": platform.system(), "release": platform.release(),
            "machine": platform.machine(), "processor": platform.processor() or None,
            "cpus": os.cpu_count(), "python": platform.python_version()}


def jax_backend() -> str | None:
    """JAX's default backend (``cpu``, ``gpu``, …), None when JAX cannot be imported."""
    try:
        import jax
    except ImportError:
        return None
    return jax.default_backend()


def collect(*, quick: bool, names: list[str] | None = None,
            now: _dt.datetime | None = None) -> dict[str, Any]:
    """The provenance record of one ``reproduce`` run (plain JSON)."""
    from verticality import __version__

    when = now if now is not None else _dt.datetime.now(_dt.UTC)
    return {
        "package": "verticality",
        "version": __version__,
        "git": git_commit(),
        "mode": "quick" if quick else "full",
        "experiments_requested": list(names) if names else "all",
        "date_utc": when.astimezone(_dt.UTC).isoformat(timespec="seconds"),
        "libraries": library_versions(),
        "jax_backend": jax_backend(),
        "machine": machine(),
    }
