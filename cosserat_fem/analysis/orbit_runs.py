"""What ``cosserat-fem orbits`` and ``cosserat-fem lyapunov`` leave in their folder and show as
they go (issue 27 item 5), around the algorithms of cosserat_fem/analysis/periodic.py
(``trace_orbits``) and cosserat_fem/analysis/lyapunov.py (``largest_exponent``).

**An orbit branch's folder** (:func:`orbit_branch`), written as the branch grows, so that a
killed run keeps every point found up to its last:

* ``orbit_branch.csv``: periodic.py's ``ORBIT_COLUMNS``, one row per point in the order
  traced (appended after each; a restart first cuts the file to its record's rows), then
  one per located special point (its ``point`` column the kind: "limit" for a fold, or any
  kind the tracer gives, "period-doubling", "torus").
* ``orbit_branch.xdmf`` (+ its HDF5 frames): the rod's state at t0 of each orbit, one frame a
  point, the frame's "time" the point's index along the branch (not p, which turns back at
  a fold); the arrays are the scene's ``output.fields`` (as a continuation's branch_<i>.xdmf,
  cosserat_fem/analysis/branch_outputs.py). Not with ``output.xdmf = false``. A restart
  first cuts it back to its record's frames (branch_outputs.cut_frames: a frame written
  after the record was saved goes).
* ``summary.json``: the reason the branch ended, its steps, rejected steps, monodromies
  (periods with the variational equations), the folds and special points, the restarts;
  also when the first orbit is not found (a SolverError: no point, its message the
  reason). A branch ends at its first accepted point after the scene's limits.wall_time
  since its part began (:data:`WALL_TIME_STOP`; the command's exit 4), restartable.
* ``continuation/``: the restart data (cosserat_fem/analysis/path_restart.py's per-rank
  arrays of the branch's last three points, ``save_branch_state``/``load_branch``, and
  ``orbits.json``, its "kind" "orbits": the scene, the period, the parameter, the
  settings, the arclength metric's weight w, each kept point's amplitude and multipliers,
  the rows and frames written). :func:`resume_orbit_branch` traces the branch on from its
  last point by the engine's ``resume`` with the same weight and the step the engine would
  have taken next (rebuilt from the pseudo-arclength constraint: ``_Recorder._step``), so
  the continued points are an uninterrupted run's to the corrector's tolerance; its new
  rows and frames are appended. The special points located in a part that was killed are
  lost (they are written at a part's end); a restarted part locates its own folds, period
  doublings and tori (the same engine as ``trace_orbits``'s: periodic.py ``orbit_engine``).

**A Lyapunov run's folder** (:func:`lyapunov_run`): ``poincare.csv`` (lyapunov.py),
``lyapunov.csv`` (per renormalisation interval: its end time [s], the stretch ln(d/d0), the
running exponent [1/s], empty while discarded; appended as each interval ends, so a run
killed by SIGTERM or SIGKILL keeps them) and ``summary.json`` (the exponent). The run
is refused before any work (and before its folder is made) if its time-marching cost exceeds
the scene's limits (cosserat_fem/analysis/budget.py, as a run of ``periods`` periods), and
stopped at ``limits.wall_time`` (observers.py ``DeadlineObserver``). A run that stops (the
wall time, a failed solve, Ctrl-C or SIGTERM) keeps what it computed: poincare.csv so far,
lyapunov.csv of the intervals done (not written if none was), and summary.json with its
status ("stopped" or "failed"), the reason, the intervals done and the exponent they give
(null if none was averaged).

Both lock their folder (io/folder_lock.py). Collective: every rank calls them.
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable
from dataclasses import asdict, replace
from pathlib import Path

import numpy as np
from mpi4py import MPI

from cosserat_fem.analysis.branch_outputs import append_on_root, cut_frames, replace_on_root
from cosserat_fem.analysis.path_restart import FOLDER, KEPT, load_branch, save_branch_state
from cosserat_fem.analysis.periodic import ORBIT_COLUMNS, OrbitBranch, OrbitPoint, orbit_point
from cosserat_fem.analysis.progress import StatusLine
from cosserat_fem.common.errors import SceneError, SolverError
from cosserat_fem.nls.arclength import Branch, ContinuationSettings, Point
from cosserat_fem.plot import LYAPUNOV as LYAPUNOV_CSV
from cosserat_fem.plot import ORBIT_BRANCH as ORBIT_CSV
from cosserat_fem.scene.build import refuse_contact

ORBIT_XDMF = "orbit_branch.xdmf"
SUMMARY = "summary.json"
#: The restart record of an orbit branch, in path_restart.FOLDER (its "kind": "orbits"; not
#: a continuation's restart.json, which ``continue --restart`` reads).
RECORD = "orbits.json"
#: progress(points on the branch, p, amplitude [m]) after each point
Progress = Callable[[int, float, float], None]


def period_value(scene, text: float | str, key: str = "--period") -> float:
    """The forcing period T [s]: a number, or an expression of the scene's constants
    (``"2*pi/(r*w1)"``); SceneError naming ``key`` unless a finite positive time."""
    from cosserat_fem.scene.expressions import Expression

    if isinstance(text, bool):
        raise SceneError(f"{key}: must be a time [s] or an expression, got {text!r}")
    constants = dict(scene.expression_names())
    try:
        if isinstance(text, str):
            value = float(Expression.parse(text, set(constants), key=key).evaluate(**constants))
        else:
            value = float(text)
    except SceneError:
        raise
    except (TypeError, ValueError, ArithmeticError) as exc:
        raise SceneError(f"{key}: {text!r}: {exc}") from None
    if not (math.isfinite(value) and value > 0.0):
        raise SceneError(f"{key}: {text!r} = {value!r} s; must be a positive time")
    return value


def _time_expressions(value, key: str):
    """(dotted key, Expression) of every expression in ``value`` (a scene's table, nested
    dataclasses, tuples) that depends on t."""
    import dataclasses

    from cosserat_fem.scene.expressions import Expression

    if isinstance(value, Expression):
        if value.depends_on("t"):
            yield key, value
    elif dataclasses.is_dataclass(value) and not isinstance(value, type):
        for item in dataclasses.fields(value):
            yield from _time_expressions(getattr(value, item.name), f"{key}.{item.name}")
    elif isinstance(value, tuple | list):
        for item in value:
            yield from _time_expressions(item, key)


def check_periodic(scene, period: float, key: str = "--period") -> None:
    """SceneError naming the load's key and ``key`` unless every load expression of the
    scene that depends on t repeats itself after ``period`` T [s]: f(s, t + T) = f(s, t) at
    5 stations s and 7 times t in a period from time.start, to 1e-9 of the largest |f| seen
    (the round-off of a sine's argument is ~1e-16 of it; a load of another period, or with
    a trend such as t sin Ωt, differs by O(1)). Loads given as tables or Python functions
    are not looked at. A scene with [contact] is refused (its orbits' shooting has no rows)."""
    refuse_contact(scene, "a periodic orbit")
    constants = dict(scene.expression_names())
    s = np.linspace(0.0, scene.rod.length, 5)[:, None]
    t = scene.time.start + period * (np.arange(7) / 7.0 + 0.0123)[None, :]
    for name, expression in _time_expressions(scene.loads, "loads"):
        try:
            now = np.broadcast_to(expression.evaluate(**constants, s=s, t=t), (5, 7))
            later = np.broadcast_to(expression.evaluate(**constants, s=s, t=t + period), (5, 7))
        except (ValueError, TypeError, ArithmeticError):
            continue  # a load of other variables: the run will say
        size = float(np.nanmax(np.abs(now))) if np.isfinite(now).any() else 0.0
        if size > 0.0 and not np.nanmax(np.abs(later - now)) <= 1e-9 * size:
            raise SceneError(
                f"{name}: {expression.source!r} is not periodic with {key} T = {period:.6g} s "
                f"(its value at t + T differs from that at t); give the forcing's period"
            )


class OrbitProgress(StatusLine):
    """Call with (points, p, amplitude) after each point of an orbit branch: its status line
    (the fraction: points over ``max_points``, as a continuation's)."""

    def __init__(self, max_points: int, stream=None, enabled=None):
        super().__init__(stream, enabled)
        self.max_points = max_points

    def __call__(self, points: int, parameter: float, amplitude: float) -> None:
        self.show(
            points / self.max_points,
            f"orbit {points}, parameter {parameter:.6g}, amplitude {amplitude:.4g} m",
        )


def _csv_line(row: dict) -> str:
    from cosserat_fem.analysis.paths import csv_lines

    return csv_lines([row])[0]


def _mu_lists(mu: np.ndarray) -> list[list[float]]:
    return [[float(m.real), float(m.imag)] for m in np.asarray(mu, dtype=complex)]


#: How a branch stopped at limits.wall_time begins its reason: it is written up to that point,
#: and ``orbits --restart DIR`` continues it (each part given limits.wall_time again).
WALL_TIME_STOP = "limits.wall_time: the branch stopped after its limit"


class _Recorder:
    """The observer of ``trace_orbits`` (and of a resumed engine): each point's row, frame,
    restart data and progress, as the branch grows (module docstring). Collective."""

    def __init__(
        self,
        shooting,
        folder: Path | None,
        progress,
        record: dict,
        lines: list[str],
        clock: float | None = None,
    ):
        """``clock``: the perf_counter at the part's start; the part ends at the first point
        after limits.wall_time of the scene has passed since (:data:`WALL_TIME_STOP`)."""
        self.shooting, self.folder, self.progress = shooting, folder, progress
        wall = shooting.scene.limits.wall_time
        self.deadline = None if clock is None or not wall else clock + wall
        self.record = record  # orbits.json's content, updated
        self.lines = lines  # orbit_branch.csv's lines (header first)
        #: the first of ``lines`` not yet in the file; 0: the file is written whole at the
        #: next flush (a new branch, or a restart's file cut back to its record's rows)
        self.written = 0
        self.kept: list[tuple[Point, float, np.ndarray]] = []
        self.told = 0  # points told in this part
        self.writer = None
        if folder is not None and shooting.scene.output.xdmf:
            from cosserat_fem.output.fields import XdmfWriter

            frames = record["frames"]
            resume = (record["restarts"], frames) if frames else None
            if resume is not None:  # a frame written after the record was saved goes
                cut_frames(folder / ORBIT_XDMF, frames, shooting.comm)
            self.writer = XdmfWriter(folder / ORBIT_XDMF, shooting.model, resume=resume)

    # -- a point ------------------------------------------------------------------------
    def orbit(self, q: Point) -> OrbitPoint:
        """The engine's point as an orbit (periodic.py's records, or kept from before a
        restart)."""
        return orbit_point(self.shooting.records, q)

    def _frame_and_row(self, orbit: OrbitPoint) -> None:
        index = self.record["frames"]
        if self.writer is not None:
            U = self.shooting.model.U
            U.x.array[: self.shooting.n_local] = orbit.state
            U.x.scatter_forward()
            self.writer.write(float(index))
        self.record["frames"] = index + 1
        self.lines.append(_csv_line(orbit.as_row(0)))

    def __call__(self, q: Point, weight: float) -> str | None:
        """After the engine's first point (its tangent turned along the traced direction, as
        the branch's first point) and each accepted one; the engine's stop hook: a reason to
        end the branch at this point (the wall time), else None."""
        if not self.told and not self.kept and self.record["direction"] < 0:
            q = replace(q, t_u=-q.t_u, t_p=-q.t_p)
        self.record["weight"] = weight
        orbit = self.orbit(q)
        self.kept = [*self.kept, (q, orbit.amplitude, orbit.multipliers)][-KEPT:]
        self.told += 1
        self._frame_and_row(orbit)
        self.record["rows"] = len(self.lines) - 1
        if self.folder is not None:
            self._save()
        if self.progress is not None:
            self.progress(self.record["frames"], q.p, orbit.amplitude)
        if self.deadline is not None:
            from cosserat_fem.common.parallel import from_root

            if from_root(self.shooting.comm, time.perf_counter() > self.deadline):
                wall = self.shooting.scene.limits.wall_time
                return f"{WALL_TIME_STOP} of {wall:g} s of wall time passed"
        return None

    def _step(self) -> float:
        """The step the engine takes next (cosserat_fem/nls/arclength.py, ``_extend``): the
        last point's step s = ⟨t, x − x_prev⟩ (the pseudo-arclength constraint, which the
        corrector met to its tolerance; t the previous point's tangent, in the metric
        w u·u + p²), grown as the engine grows it after an easy point. Before the first
        step: the settings' first."""
        settings = self.record["settings"]
        if len(self.kept) < 2:
            return settings["step"]
        (a, _, _), (b, _, _) = self.kept[-2], self.kept[-1]
        step = self.record["weight"] * self.shooting.dot(a.t_u, b.u - a.u) + a.t_p * (b.p - a.p)
        if b.iterations <= settings["easy_iterations"]:
            factor = max(settings["grow"], settings["easy_iterations"] / max(b.iterations, 1))
            step = min(step * min(factor, settings["max_grow"]), settings["max_step"])
        return step

    def _flush(self) -> None:
        """orbit_branch.csv: the lines not yet written appended (the file is written whole
        once a part, at its first flush: :attr:`written`), so a branch of n points costs
        O(n) bytes written, not O(n²)."""
        assert self.folder is not None
        comm = self.shooting.comm
        text = "".join(line + "\n" for line in self.lines[self.written :])
        if self.written:
            append_on_root(self.folder / ORBIT_CSV, text.encode(), comm)
        else:
            replace_on_root(self.folder / ORBIT_CSV, text.encode(), comm)
        self.written = len(self.lines)

    def _save(self) -> None:
        """orbit_branch.csv's new rows, then the restart data (its ``rows`` and ``frames``
        name what was written: a kill between the two leaves a row that a restart drops)."""
        assert self.folder is not None
        comm = self.shooting.comm
        self._flush()
        points = [k for k, _, _ in self.kept]
        branch = Branch(
            points=points,
            direction=self.record["direction"],
            step=self._step(),
            first_index=self.record["frames"] - len(points),
        )
        from cosserat_fem.analysis.path_restart import branch_end

        save_branch_state(self.folder, 0, branch, comm)
        self.record["branches"] = {"0": branch_end(branch)}
        self.record["kept"] = [[a, _mu_lists(m)] for _, a, m in self.kept]
        replace_on_root(
            self.folder / FOLDER / RECORD, (json.dumps(self.record) + "\n").encode(), comm
        )

    # -- the end of a part ----------------------------------------------------------------
    def finish(self, branch: OrbitBranch, untold: list[OrbitPoint], clock: float) -> dict:
        """The points the engine added without telling (the one at a bound of the range),
        the special points' rows, the files closed and summary.json (``clock``: the
        perf_counter at the part's start); returns the summary."""
        for orbit in untold:
            self._frame_and_row(orbit)
            if self.progress is not None:
                self.progress(self.record["frames"], orbit.parameter, orbit.amplitude)
        if self.writer is not None:
            self.writer.close()
        for orbit in branch.special:
            self.lines.append(_csv_line(orbit.as_row(0)))
        record = self.record
        if not untold:  # the restart data's end is the branch's: its special rows stay
            record["rows"] = len(self.lines) - 1
        record["reason"] = branch.reason
        for name in ("steps", "rejected", "monodromies"):
            record["totals"][name] += getattr(branch, name)
        record["special"] += [
            {
                "kind": q.kind,
                "parameter": q.parameter,
                "amplitude": q.amplitude,
                "stability": q.stability,
            }
            for q in branch.special
        ]
        summary = {
            "command": "orbits",
            "reason": branch.reason,
            "points": record["frames"],
            "parameter": record["parameter"],
            "period": record["period"],
            "steps_per_period": record["steps_per_period"],
            **record["totals"],
            "folds": [s for s in record["special"] if s["kind"] == "limit"],
            "special": record["special"],
            "restarts": record["restarts"],
            "wall_s": time.perf_counter() - clock,
            "files": [ORBIT_CSV, *([ORBIT_XDMF] if self.writer is not None else [])],
        }
        if self.folder is not None:
            comm = self.shooting.comm
            self._flush()
            if self.kept:  # a restart's data: there is a point to go on from
                replace_on_root(
                    self.folder / FOLDER / RECORD, (json.dumps(record) + "\n").encode(), comm
                )
            text = json.dumps(summary, indent=1) + "\n"
            replace_on_root(self.folder / SUMMARY, text.encode(), comm)
        return summary


def orbit_branch(
    scene,
    period: float | str,
    parameter: str,
    start: float,
    end: float,
    settings: ContinuationSettings,
    *,
    steps_per_period: int = 300,
    settle: int = 0,
    scale: float = 4.0,
    folder: Path | None = None,
    progress: Progress | None = None,
    comm: MPI.Comm = MPI.COMM_WORLD,
) -> tuple[OrbitBranch, dict]:
    """The branch of orbits of ``trace_orbits`` from rest (after ``settle`` periods) at p =
    ``start`` to p = ``end``, its files in ``folder`` (if given) as it grows (module
    docstring); (the branch, summary.json's content). ``folder`` must be locked by the
    caller."""
    from cosserat_fem.analysis.periodic import Shooting, trace_orbits

    clock = time.perf_counter()
    record = {
        "format": 1,
        "kind": "orbits",
        "ranks": comm.size,
        "scene": json.loads(json.dumps(scene.to_dict())),
        "period": period,
        "parameter": parameter,
        "steps_per_period": steps_per_period,
        "settings": asdict(replace(settings, p_min=min(start, end), p_max=max(start, end))),
        "direction": 1 if end > start else -1,
        "frames": 0,
        "rows": 0,
        "restarts": 0,
        "totals": {"steps": 0, "rejected": 0, "monodromies": 0},
        "special": [],
    }
    shooting = Shooting(scene, period, steps_per_period=steps_per_period, parameter=parameter)
    try:
        shooting.set_parameter(start)
        recorder = _Recorder(shooting, folder, progress, record, [",".join(ORBIT_COLUMNS)], clock)
        try:
            u = shooting.settle(shooting.rest(), int(settle))
            branch = trace_orbits(shooting, u, start, end, settings, scale, observer=recorder)
        except SolverError as exc:  # the first orbit not found: what there is, and why
            recorder.finish(OrbitBranch([], [], str(exc), 0, 0, shooting.monodromies), [], clock)
            raise
        summary = recorder.finish(branch, branch.points[recorder.told :], clock)
    finally:
        shooting.destroy()
    return branch, summary


def read_record(folder: Path, comm: MPI.Comm = MPI.COMM_WORLD) -> dict:
    """The restart record of the orbit branch in ``folder`` (rank 0 reads, all get it; its
    own file, so that ``continue --restart`` and ``orbits --restart`` each refuse the
    other's folder); SceneError naming --restart if there is none, it does not fit these
    ranks, or the branch has ended."""
    from cosserat_fem.common.safe_files import Unreadable, read_on_root

    problem = f"--restart: {str(folder)!r} holds no orbit branch to restart"
    try:
        record = json.loads(read_on_root(folder / FOLDER / RECORD, 1 << 28, comm).decode())
    except (OSError, ValueError, Unreadable) as exc:
        raise SceneError(f"{problem} ({exc})") from None
    if record.get("kind") != "orbits" or record.get("ranks") != comm.size:
        ranks = record.get("ranks")
        raise SceneError(
            f"{problem} on {comm.size} ranks (it ran on {ranks}; its states are per rank)"
        )
    if str(record.get("reason", "")).startswith("p reached"):
        raise SceneError(
            f"--restart: the orbit branch in {str(folder)!r} already ended: {record['reason']}"
        )
    return record


def resume_orbit_branch(
    folder: Path,
    max_points: int | None = None,
    progress: Progress | None = None,
    comm: MPI.Comm = MPI.COMM_WORLD,
) -> tuple[OrbitBranch, dict]:
    """The orbit branch in ``folder`` (locked by the caller) traced on from its last saved
    point with its own scene and settings (``max_points`` may be raised), its new points
    appended to its files (module docstring); (the branch from its kept points on, the
    summary)."""
    from cosserat_fem.analysis.periodic import Shooting, as_orbit_branch, orbit_engine
    from cosserat_fem.common.safe_files import Unreadable, read_on_root
    from cosserat_fem.scene.build import scene_from_dict

    clock = time.perf_counter()
    record = read_record(folder, comm)
    settings = ContinuationSettings(**record["settings"])
    if max_points is not None:
        settings = replace(settings, max_points=max_points)
        record["settings"]["max_points"] = max_points
    if settings.max_points <= record["frames"]:  # nothing to add: say so, change nothing
        raise SceneError(
            f"--max-points: the orbit branch in {str(folder)!r} has {record['frames']} points "
            f"already, max_points = {settings.max_points}; give --max-points above that"
        )
    scene = scene_from_dict(record["scene"], source=f"{folder}/{FOLDER}/{RECORD}")
    try:
        lines = read_on_root(folder / ORBIT_CSV, 1 << 30, comm).decode().splitlines()
    except Unreadable as exc:
        raise SceneError(f"--restart: {str(folder / ORBIT_CSV)!r} {exc}") from None
    if len(lines) < record["rows"] + 1:  # its rows would be lost: the user's to put back
        raise SceneError(
            f"--restart: {str(folder / ORBIT_CSV)!r} holds {max(len(lines) - 1, 0)} rows, "
            f"fewer than the {record['rows']} of the saved branch"
        )
    lines = lines[: record["rows"] + 1]
    record["restarts"] += 1
    saved = load_branch(folder, record, 0, comm)
    shooting = Shooting(
        scene,
        record["period"],
        steps_per_period=record["steps_per_period"],
        parameter=record["parameter"],
    )
    try:
        shooting.records = {}
        shooting.monodromies = 0
        recorder = _Recorder(shooting, folder, progress, record, lines, clock)
        recorder.kept = [
            (q, a, np.array([complex(*m) for m in mu]))
            for q, (a, mu) in zip(saved.points, record["kept"], strict=True)
        ]
        for q, a, mu in recorder.kept:  # as if their monodromies had been computed here
            shooting.records[(float(q.p), q.u.tobytes())] = (a, mu)
        recorder.told = len(saved.points)
        weight = record["weight"]
        engine = orbit_engine(shooting, weight, settings, lambda q: recorder(q, weight))
        kept, rejected = len(saved.points), saved.steps_rejected
        branch = as_orbit_branch(shooting, engine.resume(saved), kept, rejected)
        orbits = branch.points
        summary = recorder.finish(branch, orbits[recorder.told :], clock)
    finally:
        shooting.records = None
        shooting.destroy()
    return branch, summary


# -- the largest Lyapunov exponent ------------------------------------------------------------


def lyapunov_budget(
    scene, period: float, periods, out_dir: Path | None, comm: MPI.Comm = MPI.COMM_WORLD
) -> None:
    """SceneError (on every rank) if time-marching ``periods`` periods of ``period`` [s] from
    time.start, as a run (cosserat_fem/analysis/budget.py; its disk in ``out_dir``, made or
    not), exceeds the scene's limits: checked before the folder is made (a Lyapunov run
    marches two trajectories, so this is a lower bound of its cost)."""
    from cosserat_fem.analysis import budget
    from cosserat_fem.common.parallel import ranks_on_node

    if isinstance(periods, int) and not isinstance(periods, bool) and periods >= 1:
        span = replace(scene.time, end=scene.time.start + periods * period)
        budget.check(
            replace(scene, time=span), "run", out_dir, ranks_on_node(comm), comm.size, comm=comm
        )


class _IntervalRows:
    """lyapunov.csv's row of each interval appended as it ends (made with its header at the
    first), so that a run killed (SIGTERM, SIGKILL) keeps the stretches computed: the running
    exponent the same floating-point operations as lyapunov.running_estimate's (the sum in
    the intervals' order over (n − discard) k T), so the rows are those written at the end.
    Collective."""

    def __init__(self, folder: Path, interval: float, discard: int, comm: MPI.Comm):
        self.folder, self.interval, self.discard, self.comm = folder, interval, discard, comm
        self.n, self.total = 0, 0.0

    def __call__(self, t: float, stretch: float) -> None:
        self.n += 1
        self.total += stretch if self.n > self.discard else 0.0
        averaged = self.n - self.discard
        running = repr(float(self.total / (averaged * self.interval))) if averaged > 0 else ""
        line = f"{t!r},{stretch!r},{running}\n"
        if self.n == 1:
            text = LYAPUNOV_HEADER + line
            replace_on_root(self.folder / LYAPUNOV_CSV, text.encode(), self.comm)
        else:
            append_on_root(self.folder / LYAPUNOV_CSV, line.encode(), self.comm)


#: lyapunov.csv's header
LYAPUNOV_HEADER = "time,stretch,running_exponent\n"


def _exponent_files(folder: Path, result, summary: dict, comm: MPI.Comm) -> list[Path]:
    """lyapunov.csv of ``result``'s intervals (none: not written) and summary.json
    (``summary`` with the exponent, its settings and the intervals); the files written."""
    files = []
    if result.times.size:
        lines = [LYAPUNOV_HEADER.strip()]
        for t, s, lam in zip(result.times, result.stretches, result.running, strict=True):
            lines.append(f"{t!r},{s!r}," + (repr(float(lam)) if math.isfinite(lam) else ""))
        replace_on_root(folder / LYAPUNOV_CSV, ("\n".join(lines) + "\n").encode(), comm)
        files.append(folder / LYAPUNOV_CSV)
    summary |= {
        "exponent": result.exponent if math.isfinite(result.exponent) else None,
        "every": result.every,
        "discard": result.discard,
        "perturbation": result.perturbation,
        "intervals": int(result.times.size),
        "files": ["poincare.csv", *(f.name for f in files)],
    }
    replace_on_root(folder / SUMMARY, (json.dumps(summary, indent=1) + "\n").encode(), comm)
    return [*files, folder / SUMMARY]


def lyapunov_run(
    scene,
    period: float,
    periods: int,
    folder: Path | None,
    comm: MPI.Comm = MPI.COMM_WORLD,
    **options,
):
    """``largest_exponent`` (lyapunov.py) with its folder's files (module docstring), the run
    stopped at limits.wall_time; ``folder`` locked by the caller (the budget checked before
    it was made: :func:`lyapunov_budget`). A run that stops (limits.wall_time, a failed
    solve, Ctrl-C or SIGTERM) keeps what it computed: lyapunov.csv of the intervals done and
    summary.json with the status, the reason and the exponent of those intervals (null if
    none was averaged). Returns the LyapunovResult."""
    from cosserat_fem.analysis.lyapunov import largest_exponent
    from cosserat_fem.analysis.observers import DeadlineObserver
    from cosserat_fem.common.errors import StopError

    clock = time.perf_counter()
    wall = scene.limits.wall_time
    advice = (
        "poincare.csv and lyapunov.csv keep the periods so far; a Lyapunov run has no "
        "restart: run it again"
    )
    deadline = [DeadlineObserver(clock + wall, wall, comm, advice=advice)] if wall else []
    observers = [*options.pop("observers", ()), *deadline]
    summary: dict = {"command": "lyapunov", "period": period, "periods": periods}
    told = options.pop("stopped", None)

    def stopped(partial, exc: BaseException) -> None:
        """What stopped it, beside poincare.csv so far: the intervals done."""
        if folder is not None and isinstance(exc, StopError | SolverError | KeyboardInterrupt):
            status = "failed" if isinstance(exc, SolverError) else "stopped"
            reason = str(exc) or "interrupted (Ctrl-C or SIGTERM)"
            wall_s = time.perf_counter() - clock
            _exponent_files(
                folder,
                partial,
                summary | {"status": status, "reason": reason, "wall_s": wall_s},
                comm,
            )
        if told is not None:
            told(partial, exc)

    rows = None
    if folder is not None:
        every, discard = options.get("every", 1), options.get("discard", 0)
        rows = _IntervalRows(folder, every * period, discard, comm)
    result = largest_exponent(
        scene,
        period,
        periods=periods,
        out=folder,
        observers=observers,
        stopped=stopped,
        interval=rows,
        **options,
    )
    if folder is not None:
        summary |= {"status": "finished", "wall_s": time.perf_counter() - clock}
        result.files = [*result.files, *_exponent_files(folder, result, summary, comm)]
    return result
