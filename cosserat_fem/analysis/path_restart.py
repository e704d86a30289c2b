"""Restarts of a continuation from the last point of a branch, and of the branches after it
(issue 27 item 5).

A continuation with an output folder keeps, after each point of a branch and as it ends,
what the rest of the continuation depends on, following the run's checkpoints
(cosserat_fem/io/checkpoint.py), so a continuation killed anywhere restarts where it was and
traces what the whole run would have traced:

    continuation/restart.json          the scene (as a dict), the settings, the ranks, and per
                                       branch its end: first_index, step, rejected, direction,
                                       slot, rows, its start, special points, origin, chart
                                       moves, the queue after it, and its reason once ended
    continuation/branch<i>.rank<r>.npz  rank r's owned entries of u and t_u of the branch's
    (slot 0; slot 1: .rank<r>.b.npz)    last (at most) three points, of its start and of its
                                        special points, and in 3D their charts (the nodal
                                        quaternions: paths.py)

Each file is replaced whole (common/safe_files.replace). The arrays of a new end go to the
slot the JSON does not name, then the JSON is replaced to name it: a kill between the two
leaves the JSON and the arrays it names of the same, earlier, end.

with each point's λ, dλ/ds, sign and ln|det R_u|, iterations, kind and note in the JSON
(floats written by repr, which round-trips). The three last points are the quadratic
predictor's history; ``first_index`` counts the points before them (max_points), ``step``
is the step the next point would have taken. :func:`restart_branch` rebuilds the scene's
path problem and calls :meth:`~cosserat_fem.nls.arclength.Continuation.resume`: the same
floating-point operations on the same arrays as the uninterrupted trace (the problem's
assemblies and LU factorisations are functions of (u, λ) alone), so a continuation cut in
two gives the very points of the whole one
(tests/test_continuation.py::test_restart_equals_the_whole_branch). Arrays are per rank: a
restart needs the same number of ranks (the same partition). Only ``max_points`` may
change on restart; the range, steps and tolerances are the saved ones.

**The queue.** The whole run (paths.continue_path) traces its branches one at a time from a
queue (paths.Pending): the primary branch's directions, then a switch at each of the first
``switch`` bifurcation points located on them, each switch the new branch's two directions;
each branch is ended (its files, then its final end) before the next begins. All it keeps
to decide the next branch is the queue's pending tasks and the bifurcation points found
(a switch's start is computed from its point when the switch comes up), so each saved end
holds the queue after its branch (:func:`queue_record`), each point named by the branch end
that saved its arrays: ["start", i] (branch i's start: the λ = 0 state of the primary
branch, or a switch's start, from which the second direction is traced) or ["special", i,
k] (branch i's k-th special point). The last branch's end tells the restart
(:func:`restart_queue`) what to do: a branch that did not end (no ``reason``: killed in
it) is resumed from its saved end and ended; then the queue's tasks are traced in order,
numbered on after it. A kill between two branches (the last end has its reason) resumes
nothing and traces the queue; a restart killed in its turn is restarted alike. The files
then are the whole run's: branches.csv byte for byte, branches.json, every branch's XDMF
frames (tests/test_continuation.py::test_a_killed_continuation_traces_the_branches_after_it).

**Rows and frames.** The rows of the branch being traced are appended to branches.csv, and
its frames to branch_<i>.xdmf, as its points are accepted, before its end is saved
(branch_outputs.BranchOutputs.write_rows), and each saved end names the file's rows
through its last point (``rows``; the frames are first_index + the kept points). The
restart cuts branches.csv to the last end's ``rows`` (a row written after it goes), and the
resumed branch's XDMF to its saved points (as restart n), branches.json to the branches
ended before, and appends the rest as the whole run writes it: each branch's points' rows,
then its special points' rows (the killed branch's found before the kill come back from its
end), its entry in branches.json and its frames.

**Restarting one branch.** A restart of a branch that is not the last saved, or of the last
of a continuation that traced its whole queue (a branch ended at max_points: give a larger
--max-points), traces that branch alone (:func:`_restart_one`): its rows appended at the end
of branches.csv (the branch's index kept), its special points found after the restart
after them, its frames to its XDMF, its end and reason saved again. A branch that reached
its range's end is refused. A folder written before the queue was saved (no ``queue`` in
its ends) is restarted this way too, as then: the killed branch alone (its rows from its
saved ``rows`` on, or from its saved points on if its ends name no ``rows``; its XDMF from
its saved points on; its special points found before the kill lost), the branches after it
not traced (start them anew).
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
from mpi4py import MPI

from cosserat_fem.common.errors import SceneError
from cosserat_fem.nls.arclength import Branch, ContinuationSettings, Point

FOLDER = "continuation"
INDEX = "restart.json"
#: The points of a branch's end kept (the quadratic predictor's history).
KEPT = 3
#: branches.json's origin of a branch killed before its end saved its origin
NOT_RECORDED = "not recorded (the continuation was killed on this branch)"


def state_file(branch: int, rank: int, slot: int = 0) -> str:
    """The arrays' file of ``branch`` on ``rank`` in ``slot`` 0 or 1 (module docstring)."""
    return f"branch{branch}.rank{rank}{'.b' if slot else ''}.npz"


def branch_end(branch: Branch, slot: int = 0) -> dict:
    """The JSON part of ``branch``'s end (module docstring), its arrays in ``slot``."""
    kept = branch.points[-KEPT:]
    return {
        "slot": slot,
        "first_index": branch.first_index + len(branch.points) - len(kept),
        "step": branch.step,
        "rejected": branch.steps_rejected,
        "direction": branch.direction,
        "points": [
            {
                "p": q.p,
                "t_p": q.t_p,
                "det_sign": q.det_sign,
                "log_det": q.log_det,
                "iterations": q.iterations,
                "kind": q.kind,
            }
            for q in kept
        ],
    }


def save_branch_state(
    folder: Path,
    index: int,
    branch: Branch,
    comm: MPI.Comm,
    slot: int = 0,
    extra: dict[str, np.ndarray] | None = None,
) -> None:
    """Rank r's arrays of ``branch``'s end into its file of ``slot`` (:func:`state_file`;
    every rank its own file; the ranks agree on a failure), with the ``extra`` arrays
    (:func:`point_arrays` of the branch's start and special points)."""
    from cosserat_fem.common.errors import OutputError
    from cosserat_fem.common.parallel import agree
    from cosserat_fem.common.safe_files import replace

    kept = branch.points[-KEPT:]
    arrays = {f"u{i}": q.u for i, q in enumerate(kept)}
    arrays |= {f"t{i}": q.t_u for i, q in enumerate(kept)}
    arrays |= {f"q{i}": q.chart for i, q in enumerate(kept) if isinstance(q.chart, np.ndarray)}
    arrays |= extra or {}
    problem = None
    try:
        (folder / FOLDER).mkdir(exist_ok=True)
        buffer = _npz(arrays)
        replace(folder / FOLDER / state_file(index, comm.rank, slot), buffer)
    except OSError as exc:
        problem = OutputError(f"{folder / FOLDER}: {exc.strerror or exc}")
    agree(comm, problem)


def _npz(arrays: dict[str, np.ndarray]) -> bytes:
    import io

    out = io.BytesIO()
    np.savez(out, **arrays)
    return out.getvalue()


def point_json(point: Point) -> dict:
    """The JSON part of a saved point (floats by repr, which round-trips)."""
    return {
        "p": point.p,
        "t_p": point.t_p,
        "det_sign": point.det_sign,
        "log_det": point.log_det,
        "iterations": point.iterations,
        "kind": point.kind,
        "note": point.note,
    }


def point_arrays(point: Point, name: str) -> dict[str, np.ndarray]:
    """The arrays of a saved point under ``name``: u, t_u and its chart if it has one."""
    arrays = {f"{name}_u": point.u, f"{name}_t": point.t_u}
    if isinstance(point.chart, np.ndarray):
        arrays[f"{name}_q"] = point.chart
    return arrays


def saved_point(data: dict, arrays, name: str) -> Point:
    """The point :func:`point_json` and :func:`point_arrays` saved under ``name``."""
    chart = arrays[f"{name}_q"] if f"{name}_q" in arrays else None
    return Point(
        arrays[f"{name}_u"],
        data["p"],
        arrays[f"{name}_t"],
        data["t_p"],
        data["det_sign"],
        data["log_det"],
        data["iterations"],
        data["kind"],
        data.get("note", ""),
        chart=chart,
    )


def queue_record(pending: list, found: list, ref) -> dict:
    """The JSON of what a continuation has still to trace after its current branch
    (paths.py's queue: ``pending`` tasks, ``found`` the bifurcation points located on its
    primary branches), each point named by ``ref(point)``: ["start", i] (branch i's start)
    or ["special", i, k] (branch i's k-th special point), whose arrays that branch's end
    saved (module docstring, "The queue")."""
    tasks = []
    for task in pending:
        entry: dict = {"kind": task.kind}
        if task.kind == "trace":
            entry |= {
                "start": ref(task.start),
                "direction": task.direction,
                "search_first": task.search_first,
                "origin": task.origin,
                "primary": task.primary,
            }
        elif task.kind == "switch":
            entry["at"] = ref(task.at)
        else:
            entry["count"] = task.count
        tasks.append(entry)
    return {"pending": tasks, "found": [ref(q) for q in found]}


def write_index(
    folder: Path,
    scene_dict: dict,
    settings: ContinuationSettings,
    ends: dict,
    comm: MPI.Comm,
    restarts: int = 0,
    probe: float | None = None,
) -> None:
    """continuation/restart.json (rank 0; branch_outputs.replace_on_root); ``restarts``: how
    many times it was restarted (numbers the XDMF's restarts); ``probe``: the reported point's
    arclength, None for the default."""
    from cosserat_fem.analysis.branch_outputs import replace_on_root

    record = {
        "format": 1,
        "ranks": comm.size,
        "scene": scene_dict,
        "settings": dataclasses.asdict(settings),
        "branches": {str(k): v for k, v in sorted(ends.items())},
        "restarts": restarts,
        "probe": probe,
    }
    if comm.rank == 0:
        (folder / FOLDER).mkdir(exist_ok=True)
    replace_on_root(folder / FOLDER / INDEX, (json.dumps(record) + "\n").encode(), comm)


def read_index(folder: Path, comm: MPI.Comm) -> dict:
    """The restart record of ``folder`` (rank 0 reads, all get it); SceneError naming
    --restart if there is none or it does not fit these ranks."""
    from cosserat_fem.common.safe_files import Unreadable, read_on_root

    path = folder / FOLDER / INDEX
    try:
        record = json.loads(read_on_root(path, 1 << 28, comm).decode())
    except (OSError, ValueError, Unreadable) as exc:
        raise SceneError(
            f"--restart: {str(folder)!r} holds no continuation to restart ({exc})"
        ) from None
    if record.get("ranks") != comm.size:
        raise SceneError(
            f"--restart: the continuation in {str(folder)!r} ran on {record.get('ranks')} "
            f"ranks; restart it on as many (its states are per rank)"
        )
    return record


def _arrays(folder: Path, end: dict, index: int, comm: MPI.Comm) -> dict[str, np.ndarray]:
    """Rank r's saved arrays of branch ``index``'s end (the slot ``end`` names); SceneError
    naming --restart on every rank if one cannot read its file."""
    from zipfile import BadZipFile

    from cosserat_fem.common.parallel import agree

    path = folder / FOLDER / state_file(index, comm.rank, end.get("slot", 0))
    arrays: dict[str, np.ndarray] = {}
    problem = None
    try:
        with np.load(path) as data:
            arrays = {name: data[name] for name in data.files}
    except (OSError, ValueError, BadZipFile) as exc:  # missing or damaged: every rank refuses alike
        problem = SceneError(
            f"--restart: {str(path)!r} cannot be read ({getattr(exc, 'strerror', None) or exc})"
        )
    agree(comm, problem)
    return arrays


def load_branch(folder: Path, record: dict, index: int, comm: MPI.Comm) -> Branch:
    """The engine's :class:`~cosserat_fem.nls.arclength.Branch` of branch ``index``'s saved end
    (its last points, first_index, step, rejected, direction; its special points and
    chart moves if the end has them: a folder of before they were saved has none)."""
    end = record["branches"].get(str(index))
    if end is None:
        raise SceneError(f"--branch: no branch {index} saved in {str(folder)!r}")
    arrays = _arrays(folder, end, index, comm)
    charts: list = []  # one array per chart (the engine compares them by identity)
    for i in range(len(end["points"])):
        chart = arrays[f"q{i}"] if f"q{i}" in arrays else None
        same = chart is not None and charts and np.array_equal(charts[-1], chart)
        charts.append(charts[-1] if same else chart)
    points = [
        Point(
            arrays[f"u{i}"],
            q["p"],
            arrays[f"t{i}"],
            q["t_p"],
            q["det_sign"],
            q["log_det"],
            q["iterations"],
            q["kind"],
            chart=charts[i],
        )
        for i, q in enumerate(end["points"])
    ]
    special = [saved_point(q, arrays, f"s{k}") for k, q in enumerate(end.get("special", []))]
    return Branch(
        points=points,
        special=special,
        direction=end["direction"],
        steps_rejected=end["rejected"],
        step=end["step"],
        first_index=end["first_index"],
        charts_moved=end.get("charts_moved", 0),
    )


def load_point(folder: Path, record: dict, ref: list, comm: MPI.Comm) -> Point:
    """The saved point ``ref`` names (:func:`queue_record`): a branch's start or one of its
    special points."""
    index = ref[1]
    end = record["branches"][str(index)]
    arrays = _arrays(folder, end, index, comm)
    if ref[0] == "start":
        return saved_point(end["start"], arrays, "start")
    return saved_point(end["special"][ref[2]], arrays, f"s{ref[2]}")


def _has_work(queue: dict) -> bool:
    """Whether ``queue`` (:func:`queue_record`) has a branch left to trace."""
    for task in queue["pending"]:
        if task["kind"] != "switches" or (task["count"] > 0 and queue["found"]):
            return True
    return False


def restart_branch(
    folder: Path,
    record: dict,
    index: int,
    settings: ContinuationSettings,
    stop=None,
    progress=None,
    comm: MPI.Comm = MPI.COMM_WORLD,
):
    """Branch ``index`` of the continuation in ``folder`` traced on from its saved end with
    ``settings``, and, if it is the last branch saved and the continuation was cut before
    its end (its end's queue has work, or it did not end), everything the whole run would
    have traced after it (:func:`restart_queue`): a
    :class:`~cosserat_fem.analysis.paths.PathResult` of those branches (the restarted one's
    points from its first saved one on). Else (a branch that ended, a folder of before the
    queue was saved) only that branch: its new rows appended to branches.csv (at the end of
    the file, the branch's index kept), its frames to branch_<index>.xdmf, its end and
    reason saved again (restart.json, branches.json's entry)."""
    ends = {int(k): v for k, v in record["branches"].items()}
    last = max(ends, default=index)
    end = ends.get(last, {})
    queue = end.get("queue")
    if index == last and queue is not None and ("reason" not in end or _has_work(queue)):
        return restart_queue(folder, record, settings, stop, progress, comm)
    return _restart_one(folder, record, index, settings, stop, progress, comm)


def _csv_lines(folder: Path, comm: MPI.Comm) -> list[str]:
    """branches.csv's lines (the header alone if there is none)."""
    from cosserat_fem.analysis.branch_outputs import BRANCHES_CSV
    from cosserat_fem.analysis.paths import BRANCH_COLUMNS
    from cosserat_fem.common.safe_files import Unreadable, read_on_root

    try:
        lines = read_on_root(folder / BRANCHES_CSV, 1 << 30, comm).decode().splitlines()
    except Unreadable:
        lines = []
    return lines or [",".join(BRANCH_COLUMNS)]


def _reasons(folder: Path, comm: MPI.Comm) -> list[dict]:
    """branches.json's entries (none if there is none)."""
    from cosserat_fem.common.safe_files import Unreadable, read_on_root

    try:
        return json.loads(read_on_root(folder / "branches.json", 1 << 28, comm).decode())
    except Unreadable:
        return []


def _restart_outputs(
    folder: Path,
    record: dict,
    settings: ContinuationSettings,
    lines: list[str],
    progress,
    resumed: tuple[int, int, int] | None,
    comm: MPI.Comm,
):
    """branches.csv replaced by ``lines`` (cut back), and a restart's observer that appends to
    it and saves its ends into restart.json beside the saved ones (the restarts counted
    there only once the restart ends: :func:`_finish_index`)."""
    from cosserat_fem.analysis.branch_outputs import BRANCHES_CSV, BranchOutputs, replace_on_root

    replace_on_root(folder / BRANCHES_CSV, "".join(ln + "\n" for ln in lines).encode(), comm)
    observer = BranchOutputs(folder, progress, resumed)
    observer.csv_made, observer.file_rows = True, len(lines) - 1
    observer.ends = {int(k): v for k, v in record["branches"].items()}
    observer.slots = {k: v.get("slot", 0) for k, v in observer.ends.items()}
    restarts = int(record.get("restarts", 0))

    def save_index(new: dict) -> None:
        write_index(folder, record["scene"], settings, new, comm, restarts, record.get("probe"))

    observer.record = save_index
    return observer


def _finish_index(folder: Path, record: dict, settings, observer, comm: MPI.Comm) -> None:
    """restart.json with the restart's ends, counting it among the restarts."""
    restarts = int(record.get("restarts", 0)) + 1
    write_index(
        folder, record["scene"], settings, observer.ends, comm, restarts, record.get("probe")
    )


def _path_problem(record: dict, folder: Path, end: dict, comm: MPI.Comm):
    """The saved scene's paths.RodPath, its model's ``chart_moved`` as ``end`` saved it (it
    chooses the outputs' expressions: output/fields.py), its probe the saved one."""
    from cosserat_fem.analysis.paths import RodPath
    from cosserat_fem.scene.build import scene_from_dict

    scene = scene_from_dict(record["scene"], source=f"{folder}/{FOLDER}/{INDEX}")
    problem = RodPath(scene, comm, record.get("probe"))
    problem.model.chart_moved = bool(end.get("chart_moved", False))
    return problem


def _task(end: dict, start: Point):
    """The paths.Pending of the branch whose saved end is ``end``."""
    from cosserat_fem.analysis.paths import Pending

    origin = end.get("origin", NOT_RECORDED)
    return Pending("trace", start, end["direction"], True, origin, bool(end.get("primary")))


def restart_queue(
    folder: Path,
    record: dict,
    settings: ContinuationSettings,
    stop=None,
    progress=None,
    comm: MPI.Comm = MPI.COMM_WORLD,
):
    """The continuation in ``folder`` finished as the whole run would have (module
    docstring, "The queue"): the last branch saved traced on from its saved end unless it
    ended, then the tasks of its end's queue in order. branches.csv is cut to the rows that
    end names, branches.json to the branches ended before; each branch then appends its
    rows, its special points' rows and its entry as the whole run writes them, and its
    XDMF (the resumed one's from its saved points on)."""
    from cosserat_fem.analysis.branch_outputs import (
        BRANCHES_CSV,
        append_on_root,
        branch_entry,
        replace_on_root,
    )
    from cosserat_fem.analysis.paths import (
        PathResult,
        Pending,
        csv_lines,
        end_branch,
        path_engine,
        trace_queue,
    )

    ends = {int(k): v for k, v in record["branches"].items()}
    last = max(ends)
    end = ends[last]
    resuming = "reason" not in end
    restarts = int(record.get("restarts", 0)) + 1
    saved = load_branch(folder, record, last, comm) if resuming else None
    kept = 0 if saved is None else len(saved.points)
    first = last if resuming else last + 1  # the first branch this restart writes
    reasons = [e for e in _reasons(folder, comm) if e.get("branch", -1) < first]
    lines = _csv_lines(folder, comm)
    rows = end.get("rows")
    if isinstance(rows, int) and 0 <= rows <= len(lines) - 1:
        lines = lines[: rows + 1]  # a row written after the saved end goes
    resumed = (last, kept, restarts) if resuming else None
    observer = _restart_outputs(folder, record, settings, lines, progress, resumed, comm)
    observer._next = last + 1
    observer._branch = first  # the branches ended (the progress)
    before = {last: saved.first_index} if saved is not None else {}

    def finished(so_far) -> None:  # the special points' rows and the entry, as the whole run's
        branch, i = so_far.branches[-1], observer.index
        special = csv_lines([p.as_row(i) for p in branch.special])
        if special:
            text = "".join(line + "\n" for line in special)
            append_on_root(folder / BRANCHES_CSV, text.encode(), comm)
        reasons.append(branch_entry(i, branch, xdmf, before.get(i, 0)))
        text = json.dumps(reasons, indent=1) + "\n"
        replace_on_root(folder / "branches.json", text.encode(), comm)

    observer.finished = finished
    problem = _path_problem(record, folder, end, comm)
    xdmf = problem.scene.output.xdmf
    loaded: dict[tuple, Point] = {}

    def point(ref: list) -> Point:
        key = tuple(ref)
        if key not in loaded:
            loaded[key] = load_point(folder, record, ref, comm)
            observer.remember(loaded[key], ref)
        return loaded[key]

    def task(entry: dict) -> Pending:
        if entry["kind"] == "trace":
            start = point(entry["start"])
            keys = ("direction", "search_first", "origin", "primary")
            return Pending("trace", start, *(entry[k] for k in keys))
        if entry["kind"] == "switch":
            return Pending("switch", at=point(entry["at"]))
        return Pending("switches", count=entry["count"])

    try:
        found = [point(ref) for ref in end["queue"]["found"]]
        pending = [task(entry) for entry in end["queue"]["pending"]]
        engine = path_engine(problem, settings, stop, observer)
        result = PathResult(first_branch=first)
        if saved is not None:
            current = _task(end, point(["start", last]))
            observer.task, observer.pending, observer.found = current, pending, found
            observer.skip = kept
            observer._points = saved.first_index + kept
            branch = engine.resume(saved)
            end_branch(problem, branch, current, found, result, observer)
        trace_queue(engine, problem, pending, found, result, observer)
        result.corrector_factorisations = engine.corrector_solves
        result.jacobian_assemblies = problem.solver.stats.jacobian_assemblies
    finally:
        observer.close()
        problem.destroy()
    _finish_index(folder, record, settings, observer, comm)
    return result


def _restart_one(
    folder: Path,
    record: dict,
    index: int,
    settings: ContinuationSettings,
    stop=None,
    progress=None,
    comm: MPI.Comm = MPI.COMM_WORLD,
):
    """Branch ``index`` alone traced on from its saved end (:func:`restart_branch`)."""
    from cosserat_fem.analysis.branch_outputs import (
        BRANCHES_CSV,
        append_on_root,
        replace_on_root,
    )
    from cosserat_fem.analysis.paths import PathResult, _path_branch, path_engine
    from cosserat_fem.analysis.paths import csv_lines as rows_text

    ended = _reasons(folder, comm)
    for done in ended:  # a branch that reached its range's end has nothing to trace on
        if done.get("branch") == index and str(done.get("reason")).startswith("p reached"):
            raise SceneError(
                f"--restart: branch {index} in {str(folder)!r} already ended: {done['reason']}"
            )
    saved = load_branch(folder, record, index, comm)
    kept = len(saved.points)
    if settings.max_points <= saved.first_index + kept:  # nothing to add: change nothing
        raise SceneError(
            f"--max-points: branch {index} in {str(folder)!r} has {saved.first_index + kept} "
            f"points already, max_points = {settings.max_points}; give --max-points above that"
        )
    restarts = int(record.get("restarts", 0)) + 1
    end = record["branches"][str(index)]
    reasons = ended  # branches.json's entries (none: killed on the first branch)
    entry: dict | None = next((e for e in reasons if e.get("branch") == index), None)
    lines = _csv_lines(folder, comm)
    rows = end.get("rows")
    skip, known = 0, 0  # the saved points and the special points whose rows the file has
    if entry is not None and entry.get("points") == saved.first_index + kept:
        skip = kept  # it ended: the file has its rows, specials and later branches'
        known = len(saved.special)
    elif isinstance(rows, int) and 0 <= rows <= len(lines) - 1:
        lines = lines[: rows + 1]  # killed: its rows to its saved end (a later one's cut)
        skip = kept
    # else (a folder of before the rows were saved): its rows from the saved points on
    resumed = (index, kept, restarts)
    observer = _restart_outputs(folder, record, settings, lines, progress, resumed, comm)
    observer._points = saved.first_index + kept
    observer.skip = skip
    problem = _path_problem(record, folder, end, comm)
    try:
        if "start" in end:  # its task kept in its end (no queue traced)
            start = load_point(folder, record, ["start", index], comm)
            observer.task = _task(end, start)
            observer.remember(start, ["start", index])
        engine = path_engine(problem, settings, stop, observer)
        branch = engine.resume(saved)
        origin = end.get("origin", f"restarted ({restarts})")
        path_branch = _path_branch(problem, branch, origin, observer)
        result = PathResult([path_branch], engine.corrector_solves, first_branch=index)
        result.jacobian_assemblies = problem.solver.stats.jacobian_assemblies
        if entry is None:  # killed on this branch
            xdmf = f"branch_{index}.xdmf" if problem.scene.output.xdmf else None
            origin = end.get("origin", NOT_RECORDED)
            entry = {"branch": index, "origin": origin, "xdmf": xdmf, "approximate": []}
            reasons.append(entry)
        special = rows_text([p.as_row(index) for p in path_branch.special[known:]])
        if special:  # its points' rows were appended as they came (BranchOutputs.write_rows)
            text = "".join(line + "\n" for line in special)
            append_on_root(folder / BRANCHES_CSV, text.encode(), comm)
        entry["reason"] = branch.reason
        entry["points"] = branch.first_index + len(branch.points)
        entry["steps"] = entry["points"] - 1
        entry["rejected"] = branch.steps_rejected
        text = json.dumps(reasons, indent=1) + "\n"
        replace_on_root(folder / "branches.json", text.encode(), comm)
        observer.end(problem, branch, len(special))
    finally:
        observer.close()
        problem.destroy()
    _finish_index(folder, record, settings, observer, comm)
    return result
