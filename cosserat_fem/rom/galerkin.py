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

Refused (SceneError/SolverError, one line): a basis of another space (basis.read_basis), a
scene whose supports move (the reference holds fixed Dirichlet values), and the moving chart
(large rotations: a chart change maps U off the basis; docs/rom.md, "Large rotations").
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
        """A new residual form is the chart moving (cosserat_fem/timestepping/loop.py): refused."""
        raise SolverError(
            "the rotations reached the Euler-angle chart's limit (|θ| near π/2): the chart "
            "change maps the state off the reduced basis (large rotations are not reduced yet)",
            where="reduced run",
            suggestion="run the full model (cf.run); docs/rom.md §9",
        )

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
