"""Exceptions of cosserat-fem.

Every error the user can cause or meet is a :class:`CosseratError` carrying a one-line message,
so that the command line can print it without a traceback:

* :class:`SceneError`: bad input (scene file, ``--set`` overrides). The message starts with the
  dotted key at fault, e.g. ``rod.material.poisson_ratio: must lie in (-1, 0.5), got 0.7``.
* :class:`SolverError`: numerical trouble during a run (Newton divergence, a singular
  Jacobian, non-finite values), with the time and place where it happened and a suggestion.
* :class:`StopError`: the run stopped for a reason outside its numerics, keeping what it
  wrote and its checkpoint so that ``run --restart`` continues it: an output that could not be
  written (:class:`OutputError`: disk full, file size limit, I/O error) or a limit of the
  scene reached (:class:`LimitReached`: ``limits.wall_time``).

Exit status of the command line: 2 SceneError, 3 SolverError, 4 StopError, 1 anything else.
"""

from __future__ import annotations

import datetime
from pathlib import Path


def _one_line(text: str) -> str:
    """Collapse ``text`` to a single line (newlines and runs of blanks become one space)."""
    return " ".join(str(text).split())


class CosseratError(Exception):
    """Base class of all cosserat-fem errors; ``str()`` is a single line."""

    def __init__(self, message: str) -> None:
        self.message = _one_line(message)
        super().__init__(self.message)

    def __str__(self) -> str:
        return self.message


class SceneError(CosseratError):
    """Invalid scene input; the message starts with the dotted key at fault."""


class SolverError(CosseratError):
    """Numerical failure of a run.

    Attributes:
        time: simulation time [s] at which it happened, if known.
        where: the component involved (e.g. ``"newton"``, ``"linear solver"``), if known.
        reason: what went wrong.
        suggestion: what the user might change (e.g. ``"reduce time.step"``), if any.
        retry: whether a smaller step may avoid it (Newton failure, non-finite values, a step
            over the chart singularity), as opposed to a state that is itself the trouble.
    """

    def __init__(
        self,
        reason: str,
        *,
        time: float | None = None,
        where: str | None = None,
        suggestion: str | None = None,
        retry: bool = False,
    ) -> None:
        self.retry = retry
        self.time = time
        self.where = where
        self.reason = _one_line(reason)
        self.suggestion = _one_line(suggestion) if suggestion else None
        super().__init__(self._compose())

    def _compose(self) -> str:
        """The one-line message: ``[where] at t = ... s: reason; suggestion``."""
        head = []
        if self.where:
            head.append(self.where)
        if self.time is not None:
            head.append(f"at t = {self.time:.6g} s")
        text = (" ".join(head) + ": " if head else "") + self.reason
        if self.suggestion:
            text += f" (suggestion: {self.suggestion})"
        return text


class StopError(CosseratError):
    """The run stopped with its outputs and checkpoint kept; ``run --restart`` continues it."""


class OutputError(StopError):
    """An output (probes, XDMF/HDF5, checkpoint, summary) could not be written."""


class LimitReached(StopError):
    """The run reached a limit of its scene (``limits.wall_time``)."""


def show_value(value: object) -> str:
    """Render a user-supplied value the way it would be written in TOML, for error messages.

    ``True`` → ``true``, strings in double quotes, floats via ``repr`` (``nan``, ``inf``),
    lists element-wise, dates and times as ISO 8601 (as TOML writes them); anything else
    via ``repr``. Long renderings are shortened.
    """
    if isinstance(value, bool):
        text = "true" if value else "false"
    elif isinstance(value, str):
        text = '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    elif isinstance(value, float | int):
        text = repr(value)
    elif isinstance(value, list | tuple):
        text = "[" + ", ".join(show_value(v) for v in value) + "]"
    elif isinstance(value, dict):
        text = "{" + ", ".join(f"{k} = {show_value(v)}" for k, v in value.items()) + "}"
    elif isinstance(value, datetime.date | datetime.time):  # a TOML date or time
        text = value.isoformat()
    else:
        text = repr(value)
    text = _one_line(text)
    return text if len(text) <= 120 else text[:117] + "..."


def out_folder(out: object, option: str = "out (--out)") -> Path | None:
    """The folder that an ``out`` argument (the command line's ``--out``) names, as a Path, or
    None if none was given; a SceneError naming ``option`` for an empty name (``--out ''``
    was the current folder, or the scene's output.directory) or a path that exists and is not
    a folder."""
    if out is None:
        return None
    if not isinstance(out, str | Path) or str(out) == "":
        raise SceneError(f"{option}: must name a folder, got {out!r}")
    folder = Path(out)
    if folder.exists() and not folder.is_dir():
        raise SceneError(f"{option}: {str(out)!r} is not a folder")
    return folder
