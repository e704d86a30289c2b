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

The policy, the loop and the stop rule are written once, in C (cosserat_fem/nls/newton_loop.c
``cf_solve``, ``cf_test``; built by cosserat_fem/nls/native_newton.py); Python gives it callbacks
for DOLFINx's residual assembly (MPI, ``solver.loop = "python"``, a form the C assembler does
not carry), the Jacobian and an observer of the iterations. In a serial run the residual is
assembled in C where the form allows it (the same operations as DOLFINx's, the same iterates
bit for bit; ``NewtonSettings.loop``, docs/decisions.md "The compiled inner loop").
"""

from __future__ import annotations

import itertools
import logging
import time
from collections.abc import Callable
from dataclasses import dataclass, field, fields

import numpy as np
import ufl
from dolfinx import cpp, fem
from dolfinx.fem.petsc import assemble_matrix, create_matrix, create_vector
from petsc4py import PETSc
from ufl.algorithms.analysis import extract_coefficients, extract_constants

from cosserat_fem.common.errors import CosseratError
from cosserat_fem.nls.constraints import Identification
from cosserat_fem.nls.contact import NodeContact
from cosserat_fem.nls.contacts import Contacts
from cosserat_fem.nls.native_newton import NativeLoop, core

JACOBIAN_POLICIES = ("full", "lagged", "frozen")
_prefix_counter = itertools.count()


@dataclass(frozen=True)
class NewtonSettings:
    """The solver's settings (module docstring). The defaults are those of the solver used
    on its own (full Newton, as the unit tests and the manufactured solutions use it); a
    scene's [solver] table has its own, the schema's (cosserat_fem/scene/schema.py), and
    :meth:`of` copies every one of them: a run never meets these defaults but ``xatol``.

    Frozen: the C solve holds its own copy of the stop rule's and the policy's numbers
    (``cf_settings``, written when a solver's ``settings`` is set), so a field changed in place
    would reach Python and not C. Derive other settings with ``dataclasses.replace`` and give
    them to the solver (``solver.settings = ...``); assignment raises FrozenInstanceError
    (tests/unit/nls/test_newton.py)."""

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
    #: newton (this module's loop) | snes (PETSc's, cosserat_fem/nls/snes.py) | auto (snes if
    #: ``petsc`` gives options): :func:`cosserat_fem.nls.solvers.make_solver` chooses by it.
    nonlinear: str = "newton"
    #: SNES's PETSc options: name (without "-" and the prefix cosserat_) = value as text.
    petsc: dict = field(default_factory=dict)

    @classmethod
    def of(cls, solver) -> NewtonSettings:
        """The settings of an object with these attributes (a scene's [solver] table); those
        it lacks keep their defaults. ``petsc`` is copied: a change to the table's dict
        afterwards does not reach the settings."""
        names = [f.name for f in fields(cls) if hasattr(solver, f.name)]
        values = {name: getattr(solver, name) for name in names}
        if "petsc" in values:  # its own copy: the frozen settings share no mutable field
            values["petsc"] = dict(values["petsc"])
        return cls(**values)


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
        constraints: Identification | None = None,
        contact: NodeContact | Contacts | None = None,
    ):
        if settings.jacobian not in JACOBIAN_POLICIES:
            raise ValueError(f"unknown Jacobian policy {settings.jacobian!r}")
        if contact is not None and settings.jacobian != "full":
            raise ValueError("contact's rows change with every iterate: solver.jacobian = 'full'")
        self.U = U
        self.bcs = bcs
        #: dofs tied to others by rows of F and J (cosserat_fem/nls/constraints.py), or None;
        #: under MPI on every rank alike (its matrix operations are collective)
        self.constraints = constraints
        #: rows replaced at every iterate (cosserat_fem/nls/contact.py), or None
        self.contact = contact
        self._native: NativeLoop | None = None
        comm = U.function_space.mesh.comm
        module = core(comm)  # collective: rank 0 compiles on a cold cache
        self._ffi, self._lib = module.ffi, module.lib
        self._cs = self._ffi.new("cf_settings*")  # the stop rule's and the policy's settings
        self._state = self._ffi.new("cf_newton_state*")  # the policy's state, the counters
        self._state.need_jacobian = 1
        self._state.guard = int(contact is not None)
        self._sv = self._ffi.new("cf_solver*")  # the C solve's vectors and callbacks
        self._handle = self._ffi.new_handle(self)
        #: An exception a callback raised inside cf_solve, raised again after it.
        self.callback_error: BaseException | None = None
        self.settings = settings
        self._stats = NewtonStatistics()  # C's counters are copied in when it is read
        #: The Dirichlet values g are read again before each solve (a support may move); a
        #: time loop whose supports stay put sets it False (cosserat_fem/timestepping/loop.py), and
        #: the values read when the assembler was made stand.
        self.supports_move = True
        self._hook: Callable[[int, object, int], None] | None = None
        self._parallel = comm.size > 1
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
        self.A = self._new_matrix()
        #: the contact rows' share of A's pattern (:meth:`_renew_pattern`): the form's
        #: nonzeros, those a fresh matrix's first contact rows added, those added since
        self._pattern = {"fresh": True, "base": 0, "need": 0, "extra": 0, "renewals": 0}

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
        sv, ffi, lib = self._sv, self._ffi, self._lib
        sv.residual, sv.jacobian, sv.ctx = lib.cf_py_residual, lib.cf_py_jacobian, self._handle
        sv.u, sv.b = ffi.cast("void*", self._u.handle), ffi.cast("void*", self.b.handle)
        sv.dx, sv.ksp = ffi.cast("void*", self.dx.handle), ffi.cast("void*", self.ksp.handle)
        sv.initial = ffi.cast("void*", self._initial.handle)
        self.loop = "python"  # the residual's assembler: "python" (DOLFINx's) or "c"
        self._make_native()

    @property
    def settings(self) -> NewtonSettings:
        return self._settings

    @settings.setter
    def settings(self, settings: NewtonSettings) -> None:
        """New settings, for the C solve's stop rule and policy too."""
        self._settings = settings
        s = self._cs
        s.rtol, s.atol, s.stol, s.xatol = (
            settings.rtol,
            settings.atol,
            settings.stol,
            settings.xatol,
        )
        s.max_iterations = settings.max_iterations
        s.linear_test = settings.jacobian != "full"
        s.full = settings.jacobian == "full"
        s.lagged, s.lag = settings.jacobian == "lagged", settings.lag
        s.frozen, s.refresh_iterations = settings.jacobian == "frozen", settings.refresh_iterations

    @property
    def stats(self) -> NewtonStatistics:
        """The counters: those the C solve keeps (``cf_newton_state``), copied in at each read
        (not after each solve: a time step reads none), and the Jacobian's."""
        st, stats = self._state, self._stats
        stats.solves, stats.iterations = st.solves, st.newton_iterations
        stats.residual_assemblies, stats.retries = st.residuals, st.retries
        stats.time_residual, stats.time_solve = st.time_residual, st.time_solve
        stats.last_iterations, stats.max_iterations_in_a_solve = (
            st.last_iterations,
            st.max_in_a_solve,
        )
        return stats

    @property
    def iteration_hook(self):
        """f(it, norms, reason) after each convergence test (an observer's), or None."""
        return self._hook

    @iteration_hook.setter
    def iteration_hook(self, hook) -> None:
        self._hook = hook
        self._sv.on_iteration = self._ffi.NULL if hook is None else self._lib.cf_py_iteration

    @property
    def _need_jacobian(self) -> bool:
        """The policy: a Jacobian is assembled before the next iteration."""
        return bool(self._state.need_jacobian)

    @_need_jacobian.setter
    def _need_jacobian(self, value: bool) -> None:
        self._state.need_jacobian = int(value)

    def _compile(self, F: ufl.Form) -> None:
        """The residual and Jacobian forms of F; what the Jacobian is assembled from, and (for
        a reused Jacobian) their values at its last assembly: a restarted run re-assembles the
        very same matrix (load_state_dict)."""
        fcp, jp = self._compile_params
        t0 = time.perf_counter()
        self.F_form = fem.form(F, form_compiler_params=fcp, jit_params=jp)
        self._F_constants = F.constants()  # in the order DOLFINx packs them
        J = ufl.derivative(F, self.U, ufl.TrialFunction(self.U.function_space))
        self.J_form = fem.form(J, form_compiler_params=fcp, jit_params=jp)
        self.compile_time += time.perf_counter() - t0
        self._J_inputs = (extract_coefficients(J), extract_constants(J))
        self._J_snapshot: dict | None = None

    def set_form(self, F: ufl.Form) -> None:
        """Solve F = 0 from now on, F a residual of the same unknown (e.g. the forms of a new
        chart, cosserat_fem/rod/charts.py); the next solve assembles a new Jacobian. The matrix
        keeps its sparsity (same space), the statistics go on."""
        self._compile(F)
        self._make_native()
        self.request_jacobian()

    def _make_native(self) -> None:
        """The C residual assembler for the current form (cosserat_fem/nls/native_newton.py) when
        the settings allow it and it applies: its residual must equal DOLFINx's bit for bit;
        else cf_solve calls DOLFINx's assembly back."""
        self._native = None
        self._sv.problem = self._ffi.NULL
        self.loop = "python"
        if self.settings.loop != "auto" or self._parallel or self.contact is not None:
            return
        from cosserat_fem.nls.native_newton import NativeLoop, NotApplicable

        ties = self.constraints
        try:
            native = NativeLoop(self.F_form, self.U, self.bcs, self.b, self._F_constants, ties)
            native.refresh()
            native.residual()
            via_c = self.b.array.copy()
            self._assemble(self.b.array_w, dirichlet=True)
            if ties is not None:
                ties.apply_vector(self.b.array_w, self.U.x.array)
            if not np.array_equal(via_c, self.b.array, equal_nan=True):
                raise NotApplicable("its residual differs from DOLFINx's")
        except NotApplicable as exc:
            logging.getLogger(__name__).info("Newton's inner loop in Python: %s", exc)
            return
        self._native = native
        self._sv.problem = native.problem
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
        first and b's ghost contributions added. cf_solve counts and times it.

        Under MPI an exception of the local assembly (which may meet one rank only: a load's
        callable, a form's NaN check) does not leave this rank out of the collective steps
        that follow: it is kept in ``callback_error``, the local values are NaN, and the
        ghost scatters and the Dirichlet rows run as on every other rank. ‖F‖ is then NaN on
        every rank (DIVERGED_FNORM_NAN, or a retry), and :meth:`_finish` agrees on the
        exception (tests/test_newton_mpi.py)."""
        b = self.b if b is None else b
        if self._parallel:
            self._u.ghostUpdate(addv=_INSERT, mode=_FORWARD)
            with b.localForm() as local:
                try:
                    self._assemble(local.array_w, dirichlet=False)
                except Exception as exc:  # agreed after the solve (_finish)
                    self.callback_error = exc
                    local.array_w.fill(np.nan)
            b.ghostUpdate(addv=_ADD, mode=_REVERSE)
            cpp.fem.set_bc(b.array_w, self.bcs, self._u_owned, -1.0)
        else:
            self._assemble(b.array_w, dirichlet=True)
        if self.constraints is not None:  # (C.1)-(C.2) of cosserat_fem/nls/constraints.py
            self.constraints.apply_vector(b.array_w, self.U.x.array)
        if self.contact is not None:  # (K.1)-(K.3): not converged while its set changes
            self._state.hold = int(self.contact.apply_vector(b.array_w, self.U.x.array))
        # b's arrays are released (VecRestoreArray): its state has moved on, so PETSc does
        # not answer with a norm it cached before.

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
        """J(U) into A (identity rows and columns at the Dirichlet dofs), when cf_solve's
        policy asks for it; for a reused Jacobian its inputs are kept for a checkpoint."""
        t0 = time.perf_counter()
        self._assemble_jacobian()
        if self.settings.jacobian != "full":
            coefficients, constants = self._J_inputs
            self._J_snapshot = {
                **{f"coefficient{i}": c.x.array.copy() for i, c in enumerate(coefficients)},
                **{f"constant{i}": np.array(c.value) for i, c in enumerate(constants)},
            }
        self._stats.jacobian_assemblies += 1
        self._stats.time_jacobian += time.perf_counter() - t0

    def _new_matrix(self) -> PETSc.Mat:
        """A matrix of J's pattern (with the blocks the constraints' rows fill)."""
        if self.constraints is None:
            return create_matrix(self.J_form, mat_type="baij")
        return self.constraints.create_matrix(self.J_form)

    def _nonzeros(self) -> int:
        """A's nonzeros in use over the ranks (the same number on every rank)."""
        return int(self.A.getInfo(PETSc.Mat.InfoType.GLOBAL_SUM)["nz_used"])

    def _renew_pattern(self) -> None:
        """A fresh A when the contact rows' entries have grown past twice what a fresh
        matrix's first contact rows needed (or a tenth of the form's pattern, if more): the
        pairs' entries (cosserat_fem/nls/pair_contact.py) stay in the pattern once inserted,
        and as the pairs move along the rod they would fill it (the plectoneme's Jacobian
        grew 22-44 times after its strands met) and the LU with it. Collective."""
        p = self._pattern
        if p["fresh"] or p["extra"] <= max(2 * p["need"], p["base"] // 10):
            return
        old, self.A = self.A, self._new_matrix()
        self.ksp.reset()
        self.ksp.setOperators(self.A)
        old.destroy()
        p["fresh"] = True
        p["renewals"] += 1

    def _assemble_jacobian(self) -> None:
        """J(U) into A, with the constraints' rows (cosserat_fem/nls/constraints.py) and the
        contact rows (a fresh A first if their entries have grown: :meth:`_renew_pattern`)."""
        if self.contact is not None:
            self._renew_pattern()
        A = self.A
        A.zeroEntries()
        if self.constraints is not None:
            self.constraints.assemble_matrix(A, self.J_form, self.bcs, tangent=True)
        else:
            # assemble_matrix is a singledispatch whose overload for a PETSc.Mat first (mat,
            # form, bcs) DOLFINx's annotations do not show
            assemble_matrix(A, self.J_form, bcs=self.bcs)  # type: ignore[misc]
            A.assemble()
        if self.contact is not None:
            before = self._nonzeros()
            self.contact.apply_matrix(A)
            after = self._nonzeros()
            if after != before:
                # self contact's rows added entries (cosserat_fem/nls/pair_contact.py; the
                # pattern, not the allocation, which PETSc grows in chunks; over the ranks,
                # so that every rank resets): a new factorization from scratch (MUMPS 5.5
                # under PETSc 3.18 reused the first analysis's arrays for the larger pattern
                # and corrupted the heap)
                self.ksp.reset()
                self.ksp.setOperators(A)
            p = self._pattern
            if p["fresh"]:
                p.update(fresh=False, base=before, need=after - before)
            p["extra"] = after - p["base"]

    def _converged(self, it: int, norms) -> int:
        """The stop rule of the module docstring (``cf_test``, the one cf_solve runs) after
        iteration ``it``, norms = (‖U‖, ‖δU‖, ‖F‖): the SNES reason; the solve's running
        norms are kept for the next contraction estimate. Each result goes to
        ``iteration_hook(it, norms, reason)`` if one is set (an observer's)."""
        values = self._ffi.new("double[3]", [float(x) for x in norms])
        reason = int(self._lib.cf_test(self._cs, self._state, it, values))
        if self._hook is not None:
            self._hook(it, norms, reason)
        return reason

    def _observe(self, it: int, norms, reason: int) -> None:
        """cf_solve's on_iteration: the observer's hook (set: cf_solve calls this only then)."""
        assert self._hook is not None, "on_iteration is set only with a hook"
        self._hook(it, norms, reason)

    # -- solving --------------------------------------------------------------------------
    def request_jacobian(self) -> None:
        """Force a Jacobian re-assembly at the next Newton iteration (e.g. after h changed)."""
        self._need_jacobian = True

    def solve(self) -> int:
        """Solve from the current U (the initial guess), in C (``cf_solve``: the policy, the
        iterations, a retry; module docstring). Returns the number of iterations; raises
        NewtonFailure if it did not converge, or what a callback raised."""
        if self.supports_move and self._native is not None:
            self._native.refresh()
        # An exception an earlier solve's retry recovered from (under MPI a residual callback's
        # exception becomes a NaN residual) is not this solve's to report.
        self.callback_error = None
        # self contact's first iterate starts from the accepted pairs (pair_contact.py); the
        # mark is cleared whatever happens (one try: contact's Jacobian is full, no retry)
        first = getattr(self.contact, "first_iterate", None)
        if first is not None:
            first(True)
        try:
            status = self._lib.cf_solve(self._sv, self._cs, self._state)
        finally:
            if first is not None:
                first(False)
        st = self._state
        if status or st.reason <= 0:
            self._finish(status)
            raise NewtonFailure(_REASONS.get(st.reason, str(st.reason)), st.iterations)
        return st.iterations

    def _finish(self, status: int) -> None:
        """After a C solve: a callback's exception raised again
        (under MPI on every rank that met one; a CosseratError agreed across ranks), or a
        RuntimeError for a PETSc error code."""
        st = self._state
        if self._parallel and not status and st.reason <= 0:  # every rank's (global norms)
            from cosserat_fem.common.parallel import agree

            error, self.callback_error = self.callback_error, None
            if error is not None and not isinstance(error, CosseratError):
                error = RuntimeError(f"{type(error).__name__}: {error}")
            agree(self.U.function_space.mesh.comm, error)
        if status:
            error, self.callback_error = self.callback_error, None
            if error is None:
                error = RuntimeError(f"PETSc error {status} in a Newton solve")
            raise error

    # -- checkpoint/restart ---------------------------------------------------------------
    def state_dict(self) -> dict:
        """The policy's state, the counters and the inputs of the reused Jacobian."""
        counters = {f"stats.{f.name}": getattr(self.stats, f.name) for f in fields(self.stats)}
        state = {
            "need_jacobian": self._need_jacobian,
            "solves_since_jacobian": int(self._state.since),
            **counters,
        }
        if self._J_snapshot is not None:
            state.update({f"jacobian.{k}": v for k, v in self._J_snapshot.items()})
        if self.contact is not None:
            state.update(self.contact.state_dict())
        return state

    def load_state_dict(self, state: dict) -> None:
        """Restore :meth:`state_dict`; a reused Jacobian is re-assembled from the saved inputs
        (the same matrix, so the same LU factors and the same iterates as the first run)."""
        if "stats.history" in state:  # a checkpoint of before the running maximum
            history = np.asarray(state["stats.history"])
            state = {**state, "stats.max_iterations_in_a_solve": int(history.max(initial=0))}
        stats = self._stats
        for f in fields(stats):
            kind = type(getattr(stats, f.name))
            setattr(stats, f.name, kind(state[f"stats.{f.name}"]))
        st = self._state
        st.solves, st.newton_iterations = stats.solves, stats.iterations
        st.residuals, st.retries = stats.residual_assemblies, stats.retries
        st.time_residual, st.time_solve = stats.time_residual, stats.time_solve
        st.last_iterations, st.max_in_a_solve = (
            stats.last_iterations,
            stats.max_iterations_in_a_solve,
        )
        st.since = int(state["solves_since_jacobian"])
        if self.contact is not None:
            self.contact.load_state_dict(state)
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
        self._assemble_jacobian()
        self._J_snapshot = {
            k.removeprefix("jacobian."): np.array(v)
            for k, v in state.items()
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
