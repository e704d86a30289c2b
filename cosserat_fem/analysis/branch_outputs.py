"""What a continuation (cosserat_fem/analysis/paths.py) leaves in its folder and shows as it
goes, besides branches.csv (issue 27 item 5).

* ``branch_<i>.xdmf`` (+ its HDF5 frames), one file per branch i (i as in branches.csv's
  ``branch`` column), written by :class:`BranchOutputs` as the points are accepted (with
  restart data; else as the branch ends): one frame per point of the branch in its order
  (the located special points are not frames; they are rows of branches.csv), the frame's
  "time" the point's index along the branch (0 = its first point), not λ, which turns back
  at a fold; a killed branch keeps its frames up to its last point, and a restart cuts
  them back to its saved end and appends the rest. The arrays are the scene's
  ``output.fields`` (:class:`~cosserat_fem.output.fields.XdmfWriter`, as a static path's
  solution.xdmf), so ParaView's "Warp By Vector" draws each state of the branch. Not with
  the scene's ``output.xdmf = false``.
* ``continuation/``: each branch's end, for a restart (cosserat_fem/analysis/path_restart.py).
* ``branches.csv`` (paths.py's columns): with restart data, the rows of the branch being
  traced are appended as its points are accepted (:meth:`BranchOutputs.write_rows`), so a
  continuation killed mid-branch keeps every row up to its last point, and each saved end
  names the file's rows through it (restart.json's ``rows``, which a restart cuts the file
  back to); as each branch ends the caller rewrites the file whole from its result (the
  special points' rows after the branch's points), and a restart appends the new ones.
  The branches are ended one at a time (paths.py's queue): the next begins after
  :meth:`BranchOutputs.end` has saved the last one's final end and the queue after it.
* ``branches.json``: per branch its origin, why it ended (a bound of the range, max_points,
  ``stop``'s reason, or a step collapse with the corrector's failure), its steps and
  rejected steps (:func:`write_branch_reasons`). A branch that cannot go on still has every
  point found up to its last in branches.csv and its XDMF.
* the progress: ``progress(branch, points, load_factor)`` after each point (the command's
  :class:`~cosserat_fem.analysis.progress.ContinuationProgress`).
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from mpi4py import MPI

from cosserat_fem.analysis.path_restart import (
    branch_end,
    point_arrays,
    point_json,
    queue_record,
    save_branch_state,
)
from cosserat_fem.common.parallel import from_root
from cosserat_fem.nls.arclength import Branch, Point

#: The continuation's table (paths.py's columns)
BRANCHES_CSV = "branches.csv"
#: progress(branch index, points so far on it, λ of the last)
Progress = Callable[[int, int, float], None]


class BranchOutputs:
    """The observer :func:`~cosserat_fem.analysis.paths.continue_path` calls: ``begin`` as
    each branch begins (its task and what comes after it: paths.py's queue), ``point`` after
    each accepted point (the progress), ``branch`` as each branch ends (its rows, its XDMF,
    in ``folder`` if given) and ``end`` once the caller's files of it are written (its final
    restart data). Collective (every rank calls them)."""

    def __init__(
        self,
        folder: Path | None = None,
        progress: Progress | None = None,
        resumed: tuple[int, int, int] | None = None,
    ):
        """``resumed = (i, kept, n)``: the first branch told of is branch i resumed from its
        ``kept`` saved points (path_restart.py), its XDMF continued as restart n; the
        branches after it (a restart's queue) are i + 1, i + 2, ..."""
        self.folder = None if folder is None else Path(folder)
        self.progress = progress
        self.resumed = resumed
        self._branch = 0  # the branches ended (the progress)
        self._points = 1  # the branch's first point
        self.files: list[Path] = []
        #: each branch's saved end (path_restart.branch_end), by branch index
        self.ends: dict[int, dict] = {}
        #: each branch's slot of its saved arrays (path_restart.py), by branch index
        self.slots: dict[int, int] = {}
        #: ``record(ends)`` writes continuation/restart.json with these ends (the caller's:
        #: path_restart.write_index with its scene and settings); None: no restart data
        self.record: Callable[[dict[int, dict]], None] | None = None
        #: ``finished(result)`` after each branch is added to the result (the caller's:
        #: branches.csv and branches.json of the branches so far), or None
        self.finished: Callable[[object], None] | None = None
        #: branches.csv's data rows now (with ``record``: :meth:`write_rows`)
        self.file_rows = 0
        #: whether branches.csv is there (else the first rows come with its header)
        self.csv_made = False
        #: the index of the branch being traced, and of the next one begun
        self.index = 0 if resumed is None else resumed[0]
        self._next = self.index + 1 if resumed is not None else 0
        self._done = 0  # the current branch's points whose rows were handled
        #: the current branch's first points whose rows are in the file (a restart's)
        self.skip = 0
        #: the current branch's task (paths.Pending), the tasks after it and the bifurcation
        #: points found on the primary branches (the caller's lists, saved with each end:
        #: path_restart.queue_record); None: no queue saved (a restart of one branch)
        self.task = None
        self.pending: list = []
        self.found: list = []
        self._refs: list[tuple[Point, list]] = []  # the saved points, by identity
        self._problem = None  # the path problem told of last (its model's chart_moved)
        self._writer: Any = None  # the current branch's XDMF writer, while it is open
        self._framed = 0  # the current branch's points whose frames were handled

    def begin(self, task, pending: list, found: list) -> None:
        """Branch ``task`` (a paths.Pending) begins, ``pending`` to come after it (the
        caller's list) and ``found`` the bifurcation points to switch at."""
        self.index, self._next = self._next, self._next + 1
        self.task, self.pending, self.found = task, pending, found
        self.remember(task.start, ["start", self.index])
        self._done = self.skip = 0

    def remember(self, point: Point, ref: list) -> None:
        """``point`` is saved as ``ref`` (path_restart.queue_record), unless it already is."""
        if all(q is not point for q, _ in self._refs):
            self._refs.append((point, ref))

    def _ref(self, point: Point) -> list:
        return next(ref for q, ref in self._refs if q is point)

    def save(self, branch: Branch, comm: MPI.Comm, final: bool = False) -> None:
        """The restart data of ``branch`` as it is now (its last points, its start and
        special points, its task and the queue after it): its arrays into the slot
        restart.json does not name, then restart.json naming it (``record``;
        path_restart.py). Collective; nothing without a folder, nor before the branch ends
        (``final``) without ``record``."""
        if self.folder is None or (self.record is None and not final):
            return
        index = self.index
        slot = 1 - self.slots.get(index, 1)
        extra: dict[str, np.ndarray] = {}
        for k, q in enumerate(branch.special):
            extra |= point_arrays(q, f"s{k}")
        end = branch_end(branch, slot)
        end["special"] = [point_json(q) for q in branch.special]
        end["charts_moved"] = branch.charts_moved
        model = getattr(self._problem, "model", None)
        end["chart_moved"] = bool(getattr(model, "chart_moved", False))
        if self.task is not None:
            extra |= point_arrays(self.task.start, "start")
            end["start"] = point_json(self.task.start)
            end["origin"], end["primary"] = self.task.origin, self.task.primary
            end["queue"] = queue_record(self.pending, self.found, self._ref)
        if final:
            end["reason"] = branch.reason
        save_branch_state(self.folder, index, branch, comm, slot, extra)
        self.slots[index] = slot
        self.ends[index] = end
        if self.record is not None:
            end["rows"] = self.file_rows  # branches.csv's rows through its end
            self.record(self.ends)

    def write_rows(self, problem, branch: Branch) -> None:
        """branches.csv's rows of ``branch``'s points not yet handled, appended (the file made
        with its header first if it is not there): their (x, y, z, θ, ψ, φ) computed in
        order along the branch from its first point, as paths.py's rows of a branch are (the
        angles continued from point to point), the :attr:`skip` first ones only computed.
        The chart of the engine's current point is kept. Nothing without ``record`` (no
        restart data). Collective."""
        self._problem = problem
        if self.folder is None or self.record is None:
            return
        from cosserat_fem.analysis.paths import BRANCH_COLUMNS, _path_point, csv_lines

        if self._done == 0:
            problem.probe.angles.last = None  # continued along this branch from its start
        chart = problem.chart
        rows = []
        for i in range(self._done, len(branch.points)):
            point = _path_point(problem, branch.points[i])
            if i >= self.skip:
                rows.append(point.as_row(self.index))
        self._done = len(branch.points)
        self._write_frames(problem, branch)
        problem.use_chart(chart)
        if not rows:
            return
        text = "".join(line + "\n" for line in csv_lines(rows))
        if self.csv_made:
            append_on_root(self.folder / BRANCHES_CSV, text.encode(), problem.comm)
        else:
            header = ",".join(BRANCH_COLUMNS) + "\n"
            replace_on_root(self.folder / BRANCHES_CSV, (header + text).encode(), problem.comm)
            self.csv_made = True
        self.file_rows += len(rows)

    def point(self, point: Point) -> None:
        self._points += 1
        if self.progress is not None:
            self.progress(self._branch, self._points, point.p)

    def branch(self, problem, branch: Branch) -> None:
        """Write the rest of ``branch``'s rows and frames of ``branch_<i>.xdmf`` (engine
        points, their states u) through ``problem`` (a
        :class:`~cosserat_fem.analysis.paths.RodPath`: its model's U), and close the XDMF."""
        self._branch += 1
        self._points = 1
        if self.folder is None:
            return
        self.write_rows(problem, branch)  # the points the engine did not tell (a bound's)
        self._done = 0
        self._write_frames(problem, branch)  # all of them without restart data
        if self._writer is not None:
            self.files.append(self._writer.path)
        self.close()

    def _write_frames(self, problem, branch: Branch) -> None:
        """The frames of ``branch``'s points not yet written into ``branch_<i>.xdmf``, frame
        k the point of index k along the branch; the file opened at the branch's first (a
        resumed branch's: continued as restart n after its saved points' frames, cut back to
        them; from its saved points if it has none, a folder of before the frames were
        written as the points came). Nothing with the scene's ``output.xdmf`` false."""
        from cosserat_fem.output.fields import XdmfWriter

        if self.folder is None or not problem.scene.output.xdmf:
            return
        if self._writer is None:
            path = self.folder / f"branch_{self.index}.xdmf"
            resume, self._framed = None, 0
            if self.resumed is not None and from_root(problem.comm, path.exists()):
                self._framed = self.resumed[1]  # the saved points' frames are there
                resume = (self.resumed[2], branch.first_index + self._framed)
                cut_frames(path, resume[1], problem.comm)  # a frame after the saved end goes
            self._writer = XdmfWriter(path, problem.model, resume=resume)
        for i in range(self._framed, len(branch.points)):
            q = branch.points[i]
            if q.chart is None:
                problem.set_state(q.u, q.p)
            else:  # a point of a path with charts (paths.py)
                problem.set_state(q.u, q.p, q.chart)
            self._writer.write(float(branch.first_index + i))
        self._framed = len(branch.points)

    def close(self) -> None:
        """Close the current branch's XDMF if it is open (as a branch ends, or when the
        continuation stops on an exception: the caller's ``finally``). Collective."""
        writer, self._writer = self._writer, None
        if writer is not None:
            writer.close()

    def end(self, problem, branch: Branch, special_rows: int | None = None) -> None:
        """The caller has written its files of ``branch`` (``finished``: branches.csv with
        its special points' rows after its points, branches.json): its final end, with its
        reason and the queue after it, is saved (a kill before restarts the branch from
        its last saved point, a kill after traces the queue); ``special_rows``: the special
        points' rows written, if not all. Collective."""
        self._problem = problem
        self.file_rows += len(branch.special) if special_rows is None else special_rows
        self.save(branch, problem.comm, final=True)
        self.resumed = None
        self.skip = 0


def replace_on_root(path: str | Path, data: bytes, comm: MPI.Comm = MPI.COMM_WORLD) -> None:
    """``data`` into the file ``path`` by rank 0 (safe_files.replace: whole or not at all); the
    ranks agree on a failure (an OutputError naming the path)."""
    from cosserat_fem.common.safe_files import replace

    _on_root(path, lambda: replace(path, data), comm)


def append_on_root(path: str | Path, data: bytes, comm: MPI.Comm = MPI.COMM_WORLD) -> None:
    """``data`` appended to the existing file ``path`` by rank 0 (safe_files.open_append: the
    folder's own file, never written through a link), so a table that grows a row at a time
    costs its new rows, not its whole; the ranks agree on a failure (an OutputError naming
    the path). A failure midway may leave part of ``data``: a reader cuts the file to the
    rows its record names (orbit_runs.py, path_restart.py)."""
    import os

    from cosserat_fem.common.safe_files import open_append, write_all

    def append() -> None:
        fd = open_append(path)
        try:
            write_all(fd, data)
        finally:
            os.close(fd)

    _on_root(path, append, comm)


def cut_frames(path: Path, frames: int, comm: MPI.Comm = MPI.COMM_WORLD) -> None:
    """The XDMF series ``path`` cut back to its first ``frames`` frames (rank 0; the ranks
    agree on a failure): the XML (io/xdmf.cut_xdmf), then the frame files after them and the
    scratch XML of a frame being written (a kill after a frame's files were written and
    before the restart data that count it: the resumed writer writes those files again)."""
    from cosserat_fem.io.xdmf import cut_xdmf, frames_folder

    def cut() -> None:
        cut_xdmf(path, frames)
        folder = frames_folder(path)
        if folder.is_dir():
            for old in folder.iterdir():
                later = old.suffix == ".h5" and old.stem.isdigit() and int(old.stem) >= frames
                if later or old.suffix == ".xdmf-partial":
                    old.unlink()

    _on_root(path, cut, comm)


def _on_root(path: str | Path, write: Callable[[], None], comm: MPI.Comm) -> None:
    """``write()`` on rank 0, the ranks agreeing on its failure (an OutputError naming
    ``path``)."""
    from cosserat_fem.common.errors import CosseratError, OutputError
    from cosserat_fem.common.parallel import agree

    problem = None
    if comm.rank == 0:
        try:
            write()
        except CosseratError as exc:
            problem = exc
        except OSError as exc:
            problem = OutputError(f"{path}: {exc.strerror or exc}")
    agree(comm, problem)


def write_branch_reasons(
    path: str | Path, result, xdmf: bool = True, comm: MPI.Comm = MPI.COMM_WORLD
) -> None:
    """branches.json at ``path`` (:func:`replace_on_root`): a list, per branch of ``result``
    (a :class:`~cosserat_fem.analysis.paths.PathResult`), of {"branch", "origin", "reason",
    "points", "steps", "rejected", "charts_moved", "xdmf", "approximate"} ("charts_moved":
    the chart's moves on it, paths.py, 0 without charts; "xdmf": the branch's file name,
    null if ``xdmf`` is false; "approximate": the special points located only approximately,
    "<kind> at load factor <λ>: <note>", cosserat_fem/nls/arclength.py)."""
    rows = [branch_entry(i, b, xdmf) for i, b in enumerate(result.branches)]
    replace_on_root(path, (json.dumps(rows, indent=1) + "\n").encode(), comm)


def branch_entry(i: int, b, xdmf: bool = True, before: int = 0) -> dict:
    """branches.json's entry of branch ``i`` (:func:`write_branch_reasons`), ``b`` a
    :class:`~cosserat_fem.analysis.paths.PathBranch` whose first ``before`` points are not
    among its ``points`` (a restart's: path_restart.py)."""
    return {
        "branch": i,
        "origin": b.origin,
        "reason": b.reason,
        "points": before + len(b.points),
        "steps": before + b.steps,
        "rejected": b.rejected,
        "charts_moved": getattr(b, "charts_moved", 0),
        "xdmf": f"branch_{i}.xdmf" if xdmf else None,
        "approximate": [
            f"{q.kind} at load factor {q.factor!r}: {q.note}" for q in b.special if q.note
        ],
    }
