"""Crash-safe and quiet JIT compilation of forms (FFCx 0.5, as used by DOLFINx 0.5).

FFCx marks a compile in progress by creating ``<cache>/<module>.c`` (``open(..., "x")``) and
marks it done by creating ``<module>.c.cached``; a process that finds ``.c`` without
``.c.cached`` waits ``timeout`` (10) seconds and fails with "JIT compilation timed out". A
compile killed by Ctrl-C or SIGKILL leaves that pair behind (FFCx renames ``.c`` to
``.c.failed`` only on ``Exception``), so every later run that needs the module failed until the
file was deleted by hand. And gcc, run by cffi/distutils in a subprocess that inherits file
descriptor 2, printed its warnings (Debian builds with ``-Wall``) around our one-line messages.

:func:`install` patches ``ffcx.codegeneration.jit`` (the functions are module globals that
FFCx and ``dolfinx.jit`` look up at call time) so that

* "somebody is compiling this module right now" is an advisory lock, ``fcntl.flock`` on
  ``<cache>/<module>.lock``, held by the compiling process from the cache lookup until the
  compile has ended (success or failure) and released by the kernel when that process dies,
  SIGKILL included. A process that gets the lock and finds ``.c`` without ``.c.cached`` knows
  the earlier compile died: it removes the leftovers and compiles. One that cannot get the lock
  waits for the live compiler (at least :data:`WAIT_TIMEOUT` seconds), then fails with a
  message naming the file and the process holding it.
* a warm cache (``.c.cached`` present) is loaded without taking the lock, as before; so are the
  other MPI ranks after rank 0 compiled (``dolfinx.jit.mpi_jit_decorator``).
* during the C compile, file descriptor 2 goes to a temporary file: compiler warnings do not
  reach the terminal (they are logged at INFO on ``cosserat_fem.common.jit``: ``--verbose``). A
  failed compile raises :class:`JITCompileError`, one line with the compiler's first error and the
  path of the full log, ``<cache>/<module>.log``.
* an interrupted compile (KeyboardInterrupt, SystemExit) renames ``.c`` to ``.c.failed`` as
  FFCx does for errors, so that even processes without :func:`install` are not blocked.
* a compile that succeeded leaves no object file and an empty ``.c`` (the marker FFCx reads),
  not the source: 70 % of a cache's size (:func:`_trim`).
* a damaged library in the cache (a partial copy of the cache, a disk error) is found before it
  is loaded and compiled again, with a warning naming it: FFCx trusts ``.c.cached``, and a
  library cut short is mapped by ``dlopen`` past its end, so the first call into it dies of
  SIGBUS (under PETSc's handler: "Caught signal number 7 BUS" and exit 59); a missing one was
  "ModuleNotFoundError: Unable to find JIT module". :func:`library_damage` checks the file
  against the SHA-256 recorded beside it (``<library>.sha256``, written after each compile
  and, for libraries compiled without it, after their first good load) or, without a record,
  its ELF structure (every table and loaded segment inside the file); a load that still fails
  (ImportError, OSError) counts as damage too. The same check guards the project's own
  compiled C (cosserat_fem/nls/native_newton.py).

Processes that share a cache directory should all use :func:`install`: a plain FFCx process
compiling a module holds no lock, so a patched one that needs the same module at the same time
takes its ``.c`` for the leftover of a dead compile.
"""

from __future__ import annotations

import contextlib
import fcntl
import functools
import hashlib
import importlib.machinery
import importlib.util
import logging
import os
import re
import socket
import struct
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from cosserat_fem.common.errors import CosseratError

__all__ = [
    "WAIT_TIMEOUT",
    "JITCompileError",
    "JITLockTimeout",
    "capture_stderr",
    "install",
    "installed",
    "library_damage",
    "load_checked",
    "record_digest",
    "uninstall",
]

LOGGER = logging.getLogger("cosserat_fem.common.jit")

#: Minimum time [s] to wait for another process's compile of the same module (FFCx's own
#: ``timeout`` jit parameter, 10 s by default, is used when larger).
WAIT_TIMEOUT = 300.0

_PATCHED = (
    "get_cached_module",
    "_compile_objects",
    "compile_forms",
    "compile_expressions",
    "compile_elements",
)
_originals: dict[str, Callable[..., Any]] = {}
_install_lock = threading.Lock()
_local = threading.local()


class JITCompileError(CosseratError):
    """The C compiler failed on a JIT module; one line naming the full compiler log.

    Attributes:
        module: the module name (``libffcx_forms_<hash>`` etc.).
        log_path: the file holding the compiler's complete output.
        first_error: the compiler's first error line, if one was recognised.
    """

    def __init__(self, module: str, log_path: Path, first_error: str | None) -> None:
        self.module = module
        self.log_path = log_path
        self.first_error = first_error
        what = first_error or "the C compiler failed"
        super().__init__(f"JIT compilation of {module} failed: {what} (full log: {log_path})")


class JITLockTimeout(CosseratError, TimeoutError):
    """Another live process kept compiling the same module for longer than the wait."""


# --------------------------------------------------------------------------------------------
# Compiler output
# --------------------------------------------------------------------------------------------


@dataclass
class Captured:
    """What :func:`capture_stderr` caught; ``text`` is filled in when the block ends."""

    text: str = ""
    redirected: bool = False


@contextlib.contextmanager
def capture_stderr() -> Iterator[Captured]:
    """Send file descriptor 2 (and so ``sys.stderr`` and every subprocess started meanwhile,
    such as gcc) to a temporary file for the duration of the block.

    Process-wide: other threads' stderr output during the block is caught too. When fd 2
    cannot be duplicated (closed), nothing is redirected.
    """
    captured = Captured()
    with contextlib.suppress(Exception):
        sys.stderr.flush()
    try:
        tmp = tempfile.TemporaryFile()
    except OSError:
        yield captured
        return
    try:
        saved = os.dup(2)
    except OSError:
        tmp.close()
        yield captured
        return
    try:
        os.dup2(tmp.fileno(), 2)
        captured.redirected = True
        try:
            yield captured
        finally:
            with contextlib.suppress(Exception):
                sys.stderr.flush()
            os.dup2(saved, 2)
            tmp.seek(0)
            captured.text = tmp.read().decode(errors="replace")
    finally:
        os.close(saved)
        tmp.close()


_ERROR_LINE = re.compile(r"(?:^|: )(?:fatal )?error: ", re.IGNORECASE)
_LINKER_LINE = re.compile(r"(?:^|/)ld(?:\.\w+)?: |undefined reference", re.IGNORECASE)


def first_error_line(text: str, limit: int = 300) -> str | None:
    """The compiler's first error line in ``text`` (gcc/clang ``...: error: ...``; for a link
    failure the linker's first line rather than ``collect2: error: ld returned 1``)."""
    lines = [line.strip() for line in text.splitlines() if line.strip()]
    found = None
    for i, line in enumerate(lines):
        if _ERROR_LINE.search(line):
            found = line
            if line.startswith("collect2:"):
                found = next((x for x in lines[:i] if _LINKER_LINE.search(x)), line)
            break
    if found is None:
        found = next((x for x in lines if _LINKER_LINE.search(x)), None)
    if found is not None and len(found) > limit:
        found = found[: limit - 3] + "..."
    return found


# --------------------------------------------------------------------------------------------
# Damaged libraries
# --------------------------------------------------------------------------------------------

#: The suffix of the file beside a compiled library that holds its SHA-256 (hex, one line).
DIGEST_SUFFIX = ".sha256"


def _digest_path(library: Path) -> Path:
    return library.with_name(library.name + DIGEST_SUFFIX)


def record_digest(library: Path) -> None:
    """Write ``library``'s SHA-256 beside it (atomically; nothing if the cache is read-only)."""
    try:
        digest = hashlib.sha256(library.read_bytes()).hexdigest()
        fd, name = tempfile.mkstemp(prefix=library.name + ".", suffix=".tmp", dir=library.parent)
        try:
            os.fchmod(fd, 0o644)  # readable by the others who share the cache, as the library
            with os.fdopen(fd, "w") as stream:
                stream.write(digest + "\n")
            os.replace(name, _digest_path(library))
        except BaseException:
            with contextlib.suppress(OSError):
                os.unlink(name)
            raise
    except OSError as exc:
        LOGGER.debug("no digest recorded for %s (%s)", library, exc)


def library_damage(library: Path) -> str | None:
    """Why the compiled library ``library`` must not be loaded, or None if it looks whole.

    With a recorded digest (:func:`record_digest`), whether the bytes are still those; without
    one, :func:`elf_damage`: a library cut short (the usual damage of a partial copy or a
    full disk) has tables or segments past its end, which ``dlopen`` maps and the first use
    of which raises SIGBUS, a signal no Python code can catch."""
    try:
        data = library.read_bytes()
    except FileNotFoundError:
        return "it is missing"
    except OSError as exc:
        return f"it cannot be read ({exc.strerror or exc})"
    try:
        recorded = _digest_path(library).read_text(encoding="ascii", errors="replace").strip()
    except OSError:
        recorded = None
    if recorded is not None:
        if hashlib.sha256(data).hexdigest() != recorded:
            return f"its bytes are not those compiled (SHA-256 in {_digest_path(library).name})"
        return None
    return elf_damage(data)


_PT_LOAD, _SHT_NOBITS, _SHT_STRTAB = 1, 8, 3


def elf_damage(data: bytes) -> str | None:
    """What is wrong with the ELF shared object ``data`` (64-bit; 32-bit objects are not
    checked), or None: the file must hold its program header table, every loaded segment
    (p_offset + p_filesz), its section header table and every section with contents, and the
    section of section names must be a string table (a tail of zeros, as a crash can leave
    in a file whose size was set but whose last blocks were not written, fails that)."""
    size = len(data)
    if size == 0:
        return "it is empty"
    if size < 64 or data[:4] != b"\x7fELF":
        return "it is not an ELF shared object"
    if data[4] != 2 or data[5] not in (1, 2):
        return None  # not a 64-bit object: no structural check
    order = "<" if data[5] == 1 else ">"
    phoff, shoff = struct.unpack_from(order + "QQ", data, 32)
    phentsize, phnum, shentsize, shnum, shstrndx = struct.unpack_from(order + "5H", data, 54)
    cut = f"it is cut short ({size} bytes)"
    if phoff + phnum * phentsize > size or (shnum and shoff + shnum * shentsize > size):
        return cut
    for i in range(phnum):
        kind, offset, length = _fields(
            data, order, phoff + i * phentsize, (0, "I"), (8, "Q"), (32, "Q")
        )
        if kind == _PT_LOAD and offset + length > size:
            return cut
    for i in range(shnum):
        kind, offset, length = _fields(
            data, order, shoff + i * shentsize, (4, "I"), (24, "Q"), (32, "Q")
        )
        if kind != _SHT_NOBITS and offset + length > size:
            return cut
    if shnum and shstrndx < shnum:
        if _fields(data, order, shoff + shstrndx * shentsize, (4, "I"))[0] != _SHT_STRTAB:
            return "its section headers are damaged"
    return None


def _fields(data: bytes, order: str, base: int, *fields: tuple[int, str]) -> list[int]:
    return [struct.unpack_from(order + kind, data, base + at)[0] for at, kind in fields]


def _library(cache_dir: Path, module_name: str) -> Path:
    """The file FFCx loads for ``module_name`` (its first extension suffix found, as
    importlib's FileFinder looks them up), or where the compile puts it."""
    for suffix in importlib.machinery.EXTENSION_SUFFIXES:
        path = cache_dir / (module_name + suffix)
        if path.exists():
            return path
    return cache_dir / (module_name + importlib.machinery.EXTENSION_SUFFIXES[0])


def load_checked(library: Path, load: Callable[[], Any]) -> tuple[Any, str | None]:
    """(``load()``, None), or (None, why ``library`` must be compiled again): the library is
    checked (:func:`library_damage`) before ``load`` maps it, and a load that fails
    (ImportError, OSError: not a library, a missing symbol; AttributeError: an object
    missing from it) is damage too. A library that loads and had no digest gets one."""
    damage = library_damage(library)
    if damage is not None:
        return None, damage
    try:
        loaded = load()
    except (ImportError, OSError, AttributeError) as exc:
        return None, f"it does not load: {type(exc).__name__}: {exc}"
    if not _digest_path(library).exists():
        record_digest(library)
    return loaded, None


def warn_damaged(library: Path, damage: str) -> None:
    """The one line that says a cached library is compiled again, and why."""
    LOGGER.warning("the JIT cache holds a damaged %s (%s): compiling it again", library, damage)


# --------------------------------------------------------------------------------------------
# The per-module lock
# --------------------------------------------------------------------------------------------


@dataclass
class _Held:
    fd: int
    c_file: Path


def _frames() -> list[list[_Held]]:
    """Per thread: one list per active compile_* call, of the locks taken inside it."""
    frames = getattr(_local, "frames", None)
    if frames is None:
        frames = _local.frames = []
    return frames


def _orphans() -> dict[str, _Held]:
    """Per thread: locks taken by get_cached_module called outside a patched compile_*."""
    orphans = getattr(_local, "orphans", None)
    if orphans is None:
        orphans = _local.orphans = {}
    return orphans


def _holder(lock_path: Path) -> str:
    """Who holds ``lock_path``, as the holder wrote it (``process <pid> on <host>``)."""
    try:
        text = lock_path.read_text().split()
    except OSError:
        text = []
    if len(text) >= 2 and text[0].isdigit():
        where = "" if text[1] == socket.gethostname() else f" on {text[1]}"
        return f"process {text[0]}{where}"
    return "another process"


def _acquire(lock_path: Path, c_file: Path, wait: float) -> int:
    """An fd holding the exclusive flock on ``lock_path``, waiting up to ``wait`` seconds."""
    fd = os.open(lock_path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o666)
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            _wait_for_lock(fd, lock_path, c_file, wait)
        with contextlib.suppress(OSError):
            os.ftruncate(fd, 0)
            os.pwrite(fd, f"{os.getpid()} {socket.gethostname()}\n".encode(), 0)
        return fd
    except BaseException:
        os.close(fd)
        raise


def _wait_for_lock(fd: int, lock_path: Path, c_file: Path, wait: float) -> None:
    """Poll ``fd``'s flock (backing off to every 0.2 s) until it is ours; JITLockTimeout naming
    the holder after ``wait`` seconds."""
    start = time.monotonic()
    pause, told = 0.01, False
    LOGGER.debug("waiting for %s to finish compiling %s", _holder(lock_path), c_file)
    while True:
        time.sleep(pause)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            return
        except BlockingIOError:
            pass
        waited = time.monotonic() - start
        if not told and waited > 5.0:
            LOGGER.info("waiting for %s to finish compiling %s", _holder(lock_path), c_file)
            told = True
        if waited >= wait:
            holder = _holder(lock_path)
            raise JITLockTimeout(
                f"JIT compilation of {c_file} is still running in {holder} after {waited:.3g} s; "
                f"wait for it, or stop it and run again (a compile that died leaves nothing to "
                f"delete; should that process no longer exist, delete its lock {lock_path})"
            )
        pause = min(0.2, pause * 1.5)


def _release(held: _Held) -> None:
    with contextlib.suppress(OSError):
        os.close(held.fd)  # closing the only fd of the open file releases the flock


def _mark_interrupted(c_file: Path) -> None:
    """After KeyboardInterrupt/SystemExit: ``.c`` → ``.c.failed`` as FFCx does on errors."""
    if c_file.exists() and not c_file.with_suffix(".c.cached").exists():
        with contextlib.suppress(OSError):
            os.replace(c_file, c_file.with_suffix(".c.failed"))


def _trim(cache_dir: Path, module_name: str) -> None:
    """After a compile that succeeded: its object file removed and its source emptied (70 %
    of a cache: 49 and 129 of 254 MB measured), neither read again. The empty ``.c`` stays:
    plain FFCx takes an existing ``.c`` for "compiled or compiling" and loads the library once
    ``.c.cached`` is there; without it, it would compile the module again. The locks stay
    too: a lock file removed while another process has it open would let a third lock a new
    file of the same name at once."""
    with contextlib.suppress(OSError):
        (cache_dir / (module_name + ".o")).unlink()
    with contextlib.suppress(OSError):
        os.truncate(cache_dir / (module_name + ".c"), 0)


def _remove_leftovers(cache_dir: Path, module_name: str) -> None:
    """Files of a compile that died, or of a damaged module: source, object, library, its
    digest and the ``.c.cached`` marker (removed first: a reader then takes the lock)."""
    names = [module_name + ".c.cached", module_name + ".c", module_name + ".o"]
    for suffix in importlib.machinery.EXTENSION_SUFFIXES:
        names += [module_name + suffix, module_name + suffix + DIGEST_SUFFIX]
    for name in names:
        with contextlib.suppress(FileNotFoundError):
            (cache_dir / name).unlink()


# --------------------------------------------------------------------------------------------
# The replacements
# --------------------------------------------------------------------------------------------


def _load(cache_dir: Path, module_name: str, object_names):
    """(objects, module) of a compiled FFCx module, or (None, why it must be compiled again)
    (:func:`load_checked`). The library file is loaded by its path (:func:`_library`: the
    suffix FFCx's finder would take), not by FFCx's ``_load_objects``, whose FileFinder lists
    the whole cache folder at every form: 5-10 ms at 16 000 files, most of a test suite's
    time once many modules are cached (docs/developers.md)."""
    library = _library(cache_dir, module_name)

    def load():
        loader = importlib.machinery.ExtensionFileLoader(module_name, str(library))
        spec = importlib.util.spec_from_file_location(module_name, library, loader=loader)
        if spec is None:
            raise ImportError(f"no module spec for {library}")
        module = importlib.util.module_from_spec(spec)
        loader.exec_module(module)
        return [getattr(module.lib, name) for name in object_names], module

    return load_checked(library, load)


def _get_cached_module(module_name, object_names, cache_dir, timeout):
    """FFCx's get_cached_module with the lock: (objects, module) from the cache, or
    (None, None) with the lock held and ``.c`` created, for the caller to compile."""
    cache_dir = Path(cache_dir)
    c_file = cache_dir / (module_name + ".c")
    ready = cache_dir / (module_name + ".c.cached")
    if ready.exists():  # written last, after the library: a warm cache needs no lock
        loaded, damage = _load(cache_dir, module_name, object_names)
        if damage is None:
            return loaded

    cache_dir.mkdir(exist_ok=True, parents=True)
    lock_path = cache_dir / (module_name + ".lock")
    stale = _orphans().pop(str(c_file), None)  # ours, from a call that never compiled
    if stale is not None:
        _release(stale)
    try:
        fd = _acquire(lock_path, c_file, max(float(timeout or 0), WAIT_TIMEOUT))
    except JITLockTimeout:
        raise
    except OSError as exc:  # e.g. a read-only cache shared with us: FFCx's protocol
        LOGGER.debug("no lock %s (%s); plain FFCx cache protocol", lock_path, exc)
        return _originals["get_cached_module"](module_name, object_names, cache_dir, timeout)
    held = _Held(fd, c_file)
    try:
        if ready.exists():  # compiled by the process we waited for, or damaged
            loaded, damage = _load(cache_dir, module_name, object_names)
            if damage is None:
                _release(held)
                return loaded
            warn_damaged(_library(cache_dir, module_name), damage)
            _remove_leftovers(cache_dir, module_name)
        elif c_file.exists():
            LOGGER.info("removing the leftovers of an interrupted JIT compile: %s", c_file)
            _remove_leftovers(cache_dir, module_name)
        open(c_file, "x").close()  # FFCx's in-progress marker
    except BaseException:
        _release(held)
        raise
    frames = _frames()
    if frames:
        frames[-1].append(held)
    else:
        _orphans()[str(c_file)] = held
    return None, None


def _compile_objects(
    decl, ufl_objects, object_names, module_name, parameters, cache_dir, *args, **kwargs
):
    """FFCx's _compile_objects with fd 2 captured; compiler failures as JITCompileError."""
    cache_dir = Path(cache_dir)
    c_file = cache_dir / (module_name + ".c")
    original = _originals["_compile_objects"]
    try:
        captured = Captured()
        try:
            with capture_stderr() as captured:
                result = original(
                    decl,
                    ufl_objects,
                    object_names,
                    module_name,
                    parameters,
                    cache_dir,
                    *args,
                    **kwargs,
                )
        except Exception as exc:
            log_path = _write_log(cache_dir, module_name, c_file, exc, captured.text)
            if _is_compiler_error(exc):
                raise JITCompileError(
                    module_name, log_path, first_error_line(captured.text)
                ) from exc
            raise
        if captured.text.strip():  # warnings of a compile that succeeded: shown at --verbose
            LOGGER.info("C compiler output for %s:\n%s", module_name, captured.text.rstrip())
        record_digest(_library(cache_dir, module_name))
        _trim(cache_dir, module_name)
        return result
    except BaseException as exc:
        if not isinstance(exc, Exception):  # FFCx's own clean-up runs on Exception only
            _mark_interrupted(c_file)
        raise
    finally:
        held = _orphans().pop(str(c_file), None)
        if held is not None:
            _release(held)


def _is_compiler_error(exc: BaseException) -> bool:
    """Whether ``exc`` is cffi's VerificationError: the C compiler or the linker failed."""
    try:
        from cffi import VerificationError
    except ImportError:  # pragma: no cover - FFCx needs cffi
        return False
    return isinstance(exc, VerificationError)


def _write_log(
    cache_dir: Path, module_name: str, c_file: Path, exc: BaseException, output: str
) -> Path:
    """The exception and the compiler's ``output`` in ``<cache>/<module>.log`` (a temporary file
    if the cache is not writable); returns its path."""
    log_path = cache_dir / (module_name + ".log")
    text = (
        f"JIT compilation of {module_name} failed: {type(exc).__name__}: {exc}\n"
        f"source: {c_file.with_suffix('.c.failed')} (renamed from {c_file.name})\n"
        f"--- compiler output (stderr) ---\n{output}"
    )
    try:
        log_path.write_text(text)
    except OSError:
        fd, name = tempfile.mkstemp(prefix=module_name + ".", suffix=".log")
        with os.fdopen(fd, "w") as f:
            f.write(text)
        log_path = Path(name)
    return log_path


def _wrap_compile(original: Callable[..., Any]) -> Callable[..., Any]:
    """compile_forms & co.: release the locks taken inside the call once it has ended, i.e.
    after FFCx's own failure handling (``.c`` → ``.c.failed``) and the load on success."""

    @functools.wraps(original)
    def compile_(*args, **kwargs):
        """``original`` with a frame for the locks taken inside it, released when it ends; an
        interrupted compile renames their ``.c`` to ``.c.failed``."""
        frames = _frames()
        frames.append([])
        try:
            return original(*args, **kwargs)
        except BaseException as exc:
            if not isinstance(exc, Exception):
                for held in frames[-1]:
                    _mark_interrupted(held.c_file)
            raise
        finally:
            for held in frames.pop():
                _release(held)

    return compile_


_REPLACEMENTS: dict[str, Callable[..., Any]] = {
    "get_cached_module": _get_cached_module,
    "_compile_objects": _compile_objects,
}


def install(wait_timeout: float | None = None) -> bool:
    """Patch FFCx's JIT cache (idempotent; cheap when already installed).

    ``wait_timeout``: if given, the new :data:`WAIT_TIMEOUT`. Returns False (and patches
    nothing) when FFCx is not importable or lacks the functions patched (another version).
    """
    global WAIT_TIMEOUT
    if wait_timeout is not None:
        WAIT_TIMEOUT = float(wait_timeout)
    if _originals:
        return True
    with _install_lock:
        if _originals:
            return True
        try:
            import ffcx.codegeneration.jit as ffcx_jit
        except ImportError:
            return False
        if not all(callable(getattr(ffcx_jit, name, None)) for name in _PATCHED):
            LOGGER.debug("ffcx.codegeneration.jit is not the FFCx 0.5 layout: not patched")
            return False
        originals = {name: getattr(ffcx_jit, name) for name in _PATCHED}
        for name in _PATCHED:
            replacement = _REPLACEMENTS.get(name) or _wrap_compile(originals[name])
            setattr(ffcx_jit, name, replacement)
        _originals.update(originals)
    return True


def uninstall() -> None:
    """Restore FFCx's functions (for tests)."""
    with _install_lock:
        if not _originals:
            return
        import ffcx.codegeneration.jit as ffcx_jit

        for name, function in _originals.items():
            setattr(ffcx_jit, name, function)
        _originals.clear()


def installed() -> bool:
    return bool(_originals)
