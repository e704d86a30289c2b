"""A run: a scene in; probes, XDMF, checkpoints and a summary out (and arrays in memory).

:func:`run` composes a run from its parts: the model (cosserat_fem/rod/model.py), an integrator
and a Newton solver, the time loop (cosserat_fem/timestepping/loop.py), which is a source of events,
and the observers of those events that the run needs (cosserat_fem/analysis/observers.py): the run
folder and its summary, probes, XDMF frames, checkpoints, the progress bar, the wall-time limit,
in-memory records and the caller's own. Before any work the scene's cost is checked against
its limits (cosserat_fem/analysis/budget.py) and, on a restart, the folder's outputs against the
checkpoint: nothing is touched unless the run can go on.

Time runs in τ = ω0 t (47) inside the integrator; everything written is in SI units.
Trouble stops the run with a :class:`~cosserat_fem.common.errors.SolverError` (numerical),
:class:`~cosserat_fem.common.errors.SceneError` (a load that is not finite) or
:class:`~cosserat_fem.common.errors.StopError` (an output that cannot be written, a limit), naming
the time, the place and the reason; the outputs written so far stay readable, a checkpoint
of the last accepted state is kept where a restart can continue, and summary.json records it.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from mpi4py import MPI

from cosserat_fem.analysis import budget
from cosserat_fem.analysis.observers import StandardObservers, summary_start
from cosserat_fem.analysis.restart import check_restart_scene
from cosserat_fem.common.errors import CosseratError, SceneError
from cosserat_fem.common.parallel import agree, ranks_on_node
from cosserat_fem.io.checkpoint import Checkpoint
from cosserat_fem.io.folder_lock import folders_held
from cosserat_fem.io.probes import PROBES
from cosserat_fem.io.run_folder import check_outputs, new_run_id, prepare_output_dir
from cosserat_fem.io.xdmf import XDMF
from cosserat_fem.nls.newton import NewtonSettings
from cosserat_fem.nls.solvers import make_solver
from cosserat_fem.output.fields import PointProbe, probe_sigma
from cosserat_fem.rod.model import RodModel, build_model
from cosserat_fem.rod.obstacles import contact_rows
from cosserat_fem.scene.build import Scene, refuse_closed, refuse_contact
from cosserat_fem.scene.load_data import refuse_callable_restart
from cosserat_fem.timestepping.events import Observer
from cosserat_fem.timestepping.integrators import make_integrator
from cosserat_fem.timestepping.loop import TimeLoop


@dataclass
class RunResult:
    """What a run produced, on every rank: the folder (if it wrote one), the output steps
    taken and the time reached [s], the summary (as summary.json), the model (its U holds
    the last state); with ``record=True`` the probe's rows (t, x, y, z, θ, ψ, φ) [s, m, rad]
    at every output time, and with ``fields`` the fields p at those stations
    (``field_stations``, σ as given): ``times`` (T,) [s] and ``values`` (T, stations, 6)
    [m, rad]."""

    out_dir: Path | None
    steps: int
    time_reached: float
    summary: dict
    model: RodModel = field(repr=False)
    probes: np.ndarray | None = field(default=None, repr=False)
    field_times: np.ndarray | None = field(default=None, repr=False)
    field_values: np.ndarray | None = field(default=None, repr=False)
    field_stations: np.ndarray | None = field(default=None, repr=False)


def _leaves_plane(model: RodModel, state: np.ndarray) -> bool:
    """Whether a planar model was given a 12-component state with an out-of-plane component
    (y, θ, φ for x-z; x, ψ, φ for y-z) or a rate of one non-zero (collective)."""
    nodes, layout = model.nodes, model.layout
    full = layout.reduced and np.size(state) == 12 * nodes
    out = [i for i in range(12) if i not in layout.components]
    local = full and bool(np.any(np.asarray(state).reshape(nodes, 12)[:, out] != 0.0))
    return model.msh.comm.allreduce(local, op=MPI.LOR)


def run_scene(
    scene: Scene,
    out_dir: str | Path | None = None,
    comm: MPI.Comm = MPI.COMM_WORLD,
    observers: Sequence[Observer | Callable] = (),
    write_outputs: bool = True,
    initial_state: np.ndarray | None = None,
    restart: Checkpoint | None = None,
    progress: Callable[[float, int, int], None] | None = None,
    record: bool = False,
    fields: Sequence[float] | np.ndarray | None = None,
    field_every: int = 1,
    solver_factory: Callable | None = None,
) -> RunResult:
    """Integrate the scene over its time span (module docstring): the run behind the one
    public ``run``, cosserat_fem/api.py's (``cf.run``, which the command line calls), with
    what a program inside the package needs besides: a communicator ``comm`` (a sweep's
    group of ranks) and the scene's output.directory as the default folder.

    The rod starts from rest in its straight state, or from the scene's [initial] fields, or
    from ``initial_state`` (the array of a 12-component state U = (p, q) on the same
    discretisation, e.g. a static solution), or continues the run of the checkpoint
    ``restart`` in its folder (cosserat_fem/io/checkpoint.py; ``scene`` must then be the
    checkpoint's, with the overrides a restart allows, ``out_dir`` none or that folder,
    ``initial_state`` none: :func:`_check_restart`). Outputs go to ``out_dir`` (default
    the scene's output.directory) unless ``write_outputs`` is false. ``observers``: objects
    with the hooks of cosserat_fem/timestepping/events.py, or functions f(k, t [s], model) called at
    every output time. ``progress(t [s], steps taken, Newton iterations)`` is called at every
    output time. ``record``: keep the probe's rows in memory (``RunResult.probes``);
    ``fields``: stations σ ∈ [0, 1] at which to keep p every ``field_every`` output times.
    The output folder is locked for the run (a second writer there is refused,
    cosserat_fem/io/run_folder.py). ``solver_factory(model, F, bcs, settings)``: the
    nonlinear solver instead of make_solver's (a reduced model's, cosserat_fem/rom/galerkin.py).
    """
    t_start = time.perf_counter()
    with folders_held():  # the output folder is locked for the run
        refuse_closed(scene, "run")
        fields = _stations(fields, field_every)
        if restart is not None:
            refuse_callable_restart(scene)
            _check_restart(scene, restart, out_dir, initial_state)
            out_dir, write_outputs = restart.run_dir, True
        initial_state = _initial_array(initial_state, comm)
        out = None
        if write_outputs:
            out = Path(out_dir if out_dir is not None else scene.output.directory)
        start = restart.time if restart is not None else None
        budget.check(scene, "run", out, ranks_on_node(comm), comm.size, start=start, comm=comm)
        plan = None
        if out is not None:
            kind, run_id = ("restart", restart.run_id) if restart is not None else ("run", None)
            prepare_output_dir(out, comm, lock=kind, run_id=run_id)
            if restart is not None:  # checked before anything is built or touched
                xdmf = out / XDMF if scene.output.xdmf else None
                plan = check_outputs(restart, out / PROBES, xdmf, comm)
        model, integrator, solver = _discretise(scene, comm, initial_state, restart, solver_factory)
        probe = PointProbe(model, probe_sigma(scene), fields=scene.output.probe_fields)
        run_id = restart.run_id if restart is not None else new_run_id(comm)
        summary = summary_start(
            "run",
            scene,
            comm,
            model,
            probe,
            solver,
            run_id,
            integrator=integrator.name,
            restarted_from_s=restart.time if restart is not None else None,
            restarts=restart.restart_number if restart is not None else 0,
        )
        chain = StandardObservers(
            scene,
            model,
            solver,
            probe,
            summary,
            comm,
            t_start,
            out,
            xdmf_every=scene.output.xdmf_every(scene.time.step),
            restart=restart,
            plan=plan,
            checkpoints=scene.output.checkpoint,
            wall_time=scene.limits.wall_time,
            progress=progress,
            observers=observers,
            record=record,
            fields=fields,
            field_every=field_every,
        )
        loop = TimeLoop(
            model,
            integrator,
            solver,
            scene.time,
            chain.events,
            restart.parts if restart is not None else None,
        )
        failure = drive(loop)
        comm.barrier()  # every file is closed on every rank before anyone reads them
        if failure:
            raise failure
        times, values = chain.sampled.arrays() if chain.sampled is not None else (None, None)
        return RunResult(
            out_dir=out,
            steps=summary["steps"],
            time_reached=summary["time_reached_s"],
            summary=summary,
            model=model,
            probes=chain.recorder.rows() if chain.recorder is not None else None,
            field_times=times,
            field_values=values,
            field_stations=fields,
        )


def drive(loop) -> BaseException | None:
    """Run a source of events (``loop.run()``: a time loop, or load stepping of
    cosserat_fem/analysis/statics.py) and always end it: the state back to the last accepted one,
    then every observer's ``ended``, then the solver's PETSc objects destroyed. Returns the
    failure if the run stopped with a CosseratError (the observers have then written what a
    stopped run keeps); anything else (Ctrl-C, an observer's own exception) is raised again
    after the observers closed their files, as after a kill."""
    failure: BaseException | None = None
    try:
        try:
            loop.run()
        except CosseratError as exc:
            failure = exc
        except BaseException as exc:
            loop.back_to_accepted()
            loop.events.ended(loop, exc)
            raise
        loop.back_to_accepted()
        return loop.events.ended(loop, failure)
    finally:
        loop.solver.destroy()


def _check_restart(scene: Scene, restart, out_dir, initial_state) -> None:
    """A restart continues the checkpoint's run, in its folder, from its state, with its
    scene (changed at most where cosserat_fem/io/checkpoint.py allows): a SceneError naming the
    argument otherwise, before anything is touched (the same on every rank)."""
    if not isinstance(restart, Checkpoint):
        raise SceneError(
            f"restart: must be the checkpoint of cf.resume(folder), got {type(restart).__name__}"
        )
    if initial_state is not None:
        raise SceneError(
            "initial_state: cannot be given with restart (the run continues from "
            "the checkpoint's state)"
        )
    if out_dir is not None and not _same_folder(Path(out_dir), restart.run_dir):
        raise SceneError(
            f"out: the run continues in its checkpoint's folder "
            f"{str(restart.run_dir)!r}; give no out (or that folder), got "
            f"{str(out_dir)!r}"
        )
    check_restart_scene(restart, scene)


def _initial_array(initial_state, comm) -> np.ndarray | None:
    """``initial_state`` as a flat array of finite numbers (this rank's part), checked before
    any work: a SceneError naming it on every rank otherwise (collective). A NaN went into
    the first step and was reported as a residual that is not finite, blamed on the loads."""
    if initial_state is None:
        agree(comm, None)
        return None
    state, problem = None, None
    try:
        state = np.asarray(initial_state, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        problem = SceneError(
            f"initial_state: must be an array of numbers (12 per node), got "
            f"{type(initial_state).__name__}"
        )
    if state is not None and not np.isfinite(state).all():
        i = int(np.flatnonzero(~np.isfinite(state))[0])
        problem = SceneError(
            f"initial_state: value {i} (node {i // 12}, component {i % 12} of "
            f"12) is not finite ({state[i]!r})"
        )
    agree(comm, problem)
    return state


def _same_folder(a: Path, b: Path) -> bool:
    try:
        return a.samefile(b)
    except OSError:
        return False


def _stations(fields, field_every) -> np.ndarray | None:
    """The sampling stations σ as an array, checked before any work: finite, in [0, 1], at
    least one; ``field_every`` a whole number ≥ 1 (SceneError naming the argument)."""
    if isinstance(field_every, bool) or not isinstance(field_every, int) or field_every < 1:
        raise SceneError(f"field_every: must be a whole number >= 1, got {field_every!r}")
    if fields is None:
        return None
    try:
        stations = np.asarray(fields, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise SceneError(f"fields: must be numbers σ = s/ℓ in [0, 1], got {fields!r}") from None
    inside = np.isfinite(stations) & (stations >= 0.0) & (stations <= 1.0)
    if stations.size == 0 or not inside.all():
        raise SceneError(f"fields: must be numbers σ = s/ℓ in [0, 1], at least one, got {fields!r}")
    return stations


def _discretise(scene: Scene, comm, initial_state, restart, solver_factory=None):
    """The model (in its initial state), the integrator and the Newton solver of a run."""
    model = build_model(scene, comm)
    if initial_state is not None:
        wrong = np.size(initial_state) != 12 * model.nodes
        agree(
            comm,
            SceneError(
                f"initial_state: {np.size(initial_state)} values, expected 12 a node of this "
                f"rank's mesh ({12 * model.nodes}; a reduced state: embed it with "
                "Layout.full_array)"
            )
            if wrong
            else None,
        )
    if initial_state is not None and _leaves_plane(model, initial_state):
        model = build_model(scene, comm, planar=False)  # it keeps all twelve unknowns
    if model.needs_chart:
        model.use_chart(active=False)  # moved when θ nears ±π/2 (cosserat_fem/rod/charts.py)
    if restart is not None:
        model.U.x.array[:] = restart.parts["state"]["U"]
    elif initial_state is not None:
        model.U.x.array[:] = model.layout.from_full(initial_state, model.nodes)
    elif scene.initial.fields():
        model.U.x.array[:] = model.initial_state()
    tspan = scene.time
    integrator = make_integrator(
        tspan.integrator, model.U, model.residual, tspan.start * model.omega0, rho_inf=tspan.rho_inf
    )
    settings = NewtonSettings.of(scene.solver)
    contact = contact_rows(model)
    if contact is not None:
        if solver_factory is not None:
            refuse_contact(scene, "a reduced model")
        if tspan.integrator.startswith("sdirk"):
            raise SceneError(
                f"time.integrator: contact needs a method whose step ends at its solved state "
                f"(bdf2 or generalized-alpha; SDIRK's stages are not its step's end), got "
                f"{tspan.integrator!r}"
            )
        if settings.jacobian != "full":  # the rows change with every iterate
            logging.getLogger(__name__).info(
                "contact: full Newton (solver.jacobian = %r)", settings.jacobian
            )
            settings = replace(settings, jacobian="full")
    if solver_factory is None:
        solver = make_solver(
            integrator.residual_form(), model.U, model.bcs, settings, model.constraints, contact
        )
    else:
        solver = solver_factory(model, integrator.residual_form(), model.bcs, settings)
        space = getattr(solver, "coordinate_space", None)
        if space is not None and getattr(solver, "use_coordinates", True):
            space(integrator, tspan)  # the integrator on reduced coordinates (docs/rom.md §8)
    if restart is None:
        integrator.start(model, solver.lu_package)
        if contact is not None:  # the friction's history starts at the initial state
            contact.accept(model.U.x.array, initial=True)
    return model, integrator, solver
