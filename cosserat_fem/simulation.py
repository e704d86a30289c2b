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

from . import __version__, budget
from .adaptive import SHRINK, StateHistory, StepController
from .checkpoint import Checkpoint, CheckpointWriter, check_outputs, cut_outputs
from .errors import LimitReached, OutputError, SceneError, SolverError, StopError
from .integrators import GeneralizedAlpha, make_integrator
from .model import RodModel, build_model
from .newton import NewtonFailure, NewtonSettings, NewtonSolver
from .output import PointProbe, ProbeWriter, XdmfWriter
from .parallel import ranks_on_node
from .progress import LOGGER
from .run_folder import (
    PROBES,
    SUMMARY,
    XDMF,
    claim,
    new_run_id,
    prepare_output_dir,
    write_summary,
)
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


def cos_theta(model: RodModel, state: np.ndarray) -> np.ndarray:
    """cos θ at the owned nodes of a state array (det Ma = cos θ, (66); 1 if θ ≡ 0 is not
    solved for)."""
    n = model.V.dofmap.index_map.size_local
    theta = model.layout.index(3)
    if theta is None:
        return np.ones(n)
    return np.cos(state.reshape(-1, model.layout.size)[:n, theta])


def check_state(
    model: RodModel, t: float | None, where_prefix: str = "", before: np.ndarray | None = None
) -> np.ndarray:
    """Stop with a SolverError if U is not finite, if the Euler-angle chart is (nearly)
    singular, |cos θ| < ``CHART_COS_MIN``, or, given cos θ of the previous accepted state
    (``before``, from :func:`cos_theta` or an earlier call), if θ crossed ±π/2 at some node
    since then (cos θ changed sign: a step jumped over the singularity, through which no
    continuous motion passes, det Ma = cos θ (66)). Returns cos θ of U at the owned nodes."""
    blocks = model.U.x.array.reshape(-1, model.layout.size)
    n = model.V.dofmap.index_map.size_local
    cos_now = cos_theta(model, model.U.x.array)
    # One number and (in parallel) one reduction per step: the smallest |cos θ|; −0.5 if θ
    # crossed ±π/2, −1 if any owned value is not finite (a NaN or inf makes the sum so).
    value = 1.0
    if n:
        value = float(np.abs(cos_now).min())
        if before is not None and float((before * cos_now).min()) <= 0.0:
            value = -0.5
        if not math.isfinite(value + float(blocks[:n].sum())):
            value = -1.0
    comm = model.msh.comm
    if comm.size > 1:
        value = comm.allreduce(value, op=MPI.MIN)
    if value >= CHART_COS_MIN:
        return cos_now
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
        s, _ = _worst_place(model, np.where(before * cos_now <= 0.0, 1.0, 0.0))
        raise SolverError(
            time=t,
            where=f"{prefix}s = {s:.4g} m",
            reason="Euler-angle chart singular: θ crossed ±π/2 within the step "
            "(det Ma = cos θ changed sign)",
            suggestion=CHART_SUGGESTION,
            retry=True,
        )
    cos_all = np.cos(model.layout.full_array(model.U.x.array)[:, 3])
    s, _ = _worst_place(model, 1.0 / np.maximum(np.abs(cos_all), 1e-300))
    raise SolverError(
        time=t,
        where=f"{prefix}s = {s:.4g} m",
        reason=(
            f"Euler-angle chart singular: |cos θ| = {value:.2e} "
            "(θ near ±π/2, where det Ma = cos θ vanishes)"
        ),
        suggestion=CHART_SUGGESTION,
    )


class _Outputs:
    """Probes, XDMF frames and observers at the output grid t_k = start + k time.step.

    ``state``, when given, is the (interpolated) state array at t_k; model.U is swapped for
    it while the outputs read it, then restored.
    """

    def __init__(self, model: RodModel, probes, xdmf, xdmf_every: int, observers):
        self.model, self.probes, self.xdmf = model, probes, xdmf
        self.xdmf_every, self.observers = xdmf_every, observers
        self.time = 0.0  # wall time spent in outputs

    def __call__(self, k: int, t: float, state: np.ndarray | None = None) -> None:
        t0 = time.perf_counter()
        u = self.model.U.x.array
        kept = None
        if state is not None:
            kept = u.copy()
            u[:] = state
        if self.probes is not None:
            self.probes.write(t)
            if self.probes.comm.size > 1:
                self.probes.check()  # the owner's write error, on every rank
        if self.xdmf is not None and k % self.xdmf_every == 0:
            if self.probes is not None:
                self.probes.flush()  # probes.csv reaches every frame on disk (kill-safe)
            self.xdmf.write(t)
        for obs in self.observers:
            obs(k, t, self.model)
        if kept is not None:
            u[:] = kept
        self.time += time.perf_counter() - t0


#: Accepted steps between two looks at the clock for limits.wall_time.
DEADLINE_EVERY = 64


class _Stepper:
    """One attempted step of the integrator with the state checks, and the step counters."""

    def __init__(self, model: RodModel, integrator, solver: NewtonSolver, deadline: float):
        """``deadline``: the time.perf_counter() value at which the run stops with a
        checkpoint (limits.wall_time)."""
        self.model, self.integrator, self.solver = model, integrator, solver
        self.deadline = deadline
        self._ticks = 0
        self.omega0 = model.omega0
        self.cos_accepted = cos_theta(model, model.U.x.array)  # chart-crossing check
        self._cos_candidate = self.cos_accepted
        self.t = integrator.time / self.omega0
        self.accepted = self.rejected = self.outputs = 0
        self.smallest = self.largest = None
        self.pending = False  # a step was attempted and neither accepted nor rejected

    def _solve(self) -> int:
        """One Newton solve, with moving supports at the time of the unknown: their values
        are put into the initial guess too (the Jacobian's rows and columns of held dofs are
        those of the identity, so a guess off them costs Newton an iteration)."""
        self.model.support_dofs_to(self.model.U.x.array, self.integrator.unknown_time)
        return self.solver.solve()

    _COUNTERS = ("t", "accepted", "rejected", "outputs", "smallest", "largest")

    def state_dict(self) -> dict:
        return {k: np.nan if getattr(self, k) is None else getattr(self, k) for k in self._COUNTERS}

    def load_state_dict(self, state: dict) -> None:
        for k in self._COUNTERS:
            value = float(state[k])
            value = None if math.isnan(value) else value
            setattr(self, k, int(value) if k in ("accepted", "rejected", "outputs") else value)
        self.cos_accepted = self._cos_candidate = cos_theta(self.model, self.model.U.x.array)

    def back_to_accepted(self) -> None:
        """U back to the last accepted state if a step is pending (a run that stops)."""
        if self.pending:
            self.integrator.reject()
            self.pending = False

    def attempt(self, t_new: float) -> SolverError | None:
        """Take a step to t_new [s]; None if it converged and the state is fine, else the
        retryable SolverError (U is then left as the integrator made it: reject or accept)."""
        self.pending = True
        try:
            self.integrator.step((t_new - self.t) * self.omega0, self._solve)
            # A method whose new state is not its last stage (SDIRK3/4) meets a moving
            # support's values only to its order: put them in exactly.
            self.model.support_dofs_to(self.model.U.x.array, t_new * self.omega0)
            self._cos_candidate = check_state(self.model, t_new, before=self.cos_accepted)
        except NewtonFailure as exc:
            self._blame_loads(t_new)
            blocks = self.model.layout.size
            residual = np.abs(self.solver.b.array.reshape(-1, blocks)).max(axis=1)
            s, _ = _worst_place(self.model, residual)
            reason = f"Newton did not converge ({exc.reason}, {exc.iterations} iterations)"
            suggestion = "reduce time.step, or use solver.jacobian = 'full'"
            if exc.reason == "DIVERGED_FNORM_NAN" and exc.iterations == 0:
                # Not finite before any iteration: the loads and the state are finite (checked
                # above), so their products with the groups (48) leave double precision.
                reason += ": the residual is not finite at the start of the step"
                suggestion = "check the magnitude of the loads"
            return SolverError(
                time=t_new,
                where=f"s = {s:.4g} m (largest residual)",
                reason=reason,
                suggestion=suggestion,
                retry=True,
            )
        except SolverError as exc:
            if not exc.retry:
                raise
            self._blame_loads(t_new)
            return exc
        return None

    def _blame_loads(self, t_new: float) -> None:
        """A SceneError naming the load that is not finite during the step to t_new [s], if
        one is: then no smaller step can help (collective)."""
        stage = self.integrator.unknown_time / self.omega0
        problem = self.model.nonfinite_load([self.t, 0.5 * (self.t + t_new), stage, t_new])
        if problem:
            raise SceneError(f"{problem}: the load is not finite there")

    def accept(self, t_new: float) -> None:
        h = t_new - self.t
        self.integrator.accept(h * self.omega0)
        self.pending = False
        self.cos_accepted = self._cos_candidate
        self.t = t_new
        self.accepted += 1
        self.smallest = h if self.smallest is None else min(self.smallest, h)
        self.largest = h if self.largest is None else max(self.largest, h)

    def check_deadline(self) -> None:
        """LimitReached once past the deadline. Called by the loops where their state is
        whole (after an output step, so that the checkpoint taken on the way out continues
        exactly); looks at the clock every ``DEADLINE_EVERY`` calls, every rank alike (rank
        0's clock decides)."""
        self._ticks += 1
        if self._ticks % DEADLINE_EVERY:
            return
        comm = self.model.msh.comm
        stop = time.perf_counter() > self.deadline
        if comm.size > 1:
            stop = comm.bcast(stop, root=0)
        if stop:
            wall = self.model.scene.limits.wall_time
            raise LimitReached(
                f"limits.wall_time: the run stopped at t = {self.t:.6g} s after its limit of "
                f"{wall:g} s of wall time; continue it with run --restart DIR "
                "(--set limits.wall_time=... to allow more)"
            )

    def reject(self) -> None:
        self.integrator.reject()
        self.pending = False
        self.rejected += 1

    def counts(self) -> dict:
        return {
            "steps": self.outputs,
            "time_reached_s": self.t,
            "accepted_steps": self.accepted,
            "rejected_steps": self.rejected,
            "smallest_step_s": self.smallest,
            "largest_step_s": self.largest,
        }


class _Checkpoints:
    """Saves the whole state of a run (cosserat_fem/checkpoint.py) when due and at its end.

    ``loop`` is the time loop's own state: numbers, and objects with a ``state_dict``.
    """

    def __init__(self, writer: CheckpointWriter | None, stepper: _Stepper, probes, xdmf):
        self.writer, self.stepper, self.probes, self.xdmf = writer, stepper, probes, xdmf
        self._saved_at: float | None = None

    def maybe(self, loop: dict) -> None:
        if self.writer is not None and self.writer.due(self.stepper.t):
            self.save(loop)

    def save(self, loop: dict) -> None:
        stepper = self.stepper
        if self.writer is None or self._saved_at == stepper.t:
            return
        parts = {
            "state": {"U": stepper.model.U.x.array.copy()},
            "integrator": stepper.integrator.state_dict(),
            "newton": stepper.solver.state_dict(),
            "stepper": stepper.state_dict(),
            "loop": {k: v for k, v in loop.items() if not hasattr(v, "state_dict")},
            **{k: v.state_dict() for k, v in loop.items() if hasattr(v, "state_dict")},
        }
        digest = self.probes.digest()  # on the probe's owner, which may not be rank 0
        comm = stepper.model.msh.comm
        if comm.size > 1:
            self.probes.check()
            digest = comm.bcast(digest, root=self.probes.probe.owner)
        outputs = {
            "probe_rows": stepper.outputs + 1,
            "probes_sha256": digest,
            "xdmf_frames": None if self.xdmf is None else self.xdmf.writes,
        }
        self.writer.save(stepper.t, parts, outputs)
        self._saved_at = stepper.t
        LOGGER.info("checkpoint %d at t = %.6g s", self.writer.generation, stepper.t)


def _fixed_loop(tspan, stepper: _Stepper, emit: _Outputs, save: _Checkpoints, loop: dict) -> None:
    """Steps of time.step; a failed step is retried with half of it, at most
    time.max_halvings times, and the next nominal step is full again. ``loop`` holds the
    halving level and the part of the nominal step done (a restart's, then kept current)."""
    halvings = tspan.max_halvings
    whole = 2**halvings  # a nominal step in units of the smallest allowed sub-step
    # Halving level; progress into the nominal step, in those units.
    level = min(int(loop.get("level", 0)), halvings)
    done = float(loop.get("done", 0.0)) * whole
    if done != int(done):
        raise SceneError(
            f"time.max_halvings: the checkpoint stopped {done / whole:g} into a step, which "
            f"steps of 2^-{halvings} cannot reach; use at least the first run's value"
        )
    done = int(done)
    while stepper.outputs < tspan.n_steps:
        loop["level"], loop["done"] = level, done / whole
        units = whole >> level
        t_new = tspan.start + (stepper.outputs + (done + units) / whole) * tspan.step
        cause = stepper.attempt(t_new)
        if cause is not None:
            stepper.reject()
            LOGGER.info("step to t = %.6g s rejected (%s), level %d", t_new, cause.reason, level)
            if level >= halvings:
                raise SolverError(
                    time=cause.time,
                    where=cause.where,
                    reason=f"{cause.reason}; the step was rejected {level} times, down to "
                    f"{tspan.step / 2**level:.3g} s (time.max_halvings = {halvings})",
                    suggestion=cause.suggestion,
                )
            level += 1
            stepper.solver.request_jacobian()  # the Jacobian depends on the step size
            continue
        stepper.accept(t_new)
        done += units
        if done < whole:
            continue
        stepper.outputs, done = stepper.outputs + 1, 0
        if level:
            level = 0
            stepper.solver.request_jacobian()
        emit(stepper.outputs, stepper.t)
        loop["level"], loop["done"] = 0, 0.0
        save.maybe(loop)
        stepper.check_deadline()


MAX_CONSECUTIVE_REJECTIONS = 12


def _adaptive_loop(
    tspan, stepper: _Stepper, emit: _Outputs, save: _Checkpoints, loop: dict, resume=None
) -> None:
    """Steps chosen by the local error estimate of cosserat_fem.adaptive; outputs on the grid
    start + k time.step by interpolation. ``resume``: a checkpoint's parts to continue from."""
    model, solver = stepper.model, stepper.solver
    order = stepper.integrator.order
    layout = model.layout
    n_owned = model.V.dofmap.index_map.size_local * layout.size
    # The error of p (the first entries of each block) is controlled, not that of the rates q
    # (cosserat_fem.adaptive).
    control = StepController(
        tspan.rtol,
        tspan.atol,
        order,
        model.msh.comm,
        n_owned,
        block=layout.size,
        controlled=slice(0, layout.p_count),
        counted=6,  # the six fields of p, also when a planar model solves three of them
    )
    history = StateHistory(capacity=order + 2)
    span = tspan.end - tspan.start
    h_max = tspan.max_step or span
    h_min = 1e-12 * span
    if resume is None:
        history.push(stepper.t, model.U.x.array)
        h = min(tspan.step, h_max)
    else:
        history.load_state_dict(resume["history"])
        control.load_state_dict(resume["control"])
        h = float(resume["loop"]["h"])
    loop.update(history=history, control=control, h=h)
    consecutive = 0
    while stepper.t < tspan.end - 1e-12 * span:
        loop["h"] = h
        h = min(h, tspan.end - stepper.t)
        t_new = stepper.t + h
        cause = stepper.attempt(t_new)
        error = None
        if cause is None and len(history) == order + 2:
            u = model.U.x.array
            error = control.error_norm(u - history.polynomial(t_new, order + 2), u)
        if cause is not None or (error is not None and error > 1.0):
            stepper.reject()
            LOGGER.info(
                "step to t = %.6g s rejected: %s",
                t_new,
                cause.reason if cause else f"error estimate {error:.3g} > 1",
            )
            control.reject()
            consecutive += 1
            h *= control.factor(error, rejected=True) if cause is None else SHRINK
            if consecutive > MAX_CONSECUTIVE_REJECTIONS or h < h_min:
                reason = cause.reason if cause else f"local error estimate {error:.3g} > 1"
                raise SolverError(
                    time=t_new,
                    where=cause.where if cause else None,
                    reason=f"{reason}; {consecutive} steps rejected in a row, the last "
                    f"{h:.3g} s (time.rtol = {tspan.rtol:g})",
                    suggestion=cause.suggestion if cause else "loosen time.rtol/time.atol",
                )
            solver.request_jacobian()  # the Jacobian depends on the step size
            loop["h"] = h
            continue
        consecutive = 0
        stepper.accept(t_new)
        history.push(t_new, model.U.x.array)
        control.accept(model.U.x.array)
        while stepper.outputs < tspan.n_steps:
            t_k = tspan.start + (stepper.outputs + 1) * tspan.step
            if t_k > t_new + 1e-9 * tspan.step:
                break
            stepper.outputs += 1
            exact = abs(t_k - t_new) <= 1e-9 * tspan.step
            emit(stepper.outputs, t_k, None if exact else history.polynomial(t_k, 4))
        if error is not None:
            h_next = min(h * control.factor(error), h_max)
            if h_next != h:
                # A new Jacobian for the new step: one kept across a change of ±25 % made
                # modified Newton contract 4x per iteration only, and the frozen policy then
                # refreshed it anyway (measured: fewer iterations, the same run time).
                solver.request_jacobian()
            h = h_next
        loop["h"] = h
        save.maybe(loop)
        stepper.check_deadline()


def _consistent_rate(integrator: GeneralizedAlpha, model: RodModel, lu_package: str) -> None:
    """U̇_0 from F(U_0, U̇_0, τ_0) = 0, affine in U̇_0 (one linear solve).

    Assembled and solved through the API, not dolfinx's ``LinearProblem``: that sets three
    PETSc options per instance and never removes them, and PETSc 3.18 holds 512, so a process
    that runs ~170 scenes (the work-precision benchmark) would fail with error 55.
    """
    a, L, W = integrator.initial_rate_problem()
    a_form, L_form = fem.form(a), fem.form(L)
    model.move_supports(integrator.time, rates=True)  # moving supports: U̇ = their rates
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
    model.move_supports(integrator.time)
    integrator.set_initial_rate(W.x.array)
    for obj in (ksp, A, b):
        obj.destroy()


def _leaves_plane(model: RodModel, state: np.ndarray) -> bool:
    """Whether a planar model was given a 12-component state with an out-of-plane component
    (y, θ, φ for x-z; x, ψ, φ for y-z) or a rate of one non-zero (collective)."""
    nodes, layout = model.nodes, model.layout
    full = layout.reduced and np.size(state) == 12 * nodes
    out = [i for i in range(12) if i not in layout.components]
    local = full and bool(np.any(np.asarray(state).reshape(nodes, 12)[:, out] != 0.0))
    return model.msh.comm.allreduce(local, op=MPI.LOR)


def run(
    scene: Scene,
    out_dir: str | Path | None = None,
    comm: MPI.Comm = MPI.COMM_WORLD,
    observers: tuple[Observer, ...] = (),
    write_outputs: bool = True,
    initial_state: np.ndarray | None = None,
    restart: Checkpoint | None = None,
    progress: Callable[[float, int, int], None] | None = None,
) -> RunResult:
    """Integrate the scene over its time span; see the module docstring.

    The rod starts from rest in its straight state, or from ``initial_state`` (the array of a
    12-component state U = (p, q) on the same discretisation, e.g. a static solution), or
    continues the run of the checkpoint ``restart`` in its folder (cosserat_fem/checkpoint.py;
    ``scene`` is then the checkpoint's, with the overrides a restart allows). ``progress``
    is called with (t [s], steps taken, Newton iterations) after every output step.

    Before any work the scene's cost is checked against its limits (cosserat_fem/budget.py)
    and, on a restart, the folder's outputs against the checkpoint: nothing is touched
    unless the run can go on. Raises SolverError (numerical trouble), StopError (an output
    that cannot be written, a limit reached) or SceneError (bad input).
    """
    t_start = time.perf_counter()
    if restart is not None:
        out_dir, write_outputs = restart.run_dir, True
    out = Path(out_dir if out_dir is not None else scene.output.directory)
    tspan = scene.time
    budget.check(
        scene,
        "run",
        out if write_outputs else None,
        ranks_on_node(comm),
        comm.size,
        start=restart.time if restart is not None else None,
    )
    plan = None
    if write_outputs:
        prepare_output_dir(out, comm)
        if restart is not None:  # checked before anything is built or touched
            xdmf_path = out / XDMF if scene.output.xdmf else None
            plan = check_outputs(restart, out / PROBES, xdmf_path, comm)
    model = build_model(scene, comm)
    if initial_state is not None and _leaves_plane(model, initial_state):
        model = build_model(scene, comm, planar=False)  # it keeps all twelve unknowns
    if restart is not None:
        model.U.x.array[:] = restart.parts["state"]["U"]
    elif initial_state is not None:
        model.U.x.array[:] = model.layout.from_full(initial_state, model.nodes)
    elif scene.initial.fields():
        model.U.x.array[:] = model.initial_state()
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
    if restart is not None:
        integrator.load_state_dict(restart.parts["integrator"])
        solver.load_state_dict(restart.parts["newton"])
    elif isinstance(integrator, GeneralizedAlpha):
        _consistent_rate(integrator, model, solver.lu_package)

    probe = PointProbe(model, probe_sigma(scene))
    summary = {
        "status": "running",
        "run_id": restart.run_id if restart is not None else new_run_id(comm),
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
        "restarted_from_s": restart.time if restart is not None else None,
        "restarts": restart.restart_number if restart is not None else 0,
        "skipped_terms": model.skipped,
        "solved_unknowns": list(model.layout.names),
        "groups": model.groups.as_dict(),
        "python": platform.python_version(),
        "scene": scene.to_dict(),
    }
    stepper = _Stepper(model, integrator, solver, t_start + scene.limits.wall_time)
    loop_state: dict = {}
    if restart is not None:
        stepper.load_state_dict(restart.parts["stepper"])
        loop_state.update(restart.parts["loop"])
    if progress is not None:
        observers = (
            *observers,
            lambda k, t, m: progress(t, stepper.accepted, solver.stats.iterations),
        )
    outputs = _RunOutputs(scene, model, probe, out, summary, comm) if write_outputs else None
    failure: SolverError | StopError | None = None
    setup_time = loop_time = 0.0
    emit = _Outputs(model, None, None, scene.output.xdmf_every(tspan.step), observers)
    save = _Checkpoints(None, stepper, None, None)
    try:
        if outputs is not None:
            outputs.open(restart, plan)
            emit.probes, emit.xdmf = outputs.probes, outputs.xdmf
            save = _Checkpoints(outputs.checkpoints, stepper, outputs.probes, outputs.xdmf)
        setup_time = time.perf_counter() - t_start
        t_loop = time.perf_counter()
        try:
            if tspan.adaptive:
                parts = restart.parts if restart is not None else None
                _adaptive_loop(tspan, stepper, emit, save, loop_state, resume=parts)
            else:
                _fixed_loop(tspan, stepper, emit, save, loop_state)
        finally:
            loop_time = time.perf_counter() - t_loop
    except (SolverError, StopError, SceneError) as exc:
        failure = exc
    finally:
        failure = _finish(stepper, save, loop_state, outputs, failure, tspan.n_steps)
    output_time = emit.time
    summary.update(
        {
            "status": _status(failure),
            "message": str(failure) if failure else "",
            **stepper.counts(),
            "checkpoints_written": save.writer.written if save.writer else 0,
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
    if outputs is not None and outputs.opened:
        write_summary(out / SUMMARY, summary, comm, strict=failure is None)
    solver.destroy()
    comm.barrier()  # every file is closed on every rank before anyone reads them
    if failure:
        raise failure
    return RunResult(
        out_dir=out,
        steps=summary["steps"],
        time_reached=summary["time_reached_s"],
        summary=summary,
        model=model,
    )


def _status(failure: Exception | None) -> str:
    if failure is None:
        return "completed"
    return "stopped" if isinstance(failure, StopError) else "failed"


def _finish(stepper, save, loop_state, outputs, failure, n_steps: int):
    """The end of a run, stopped or not: a last checkpoint of the last accepted state (to
    continue or extend the run), unless an output failed (the outputs then end before the
    steps taken: the last periodic checkpoint stands); the outputs closed. Returns the
    failure to report (a failed last checkpoint if there was none)."""
    ended = failure is not None or stepper.outputs == n_steps
    if ended and not isinstance(failure, OutputError):
        stepper.back_to_accepted()
        try:
            save.save(loop_state)
        except OutputError as exc:
            failure = failure or exc
    if outputs is not None:
        try:
            outputs.close()
        except OutputError as exc:
            failure = failure or exc
    return failure


class _RunOutputs:
    """The files of a run in its folder: probes.csv, the XDMF pair, the checkpoints."""

    def __init__(self, scene: Scene, model: RodModel, probe, out: Path, summary: dict, comm):
        self.scene, self.model, self.probe = scene, model, probe
        self.out, self.summary, self.comm = out, summary, comm
        self.probes = self.xdmf = self.checkpoints = None
        self.opened = False

    def open(self, restart: Checkpoint | None, plan) -> None:
        """A new run claims the folder (cosserat_fem/run_folder.py); a restart cuts the
        outputs back to its checkpoint (checked already: ``plan``). Then summary.json says
        "running", and the writers open."""
        scene, model, out, comm = self.scene, self.model, self.out, self.comm
        if restart is None:
            claim(out, comm, scene.output.xdmf, self.summary)
        else:
            cut_outputs(plan, comm)
            write_summary(out / SUMMARY, self.summary, comm)
        self.opened = True
        self.probes = ProbeWriter(out / PROBES, self.probe, resume=restart is not None)
        if scene.output.xdmf:
            if restart is None:
                self.xdmf = XdmfWriter(out / XDMF, model, run_id=self.summary["run_id"])
            else:
                resume = (restart.restart_number, plan.frames)
                self.xdmf = XdmfWriter(out / XDMF, model, resume=resume)
        if restart is None:
            self.probes.write(scene.time.start)
            if self.xdmf is not None:
                self.xdmf.write(scene.time.start)
        if scene.output.checkpoint:
            self.checkpoints = CheckpointWriter(
                out,
                comm,
                scene.output.checkpoint_interval,
                scene.time.start,
                scene.to_dict(),
                self.summary["run_id"],
                previous=restart,
            )

    def close(self) -> None:
        if self.probes is not None:
            self.probes.close()
            self.probes.check()
        if self.xdmf is not None:
            self.xdmf.close()
