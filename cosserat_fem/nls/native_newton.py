"""Newton's method in C (cosserat_fem/nls/newton_loop.c): its build, its callbacks, its assembler.

Every Newton solve runs ``cf_solve`` (:class:`~cosserat_fem.nls.newton.NewtonSolver`: the policy,
the iterations and the stop rule, written once; docs/decisions.md "One core"), which calls
Python back through the cffi callbacks bound here (:func:`_bind_callbacks`): DOLFINx's residual
assembly where the C one does not apply, the Jacobian's assembly, an observer of the
iterations, SNES's iterations (cosserat_fem/nls/snes.py). :class:`NativeLoop` is the C residual
assembler (``cf_residual``), which saves DOLFINx's coefficient and constant packing on each
call. It applies when the run is serial and the residual has cell and exterior facet integrals
only (an interior facet integral, a point load's, keeps DOLFINx's assembly), and only after it
has proved itself on the form: the coefficient tables are read off DOLFINx's
``pack_coefficients`` and the first residual must equal DOLFINx's assembly bit for bit, else
DOLFINx's is used (the reason logged at INFO; tests/test_native_newton.py).

The C source is compiled once per machine with cffi into the JIT cache directory
(``$XDG_CACHE_HOME/fenics``, as FFCx's forms), against PETSc's headers and FFCx's ufcx.h; a
failed compile is a CosseratError when a solver is built (FFCx's forms need the compiler too);
under MPI rank 0 compiles while the others wait, and a failure is agreed (:func:`core`).
A cached library is checked before it is loaded (cosserat_fem/common/jit.py ``load_checked``): a
damaged one is compiled again.
"""

from __future__ import annotations

import hashlib
import importlib.machinery
import importlib.util
import logging
import os
import re
import shutil
import subprocess
import tempfile
from pathlib import Path

import numpy as np
from dolfinx import cpp

log = logging.getLogger(__name__)

SOURCE = Path(__file__).with_name("newton_loop.c")

CDEF = """
typedef struct {
  void* kernel; int32_t entities; const int32_t* cells; const int32_t* local_facets;
  int32_t wsize; const int32_t* source; const int32_t* index; const double* weights;
} cf_integral;
typedef struct {
  int32_t n_integrals; const cf_integral* integrals; double* const* coefficients;
  int32_t n_constants; double* const* constant_values; const int32_t* constant_sizes;
  double* constants; const double* coordinates; int32_t coordinates_per_cell;
  const int32_t* dofs; int32_t dofs_per_cell; int32_t n_bc; const int32_t* bc_dofs;
  const double* bc_values; const double* u_values; double* w; double* be; void* b;
  int32_t n_ties; const int32_t* tie_copies; const int32_t* tie_masters;
  const int32_t* tie_added;
} cf_problem;
typedef int (*cf_call)(void* ctx);
typedef int (*cf_observe)(void* ctx, int it, const double* norms, int reason);
typedef int (*cf_run)(void* ctx, int* iterations, int* reason);
typedef int (*cf_guess)(void* ctx, int restore);
typedef struct {
  double rtol, atol, stol, xatol; int max_iterations; int linear_test;
  int full, lagged, lag, frozen, refresh_iterations;
} cf_settings;
typedef struct {
  cf_problem* problem; cf_call residual, jacobian; cf_observe on_iteration; cf_run run;
  void* ctx; void *u, *b, *dx, *ksp, *initial; cf_guess guess;
} cf_solver;
typedef struct {
  double f0, f_prev, update_prev; double norms[3]; int need_jacobian, since;
  int iterations, reason; int64_t solves, newton_iterations, retries, residuals;
  int last_iterations, max_in_a_solve; double time_solve, time_residual;
  int hold, guard;
} cf_newton_state;
int cf_residual(cf_problem* p);
int cf_test(const cf_settings* s, cf_newton_state* st, int it, const double* n);
int cf_solve(const cf_solver* sv, const cf_settings* s, cf_newton_state* st);
void* cf_kernel(uintptr_t form, int type, int i);
typedef struct {
  int32_t stages, n; double gamma; const double *A, *b, *c;
  double *u, *z, *u_n, *K, *taus, *rates, *times, *guess; double* time_value;
  int32_t predict; double h, time; int64_t stored; double unknown_time;
} cf_sdirk;
void cf_sdirk_stage(cf_sdirk* sd, int i);
void cf_sdirk_predict(cf_sdirk* sd, int i);
void cf_sdirk_accept(cf_sdirk* sd);
typedef struct {
  int32_t n, m; const double *V, *DV, *WV, *ref; const double *G, *g; double c;
  int32_t n_rows; const int32_t* rows; int32_t n_rest; const int32_t* rest;
  int32_t n_fit; const int32_t* fit; const double* P; int32_t project_all;
  cf_problem *F, *J; const cf_settings* s;
  cf_newton_state* st; const cf_solver* solver; void* observer;
  double *q, *r, *dq, *Jr, *lu, *work; int32_t* piv; int32_t factored;
  int64_t jacobians, full_projections; double time_jacobian;
  int32_t coordinates; int32_t n_lifts; double* const* lift_values;
  double* const* lift_coords; const double* lift_affine; double* q0;
  const double* VT; double* t;
} cf_reduced;
int cf_reduced_residual(cf_problem* p, const double* DV, int32_t m, double* r, double* out);
int cf_reduced_jacobian(cf_problem* p, const double* DV, const double* V, int32_t m, double* Jr,
                        double* work);
int cf_reduced_run(void* ctx, int* iterations, int* reason);
int cf_reduced_guess(void* ctx, int restore);
void cf_lift(const double* V, const double* ref, int32_t m, const double* q, double affine,
             const int32_t* rows, int32_t count, double* u);
extern "Python" int cf_py_residual(void* ctx);
extern "Python" int cf_py_jacobian(void* ctx);
extern "Python" int cf_py_iteration(void* ctx, int it, const double* norms, int reason);
extern "Python" int cf_py_run(void* ctx, int* iterations, int* reason);
"""
#: A callback's status when Python stored an exception (newton_loop.c CF_CALLBACK_ERROR).
CALLBACK_ERROR = -2


class NotApplicable(Exception):
    """Why a solver assembles its residual with DOLFINx (or why the C core is not built)."""


# --- the compiled module ------------------------------------------------------------------


def _petsc_build() -> tuple[list[str], str]:
    """(include directories, library directory) of the PETSc petsc4py was built against, and
    of its MPI."""
    import petsc4py

    petsc_dir = Path(petsc4py.get_config()["PETSC_DIR"])
    arch = petsc4py.get_config().get("PETSC_ARCH") or ""
    includes = [str(petsc_dir / "include"), str(petsc_dir / arch / "include")]
    variables = petsc_dir / arch / "lib" / "petsc" / "conf" / "petscvariables"
    if variables.exists():
        text = variables.read_text(errors="replace")
        found = re.search(r"^PETSC_CC_INCLUDES\s*=(.*)$", text, re.MULTILINE)
        if found:
            includes += [f[2:] for f in found.group(1).split() if f.startswith("-I")]
    mpicc = shutil.which("mpicc")
    if mpicc is not None:
        shown = subprocess.run(
            [mpicc, "--showme:incdirs"], capture_output=True, text=True, check=False
        )
        if shown.returncode == 0:
            includes += shown.stdout.split()
    return [i for i in dict.fromkeys(includes) if Path(i).is_dir()], str(petsc_dir / arch / "lib")


def _ufcx_include() -> str:
    import ffcx.codegeneration

    return str(Path(ffcx.codegeneration.__file__).parent)


def _cache_dir() -> Path:
    from dolfinx import jit

    return Path(jit.get_parameters()["cache_dir"]).expanduser()


_MODULE = None
#: Why the module could not be built, once that is known: the process does not try again.
_FAILED: str | None = None
COMPILE_ARGS = ["-O2", "-g0", "-ffp-contract=off"]  # no fused multiply-adds: Python's IEEE


def compiled():
    """The compiled module (``ffi``, ``lib``), made on first use and cached on disk; raises
    :class:`NotApplicable` if it cannot be built (remembered for the process: it is not tried
    again).

    A cached library is checked before it is loaded (cosserat_fem/common/jit.py
    :func:`~cosserat_fem.common.jit.library_damage`: its recorded SHA-256, or its ELF structure):
    a damaged one, or one that does not load, is compiled again with a warning."""
    global _MODULE
    if _MODULE is not None:
        return _MODULE
    if _FAILED is not None:
        raise NotApplicable(_FAILED)
    from cosserat_fem.common.jit import load_checked, record_digest, warn_damaged

    source = SOURCE.read_text()
    target = library_path(source)
    name = target.name.split(".")[0]
    module, damage = None, None
    if target.exists():
        module, damage = load_checked(target, lambda: _load(name, target))
    if module is None:
        if damage is not None:
            warn_damaged(target, damage)
            target.unlink(missing_ok=True)
        _build(name, source, target)
        record_digest(target)
        module = _load(name, target)
    _bind_callbacks(module)
    _MODULE = module
    return module


def core(comm=None):
    """:func:`compiled` for a solver or an integrator being built: a CosseratError naming the
    C core if it cannot be built (no compiler or no PETSc headers: there is no other core).

    Under MPI (``comm`` of several ranks; collective) rank 0 loads or compiles it first, the
    others wait (one compiler on a cold cache, not one per rank, as DOLFINx's JIT does for
    FFCx's forms) and then load rank 0's library from the cache, or compile it themselves if
    they do not see it (a cache local to their node). A failure on any rank is raised on every
    rank as the same one line (cosserat_fem.common.parallel.agree): no rank is left waiting for
    another (tests/test_newton_mpi.py)."""
    from cosserat_fem.common.errors import CosseratError
    from cosserat_fem.common.parallel import agree

    def attempt() -> CosseratError | None:
        try:
            compiled()
        except NotApplicable as exc:
            return CosseratError(f"Newton's C core (cosserat_fem/nls/newton_loop.c): {exc}")
        except Exception as exc:  # an OSError of the cache, a load that fails: agreed too
            return CosseratError(
                f"Newton's C core (cosserat_fem/nls/newton_loop.c): {type(exc).__name__}: {exc}"
            )
        return None

    if comm is None or comm.size == 1:
        problem = attempt()
        if problem is not None:
            raise problem
        return _MODULE
    agree(comm, attempt() if comm.rank == 0 else None)  # the others wait for rank 0's compile
    agree(comm, attempt() if comm.rank != 0 else None)
    return _MODULE


def _bind_callbacks(module) -> None:
    """The Python ends of cf_solve's callbacks (newton_loop.c): each calls a method of the
    solver whose handle is ``ctx`` (``_residual``, ``_jacobian``, ``_observe``, ``_iterate``);
    an exception, which cannot cross C, is stored in the solver's ``callback_error`` and
    answered with :data:`CALLBACK_ERROR`, and the solver raises it when cf_solve returns
    (under MPI a residual's exception is answered with a NaN residual instead, so that every
    rank leaves the solve alike: the local assembly's own, in ``_residual``, which still runs
    the ghost scatters every rank waits in; anything else, here)."""
    ffi = module.ffi
    from_handle = ffi.from_handle

    def guarded(name: str):
        def call(ctx, *args):
            solver = from_handle(ctx)
            try:
                return getattr(solver, name)(*args) or 0
            except BaseException as exc:  # re-raised by the solver after cf_solve
                solver.callback_error = exc
                return CALLBACK_ERROR

        return call

    def residual(ctx):
        solver = from_handle(ctx)
        try:
            solver._residual()
            return 0
        except BaseException as exc:
            solver.callback_error = exc
            if not solver._parallel:
                return CALLBACK_ERROR
            # Under MPI the other ranks go on into the norm's reduction: a NaN residual ends
            # the solve on every rank alike (DIVERGED_FNORM_NAN), and the solver then agrees
            # on the exception (cosserat_fem.common.parallel.agree). The local assembly's exception
            # does not come here: _residual keeps it and still runs the ghost scatters.
            solver.b.set(float("nan"))
            return 0

    ffi.def_extern(name="cf_py_residual")(residual)
    ffi.def_extern(name="cf_py_jacobian")(guarded("_jacobian"))
    observe, run = guarded("_observe"), guarded("_iterate")
    ffi.def_extern(name="cf_py_iteration")(
        lambda ctx, it, norms, reason: observe(ctx, it, (norms[0], norms[1], norms[2]), reason)
    )

    def iterate(ctx, iterations, reason):
        answer = [0, 0]
        status = run(ctx, answer)
        iterations[0], reason[0] = answer
        return status

    ffi.def_extern(name="cf_py_run")(iterate)


def library_path(source: str | None = None) -> Path:
    """Where the compiled C loop of ``source`` (default: newton_loop.c as it is) is cached:
    its name holds a hash of the source, the declarations, the compiler's flags and the
    versions of PETSc, FFCx and cffi."""
    import cffi
    import ffcx
    import petsc4py

    source = SOURCE.read_text() if source is None else source
    build = [
        source,
        CDEF,
        *COMPILE_ARGS,
        str(petsc4py.get_config()),
        ffcx.__version__,
        cffi.__version__,
    ]
    key = hashlib.sha1("\n".join(build).encode()).hexdigest()[:16]
    suffix = importlib.machinery.EXTENSION_SUFFIXES[0]
    return _cache_dir() / f"cosserat_newton_loop_{key}{suffix}"


def _load(name: str, target: Path):
    spec = importlib.util.spec_from_file_location(name, target)
    if spec is None or spec.loader is None:  # damage, as load_checked takes an ImportError
        raise ImportError(f"{target} is not a loadable module")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _build(name: str, source: str, target: Path) -> None:
    """Compile ``source`` into the library ``target`` (moved there whole, atomically: a
    concurrent process finds it whole or not at all); NotApplicable if it does not compile."""
    global _FAILED
    import cffi

    includes, libdir = _petsc_build()
    includes.append(_ufcx_include())
    ffi = cffi.FFI()
    ffi.cdef(CDEF)
    ffi.set_source(
        name,
        source,
        include_dirs=includes,
        libraries=["petsc_real"],
        library_dirs=[libdir],
        extra_link_args=[f"-Wl,-rpath,{libdir}"],
        extra_compile_args=COMPILE_ARGS,
    )
    target.parent.mkdir(parents=True, exist_ok=True)
    from cosserat_fem.common.jit import capture_stderr

    with tempfile.TemporaryDirectory(dir=target.parent) as work, capture_stderr() as captured:
        try:
            built = ffi.compile(tmpdir=work)
        except Exception as exc:  # a compiler or a missing header: keep the Python loop
            _FAILED = f"the C loop did not compile ({exc})"
            raise NotApplicable(_FAILED) from None
        os.replace(built, target)
    if captured.text.strip():
        log.info("compiling %s:\n%s", SOURCE.name, captured.text)


# --- one solver's loop ----------------------------------------------------------------------


def _gather_tables(form) -> dict:
    """{(integral type, id): (source (wsize,), index (entities, wsize))}: where DOLFINx's
    ``pack_coefficients`` takes each packed value from, read off by packing the coefficients'
    own positions (one coefficient at a time, the others NaN)."""
    coefficients = form.coefficients
    kept = [c.x.array.copy() for c in coefficients]
    source: dict = {}
    index: dict = {}
    try:
        for k, c in enumerate(coefficients):
            for other in coefficients:
                other.x.array[:] = np.nan
            c.x.array[:] = np.arange(c.x.array.size, dtype=float)
            for key, packed in cpp.fem.pack_coefficients(form).items():
                mine = ~np.isnan(packed)
                columns = mine.all(axis=0)
                if not np.array_equal(columns, mine.any(axis=0)):
                    raise NotApplicable("a packed coefficient mixes entities")
                values = packed[:, columns]
                if not np.array_equal(values, np.rint(values)):
                    raise NotApplicable("packed coefficients are transformed (not a gather)")
                src = source.setdefault(key, np.full(packed.shape[1], -1, dtype=np.int32))
                idx = index.setdefault(key, np.zeros(packed.shape, dtype=np.int32))
                src[columns] = k
                idx[:, columns] = values.astype(np.int32)
    finally:
        for c, values in zip(coefficients, kept, strict=True):
            c.x.array[:] = values
    for key, src in source.items():
        if (src < 0).any():
            raise NotApplicable(f"packed values of no coefficient in integral {key}")
    return {key: (source[key], index[key]) for key in source}


class NativeLoop:
    """The C residual assembler (``cf_residual``) of a serial NewtonSolver's form (module
    docstring): ``problem`` is what cf_solve's ``problem`` points to. ``refresh`` before a
    solve whose Dirichlet values moved."""

    def __init__(self, form, U, bcs, b, constants, ties=None):
        """``b``: the solver's residual vector; ``constants``: the form's DOLFINx Constants
        in its order (the UFL form's ``constants()``), whose own storage cf_residual reads;
        ``ties``: dofs identified by rows (cosserat_fem/nls/constraints.py), or None."""
        mesh = U.function_space.mesh
        if mesh.comm.size > 1:
            raise NotApplicable("a parallel run")
        if ties is not None and ties.joints:  # cf_residual applies the linear ties only
            raise NotApplicable("a hinge's or a driven joint's rows (nls/constraints.py Joint)")
        types = list(form.integral_types)
        if cpp.fem.IntegralType.interior_facet in types:
            raise NotApplicable("an interior facet integral (a point load)")
        if form.needs_facet_permutations:
            raise NotApplicable("facet permutations")
        module = compiled()
        self.ffi, self.lib = module.ffi, module.lib
        ffi = self.ffi
        self._keep: list = []  # every array the C side points into

        pointer = self._pointer

        V = U.function_space
        bs = V.dofmap.bs
        nodes = V.dofmap.list.array.reshape(-1, V.dofmap.dof_layout.num_dofs)
        dofs = (bs * nodes[:, :, None] + np.arange(bs)).reshape(nodes.shape[0], -1)
        dofs = np.ascontiguousarray(dofs, dtype=np.int32)
        geometry = mesh.geometry
        x_nodes = geometry.dofmap.array.reshape(nodes.shape[0], -1)
        coordinates = np.ascontiguousarray(geometry.x[x_nodes].reshape(nodes.shape[0], -1))

        tables = _gather_tables(form)
        self._parts: list = []  # per integral: (kernel, cells, facets, source, index)
        address = int(ffi.cast("uintptr_t", ffi.addressof(form.ufcx_form)))
        integrals = []
        for kind in (cpp.fem.IntegralType.cell, cpp.fem.IntegralType.exterior_facet):
            if kind not in types:
                continue
            for i, ident in enumerate(form.integral_ids(kind)):
                domain = np.asarray(form.domains(kind, ident), dtype=np.int32)
                if kind == cpp.fem.IntegralType.cell:
                    cells, facets = np.ascontiguousarray(domain), None
                else:
                    pairs = domain.reshape(-1, 2)
                    cells = np.ascontiguousarray(pairs[:, 0])
                    facets = np.ascontiguousarray(pairs[:, 1])
                source, index = tables[(kind, ident)]
                if index.shape[0] != cells.size:
                    raise NotApplicable(f"packed entities of integral {(kind, ident)}")
                kernel = self.lib.cf_kernel(address, int(kind), i)
                self._parts.append((kernel, cells, facets, source, index))
                integrals.append(
                    {
                        "kernel": kernel,
                        "entities": cells.size,
                        "cells": pointer(cells, "int32_t*"),
                        "local_facets": ffi.NULL if facets is None else pointer(facets, "int32_t*"),
                        "wsize": index.shape[1],
                        "source": pointer(np.ascontiguousarray(source), "int32_t*"),
                        "index": pointer(np.ascontiguousarray(index), "int32_t*"),
                    }
                )
        self._integrals = ffi.new("cf_integral[]", integrals)
        arrays = [c.x.array for c in form.coefficients]
        self._coefficients = ffi.new("double*[]", [pointer(a, "double*") for a in arrays])
        storages = [c._cpp_object.value for c in constants]  # each Constant's own storage
        self.constants = np.zeros_like(cpp.fem.pack_constants(form))
        if sum(v.size for v in storages) != self.constants.size or not all(
            v.dtype == np.float64 and v.flags.c_contiguous for v in storages
        ):
            raise NotApplicable("the packed constants are not the Constants' values")
        self._constant_values = ffi.new("double*[]", [pointer(v, "double*") for v in storages])
        self._constant_sizes = np.array([v.size for v in storages] or [0], dtype=np.int32)
        self.bc_values = np.zeros_like(U.x.array)
        self._zeros = np.zeros_like(U.x.array)
        bc_parts = [bc.dof_indices()[0][: bc.dof_indices()[1]] for bc in bcs]
        bc_dofs = np.ascontiguousarray(
            np.concatenate([np.zeros(0, np.int32), *bc_parts]), dtype=np.int32
        )
        wsize = max((d["wsize"] for d in integrals), default=0)
        self._wsize, self._cells_total = wsize, nodes.shape[0]
        p = ffi.new("cf_problem*")
        p.n_integrals = len(integrals)
        p.integrals = self._integrals
        p.coefficients = self._coefficients
        p.n_constants = len(storages)
        p.constant_values = self._constant_values
        p.constant_sizes = pointer(self._constant_sizes, "int32_t*")
        p.constants = pointer(self.constants, "double*")
        p.coordinates = pointer(coordinates, "double*")
        p.coordinates_per_cell = coordinates.shape[1]
        p.dofs = pointer(dofs, "int32_t*")
        p.dofs_per_cell = dofs.shape[1]
        p.n_bc = bc_dofs.size
        p.bc_dofs = pointer(bc_dofs, "int32_t*")
        p.bc_values = pointer(self.bc_values, "double*")
        p.u_values = pointer(U.x.array, "double*")
        p.w = pointer(np.zeros(max(wsize, 1)), "double*")
        p.be = pointer(np.zeros(dofs.shape[1]), "double*")
        p.b = ffi.cast("void*", b.handle)
        if ties is not None:
            p.n_ties = len(ties)
            p.tie_copies = pointer(np.ascontiguousarray(ties.copies, dtype=np.int32), "int32_t*")
            p.tie_masters = pointer(np.ascontiguousarray(ties.masters, dtype=np.int32), "int32_t*")
            p.tie_added = pointer(ties.added.astype(np.int32), "int32_t*")
        self.problem = p
        self._form, self._bcs = form, bcs

    def sampled(self, cells: np.ndarray, weights: np.ndarray, tensor: int):
        """A cf_problem of this form's integrals over the entities of ``cells`` only (a
        facet integral: its facets of those cells), each entity weighted by its cell's
        entry of ``weights`` (indexed by cell), for cf_reduced_residual (``tensor`` = 1:
        element vectors) or cf_reduced_jacobian (``tensor`` = 2: element matrices); it
        shares this one's coefficients, constants, geometry and dofmap. Also returns the
        entries of the coefficient arrays the sampled entities read, per coefficient."""
        ffi = self.ffi
        chosen = np.zeros(self._cells_total, dtype=bool)
        chosen[cells] = True
        integrals: list = []
        reads: dict[int, list] = {}
        for kernel, all_cells, facets, source, index in self._parts:
            mask = chosen[all_cells]
            mine = np.ascontiguousarray(all_cells[mask])
            idx = np.ascontiguousarray(index[mask])
            xi = np.ascontiguousarray(weights[mine], dtype=float)
            for k in np.unique(source):
                reads.setdefault(int(k), []).append(idx[:, source == k].ravel())
            integrals.append(
                {
                    "kernel": kernel,
                    "entities": mine.size,
                    "cells": self._pointer(mine, "int32_t*"),
                    "local_facets": ffi.NULL
                    if facets is None
                    else self._pointer(np.ascontiguousarray(facets[mask]), "int32_t*"),
                    "wsize": idx.shape[1],
                    "source": self._pointer(np.ascontiguousarray(source), "int32_t*"),
                    "index": self._pointer(idx, "int32_t*"),
                    "weights": self._pointer(xi, "double*"),
                }
            )
        table = ffi.new("cf_integral[]", integrals)
        self._keep.append(table)
        p = ffi.new("cf_problem*", self.problem[0])
        p.n_integrals = len(integrals)
        p.integrals = table
        p.be = self._pointer(np.zeros(self.problem.dofs_per_cell**tensor), "double*")
        p.w = self._pointer(np.zeros(max(self._wsize, 1)), "double*")
        self._keep.append(p)
        return p, {k: np.unique(np.concatenate(v)) for k, v in reads.items()}

    def _pointer(self, array: np.ndarray, kind: str):
        """A C pointer into ``array``, kept alive with this object."""
        self._keep.append(array)
        return self.ffi.cast(kind, array.ctypes.data)

    def refresh(self) -> None:
        """The Dirichlet values g as they are now (before a solve, while a support moves); set
        at construction. The constants need none: cf_residual reads the Constants' own
        storage at each residual."""
        self.bc_values.fill(0.0)
        cpp.fem.set_bc(self.bc_values, self._bcs, self._zeros, 1.0)

    def residual(self) -> None:
        """b = F(U) with the Dirichlet rows x − g (NewtonSolver._residual)."""
        status = self.lib.cf_residual(self.problem)
        if status:
            raise RuntimeError(f"PETSc error {status} in the residual")
