"""Static equilibrium by load stepping: F(U, 0, τ; λ) = 0 for a load factor λ from 0 to 1.

All loads of the scene (distributed force and torque, end force and torque), evaluated at the
time ``static.time``, are multiplied by λ. The factor grows in ``static.load_steps`` equal
increments; each increment is a Newton solve from a secant predictor
U = U_n + (Δλ/Δλ_{n−1}) (U_n − U_{n−1}). An increment that fails (Newton divergence, a
non-finite state, or the Euler-angle chart's singularity cos θ → 0) is retried with half the
increment, down to 2^−``static.max_bisections`` of the nominal increment (then the run stops
with the reason); after a success the increment doubles again up to its nominal size. This
load control with step halving follows the equilibrium path up to, but not past, a limit
point; the rolled-up cantilever and the elastica have none.

Outputs are those of a dynamic run with the load factor in place of time: ``probes.csv``
(header ``t,x,y,z,theta,psi,phi``; for a static run the column ``t`` holds λ, one row per
accepted load step, the last row the final state), ``solution.xdmf`` (one entry per accepted
step, "time" = λ) and ``summary.json``.
"""

from __future__ import annotations

import time as clock
from dataclasses import dataclass
from pathlib import Path

from mpi4py import MPI

from . import __version__, budget
from .errors import OutputError, SceneError, SolverError
from .integrators import make_integrator
from .model import RodModel, build_model
from .newton import NewtonFailure, NewtonSolver
from .output import PointProbe, ProbeWriter, XdmfWriter
from .parallel import ranks_on_node
from .progress import LOGGER
from .run_folder import PROBES, SUMMARY, XDMF, claim, new_run_id, prepare_output_dir, write_summary
from .scene import Scene
from .simulation import check_state, cos_theta, newton_settings, probe_sigma


@dataclass
class StaticResult:
    model: RodModel
    load_factors: list[float]
    iterations: list[int]
    bisections: int
    summary: dict


def static_path(
    scene: Scene,
    out_dir: str | Path | None = None,
    comm: MPI.Comm = MPI.COMM_WORLD,
    write_outputs: bool = True,
) -> StaticResult:
    """Follow the static equilibrium path from the straight rod to the full loads."""
    t_start = clock.perf_counter()
    out = Path(out_dir if out_dir is not None else scene.output.directory)
    budget.check(scene, "static", out if write_outputs else None, ranks_on_node(comm), comm.size)
    if scene.supports.start_motion or scene.supports.end_motion:
        raise SceneError(
            "supports.*_motion: prescribed support motion is for time integration (run), "
            "not for static solves"
        )
    if write_outputs:
        prepare_output_dir(out, comm)
    model = build_model(scene, comm)
    problem = model.nonfinite_load([scene.static.time])
    if problem:
        raise SceneError(f"{problem}: the load is not finite there (static.time)")
    integrator = make_integrator("static", model.U, model.residual, 0.0)
    settings = newton_settings(scene)
    if settings.jacobian != "full":
        # The matrix changes with every load increment, and the large-deflection tests rely on
        # full Newton's quadratic end (a reused matrix left roll-up gaps of 7e-8).
        LOGGER.info("static: full Newton (solver.jacobian = %r is for runs)", settings.jacobian)
    settings.jacobian = "full"
    solver = NewtonSolver(integrator.residual_form(), model.U, model.bcs, settings)
    integrator.prepare(scene.static.time * model.omega0)

    summary = {
        "status": "running",
        "run_id": new_run_id(comm),
        "kind": "static",
        "probe_t_column": "load factor",
        "cosserat_fem": __version__,
        "scene_file": scene.source,
        "mpi_ranks": comm.size,
        "dofs": model.global_dofs(),
        "newton": "full",
        "scene": scene.to_dict(),
    }
    probes = xdmf = None
    if write_outputs:
        claim(out, comm, scene.output.xdmf, summary)
        try:
            probes = ProbeWriter(
                out / PROBES, PointProbe(model, probe_sigma(scene))
            )
            probes.write(0.0)
            if scene.output.xdmf:
                xdmf = XdmfWriter(out / XDMF, model, run_id=summary["run_id"])
                xdmf.write(0.0)
        except OutputError:
            if probes is not None:
                probes.close()
            solver.destroy()
            raise

    nominal = 1.0 / scene.static.load_steps
    smallest = nominal / 2**scene.static.max_bisections
    lam, step, prev_step = 0.0, nominal, None
    U_n = model.U.x.array.copy()
    U_nm1 = None
    factors, iterations, bisections = [0.0], [], 0
    failure = None
    try:
        while lam < 1.0 - 1e-14:
            trial = min(lam + step, 1.0)
            model.load_factor.value = trial
            if U_nm1 is not None and prev_step:
                model.U.x.array[:] = U_n + (trial - lam) / prev_step * (U_n - U_nm1)
            else:
                model.U.x.array[:] = U_n
            try:
                its = solver.solve()
                check_state(
                    model,
                    scene.static.time,
                    where_prefix=f"load factor {trial:.6g} (from {lam:.6g})",
                    before=cos_theta(model, U_n),
                )
            except (NewtonFailure, SolverError) as exc:
                bisections += 1
                step *= 0.5
                if step < smallest * (1.0 - 1e-12):
                    raise SolverError(
                        time=None,
                        where=f"load factor {trial:.6g} (last converged {lam:.6g})",
                        reason=f"no load increment down to 1/{2**scene.static.max_bisections} of "
                        f"the nominal one converges: {exc.reason}",
                        suggestion=getattr(exc, "suggestion", None)
                        or "increase static.load_steps, or the load passes a limit point",
                    ) from None
                continue
            U_nm1, U_n = U_n, model.U.x.array.copy()
            prev_step, lam = trial - lam, trial
            step = min(2.0 * step, nominal)
            factors.append(lam)
            iterations.append(its)
            if probes is not None:
                probes.write(lam)
                if comm.size > 1:
                    probes.check()
            if xdmf is not None:
                if probes is not None:
                    probes.flush()  # probes.csv reaches every frame on disk (kill-safe)
                xdmf.write(lam)
    except (SolverError, OutputError) as exc:
        failure = exc
        model.U.x.array[:] = U_n
    finally:
        try:
            if probes is not None:
                probes.close()
                probes.check()
        except OutputError as exc:
            failure = failure or exc
        if xdmf is not None:
            xdmf.close()
        solver.destroy()
    summary.update(
        {
            "status": ("stopped" if isinstance(failure, OutputError) else "failed")
            if failure
            else "completed",
            "message": str(failure) if failure else "",
            "load_factors": factors,
            "newton_iterations": iterations,
            "bisections": bisections,
            "wall_time_s": {"total": clock.perf_counter() - t_start},
        }
    )
    if write_outputs:
        write_summary(out / SUMMARY, summary, comm, strict=failure is None)
    comm.barrier()
    if failure:
        raise failure
    return StaticResult(model, factors, iterations, bisections, summary)


def solve_static(scene: Scene, comm: MPI.Comm = MPI.COMM_WORLD) -> tuple[RodModel, int]:
    """Static equilibrium under the scene's loads, without writing outputs.

    Returns the model (``model.U`` holds the solution) and the total Newton iterations.
    """
    result = static_path(scene, comm=comm, write_outputs=False)
    return result.model, sum(result.iterations)
