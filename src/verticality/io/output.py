"""Output paths, checked before the work that fills them."""

from __future__ import annotations

from pathlib import Path

from verticality.errors import InputError


def check_writable_file(path, option: str = "--out") -> Path:
    """Refuse, before any work, an output file that cannot be written: a folder, or a file whose
    folder cannot be created or written. Missing folders are created (the writers would create
    them too); no file is left behind and an existing one is not changed."""
    path = Path(path)
    if path.is_dir():
        raise InputError(f"{option} {path}: is a folder; give a file name")
    existed = path.exists()
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        with path.open("a"):
            pass
    except OSError as exc:
        raise InputError(f"{option} {path}: cannot write ({exc.strerror})") from None
    if not existed:
        path.unlink(missing_ok=True)
    return path
