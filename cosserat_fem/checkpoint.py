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
* how far the outputs got: the probe rows and XDMF frames at the checkpoint's time.

Layout, in the run's output folder::

    checkpoint/checkpoint.json         the index: generation, time, ranks, scene, outputs
    checkpoint/state<g mod 2>.rank<r>.npz   rank r's arrays of generation g

Checkpoints alternate between two slots and the index is replaced atomically after every
rank has written its slot, so a run killed at any moment (SIGKILL included) leaves the index
naming a complete checkpoint. Arrays are per rank: a restart needs the same number of ranks
(the same mesh partition). When to write them: ``output.checkpoint_interval`` (simulated
time; "auto" = a tenth of the run) and at the end of the run, completed or stopped by a
solver failure (the last accepted state), unless ``output.checkpoint = false``.

On restart (``cosserat-fem run --restart DIR``) the scene is the checkpoint's own; only keys
that do not change the discrete problem may be overridden (:data:`RESTART_KEYS`), e.g.
``--set time.end=0.12`` to continue a completed run. Outputs written after the checkpoint (by
a run killed later) are cut back to it: probes.csv to its rows, the XDMF file to its frames;
new frames go into ``<name>-restart<n>.h5``, referenced by the one ``<name>.xdmf``.
"""

from __future__ import annotations

import json
import math
import os
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from mpi4py import MPI

from .errors import SceneError

FORMAT = 1
DIRECTORY = "checkpoint"
INDEX = "checkpoint.json"
#: Scene keys a restart may override (prefixes end with "."): none changes the discretisation,
#: the model or the output grid.
RESTART_KEYS = (
    "time.end",
    "time.max_halvings",
    "solver.",
    "output.checkpoint",
    "output.checkpoint_interval",
)


def _flatten(parts: dict[str, dict]) -> dict[str, np.ndarray]:
    """{"part.key": array} from {"part": {"key": value}}; scalars become 0-d arrays."""
    return {f"{p}.{k}": np.asarray(v) for p, state in parts.items() for k, v in state.items()}


def _unflatten(arrays: dict[str, np.ndarray]) -> dict[str, dict[str, np.ndarray]]:
    parts: dict[str, dict[str, np.ndarray]] = {}
    for name, value in arrays.items():
        part, key = name.split(".", 1)
        parts.setdefault(part, {})[key] = value
    return parts


@dataclass
class Checkpoint:
    """A loaded checkpoint: the index (``meta``, the same on every rank) and this rank's
    state, by part (``parts["integrator"]["U_n"]``, ...)."""

    run_dir: Path
    meta: dict[str, Any]
    parts: dict[str, dict[str, np.ndarray]]

    @property
    def time(self) -> float:
        return float(self.meta["time"])


class CheckpointWriter:
    """Writes checkpoints into ``<run_dir>/checkpoint`` (module docstring)."""

    def __init__(
        self,
        run_dir: Path,
        comm: MPI.Comm,
        interval: float,
        start: float,
        scene: dict,
        previous: Checkpoint | None = None,
    ):
        self.directory = Path(run_dir) / DIRECTORY
        self.comm = comm
        self.interval, self.start = interval, start
        self.scene = scene
        self.generation = int(previous.meta["generation"]) if previous else 0
        self.restarts = int(previous.meta["restarts"]) + 1 if previous else 0
        self.written = 0
        if comm.rank == 0:
            self.directory.mkdir(exist_ok=True)
        comm.barrier()
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

    def save(self, t: float, parts: dict[str, dict], outputs: dict[str, int]) -> None:
        """Write generation g + 1 of the state ``parts`` at time t [s] (collective)."""
        generation = self.generation + 1
        slot = generation % 2
        path = self.directory / f"state{slot}.rank{self.comm.rank}.npz"
        tmp = path.with_name(path.name + ".tmp")
        arrays = _flatten(parts)
        arrays["meta.generation"] = np.asarray(generation)
        with open(tmp, "wb") as stream:
            np.savez(stream, **arrays)
        os.replace(tmp, path)
        self.comm.barrier()  # every rank's slot is complete before the index names it
        if self.comm.rank == 0:
            index = {
                "format": FORMAT,
                "generation": generation,
                "slot": slot,
                "time": t,
                "ranks": self.comm.size,
                "restarts": self.restarts,
                "outputs": outputs,
                "scene": self.scene,
            }
            tmp_index = self.directory / (INDEX + ".tmp")
            tmp_index.write_text(json.dumps(index, indent=1) + "\n", encoding="utf-8")
            os.replace(tmp_index, self.directory / INDEX)
        self.comm.barrier()
        self.generation = generation
        self.written += 1
        self._schedule(t)


def load_checkpoint(run_dir: str | Path, comm: MPI.Comm = MPI.COMM_WORLD) -> Checkpoint:
    """The last complete checkpoint of the run in ``run_dir``; SceneError if there is none or
    it does not fit this run (another number of ranks, an unknown format)."""
    run_dir = Path(run_dir)
    index_path = run_dir / DIRECTORY / INDEX
    meta, error = None, None
    if comm.rank == 0:
        try:
            meta = json.loads(index_path.read_text(encoding="utf-8"))
        except FileNotFoundError:
            error = f"--restart: no checkpoint in {str(run_dir)!r} (no {DIRECTORY}/{INDEX})"
        except (OSError, ValueError) as exc:
            error = f"--restart: cannot read {str(index_path)!r} ({exc})"
        if meta is not None and meta.get("format") != FORMAT:
            found = meta.get("format")
            error = f"--restart: {str(index_path)!r} has format {found!r}, not {FORMAT}"
    meta, error = comm.bcast((meta, error), root=0)
    if error:
        raise SceneError(error)
    if meta["ranks"] != comm.size:
        raise SceneError(
            f"--restart: the checkpoint was written by {meta['ranks']} MPI ranks; restart "
            f"with the same number (mpirun -n {meta['ranks']}), not {comm.size}"
        )
    path = run_dir / DIRECTORY / f"state{meta['slot']}.rank{comm.rank}.npz"
    problem = None
    try:
        with np.load(path) as data:
            arrays = {name: data[name] for name in data.files}
        if int(arrays.pop("meta.generation")) != meta["generation"]:
            problem = f"{path.name} is not of generation {meta['generation']}"
    except (OSError, ValueError, KeyError) as exc:
        arrays, problem = {}, f"cannot read {path.name} ({exc})"
    problems = [p for p in comm.allgather(problem) if p]
    if problems:
        raise SceneError(f"--restart: damaged checkpoint in {str(run_dir)!r}: {problems[0]}")
    return Checkpoint(run_dir, meta, _unflatten(arrays))


def restart_overrides(overrides: list[str] | tuple[str, ...]) -> None:
    """SceneError unless every ``--set`` key of a restart is one of :data:`RESTART_KEYS`."""
    for text in overrides:
        key = text.split("=", 1)[0].strip()
        if not any(key == k or (k.endswith(".") and key.startswith(k)) for k in RESTART_KEYS):
            allowed = ", ".join(k + "*" if k.endswith(".") else k for k in RESTART_KEYS)
            raise SceneError(
                f"--set {key}: cannot change on --restart (the checkpoint's discrete problem "
                f"is fixed); allowed: {allowed}"
            )


# --------------------------------------------------------------------------------- outputs
def cut_probes(path: Path, rows: int) -> None:
    """Keep the header and the first ``rows`` rows of probes.csv (rows after the checkpoint,
    and a line cut by a kill, go)."""
    with open(path, "r+b") as stream:
        end = 0
        for _ in range(rows + 1):
            line = stream.readline()
            if not line.endswith(b"\n"):
                raise SceneError(
                    f"--restart: {str(path)!r} holds fewer than the checkpoint's {rows} rows"
                )
            end += len(line)
        stream.truncate(end)


ET.register_namespace("xi", "http://www.w3.org/2001/XInclude")


def cut_xdmf(path: Path, frames: int) -> None:
    """Keep the first ``frames`` time steps of every temporal collection of the XDMF file
    (written by rank 0 only; replaced atomically)."""
    tree = ET.parse(path)
    for collection in tree.getroot().iter("Grid"):
        if collection.get("GridType") != "Collection":
            continue
        steps = collection.findall("Grid")
        if len(steps) < frames:
            raise SceneError(
                f"--restart: {str(path)!r} holds {len(steps)} frames of "
                f"{collection.get('Name')!r}, fewer than the checkpoint's {frames}"
            )
        for step in steps[frames:]:
            collection.remove(step)
    tmp = path.with_name(path.name + ".tmp")
    tree.write(tmp, encoding="utf-8", xml_declaration=True)
    os.replace(tmp, path)


def cut_outputs(
    checkpoint: Checkpoint, probes: Path | None, xdmf: Path | None, probe_owner: bool, comm
) -> None:
    """Cut probes.csv (on the probe's owner) and the XDMF file (rank 0) back to the
    checkpoint; a problem on any rank is raised on every rank."""
    outputs = checkpoint.meta["outputs"]
    problem = None
    try:
        if probes is not None and probe_owner:
            cut_probes(probes, outputs["probe_rows"])
        if xdmf is not None and comm.rank == 0:
            if outputs["xdmf_frames"] is None:
                raise SceneError("--restart: the checkpointed run wrote no XDMF file")
            cut_xdmf(xdmf, outputs["xdmf_frames"])
    except SceneError as exc:
        problem = str(exc)
    except (OSError, ET.ParseError) as exc:
        problem = f"--restart: cannot continue the outputs in {str(checkpoint.run_dir)!r} ({exc})"
    problems = [p for p in comm.allgather(problem) if p]
    if problems:
        raise SceneError(problems[0])
