"""Reading a run's outputs without DOLFINx: a run folder (:func:`open_run`: summary.json,
probes.csv and solution.xdmf) and a sweep's table (sweep.csv and its parts).

For ``cosserat-fem plot`` and ``cosserat-fem render`` (cosserat_fem/plot.py, render.py), which
must also work on a machine without the solver stack: numpy, the standard library's XML
parser and h5py (the ``plot``/``render`` extras) only. Each file is read by its format's module
(cosserat_fem/io/: probes.py, xdmf.py, run_folder.py), which says what it checks; h5py cannot
be used in a process that has loaded DOLFINx (the two HDF5 libraries clash: "Not a datatype"),
so this module never imports DOLFINx and should not be imported next to it; tests read the
files through ``cosserat-fem plot``/``render`` in a subprocess.

Damaged, truncated, foreign or hostile files are bad input: a :class:`SceneError` (exit 2)
whose one-line message names the file at fault, most often first (text taken from a file is
quoted with ``repr``, so no control character reaches the terminal), never another
exception (cosserat_fem/io/reading.py). Every file is a regular file (not a folder, device,
FIFO or dangling link: looked at before it is opened, and opened without blocking,
cosserat_fem/safe_files.py) of bounded size; numbers are finite and at most
:data:`~cosserat_fem.io.reading.MAX_MAGNITUDE` in magnitude (NaN and inf are refused, not
plotted: a run never writes them, so they mean damage; and matplotlib and VTK fail on values
near the float range anyway). summary.json: a JSON object; ``kind`` and ``scene.title``
strings, ``scene`` and ``scene.rod`` objects, ``scene.rod.length`` a positive number, where
present. A scratch ``solution.xdmf-partial`` or ``summary.json.tmp`` left by a killed run is
never read.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from . import safe_files
from .errors import SceneError
from .io.probes import PROBE_COLUMNS, PROBES, read_probe_table
from .io.reading import (
    is_file,
    quoted,
)
from .io.run_folder import SUMMARY, read_summary
from .io.xdmf import XDMF, RodSeries, read_xdmf

#: Largest files read [bytes]: an XDMF file ~1-2.5 kB a frame (some 60 000 frames),
#: summary.json ~4 kB.
#: Longest title shown in a figure [characters].
MAX_TITLE = 120


@dataclass
class Run:
    """A run folder's outputs: summary (or None), probes (rows, or None), XDMF path (or None),
    and the names of the probes' columns."""

    directory: Path
    summary: dict | None
    probes: np.ndarray | None
    xdmf: Path | None
    probe_columns: tuple[str, ...] = PROBE_COLUMNS

    @property
    def time_label(self) -> str:
        """What the probes' t column and the XDMF times are."""
        if self.summary and self.summary.get("kind") == "static":
            return "load factor"
        return "t [s]"

    @property
    def title(self) -> str:
        """The scene's title (else the folder's name) for a picture: control characters as
        blanks, shortened to MAX_TITLE characters."""
        scene = (self.summary or {}).get("scene") or {}
        title = scene.get("title") or self.directory.resolve().name or str(self.directory)
        title = "".join(c if c.isprintable() else " " for c in title[: MAX_TITLE + 1])
        return title if len(title) <= MAX_TITLE else title[: MAX_TITLE - 3] + "..."

    @property
    def length(self) -> float | None:
        scene = (self.summary or {}).get("scene") or {}
        length = (scene.get("rod") or {}).get("length")
        return None if length is None else float(length)

    @property
    def probe_place(self) -> str:
        """Where probes.csv's values are taken, for a label: "ℓ" (the end at s = ℓ), "0", or
        "s = ... m" (from summary.json's probe_s_m; "ℓ" when it does not say)."""
        summary = self.summary or {}
        where, length = summary.get("probe_s_m"), self.length
        if not isinstance(where, int | float) or isinstance(where, bool) or length is None:
            return "ℓ"
        if where == length:
            return "ℓ"
        return "0" if where == 0 else f"s = {where:g} m"

    def series(self) -> RodSeries:
        if self.xdmf is None:
            raise SceneError(f"{self.directory}: no solution.xdmf (was output.xdmf = false?)")
        return read_xdmf(self.xdmf, length=self.length)


def open_run(directory: str | Path, command: str) -> Run:
    """The outputs of the run in ``directory``; a folder without any is bad input, and so is a
    damaged file (see the module docstring). The XDMF file is read by :meth:`Run.series`."""
    path = Path(directory)
    if not path.is_dir():
        raise SceneError(f"{command}: {str(path)!r} is not a folder")
    summary_path, probes_path = path / SUMMARY, path / PROBES
    summary = read_summary(summary_path) if is_file(summary_path) else None
    columns, probes = read_probe_table(probes_path) if is_file(probes_path) else (None, None)
    xdmf = path / XDMF
    run = Run(path, summary, probes, xdmf if is_file(xdmf) else None, columns or PROBE_COLUMNS)
    if run.probes is None and run.xdmf is None:
        raise SceneError(
            f"{command}: {str(path)!r} holds no run outputs (probes.csv, solution.xdmf); "
            "give the folder of a run (cosserat-fem run/static --out DIR)"
        )
    return run


# --- a sweep's table (cosserat_fem/sweep_run.py) ----------------------------------------------
#: A sweep's table, and the folder of its parts (one a group of ranks: table/group-<k>.csv).
SWEEP_TABLE, SWEEP_PARTS = "sweep.csv", "table"
#: A member's status when it stopped for a passing reason (a full disk, limits.wall_time): not
#: finished; a sweep started again runs it, and its later row takes the stopped one's place.
STOPPED = "stopped"


def read_sweep_rows(directory: str | Path, parts_only: bool = False) -> tuple[list[str], list]:
    """(columns, rows) of the sweep in ``directory``: its sweep.csv, or its table parts (with
    ``parts_only``, or while there is no sweep.csv: a sweep killed or still running). A cut
    last line of a file (a kill) is left out, not changed on disk; the rows (dicts of text)
    come sorted by member. An unreadable file (a special file: refused, never opened) or a
    member that is not a number is bad input."""
    import csv

    directory = Path(directory)
    table = directory / SWEEP_TABLE
    if not parts_only and is_file(table):
        sources = [table]
    else:
        sources = sorted((directory / SWEEP_PARTS).glob("group-*.csv"))
    columns: list[str] = []
    rows: list[dict] = []
    for source in sources:
        try:
            text = safe_files.read_text(source)
        except (OSError, UnicodeDecodeError) as exc:
            reason = exc.strerror if isinstance(exc, OSError) else exc
            raise SceneError(f"{quoted(source)}: cannot read it ({reason})") from None
        reader = csv.DictReader(text[: text.rfind("\n") + 1].splitlines())
        rows += _whole_rows(source, reader, columns)
        columns = list(reader.fieldnames or columns)
    if sources != [table]:
        rows = _latest_rows(rows)
    try:
        rows.sort(key=lambda row: int(row["member"]))
    except (KeyError, TypeError, ValueError):
        raise SceneError(f"{quoted(directory)}: not a sweep's table (a member that is not a "
                         "number)") from None  # fmt: skip
    return columns, rows


def _latest_rows(rows: list[dict]) -> list[dict]:
    """The rows of a sweep's table parts without those a later run replaced: a member's
    "stopped" row gives way to a row of its run again, or to its last stopped row (the parts
    are read in the order of their groups, not of time). Two rows of a member that did not
    stop are both kept (not the rows of one sweep: check_sweep_rows refuses them)."""
    ran = {row.get("member") for row in rows if row.get("status") != STOPPED}
    last_stop = {row.get("member"): row for row in rows
                 if row.get("status") == STOPPED and row.get("member") not in ran}  # fmt: skip
    return [row for row in rows
            if row.get("status") != STOPPED or last_stop.get(row.get("member")) is row]  # fmt: skip


def _whole_rows(source: Path, reader, columns: list[str]) -> list[dict]:
    """The rows of one file of a sweep's table, each with a field for every column of its
    header, the header the same as the other files' (``columns``, if read); SceneError naming
    the file and line otherwise: rows of another table, or damaged, are not merged."""
    header = reader.fieldnames
    if header is None:  # an empty part: its group was killed before it wrote its header
        return []
    if columns and list(header) != columns:
        raise SceneError(f"{quoted(source)}: its columns are not those of the sweep's other "
                         "table parts: not the same sweep's table")  # fmt: skip
    if len(set(header)) != len(header) or "" in header:
        raise SceneError(f"{quoted(source)}: a header with an empty or repeated column; not a "
                         "sweep's table")  # fmt: skip
    rows = []
    for row in reader:
        extra = row.pop(None, None) or []  # fields beyond the header's
        missing = sum(row[k] is None for k in header)  # fields short of it
        if extra or missing:
            raise SceneError(f"{quoted(source)}: line {reader.line_num} has "
                             f"{len(header) + len(extra) - missing} fields, not the header's "
                             f"{len(header)}")  # fmt: skip
        rows.append(row)
    return rows


def check_sweep_rows(directory: str | Path, columns: list[str], rows: list[dict],
                     record: dict) -> tuple[str, ...]:  # fmt: skip
    """The varied keys of the sweep recorded in ``record`` (its sweep.json, from
    cosserat_fem/sweep_run.py) after checking that ``rows`` are its rows: one a member, each
    of a member it has (0 ... members − 1), with the member's values of the varied keys as
    the sweep's table writes them (JSON), and the table's varied columns the record's.
    SceneError naming the table otherwise: a row of another sweep is not merged."""
    where = quoted(Path(directory) / SWEEP_TABLE)
    varied, members = record.get("varied"), record.get("members")
    if not (isinstance(varied, list) and all(isinstance(k, str) for k in varied)
            and isinstance(members, int) and not isinstance(members, bool)):  # fmt: skip
        raise SceneError(f"{quoted(Path(directory) / 'sweep.json')}: not a sweep's record "
                         "(varied, members)")  # fmt: skip
    if "wall_s" not in columns or "steps" not in columns or columns[
            columns.index("wall_s") + 1 : columns.index("steps")] != varied:  # fmt: skip
        raise SceneError(f"{where}: its varied columns are not the sweep's {varied}")
    values = _member_values(record, members)
    seen: set[int] = set()
    for row in rows:
        index = int(row["member"])
        if not 0 <= index < members or index in seen:
            reason = "twice" if index in seen else f"but the sweep has {members} members"
            raise SceneError(f"{where}: a row of member {index}, {reason}: not this sweep's "
                             "rows")  # fmt: skip
        seen.add(index)
        if values is not None and any(row[k] != json.dumps(values[index].get(k))
                                      for k in varied):  # fmt: skip
            raise SceneError(f"{where}: the row of member {index} holds other values of "
                             f"{', '.join(varied)} than the sweep's member: not this sweep's row")
    return tuple(varied)


def _member_values(record: dict, members: int) -> list[dict] | None:
    """Each member's values of the varied keys, from the record's fingerprint (the sweep's
    JSON document, cosserat_fem/sweep_spec.py), or None where it does not hold them."""
    try:
        listed = json.loads(record.get("fingerprint"))["members"]
    except (TypeError, ValueError, KeyError, RecursionError):
        return None
    if not isinstance(listed, list) or len(listed) != members:
        return None
    values = [m[0] if isinstance(m, list) and len(m) == 2 else m for m in listed]
    return values if all(isinstance(v, dict) for v in values) else None


