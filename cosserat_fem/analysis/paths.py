"""The rod's static equilibrium path in the load factor λ, continued around folds and onto the
branches that bifurcate from it (issue 27 item 2).

The path is R(U, λ) = 0, R the static residual of cosserat_fem/analysis/statics.py (every load
of the scene, at static.time, times λ = ``model.load_factor``), continued by the
pseudo-arclength engine of cosserat_fem/nls/arclength.py. :class:`RodPath` is the engine's
problem: its residual and Jacobian are the static Newton solver's own assemblies
(statics.static_solver: the exact UFL Jacobian, rows and columns of the Dirichlet dofs the
identity's), factored by MUMPS with the determinant asked for (ICNTL(33): det R_u =
RINFOG(12) · 2^INFOG(34), its sign the bifurcations' test) in serial and under MPI.

**R_p.** Every load enters the residual as λ times a term that does not depend on λ (the loads
are linear in λ: dead forces and torques, follower end loads, gravity), so
R_λ = R(U, 1) − R(U, 0) exactly, two residual assemblies at the current U; the Dirichlet rows
(x − g) cancel.

**The metric.** u is the owned entries of U (dimensionless: x/ℓ, angles in rad, and the rates,
zero in a static state), and ⟨a, b⟩ = Σ a_i b_i / N (N the global number of unknowns): the
arclength weighs the mean square of the state against λ², so a step of Δs moves the state's
RMS and λ together by about Δs.

**The predictor's refinement** (:meth:`RodPath.refine_prediction`, which the engine calls on
each predicted state): the angles as predicted, the positions solved for them from the rows of
the linear momentum balance, which are linear in the positions when the angles are held (the
section force n = R(ψ) C (R(ψ)ᵀ r' − e3) is linear in r', the loads dead). It removes the
positions' error that a predictor makes on a path curved in the state space (the roll-up: x
and z the sine and cosine of the angle), which otherwise bounds the step by Newton's basin.

**Rods in 3D: the chart moves on the path.** A scene solved in 3D (θ and ψ both solved) has
the chart of large rotations (cosserat_fem/rod/charts.py) from λ = 0 on, as load stepping
does: the angles are measured from the nodal frames Q, and (:meth:`RodPath.chart_move`)
before each step, when some node's |θ| exceeds charts.RESET_THETA = 0.9 rad (statics' and
runs' test, model.chart_move_due), Q moves onto the rod's rotation and the state's angles
and rates are re-expressed in it (model.reset_chart's maps: directors and positions
unchanged at the nodes). The engine re-expresses the branch's last point as the next
step's base (nls/arclength.py, "Charts": corrected on the hyperplane normal to the image
J t of its tangent, the step scaled by ‖J t‖, no sign change of det R_u looked for across
the move; the branch keeps the point as accepted); each point keeps its
chart (:attr:`RodPath.chart`, the nodal quaternions), with which its outputs are computed.
A point with some node's θ beyond :data:`CHART_THETA_MAX` in its chart is rejected
(:meth:`RodPath.inadmissible`; the step halved), so no step crosses θ = ±π/2, where det R_u
vanishes by the chart alone. So a 3D branch goes on past any rotation, and an out-of-plane
bifurcation (a strip's lateral–torsional buckling, Lee's frame) is switched onto like any
other (tests/test_continuation.py). Planar scenes in the x-z plane (the single angle ψ,
unbounded in the chart) have no chart and nothing moves. The y-z plane (θ alone, singular
at ±π/2, and no chart without ψ) is refused: solve such a scene in 3D
(discretisation.planar = "off").
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Protocol

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from cosserat_fem.analysis.branch_outputs import BranchOutputs
from cosserat_fem.analysis.statics import check_static_scene, static_solver
from cosserat_fem.common.errors import SceneError
from cosserat_fem.common.parallel import agree_and_gather
from cosserat_fem.nls.arclength import Branch, Continuation, ContinuationSettings, Point
from cosserat_fem.output.fields import PointProbe, probe_sigma
from cosserat_fem.rod.checks import cos_theta
from cosserat_fem.rod.model import build_model
from cosserat_fem.scene.build import Scene

#: A point with some node's θ beyond this [rad] in its chart is not accepted (the engine halves
#: the step): the chart moves before a step from a point where |θ| > charts.RESET_THETA =
#: 0.9, so a branch's points keep |cos θ| ≥ cos 1.3 = 0.27, and no step crosses θ = ±π/2,
#: where det Ma = cos θ (66), and so det R_u, vanishes by the chart alone (measured on the
#: cantilever rolled about e1 before this check: a spurious "bifurcation" at λ = 0.83).
CHART_THETA_MAX = 1.3


def check_path_scene(scene: Scene, command: str = "continue") -> None:
    """SceneError naming the key unless the path of ``scene`` can be continued: it has static
    states (statics.check_static_scene) and is not solved in the y-z plane (θ alone, no
    chart: module docstring). From the scene alone (build_model solves the plane of
    Scene.plane()), so a command checks it before it makes its folder."""
    check_static_scene(scene, command)
    structure = scene.structure
    if structure is not None:
        turned = [i for i, x in enumerate(structure.supports) if x.rotation is not None]
        driven = [i for i, j in enumerate(structure.joints) if j.kind == "driven"]
        if turned or driven:
            key = (
                f"structure.supports[{turned[0]}].rotation"
                if turned
                else f"structure.joints[{driven[0]}].angle"
            )
            raise SceneError(
                f"{key}: continuation scales the loads by λ, not a prescribed turn (not "
                "linear in λ in the angles); use static for it"
            )
    if scene.plane() == "y-z":
        raise SceneError(
            "discretisation.planar: continuation does not follow a rod in the y-z plane "
            "(θ alone meets the Euler-angle chart's singularity θ = ±π/2, and a chart "
            'needs ψ too): solve it in 3D (discretisation.planar = "off")'
        )


class RodPath:
    """R(U, λ) = 0 of a scene as a :class:`~cosserat_fem.nls.arclength.ContinuationProblem`
    with charts (module docstring)."""

    def __init__(self, scene: Scene, comm: MPI.Comm = MPI.COMM_WORLD, probe: float | None = None):
        """``probe``: the arclength s [m] of the point whose (x, y, z, θ, ψ, φ) the path
        reports (:meth:`tip`), in [0, ℓ]; default the probe point of the other commands
        (output.fields.probe_sigma: the free end, else mid-span)."""
        check_path_scene(scene)
        self.scene = scene
        self.model = model = build_model(scene, comm)
        assert model.layout.index(3) is None or model.needs_chart, "the y-z plane is refused"
        #: the current chart: the nodal quaternions (local, with ghosts), one array per chart
        #: (the engine compares charts by identity), or None (a planar scene)
        self.chart: np.ndarray | None = None
        self.charts_moved = 0
        if model.needs_chart:
            model.use_chart()  # before the solver's forms: they carry it (statics.py)
            assert model.chart is not None
            self.chart = model.chart.x.array.copy()
        self.comm = comm
        self.solver = solver = static_solver(scene, model)
        V = model.U.function_space
        self.owned = V.dofmap.index_map.size_local * V.dofmap.index_map_bs
        self.size = model.global_dofs()
        self.ksp = self._new_ksp()
        self._x, self._rhs = solver.A.createVecs()
        self._blocks: tuple[np.ndarray, np.ndarray] | None = None
        self._aij: PETSc.Mat | None = None
        length = scene.rod.length
        if probe is not None and not 0.0 <= probe <= length:
            raise SceneError(f"probe (--probe): must lie in [0, {length!r}] (m), got {probe!r}")
        sigma = probe_sigma(scene) if probe is None else probe / length
        self.probe = PointProbe(model, sigma)

    # -- the chart -------------------------------------------------------------------------
    def use_chart(self, chart: object) -> None:
        """Measure the angles in ``chart`` (a :attr:`chart` of this path) from now on."""
        if chart is None or chart is self.chart:
            return
        assert isinstance(chart, np.ndarray), "a chart of this path"
        model = self.model
        assert model.chart is not None, "a chart was made"
        model.chart.x.array[:] = chart
        model.chart_moved = bool(np.any(chart.reshape(-1, 4)[:, 1:] != 0.0)) or model.chart_moved
        self.chart = chart

    def chart_move(self, u: np.ndarray):
        """Move the chart onto the rod's rotation in the state u if some node's |θ| exceeds
        charts.RESET_THETA (model.chart_move_due, the test of statics and runs), and return
        the map of owned state vectors from the old chart to the new (model.chart_maps:
        nodewise, so a vector's owned entries map alone); else None. Collective."""
        model = self.model
        if model.chart is None:
            return None
        U = model.U
        U.x.array[: self.owned] = u
        U.x.scatter_forward()
        if model.chart_move_due(cos_theta(model, U.x.array)) is None:
            return None
        Q_new = model.new_chart(U.x.array)
        state_map = model.chart_maps(Q_new)[0]
        model.set_chart(Q_new)
        self.chart = model.chart.x.array.copy()
        self.charts_moved += 1
        size, owned = U.x.array.size, self.owned

        def to_new(v: np.ndarray) -> np.ndarray:
            full = np.zeros(size)
            full[:owned] = v
            return state_map(full)[:owned]

        return to_new

    def inadmissible(self, u: np.ndarray) -> str | None:
        """Why the state u lies too near its chart's singularity θ = ±π/2: some node's
        cos θ < cos :data:`CHART_THETA_MAX` (model.fork_nodes apart, whose chart does not
        move), or None. Collective."""
        model = self.model
        if model.chart is None:
            return None
        cos = cos_theta(model, u).copy()  # u: the owned nodes' entries
        cos[model.fork_nodes[model.fork_nodes < cos.size]] = 1.0
        smallest = self.comm.allreduce(float(np.min(cos, initial=1.0)), op=MPI.MIN)
        if smallest >= math.cos(CHART_THETA_MAX):
            return None
        return (
            f"some node's θ passed {CHART_THETA_MAX} rad in its chart (the chart's "
            "singularity θ = ±π/2 is near)"
        )

    # -- the state -------------------------------------------------------------------------
    def set_state(self, u: np.ndarray, p: float, chart: object = None) -> None:
        """U's owned entries = u (ghosts updated), λ = p; in ``chart`` if given."""
        self.use_chart(chart)
        U = self.model.U
        U.x.array[: self.owned] = u
        U.x.scatter_forward()
        self.model.load_factor.value = p

    def state(self) -> np.ndarray:
        return self.model.U.x.array[: self.owned].copy()

    # -- the problem -----------------------------------------------------------------------
    def residual(self, u: np.ndarray, p: float) -> np.ndarray:
        self.set_state(u, p)
        self.solver._residual()
        values = self.solver.b.array.copy()
        if not np.isfinite(self.comm.allreduce(float(np.sum(values)))):
            raise FloatingPointError("the residual is not finite")
        return values

    def _new_ksp(self) -> PETSc.KSP:
        """MUMPS' LU of R_u, the determinant asked for (made at the first linearise)."""
        ksp = PETSc.KSP().create(self.comm)
        ksp.setOptionsPrefix("cosserat_path_")
        ksp.setType("preonly")
        pc = ksp.getPC()
        pc.setType("lu")
        pc.setFactorSolverType("mumps")
        ksp.setOperators(self.solver.A)
        self._factor_ready = False
        return ksp

    def linearise(self, u: np.ndarray, p: float) -> None:
        """Assemble and factor R_u at (u, λ = p). A failed factorisation raises a
        ZeroDivisionError and replaces the solver: PETSc 3.18's MUMPS interface does not
        factor again after a failure (MatFactorNumeric_MUMPS returns at once while MUMPS's
        INFOG(1) of the last call is negative), which made every later step of the branch
        fail."""
        self.set_state(u, p)
        self.solver._jacobian()
        if not self._factor_ready:
            pc = self.ksp.getPC()
            pc.setFactorSetUpSolverType()
            pc.getFactorMatrix().setMumpsIcntl(33, 1)  # the determinant
            self._factor_ready = True
        self.ksp.getPC().setUp()  # factor now (KSPSetUp would wait for the next solve)
        info = self.ksp.getPC().getFactorMatrix().getMumpsInfog(1)
        if info < 0:
            self.ksp.destroy()
            self.ksp = self._new_ksp()
            raise ZeroDivisionError(f"the LU factorisation failed (MUMPS INFOG(1) = {info})")

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        self._rhs.array[:] = rhs
        self.ksp.solve(self._rhs, self._x)
        if self.ksp.getConvergedReason() < 0:
            raise ZeroDivisionError(f"the LU solve failed ({self.ksp.getConvergedReason()})")
        return self._x.array.copy()

    def dparameter(self, u: np.ndarray, p: float) -> np.ndarray:
        one = self.residual(u, 1.0)
        zero = self.residual(u, 0.0)
        self.model.load_factor.value = p
        return one - zero

    def dot(self, a: np.ndarray, b: np.ndarray) -> float:
        return self.comm.allreduce(float(a @ b)) / self.size

    def determinant(self) -> tuple[float, float]:
        F = self.ksp.getPC().getFactorMatrix()
        mantissa, exponent = F.getMumpsRinfog(12), F.getMumpsInfog(34)
        if mantissa == 0.0:
            return 0.0, -math.inf
        return math.copysign(1.0, mantissa), math.log(abs(mantissa)) + exponent * math.log(2.0)

    def _position_blocks(self) -> tuple[np.ndarray, np.ndarray] | None:
        """(rows, columns), local owned indices: the rows of the linear momentum balance (the
        entries of the positions' rates, whose test functions weigh n' + f = 0) and the
        columns of the positions, both without the Dirichlet dofs (a clamp holds p and q
        alike, so the two are as many) and a joint's copies (whose rows are constraints, and
        whose positions follow their masters'); None if they are not (then no refinement)."""
        layout = self.model.layout
        bs = layout.size
        fixed = np.zeros(self.owned, dtype=bool)
        for bc in self.model.bcs:
            dofs, ghost_start = bc.dof_indices()
            fixed[dofs[dofs < self.owned]] = True
        ties = self.model.constraints  # a joint's copy: its rows are its constraint's
        if ties is not None:
            fixed[ties.copies] = True
        slots = np.arange(self.owned) % bs
        components = np.asarray(layout.components)[slots]
        rows = np.flatnonzero(np.isin(components, (6, 7, 8)) & ~fixed)
        cols = np.flatnonzero(np.isin(components, (0, 1, 2)) & ~fixed)
        if self.comm.allreduce(int(rows.size != cols.size), op=MPI.MAX):
            return None  # a support holds p and q differently: no square block, no refinement
        return rows, cols

    def refine_prediction(self, u: np.ndarray, p: float) -> np.ndarray:
        """The predictor's positions solved for its angles: with the angles ψ held, the linear
        momentum balance is linear in the positions (the section force
        n = R(ψ) C (R(ψ)ᵀ r' − e3) is linear in r', and the loads are dead), so one solve of
        its rows for the positions' columns puts them where the predicted angles and strains
        put them (on the roll-up, x and z are the sine and cosine of the angle: a tangent's
        error in them limits the step, docs/continuation.md)."""
        if self._blocks is None:
            self._blocks = self._position_blocks() or (np.zeros(0, int), np.zeros(1, int))
        rows, cols = self._blocks
        if rows.size != cols.size:
            return u
        R = self.residual(u, p)
        self.solver._jacobian()
        # into a matrix of its own (petsc4py's convert without ``out`` converts in place)
        A = self.solver.A.convert("aij", self._aij if self._aij is not None else PETSc.Mat())
        self._aij = A
        start = A.getOwnershipRange()[0]
        row_is = PETSc.IS().createGeneral((rows + start).astype(PETSc.IntType), comm=self.comm)
        col_is = PETSc.IS().createGeneral((cols + start).astype(PETSc.IntType), comm=self.comm)
        block = A.createSubMatrix(row_is, col_is)
        ksp = PETSc.KSP().create(self.comm)
        try:
            ksp.setType("preonly")
            ksp.getPC().setType("lu")
            ksp.getPC().setFactorSolverType("mumps" if self.comm.size > 1 else "petsc")
            ksp.setOperators(block)
            x, b = block.createVecs()
            b.array[:] = R[rows]
            ksp.solve(b, x)
            if ksp.getConvergedReason() < 0:
                raise ZeroDivisionError("the positions' block is singular")
            refined = u.copy()
            refined[cols] -= x.array
            if self.model.constraints is not None:  # the copies with their masters
                self.model.constraints.enforce(refined)
            return refined
        finally:
            for obj in (ksp, block, row_is, col_is):
                obj.destroy()

    # -- outputs ---------------------------------------------------------------------------
    def tip(self, u: np.ndarray, chart: object = None) -> np.ndarray:
        """(x, y, z, θ, ψ, φ) [m, rad] at the probe point (default the free end) of the state
        u (in ``chart`` if given; the angles those of the rod's rotation in the fixed basis,
        output/fields.py)."""
        self.use_chart(chart)
        self.model.U.x.array[: self.owned] = u
        self.model.U.x.scatter_forward()
        values = self.probe.values()
        return np.asarray(self.comm.bcast(values, root=self.probe.owner))[:6]

    def destroy(self) -> None:
        if self._aij is not None:
            self._aij.destroy()
        self.ksp.destroy()
        self._x.destroy()
        self._rhs.destroy()
        self.solver.destroy()


@dataclass
class PathPoint:
    """A state on a branch: the load factor λ, the free end's (x, y, z, θ, ψ, φ) [m, rad]
    (``tip``), the RMS of the state's unknowns (``norm``, dimensionless), dλ/ds, the sign of
    det R_u, and ``kind``: "regular", "start", "end", "limit" or "bifurcation"; ``note``: why
    a special point is only approximate (the engine's Point.note; not a column of
    branches.csv), else ""."""

    factor: float
    tip: np.ndarray
    norm: float
    dfactor: float
    det_sign: float
    kind: str = "regular"
    note: str = ""

    def as_row(self, branch: int) -> dict:
        x, y, z, theta, psi, phi = (float(v) for v in self.tip)
        return {
            "branch": branch,
            "load_factor": self.factor,
            "x": x,
            "y": y,
            "z": z,
            "theta": theta,
            "psi": psi,
            "phi": phi,
            "norm": self.norm,
            "dfactor_ds": self.dfactor,
            "det_sign": self.det_sign,
            "point": self.kind,
        }


@dataclass
class PathBranch:
    """One traced branch: its points in order, the special points located on it, how it
    started ("primary", or "switched at λ = ...") and why it ended."""

    points: list[PathPoint]
    special: list[PathPoint]
    origin: str
    reason: str
    steps: int
    rejected: int
    #: the chart's moves on it (module docstring)
    charts_moved: int = 0


@dataclass
class PathResult:
    """The branches traced, in order: the primary branch's two directions first, then two for
    each bifurcation switched at; ``corrector_factorisations``: LU factorisations of R_u by
    the correctors (the engine's ``corrector_solves``), ``jacobian_assemblies`` all of them."""

    branches: list[PathBranch] = field(default_factory=list)
    corrector_factorisations: int = 0
    #: the index in its folder of ``branches[0]`` (a restart's first branch; 0 otherwise)
    first_branch: int = 0
    #: Jacobian assemblies in all (correctors, tangents and determinants, refinements,
    #: null vectors), each followed by a factorisation.
    jacobian_assemblies: int = 0

    def rows(self) -> list[dict]:
        return [p.as_row(i) for i, b in enumerate(self.branches) for p in [*b.points, *b.special]]


def _path_point(problem: RodPath, point: Point) -> PathPoint:
    norm = math.sqrt(problem.dot(point.u, point.u))
    tip = problem.tip(point.u, point.chart)
    return PathPoint(point.p, tip, norm, point.t_p, point.det_sign, point.kind, point.note)


def _path_branch(
    problem: RodPath, branch: Branch, origin: str, observer: BranchOutputs | None = None
) -> PathBranch:
    problem.probe.angles.last = None  # the angles continued along this branch from its start
    if observer is not None:
        observer.branch(problem, branch)
    return PathBranch(
        [_path_point(problem, q) for q in branch.points],
        [_path_point(problem, q) for q in branch.special],
        origin,
        branch.reason,
        len(branch.points) - 1,
        branch.steps_rejected,
        branch.charts_moved,
    )


def path_engine(
    problem: RodPath,
    settings: ContinuationSettings,
    stop: Callable[[PathPoint], str | None] | None = None,
    observer: BranchOutputs | None = None,
) -> Continuation:
    """The engine on ``problem``, its ``stop`` told of each point as a :class:`PathPoint` and
    ``observer`` (branch_outputs.py) of each engine point.

    Under MPI the ranks agree after each point: an exception of ``stop`` or of the
    observer's progress on one rank is raised on every rank (common/parallel.agree: its
    class and message), and rank 0's reason to stop is every rank's, so no rank goes on into
    a collective the others have left."""
    wrapped = None
    comm = problem.comm
    if stop is not None or observer is not None:

        def wrapped(q: Point) -> str | None:
            if observer is not None and engine.branch is not None:
                observer.write_rows(problem, engine.branch)  # collective, before any user
                observer.save(engine.branch, comm)  # code; the rows first (branch_outputs.py)
            point = None if stop is None else _path_point(problem, q)  # collective (the probe)
            error, reason = None, None
            try:
                if observer is not None:
                    observer.point(q)
                if stop is not None and point is not None:
                    reason = stop(point)
            except Exception as exc:
                if comm.size == 1:
                    raise
                error = exc
            return agree_and_gather(comm, error, reason)[0]

    engine = Continuation(problem, settings, wrapped)
    return engine


@dataclass
class Pending:
    """A step of a continuation to come (its queue: :func:`continue_path`): ``kind``
    "trace", the branch from ``start`` along ``direction`` × its tangent (``search_first``:
    its first segment searched for special points; ``primary``: its bifurcation points are
    switched at later; ``origin`` as in :class:`PathBranch`); "switches", a switch at each
    of the first ``count`` bifurcation points found on the primary branches; "switch", the
    other branch through the bifurcation point ``at``, both ways."""

    kind: str
    start: Point | None = None
    direction: int = 1
    search_first: bool = True
    origin: str = "primary"
    primary: bool = False
    count: int = 0
    at: Point | None = None


def trace_queue(
    engine: Continuation,
    problem: RodPath,
    pending: list[Pending],
    found: list[Point],
    result: PathResult,
    observer: BranchOutputs | None = None,
) -> None:
    """Trace the branches of ``pending`` in order (it is emptied), each ended (its
    :class:`PathBranch` appended to ``result``, the observer's files and restart data
    written) before the next begins; the bifurcation points of the primary ones are
    appended to ``found``. All the continuation keeps to decide its next branch is in
    ``pending`` and ``found``, which the observer saves with each branch's end
    (path_restart.queue_record), so a restart traces what the whole run would."""
    while pending:
        task = pending.pop(0)
        if task.kind == "switches":
            pending[:0] = [Pending("switch", at=q) for q in found[: task.count]]
            continue
        if task.kind == "switch":
            assert task.at is not None
            start = engine.switch_start(task.at)
            origin = f"switched at load factor {task.at.p:.9g}"
            pending[:0] = [Pending("trace", start, d, False, origin) for d in (1, -1)]
            continue
        assert task.start is not None
        if observer is not None:
            observer.begin(task, pending, found)
        branch = engine.trace(task.start, task.direction, task.search_first)
        end_branch(problem, branch, task, found, result, observer)


def end_branch(
    problem: RodPath,
    branch: Branch,
    task: Pending,
    found: list[Point],
    result: PathResult,
    observer: BranchOutputs | None = None,
) -> None:
    """``branch`` (traced for ``task``) ended: its bifurcation points appended to ``found``
    if it is primary, its :class:`PathBranch` to ``result``, then the observer's files, the
    caller's (``finished``) and its final restart data, in that order."""
    index = len(result.branches) if observer is None else observer.index
    if task.primary:
        for k, q in enumerate(branch.special):
            if q.kind == "bifurcation":
                found.append(q)
                if observer is not None:
                    observer.remember(q, ["special", index, k])
    result.branches.append(_path_branch(problem, branch, task.origin, observer))
    if observer is not None:
        if observer.finished is not None:
            observer.finished(result)
        observer.end(problem, branch)


def continue_path(
    scene: Scene,
    settings: ContinuationSettings,
    switch: int = 1,
    stop: Callable[[PathPoint], str | None] | None = None,
    directions: tuple[int, ...] = (1, -1),
    comm: MPI.Comm = MPI.COMM_WORLD,
    observer: BranchOutputs | None = None,
    probe: float | None = None,
) -> PathResult:
    """The path from the unloaded rod (λ = 0) traced along ``directions`` (+1: λ growing;
    a direction that leaves [p_min, p_max] at once is not traced), then, at each of the first
    ``switch`` bifurcation points located on it, the other branch both ways; each branch ends
    at a bound of [settings.p_min, p_max] (a point there), max_points, ``stop(point)`` or a
    step collapse (its reason kept). The branches are a queue (:class:`Pending`,
    :func:`trace_queue`), each ended before the next begins. ``observer``: told of each
    point and each branch as it ends (cosserat_fem/analysis/branch_outputs.py: the progress,
    the XDMF, the restart data with the queue). ``probe``: the arclength [m] of the point
    reported as each point's ``tip`` (:class:`RodPath`; default the free end, else
    mid-span)."""
    problem = RodPath(scene, comm, probe)
    try:
        engine = path_engine(problem, settings, stop, observer)
        start = engine.start_point(problem.state(), 0.0)
        result = PathResult()
        pending = [
            Pending("trace", start, d, True, "primary", True)
            for d in directions
            if not ((d > 0 and settings.p_max <= 0.0) or (d < 0 and settings.p_min >= 0.0))
        ]  # a direction in which λ would leave the range at once is not traced
        pending.append(Pending("switches", count=switch))
        trace_queue(engine, problem, pending, [], result, observer)
        result.corrector_factorisations = engine.corrector_solves
        result.jacobian_assemblies = problem.solver.stats.jacobian_assemblies
        return result
    finally:
        if observer is not None:
            observer.close()  # a branch's XDMF left open by an exception
        problem.destroy()


#: The columns of branches.csv, one row per point (special points after their branch's).
BRANCH_COLUMNS = tuple(PathPoint(0.0, np.zeros(6), 0.0, 0.0, 1.0).as_row(0))


class BranchRows(Protocol):
    """What :func:`write_branches` writes: one dict a point, in the columns' order."""

    def rows(self) -> list[dict]: ...


def write_branches(
    path: str | Path,
    result: BranchRows,
    comm: MPI.Comm = MPI.COMM_WORLD,
    columns: tuple[str, ...] = BRANCH_COLUMNS,
) -> None:
    """branches.csv at ``path`` (rank 0 writes; the ranks agree on a failure): the header
    ``columns``, by default :data:`BRANCH_COLUMNS` (branch index, λ, the free end's x, y, z
    [m], θ, ψ, φ [rad], the state's RMS norm, dλ/ds, sign of det R_u, the point's kind), one
    row per point (``result.rows()``: dicts in the columns' order; periodic orbits' are
    cosserat_fem/analysis/periodic.py's ORBIT_COLUMNS)."""
    from cosserat_fem.analysis.branch_outputs import replace_on_root

    lines = [",".join(columns), *csv_lines(result.rows())]
    replace_on_root(path, ("\n".join(lines) + "\n").encode(), comm)


def csv_lines(rows: list[dict]) -> list[str]:
    """branches.csv's lines of ``rows`` (:meth:`PathPoint.as_row`; floats by repr)."""
    return [",".join(repr(v) if isinstance(v, float) else str(v) for v in r.values()) for r in rows]
