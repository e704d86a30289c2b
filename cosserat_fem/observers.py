"""Observers of a run's events (cosserat_fem/events.py): what a run writes and records.

Each observer has one job; a run is composed of the ones it needs (cosserat_fem/simulation.py,
statics.py), in this order:

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
  reached any of them under mpirun (cosserat_fem/parallel.py);
* :class:`FolderSummary`: summary.json at the end;
* :class:`EnergyRecorder`: the rod's energy and its loads' power at every output time
  (cosserat_fem/energy.py), for studies and tests.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from .energy import EnergyMonitor
from .errors import LimitReached, SceneError, SolverError
from .events import Observer
from .fields import LineSampler, PointProbe, XdmfWriter
from .io.checkpoint import Checkpoint, CheckpointWriter
from .io.probes import ProbeWriter, last_probe_row
from .io.run_folder import SUMMARY, claim, cut_outputs, write_summary
from .log import LOGGER
from .parallel import check_interrupt, from_root


class FolderStart(Observer):
    """Claims the folder of a new run, or cuts a restart's outputs back to its checkpoint
    (``plan``, from io/run_folder.py's check_outputs); then summary.json says "running".
    ``writes_checkpoint``: the run writes checkpoints (a file of the user's named
    ``checkpoint`` is then in its way, run_folder.claim)."""

    def __init__(self, folder: Path, comm, writes_xdmf: bool, summary: dict, plan=None,
                 writes_checkpoint: bool = False):  # fmt: skip
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


class FolderSummary(Observer):
    """summary.json at the end: ``finish(loop, failure)`` gives its content. A summary that
    cannot be written is an OutputError unless the run already failed (the earlier one
    stays)."""

    def __init__(self, folder: Path, comm, start: FolderStart, finish):
        self.folder, self.comm, self.start, self.finish = folder, comm, start, finish

    def ended(self, loop, failure) -> None:
        if self.start.claimed:
            write_summary(
                self.folder / SUMMARY, self.finish(loop, failure), self.comm, failure is None
            )


class ProbeObserver(Observer):
    """probes.csv: the probe's values (x, y, z, θ, ψ, φ) [m, rad] at every output time; a
    restart continues the angles (PointProbe: from the fixed basis, continued) from the
    file's last row."""

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
        self.writer.write(t)
        if self.writer.comm.size > 1:
            self.writer.check()  # the owner's write error, on every rank

    def flush(self) -> None:
        if self.writer is not None:
            self.writer.flush()

    def digest(self) -> str | None:
        """SHA-256 of probes.csv so far, the same on every rank (collective)."""
        digest = self.writer.digest()  # on the probe's owner, which may not be rank 0
        comm = self.writer.comm
        if comm.size > 1:
            self.writer.check()
            digest = comm.bcast(digest, root=self.probe.owner)
        return digest

    def ended(self, loop, failure) -> None:
        if self.writer is not None:
            self.writer.close()
            self.writer.check()


class XdmfObserver(Observer):
    """solution.xdmf + .h5: a frame every ``every`` output steps (and the start), the fields
    of ``output.fields``; ``resume = (n, frames)`` continues a restart's file."""

    def __init__(self, path: Path, model, every: int, probes: ProbeObserver | None,
                 run_id: str | None = None, resume: tuple[int, int] | None = None):  # fmt: skip
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
            self.writer.write(t)

    @property
    def frames(self) -> int | None:
        return None if self.writer is None else self.writer.writes

    def ended(self, loop, failure) -> None:
        if self.writer is not None:
            self.writer.close()


class ProgressObserver(Observer):
    """Calls ``callback(t [s], steps taken, Newton iterations)`` at every output time."""

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

    def __init__(self, folder: Path, comm, scene, run_id: str, probes: ProbeObserver,
                 xdmf: XdmfObserver | None, previous: Checkpoint | None = None):  # fmt: skip
        self.folder, self.comm, self.scene, self.run_id = folder, comm, scene, run_id
        self.probes, self.xdmf, self.previous = probes, xdmf, previous
        self.writer: CheckpointWriter | None = None
        self._saved_at: float | None = None

    @property
    def written(self) -> int:
        return 0 if self.writer is None else self.writer.written

    def started(self, loop) -> None:
        out = self.scene.output
        self.writer = CheckpointWriter(self.folder, self.comm, out.checkpoint_interval,
                                       self.scene.time.start, self.scene.to_dict(), self.run_id,
                                       previous=self.previous)  # fmt: skip

    def step_finished(self, loop) -> None:
        if self.writer.due(loop.state.t):
            self.save(loop)

    def save(self, loop) -> None:
        """A checkpoint of the loop's state at its time t [s] with how far the outputs got (probe
        rows, their SHA-256, XDMF frames); none if one was written at t already. Collective."""
        t = loop.state.t
        if self._saved_at == t:
            return
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
    ``every`` steps, where the loop's state is whole, every rank alike (rank 0's clock)."""

    def __init__(self, deadline: float, wall_time: float, comm, every: int = 64):
        self.deadline, self.wall_time, self.comm, self.every = deadline, wall_time, comm, every
        self._ticks = 0

    def step_finished(self, loop) -> None:
        """Every ``every`` steps: LimitReached once rank 0's clock has passed the deadline."""
        self._ticks += 1
        if self._ticks % self.every:
            return
        if from_root(self.comm, time.perf_counter() > self.deadline):
            raise LimitReached(
                f"limits.wall_time: the run stopped at t = {loop.state.t:.6g} s after its limit "
                f"of {self.wall_time:g} s of wall time; continue it with run --restart DIR "
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
    the start and every output time: ``rows()`` on every rank (one broadcast at the end)."""

    def __init__(self, probe: PointProbe):
        self.probe = probe
        self._rows: list[np.ndarray] = []

    def started(self, loop) -> None:
        if not loop.restarted:
            self.output(loop, 0, loop.state.t)

    def output(self, loop, k: int, t: float) -> None:
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
        self._values: list[np.ndarray] = []

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
        return np.array(self._times), values


class EnergyRecorder(Observer):
    """Observer (cosserat_fem/events.py): at every output time t [s], the rod's energy
    E = T + V [J] and the power P [W] of its loads and damping: lists ``t``, ``E``, ``P``."""

    def __init__(self):
        self.monitor: EnergyMonitor | None = None
        self.t: list[float] = []
        self.E: list[float] = []
        self.P: list[float] = []

    def output(self, loop, k: int, t: float) -> None:
        """Appends t [s], E = T + V [J] and P [W]; the monitor is built at the first output."""
        if self.monitor is None:
            self.monitor = EnergyMonitor(loop.model)
        self.t.append(t)
        self.E.append(sum(self.monitor.energies()))
        self.P.append(self.monitor.power(t))
