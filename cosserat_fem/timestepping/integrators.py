"""Implicit time integrators for first-order systems  F(U, dU/dτ, τ; V) = 0.

An integrator knows nothing of rods. It is given the unknown Function ``U`` (the state at the
new time level, which Newton solves for) and a callable ``residual(U_eval, Udot_eval,
time_eval) -> ufl.Form``; it returns the residual form in which U_eval, Udot_eval and
time_eval are the scheme's UFL combinations of ``U``, its own history Functions and
Constants, and it updates the history after each accepted step.

* :class:`Static`: Udot = 0 (equilibrium; used for static loads).
* :class:`BDF2`: variable-step two-step backward differentiation formula,
  Udot_{n+1} = [(1+2ω)/(1+ω) U_{n+1} − (1+ω) U_n + ω²/(1+ω) U_{n−1}] / h_n, ω = h_n/h_{n−1};
  second order and L-stable. "Proper start": its first step is an implicit-midpoint step,
  F((U_0 + U_1)/2, (U_1 − U_0)/h, τ_0 + h/2) = 0 (one-step, second order, local error O(h³)),
  so no first-order error enters the history.
* :class:`GeneralizedAlpha`: Jansen, Whiting & Hulbert (2000), CMAME 190:305-319, for
  first-order systems, with spectral radius at infinity ρ∞ ∈ [0, 1]:
  αm = ½ (3 − ρ∞)/(1 + ρ∞), αf = 1/(1 + ρ∞), γ = ½ + αm − αf;
  U_{n+1} = U_n + h U̇_n + γ h (U̇_{n+1} − U̇_n),
  F(U_n + αf (U_{n+1} − U_n), U̇_n + αm (U̇_{n+1} − U̇_n), τ_n + αf h) = 0.
  Second order for every ρ∞; ρ∞ = 1 is the (non-dissipative) midpoint rule. The initial
  rate U̇_0 is made consistent by one linear solve (``initial_rate``).
* :class:`SDIRK`: singly diagonally implicit Runge–Kutta methods, A-stable, of order 3
  (Nørsett/Crouzeix, two stages, γ = (3 + √3)/6) and order 4 (Crouzeix 1975, three stages,
  γ = 1/2 + cos(π/18)/√3). Stage i solves F(U_i, K_i, τ_n + c_i h) = 0 with
  K_i = (U_i − Z_i)/(γ h), Z_i = U_n + h Σ_{j<i} a_ij K_j, one after the other; then
  U_{n+1} = U_n + h Σ b_i K_i. Every stage has the same γ h, so the stage Jacobians are one
  matrix and a frozen Jacobian (and its LU factors) serves all stages of all steps.
  |R(∞)| = 0.73 (order 3) and 0.63 (order 4): unresolved modes are damped, resolved ones lose
  amplitude at order p + 1 per step.

Every integrator advances by :meth:`Integrator.step` (one or several nonlinear solves through
the ``solve`` callable it is given) and :meth:`Integrator.accept` once the caller has checked
the new state.

**One-step steps around a jump.** BDF2 (from its last two states) and generalized-α at ρ∞ < 1
(from its rate recurrence) carry history that a jump of the solution's rate within a step (an
impact) spoils: the steps after it drag the jump on. Such an integrator is ``multistep``; its
caller may ask for implicit-midpoint steps, F((U_n + U_{n+1})/2, (U_{n+1} − U_n)/h,
τ_n + h/2) = 0, by :meth:`Integrator.use_one_step` (BDF2: its start step; generalized-α: its
own form at αm = αf = γ = ½), and go back to the method by ``use_one_step(False)`` and
:meth:`Integrator.restart` (generalized-α: a consistent rate at the new state, as at its
start; BDF2: its first step's Newton starts from U_n, not from the extrapolation of two
midpoint states). The midpoint rule depends on U_n only and changes the kinetic energy of a
mechanical system by the work of its forces exactly, at a jump too (cosserat_fem/nls/contact.py,
``NodeContact.accept``); the caller decides when (cosserat_fem/timestepping/loop.py).

**The space of the state arrays.** Everything an integrator does with U is linear (stage
combinations, rates, predictors), so it runs unchanged on any coordinates of U that an affine
map U = U_ref + V y gives (docs/rom.md §5, §8). Its arrays belong to a ``space``
(:class:`FullSpace`: U's own values, zero-copy, the default; a reduced model's coordinates y,
cosserat_fem/rom/hyper.py ``ReducedCoordinates``): ``space.values(F)`` is the array it treats
as the Function F's values, ``space.size`` their length, ``to_full``/``from_full`` convert a
checkpoint's arrays (which are always full vectors). :meth:`Integrator.use_space` moves an
integrator into another space before its first step (the four here can; the forms read
their Functions, which the space's owner writes where they are read).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import ufl
from dolfinx import fem
from dolfinx.fem.petsc import apply_lifting, assemble_matrix, assemble_vector, set_bc
from mpi4py import MPI
from petsc4py import PETSc

ResidualFactory = Callable[[object, object, object], ufl.Form]
#: A change of variables (:meth:`Integrator.change_variables`): state array -> state array.
StateMap = Callable[[np.ndarray], np.ndarray]
#: The same change for a rate: (state array, rate array at it) -> rate array.
RateMap = Callable[[np.ndarray, np.ndarray], np.ndarray]


class FullSpace:
    """The full model's space of state arrays: a Function's own values (zero-copy); the
    conversions of a checkpoint's arrays are copies (module docstring, "The space")."""

    reduced = False

    def __init__(self, U: fem.Function):
        self.size = U.x.array.size

    def values(self, F: fem.Function, rate: bool = False) -> np.ndarray:
        """The array the integrator treats as F's values (F's own, here)."""
        return F.x.array

    def to_full(self, array: np.ndarray, rate: bool = False) -> np.ndarray:
        """A copy of a state (or with ``rate`` a rate) array as a full vector."""
        return array.copy()

    def from_full(self, array: np.ndarray, rate: bool = False) -> np.ndarray:
        """A full vector's array in this space (itself)."""
        return np.asarray(array)

    def lift(self) -> None:
        """The Functions' full values from the coordinates (nothing: they are the values)."""

    def refuse_chart(self) -> None:
        """The chart may move (the full model's variables change with it)."""


def _constant(U: fem.Function, value: float = 0.0) -> fem.Constant:
    return fem.Constant(U.function_space.mesh, PETSc.ScalarType(value))


def time_view(constant: fem.Constant) -> np.ndarray:
    """The 0-d array that is a scalar Constant's own storage: ``view[()] = x`` sets it at a
    tenth of the cost of ``constant.value = x``, which wraps the storage anew each call."""
    return constant._cpp_object.value


class Integrator:
    """Common interface. Subclasses define the forms and the history update."""

    name = "integrator"
    order = 0
    #: whether the steps carry history that a jump of the rate spoils (module docstring,
    #: "One-step steps around a jump")
    multistep = False

    def __init__(self, U: fem.Function, residual: ResidualFactory, time: float = 0.0):
        self.U = U
        self.time = float(time)
        self.time_eval = _constant(U, time)
        self._factory = residual
        self.steps_taken = 0
        self.unknown_time = self.time  # τ of the unknown U in the current solve
        self.space: FullSpace = FullSpace(U)  # of the state arrays (module docstring)

    def use_space(self, space) -> None:
        """Keep the state arrays in ``space`` from now on (before the first step; module
        docstring, "The space"); NotImplementedError with the reason if this integrator cannot
        (it writes U's values directly)."""
        raise NotImplementedError(
            f"the {self.name} integrator writes U's values directly (only SDIRK runs on "
            "reduced coordinates)"
        )

    def residual_form(self) -> ufl.Form:
        raise NotImplementedError

    def start(self, problem, lu_package: str) -> None:
        """The integrator's own set-up before the first step of a run that starts from the
        state in U (not a restart, whose history comes from :meth:`load_state_dict`). Most
        integrators need none; :class:`GeneralizedAlpha` solves for a consistent rate.
        ``problem`` gives what such a solve needs of the system: ``bcs`` (the Dirichlet
        conditions), ``constraints`` (dofs tied by rows, cosserat_fem/nls/constraints.py, or
        None), ``move_supports(τ, rates=False)`` (prescribed values, or their rates,
        at τ), ``sync_loads(time_eval)`` (data loads at the Constant's τ); ``lu_package`` the
        LU factorisation's PETSc package."""

    def prepare(self, h: float) -> None:
        """Set the Constants for a step of size h from ``self.time`` and predict U."""
        raise NotImplementedError

    def use_one_step(self, on: bool) -> None:
        """From the next step on, implicit-midpoint steps (``on``) or the method's own again
        (module docstring, "One-step steps around a jump"); nothing for a one-step method.
        The residual's coefficients change: a Jacobian kept from before is stale (the caller
        asks its solver for a new one)."""

    def restart(self, problem, lu_package: str) -> None:
        """Before the first step after midpoint steps: history derived anew from the state in
        U alone (``problem``, ``lu_package``: :meth:`start`); nothing for most integrators."""

    def step(self, h: float, solve: Callable[[], int]) -> int:
        """Advance U from ``self.time`` to ``self.time + h``; the Newton iterations used.

        ``solve`` solves the residual form for U from the current U (the predictor). One-stage
        schemes call it once; Runge–Kutta schemes once per stage.
        """
        self.prepare(h)
        return solve()

    def accept(self, h: float) -> None:
        """Update the history after a converged step of size h."""
        self.time += h
        self.steps_taken += 1

    def reject(self) -> None:
        """Undo a step that is not accepted: U back to the last accepted state (the history
        is only updated by :meth:`accept`)."""
        self.space.values(self.U)[:] = self.last_accepted()

    def last_accepted(self) -> np.ndarray:
        """The state array at ``self.time``."""
        raise NotImplementedError

    def change_variables(self, state_map: StateMap, rate_map: RateMap) -> None:
        """Between steps, the unknowns change to new variables of the same motion (a new
        chart): ``state_map(U)`` gives a state array in the new variables, ``rate_map(U, U̇)``
        the rate U̇ at the old state U in them. U and every stored state and rate are mapped;
        history whose states are not stored is dropped (a predictor then starts afresh), which
        keeps the method's order (docs/decisions.md, "Charts")."""
        self.U.x.array[:] = state_map(self.U.x.array)

    def state_dict(self) -> dict:
        """Everything the next steps depend on besides U (arrays are this rank's, copies):
        with :meth:`load_state_dict` a restarted run continues bit for bit."""
        return {"time": self.time, "steps_taken": self.steps_taken}

    def load_state_dict(self, state: dict) -> None:
        """The inverse of :meth:`state_dict`; the coordinates of U from U (which the caller
        set) where the space is not U's own."""
        self.time = float(state["time"])
        self.steps_taken = int(state["steps_taken"])
        if self.space.reduced:
            self.space.values(self.U)[:] = self.space.from_full(self.U.x.array)

    def _copy(self, dst: fem.Function, src: fem.Function) -> None:
        dst.x.array[:] = src.x.array


class Static(Integrator):
    """Equilibrium: F(U, 0, τ) = 0. ``prepare`` only sets the load time."""

    name = "static"

    def residual_form(self) -> ufl.Form:
        return self._factory(self.U, ufl.zero(self.U.ufl_shape), self.time_eval)

    def prepare(self, h: float) -> None:
        self.time_eval.value = self.time + h
        self.unknown_time = self.time + h

    def use_space(self, space) -> None:
        """Only U, in ``space`` (before the first step)."""
        self.space = space
        space.values(self.U)


class BDF2(Integrator):
    """Variable-step BDF2 started by one implicit-midpoint step (module docstring)."""

    name = "bdf2"
    order = 2
    multistep = True

    def __init__(self, U, residual, time=0.0):
        super().__init__(U, residual, time)
        self._one_step = False  # midpoint steps (use_one_step)
        V = U.function_space
        self.U_n = fem.Function(V, name="U_n")
        self.U_nm1 = fem.Function(V, name="U_nm1")
        self._copy(self.U_n, U)
        self._copy(self.U_nm1, U)
        self.a0, self.a1, self.a2 = (_constant(U) for _ in range(3))
        self.mid = _constant(U, 1.0)  # 1 for the midpoint start, 0 for BDF2 steps
        self.h_prev: float | None = None
        #: the next BDF2 step is the first after midpoint steps (:meth:`restart`): its
        #: predictor is U_n, not the extrapolation
        self.after_midpoint = False
        self._arrays()

    def _arrays(self) -> None:
        """U's, U_n's and U_{n−1}'s arrays in ``self.space`` (module docstring, "The space")."""
        values = self.space.values
        self._u, self._un, self._unm1 = values(self.U), values(self.U_n), values(self.U_nm1)

    def use_space(self, space) -> None:
        """The steps on ``space``'s arrays (before the first step)."""
        if self.steps_taken:
            raise NotImplementedError("bdf2: a space is chosen before the first step")
        self.space = space
        self._arrays()

    def residual_form(self) -> ufl.Form:
        U, Un, Unm1 = self.U, self.U_n, self.U_nm1
        U_eval = U + self.mid * 0.5 * (Un - U)
        Udot = self.a0 * U + self.a1 * Un + self.a2 * Unm1
        return self._factory(U_eval, Udot, self.time_eval)

    def prepare(self, h: float) -> None:
        """First step (and every step after ``use_one_step(True)``): the implicit-midpoint step
        from U = U_n; later steps: the BDF2 coefficients for ω = h/h_prev and the linear
        predictor, except for the first step after midpoint steps (:meth:`restart`), which
        starts from U = U_n."""
        self.unknown_time = self.time + h
        if self.h_prev is None or self._one_step:  # implicit-midpoint start
            self.mid.value = 1.0
            self.a0.value, self.a1.value, self.a2.value = 1.0 / h, -1.0 / h, 0.0
            self.time_eval.value = self.time + 0.5 * h
            self._u[:] = self._un
            return
        w = h / self.h_prev
        self.mid.value = 0.0
        self.a0.value = (1.0 + 2.0 * w) / ((1.0 + w) * h)
        self.a1.value = -(1.0 + w) / h
        self.a2.value = w * w / ((1.0 + w) * h)
        self.time_eval.value = self.time + h
        if self.after_midpoint:
            self._u[:] = self._un
        else:  # Predictor: linear extrapolation through U_{n-1}, U_n.
            self._u[:] = (1.0 + w) * self._un - w * self._unm1

    def use_one_step(self, on: bool) -> None:
        """Midpoint steps from the next one on (``on``), or BDF2 again: its formula then reads
        U_{n−1}, U_n of the last midpoint step, both after the jump; its first step's
        predictor is U_n (:meth:`restart`)."""
        self._one_step = bool(on)

    def restart(self, problem, lu_package: str) -> None:
        """The first BDF2 step after midpoint steps starts Newton from U_n: U_{n−1} and U_n
        are midpoint states around impacts, whose velocity unknowns alternate (a pressed
        node's normal velocity flips each undamped midpoint step, v_n = −v_{n−1}), and the
        extrapolation (1 + ω) v_n − ω v_{n−1} would start Newton from (1 + 2ω) v_n
        (docs/decisions.md, "BDF2's first step after impacts"). The flag survives a
        rejected step (its retry starts from U_n too) and is cleared by the next accepted
        one."""
        self.after_midpoint = True

    def accept(self, h: float) -> None:
        self._unm1[:] = self._un
        self._un[:] = self._u
        self.h_prev = h
        self.after_midpoint = False
        super().accept(h)

    def last_accepted(self) -> np.ndarray:
        return self._un

    def change_variables(self, state_map: StateMap, rate_map: RateMap) -> None:
        """U, U_n and U_{n−1} mapped: the next step's BDF2 formula and predictor go on (a
        reduced space refuses: the new chart's variables are off its basis)."""
        self.space.refuse_chart()
        super().change_variables(state_map, rate_map)
        self.U_n.x.array[:] = state_map(self.U_n.x.array)
        self.U_nm1.x.array[:] = state_map(self.U_nm1.x.array)

    def state_dict(self) -> dict:
        """Adds U_n, U_{n−1}, h_prev (NaN before the first step, which is the midpoint start)
        and whether the next step is the first after midpoint steps (1.0 or 0.0)."""
        return {
            **super().state_dict(),
            "U_n": self.space.to_full(self._un),
            "U_nm1": self.space.to_full(self._unm1),
            "h_prev": np.nan if self.h_prev is None else self.h_prev,
            "after_midpoint": float(self.after_midpoint),
        }

    def load_state_dict(self, state: dict) -> None:
        """The inverse of :meth:`state_dict`."""
        super().load_state_dict(state)
        self._un[:] = self.space.from_full(state["U_n"])
        self._unm1[:] = self.space.from_full(state["U_nm1"])
        h_prev = float(state["h_prev"])
        self.h_prev = None if np.isnan(h_prev) else h_prev
        self.after_midpoint = bool(state.get("after_midpoint", 0.0))  # older checkpoints: False


def alpha_parameters(rho_inf: float) -> tuple[float, float, float]:
    """(αm, αf, γ) of Jansen, Whiting & Hulbert (2000) for spectral radius ρ∞ ∈ [0, 1]."""
    if not 0.0 <= rho_inf <= 1.0:
        raise ValueError(f"rho_inf must lie in [0, 1], got {rho_inf}")
    alpha_m = 0.5 * (3.0 - rho_inf) / (1.0 + rho_inf)
    alpha_f = 1.0 / (1.0 + rho_inf)
    return alpha_m, alpha_f, 0.5 + alpha_m - alpha_f


class GeneralizedAlpha(Integrator):
    """Generalized-α for first-order systems (module docstring)."""

    name = "generalized-alpha"
    order = 2

    def __init__(self, U, residual, time=0.0, rho_inf: float = 0.5):
        super().__init__(U, residual, time)
        self.rho_inf = rho_inf
        self.alpha_m, self.alpha_f, self.gamma = alpha_parameters(rho_inf)
        self.multistep = rho_inf < 1.0  # ρ∞ = 1 is the midpoint rule: one-step already
        # αm, αf in the forms: ½ for midpoint steps (use_one_step), γ follows in accept
        self._am, self._af = _constant(U, self.alpha_m), _constant(U, self.alpha_f)
        self._one_step = False
        self._alpha_now = self.alpha_f, self.gamma  # αf, γ of the steps (use_one_step)
        V = U.function_space
        self.U_n = fem.Function(V, name="U_n")
        self.Udot_n = fem.Function(V, name="Udot_n")
        self._copy(self.U_n, U)
        self.inv_gh = _constant(U, 1.0)
        self.h = _constant(U, 1.0)
        self._Udot_prev: np.ndarray | None = None
        self._h_prev = 1.0
        # U's, U_n's and U̇_n's arrays in the space (at first the Functions' own memory;
        # Function.x costs 1.2 μs a call).
        self._arrays = self._space_arrays()

    def _space_arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        values = self.space.values
        return values(self.U), values(self.U_n), values(self.Udot_n, rate=True)

    def use_space(self, space) -> None:
        """The steps on ``space``'s arrays (before the first step; U̇_n, a rate, as one)."""
        if self.steps_taken:
            raise NotImplementedError("generalized-alpha: a space is chosen before the first step")
        self.space = space
        self._arrays = self._space_arrays()

    def _rate_new(self):
        """U̇_{n+1} as a UFL expression of the unknown U = U_{n+1}."""
        return self.Udot_n + self.inv_gh * (self.U - self.U_n - self.h * self.Udot_n)

    def residual_form(self) -> ufl.Form:
        am, af = self._am, self._af
        U_eval = self.U_n + af * (self.U - self.U_n)
        Udot_eval = self.Udot_n + am * (self._rate_new() - self.Udot_n)
        return self._factory(U_eval, Udot_eval, self.time_eval)

    def initial_rate_problem(self) -> tuple[ufl.Form, ufl.Form, fem.Function]:
        """Forms (a, L) of the linear problem for a consistent U̇_0 (F is affine in U̇)."""
        V = self.U.function_space
        W = fem.Function(V, name="Udot0")
        F0 = self._factory(self.U_n, W, self.time_eval)
        dW = ufl.TrialFunction(V)
        a = ufl.derivative(F0, W, dW)
        L = -ufl.replace(F0, {W: ufl.zero(self.U.ufl_shape)})
        return a, L, W

    def set_initial_rate(self, rate: np.ndarray) -> None:
        """U̇_0 from a full rate array (in the space's coordinates)."""
        self._arrays[2][:] = self.space.from_full(rate, rate=True)

    def start(self, problem, lu_package: str) -> None:
        """U̇_0 consistent with U_0: F(U_0, U̇_0, τ_0) = 0, affine in U̇_0, is one linear solve
        (:meth:`initial_rate_problem`), with the supports' rates as U̇_0's prescribed values
        (``problem`` and ``lu_package``: :meth:`Integrator.start`).

        Assembled and solved through the API, not dolfinx's ``LinearProblem``: that sets three
        PETSc options per instance and never removes them, and PETSc 3.18 holds 512, so a
        process that runs ~170 scenes (the work-precision benchmark) would fail with error 55.
        """
        a, L, W = self.initial_rate_problem()
        a_form, L_form = fem.form(a), fem.form(L)
        problem.move_supports(self.time, rates=True)  # moving supports: U̇ = their rates
        problem.sync_loads(self.time_eval)  # loads given by data, at τ0
        ties = getattr(problem, "constraints", None)  # dofs tied by rows (nls/constraints.py)
        if ties is None:
            A = assemble_matrix(a_form, bcs=problem.bcs)
            A.assemble()
        else:
            A = ties.assemble_matrix(ties.create_matrix(a_form), a_form, problem.bcs)
        b = assemble_vector(L_form)
        apply_lifting(b, [a_form], bcs=[problem.bcs])
        b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        set_bc(b, problem.bcs)
        if ties is not None:  # the copies' rates equal their masters'
            ties.apply_vector(b.array_w, None)
        ksp = PETSc.KSP().create(self.U.function_space.mesh.comm)
        ksp.setType("preonly")
        ksp.getPC().setType("lu")
        ksp.getPC().setFactorSolverType(lu_package)
        contact = getattr(problem, "contact", None)  # rows of nls/contact.py, or None
        if contact is None:
            ksp.setOperators(A)
            ksp.solve(b, W.vector)
        else:
            self._rest_on_obstacles(contact, A, b, W, ksp)
        W.x.scatter_forward()
        problem.move_supports(self.time)
        self.set_initial_rate(W.x.array)
        for obj in (ksp, A, b):
            obj.destroy()

    def _rest_on_obstacles(self, contact, A: PETSc.Mat, b: PETSc.Vec, W, ksp) -> None:
        """U̇_0 with the nodes that rest on an obstacle held from accelerating into it and
        their friction (contact.hold_rates), those the obstacle would pull let go and the
        solve repeated (at most three times): without it the rate starts falling through the
        obstacle and sliding without friction, and the method's acceleration carries that
        start on (an oscillation of the contact force about the weight that ρ∞ damps, a
        slide 0.8 % too long)."""
        u = self.U.x.array
        comm = self.U.function_space.mesh.comm
        nodes = contact.touching(u)
        for _ in range(3):
            held, rhs = A.copy(), b.copy()
            contact.hold_rates(held, rhs.array_w, nodes, u)
            ksp.setOperators(held)
            ksp.solve(rhs, W.vector)
            residual = b.duplicate()
            A.mult(W.vector, residual)
            residual.axpy(-1.0, b)
            pulled = contact.normal_reactions(residual.array, nodes, u) < 0.0
            for obj in (held, rhs, residual):
                obj.destroy()
            if not comm.allreduce(bool(pulled.any()), op=MPI.LOR):
                return
            nodes = nodes[~pulled]

    def use_one_step(self, on: bool) -> None:
        """Midpoint steps from the next one on (``on``: αm = αf = γ = ½, where the rate
        recurrence drops out of the residual: U̇ = (U_{n+1} − U_n)/h at the midpoint), or the
        method's own parameters again; then :meth:`restart` makes the rate consistent."""
        self._one_step = bool(on) and self.multistep
        am, af, gamma = (0.5, 0.5, 0.5) if self._one_step else alpha_parameters(self.rho_inf)
        self._am.value, self._af.value = am, af
        self._alpha_now = af, gamma

    def restart(self, problem, lu_package: str) -> None:
        """The rate U̇_n made consistent with U_n anew (:meth:`start`'s solve at τ_n, the
        nodes resting on an obstacle held): the midpoint steps' rate recurrence, which their
        residual does not read, carries the jump's impulse; the predictor's previous rate is
        dropped. A contact that cannot hold its nodes' rates (``contact.holds_rates()``
        False) keeps the midpoint steps' rate instead."""
        contact = getattr(problem, "contact", None)
        if contact is None or contact.holds_rates():
            self.time_eval.value = self.time
            self.start(problem, lu_package)
        # else the contact cannot hold its nodes' rates (a rod pressed on itself): the
        # midpoint steps' own rate (U_{n+1} − U_n)/h is kept, as BDF2 keeps its states
        self._Udot_prev = None

    def prepare(self, h: float) -> None:
        """The Constants for a step of h from τ_n (evaluation at τ_n + αf h) and the second-order
        predictor of the comment below."""
        alpha_f, gamma = self._alpha_now
        self.unknown_time = self.time + h
        self.h.value = h
        self.inv_gh.value = 1.0 / (gamma * h)
        self.time_eval.value = self.time + alpha_f * h
        # Predictor: U_{n+1} = U_n + h U̇_n + ½ h² Ü_n, with Ü_n from the last two rates
        # (first step: U_n + h U̇_n). Second order, it saves about one Newton iteration a step.
        u, un, vn = self._arrays
        np.multiply(vn, h, out=u)
        u += un
        if self._Udot_prev is not None:
            u += (0.5 * h * h / self._h_prev) * (vn - self._Udot_prev)

    def accept(self, h: float) -> None:
        """U̇_{n+1} = U̇_n + (U_{n+1} − U_n − h U̇_n)/(γ h) and U_n = U_{n+1}; U̇_n and h are
        kept for the next predictor. A midpoint step (:meth:`use_one_step`) keeps its own
        rate (U_{n+1} − U_n)/h instead, which its residual read: the recurrence's
        2 (U_{n+1} − U_n)/h − U̇_n would carry a jump's impulse on, alternating, into the
        predictor (the residual of the next midpoint step does not read U̇_n)."""
        u, un, vn = self._arrays
        if self._Udot_prev is None:
            self._Udot_prev = vn.copy()
        else:
            self._Udot_prev[:] = vn
        self._h_prev = h
        if self._one_step:
            np.subtract(u, un, out=vn)
            vn *= 1.0 / h
        else:  # U̇_{n+1} = U̇_n + (U_{n+1} − U_n − h U̇_n)/(γ h)
            increment = u - un
            increment -= h * vn
            increment *= 1.0 / (self.gamma * h)
            vn += increment
        un[:] = u
        super().accept(h)

    def last_accepted(self) -> np.ndarray:
        return self._arrays[1]

    def change_variables(self, state_map: StateMap, rate_map: RateMap) -> None:
        """U, U_n and U̇_n (at U_n) mapped; the previous rate, whose state is not kept, is
        dropped: the next predictor is U_n + h U̇_n (a reduced space refuses)."""
        self.space.refuse_chart()
        u_n = self.U_n.x.array.copy()
        super().change_variables(state_map, rate_map)
        self.Udot_n.x.array[:] = rate_map(u_n, self.Udot_n.x.array)
        self.U_n.x.array[:] = state_map(u_n)
        self._Udot_prev = None

    def state_dict(self) -> dict:
        """Adds U_n, U̇_n and the previous rate (empty before the first step) with its step
        h_prev."""
        previous, space = self._Udot_prev, self.space
        return {
            **super().state_dict(),
            "U_n": space.to_full(self._arrays[1]),
            "Udot_n": space.to_full(self._arrays[2], rate=True),
            "Udot_prev": np.zeros(0) if previous is None else space.to_full(previous, rate=True),
            "h_prev": self._h_prev,
        }

    def load_state_dict(self, state: dict) -> None:
        """The inverse of :meth:`state_dict`."""
        super().load_state_dict(state)
        space = self.space
        self._arrays[1][:] = space.from_full(state["U_n"])
        self._arrays[2][:] = space.from_full(state["Udot_n"], rate=True)
        previous = np.asarray(state["Udot_prev"])
        self._Udot_prev = space.from_full(previous, rate=True).copy() if previous.size else None
        self._h_prev = float(state["h_prev"])


#: The most stages an SDIRK tableau may have (newton_loop.c CF_MAX_STAGES).
MAX_STAGES = 8


def _sdirk_tableau(order: int) -> tuple[float, np.ndarray, np.ndarray]:
    """(γ, A, b) of the A-stable SDIRK methods of the module docstring."""
    if order == 3:
        g = (3.0 + np.sqrt(3.0)) / 6.0
        return g, np.array([[g, 0.0], [1.0 - 2.0 * g, g]]), np.array([0.5, 0.5])
    if order == 4:
        g = 0.5 + np.cos(np.pi / 18.0) / np.sqrt(3.0)
        d = 1.0 / (6.0 * (2.0 * g - 1.0) ** 2)
        A = np.array([[g, 0.0, 0.0], [0.5 - g, g, 0.0], [2.0 * g, 1.0 - 4.0 * g, g]])
        return g, A, np.array([d, 1.0 - 2.0 * d, d])
    raise ValueError(f"no SDIRK method of order {order}")


class SDIRK(Integrator):
    """A-stable SDIRK of order 3 or 4 (module docstring).

    Predictor: each stage starts from U = Z_i + γ h K̃_i, where K̃_i extrapolates the last
    s stage rates (this step's and those of the accepted steps before it, at their own
    times) by a polynomial of degree s − 1 to the stage time τ_n + c_i h; its error is
    O(h^s), so a frozen Jacobian needs two to three iterations a stage. One degree lower
    than the rates allow: the stage rates of the stiff (axial, shear) components are not
    smooth, and a higher degree amplifies them (measured: docs/decisions.md, "The stage
    predictor"). Only accepted steps enter the stored rates, so a rejected step leaves
    nothing to undo but U.
    """

    def __init__(self, U, residual, time=0.0, order: int = 3):
        super().__init__(U, residual, time)
        self.order = order
        self.name = f"sdirk{order}"
        self.gamma, self.A, self.b = _sdirk_tableau(order)
        self.c = self.A.sum(axis=1)
        self.Z = fem.Function(U.function_space, name="Z")  # U_n + h Σ_{j<i} a_ij K_j
        self.inv_gh = _constant(U, 1.0)
        stages = len(self.b)
        if stages > MAX_STAGES:
            raise ValueError(f"an SDIRK tableau of {stages} stages; at most {MAX_STAGES}")
        self._taus = np.zeros(stages)  # the times of this step's stage rates
        self._times = np.zeros(stages)  # and of the stored ones
        self._stored = 0
        self._arrays()

    def _arrays(self) -> None:
        """The state arrays in ``self.space`` (module docstring, "The space"): U's and Z's
        values (``_u``, ``_z``), U_n, this step's stage rates K_i, and the last s stage rates
        of accepted steps, a ring buffer in the order computed (slot = count mod s); then
        the C kernels' struct pointing into them."""
        stages, size = len(self.b), self.space.size
        self._u = self.space.values(self.U)
        self._z = self.space.values(self.Z)
        self.U_n = self._u.copy()
        self.K = np.zeros((stages, size))
        self._rates = np.zeros((stages, size))
        self._kernels()

    def use_space(self, space) -> None:
        """The stages on ``space``'s arrays (before the first step): U_n from U's coordinates;
        the predictor's stored rates start empty."""
        if self.steps_taken or self._stored:
            raise NotImplementedError("sdirk: a space is chosen before the first step")
        self.space = space
        self._arrays()

    def _kernels(self) -> None:
        """The C kernels of the step's arithmetic (newton_loop.c ``cf_sdirk_*``) and the
        struct they share, which points into this integrator's arrays (kept in place: they are
        only ever assigned into)."""
        from cosserat_fem.nls.native_newton import core

        module = core(self.U.function_space.mesh.comm)  # collective
        ffi, self._lib = module.ffi, module.lib
        self._tableau = [
            np.ascontiguousarray(x, dtype=np.float64) for x in (self.A, self.b, self.c)
        ]
        self._guess = np.zeros(self.U_n.size)  # the predictor's scratch
        self._inv_gh_value = time_view(self.inv_gh)

        def pointer(array: np.ndarray):
            assert array.dtype == np.float64 and array.flags.c_contiguous
            return ffi.cast("double*", array.ctypes.data)

        sd = ffi.new("cf_sdirk*")
        sd.stages, sd.n, sd.gamma = len(self.b), self.U_n.size, float(self.gamma)
        sd.A, sd.b, sd.c = (pointer(x) for x in self._tableau)
        sd.u, sd.z, sd.u_n = pointer(self._u), pointer(self._z), pointer(self.U_n)
        sd.K, sd.taus = pointer(self.K), pointer(self._taus)
        sd.rates, sd.times = pointer(self._rates), pointer(self._times)
        sd.guess, sd.time_value = pointer(self._guess), pointer(time_view(self.time_eval))
        self._sd = sd

    def residual_form(self) -> ufl.Form:
        return self._factory(self.U, self.inv_gh * (self.U - self.Z), self.time_eval)

    def prepare(self, h: float) -> None:
        self._inv_gh_value[()] = 1.0 / (self.gamma * h)

    def predict(self, stage: int) -> None:
        """The initial guess of stage ``stage`` into U (after its Z_i and τ_i are set, before
        its solve): U = Z_i + γ h K̃_i, K̃_i the Lagrange extrapolation to τ_i of the newest s
        stage rates known before it (this step's and the accepted steps', at their own times;
        K̃_i = 0 with none). A stored rate whose time coincides with that of a newer one is left
        out (SDIRK4's first stage lies beyond its step, so after a step ratio of (γ − 1)/γ a
        stage time repeats exactly: the weights would divide by zero). The C kernel
        ``cf_sdirk_predict``, which :meth:`step` runs inside ``cf_sdirk_stage`` unless this
        method is overridden (in a subclass, on the class or on the instance): then
        :meth:`step` calls the override instead, at every stage."""
        self._lib.cf_sdirk_predict(self._sd, stage)

    def step(self, h: float, solve: Callable[[], int]) -> int:
        """The stages one after the other (module docstring): per stage ``cf_sdirk_stage``
        (K_{i−1} = (U − Z_{i−1})/(γ h) of the stage before; Z_i; τ_i; the guess of
        :meth:`predict`), then ``solve()``; after the last, ``cf_sdirk_stage`` makes its K
        and U = U_n + h Σ b_i K_i. Returns the Newton iterations of all stages. The same code
        serial and MPI: the kernels work elementwise on the local arrays, ghosts included."""
        self.prepare(h)
        lib, sd = self._lib, self._sd
        own_guess = type(self).predict is not _PREDICT or "predict" in self.__dict__
        sd.h, sd.time, sd.stored, sd.predict = h, self.time, self._stored, not own_guess
        iterations = 0
        for i in range(sd.stages):
            lib.cf_sdirk_stage(sd, i)
            self.unknown_time = sd.unknown_time
            if own_guess:
                self.predict(i)
            iterations += solve()
        lib.cf_sdirk_stage(sd, sd.stages)
        return iterations

    def accept(self, h: float) -> None:
        """U_n = U; this step's stage rates and their times go into the ring buffer of the
        predictor (``cf_sdirk_accept``)."""
        sd = self._sd
        sd.stored = self._stored
        self._lib.cf_sdirk_accept(sd)
        self._stored = sd.stored
        super().accept(h)

    def last_accepted(self) -> np.ndarray:
        return self.U_n

    def change_variables(self, state_map: StateMap, rate_map: RateMap) -> None:
        """U and U_n mapped; the predictor's stage rates, whose states are not kept, are
        dropped (the next step's first stage starts from U_n). A reduced space refuses (the
        new chart's variables are off its basis)."""
        self.space.refuse_chart()
        super().change_variables(state_map, rate_map)
        self.U_n[:] = state_map(self.U_n)
        self._stored = 0

    def state_dict(self) -> dict:
        """Adds U_n and the predictor's ring buffer: stage rates, their times, the count stored
        (full vectors in any space)."""
        return {
            **super().state_dict(),
            "U_n": self.space.to_full(self.U_n),
            "rates": self.space.to_full(self._rates, rate=True),
            "rate_times": self._times.copy(),
            "stored": self._stored,
        }

    def load_state_dict(self, state: dict) -> None:
        """The inverse of :meth:`state_dict`."""
        super().load_state_dict(state)
        self.U_n[:] = self.space.from_full(state["U_n"])
        rates, times, stored = state["rates"], state["rate_times"], int(state["stored"])
        size = len(self._times)
        if len(times) > size:  # a checkpoint of the predictor of degree s: its newest s rates
            newest = [(stored - size + j) % len(times) for j in range(size)]
            slots = [(stored - size + j) % size for j in range(size)]
            rates, times = rates[newest][np.argsort(slots)], times[newest][np.argsort(slots)]
        self._rates[:] = self.space.from_full(rates, rate=True)
        self._times[:] = times
        self._stored = stored


#: SDIRK's own predictor (the C kernel): a step compares an integrator's ``predict`` with it.
_PREDICT = SDIRK.predict

INTEGRATORS = ("bdf2", "generalized-alpha", "sdirk3", "sdirk4", "static")


def make_integrator(name: str, U, residual: ResidualFactory, time: float, rho_inf: float = 0.5):
    """The integrator ``name`` (one of INTEGRATORS) of ``U`` and ``residual``, starting at
    τ = ``time`` (τ = ω0 t, (47)); ``rho_inf``: generalized-α's ρ∞. ValueError for another
    name."""
    if name == "generalized-alpha":
        return GeneralizedAlpha(U, residual, time, rho_inf=rho_inf)
    if name in ("sdirk3", "sdirk4"):
        return SDIRK(U, residual, time, order=int(name[-1]))
    if name == "bdf2":
        return BDF2(U, residual, time)
    if name == "static":
        return Static(U, residual, time)
    raise ValueError(f"unknown integrator {name!r}; expected one of {list(INTEGRATORS)}")
