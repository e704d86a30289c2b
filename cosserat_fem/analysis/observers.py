"""Observers of a run's events (cosserat_fem/timestepping/events.py): what a run writes and records.

Each observer has one job. A run and a static solve (cosserat_fem/analysis/simulation.py,
statics.py) take the same chain from :class:`StandardObservers`, its differences as arguments, in
this order:

* :class:`FolderStart`: a new run claims its folder (an earlier run's stale files removed,
  summary.json "running" with the run's identity, cosserat_fem/io/run_folder.py); a restart cuts
  the outputs back to its checkpoint (checked before anything was built);
* :class:`ProbeObserver`: probes.csv, a row per output time;
* :class:`XdmfObserver`: an XDMF frame every ``output.xdmf_interval`` (probes.csv flushed
  first, so that it reaches every frame on disk);
* :class:`ProgressObserver`: the progress bar (or any callback of (t, steps, iterations));
* user observers, :class:`ProbeRecorder`, :class:`FieldRecorder` (the Python API's arrays);
* :class:`CheckpointObserver`: checkpoints when due and at the end (cosserat_fem/io/checkpoint.py);
* :class:`DeadlineObserver`: stops the run at ``limits.wall_time``, with a checkpoint;
* :class:`InterruptObserver`: stops every rank at the same step after an interrupt (SIGINT)
  reached any of them under mpirun (cosserat_fem/common/parallel.py);
* :class:`RunSummary`: the summary completed at the end (:func:`summary_start` begins it, the
  same for run, static and modes), and summary.json written.

Not in the chain, passed as a user observer: :class:`PoincareSection` (poincare.csv, one state
a forcing period; cosserat_fem/analysis/lyapunov.py uses it).

(The rod's energy at every output time, for tests: tests/rod_energy.py's EnergyRecorder.)
"""

from __future__ import annotations

import platform
import time
from collections import deque
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from cosserat_fem import __version__
from cosserat_fem.common.errors import CosseratError, LimitReached, SceneError, SolverError
from cosserat_fem.common.log import LOGGER
from cosserat_fem.common.parallel import check_interrupt, from_root
from cosserat_fem.io.checkpoint import Checkpoint, CheckpointWriter
from cosserat_fem.io.probes import PROBES, ProbeWriter, last_probe_row
from cosserat_fem.io.run_folder import SUMMARY, claim, cut_outputs, status_of, write_summary
from cosserat_fem.io.xdmf import XDMF
from cosserat_fem.output.fields import LineSampler, PointProbe, XdmfWriter, probe_position
from cosserat_fem.timestepping.events import Events, Observer


def _contact_entries(solver) -> dict:
    """summary.json's "contact" (cosserat_fem/nls/contact.py ``NodeContact.summary``), if the
    solver imposes contact."""
    contact = getattr(solver, "contact", None)
    return {} if contact is None else {"contact": contact.summary()}


class FolderStart(Observer):
    """Claims the folder of a new run, or cuts a restart's outputs back to its checkpoint
    (``plan``, from io/run_folder.py's check_outputs); then summary.json says "running".
    ``writes_checkpoint``: the run writes checkpoints (a file of the user's named
    ``checkpoint`` is then in its way, run_folder.claim)."""

    def __init__(
        self,
        folder: Path,
        comm,
        writes_xdmf: bool,
        summary: dict,
        plan=None,
        writes_checkpoint: bool = False,
    ):
        self.folder, self.comm, self.writes_xdmf = folder, comm, writes_xdmf
        self.summary, self.plan = summary, plan
        self.writes_checkpoint = writes_checkpoint
        self.claimed = False

    def started(self, loop) -> None:
        """Collective: the folder claimed or cut back to the checkpoint, then summary.json."""
        if self.plan is None:
            claim(self.folder, self.comm, self.writes_xdmf, self.summary, self.writes_checkpoint)
        else:
            cut_outputs(self.plan, self.comm)
            write_summary(self.folder / SUMMARY, self.summary, self.comm)
        self.claimed = True


def summary_start(
    kind: str,
    scene,
    comm,
    model=None,
    probe: PointProbe | None = None,
    solver=None,
    run_id: str | None = None,
    **extra,
) -> dict:
    """The summary (summary.json of a run or a static solve, modes.json of modes) as it
    starts, status "running": ``kind`` ("run", "static", "modes"), ``run_id`` if given, the
    version, the scene file and its SHA-256, the MPI ranks; with ``model`` its discretisation
    (dofs, elements, degree, quadrature degree, ω0 [rad/s], skipped terms, solved unknowns,
    groups); with ``probe`` its arc length [m] and the point of the rod at rest from which
    probes.csv's x, y, z are displacements [m]; with ``solver`` its LU package; then
    ``extra``, the Python version and the scene (as validated). :class:`RunSummary` completes
    it at the end."""
    summary: dict = {"status": "running", "kind": kind}
    if run_id is not None:
        summary["run_id"] = run_id
    summary.update(
        {
            "cosserat_fem": __version__,
            "scene_file": scene.source,
            "scene_file_sha256": scene.source_sha256,
            "mpi_ranks": comm.size,
        }
    )
    if model is not None:
        disc = scene.discretisation
        summary.update(
            {
                "dofs": model.global_dofs(),
                "elements": disc.elements,
                "degree": disc.degree,
                "quadrature_degree": disc.quadrature_degree,
                "omega0_rad_s": model.omega0,
                "skipped_terms": model.skipped,
                "solved_unknowns": list(model.layout.names),
                "groups": model.groups.as_dict(),
            }
        )
    if probe is not None and scene.structure is not None:  # at a node, not at an s
        node = scene.structure.probe_node()
        summary.update({"probe_node": node, "probe_reference_position_m": probe_position(scene, 0)})
    elif probe is not None:
        at = probe.sigma * scene.rod.length
        summary.update({"probe_s_m": at, "probe_reference_position_m": probe_position(scene, at)})
    if solver is not None:
        summary["lu_package"] = solver.lu_package
    summary.update(extra)
    summary.update({"python": platform.python_version(), "scene": scene.to_dict()})
    return summary


class RunSummary(Observer):
    """The summary of :func:`summary_start` completed at the end of a run or a static solve
    (``summary``, updated in place), and written as summary.json if the folder was claimed
    (``start``): the status and message (cosserat_fem/io/run_folder.py's status_of), the
    loop's counters (``loop.state.counts()``; ``ended_early`` with the reason if the loop
    ended early), the checkpoints written, Newton's counts and its loop, and wall times [s]
    from ``t_start`` (a time.perf_counter() value): the solve loop from its first step to its
    last (the folder claimed and the first frame written belong to the set-up, as the first
    row of probes.csv does), its output part, JIT compilation, the total; then the entries
    of every observer of the run with a ``summary_entries()`` method (a dict: the reduced
    run's error indicator, cosserat_fem/rom/indicator.py). A summary that
    cannot be written is an OutputError unless the run already failed (the earlier one
    stays)."""

    def __init__(
        self,
        summary: dict,
        solver,
        t_start: float,
        comm,
        folder: Path | None = None,
        start: FolderStart | None = None,
        checkpoints: CheckpointObserver | None = None,
    ):
        self.summary, self.solver, self.t_start, self.comm = summary, solver, t_start, comm
        self.folder, self.start, self.checkpoints = folder, start, checkpoints

    def ended(self, loop, failure) -> None:
        now = time.perf_counter()
        since = loop.stepping_since or now
        loop_time = (loop.stepping_until or now) - since
        output = loop.events.output_time
        self.summary.update(
            {
                "status": status_of(failure),
                "message": str(failure) if failure else "",
                **loop.state.counts(),
                **({"ended_early": loop.end_reason} if loop.end_reason else {}),
                "checkpoints_written": self.checkpoints.written if self.checkpoints else 0,
                "newton": {**self.solver.stats.as_dict(), "loop": self.solver.loop},
                **_contact_entries(self.solver),
                "wall_time_s": {
                    "setup": since - self.t_start,
                    "jit_compile": self.solver.compile_time,
                    "solve_loop": loop_time,
                    "solve_loop_without_output": loop_time - output,
                    "output": output,
                    "total": now - self.t_start,
                },
            }
        )
        for observer in loop.events.observers:  # an observer's own entries, if it has any
            entries = getattr(observer, "summary_entries", None)
            if callable(entries):  # merged one level deep: two observers may fill "rom"
                for key, value in entries().items():
                    held = self.summary.get(key)
                    if isinstance(held, dict) and isinstance(value, dict):
                        held.update(value)
                    else:
                        self.summary[key] = value
        if self.start is not None and self.start.claimed:
            assert self.folder is not None, "a folder start comes with its folder"
            write_summary(self.folder / SUMMARY, self.summary, self.comm, failure is None)


def probe_rows(probe: PointProbe) -> np.ndarray | None:
    """The entries of U a probe reads (its node's block, or its cell's dofs), int32; None off
    its rank. A reduced run in reduced coordinates lifts only these at an output
    (TimeLoop.lift, docs/rom.md §8)."""
    if probe.cell is None:
        return None
    bs = probe.U.function_space.dofmap.bs
    if probe._node is not None:
        nodes = np.array([probe._node])
    else:
        nodes = probe.U.function_space.dofmap.cell_dofs(probe.cell)
    return np.ascontiguousarray((bs * nodes[:, None] + np.arange(bs)).ravel(), dtype=np.int32)


class ProbeObserver(Observer):
    """probes.csv: the probe's values (x, y, z, θ, ψ, φ) [m, rad] at every output time; a
    restart continues the angles (PointProbe: from the fixed basis, continued) from the
    file's last row. In reduced coordinates it lifts the probe's rows of U only."""

    needs_full_state = False

    def __init__(self, path: Path, probe: PointProbe, resume: bool = False):
        self.path, self.probe, self.resume = path, probe, resume
        self.writer: ProbeWriter | None = None

    def started(self, loop) -> None:
        if self.resume and self.probe.is_owner:
            self.probe.seed(last_probe_row(self.path))
        self.writer = ProbeWriter(self.path, self.probe, resume=self.resume)
        if not self.resume:
            self.writer.write(loop.state.t)

    def output(self, loop, k: int, t: float) -> None:
        writer = self.writer
        assert writer is not None, "started() made the writer"
        rows = probe_rows(self.probe)
        if rows is not None:
            loop.lift(rows)
        writer.write(t)
        if writer.comm.size > 1:
            writer.check()  # the owner's write error, on every rank

    def flush(self) -> None:
        if self.writer is not None:
            self.writer.flush()

    def digest(self) -> str | None:
        """SHA-256 of probes.csv so far, the same on every rank (collective)."""
        writer = self.writer
        assert writer is not None, "started() made the writer"
        digest = writer.digest()  # on the probe's owner, which may not be rank 0
        comm = writer.comm
        if comm.size > 1:
            writer.check()
            digest = comm.bcast(digest, root=self.probe.owner)
        return digest

    def ended(self, loop, failure) -> None:
        if self.writer is not None:
            self.writer.close()
            self.writer.check()


class XdmfObserver(Observer):
    """solution.xdmf + .h5: a frame every ``every`` output steps (and the start), the fields
    of ``output.fields``; ``resume = (n, frames)`` continues a restart's file."""

    def __init__(
        self,
        path: Path,
        model,
        every: int,
        probes: ProbeObserver | None,
        run_id: str | None = None,
        resume: tuple[int, int] | None = None,
    ):
        self.path, self.model, self.every, self.probes = path, model, every, probes
        self.run_id, self.resume = run_id, resume
        self.writer: XdmfWriter | None = None

    def started(self, loop) -> None:
        self.writer = XdmfWriter(self.path, self.model, resume=self.resume, run_id=self.run_id)
        if self.resume is None:
            self.writer.write(loop.state.t)

    def output(self, loop, k: int, t: float) -> None:
        if k % self.every == 0:
            if self.probes is not None:
                self.probes.flush()  # probes.csv reaches every frame on disk (kill-safe)
            assert self.writer is not None, "started() made the writer"
            self.writer.write(t)

    @property
    def frames(self) -> int | None:
        return None if self.writer is None else self.writer.writes

    def ended(self, loop, failure) -> None:
        if self.writer is not None:
            self.writer.close()


class ProgressObserver(Observer):
    """Calls ``callback(t [s], steps taken, Newton iterations)`` at every output time."""

    needs_full_state = False  # reads no state

    def __init__(self, callback):
        self.callback = callback

    def output(self, loop, k: int, t: float) -> None:
        self.callback(t, loop.state.accepted, loop.solver.stats.iterations)


class CheckpointObserver(Observer):
    """Checkpoints every ``output.checkpoint_interval`` (at a step's end, where the loop's
    state is whole) and at the end of a run that completed or stopped for a reason a restart
    can continue from (numerical trouble, a non-finite load, a limit): the last accepted
    state. Not after an output failure (the outputs then end before the steps taken: the
    last periodic checkpoint stands) nor an interruption (as after a kill)."""

    RESUMABLE = (SolverError, SceneError, LimitReached)
    needs_full_state = False  # TimeLoop.state_dict lifts what it keeps

    def __init__(
        self,
        folder: Path,
        comm,
        scene,
        run_id: str,
        probes: ProbeObserver,
        xdmf: XdmfObserver | None,
        previous: Checkpoint | None = None,
    ):
        self.folder, self.comm, self.scene, self.run_id = folder, comm, scene, run_id
        self.probes, self.xdmf, self.previous = probes, xdmf, previous
        self.writer: CheckpointWriter | None = None
        self._saved_at: float | None = None

    @property
    def written(self) -> int:
        return 0 if self.writer is None else self.writer.written

    def started(self, loop) -> None:
        out = self.scene.output
        self.writer = CheckpointWriter(
            self.folder,
            self.comm,
            out.checkpoint_interval,
            self.scene.time.start,
            self.scene.to_dict(),
            self.run_id,
            previous=self.previous,
        )

    def step_finished(self, loop) -> None:
        assert self.writer is not None, "started() made the writer"
        if self.writer.due(loop.state.t):
            self.save(loop)

    def save(self, loop) -> None:
        """A checkpoint of the loop's state at its time t [s] with how far the outputs got (probe
        rows, their SHA-256, XDMF frames); none if one was written at t already. Collective."""
        t = loop.state.t
        if self._saved_at == t:
            return
        assert self.writer is not None, "started() made the writer"
        outputs = {
            "probe_rows": loop.state.outputs + 1,
            "probes_sha256": self.probes.digest(),
            "xdmf_frames": None if self.xdmf is None else self.xdmf.frames,
        }
        self.writer.save(t, loop.state_dict(), outputs)
        self._saved_at = t
        LOGGER.info("checkpoint %d at t = %.6g s", self.writer.generation, t)

    def ended(self, loop, failure) -> None:
        if self.writer is None:
            return
        if (failure is None and loop.completed) or isinstance(failure, self.RESUMABLE):
            self.save(loop)


class DeadlineObserver(Observer):
    """Stops the run (LimitReached, exit 4, with a checkpoint) once ``deadline``, a
    time.perf_counter() value, has passed: limits.wall_time. Looks at the clock every
    ``every`` steps, where the loop's state is whole, every rank alike (rank 0's clock).
    ``advice``: how the stopped run goes on, in its message."""

    needs_full_state = False  # reads no state

    def __init__(
        self,
        deadline: float,
        wall_time: float,
        comm,
        every: int = 64,
        advice: str = "continue it with run --restart DIR",
    ):
        self.deadline, self.wall_time, self.comm, self.every = deadline, wall_time, comm, every
        self.advice = advice
        self._ticks = 0

    def step_finished(self, loop) -> None:
        """Every ``every`` steps: LimitReached once rank 0's clock has passed the deadline."""
        self._ticks += 1
        if self._ticks % self.every:
            return
        if from_root(self.comm, time.perf_counter() > self.deadline):
            raise LimitReached(
                f"limits.wall_time: the run stopped at t = {loop.state.t:.6g} s after its limit "
                f"of {self.wall_time:g} s of wall time; {self.advice} "
                "(--set limits.wall_time=... to allow more)"
            )


class InterruptObserver(Observer):
    """KeyboardInterrupt on every rank at the end of a step once any rank of ``comm`` was
    interrupted under mpirun (parallel.check_interrupt), where the loop's state is whole:
    the ranks stop alike, none waits for the others. Looked at about every ``interval``
    seconds (the steps in between chosen by rank 0 from the pace of the last ones, at most
    ``most``: a step slowed down 64 times by halvings still looks within a few seconds, well
    inside parallel.ABORT_AFTER): an allreduce every step made a sweep on a group of two
    ranks a quarter slower on a busy machine (docs/decisions.md, "Interrupts under MPI")."""

    needs_full_state = False  # reads no state

    def __init__(self, comm, interval: float = 0.1, most: int = 100):
        self.comm, self.interval, self.most = comm, interval, most
        self.every, self._ticks, self._since = 1, 0, time.perf_counter()

    def step_finished(self, loop) -> None:
        self._ticks += 1
        if self._ticks < self.every:
            return
        now = time.perf_counter()
        pace = max(now - self._since, 1e-9) / self._ticks  # s a step
        wanted = max(1, min(self.most, int(self.interval / pace)))
        self.every = check_interrupt(self.comm, wanted)
        self._ticks, self._since = 0, now


class ProbeRecorder(Observer):
    """The probe's rows (t, x, y, z, θ, ψ, φ, ...) [s, m, rad] (its ``columns``) in memory, at
    the start and every output time: ``rows()`` on every rank (one broadcast at the end).
    In reduced coordinates it lifts the probe's rows of U only."""

    needs_full_state = False

    def __init__(self, probe: PointProbe):
        self.probe = probe
        self._rows: list[np.ndarray] = []
        self._lift_rows: np.ndarray | None = probe_rows(probe)

    def started(self, loop) -> None:
        if not loop.restarted:
            self.output(loop, 0, loop.state.t)

    def output(self, loop, k: int, t: float) -> None:
        if k and self._lift_rows is not None:  # (k = 0: the initial state, full)
            loop.lift(self._lift_rows)
        values = self.probe.values()
        if values is not None:
            self._rows.append(np.concatenate([[t], values]))

    def rows(self) -> np.ndarray:
        comm = self.probe.U.function_space.mesh.comm
        rows = np.array(self._rows).reshape(-1, len(self.probe.columns))
        return rows if comm.size == 1 else comm.bcast(rows, root=self.probe.owner)


class FieldRecorder(Observer):
    """The fields p = (x, y, z, θ, ψ, φ) [m, rad] at arc lengths σ ℓ (``sigmas``: σ in
    [0, 1]) every ``every`` output times and at the start: ``times`` (T,), ``values``
    (T, len(sigmas), 6), the same on every rank."""

    def __init__(self, model, sigmas, every: int = 1):
        self.sampler = LineSampler(model, np.asarray(sigmas, dtype=float))
        self.every = every
        self._times: list[float] = []
        self._values: list[np.ndarray | None] = []  # None on ranks other than 0

    def started(self, loop) -> None:
        if not loop.restarted:
            self._sample(loop.state.t)

    def output(self, loop, k: int, t: float) -> None:
        if k % self.every == 0:
            self._sample(t)

    def _sample(self, t: float) -> None:
        self._times.append(t)
        self._values.append(self.sampler.sample())  # on rank 0

    def arrays(self) -> tuple[np.ndarray, np.ndarray]:
        """(``times`` (T,) [s], ``values`` (T, len(sigmas), 6) [m, rad]) on every rank
        (collective)."""
        comm = self.sampler.comm
        values = np.array(self._values) if comm.rank == 0 else None
        if comm.size > 1:
            values = comm.bcast(values, root=0)
        assert values is not None, "rank 0's values, broadcast"
        return np.array(self._times), values


class StandardObservers:
    """The observers of a run or a static solve, in the order of the module docstring, and
    its :class:`Events` (``events``). ``summary`` from :func:`summary_start`; ``out`` the
    folder (None: no files); ``xdmf_every`` output steps between XDMF frames; ``restart`` and
    ``plan`` (io/run_folder.py's check_outputs) continue a checkpoint's outputs;
    ``checkpoints`` writes them (the scene's output.checkpoint); ``wall_time`` [s] the limit
    after ``t_start`` (None: none); ``progress(t, steps, iterations)``; ``observers`` the
    caller's; ``record`` keeps the probe's rows (``recorder``), ``fields`` the stations σ
    sampled every ``field_every`` output times (``sampled``)."""

    def __init__(
        self,
        scene,
        model,
        solver,
        probe: PointProbe,
        summary: dict,
        comm,
        t_start: float,
        out: Path | None,
        *,
        xdmf_every: int,
        restart: Checkpoint | None = None,
        plan=None,
        checkpoints: bool = False,
        wall_time: float | None = None,
        progress: Callable | None = None,
        observers: Sequence[Observer | Callable] = (),
        record: bool = False,
        fields: np.ndarray | None = None,
        field_every: int = 1,
    ):
        chain: list[Observer | Callable] = []
        begin = probes = xdmf = None
        if out is not None:
            begin = FolderStart(
                out, comm, scene.output.xdmf, summary, plan, writes_checkpoint=checkpoints
            )
            probes = ProbeObserver(out / PROBES, probe, resume=restart is not None)
            chain += [begin, probes]
            if scene.output.xdmf:
                resume = (restart.restart_number, plan.frames) if restart is not None else None
                xdmf = XdmfObserver(
                    out / XDMF, model, xdmf_every, probes, summary["run_id"], resume
                )
                chain.append(xdmf)
        if progress is not None:
            chain.append(ProgressObserver(progress))
        chain += list(observers)
        self.recorder = ProbeRecorder(probe) if record else None
        self.sampled = FieldRecorder(model, fields, field_every) if fields is not None else None
        chain += [o for o in (self.recorder, self.sampled) if o is not None]
        self.checkpoints = None
        if out is not None and checkpoints:
            assert probes is not None, "made with the folder"
            self.checkpoints = CheckpointObserver(
                out, comm, scene, summary["run_id"], probes, xdmf, previous=restart
            )
            chain.append(self.checkpoints)
        if wall_time is not None:
            advice = (  # a reduced run continues on its basis (cosserat_fem/rom/runs.py)
                "continue it with rom run --restart DIR --basis FILE"
                if getattr(solver, "basis", None) is not None
                else "continue it with run --restart DIR"
            )
            chain.append(DeadlineObserver(t_start + wall_time, wall_time, comm, advice=advice))
        chain.append(InterruptObserver(comm))
        chain.append(RunSummary(summary, solver, t_start, comm, out, begin, self.checkpoints))
        self.events = Events(chain)


class PoincareSection(Observer):
    """A Poincaré section of a periodically forced run: the state once a forcing period
    ``period`` T [s], at the section times t_j = (j + ``phase``/2π) T (``phase`` φ0 [rad]: the
    forcing's phase, its time origin the run's t = 0), for every t_j from the run's start on.

    At each t_j: the probe's values at σ = ``sigma`` (default the scene's probe point) and the
    root mean square of the state's entries over the rod's degrees of freedom (U in the
    solver's units, dimensionless: cosserat_fem/io/poincare.py), from the state at t_j: the
    output state itself when an output time lands on t_j (to 1e-9 T), else the cubic through
    the four output states around it (Lagrange, the two before and the two after t_j where
    there are, timestepping/adaptive.py ``lagrange_weights``): interpolation error
    O(Δt⁴ ‖∂⁴U/∂t⁴‖), Δt = time.step, below the error of the integrators of order ≤ 3 (and
    SDIRK4's own), so that a section between output times is as good as one on them. ``rows``
    (on every rank after the run): (j, t_j, probe values, state_rms); with ``path``,
    poincare.csv there, each row appended as it is sampled (so that a run killed by SIGTERM
    or SIGKILL keeps the rows so far) and the file written whole again at the run's end (the
    same bytes: cosserat_fem/io/poincare.py ``poincare_bytes``)."""

    def __init__(
        self,
        period: float,
        phase: float = 0.0,
        path: Path | None = None,
        sigma: float | None = None,
    ):
        if not (np.isfinite(period) and period > 0.0):
            raise SceneError(f"period: must be a positive time [s], got {period!r}")
        if not np.isfinite(phase):
            raise SceneError(f"phase: must be a finite angle [rad], got {phase!r}")
        self.period, self.phase, self.path, self.sigma = float(period), float(phase), path, sigma
        self._buffer: deque[tuple[float, np.ndarray]] = deque(maxlen=4)
        self._rows: list[np.ndarray] = []
        self._appended = False  # poincare.csv made, with its header (at the first row)
        self.rows: np.ndarray | None = None
        self.columns: tuple[str, ...] = ()

    def section_time(self, j: int) -> float:
        """t_j [s]."""
        return (j + self.phase / (2.0 * np.pi)) * self.period

    def started(self, loop) -> None:
        from dolfinx import fem

        from cosserat_fem.io.poincare import poincare_columns
        from cosserat_fem.output.fields import probe_sigma

        model = loop.model
        scene = model.scene
        sigma = probe_sigma(scene) if self.sigma is None else self.sigma
        self.scratch = fem.Function(model.V)
        fields = scene.output.probe_fields
        self.probe = PointProbe(model, sigma, U=self.scratch, fields=fields)
        self.columns = poincare_columns(fields)
        self.comm = model.msh.comm
        self.owned = model.V.dofmap.index_map.size_local * model.V.dofmap.index_map_bs
        self.entries = self.comm.allreduce(self.owned)
        t0 = loop.state.t
        self.next = int(np.ceil((t0 - 1e-9 * self.period) / self.period - self.phase / 2 / np.pi))
        self._push(t0, model.U.x.array)

    def output(self, loop, k: int, t: float) -> None:
        self._push(t, loop.model.U.x.array)

    def _push(self, t: float, u: np.ndarray) -> None:
        """Keep the output state (t, u) and sample every section time it completes."""
        from cosserat_fem.timestepping.adaptive import lagrange_weights

        self._buffer.append((t, u.copy()))
        close = 1e-9 * self.period
        while True:
            t_j = self.section_time(self.next)
            times = [ti for ti, _ in self._buffer]
            if abs(times[-1] - t_j) <= close:
                self._sample(t_j, self._buffer[-1][1])
            elif len(times) == 4 and t_j <= times[-2]:
                weights = lagrange_weights(times, t_j)
                self._sample(
                    t_j, sum(w * ui for w, (_, ui) in zip(weights, self._buffer, strict=True))
                )
            else:
                return
            self.next += 1

    def _sample(self, t: float, state: np.ndarray) -> None:
        self.scratch.x.array[:] = state
        owned = state[: self.owned]
        rms = np.sqrt(self.comm.allreduce(float(owned @ owned)) / self.entries)
        values = self.probe.values()
        row = None if values is None else np.concatenate([[self.next, t], values, [rms]])
        if row is not None:
            self._rows.append(row)
        if self.path is not None:
            self._append(row)

    def _append(self, row: np.ndarray | None) -> None:
        """The probe owner's ``row`` appended to poincare.csv by rank 0 (the header with the
        first); collective, the ranks agree on a failure."""
        from cosserat_fem.analysis.branch_outputs import append_on_root, replace_on_root
        from cosserat_fem.io.poincare import poincare_bytes

        if self.comm.size > 1:
            row = self.comm.bcast(row, root=self.probe.owner)
        assert row is not None and self.path is not None, "the probe's owner sampled it"
        text = poincare_bytes(self.columns, row)
        if self._appended:
            append_on_root(self.path, text[text.index(b"\n") + 1 :], self.comm)
        else:
            replace_on_root(self.path, text, self.comm)
        self._appended = True

    def ended(self, loop, failure) -> None:
        from cosserat_fem.common.parallel import agree
        from cosserat_fem.io.output_files import write_output
        from cosserat_fem.io.poincare import poincare_bytes

        if not self.columns:  # the run failed before it started
            return
        rows = np.array(self._rows).reshape(-1, len(self.columns))
        owner = self.probe.owner
        self.rows = rows if self.comm.size == 1 else self.comm.bcast(rows, root=owner)
        if self.path is None:
            return
        problem = None
        if self.comm.rank == owner:
            try:
                write_output(Path(self.path), poincare_bytes(self.columns, self.rows), "run")
            except CosseratError as exc:
                problem = exc
        agree(self.comm, problem)
