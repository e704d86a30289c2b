"""Loads from data: a load component given by a table of values (a CSV file of t, or of t and
s, against values) or by a Python callable, in place of an expression (docs/loads.md).

Where. Any component of ``loads.force_density`` [N/m] and ``loads.torque_density`` [N m/m]
(functions of t and s), of ``loads.start``/``loads.end``/``loads.point`` ``force`` [N] and
``torque`` [N m] (of t only), and of ``supports.start_motion``/``end_motion`` [m] (of t only; a
table, not a callable, for a prescribed motion needs its rate and acceleration). Units are
those of the expression the component replaces; t in s, s in m.

A table in a scene is an inline table in the component's place::

    [loads.end]
    force = [0, 0, {table = "tip.csv", column = "F", interpolation = "cubic"}]

with the keys of :data:`cosserat_fem.scene.schema.LOAD_TABLE`: ``table`` (the file, relative to the
scene file; to the working directory for a dict given to ``cf.load``), ``column`` (the value
column), ``interpolation`` (in t), ``s_interpolation`` (a grid's, in s), ``outside`` and
``sha256`` (optional: the SHA-256 the file's content must have).

The file. UTF-8 text, comma-separated; blank lines and lines starting with ``#`` are skipped;
the first other line names the columns (distinct names; ``t`` required, ``s`` optional),
every further line is a row of finite numbers, one for each column. Without an ``s`` column,
t increases strictly from row to row. With one, the rows are a full grid in blocks of equal t
(t increasing from block to block), each block holding the same s values, increasing. At most
:data:`MAX_TABLE_BYTES` (16 MiB) and a regular file (not a FIFO or a device, which could hang
or never end). Every refusal is one line naming the component's key (``loads.end.force[2].
table``), the file and the line.

Interpolation in t (``interpolation``), with the interpolation error for a smooth f sampled
at spacing h (f^(k) its k-th derivative):

* ``"linear"`` (default): piecewise linear, C0; |f − I f| <= h²/8 max|f''|: order 2.
* ``"cubic"``: the cubic spline with not-a-knot ends (scipy's CubicSpline), C2: order 4
  (error <= C h⁴ max|f''''|); needs 4 rows. Smooth, but it overshoots near jumps.
* ``"pchip"``: the monotone piecewise cubic Hermite interpolant (Fritsch-Carlson, scipy's
  PchipInterpolator), C1, never beyond the values of the two rows around t (no overshoot:
  for measured data with steps); order 3 where f' does not vanish, 2 near extrema, where its
  slope estimate is set to zero.
* ``"previous"``: the value of the last row at or before t (sample and hold), order 1;
  not for a prescribed motion, whose position would jump with zero velocity.

A grid is interpolated in t first, then in s (``s_interpolation``: ``"linear"`` or
``"cubic"``, as above); for these tensor-product interpolants the order does not matter.
The rate and acceleration of a prescribed motion are the derivatives of the interpolant:
with ``"linear"`` the rate is the slope of each segment and the acceleration zero (the
jumps at the rows are not seen, as for ``heaviside`` in an expression); with ``"cubic"`` both
are continuous; with ``"pchip"`` the rate is.

Outside the table (``outside``): ``"refuse"`` (default): the table must cover the scene's
time span [time.start, time.end] and static.time (and a grid the rod, [0, rod.length]),
checked when the scene is read; a Runge-Kutta stage may lie outside its step (SDIRK4's by
0.069 of a step), and there, near the span's ends, the interpolant's end pieces continue.
``"hold"``: the value of the nearest end row (rate zero). ``"zero"``: zero.

A callable (through the API only: ``cf.load(scene, {"loads.end.force": [0, 0, f]})``):
``f(t)`` for a load of t, ``f(t, s)`` for a distributed load of t and s (its required
positional parameters decide which), t a float [s] and s a NumPy array of arc lengths [m]
(the quadrature points of the rank's cells), returning a number or an array of s's shape. It
is called where an expression would be evaluated: at every stage time of a step, on every
rank, the same number of times with the same t (a load of t only goes into a DOLFINx
Constant, one of t and s into a Function at the quadrature points: cosserat_fem/
load_coefficients.py). Its errors and non-finite values are refused in one line naming the
key and the time, on every rank; a load of t only must be the same on every rank. A callable
is not data: a checkpoint or summary.json records its name only, so a run with a callable
load cannot be restarted (refused in one line): run it again.

Reading. :class:`TableStore` reads each file once (per store): with a communicator, rank 0
reads it and broadcasts the bytes, which every rank parses alike; its SHA-256 becomes part of
the resolved scene (``Scene.to_dict``: what summary.json and a checkpoint hold) and of a
sweep's fingerprint, so a restart or a resumed sweep with another table's content is refused.
Tests: tests/test_load_data.py; the C step's copy of the loads,
tests/test_native_newton.py::test_loads_from_data_in_the_c_step_bit_for_bit.
"""

from __future__ import annotations

import hashlib
import inspect
import math
import os
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np

from cosserat_fem.common import safe_files
from cosserat_fem.common.errors import SceneError, show_value

#: The interpolations in t, and what each is (validate prints it).
INTERPOLATIONS = {
    "linear": "piecewise linear, C0, error O(h^2)",
    "cubic": "cubic spline with not-a-knot ends, C2, error O(h^4)",
    "pchip": "monotone cubic Hermite (PCHIP), C1, no overshoot, error O(h^3)",
    "previous": "the last row at or before t (sample and hold), error O(h)",
}
#: The interpolations of a grid in s.
S_INTERPOLATIONS = ("linear", "cubic")
#: What a table gives outside its rows (module docstring).
OUTSIDE = ("refuse", "hold", "zero")
#: Rows (distinct t, or distinct s) each interpolation needs.
MIN_ROWS = {"linear": 2, "cubic": 4, "pchip": 2, "previous": 1}
#: The largest table file read [bytes]: 16 MiB, about a million numbers; a longer history is
#: a run of its own to prepare (resample it).
MAX_TABLE_BYTES = 16 * 2**20
#: The most numbers a sampler's weights in s may take (:meth:`LoadTable.sampler`): 4 million,
#: 32 MB.
MAX_WEIGHTS = 4_000_000
#: A table component's choices (the keys of its inline table besides table, column, sha256).
_OPTIONS = ("interpolation", "s_interpolation", "outside")


# ====================================================================================== files
@dataclass(frozen=True)
class TableFile:
    """A table file as read: its absolute path, the SHA-256 of its bytes, the column names,
    the values (rows, columns) and each row's line number in the file (for messages)."""

    path: str
    sha256: str
    columns: tuple[str, ...]
    values: np.ndarray = field(compare=False, repr=False)
    lines: np.ndarray = field(compare=False, repr=False)

    def column(self, name: str) -> np.ndarray:
        return self.values[:, self.columns.index(name)]


def read_bytes(path: str, key: str, comm=None) -> bytes:
    """The bytes of the table file ``path``, a regular file of at most MAX_TABLE_BYTES, read
    on rank 0 of ``comm`` for every rank (cosserat_fem/common/safe_files.py: opened without
    blocking,
    checked on the open file); SceneError naming ``key`` otherwise, on every rank."""
    try:
        return safe_files.read_on_root(path, MAX_TABLE_BYTES, comm)
    except safe_files.Unreadable as exc:
        raise SceneError(f"{key}: table file {path!r} {exc}") from None


def parse_table(data: bytes, path: str, key: str) -> TableFile:
    """The table in ``data`` (the file format of the module docstring); SceneError naming
    ``key``, the file and the line at the first thing wrong. The rows are converted by NumPy
    all at once (why: docs/decisions.md, "Loads from data", reading cost) and, if
    that finds anything wrong, again line by line, which names the first line at fault."""
    digest = hashlib.sha256(data).hexdigest()
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise SceneError(
            f"{key}: {path!r} is not UTF-8 text ({exc.reason} at byte {exc.start})"
        ) from None
    lines = text.removeprefix("\ufeff").splitlines()
    numbers = [i for i, line in enumerate(lines) if (body := line.strip()) and body[0] != "#"]
    if not numbers:
        raise SceneError(f"{key}: {path!r} holds no header line (the column names, e.g. t, F)")
    first, rows = numbers[0], numbers[1:]
    where = f"{key}: {path!r} line {first + 1}"
    header = _header([cell.strip() for cell in lines[first].strip().split(",")], where)
    if not rows:
        raise SceneError(f"{key}: {path!r} holds a header but no rows")
    values = _all_rows([lines[i] for i in rows], len(header))
    if values is None:
        values = np.array([_row(lines[i], i + 1, header, f"{key}: {path!r}") for i in rows])
    return TableFile(path, digest, tuple(header), values, np.array(rows) + 1)


def _all_rows(lines: list[str], columns: int) -> np.ndarray | None:
    """The rows as a (rows, columns) array of finite numbers, or None if any line is not
    ``columns`` numbers separated by commas or a number is not finite (then :func:`_row`
    finds which)."""
    if any(line.count(",") != columns - 1 for line in lines):
        return None
    cells = ",".join(lines).split(",")
    try:
        values = np.array(cells, dtype=float)
    except ValueError:
        return None
    if values.size != len(lines) * columns or not np.isfinite(values).all():
        return None
    return values.reshape(len(lines), columns)


def _row(line: str, number: int, header: list[str], file: str) -> list[float]:
    """One row of numbers, one for each column; SceneError naming the line otherwise."""
    where = f"{file} line {number}"
    cells = [cell.strip() for cell in line.strip().split(",")]
    if len(cells) != len(header):
        raise SceneError(
            f"{where}: {len(cells)} values, the header names {len(header)} "
            f"columns ({', '.join(header)})"
        )
    return [_number(cell, name, where) for cell, name in zip(cells, header, strict=True)]


def _header(cells: list[str], where: str) -> list[str]:
    """The column names of a header line: non-empty, distinct, with a ``t`` column."""
    for i, name in enumerate(cells):
        if not name:
            raise SceneError(f"{where}: column {i + 1} of the header has no name")
        if name in cells[:i]:
            raise SceneError(f"{where}: the header names column {name!r} twice")
        if _is_number(name):
            raise SceneError(
                f"{where}: the first line must name the columns (e.g. t, F), got "
                f"the number {name!r}"
            )
    if "t" not in cells:
        raise SceneError(f"{where}: the header needs a column t (time [s]), got {', '.join(cells)}")
    return cells


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _number(cell: str, column: str, where: str) -> float:
    """A cell as a finite float; SceneError naming the column otherwise."""
    try:
        value = float(cell)
    except ValueError:
        raise SceneError(f"{where}: column {column}: not a number: {show_value(cell)}") from None
    if not math.isfinite(value):
        raise SceneError(f"{where}: column {column}: not a finite number: {cell}")
    return value


class TableStore:
    """Where a scene's tables are read: relative paths from ``base`` (default: the working
    directory), each file once per store. With a communicator of several ranks (``comm``)
    rank 0 reads it and broadcasts its bytes (or the reason it could not), so every rank
    parses the same bytes (every rank must then resolve its scenes alike: collective);
    without one, this process reads it. :meth:`seal` makes a later read an internal error
    (a sweep's member scenes are built in groups of ranks from the tables read when the sweep
    was validated, on every rank: cosserat_fem/studies/sweep_spec.py)."""

    def __init__(self, base: str | Path | None = None, comm=None):
        self.base = Path(base) if base is not None else Path.cwd()
        self.comm = comm
        self.files: dict[str, TableFile] = {}
        self.sealed = False

    @classmethod
    def collective(cls, base: str | Path | None = None) -> TableStore:
        """A store whose reads are collective over MPI.COMM_WORLD (rank 0 reads)."""
        from mpi4py import MPI

        return cls(base, MPI.COMM_WORLD)

    def path(self, name: str) -> str:
        """The absolute path of ``name`` (relative to :attr:`base`), not resolving links."""
        return os.path.abspath(self.base / Path(name).expanduser())

    def read(self, name: str, key: str) -> TableFile:
        """The table file ``name``; SceneError naming ``key`` if it cannot be read or parsed."""
        path = self.path(name)
        if path in self.files:
            return self.files[path]
        if self.sealed:
            raise RuntimeError(f"{key}: table {path!r} was not read when the scenes were checked")
        data = read_bytes(path, key, self.comm)
        table = parse_table(data, path, key)
        self.files[path] = table
        return table

    def seal(self) -> None:
        self.sealed = True

    def digests(self) -> dict[str, str]:
        """{absolute path: SHA-256} of every file read."""
        return {path: table.sha256 for path, table in sorted(self.files.items())}


# ===================================================================================== tables
def _ppoly(x: np.ndarray, y: np.ndarray, kind: str):
    """The interpolant of (x, y) (y's first axis along x) as a scipy PPoly; None for
    "previous" (indexed directly)."""
    from scipy.interpolate import CubicSpline, PchipInterpolator, PPoly

    if kind == "cubic":
        return CubicSpline(x, y, axis=0, bc_type="not-a-knot")
    if kind == "pchip":
        return PchipInterpolator(x, y, axis=0)
    if kind == "linear":
        slopes = np.diff(y, axis=0) / np.diff(x).reshape(-1, *([1] * (y.ndim - 1)))
        return PPoly(np.stack([slopes, y[:-1]]), x)
    return None


class _Data:
    """What a load given by data shares with an Expression's interface (the names it
    depends on, never zero or constant) and its sampling at fixed points."""

    is_zero = False
    is_constant = False

    @property
    def with_s(self) -> bool:
        """Whether it is a function of s as well as t."""
        raise NotImplementedError

    @property
    def names(self) -> frozenset[str]:
        return frozenset({"t", "s"} if self.with_s else {"t"})

    def depends_on(self, name: str) -> bool:
        return name in self.names

    def at(self, t: float, s: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def sampler(self, s: np.ndarray) -> Callable[[float], np.ndarray]:
        """t ↦ :meth:`at` (t, ``s``)."""
        s = np.asarray(s, dtype=float)
        return lambda t: self.at(t, s)


@dataclass(frozen=True)
class LoadTable(_Data):
    """A load component given by a table (module docstring): the component's ``key``, the
    file, the value ``column`` and the choices; ``order``: the derivative in t it gives (a
    prescribed motion's rate and acceleration). Compared by the file's path and content and
    the choices. Evaluated like an :class:`~cosserat_fem.scene.expressions.Expression`
    (:meth:`evaluate`) and, per time, by :meth:`value` (of t only) or :meth:`at` (of t, s)."""

    key: str = field(compare=False)
    file: TableFile = field(repr=False)
    column: str
    interpolation: str = "linear"
    s_interpolation: str = "linear"
    outside: str = "refuse"
    order: int = 0
    #: The file's name as the scene wrote it (messages).
    name: str = field(default="", compare=False)

    # -- construction ---------------------------------------------------------------------
    @classmethod
    def build(cls, key: str, file: TableFile, spec: Mapping[str, Any], name: str) -> LoadTable:
        """The component of ``spec`` (an inline table the schema checked) on ``file``;
        SceneError naming the key for a missing column, a non-increasing t or s, an incomplete
        grid or too few rows, or a content that is not the ``sha256`` given."""
        where = f"{key}.table: {file.path!r}"
        given = spec.get("sha256")
        if given and given.strip().lower() != file.sha256:
            raise SceneError(
                f"{key}.sha256: {file.path!r} has the SHA-256 {file.sha256}, "
                f"not the {given.strip()} the scene requires (the file changed)"
            )
        column = spec["column"]
        if column not in file.columns or column in ("t", "s"):
            others = [c for c in file.columns if c not in ("t", "s")]
            raise SceneError(
                f"{key}.column: {file.path!r} has no value column "
                f"{show_value(column)} (its value columns: "
                f"{', '.join(others) or 'none'})"
            )
        options = {option: spec[option] for option in _OPTIONS if spec.get(option)}
        table = cls(key, file, column, **options, name=name)
        table._structure(where)
        return table

    def _structure(self, where: str) -> None:
        """Refuse rows that are not increasing in t (a grid: not a full grid), or too few."""
        t, lines = self.file.column("t"), self.file.lines
        need = MIN_ROWS[self.interpolation]
        if not self.grid:
            bad = np.flatnonzero(np.diff(t) <= 0.0)
            if bad.size:
                i = bad[0] + 1
                raise SceneError(
                    f"{where} line {lines[i]}: t = {t[i]!r} does not increase (the "
                    f"row before has t = {t[i - 1]!r}); t must increase strictly"
                )
            if len(t) < need:
                raise SceneError(
                    f"{where}: {len(t)} rows; interpolation "
                    f"{show_value(self.interpolation)} needs at least {need}"
                )
            return
        s = self.file.column("s")
        bad = np.flatnonzero(np.diff(t) < 0.0)
        if bad.size:
            i = bad[0] + 1
            raise SceneError(
                f"{where} line {lines[i]}: t = {t[i]!r} is before the row before "
                f"({t[i - 1]!r}); a grid's rows go in blocks of increasing t"
            )
        starts = np.concatenate([[0], np.flatnonzero(np.diff(t)) + 1])
        sizes = np.diff(np.append(starts, len(t)))
        first = s[: sizes[0]]
        bad = np.flatnonzero(np.diff(first) <= 0.0)
        if bad.size:
            i = bad[0] + 1
            raise SceneError(
                f"{where} line {lines[i]}: s = {s[i]!r} does not increase within "
                f"the block of t = {t[0]!r} (the row before has s = {s[i - 1]!r})"
            )
        for start, size in zip(starts, sizes, strict=True):
            block = s[start : start + size]
            if size != sizes[0] or np.any(block != first):
                i = start + int(np.argmax(np.append(block[: sizes[0]] != first[:size], True)))
                raise SceneError(
                    f"{where} line {lines[min(i, len(t) - 1)]}: not a full grid: "
                    f"every block of equal t must hold the {sizes[0]} values of s "
                    f"of the first block ({first[0]!r} to {first[-1]!r}), in that "
                    "order"
                )
        if len(starts) < need:
            raise SceneError(
                f"{where}: {len(starts)} times in the grid; interpolation "
                f"{show_value(self.interpolation)} needs at least {need}"
            )
        need_s = MIN_ROWS[self.s_interpolation]
        if sizes[0] < need_s:
            raise SceneError(
                f"{where}: {sizes[0]} values of s in the grid; s_interpolation "
                f"{show_value(self.s_interpolation)} needs at least {need_s}"
            )

    # -- what it is -----------------------------------------------------------------------
    @property
    def grid(self) -> bool:
        """Whether the table has an s column (a function of t and s)."""
        return "s" in self.file.columns

    @property
    def with_s(self) -> bool:
        return self.grid

    @property
    def source(self) -> str:
        """The component in words, for messages."""
        rate = {0: "", 1: "the rate of ", 2: "the acceleration of "}.get(self.order, "")
        shown = self.name or self.file.path
        return f"{rate}table {shown!r} column {self.column!r} ({self.interpolation})"

    @cached_property
    def _times(self) -> np.ndarray:
        t = self.file.column("t")
        return t[:: self._width] if self.grid else t

    @cached_property
    def _width(self) -> int:
        return len(np.unique(self.file.column("s"))) if self.grid else 1

    @cached_property
    def _s(self) -> np.ndarray | None:
        return self.file.column("s")[: self._width] if self.grid else None

    @cached_property
    def _values(self) -> np.ndarray:
        """The values, (times,) or (times, s) for a grid."""
        y = self.file.column(self.column)
        return y.reshape(-1, self._width) if self.grid else y

    @cached_property
    def _interpolant(self):
        return _ppoly(self._times, self._values, self.interpolation)

    def span(self) -> tuple[float, float]:
        """The first and last t of the table [s]."""
        return float(self._times[0]), float(self._times[-1])

    def s_span(self) -> tuple[float, float] | None:
        """A grid's first and last s [m] (None for a table of t only)."""
        return None if self._s is None else (float(self._s[0]), float(self._s[-1]))

    def describe(self) -> str:
        """The table in one line for ``validate``: rows, span, interpolation, content."""
        t0, t1 = self.span()
        text = (
            f"table {self.file.path}, column {self.column}: {len(self._times)} rows, t in "
            f"[{t0:.6g}, {t1:.6g}] s"
        )
        if self.grid:
            s_span = self.s_span()
            assert s_span is not None, "a grid has its s"
            s0, s1 = s_span
            text += (
                f" x {self._width} values of s in [{s0:.6g}, {s1:.6g}] m "
                f"({self.s_interpolation} in s)"
            )
        return (
            f"{text}; {INTERPOLATIONS[self.interpolation]}; outside "
            f"{show_value(self.outside)}; sha256 {self.file.sha256}"
        )

    def to_dict(self) -> dict[str, Any]:
        """The component as a scene writes it, with the absolute path and the content's
        SHA-256 (what a checkpoint and summary.json hold)."""
        out = {"table": self.file.path, "column": self.column, "interpolation": self.interpolation}
        if self.grid:
            out["s_interpolation"] = self.s_interpolation
        out.update(outside=self.outside, sha256=self.file.sha256)
        return out

    def derivative(self, name: str) -> LoadTable:
        """d/dt of the interpolant (a prescribed motion's rate); ValueError for s."""
        if name != "t" or self.grid:
            raise ValueError(f"{self.key}: a table's derivative is in t, of a table of t only")
        from dataclasses import replace

        return replace(self, order=self.order + 1)

    # -- values ---------------------------------------------------------------------------
    def _in_time(self, t: np.ndarray) -> np.ndarray:
        """The (order-th derivative of the) interpolant in t at the times ``t``: (len(t),) or
        (len(t), s) for a grid, with the outside rule."""
        times, y = self._times, self._values
        if self.interpolation == "previous":
            if self.order:
                out = np.zeros((len(t), *y.shape[1:]))
            else:
                index = np.clip(np.searchsorted(times, t, side="right") - 1, 0, len(times) - 1)
                out = y[index].astype(float)
        else:
            out = np.asarray(self._interpolant(t, nu=self.order, extrapolate=True), dtype=float)
        if self.outside != "refuse":
            below, above = t < times[0], t > times[-1]
            if self.outside == "hold" and not self.order:
                out[below], out[above] = y[0], y[-1]
            else:
                out[below | above] = 0.0
        return out

    def _in_s(self, profile: np.ndarray, s: np.ndarray) -> np.ndarray:
        """A grid's values at one time (``profile``, at its s; or columns of such) interpolated
        at ``s`` [m]: (len(s),) (or (len(s), columns))."""
        grid = self._s
        assert grid is not None, "called for a grid"
        out: np.ndarray
        if self.s_interpolation == "cubic":
            out = np.asarray(_ppoly(grid, profile, "cubic")(s), dtype=float)
        elif profile.ndim == 1:
            out = np.interp(s, grid, profile)  # beyond the ends: their values
        else:
            out = np.column_stack([np.interp(s, grid, column) for column in profile.T])
        if self.outside == "hold":
            out[s < grid[0]], out[s > grid[-1]] = profile[0], profile[-1]
        elif self.outside == "zero":
            out[(s < grid[0]) | (s > grid[-1])] = 0.0
        return out

    def _at_time(self, t: float) -> Any:
        """:meth:`_in_time` at one time t inside the table (a number, or a grid's row) by
        Horner's rule on the piece's coefficients: each stage of a run asks for one t, and
        scipy's evaluation spends far more in its checks (why: docs/decisions.md, "Loads from
        data", the C step)."""
        times = self._times
        if self.order or self.interpolation == "previous" or not times[0] <= t <= times[-1]:
            return self._in_time(np.array([t]))[0]
        piece = min(int(np.searchsorted(times, t, side="right")) - 1, len(times) - 2)
        coefficients = self._interpolant.c[:, piece]
        dt, value = t - times[piece], coefficients[0]
        for c in coefficients[1:]:
            value = value * dt + c
        return value

    def value(self, t: float) -> float:
        """A table of t only at time ``t`` [s]."""
        return float(self._at_time(float(t)))

    def sampler(self, s: np.ndarray) -> Callable[[float], np.ndarray]:
        """t ↦ the values at the fixed arc lengths ``s`` [m] (the quadrature points of a
        model, sampled at every stage): :meth:`at`, with a cubic grid's weights in s
        computed once (the spline is linear in the values; why: docs/decisions.md, "Loads
        from data", the C step) unless they would take more than :data:`MAX_WEIGHTS` numbers."""
        s = np.asarray(s, dtype=float)
        width = self._width
        if (
            not self.grid
            or self.s_interpolation != "cubic"
            or width**2 + s.size * width > (MAX_WEIGHTS)
        ):
            return super().sampler(s)
        weights = self._in_s(np.eye(width), s.ravel())  # (points, width)
        return lambda t: (weights @ self._at_time(float(t))).reshape(s.shape)

    def at(self, t: float, s: np.ndarray) -> np.ndarray:
        """The values at time ``t`` [s] and the arc lengths ``s`` [m] (any table)."""
        s = np.asarray(s, dtype=float)
        if not self.grid:
            return np.full(s.shape, self.value(t))
        return self._in_s(self._at_time(float(t)), s.ravel()).reshape(s.shape)

    def evaluate(self, **values: Any) -> Any:
        """As :meth:`Expression.evaluate <cosserat_fem.scene.expressions.Expression.evaluate>`:
        ``t`` (and ``s`` for a grid) floats or arrays, other names ignored; a float for
        scalars, else an array of the broadcast shape."""
        if self.grid or "t" not in values:
            return _evaluate_by_time(self, values)
        t = np.asarray(values["t"], dtype=float)
        shape = np.broadcast_shapes(t.shape, np.shape(values.get("s", 0.0)))
        out = self._in_time(np.broadcast_to(t, shape).ravel()).reshape(shape)
        return float(out) if out.ndim == 0 else out


def _evaluate_by_time(component, values: Mapping[str, Any], failed: float | None = None) -> Any:
    """``component.at(t, s)`` over arrays of t and s (broadcast), one call per distinct t; a
    float when t and s are scalars. ``failed``: the value where ``at`` raises SceneError
    (None: it is raised)."""
    if "t" not in values:
        raise ValueError(f"no value given for t in {component.source!r}")
    t = np.asarray(values["t"], dtype=float)
    s = np.asarray(values.get("s", 0.0), dtype=float)
    scalar = t.ndim == 0 and s.ndim == 0
    t, s = np.broadcast_arrays(t, s)
    out = np.empty(t.shape)
    for time in np.unique(t):
        mine = t == time
        try:
            out[mine] = component.at(float(time), s[mine])
        except SceneError:
            if failed is None:
                raise
            out[mine] = failed
    return float(out) if scalar else out


# ================================================================================== callables
def _required_positional(function: Callable) -> int | None:
    """How many positional parameters ``function`` requires (None if unknown: a builtin
    without a signature, which is then called as f(t))."""
    try:
        parameters = inspect.signature(function).parameters.values()
    except (TypeError, ValueError):
        return None
    kinds = (inspect.Parameter.POSITIONAL_ONLY, inspect.Parameter.POSITIONAL_OR_KEYWORD)
    return sum(1 for p in parameters if p.kind in kinds and p.default is inspect.Parameter.empty)


@dataclass(frozen=True, eq=False)
class LoadCallable(_Data):
    """A load component given by a Python callable (module docstring): ``f(t)`` or, with
    ``with_s``, ``f(t, s)``. Equal only to itself."""

    key: str
    function: Callable = field(repr=False)
    with_s: bool = False

    @property
    def qualified_name(self) -> str:
        f = self.function
        name = getattr(f, "__qualname__", None) or getattr(f, "__name__", None) or repr(f)
        module = getattr(f, "__module__", None)
        return f"{module}.{name}" if module else name

    @property
    def source(self) -> str:
        return f"callable {self.qualified_name}({'t, s' if self.with_s else 't'})"

    def to_dict(self) -> dict[str, str]:
        """Its name only: a callable is not data (module docstring)."""
        return {"callable": self.qualified_name}

    def describe(self) -> str:
        return f"{self.source}, called at every stage time on every rank"

    def _fail(self, what: str, t: float) -> SceneError:
        return SceneError(f"{self.key}: the {self.source} {what} at t = {t:.10g} s")

    def value(self, t: float) -> float:
        """f(t) as a finite float; SceneError naming the key otherwise."""
        try:
            result = self.function(float(t))
        except Exception as exc:  # the user's code: any error is its refusal
            raise self._fail(f"raised {type(exc).__name__}: {exc}", t) from None
        try:
            value = float(np.asarray(result, dtype=float))
        except (TypeError, ValueError):
            raise self._fail(f"returned {show_value(result)}, not a number", t) from None
        if not math.isfinite(value):
            raise self._fail(f"returned {value!r}", t)
        return value

    def at(self, t: float, s: np.ndarray) -> np.ndarray:
        """f(t, s) (or f(t) everywhere) as finite floats of s's shape; SceneError otherwise."""
        s = np.asarray(s, dtype=float)
        if not self.with_s:
            return np.full(s.shape, self.value(t))
        try:
            result = self.function(float(t), s.copy())
        except Exception as exc:  # the user's code
            raise self._fail(f"raised {type(exc).__name__}: {exc}", t) from None
        try:
            values = np.broadcast_to(np.asarray(result, dtype=float), s.shape)
        except (TypeError, ValueError):
            raise self._fail(
                f"returned {show_value(result)}, not numbers of the shape of s {s.shape}", t
            ) from None
        bad = np.flatnonzero(~np.isfinite(values.ravel()))
        if bad.size:
            raise self._fail(
                f"returned {values.ravel()[bad[0]]!r} at s = {s.ravel()[bad[0]]:.6g} m", t
            )
        return np.array(values)

    def evaluate(self, **values: Any) -> Any:
        """As :meth:`LoadTable.evaluate`; a failure gives NaN (for the search of a load that
        is not finite: cosserat_fem/rod/model.py ``nonfinite_load``)."""
        return _evaluate_by_time(self, values, failed=math.nan)


# ================================================================================= components
DataLoad = LoadTable | LoadCallable


def is_data(component: object) -> bool:
    """Whether a load component is given by data (a table or a callable)."""
    return isinstance(component, LoadTable | LoadCallable)


def parse_component(
    value: object, names: Iterable[str], key: str, tables: TableStore, motion: bool = False
):
    """One load component: an Expression of ``names`` (a number or a string), a
    :class:`LoadTable` (an inline table the schema checked) or a :class:`LoadCallable`;
    ``motion``: a prescribed motion's (tables only, not "previous"). SceneError naming
    ``key``."""
    from cosserat_fem.scene.expressions import Expression

    allowed = frozenset(names)
    if isinstance(value, dict):
        table = LoadTable.build(
            key, tables.read(value["table"], f"{key}.table"), value, value["table"]
        )
        if table.grid and "s" not in allowed:
            raise SceneError(
                f"{key}: {table.source} has an s column (a grid), but this load depends on t only"
            )
        if motion and table.interpolation == "previous":
            raise SceneError(
                f'{key}.interpolation: "previous" is not allowed for a prescribed '
                "motion (its position would jump with zero velocity); use "
                '"linear", "cubic" or "pchip"'
            )
        return table
    if callable(value) and not isinstance(value, str):
        if motion:
            raise SceneError(
                f"{key}: a prescribed motion cannot be a callable (its rate and "
                "acceleration are needed); give a table or an expression"
            )
        with_s = _required_positional(value) == 2
        if with_s and "s" not in allowed:
            raise SceneError(
                f"{key}: a callable here is f(t) (this load depends on t only), "
                f"got {LoadCallable(key, value, True).source}"
            )
        return LoadCallable(key, value, with_s)
    return Expression.parse(value, allowed, key)


def parse_load_vector(
    value: object, names: Iterable[str], key: str, tables: TableStore, motion: bool = False
) -> tuple:
    """Three load components (:func:`parse_component`); their keys are ``key[i]``."""
    if not isinstance(value, list | tuple) or len(value) != 3:
        raise SceneError(
            f"{key}: must be a list of 3 numbers, expression strings or tables, "
            f"got {show_value(value)}"
        )
    names = frozenset(names)
    x, y, z = (
        parse_component(v, names, f"{key}[{i}]", tables, motion) for i, v in enumerate(value)
    )
    return x, y, z


def component_dict(component) -> Any:
    """A component as a scene writes it: an expression's source, a table's or a callable's
    :meth:`to_dict`."""
    return component.to_dict() if is_data(component) else component.source


def check_span(component, start: float, end: float, static_time: float, length: float) -> None:
    """A table with outside = "refuse" must cover the time span [``start``, ``end``] and
    ``static_time`` [s], and a grid the rod [0, ``length``] [m]; SceneError naming the key."""
    if not isinstance(component, LoadTable) or component.outside != "refuse":
        return
    t0, t1 = component.span()
    lo, hi = min(start, static_time), max(end, static_time)
    if t0 > lo or t1 < hi:
        raise SceneError(
            f"{component.key}: {component.source} covers t in [{t0:.10g}, "
            f"{t1:.10g}] s, the scene needs [{lo:.10g}, {hi:.10g}] s (time.start "
            'to time.end, and static.time); extend it, or set outside = "hold" '
            'or "zero"'
        )
    if component.grid:
        s_span = component.s_span()
        assert s_span is not None, "a grid has its s"
        s0, s1 = s_span
        if s0 > 0.0 or s1 < length:
            raise SceneError(
                f"{component.key}: {component.source} covers s in [{s0:.10g}, "
                f"{s1:.10g}] m, the rod is [0, {length:.10g}] m; extend it, or set "
                'outside = "hold" or "zero"'
            )


def refuse_callable_restart(scene) -> None:
    """SceneError naming the first load of ``scene`` given by a callable: a checkpoint cannot
    hold a callable, so it cannot say that one given again is the run's (a restart through
    ``cf.run(scene, restart=...)``; ``cf.resume`` refuses the saved scene itself)."""
    for key, component in scene.load_components():
        if isinstance(component, LoadCallable):
            raise SceneError(
                f"{key}: a run with a callable load ({component.source}) cannot be "
                "restarted (a checkpoint cannot hold a callable); run it again"
            )
