"""Periodic orbits of a periodically forced rod by shooting, and their Floquet stability.

**The map.** The rod is forced with period T [s] (e.g. T = 2π/Ω for a load ∝ sin Ωt). Its
period map Φ_T takes the state U0 at t0 = time.start to the state one period later, by
N = ``steps_per_period`` fixed steps h = T/N of the scene's SDIRK integrator
(cosserat_fem/timestepping/integrators.py; time.integrator = "sdirk3" or "sdirk4"), the same
steps and Newton solves as a run (cosserat_fem/timestepping/loop.py). SDIRK is a one-step
method: the state of the discrete map is U = (p, q) alone, the unknowns the rod solves for
(its free dofs: n = 2 × the free dofs of p), so Φ_T is a map of R^n whose n multipliers all
approximate the flow's (the history of BDF2 or generalized-α's rate would add spurious
ones). The predictor's stored stage rates are cleared at the start of each period, so that
Φ_T depends on U0 alone (they only move Newton's starting guess, not the converged stages).

**Its derivative, the monodromy matrix M = ∂Φ_T/∂U0**, by the variational equations of the
discrete map itself, carried through each stage: stage i solves
F(U_i, (U_i − Z_i)/(γh), τ_i) = 0 with Z_i = U_n + h Σ_{j<i} a_ij K_j, so

    J_i dU_i = −(∂F/∂Z) dZ_i,    dK_i = (dU_i − dZ_i)/(γh),    dU_{n+1} = dU_n + h Σ b_i dK_i,

J_i = ∂F/∂U the stage's exact Jacobian at its converged state, ∂F/∂Z the derivative of the
residual form in the history Function Z, both assembled from UFL (``ufl.derivative``). The
columns dU are carried as one dense matrix X (n_local × n) from X_0 = I (zero at the held
dofs, which are no state): per stage one Jacobian assembled and factored, one sparse × dense
product and one multi-right-hand-side back-solve (``MatMatSolve``). This is the exact
derivative of the discrete map (to the stage solves' tolerance), at the cost of one period of
time marching plus, per stage, one factorisation and n back-solves; n + 1 finite-difference
periods would cost n + 1 periods and carry a differencing error. The Newton iterations' own
frozen factors are not used: they are of an older state, and M needs the Jacobian at the
converged stage.

**Multipliers and stability.** The eigenvalues μ of M (over the free dofs) are the orbit's
Floquet multipliers. Of a linear mode with damping ratio ζ and damped frequency ω_d the flow's
pair is exp(−ζωT) exp(±iω_dT); the scheme's is R(λh)^N, R its stability function
(tests/test_periodic.py bounds the difference). The orbit is stable when every |μ| < 1; a
real μ crossing +1 marks a fold (cyclic fold), −1 period doubling, and a complex pair
crossing |μ| = 1 a torus (Neimark–Sacker) bifurcation (:func:`classify`).

**Shooting.** A periodic orbit solves R(U0) = Φ_T(U0) − U0 = 0; Newton's iteration
(M − I) δ = −R, U0 ← U0 + δ, each iteration one period with the variational equations. At
the held dofs Φ_T(U0) and U0 both hold the supports' values: R = 0, M's rows are zero, and
M − I is −I there.

**Continuation protocol** (a pseudo-arclength engine, cosserat_fem/nls/arclength.py, calls
these on :class:`Shooting`): ``residual(u, p)`` = Φ_T(u) − u with p the forcing parameter
(a scene parameter, e.g. r of Ω = r ω1; the period follows from the period expression),
``linearise(u, p)`` assembles and factors M − I, ``solve(rhs)``, ``dparameter(u, p)`` =
∂R/∂p (a forward difference: one more period), ``dot(a, b)`` summed over the ranks and
``determinant()`` = (sign, ln|det(M − I)|) from the LU (it changes sign where a real μ
crosses +1: at a fold the engine's limit point). Vectors are this rank's owned entries of the
model's U. :func:`trace_orbits` (``cf.periodic_branch``) runs the engine on it through the
folds of a frequency response, each point's multipliers those of the monodromy the engine
computed there for its tangent.

**Period doubling and tori** are the roots of two test functions of the multipliers, which
the engine locates like a fold (its ``tests``): det(M + I) = Π(1 + μ), whose sign changes
where a real μ crosses −1 (:func:`period_doubling_test`), and the bialternate product
Π_{i<j}(μ_i μ_j − 1), whose sign changes where a complex pair crosses |μ| = 1
(:func:`torus_test`). Both are continuous along a branch, across a pair's meeting on the
real axis too, which a product over the complex pairs alone is not.

**MPI.** Parallel in space, not in time: each rank carries its owned rows of X; the matrices
are PETSc's (MUMPS under mpirun) and M is gathered (n × n, dense) on every rank for its
eigenvalues and the Newton step, whose solve is rank 0's, broadcast. The period map itself is
the same code as a run's. A small rod (n ≤ :data:`GATHERED_DOFS`) under mpirun solves each
stage's variational equations gathered instead: every rank gathers ∂F/∂U, ∂F/∂Z (sparse) and
dZ_i (dense) whole and solves for all of dU_i by SuperLU (scipy), keeping its own rows. The
solve is then redundant, but it is one LU and a solve of n columns a stage, where MUMPS's
distributed factorisation and n-column solve exchange messages that cost far more on a rod
of a few hundred unknowns (the 8-element rod of demos/frequency_response.py: 150 unknowns,
a monodromy of 100 steps 2.6 s on two ranks, of which MUMPS's factorisations and solves
1.5 s, against 0.27 s serially; docs/decisions.md).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.linalg
import ufl
from dolfinx import fem
from dolfinx.fem.petsc import assemble_matrix, create_matrix
from mpi4py import MPI
from petsc4py import PETSc

from cosserat_fem.common.errors import SceneError, SolverError
from cosserat_fem.common.parallel import agree
from cosserat_fem.output.fields import PointProbe, probe_sigma
from cosserat_fem.scene.build import Scene
from cosserat_fem.scene.expressions import Expression
from cosserat_fem.scene.layout import Layout
from cosserat_fem.timestepping.events import Events, Observer
from cosserat_fem.timestepping.integrators import SDIRK
from cosserat_fem.timestepping.loop import TimeLoop

#: The most memory [bytes] the dense columns of the variational equations (X, the stages' dK,
#: PETSc's two dense matrices, a copy) may take on a rank.
MAX_DENSE_BYTES = 2 * 2**30

#: Under mpirun, a rod of at most this many unknowns solves its variational stages gathered
#: on every rank (module docstring, "MPI"): ~100 MB of dense n × n arrays a rank at the bound.
GATHERED_DOFS = 2000

#: |μ| within this of 1 counts as on the unit circle in :func:`classify`.
UNIT_CIRCLE = 1e-9


def classify(multipliers: np.ndarray) -> str:
    """The stability of an orbit from its Floquet multipliers: "stable" if every |μ| < 1, else
    how it is lost: "fold" (a real μ > 1: the middle branch of a multivalued response, beyond
    a cyclic fold), "period-doubling" (a real μ < −1) or "torus" (a complex pair outside the
    unit circle); the largest |μ| decides."""
    mu = np.asarray(multipliers)
    if mu.size == 0 or np.abs(mu).max() < 1.0 - UNIT_CIRCLE:
        return "stable"
    worst = mu[np.argmax(np.abs(mu))]
    if abs(worst.imag) > UNIT_CIRCLE * abs(worst):
        return "torus"
    return "fold" if worst.real > 0.0 else "period-doubling"


def _signed_product(factors: np.ndarray) -> float:
    """Π f_k of factors whose product is real (conjugates paired), from logarithms: its sign
    × exp(Σ ln|f_k|), the exponent clipped to ±700 (no overflow for any n; over multipliers
    spread around a circle of radius < 1 the mean of ln|1 + μ| is 0 by Jensen's formula, so
    the sum stays moderate); 0 if a factor is."""
    f = np.asarray(factors, dtype=complex).reshape(-1)
    size = np.abs(f)
    if np.any(size == 0.0):
        return 0.0
    phase = np.prod(f / size)
    log = float(np.sum(np.log(size)))
    return math.copysign(math.exp(min(max(log, -700.0), 700.0)), phase.real)


def period_doubling_test(multipliers: np.ndarray) -> float:
    """Π (1 + μ_k) = det(M + I) over the multipliers: continuous in the orbit, zero where a
    μ = −1; it changes sign where a real multiplier crosses −1 (period doubling), never where
    a complex pair moves (its factor |1 + μ|² > 0) or a real μ > −1 moves."""
    return _signed_product(1.0 + np.asarray(multipliers, dtype=complex))


def torus_test(multipliers: np.ndarray) -> float:
    """The bialternate product Π_{i<j} (μ_i μ_j − 1) (Govaerts, "Numerical Methods for
    Bifurcations of Dynamical Equilibria", 2000, ch. 4; Kuznetsov, "Elements of Applied
    Bifurcation Theory", 10.3): continuous, also where a complex pair meets on the real axis
    and splits (then μ_i μ_j = |μ|² still); a complex pair's factor is |μ|² − 1, so it changes
    sign where a pair crosses the unit circle (Neimark–Sacker: a torus), and also where two
    real multipliers' product crosses 1 (a neutral saddle, no bifurcation: :func:`is_torus`
    tells them apart)."""
    mu = np.asarray(multipliers, dtype=complex).reshape(-1)
    factors = [mu[i] * mu[i + 1 :] - 1.0 for i in range(mu.size - 1)]
    return _signed_product(np.concatenate(factors)) if factors else 1.0


def is_torus(multipliers: np.ndarray) -> bool:
    """At a root of :func:`torus_test`: whether the product μ_i μ_j nearest 1 is a complex
    pair's (a torus bifurcation) rather than two real multipliers' (a neutral saddle)."""
    mu = np.asarray(multipliers, dtype=complex).reshape(-1)
    if mu.size < 2:
        return False
    products = np.abs(np.multiply.outer(mu, mu) - 1.0)
    products[np.tril_indices(mu.size)] = np.inf
    i, _ = np.unravel_index(np.argmin(products), products.shape)
    return bool(abs(mu[i].imag) > UNIT_CIRCLE * abs(mu[i]))


def floquet_tests(multipliers_of) -> dict:
    """The test functions of a branch of orbits for the continuation engine's ``tests``
    (cosserat_fem/nls/arclength.py): kind → f(point), "period-doubling"
    (:func:`period_doubling_test`) and "torus" (:func:`torus_test`), of the multipliers
    ``multipliers_of(point)`` of the engine's point."""
    return {
        "period-doubling": lambda q: period_doubling_test(multipliers_of(q)),
        "torus": lambda q: torus_test(multipliers_of(q)),
    }


@dataclass
class Orbit:
    """A periodic orbit: ``state`` this rank's array of U at t0 (the model's layout),
    ``parameter`` p, ``period`` T [s], ``amplitude`` half the range of the probe's x [m] over
    the period (sampled at every step), ``multipliers`` the Floquet multipliers (largest
    modulus first), ``stability`` (:func:`classify`), the shooting ``iterations`` and the last
    residual ‖Φ_T(U0) − U0‖ (dimensionless, as U)."""

    state: np.ndarray
    parameter: float
    period: float
    amplitude: float
    multipliers: np.ndarray
    stability: str
    iterations: int
    residual: float

    @property
    def stable(self) -> bool:
        return self.stability == "stable"


class _StageHook(Observer):
    """Calls the shooting problem's variational stage after each converged stage solve."""

    def __init__(self, shooting: Shooting):
        self.shooting = shooting

    def solve_done(self, loop, iterations: int) -> None:
        self.shooting._stage_done()


def dense_problem(n: int, n_local: int, stages: int) -> SceneError | None:
    """Why the dense columns of the variational equations of ``n`` unknowns, ``n_local`` on
    the fullest rank, with ``stages`` stages exceed :data:`MAX_DENSE_BYTES`, or None."""
    dense = (4 + stages) * 8 * n * n_local
    if dense <= MAX_DENSE_BYTES:
        return None
    return SceneError(
        f"discretisation.elements: the monodromy matrix of {n} dofs needs "
        f"{dense / 2**30:.1f} GiB of dense columns on a rank (at most "
        f"{MAX_DENSE_BYTES / 2**30:.0f}); use fewer elements or more ranks"
    )


def _csr(A: PETSc.Mat) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """This rank's rows of the AIJ matrix ``A``: (entries a row, global columns, values)."""
    indptr, indices, values = A.getValuesCSR()
    return np.diff(indptr), indices, values


def shooting_problem(
    scene, steps_per_period, parameter: str | None, ranks: int | None = None
) -> SceneError | None:
    """Why :class:`Shooting` cannot shoot over this scene's period (its integrator, fixed
    steps, ``steps_per_period``, ``parameter``, the dense columns on ``ranks`` ranks, default
    MPI.COMM_WORLD's, at least: :func:`dense_problem` of the scene's unknowns shared evenly),
    or None: checked before any work (or folder)."""
    from cosserat_fem.scene.layout import FULL
    from cosserat_fem.scene.resolved import PLANAR
    from cosserat_fem.timestepping.integrators import _sdirk_tableau

    problem = None
    if scene.time.integrator not in ("sdirk3", "sdirk4"):
        problem = SceneError(
            f"time.integrator: periodic orbits need a one-step method, sdirk3 or sdirk4 "
            f"(the state of the period map is then U alone), got {scene.time.integrator!r}"
        )
    elif scene.time.adaptive:
        problem = SceneError("time.adaptive: periodic orbits need fixed steps (false)")
    elif isinstance(steps_per_period, bool) or not (
        isinstance(steps_per_period, int) and steps_per_period >= 1
    ):
        problem = SceneError(
            f"steps_per_period: must be a whole number >= 1, got {steps_per_period!r}"
        )
    elif parameter is not None and parameter not in scene.parameters:
        problem = SceneError(
            f"parameter: {parameter!r} is not one of the scene's parameters "
            f"{sorted(scene.parameters)}"
        )
    else:
        plane = scene.plane()
        disc = scene.discretisation
        n = (disc.elements * disc.degree + 1) * len(PLANAR[plane] if plane else FULL)
        ranks = MPI.COMM_WORLD.size if ranks is None else ranks
        stages = _sdirk_tableau(int(scene.time.integrator[-1]))[2].size
        problem = dense_problem(n, -(-n // ranks), stages)
    return problem


class Shooting:
    """The period map of ``scene`` and its monodromy matrix (module docstring).

    ``period``: T [s], a number or an expression of the scene's constants (``"2*pi/(r*w1)"``);
    ``parameter``: the name of the scene parameter p the continuation protocol varies (the
    period follows from its expression); ``steps_per_period`` N; ``stol``: the stage solves'
    relative update tolerance (tighter than a run's: the shooting residual must resolve
    well below the orbit's changes)."""

    def __init__(
        self,
        scene: Scene,
        period: float | str,
        *,
        steps_per_period: int = 300,
        parameter: str | None = None,
        stol: float = 1e-11,
        comm: MPI.Comm = MPI.COMM_WORLD,
    ):
        from dataclasses import replace

        from cosserat_fem.analysis.simulation import _discretise

        problem = shooting_problem(scene, steps_per_period, parameter, comm.size)
        agree(comm, problem)
        self.scene, self.comm, self.steps = scene, comm, steps_per_period
        self.parameter = parameter
        self._constants = dict(scene.expression_names())
        self._period_source = period
        self.period = self._period_at(None)
        model, integrator, solver = _discretise(scene, comm, None, None)
        assert isinstance(integrator, SDIRK), "checked above"
        if model.needs_chart:
            model.use_chart(active=False)
        solver.settings = replace(solver.settings, stol=stol, atol=1e-16, rtol=0.0)
        self.model, self.integrator, self.solver = model, integrator, solver
        self.t0 = scene.time.start
        self.probe = PointProbe(model, probe_sigma(scene))
        self._hook = _StageHook(self)
        self._tangent = False
        self._setup_tangent()
        self.linearised: np.ndarray | None = None  # M at the last linearise
        #: when a dict: each linearise stores {(p, u bytes): (amplitude [m], multipliers)}
        #: (the probe's x sampled at every step of that period), for a branch's points
        self.monodromies = 0  # periods run with the variational equations
        self.records: dict[tuple[float, bytes], tuple[float, np.ndarray]] | None = None
        self._lu: tuple[np.ndarray, np.ndarray] | None = None

    # -- the forcing parameter ------------------------------------------------------------
    def _period_at(self, p: float | None) -> float:
        """T [s] at parameter value p (None: the scene's)."""
        constants = dict(self._constants)
        if p is not None and self.parameter is not None:
            constants[self.parameter] = p
        source = self._period_source
        if isinstance(source, str):
            value = float(
                Expression.parse(source, set(constants), key="period").evaluate(**constants)
            )
        else:
            value = float(source)
        if not (math.isfinite(value) and value > 0.0):
            raise SceneError(f"period: {source!r} = {value!r} s; must be a positive time")
        return value

    def set_parameter(self, p: float) -> None:
        """The forcing parameter p: the scene parameter's Constant, and the period."""
        if self.parameter is None:
            raise SceneError("parameter: give the name of the scene parameter to vary")
        self.model.set_parameter(self.parameter, p)
        self.period = self._period_at(p)

    # -- the variational equations ----------------------------------------------------------
    def _setup_tangent(self) -> None:
        """Forms, matrices and the LU solver of the variational stages (module docstring)."""
        model, integrator, solver = self.model, self.integrator, self.solver
        V = model.V
        F = integrator.residual_form()
        dU = ufl.TrialFunction(V)
        self._J_form = solver.J_form  # ∂F/∂U, the Newton solver's own compiled form
        self._JZ_form = fem.form(ufl.derivative(F, integrator.Z, dU))
        self._J = create_matrix(self._J_form)  # AIJ: MatMatSolve needs no blocked variant
        self._JZ = create_matrix(self._JZ_form)
        imap = V.dofmap.index_map
        bs = V.dofmap.index_map_bs
        self.n_local = imap.size_local * bs
        self.n = imap.size_global * bs
        self.first = imap.local_range[0] * bs
        held = np.zeros(self.n_local, dtype=bool)
        for bc in model.bcs:
            dofs, _ = bc.dof_indices()
            held[dofs[dofs < self.n_local]] = True
        self.held_local = held
        self.held = np.concatenate(self.comm.allgather(held))
        self.free = np.flatnonzero(~self.held)
        #: the variational stages solved gathered on every rank (module docstring, "MPI")
        self.gathered = self.comm.size > 1 and self.n <= GATHERED_DOFS
        stages = len(integrator.b)
        problem = dense_problem(self.n, max(self.comm.allgather(self.n_local)), stages)
        if problem is not None:  # the partition's fullest rank (shooting_problem: an even one)
            raise problem
        self._ksp = PETSc.KSP().create(self.comm)
        self._ksp.setType("preonly")
        self._ksp.getPC().setType("lu")
        self._ksp.getPC().setFactorSolverType(solver.lu_package)
        self._ksp.setOperators(self._J)
        sizes = ((self.n_local, self.n), (None, self.n))
        self._B = PETSc.Mat().createDense(sizes, comm=self.comm)
        self._B.setUp()
        self._Y = PETSc.Mat().createDense(sizes, comm=self.comm)
        self._Y.setUp()
        self._X = np.zeros((self.n_local, self.n))
        self._dK = np.zeros((stages, self.n_local, self.n))
        self._stage = 0
        self._h = 0.0  # the step in τ of the current period

    def _stage_done(self) -> None:
        """After stage i's solve converged (U = U_i, Z = Z_i, τ = τ_i): dZ_i, dU_i, dK_i."""
        if not self._tangent:
            return
        integ, i = self.integrator, self._stage
        h = self._h  # the step in τ
        dZ = self._X.copy()
        for j in range(i):
            dZ += h * integ.A[i, j] * self._dK[j]
        dU = self._stage_solve(dZ)
        self._dK[i] = (dU - dZ) / (integ.gamma * h)
        self._stage += 1

    def _stage_solve(self, dZ: np.ndarray) -> np.ndarray:
        """The owned rows of dU_i = −(∂F/∂U)⁻¹ (∂F/∂Z) dZ_i (the held rows' right-hand side 0:
        J has the identity's rows there), assembled at the stage's state; by PETSc (MUMPS
        under mpirun), or gathered on every rank (:attr:`gathered`)."""
        for A, form, bcs in (
            (self._J, self._J_form, self.model.bcs),
            (self._JZ, self._JZ_form, []),
        ):
            A.zeroEntries()
            # the singledispatch's overload for a PETSc.Mat, (mat, form, bcs), is not in
            # DOLFINx's annotations
            assemble_matrix(A, form, bcs=bcs)  # type: ignore[misc]
            A.assemble()
        if self.gathered:
            import scipy.sparse.linalg

            parts = self.comm.allgather((_csr(self._J), _csr(self._JZ), dZ))  # one message
            J, JZ = (self._whole([part[k] for part in parts]) for k in (0, 1))
            Y = -(JZ @ np.vstack([part[2] for part in parts]))
            Y[self.held] = 0.0
            dU = scipy.sparse.linalg.splu(J.tocsc()).solve(Y)
            return dU[self.first : self.first + self.n_local]
        self._ksp.getPC().setUp()  # refactors: KSPSetUp alone keeps the old factors
        B = self._B.getDenseArray()
        B[:] = dZ
        self._JZ.matMult(self._B, self._Y)
        Y = self._Y.getDenseArray()
        Y[self.held_local] = 0.0  # the held rows: dU = 0 there (J has the identity's)
        Y *= -1.0
        self._ksp.getPC().getFactorMatrix().matSolve(self._Y, self._B)
        return self._B.getDenseArray()  # a view, read before the next stage's solve

    def _whole(self, parts: list[tuple[np.ndarray, np.ndarray, np.ndarray]]):
        """The n × n matrix (scipy CSR) of the ranks' :func:`_csr` ``parts`` of a distributed
        AIJ matrix, in rank order (ownership ranges are contiguous and in rank order)."""
        import scipy.sparse

        starts = np.concatenate([[0], np.cumsum(np.concatenate([c for c, _, _ in parts]))])
        columns = np.concatenate([i for _, i, _ in parts])
        entries = np.concatenate([v for _, _, v in parts])
        return scipy.sparse.csr_matrix((entries, columns, starts), shape=(self.n, self.n))

    # -- the period map ---------------------------------------------------------------------
    def _start(self, u: np.ndarray) -> TimeLoop:
        """The model and the integrator at t0 in the state u (owned entries), the predictor's
        history cleared; a time loop over them that announces each stage to the tangent."""
        model, integ = self.model, self.integrator
        U = model.U
        U.x.array[: self.n_local] = u
        U.x.scatter_forward()
        if model.motions:
            model.support_dofs_to(U.x.array, self.t0 * model.omega0)
        stages = len(integ.b)
        size = U.x.array.size
        integ.load_state_dict(
            {
                "time": self.t0 * model.omega0,
                "steps_taken": 0,
                "U_n": U.x.array.copy(),
                "rates": np.zeros((stages, size)),
                "rate_times": np.zeros(stages),
                "stored": 0,
            }
        )
        self.solver.request_jacobian()
        return TimeLoop(model, integ, self.solver, self.scene.time, Events([self._hook]))

    def advance(self, u: np.ndarray, tangent: bool = False, probe: bool = False):
        """Φ_T(u) (owned entries) over one period from t0; with ``tangent`` also M (n × n,
        on every rank); with ``probe`` also the probe's x [m] at each step (every rank).
        SolverError if a step fails (a halved step would change the map)."""
        loop = self._start(u)
        self._tangent = tangent
        if tangent:
            self._X[:] = 0.0
            rows = np.arange(self.n_local)
            self._X[rows, self.first + rows] = 1.0
            self._X[self.held_local] = 0.0
        xs = [self._probe_x()] if probe else []
        h = self.period / self.steps
        self._h = h * self.model.omega0  # in τ = ω0 t
        integ = self.integrator
        try:
            for k in range(1, self.steps + 1):
                t_new = self.t0 + k * h
                self._stage = 0
                cause = loop.attempt(t_new)
                if cause is not None:
                    raise SolverError(
                        time=cause.time,
                        where=cause.where,
                        reason=f"{cause.reason} (a step of the period map, which is not halved)",
                        suggestion="raise steps_per_period",
                    )
                if tangent:
                    self._X += self._h * np.tensordot(integ.b, self._dK, axes=1)
                loop.accept(t_new)
                if loop.state.chart_resets:
                    raise SolverError(
                        time=t_new,
                        reason="the angles' chart moved during the period",
                        suggestion="periodic orbits of rotations near θ = ±π/2 are not supported",
                    )
                if probe:
                    xs.append(self._probe_x())
        finally:
            self._tangent = False
        u_new = self.model.U.x.array[: self.n_local].copy()
        self.monodromies += bool(tangent)
        M = self._gather(self._X) if tangent else None
        return u_new, M, (np.array(xs) if probe else None)

    def _probe_x(self) -> float:
        values = self.probe.values()
        x = float(values[0]) if values is not None else 0.0
        return self.comm.bcast(x, root=self.probe.owner)

    def _gather(self, rows: np.ndarray) -> np.ndarray:
        """The n × n matrix whose owned rows each rank holds (ownership ranges are
        contiguous and in rank order)."""
        return np.vstack(self.comm.allgather(rows))

    def multipliers(self, M: np.ndarray) -> np.ndarray:
        """The eigenvalues of M over the free dofs, largest modulus first."""
        mu = scipy.linalg.eigvals(M[np.ix_(self.free, self.free)])
        return mu[np.argsort(-np.abs(mu), kind="stable")]

    # -- the continuation protocol -------------------------------------------------------------
    def residual(self, u: np.ndarray, p: float | None = None) -> np.ndarray:
        """Φ_T(u) − u at parameter p (None: the current)."""
        if p is not None:
            self.set_parameter(p)
        return self.advance(u)[0] - u

    def linearise(self, u: np.ndarray, p: float | None = None) -> np.ndarray:
        """M at (u, p) and the LU factors of M − I (for :meth:`solve`); returns the residual
        Φ_T(u) − u, which the same period gives."""
        if p is not None:
            self.set_parameter(p)
        record = self.records is not None
        u_new, M, xs = self.advance(u, tangent=True, probe=record)
        self.linearised = M
        self._lu = scipy.linalg.lu_factor(M - np.eye(self.n)) if self.comm.rank == 0 else None
        if self.records is not None:
            assert xs is not None
            at = p if p is not None else self.model.parameter_value(str(self.parameter))
            key = (float(at), u.tobytes())
            self.records[key] = (0.5 * float(xs.max() - xs.min()), self.multipliers(M))
        return u_new - u

    def determinant(self) -> tuple[float, float]:
        """(sign, ln |det(M − I)|) from the LU factors of the last :meth:`linearise` (every
        rank). det(M − I) = Π(μ_k − 1) over the multipliers (the held dofs' rows give −1
        each, a constant sign): it changes sign where a real μ crosses +1, at a fold of the
        orbit branch; a complex pair's factor |μ − 1|² > 0 never does."""
        result = None
        if self.comm.rank == 0:
            assert self._lu is not None, "linearise first"
            lu, piv = self._lu
            diag = np.diag(lu)
            swaps = int(np.count_nonzero(piv != np.arange(piv.size)))
            sign = float((-1) ** swaps * np.prod(np.sign(diag)))
            result = (sign, float(np.sum(np.log(np.abs(diag)))))
        return self.comm.bcast(result, root=0)

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        """x (owned entries) with (M − I) x = rhs, M of the last :meth:`linearise`."""
        full = np.concatenate(self.comm.allgather(np.asarray(rhs)))
        x = scipy.linalg.lu_solve(self._lu, full) if self.comm.rank == 0 else None
        x = self.comm.bcast(x, root=0)
        return x[self.first : self.first + self.n_local]

    def dparameter(self, u: np.ndarray, p: float, relative_step: float = 1e-6) -> np.ndarray:
        """∂R/∂p at (u, p) by a forward difference of step δ = ``relative_step`` |p| (its
        error O(δ) relative: 1e-6 against the truncation, 1e-11/1e-6 = 1e-5 against the stage
        solves' tolerance); the parameter is left at p."""
        delta = relative_step * max(abs(p), 1.0)
        base = self.residual(u, p)
        shifted = self.residual(u, p + delta)
        self.set_parameter(p)
        return (shifted - base) / delta

    def dot(self, a: np.ndarray, b: np.ndarray) -> float:
        """a · b summed over the ranks' owned entries."""
        return self.comm.allreduce(float(np.dot(a, b)), op=MPI.SUM)

    # -- shooting ---------------------------------------------------------------------------
    def rest(self) -> np.ndarray:
        """The state at rest (owned entries, supports' values)."""
        return self.model.U.x.array[: self.n_local] * 0.0

    def check_state(self, state) -> np.ndarray:
        """``state`` as this rank's owned entries of U (the model's layout): SceneError naming
        ``guess`` unless it is that many finite numbers (collective)."""
        problem, u = None, None
        try:
            u = np.asarray(state, dtype=float).reshape(-1)
        except (TypeError, ValueError):
            problem = SceneError(f"guess: must be an array of numbers, got {type(state).__name__}")
        if u is not None and u.size != self.n_local:
            problem = SceneError(
                f"guess: {u.size} values, expected this rank's {self.n_local} of U "
                f"({self.model.layout.size} a node: an Orbit's state)"
            )
        elif u is not None and not np.isfinite(u).all():
            problem = SceneError("guess: not every value is finite")
        agree(self.comm, problem)
        assert u is not None
        return u.copy()

    def modal_state(self, phi, dphi, q: float, qdot: float) -> np.ndarray:
        """A state of bending in x with one shape (owned entries): x(s) = q φ(s), ψ(s) = q φ'(s)
        and their rates q̇ φ, q̇ φ' [m, rad, m/s, rad/s] (φ, φ' functions of s [m]); e.g. the
        harmonic balance's q(t0), q̇(t0) of cosserat_fem/reference/backbone.py, as a guess."""
        model = self.model
        layout = model.layout
        s = model.V.tabulate_dof_coordinates()[:, 0] * model.length
        full = np.zeros((s.size, 12))
        full[:, 0], full[:, 4] = q * phi(s), q * dphi(s)
        full[:, 6], full[:, 10] = qdot * phi(s), qdot * dphi(s)
        full /= Layout().si_scale(model.length, model.omega0)  # to U's units
        state = full[:, list(layout.components)].reshape(-1)
        return state[: self.n_local]

    def settle(self, u: np.ndarray, periods: int) -> np.ndarray:
        """The state after ``periods`` periods of time marching from u (a guess that time
        marching can reach: a stable orbit's basin)."""
        for _ in range(periods):
            u = self.advance(u)[0]
        return u

    def find(self, guess: np.ndarray, tolerance: float = 1e-9, max_iterations: int = 20) -> Orbit:
        """The periodic orbit near ``guess`` by Newton's iteration on Φ_T(u) − u (module
        docstring), until ‖δ‖ ≤ tolerance (1 + ‖u‖); then one more period for the multipliers
        at the orbit and the probe's amplitude. SolverError if it does not converge."""
        u = np.asarray(guess, dtype=float).copy()
        iterations = 0
        while iterations < max_iterations:
            iterations += 1
            r = self.linearise(u)
            delta = self.solve(-r)
            u += delta
            size = math.sqrt(self.dot(delta, delta))
            if size <= tolerance * (1.0 + math.sqrt(self.dot(u, u))):
                break
        else:
            raise SolverError(
                reason=f"shooting did not converge in {max_iterations} Newton iterations "
                f"(last update {size:.3g})",
                suggestion="start from a closer guess (settled periods, the harmonic balance)",
            )
        u_end, M, xs = self.advance(u, tangent=True, probe=True)
        mu = self.multipliers(M)
        assert xs is not None
        return Orbit(
            state=u,
            parameter=float(self.model.parameter_value(self.parameter))
            if self.parameter is not None
            else math.nan,
            period=self.period,
            amplitude=0.5 * float(xs.max() - xs.min()),
            multipliers=mu,
            stability=classify(mu),
            iterations=iterations,
            residual=math.sqrt(self.dot(u_end - u, u_end - u)),
        )

    def destroy(self) -> None:
        """Free the PETSc objects (the solver's too)."""
        for obj in (self._ksp, self._J, self._JZ, self._B, self._Y):
            obj.destroy()
        self.solver.destroy()


# -- branches of periodic orbits ------------------------------------------------------------

#: The columns of an orbit branch's CSV (:func:`~cosserat_fem.analysis.paths.write_branches`):
#: branch index, the parameter p, the amplitude [m], the largest multiplier's |μ|, Re μ, Im μ,
#: dp/ds, the sign of det(M − I), the stability (:func:`classify`) and the point's kind
#: ("period-doubling", "torus" rows since the tori and doublings are located: at such a row,
#: on a branch stable before it, the largest multiplier is the one on the circle).
ORBIT_COLUMNS = (
    "branch",
    "parameter",
    "amplitude",
    "mu_abs",
    "mu_re",
    "mu_im",
    "dparameter_ds",
    "det_sign",
    "stability",
    "point",
)


@dataclass
class OrbitPoint:
    """An orbit on a branch: ``parameter`` p, ``amplitude`` [m] (as :class:`Orbit`'s),
    ``multipliers`` (largest modulus first), ``stability``, dp/ds (``dparameter``), the sign of
    det(M − I), ``kind`` ("start", "regular", "end", or a located point: "limit" a fold,
    "period-doubling", "torus", "bifurcation") and ``state`` (this rank's U at t0)."""

    parameter: float
    amplitude: float
    multipliers: np.ndarray
    stability: str
    dparameter: float
    det_sign: float
    kind: str
    state: np.ndarray

    def as_row(self, branch: int) -> dict:
        mu = complex(self.multipliers[0])
        return dict(
            zip(
                ORBIT_COLUMNS,
                (
                    branch,
                    self.parameter,
                    self.amplitude,
                    abs(mu),
                    mu.real,
                    mu.imag,
                    self.dparameter,
                    self.det_sign,
                    self.stability,
                    self.kind,
                ),
                strict=True,
            )
        )


@dataclass
class OrbitBranch:
    """A traced branch of periodic orbits: ``points`` in the order traced, ``special`` the
    located points (not among ``points``): ``folds``, the limit points (a real multiplier
    at +1), ``period_doublings`` (a real multiplier at −1), ``tori`` (a complex pair on the
    unit circle: Neimark–Sacker), and any "bifurcation" (det(M − I) changing sign at no
    fold); why it ended (``reason``); its
    cost: continuation ``steps`` (accepted), ``rejected`` steps and ``monodromies`` (periods
    with the variational equations, each about 34 periods of time marching,
    docs/decisions.md)."""

    points: list[OrbitPoint]
    special: list[OrbitPoint]
    reason: str
    steps: int
    rejected: int
    monodromies: int

    def rows(self) -> list[dict]:
        return [q.as_row(0) for q in [*self.points, *self.special]]

    @property
    def folds(self) -> list[OrbitPoint]:
        return [q for q in self.special if q.kind == "limit"]

    @property
    def period_doublings(self) -> list[OrbitPoint]:
        return [q for q in self.special if q.kind == "period-doubling"]

    @property
    def tori(self) -> list[OrbitPoint]:
        return [q for q in self.special if q.kind == "torus"]


def _failing_step(method, u: np.ndarray, p: float) -> np.ndarray:
    """``method(u, p)``, a failed period (SolverError: a stage that did not converge, e.g. from
    a prediction too far) raised as the RuntimeError the engine takes for a failed step."""
    try:
        return method(u, p)
    except SolverError as exc:
        raise RuntimeError(str(exc)) from None


class _Weighted:
    """A :class:`Shooting` whose ``dot`` is weighted by w (the arclength's metric,
    :func:`trace_orbits`); everything else is the shooting's own."""

    def __init__(self, shooting: Shooting, weight: float):
        self.shooting, self.weight = shooting, weight
        self.solve, self.determinant = shooting.solve, shooting.determinant

    def residual(self, u: np.ndarray, p: float) -> np.ndarray:
        return _failing_step(self.shooting.residual, u, p)

    def linearise(self, u: np.ndarray, p: float) -> None:
        _failing_step(self.shooting.linearise, u, p)

    def dparameter(self, u: np.ndarray, p: float) -> np.ndarray:
        return _failing_step(self.shooting.dparameter, u, p)

    def dot(self, a: np.ndarray, b: np.ndarray) -> float:
        return self.weight * self.shooting.dot(a, b)


def orbit_engine(shooting: Shooting, weight: float, settings, watch=None):
    """The continuation engine (cosserat_fem/nls/arclength.py) on ``shooting``'s problem in
    the metric of weight w (:func:`trace_orbits`), with the Floquet test functions
    (:func:`floquet_tests`) of the multipliers in ``shooting.records`` and ``watch`` as its
    ``stop`` hook: :func:`trace_orbits`'s, and a restarted branch's
    (cosserat_fem/analysis/orbit_runs.py)."""
    from cosserat_fem.nls.arclength import Continuation

    records = shooting.records
    assert records is not None, "the shooting's records are kept while a branch is traced"

    def multipliers(q) -> np.ndarray:
        return records[(float(q.p), q.u.tobytes())][1]

    return Continuation(
        _Weighted(shooting, weight), settings, watch, tests=floquet_tests(multipliers)
    )


def orbit_point(records: dict, q) -> OrbitPoint:
    """The engine's point ``q`` as an orbit: its amplitude and multipliers from the monodromy
    computed there (``records``: (p, u's bytes) → (amplitude, multipliers))."""
    amplitude, mu = records[(float(q.p), q.u.tobytes())]
    return OrbitPoint(q.p, amplitude, mu, classify(mu), q.t_p, q.det_sign, q.kind, q.u.copy())


def as_orbit_branch(shooting: Shooting, branch, kept: int = 1, rejected: int = 0) -> OrbitBranch:
    """The engine's ``branch`` as an :class:`OrbitBranch`: its points and special points as
    orbits (:func:`orbit_point`), a root of the torus test at which no complex pair is on
    the circle (a neutral saddle, :func:`is_torus`) dropped; the steps counted beyond the
    ``kept`` points it started with and the ``rejected`` steps it had."""
    records = shooting.records
    assert records is not None, "the shooting's records are kept while a branch is traced"
    special = [orbit_point(records, q) for q in branch.special]
    return OrbitBranch(
        [orbit_point(records, q) for q in branch.points],
        [q for q in special if q.kind != "torus" or is_torus(q.multipliers)],
        branch.reason,
        len(branch.points) - kept,
        branch.steps_rejected - rejected,
        shooting.monodromies,
    )


def trace_orbits(
    shooting: Shooting,
    guess: np.ndarray,
    start: float,
    end: float,
    settings=None,
    scale: float = 4.0,
    observer=None,
) -> OrbitBranch:
    """The branch of periodic orbits from the one near ``guess`` at p = ``start`` to p =
    ``end`` (either side), by the pseudo-arclength engine (cosserat_fem/nls/arclength.py) on
    the shooting problem R(u, p) = Φ_T(u) − u, through its folds, which it locates (limit
    points: dp/ds = 0, where det(M − I) changes sign and a real multiplier crosses +1), and
    its period doublings and tori, located as the roots of the engine's ``tests``
    (:func:`floquet_tests`; a root of the bialternate product at which no complex pair is on
    the circle, a neutral saddle, is dropped). Each is located by the engine's regula falsi
    in arclength to ``settings.locate_tolerance`` (each evaluation a corrected orbit), so
    its p to that too (|dp/ds| ≤ 1), and the multiplier at −1 (the pair on the circle) to
    |dμ/ds| times it.

    The metric: ‖(u, p)‖² = w u·u + p², w chosen so that the start orbit's weighted norm is
    ``scale`` × its amplitude / ℓ (one mode dominates, so this holds along the branch): with
    4, a 25 mm amplitude range of a 1 m rod weighs as Δp = 0.1. ``settings``: a
    :class:`~cosserat_fem.nls.arclength.ContinuationSettings` (p_min, p_max are set from
    start, end). Each point's multipliers and amplitude are those of the monodromy the engine
    computed there for its tangent (no extra period). ``observer(point, weight)``, if given,
    is told of the engine's first point and of each accepted one as the branch grows (the
    command line's outputs and restart data: cosserat_fem/analysis/orbit_runs.py)."""
    from dataclasses import replace

    from cosserat_fem.nls.arclength import ContinuationSettings

    settings = replace(
        settings or ContinuationSettings(),
        p_min=min(start, end),
        p_max=max(start, end),
    )
    shooting.records = {}
    shooting.monodromies = 0
    try:
        shooting.set_parameter(start)
        first = shooting.find(guess)
        size = math.sqrt(shooting.dot(first.state, first.state))
        weight = (scale * first.amplitude / shooting.model.length / size) ** 2
        watch = None if observer is None else (lambda q: observer(q, weight))
        engine = orbit_engine(shooting, weight, settings, watch)
        direction = 1 if end > start else -1
        origin = engine.start_point(first.state, start, direction)
        if observer is not None:
            observer(origin, weight)
        return as_orbit_branch(shooting, engine.trace(origin, 1))
    finally:
        shooting.records = None
