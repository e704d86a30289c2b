"""The reduced model's commands (issue 28, "Use"; docs/rom.md §11): a basis built from full
runs of one scene, several, or chosen members of a sweep (:func:`build`), a reduced run that
writes a full run's outputs with the basis's provenance in summary.json (:func:`run`), and the
validation of reduced runs against full ones (:func:`validate`). ``cosserat-fem rom build|run|
validate`` (cosserat_fem/cli.py) and ``cf.rom.build|run|validate`` are these functions.

**Training on several runs.** One :class:`~cosserat_fem.rom.basis.SnapshotCollector` observes
every training run (docs/rom.md §1): the snapshots of all of them, u_i = U(t_i) − U_ref, share
the reference U_ref, the rest state the first run starts from; a run that starts elsewhere is
refused in one line naming it. Each training run is a run as ``cosserat-fem run`` makes it, on
every MPI rank (the mesh distributed), its outputs kept in a folder if asked.

**A reduced run** is ``run_scene`` with the reduced solver (cosserat_fem/rom/galerkin.py
``solver_factory``): probes.csv, solution.xdmf, checkpoints and summary.json as a full run
writes them (U is a full vector U_ref + V q at every output), and ``summary["rom"]`` holds
the model ("reduced"), the basis file, its SHA-256, its modes, energy left out and
provenance (without the scene's text), written when the run starts (:class:`RomSummary`), so
that a run stopped early says it is reduced. A reduced run's checkpoint holds the full U:
``rom run --restart DIR --basis FILE`` continues it reduced on the same basis (another is
refused), and ``run --restart DIR`` (the full model) refuses it (cosserat_fem/api.py).

**Validation.** Each target (a scene, or chosen members of a sweep) run in full and reduced,
the relative L2 error of the free end's (x, y, z) over the output times (docs/rom.md §7,
basis.relative_l2) beside the reduced run's error indicator ``summary["rom"]["indicator"]``
["max"] and ``summary["rom"]["outside_training"]`` where the reduced solver reports them
("n/a" otherwise): validation.csv and a table.
"""

from __future__ import annotations

import csv
import hashlib
import io
import json
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from cosserat_fem.common import safe_files
from cosserat_fem.common.errors import SceneError
from cosserat_fem.rom.indicator import DEFAULT as DEFAULT_INDICATOR
from cosserat_fem.rom.indicator import ErrorIndicator, IndicatorSettings, load_values
from cosserat_fem.scene.build import Scene
from cosserat_fem.timestepping.events import Observer

#: The table of :func:`validate` in its folder.
VALIDATION = "validation.csv"
VALIDATION_COLUMNS = (
    "target",
    "status",
    "modes",
    "energy_left_out",
    "error",
    "indicator",
    "outside_training",
    "full_steps",
    "reduced_steps",
)
#: The rows of probes.csv compared: the free end's x, y, z [m] (columns 1-3).
POSITION = slice(1, 4)


# --- choosing members -------------------------------------------------------------------------


def parse_members(text: str | Sequence[int] | None, count: int, option: str = "--members"):
    """The members chosen by ``text``: "0,10,20", a range "start:stop[:step]" (Python's slice,
    stop excluded; "::20" every 20th), "random:N" (N members drawn without replacement by
    Python's random.Random(0): the same on every rank and run, sorted), or a list of whole
    numbers; None: every member. A SceneError naming ``option`` if one is not a member of
    the ``count``."""
    if text is None:
        return list(range(count))
    if isinstance(text, str) and text.strip().startswith("random:"):
        import random

        try:
            n = int(text.strip().removeprefix("random:"))
        except ValueError:
            n = -1
        if not 1 <= n <= count:
            raise SceneError(
                f"{option}: random:N draws N of the sweep's {count} members, got {text!r}"
            )
        return sorted(random.Random(0).sample(range(count), n))
    if isinstance(text, str):
        chosen: list[int] = []
        try:
            for part in text.split(","):
                part = part.strip()
                if ":" in part:
                    bounds = [int(b) if b.strip() else None for b in part.split(":")]
                    if len(bounds) > 3 or bounds[2:] == [0]:
                        raise ValueError(part)
                    chosen += list(range(count))[slice(*bounds)]
                else:
                    chosen.append(int(part))
        except ValueError:
            raise SceneError(
                f"{option}: member numbers '0,10,20' or a range 'start:stop:step', got {text!r}"
            ) from None
    else:
        chosen = list(text)
    for m in chosen:
        if isinstance(m, bool) or not isinstance(m, int | np.integer) or not 0 <= m < count:
            raise SceneError(
                f"{option}: member {m!r} out of range (the sweep has members 0 to {count - 1})"
            )
    if not chosen:
        raise SceneError(f"{option}: chooses no member of the sweep's {count}")
    return list(dict.fromkeys(int(m) for m in chosen))


@dataclass
class Target:
    """A full run to train on or to validate: its name (a member's folder name, or "scene"),
    its scene and a maker of the observers each of its runs needs (a forced member's
    response, which ends it once settled: one for each run)."""

    name: str
    scene: Scene
    observers: Callable[[], list] = list


def sweep_targets(spec, members: Sequence[int]) -> list[Target]:
    """The runs of the chosen ``members`` of a sweep from rest, as the sweep runs a member
    without a predecessor: a forced member ([sweep.response]) over its forced span with its
    response observer, which ends the run once the response has settled."""
    from cosserat_fem.studies.sweep_run import _forced

    targets = []
    for index in members:
        member = spec.members[index]
        if spec.response is not None:
            scene = _forced(spec, member, None)[0]

            def fresh(member=member) -> list:
                return [_forced(spec, member, None)[1]]

            targets.append(Target(member.name, scene, fresh))
        else:
            targets.append(Target(member.name, spec.scene(member)))
    return targets


def chosen_targets(scenes, sweep, members) -> list[Target]:
    """The runs of ``scenes`` (a Scene or several: "scene", or "scene0", "scene1", ...) and of
    the ``members`` of ``sweep`` (:func:`parse_members`, :func:`sweep_targets`); --members
    without a sweep refused."""
    if not isinstance(scenes, list | tuple):
        scenes = [scenes]
    targets = [
        Target("scene" if len(scenes) == 1 else f"scene{i}", s) for i, s in enumerate(scenes)
    ]
    if sweep is not None:
        targets += sweep_targets(sweep, parse_members(members, len(sweep.members)))
    elif members is not None:
        raise SceneError("--members: chooses members of a sweep; give --sweep FILE")
    return targets


# --- build ------------------------------------------------------------------------------------


def _check_choice(tolerance, modes) -> None:
    if (tolerance is None) == (modes is None):
        raise SceneError("--tolerance, --modes: give one (the energy left out, or the modes)")
    if modes is not None and (isinstance(modes, bool) or not isinstance(modes, int) or modes < 1):
        raise SceneError(f"--modes: must be a whole number >= 1, got {modes!r}")
    if tolerance is not None and (
        isinstance(tolerance, bool)
        or not isinstance(tolerance, int | float)
        or not 0.0 <= tolerance < 1.0
    ):
        raise SceneError(f"--tolerance: must be a number in [0, 1), got {tolerance!r}")


def _check_ecsw(ecsw, where: str, comm) -> None:
    """ECSW's tolerance, a number in (0, 1), and a serial training (docs/rom.md §9), checked
    before any run: one line naming ``where``."""
    if ecsw is None:
        return
    if isinstance(ecsw, bool) or not isinstance(ecsw, int | float) or not 0.0 < ecsw < 1.0:
        raise SceneError(f"{where}: must be a number in (0, 1), got {ecsw!r}")
    if comm.size > 1:
        raise SceneError(
            f"{where}: hyper-reduction is trained serially (docs/rom.md §9); run without mpirun"
        )


def train_targets(
    targets: Sequence[Target],
    *,
    tolerance: float | None = None,
    modes: int | None = None,
    every: int = 1,
    keep: str | Path | None = None,
    comm=None,
):
    """The POD basis of full runs of ``targets`` (module docstring, "Training"): one
    SnapshotCollector over all of them, every ``every``-th output a snapshot, the modes
    whose energy left out is at most ``tolerance`` or the first ``modes``; with ``keep``,
    each run's outputs in keep/<name>. Returns (the Basis, the last run's model).
    Collective."""
    from mpi4py import MPI

    from cosserat_fem.analysis.simulation import run_scene
    from cosserat_fem.rom import basis as rb

    _check_choice(tolerance, modes)
    if not targets:
        raise SceneError("rom build: no run to train on")
    collector = rb.SnapshotCollector(every)
    comm = MPI.COMM_WORLD if comm is None else comm
    model, reached = None, []
    for target in targets:
        out = None if keep is None else Path(keep) / target.name
        try:
            result = run_scene(
                target.scene,
                out,
                comm=comm,
                observers=[collector, *target.observers()],
                write_outputs=out is not None,
            )
        except SceneError as exc:
            raise SceneError(f"rom build: training run {target.name}: {exc}") from None
        model = result.model
        reached.append(result.time_reached)
    scenes = [t.scene for t in targets]
    provenance = {
        **rb.scene_provenance(scenes[0]),
        "runs": [
            {
                "name": t.name,
                "scene_sha256": getattr(t.scene, "source_sha256", None),
                "title": getattr(t.scene, "title", None),
                "time_s": [t.scene.time.start, t.scene.time.end],
                "time_reached_s": end,  # a forced member ends once settled
                "step_s": t.scene.time.step,
                "loads": t.scene.to_dict().get("loads"),
                "load_values": load_values(t.scene),  # the out-of-training flag's
            }
            for t, end in zip(targets, reached, strict=True)
        ],
        "every": every,
    }
    basis = rb.pod_basis(model, collector, 0.0 if tolerance is None else tolerance, provenance)
    if modes is not None:
        if modes > basis.modes:
            raise SceneError(
                f"--modes: the snapshots give at most {basis.modes} modes, got {modes}"
            )
        basis = basis.truncated(modes)
        basis.provenance["tolerance"] = None
    return basis, model


def build(
    scenes=(),
    out: str | Path | None = None,
    *,
    sweep=None,
    members: str | Sequence[int] | None = None,
    tolerance: float | None = None,
    modes: int | None = None,
    every: int = 1,
    keep: str | Path | None = None,
    ecsw: float | None = None,
):
    """A reduced basis from full runs of ``scenes`` (a Scene or several) and/or of the
    ``members`` of ``sweep`` (a SweepSpec of cf.load_sweep; members as :func:`parse_members`
    reads them), with ``tolerance`` (energy left out, docs/rom.md (3)) or ``modes``, a
    snapshot every ``every`` outputs; with ``ecsw`` (a tolerance in (0, 1)), hyper-reduced:
    ECSW's elements and weights from second full runs of the same targets (docs/rom.md §9;
    serial only); written to ``out``.npz and ``out``.json if given (basis.write_basis); the
    training runs' outputs in ``keep``/<name> if given. Returns the
    :class:`~cosserat_fem.rom.basis.Basis`. Collective."""
    from mpi4py import MPI

    from cosserat_fem.rom import basis as rb

    _check_choice(tolerance, modes)
    _check_ecsw(ecsw, "--ecsw", MPI.COMM_WORLD)
    targets = chosen_targets(scenes, sweep, members)
    if out is not None:  # before the training runs; rank 0 writes it (basis.write_basis)
        from mpi4py import MPI

        from cosserat_fem.io.run_folder import prepare_output_dir

        try:
            prepare_output_dir(Path(out).absolute().parent, MPI.COMM_WORLD)
        except SceneError as exc:
            raise SceneError(f"--out: {str(exc).partition(': ')[2]}") from None
    basis, model = train_targets(targets, tolerance=tolerance, modes=modes, every=every, keep=keep)
    if ecsw is not None:
        from cosserat_fem.rom import hyper

        basis = hyper.ecsw(targets, basis, ecsw)
    if out is not None:
        rb.write_basis(basis, model, out)
    return basis


# --- a reduced run ----------------------------------------------------------------------------


def basis_digest(path: str | Path) -> str | None:
    """SHA-256 of the basis file's .npz (None if it cannot be read)."""
    from cosserat_fem.rom.basis import basis_paths

    try:
        return hashlib.sha256(safe_files.read_regular(basis_paths(path)[0])).hexdigest()
    except OSError:
        return None


def basis_identity(basis, comm) -> str:
    """The digest of ``basis``'s arrays over the ranks (Basis.digest: this rank's rows): the
    one rank's, or the SHA-256 of the ranks' digests in rank order (a restart runs on as many
    ranks, the same partition). Collective."""
    own = basis.digest
    if comm.size == 1:
        return own
    return hashlib.sha256("".join(comm.allgather(own)).encode()).hexdigest()


def rom_record(basis, path: str | Path | None, comm=None) -> dict:
    """summary.json's ``rom`` of a reduced run on ``basis`` read from ``path``: the model, the
    file and its SHA-256, the digest of the basis's arrays (:func:`basis_identity`; a basis in
    memory has no file), the modes and energy left out, the provenance (without the scene's
    text)."""
    from mpi4py import MPI

    provenance = {k: v for k, v in basis.provenance.items() if k != "scene_text"}
    provenance.pop("snapshot_times_s", None)
    return {
        "model": "reduced",
        "basis": {
            "file": None if path is None else str(Path(path).resolve()),
            "sha256": None if path is None else basis_digest(path),
            "digest": basis_identity(basis, MPI.COMM_WORLD if comm is None else comm),
            "modes": basis.modes,
            "energy_left_out": basis.energy_left_out(),
            "provenance": provenance,
        },
    }


class RomSummary(Observer):
    """Puts ``rom`` (:func:`rom_record`) into the run's summary when the run starts, and
    writes summary.json again then if the run has a folder (the running run's file says it is
    reduced). Merged into what the reduced solver may have put there (its indicator)."""

    def __init__(self, path: str | Path | None):
        self.path = path

    def started(self, loop) -> None:
        from cosserat_fem.analysis.observers import FolderStart, RunSummary
        from cosserat_fem.io.run_folder import SUMMARY, write_summary

        record = rom_record(loop.solver.basis, self.path, loop.model.msh.comm)
        for observer in loop.events.observers:
            if isinstance(observer, RunSummary):
                observer.summary.setdefault("rom", {}).update(record)
        for observer in loop.events.observers:
            if isinstance(observer, FolderStart) and observer.claimed:
                comm = loop.model.msh.comm
                write_summary(observer.folder / SUMMARY, observer.summary, comm)


def recorded_basis(folder: str | Path) -> dict | None:
    """The ``rom`` of the run in ``folder`` (its summary.json), or None: a full run, or none
    readable."""
    try:
        summary = json.loads(safe_files.read_text(Path(folder) / "summary.json"))
    except (OSError, ValueError):
        return None
    rom = summary.get("rom") if isinstance(summary, dict) else None
    return rom if isinstance(rom, dict) and rom.get("model") == "reduced" else None


def check_basis_file(basis, scene=None) -> Path | None:
    """The .npz of a basis file's path (None for a Basis in memory); SceneError naming
    --basis if there is no such file, and, given the ``scene`` it is to run, one naming the
    file if its .json says it was made for other elements, degree or supports, or for one
    rank (ECSW's sampling) under mpirun: what the scene alone decides, checked before any
    folder is made or run is done (basis.read_basis checks the whole space at the run)."""
    from mpi4py import MPI

    from cosserat_fem.rom.basis import Basis, basis_paths, supports_of

    if isinstance(basis, Basis):
        return None
    path, meta = basis_paths(basis)
    if not path.is_file():
        raise SceneError(f"--basis: no basis file {str(path)!r}")
    if scene is None:
        return path
    try:
        document = json.loads(safe_files.read_text(meta))
        space = document["space"]
        provenance = document.get("provenance", {})
    except (OSError, ValueError, KeyError, TypeError):
        return path  # read_basis says why, in one line, at the run
    expected = {
        "elements": scene.discretisation.elements,
        "degree": scene.discretisation.degree,
        "supports": supports_of(scene),
    }
    for name, value in expected.items():
        if name in space and space[name] != value:
            raise SceneError(
                f"basis {str(path)!r}: made for {name} = {space[name]!r}, the scene has "
                f"{value!r} (rebuild the basis for this scene)"
            )
    if isinstance(provenance, dict) and "ecsw" in provenance and MPI.COMM_WORLD.size > 1:
        raise SceneError(
            f"basis {str(path)!r}: hyper-reduced (sampled elements), which runs serially only"
        )
    return path


def run(
    scene,
    basis,
    out=None,
    *,
    observers: Sequence = (),
    record: bool = True,
    initial_state: np.ndarray | None = None,
    restart=None,
    progress=None,
    comm=None,
    indicator: IndicatorSettings | None = DEFAULT_INDICATOR,
    hyper: bool | None = None,
):
    """A reduced run of ``scene`` on ``basis`` (a Basis or a basis file): cf.run's
    RunResult, the time loop, integrator, observers and outputs (with ``out``: probes.csv,
    XDMF, checkpoints, summary.json) the full run's, ``summary["rom"]`` the basis's record
    (module docstring). ``restart``: the checkpoint of a reduced run (cf.resume), continued
    on the same basis file (another is refused); ``initial_state`` as cf.run's (its part
    off the basis is dropped at the first solve). ``indicator``: the error indicator's settings
    (cosserat_fem/rom/indicator.py; its estimate and the out-of-training flags in
    summary["rom"]), None: none. ``hyper``: the hyper-reduced solve on the basis's sampled
    elements (None: if it has them; False: the Galerkin solve with every element;
    cosserat_fem/rom/hyper.py)."""
    from mpi4py import MPI

    from cosserat_fem.analysis.simulation import run_scene
    from cosserat_fem.common.errors import out_folder
    from cosserat_fem.rom import galerkin

    if indicator is not None and not isinstance(indicator, IndicatorSettings):
        raise SceneError(
            f"indicator: must be IndicatorSettings or None, got {type(indicator).__name__}"
        )
    path = check_basis_file(basis, scene if comm is None else None)
    held = None
    if restart is not None:
        held = recorded_basis(restart.run_dir)
        if held is None:
            raise SceneError(
                f"--restart: {str(restart.run_dir)!r} is not a reduced run (continue it with "
                "cosserat-fem run --restart)"
            )
        kept = held["basis"]
        if path is not None:  # a file: its SHA-256
            same = basis_digest(path) == kept.get("sha256")
        else:  # a Basis in memory: its arrays' digest (a run of before the digest: none)
            same = "digest" in kept and kept["digest"] == basis_identity(
                basis, MPI.COMM_WORLD if comm is None else comm
            )
        if not same:
            name = kept.get("file") or f"a basis in memory, digest {kept.get('digest')}"
            raise SceneError(
                f"--basis: not the basis the run in {str(restart.run_dir)!r} was started with "
                f"({name})"
            )
    state = None if restart is None else restart.parts.get(ErrorIndicator.PART)
    own = [ErrorIndicator(indicator, held, state)] if indicator is not None else []
    out = out_folder(out)
    return run_scene(
        scene,
        out_dir=out,
        comm=MPI.COMM_WORLD if comm is None else comm,
        observers=[RomSummary(path), *observers, *own],
        write_outputs=out is not None or restart is not None,
        record=record,
        initial_state=initial_state,
        restart=restart,
        progress=progress,
        solver_factory=galerkin.solver_factory(basis, hyper),
    )


# --- validation -------------------------------------------------------------------------------


def indicator_of(summary: dict) -> tuple[float | None, list | None]:
    """The reduced run's indicator (``summary["rom"]["indicator"]["max"]``) and the ways it
    went outside its training (``summary["rom"]["outside_training"]``), None where absent."""
    rom = summary.get("rom") if isinstance(summary, dict) else None
    rom = rom if isinstance(rom, dict) else {}
    indicator = rom.get("indicator")
    value = indicator.get("max") if isinstance(indicator, dict) else None
    outside = rom.get("outside_training")
    return (
        float(value) if isinstance(value, int | float) else None,
        outside if isinstance(outside, list) else None,
    )


@dataclass
class Validation:
    """What :func:`validate` found: ``rows`` (one per target, :data:`VALIDATION_COLUMNS`), the
    table's path (None without a folder)."""

    rows: list[dict]
    table: Path | None


def _cell(value) -> str:
    if value is None:
        return "n/a"
    if isinstance(value, float):
        return repr(value)
    if isinstance(value, list):
        return "; ".join(str(v) for v in value) if value else "none"
    return str(value)


def validate(
    basis,
    scenes=(),
    out: str | Path | None = None,
    *,
    sweep=None,
    members: str | Sequence[int] | None = None,
) -> Validation:
    """Each target (``scenes``; the ``members`` of ``sweep``) run in full and reduced on
    ``basis`` (a basis file), into out/full/<name> and out/reduced/<name> if ``out`` is
    given: per target the relative L2 error of the free end's (x, y, z) (basis.relative_l2,
    over the output times both runs reached: a forced member ends once settled) and the
    reduced run's indicator and what it found outside its training (module docstring);
    validation.csv in ``out``, written again after each target (a stop keeps the rows made)
    with the rows of other targets an earlier validation left there. A target whose full or
    reduced run fails (a SolverError: the reduced run's refusal at the chart's move, a
    diverged solve) is a row with that line in ``status`` and no error; a stop (wall time,
    Ctrl-C) ends the validation after the table is written. Collective."""
    from mpi4py import MPI

    from cosserat_fem.analysis.simulation import run_scene
    from cosserat_fem.common.errors import SolverError, out_folder
    from cosserat_fem.rom.basis import relative_l2

    targets = chosen_targets(scenes, sweep, members)
    if not targets:
        raise SceneError("rom validate: give a SCENE or --sweep FILE")
    for target in targets:  # every target's basis refusal before any run or folder
        check_basis_file(basis, target.scene)
    out = out_folder(out)
    comm = MPI.COMM_WORLD
    table = None if out is None else out / VALIDATION
    earlier = [] if table is None else _earlier_rows(table, comm)
    rows: list[dict] = []
    for target in targets:
        row: dict = {"target": target.name, "status": "completed"}
        try:
            full = run_scene(
                target.scene,
                None if out is None else out / "full" / target.name,
                observers=target.observers(),
                write_outputs=out is not None,
                record=True,
            )
            reduced = run(
                target.scene,
                basis,
                None if out is None else out / "reduced" / target.name,
                observers=target.observers(),
            )
        except SolverError as exc:  # the target's row says why; the others go on
            row["status"] = str(exc).replace("\n", " ")
            rows.append(row)
            _write_validation(table, earlier, rows, comm)
            continue
        assert full.probes is not None and reduced.probes is not None, "recorded"
        indicator, outside = indicator_of(reduced.summary)
        n = min(len(full.probes), len(reduced.probes))  # a forced run ends once settled
        rom = reduced.summary["rom"]["basis"]
        row.update(
            {
                "modes": rom["modes"],
                "energy_left_out": rom["energy_left_out"],
                "error": relative_l2(reduced.probes[:n, POSITION], full.probes[:n, POSITION]),
                "indicator": indicator,
                "outside_training": outside,
                "full_steps": full.summary["steps"],
                "reduced_steps": reduced.summary["steps"],
            }
        )
        rows.append(row)
        _write_validation(table, earlier, rows, comm)
    return Validation(rows, table)


def _earlier_rows(table: Path, comm) -> list[dict]:
    """The rows of a validation.csv already in the folder (an earlier validation's), as
    strings; none if it cannot be read. Rank 0's, every rank's."""
    rows: list[dict] = []
    if comm.rank == 0:
        try:
            text = safe_files.read_text(table)
            rows = [dict(r) for r in csv.DictReader(io.StringIO(text))]
        except (OSError, ValueError):
            rows = []
    return comm.bcast(rows, root=0) if comm.size > 1 else rows


def _write_validation(table: Path | None, earlier: list[dict], rows: list[dict], comm) -> None:
    """validation.csv: the earlier rows of targets not validated now, then this validation's
    (:data:`VALIDATION_COLUMNS`); replaced whole by rank 0 (a FIFO there blocks no one), a
    failure raised on every rank alike."""
    if table is None:
        return
    from cosserat_fem.common.errors import OutputError
    from cosserat_fem.common.parallel import agree

    problem = None
    if comm.rank == 0:
        now = {row["target"] for row in rows}
        text = io.StringIO(newline="")
        writer = csv.writer(text)
        writer.writerow(VALIDATION_COLUMNS)
        for old in earlier:
            if old.get("target") not in now:
                writer.writerow([old.get(c, "n/a") for c in VALIDATION_COLUMNS])
        for row in rows:
            writer.writerow([_cell(row.get(c)) for c in VALIDATION_COLUMNS])
        try:
            safe_files.replace(table, text.getvalue().encode("utf-8"))
        except OSError as exc:
            problem = OutputError(f"rom validate: cannot write {str(table)!r} ({exc})")
    agree(comm, problem)  # every rank raises alike: none waits for rank 0


def validation_lines(result: Validation) -> list[str]:
    """The table the command prints: per target its modes, energy left out, error, indicator
    and what was outside the training."""
    lines = [
        f"{'target':<10} {'modes':>5} {'energy left':>12} {'error':>12} {'indicator':>12}  "
        "outside training"
    ]
    for row in result.rows:
        if row.get("status", "completed") != "completed":
            lines.append(f"{row['target']:<10} failed: {row['status']}")
            continue
        indicator = "n/a" if row["indicator"] is None else f"{row['indicator']:.3e}"
        lines.append(
            f"{row['target']:<10} {row['modes']:5d} {row['energy_left_out']:12.3e} "
            f"{row['error']:12.3e} {indicator:>12}  {_cell(row['outside_training'])}"
        )
    return lines
