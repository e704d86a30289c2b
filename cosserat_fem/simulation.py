"""The time loop: a scene in, probes, XDMF and a summary out.

Time runs in τ = ω0 t (47) inside the integrator; everything written is in SI units.
After each step the state is checked: Newton must converge, U must be finite and the
Euler-angle chart must stay regular (|cos θ| ≥ ``CHART_COS_MIN``, since det Ma = cos θ (66)).
Trouble stops the run with a :class:`~cosserat_fem.errors.SolverError` that names the time,
the place along the rod and the reason; the outputs written so far stay readable and
``summary.json`` records the failure.
"""

from __future__ import annotations

import math
import platform
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from dolfinx import fem
from dolfinx.fem.petsc import apply_lifting, assemble_matrix, assemble_vector, set_bc
from mpi4py import MPI
from petsc4py import PETSc

from . import __version__
from .errors import SceneError, SolverError
from .integrators import GeneralizedAlpha, make_integrator
from .model import RodModel, build_model
from .newton import NewtonFailure, NewtonSettings, NewtonSolver
from .output import PointProbe, ProbeWriter, XdmfWriter, write_json
from .scene import Scene

CHART_COS_MIN = 1e-2
Observer = Callable[[int, float, RodModel], None]


@dataclass
class RunResult:
    """What a run produced (on every rank; file paths are the same on all ranks)."""

    out_dir: Path
    steps: int
    time_reached: float
    summary: dict
    model: RodModel = field(repr=False)


def probe_sigma(scene: Scene) -> float:
    """The probe point: the free end at s = ℓ, else the free end at s = 0, else mid-span."""
    if scene.supports.end == "free":
        return 1.0
    if scene.supports.start == "free":
        return 0.0
    return 0.5


def newton_settings(scene: Scene) -> NewtonSettings:
    s = scene.solver
    return NewtonSettings(
        jacobian=s.jacobian,
        lag=s.lag,
        refresh_iterations=s.refresh_iterations,
        rtol=s.rtol,
        atol=s.atol,
        stol=s.stol,
        max_iterations=s.max_iterations,
        linear_solver=s.linear_solver,
    )


def prepare_output_dir(path: Path, comm: MPI.Comm) -> Path:
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


def _worst_place(model: RodModel, values: np.ndarray) -> tuple[float, float]:
    """(s [m], value) of the largest |value| over the rod; values: local per-block array."""
    imap = model.V.dofmap.index_map
    n = imap.size_local
    coords = model.V.tabulate_dof_coordinates()[:n, 0]
    local = np.abs(values[:n]) if n else np.zeros(1)
    i = int(np.argmax(local)) if n else 0
    mine = (float(local[i]) if n else -1.0, float(coords[i]) * model.length if n else 0.0)
    return max(model.msh.comm.allgather(mine))[::-1]


CHART_SUGGESTION = (
    "d3 is nearly parallel to e2, which the Euler angles (18) cannot represent; orient the rod "
    "so that large bending is about e2 (carried by ψ, which the chart allows without bound)"
)


def check_state(
    model: RodModel, t: float | None, where_prefix: str = "", previous: np.ndarray | None = None
) -> None:
    """Stop with a SolverError if U is not finite, if the Euler-angle chart is (nearly)
    singular, |cos θ| < ``CHART_COS_MIN``, or, given the ``previous`` state array, if θ crossed
    ±π/2 at some node since then (cos θ changed sign: a step jumped over the singularity,
    through which no continuous motion passes, det Ma = cos θ (66))."""
    blocks = model.U.x.array.reshape(-1, 12)
    n = model.V.dofmap.index_map.size_local
    # One number and (in parallel) one reduction per step: the smallest |cos θ|; −0.5 if θ
    # crossed ±π/2, −1 if any owned value is not finite (a NaN or inf makes the sum so).
    value = 1.0
    if n:
        cos_theta = np.cos(blocks[:n, 3])
        value = float(np.abs(cos_theta).min())
        if previous is not None:
            before = np.cos(previous.reshape(-1, 12)[:n, 3])
            if float((before * cos_theta).min()) <= 0.0:
                value = -0.5
        if not math.isfinite(value + float(blocks[:n].sum())):
            value = -1.0
    comm = model.msh.comm
    if comm.size > 1:
        value = comm.allreduce(value, op=MPI.MIN)
    if value >= CHART_COS_MIN:
        return
    prefix = f"{where_prefix}{', ' if where_prefix else ''}"
    if value == -1.0:
        bad = np.where(np.isfinite(blocks).all(axis=1), 0.0, 1.0)
        s, _ = _worst_place(model, bad)
        raise SolverError(
            time=t,
            where=f"{prefix}s = {s:.4g} m",
            reason="the solution became non-finite (NaN/inf)",
            suggestion="reduce time.step or check the loads",
            retry=True,
        )
    if value == -0.5:
        before = np.cos(previous.reshape(-1, 12)[:, 3])
        crossed = np.where(before * np.cos(blocks[:, 3]) <= 0.0, 1.0, 0.0)
        s, _ = _worst_place(model, crossed)
        raise SolverError(
            time=t,
            where=f"{prefix}s = {s:.4g} m",
            reason="Euler-angle chart singular: θ crossed ±π/2 within the step "
            "(det Ma = cos θ changed sign)",
            suggestion=CHART_SUGGESTION,
            retry=True,
        )
    s, _ = _worst_place(model, 1.0 / np.maximum(np.abs(np.cos(blocks[:, 3])), 1e-300))
    raise SolverError(
        time=t,
        where=f"{prefix}s = {s:.4g} m",
        reason=(
            f"Euler-angle chart singular: |cos θ| = {value:.2e} "
            "(θ near ±π/2, where det Ma = cos θ vanishes)"
        ),
        suggestion=CHART_SUGGESTION,
    )


def _consistent_rate(integrator: GeneralizedAlpha, model: RodModel, lu_package: str) -> None:
    """U̇_0 from F(U_0, U̇_0, τ_0) = 0, affine in U̇_0 (one linear solve).

    Assembled and solved through the API, not dolfinx's ``LinearProblem``: that sets three
    PETSc options per instance and never removes them, and PETSc 3.18 holds 512, so a process
    that runs ~170 scenes (the work-precision benchmark) would fail with error 55.
    """
    a, L, W = integrator.initial_rate_problem()
    a_form, L_form = fem.form(a), fem.form(L)
    A = assemble_matrix(a_form, bcs=model.bcs)
    A.assemble()
    b = assemble_vector(L_form)
    apply_lifting(b, [a_form], bcs=[model.bcs])
    b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    set_bc(b, model.bcs)
    ksp = PETSc.KSP().create(model.msh.comm)
    ksp.setOperators(A)
    ksp.setType("preonly")
    ksp.getPC().setType("lu")
    ksp.getPC().setFactorSolverType(lu_package)
    ksp.solve(b, W.vector)
    W.x.scatter_forward()
    integrator.set_initial_rate(W.x.array)
    for obj in (ksp, A, b):
        obj.destroy()


def run(
    scene: Scene,
    out_dir: str | Path | None = None,
    comm: MPI.Comm = MPI.COMM_WORLD,
    observers: tuple[Observer, ...] = (),
    write_outputs: bool = True,
    initial_state: np.ndarray | None = None,
) -> RunResult:
    """Integrate the scene over its time span; see the module docstring.

    The rod starts from rest in its straight state, or from ``initial_state`` (the array of a
    12-component state U = (p, q) on the same discretisation, e.g. a static solution).
    """
    t_start = time.perf_counter()
    out = Path(out_dir if out_dir is not None else scene.output.directory)
    if write_outputs:
        prepare_output_dir(out, comm)
    model = build_model(scene, comm)
    if initial_state is not None:
        model.U.x.array[:] = initial_state
    tspan = scene.time
    omega0 = model.omega0
    integrator = make_integrator(
        tspan.integrator, model.U, model.residual, tspan.start * omega0, rho_inf=tspan.rho_inf
    )
    solver = NewtonSolver(
        integrator.residual_form(),
        model.U,
        model.bcs,
        newton_settings(scene),
    )
    if isinstance(integrator, GeneralizedAlpha):
        _consistent_rate(integrator, model, solver.lu_package)

    probe = PointProbe(model.U, probe_sigma(scene), model.length)
    probes = xdmf = None
    if write_outputs:
        probes = ProbeWriter(out / "probes.csv", probe)
        probes.write(tspan.start)
        if scene.output.xdmf:
            xdmf = XdmfWriter(out / "solution.xdmf", model.U, model.length)
            xdmf.write(tspan.start)
    xdmf_every = scene.output.xdmf_every(tspan.step)
    setup_time = time.perf_counter() - t_start

    summary = {
        "status": "running",
        "cosserat_fem": __version__,
        "scene_file": scene.source,
        "mpi_ranks": comm.size,
        "dofs": model.global_dofs(),
        "elements": scene.discretisation.elements,
        "degree": scene.discretisation.degree,
        "quadrature_degree": scene.discretisation.quadrature_degree,
        "integrator": integrator.name,
        "omega0_rad_s": omega0,
        "probe_s_m": probe.sigma * model.length,
        "lu_package": solver.lu_package,
        "skipped_terms": model.skipped,
        "groups": model.groups.as_dict(),
        "python": platform.python_version(),
        "scene": scene.to_dict(),
    }
    n_steps = tspan.n_steps
    halvings = tspan.max_halvings
    whole = 2**halvings  # a nominal step in units of the smallest allowed sub-step
    step = 0  # nominal steps completed: outputs are written at start + step * time.step
    t = tspan.start
    t_loop = time.perf_counter()
    output_time = 0.0
    failure: SolverError | None = None
    previous = model.U.x.array.copy()  # the last accepted state (chart-crossing check)
    level, done = 0, 0  # current halving level; progress into the nominal step, in units
    rejected, smallest = 0, tspan.step
    try:
        while step < n_steps:
            units = whole >> level
            t_new = tspan.start + (step + (done + units) / whole) * tspan.step
            h = (t_new - t) * omega0
            try:
                integrator.step(h, solver.solve)
                check_state(model, t_new, previous=previous)
                cause = None
            except NewtonFailure as exc:
                s, _ = _worst_place(model, solver.b.array.reshape(-1, 12).max(axis=1))
                cause = SolverError(
                    time=t_new,
                    where=f"s = {s:.4g} m (largest residual)",
                    reason=f"Newton did not converge ({exc.reason}, {exc.iterations} iterations)",
                    suggestion="reduce time.step, or use solver.jacobian = 'full'",
                    retry=True,
                )
            except SolverError as exc:
                if not exc.retry:
                    raise
                cause = exc
            if cause is not None:
                # Reject the step and retry with half of it, at most time.max_halvings times.
                integrator.reject()
                rejected += 1
                if level >= halvings:
                    raise SolverError(
                        time=cause.time,
                        where=cause.where,
                        reason=f"{cause.reason}; the step was rejected {level} times, down to "
                        f"{tspan.step / 2**level:.3g} s (time.max_halvings = {halvings})",
                        suggestion=cause.suggestion,
                    )
                level += 1
                solver.request_jacobian()  # the Jacobian depends on the step size
                continue
            integrator.accept(h)
            previous[:] = model.U.x.array
            t = t_new
            smallest = min(smallest, tspan.step / 2**level)
            done += units
            if done < whole:
                continue
            step, done = step + 1, 0
            if level:
                level = 0
                solver.request_jacobian()
            t0 = time.perf_counter()
            if probes is not None:
                probes.write(t)
            if xdmf is not None and step % xdmf_every == 0:
                xdmf.write(t)
            for obs in observers:
                obs(step, t, model)
            output_time += time.perf_counter() - t0
    except SolverError as exc:
        failure = exc
    finally:
        loop_time = time.perf_counter() - t_loop
        if probes is not None:
            probes.close()
        if xdmf is not None:
            xdmf.close()
    summary.update(
        {
            "status": "failed" if failure else "completed",
            "message": str(failure) if failure else "",
            "steps": step,
            "time_reached_s": t,
            "rejected_steps": rejected,
            "smallest_step_s": smallest,
            "newton": solver.stats.as_dict(),
            "wall_time_s": {
                "setup": setup_time,
                "jit_compile": solver.compile_time,
                "solve_loop": loop_time,
                "solve_loop_without_output": loop_time - output_time,
                "output": output_time,
                "total": time.perf_counter() - t_start,
            },
        }
    )
    if write_outputs:
        write_json(out / "summary.json", summary, comm)
    solver.destroy()
    comm.barrier()  # every file is closed on every rank before anyone reads them
    if failure:
        raise failure
    return RunResult(out_dir=out, steps=step, time_reached=t, summary=summary, model=model)
