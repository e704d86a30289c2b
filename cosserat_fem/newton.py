"""Newton's method for a DOLFINx residual form, with Jacobian policies.

Each nonlinear solve iterates U_{k+1} = U_k − δU_k, J δU_k = F(U_k), with the full step (no
line search), the exact UFL Jacobian J assembled into a blocked (BAIJ) matrix and a direct
solve: a PETSc KSP ``preonly`` + LU (PETSc's own LU in serial, MUMPS under MPI). The loop is
SNES ``newtonls`` with the ``basic`` line search written out (docs/decisions.md, "The lean
Newton loop"): the same iterates, norms, iteration counts and reasons, without SNES's calls
into Python. The Jacobian policy decides when the matrix is re-assembled:

* ``full``:   at every Newton iteration (quadratic convergence);
* ``lagged``: at the first iteration of every ``lag``-th solve, otherwise the last matrix
  and its LU factors are reused (modified Newton);
* ``frozen``: kept until a solve needs more than ``refresh_iterations`` iterations, then
  re-assembled for the next solve (modified Newton).

A solve that fails with an old matrix is retried once with a fresh one before failure is
reported. A matrix that is not re-assembled keeps its PETSc object state, so the LU factors
are reused (PCSetUp sees an unchanged operator).

Convergence (:meth:`NewtonSolver._converged`), called with norms = (‖U_k‖, ‖δU_k‖,
‖F(U_k)‖) after each iteration k ≥ 1 and with (0, 0, ‖F(U_0)‖) at k = 0, as SNES calls its
test: ‖F‖ ≤ atol, or ‖F‖ ≤ rtol ‖F0‖, or the update test ‖δU_k‖ ≤ stol ‖U‖ + xatol. With a
reused Jacobian the iteration converges linearly, and from the second iteration on it also
stops when its estimated error is that small: η_k ‖δU_k‖ ≤ stol ‖U‖ + xatol,
η_k = ρ_k/(1 − ρ_k) (Hairer & Wanner, Solving ODEs II, IV.8, eq. (8.10)), with the
contraction ρ_k the larger of the update ratio ‖δU_k‖/‖δU_{k−1}‖ and the residual ratio
‖F(U_k)‖/‖F(U_{k−1})‖. Full Newton keeps the update test alone. A solve also ends, without
the test, when ‖F‖ is not finite (``DIVERGED_FNORM_NAN``) or the linear solve fails, e.g. at
a zero pivot (``DIVERGED_LINEAR_SOLVE``), after the iterations completed before. Outcomes
are PETSc's SNES reasons (``PETSc.SNES.ConvergedReason``; :class:`NewtonFailure` carries
the name). Why each of these, with the measurements: docs/decisions.md, "The Newton stop
rule" and "No line search".

In a serial run each iteration is one call into C where the form allows it
(cosserat_fem/native_newton.py: the same operations, the same iterates bit for bit;
``NewtonSettings.loop``, docs/decisions.md "The compiled inner loop").
"""

from __future__ import annotations

import itertools
import logging
import math
import time
from dataclasses import dataclass, field, fields

import numpy as np
import ufl
from dolfinx import cpp, fem
from dolfinx.fem.petsc import assemble_matrix, create_matrix, create_vector
from petsc4py import PETSc
from ufl.algorithms.analysis import extract_coefficients, extract_constants

from .native_newton import NEED_JACOBIAN

JACOBIAN_POLICIES = ("full", "lagged", "frozen")
_prefix_counter = itertools.count()


@dataclass
class NewtonSettings:
    """The solver's settings (module docstring). The defaults are those of the solver used
    on its own (full Newton, as the unit tests and the manufactured solutions use it); a
    scene's [solver] table has its own, the schema's (cosserat_fem/schema.py), and
    :meth:`of` copies every one of them: a run never meets these defaults but ``xatol``."""

    jacobian: str = "full"
    lag: int = 10
    refresh_iterations: int = 4
    rtol: float = 1e-10
    atol: float = 1e-12
    stol: float = 1e-8
    xatol: float = 1e-13
    max_iterations: int = 25
    linear_solver: str = "auto"  # auto | petsc | mumps | superlu
    loop: str = "auto"  # auto (the C inner loop where it applies: native_newton.py) | python
    #: newton (this module's loop) | snes (PETSc's, cosserat_fem/snes.py) | auto (snes if
    #: ``petsc`` gives options): :func:`cosserat_fem.solvers.make_solver` chooses by it.
    nonlinear: str = "newton"
    #: SNES's PETSc options: name (without "-" and the prefix cosserat_) = value as text.
    petsc: dict = field(default_factory=dict)

    @classmethod
    def of(cls, solver) -> NewtonSettings:
        """The settings of an object with these attributes (a scene's [solver] table); those
        it lacks keep their defaults."""
        names = [f.name for f in fields(cls) if hasattr(solver, f.name)]
        return cls(**{name: getattr(solver, name) for name in names})


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
    #: The most iterations a solve took (a running maximum: nothing grows with the run's length).
    max_iterations_in_a_solve: int = 0

    def as_dict(self) -> dict:
        return dict(self.__dict__)


class NewtonFailure(RuntimeError):
    """A nonlinear solve did not converge (the caller adds time and place)."""

    def __init__(self, reason: str, iterations: int):
        super().__init__(reason)
        self.reason = reason
        self.iterations = iterations


_REASONS = {v: k for k, v in vars(PETSc.SNES.ConvergedReason).items() if isinstance(v, int)}
_INSERT, _ADD = PETSc.InsertMode.INSERT, PETSc.InsertMode.ADD
_FORWARD, _REVERSE = PETSc.ScatterMode.FORWARD, PETSc.ScatterMode.REVERSE


class NewtonSolver:
    """Newton solver for F(U; V) = 0 with Dirichlet conditions ``bcs`` on U (module docstring).

    The residual rows of constrained dofs are x − g and the Jacobian's rows and columns there
    the identity's, so a guess off the Dirichlet values g still converges, but its first
    update ignores their coupling to the free dofs: the caller puts g into the guess (the time
    loop does for moving supports; docs/decisions.md, "Dirichlet values in the guess").
    The iterates are U's own vector (without a line search F is only evaluated at iterates);
    ``b`` holds F at the last one (also after a failure).
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
        self._native = None
        self.settings = settings
        self.stats = NewtonStatistics()
        self.iteration_hook = None  # f(it, norms, reason) after each convergence test
        comm = U.function_space.mesh.comm
        self._parallel = comm.size > 1
        self._update_prev = 0.0  # ‖δU_{k−1}‖ of the current solve
        self._f_prev = 0.0  # ‖F(U_{k−1})‖ of the current solve
        self._f0 = 0.0
        self._compile_params = (form_compiler_params or {}, jit_params or {})
        self.compile_time = 0.0
        self._compile(F)

        self._u = U.vector  # the iterate: U's own PETSc vector
        index_map = U.function_space.dofmap.index_map
        owned = index_map.size_local * U.function_space.dofmap.index_map_bs
        self._u_owned = U.x.array[:owned]  # its owned values, for the Dirichlet rows
        self.b = create_vector(self.F_form)  # F(U)
        self.dx = create_vector(self.F_form)  # the Newton update δU
        self._initial = create_vector(self.F_form)  # the initial guess, kept for a retry
        self.A = create_matrix(self.J_form, mat_type="baij")
        self._need_jacobian = True
        self._solves_since_jacobian = 0

        self.lu_package = self._lu_package(comm, settings.linear_solver)
        self.ksp = PETSc.KSP().create(comm)
        # Configured through the API, not the options database: PETSc 3.18 keeps at most 512
        # options, and a session that builds many solvers (a test suite) would fill it.
        # setFromOptions still lets a user override any of it with -<prefix>ksp_/pc_ options.
        self.ksp.setOptionsPrefix(f"cosserat_newton_{next(_prefix_counter)}_")
        self.ksp.setType("preonly")
        self.ksp.getPC().setType("lu")
        self.ksp.getPC().setFactorSolverType(self.lu_package)
        if self.lu_package == "petsc" and settings.jacobian == "frozen":
            # The rod's dofs are numbered along it: in their own order the factors fill more
            # but PETSc's blocked triangular solves run 1.2-2.5x faster, which a factorisation
            # kept for thousands of solves repays (docs/decisions.md, "LU ordering").
            self.ksp.getPC().setFactorOrdering("natural")
        self.ksp.setOperators(self.A)
        self.ksp.setFromOptions()
        self.loop = "python"  # what runs the iterations: "python" or "c" (_make_native)
        self._make_native()

    @property
    def settings(self) -> NewtonSettings:
        return self._settings

    @settings.setter
    def settings(self, settings: NewtonSettings) -> None:
        """New settings, for the C loop's stop rule too."""
        self._settings = settings
        if self._native is not None:
            self._native.configure(settings)

    def _compile(self, F: ufl.Form) -> None:
        """The residual and Jacobian forms of F; what the Jacobian is assembled from, and (for
        a reused Jacobian) their values at its last assembly: a restarted run re-assembles the
        very same matrix (load_state_dict)."""
        fcp, jp = self._compile_params
        t0 = time.perf_counter()
        self.F_form = fem.form(F, form_compiler_params=fcp, jit_params=jp)
        J = ufl.derivative(F, self.U, ufl.TrialFunction(self.U.function_space))
        self.J_form = fem.form(J, form_compiler_params=fcp, jit_params=jp)
        self.compile_time += time.perf_counter() - t0
        self._J_inputs = (extract_coefficients(J), extract_constants(J))
        self._J_snapshot: dict | None = None

    def set_form(self, F: ufl.Form) -> None:
        """Solve F = 0 from now on, F a residual of the same unknown (e.g. the forms of a new
        chart, cosserat_fem/charts.py); the next solve assembles a new Jacobian. The matrix
        keeps its sparsity (same space), the statistics go on."""
        self._compile(F)
        self._make_native()
        self.request_jacobian()

    def _make_native(self) -> None:
        """The C inner loop for the current form (cosserat_fem/native_newton.py) when the
        settings allow it and it applies: its residual must equal DOLFINx's bit for bit."""
        self._native = None
        self.loop = "python"
        if self.settings.loop != "auto" or self._parallel:
            return
        from .native_newton import NativeLoop, NotApplicable

        try:
            native = NativeLoop(self.F_form, self.U, self.bcs, self._u, self.b, self.dx,
                                self.ksp, self.settings)  # fmt: skip
            native.refresh()
            native.residual()
            via_c = self.b.array.copy()
            self._assemble(self.b.array_w, dirichlet=True)
            if not np.array_equal(via_c, self.b.array, equal_nan=True):
                raise NotApplicable("its residual differs from DOLFINx's")
        except NotApplicable as exc:
            logging.getLogger(__name__).info("Newton's inner loop in Python: %s", exc)
            return
        self._native = native
        self.loop = "c"

    @staticmethod
    def _lu_package(comm, choice: str) -> str:
        """The LU package for solver.linear_solver = ``choice``: "auto" is PETSc's own in serial,
        MUMPS under MPI; ValueError for PETSc's own under MPI."""
        if choice == "auto":
            return "petsc" if comm.size == 1 else "mumps"
        if choice == "petsc" and comm.size > 1:
            raise ValueError("PETSc's own LU is serial only; use linear_solver = 'mumps'")
        return choice

    # -- residual, Jacobian, convergence test ----------------------------------------------
    def _residual(self, b: PETSc.Vec | None = None) -> None:
        """b = F(U), with x − g in the rows of the Dirichlet dofs (class docstring); ``b`` is
        the solver's own vector unless given (one of SNES's). Under MPI U's ghosts are updated
        first and b's ghost contributions added."""
        t0 = time.perf_counter()
        b = self.b if b is None else b
        if self._parallel:
            self._u.ghostUpdate(addv=_INSERT, mode=_FORWARD)
            with b.localForm() as local:
                self._assemble(local.array_w, dirichlet=False)
            b.ghostUpdate(addv=_ADD, mode=_REVERSE)
            cpp.fem.set_bc(b.array_w, self.bcs, self._u_owned, -1.0)
        else:
            self._assemble(b.array_w, dirichlet=True)
        # b's arrays are released (VecRestoreArray): its state has moved on, so PETSc does
        # not answer with a norm it cached before.
        self.stats.residual_assemblies += 1
        self.stats.time_residual += time.perf_counter() - t0

    def _norms(self) -> tuple[float, float, float]:
        """(‖U‖, ‖δU‖, ‖F‖) after an iteration, in one reduction as SNES's line search takes
        them (which rounds differently from three norms under MPI)."""
        u, dx, b = self._u, self.dx, self.b
        b.normBegin()
        dx.normBegin()
        u.normBegin()
        fnorm, ynorm = b.normEnd(), dx.normEnd()
        return u.normEnd(), ynorm, fnorm

    def _assemble(self, array: np.ndarray, dirichlet: bool) -> None:
        """F(U) into ``array`` (zeroed first): DOLFINx's assemble_vector without its Python
        layers (coefficients and constants packed anew); with ``dirichlet`` (``array`` then
        the owned values) also the rows x − g of the Dirichlet dofs."""
        form = self.F_form
        array.fill(0.0)
        coefficients, constants = cpp.fem.pack_coefficients(form), cpp.fem.pack_constants(form)
        cpp.fem.assemble_vector(array, form, constants, coefficients)
        if dirichlet:
            cpp.fem.set_bc(array, self.bcs, self._u_owned, -1.0)

    def _jacobian(self) -> None:
        """J(U) into A when the policy asks for it (identity rows and columns at the Dirichlet
        dofs); for a reused Jacobian its inputs are kept for a checkpoint."""
        if not (self._need_jacobian or self.settings.jacobian == "full"):
            return
        t0 = time.perf_counter()
        A = self.A
        A.zeroEntries()
        assemble_matrix(A, self.J_form, bcs=self.bcs)
        A.assemble()
        if self.settings.jacobian != "full":
            coefficients, constants = self._J_inputs
            self._J_snapshot = {
                **{f"coefficient{i}": c.x.array.copy() for i, c in enumerate(coefficients)},
                **{f"constant{i}": np.array(c.value) for i, c in enumerate(constants)},
            }
        self._need_jacobian = False
        self._solves_since_jacobian = 0
        self.stats.jacobian_assemblies += 1
        self.stats.time_jacobian += time.perf_counter() - t0

    def _converged(self, it: int, norms) -> int:
        """Convergence test of the module docstring; norms = (‖U‖, ‖δU‖, ‖F‖). Each result
        goes to ``iteration_hook(it, norms, reason)`` if one is set (an observer's)."""
        reason = self._test(it, norms)
        if self.iteration_hook is not None:
            self.iteration_hook(it, norms, reason)
        return reason

    def _test(self, it: int, norms) -> int:
        """The SNES reason after iteration ``it``, norms = (‖U‖, ‖δU‖, ‖F‖), by the tests of the
        module docstring; keeps ‖δU‖ and ‖F‖ for the next contraction estimate."""
        xnorm, ynorm, fnorm = norms
        reasons, st = PETSc.SNES.ConvergedReason, self.settings
        if fnorm != fnorm or ynorm != ynorm:
            return reasons.DIVERGED_FNORM_NAN
        if it == 0:
            self._f0 = self._f_prev = fnorm
            return reasons.CONVERGED_FNORM_ABS if fnorm <= st.atol else reasons.ITERATING
        linear = it >= 2 and st.jacobian != "full" and self._update_prev > 0.0
        # The contraction as both the updates and the residuals see it (module docstring).
        rho = max(ynorm / self._update_prev, fnorm / self._f_prev) if linear else 0.0
        self._update_prev, self._f_prev = ynorm, fnorm
        if fnorm <= st.atol:
            return reasons.CONVERGED_FNORM_ABS
        if fnorm <= st.rtol * self._f0:
            return reasons.CONVERGED_FNORM_RELATIVE
        tolerance = st.stol * xnorm + st.xatol
        if ynorm <= tolerance or (linear and rho < 1.0 and ynorm * rho / (1.0 - rho) <= tolerance):
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
        initial = self._initial
        self._u.copy(initial)
        fresh = self._need_jacobian or policy == "full"
        iterations, reason = self._run()
        if reason <= 0 and not fresh:
            # An old Jacobian may be the cause: retry once from the same guess with a new one.
            self.stats.retries += 1
            initial.copy(self._u)
            self._need_jacobian = True
            more, reason = self._run()
            iterations += more
        self._solves_since_jacobian += 1
        self.stats.solves += 1
        self.stats.last_iterations = iterations
        self.stats.max_iterations_in_a_solve = max(
            self.stats.max_iterations_in_a_solve, iterations
        )
        if reason <= 0:
            raise NewtonFailure(_REASONS.get(reason, str(reason)), iterations)
        if policy == "frozen" and iterations > self.settings.refresh_iterations:
            self._need_jacobian = True
        return iterations

    def _iteration(self) -> tuple[int, tuple[float, float, float] | None]:
        """One Newton iteration from U with F(U) in b: the linear solve, U ← U − δU, F(U) and
        the norms; (the KSP's reason, the norms (‖U‖, ‖δU‖, ‖F‖) or None if it failed).
        The C loop does the same in one call (cosserat_fem/newton_loop.c)."""
        ksp = self.ksp
        ksp.solve(self.b, self.dx)
        reason = ksp.getConvergedReason()
        if reason < 0:
            return reason, None
        self._u.axpy(-1.0, self.dx)
        self._residual()
        return reason, self._norms()

    def _run(self) -> tuple[int, int]:
        """Newton's iterations from U, which then holds the last iterate: (iterations, SNES
        reason). The steps, norms and exits of SNES newtonls with the basic line search."""
        t0 = time.perf_counter()
        reasons = PETSc.SNES.ConvergedReason
        native = self._native
        if native is not None and self.iteration_hook is None and self.settings.jacobian != "full":
            return self._run_native(t0)
        if native is not None:
            counted = self._refresh_native()
            residual, iteration = native.residual, native.iterate
        else:
            residual, iteration = self._residual, self._iteration
        residual()
        fnorm = self.b.norm()
        it = 0
        if not math.isfinite(fnorm):
            reason = reasons.DIVERGED_FNORM_NAN
        else:
            reason = self._converged(0, (0.0, 0.0, fnorm))
        while reason == reasons.ITERATING and it < self.settings.max_iterations:
            self._jacobian()
            ksp_reason, norms = iteration()
            if ksp_reason < 0:
                reason = reasons.DIVERGED_LINEAR_SOLVE
                break
            if not math.isfinite(norms[2]):
                reason = reasons.DIVERGED_FNORM_NAN
                break
            it += 1
            reason = self._converged(it, norms)
        if reason == reasons.ITERATING:
            reason = reasons.DIVERGED_MAX_IT
        if native is not None:
            self._count_native(counted)
        self.stats.time_solve += time.perf_counter() - t0
        self.stats.iterations += it
        return it, reason

    def _refresh_native(self) -> tuple[int, float]:
        """The C loop's constants and Dirichlet values for this solve; its counters before it."""
        self._native.refresh()
        return self._native.counters

    def _count_native(self, counted: tuple[int, float]) -> None:
        """The C loop's residual assemblies and their time since ``counted``, into the stats."""
        assemblies, seconds = self._native.counters
        self.stats.residual_assemblies += assemblies - counted[0]
        self.stats.time_residual += seconds - counted[1]

    def _run_native(self, t0: float) -> tuple[int, int]:
        """:meth:`_run` in one call into C (cosserat_fem/newton_loop.c ``cf_newton``, for a
        reused Jacobian and no iteration hook): the same iterates, norms, counts and reasons."""
        counted = self._refresh_native()
        st = self._native.newton(self._need_jacobian, self._jacobian, self._update_prev)
        self._f0, self._f_prev, self._update_prev = st.f0, st.f_prev, st.update_prev
        self._count_native(counted)
        self.stats.time_solve += time.perf_counter() - t0
        self.stats.iterations += st.iterations
        return st.iterations, st.reason

    def solve_stages(self, sd, call) -> None:
        """The Newton solves of a time step taken in C (cosserat_fem/native_sdirk.py): ``call()``
        runs ``cf_sdirk_step`` on ``sd`` (its ``cf_sdirk``) with this solver's C loop, which
        applies :meth:`solve`'s policy per stage. The policy's state goes in, the counters come
        out as :meth:`solve` keeps them, a Jacobian is assembled whenever the C asks for one,
        and a stage that fails raises the NewtonFailure :meth:`solve` raises."""
        native = self._native
        counted = native.counters
        stats = self.stats
        sd.need_jacobian, sd.since = self._need_jacobian, self._solves_since_jacobian
        sd.solves = sd.newton_iterations = sd.retries = 0
        sd.time_solve = 0.0
        sd.max_in_a_solve = stats.max_iterations_in_a_solve
        st = native.state
        st.update_prev = self._update_prev
        status = call()
        while status == NEED_JACOBIAN:
            t0 = time.perf_counter()
            self._need_jacobian = True
            self._jacobian()
            sd.need_jacobian = sd.since = 0
            sd.time_solve += time.perf_counter() - t0
            status = call()
        if status:
            raise RuntimeError(f"PETSc error {status} in the C time step, stage {sd.stage + 1}, "
                               f"its unknown at τ = ω0 t = {sd.unknown_time:.10g}")
        self._f0, self._f_prev, self._update_prev = st.f0, st.f_prev, st.update_prev
        self._need_jacobian, self._solves_since_jacobian = bool(sd.need_jacobian), sd.since
        stats.solves += sd.solves
        stats.iterations += sd.newton_iterations
        stats.retries += sd.retries
        stats.time_solve += sd.time_solve
        if sd.solves:
            stats.last_iterations = sd.last_iterations
        stats.max_iterations_in_a_solve = sd.max_in_a_solve
        self._count_native(counted)
        if sd.reason <= 0:
            raise NewtonFailure(_REASONS.get(sd.reason, str(sd.reason)), sd.stage_iterations)

    # -- checkpoint/restart ---------------------------------------------------------------
    def state_dict(self) -> dict:
        """The policy's state, the counters and the inputs of the reused Jacobian."""
        counters = {f"stats.{f.name}": getattr(self.stats, f.name) for f in fields(self.stats)}
        state = {
            "need_jacobian": self._need_jacobian,
            "solves_since_jacobian": self._solves_since_jacobian,
            **counters,
        }
        if self._J_snapshot is not None:
            state.update({f"jacobian.{k}": v for k, v in self._J_snapshot.items()})
        return state

    def load_state_dict(self, state: dict) -> None:
        """Restore :meth:`state_dict`; a reused Jacobian is re-assembled from the saved inputs
        (the same matrix, so the same LU factors and the same iterates as the first run)."""
        if "stats.history" in state:  # a checkpoint of before the running maximum
            history = np.asarray(state["stats.history"])
            state = {**state, "stats.max_iterations_in_a_solve": int(history.max(initial=0))}
        for f in fields(self.stats):
            kind = type(getattr(self.stats, f.name))
            setattr(self.stats, f.name, kind(state[f"stats.{f.name}"]))
        self._solves_since_jacobian = int(state["solves_since_jacobian"])
        self._need_jacobian = bool(state["need_jacobian"])
        if self.settings.jacobian == "full" or "jacobian.coefficient0" not in state:
            self._need_jacobian = True
            return
        coefficients, constants = self._J_inputs
        kept_c = [c.x.array.copy() for c in coefficients]
        kept_k = [np.array(c.value) for c in constants]
        for i, c in enumerate(coefficients):
            c.x.array[:] = state[f"jacobian.coefficient{i}"]
        for i, c in enumerate(constants):
            c.value = state[f"jacobian.constant{i}"]
        self.A.zeroEntries()
        assemble_matrix(self.A, self.J_form, bcs=self.bcs)
        self.A.assemble()
        self._J_snapshot = {
            k.removeprefix("jacobian."): np.array(v) for k, v in state.items()
            if k.startswith("jacobian.")
        }
        for c, value in zip(coefficients, kept_c, strict=True):
            c.x.array[:] = value
        for c, value in zip(constants, kept_k, strict=True):
            c.value = value
        # The saved "need a new Jacobian" flag stands: a pending refresh still happens.

    def destroy(self) -> None:
        """Free the PETSc objects (KSP, matrix, vectors); the solver is unusable afterwards."""
        self.ksp.destroy()
        self.A.destroy()
        self.b.destroy()
        self.dx.destroy()
        self._initial.destroy()
