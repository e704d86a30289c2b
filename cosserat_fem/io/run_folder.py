"""The output folder of a run: made and checked, locked, claimed by a new run, and its
summary.json.

A folder holds the outputs of one run at a time, and has one writer at a time:

* **The lock** (cosserat_fem/io/folder_lock.py): one writer a folder, taken by
  :func:`prepare_output_dir` with ``lock``.
* **The claim.** A new ``run`` or ``static`` first removes what an earlier run left there that
  it will not overwrite itself, so that no stale file can be mistaken for its own: the earlier
  run's checkpoint (a restart would otherwise continue it after the new outputs), its XDMF
  file and frames, and the HDF5 files and scratch XML of the earlier single-file layout
  (``solution.h5``, ``solution-restart<n>.h5``, ``solution.xdmf-partial``). Only the
  project's own files go (:func:`stale_outputs`): in ``checkpoint/`` and ``solution.frames/``
  the names the project writes there (:data:`cosserat_fem.io.checkpoint.OWN_FILES`,
  :data:`cosserat_fem.io.xdmf.FRAME_NAME`), never a subfolder or a file of another name (a
  user's notes, another run nested inside); a folder left empty goes too. A link at one of
  these names is removed, never followed. Where something of the user's stands where the run
  must write (a file named ``checkpoint``, a folder named ``probes.csv``), the run is refused
  in one line before anything is removed (:func:`conflict`). Then it writes summary.json with
  the status "running" and a new run identity (:func:`new_run_id`) before any other output,
  which the checkpoint and the XDMF file carry too (cosserat_fem/io/checkpoint.py).
* **A restart** continues the outputs of the folder only if they are the checkpoint's run's
  and reach its checkpoint (:func:`check_outputs`, touching nothing), then cuts them back to
  it (:func:`cut_outputs`): cosserat_fem/io/checkpoint.py's docstring.

Every file of the folder is written as a new file or by an atomic rename, never through a
link, and no special file is opened (cosserat_fem/common/safe_files.py).
Tests: tests/test_run_folders.py, tests/test_claims.py.
"""

from __future__ import annotations

import json
import os
import uuid
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

from mpi4py import MPI

from cosserat_fem.common import safe_files
from cosserat_fem.common.errors import OutputError, SceneError
from cosserat_fem.common.parallel import agree, from_root
from cosserat_fem.io.checkpoint import DIRECTORY, INDEX, OWN_FILES, Checkpoint
from cosserat_fem.io.folder_lock import _HELD, FolderLock, held_lock, lock_key
from cosserat_fem.io.probes import PROBES, probe_prefix
from cosserat_fem.io.reading import decode, finite_number, json_kind, quoted, read_bytes
from cosserat_fem.io.xdmf import FRAME_NAME, XDMF, cut_xdmf, frames_folder, xdmf_problem

#: The run's summary: written when it starts (status "running"), replaced at its end.
SUMMARY = "summary.json"
#: Largest summary.json read [bytes] (a run's is ~4 kB).
MAX_SUMMARY_BYTES = 16 << 20


def prepare_output_dir(
    path: Path, comm: MPI.Comm, lock: str | None = None, run_id: str | None = None
) -> Path:
    """Make ``path`` if needed and check that it can be written (collective); with ``lock``
    (the kind of writer: "run", "static", "restart", "sweep", "modes", "stability"), also
    take the folder's lock (:class:`FolderLock`, run id ``run_id`` if known) for the enclosing
    :func:`holding_folders` call, or refuse in one line naming its holder."""
    held = _HELD.get()
    if lock is not None and held is None:
        raise RuntimeError("prepare_output_dir(lock=...) outside a holding_folders call")
    key = lock_key(lock or "run")  # --out if the command line gave it (folder_lock.named_by)
    problem: SceneError | None = None
    if comm.rank == 0:
        try:
            path.mkdir(parents=True, exist_ok=True)
            if lock is not None:
                assert held is not None  # refused above
                held.append(FolderLock.take(path, lock, run_id))
            else:
                probe = path / f".write-test-{uuid.uuid4().hex}"  # a new name: nothing followed
                os.close(safe_files.create(probe))
                probe.unlink()
        except SceneError as exc:
            problem = exc
        except OSError as exc:
            problem = SceneError(f"{key}: cannot write to {str(path)!r} ({exc.strerror or exc})")
    agree(comm, problem)
    return path


def new_run_id(comm: MPI.Comm) -> str:
    """A new identity, the same on every rank."""
    return from_root(comm, uuid.uuid4().hex if comm.rank == 0 else None)


def _earlier_layout(folder: Path) -> list[Path]:
    """The HDF5 files and scratch XML of the earlier single-file layout (and of a killed
    XDMF rewrite): ``solution.h5``, ``solution-restart<n>.h5``, ``solution*.xdmf-partial``."""
    stem = Path(XDMF).stem
    names = [folder / f"{stem}.h5", *sorted(folder.glob(f"{stem}-restart*.h5"))]
    names += sorted(folder.glob(f"{stem}*.xdmf-partial"))
    return [p for p in names if p.is_symlink() or (p.exists() and not p.is_dir())]


def stale_outputs(folder: Path) -> list[tuple[Path, object | None]]:
    """What a new run removes of an earlier run's outputs in ``folder``, in this order (module
    docstring): (path, None) for a file, (folder, pattern) for the files of a folder whose
    names the pattern matches (:func:`cosserat_fem.common.safe_files.remove_own_files`): the
    checkpoint (its index first), the XDMF file (so that no XML names a removed file; a new
    series publishes its own), its frames, the files of the earlier single-file layout."""
    stale: list[tuple[Path, object | None]] = [(folder / DIRECTORY, OWN_FILES)]
    if (folder / XDMF).is_symlink() or (folder / XDMF).exists():
        stale.append((folder / XDMF, None))
    stale.append((frames_folder(folder / XDMF), FRAME_NAME))
    return stale + [(p, None) for p in _earlier_layout(folder)]


def conflict(folder: Path, writes_xdmf: bool, writes_checkpoint: bool) -> str | None:
    """Where something that is not the project's stands where a new run in ``folder`` must
    write (a folder at a file's name, a file at a folder's, a folder among the checkpoint's
    or the frames' files), the first such, in words; else None."""
    files = [PROBES, SUMMARY, f"{SUMMARY}.tmp"]
    folders = []
    if writes_xdmf:
        files += [XDMF, f"{XDMF}-partial"]
        folders.append((frames_folder(folder / XDMF), FRAME_NAME, "XDMF frames"))
    if writes_checkpoint:
        folders.append((folder / DIRECTORY, OWN_FILES, "checkpoint"))
    for name in files:
        if (folder / name).is_dir() and not (folder / name).is_symlink():
            return f"{str(folder / name)!r} is a folder where the run writes its file {name}"
    for path, own, what in folders:
        if path.is_symlink() or not (path.exists() or path.is_symlink()):
            continue
        if not path.is_dir():
            kind = safe_files.kind(os.lstat(path).st_mode)
            return f"{str(path)!r} is {kind} where the run makes its {what} folder"
        for entry in os.scandir(path):
            if entry.is_dir(follow_symlinks=False) and (
                own.fullmatch(entry.name) or entry.name == INDEX
            ):
                return f"{str(Path(entry.path))!r} is a folder where the run writes its {what}"
    return None


def claim(
    folder: Path, comm: MPI.Comm, writes_xdmf: bool, summary: dict, writes_checkpoint: bool = False
) -> None:
    """Make ``folder`` the new run's (module docstring): refuse, touching nothing, if
    something of the user's stands where the run writes (:func:`conflict`); else remove the
    stale outputs of an earlier run (:func:`stale_outputs`; the checkpoint's index first, so
    that a kill half-way leaves nothing to restart from), then write ``summary`` (status
    "running", the run id) before any other output. Collective."""
    problem = None
    if comm.rank == 0:
        lock = held_lock(folder)
        if lock is not None:
            lock.note(summary["run_id"])
        try:
            found = conflict(folder, writes_xdmf, writes_checkpoint)
            if found:
                problem = SceneError(
                    f"output.directory: {found}; it is not the run's to remove: move it, or "
                    "give another --out"
                )
            else:
                for path, own in stale_outputs(folder):
                    if own is None:
                        safe_files.remove_name(path)
                    else:
                        safe_files.remove_own_files(path, own, first=INDEX)
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
    from cosserat_fem.common.errors import StopError

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
        try:
            safe_files.replace(path, json.dumps(data, indent=2, sort_keys=False) + "\n")
        except OSError as exc:
            problem = OutputError(f"output: cannot write {str(path)!r} ({exc.strerror or exc})")
    if strict:
        agree(comm, problem)


def read_summary(path: str | Path) -> dict:
    """summary.json as a dict, with the fields that plot and render use checked: ``kind`` and
    ``scene.title`` strings, ``scene.rod.length`` a positive number, where present."""
    path = Path(path)
    text = decode(path, read_bytes(path, MAX_SUMMARY_BYTES))
    try:
        summary = json.loads(text)
    except (ValueError, RecursionError) as exc:  # RecursionError: [[[[... nested too deep
        message = str(exc) if isinstance(exc, ValueError) else "nested too deep"
        raise SceneError(f"{quoted(path)}: not JSON ({message})") from None
    if not isinstance(summary, dict):
        raise SceneError(
            f"{quoted(path)}: not a run's summary (a JSON object) but {json_kind(summary)}"
        )

    def bad(key: str, expected: str, value: object) -> SceneError:
        return SceneError(f"{quoted(path)}: {key} must be {expected}, got {json_kind(value)}")

    kind = summary.get("kind")
    if kind is not None and not isinstance(kind, str):
        raise bad("kind", "a string", kind)
    scene = summary.get("scene")
    if scene is None:
        return summary
    if not isinstance(scene, dict):
        raise bad("scene", "an object", scene)
    title = scene.get("title")
    if title is not None and not isinstance(title, str):
        raise bad("scene.title", "a string", title)
    rod = scene.get("rod")
    if rod is not None and not isinstance(rod, dict):
        raise bad("scene.rod", "an object", rod)
    length = (rod or {}).get("length")
    if length is not None:
        number = finite_number(length)
        if number is None or number <= 0:
            shown = json_kind(length)
            if not isinstance(length, bool) and isinstance(length, int | float):
                shown = repr(length) if len(repr(length)) <= 20 else repr(length)[:17] + "..."
            raise SceneError(
                f"{quoted(path)}: scene.rod.length must be a positive number, got {shown}"
            )
    return summary


# --- a restart: the outputs it continues ---------------------------------------------------


@dataclass
class RestartPlan:
    """What :func:`check_outputs` found (on rank 0): where probes.csv is cut (bytes) and how
    many XDMF frames are kept."""

    probes: Path | None
    probe_bytes: int | None
    xdmf: Path | None
    frames: int | None
    restart_number: int


def check_outputs(
    checkpoint: Checkpoint, probes: Path | None, xdmf: Path | None, comm: MPI.Comm
) -> RestartPlan:
    """Check, touching nothing, that the outputs in the checkpoint's folder are its run's and
    reach it (module docstring), on rank 0; SceneError on every rank otherwise (collective).
    The folder is shared by the ranks, as the XDMF file already requires."""
    outputs = checkpoint.meta["outputs"]
    run_dir = checkpoint.run_dir
    problem, offset = None, None
    if comm.rank == 0:
        try:
            problem = _summary_problem(run_dir / SUMMARY, checkpoint.run_id)
            problem = problem or _linked_folder(run_dir, xdmf)
            if problem is None and xdmf is not None:
                if outputs.get("xdmf_frames") is None:
                    problem = "the checkpointed run wrote no XDMF file"
                else:
                    problem = xdmf_problem(xdmf, int(outputs["xdmf_frames"]), checkpoint.run_id)
            if problem is None and probes is not None:
                offset, digest = probe_prefix(probes, int(outputs["probe_rows"]))
                if digest.hexdigest() != outputs.get("probes_sha256"):
                    problem = (
                        f"{str(probes)!r} differs from the checkpointed run's rows (written by "
                        "another run, or edited)"
                    )
        except SceneError as exc:
            problem = str(exc).removeprefix("--restart: ")
        except (OSError, ValueError, ET.ParseError) as exc:
            problem = f"cannot read the outputs in {str(run_dir)!r} ({exc})"
    agree(comm, SceneError(f"--restart: {problem}") if problem else None)
    frames = outputs.get("xdmf_frames") if xdmf is not None else None
    return RestartPlan(probes, offset, xdmf, frames, checkpoint.restart_number)


def _linked_folder(run_dir: Path, xdmf: Path | None) -> str | None:
    """Why the restart would write into a folder outside ``run_dir``: its checkpoint folder or
    the XDMF file's frames folder is a link to one (a file that is a link is replaced, never
    written through; a folder's files cannot be)."""
    for folder in [run_dir / DIRECTORY] + ([frames_folder(xdmf)] if xdmf is not None else []):
        if folder.is_symlink():
            return (
                f"{str(folder)!r} is a link to a folder elsewhere, which the restart would "
                "write into; copy the run's folder with its files (cp -a), then restart the copy"
            )
    return None


def _summary_problem(path: Path, run_id: str) -> str | None:
    """Why summary.json does not show the checkpoint's run (written when the run started)."""
    try:
        summary = json.loads(safe_files.read_text(path))
    except FileNotFoundError:
        summary = None
    if not isinstance(summary, dict) or summary.get("run_id") != run_id:
        return (
            f"the outputs in {str(path.parent)!r} are not the checkpoint's run's (the run id "
            f"of {path.name} differs): another run was written into the folder after it"
        )
    return None


def cut_outputs(plan: RestartPlan, comm: MPI.Comm) -> None:
    """Cut the outputs back to the checkpoint as ``plan`` (from :func:`check_outputs`) says,
    on rank 0: probes.csv, the XDMF file, then (once the XML no longer names them) the frame
    files after the checkpoint's frames and the scratch XML of a killed frame in its frames
    folder, and the HDF5 files of later restarts of the earlier single-file layout (which
    hold frames after the checkpoint only: a restart killed before its first checkpoint left
    them). An OutputError on every rank if a file cannot be changed (collective)."""
    problem = None
    if comm.rank == 0:
        try:
            if plan.probes is not None:  # a link: cut as the folder's own copy
                safe_files.own_copy(plan.probes, plan.probe_bytes)
            if plan.xdmf is not None:
                assert plan.frames is not None  # check_outputs sets both or neither
                cut_xdmf(plan.xdmf, plan.frames)
                folder = frames_folder(plan.xdmf)
                if folder.is_dir():
                    for old in folder.iterdir():
                        later = old.suffix == ".h5" and old.stem.isdigit()
                        if (later and int(old.stem) >= plan.frames) or (
                            old.suffix == ".xdmf-partial"
                        ):
                            old.unlink()
                stem = plan.xdmf.stem
                for old in plan.xdmf.parent.glob(f"{stem}-restart*.h5"):
                    number = old.stem.removeprefix(f"{stem}-restart")
                    if number.isdigit() and int(number) >= plan.restart_number:
                        old.unlink()
        except (OSError, ET.ParseError) as exc:
            problem = OutputError(
                f"--restart: cannot cut the outputs back to the checkpoint ({exc})"
            )
    agree(comm, problem)
