"""Text lines read with a bound: the one reader of every text input (IMU CSV files, ``stream``'s
pipe, MOTION.csv), so that no line, however long, is held whole, and a line that is not UTF-8
text is told apart instead of ending the read.

A file is opened as bytes and decoded as UTF-8 (a leading byte-order mark dropped) with the
undecodable bytes kept as escapes (``surrogateescape``), line ends of any kind (``\\n``,
``\\r\\n``, ``\\r``) as text files are read. :func:`read_line` reads at most
:data:`MAX_LINE_CHARS` characters of a line; the rest of a longer line is read in pieces and
dropped. Each line comes with its problem, if any (:class:`Line`): a file reader refuses it naming
the line (:func:`check_line`), ``stream`` writes its row flagged and goes on.
"""

from __future__ import annotations

import io
from collections.abc import Iterator
from typing import NamedTuple, TextIO

from verticality.core.errors import InputError

MAX_LINE_CHARS = 2**20  # an IMU row is ~100 characters, a wide log's header a few thousand
_SKIP_CHARS = 2**16  # the rest of a line too long is read (and dropped) this much at a time


class Line(NamedTuple):
    """One line without its end (``text``), and why it cannot be read as text (``problem``,
    None when it can): too long (``text`` then holds its first :data:`MAX_LINE_CHARS`
    characters) or not UTF-8. ``left``: the rest of a line too long was not read (the reader
    cannot go on to the next line)."""

    text: str
    problem: str | None = None
    left: bool = False


def open_text(path) -> TextIO:
    """The file at ``path`` for :func:`read_line`: bytes decoded as UTF-8 (byte-order mark
    dropped, undecodable bytes kept as escapes), universal line ends."""
    return io.TextIOWrapper(open(path, "rb"), encoding="utf-8-sig",  # noqa: SIM115
                            errors="surrogateescape", newline=None)


def text_of(stream: TextIO) -> TextIO:
    """A text stream for :func:`read_line`: standard input (any stream with a byte ``buffer``)
    read from its bytes as :func:`open_text` reads a file, so that a line that is not UTF-8 does
    not end the read; a stream of text (no buffer) as it is."""
    buffer = getattr(stream, "buffer", None)
    if buffer is None:
        return stream
    return io.TextIOWrapper(buffer, encoding="utf-8-sig", errors="surrogateescape", newline=None)


def read_line(fh: TextIO, limit: int | None = None, skip_rest: bool = False) -> Line | None:
    """The next line of ``fh`` (None at its end), read with at most ``limit`` characters held
    (default :data:`MAX_LINE_CHARS`). Of a longer line the first ``limit`` characters come with
    the problem; with ``skip_rest`` the rest of it is read (a piece at a time, dropped), so that
    the next call gives the next line (a stream that goes on), else it is left (a file that is
    refused there: a 2 GB line is not read to be refused)."""
    limit = MAX_LINE_CHARS if limit is None else limit
    text = fh.readline(limit + 1)
    if not text:
        return None
    if len(text) > limit and not text.endswith("\n"):
        if not skip_rest:
            return Line(text[:limit], f"longer than any row (more than {limit} characters)",
                        left=True)
        n = len(text)
        while (more := fh.readline(_SKIP_CHARS)) and not more.endswith("\n"):
            n += len(more)
        n += len(more.rstrip("\r\n"))
        return Line(text[:limit], f"a line of {n} characters, longer than any row "
                                  f"({limit} at most)")
    text = text.rstrip("\r\n")
    if not text.isascii():
        try:
            text.encode("utf-8")
        except UnicodeEncodeError as exc:  # an undecodable byte, kept as a lone surrogate
            byte = ord(text[exc.start]) - 0xDC00
            return Line(text, f"not UTF-8 text (byte 0x{byte:02x} at character "
                              f"{exc.start + 1})")
    return Line(text)


def lines(fh: TextIO, limit: int | None = None, skip_rest: bool = False) -> Iterator[Line]:
    """Every remaining line of ``fh`` (:func:`read_line`; without ``skip_rest`` a line too long
    ends them: the reader refuses it)."""
    while (line := read_line(fh, limit, skip_rest)) is not None:
        yield line
        if line.left:
            return


def check_line(line: Line, source: str, line_no: int) -> str:
    """The text of ``line``, or a one-line :class:`InputError` naming ``source`` and the line
    (1-based) when it cannot be read."""
    if line.problem is not None:
        raise InputError(f"{source}: line {line_no}: {line.problem}")
    return line.text


def header_line(fh: TextIO, source: str, limit: int | None = None) -> str:
    """The first line of ``fh`` (the header of a CSV), checked as :func:`check_line` checks
    one; an empty file gives ``""``."""
    line = read_line(fh, limit)
    return "" if line is None else check_line(line, source, 1)
