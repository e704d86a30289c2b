"""The Python API: scenes, runs, static solves and modes from a script or a notebook, with
results as NumPy arrays in memory. The command line is a thin layer over the same functions.

    import numpy as np
    import cosserat_fem as cf

    scene = cf.load("scenes/cao_tucker_2008.toml", {"time.end": 0.003})
    result = cf.run(scene, fields=np.linspace(0.0, 1.0, 5))   # out="DIR": files as well
    t, x_tip = result.probes[:, 0], result.probes[:, 1]       # [s], [m]
    x_rod = result.field_values[-1, :, 0]                     # x(s) at the end [m]
    modes = cf.modes(scene, count=4)                          # [m.frequency_hz for m in modes]
    found = cf.stability(scene, 0.0, 2.0)                     # found.critical, found.kind
    chaos = cf.lyapunov(scene, 2 * np.pi / 1600, periods=40)  # chaos.exponent [1/s], .poincare
    stations = np.linspace(0.0, 1.0, 49)
    pod = cf.pod(cf.run(scene, fields=stations), stations)    # pod.energies, pod.shapes

Everything is SI: lengths in m, angles in rad, times in s. Under ``mpirun`` every rank
calls the same functions and gets the same arrays.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from cosserat_fem.common.errors import SceneError, out_folder
from cosserat_fem.io.folder_lock import holding_folders
from cosserat_fem.scene.build import Scene, load_scene, refuse_structure, scene_from_dict
from cosserat_fem.scene.load_data import TableStore
from cosserat_fem.scene.schema import UNSET  # noqa: F401 - cf.UNSET: an override that removes its key
from cosserat_fem.timestepping.events import Observer


def load(
    source: str | Path | Mapping[str, Any], overrides: Mapping[str, Any] | Sequence[str] = ()
) -> Scene:
    """A validated scene from a TOML file or a dict of tables (as TOML reads), with
    ``overrides``: a mapping of dotted keys to values (``{"time.end": 0.01}``; the value
    :data:`UNSET` removes the key or table, ``{"rod.section.a": cf.UNSET}``) or
    ``"dotted.key=value"`` strings as the command line's ``--set``. A load component may be a
    table (``{"table": "file.csv", "column": "F"}``, relative to the scene file, or to the
    working directory for a dict) or a Python callable, f(t) or f(t, s) for a distributed
    load (``{"loads.end.force": [0, 0, f]}``; cosserat_fem/scene/load_data.py). Bad input raises a
    :class:`~cosserat_fem.common.errors.SceneError` naming the key. Under mpirun every rank calls it
    (rank 0 reads the tables)."""
    if isinstance(source, Mapping):
        tables = TableStore.collective()
        return scene_from_dict(dict(source), overrides=overrides, tables=tables)
    if not isinstance(source, str | Path):
        raise SceneError(
            f"source: a scene file's path or a dict of tables, got {type(source).__name__}"
        )
    return load_scene(source, overrides)


def run(
    scene: Scene,
    out: str | Path | None = None,
    *,
    fields: Sequence[float] | np.ndarray | None = None,
    field_every: int = 1,
    observers: Sequence[Observer | Callable] = (),
    initial_state: np.ndarray | None = None,
    restart=None,
    progress: Callable[[float, int, int], None] | None = None,
    record: bool = True,
):
    """Integrate the scene in time; a :class:`~cosserat_fem.analysis.simulation.RunResult` whose
    ``probes`` are the probe's rows (t, x, y, z, θ, ψ, φ) at every output time (unless
    ``record`` is false) and, with ``fields`` (stations σ = s/ℓ in [0, 1]), ``field_times``
    (T,) and ``field_values`` (T, stations, 6) every ``field_every`` output times. Files
    (probes.csv, XDMF, checkpoints, summary.json) only with ``out``, or in the checkpoint's
    folder with ``restart`` (from :func:`resume`; ``scene`` must then be the checkpoint's,
    changed at most in the keys a restart may change, ``out`` none or that folder, and
    ``initial_state`` none: a SceneError otherwise). ``observers``:
    cosserat_fem/timestepping/events.py;
    ``progress(t [s], steps, Newton iterations)`` at every output time."""
    if fields is not None:
        refuse_structure(scene, "run with fields at stations s")
    from cosserat_fem.analysis.simulation import run_scene
    from cosserat_fem.timestepping.events import as_observer

    out = out_folder(out)
    observers = [as_observer(o) for o in observers]  # checked before any work
    if restart is not None and hasattr(restart, "run_dir"):
        from cosserat_fem.rom.runs import recorded_basis

        if recorded_basis(restart.run_dir) is not None:  # its checkpoint's U is U_ref + V q
            raise SceneError(
                f"--restart: {str(restart.run_dir)!r} is a reduced run; continue it with "
                "cosserat-fem rom run --restart DIR --basis FILE (cf.rom.run)"
            )
    if progress is not None and not callable(progress):
        raise SceneError(
            f"progress: must be a function progress(t, steps, iterations), got "
            f"{type(progress).__name__}"
        )
    return run_scene(
        scene,
        out,
        observers=observers,
        write_outputs=out is not None or restart is not None,
        initial_state=initial_state,
        restart=restart,
        progress=progress,
        record=record,
        fields=fields,
        field_every=field_every,
    )


def load_sweep(
    source: str | Path,
    overrides: Mapping[str, Any] | Sequence[str] = (),
    *,
    changes: Mapping[str, Any] | None = None,
):
    """A sweep file read and every member's scene validated (cosserat_fem/studies/sweep_spec.py);
    ``overrides``: dotted scene keys for the base scene; ``changes``: the file's [sweep]
    table changed first, tables merged key by key (``{"vary": {"parameters.r": [0.9, 1.1]}}``:
    the same sweep over other values), ``cf.UNSET`` removing a key (``{"vary":
    {"parameters.f0": cf.UNSET, ...}}``: vary another parameter instead)."""
    from cosserat_fem.studies.sweep_spec import load_sweep as load

    return load(source, overrides, changes)


def sweep(spec, out: str | Path, *, progress: bool = False):
    """Run a sweep's members not finished in ``out`` (cosserat_fem/studies/sweep_run.py; under
    mpirun, groups of ``group_size`` ranks): a SweepResult with the table's path and rows. With
    ``progress``: a line on stderr as each member finishes, with the time left."""
    from cosserat_fem.studies.sweep_run import run_sweep
    from cosserat_fem.studies.sweep_spec import SweepSpec

    if not isinstance(spec, SweepSpec):
        raise SceneError(f"spec: must be a sweep of cf.load_sweep(path), got {type(spec).__name__}")
    if out is None:
        raise SceneError("out (--out): a sweep needs its folder")
    return run_sweep(spec, out_folder(out), progress=progress)


def resume(folder: str | Path, overrides: Mapping[str, Any] | Sequence[str] = ()):
    """The scene and the checkpoint to continue the run in ``folder`` (``run(scene,
    restart=checkpoint)``), with the overrides a restart allows (cosserat_fem/io/checkpoint.py:
    time.end, solver.*, limits.*, ...); SceneError if there is no usable checkpoint, or
    time.end is not later than it, or a table's content is not the one the run used (its
    SHA-256 is in the checkpoint's scene), or a load was a Python callable (not data: a run
    with one cannot be restarted)."""
    from cosserat_fem.analysis.restart import FIXED_KEYS, restart_overrides
    from cosserat_fem.io.checkpoint import load_checkpoint
    from cosserat_fem.scene.schema import Removal

    if isinstance(overrides, Mapping):
        texts: Sequence[str] = [Removal(k) if v is UNSET else f"{k}=" for k, v in overrides.items()]
    else:
        texts = overrides
    restart_overrides(texts)
    checkpoint = load_checkpoint(folder)
    scene = scene_from_dict(
        checkpoint.meta["scene"],
        source=f"{folder}/checkpoint",
        overrides=overrides,
        fixed=FIXED_KEYS,
        after=checkpoint.time,
        tables=TableStore.collective(folder),
    )
    return scene, checkpoint


def static(scene: Scene, out: str | Path | None = None, *, observers=()):
    """Static equilibrium under the scene's loads by load stepping; a
    :class:`~cosserat_fem.analysis.statics.StaticResult` whose ``probes`` are the probe's rows
    (λ, x, y, z, θ, ψ, φ) at every accepted load factor λ. Files only with ``out``."""
    from cosserat_fem.analysis.statics import static_path
    from cosserat_fem.timestepping.events import as_observer

    out = out_folder(out)
    observers = [as_observer(o) for o in observers]  # checked before any work
    return static_path(scene, out, write_outputs=out is not None, observers=observers, record=True)


def modes(scene: Scene, count: int = 10, about: str = "undeformed", out: str | Path | None = None):
    """The ``count`` lowest natural modes (cosserat_fem/analysis/modal.py) about the straight rod
    or, with ``about="static"``, the static state under the scene's loads: a list of
    :class:`~cosserat_fem.analysis.modal.Mode` (``omega`` [rad/s], ``frequency_hz``, ``kind``,
    ``shape``); modes.csv, modes.xdmf and modes.json only with ``out``."""
    from cosserat_fem.analysis.equilibria import compute_modes

    return compute_modes(scene, count, about, out=out_folder(out))[1]


def stability(
    scene: Scene,
    low: float = 0.0,
    high: float = 1.0,
    *,
    samples: int = 5,
    tolerance: float = 1e-8,
    count: int = 6,
    out: str | Path | None = None,
):
    """Stability of the scene's static states for load factors f in [low, high] (every load
    × f; cosserat_fem/analysis/equilibria.py) and the critical factor where it is lost: a
    :class:`~cosserat_fem.analysis.equilibria.StabilityResult` with ``critical`` (None if stability
    is not lost in the range), ``kind`` ("divergence": buckling; "flutter"), ``bracket`` and
    ``points`` (each state's ``status`` and ``eigenvalues`` of K φ = λ M φ, units of ω0²).
    ``samples``: equally spaced factors visited first (up to the first unstable one);
    ``tolerance``: the root finder's, |Δf| ≤ tolerance (1 + |f|); ``count``: eigenvalues
    nearest 0 computed at each state. stability.json only with ``out``."""
    from cosserat_fem.analysis.equilibria import stability as analyse

    return analyse(scene, low, high, samples, tolerance, count, out_folder(out))


def stability_at(scene: Scene, factor: float = 1.0, *, count: int = 6):
    """The static state at load factor ``factor`` (1: the scene's loads) and whether it is
    stable: a :class:`~cosserat_fem.analysis.equilibria.StabilityPoint` (``status``: "stable",
    "divergence" or "flutter"; ``eigenvalues``, ``kinds``)."""
    from cosserat_fem.analysis.equilibria import stability_at as at

    return at(scene, factor, count)


def _whole(name: str, value, low: int) -> int:
    """``value`` if it is a whole number >= ``low``, else a SceneError naming ``name``."""
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < low:
        raise SceneError(f"{name}: must be a whole number >= {low}, got {value!r}")
    return int(value)


def _check_shooting(scene: Scene, settle, steps_per_period, flags: bool = False) -> None:
    """A shooting request checked before any folder is made: ``settle`` >= 0,
    ``steps_per_period`` >= 1 (with ``flags``, the command line's flags named too), and the
    scene's integrator and steps (periodic.shooting_problem)."""
    from cosserat_fem.analysis.periodic import shooting_problem

    for name, value, low in (("settle", settle, 0), ("steps_per_period", steps_per_period, 1)):
        flag = f" (--{name.replace('_', '-')})" if flags else ""
        _whole(name + flag, value, low)
    problem = shooting_problem(scene, steps_per_period, None)
    if problem is not None:
        raise problem


def _shooting_budget(scene: Scene, period: float, settle: int, steps_per_period: int) -> None:
    """SceneError naming --settle and --steps-per-period if time-marching ``settle`` + 1
    periods of ``steps_per_period`` steps, the least a shooting does (its Newton iterations
    and monodromies take more), exceeds the scene's limits (budget.py, as a run)."""
    from dataclasses import replace

    from mpi4py import MPI

    from cosserat_fem.analysis import budget
    from cosserat_fem.common.parallel import ranks_on_node

    comm = MPI.COMM_WORLD
    end = scene.time.start + (settle + 1) * period
    span = replace(scene.time, step=period / steps_per_period, end=end, adaptive=False)
    quiet = replace(scene.output, xdmf=False, checkpoint=False)
    try:
        budget.check(
            replace(scene, time=span, output=quiet),
            "run",
            None,
            ranks_on_node(comm),
            comm.size,
            comm=comm,
        )
    except SceneError as exc:
        raise SceneError(f"--settle, --steps-per-period: {exc}") from None


def periodic_orbit(
    scene: Scene,
    period: float | str,
    *,
    guess=None,
    settle: int = 0,
    steps_per_period: int = 300,
    tolerance: float = 1e-9,
    max_iterations: int = 20,
):
    """The periodic orbit of the scene's forced rod near ``guess``, by shooting over one
    forcing period T = ``period`` [s] (a number or an expression of the scene's constants,
    ``"2*pi/(r*w1)"``) in ``steps_per_period`` fixed steps of its SDIRK integrator, and its
    stability from the Floquet multipliers (cosserat_fem/analysis/periodic.py). ``guess``: this
    rank's array of the model's U (an earlier :class:`~cosserat_fem.analysis.periodic.Orbit`'s
    ``state``, or the orbit itself), or None for rest; ``settle``: periods time-marched from it
    first. Newton stops when its update is below ``tolerance`` (1 + ‖U0‖). Returns the
    :class:`~cosserat_fem.analysis.periodic.Orbit`: ``state`` (U at time.start), ``amplitude``
    (half the range of the probe's x [m]), ``multipliers``, ``stability`` ("stable", "fold",
    "period-doubling", "torus"). Under mpirun every rank gets its own part of ``state`` and the
    same rest. On a structure the probe is its probe node (structure.probe)."""
    from cosserat_fem.analysis.periodic import Orbit, Shooting

    _check_shooting(scene, settle, steps_per_period)
    _whole("max_iterations", max_iterations, 1)
    if not (isinstance(tolerance, int | float) and 0.0 < tolerance < 1.0):
        raise SceneError(f"tolerance: must be a number in (0, 1), got {tolerance!r}")
    shooting = Shooting(scene, period, steps_per_period=steps_per_period)
    try:
        if isinstance(guess, Orbit):
            guess = guess.state
        u = shooting.rest() if guess is None else shooting.check_state(guess)
        u = shooting.settle(u, int(settle))
        return shooting.find(u, tolerance, int(max_iterations))
    finally:
        shooting.destroy()


def lyapunov(
    scene: Scene, period: float, *, periods: int, out: str | Path | None = None, **options
):
    """The largest Lyapunov exponent [1/s] of the scene forced with period ``period`` T [s],
    by Benettin's method over ``periods`` periods from time.start (a reference and a perturbed
    trajectory, the perturbation rescaled every period), and its Poincaré section
    (cosserat_fem/analysis/lyapunov.py): a
    :class:`~cosserat_fem.analysis.lyapunov.LyapunovResult` with ``exponent``, its history
    (``times``, ``stretches``, ``running``) and the section's rows ``poincare``
    (``columns``); poincare.csv in ``out`` if given. ``options``: ``every``, ``discard``,
    ``phase``, ``perturbation``, ``seed``, ``observers``, ``initial_state`` (as
    :func:`run`'s), documented on ``largest_exponent`` there. time.step must divide every·T,
    with fixed steps."""
    refuse_structure(scene, "lyapunov")
    from cosserat_fem.analysis.lyapunov import largest_exponent

    _lyapunov_options(options)
    return largest_exponent(scene, period, periods=periods, out=out_folder(out), **options)


def _lyapunov_options(options: Mapping[str, Any]) -> None:
    """SceneError naming the first of ``options`` that ``largest_exponent`` does not take
    (a misspelt keyword was a TypeError, not the one line of bad input)."""
    import inspect

    from cosserat_fem.analysis.lyapunov import largest_exponent

    known = set(inspect.signature(largest_exponent).parameters) - {"scene", "period", "periods"}
    known -= {"out", "comm"}
    for name in options:
        if name not in known:
            raise SceneError(
                f"{name}: not an option of lyapunov (it takes {', '.join(sorted(known))})"
            )


def pod(
    source,
    stations: Sequence[float] | np.ndarray | None = None,
    *,
    modes: int | None = None,
    weighting: str = "displacement",
    remove_mean: bool = True,
    out: str | Path | None = None,
):
    """Karhunen–Loève (POD) modes of a run's response (cosserat_fem/studies/karhunen_loeve.py): a
    :class:`~cosserat_fem.studies.karhunen_loeve.PodResult` with ``energies``, ``fractions``,
    ``cumulative``, ``shapes`` (K, stations, 3 or 6) and ``coefficients`` (T, K).

    ``source``: a run's folder (its XDMF frames are the snapshots; stations: its output
    points), or a :class:`~cosserat_fem.analysis.simulation.RunResult` of ``run(scene,
    fields=stations)`` with the same ``stations`` (σ = s/ℓ). ``modes``: how many (default
    min(10, snapshots)); ``weighting``: "displacement" (x, y, z; energies in m³) or "kinetic"
    (x, y, z and θ, ψ, φ weighted by ρA and ρ I: the mass inner product; kg m²);
    ``remove_mean``: subtract the time mean first (the Karhunen–Loève convention). With
    ``out``: pod.csv, pod.xdmf (+ pod.frames/) and pod.png there (rank 0 writes), their paths
    in ``result.files``. Bad input raises a SceneError naming the argument."""
    from mpi4py import MPI

    from cosserat_fem.common.errors import CosseratError
    from cosserat_fem.common.parallel import agree
    from cosserat_fem.io.output_files import output_folder
    from cosserat_fem.plot import plot_pod
    from cosserat_fem.studies.karhunen_loeve import (
        POD_PNG,
        read_run,
        snapshots_of_result,
        write_pod,
    )
    from cosserat_fem.studies.karhunen_loeve import pod as decompose

    out = out_folder(out)
    if isinstance(source, str | Path):
        if stations is not None:
            raise SceneError("stations: a run folder's are its output points; give none")
        snapshots = read_run(source)
    else:
        if stations is None:
            raise SceneError(
                "stations: give the fields σ the run was given (run(scene, fields=stations))"
            )
        snapshots = snapshots_of_result(source, stations)
    result = decompose(snapshots, modes, weighting, remove_mean)
    if out is not None:
        comm = MPI.COMM_WORLD
        problem = None
        if comm.rank == 0:
            try:
                folder = output_folder(out, Path(out), "pod")
                result.files = [*write_pod(result, folder), plot_pod(result, folder / POD_PNG)]
            except CosseratError as exc:  # bad input, or a write that failed (OutputError)
                problem = exc
        agree(comm, problem)
        result.files = comm.bcast(result.files, root=0)
    return result


def _number(name: str, value, positive: bool = True) -> float:
    """``value`` as a float, or SceneError naming ``name`` unless it is a finite (positive)
    number."""
    import math

    if isinstance(value, bool) or not isinstance(value, int | float | np.floating):
        raise SceneError(f"{name}: must be a number, got {value!r}")
    if not math.isfinite(value) or (positive and value <= 0.0):
        sign = " positive" if positive else ""
        raise SceneError(f"{name}: must be a finite{sign} number, got {value!r}")
    return float(value)


@holding_folders
def continuation(
    scene: Scene | None,
    low: float = 0.0,
    high: float = 1.0,
    *,
    step: float = 0.05,
    max_step: float = 1.0,
    min_step: float = 1e-6,
    max_points: int | None = None,
    switch: int = 1,
    directions: Sequence[int] = (1, -1),
    stop: Callable | None = None,
    out: str | Path | None = None,
    progress: Callable[[int, int, float], None] | None = None,
    restart: str | Path | None = None,
    branch: int = -1,
    probe: float | None = None,
):
    """The static equilibrium path in the load factor λ (every load × λ) by pseudo-arclength
    continuation from the unloaded rod (cosserat_fem/analysis/paths.py,
    cosserat_fem/nls/arclength.py): around limit points (located), with the bifurcation
    points located by the sign of det R_u and the first ``switch`` of them switched onto,
    each branch traced both ways (``directions``: +1 with λ growing first) until λ leaves
    [low, high] (the last point at the bound), ``max_points``, ``stop(point)`` (a reason,
    or None to go on) or a step collapse below ``min_step`` (the reason kept). Steps are
    arclength in the metric √(RMS(ΔU)² + Δλ²) (U dimensionless: x/ℓ and rad). In 3D the
    chart of large rotations moves on the path; the y-z plane is refused. Returns a
    :class:`~cosserat_fem.analysis.paths.PathResult`: ``branches``, each with ``points``
    (``factor`` λ, ``tip`` (x, y, z, θ, ψ, φ) of the free end [m, rad], ``norm``,
    ``dfactor`` dλ/ds, ``det_sign``, ``kind``), ``special`` points, ``origin`` and
    ``reason``. With ``out``: branches.csv there, branches.json (each branch's origin and
    why it ended) and branch_<i>.xdmf (each branch's states, the frame's time the point's
    index: cosserat_fem/analysis/branch_outputs.py). ``progress(branches finished, points
    on the branch, λ)`` after each point; ``max_points`` default 200.

    ``restart``: the folder of an earlier continuation (its ``out``): its branch ``branch``
    (default the last) traced on from its last point with its own scene and settings (give
    ``scene`` None), but ``max_points`` if given (cosserat_fem/analysis/path_restart.py);
    returns that branch and, when the continuation was cut short, every branch the whole run
    would have traced after it, in its order (``first_branch`` the first's index in the
    folder), their points appended to the folder's files. ``probe``: the
    arclength s [m] of the point reported as ``tip`` instead (the load point of a frame
    pinned at both ends, say); a restart keeps the first run's. On a structure ``tip`` is its
    probe node's (structure.probe), and ``probe`` is refused (no arclength s)."""
    if scene is not None and scene.structure is not None and probe is not None:
        raise SceneError(
            "probe: a structure has no arclength s; name the node with structure.probe"
        )
    import dataclasses

    from mpi4py import MPI

    from cosserat_fem.analysis import path_restart
    from cosserat_fem.analysis.branch_outputs import BranchOutputs, write_branch_reasons
    from cosserat_fem.analysis.paths import check_path_scene, continue_path, write_branches
    from cosserat_fem.io.run_folder import prepare_output_dir
    from cosserat_fem.nls.arclength import ContinuationSettings

    _check_progress(progress, "progress(branches, points, load_factor)")
    if restart is not None:
        held = _restart_folder(scene, restart, "continuation")
        record = path_restart.read_index(held, MPI.COMM_WORLD)
        saved = ContinuationSettings(**record["settings"])
        if max_points is not None:
            check_max_points(max_points)
            saved = dataclasses.replace(saved, max_points=max_points)
        if isinstance(branch, bool) or not isinstance(branch, int):
            raise SceneError(f"branch (--branch): must be a whole number, got {branch!r}")
        index = branch if branch >= 0 else len(record["branches"]) + branch
        return path_restart.restart_branch(held, record, index, saved, stop, progress)
    if not isinstance(scene, Scene):
        raise SceneError(f"scene: must be a Scene (cf.load), got {type(scene).__name__}")
    max_points = 200 if max_points is None else max_points
    low, high = _number("low (--range)", low, False), _number("high (--range)", high, False)
    if high <= low:
        raise SceneError(f"high (--range): must exceed low, got {low!r} {high!r}")
    step, max_step = _number("step (--step)", step), _number("max_step (--max-step)", max_step)
    min_step = _number("min_step", min_step)
    if not min_step <= step <= max_step:
        raise SceneError(f"step (--step): must lie in [min_step, max_step], got {step!r}")
    check_max_points(max_points)
    if isinstance(switch, bool) or not isinstance(switch, int) or switch < 0:
        raise SceneError(f"switch (--switch): must be a whole number >= 0, got {switch!r}")
    if not directions or any(d not in (1, -1) for d in directions):
        raise SceneError(f"directions: +1 and/or -1, got {directions!r}")
    settings = ContinuationSettings(
        step=step,
        min_step=min_step,
        max_step=max_step,
        max_points=max_points,
        max_iterations=scene.solver.max_iterations,
        p_min=low,
        p_max=high,
    )
    if probe is not None:  # checked before the folder is made
        probe = _number("probe (--probe)", probe, False)
        if not 0.0 <= probe <= scene.rod.length:
            raise SceneError(
                f"probe (--probe): must lie in [0, {scene.rod.length!r}] (m), got {probe!r}"
            )
    check_path_scene(scene)  # a scene it cannot follow: before the folder is made too
    out = out_folder(out)
    folder = None if out is None else prepare_output_dir(out, MPI.COMM_WORLD, "continue")
    observer = BranchOutputs(folder, progress)
    if folder is not None:  # restart data as each branch grows (path_restart.py)
        scene_dict = json.loads(json.dumps(scene.to_dict()))

        def save_index(ends: dict) -> None:
            path_restart.write_index(
                folder, scene_dict, settings, ends, MPI.COMM_WORLD, probe=probe
            )

        observer.record = save_index

        def finished(so_far) -> None:  # the files of the branches ended (a kill keeps them)
            write_branches(Path(folder) / "branches.csv", so_far)
            write_branch_reasons(Path(folder) / "branches.json", so_far, scene.output.xdmf)

        observer.finished = finished
    result = continue_path(
        scene, settings, switch, stop, tuple(directions), observer=observer, probe=probe
    )
    if folder is not None:
        write_branches(Path(folder) / "branches.csv", result)
        write_branch_reasons(Path(folder) / "branches.json", result, scene.output.xdmf)
        save_index(observer.ends)
    return result


def _check_progress(progress, signature: str) -> None:
    """SceneError naming ``progress`` unless it is None or callable."""
    if progress is not None and not callable(progress):
        raise SceneError(f"progress: must be a function {signature}, got {type(progress).__name__}")


def _restart_folder(scene, restart, what: str) -> Path:
    """The folder ``restart`` of an earlier ``what`` (continuation, orbit branch), locked for
    its restart; SceneError if a ``scene`` is given (the restart's is the folder's) or the
    folder is not one."""
    from mpi4py import MPI

    from cosserat_fem.io.run_folder import prepare_output_dir

    if scene is not None:
        raise SceneError(f"restart: the scene is the restarted {what}'s; give None")
    given = out_folder(restart, "--restart")
    if given is None or not given.is_dir():
        raise SceneError(f"--restart: {str(restart)!r} is not a folder")
    return prepare_output_dir(given, MPI.COMM_WORLD, "restart")


def check_max_points(max_points) -> None:
    """SceneError naming --max-points unless a whole number in [2, 100000]."""
    if isinstance(max_points, bool) or not isinstance(max_points, int):
        raise SceneError(f"max_points (--max-points): must be a whole number, got {max_points!r}")
    if max_points < 2 or max_points > 100_000:
        raise SceneError(f"max_points (--max-points): must lie in [2, 100000], got {max_points}")


@holding_folders
def periodic_branch(
    scene: Scene,
    period: float | str,
    parameter: str,
    start: float,
    end: float,
    *,
    guess=None,
    settle: int = 0,
    steps_per_period: int = 300,
    step: float = 0.005,
    max_step: float = 0.01,
    scale: float = 4.0,
    max_points: int = 300,
    out: str | Path | None = None,
):
    """The branch of forced periodic orbits in the scene parameter ``parameter`` p (e.g. r of
    Ω = r ω1, with ``period`` an expression of it, ``"2*pi/(r*w1)"``) from p = ``start`` to
    p = ``end``, by pseudo-arclength continuation of the shooting problem
    (cosserat_fem/analysis/periodic.py ``trace_orbits``; cosserat_fem/nls/arclength.py):
    through its folds, unstable parts included, each orbit with its Floquet multipliers and
    stability, the folds located (dp/ds = 0, where a real multiplier crosses +1), and the
    period doublings (a real multiplier crossing −1) and tori (a complex pair crossing
    |μ| = 1), each with its multipliers. The first orbit is shot from ``guess`` (an Orbit or
    this rank's U; None: rest) after ``settle`` periods. Steps (``step``, up to ``max_step``)
    are arclength in √(w ‖ΔU‖² + Δp²), w making the first orbit's weighted norm ``scale`` ×
    its amplitude / ℓ. Returns an :class:`~cosserat_fem.analysis.periodic.OrbitBranch`:
    ``points`` (``parameter``, ``amplitude`` [m], ``multipliers``, ``stability``, ``kind``,
    ``state``), ``folds``, ``period_doublings``, ``tori``, ``special``, ``reason``, ``steps``,
    ``monodromies``. With ``out``: orbit_branch.csv there (columns ``ORBIT_COLUMNS``)."""
    refuse_structure(scene, "a branch of orbits over a parameter range")
    from mpi4py import MPI

    from cosserat_fem.analysis.paths import write_branches
    from cosserat_fem.analysis.periodic import ORBIT_COLUMNS, Orbit, Shooting, trace_orbits
    from cosserat_fem.io.run_folder import prepare_output_dir

    start, end = _number("start", start, False), _number("end", end, False)
    settings, scale = _orbit_settings(start, end, step, max_step, scale, settle, max_points)
    out = out_folder(out)
    folder = None if out is None else prepare_output_dir(out, MPI.COMM_WORLD, "continue")
    shooting = Shooting(scene, period, steps_per_period=steps_per_period, parameter=parameter)
    try:
        if isinstance(guess, Orbit):
            guess = guess.state
        shooting.set_parameter(start)
        u = shooting.rest() if guess is None else shooting.check_state(guess)
        u = shooting.settle(u, int(settle))
        branch = trace_orbits(shooting, u, start, end, settings, scale)
    finally:
        shooting.destroy()
    if folder is not None:
        write_branches(Path(folder) / "orbit_branch.csv", branch, columns=ORBIT_COLUMNS)
    return branch


def _orbit_settings(start, end, step, max_step, scale, settle, max_points, flags=False):
    """The engine's settings of an orbit branch (steps, max_points; the shooting's
    tolerances 1e-9, folds located to 1e-6 in arclength) and the metric's ``scale``, or a
    SceneError naming the argument first (with ``flags``, its command line flag too)."""
    from dataclasses import replace

    from cosserat_fem.nls.arclength import ContinuationSettings

    def name(argument: str) -> str:
        flag = {"start": "from", "end": "to"}.get(argument, argument.replace("_", "-"))
        return f"{argument} (--{flag})" if flags and argument != "scale" else argument

    if start == end:
        raise SceneError(f"{name('end')}: must differ from {name('start')}, got {end!r}")
    step, max_step = _number(name("step"), step), _number(name("max_step"), max_step)
    scale = _number("scale", scale)
    if step > max_step:
        raise SceneError(f"{name('step')}: must not exceed max_step {max_step!r}, got {step!r}")
    _whole(name("settle"), settle, 0)
    if _whole(name("max_points"), max_points, 2) > 100_000:  # as a continuation's bound
        raise SceneError(f"{name('max_points')}: must lie in [2, 100000], got {max_points}")
    settings = replace(
        ContinuationSettings(),
        step=step,
        max_step=max_step,
        max_points=int(max_points),
        tolerance=1e-9,
        locate_tolerance=1e-6,
    )
    return settings, scale


@holding_folders
def orbits(
    scene: Scene | None,
    period: float | str | None = None,
    parameter: str | None = None,
    start: float = 0.0,
    end: float = 1.0,
    *,
    settle: int = 0,
    steps_per_period: int = 300,
    step: float = 0.005,
    max_step: float = 0.01,
    scale: float = 4.0,
    max_points: int | None = None,
    out: str | Path | None = None,
    progress: Callable[[int, float, float], None] | None = None,
    restart: str | Path | None = None,
):
    """:func:`periodic_branch` with the command line's outputs, written as the branch grows
    (cosserat_fem/analysis/orbit_runs.py): orbit_branch.csv, orbit_branch.xdmf (the rod at t0
    of each orbit, a frame a point), summary.json (the reason, steps, monodromies, folds)
    and the restart data in ``out``; ``progress(points, p, amplitude [m])`` after each point
    (``max_points`` default 300). ``restart``: the folder of an earlier branch (give
    ``scene`` None): traced on from its last point with its own scene and settings, but
    ``max_points`` if given, the new points appended. A ``period`` that the scene's load
    expressions do not repeat after is refused (orbit_runs.check_periodic). Returns (the
    :class:`~cosserat_fem.analysis.periodic.OrbitBranch`, the summary dict)."""
    refuse_structure(scene, "a branch of orbits over a parameter range")
    from mpi4py import MPI

    from cosserat_fem.analysis import orbit_runs
    from cosserat_fem.io.run_folder import prepare_output_dir

    _check_progress(progress, "progress(points, parameter, amplitude)")
    if restart is not None:
        if max_points is not None:
            _orbit_settings(0.0, 1.0, 1.0, 1.0, 1.0, 0, max_points, True)  # checks it
        held = _restart_folder(scene, restart, "branch")
        return orbit_runs.resume_orbit_branch(held, max_points, progress)
    if not isinstance(scene, Scene):
        raise SceneError(f"scene: must be a Scene (cf.load), got {type(scene).__name__}")
    if period is None:
        raise SceneError("period (--period): give the forcing period [s] or its expression")
    if not isinstance(parameter, str):
        raise SceneError(f"parameter (--parameter): a scene parameter's name, got {parameter!r}")
    start = _number("start (--from)", start, False)
    end = _number("end (--to)", end, False)
    max_points = 300 if max_points is None else max_points
    settings, scale = _orbit_settings(start, end, step, max_step, scale, settle, max_points, True)
    _check_shooting(scene, settle, steps_per_period, True)
    value = orbit_runs.period_value(scene, period, "period (--period)")
    orbit_runs.check_periodic(scene, value)
    _shooting_budget(scene, value, settle, steps_per_period)
    if parameter not in scene.parameters:
        raise SceneError(
            f"parameter (--parameter): {parameter!r} is not one of the scene's parameters "
            f"{sorted(scene.parameters)}"
        )
    out = out_folder(out)
    folder = None if out is None else prepare_output_dir(out, MPI.COMM_WORLD, "orbits")
    return orbit_runs.orbit_branch(
        scene,
        period,
        parameter,
        start,
        end,
        settings,
        steps_per_period=steps_per_period,
        settle=settle,
        scale=scale,
        folder=folder,
        progress=progress,
    )


@holding_folders
def lyapunov_run(
    scene: Scene, period: float | str, *, periods: int, out: str | Path | None = None, **options
):
    """:func:`lyapunov` with the command line's outputs (cosserat_fem/analysis/orbit_runs.py):
    poincare.csv, lyapunov.csv (time [s], stretch, running exponent [1/s]) and summary.json
    (the exponent) in ``out``, the folder locked; ``period`` a time [s] or an expression of
    the scene's constants, which its load expressions must repeat after; refused before
    any work if a run of ``periods`` periods would
    exceed the scene's limits, stopped at limits.wall_time (a StopError). ``options``: as
    :func:`lyapunov`'s."""
    refuse_structure(scene, "lyapunov")
    from mpi4py import MPI

    from cosserat_fem.analysis import orbit_runs
    from cosserat_fem.analysis.lyapunov import check_request
    from cosserat_fem.io.run_folder import prepare_output_dir

    if not isinstance(scene, Scene):
        raise SceneError(f"scene: must be a Scene (cf.load), got {type(scene).__name__}")
    _lyapunov_options(options)
    value = orbit_runs.period_value(scene, period)
    orbit_runs.check_periodic(scene, value)
    check_request(  # before the folder is made (largest_exponent's defaults)
        scene,
        value,
        periods,
        options.get("every", 1),
        options.get("discard", 0),
        options.get("perturbation"),
    )
    out = out_folder(out)
    orbit_runs.lyapunov_budget(scene, value, periods, out)  # before the folder is made
    folder = None if out is None else prepare_output_dir(out, MPI.COMM_WORLD, "lyapunov")
    return orbit_runs.lyapunov_run(scene, value, periods, folder, **options)
