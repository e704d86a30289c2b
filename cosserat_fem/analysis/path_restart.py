"""Restarts of a continuation from the last point of a branch (issue 27 item 5).

A continuation with an output folder keeps, after each point of a branch and as it ends,
what the rest of that branch depends on, following the run's checkpoints
(cosserat_fem/io/checkpoint.py), so a continuation killed mid-branch restarts from its last
point:

    continuation/restart.json          the scene (as a dict), the settings, the ranks, and per
                                       branch its end: first_index, step, rejected, direction,
                                       slot
    continuation/branch<i>.rank<r>.npz  rank r's owned entries of u and t_u of the branch's
    (slot 0; slot 1: .rank<r>.b.npz)    last (at most) three points, and in 3D their charts
                                        (the nodal quaternions: paths.py)

Each file is replaced whole (common/safe_files.replace). The arrays of a new end go to the
slot the JSON does not name, then the JSON is replaced to name it: a kill between the two
leaves the JSON and the arrays it names of the same, earlier, end.

with each point's λ, dλ/ds, sign and ln|det R_u|, iterations and kind in the JSON (floats
written by repr, which round-trips). The three last points are the quadratic predictor's
history; ``first_index`` counts the points before them (max_points), ``step`` is the step
the next point would have taken. :func:`resume_branch` rebuilds the scene's path problem and
calls :meth:`~cosserat_fem.nls.arclength.Continuation.resume`: the same floating-point
operations on the same arrays as the uninterrupted trace (the problem's assemblies and LU
factorisations are functions of (u, λ) alone), so a continuation cut in two gives the very
points of the whole one (tests/test_continuation.py::test_restart_equals_the_whole_branch).
Arrays are per rank: a restart needs the same number of ranks (the same partition).

Only ``max_points`` may change on restart (a branch that ended at max_points goes on); the
range, steps and tolerances are the saved ones. The continued points are appended to the
branch's rows of branches.csv and frames of its branch_<i>.xdmf, and its end saved again.

**Rows.** The rows of the branch being traced are appended to branches.csv as its points
are accepted, before its end is saved (branch_outputs.BranchOutputs.write_rows), and each
saved end names the file's rows through its last point (``rows``). A continuation killed
mid-branch has branches.csv with the branches that ended before and the killed branch's rows
up to its last point, branches.json and the XDMF of the branches that ended before; the
restart cuts branches.csv to the saved end's ``rows`` (a row written after the end was saved
goes) and appends the rest as it goes, so the file ends as the uninterrupted run's; a
restart killed in its turn is restarted alike. A switch traces its two directions before
either is ended: the second's rows are written when it ends (a kill before loses them, and
its end names no ``rows``), and each saves its end under its own index. The killed branch's
XDMF has its frames from the saved (last three) points on, and the branches after it are not
traced (start them anew). A branch that ended (branches.json has its points) is continued
at the end of the file, after the branches traced after it. A folder whose ends name no
``rows`` (written before they were saved) gets the killed branch's rows from its saved
points on.
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
    folder: Path, index: int, branch: Branch, comm: MPI.Comm, slot: int = 0
) -> None:
    """Rank r's arrays of ``branch``'s end into its file of ``slot`` (:func:`state_file`;
    every rank its own file; the ranks agree on a failure)."""
    from cosserat_fem.common.errors import OutputError
    from cosserat_fem.common.parallel import agree
    from cosserat_fem.common.safe_files import replace

    kept = branch.points[-KEPT:]
    arrays = {f"u{i}": q.u for i, q in enumerate(kept)}
    arrays |= {f"t{i}": q.t_u for i, q in enumerate(kept)}
    arrays |= {f"q{i}": q.chart for i, q in enumerate(kept) if isinstance(q.chart, np.ndarray)}
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


def load_branch(folder: Path, record: dict, index: int, comm: MPI.Comm) -> Branch:
    """The engine's :class:`~cosserat_fem.nls.arclength.Branch` of branch ``index``'s saved end
    (its last points, first_index, step, rejected, direction)."""
    end = record["branches"].get(str(index))
    if end is None:
        raise SceneError(f"--branch: no branch {index} saved in {str(folder)!r}")
    from zipfile import BadZipFile

    from cosserat_fem.common.parallel import agree

    path = folder / FOLDER / state_file(index, comm.rank, end.get("slot", 0))
    try:
        arrays = np.load(path)
        problem = None
    except (OSError, ValueError, BadZipFile) as exc:  # missing or damaged: every rank refuses alike
        problem = SceneError(
            f"--restart: {str(path)!r} cannot be read ({getattr(exc, 'strerror', None) or exc})"
        )
    agree(comm, problem)
    with arrays:
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
    return Branch(
        points=points,
        direction=end["direction"],
        steps_rejected=end["rejected"],
        step=end["step"],
        first_index=end["first_index"],
    )


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
    ``settings``: a :class:`~cosserat_fem.analysis.paths.PathResult` of that one branch (its
    points from the first saved one on), its new rows appended to branches.csv (at the end
    of the file, the branch's index kept), its frames to branch_<index>.xdmf, its end and
    reason saved again (restart.json, branches.json's entry)."""
    from cosserat_fem.analysis.branch_outputs import (
        BRANCHES_CSV,
        BranchOutputs,
        append_on_root,
        replace_on_root,
    )
    from cosserat_fem.analysis.paths import (
        BRANCH_COLUMNS,
        PathResult,
        RodPath,
        _path_branch,
        csv_lines,
        path_engine,
    )
    from cosserat_fem.common.safe_files import Unreadable, read_on_root
    from cosserat_fem.scene.build import scene_from_dict

    try:  # a branch that reached its range's end has nothing to trace on
        ended = json.loads(read_on_root(folder / "branches.json", 1 << 28, comm).decode())
    except Unreadable:
        ended = []
    for entry in ended:
        if entry.get("branch") == index and str(entry.get("reason")).startswith("p reached"):
            raise SceneError(
                f"--restart: branch {index} in {str(folder)!r} already ended: {entry['reason']}"
            )
    scene = scene_from_dict(record["scene"], source=f"{folder}/{FOLDER}/{INDEX}")
    saved = load_branch(folder, record, index, comm)
    kept = len(saved.points)
    if settings.max_points <= saved.first_index + kept:  # nothing to add: change nothing
        raise SceneError(
            f"--max-points: branch {index} in {str(folder)!r} has {saved.first_index + kept} "
            f"points already, max_points = {settings.max_points}; give --max-points above that"
        )
    restarts = int(record.get("restarts", 0)) + 1
    observer = BranchOutputs(folder, progress, resumed=(index, kept, restarts))
    observer._points = saved.first_index + kept
    observer.slots[index] = record["branches"][str(index)].get("slot", 0)
    ends = {int(k): v for k, v in record["branches"].items()}
    probe = record.get("probe")
    reasons = ended  # branches.json's entries (none: killed on the first branch)
    entry = next((e for e in reasons if e.get("branch") == index), None)
    try:
        lines = read_on_root(folder / BRANCHES_CSV, 1 << 30, comm).decode().splitlines()
    except Unreadable:
        lines = []
    lines = lines or [",".join(BRANCH_COLUMNS)]
    rows = ends[index].get("rows")
    if entry is not None and entry.get("points") == saved.first_index + kept:
        observer.skip = kept  # it ended: the file has its rows, specials and later branches'
    elif isinstance(rows, int) and 0 <= rows <= len(lines) - 1:
        lines = lines[: rows + 1]  # killed: its rows to its saved end (a later one's cut)
        observer.skip = kept
    # else (a folder of before the rows were saved): its rows from the saved points on
    replace_on_root(folder / BRANCHES_CSV, "".join(ln + "\n" for ln in lines).encode(), comm)
    observer.csv_made, observer.file_rows = True, len(lines) - 1

    def save_index(new: dict) -> None:
        write_index(folder, record["scene"], settings, ends | new, comm, restarts - 1, probe)

    observer.record = save_index
    problem = RodPath(scene, comm, record.get("probe"))
    try:
        engine = path_engine(problem, settings, stop, observer)
        branch = engine.resume(saved)
        path_branch = _path_branch(problem, branch, f"restarted ({restarts})", observer)
        result = PathResult([path_branch], engine.corrector_solves)
        result.jacobian_assemblies = problem.solver.stats.jacobian_assemblies
    finally:
        problem.destroy()
    if entry is None:  # killed on this branch
        xdmf = f"branch_{index}.xdmf" if scene.output.xdmf else None
        origin = "not recorded (the continuation was killed on this branch)"
        entry = {"branch": index, "origin": origin, "xdmf": xdmf, "approximate": []}
        reasons.append(entry)
    special = csv_lines([p.as_row(index) for p in path_branch.special])
    if special:  # its points' rows were appended as they came (BranchOutputs.write_rows)
        text = "".join(line + "\n" for line in special)
        append_on_root(folder / BRANCHES_CSV, text.encode(), comm)
    entry["reason"] = branch.reason
    entry["points"] = branch.first_index + len(branch.points)
    entry["steps"] = entry["points"] - 1
    entry["rejected"] = branch.steps_rejected
    replace_on_root(folder / "branches.json", (json.dumps(reasons, indent=1) + "\n").encode(), comm)
    write_index(folder, record["scene"], settings, ends | observer.ends, comm, restarts, probe)
    return result
