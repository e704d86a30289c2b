"""Reading a run's outputs without DOLFINx: probes.csv, summary.json and the XDMF time series.

For ``cosserat-fem plot`` and ``cosserat-fem render`` (cosserat_fem/plot.py, render.py), which
must also work on a machine without the solver stack: numpy, the standard library's XML
parser and h5py (the ``plot``/``render`` extras) only. The XDMF file is the one of
:class:`cosserat_fem.output.XdmfWriter`: one temporal collection whose frames each carry the
mesh (the reference centreline (0, 0, s) [m]), the time and the point arrays. Files of the
earlier layout (DOLFINx's: a "mesh" grid with σ = s/ℓ along the first axis and one
collection per array) are read too.

h5py cannot be used in a process that has loaded DOLFINx (the two HDF5 libraries clash:
"Not a datatype"), so this module never imports DOLFINx and should not be imported next to
it; tests read the files through ``cosserat-fem plot``/``render`` in a subprocess.

Damaged, truncated, foreign or hostile files are bad input: a :class:`SceneError` (exit 2)
whose one-line message names the file at fault, most often first (text taken from a file is
quoted with ``repr``, so no control character reaches the terminal), never another
exception. What is read has passed these checks:

* Every file is a regular file (not a folder, device, FIFO or dangling link: looked at before
  it is opened, and opened without blocking, cosserat_fem/safe_files.py) of at most
  :data:`MAX_PROBES_BYTES`, :data:`MAX_SUMMARY_BYTES` or :data:`MAX_XDMF_BYTES`; text is
  UTF-8.
* Numbers: finite and at most :data:`MAX_MAGNITUDE` in magnitude. NaN and inf are refused,
  not plotted: a run never writes them (it stops with a SolverError before a non-finite
  state reaches its outputs), so they mean damage; and matplotlib and VTK fail on values
  near the float range anyway.
* probes.csv: the header ``t,x,y,z,theta,psi,phi``, optionally followed by the columns of
  ``output.probe_fields`` (:data:`PROBE_FIELD_COLUMNS`, in that order), then every whole line
  as many numbers as the header names (blank lines are skipped). The text after the last
  newline is a row cut by a killed run and is dropped, whatever it holds; an empty file or a
  cut header (a run killed as it made the file) reads as no rows.
* summary.json: a JSON object; ``kind`` and ``scene.title`` strings, ``scene`` and
  ``scene.rod`` objects, ``scene.rod.length`` a positive number, where present.
* solution.xdmf: XML without entity declarations (an entity-expansion bomb is refused before
  anything is expanded), root ``Xdmf`` with a ``Domain`` (after the root, the writer's
  processing instruction of spare blanks, ``<?cosserat-fem-spare ...?>``, or any other, is
  skipped; frames may be separated by runs of blanks); each frame a ``Time`` whose value
  is a number, each ``Attribute`` a name and an HDF ``DataItem`` ``file.h5:/dataset`` whose
  file is a plain name in the XDMF file's folder (the single-file layout of earlier versions:
  ``solution.h5``, ``solution-restart<n>.h5``) or a file of the frames folder beside it,
  ``<name>.frames/mesh.h5`` or ``<name>.frames/<digits>.h5`` (one file a frame, written by
  :class:`cosserat_fem.output.XdmfWriter`; one folder level, no ``..``, no absolute path,
  nothing else); each dataset there, numeric, of the XML's ``Dimensions``; the geometry
  (N, 2 or 3) as its ``GeometryType`` says, N >= 2 points spanning a positive length; the
  topology integers in [0, N) (a message about the geometry or topology names its .h5 file
  first); every array (N, 3). At most :data:`MAX_VALUES` numbers are
  read from the .h5 files of one XDMF file. An XDMF file without any frame (a run killed
  before its first) raises :class:`NoFramesError`, which ``plot`` takes as "no surfaces"
  when probes.csv has rows.
* A scratch ``solution.xdmf-partial`` or ``summary.json.tmp`` left by a killed run is never
  read.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from . import safe_files
from .errors import SceneError
from .io.probes import PROBE_COLUMNS, read_probe_table
from .io.reading import (
    decode,
    finite_number,
    is_file,
    json_kind,
    quoted,
    read_bytes,
)
from .io.xdmf import RodSeries, read_xdmf

#: Largest files read [bytes]: an XDMF file ~1-2.5 kB a frame (some 60 000 frames),
#: summary.json ~4 kB.
MAX_SUMMARY_BYTES = 16 << 20
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
    summary_path, probes_path = path / "summary.json", path / "probes.csv"
    summary = read_summary(summary_path) if is_file(summary_path) else None
    columns, probes = read_probe_table(probes_path) if is_file(probes_path) else (None, None)
    xdmf = path / "solution.xdmf"
    run = Run(path, summary, probes, xdmf if is_file(xdmf) else None, columns or PROBE_COLUMNS)
    if run.probes is None and run.xdmf is None:
        raise SceneError(
            f"{command}: {str(path)!r} holds no run outputs (probes.csv, solution.xdmf); "
            "give the folder of a run (cosserat-fem run/static --out DIR)"
        )
    return run


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


