"""Running a sweep (cosserat_fem/studies/sweep_spec.py) over MPI: groups of ranks, members dealt by
a one-sided counter, one row per member in the results table.

Under ``mpirun -n N`` the world splits (``MPI.Comm.Split``) into N / group_size groups of
consecutive ranks. Each group takes the next member from a counter on world rank 0
(``MPI.Win.Fetch_and_op``: dynamic dealing, so that members of unequal cost balance), runs it
on its own communicator exactly as ``cosserat-fem run`` runs the member's scene alone (so its
results are the same bit for bit), and its first rank appends the member's row to the group's
part of the table, ``table/group-<k>.csv``, flushed row by row. When every member is done,
world rank 0 merges the parts into ``sweep.csv``, sorted by member. Each member's folder is
``members/m<index>``: all of a run's outputs, or with ``keep = "probes"`` its probes.csv and
summary.json only.

A member that fails (Newton that gives up: "failed"; a SceneError at run time or a bug:
"error") is recorded with its status and one-line reason and the sweep goes on. A member
that stops for a passing reason ("stopped": a StopError such as a full disk or
limits.wall_time, a folder it cannot make, memory or disk the machine lacks now) is recorded
but not finished: it keeps its checkpoint, the chain it continues stops there, and the sweep
raises StopError (exit 4) once its table is written. A sweep that is killed or stopped and
started again with the same ``--out`` skips the members that finished, runs those without a
row from their start (a row cut by the kill is dropped) and continues each stopped member
from its checkpoint (else from its start); ``sweep.json`` records the sweep (written
atomically: a damaged one is refused in one line naming it), and a different sweep in the
same folder is refused (limits.* may differ: SweepSpec.fingerprint). The sweep holds its
folder's lock while it runs (a second sweep or run there is refused, naming it;
cosserat_fem/io/run_folder.py); the members' folders inside are its own. Its files are never
written through a link, nor is a special file opened (cosserat_fem/common/safe_files.py). Members
run one after another in each group, and a member's rows of probes are only held until its
row is written: memory per rank does not grow with the sweep.

A frequency response (``[sweep.response]``) deals chains rather than members: a group runs
a chain's members in order, each from the final state its predecessor saved in
``final_state.npz`` (kept with ``keep = "probes"`` too) and at the start time that carries the
forcing's phase over (response.continued_start); a restarted chain continues from the last
finished member's saved state; after a failed member its chain goes on from rest.

A bifurcation diagram (``[sweep.poincare]``) runs each member with a Poincaré section
(cosserat_fem/analysis/observers.py ``PoincareSection``: poincare.csv in its folder, kept with
``keep = "probes"`` too; such a member stopped before runs again from its start, as its
section is not in a checkpoint); with a continuation its chains run as a response's, each
member from its predecessor's final state over its scene's time span shifted to the start that
carries the forcing's phase over. World rank 0 then gathers the points of every completed
member, but its first ``discard``, into ``bifurcation.csv`` (:func:`gather_sections`).

The row: ``member``, ``status`` ("completed", or "failed", "error", "stopped" as above),
``wall_s`` (the member's run), each varied key's value, the run's ``steps`` and
``newton_iterations``, with ``[sweep.rom]`` the ``model`` each member used ("reduced",
"full") and the reduced run's error ``indicator`` (its summary's rom.indicator.max, empty
where absent), and for each probe column c (x, y, z [m], theta, psi, phi [rad]):
``final_c`` and ``max_abs_c`` over the run; for a frequency response, the chain's
``direction``, the ``previous`` member it continued (empty: from rest), its ``start_s`` and
``end_s``, the ``periods`` it ran, whether it ``settled`` and the last period's ``change``,
and per column c its ``amp_c``, ``mean_c``, ``h1_c`` and ``phase_c``
(cosserat_fem/studies/response.py); ``message`` for a failure.
A sweep with ``[sweep.rom]`` (docs/rom.md §11) runs its members on a reduced model: the
basis file given, or one made before any member runs from full runs (from rest, on every
rank of the world, as ``cosserat-fem rom build`` makes it) of the members it names, written
to ``rom/basis.npz`` in the sweep's folder with those runs' outputs in ``rom/training/``;
a sweep started again reuses a basis it can read (:func:`sweep_basis`).
Tests: tests/test_sweep.py, tests/test_response.py, tests/test_bifurcation_diagram.py,
tests/test_rom_cli.py.
"""

from __future__ import annotations

import contextlib
import io
import json
import shutil
import time
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from mpi4py import MPI

from cosserat_fem.analysis import budget
from cosserat_fem.analysis.progress import SweepProgress
from cosserat_fem.common import safe_files
from cosserat_fem.common.errors import (
    CosseratError,
    OutputError,
    SceneError,
    SolverError,
    StopError,
)
from cosserat_fem.common.parallel import agree
from cosserat_fem.io.folder_lock import holding_folders
from cosserat_fem.io.poincare import POINCARE, STATE_RMS, read_poincare
from cosserat_fem.io.probes import PROBE_COLUMNS, PROBES
from cosserat_fem.io.run_folder import SUMMARY, prepare_output_dir
from cosserat_fem.io.sweep_table import (
    MEMBERS,
    RECORD,
    STOPPED,
    SWEEP_PARTS,
    SWEEP_TABLE,
    cut_rows_off,
    open_part,
    part_path,
    read_record,
    read_sweep_rows,
    table_line,
    write_bifurcation,
    write_record,
    write_table,
)
from cosserat_fem.rod.charts import change_chart
from cosserat_fem.studies.response import COLUMNS as RESPONSE_NAMES
from cosserat_fem.studies.response import MEASURES, PeriodicResponse, continued_start
from cosserat_fem.studies.sweep_spec import Member, SweepSpec, forced_span

PROBE_NAMES = PROBE_COLUMNS[1:]  # x, y, z [m], θ, ψ, φ [rad]
FINAL_STATE = "final_state.npz"
#: How a stopped run's message (observers.DeadlineObserver) starts its advice.
RUN_ADVICE = "; continue it with run --restart"


@dataclass
class SweepResult:
    """What a sweep did (on every rank): the table's path, the members run now, those skipped
    as finished before, and the rows (on world rank 0; sorted by member)."""

    table: Path
    ran: int
    skipped: int
    rows: list[dict]


#: A forced member's columns besides a sweep's (cosserat_fem/studies/response.py).
RESPONSE_COLUMNS = ("direction", "previous", "start_s", "end_s", "periods", "settled", "change")


def columns(spec: SweepSpec) -> list[str]:
    """The table's columns (module docstring)."""
    qoi = [f"{kind}_{name}" for name in PROBE_NAMES for kind in ("final", "max_abs")]
    response = []
    if spec.response is not None:
        response = [*RESPONSE_COLUMNS, *(f"{m}_{c}" for c in RESPONSE_NAMES for m in MEASURES)]
    rom = ["model"] if spec.rom is not None else []
    return [
        "member",
        "status",
        *rom,
        "wall_s",
        *spec.varied,
        "steps",
        "newton_iterations",
        *(["indicator"] if rom else []),
        *qoi,
        *response,
        "message",
    ]


def _row(
    spec: SweepSpec,
    member: Member,
    status: str,
    wall: float,
    summary: dict | None,
    probes: np.ndarray | None,
    message: str,
    response: dict | None = None,
) -> dict:
    row = {"member": member.index, "status": status, "wall_s": f"{wall:.6g}"}
    row.update({key: json.dumps(member.values.get(key)) for key in spec.varied})
    if spec.response is not None:
        response = response or {}
        row["direction"] = member.direction
        for key, value in response.items():
            row[key] = (
                repr(value)
                if isinstance(value, float)
                else ""
                if value is None
                else json.dumps(value)
            )
    row["steps"] = summary.get("steps", "") if summary else ""
    row["newton_iterations"] = summary.get("newton", {}).get("iterations", "") if summary else ""
    if spec.rom is not None:
        from cosserat_fem.rom.runs import indicator_of

        row["model"] = spec.rom.model
        indicator = indicator_of(summary)[0] if summary else None
        row["indicator"] = "" if indicator is None else repr(indicator)
    for i, name in enumerate(PROBE_NAMES):
        if probes is not None and len(probes):
            row[f"final_{name}"] = repr(float(probes[-1, 1 + i]))
            row[f"max_abs_{name}"] = repr(float(np.abs(probes[:, 1 + i]).max()))
        else:
            row[f"final_{name}"] = row[f"max_abs_{name}"] = ""
    row["message"] = " ".join(message.split())
    return row


def _finished(out: Path) -> dict[int, dict]:
    """{member: row} of the rows already in the table's parts, a member's "stopped" row
    given way to a row of its run again (io/sweep_table.py's read_sweep_rows)."""
    return {int(row["member"]): row for row in read_sweep_rows(out, parts_only=True)[1]}


def _status(exc: Exception) -> str:
    """A member's status after ``exc`` (module docstring): "stopped" for a passing reason (a
    StopError: an output it could not write, limits.wall_time; the memory or disk it lacked;
    an OSError or MemoryError that escaped), "failed" for numerical trouble or another of
    the project's errors, "error" for bad input found during the run or a bug."""
    if isinstance(exc, StopError | OSError | MemoryError):
        return STOPPED
    if isinstance(exc, CosseratError) and not isinstance(exc, SceneError):
        return "failed"
    return "error"


def _fresh_folder(folder: Path, comm) -> None:
    """``folder`` emptied (a member cut short by a kill or stopped without a checkpoint runs
    again from the start) and made; OutputError on every rank of ``comm`` if it cannot be
    (a passing reason: the member stops)."""
    problem = None
    if comm.rank == 0:
        try:
            if folder.exists():
                shutil.rmtree(folder)
            folder.mkdir(parents=True)
        except OSError as exc:
            problem = OutputError(
                f"sweep: cannot make {str(folder)!r} afresh for its member ({exc.strerror or exc})"
            )
    agree(comm, problem)


def _checkpoint(folder: Path, scene, comm):
    """The checkpoint a stopped member continues from: its folder's, if it is intact, before
    the member's end and its outputs are the checkpoint's run's (checkpoint.py's checks, as
    ``run --restart`` makes them); else None (the member runs from the start). Collective
    over ``comm``: every rank finds the same."""
    from cosserat_fem.io.checkpoint import load_checkpoint
    from cosserat_fem.io.run_folder import check_outputs
    from cosserat_fem.io.xdmf import XDMF

    try:
        checkpoint = load_checkpoint(folder, comm)
        if not checkpoint.time < scene.time.end:
            return None
        check_outputs(
            checkpoint, folder / PROBES, folder / XDMF if scene.output.xdmf else None, comm
        )
    except SceneError:
        return None
    return checkpoint


def _whole_probes(folder: Path, comm) -> np.ndarray | None:
    """The rows of a continued member's probes.csv, from its start (a restart's result holds
    the rows after the checkpoint only): read on rank 0, for the row it writes."""
    from cosserat_fem.io.probes import read_probe_table

    return read_probe_table(folder / PROBES)[1] if comm.rank == 0 else None


def _affordable(scene, folder: Path, comm, start: float | None) -> None:
    """StopError if the member's run would be refused for what this machine has now (free
    disk, memory available): its cost was checked against its limits when the sweep was
    loaded, so what refuses it now passes (budget.py, as simulation.run_scene checks it)."""
    from cosserat_fem.common.parallel import ranks_on_node

    try:
        budget.check(
            scene, "run", folder, ranks_on_node(comm), comm.size, start=start, comm=comm
        )  # every rank of the group stops alike
    except SceneError as exc:
        raise StopError(f"{exc} (now: the sweep runs it when started again)") from None


def _prepare(spec: SweepSpec, out: Path) -> dict[int, dict]:
    """The output folder (world rank 0): made, the sweep recorded or checked against the one
    it holds; the rows of members already finished."""
    out.mkdir(parents=True, exist_ok=True)
    for name in (SWEEP_PARTS, MEMBERS):
        if (out / name).is_symlink():
            raise SceneError(
                f"sweep: {str(out / name)!r} is a link to a folder elsewhere, "
                "which the sweep would write into; use another --out"
            )
    (out / SWEEP_PARTS).mkdir(exist_ok=True)
    record = out / RECORD
    fingerprint = spec.fingerprint()
    if record.exists() or record.is_symlink():
        held, reason = read_record(record)
        if reason or held is None:
            raise SceneError(
                f"sweep: {str(record)!r} is not the record of a sweep ({reason}); "
                "remove it to start the sweep there anew, or use another --out"
            )
        if held.get("fingerprint") != fingerprint:
            raise SceneError(
                f"sweep: {str(out)!r} holds another sweep (other scene or members); "
                "use another --out, or remove it"
            )
    else:
        document = {
            "fingerprint": fingerprint,
            "members": len(spec.members),
            "varied": list(spec.varied),
            "source": spec.source,
            "continuation": spec.continuation,
        }
        write_record(out, document)
    cut_rows_off(out)
    return _finished(out)


@dataclass
class _Final:
    """A member's final state, to continue from: its index, time [s] and forcing period [s],
    and this rank's part of the state (the 12-component U = (p, q) of simulation.run_scene's
    ``initial_state``)."""

    index: int
    t: float
    period: float
    state: np.ndarray


def _final_state(model) -> np.ndarray:
    """This rank's part of the model's state as all twelve components, its angles measured
    from the fixed basis (a chart moved during the run, cosserat_fem/rod/charts.py, is undone:
    the next member starts without one)."""
    full = model.layout.full_array(model.U.x.array)
    if model.chart is not None:
        Q = model.chart.x.array.reshape(-1, 4)
        identity = np.zeros_like(Q)
        identity[:, 0] = 1.0
        if not np.array_equal(Q, identity):
            full = change_chart(full, Q, identity)
    return full.ravel().copy()


def _save_final(folder: Path, final: _Final, comm) -> None:
    """``final_state.npz`` in the member's folder: t, period and each rank's part (U0, U1,
    ...; a chain runs on one group, so the parts fit the next member's partition). Every rank
    raises alike if rank 0 cannot write it."""
    parts = comm.gather(final.state, root=0)
    problem = None
    if comm.rank == 0:
        arrays = {f"U{r}": part for r, part in enumerate(parts)}
        data = io.BytesIO()
        np.savez(data, t=final.t, period=final.period, **arrays)
        try:
            safe_files.replace(folder / FINAL_STATE, data.getvalue(), folder / ".final_state.npz")
        except OSError as exc:
            problem = OutputError(f"sweep: cannot write {str(folder / FINAL_STATE)!r} ({exc})")
    agree(comm, problem)


def _load_final(folder: Path, index: int, comm) -> _Final | None:
    """The final state a member saved, or None if it has none (it failed) or it cannot be
    read (the chain then goes on from rest; every rank reads the same file alike). A group of
    another size is refused before (the sweep's fingerprint holds group_size)."""
    path = folder / FINAL_STATE
    try:
        with np.load(io.BytesIO(safe_files.read_regular(path))) as data:
            final = _Final(
                index, float(data["t"]), float(data["period"]), np.array(data[f"U{comm.rank}"])
            )
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile):
        final = None
    read = final is not None if comm.size == 1 else comm.allreduce(final is not None, MPI.LAND)
    return final if read else None  # every rank alike: one rank from rest would hang the rest


def _forced(spec: SweepSpec, member: Member, before: _Final | None):
    """A forced member's scene, its response observer and its start (module docstring of
    cosserat_fem/studies/response.py): from the scene's time.start at rest, or continuing ``before``
    with the forcing's phase carried over."""
    from cosserat_fem.output.fields import probe_sigma

    settings = spec.response
    assert settings is not None, "a forced member's sweep has its sweep.response"
    own = spec.scene(member)
    where = f"member {member.index}"
    period, span = forced_span(settings, own, own.time.start, where)
    if before is not None:
        start = continued_start(before.t, before.period, period)
        span = forced_span(settings, own, start, where)[1]
    scene = spec.scene(member, span)
    return scene, PeriodicResponse(settings, period, probe_sigma(scene)), period


def _continued(spec: SweepSpec, member: Member, before: _Final | None):
    """A member of a Poincaré section's chain ([sweep.poincare] with a continuation, no
    [sweep.response]): its scene and the section's period [s]; continuing ``before``, its
    scene's time span (time.end − time.start) from the start that carries the forcing's
    phase over (response.continued_start)."""
    period = spec.section_period(member)
    own = spec.scene(member)
    if before is None:
        return own, period
    start = continued_start(before.t, before.period, period)
    span = {"time.start": start, "time.end": start + (own.time.end - own.time.start)}
    return spec.scene(member, span), period


def _run_member(
    spec: SweepSpec,
    member: Member,
    folder: Path,
    comm,
    before: _Final | None = None,
    resume: bool = False,
    basis: Path | None = None,
) -> tuple[dict, _Final | None]:
    """Run one member on ``comm`` into ``folder`` (a member of a chain continuing ``before``
    if given; with ``resume``, a member that stopped before, from its checkpoint if it has a
    usable one: not a forced member nor one with a Poincaré section, whose measurement or
    section is not in the checkpoint); its row and, for a chain, its final state (every
    rank of ``comm``). With [sweep.poincare], the member's poincare.csv in ``folder``; with
    ``basis`` (a basis file), a reduced run on it (cosserat_fem/rom/runs.py)."""
    from cosserat_fem.analysis.simulation import run_scene

    t0 = time.perf_counter()
    summary, probes, status, message = None, None, "completed", ""
    response, final = None, None
    period: float | None = None
    try:
        observers: list = []
        initial, checkpoint = None, None
        if spec.response is not None:
            scene, response, period = _forced(spec, member, before)
            observers = [response]
            initial = before.state if before is not None else None
        elif spec.chains_continue:
            scene, period = _continued(spec, member, before)
            initial = before.state if before is not None else None
        else:
            scene = spec.scene(member)
            if resume and spec.poincare is None:
                checkpoint = _checkpoint(folder, scene, comm)
        if spec.poincare is not None:
            from cosserat_fem.analysis.observers import PoincareSection

            section_period = spec.section_period(member)
            observers.append(
                PoincareSection(section_period, spec.poincare.phase, folder / POINCARE)
            )
        if checkpoint is None:
            _fresh_folder(folder, comm)
        _affordable(scene, folder, comm, checkpoint.time if checkpoint is not None else None)
        options = {
            "comm": comm,
            "record": True,
            "observers": observers,
            "initial_state": initial,
            "restart": checkpoint,
        }
        if basis is None:
            result = run_scene(scene, folder, **options)
        else:
            from cosserat_fem.rom.runs import run as reduced_run

            result = reduced_run(scene, basis, folder, **options)
        summary = result.summary
        probes = result.probes if checkpoint is None else _whole_probes(folder, comm)
        if spec.chains_continue:
            state = _final_state(result.model)
            assert period is not None, "continuing chains are forced (their period is set)"
            final = _Final(member.index, result.time_reached, period, state)
            _save_final(folder, final, comm)
    except Exception as exc:  # recorded, and the sweep goes on (a bug's too: "error")
        status = _status(exc)
        # a run's advice to restart it is the sweep's to follow when started again
        message = f"{type(exc).__name__}: {str(exc).split(RUN_ADVICE)[0]}"
    wall = time.perf_counter() - t0
    if summary is None and (folder / SUMMARY).exists():
        summary = json.loads(safe_files.read_text(folder / SUMMARY))
    if comm.rank == 0 and spec.keep == "probes" and status != STOPPED and folder.exists():
        for entry in folder.iterdir():  # a stopped member keeps all, to continue from
            if entry.name not in (PROBES, SUMMARY, FINAL_STATE, POINCARE):
                shutil.rmtree(entry) if entry.is_dir() else entry.unlink()
    measured = None
    if spec.response is not None:
        measured = {
            "previous": before.index if before is not None else None,
            **(response.result if response is not None and response.result else {}),
        }
    return _row(spec, member, status, wall, summary, probes, message, measured), final


def _run_chain(
    spec: SweepSpec,
    chain: tuple[int, ...],
    done: set[int],
    stopped: set[int],
    out: Path,
    comm,
    write,
    basis: Path | None = None,
) -> int:
    """Run a chain's members not done, in order, each continuing the one before it when the
    sweep continues (from its saved state if it was done before a restart); those in
    ``stopped`` continue their stopped run (:func:`_run_member`). ``write(row)`` each row.
    A member that stops ends its chain when the next would continue it (the chain goes on
    when the sweep is started again). ``basis``: the reduced members' basis file. The
    number run."""
    ran, before = 0, None
    for position, index in enumerate(chain):
        member = spec.members[index]
        folder = out / MEMBERS / member.name
        if index in done:
            continue
        if (
            spec.chains_continue
            and position
            and (before is None or before.index != chain[position - 1])
        ):
            previous = spec.members[chain[position - 1]]
            before = _load_final(out / MEMBERS / previous.name, previous.index, comm)
        row, before = _run_member(spec, member, folder, comm, before, index in stopped, basis)
        write(row)
        ran += 1
        if row["status"] == STOPPED and spec.chains_continue:
            break
    return ran


class _Counter:
    """The next member to run, shared by every group: an integer on world rank 0 that each
    group's first rank increments with MPI_Fetch_and_op (one-sided: no rank serves it)."""

    def __init__(self, world):
        self.window = MPI.Win.Allocate(8 if world.rank == 0 else 0, 8, comm=world)
        if world.rank == 0:
            # mpi4py's memory has the buffer protocol; its stub does not declare it
            np.frombuffer(self.window.tomemory(), dtype=np.int64)[0] = 0  # type: ignore[call-overload]
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


@holding_folders
def run_sweep(
    spec: SweepSpec, out: str | Path, world=MPI.COMM_WORLD, progress: bool = False
) -> SweepResult:
    """Run the members of ``spec`` not yet finished in ``out`` (module docstring), holding the
    folder's lock; collective over ``world``. ``progress`` (the same on every rank): a line on
    stderr per member finished (cosserat_fem/analysis/progress.py SweepProgress)."""
    out = Path(out)
    if world.size % spec.group_size:
        raise SceneError(
            f"sweep.group_size: {spec.group_size} does not divide the {world.size} "
            "ranks (mpirun -n must be a multiple of it)"
        )
    fields = columns(spec)
    prepare_output_dir(out, world, lock="sweep")
    error, finished = None, {}
    if world.rank == 0:
        try:
            finished = _prepare(spec, out)
        except (SceneError, OSError) as exc:
            error = str(exc) if isinstance(exc, SceneError) else f"sweep: {exc}"
    error = world.bcast(error, root=0)
    if error:
        raise SceneError(error)
    status = world.bcast({k: row["status"] for k, row in finished.items()}, root=0)
    done = {k for k, v in status.items() if v != STOPPED}
    stopped = set(status) - done
    todo = [chain for chain in spec.chains if not done.issuperset(chain)]
    # PETSc initialises collectively over the world communicator when DOLFINx is first
    # imported: every rank does it now, before the groups go their own ways (a group with
    # no member would never import it, and the others' import would wait for it for ever).
    from cosserat_fem.analysis import simulation  # noqa: F401

    basis = sweep_basis(spec, out, world)
    color = world.rank // spec.group_size
    group = world.Split(color, world.rank)
    leader = group.rank == 0  # writes the group's table part
    counter = _Counter(world)
    members = sum(index not in done for chain in todo for index in chain)
    report = SweepProgress(members, _Counter(world)) if progress else None
    part = part_path(out, color)
    ran, stream, failure = 0, None, None
    try:
        problem: CosseratError | None = None
        if leader:
            try:
                stream = open_part(part, fields)
            except OSError as exc:
                problem = OutputError(f"sweep: cannot write {str(part)!r} ({exc})")
        agree(group, problem)

        def write(row: dict) -> None:
            """The row appended to the group's part; every rank of the group raises alike if
            the leader cannot write it."""
            problem = None
            if stream is not None:
                try:
                    stream.write(table_line(fields, row))
                    stream.flush()
                except OSError as exc:
                    problem = OutputError(f"sweep: cannot write {str(part)!r} ({exc})")
            agree(group, problem)
            if report is not None and leader:
                report(row)

        while True:
            k = counter.next() if leader else None
            k = group.bcast(k, root=0)
            if k >= len(todo):
                break
            ran += _run_chain(spec, todo[k], done, stopped, out, group, write, basis)
    except CosseratError as exc:  # a group's part it cannot write: raised by every rank below
        failure = exc
    finally:
        if stream is not None:
            with contextlib.suppress(OSError):  # what it could not write was reported
                stream.close()
        world.Barrier()
        counter.free()
        if report is not None:
            report.counter.free()
        group.Free()
    agree(world, failure)  # the other groups would wait for this one's ranks for ever
    ran = world.allreduce(ran if leader else 0, op=MPI.SUM)  # before rank 0 works alone
    rows: list = []
    problem = None
    if world.rank == 0:  # alone: what it meets is every rank's (agree), never a hang
        try:
            rows = list(_finished(out).values())  # sorted by member
            write_table(out, fields, rows)
            if spec.poincare is not None:
                gather_sections(spec, out, rows)
        except OSError as exc:
            problem = OutputError(
                f"sweep: cannot write {str(out / SWEEP_TABLE)!r} "
                f"({exc.strerror or exc}); its rows are kept in {SWEEP_PARTS}/"
            )
        except CosseratError as exc:  # a table part damaged while the sweep ran
            problem = exc
    agree(world, problem)
    _stop_if_unfinished(spec, rows, world)
    return SweepResult(out / SWEEP_TABLE, ran, len(done), rows)


#: Where a sweep trains its reduced members' basis ([sweep.rom] train), in its folder.
ROM_FOLDER = "rom"


def sweep_basis(spec: SweepSpec, out: Path, world) -> Path | None:
    """The basis file of the sweep's reduced members (module docstring), None if they run in
    full: the file of ``[sweep.rom] basis``, checked against the first member's mesh
    (basis.read_basis: another mesh or space refused in one line), or ``rom/basis.npz`` in
    ``out`` trained now from full runs of the members of ``[sweep.rom] train`` (from rest,
    each on the first group of group_size ranks of ``world``, as a member runs, the other
    ranks waiting; their outputs in rom/training/<member>), or, when the
    sweep is started again, the one trained before if it can be read. Collective."""
    from cosserat_fem.rod.model import build_model
    from cosserat_fem.rom import basis as rb
    from cosserat_fem.rom.runs import sweep_targets, train_targets

    if not spec.reduced:
        return None
    assert spec.rom is not None

    def unreadable(file) -> SceneError | None:
        """Why the basis ``file`` cannot run the members (read on a group of group_size
        ranks, as a member reads it: a hyper-reduced basis is read on one), agreed by every
        rank; None if it can."""
        group = world.Split(world.rank // spec.group_size, world.rank)
        try:
            rb.read_basis(file, build_model(spec.scene(spec.members[0]), group))
            problem = None
        except SceneError as exc:
            problem = str(exc)
        finally:  # the model's mesh holds a duplicate of its own (DOLFINx's MPI::Comm)
            group.Free()
        found = [p for p in world.allgather(problem) if p] if world.size > 1 else [problem]
        return SceneError(found[0]) if found and found[0] else None

    if spec.rom.basis is not None:
        problem = unreadable(spec.rom.basis)  # refused here, before any member runs
        if problem is not None:
            raise SceneError(f"sweep.rom.basis: {problem}")
        return Path(spec.rom.basis)
    path = out / ROM_FOLDER / "basis.npz"
    if path.is_file() and (out / ROM_FOLDER / "basis.json").is_file():
        if unreadable(path) is None:  # else cut by a kill: trained again
            return path
    targets = sweep_targets(spec, spec.rom.train)
    settings = spec.rom

    def train(comm) -> None:
        trained, model = train_targets(
            targets,
            tolerance=settings.tolerance,
            modes=settings.modes,
            every=settings.every,
            keep=out / ROM_FOLDER / "training",
            comm=comm,
        )
        if settings.ecsw is not None:  # ECSW's second runs (docs/rom.md §9)
            from cosserat_fem.rom import hyper

            trained = hyper.ecsw(targets, trained, settings.ecsw, comm=comm)
        rb.write_basis(trained, model, path)

    if world.size == spec.group_size:
        train(world)
        return path
    # trained as a member runs: on the first group of group_size ranks (ECSW: one rank), the
    # others waiting for its file; an 8-element rod's run on every rank of a world costs
    # tens of times its serial run in messages, and the basis is then the serial sweep's
    first = world.rank < spec.group_size
    group = world.Split(0 if first else MPI.UNDEFINED, world.rank)
    failure: CosseratError | None = None
    if first:
        try:
            train(group)
        except CosseratError as exc:
            failure = exc
        except Exception as exc:  # PETSc, an SVD, memory: the waiting ranks must hear it too
            failure = SolverError(f"sweep.rom: training the basis failed: {exc}")
        finally:
            group.Free()
    agree(world, failure)
    return path


#: bifurcation.csv's columns of a member's section point (poincare.csv's, without the
#: columns of output.probe_fields).
SECTION_NAMES = ("period", "t", *PROBE_NAMES, STATE_RMS)


def bifurcation_columns(spec: SweepSpec) -> list[str]:
    """bifurcation.csv's columns: ``member``, the varied keys, the chain's ``direction``,
    ``point`` (the point's number in the member's diagram, from 0), then the section's
    ``period`` j, ``t`` [s], x, y, z [m], θ, ψ, φ [rad] at the probe point and
    ``state_rms`` (cosserat_fem/io/poincare.py)."""
    return ["member", *spec.varied, "direction", "point", *SECTION_NAMES]


def gather_sections(spec: SweepSpec, out: Path, rows: list[dict]) -> Path:
    """bifurcation.csv in ``out`` (io/sweep_table.py write_bifurcation): the section points of
    every completed member of ``rows`` (its poincare.csv), but its first
    sweep.poincare.discard ones, sorted by member and point; values as poincare.csv holds
    them (17 digits). SceneError naming a member's poincare.csv that cannot be read,
    OSError if the table cannot be written (world rank 0)."""
    assert spec.poincare is not None
    fields = bifurcation_columns(spec)
    points: list[dict] = []
    for row in rows:
        if row["status"] != "completed":
            continue
        member = spec.members[int(row["member"])]
        columns, section = read_poincare(out / MEMBERS / member.name / POINCARE)
        take = [columns.index(c) for c in SECTION_NAMES]
        values = {key: json.dumps(member.values.get(key)) for key in spec.varied}
        for k, point in enumerate(section[spec.poincare.discard :, take]):
            points.append(
                {
                    "member": member.index,
                    **values,
                    "direction": member.direction,
                    "point": k,
                    "period": int(point[0]),
                    **{
                        c: repr(float(v)) for c, v in zip(SECTION_NAMES[1:], point[1:], strict=True)
                    },
                }
            )
    return write_bifurcation(out, fields, points)


def _stop_if_unfinished(spec: SweepSpec, rows: list[dict], world) -> None:
    """StopError on every rank if members stopped, or were not run because a member they
    continue stopped (rows on world rank 0): the sweep is not finished, and started again
    with the same --out it continues them."""
    problem = None
    if world.rank == 0:
        have = {int(row["member"]) for row in rows}
        halted = [row for row in rows if row["status"] == STOPPED]
        left = len(spec.members) - len(have)
        if halted or left:
            first = f" (member {halted[0]['member']}: {halted[0]['message']})" if halted else ""
            problem = StopError(
                f"sweep: {len(halted)} member{'s' if len(halted) != 1 else ''} stopped{first}"
                f"{f' and {left} not run after them' if left else ''}; start the sweep again "
                "with the same --out to continue (limits.* may change)"
            )
    agree(world, problem)
