"""Checkpoint/restart: a stopped run continues from its last checkpoint, bit for bit.

A checkpoint holds everything the remaining steps depend on, so that a restarted run gives
the probes of an uninterrupted run to round-off (in fact identically, ``tests/test_restart.py``):

* the state U and the integrator's history (``Integrator.state_dict``: previous states and
  step sizes, generalized-α's rate, SDIRK's stored stage rates for its predictor);
* the Newton solver's policy state and, for a reused (``lagged``/``frozen``) Jacobian, the
  values of every coefficient and constant it was assembled from: the restarted run assembles
  the same matrix, hence the same LU factors and the same modified-Newton iterates
  (``NewtonSolver.state_dict``); the counters continue;
* the time loop's position (time, step counters, a fixed step's halving level, an adaptive
  step's size, error-estimate history and field peaks);
* how far the outputs got: the probe rows (and the SHA-256 of probes.csv up to them) and the
  XDMF frames at the checkpoint's time.

Layout, in the run's output folder::

    checkpoint/checkpoint.json         the index: run id, ranks, scene, and the two newest
                                       checkpoints (generation, slot, time, outputs, digests)
    checkpoint/state<g mod 2>.rank<r>.npz   rank r's arrays of generation g

Checkpoints alternate between two slots and the index is replaced atomically after every
rank has written its slot, so a run killed at any moment (SIGKILL included) leaves the index
naming a complete checkpoint. The index holds the SHA-256 of every rank's state file: a
truncated or bit-flipped file is found, named, and the previous checkpoint (the other slot)
used instead when it is intact. Arrays are per rank: a restart needs the same number of ranks
(the same mesh partition). A write that fails (disk full, file size limit) leaves the index
naming the last complete checkpoint (:class:`~cosserat_fem.common.errors.OutputError`).
When to write them: ``output.checkpoint_interval`` (simulated
time; "auto" = a tenth of the run) and at the end of the run, completed or stopped by a
solver failure (the last accepted state), unless ``output.checkpoint = false``.

On restart (``cosserat-fem run --restart DIR``) the scene is the checkpoint's own; only keys
that do not change the discrete problem may be overridden (cosserat_fem/analysis/restart.py), e.g.
``--set time.end=0.12`` to continue a completed run. Everything is checked before anything is
touched (cosserat_fem/io/run_folder.py, ``check_outputs``): the outputs must be the checkpoint's
run's (the run id of summary.json and solution.xdmf, written when the run started, and the
digest of probes.csv up to the checkpoint's rows), and must reach the checkpoint. Only then are
the outputs written after the checkpoint (by a run killed later) cut back to it
(``cut_outputs``): probes.csv to its rows, the XDMF file to its frames, and then (the XML cut
first, so that a kill half-way leaves no XML naming a deleted file) the frame files after them,
``<name>.frames/<i>.h5`` for i >= the checkpoint's frames, deleted; new frames go into new frame
files, ``<name>.frames/<frames>.h5`` on, referenced by the one ``<name>.xdmf``
(cosserat_fem/io/xdmf.py). Outputs of the earlier single-file layout are continued the same way
(their ``<name>-restart<m>.h5`` files of later restarts deleted). A new run into a folder
removes the checkpoint of an earlier one (cosserat_fem/io/run_folder.py): the files of
:data:`OWN_FILES` in ``checkpoint/``, nothing else there.

No file is written through a link, and no special file is read (cosserat_fem/common/safe_files.py):
the index and the state files are replaced by an atomic rename, probes.csv is cut as the
folder's own copy when it is a link (a restart of a copy made with ``cp -as``, ``cp -al`` or
``rsync --link-dest`` leaves the original as it was), and a restart whose ``checkpoint/`` or
frames folder is a link to a folder elsewhere is refused (it would write there). A restart
also holds the folder's lock (cosserat_fem/io/run_folder.py); a run in progress there is named
before the checkpoint is read.
"""

from __future__ import annotations

import hashlib
import io
import json
import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from mpi4py import MPI

from cosserat_fem.common import safe_files
from cosserat_fem.common.errors import OutputError, SceneError
from cosserat_fem.common.log import LOGGER
from cosserat_fem.common.parallel import agree
from cosserat_fem.io.folder_lock import refuse_if_held

FORMAT = 3  # 3: the time loop's state in one part, "loop" (cosserat_fem/timestepping/loop.py)
DIRECTORY = "checkpoint"
INDEX = "checkpoint.json"
#: The names of the files the project writes in ``checkpoint/`` (and their scratch names): what
#: a new run removes there.
OWN_FILES = re.compile(rf"(?:{re.escape(INDEX)}|state[01]\.rank[0-9]+\.npz)(?:\.tmp)?")


def state_file(slot: int, rank: int) -> str:
    """The name, in :data:`DIRECTORY`, of rank ``rank``'s state file of slot ``slot`` (0, 1);
    :data:`OWN_FILES` matches it."""
    return f"state{slot}.rank{rank}.npz"


def _flatten(parts: dict[str, dict]) -> dict[str, np.ndarray]:
    """{"part.key": array} from {"part": {"key": value}}; scalars become 0-d arrays."""
    return {f"{p}.{k}": np.asarray(v) for p, state in parts.items() for k, v in state.items()}


def _unflatten(arrays: dict[str, np.ndarray]) -> dict[str, dict[str, np.ndarray]]:
    """{"part": {"key": array}} from {"part.key": array}: the inverse of :func:`_flatten`."""
    parts: dict[str, dict[str, np.ndarray]] = {}
    for name, value in arrays.items():
        part, key = name.split(".", 1)
        parts.setdefault(part, {})[key] = value
    return parts


@dataclass
class Checkpoint:
    """A loaded checkpoint: the index entry (``meta``: run id, scene, time, outputs, ...; the
    same on every rank) and this rank's state, by part (``parts["integrator"]["U_n"]``, ...)."""

    run_dir: Path
    meta: dict[str, Any]
    parts: dict[str, dict[str, np.ndarray]]

    @property
    def time(self) -> float:
        return float(self.meta["time"])

    @property
    def run_id(self) -> str:
        return str(self.meta["run_id"])

    @property
    def restart_number(self) -> int:
        """The number of the restart that continues this checkpoint (1 for the first)."""
        return int(self.meta["restarts"]) + 1


class CheckpointWriter:
    """Writes checkpoints into ``<run_dir>/checkpoint`` (module docstring)."""

    def __init__(
        self,
        run_dir: Path,
        comm: MPI.Comm,
        interval: float,
        start: float,
        scene: dict,
        run_id: str,
        previous: Checkpoint | None = None,
    ):
        self.directory = Path(run_dir) / DIRECTORY
        self.comm = comm
        self.interval, self.start = interval, start
        self.scene, self.run_id = scene, run_id
        self.generation = int(previous.meta["generation"]) if previous else 0
        self.restarts = previous.restart_number if previous else 0
        self._entries: list[dict] = [_entry(previous.meta)] if previous else []
        self.written = 0
        problem = None
        if comm.rank == 0:
            try:
                self.directory.mkdir(exist_ok=True)
            except OSError as exc:
                problem = OutputError(f"checkpoint: cannot make {str(self.directory)!r} ({exc})")
        agree(comm, problem)
        self._next = math.inf
        self._schedule(previous.time if previous else start)

    def _schedule(self, t: float) -> None:
        """The next checkpoint time: the first start + k interval beyond t."""
        if self.interval <= 0.0:
            self._next = math.inf
            return
        k = math.floor((t - self.start) / self.interval + 1e-9) + 1
        self._next = self.start + k * self.interval

    def due(self, t: float) -> bool:
        return t >= self._next - 1e-9 * self.interval

    def save(self, t: float, parts: dict[str, dict], outputs: dict[str, Any]) -> None:
        """Write generation g + 1 of the state ``parts`` at time t [s] (collective). An
        OutputError on every rank if any rank cannot write; the index then still names the
        last complete checkpoint."""
        generation = self.generation + 1
        slot = generation % 2
        path = self.directory / state_file(slot, self.comm.rank)
        buffer = io.BytesIO()
        arrays = _flatten(parts)
        arrays["meta.generation"] = np.asarray(generation)
        np.savez(buffer, **arrays)
        data = buffer.getvalue()
        problem = _write_atomically(path, data)
        digests = self.comm.allgather(hashlib.sha256(data).hexdigest())
        agree(self.comm, problem)  # every rank's slot is complete before the index names it
        problem = None
        if self.comm.rank == 0:
            entry = {
                "generation": generation,
                "slot": slot,
                "time": t,
                "restarts": self.restarts,
                "outputs": outputs,
                "digests": digests,
            }
            index = {
                "format": FORMAT,
                "run_id": self.run_id,
                "ranks": self.comm.size,
                "scene": self.scene,
                "checkpoints": [entry, *self._entries[:1]],
            }
            index["checksum"] = _checksum(index)
            text = json.dumps(index, indent=1) + "\n"
            problem = _write_atomically(self.directory / INDEX, text.encode("utf-8"))
            if problem is None:
                self._entries = [entry]
        agree(self.comm, problem)
        self.generation = generation
        self.written += 1
        self._schedule(t)


def _checksum(index: dict) -> str:
    """SHA-256 of the index's content (all but the checksum itself), in a canonical form:
    a changed digit of a time or a count is found, not only damage to the state files."""
    content = {k: v for k, v in index.items() if k != "checksum"}
    return hashlib.sha256(json.dumps(content, sort_keys=True).encode("utf-8")).hexdigest()


def _entry(meta: dict) -> dict:
    return {k: meta[k] for k in ("generation", "slot", "time", "restarts", "outputs", "digests")}


def _write_atomically(path: Path, data: bytes) -> OutputError | None:
    """Write ``data`` to ``path`` through a temporary file and a rename; the error, if any
    (the temporary file is removed, ``path`` is untouched)."""
    try:
        safe_files.replace(path, data)
    except OSError as exc:
        return OutputError(f"checkpoint: cannot write {str(path)!r} ({exc.strerror or exc})")
    return None


# ---------------------------------------------------------------------------------- loading
_INDEX_FIELDS = {"format": int, "run_id": str, "ranks": int, "scene": dict, "checkpoints": list}
_ENTRY_FIELDS = {
    "generation": int,
    "slot": int,
    "time": float,
    "restarts": int,
    "outputs": dict,
    "digests": list,
}


def _index_problem(meta: Any, path: Path) -> str | None:
    """What is wrong with a parsed index, or None."""
    where = f"{str(path)!r}"
    if not isinstance(meta, dict):
        return f"{where} is not a checkpoint index"
    if meta.get("format") != FORMAT:
        return (
            f"{where} has format {meta.get('format')!r}, not {FORMAT} (written by another "
            "version of cosserat-fem)"
        )
    if meta.get("checksum") != _checksum(meta):
        return f"{where} does not match its checksum (damaged or edited)"
    entries = meta.get("checkpoints")
    checks = [(meta, _INDEX_FIELDS)]
    checks += [(e, _ENTRY_FIELDS) for e in entries or [] if isinstance(e, dict)]
    if not entries or not all(isinstance(e, dict) for e in entries):
        return f"{where} names no checkpoint"
    for table, fields in checks:
        for name, kind in fields.items():
            value = table.get(name)
            ok = isinstance(value, kind) and not isinstance(value, bool)
            if kind is float:
                ok = (
                    isinstance(value, int | float)
                    and not isinstance(value, bool)
                    and math.isfinite(value)
                )
            if not ok:
                return f"{where}: {name} is missing or not a {kind.__name__}"
    return None


def _read_state(path: Path, entry: dict, rank: int) -> tuple[dict | None, str | None]:
    """This rank's arrays of ``entry`` from ``path``, checked against the index's digest and
    generation; (None, what is wrong) if it cannot be used."""
    try:
        data = safe_files.read_regular(path)
        digests = entry["digests"]
        if len(digests) <= rank or hashlib.sha256(data).hexdigest() != digests[rank]:
            return None, f"{path.name} does not match its checksum (damaged or replaced)"
        with np.load(io.BytesIO(data)) as npz:
            arrays = {name: npz[name] for name in npz.files}
        if int(arrays.pop("meta.generation")) != entry["generation"]:
            return None, f"{path.name} is not of generation {entry['generation']}"
    except Exception as exc:  # noqa: BLE001 - any failure to read is a damaged checkpoint
        return None, f"cannot read {path.name} ({type(exc).__name__}: {exc})"
    return arrays, None


def load_checkpoint(run_dir: str | Path, comm: MPI.Comm = MPI.COMM_WORLD) -> Checkpoint:
    """The last intact checkpoint of the run in ``run_dir`` (the newest, else the previous
    one if the newest is damaged); SceneError if there is none or it does not fit this run
    (another number of ranks, another format). Collective: every rank agrees on what it
    found before any goes on."""
    run_dir = Path(run_dir)
    refuse_if_held(run_dir, comm, "restart")
    index_path = run_dir / DIRECTORY / INDEX
    meta, error = None, None
    if comm.rank == 0:
        try:
            meta = json.loads(safe_files.read_text(index_path))
            error = _index_problem(meta, index_path)
        except FileNotFoundError:
            error = f"no checkpoint in {str(run_dir)!r} (no {DIRECTORY}/{INDEX})"
        except (OSError, ValueError) as exc:
            reason = exc.strerror if isinstance(exc, OSError) and exc.strerror else exc
            error = f"cannot read {str(index_path)!r} ({reason})"
    meta, error = comm.bcast((meta, error), root=0)
    if error:
        raise SceneError(f"--restart: {error}")
    if meta["ranks"] != comm.size:
        raise SceneError(
            f"--restart: the checkpoint was written by {meta['ranks']} MPI ranks; restart "
            f"with the same number (mpirun -n {meta['ranks']}), not {comm.size}"
        )
    found: list[str] = []
    for entry in meta["checkpoints"][:2]:
        path = run_dir / DIRECTORY / state_file(entry["slot"], comm.rank)
        arrays, problem = _read_state(path, entry, comm.rank)
        problems = [p for p in comm.allgather(problem) if p]
        if not problems:
            assert arrays is not None  # no problem on this rank: its arrays were read
            common = {k: v for k, v in meta.items() if k not in ("checkpoints", "checksum")}
            if found:
                LOGGER.warning(
                    "checkpoint: %s; continuing from the previous checkpoint at t = %.6g s",
                    found[0],
                    entry["time"],
                )
            return Checkpoint(run_dir, {**common, **entry}, _unflatten(arrays))
        found.append(problems[0])
    raise SceneError(f"--restart: damaged checkpoint in {str(run_dir)!r}: {found[0]}")
