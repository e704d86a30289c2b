"""A sweep's files (cosserat_fem/studies/sweep_run.py runs the sweep): its table, each writer beside
its reader, and its record.

* ``sweep.csv`` (:data:`SWEEP_TABLE`): one row a member, sorted by member, the columns of
  ``sweep_run.columns``; merged by world rank 0 when every member is done
  (:func:`write_table`), from
* ``table/group-<k>.csv`` (:data:`SWEEP_PARTS`): the part of group k, its header then a row
  appended and flushed per member (:func:`open_part`, :func:`table_line`); a row cut by a kill
  is cut off before a sweep continues (:func:`cut_rows_off`). Read (checked, merged, sorted)
  by :func:`read_sweep_rows`; a table's rows checked against the sweep's record by
  :func:`check_sweep_rows`.
* ``bifurcation.csv`` (:data:`BIFURCATION`): a bifurcation diagram ([sweep.poincare]), one row
  a section point of a member, the columns of ``sweep_run.bifurcation_columns``; written by
  world rank 0 with sweep.csv (:func:`write_bifurcation`), read by :func:`read_bifurcation`.
* ``members/`` (:data:`MEMBERS`): a run folder a member, ``members/m<index>``.
* ``sweep.json`` (:data:`RECORD`): the sweep's record (fingerprint, members, varied keys,
  source, continuation), written atomically (:func:`write_record`), read by
  :func:`read_record`.

No DOLFINx: ``cosserat-fem plot`` reads these files without the solver stack. A file is never
written through a link nor a special file opened (cosserat_fem/common/safe_files.py); damaged or
foreign files are bad input, one line naming the file (a SceneError).
Tests: tests/test_sweep.py, tests/test_bifurcation_diagram.py.
"""

from __future__ import annotations

import csv
import io
import json
import os
from pathlib import Path

from cosserat_fem.common import safe_files
from cosserat_fem.common.errors import SceneError
from cosserat_fem.io.reading import is_file, quoted

#: A sweep's table, and the folder of its parts (one a group of ranks: table/group-<k>.csv).
SWEEP_TABLE, SWEEP_PARTS = "sweep.csv", "table"
#: The sweep's record.
RECORD = "sweep.json"
#: A bifurcation diagram's section points ([sweep.poincare]).
BIFURCATION = "bifurcation.csv"
#: The folder of the members' run folders (``members/m<index>``, sweep_spec.Member.name).
MEMBERS = "members"
#: A member's status when it stopped for a passing reason (a full disk, limits.wall_time): not
#: finished; a sweep started again runs it, and its later row takes the stopped one's place.
STOPPED = "stopped"


# --- the writers --------------------------------------------------------------------------------
def part_path(out: Path, group: int) -> Path:
    """The table part of group ``group`` in the sweep's folder ``out``."""
    return Path(out) / SWEEP_PARTS / f"group-{group}.csv"


def table_line(fields: list[str], row: dict) -> str:
    """``row`` as one line of the table (CSV, "\n"), its values in the order of ``fields``."""
    buffer = io.StringIO()
    csv.DictWriter(buffer, fields, lineterminator="\n").writerow(row)
    return buffer.getvalue()


def open_part(part: Path, fields: list[str]):
    """The table part ``part`` open for appending rows (text, UTF-8), its header ``fields``
    written first if it is new or empty; OSError if it cannot be."""
    new = not (part.exists() or part.is_symlink()) or part.stat().st_size == 0
    fd = safe_files.create(part) if new else safe_files.open_append(part)
    stream = os.fdopen(fd, "a", encoding="utf-8", newline="")
    if new:
        stream.write(",".join(fields) + "\n")
        stream.flush()
    return stream


def cut_rows_off(out: Path) -> None:
    """A row cut by a kill is cut off its table part too, so that the next row starts a line
    (world rank 0, before anything is appended)."""
    for part in (Path(out) / SWEEP_PARTS).glob("group-*.csv"):
        raw = safe_files.read_regular(part)
        whole = raw.rfind(b"\n") + 1
        if whole != len(raw):
            safe_files.own_copy(part, whole)


def write_table(out: Path, fields: list[str], rows: list[dict]) -> Path:
    """sweep.csv in ``out``: the header ``fields`` and ``rows`` (sorted by member), replaced
    atomically; OSError if it cannot be written."""
    path = Path(out) / SWEEP_TABLE
    text = ",".join(fields) + "\n" + "".join(table_line(fields, r) for r in rows)
    safe_files.replace(path, text, path.with_name(f".{SWEEP_TABLE}.tmp"))
    return path


def write_bifurcation(out: Path, fields: list[str], rows: list[dict]) -> Path:
    """bifurcation.csv in ``out``: the header ``fields`` and ``rows``, replaced atomically;
    OSError if it cannot be written."""
    path = Path(out) / BIFURCATION
    text = ",".join(fields) + "\n" + "".join(table_line(fields, r) for r in rows)
    safe_files.replace(path, text, path.with_name(f".{BIFURCATION}.tmp"))
    return path


def write_record(out: Path, document: dict) -> None:
    """sweep.json in ``out``: ``document`` as indented JSON, replaced atomically."""
    safe_files.replace(Path(out) / RECORD, json.dumps(document, indent=1) + "\n")


def read_record(path: Path) -> tuple[dict | None, str | None]:
    """(the record, None) of the sweep.json ``path``, or (None, why it is not a sweep's
    record: the reason it cannot be read, "not JSON", "not a JSON object")."""
    try:
        held = json.loads(safe_files.read_text(path))
    except (OSError, ValueError, RecursionError) as exc:
        return None, (exc.strerror or str(exc)) if isinstance(exc, OSError) else "not JSON"
    return (held, None) if isinstance(held, dict) else (None, "not a JSON object")


# --- the reader ---------------------------------------------------------------------------------
def _whole_lines(path: Path) -> csv.DictReader:
    """A CSV reader of the file ``path``'s whole lines (a cut last line, of a kill, left
    out, not changed on disk); SceneError naming it if it cannot be read (a special file:
    refused, never opened)."""
    try:
        text = safe_files.read_text(path)
    except (OSError, UnicodeDecodeError) as exc:
        reason = exc.strerror if isinstance(exc, OSError) else exc
        raise SceneError(f"{quoted(path)}: cannot read it ({reason})") from None
    return csv.DictReader(text[: text.rfind("\n") + 1].splitlines())


def read_bifurcation(directory: str | Path, varied: list[str]) -> list[dict]:
    """The rows of the bifurcation.csv in ``directory`` (dicts of text) written for the
    sweep's ``varied`` keys: SceneError naming the file if it cannot be read, or its header
    is not member, the varied keys, direction, point, then a section's columns, or a line
    has another number of fields (a cut last line, of a kill, is left out)."""
    path = Path(directory) / BIFURCATION
    reader = _whole_lines(path)
    header = list(reader.fieldnames or [])
    if header[: len(varied) + 3] != ["member", *varied, "direction", "point"]:
        raise SceneError(
            f"{quoted(path)}: not a bifurcation diagram of the sweep's varied keys {varied} "
            f"(header {','.join(header)[:80]!r})"
        )
    return _whole_rows(path, reader, [])


def read_sweep_rows(directory: str | Path, parts_only: bool = False) -> tuple[list[str], list]:
    """(columns, rows) of the sweep in ``directory``: its sweep.csv, or its table parts (with
    ``parts_only``, or while there is no sweep.csv: a sweep killed or still running). A cut
    last line of a file (a kill) is left out, not changed on disk; the rows (dicts of text)
    come sorted by member. An unreadable file (a special file: refused, never opened) or a
    member that is not a number is bad input."""
    directory = Path(directory)
    table = directory / SWEEP_TABLE
    if not parts_only and is_file(table):
        sources = [table]
    else:
        sources = sorted((directory / SWEEP_PARTS).glob("group-*.csv"))
    columns: list[str] = []
    rows: list[dict] = []
    for source in sources:
        reader = _whole_lines(source)
        rows += _whole_rows(source, reader, columns)
        columns = list(reader.fieldnames or columns)
    if sources != [table]:
        rows = _latest_rows(rows)
    try:
        rows.sort(key=lambda row: int(row["member"]))
    except (KeyError, TypeError, ValueError):
        raise SceneError(
            f"{quoted(directory)}: not a sweep's table (a member that is not a number)"
        ) from None
    return columns, rows


def _latest_rows(rows: list[dict]) -> list[dict]:
    """The rows of a sweep's table parts without those a later run replaced: a member's
    "stopped" row gives way to a row of its run again, or to its last stopped row (the parts
    are read in the order of their groups, not of time). Two rows of a member that did not
    stop are both kept (not the rows of one sweep: check_sweep_rows refuses them)."""
    ran = {row.get("member") for row in rows if row.get("status") != STOPPED}
    last_stop = {
        row.get("member"): row
        for row in rows
        if row.get("status") == STOPPED and row.get("member") not in ran
    }
    return [
        row
        for row in rows
        if row.get("status") != STOPPED or last_stop.get(row.get("member")) is row
    ]


def _whole_rows(source: Path, reader, columns: list[str]) -> list[dict]:
    """The rows of one file of a sweep's table, each with a field for every column of its
    header, the header the same as the other files' (``columns``, if read); SceneError naming
    the file and line otherwise: rows of another table, or damaged, are not merged."""
    header = reader.fieldnames
    if header is None:  # an empty part: its group was killed before it wrote its header
        return []
    if columns and list(header) != columns:
        raise SceneError(
            f"{quoted(source)}: its columns are not those of the sweep's other "
            "table parts: not the same sweep's table"
        )
    if len(set(header)) != len(header) or "" in header:
        raise SceneError(
            f"{quoted(source)}: a header with an empty or repeated column; not a sweep's table"
        )
    rows = []
    for row in reader:
        extra = row.pop(None, None) or []  # fields beyond the header's
        missing = sum(row[k] is None for k in header)  # fields short of it
        if extra or missing:
            raise SceneError(
                f"{quoted(source)}: line {reader.line_num} has "
                f"{len(header) + len(extra) - missing} fields, not the header's "
                f"{len(header)}"
            )
        rows.append(row)
    return rows


def check_sweep_rows(
    directory: str | Path, columns: list[str], rows: list[dict], record: dict
) -> tuple[str, ...]:
    """The varied keys of the sweep recorded in ``record`` (its sweep.json, from
    cosserat_fem/studies/sweep_run.py) after checking that ``rows`` are its rows: one a member, each
    of a member it has (0 ... members − 1), with the member's values of the varied keys as
    the sweep's table writes them (JSON), and the table's varied columns the record's.
    SceneError naming the table otherwise: a row of another sweep is not merged."""
    where = quoted(Path(directory) / SWEEP_TABLE)
    varied, members = record.get("varied"), record.get("members")
    if not (
        isinstance(varied, list)
        and all(isinstance(k, str) for k in varied)
        and isinstance(members, int)
        and not isinstance(members, bool)
    ):
        raise SceneError(
            f"{quoted(Path(directory) / RECORD)}: not a sweep's record (varied, members)"
        )
    if (
        "wall_s" not in columns
        or "steps" not in columns
        or columns[columns.index("wall_s") + 1 : columns.index("steps")] != varied
    ):
        raise SceneError(f"{where}: its varied columns are not the sweep's {varied}")
    values = _member_values(record, members)
    seen: set[int] = set()
    for row in rows:
        index = int(row["member"])
        if not 0 <= index < members or index in seen:
            reason = "twice" if index in seen else f"but the sweep has {members} members"
            raise SceneError(f"{where}: a row of member {index}, {reason}: not this sweep's rows")
        seen.add(index)
        if values is not None and any(row[k] != json.dumps(values[index].get(k)) for k in varied):
            raise SceneError(
                f"{where}: the row of member {index} holds other values of "
                f"{', '.join(varied)} than the sweep's member: not this sweep's row"
            )
    return tuple(varied)


def _member_values(record: dict, members: int) -> list[dict] | None:
    """Each member's values of the varied keys, from the record's fingerprint (the sweep's
    JSON document, cosserat_fem/studies/sweep_spec.py), or None where it does not hold them."""
    try:
        listed = json.loads(record.get("fingerprint") or "")["members"]
    except (TypeError, ValueError, KeyError, RecursionError):
        return None
    if not isinstance(listed, list) or len(listed) != members:
        return None
    values = [m[0] if isinstance(m, list) and len(m) == 2 else m for m in listed]
    return values if all(isinstance(v, dict) for v in values) else None
