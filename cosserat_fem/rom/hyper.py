"""Hyper-reduction of the reduced model: energy-conserving sampling and weighting (ECSW,
Farhat, Chapman & Avery 2015) and the reduced Newton iteration on the sampled elements, in C
(issue 28; docs/rom.md §5 and §9).

The Galerkin-reduced residual of a stage (docs/rom.md (5)) is a sum over the elements e (each
cell with its exterior facets):

    r(q) = Σ_e (D V)ᵀ_e F_e(U_ref,e + V_e q),                                   (docs/rom.md (9))

F_e the element vector of the stage residual, V_e, (D V)_e the rows of the basis at e's dofs.
ECSW keeps a few elements E with weights ξ_e ≥ 0,

    r̃(q) = Σ_{e∈E} ξ_e (D V)ᵀ_e F_e(U_e),   J̃_r(q) = Σ_{e∈E} ξ_e (D V)ᵀ_e J_e(U_e) V_e,   (10)

chosen on training states u_s (the stage values of a full run, projected onto the basis:
ũ_s = U_ref + V Vᵀ W (u_s − U_ref)) so that the weighted sum reproduces the full sum:

    min ‖ξ‖₀  subject to  ‖C ξ − d‖₂ ≤ τ ‖d‖₂,  ξ ≥ 0,                         (11)

C's column e the stacked (over s) contributions c_se = (D V)ᵀ_e F_e(ũ_s)/‖C_s‖_F (each
training state's block scaled by its Frobenius norm, so that a state whose terms are large
does not outweigh the others), d = C 1 (ξ = 1 is exact): Farhat et al.'s tolerance,
relative to d. Here F is the whole stage residual (inertia, stiffness and load), whose terms
cancel at a converged stage: d is the small Galerkin residual of the projected state (on the
paper's scene ‖d‖ = 0.8% of ‖C‖_F), so the fit must reproduce the terms to τ times that;
measured on the paper's 8 elements, every one is needed for any τ ≤ 1e-1 (docs/rom.md §8).
(11) is solved approximately by Lawson & Hanson's non-negative least squares stopped as soon
as the residual is below τ ‖d‖ (:func:`nnls_select`, the greedy NNLS of Farhat et al.):
elements enter one at a time, the one whose column correlates best with the
residual, and the weights are the non-negative least-squares fit on those chosen.

With weights ξ ≥ 0, J̃_r is a sum of the elements' projected Jacobians with positive weights:
the reduced system keeps the sign structure (the energy) of the Galerkin one.

Online (:class:`HyperSolver`), each Newton iteration of the reduced coordinates q (V has
m = 2k columns) costs O(m |E| n_e) for r̃ and O(|E| (n_e² m + n_e m²)) for J̃_r (n_e the dofs
of an element) and O(m³) for its LU, all in C (newton_loop.c ``cf_reduced_run``), with the
state reconstructed only on the entries of U the sampled elements read.

Two ways to keep the integrator's state (docs/rom.md §8). **Reduced coordinates** (the
default where it applies: fixed steps; :meth:`HyperSolver.coordinate_space`): the
integrator's arrays are the coordinates y of U = U_ref + V y (:class:`ReducedCoordinates`,
its "space"), 2k-vectors; SDIRK's C kernels (cf_sdirk_*) run on them unchanged, q is the
iteration's unknown and guess, the integrator's other Functions (SDIRK's Z; BDF2's U_n,
U_{n−1}; generalized-α's U_n, U̇_n) are written on the sampled rows before each solve,
and the full U only where something reads it (TimeLoop.lift: outputs, a probe's rows,
checkpoints, observers, the run's end); the time loop's state check is the O(m) bound of
:class:`ReducedStateCheck`. Nothing a step does is O(n). **Full vectors** (otherwise:
adaptive steps read U; or on request, ``galerkin.solver_factory(..., coordinates=False)``):
at the end of each solve the whole U = U_ref + V q is written for the integrator (O(n m)),
whose arithmetic is O(n) a stage, and its guess is read off the sampled rows,
q₀ = V_S⁺ (U − U_ref)_S (every state the integrator forms from reduced ones is in the affine
space; checked there, else and at the first solve the W-projection over every row).

Serial only: the C assembler is serial, and the sampled elements would be spread over the
ranks; a hyper-reduced run under MPI is refused (one line).
"""

from __future__ import annotations

import math

import numpy as np

from cosserat_fem.common.errors import SceneError, SolverError
from cosserat_fem.rod.charts import RESET_THETA
from cosserat_fem.rod.checks import StateCheck, check_state
from cosserat_fem.rom.galerkin import HYPER_CHARTS, ReducedSolver, chart_refusal
from cosserat_fem.timestepping.events import Observer
from cosserat_fem.timestepping.integrators import FullSpace

# --- ECSW's selection (pure numpy) ----------------------------------------------------------


def nnls_select(
    C: np.ndarray,
    d: np.ndarray,
    tolerance: float,
    max_elements: int | None = None,
    scale: float | None = None,
) -> tuple[np.ndarray, np.ndarray, float]:
    """ξ ≥ 0 with few nonzeros such that ‖C ξ − d‖₂ ≤ tolerance · scale (docs/rom.md (11);
    ``scale`` default ‖d‖₂):
    Lawson & Hanson's active-set NNLS (Solving Least Squares Problems, 1974, ch. 23) stopped
    as soon as the residual is that small. Returns (the chosen columns, their weights > 0,
    the relative residual reached). ``max_elements`` (default: all columns) bounds the
    chosen set; if it is reached first the residual is above ``tolerance`` (the caller says
    so)."""
    C = np.asarray(C, dtype=float)
    d = np.asarray(d, dtype=float)
    if not (0.0 <= tolerance < 1.0):
        raise SceneError(f"tolerance: must be in [0, 1), got {tolerance!r}")
    rows, cols = C.shape
    limit = cols if max_elements is None else min(max_elements, cols)
    scale = float(np.linalg.norm(d)) if scale is None else float(scale)
    x = np.zeros(cols)
    if scale == 0.0:
        return np.zeros(0, dtype=int), np.zeros(0), 0.0
    passive = np.zeros(cols, dtype=bool)
    residual = d.copy()
    for _outer in range(3 * cols + 10):
        error = float(np.linalg.norm(residual)) / scale
        if error <= tolerance or passive.sum() >= limit:
            break
        gradient = C.T @ residual
        gradient[passive] = -np.inf
        j = int(np.argmax(gradient))
        if not gradient[j] > 0.0:
            break  # the NNLS optimum: no column lowers the residual
        passive[j] = True
        while True:  # the inner loop: least squares on the passive set, kept ≥ 0
            chosen = np.flatnonzero(passive)
            z = np.zeros(cols)
            z[chosen] = np.linalg.lstsq(C[:, chosen], d, rcond=None)[0]
            if (z[chosen] > 0.0).all():
                x = z
                break
            negative = chosen[z[chosen] <= 0.0]
            alpha = np.min(x[negative] / (x[negative] - z[negative]))
            x = x + alpha * (z - x)
            passive &= x > 1e-14 * max(1.0, float(np.max(np.abs(x))))
            x[~passive] = 0.0
            if not passive.any():
                break
        residual = d - C @ x
    chosen = np.flatnonzero(x > 0.0)
    error = float(np.linalg.norm(d - C[:, chosen] @ x[chosen])) / scale
    return chosen, x[chosen], error


def training_system(blocks: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """(C, d) of (11) from each training state's (cells, m) contributions c_se: the blocks
    stacked as rows (s, component), each scaled by its Frobenius norm (a zero block left
    out), d = C 1."""
    rows = []
    for block in blocks:
        norm = float(np.linalg.norm(block))
        if norm > 0.0:
            rows.append(block.T / norm)
    if not rows:
        raise SceneError("ecsw: every training state's residual is zero (nothing to fit)")
    C = np.vstack(rows)
    return C, C.sum(axis=1)


# --- the training states ---------------------------------------------------------------------


class ContributionCollector(Observer):
    """Each Newton solve's converged stage (every ``every``-th solve_done of a full serial run
    with the C assembler), its state projected onto ``basis`` and the (cells, m) element
    contributions (D V)ᵀ_e F_e(ũ_s) of the stage residual evaluated there (U is restored
    after). ``blocks``: one array per training state."""

    def __init__(self, basis, every: int = 1):
        if isinstance(every, bool) or not isinstance(every, int) or every < 1:
            raise SceneError(f"every: must be a whole number >= 1, got {every!r}")
        self.basis, self.every = basis, every
        self.blocks: list[np.ndarray] = []
        self._solves = 0
        self._V = np.ascontiguousarray(basis.V)
        tests = basis.tests if basis.tests is not None else np.ones(len(basis.weights))
        self._DV = np.ascontiguousarray(tests[:, None] * basis.V)
        self._WV = basis.weights[:, None] * basis.V

    def solve_done(self, loop, iterations: int) -> None:
        self._solves += 1
        if (self._solves - 1) % self.every:
            return
        native = getattr(loop.solver, "_native", None)
        if native is None:
            raise SceneError("ecsw: training needs a serial run with the C assembler")
        u = loop.model.U.x.array
        n = self._V.shape[0]
        kept = u.copy()
        b = self.basis
        u[:n] = b.reference + self._V @ (self._WV.T @ (kept[:n] - b.reference))
        out = np.zeros((native._cells_total, self._V.shape[1]))
        try:
            native.lib.cf_reduced_residual(
                native.problem,
                native.ffi.cast("double*", self._DV.ctypes.data),
                self._V.shape[1],
                native.ffi.NULL,
                native.ffi.cast("double*", out.ctypes.data),
            )
        finally:
            u[:] = kept
        self.blocks.append(out)


def cell_midpoints(model) -> np.ndarray:
    """σ of each local cell's midpoint (the rank-independent name of a cell in a basis file)."""
    from dolfinx import mesh as dmesh

    msh = model.msh
    cells = np.arange(msh.topology.index_map(1).size_local, dtype=np.int32)
    return dmesh.compute_midpoints(msh, 1, cells)[:, 0]


def ecsw(
    scenes, basis, tolerance: float, every: int = 1, max_elements: int | None = None, comm=None
):
    """ECSW's elements and weights (module docstring, (11)) for ``basis`` from full runs of
    ``scenes`` (serial): each stage's state, projected, gives a training block. A scene may
    also be a training run with its own observers (cosserat_fem/rom/runs.py ``Target``: its
    ``scene`` and ``observers()``, e.g. a forced member's stop once settled). Returns the
    basis with ``sample_cells`` and ``sample_weights`` set and the fit in its provenance
    (tolerance, elements, the fit error ‖C ξ − d‖/‖d‖ reached, the training states).
    ``comm``: the runs' communicator (default COMM_WORLD; one rank's, COMM_SELF, for a sweep's
    training on its rank 0)."""
    from dataclasses import replace

    from mpi4py import MPI

    from cosserat_fem.analysis.simulation import run_scene

    if not 0.0 < tolerance < 1.0:
        raise SceneError(f"ecsw: the tolerance must be in (0, 1), got {tolerance!r}")
    collector = ContributionCollector(basis, every)
    model = None
    for item in scenes:
        scene, own = (item.scene, item.observers()) if hasattr(item, "scene") else (item, [])
        result = run_scene(
            scene,
            comm=MPI.COMM_WORLD if comm is None else comm,
            write_outputs=False,
            observers=[collector, *own],
            record=False,
        )
        model = result.model
    if model is not None and model.msh.comm.size > 1:
        raise SceneError("ecsw: hyper-reduction is serial only (docs/rom.md §9)")
    C, d = training_system(collector.blocks)
    chosen, weights, error = nnls_select(C, d, tolerance, max_elements)
    provenance = {
        **basis.provenance,
        "ecsw": {
            "tolerance": float(tolerance),
            "elements": int(chosen.size),
            "of": int(C.shape[1]),
            "fit_error": error,
            "training_states": len(collector.blocks),
            "every": every,
        },
    }
    assert model is not None
    return replace(
        basis,
        provenance=provenance,
        sample_cells=chosen.astype(np.int32),
        sample_weights=weights,
        sample_sigma=cell_midpoints(model)[chosen],
    )


# --- the hyper-reduced solve -------------------------------------------------------------------

#: The largest condition number of V's sampled rows for reading the guess's q₀ off them
#: (newton_loop.c ``project``: its round-off grows with it; 1e6 keeps q₀ to 1e-10).
CONDITION_LIMIT = 1e6


class HyperSolver(ReducedSolver):
    """ReducedSolver whose iterations are cf_reduced_run on the sampled elements (module
    docstring); ``loop`` is "hyper". J̃_r and its LU live in C; a checkpoint keeps the
    policy's state but not J̃_r, so a restarted run forms a fresh one at its first solve
    (the same solution to the Newton tolerance, not the same iterates bit for bit as the
    full model's restart gives)."""

    def __init__(self, F, U, bcs, settings, basis):
        super().__init__(F, U, bcs, settings, basis)
        if self._parallel:
            raise SceneError("rom: a hyper-reduced run is serial only (docs/rom.md §9)")
        if self._assembler is None:
            raise SceneError(
                "rom: hyper-reduction needs the C assembler, which this scene's residual "
                "does not allow (a point load); run without the sampling (hyper = False)"
            )
        self._build(basis)

    def _build(self, basis) -> None:
        from cosserat_fem.nls.native_newton import NativeLoop

        ffi, lib = self._ffi, self._lib
        assembler = self._assembler
        assert assembler is not None, "checked in __init__"
        cells = np.asarray(basis.sample_cells, dtype=np.int32)
        by_cell = np.zeros(assembler._cells_total)
        by_cell[cells] = basis.sample_weights
        self._J_native = NativeLoop(self.J_form, self.U, self.bcs, self.b, list(self._J_inputs[1]))
        Fp, reads_F = assembler.sampled(cells, by_cell, 1)
        Jp, reads_J = self._J_native.sampled(cells, by_cell, 2)
        u = self.U.x.array
        rows: list[np.ndarray] = [np.zeros(0, dtype=np.int32)]
        for native, reads in ((assembler, reads_F), (self._J_native, reads_J)):
            for k, entries in reads.items():
                if ffi.cast("uintptr_t", native.problem.coefficients[k]) == u.ctypes.data:
                    rows.append(entries)
        self._reads = [(assembler, reads_F), (self._J_native, reads_J)]
        n = self.V.shape[0]
        row_array = np.unique(np.concatenate(rows)).astype(np.int32)
        row_array = np.ascontiguousarray(row_array[row_array < n])
        m = self.V.shape[1]
        rest = np.setdiff1d(np.arange(n, dtype=np.int32), row_array).astype(np.int32)
        fit = row_array[np.abs(self.V[row_array]).max(axis=1, initial=0.0) > 0.0]
        P = np.zeros((m, 0))
        if m <= fit.size <= n // 2:  # q₀ read off the sampled rows (newton_loop.c project),
            # where they are fewer than half of U's (else the W-projection costs no more)
            sigma = np.linalg.svd(self.V[fit], compute_uv=False)
            if sigma[-1] > 0 and sigma[0] / sigma[-1] <= CONDITION_LIMIT:
                P = np.linalg.pinv(self.V[fit])
        if P.shape[1] == 0:
            fit = fit[:0]
        self.cheap_projection = bool(fit.size)
        self._arrays = arrays = {
            "V": self.V,
            "DV": np.ascontiguousarray(self.DV),
            "WV": np.ascontiguousarray(self.WV),
            "ref": np.ascontiguousarray(self.basis.reference),
            "G": np.ascontiguousarray(self.V.T @ self.V),
            "g": self.V.T @ self.basis.reference,
            "rows": row_array,
            "rest": np.ascontiguousarray(rest),
            "fit": np.ascontiguousarray(fit, dtype=np.int32),
            "P": np.ascontiguousarray(P),
            "q": np.zeros(m),
            "r": np.zeros(m),
            "dq": np.zeros(m),
            "Jr": np.zeros((m, m)),
            "lu": np.zeros((m, m)),
            "work": np.zeros((Jp.dofs_per_cell, m)),
            "piv": np.zeros(m, dtype=np.int32),
            "q0": np.zeros(m),
        }
        self._R = R = ffi.new("cf_reduced*")
        R.n, R.m = n, m
        for name in ("V", "DV", "WV", "ref", "G", "g", "P", "q", "r", "dq", "Jr", "lu", "work"):
            setattr(R, name, ffi.cast("double*", arrays[name].ctypes.data))
        R.c = float(self.basis.reference @ self.basis.reference)
        self._set_rows(row_array)
        R.piv = ffi.cast("int32_t*", arrays["piv"].ctypes.data)
        R.q0 = ffi.cast("double*", arrays["q0"].ctypes.data)
        R.n_rest, R.rest = rest.size, ffi.cast("int32_t*", arrays["rest"].ctypes.data)
        R.n_fit, R.fit = fit.size, ffi.cast("int32_t*", arrays["fit"].ctypes.data)
        R.project_all = 1  # the first guess: the W-projection (it may be off the basis)
        R.F, R.J = Fp, Jp
        R.s, R.st = self._cs, self._state
        R.solver, R.observer = self._sv, self._handle  # the observer hook, if one is set
        self._R = R
        self.sampled_rows = row_array.size
        self.reduced_coordinates = False  # coordinate_space switches it on
        self.use_coordinates = True  # galerkin.solver_factory may say no
        self._sv.run = ffi.addressof(lib, "cf_reduced_run")
        self._sv.ctx = ffi.cast("void*", R)
        self.loop = "hyper"

    @property
    def q(self):
        return self._arrays["q"]

    @q.setter
    def q(self, value) -> None:  # ReducedSolver's constructor sets it
        if hasattr(self, "_arrays"):
            self._arrays["q"][:] = value

    @property
    def Jr(self):
        return self._arrays["Jr"] if hasattr(self, "_arrays") else self._Jr0

    @Jr.setter
    def Jr(self, value) -> None:
        self._Jr0 = value

    @property
    def stats(self):
        stats = ReducedSolver.stats.fget(self)  # type: ignore[attr-defined]
        if hasattr(self, "_R"):
            stats.jacobian_assemblies = int(self._R.jacobians)
            stats.time_jacobian = float(self._R.time_jacobian)
        return stats

    def request_jacobian(self) -> None:
        self._need_jacobian = True

    # -- reduced coordinates (docs/rom.md §8) -------------------------------------------------
    def coordinate_space(self, integrator, tspan) -> ReducedCoordinates | None:
        """Run ``integrator`` on the reduced coordinates (module docstring of
        :class:`ReducedCoordinates`): its state arrays are q and 2k-vectors, this solver's
        iterations start from q as the integrator leaves it and write U and the integrator's
        Functions on the sampled rows only. Returns the space, or None (the reason logged at
        INFO; the run keeps the full-vector state, U = U_ref + V q written at every solve) for
        adaptive steps (their error control reads U) or an integrator that refuses."""
        from cosserat_fem.common.log import LOGGER

        if tspan.adaptive:
            LOGGER.info("reduced run: full-vector state (adaptive steps read U's error)")
            return None
        space = ReducedCoordinates(self)
        try:
            integrator.use_space(space)
        except NotImplementedError as exc:
            LOGGER.info("reduced run: full-vector state (%s)", exc)
            return None
        space.activate()
        return space

    def _bind_lifts(self, functions: list) -> None:
        """The C iteration's lifts of the integrator's Functions (other than U) on the sampled
        rows, each from its coordinates: ``functions`` = [(Function, coordinates, affine)];
        the rows they are read at are added to U's (the same entries of the same space)."""
        ffi, R = self._ffi, self._R
        rows = [self._arrays["rows"]]
        for F, _c, _a in functions:
            address = F.x.array.ctypes.data
            for native, reads in self._reads:
                for k, entries in reads.items():
                    if ffi.cast("uintptr_t", native.problem.coefficients[k]) == address:
                        rows.append(entries)
        n = self.V.shape[0]
        union = np.unique(np.concatenate(rows)).astype(np.int32)
        self._arrays["lift_rows"] = union = np.ascontiguousarray(union[union < n])
        self._arrays["lift_affine"] = np.array([a for _F, _c, a in functions] or [0.0])
        self._lift_values = ffi.new(
            "double*[]", [ffi.cast("double*", F.x.array.ctypes.data) for F, _c, _a in functions]
        )
        self._lift_coords = ffi.new(
            "double*[]", [ffi.cast("double*", c.ctypes.data) for _F, c, _a in functions]
        )
        R.n_lifts = len(functions)
        R.lift_values, R.lift_coords = self._lift_values, self._lift_coords
        R.lift_affine = ffi.cast("double*", self._arrays["lift_affine"].ctypes.data)
        self._set_rows(union)

    def _set_rows(self, rows: np.ndarray) -> None:
        """The C iteration's sampled rows, with V's rows there transposed (newton_loop.c
        ``set_values``) and its scratch."""
        ffi, R = self._ffi, self._R
        self._arrays["rows_now"] = rows
        self._arrays["VT"] = VT = np.ascontiguousarray(self.V[rows].T)
        self._arrays["t"] = t = np.zeros(max(rows.size, 1))
        R.n_rows, R.rows = rows.size, ffi.cast("int32_t*", rows.ctypes.data)
        R.VT, R.t = ffi.cast("double*", VT.ctypes.data), ffi.cast("double*", t.ctypes.data)

    def _coordinates_on(self) -> None:
        """cf_reduced_run in reduced coordinates: the guess is q (kept by cf_reduced_guess
        for a retry), nothing projected, U's other rows left alone."""
        R = self._R
        R.coordinates, R.project_all = 1, 0
        self._sv.guess = self._ffi.addressof(self._lib, "cf_reduced_guess")
        self.reduced_coordinates = True


class ReducedCoordinates(FullSpace):
    """The space of a reduced run's state arrays (cosserat_fem/timestepping/integrators.py,
    "The space"; docs/rom.md §8): the coordinates y of U = U_ref + V y (a state) or of
    U̇ = V y (a rate), length m = 2k. U's are the solver's q (the C iteration's unknown); each
    other Function the integrator keeps (SDIRK's Z) gets its own, and the solver writes it on
    the sampled elements' rows before each solve (cf_reduced_run). Nothing here is O(n) a
    step: the full values are written by :meth:`lift` (outputs, checkpoints, an observer that
    asks, the end of a run), O(n m). Its arrays are serial (a hyper-reduced run is)."""

    reduced = True

    def __init__(self, solver: HyperSolver):
        self.solver = solver
        self.V, self.ref = solver.V, np.ascontiguousarray(solver.basis.reference)
        self.WV = np.ascontiguousarray(solver.WV)
        self.n, self.size = self.V.shape
        solver.q[:] = self.from_full(solver.U.x.array)  # U's coordinates, from U now
        self.functions: list = [(solver.U, solver.q, 1.0)]  # (Function, coordinates, affine)

    def values(self, F, rate: bool = False) -> np.ndarray:
        """F's coordinates: U's are the solver's q (the W-projection of U's values when this
        space was made), another Function's a new array (the W-projection of its values
        now), lifted by the solver on its rows before each solve."""
        for G, c, _a in self.functions:
            if G is F:
                return c
        c = self.from_full(F.x.array, rate)
        self.functions.append((F, c, 0.0 if rate else 1.0))
        return c

    def activate(self) -> None:
        """The solver's iteration switched to these coordinates (after the integrator took
        its arrays): the other Functions' lifts bound."""
        solver = self.solver
        solver._bind_lifts(self.functions[1:])
        solver._coordinates_on()

    def from_full(self, array: np.ndarray, rate: bool = False) -> np.ndarray:
        """The W-projection y = (W V)ᵀ (u − U_ref) of a full state (rate: (W V)ᵀ u), rows of a
        2-d array each; exact on U_ref + span V to round-off (Vᵀ W V = I)."""
        a = np.asarray(array)[..., : self.n]
        return np.ascontiguousarray((a if rate else a - self.ref) @ self.WV)

    def to_full(self, array: np.ndarray, rate: bool = False) -> np.ndarray:
        """U_ref + V y (rate: V y), rows of a 2-d array each."""
        full = np.asarray(array) @ self.V.T
        return full if rate else full + self.ref

    def lift(self) -> None:
        """Every registered Function's values (U and the integrator's) written in full from its
        coordinates (newton_loop.c ``cf_lift``, the arithmetic of the iteration's rows)."""
        for F, c, affine in self.functions:
            self.lift_rows(F.x.array, c, affine, None)

    def lift_rows(self, out: np.ndarray, c: np.ndarray, affine: float, rows) -> None:
        """out[rows] = affine U_ref + V c on ``rows`` (int32 array; None: every row)."""
        solver = self.solver
        ffi, lib = solver._ffi, solver._lib
        count = self.n if rows is None else rows.size
        lib.cf_lift(
            ffi.cast("double*", self.V.ctypes.data),
            ffi.cast("double*", self.ref.ctypes.data),
            self.size,
            ffi.cast("double*", c.ctypes.data),
            float(affine),
            ffi.NULL if rows is None else ffi.cast("int32_t*", rows.ctypes.data),
            count,
            ffi.cast("double*", out.ctypes.data),
        )

    def refuse_chart(self) -> None:
        """The chart's move: a hyper-reduced run's refusal (galerkin.HYPER_CHARTS)."""
        raise chart_refusal(HYPER_CHARTS)

    def state_check(self, model) -> ReducedStateCheck:
        return ReducedStateCheck(model, self)


class ReducedStateCheck(StateCheck):
    """The time loop's state check (cosserat_fem/rod/checks.py) on reduced coordinates, O(m) a
    step: U = U_ref + V y is finite iff y is (V, U_ref finite), and every node's θ lies within

        |θ_j| ≤ max_j |θ_ref,j| + Σ_i (max_j |V_θj,i|) |y_i| = B,                      (8.1)

    (the θ rows of U_ref and V). While B < charts.RESET_THETA (0.9 rad) no node is near the
    chart's singularity (|cos θ| > cos 0.9 = 0.62 > CHART_COS_MIN) nor can cross it, and no
    chart move is due: ``quiet``, and the loop skips its chart watch. Otherwise cos θ is
    formed exactly on the θ rows (O(nodes m)) and checked as the full model's; a failure is
    reported from the lifted U (the place along the rod)."""

    def __init__(self, model, space: ReducedCoordinates):
        super().__init__(model)
        self.space = space
        self._y = space.values(model.U)
        self._owned = self._y  # the finite test's sum (StateCheck.__call__)
        self.quiet = True
        self._rows: np.ndarray | None = None
        if self._theta is not None:
            size, nodes = model.layout.size, self._ones.size
            theta = model.layout.index(3)
            self._rows = np.ascontiguousarray(np.arange(nodes) * size + theta, dtype=np.int32)
            self._rows = self._rows[self._rows < space.n]
            V_theta = space.V[self._rows]
            self._column = np.abs(V_theta).max(axis=0, initial=0.0)
            self._reference = float(np.abs(space.ref[self._rows]).max(initial=0.0))
            self._theta_now = np.zeros(space.n)

    def bound(self) -> float:
        """B of (8.1) (0 without a chart)."""
        if self._rows is None:
            return 0.0
        return self._reference + float(self._column @ np.abs(self._y))

    def cos_theta(self) -> np.ndarray:
        """cos θ at the owned nodes, exact (the θ rows lifted), or ones without a chart."""
        if self._rows is None:
            return self._ones
        self.space.lift_rows(self._theta_now, self._y, 1.0, self._rows)
        return np.cos(self._theta_now[self._rows])

    def __call__(self, t, where_prefix: str = "", before=None) -> np.ndarray:
        if self._rows is not None and not self.bound() < RESET_THETA:
            self.quiet = False
        elif math.isfinite(float(np.add.reduce(self._y))):
            self.quiet = True
            return self._ones
        try:
            return super().__call__(t, where_prefix, before)
        except SolverError:
            self.space.lift()  # the report's place, from the full U
            return check_state(self.model, t, where_prefix, before)
