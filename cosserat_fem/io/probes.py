"""probes.csv: the probe's row a step (or a load step), written by the rank that owns the
probe point (:class:`ProbeWriter`) and read back without DOLFINx (:func:`read_probe_table`).

The format, and its names, are kept here and nowhere else: the header ``t,x,y,z,theta,psi,phi``
(:data:`PROBE_COLUMNS`), optionally followed by the columns of ``output.probe_fields``
(:data:`PROBE_FIELD_COLUMNS`, in that order), then one row a step: t with 11 significant
digits, every other value with 17 (``%.16e``), separated by commas, each row ending in a
newline. Quantities in SI units: positions in m (x = ℓ p1, ...), angles in rad, time in s (the
load factor for a static run). The values are sampled by cosserat_fem/output/fields.py
(:class:`~cosserat_fem.output.fields.PointProbe`).

A run killed at any moment leaves whole rows and at most one cut last line, which the reader
and a restart drop (:class:`ProbeWriter`; docs/stability.md). probes.csv is made as a new
file, or, on a restart, continued as the folder's own copy: never written through a link
(cosserat_fem/common/safe_files.py).

What the reader checks (bad input otherwise: a :class:`SceneError` naming the file and line):
a regular file of at most :data:`MAX_PROBES_BYTES`, UTF-8; a known header (an empty file or a
cut header, a run killed as it made the file, reads as no rows); every whole line as many
finite numbers (at most :data:`~cosserat_fem.io.reading.MAX_MAGNITUDE` in magnitude) as the
header names, blank lines skipped; the text after the last newline dropped, whatever it holds.
"""

from __future__ import annotations

import hashlib
import itertools
import math
import os
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from cosserat_fem.common import safe_files
from cosserat_fem.common.errors import OutputError, SceneError
from cosserat_fem.common.parallel import agree
from cosserat_fem.io.reading import MAX_MAGNITUDE, check_size, decode, excerpt, quoted

if TYPE_CHECKING:
    from cosserat_fem.output.fields import PointProbe

#: The file's name in a run's folder.
PROBES = "probes.csv"
PROBE_COLUMNS = ("t", "x", "y", "z", "theta", "psi", "phi")
PROBE_HEADER = ",".join(PROBE_COLUMNS)
#: The columns that each choice of ``output.probe_fields`` appends to probes.csv, in this order
#: (the schema's choices): the unit quaternion (q0 the scalar part) of the rotation that takes
#: e_j to the directors d_j, continued in sign from row to row; the directors' components in
#: the fixed basis (d1_x = d1 · e1, ...); the displacement [m] of the centre of the rigid body
#: ([loads.body], forms/rigid_body.py) carried by the end the probe is at.
PROBE_FIELD_COLUMNS = {
    "quaternion": ("q0", "q1", "q2", "q3"),
    "directors": tuple(f"d{j}_{c}" for j in (1, 2, 3) for c in "xyz"),
    "body": ("body_x", "body_y", "body_z"),
    "contact": ("contact_qx", "contact_qy", "contact_qz", "contact_gap", "contact_state"),
}


def probe_columns(fields: tuple[str, ...] = ()) -> tuple[str, ...]:
    """probes.csv's columns with the ``output.probe_fields`` ``fields``: t, x, ..., φ, then each
    field's columns in the order of :data:`PROBE_FIELD_COLUMNS`."""
    extra = [c for name, cols in PROBE_FIELD_COLUMNS.items() if name in fields for c in cols]
    return (*PROBE_COLUMNS, *extra)


#: Every header a probes.csv may have (any subset of the fields, in their order), and its columns.
_HEADERS = {
    ",".join(columns): columns
    for n in range(len(PROBE_FIELD_COLUMNS) + 1)
    for columns in map(probe_columns, itertools.combinations(PROBE_FIELD_COLUMNS, n))
}
#: Largest probes.csv read [bytes]: ~150 bytes a row (about 7 million rows).
MAX_PROBES_BYTES = 1 << 30
#: Longest line of probes.csv [bytes] (a row is ~150).
MAX_LINE_BYTES = 4096


def read_probes(path: str | Path) -> np.ndarray:
    """Rows (t, x, y, z, θ, ψ, φ, ...) of probes.csv, (n, columns): the columns that its header
    names (:func:`read_probe_table`)."""
    return read_probe_table(path)[1]


def read_probe_table(path: str | Path) -> tuple[tuple[str, ...], np.ndarray]:
    """(columns, rows) of probes.csv: the header's names and the rows (n, len(columns)); a cut
    last line (a killed run) is dropped, an empty file or a cut header is no rows (of the base
    columns); anything else that is not a known header and as many finite numbers on each
    whole line is bad input (see the module docstring)."""
    path = Path(path)
    check_size(path, MAX_PROBES_BYTES)
    blocks: list[np.ndarray] = []
    rows: list[list[float]] = []
    try:
        with os.fdopen(safe_files.open_regular(path), "rb") as stream:
            first = stream.readline(MAX_LINE_BYTES)
            if not first.endswith(b"\n"):
                # No whole line: a run killed as it made the file left an empty file or a
                # cut header.
                if not stream.read(1) and any(h.encode().startswith(first) for h in _HEADERS):
                    return PROBE_COLUMNS, np.empty((0, len(PROBE_COLUMNS)))
                raise SceneError(
                    f"{quoted(path)}: not a probes.csv (no header line {PROBE_HEADER!r})"
                )
            header = decode(path, first, "line 1: ").rstrip("\n").rstrip("\r")
            columns = _HEADERS.get(header)
            if columns is None:
                raise SceneError(
                    f"{quoted(path)}: not a probes.csv (header {excerpt(header)}, expected "
                    f"{PROBE_HEADER!r} and the columns of output.probe_fields)"
                )
            number = 1
            while raw := stream.readline(MAX_LINE_BYTES):
                number += 1
                if not raw.endswith(b"\n"):
                    if stream.read(1):
                        raise SceneError(
                            f"{quoted(path)}: line {number} is longer than {MAX_LINE_BYTES} "
                            "bytes; not a probes.csv"
                        )
                    break  # the row being written when the run was killed
                row = _probe_row(path, number, raw, columns)
                if row is not None:
                    rows.append(row)
                if len(rows) == 65536:
                    blocks.append(np.array(rows))
                    rows = []
    except OSError as exc:
        raise SceneError(f"{quoted(path)}: cannot read it ({exc.strerror or exc})") from None
    blocks.append(np.array(rows, dtype=float).reshape(-1, len(columns)))
    return columns, np.concatenate(blocks)


def _probe_row(path: Path, number: int, raw: bytes, columns: tuple[str, ...]) -> list[float] | None:
    """The numbers of line ``number`` of probes.csv (None for a blank line)."""
    text = decode(path, raw, f"line {number}: ").rstrip("\n").rstrip("\r")
    if not text.strip():
        return None
    values = text.split(",")
    if len(values) != len(columns):
        raise SceneError(
            f"{quoted(path)}: line {number} has {len(values)} values, expected "
            f"{len(columns)} ({excerpt(','.join(columns), 200)})"
        )
    row = []
    for name, value in zip(columns, values, strict=True):
        try:
            v = float(value)
        except ValueError:
            raise SceneError(
                f"{quoted(path)}: line {number}, column {name}: {excerpt(value)} is not a number"
            ) from None
        if not (math.isfinite(v) and abs(v) <= MAX_MAGNITUDE):
            raise SceneError(
                f"{quoted(path)}: line {number}, column {name}: {v!r} is not a finite "
                f"number within ±{MAX_MAGNITUDE:g} (a run writes none)"
            )
        row.append(v)
    return row


def last_probe_row(path: Path) -> np.ndarray:
    """The last whole row of probes.csv (a restart's, already cut back to its checkpoint),
    as numbers."""
    with os.fdopen(safe_files.open_regular(path), "rb") as stream:
        stream.seek(0, os.SEEK_END)
        size = stream.tell()
        stream.seek(max(0, size - 4096))
        lines = stream.read().decode("utf-8").splitlines()
    return np.array([float(v) for v in lines[-1].split(",")])


def probe_prefix(path: Path, rows: int) -> tuple[int, Any]:
    """(bytes, sha256) of the header and the first ``rows`` rows of probes.csv."""
    digest = hashlib.sha256()
    end = 0
    with os.fdopen(safe_files.open_regular(path), "rb") as stream:
        for _ in range(rows + 1):
            line = stream.readline()
            if not line.endswith(b"\n"):
                raise SceneError(
                    f"--restart: {str(path)!r} holds fewer than the checkpoint's {rows} rows"
                )
            digest.update(line)
            end += len(line)
    return end, digest


class ProbeWriter:
    """``probes.csv`` with the header t,x,y,z,theta,psi,phi (and the columns of the probe's
    ``output.probe_fields``), written by the probe's owner.

    Rows are buffered and handed to the operating system when ``flush_every`` rows are pending,
    when ``max_delay`` seconds (wall time) have passed since the last flush, and before every
    XDMF frame (the run flushes its probes before it writes a frame,
    cosserat_fem/analysis/simulation.py and statics.py). So a killed run loses at most the rows
    since the last XDMF frame (7 rows at the default scene's 8 steps a frame) or of the last
    ``max_delay`` s, and probes.csv always reaches the last frame of the XDMF file
    (tests/test_kill.py; why not a flush every row: docs/decisions.md, "Probe rows: flushed in
    blocks, formatted in one call"). A SIGKILL inside the write() of a block can leave the block cut
    where a page of the file ends (Linux copies a write a page at a time and stops between pages for
    a fatal signal): the file then ends with part of a row, which
    :func:`cosserat_fem.output.results.read_probes` and a restart drop (docs/stability.md).

    The SHA-256 of the bytes written (:meth:`digest`) goes into each checkpoint, so that a
    restart can prove that probes.csv is the checkpointed run's (cosserat_fem/io/checkpoint.py).
    A write that fails (disk full, file size limit) raises :class:`OutputError` at once in
    serial; under MPI the owner keeps it and every rank raises it at :meth:`check`.
    """

    def __init__(
        self,
        path: Path,
        probe: PointProbe,
        flush_every: int = 200,
        max_delay: float = 0.05,
        resume: bool = False,
    ):
        """``resume``: continue the existing file (a restart, which has cut it back; a link
        is continued as the folder's own copy), else make a new file (never written through a
        link, module docstring)."""
        self.path = Path(path)
        self.probe = probe
        self.comm = probe.U.function_space.mesh.comm
        self.flush_every = flush_every
        self.max_delay = max_delay
        self.error: OutputError | None = None
        self._pending = 0
        self._rows = np.empty((flush_every, len(probe.columns)))
        self._format = "%.10e," + ",".join(["%.16e"] * (len(probe.columns) - 1)) + "\n"
        self._file = None
        self._deadline = 0.0
        self._sha = hashlib.sha256()
        if probe.is_owner:
            try:
                if resume:
                    fd = safe_files.open_append(path)
                    self._file = os.fdopen(fd, "a", encoding="utf-8")
                    self._sha.update(safe_files.read_fd(fd))
                else:
                    self._file = os.fdopen(safe_files.create(path), "w", encoding="utf-8")
            except OSError as exc:
                self._fail(exc)
            if not resume:
                self._write(",".join(probe.columns) + "\n")
            self.flush()
        self.check()

    def _fail(self, exc: OSError) -> None:
        """Keep the OutputError of a failed write and write no more; raised at once in serial, at
        :meth:`check` under MPI."""
        self.error = OutputError(
            f"output: cannot write {str(self.path)!r} ({exc.strerror or exc}); the rows "
            "before are kept"
        )
        self._file = None
        if self.comm.size == 1:
            raise self.error

    def _write(self, text: str) -> None:
        """``text`` to the file (flushed) and into the SHA-256; a failure goes to :meth:`_fail`."""
        if self._file is None:
            return
        try:
            self._file.write(text)
            self._file.flush()
        except OSError as exc:
            self._fail(exc)
            return
        self._sha.update(text.encode("utf-8"))

    def check(self) -> None:
        """Raise, on every rank, an error the owner met (collective under MPI)."""
        agree(self.comm, self.error)

    def write(self, t: float) -> None:
        """Buffer the row of time t; see the class docstring for when rows go to the file."""
        if self._file is None:
            return
        row = self._rows[self._pending]
        row[0] = t
        row[1:] = self.probe.values()
        self._pending += 1
        if self._pending >= self.flush_every or time.monotonic() >= self._deadline:
            self.flush()

    def flush(self, sync: bool = False) -> None:
        """Hand the pending rows to the operating system; ``sync``: fsync too (at the end)."""
        if self._file is not None:
            if self._pending:
                # One formatting call for the whole block (docs/decisions.md, "Probe rows").
                block = tuple(self._rows[: self._pending].ravel())
                self._pending = 0
                self._write((self._format * (len(block) // len(self.probe.columns))) % block)
            if sync and self._file is not None:
                try:
                    os.fsync(self._file.fileno())
                except OSError as exc:
                    self._fail(exc)
            self._deadline = time.monotonic() + self.max_delay

    def digest(self) -> str | None:
        """SHA-256 of what probes.csv holds (rows pending are written first); None off the
        owner."""
        if not self.probe.is_owner:
            return None
        self.flush()
        return self._sha.hexdigest()

    def close(self) -> None:
        """Flush, fsync and close the owner's file; a failure is handled as by :meth:`_fail`."""
        if self._file is not None:
            self.flush(sync=True)
            if self._file is not None:
                self._file.close()
            self._file = None
