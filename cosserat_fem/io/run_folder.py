"""The output folder of a run: made and checked, locked, claimed by a new run, and its
summary.json.

A folder holds the outputs of one run at a time, and has one writer at a time:

* **The lock.** A ``run``, ``static``, ``run --restart`` or ``sweep`` holds an exclusive lock on
  its folder from before it reads or touches anything there to its end
  (:func:`prepare_output_dir` with ``lock``, released when the enclosing
  :func:`holding_folders` call returns or raises). A second writer is refused at once, in one
  line naming the holder: its kind, run id, process, host, start time and command line
  (written into the lock file by the holder). The lock is ``flock(2)`` on the file
  ``.cosserat-fem.lock`` in the folder, taken by rank 0 (under MPI every rank agrees on the
  outcome): the kernel releases it when the holder dies, SIGKILL included, so a killed run
  leaves no stale lock (the file it leaves is taken over by the next run); the holder removes
  the file when it ends. Why ``flock`` and what it does not cover (file systems without
  locks): docs/decisions.md, "One writer a folder".
* **The claim.** A new ``run`` or ``static`` first removes what an earlier run left there that
  it will not overwrite itself, so that no stale file can be mistaken for its own: the earlier
  run's checkpoint (a restart would otherwise continue it after the new outputs), its XDMF
  file and frames, and the HDF5 files and scratch XML of the earlier single-file layout
  (``solution.h5``, ``solution-restart<n>.h5``, ``solution.xdmf-partial``). Only the
  project's own files go (:func:`stale_outputs`): in ``checkpoint/`` and ``solution.frames/``
  the names the project writes there (:data:`cosserat_fem.io.checkpoint.OWN_FILES`,
  :data:`cosserat_fem.results.FRAME_NAME`), never a subfolder or a file of another name (a
  user's notes, another run nested inside); a folder left empty goes too. A link at one of
  these names is removed, never followed. Where something of the user's stands where the run
  must write (a file named ``checkpoint``, a folder named ``probes.csv``), the run is refused
  in one line before anything is removed (:func:`conflict`). Then it writes summary.json with
  the status "running" and a new run identity (:func:`new_run_id`) before any other output,
  which the checkpoint and the XDMF file carry too (cosserat_fem/io/checkpoint.py).

Every file of the folder is written as a new file or by an atomic rename, never through a
link, and no special file is opened (cosserat_fem/safe_files.py).
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
import uuid
from pathlib import Path

from mpi4py import MPI

from .. import safe_files
from ..errors import OutputError, SceneError
from ..parallel import agree, from_root
from .probes import PROBES
from .reading import decode, finite_number, json_kind, quoted, read_bytes
from .xdmf import XDMF

#: The run's summary: written when it starts (status "running"), replaced at its end.
SUMMARY = "summary.json"
#: Largest summary.json read [bytes] (a run's is ~4 kB).
MAX_SUMMARY_BYTES = 16 << 20
#: The lock file of a folder (:class:`FolderLock`).
LOCK = ".cosserat-fem.lock"
#: The key a refusal names, by the kind of writer that asks for the folder.
LOCK_KEYS = {"run": "output.directory", "static": "output.directory", "restart": "--restart",
             "sweep": "sweep --out"}  # fmt: skip
#: Bytes of the holder's record in the lock file (padded with blanks: rewritten in place).
_RECORD = 1024


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
        record = {"what": what, "run_id": run_id, "pid": os.getpid(),
                  "host": socket.gethostname(), "started": time.strftime("%Y-%m-%d %H:%M:%S %z"),
                  "command": " ".join(sys.argv)[:400]}  # fmt: skip
        for _ in range(100):  # a lock file renamed or removed under us: open it again
            fd = cls._open(path)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                holder = _holder(fd)
                os.close(fd)
                raise SceneError(
                    f"{LOCK_KEYS.get(what, 'output.directory')}: {str(folder)!r} is in use by "
                    f"{holder}; one writer a folder: wait for it to end, or write elsewhere"
                ) from None
            except OSError as exc:
                os.close(fd)
                if exc.errno not in (errno.ENOLCK, errno.EOPNOTSUPP, errno.ENOSYS):
                    raise
                from ..progress import LOGGER

                LOGGER.warning("%s: the file system cannot lock %s (%s); a second writer into "
                               "the folder would not be refused", what, path, exc.strerror)
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
                fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW | os.O_NONBLOCK
                             | os.O_CLOEXEC, 0o644)  # fmt: skip
            except OSError as exc:
                if exc.errno not in (errno.ELOOP, errno.ENXIO, errno.EISDIR):
                    raise
                if exc.errno == errno.EISDIR:
                    raise IsADirectoryError(errno.EISDIR, "is a folder, not the lock file",
                                            str(path)) from None  # fmt: skip
                safe_files.remove_name(path)  # a link (ELOOP) or a FIFO without reader (ENXIO)
                continue
            info = os.fstat(fd)
            if stat.S_ISREG(info.st_mode) and info.st_nlink == 1:
                return fd
            os.close(fd)
            safe_files.remove_name(path)
        raise OSError(errno.EAGAIN, "the lock file keeps changing", str(path))

    def _write(self) -> None:
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


def holding_folders(function):
    """Decorator: the folder locks taken during a call of ``function`` (by
    :func:`prepare_output_dir` with ``lock``) are released when it returns or raises."""

    @functools.wraps(function)
    def call(*args, **kwargs):
        held: list[FolderLock] = []
        token = _HELD.set(held)
        try:
            return function(*args, **kwargs)
        finally:
            _HELD.reset(token)
            for lock in reversed(held):
                lock.release()

    return call


def held_lock(folder: Path) -> FolderLock | None:
    """The lock of ``folder`` held by the current :func:`holding_folders` call, if any."""
    for lock in _HELD.get() or []:
        if lock.folder == folder:
            return lock
    return None


def prepare_output_dir(path: Path, comm: MPI.Comm, lock: str | None = None,
                       run_id: str | None = None) -> Path:  # fmt: skip
    """Make ``path`` if needed and check that it can be written (collective); with ``lock``
    (the kind of writer: "run", "static", "restart", "sweep"), also take the folder's lock
    (:class:`FolderLock`, run id ``run_id`` if known) for the enclosing
    :func:`holding_folders` call, or refuse in one line naming its holder."""
    held = _HELD.get()
    if lock is not None and held is None:
        raise RuntimeError("prepare_output_dir(lock=...) outside a holding_folders call")
    key = LOCK_KEYS.get(lock or "run", "output.directory")
    problem: SceneError | None = None
    if comm.rank == 0:
        try:
            path.mkdir(parents=True, exist_ok=True)
            if lock is not None:
                held.append(FolderLock.take(path, lock, run_id))
            else:
                probe = path / f".write-test-{uuid.uuid4().hex}"  # a new name: nothing followed
                os.close(safe_files.create(probe))
                probe.unlink()
        except SceneError as exc:
            problem = exc
        except OSError as exc:
            problem = SceneError(f"{key}: cannot write to {str(path)!r} ({exc.strerror or exc})")
    agree(comm, problem)
    return path


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


def new_run_id(comm: MPI.Comm) -> str:
    """A new identity, the same on every rank."""
    return from_root(comm, uuid.uuid4().hex if comm.rank == 0 else None)


def _earlier_layout(folder: Path) -> list[Path]:
    """The HDF5 files and scratch XML of the earlier single-file layout (and of a killed
    XDMF rewrite): ``solution.h5``, ``solution-restart<n>.h5``, ``solution*.xdmf-partial``."""
    stem = Path(XDMF).stem
    names = [folder / f"{stem}.h5", *sorted(folder.glob(f"{stem}-restart*.h5"))]
    names += sorted(folder.glob(f"{stem}*.xdmf-partial"))
    return [p for p in names if p.is_symlink() or (p.exists() and not p.is_dir())]


def stale_outputs(folder: Path) -> list[tuple[Path, object | None]]:
    """What a new run removes of an earlier run's outputs in ``folder``, in this order (module
    docstring): (path, None) for a file, (folder, pattern) for the files of a folder whose
    names the pattern matches (:func:`cosserat_fem.safe_files.remove_own_files`): the
    checkpoint (its index first), the XDMF file (so that no XML names a removed file; a new
    series publishes its own), its frames, the files of the earlier single-file layout."""
    from .checkpoint import DIRECTORY, OWN_FILES
    from .xdmf import FRAME_NAME, frames_folder

    stale: list[tuple[Path, object | None]] = [(folder / DIRECTORY, OWN_FILES)]
    if (folder / XDMF).is_symlink() or (folder / XDMF).exists():
        stale.append((folder / XDMF, None))
    stale.append((frames_folder(folder / XDMF), FRAME_NAME))
    return stale + [(p, None) for p in _earlier_layout(folder)]


def conflict(folder: Path, writes_xdmf: bool, writes_checkpoint: bool) -> str | None:
    """Where something that is not the project's stands where a new run in ``folder`` must
    write (a folder at a file's name, a file at a folder's, a folder among the checkpoint's
    or the frames' files), the first such, in words; else None."""
    from .checkpoint import DIRECTORY, INDEX, OWN_FILES
    from .xdmf import FRAME_NAME, frames_folder

    files = [PROBES, SUMMARY, f"{SUMMARY}.tmp"]
    folders = []
    if writes_xdmf:
        files += [XDMF, f"{XDMF}-partial"]
        folders.append((frames_folder(folder / XDMF), FRAME_NAME, "XDMF frames"))
    if writes_checkpoint:
        folders.append((folder / DIRECTORY, OWN_FILES, "checkpoint"))
    for name in files:
        if (folder / name).is_dir() and not (folder / name).is_symlink():
            return f"{str(folder / name)!r} is a folder where the run writes its file {name}"
    for path, own, what in folders:
        if path.is_symlink() or not (path.exists() or path.is_symlink()):
            continue
        if not path.is_dir():
            kind = safe_files.kind(os.lstat(path).st_mode)
            return f"{str(path)!r} is {kind} where the run makes its {what} folder"
        for entry in os.scandir(path):
            if entry.is_dir(follow_symlinks=False) and (
                own.fullmatch(entry.name) or entry.name == INDEX
            ):
                return f"{str(Path(entry.path))!r} is a folder where the run writes its {what}"
    return None


def claim(folder: Path, comm: MPI.Comm, writes_xdmf: bool, summary: dict,
          writes_checkpoint: bool = False) -> None:  # fmt: skip
    """Make ``folder`` the new run's (module docstring): refuse, touching nothing, if
    something of the user's stands where the run writes (:func:`conflict`); else remove the
    stale outputs of an earlier run (:func:`stale_outputs`; the checkpoint's index first, so
    that a kill half-way leaves nothing to restart from), then write ``summary`` (status
    "running", the run id) before any other output. Collective."""
    from .checkpoint import INDEX

    problem = None
    if comm.rank == 0:
        lock = held_lock(folder)
        if lock is not None:
            lock.note(summary["run_id"])
        try:
            found = conflict(folder, writes_xdmf, writes_checkpoint)
            if found:
                problem = SceneError(
                    f"output.directory: {found}; it is not the run's to remove: move it, or "
                    "give another --out"
                )
            else:
                for path, own in stale_outputs(folder):
                    if own is None:
                        safe_files.remove_name(path)
                    else:
                        safe_files.remove_own_files(path, own, first=INDEX)
        except OSError as exc:
            problem = SceneError(
                f"output.directory: cannot remove the outputs of an earlier run in "
                f"{str(folder)!r} ({exc.strerror or exc})"
            )
    agree(comm, problem)
    write_summary(folder / SUMMARY, summary, comm)


def status_of(failure: BaseException | None) -> str:
    """summary.json's status of a run that ended with ``failure``: "completed" (none),
    "interrupted" (Ctrl-C), "stopped" (a StopError: an output, a limit; resumable) or
    "failed"."""
    from ..errors import StopError

    if failure is None:
        return "completed"
    if isinstance(failure, KeyboardInterrupt):
        return "interrupted"
    return "stopped" if isinstance(failure, StopError) else "failed"


def write_summary(path: Path, data: dict, comm: MPI.Comm, strict: bool = True) -> None:
    """Write summary.json atomically on rank 0 (collective). A failure is an OutputError on
    every rank, or, with ``strict=False`` (the summary at the end of a run that already
    stopped with an error), ignored: the earlier summary stays."""
    problem = None
    if comm.rank == 0:
        try:
            safe_files.replace(path, json.dumps(data, indent=2, sort_keys=False) + "\n")
        except OSError as exc:
            problem = OutputError(f"output: cannot write {str(path)!r} ({exc.strerror or exc})")
    if strict:
        agree(comm, problem)


def read_summary(path: str | Path) -> dict:
    """summary.json as a dict, with the fields that plot and render use checked: ``kind`` and
    ``scene.title`` strings, ``scene.rod.length`` a positive number, where present."""
    path = Path(path)
    text = decode(path, read_bytes(path, MAX_SUMMARY_BYTES))
    try:
        summary = json.loads(text)
    except (ValueError, RecursionError) as exc:  # RecursionError: [[[[... nested too deep
        message = str(exc) if isinstance(exc, ValueError) else "nested too deep"
        raise SceneError(f"{quoted(path)}: not JSON ({message})") from None
    if not isinstance(summary, dict):
        raise SceneError(
            f"{quoted(path)}: not a run's summary (a JSON object) but {json_kind(summary)}"
        )

    def bad(key: str, expected: str, value: object) -> SceneError:
        return SceneError(f"{quoted(path)}: {key} must be {expected}, got {json_kind(value)}")

    kind = summary.get("kind")
    if kind is not None and not isinstance(kind, str):
        raise bad("kind", "a string", kind)
    scene = summary.get("scene")
    if scene is None:
        return summary
    if not isinstance(scene, dict):
        raise bad("scene", "an object", scene)
    title = scene.get("title")
    if title is not None and not isinstance(title, str):
        raise bad("scene.title", "a string", title)
    rod = scene.get("rod")
    if rod is not None and not isinstance(rod, dict):
        raise bad("scene.rod", "an object", rod)
    length = (rod or {}).get("length")
    if length is not None:
        number = finite_number(length)
        if number is None or number <= 0:
            shown = json_kind(length)
            if not isinstance(length, bool) and isinstance(length, int | float):
                shown = repr(length) if len(repr(length)) <= 20 else repr(length)[:17] + "..."
            raise SceneError(
                f"{quoted(path)}: scene.rod.length must be a positive number, got {shown}"
            )
    return summary
