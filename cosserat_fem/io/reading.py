"""What every reader of a run's files checks: the file is a regular file of bounded size,
its text UTF-8, its numbers finite (cosserat_fem/output/results.py's module docstring, and the
readers of cosserat_fem/io/). Damaged, truncated, foreign or hostile files are bad input: a
:class:`SceneError` (exit 2) whose one-line message names the file at fault, most often first
(text taken from a file is quoted with ``repr``, so no control character reaches the terminal).

No DOLFINx, no MPI: numpy and the standard library only (``cosserat-fem plot``/``render`` run
on a machine without the solver stack).
"""

from __future__ import annotations

import math
from pathlib import Path

from cosserat_fem.common import safe_files
from cosserat_fem.common.errors import SceneError

#: Largest magnitude of a value read; beyond it matplotlib and VTK overflow (their ranges
#: and squares of values near 1e308 are inf) and no rod's output has it.
MAX_MAGNITUDE = 1e100


def quoted(path: str | Path) -> str:
    return repr(str(path))


def excerpt(text: str, size: int = 40) -> str:
    """``text`` from a file, for a message: quoted with ``repr`` (no control characters reach
    the terminal), shortened."""
    return repr(text if len(text) <= size else text[:size] + "...")


def short_reason(exc: BaseException, size: int = 160) -> str:
    """A library's exception, shortened for a message (HDF5's can run to 400 characters)."""
    text = " ".join(str(exc).split()) or type(exc).__name__
    return text if len(text) <= size else text[: size - 3] + "..."


def json_kind(value: object) -> str:
    """What a JSON value is, in words, for a message ("an object", "a number", ...)."""
    if isinstance(value, bool):
        return "a boolean"
    if value is None:
        return "null"
    names = {dict: "an object", list: "an array", str: "a string", int: "a number"}
    return names.get(type(value), "a number")


def is_file(path: Path) -> bool:
    """Whether there is a regular file at ``path`` (links followed); anything else there (a
    folder, a device, a FIFO, a dangling or looping link) is bad input."""
    try:
        if path.is_file():
            return True
        if not path.exists() and not path.is_symlink():
            return False
        if path.is_dir():
            problem = "is a folder, not a file"
        elif path.exists():
            problem = "is not a regular file (a device, FIFO or socket)"
        else:
            problem = "is a link to nothing (or a loop of links)"
    except (OSError, ValueError) as exc:  # ValueError: a NUL in the name
        raise SceneError(f"{quoted(path)}: cannot look at it ({exc})") from None
    raise SceneError(f"{quoted(path)}: {problem}")


def check_size(path: Path, limit: int, what: str = "") -> None:
    """SceneError if ``path`` cannot be looked at or holds more than ``limit`` bytes;
    ``what``: the kind of file, for the message (default: a run's output)."""
    try:
        size = path.stat().st_size
    except OSError as exc:
        raise SceneError(f"{quoted(path)}: cannot read it ({exc})") from None
    if size > limit:
        kind = f"{what} can have" if what else "a run's file can have; not a run's output"
        raise SceneError(f"{quoted(path)}: {size} bytes, more than the {limit >> 20} MiB {kind}")


def read_bytes(path: Path, limit: int) -> bytes:
    """The content of the regular file ``path``, refused if larger than ``limit`` bytes."""
    check_size(path, limit)
    try:
        data = safe_files.read_regular(path, limit)
    except OSError as exc:
        raise SceneError(f"{quoted(path)}: cannot read it ({exc.strerror or exc})") from None
    if len(data) > limit:
        raise SceneError(f"{quoted(path)}: more than {limit >> 20} MiB; not a run's output")
    return data


def decode(path: Path, data: bytes, where: str = "") -> str:
    """``data`` as UTF-8 text; SceneError naming the first bad byte and its offset (``where``: a
    prefix such as "line 3: ")."""
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise SceneError(
            f"{quoted(path)}: {where}not UTF-8 text (byte 0x{data[exc.start]:02x} at offset "
            f"{exc.start}); not a run's output"
        ) from None


def finite_number(value: object) -> float | None:
    """``value`` as a float if it is a finite JSON number within MAX_MAGNITUDE, else None."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        return None
    try:
        number = float(value)
    except OverflowError:
        return None
    return number if math.isfinite(number) and abs(number) <= MAX_MAGNITUDE else None
