"""The lock of an output folder: one writer at a time (a ``run``, ``static``, ``run --restart``,
``sweep``, ``modes`` or ``stability``; cosserat_fem/io/run_folder.py makes and claims the folder,
the restart's checkpoint reader refuses a held one).

A ``run``, ``static``, ``run --restart``, ``sweep``, ``modes`` or ``stability`` holds an exclusive
lock on its folder from before it reads or touches anything there to its end
(:func:`cosserat_fem.io.run_folder.prepare_output_dir` with ``lock``, released when the
enclosing :func:`holding_folders` call or :func:`folders_held` block returns or raises). A
second writer is refused at once, in one line naming the holder: its kind, run id, process,
host, start time and command line (written into the lock file by the holder), and the key
that named the folder (:data:`LOCK_KEYS` by kind, or ``--out`` where the command line gave it:
:func:`named_by`). The lock is
``flock(2)`` on the file ``.cosserat-fem.lock`` in the folder, taken by rank 0 (under MPI every
rank agrees on the outcome): the kernel releases it when the holder dies, SIGKILL included, so
a killed run leaves no stale lock (the file it leaves is taken over by the next run); the
holder removes the file when it ends. Why ``flock`` and what it does not cover (file systems
without locks): docs/decisions.md, "One writer a folder".
Tests: tests/test_run_folders.py.
"""

from __future__ import annotations

import contextlib
import contextvars
import errno
import fcntl
import functools
import json
import os
import socket
import stat
import sys
import time
from pathlib import Path

from mpi4py import MPI

from cosserat_fem.common import safe_files
from cosserat_fem.common.errors import SceneError
from cosserat_fem.common.log import LOGGER
from cosserat_fem.common.parallel import agree

#: The lock file of a folder (:class:`FolderLock`).
LOCK = ".cosserat-fem.lock"
#: The key a refusal names, by the kind of writer that asks for the folder.
LOCK_KEYS = {
    "run": "output.directory",
    "static": "output.directory",
    "restart": "--restart",
    "sweep": "sweep --out",
    "modes": "output.directory",
    "stability": "output.directory",
    "continue": "output.directory",
    "orbits": "output.directory",
    "lyapunov": "output.directory",
}
#: Bytes of the holder's record in the lock file (padded with blanks: rewritten in place).
_RECORD = 1024


#: The command line's option that named the folder (``--out``) while :func:`named_by` says
#: so: refusals name it, not the writer's key in :data:`LOCK_KEYS`.
_OPTION: contextvars.ContextVar[str | None] = contextvars.ContextVar(
    "cosserat_fem_folder_option", default=None
)


def lock_key(what: str) -> str:
    """The key a refusal of the folder of a writer of kind ``what`` names: the option the
    user gave (:func:`named_by`), else :data:`LOCK_KEYS`' (default output.directory)."""
    return _OPTION.get() or LOCK_KEYS.get(what, "output.directory")


@contextlib.contextmanager
def named_by(option: str | None):
    """Within the block, folder refusals name ``option`` (the command line's ``--out``, when
    it was given) instead of the writer's key; None: the writer's key."""
    token = _OPTION.set(option)
    try:
        yield
    finally:
        _OPTION.reset(token)


class FolderLock:
    """The exclusive lock of one folder, held by this process (module docstring): taken by
    :meth:`take`, ended by :meth:`release`. The lock file holds the holder's record, a JSON
    object (what, run_id, pid, host, started, command) padded to :data:`_RECORD` bytes."""

    def __init__(self, folder: Path, fd: int | None, record: dict):
        self.folder, self.fd, self.record = folder, fd, record

    @classmethod
    def take(cls, folder: Path, what: str, run_id: str | None = None) -> FolderLock:
        """The lock of ``folder`` (which exists) for a writer of kind ``what``; SceneError
        naming the holder if another holds it. On a file system that cannot lock (ENOLCK,
        EOPNOTSUPP) the writer goes on unprotected, with a warning."""
        path = folder / LOCK
        record = {
            "what": what,
            "run_id": run_id,
            "pid": os.getpid(),
            "host": socket.gethostname(),
            "started": time.strftime("%Y-%m-%d %H:%M:%S %z"),
            "command": " ".join(sys.argv)[:400],
        }
        for _ in range(100):  # a lock file renamed or removed under us: open it again
            fd = cls._open(path)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                holder = _holder(fd)
                os.close(fd)
                raise SceneError(
                    f"{lock_key(what)}: {str(folder)!r} is in use by "
                    f"{holder}; one writer a folder: wait for it to end, or write elsewhere"
                ) from None
            except OSError as exc:
                os.close(fd)
                if exc.errno not in (errno.ENOLCK, errno.EOPNOTSUPP, errno.ENOSYS):
                    raise
                LOGGER.warning(
                    "%s: the file system cannot lock %s (%s); a second writer into "
                    "the folder would not be refused",
                    what,
                    path,
                    exc.strerror,
                )
                return cls(folder, None, record)
            try:
                here = os.lstat(path)
            except FileNotFoundError:
                here = None
            opened = os.fstat(fd)
            if here is not None and (here.st_dev, here.st_ino) == (opened.st_dev, opened.st_ino):
                lock = cls(folder, fd, record)
                with contextlib.suppress(OSError):
                    os.ftruncate(fd, _RECORD)
                    lock._write()
                return lock
            os.close(fd)
        raise OSError(errno.EAGAIN, "the lock file keeps changing", str(path))

    @staticmethod
    def _open(path: Path) -> int:
        """A descriptor of the lock file, made if missing; a link, a special file or a file
        with other names at its name is removed first (never followed or written through)."""
        for _ in range(100):
            try:
                fd = os.open(
                    path,
                    os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_CLOEXEC,
                    0o644,
                )
            except OSError as exc:
                if exc.errno not in (errno.ELOOP, errno.ENXIO, errno.EISDIR):
                    raise
                if exc.errno == errno.EISDIR:
                    raise IsADirectoryError(
                        errno.EISDIR, "is a folder, not the lock file", str(path)
                    ) from None
                safe_files.remove_name(path)  # a link (ELOOP) or a FIFO without reader (ENXIO)
                continue
            info = os.fstat(fd)
            if stat.S_ISREG(info.st_mode) and info.st_nlink == 1:
                return fd
            os.close(fd)
            safe_files.remove_name(path)
        raise OSError(errno.EAGAIN, "the lock file keeps changing", str(path))

    def _write(self) -> None:
        """The record into the held lock file (nothing once released)."""
        if self.fd is None:
            return
        text = json.dumps(self.record).encode("utf-8")[: _RECORD - 1]
        safe_files.write_all(self.fd, text.ljust(_RECORD - 1) + b"\n", 0)

    def note(self, run_id: str) -> None:
        """The run id in the holder's record (known once the run claims the folder)."""
        self.record["run_id"] = run_id
        if self.fd is not None:
            with contextlib.suppress(OSError):
                self._write()

    def release(self) -> None:
        """The lock file removed (if it is still ours) and the lock released."""
        if self.fd is None:
            return
        fd, self.fd = self.fd, None
        with contextlib.suppress(OSError):
            here, opened = os.lstat(self.folder / LOCK), os.fstat(fd)
            if (here.st_dev, here.st_ino) == (opened.st_dev, opened.st_ino):
                os.unlink(self.folder / LOCK)
        os.close(fd)


def _holder(fd: int) -> str:
    """Who holds the lock of the open lock file ``fd``, from the record the holder wrote."""
    try:
        record = json.loads(os.pread(fd, 4 * _RECORD, 0).decode("utf-8"))
    except (OSError, ValueError):
        record = None
    if not isinstance(record, dict):
        return "another process (it has not said which yet)"
    parts = [f"run id {record['run_id']}"] if record.get("run_id") else []
    parts.append(f"process {record.get('pid')} on {record.get('host')!r}")
    parts.append(f"started {record.get('started')}")
    parts.append(f"command {record.get('command')!r}")
    return f"another cosserat-fem {record.get('what', 'writer')} ({', '.join(parts)})"


#: The folder locks taken in the innermost :func:`holding_folders` call (None outside one).
_HELD: contextvars.ContextVar[list[FolderLock] | None] = contextvars.ContextVar(
    "cosserat_fem_folder_locks", default=None
)


@contextlib.contextmanager
def folders_held():
    """The folder locks taken inside the ``with`` block (by :func:`prepare_output_dir` with
    ``lock``) are released when it ends or raises."""
    held: list[FolderLock] = []
    token = _HELD.set(held)
    try:
        yield
    finally:
        _HELD.reset(token)
        for lock in reversed(held):
            lock.release()


def holding_folders(function):
    """Decorator: the folder locks taken during a call of ``function`` (:func:`folders_held`)
    are released when it returns or raises."""

    @functools.wraps(function)
    def call(*args, **kwargs):
        with folders_held():
            return function(*args, **kwargs)

    return call


def held_lock(folder: Path) -> FolderLock | None:
    """The lock of ``folder`` held by the current :func:`holding_folders` call, if any."""
    for lock in _HELD.get() or []:
        if lock.folder == folder:
            return lock
    return None


def refuse_if_held(folder: Path, comm: MPI.Comm, what: str) -> None:
    """SceneError on every rank, naming the holder, if another process holds the lock of
    ``folder`` (tried and let go at once, before a writer of kind ``what`` reads what it will
    continue; the writer takes it for good with :func:`prepare_output_dir`). Collective."""
    problem = None
    if comm.rank == 0 and folder.is_dir():
        try:
            FolderLock.take(folder, what).release()
        except SceneError as exc:
            problem = exc
        except OSError:
            pass  # a folder that cannot be written is refused when the writer takes it
    agree(comm, problem)
