"""PETSc's SNES as the nonlinear solver, configured by PETSc options (solver.nonlinear = "snes").

:class:`SNESSolver` is a :class:`~cosserat_fem.nls.newton.NewtonSolver` whose iterations PETSc's
SNES runs: the same interface (``solve``, ``request_jacobian``, ``set_form``, ``b``, the
statistics, ``state_dict``), the same residual and Jacobian assembly, the same Jacobian
policies (full, lagged, frozen: SNES asks for the Jacobian at every iteration and the policy
decides whether it is assembled; an unchanged matrix keeps its LU factors), the same retry with
a fresh Jacobian, and the same stop rule: the policy and the retry are cf_solve's
(cosserat_fem/nls/newton_loop.c), which calls SNESSolve back instead of its own iterations, and
the stop rule ``cf_test`` (:meth:`NewtonSolver._converged`) is SNES's convergence test, called
by SNES with (‖U_k‖, ‖δU_k‖, ‖F(U_k)‖) as the project's loop calls it. Its
tolerances are SNES's own: solver.rtol, atol, stol and max_iterations set them, and the options
``snes_rtol``, ``snes_atol``, ``snes_stol`` and ``snes_max_it`` override them.

The defaults are those of the project's loop: SNES ``newtonls`` with the ``basic`` line search
(the full step) over the same KSP (``preonly`` + LU: PETSc's own in serial, MUMPS under MPI),
so that SNES's iterates are the loop's, up to the order of operations
(tests/test_snes.py). A time step or a load step whose solve fails (any SNES divergence:
``DIVERGED_LINE_SEARCH``, ``DIVERGED_TR_DELTA``, ...) raises the
:class:`~cosserat_fem.nls.newton.NewtonFailure` the loop raises, and is rejected and retried smaller
in the same way.

Options: ``settings.petsc`` (a scene's [solver.petsc] table; ``--petsc NAME=VALUE`` on the
command line) holds PETSc options without the leading "-" and the prefix
:data:`~cosserat_fem.scene.schema.PETSC_PREFIX` (``cosserat_``), e.g. ``snes_type = "newtontr"``,
``snes_linesearch_type = "bt"``, ``ksp_type = "gmres"``, ``pc_type = "bjacobi"``,
``snes_monitor = ""``. They are in PETSc's options database while SNES reads them (its set-up
and each solve: ``*_view`` and ``*_converged_reason`` options are read at every solve; with no
option given, only the :data:`DEFAULTS`, read at the set-up, the solves leave the database
alone), and taken out after, so that solvers built one after another (a sweep, a test
session) do not see each other's options; options given to PETSc otherwise
(``PETSC_OPTIONS="-cosserat_..."``) apply too. A value PETSc refuses, or an option PETSc has
not used by the end of the first solve (a misspelling, an option of a type not chosen), is a
SceneError naming the key.
"""

from __future__ import annotations

import contextlib
import ctypes
import time
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path

from dolfinx.fem.petsc import create_vector
from petsc4py import PETSc

from cosserat_fem.common.errors import SceneError
from cosserat_fem.common.parallel import agree
from cosserat_fem.nls.newton import NewtonSolver
from cosserat_fem.scene.schema import PETSC_PREFIX

_INSERT, _FORWARD = PETSc.InsertMode.INSERT, PETSc.ScatterMode.FORWARD
_USED = None


def _option_used(name: str) -> bool:
    """Whether PETSc has read the option ``name`` (without "-") of its global database
    (PetscOptionsUsed, which petsc4py does not wrap)."""
    global _USED
    if _USED is None:
        import petsc4py

        config = petsc4py.get_config()
        libdir = Path(config["PETSC_DIR"]) / (config.get("PETSC_ARCH") or "") / "lib"
        library = next(iter(sorted(libdir.glob("libpetsc*.so*"))))
        _USED = ctypes.CDLL(str(library)).PetscOptionsUsed
        _USED.argtypes = [ctypes.c_void_p, ctypes.c_char_p, ctypes.POINTER(ctypes.c_int)]
        _USED.restype = ctypes.c_int
    used = ctypes.c_int(0)
    if _USED(None, name.encode(), ctypes.byref(used)) != 0:
        return True  # PETSc could not say: nothing is reported
    return bool(used.value)


#: The defaults that differ from SNES's own (petsc4py 3.18 has no SNESLineSearch to set them
#: through): the full step, as the project's loop takes it. An option given otherwise (the
#: scene, ``PETSC_OPTIONS``) wins.
DEFAULTS = {"snes_linesearch_type": "basic"}


@contextlib.contextmanager
def petsc_options(options: dict[str, str], used: set[str] | None = None) -> Iterator[None]:
    """``options`` (name without "-" and prefix = value), and the :data:`DEFAULTS` that
    PETSc's database does not hold yet, in the database under :data:`PETSC_PREFIX` inside the
    block; after it each is taken out again (a value given to PETSc before is put back), and
    the names of ``options`` PETSc read are added to ``used`` if given."""
    database = PETSc.Options()
    given = {
        **{k: v for k, v in DEFAULTS.items() if not database.hasName(PETSC_PREFIX + k)},
        **options,
    }
    before = {}
    for name, value in given.items():
        full = PETSC_PREFIX + name
        before[full] = database.getString(full, "") if database.hasName(full) else None
        database.setValue(full, value)
    try:
        yield
    finally:
        for name in given:
            full = PETSC_PREFIX + name
            if used is not None and name in options and _option_used(full):
                used.add(name)
            if before[full] is None:
                database.delValue(full)
            else:
                database.setValue(full, before[full])


def _last_line(error: PETSc.Error) -> str:
    """PETSc's own reason of ``error``: the last line of its message, without the rank."""
    lines = [line.split("] ", 1)[-1].strip() for line in str(error).splitlines()]
    return next((line for line in reversed(lines) if line), f"error code {error.ierr}")


class SNESSolver(NewtonSolver):
    """The Newton solver of cosserat_fem/nls/newton.py with SNES running its iterations (module
    docstring). SNES iterates on a vector of its own (a line search evaluates F at trial
    points); U is set to the point before each residual or Jacobian assembly and holds the
    last iterate after a solve. ``loop`` is "snes"."""

    def __init__(self, *args, **kwargs):
        """NewtonSolver's arguments: F, U, bcs, settings (its ``petsc`` options), ..."""
        super().__init__(*args, **kwargs)
        self.comm = self.U.function_space.mesh.comm
        self._x = create_vector(self.F_form)  # SNES's iterate
        self.options = dict(self.settings.petsc)
        #: The options PETSc has read so far; None once they have been checked (first solve).
        self._used: set[str] | None = set()
        self.snes = self._create(self.comm, self.ksp)
        problem = None
        with petsc_options(self.options, self._used):
            try:
                self.snes.setFromOptions()
            except PETSc.Error as exc:
                problem = self._refused(exc)
        agree(self.comm, problem)
        rtol, atol, stol, max_it = self.snes.getTolerances()
        self.settings = replace(
            self.settings, rtol=rtol, atol=atol, stol=stol, max_iterations=max_it
        )

    def _create(self, comm, ksp: PETSc.KSP) -> PETSc.SNES:
        """A SNES of the defaults of the module docstring over ``ksp``, with this solver's
        residual, Jacobian, stop rule and tolerances, prefix :data:`PETSC_PREFIX`."""
        snes = PETSc.SNES().create(comm)
        snes.setKSP(ksp)
        snes.setOptionsPrefix(PETSC_PREFIX)
        snes.setType("newtonls")  # its line search: DEFAULTS
        snes.setFunction(self._snes_residual, self.b)
        snes.setJacobian(self._snes_jacobian, self.A)
        snes.setConvergenceTest(self._snes_test)
        st = self.settings
        snes.setTolerances(rtol=st.rtol, atol=st.atol, stol=st.stol, max_it=st.max_iterations)
        return snes

    def _refused(self, error: PETSc.Error) -> SceneError:
        """The SceneError for options PETSc refused when the SNES read them: the key is the
        first option that a SNES of the same set-up refuses alone."""
        reason = _last_line(error)
        for name, value in self.options.items():
            ksp = PETSc.KSP().create(self.comm)
            ksp.setType("preonly")
            ksp.getPC().setType("lu")
            ksp.getPC().setFactorSolverType(self.lu_package)
            trial = self._create(self.comm, ksp)
            try:
                with petsc_options({name: value}):
                    trial.setFromOptions()
            except PETSc.Error as exc:
                reason = _last_line(exc)
                return SceneError(f"solver.petsc.{name}: PETSc refused {value!r}: {reason}")
            finally:
                trial.destroy()
                ksp.destroy()
        return SceneError(f"solver.petsc: PETSc refused these options together: {reason}")

    def _make_native(self) -> None:
        """No C assembler: cf_solve runs SNES (:meth:`_iterate`) for its iterations."""
        self._native = None
        self._sv.problem = self._ffi.NULL
        self._sv.run = self._lib.cf_py_run
        self.loop = "snes"

    # -- SNES's callbacks ---------------------------------------------------------------------
    def _to_U(self, x: PETSc.Vec) -> None:
        """U's values ← SNES's point x (its owned values; the assembly updates the ghosts)."""
        x.copy(self._u)

    def _snes_residual(self, snes, x: PETSc.Vec, f: PETSc.Vec) -> None:
        """F(x) into f, counted and timed in the C solve's counters."""
        t0 = time.perf_counter()
        self._to_U(x)
        self._residual(f)
        st = self._state
        st.residuals += 1
        st.time_residual += time.perf_counter() - t0

    def _snes_jacobian(self, snes, x: PETSc.Vec, J: PETSc.Mat, P: PETSc.Mat) -> None:
        """J(x) into A when cf_solve's Jacobian policy asks for it (SNES asks at every
        iteration); U is set to x only then."""
        st = self._state
        if st.need_jacobian or self._cs.full:
            self._to_U(x)
            self._jacobian()
            st.need_jacobian, st.since = 0, 0

    def _snes_test(self, snes, it: int, norms: tuple[float, float, float]) -> int:
        return self._converged(it, norms)

    # -- a solve ------------------------------------------------------------------------------
    def _iterate(self, answer: list) -> None:
        """cf_solve's ``run``: SNES's iterations from U, which then holds the last iterate;
        ``answer`` = [iterations, SNES reason]. After the first solve, an option PETSc has not
        read is a SceneError."""
        snes = self.snes
        self._u.copy(self._x)
        if self.options or self._used is not None:
            with petsc_options(self.options, self._used):
                snes.solve(None, self._x)
        else:
            snes.solve(None, self._x)
        self._x.copy(self._u)
        if self._parallel:
            self._u.ghostUpdate(addv=_INSERT, mode=_FORWARD)
        answer[:] = snes.getIterationNumber(), snes.getConvergedReason()
        if self._used is not None:
            self._check_used(self._used)

    def _check_used(self, used: set[str]) -> None:
        """SceneError (on every rank) naming the first option PETSc has not read by now (of
        those not in ``used``, the options read so far)."""
        unused = [name for name in self.options if name not in used]
        self._used = None
        problem = None
        if unused:
            ksp = self.snes.getKSP()
            chosen = (
                f"snes_type {self.snes.getType()}, ksp_type {ksp.getType()}, pc_type "
                f"{ksp.getPC().getType()}"
            )
            problem = SceneError(
                f"solver.petsc.{unused[0]}: PETSc did not use this option ({chosen}): misspelt, "
                "or an option of a type not chosen"
            )
        agree(self.comm, problem)

    def destroy(self) -> None:
        """Free SNES and its vector, then the Newton solver's PETSc objects."""
        self.snes.destroy()
        self._x.destroy()
        super().destroy()
