"""Running a sweep (cosserat_fem/sweep_spec.py) over MPI: groups of ranks, members dealt by a
one-sided counter, one row per member in the results table.

Under ``mpirun -n N`` the world splits (``MPI.Comm.Split``) into N / group_size groups of
consecutive ranks. Each group takes the next member from a counter on world rank 0
(``MPI.Win.Fetch_and_op``: dynamic dealing, so that members of unequal cost balance), runs it
on its own communicator exactly as ``cosserat-fem run`` runs the member's scene alone (so its
results are the same bit for bit), and its first rank appends the member's row to the group's
part of the table, ``table/group-<k>.csv``, flushed row by row. When every member is done,
world rank 0 merges the parts into ``sweep.csv``, sorted by member. Each member's folder is
``members/m<index>``: all of a run's outputs, or with ``keep = "probes"`` its probes.csv and
summary.json only.

A member that fails (a SceneError at run time, Newton that gives up, a limit) is recorded with
its status and one-line reason and the sweep goes on. A sweep that is killed and started
again with the same ``--out`` skips the members that have a row (a row cut by the kill is
dropped and its member run again); ``sweep.json`` records the sweep, and a different sweep in
the same folder is refused. Members run one after another in each group, and a member's rows
of probes are only held until its row is written: memory per rank does not grow with the sweep.

The row: ``member``, ``status`` ("completed", or the run's failure: "failed", "stopped",
"error"), ``wall_s`` (the member's run), each varied key's value, the run's ``steps`` and
``newton_iterations``, and for each probe column c (x, y, z [m], theta, psi, phi [rad]):
``final_c`` and ``max_abs_c`` over the run; ``message`` for a failure.
"""

from __future__ import annotations

import csv
import io
import json
import shutil
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from mpi4py import MPI

from .errors import CosseratError, SceneError, SolverError, StopError
from .results import SWEEP_PARTS, SWEEP_TABLE, read_sweep_rows
from .sweep_spec import Member, SweepSpec

PROBE_NAMES = ("x", "y", "z", "theta", "psi", "phi")
RECORD = "sweep.json"


@dataclass
class SweepResult:
    """What a sweep did (on every rank): the table's path, the members run now, those skipped
    as finished before, and the rows (on world rank 0; sorted by member)."""

    table: Path
    ran: int
    skipped: int
    rows: list[dict]


def columns(spec: SweepSpec) -> list[str]:
    """The table's columns (module docstring)."""
    qoi = [f"{kind}_{name}" for name in PROBE_NAMES for kind in ("final", "max_abs")]
    return ["member", "status", "wall_s", *spec.varied, "steps", "newton_iterations", *qoi,
            "message"]  # fmt: skip


def _row(spec: SweepSpec, member: Member, status: str, wall: float, summary: dict | None,
         probes: np.ndarray | None, message: str) -> dict:  # fmt: skip
    row = {"member": member.index, "status": status, "wall_s": f"{wall:.6g}"}
    row.update({key: json.dumps(member.values.get(key)) for key in spec.varied})
    row["steps"] = summary.get("steps", "") if summary else ""
    row["newton_iterations"] = summary.get("newton", {}).get("iterations", "") if summary else ""
    for i, name in enumerate(PROBE_NAMES):
        have = probes is not None and len(probes)
        row[f"final_{name}"] = repr(float(probes[-1, 1 + i])) if have else ""
        row[f"max_abs_{name}"] = repr(float(np.abs(probes[:, 1 + i]).max())) if have else ""
    row["message"] = " ".join(message.split())
    return row


def _csv_line(fields: list[str], row: dict) -> str:
    buffer = io.StringIO()
    csv.DictWriter(buffer, fields, lineterminator="\n").writerow(row)
    return buffer.getvalue()


def _cut_rows_off(out: Path) -> None:
    """A row cut by a kill is cut off its table part too, so that the next row starts a line
    (world rank 0, before anything is appended)."""
    for part in (out / SWEEP_PARTS).glob("group-*.csv"):
        raw = part.read_bytes()
        whole = raw.rfind(b"\n") + 1
        if whole != len(raw):
            with open(part, "r+b") as stream:
                stream.truncate(whole)


def _finished(out: Path) -> dict[int, dict]:
    """{member: row} of the rows already in the table's parts."""
    return {int(row["member"]): row for row in read_sweep_rows(out, parts_only=True)[1]}


def _prepare(spec: SweepSpec, out: Path) -> dict[int, dict]:
    """The output folder (world rank 0): made, the sweep recorded or checked against the one
    it holds; the rows of members already finished."""
    out.mkdir(parents=True, exist_ok=True)
    (out / SWEEP_PARTS).mkdir(exist_ok=True)
    record = out / RECORD
    fingerprint = spec.fingerprint()
    if record.exists():
        held = json.loads(record.read_text(encoding="utf-8"))
        if held.get("fingerprint") != fingerprint:
            raise SceneError(f"sweep: {str(out)!r} holds another sweep (other scene or members); "
                             "use another --out, or remove it")  # fmt: skip
    else:
        document = {"fingerprint": fingerprint, "members": len(spec.members),
                    "varied": list(spec.varied), "source": spec.source}  # fmt: skip
        record.write_text(json.dumps(document, indent=1) + "\n", encoding="utf-8")
    _cut_rows_off(out)
    return _finished(out)


def _run_member(spec: SweepSpec, member: Member, folder: Path, comm) -> dict:
    """Run one member on ``comm`` into ``folder``; its row (every rank of ``comm``)."""
    from .simulation import run

    if comm.rank == 0 and folder.exists():
        shutil.rmtree(folder)  # a member cut short by a kill runs again from the start
    comm.Barrier()
    t0 = time.perf_counter()
    summary, probes, status, message = None, None, "completed", ""
    try:
        result = run(spec.scene(member), folder, comm=comm, record=True)
        summary, probes = result.summary, result.probes
    except Exception as exc:  # recorded, and the sweep goes on (a bug's too: "error")
        status = "error"
        if isinstance(exc, SolverError):
            status = "failed"
        elif isinstance(exc, StopError):
            status = "stopped"
        elif isinstance(exc, CosseratError) and not isinstance(exc, SceneError):
            status = "failed"
        message = f"{type(exc).__name__}: {exc}"
    wall = time.perf_counter() - t0
    if summary is None and (folder / "summary.json").exists():
        summary = json.loads((folder / "summary.json").read_text(encoding="utf-8"))
    if comm.rank == 0 and spec.keep == "probes" and folder.exists():
        for entry in folder.iterdir():
            if entry.name not in ("probes.csv", "summary.json"):
                shutil.rmtree(entry) if entry.is_dir() else entry.unlink()
    return _row(spec, member, status, wall, summary, probes, message)


class _Counter:
    """The next member to run, shared by every group: an integer on world rank 0 that each
    group's first rank increments with MPI_Fetch_and_op (one-sided: no rank serves it)."""

    def __init__(self, world):
        self.window = MPI.Win.Allocate(8 if world.rank == 0 else 0, 8, comm=world)
        if world.rank == 0:
            np.frombuffer(self.window.tomemory(), dtype=np.int64)[0] = 0
        world.Barrier()
        self._one = np.ones(1, dtype=np.int64)
        self._got = np.zeros(1, dtype=np.int64)

    def next(self) -> int:
        self.window.Lock(0)
        self.window.Fetch_and_op(self._one, self._got, 0, op=MPI.SUM)
        self.window.Unlock(0)
        return int(self._got[0])

    def free(self) -> None:
        self.window.Free()


def run_sweep(spec: SweepSpec, out: str | Path, world=MPI.COMM_WORLD) -> SweepResult:
    """Run the members of ``spec`` not yet finished in ``out`` (module docstring);
    collective over ``world``."""
    out = Path(out)
    if world.size % spec.group_size:
        raise SceneError(f"sweep.group_size: {spec.group_size} does not divide the {world.size} "
                         "ranks (mpirun -n must be a multiple of it)")  # fmt: skip
    fields = columns(spec)
    error, finished = None, {}
    if world.rank == 0:
        try:
            finished = _prepare(spec, out)
        except (SceneError, OSError) as exc:
            error = str(exc) if isinstance(exc, SceneError) else f"sweep: {exc}"
    error = world.bcast(error, root=0)
    if error:
        raise SceneError(error)
    done = set(world.bcast(sorted(finished), root=0))
    todo = [m for m in spec.members if m.index not in done]
    color = world.rank // spec.group_size
    group = world.Split(color, world.rank)
    leader = group.rank == 0  # writes the group's table part
    counter = _Counter(world)
    part = out / SWEEP_PARTS / f"group-{color}.csv"
    ran = 0
    try:
        if leader:
            new = not part.exists() or part.stat().st_size == 0
            stream = open(part, "a", encoding="utf-8", newline="")  # noqa: SIM115
            if new:
                stream.write(",".join(fields) + "\n")
                stream.flush()
        while True:
            k = counter.next() if leader else None
            k = group.bcast(k, root=0)
            if k >= len(todo):
                break
            member = todo[k]
            row = _run_member(spec, member, out / "members" / member.name, group)
            ran += 1
            if leader:
                stream.write(_csv_line(fields, row))
                stream.flush()
        if leader:
            stream.close()
    finally:
        world.Barrier()
        counter.free()
        group.Free()
    ran = world.allreduce(ran if leader else 0, op=MPI.SUM)  # before rank 0 works alone
    rows = []
    if world.rank == 0:
        rows = list(_finished(out).values())  # sorted by member
        text = ",".join(fields) + "\n" + "".join(_csv_line(fields, r) for r in rows)
        temporary = out / f".{SWEEP_TABLE}.tmp"
        temporary.write_text(text, encoding="utf-8")
        temporary.replace(out / SWEEP_TABLE)
    return SweepResult(out / SWEEP_TABLE, ran, len(done), rows)
