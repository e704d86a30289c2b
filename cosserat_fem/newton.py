"""Newton's method by PETSc SNES for a DOLFINx residual form, with Jacobian policies.

Each nonlinear solve is a petsc4py SNES (``newtonls``) with the exact UFL Jacobian assembled
into a blocked (BAIJ) matrix and a direct solve (KSP ``preonly`` + LU: PETSc's own LU in
serial, MUMPS under MPI). The Jacobian policy decides when the matrix is re-assembled:

* ``full``:   at every Newton iteration (quadratic convergence);
* ``lagged``: at the first iteration of every ``lag``-th solve, otherwise the last matrix
  and its LU factors are reused (modified Newton);
* ``frozen``: kept until a solve needs more than ``refresh_iterations`` iterations, then
  re-assembled for the next solve (modified Newton).

Line search: none (``basic``, the full Newton step). The residual rows have very different
scales (axial rows carry ν02 ≈ 6e5 for the paper's rod), so a full step that is excellent in
the solution norm can raise ‖F‖ through a second-order axial residual ν02 ψ²/2; the ``bt``
line search then damps good steps (measured: 5 iterations instead of 3 for a small static
load, 6 with ``l2``).

Convergence (our own test, :meth:`NewtonSolver._converged`): ‖F‖ ≤ atol, or ‖F‖ ≤ rtol ‖F0‖,
or ‖δU‖ ≤ stol ‖U‖ + xatol. The update test ends most solves: the residual's round-off floor
grows with the deformation (measured 3e-13 at strains of 1e-4 up to 1.5e-11 at rotations of
0.3 rad), so a fixed atol could stall, while ‖δU‖/‖U‖ reaches 1e-14 to 1e-10; after a
quadratic step with ‖δU‖ ≤ 1e-8 ‖U‖ the remaining error is of order 1e-16 ‖U‖. The absolute
part xatol = 1e-13 (U is dimensionless: 1e-13 ℓ in position, 1e-13 rad) covers tiny states,
where the update's round-off floor is absolute (about 3e-16, set by terms such as 1 + p3′)
and a purely relative test can never be met (measured: a thin rod under a small axial load,
‖U‖ = 1.6e-8, stalled at ‖δU‖/‖U‖ = 2e-8).

With ``lagged`` and ``frozen``, a solve that fails with an old matrix is retried once with a
fresh one before failure is reported. A matrix that is not re-assembled keeps its PETSc
object state, so the LU factors are reused rather than recomputed (PCSetUp sees an unchanged
operator).
"""

from __future__ import annotations

import itertools
import time
from dataclasses import dataclass, field

import ufl
from dolfinx import fem
from dolfinx.fem.petsc import assemble_matrix, assemble_vector, create_matrix, create_vector, set_bc
from petsc4py import PETSc

JACOBIAN_POLICIES = ("full", "lagged", "frozen")
_prefix_counter = itertools.count()


@dataclass
class NewtonSettings:
    jacobian: str = "full"
    lag: int = 10
    refresh_iterations: int = 4
    rtol: float = 1e-10
    atol: float = 1e-12
    stol: float = 1e-8
    xatol: float = 1e-13
    max_iterations: int = 25
    linear_solver: str = "auto"  # auto | petsc | mumps | superlu


@dataclass
class NewtonStatistics:
    """Counters over the lifetime of the solver (for summary.json and the tests)."""

    solves: int = 0
    iterations: int = 0
    residual_assemblies: int = 0
    jacobian_assemblies: int = 0
    retries: int = 0
    time_residual: float = 0.0
    time_jacobian: float = 0.0
    time_solve: float = 0.0
    last_iterations: int = 0
    history: list[int] = field(default_factory=list, repr=False)

    def as_dict(self) -> dict:
        d = dict(self.__dict__)
        d["max_iterations_in_a_solve"] = max(d.pop("history"), default=0)
        return d


class NewtonFailure(RuntimeError):
    """A nonlinear solve did not converge (the caller adds time and place)."""

    def __init__(self, reason: str, iterations: int):
        super().__init__(reason)
        self.reason = reason
        self.iterations = iterations


_REASONS = {v: k for k, v in vars(PETSc.SNES.ConvergedReason).items() if isinstance(v, int)}


class NewtonSolver:
    """SNES Newton solver for F(U; V) = 0 with Dirichlet conditions ``bcs`` on U.

    The Dirichlet values must be satisfied by every initial guess (here they are homogeneous
    and the predictors keep them), so no lifting is needed: the residual rows of constrained
    dofs are set to x − g = x.
    """

    def __init__(
        self,
        F: ufl.Form,
        U: fem.Function,
        bcs: list,
        settings: NewtonSettings,
        form_compiler_params: dict | None = None,
        jit_params: dict | None = None,
    ):
        if settings.jacobian not in JACOBIAN_POLICIES:
            raise ValueError(f"unknown Jacobian policy {settings.jacobian!r}")
        self.U = U
        self.bcs = bcs
        self.settings = settings
        self.stats = NewtonStatistics()
        comm = U.function_space.mesh.comm
        fcp = form_compiler_params or {}
        jp = jit_params or {}
        t0 = time.perf_counter()
        self.F_form = fem.form(F, form_compiler_params=fcp, jit_params=jp)
        dU = ufl.TrialFunction(U.function_space)
        self.J_form = fem.form(ufl.derivative(F, U, dU), form_compiler_params=fcp, jit_params=jp)
        self.compile_time = time.perf_counter() - t0

        self.b = create_vector(self.F_form)
        # SNES iterates on its own vector: the callbacks copy trial points into U, which must
        # never alias the current iterate (a line search evaluates F away from it).
        self.x = create_vector(self.F_form)
        self.A = create_matrix(self.J_form, mat_type="baij")
        self._need_jacobian = True
        self._solves_since_jacobian = 0

        self.snes = PETSc.SNES().create(comm)
        prefix = f"cosserat_newton_{next(_prefix_counter)}_"
        self.snes.setOptionsPrefix(prefix)
        # Configured through the API, not the options database: PETSc 3.18 keeps at most 512
        # options, and a session that builds many solvers (a test suite) would fill it.
        # setFromOptions still lets a user override any of it with -<prefix>snes_... options.
        self.snes.setType("newtonls")
        self.snes.setTolerances(
            rtol=settings.rtol,
            atol=settings.atol,
            stol=settings.stol,
            max_it=settings.max_iterations,
        )
        self.snes.setMaxFunctionEvaluations(10 * settings.max_iterations + 10)
        self.lu_package = self._lu_package(comm, settings.linear_solver)
        ksp = self.snes.getKSP()
        ksp.setType("preonly")
        ksp.getPC().setType("lu")
        ksp.getPC().setFactorSolverType(self.lu_package)
        # petsc4py 3.18 has no line-search API: set it as an option and remove it again.
        options = PETSc.Options()
        options[prefix + "snes_linesearch_type"] = "basic"
        self.snes.setFromOptions()
        options.delValue(prefix + "snes_linesearch_type")
        self.snes.setConvergenceTest(self._converged)
        self._f0 = 0.0
        self.snes.setFunction(self._residual, self.b)
        self.snes.setJacobian(self._jacobian, self.A)

    @staticmethod
    def _lu_package(comm, choice: str) -> str:
        if choice == "auto":
            return "petsc" if comm.size == 1 else "mumps"
        if choice == "petsc" and comm.size > 1:
            raise ValueError("PETSc's own LU is serial only; use linear_solver = 'mumps'")
        return choice

    # -- SNES callbacks -------------------------------------------------------------------
    def _update_state(self, x: PETSc.Vec) -> None:
        x.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
        x.copy(self.U.vector)
        self.U.vector.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)

    def _residual(self, snes, x: PETSc.Vec, b: PETSc.Vec) -> None:
        t0 = time.perf_counter()
        self._update_state(x)
        with b.localForm() as b_local:
            b_local.set(0.0)
        assemble_vector(b, self.F_form)
        b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        set_bc(b, self.bcs, x, -1.0)
        self.stats.residual_assemblies += 1
        self.stats.time_residual += time.perf_counter() - t0

    def _jacobian(self, snes, x: PETSc.Vec, A: PETSc.Mat, P: PETSc.Mat) -> None:
        if not (self._need_jacobian or self.settings.jacobian == "full"):
            return
        t0 = time.perf_counter()
        self._update_state(x)
        A.zeroEntries()
        assemble_matrix(A, self.J_form, bcs=self.bcs)
        A.assemble()
        self._need_jacobian = False
        self._solves_since_jacobian = 0
        self.stats.jacobian_assemblies += 1
        self.stats.time_jacobian += time.perf_counter() - t0

    def _converged(self, snes, it: int, norms) -> int:
        """Convergence test of the module docstring; norms = (‖U‖, ‖δU‖, ‖F‖)."""
        xnorm, ynorm, fnorm = norms
        reasons, st = PETSc.SNES.ConvergedReason, self.settings
        if fnorm != fnorm:
            return reasons.DIVERGED_FNORM_NAN
        if it == 0:
            self._f0 = fnorm
            return reasons.CONVERGED_FNORM_ABS if fnorm <= st.atol else reasons.ITERATING
        if fnorm <= st.atol:
            return reasons.CONVERGED_FNORM_ABS
        if fnorm <= st.rtol * self._f0:
            return reasons.CONVERGED_FNORM_RELATIVE
        if ynorm <= st.stol * xnorm + st.xatol:
            return reasons.CONVERGED_SNORM_RELATIVE
        if it >= st.max_iterations:
            return reasons.DIVERGED_MAX_IT
        return reasons.ITERATING

    # -- solving --------------------------------------------------------------------------
    def request_jacobian(self) -> None:
        """Force a Jacobian re-assembly at the next Newton iteration (e.g. after h changed)."""
        self._need_jacobian = True

    def solve(self) -> int:
        """Solve from the current U (the initial guess). Returns the number of iterations."""
        policy = self.settings.jacobian
        if policy == "lagged" and self._solves_since_jacobian >= self.settings.lag:
            self._need_jacobian = True
        initial = self.U.vector.copy()
        fresh = self._need_jacobian or policy == "full"
        iterations, reason = self._run()
        if reason <= 0 and not fresh:
            # An old Jacobian may be the cause: retry once from the same guess with a new one.
            self.stats.retries += 1
            initial.copy(self.U.vector)
            self.U.vector.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
            self._need_jacobian = True
            more, reason = self._run()
            iterations += more
        initial.destroy()
        self._solves_since_jacobian += 1
        self.stats.solves += 1
        self.stats.last_iterations = iterations
        self.stats.history.append(iterations)
        if reason <= 0:
            raise NewtonFailure(_REASONS.get(reason, str(reason)), iterations)
        if policy == "frozen" and iterations > self.settings.refresh_iterations:
            self._need_jacobian = True
        return iterations

    def _run(self) -> tuple[int, int]:
        t0 = time.perf_counter()
        self.U.vector.copy(self.x)
        self.snes.solve(None, self.x)
        self._update_state(self.x)
        self.stats.time_solve += time.perf_counter() - t0
        it = self.snes.getIterationNumber()
        self.stats.iterations += it
        return it, self.snes.getConvergedReason()

    def destroy(self) -> None:
        self.snes.destroy()
        self.A.destroy()
        self.b.destroy()
        self.x.destroy()
