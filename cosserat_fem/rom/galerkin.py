"""The reduced model's nonlinear solve: Galerkin projection of the full residual onto a POD
basis, inside the project's time loop (issue 28, online part; docs/rom.md).

Each Newton solve of the time loop (one per implicit stage of the integrator) solves
F(U) = 0 for the unknown U; the reduced solve restricts U to the affine space
U = U_ref + V q (cosserat_fem/rom/basis.py) and asks the residual to be orthogonal to the
basis:

    r(q) = Vᵀ F(U_ref + V q) = 0,        J_r(q) = Vᵀ J(U_ref + V q) V,        (docs/rom.md (5))

J = ∂F/∂U the full model's exact Jacobian (the integrator's stage Jacobian, assembled in full:
hyper-reduction is the next step), Newton's iteration q ← q − J_r⁻¹ r a k × k dense solve.
The integrators are unchanged: they build the stage residual F from the model's residual and
call the solver, which gets the integrator's guess in U, projects it, q₀ = Vᵀ W (U − U_ref)
(V is W-orthonormal), and leaves U = U_ref + V q; the integrator then forms its stage rates
from U as for the full model. Everything the integrator does with U is linear in U (stage
combinations, predictions), so every state it makes stays in the affine space.

:class:`ReducedSolver` is a :class:`~cosserat_fem.nls.newton.NewtonSolver` whose iterations are
this Galerkin Newton (cf_solve's ``run`` callback, as SNES's are: newton_loop.c), so the
time loop, the Jacobian policies (full: J_r re-assembled at every iteration; lagged and
frozen: kept across solves as cf_solve decides, with a retry on a fresh one), the stop rule
(``cf_test`` on (‖U‖, ‖V δq‖, ‖r‖), 2-norms) and the statistics are the full model's. The
residual is assembled by the C assembler where it applies (serial), else by DOLFINx.

**Large rotations: a basis per chart** (docs/rom.md §9). When the Euler angles' chart moves
(cosserat_fem/timestepping/loop.py ``watch_chart``: the integrator's states mapped in full, the
model given the new chart), :meth:`ReducedSolver.follow_chart` makes the basis of the new
chart (basis.in_chart: the training snapshots mapped from the charts they were recorded in,
POD'd again to the same k), projects the state onto it and goes on.

Refused (SceneError/SolverError, one line): a basis of another space (basis.read_basis), a
scene whose supports move (the reference holds fixed Dirichlet values), and a chart move the
reduced run cannot follow (:func:`chart_refusal`): a hyper-reduced run, a basis without its
snapshots (a basis file's), a run under MPI, a restart whose chart had moved.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import scipy.linalg
from petsc4py import PETSc

from cosserat_fem.common.errors import SceneError, SolverError
from cosserat_fem.nls.newton import NewtonSettings, NewtonSolver
from cosserat_fem.rom.basis import Basis, owned, read_basis

_REASON = PETSc.SNES.ConvergedReason

#: Why a hyper-reduced run refuses the chart's move (docs/rom.md §9).
HYPER_CHARTS = (
    "a hyper-reduced run cannot follow the chart (ECSW's elements and weights are fitted to "
    "the first chart's modes; a Galerkin run, hyper=False, follows it)"
)


def chart_refusal(reason: str) -> SolverError:
    """The reduced run's one-line refusal of the chart's move (|θ| near π/2), with ``reason``."""
    return SolverError(
        f"the rotations reached the Euler-angle chart's limit (|θ| near π/2): {reason}",
        where="reduced run",
        suggestion="run the full model (cf.run); docs/rom.md §9",
    )


class ReducedSolver(NewtonSolver):
    """The Galerkin-reduced Newton solve of F(U) = 0 on U = U_ref + V q (module docstring);
    ``basis`` (cosserat_fem/rom/basis.py) gives V, U_ref and W on this rank's owned rows.
    ``loop`` is "galerkin"; ``q`` the last reduced coordinates."""

    def __init__(self, F, U, bcs, settings: NewtonSettings, basis: Basis):
        n = U.function_space.dofmap.index_map.size_local * U.function_space.dofmap.index_map_bs
        if basis.V.shape[0] != n:
            raise SceneError(f"basis: {basis.V.shape[0]} rows on this rank, the model's U owns {n}")
        self.basis = basis
        self.V = np.ascontiguousarray(basis.V)
        tests = basis.tests if basis.tests is not None else np.ones(n)
        self.DV = tests[:, None] * self.V  # the test vectors D V of the rows (48)
        self.WV = basis.weights[:, None] * self.V  # for q = Vᵀ W (U − U_ref)
        self.q = np.zeros(basis.modes)
        self.Jr = np.zeros((basis.modes, basis.modes))
        self._Jr_lu: tuple | None = None  # J_r's LU factors (scipy.linalg.lu_factor)
        self._Vq = np.zeros(n)
        self.reduction_time = 0.0  # seconds spent forming J_r (J V and its projection)
        self._Vmat = None  # V as a dense PETSc matrix, for J V
        self._following = False  # a chart move followed (follow_chart)
        #: One entry per chart move followed: projection errors, energy left out, wall time.
        self.chart_moves: list[dict] = []
        super().__init__(F, U, bcs, settings)
        self.comm = U.function_space.mesh.comm
        self._x, self._y = self.A.createVecs()

    def _make_native(self) -> None:
        """The C residual assembler where it applies (NewtonSolver's), and cf_solve runs
        :meth:`_iterate` for its iterations."""
        super()._make_native()
        self._assembler = self._native
        self._native = None  # cf_solve's own use of it: none (its run is ours)
        self._sv.run = self._lib.cf_py_run
        self.loop = "galerkin"

    def set_form(self, F) -> None:
        """A new residual form is the chart moving (cosserat_fem/timestepping/loop.py): taken
        after :meth:`follow_chart` made the basis of the new chart, else (a restart whose
        chart had moved: the basis of that chart is not rebuilt) refused."""
        if not self._following:
            raise chart_refusal(
                "the checkpoint's chart has moved, and a reduced run continues in a moved "
                "chart only within the run that moved it (its basis per chart)"
            )
        super().set_form(F)

    def follow_chart(self, model, integrator) -> None:
        """The chart moved (cosserat_fem/timestepping/loop.py ``watch_chart``, after the
        integrator's states were mapped in full and the model took the new chart): the basis
        of the new chart (basis.in_chart: the training snapshots mapped into it, POD'd again
        to the same k), then U and the last accepted state projected onto it,
        U ← U_ref + V Vᵀ W (U − U_ref), their relative W-norm projection error recorded in
        :attr:`chart_moves` with the new POD's energy left out and the wall time; the
        reduced Jacobian is made afresh. Refused in one line where it cannot follow: a
        hyper-reduced run (ECSW's elements and weights were fitted to the first chart's
        modes), or a basis without its snapshots (docs/rom.md §9)."""
        from cosserat_fem.rom.basis import in_chart

        t0 = time.perf_counter()
        if self.loop == "hyper":
            raise chart_refusal(HYPER_CHARTS)
        basis, left = in_chart(self.basis, model)
        self._use_basis(basis)
        n = len(basis.weights)
        errors = []
        for state in (self.U.x.array, integrator.last_accepted()):
            u = state[:n] - basis.reference
            c = self.WV.T @ u
            off = u - self.V @ c
            norm = float(np.sqrt(u @ (basis.weights * u)))
            errors.append(float(np.sqrt(off @ (basis.weights * off))) / norm if norm else 0.0)
            state[:n] = basis.reference + self.V @ c
        self.q = self.WV.T @ (self.U.x.array[:n] - basis.reference)
        self._following = True
        self.request_jacobian()
        self.chart_moves.append(
            {
                "time_s": float(integrator.time / model.omega0),
                "projection_error": errors[0],
                "projection_error_accepted": errors[1],
                "energy_left_out": left,
                "wall_time_s": time.perf_counter() - t0,
            }
        )

    def _use_basis(self, basis: Basis) -> None:
        """V, D V, W V of ``basis`` from now on (the same k); J_r and V's PETSc copy dropped."""
        self.basis = basis
        self.V = np.ascontiguousarray(basis.V)
        tests = basis.tests if basis.tests is not None else np.ones(len(basis.weights))
        self.DV = tests[:, None] * self.V
        self.WV = basis.weights[:, None] * self.V
        self._Jr_lu = None
        if self._Vmat is not None:
            self._Vmat.destroy()
            self._Vmat = None

    # -- the reduced iteration ----------------------------------------------------------------
    def _sum(self, local: np.ndarray) -> np.ndarray:
        return self.comm.allreduce(local) if self._parallel else local

    def _set_state(self) -> None:
        np.dot(self.V, self.q, out=self._Vq)
        np.add(self.basis.reference, self._Vq, out=self._u_owned)

    def _reduced_residual(self) -> np.ndarray:
        """r = Vᵀ F(U) (U = U_ref + V q set), counted and timed as cf_solve counts its own."""
        t0 = time.perf_counter()
        if self._assembler is not None:
            if self.supports_move:
                self._assembler.refresh()
            self._assembler.residual()
        else:
            self._residual()
        r = self._sum(self.DV.T @ self.b.array)
        st = self._state
        st.residuals += 1
        st.time_residual += time.perf_counter() - t0
        return r

    def _reduced_jacobian(self) -> None:
        """J_r = (D V)ᵀ J V: J assembled in full (NewtonSolver._jacobian), then one sparse
        times dense product (PETSc MatMatMult with V as a dense matrix)."""
        self._jacobian()
        t0 = time.perf_counter()
        if self._Vmat is None:
            self._Vmat = PETSc.Mat().createDense(
                (self.A.getSizes()[1], (None, self.V.shape[1])), array=self.V, comm=self.comm
            )
        AV = self.A.matMult(self._Vmat)
        self.Jr = self._sum(self.DV.T @ AV.getDenseArray())
        AV.destroy()
        self._Jr_lu = None
        if np.isfinite(self.Jr).all():
            lu, piv = scipy.linalg.lu_factor(self.Jr, check_finite=False)
            if np.all(np.abs(np.diag(lu)) > 0):
                self._Jr_lu = (lu, piv)
        self.reduction_time += time.perf_counter() - t0

    def _iterate(self, answer: list) -> None:
        """cf_solve's ``run``: Galerkin Newton from the projection of the guess in U; U then
        holds U_ref + V q of the last iterate; ``answer`` = [iterations, SNES reason]."""
        st, s = self._state, self.settings
        u = self._u_owned
        self.q = self._sum(self.WV.T @ (u - self.basis.reference))
        self._set_state()
        r = self._reduced_residual()
        fnorm = float(np.linalg.norm(r))
        if not np.isfinite(fnorm):
            answer[:] = 0, _REASON.DIVERGED_FNORM_NAN
            return
        reason = self._converged(0, (0.0, 0.0, fnorm))
        it = 0
        while reason == _REASON.CONVERGED_ITERATING and it < s.max_iterations:
            if st.need_jacobian or s.jacobian == "full":
                self._reduced_jacobian()
                st.need_jacobian, st.since = 0, 0
            if self._Jr_lu is None:  # singular or not finite
                reason = _REASON.DIVERGED_LINEAR_SOLVE
                break
            dq = scipy.linalg.lu_solve(self._Jr_lu, r, check_finite=False)
            self.q = self.q - dq
            self._set_state()
            r = self._reduced_residual()
            fnorm = float(np.linalg.norm(r))
            if not np.isfinite(fnorm):
                reason = _REASON.DIVERGED_FNORM_NAN
                break
            # 2-norms by numpy: U's PETSc vector caches its norm, and U changed under it
            step = self.V @ dq
            squares = self._sum(np.array([step @ step, u @ u]))
            it += 1
            reason = self._converged(
                it, (float(np.sqrt(squares[1])), float(np.sqrt(squares[0])), fnorm)
            )
        if reason == _REASON.CONVERGED_ITERATING:
            reason = _REASON.DIVERGED_MAX_IT
        answer[:] = it, int(reason)

    def destroy(self) -> None:
        self._x.destroy()
        self._y.destroy()
        if self._Vmat is not None:
            self._Vmat.destroy()
        super().destroy()


def solver_factory(basis: Basis | str | Path, hyper: bool | None = None, coordinates: bool = True):
    """The run's solver maker (cosserat_fem/analysis/simulation.py ``solver_factory``): a
    :class:`ReducedSolver` on ``basis`` (a Basis, or the path of a basis file, read for the
    run's model and refused if it does not match); with ``hyper`` (None: when the basis
    carries ECSW's sampling) the hyper-reduced solver (cosserat_fem/rom/hyper.py), whose
    integrator runs on the reduced coordinates where it can (``coordinates``; False: the
    full-vector state, U = U_ref + V q written at every solve; docs/rom.md §8)."""

    def make(model, F, bcs, settings: NewtonSettings) -> ReducedSolver:
        if model.motions:
            raise SceneError(
                "supports: a reduced run needs fixed supports (the basis's reference holds "
                "their values)"
            )
        chosen = basis if isinstance(basis, Basis) else read_basis(basis, model)
        if chosen.V.shape[0] != owned(model):
            raise SceneError(
                "basis: its rows are not this run's (built on another number of ranks); "
                "write it to a file and read it (cosserat_fem/rom/basis.py)"
            )
        if hyper and not chosen.sampled:
            raise SceneError("hyper: the basis has no sampled elements (cf.rom.hyper.ecsw)")
        if chosen.sampled and hyper is not False:
            from cosserat_fem.rom.hyper import HyperSolver

            solver = HyperSolver(F, model.U, bcs, settings, chosen)
            solver.use_coordinates = coordinates
            return solver
        return ReducedSolver(F, model.U, bcs, settings, chosen)

    return make


def run(scene, basis: Basis | str | Path, out=None, **keywords):
    """A reduced run of ``scene`` on ``basis``: cosserat_fem/rom/runs.py's :func:`run` (cf.rom.run),
    the one reduced run, with its keywords (``observers``, ``record``, ``initial_state``,
    ``indicator``, ``restart``, ``progress``, ``comm``, ``hyper``)."""
    from cosserat_fem.rom.runs import run as reduced_run

    return reduced_run(scene, basis, out, **keywords)
