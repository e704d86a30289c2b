"""The output folder of a run: made and checked, claimed by a new run, and its summary.json.

A folder holds the outputs of one run at a time. A new ``run`` or ``static`` into a folder
first removes what an earlier run left there that it will not overwrite itself, so that no
stale file can be mistaken for its own: the earlier run's checkpoint (a restart would
otherwise continue it after the new outputs), its XDMF file and frames folder
(``solution.frames/``, cosserat_fem/output.py), and the HDF5 files and scratch XML of the
earlier single-file layout (``solution.h5``, ``solution-restart<n>.h5``,
``solution.xdmf-partial``). Only these names are removed; other files in the folder are left
alone. Then it writes summary.json with the
status "running" and a new run identity (:func:`new_run_id`) before any other output, which
the checkpoint and the XDMF file carry too (cosserat_fem/checkpoint.py).
"""

from __future__ import annotations

import json
import shutil
import uuid
from pathlib import Path

from mpi4py import MPI

from .errors import OutputError, SceneError
from .parallel import agree, from_root

PROBES, XDMF, SUMMARY = "probes.csv", "solution.xdmf", "summary.json"


def prepare_output_dir(path: Path, comm: MPI.Comm) -> Path:
    """Make ``path`` if needed and check that it can be written (collective)."""
    error = None
    if comm.rank == 0:
        try:
            path.mkdir(parents=True, exist_ok=True)
            probe = path / ".write-test"
            probe.write_text("")
            probe.unlink()
        except OSError as exc:
            error = f"output.directory: cannot write to {str(path)!r} ({exc.strerror or exc})"
    error = comm.bcast(error, root=0)
    if error:
        raise SceneError(error)
    return path


def new_run_id(comm: MPI.Comm) -> str:
    """A new identity, the same on every rank."""
    return from_root(comm, uuid.uuid4().hex if comm.rank == 0 else None)


def stale_outputs(folder: Path, writes_xdmf: bool) -> list[Path]:
    """The files of an earlier run in ``folder`` that a new run removes (whether or not it
    writes an XDMF file, ``writes_xdmf``), in the order they are removed: the checkpoint, the
    XDMF file (so that no XML names a removed file; a new XDMF series publishes its own), its
    frames folder, and the HDF5 files and scratch XML of the earlier single-file layout."""
    from .checkpoint import DIRECTORY
    from .output import frames_folder

    stem = Path(XDMF).stem
    stale = [folder / DIRECTORY, folder / XDMF, frames_folder(folder / XDMF), folder / f"{stem}.h5"]
    stale += sorted(folder.glob(f"{stem}-restart*.h5"))
    stale += sorted(folder.glob(f"{stem}*.xdmf-partial"))
    return [p for p in stale if p.exists() or p.is_symlink()]


def claim(folder: Path, comm: MPI.Comm, writes_xdmf: bool, summary: dict) -> None:
    """Make ``folder`` the new run's: remove the stale outputs of an earlier run (the
    checkpoint's index first, so that a kill half-way leaves nothing to restart from), then
    write ``summary`` (status "running", the run id) before any other output. Collective."""
    problem = None
    if comm.rank == 0:
        try:
            for path in stale_outputs(folder, writes_xdmf):
                if path.is_dir() and not path.is_symlink():
                    (path / "checkpoint.json").unlink(missing_ok=True)
                    shutil.rmtree(path)
                else:
                    path.unlink()
        except OSError as exc:
            problem = SceneError(
                f"output.directory: cannot remove the outputs of an earlier run in "
                f"{str(folder)!r} ({exc.strerror or exc})"
            )
    agree(comm, problem)
    write_summary(folder / SUMMARY, summary, comm)


def status_of(failure: BaseException | None) -> str:
    """summary.json's status of a run that ended with ``failure``: "completed" (none),
    "interrupted" (Ctrl-C), "stopped" (a StopError: an output, a limit; resumable) or
    "failed"."""
    from .errors import StopError

    if failure is None:
        return "completed"
    if isinstance(failure, KeyboardInterrupt):
        return "interrupted"
    return "stopped" if isinstance(failure, StopError) else "failed"


def write_summary(path: Path, data: dict, comm: MPI.Comm, strict: bool = True) -> None:
    """Write summary.json atomically on rank 0 (collective). A failure is an OutputError on
    every rank, or, with ``strict=False`` (the summary at the end of a run that already
    stopped with an error), ignored: the earlier summary stays."""
    problem = None
    if comm.rank == 0:
        tmp = path.with_suffix(".json.tmp")
        try:
            tmp.write_text(json.dumps(data, indent=2, sort_keys=False) + "\n", encoding="utf-8")
            tmp.replace(path)
        except OSError as exc:
            tmp.unlink(missing_ok=True)
            problem = OutputError(f"output: cannot write {str(path)!r} ({exc.strerror or exc})")
    if strict:
        agree(comm, problem)
