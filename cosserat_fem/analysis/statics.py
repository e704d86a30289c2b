"""Static equilibrium by load stepping: F(U, 0, τ; λ) = 0 for a load factor λ from 0 to 1.

All loads of the scene (distributed force and torque, end force and torque), evaluated at the
time ``static.time``, are multiplied by λ, and so are the angles of a structure's turned nodes
(``rotation`` α: the node turned by α(static.time) λ, RodModel.turn_nodes). The factor grows
in ``static.load_steps`` equal increments; each increment is a Newton solve from a secant predictor
U = U_n + (Δλ/Δλ_{n−1}) (U_n − U_{n−1}). An increment that fails (Newton divergence, a
non-finite state, or the Euler-angle chart's singularity cos θ → 0) is retried with half the
increment, down to 2^−``static.max_bisections`` of the nominal increment (then the run stops
with the reason); after a success the increment doubles again up to its nominal size. This
load control with step halving follows the equilibrium path up to, but not past, a limit
point; the rolled-up cantilever and the elastica have none.

The load stepping is a source of the events of cosserat_fem/timestepping/events.py with the load
factor λ in place of time (:class:`StaticLoop`), and its outputs are those observers of a dynamic
run: ``probes.csv`` (header ``t,x,y,z,theta,psi,phi``; for a static run the column ``t``
holds λ, one row per accepted load step, the last row the final state), ``solution.xdmf``
(one entry per accepted step, "time" = λ) and ``summary.json``. Every load step assembles
the Jacobian (full Newton): the matrix changes with the load.
"""

from __future__ import annotations

import time as clock
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from mpi4py import MPI

from cosserat_fem.analysis import budget
from cosserat_fem.analysis.observers import StandardObservers, summary_start
from cosserat_fem.analysis.simulation import drive
from cosserat_fem.common.errors import SceneError, SolverError
from cosserat_fem.common.log import LOGGER
from cosserat_fem.common.parallel import ranks_on_node
from cosserat_fem.io.folder_lock import holding_folders
from cosserat_fem.io.run_folder import new_run_id, prepare_output_dir
from cosserat_fem.nls.newton import NewtonFailure, NewtonSettings, NewtonSolver
from cosserat_fem.nls.solvers import make_solver
from cosserat_fem.output.fields import PointProbe, probe_sigma
from cosserat_fem.rod.checks import check_state, cos_theta
from cosserat_fem.rod.model import RodModel, build_model
from cosserat_fem.rod.obstacles import contact_rows
from cosserat_fem.scene.build import Scene, refuse_closed, refuse_contact
from cosserat_fem.timestepping.events import Events, Observer
from cosserat_fem.timestepping.integrators import make_integrator


@dataclass
class StaticResult:
    """The model (its U holds the final state), the load factors reached, the Newton
    iterations of each accepted load step, the bisections and the summary; with
    ``record=True`` the probe's rows (λ, x, y, z, θ, ψ, φ) [1, m, rad] at every load factor."""

    model: RodModel
    load_factors: list[float]
    iterations: list[int]
    bisections: int
    summary: dict
    probes: np.ndarray | None = field(default=None, repr=False)


@dataclass
class StaticState:
    """Where load stepping is: ``t`` the load factor λ of the last accepted state (in the
    place of time, for the observers), accepted load steps, bisections (``rejected``),
    output steps, the load factors reached (0 first) and the Newton iterations of each
    accepted step, the chart's moves."""

    t: float = 0.0
    accepted: int = 0
    rejected: int = 0
    outputs: int = 0
    factors: list[float] = field(default_factory=lambda: [0.0])
    iterations: list[int] = field(default_factory=list)
    chart_resets: int = 0

    def counts(self) -> dict:
        """The counters as summary.json reports them."""
        return {
            "load_factors": self.factors,
            "newton_iterations": self.iterations,
            "bisections": self.rejected,
            "chart_resets": self.chart_resets,
        }


class StaticLoop:
    """Load stepping of the module docstring, announcing each step to ``events``."""

    restarted = False
    end_reason = None  # it never ends early

    def __init__(
        self,
        model: RodModel,
        solver: NewtonSolver,
        scene: Scene,
        events: Events,
        start: float = 0.0,
        target: float = 1.0,
        steps: int | None = None,
    ):
        """From the state in ``model.U`` at load factor ``start`` to ``target`` (either side
        of it) in ``steps`` nominal increments (default static.load_steps)."""
        self.model, self.solver, self.scene, self.events = model, solver, scene, events
        self.state = StaticState(t=start, factors=[start])
        self.target = target
        self.steps = steps or scene.static.load_steps
        self.stepping_since: float | None = None  # time.perf_counter() at the first step
        self.stepping_until: float | None = None  # and after the last
        if events.listens("newton_iteration"):
            solver.iteration_hook = lambda it, norms, reason: events.newton_iteration(
                self, it, norms, reason
            )

    @property
    def completed(self) -> bool:
        return abs(self.target - self.state.t) <= 1e-14 * max(1.0, abs(self.target))

    def lift(self, rows: np.ndarray | None = None) -> None:
        """TimeLoop.lift's contract (the full state in U before an observer reads it): load
        stepping's U is always the full state, so nothing to do."""

    def _move_chart(self, U_n: np.ndarray) -> bool:
        """Before a load step: move the chart onto the rod's rotation (changing U_n in place)
        when |cos θ| < cos charts.RESET_THETA at some node, so that the step starts far from
        the chart's singularity (cosserat_fem/rod/charts.py). Returns whether it moved."""
        model = self.model
        if model.chart is None or model.chart_move_due(cos_theta(model, U_n)) is None:
            return False
        model.reset_chart(U_n)
        self.state.chart_resets += 1
        return True

    def back_to_accepted(self) -> None:
        """Nothing to do: a load step that fails restores the last accepted state itself."""

    def run(self) -> None:
        """The load steps from λ = start to target (0 to 1 by default), the increment halved on
        failure and doubled back after a success (module docstring); SolverError once one below
        2^−max_bisections of the nominal increment fails. U ends at the last accepted state."""
        model, solver, st, events = self.model, self.solver, self.state, self.events
        static = self.scene.static
        events.started(self)
        nominal = (self.target - st.t) / self.steps  # signed: the path may go down
        smallest = abs(nominal) / 2**static.max_bisections
        step, prev_step = nominal, None
        U_n = model.U.x.array.copy()
        U_nm1 = None
        self.stepping_since = clock.perf_counter()
        try:
            while not self.completed:
                if self._move_chart(U_n):
                    U_nm1 = None  # the secant predictor's old state is in the old chart
                lam = st.t
                trial = lam + step
                if (trial - self.target) * nominal > 0.0:  # past the target
                    trial = self.target
                events.step_attempted(self, trial)
                model.load_factor.value = trial
                if U_nm1 is not None and prev_step:
                    model.U.x.array[:] = U_n + (trial - lam) / prev_step * (U_n - U_nm1)
                else:
                    model.U.x.array[:] = U_n
                model.turn_nodes(static.time, trial)  # prescribed rotations: α λ
                try:
                    its = solver.solve()
                    events.solve_done(self, its)
                    check_state(
                        model,
                        static.time,
                        where_prefix=f"load factor {trial:.6g} (from {lam:.6g})",
                        before=cos_theta(model, U_n),
                    )
                    through = getattr(solver.contact, "interpenetration", lambda: None)()
                    if through is not None:  # self contact: the rod through itself
                        raise SolverError(
                            through[1], where=f"load factor {trial:.6g}, {through[0]}", retry=True
                        )
                except (NewtonFailure, SolverError) as exc:
                    st.rejected += 1
                    step *= 0.5
                    unsettled = (
                        solver.contact.unsettled()
                        if isinstance(exc, NewtonFailure) and solver.contact is not None
                        else ""
                    )
                    cause = (
                        exc
                        if isinstance(exc, SolverError)
                        else SolverError(
                            f"Newton did not converge ({exc.reason}, {exc.iterations} iterations)",
                            where=f"load factor {trial:.6g}",
                            retry=True,
                        )
                    )
                    events.step_rejected(self, cause)
                    if abs(step) < smallest * (1.0 - 1e-12):
                        raise SolverError(
                            time=None,
                            where=f"load factor {trial:.6g} (last converged {lam:.6g})",
                            reason=f"no load increment down to 1/{2**static.max_bisections} "
                            f"of the nominal one converges: {exc.reason}"
                            + (f" ({unsettled})" if unsettled else ""),
                            suggestion=getattr(exc, "suggestion", None)
                            or (
                                "the contact set does not settle: a rod that slides along most "
                                "of its contact may need a run in time (docs/contact.md)"
                                if unsettled
                                else "increase static.load_steps, or the load passes a limit point"
                            ),
                        ) from None
                    continue
                U_nm1, U_n = U_n, model.U.x.array.copy()
                if solver.contact is not None:  # the friction's history: this load step
                    solver.contact.accept(U_n)
                prev_step, st.t = trial - lam, trial
                step = 2.0 * step if abs(2.0 * step) < abs(nominal) else nominal
                st.accepted += 1
                st.outputs += 1
                st.factors.append(trial)
                st.iterations.append(its)
                events.step_accepted(self)
                events.output(self, st.outputs, trial)
                events.step_finished(self)
        finally:
            self.stepping_until = clock.perf_counter()
            model.U.x.array[:] = U_n  # the last accepted state


def check_static_scene(scene: Scene, command: str) -> None:
    """SceneError naming the key unless the scene has static states: an open rod (not
    reference.closed), held (not a mechanism), with no prescribed support motion."""
    refuse_closed(scene, command)
    if command != "static":
        refuse_contact(scene, command)
    if scene.structure is not None and scene.mechanism:
        raise SceneError(
            "structure.supports: a static equilibrium needs the structure held; its supports "
            "leave it a mechanism, whose rigid-body motion no load stops"
        )
    if scene.supports.mechanism and scene.structure is None and scene.contact is None:
        raise SceneError(
            f'supports: a static equilibrium needs the rod held (start = "{scene.supports.start}"'
            f', end = "{scene.supports.end}" leave it a mechanism, whose rigid-body motion no '
            "load stops); clamp one end or pin both, or follow its motion with run"
        )
    if scene.supports.start_motion or scene.supports.end_motion:
        raise SceneError(
            "supports.*_motion: prescribed support motion is for time integration (run), "
            "not for static solves"
        )


def static_solver(scene: Scene, model: RodModel) -> NewtonSolver:
    """Full Newton on the static residual F(U, 0, τ; λ) of ``model`` (λ: model.load_factor),
    the loads evaluated at static.time; SceneError if a load is not finite there."""
    problem = model.nonfinite_load([scene.static.time])
    if problem:
        raise SceneError(f"{problem}: the load is not finite there (static.time)")
    integrator = make_integrator("static", model.U, model.residual, 0.0)
    settings = NewtonSettings.of(scene.solver)
    if settings.jacobian != "full":
        # The matrix changes with every load increment, and the large-deflection tests rely on
        # full Newton's quadratic end (a reused matrix left roll-up gaps of 7e-8).
        LOGGER.info("static: full Newton (solver.jacobian = %r is for runs)", settings.jacobian)
    settings = replace(settings, jacobian="full")
    contact = contact_rows(model)
    solver = make_solver(
        integrator.residual_form(), model.U, model.bcs, settings, model.constraints, contact
    )
    if contact is not None:
        contact.accept(model.U.x.array, initial=True)  # the friction's history starts here
    integrator.prepare(scene.static.time * model.omega0)
    model.sync_loads(integrator.time_eval)  # loads given by data, at static.time
    return solver


@holding_folders
def static_path(
    scene: Scene,
    out_dir: str | Path | None = None,
    comm: MPI.Comm = MPI.COMM_WORLD,
    write_outputs: bool = True,
    observers: Sequence[Observer | Callable] = (),
    record: bool = False,
) -> StaticResult:
    """Follow the static equilibrium path from the straight rod to the full loads (module
    docstring); ``observers`` as for cosserat_fem.analysis.simulation.run_scene, with λ in place of
    t;
    ``record``: keep the probe's rows in memory (``StaticResult.probes``)."""
    t_start = clock.perf_counter()
    out = Path(out_dir if out_dir is not None else scene.output.directory)
    budget.check(
        scene, "static", out if write_outputs else None, ranks_on_node(comm), comm.size, comm=comm
    )
    check_static_scene(scene, "static")
    if write_outputs:
        prepare_output_dir(out, comm, lock="static")
    model = build_model(scene, comm)
    if model.needs_chart:
        model.use_chart()  # rotations of any size (cosserat_fem/rod/charts.py)
    solver = static_solver(scene, model)
    probe = PointProbe(model, probe_sigma(scene), fields=scene.output.probe_fields)
    summary = summary_start(
        "static", scene, comm, model, probe, solver, new_run_id(comm), probe_t_column="load factor"
    )
    chain = StandardObservers(
        scene,
        model,
        solver,
        probe,
        summary,
        comm,
        t_start,
        out if write_outputs else None,
        xdmf_every=1,
        observers=observers,
        record=record,
    )
    loop = StaticLoop(model, solver, scene, chain.events)
    failure = drive(loop)
    comm.barrier()
    if failure:
        raise failure
    st = loop.state
    rows = chain.recorder.rows() if chain.recorder is not None else None
    return StaticResult(model, st.factors, st.iterations, st.rejected, summary, rows)


def solve_static(scene: Scene, comm: MPI.Comm = MPI.COMM_WORLD) -> tuple[RodModel, int]:
    """Static equilibrium under the scene's loads, without writing outputs.

    Returns the model (``model.U`` holds the solution) and the total Newton iterations.
    """
    result = static_path(scene, comm=comm, write_outputs=False)
    return result.model, sum(result.iterations)
