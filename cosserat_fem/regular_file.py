"""Reading a file the user names, bounded and without blocking: regular files only.

``open()`` of a FIFO waits for a writer for ever, and ``read()`` of ``/dev/zero`` or a pipe
never ends; a file that grows while it is read has no size to trust. :func:`read_regular`
opens without blocking (``O_NONBLOCK``: a FIFO opens at once), looks at what it opened
(``fstat`` of the open file, not of the name, which another process may change in between),
refuses anything but a regular file, and reads at most ``limit`` bytes. No DOLFINx, and no
MPI but the communicator a caller passes: :func:`read_on_root` reads on its rank 0 and gives
every rank the same bytes (or the same refusal).
"""

from __future__ import annotations

import os
import stat
from pathlib import Path

_KINDS = (
    (stat.S_ISDIR, "a folder"),
    (stat.S_ISFIFO, "a FIFO"),
    (stat.S_ISCHR, "a character device"),
    (stat.S_ISBLK, "a block device"),
    (stat.S_ISSOCK, "a socket"),
)


class Unreadable(Exception):
    """Why a file could not be read, as words that follow its name ("is a FIFO, not a regular
    file", "was not found", ...); the caller makes the message its own error."""


def kind_of(mode: int) -> str:
    """What a file of ``st_mode`` ``mode`` is, in words ("a regular file", "a FIFO", ...)."""
    if stat.S_ISREG(mode):
        return "a regular file"
    return next((name for test, name in _KINDS if test(mode)), "not a regular file")


def read_regular(path: str | Path, limit: int) -> bytes:
    """The bytes of the regular file ``path`` (links followed), at most ``limit`` of them;
    :class:`Unreadable` for anything else: missing, a folder, a FIFO, a device, a socket,
    larger than ``limit`` (also if it grows past it while read), or an I/O error. Never
    blocks on a FIFO."""
    flags = os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_NOCTTY", 0) | getattr(os, "O_CLOEXEC", 0)
    try:
        fd = os.open(path, flags)
    except FileNotFoundError:
        raise Unreadable("was not found") from None
    except (OSError, ValueError) as exc:  # ValueError: a NUL in the name
        raise Unreadable(f"cannot be opened ({getattr(exc, 'strerror', None) or exc})") from None
    try:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):
            raise Unreadable(f"is {kind_of(info.st_mode)}, not a regular file")
        if info.st_size > limit:
            raise Unreadable(f"holds {info.st_size} bytes, more than the {_size(limit)} allowed")
        chunks, total = [], 0
        while total <= limit:
            chunk = os.read(fd, min(1 << 20, limit + 1 - total))
            if not chunk:
                break
            chunks.append(chunk)
            total += len(chunk)
        if total > limit:
            raise Unreadable(f"grew past the {_size(limit)} allowed while it was read")
        return b"".join(chunks)
    except OSError as exc:
        raise Unreadable(f"cannot be read ({exc.strerror or exc})") from None
    finally:
        os.close(fd)


def _size(n: int) -> str:
    """``n`` bytes in words: "16 MiB", "4 kiB" or "100 bytes"."""
    for unit, shift in (("MiB", 20), ("kiB", 10)):
        if n >= 1 << shift and n % (1 << shift) == 0:
            return f"{n >> shift} {unit}"
    return f"{n} bytes"


def read_on_root(path: str | Path, limit: int, comm=None) -> bytes:
    """:func:`read_regular` on rank 0 of ``comm`` and its bytes on every rank, or
    :class:`Unreadable` with rank 0's reason on every rank (collective; a plain read without
    ``comm`` or on one rank): the ranks of a job parse one input, whatever each would have
    read (a copy per node, a file edited meanwhile), and a FIFO is opened once."""
    if comm is None or comm.size == 1:
        return read_regular(path, limit)
    found: tuple[bytes | None, str | None] = (None, None)
    if comm.rank == 0:
        try:
            found = (read_regular(path, limit), None)
        except Unreadable as exc:
            found = (None, str(exc))
    data, reason = comm.bcast(found, root=0)
    if reason is not None:
        raise Unreadable(reason)
    return data
