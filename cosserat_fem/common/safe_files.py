"""Files of a run's folder read and written safely: a special file is never opened, a link is
never written through.

Readers (plot, pod, a restart's checks, a sweep's table) and writers (every output) meet
folders that users copy, link and edit. Two rules, for every file the project opens there:

* **Only regular files are opened.** A FIFO, a socket or a device (``/dev/zero`` linked in)
  blocks an ``open`` or a read for ever, or never ends. :func:`open_regular` looks at the file
  first (``stat``) and opens it with ``O_NONBLOCK`` (a FIFO then opens at once, and is refused
  after ``fstat``); anything but a regular file is a :class:`NotRegularFile`, an ``OSError``
  whose ``strerror`` says what the file is ("is a FIFO, not a regular file"), so that a
  caller's ``except OSError`` reports it in its one line naming the file. Links are followed
  for reading: reading through a link changes nothing.
* **Nothing is written through a link.** A symbolic link, or a hard link (a file with more
  than one name, ``st_nlink > 1``: ``cp -al``, ``rsync --link-dest``), shares its bytes with a
  file outside the folder, which a write in place would change. So a file is written only as
  a new file: its name removed, then created with ``O_CREAT | O_EXCL | O_NOFOLLOW``
  (:func:`create`, :func:`write_new`), or written under a scratch name and renamed over the
  name (:func:`replace`, atomic). A file that is continued (probes.csv on a restart, a sweep's
  table parts) is first made the folder's own (:func:`own_copy`): a link is replaced by a new
  file holding a copy of what is kept (the other names keep their bytes), and the file is then
  opened with ``O_NOFOLLOW`` and its one link checked on the open descriptor
  (:func:`open_append`).

Removing a name (:func:`remove_name`) never follows it either: the link goes, its target
stays; a folder at a file's name is refused (an ``IsADirectoryError`` naming it), never
emptied. Every function here is a plain POSIX call on this process's files: no MPI of its own
(the callers run them on one rank and agree on the outcome, cosserat_fem/common/parallel.py, or pass
the communicator :func:`read_on_root` reads for) and no DOLFINx (results.py uses them without
the solver stack).

The files a user names (a scene, a sweep file, a table of loads) are read by
:func:`read_input_file`, with a bound: :class:`Unreadable` says in words why one cannot be
read, and :func:`read_on_root` reads it once for every MPI rank.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import os
import stat
from pathlib import Path

#: Bytes read or copied a call.
_CHUNK = 1 << 20


class NotRegularFile(OSError):
    """A file that is not a regular file where one is read or continued (a FIFO, a socket, a
    device, a folder), or one with other names where one is continued: ``strerror`` says
    which ("is a FIFO, not a regular file"), ``filename`` is the path, ``str()`` both."""

    def __str__(self) -> str:
        return f"{self.filename!r} {self.strerror}"


def kind(mode: int) -> str:
    """What a file of ``st_mode`` ``mode`` is, in words ("a FIFO", "a folder", ...)."""
    for test, name in (
        (stat.S_ISREG, "a regular file"),
        (stat.S_ISDIR, "a folder"),
        (stat.S_ISFIFO, "a FIFO"),
        (stat.S_ISSOCK, "a socket"),
        (stat.S_ISCHR, "a character device"),
        (stat.S_ISBLK, "a block device"),
        (stat.S_ISLNK, "a symbolic link"),
    ):
        if test(mode):
            return name
    return "a special file"


def _refuse(path: str | Path, mode: int) -> NotRegularFile:
    return NotRegularFile(errno.EINVAL, f"is {kind(mode)}, not a regular file", str(path))


def open_regular(path: str | Path, flags: int = os.O_RDONLY) -> int:
    """A descriptor of the regular file ``path`` (links followed), opened with ``flags``
    without ever blocking on a FIFO or a device; :class:`NotRegularFile` for anything else,
    ``FileNotFoundError`` if there is nothing. The caller closes it."""
    info = os.stat(path)
    if not stat.S_ISREG(info.st_mode):
        raise _refuse(path, info.st_mode)
    fd = os.open(path, flags | os.O_NONBLOCK | os.O_CLOEXEC)
    try:
        info = os.fstat(fd)  # what was opened, should the name have changed meanwhile
        if not stat.S_ISREG(info.st_mode):
            raise _refuse(path, info.st_mode)
        fcntl.fcntl(fd, fcntl.F_SETFL, fcntl.fcntl(fd, fcntl.F_GETFL) & ~os.O_NONBLOCK)
    except BaseException:
        os.close(fd)
        raise
    return fd


def _read_fd(fd: int, limit: int | None, offset: int = 0) -> bytes:
    """The bytes of ``fd`` from ``offset`` to its end, or its first ``limit`` + 1 bytes (so
    that a caller sees that there are more)."""
    parts, size = [], 0
    while limit is None or size <= limit:
        want = _CHUNK if limit is None else min(_CHUNK, limit + 1 - size)
        part = os.pread(fd, want, offset + size)
        if not part:
            break
        parts.append(part)
        size += len(part)
    return b"".join(parts)


def read_regular(path: str | Path, limit: int | None = None) -> bytes:
    """The content of the regular file ``path`` (:func:`open_regular`); with ``limit``, at most
    ``limit`` + 1 bytes (more than ``limit`` means the file is too large for the caller)."""
    fd = open_regular(path)
    try:
        return _read_fd(fd, limit)
    finally:
        os.close(fd)


class Unreadable(Exception):
    """Why a file the user named could not be read, as words that follow its name ("is a
    FIFO, not a regular file", "was not found", ...); the caller makes the message its own
    error (a SceneError naming the key)."""


def _size(n: int) -> str:
    """``n`` bytes in words: "16 MiB", "4 kiB" or "100 bytes"."""
    for unit, shift in (("MiB", 20), ("kiB", 10)):
        if n >= 1 << shift and n % (1 << shift) == 0:
            return f"{n >> shift} {unit}"
    return f"{n} bytes"


def read_input_file(path: str | Path, limit: int) -> bytes:
    """The bytes of the regular file ``path`` (links followed, :func:`open_regular`), at most
    ``limit`` of them; :class:`Unreadable` for anything else: missing, a folder, a FIFO, a
    device, a socket, larger than ``limit`` (also if it grows past it while read), or an I/O
    error. Never blocks on a FIFO."""
    try:
        fd = open_regular(path)
    except FileNotFoundError:
        raise Unreadable("was not found") from None
    except NotRegularFile as exc:
        raise Unreadable(exc.strerror) from None
    except (OSError, ValueError) as exc:  # ValueError: a NUL in the name
        raise Unreadable(f"cannot be opened ({getattr(exc, 'strerror', None) or exc})") from None
    try:
        size = os.fstat(fd).st_size
        if size > limit:
            raise Unreadable(f"holds {size} bytes, more than the {_size(limit)} allowed")
        data = _read_fd(fd, limit)
    except OSError as exc:
        raise Unreadable(f"cannot be read ({exc.strerror or exc})") from None
    finally:
        os.close(fd)
    if len(data) > limit:
        raise Unreadable(f"grew past the {_size(limit)} allowed while it was read")
    return data


def read_on_root(path: str | Path, limit: int, comm=None) -> bytes:
    """:func:`read_input_file` on rank 0 of ``comm`` and its bytes on every rank, or
    :class:`Unreadable` with rank 0's reason on every rank (collective; a plain read without
    ``comm`` or on one rank): the ranks of a job parse one input, whatever each would have
    read (a copy per node, a file edited meanwhile), and a FIFO is opened once."""
    if comm is None or comm.size == 1:
        return read_input_file(path, limit)
    found: tuple[bytes | None, str | None] = (None, None)
    if comm.rank == 0:
        try:
            found = (read_input_file(path, limit), None)
        except Unreadable as exc:
            found = (None, str(exc))
    data, reason = comm.bcast(found, root=0)
    if reason is not None:
        raise Unreadable(reason)
    return data


def read_text(path: str | Path, limit: int | None = None) -> str:
    """:func:`read_regular` as UTF-8 text (``UnicodeDecodeError``, a ``ValueError``, if not)."""
    return read_regular(path, limit).decode("utf-8")


def remove_name(path: str | Path) -> None:
    """Remove the name ``path`` if there is one: a file, a link (not its target) or a special
    file; a folder there is an ``IsADirectoryError`` naming it (never emptied)."""
    try:
        info = os.lstat(path)
    except FileNotFoundError:
        return
    if stat.S_ISDIR(info.st_mode):
        raise IsADirectoryError(errno.EISDIR, "is a folder, not a file", str(path))
    with contextlib.suppress(FileNotFoundError):
        os.unlink(path)


def create(path: str | Path, mode: int = 0o644) -> int:
    """A descriptor (write only) of a new, empty file ``path``: whatever had the name before
    removed (:func:`remove_name`), never followed or truncated. The caller closes it."""
    flags = os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW | os.O_CLOEXEC
    try:
        return os.open(path, flags, mode)
    except FileExistsError:  # (a link, even to nothing, is there too: O_EXCL never follows)
        remove_name(path)
        return os.open(path, flags, mode)


def write_all(fd: int, data, offset: int | None = None) -> None:
    """All of ``data`` (bytes-like) to ``fd``: at its position, or from ``offset``."""
    view = memoryview(data).cast("B")
    while view:
        if offset is None:
            written = os.write(fd, view)
        else:
            written = os.pwrite(fd, view, offset)
            offset += written
        view = view[written:]


def write_new(path: str | Path, data) -> None:
    """``data`` (bytes-like) as the new file ``path`` (:func:`create`)."""
    fd = create(path)
    try:
        write_all(fd, data, 0)
    finally:
        os.close(fd)


def scratch_name(path: str | Path) -> Path:
    """The scratch name :func:`replace` writes under: ``<name>.tmp`` beside ``path``."""
    path = Path(path)
    return path.with_name(path.name + ".tmp")


def replace(path: str | Path, data, scratch: str | Path | None = None) -> None:
    """``data`` (bytes-like, or text as UTF-8) as the file ``path``, atomically: a new file
    under ``scratch`` (default :func:`scratch_name`) renamed over ``path`` (a link there is
    replaced, its target untouched). On failure the scratch file is removed and ``path`` is
    as it was; the OSError is raised."""
    if isinstance(data, str):
        data = data.encode("utf-8")
    scratch = scratch_name(path) if scratch is None else Path(scratch)
    try:
        write_new(scratch, data)
        os.replace(scratch, path)
    except BaseException:
        with contextlib.suppress(OSError):
            if not os.path.isdir(scratch) or os.path.islink(scratch):
                os.unlink(scratch)
        raise


def own_copy(path: str | Path, keep: int | None = None) -> None:
    """Make the file ``path`` the folder's own, holding its first ``keep`` bytes (default all):
    a link (symbolic or hard) is replaced by a new file with a copy of them, the file it led
    to left as it was; a file of one name is cut to ``keep`` in place. NotRegularFile for a
    special file or a folder (or a link to one), FileNotFoundError if there is none."""
    info = os.lstat(path)
    if not (stat.S_ISLNK(info.st_mode) or stat.S_ISREG(info.st_mode)):
        raise _refuse(path, info.st_mode)
    if stat.S_ISREG(info.st_mode) and info.st_nlink == 1:
        fd = os.open(path, os.O_WRONLY | os.O_NOFOLLOW | os.O_CLOEXEC)
        try:
            opened = os.fstat(fd)
            if (opened.st_dev, opened.st_ino) == (info.st_dev, info.st_ino) and (
                opened.st_nlink == 1
            ):
                if keep is not None and keep < opened.st_size:
                    os.ftruncate(fd, keep)
                return
        finally:
            os.close(fd)
    data = read_regular(path, keep)
    replace(path, data if keep is None else data[:keep])


def _alone(path: str | Path, fd: int) -> None:
    """NotRegularFile unless ``fd`` is a regular file with one name (no hard link)."""
    info = os.fstat(fd)
    if not stat.S_ISREG(info.st_mode):
        raise _refuse(path, info.st_mode)
    if info.st_nlink != 1:
        raise NotRegularFile(
            errno.EMLINK, "has other names (hard links): not written through", str(path)
        )


def open_append(path: str | Path) -> int:
    """A descriptor (read and append) of the existing file ``path``, made the folder's own
    first (:func:`own_copy`); refused (NotRegularFile) should it have become a link or a
    special file since. The caller closes it."""
    own_copy(path)
    fd = os.open(path, os.O_RDWR | os.O_APPEND | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_CLOEXEC)
    try:
        _alone(path, fd)
        fcntl.fcntl(fd, fcntl.F_SETFL, fcntl.fcntl(fd, fcntl.F_GETFL) & ~os.O_NONBLOCK)
    except BaseException:
        os.close(fd)
        raise
    return fd


def read_fd(fd: int) -> bytes:
    """All the bytes of the open file ``fd`` (from its start; its position unchanged)."""
    return _read_fd(fd, None)


def remove_own_files(folder: str | Path, own, first: str | None = None) -> None:
    """Remove from ``folder`` the files whose names ``own`` (a compiled pattern) matches in
    full, the name ``first`` first, and then the folder itself if that left it empty; never a
    subfolder or a file of another name. A link at ``folder`` itself is removed, its target
    left (nothing of it is the project's). Nothing there, nothing done."""
    folder = Path(folder)
    try:
        info = os.lstat(folder)
    except FileNotFoundError:
        return
    if not stat.S_ISDIR(info.st_mode):
        if stat.S_ISLNK(info.st_mode):
            os.unlink(folder)
        return
    names = sorted(e.name for e in os.scandir(folder) if not e.is_dir(follow_symlinks=False))
    if first in names:
        names.remove(first)
        names.insert(0, first)
    for name in names:
        if own.fullmatch(name):
            with contextlib.suppress(FileNotFoundError):
                os.unlink(folder / name)
    with contextlib.suppress(OSError):  # not empty: the rest is not the project's
        os.rmdir(folder)
