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

**Planar scenes only.** A scene solved in the x-z plane has the single angle ψ, which the
Euler-angle chart (18) lets grow without bound: no chart, and nothing on the path to move.
In 3D the chart of large rotations (cosserat_fem/rod/charts.py) moves onto the rod when θ
nears π/2, which changes the unknowns U and so the path's coordinates in the middle of a
branch; that is not done on a path yet, so a scene that needs the chart (θ and ψ both solved)
is refused with the reason (a SceneError naming discretisation.planar). A scene in the y-z
plane (angle θ) is refused too: θ = ±π/2 is the chart's singular point.

One exception: a rod curved at rest in the x-z plane (bent about e2) under in-plane loads
(:func:`in_xz_plane`; Lee's frame), which the scene solves in 3D (a curved rod is never
reduced to a plane). Its primary path stays in the plane, θ = φ = 0 (the out-of-plane
equations hold with them zero), so the chart is never needed there; its R_u has the
out-of-plane stiffness too, so a lateral (out-of-plane) bifurcation is located like any
other. A branch switched onto there leaves the plane: it ends when some node's |θ| reaches
:data:`THETA_LIMIT` (the reason says so), short of the chart's singularity.
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
from cosserat_fem.rod.model import build_model
from cosserat_fem.scene.build import Scene

#: On a rod solved in 3D that starts in the x-z plane (:func:`in_xz_plane`), a branch ends
#: where some node's |θ| reaches this [rad]: the Euler-angle chart is singular at π/2.
THETA_LIMIT = 1.2


def in_xz_plane(scene: Scene) -> bool:
    """Whether a scene solved in 3D (a rod curved at rest is never reduced to a plane:
    Scene.plane) stays in the x-z plane: its reference curve in it (y = 0) and bent about e2
    (d0_2 = ±e2) at 1001 points, and nothing that leaves the plane (the plane's own test).
    Then θ = φ = 0 on the path (the out-of-plane equations hold with them zero), far from the
    chart's singularity θ = ±π/2, so the 3D unknowns need no chart move."""
    reference = scene.reference
    if not reference.curved or reference.closed:
        return False
    s = np.linspace(0.0, scene.rod.length, 1001)
    frames = reference.frames(s)
    return bool(
        np.all(np.abs(reference.positions(s)[:, 1]) < 1e-12 * scene.rod.length)
        and np.all(np.abs(np.abs(frames[:, 1, 1]) - 1.0) < 1e-12)
        and scene._stays_in("x-z")
    )


class RodPath:
    """R(U, λ) = 0 of a planar scene as a :class:`~cosserat_fem.nls.arclength.ContinuationProblem`
    (module docstring)."""

    def __init__(self, scene: Scene, comm: MPI.Comm = MPI.COMM_WORLD, probe: float | None = None):
        """``probe``: the arclength s [m] of the point whose (x, y, z, θ, ψ, φ) the path
        reports (:meth:`tip`), in [0, ℓ]; default the probe point of the other commands
        (output.fields.probe_sigma: the free end, else mid-span)."""
        check_static_scene(scene, "continue")
        self.scene = scene
        self.model = model = build_model(scene, comm)
        self.in_plane_3d = in_xz_plane(scene)
        if not self.in_plane_3d and (model.needs_chart or model.layout.index(3) is not None):
            raise SceneError(
                "discretisation.planar: continuation follows rods bent in the x-z plane only "
                "(a rod in 3D or in the y-z plane meets the Euler-angle chart's singularity "
                "θ = ±π/2, whose chart move on a path is not done yet)"
            )
        self.comm = comm
        self.solver = solver = static_solver(scene, model)
        V = model.U.function_space
        self.owned = V.dofmap.index_map.size_local * V.dofmap.index_map_bs
        self.size = model.global_dofs()
        self.ksp = PETSc.KSP().create(comm)
        self.ksp.setOptionsPrefix("cosserat_path_")
        self.ksp.setType("preonly")
        pc = self.ksp.getPC()
        pc.setType("lu")
        pc.setFactorSolverType("mumps")
        self.ksp.setOperators(solver.A)
        self._x, self._rhs = solver.A.createVecs()
        self._factor_ready = False
        self._blocks: tuple[np.ndarray, np.ndarray] | None = None
        self._aij: PETSc.Mat | None = None
        length = scene.rod.length
        if probe is not None and not 0.0 <= probe <= length:
            raise SceneError(f"probe (--probe): must lie in [0, {length!r}] (m), got {probe!r}")
        sigma = probe_sigma(scene) if probe is None else probe / length
        self.probe = PointProbe(model, sigma)

    # -- the state -------------------------------------------------------------------------
    def set_state(self, u: np.ndarray, p: float) -> None:
        """U's owned entries = u (ghosts updated), λ = p."""
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

    def linearise(self, u: np.ndarray, p: float) -> None:
        self.set_state(u, p)
        self.solver._jacobian()
        if not self._factor_ready:
            pc = self.ksp.getPC()
            pc.setFactorSetUpSolverType()
            pc.getFactorMatrix().setMumpsIcntl(33, 1)  # the determinant
            self._factor_ready = True
        self.ksp.getPC().setUp()  # factor now (KSPSetUp would wait for the next solve)

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
        alike, so the two are as many); None if they are not (then no refinement)."""
        layout = self.model.layout
        bs = layout.size
        fixed = np.zeros(self.owned, dtype=bool)
        for bc in self.model.bcs:
            dofs, ghost_start = bc.dof_indices()
            fixed[dofs[dofs < self.owned]] = True
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
            return refined
        finally:
            for obj in (ksp, block, row_is, col_is):
                obj.destroy()

    def largest_theta(self, u: np.ndarray) -> float:
        """max |θ| [rad] over the nodes of the state u (0 if θ is not solved)."""
        slot = self.model.layout.index(3)
        if slot is None:
            return 0.0
        local = u[slot :: self.model.layout.size]
        return self.comm.allreduce(float(np.max(np.abs(local), initial=0.0)), op=MPI.MAX)

    # -- outputs ---------------------------------------------------------------------------
    def tip(self, u: np.ndarray) -> np.ndarray:
        """(x, y, z, θ, ψ, φ) [m, rad] at the probe point (default the free end) of the state
        u."""
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


@dataclass
class PathResult:
    """The branches traced, in order: the primary branch's two directions first, then two for
    each bifurcation switched at; ``corrector_factorisations``: LU factorisations of R_u by
    the correctors (the engine's ``corrector_solves``), ``jacobian_assemblies`` all of them."""

    branches: list[PathBranch] = field(default_factory=list)
    corrector_factorisations: int = 0
    #: Jacobian assemblies in all (correctors, tangents and determinants, refinements,
    #: null vectors), each followed by a factorisation.
    jacobian_assemblies: int = 0

    def rows(self) -> list[dict]:
        return [p.as_row(i) for i, b in enumerate(self.branches) for p in [*b.points, *b.special]]


def _path_point(problem: RodPath, point: Point) -> PathPoint:
    norm = math.sqrt(problem.dot(point.u, point.u))
    tip = problem.tip(point.u)
    return PathPoint(point.p, tip, norm, point.t_p, point.det_sign, point.kind, point.note)


def _path_branch(
    problem: RodPath, branch: Branch, origin: str, observer: BranchOutputs | None = None
) -> PathBranch:
    if observer is not None:
        observer.branch(problem, branch)
    return PathBranch(
        [_path_point(problem, q) for q in branch.points],
        [_path_point(problem, q) for q in branch.special],
        origin,
        branch.reason,
        len(branch.points) - 1,
        branch.steps_rejected,
    )


def path_engine(
    problem: RodPath,
    settings: ContinuationSettings,
    stop: Callable[[PathPoint], str | None] | None = None,
    observer: BranchOutputs | None = None,
) -> Continuation:
    """The engine on ``problem``, its ``stop`` told of each point as a :class:`PathPoint` and
    ``observer`` (branch_outputs.py) of each engine point; a branch of a curved rod in the
    x-z plane solved in 3D ends where |θ| reaches :data:`THETA_LIMIT` (the chart).

    Under MPI the ranks agree after each point: an exception of ``stop`` or of the
    observer's progress on one rank is raised on every rank (common/parallel.agree: its
    class and message), and rank 0's reason to stop is every rank's, so no rank goes on into
    a collective the others have left."""
    wrapped = None
    comm = problem.comm
    if stop is not None or observer is not None or problem.in_plane_3d:

        def wrapped(q: Point) -> str | None:
            if observer is not None and engine.branch is not None:
                observer.save(engine.branch, comm)  # collective, before any user code
            chart = problem.in_plane_3d and problem.largest_theta(q.u) >= THETA_LIMIT
            point = None if stop is None else _path_point(problem, q)  # collective (the probe)
            error, reason = None, None
            try:
                if observer is not None:
                    observer.point(q)
                if chart:
                    reason = f"|θ| reached {THETA_LIMIT} rad out of the x-z plane (the chart)"
                elif stop is not None and point is not None:
                    reason = stop(point)
            except Exception as exc:
                if comm.size == 1:
                    raise
                error = exc
            return agree_and_gather(comm, error, reason)[0]

    engine = Continuation(problem, settings, wrapped)
    return engine


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
    step collapse (its reason kept). ``observer``: told of each point and each branch as it
    ends (cosserat_fem/analysis/branch_outputs.py: the progress, the XDMF). ``probe``: the
    arclength [m] of the point reported as each point's ``tip`` (:class:`RodPath`; default
    the free end, else mid-span)."""
    problem = RodPath(scene, comm, probe)
    try:
        engine = path_engine(problem, settings, stop, observer)
        start = engine.start_point(problem.state(), 0.0)
        result = PathResult()
        found: list[Point] = []
        for d in directions:
            if (d > 0 and settings.p_max <= 0.0) or (d < 0 and settings.p_min >= 0.0):
                continue  # λ would leave the range at once
            branch = engine.trace(start, d)
            found += [q for q in branch.special if q.kind == "bifurcation"]
            result.branches.append(_path_branch(problem, branch, "primary", observer))
            if observer is not None and observer.finished is not None:
                observer.finished(result)
        for point in found[:switch]:
            for branch in engine.switch(point):
                origin = f"switched at load factor {point.p:.9g}"
                result.branches.append(_path_branch(problem, branch, origin, observer))
                if observer is not None and observer.finished is not None:
                    observer.finished(result)
        result.corrector_factorisations = engine.corrector_solves
        result.jacobian_assemblies = problem.solver.stats.jacobian_assemblies
        return result
    finally:
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
