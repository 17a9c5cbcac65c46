"""The paths a command reads and writes, checked before any work: every output is resolved
(``realpath``: ``./sub/../rec.csv``, a symlink and a hard link all name the file they reach) and
compared with every input and with the other outputs, so that no run overwrites its own recording
or writes two results to one file; an output must be a writable file (not a folder), a figure's
extension one that matplotlib can write; an input must be an existing file (a folder is named as
one). Every command that writes calls :func:`check_paths` first; a refusal is an
:class:`~verticality.core.errors.InputError` (one line, exit status 2).
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Mapping
from pathlib import Path

from verticality.core.errors import InputError


def resolved(path) -> str:
    """The absolute path ``path`` reaches, symlinks and ``..`` resolved (also for a file that does
    not exist yet: its existing folders are resolved)."""
    return os.path.realpath(os.path.abspath(os.fspath(path)))


def same_file(a, b) -> bool:
    """Whether paths ``a`` and ``b`` reach the same file: the same resolved path, or (both
    existing) the same device and inode (a hard link)."""
    if resolved(a) == resolved(b):
        return True
    try:
        return os.path.samefile(a, b)
    except OSError:
        return False


def check_input_file(path, what: str = "input") -> Path:
    """An existing, readable file; a missing path and a folder are refused, each in its own
    words."""
    path = Path(path)
    if path.is_dir():
        raise InputError(f"{path}: is a directory; give a file ({what})")
    if not path.exists():
        raise InputError(f"{path}: no such file")
    if not os.access(path, os.R_OK):
        raise InputError(f"{path}: permission denied (cannot read)")
    return path


def check_writable_file(path, option: str = "--out") -> Path:
    """Refuse, before any work, an output file that cannot be written: a folder, or a file whose
    folder cannot be created or written. Missing folders are created (the writers would create
    them too); no file is left behind and an existing one is not changed."""
    path = Path(path)
    if path.is_dir():
        raise InputError(f"{option} {path}: is a folder; give a file name")
    check_not_device(path, option)
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


def check_not_device(path, option: str = "--out") -> None:
    """Refuse an output that exists and is not a regular file (``/dev/full``, ``/dev/null``, a
    FIFO, a socket): the writers write beside it and rename, or would report a write that a
    device swallowed or refused."""
    import stat

    try:
        mode = os.stat(path).st_mode
    except OSError:
        return  # not there (yet): a regular file will be created
    if not stat.S_ISREG(mode) and not stat.S_ISDIR(mode):
        kind = ("a character device" if stat.S_ISCHR(mode) else "a block device"
                if stat.S_ISBLK(mode) else "a pipe" if stat.S_ISFIFO(mode) else "a socket"
                if stat.S_ISSOCK(mode) else "not a regular file")
        raise InputError(f"{option} {path}: is {kind}, not a file; give a file name")


def check_written(path, option: str = "--out") -> Path:
    """After a write: ``path`` is a regular file holding at least one byte, its data flushed to
    the disk (``fsync``); else an :class:`InputError` instead of a "wrote" for a write that did
    not happen (a device, a file system that lost it)."""
    path = Path(path)
    check_not_device(path, option)
    try:
        fd = os.open(path, os.O_RDONLY)
        try:
            os.fsync(fd)
            size = os.fstat(fd).st_size
        finally:
            os.close(fd)
    except OSError as exc:
        raise InputError(f"{option} {path}: the write did not reach the disk "
                         f"({exc.strerror})") from None
    if size == 0:
        raise InputError(f"{option} {path}: nothing was written (0 bytes)")
    return path


def fingerprint(path) -> dict:
    """What a file is now: its size, modification time (ns) and SHA-256, so that an output made
    from it can later prove it was made from this content (a recording that grew, was edited or
    replaced is estimated again)."""
    import hashlib

    path = Path(path)
    st = path.stat()
    h = hashlib.sha256()
    with path.open("rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return {"size": st.st_size, "mtime_ns": st.st_mtime_ns, "sha256": h.hexdigest()}


def figure_formats() -> dict[str, str]:
    """The file extensions matplotlib can write (without the dot) and their descriptions."""
    from matplotlib.figure import Figure

    return Figure().canvas.get_supported_filetypes()


def check_figure_name(path, option: str = "--plot") -> Path:
    """A figure file name whose extension matplotlib can write (``.png``, ``.pdf``, ``.svg`` …)."""
    path = Path(path)
    ext = path.suffix.lower().removeprefix(".")
    formats = figure_formats()
    if ext not in formats:
        shown = f"extension .{ext}" if ext else "no extension"
        raise InputError(f"{option} {path}: {shown}, not a figure format; use one of "
                         f"{', '.join('.' + e for e in sorted(formats))}")
    return path


def check_paths(outputs: Mapping[str, object], inputs: Iterable[object] = (),
                figures: Iterable[str] = ()) -> dict[str, Path]:
    """Check the paths of a command before its work: ``outputs`` {option: path or None} (None:
    not asked for), ``inputs`` the files it reads (None entries ignored), ``figures`` the options of
    ``outputs`` that are figures (:func:`check_figure_name`). Refuses an output that reaches an
    input (:func:`same_file`) or another output, a folder, a figure with an unknown extension and
    an output that cannot be written (:func:`check_writable_file`), in that order, so that nothing
    is created when the run is refused. Returns the outputs given, as paths."""
    outs = {opt: Path(p) for opt, p in outputs.items() if p is not None}
    ins = [Path(p) for p in inputs if p is not None]
    for opt, out in outs.items():
        for src in ins:
            if same_file(out, src):
                raise InputError(f"{opt} {out}: is the input {src}; writing it would destroy the "
                                 "input: give another file name")
    names = list(outs.items())
    for i, (opt, out) in enumerate(names):
        for opt2, out2 in names[i + 1:]:
            if same_file(out, out2):
                raise InputError(f"{opt} and {opt2} name the same file {out}: give two names")
    for opt, out in outs.items():
        if out.is_dir():
            raise InputError(f"{opt} {out}: is a folder; give a file name")
        check_not_device(out, opt)
    for opt in figures:
        if opt in outs:
            check_figure_name(outs[opt], opt)
    for opt, out in outs.items():
        check_writable_file(out, opt)
    return outs


def check_output_folder(path, option: str = "--out", inputs: Iterable[object] = ()) -> Path:
    """A folder to write results into: not an existing file, not an input file, creatable."""
    path = Path(path)
    for src in inputs:
        if src is not None and same_file(path, src):
            raise InputError(f"{option} {path}: is the input {src}; give another folder")
    if path.exists() and not path.is_dir():
        check_not_device(path, option)
        raise InputError(f"{option} {path}: is a file; give a folder")
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"{option} {path}: cannot create the folder ({exc.strerror})") from None
    if not os.access(path, os.W_OK):
        raise InputError(f"{option} {path}: cannot write in the folder (permission denied)")
    return path
