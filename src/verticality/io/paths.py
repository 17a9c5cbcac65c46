"""The paths a command reads and writes, checked before any work, and the one way outputs are
written.

Checks: every output is resolved (``realpath``: ``./sub/../rec.csv``, a symlink and a hard link
all name the file they reach) and compared with every input and with the other outputs, so that no
run overwrites its own recording or writes two results to one file; an output must be a writable
file (not a folder), a figure's extension one that matplotlib can write; an input must be an
existing regular file (a folder, a pipe or a device is named as one). Every command that writes
calls :func:`check_paths` first; a refusal is an :class:`~verticality.core.errors.InputError`
(one line, exit status 2).

Writing (:func:`atomic_output`, :func:`write_atomic`): every output file is written to a
temporary file beside it (``NAME.part``) and renamed over it when complete, so that

* a file that exists is complete, and a refusal or a crash midway leaves the old one;
* nothing is written *through* a link: a symlink (or a hard link) planted where the output goes is
  replaced by the new file, and the file it pointed to is left alone; a folder of the output
  reached through a link out of the folder the user named is refused (``root``);
* an existing output keeps its permissions (a private ``0600`` file stays private);
* two runs writing one file cannot mix: the temporary file is locked (``flock``) while it is
  written, and a second run refuses in one line instead of writing into it (a ``.part`` left by a
  run that was killed is not locked and is taken over).

Folders written by one run at a time (``reproduce --out``, ``sweep --out``, ``estimate FOLDER
--out``) are locked as a whole (:func:`folder_lock`).
"""

from __future__ import annotations

import os
import stat
from collections.abc import Callable, Iterable, Iterator, Mapping
from contextlib import contextmanager
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


def check_input_file(path, what: str = "input", regular: bool = True) -> Path:
    """An existing, readable file; a missing path and a folder are refused, each in its own
    words, and (``regular``) a pipe, a socket or a device: a file read whole or twice (sized,
    then read) must end, and must be there again the second time (``stream`` reads a pipe with
    ``regular=False``)."""
    path = Path(path)
    if path.is_dir():
        raise InputError(f"{path}: is a directory; give a file ({what})")
    if not path.exists():
        raise InputError(f"{path}: no such file")
    if regular and not path.is_file():
        raise InputError(f"{path}: is {file_kind(path)}, not a file; give a file ({what})"
                         + ("; `verticality stream` reads a pipe" if what == "input" else ""))
    if not os.access(path, os.R_OK):
        raise InputError(f"{path}: permission denied (cannot read)")
    return path


def file_kind(path) -> str:
    """What ``path`` is, in words ("a pipe", "a character device", …; "a file" for a regular
    file)."""
    try:
        mode = os.stat(path).st_mode
    except OSError:
        return "missing"
    return ("a file" if stat.S_ISREG(mode) else "a folder" if stat.S_ISDIR(mode)
            else "a character device" if stat.S_ISCHR(mode) else "a block device"
            if stat.S_ISBLK(mode) else "a pipe" if stat.S_ISFIFO(mode) else "a socket"
            if stat.S_ISSOCK(mode) else "not a regular file")


def check_writable_file(path, option: str = "--out") -> Path:
    """Refuse, before any work, an output file that cannot be written: a folder, a file whose
    folder cannot be created or written, an existing file without write permission, one that
    another run is writing now. Missing folders are created (the writers would create them too);
    no file is created, and none is opened: a link where the output goes is not followed (the
    writer replaces it, :func:`atomic_output`)."""
    path = Path(path)
    if path.is_dir():
        raise InputError(f"{option} {path}: is a folder; give a file name")
    check_not_device(path, option)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"{option} {path}: cannot write ({exc.strerror})") from None
    folder = path.parent if str(path.parent) else Path(".")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise InputError(f"{option} {path}: cannot write (permission denied in its folder)")
    if path.is_file() and not path.is_symlink() and not os.access(path, os.W_OK):
        raise InputError(f"{option} {path}: cannot write (the file is read-only)")
    check_not_busy(path, option)
    return path


def check_not_device(path, option: str = "--out") -> None:
    """Refuse an output that exists and is not a regular file (``/dev/full``, ``/dev/null``, a
    FIFO, a socket): the writers write beside it and rename, or would report a write that a
    device swallowed or refused."""
    try:
        mode = os.stat(path).st_mode
    except OSError:
        return  # not there (yet): a regular file will be created
    if not stat.S_ISREG(mode) and not stat.S_ISDIR(mode):
        raise InputError(f"{option} {path}: is {file_kind(path)}, not a file; give a file name")


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


# ---------------------------------------------------------------------------------------------
# writing


PART_SUFFIX = ".part"


def part_path(final) -> Path:
    """The temporary file an output is written to before it is renamed over ``final``."""
    final = Path(final)
    return final.with_name(final.name + PART_SUFFIX)


def inside(path, root) -> bool:
    """Whether ``path`` (resolved: links and ``..`` followed) is ``root`` or lies under it."""
    r, p = resolved(root), resolved(path)
    return p == r or p.startswith(r.rstrip(os.sep) + os.sep)


def _lock(fd: int) -> bool:
    """Take the exclusive lock of the open file ``fd`` without waiting; False when another
    process holds it (no ``flock`` on this system: always True)."""
    try:
        import fcntl
    except ImportError:  # pragma: no cover (not POSIX)
        return True
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        return False
    except OSError as exc:  # a file system without locks (some network ones): write unlocked
        import errno

        if exc.errno not in (errno.ENOLCK, errno.EOPNOTSUPP, errno.EINVAL):
            raise
    return True


def _busy(option: str, final, what: str = "file") -> InputError:
    return InputError(f"{option} {final}: another run is writing this {what} now; wait for it to "
                      f"end, or give another {option}")


def check_not_busy(final, option: str = "--out") -> None:
    """Refuse ``final`` when another run holds its temporary file (:func:`atomic_output`), before
    any work: that run's output would replace this one's, or this one's it."""
    part = part_path(final)
    try:
        fd = os.open(part, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK)
    except OSError:
        return  # none (a link there is replaced or refused when writing)
    try:
        import fcntl

        try:
            fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
        except BlockingIOError:
            raise _busy(option, final) from None
        except OSError:
            pass  # not a file that can be locked: the writer refuses it
    except ImportError:  # pragma: no cover (not POSIX)
        pass
    finally:
        os.close(fd)


def _umask() -> int:
    """This process's umask (read, not changed: other threads may be creating files)."""
    try:
        with open("/proc/self/status", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError):
        pass
    return 0o022


def _open_part(final: Path, option: str) -> int:
    """The temporary file of ``final``, created (or a killed run's taken over), locked and empty;
    its descriptor. Refused: another run holds it; it is not a regular file (a link planted
    there)."""
    part = part_path(final)
    flags = os.O_WRONLY | os.O_NOFOLLOW | getattr(os, "O_CLOEXEC", 0)
    for _ in range(20):  # a race with another run's rename: look again
        try:
            fd = os.open(part, flags | os.O_CREAT | os.O_EXCL, 0o666)
            new = True
        except FileExistsError:
            try:
                fd = os.open(part, flags | os.O_NONBLOCK)
            except FileNotFoundError:
                continue  # renamed away meanwhile
            except OSError as exc:  # a link (ELOOP), a FIFO without a reader, a folder
                raise InputError(f"{option} {final}: {part.name} beside it is not a file this "
                                 f"program wrote ({exc.strerror}); remove it") from None
            new = False
        try:
            if not _lock(fd):
                raise _busy(option, final)
            st = os.fstat(fd)
            try:
                now = os.lstat(part)
            except FileNotFoundError:
                now = None
            if now is None or (now.st_dev, now.st_ino) != (st.st_dev, st.st_ino):
                os.close(fd)
                continue  # it was renamed or replaced between the open and the lock
            if not stat.S_ISREG(st.st_mode):
                raise InputError(f"{option} {final}: {part.name} beside it is not a file this "
                                 "program wrote; remove it")
            if not new:  # left by a run that was killed: ours now
                os.ftruncate(fd, 0)
                os.fchmod(fd, 0o666 & ~_umask())
            return fd
        except BaseException:
            try:
                os.close(fd)
            except OSError:
                pass
            raise
    raise _busy(option, final)


@contextmanager
def atomic_output(final, option: str = "--out", root=None) -> Iterator[Path]:
    """Write an output file through a temporary file: ``with atomic_output(path) as tmp:`` write
    ``tmp`` (by its name, any number of times); when the block ends without an exception ``tmp``
    is flushed to the disk, given the permissions of the file it replaces (if any) and renamed
    over ``final`` (the name itself: a link there is replaced, never written through); on an
    exception ``tmp`` is removed and ``final`` left as it was. While the block runs ``tmp`` is
    locked: a second run writing ``final`` is refused (:class:`InputError`, one line).

    ``root``: the folder the user named (``--out DIR``); ``final``'s folder must lie inside it
    once links are followed (a folder link planted in it that leads out is refused). Missing
    folders are created."""
    final = Path(final)
    try:
        final.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"{option} {final}: cannot create its folder ({exc.strerror})") from None
    if root is not None and not inside(final.parent, root):
        raise InputError(f"{option} {final}: its folder leads out of {root} (a link); remove "
                         "the link or give another folder")
    fd = _open_part(final, option)
    part = part_path(final)
    try:
        try:
            yield part
            st = os.lstat(part)
            mine = os.fstat(fd)
            if (st.st_dev, st.st_ino) != (mine.st_dev, mine.st_ino):
                raise InputError(f"{option} {final}: its temporary file was replaced while it "
                                 "was written; nothing was written")
            os.fsync(fd)
            try:
                old = os.lstat(final)
            except FileNotFoundError:
                old = None
            if old is not None and stat.S_ISREG(old.st_mode):
                os.fchmod(fd, stat.S_IMODE(old.st_mode))  # a private file stays private
            os.replace(part, final)
        except BaseException:
            try:  # ours only: the lock is held, so no other run wrote there
                st = os.lstat(part)
                mine = os.fstat(fd)
                if (st.st_dev, st.st_ino) == (mine.st_dev, mine.st_ino):
                    os.unlink(part)
            except OSError:
                pass
            raise
    finally:
        os.close(fd)


def write_atomic(final, write: Callable[[Path], object], option: str = "--out",
                 root=None) -> Path:
    """``write(tmp)`` inside :func:`atomic_output` (``final`` exists only complete, keeps its
    permissions, is never written through a link, one writer at a time); returns ``final``."""
    with atomic_output(final, option, root) as tmp:
        write(tmp)
    return Path(final)


def write_text(final, text: str, option: str = "--out", root=None) -> Path:
    """``text`` as UTF-8 to ``final`` through :func:`write_atomic` (characters that cannot be
    encoded, such as the undecodable bytes of a file name, written as backslash escapes)."""
    return write_atomic(final, lambda tmp: tmp.write_text(text, encoding="utf-8",
                                                          errors="backslashreplace"),
                        option, root)


@contextmanager
def folder_lock(path, option: str = "--out") -> Iterator[Path]:
    """Hold the output folder ``path`` (existing) for one run: a second run into it while this one
    lasts is refused (:class:`InputError`, one line) instead of mixing its files with this one's.
    The lock (``flock`` on the folder) ends with the block or the process: nothing is left
    behind."""
    path = Path(path)
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0))
    except OSError as exc:
        raise InputError(f"{option} {path}: cannot open the folder ({exc.strerror})") from None
    try:
        if not _lock(fd):
            raise _busy(option, path, "folder")
        yield path
    finally:
        os.close(fd)


def confined_folder(root, name: str, option: str = "--out") -> Path:
    """The folder ``root/name`` (created), refused when ``name`` is not one plain folder name or
    when the folder, links followed, lies outside ``root`` (a link planted there)."""
    if not is_plain_name(name):
        raise InputError(f"{option} {root}: {name!r} is not a plain folder name")
    folder = Path(root) / name
    if not inside(folder, root):
        raise InputError(f"{option} {root}: {name} there leads out of the folder (a link); "
                         "remove it or give another folder")
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"{option} {folder}: cannot create the folder ({exc.strerror})") from None
    return folder


def is_plain_name(name) -> bool:
    """Whether ``name`` is one file or folder name: not empty, not ``.`` or ``..``, no ``/`` (or
    ``\\``), no NUL."""
    return (isinstance(name, str) and name not in ("", ".", "..")
            and not any(c in name for c in "/\\\x00"))
