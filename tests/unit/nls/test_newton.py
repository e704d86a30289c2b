"""Unit tests of Newton's stop rule, ``cf_test`` (cosserat_fem/nls/newton_loop.c), the one rule
every solve runs (cf_solve's, and SNES's convergence test), reached from Python through
cosserat_fem.nls.newton.NewtonSolver._converged.

The rule (module docstring of cosserat_fem/nls/newton.py), with norms = (‖U‖, ‖δU_k‖, ‖F(U_k)‖):
stop when ‖F‖ ≤ atol, or ‖F‖ ≤ rtol ‖F(U_0)‖, or ‖δU_k‖ ≤ stol ‖U‖ + xatol (the update
test); with a reused Jacobian (lagged, frozen) also, from the second iteration on, when
η_k ‖δU_k‖ ≤ stol ‖U‖ + xatol, η = ρ/(1 − ρ), ρ the larger of ‖δU_k‖/‖δU_{k−1}‖ and
‖F_k‖/‖F_{k−1}‖ (ρ < 1 only).

``_converged(it, norms)`` reads only the solver's settings and its own running norms (‖F_0‖,
‖F_{k−1}‖, ‖δU_{k−1}‖), so the constructed sequences are fed to it directly, on a real
NewtonSolver (the smallest one: two DG0 unknowns on one cell, F = U∘U − g). Two real solves
then check that the Newton loop hands it the norms in the documented order and that a frozen-
Jacobian solve stops where the documented rule, written out independently here, says it must.
"""

from __future__ import annotations

import dataclasses
import math
import types

import numpy as np
import pytest
import ufl
from conftest import jit_installed
from dolfinx import fem, mesh
from mpi4py import MPI
from petsc4py import PETSc

from cosserat_fem.nls.newton import NewtonSettings, NewtonSolver

pytestmark = pytest.mark.unit

R = PETSc.SNES.ConvergedReason
ITERATING, ABS, REL, STEP = (
    R.ITERATING,
    R.CONVERGED_FNORM_ABS,
    R.CONVERGED_FNORM_RELATIVE,
    R.CONVERGED_SNORM_RELATIVE,
)
NAN, MAX_IT = R.DIVERGED_FNORM_NAN, R.DIVERGED_MAX_IT
DEFAULT = NewtonSettings()
TOL = DEFAULT.stol * 1.0 + DEFAULT.xatol  # the step tolerance at ‖U‖ = 1 (1e-8 + 1e-13)


@pytest.fixture(scope="module", autouse=True)
def _quiet_safe_jit():
    with jit_installed():  # the project's crash-safe, quiet compiles (tests/conftest.py)
        yield


class Squares:
    """F(U) = U∘U − g on two DG0 unknowns of a one-cell mesh (rows exactly U_i² − g_i)."""

    def __init__(self, settings: NewtonSettings, g=(4.0, 9.0)):
        msh = mesh.create_unit_interval(MPI.COMM_SELF, 1)
        V = fem.VectorFunctionSpace(msh, ("DG", 0), dim=2)
        self.U = fem.Function(V)
        self.g = fem.Constant(msh, PETSc.ScalarType(g))
        F = ufl.inner(ufl.elem_mult(self.U, self.U) - self.g, ufl.TestFunction(V)) * ufl.dx
        self.solver = NewtonSolver(F, self.U, [], settings)


@pytest.fixture(scope="module")
def problem():
    """The solver whose rule (``cf_test``, through ``_converged``) the sequences are fed to."""
    squares = Squares(NewtonSettings())
    yield squares
    squares.solver.destroy()


def feed(problem: Squares, settings: NewtonSettings, norms) -> tuple[int, int]:
    """(iteration, reason) at which ``problem``'s rule stops on the sequence ``norms`` of
    (‖U‖, ‖δU‖, ‖F‖), iteration 0 first; (len, ITERATING) if it never stops."""
    solver = problem.solver
    test = solver._converged
    solver.settings = settings
    for it, triple in enumerate(norms):
        reason = test(it, triple)
        if reason != ITERATING:
            return it, reason
    return len(norms), ITERATING


def frozen(**changes) -> NewtonSettings:
    return dataclasses.replace(DEFAULT, jacobian="frozen", **changes)


def full(**changes) -> NewtonSettings:
    return dataclasses.replace(DEFAULT, jacobian="full", **changes)


# ---------------------------------------------------------------------- constructed sequences
def test_quadratic_sequence_stops_by_the_update_test(problem):
    """Full Newton, ‖U‖ = 1, updates 1e-1, 1e-2, 1e-4, 1e-8 (quadratic), residuals falling to
    a round-off floor of 1e-6 (badly scaled rows: above rtol ‖F_0‖ = 1e-7 and atol): only the
    update test can stop it, at iteration 4 where ‖δU‖ = 1e-8 ≤ 1e-8 + 1e-13. The same sequence
    with the last update 1.1e-8 does not stop."""
    norms = [
        (1.0, 0.0, 1e3),
        (1.0, 1e-1, 1e-2),
        (1.0, 1e-2, 1e-4),
        (1.0, 1e-4, 1e-6),
        (1.0, 1e-8, 1e-6),
    ]
    assert feed(problem, full(), norms) == (4, STEP)
    norms[-1] = (1.0, 1.1e-8, 1e-6)
    assert feed(problem, full(), norms) == (5, ITERATING)


def test_update_test_boundary(problem):
    """‖δU‖ exactly stol ‖U‖ + xatol stops (≤), the next double above it does not; at
    ‖U‖ = 3 the tolerance is 3e-8 + 1e-13 (relative part scales with ‖U‖)."""
    st = full()
    for x in (1.0, 3.0):
        tol = st.stol * x + st.xatol
        start = (x, 0.0, 1.0)
        assert feed(problem, st, [start, (x, tol, 0.5)]) == (1, STEP)
        above = np.nextafter(tol, np.inf)
        assert feed(problem, st, [start, (x, above, 0.5)]) == (2, ITERATING)


def test_linear_sequence_stops_by_the_error_estimate(problem):
    """A reused Jacobian, contraction ρ = 0.1 in both updates and residuals, updates 5e-4,
    5e-5, ..., 5e-8: the error estimate ρ/(1 − ρ) ‖δU‖ = 5.6e-9 ≤ 1e-8 stops it at iteration 5
    (‖δU_5‖ = 5e-8 itself is 5x too large for the update test, which full Newton waits for:
    iteration 6, 5e-9)."""
    updates = [5e-4 * 0.1**k for k in range(6)]
    residuals = [1e2 * 0.1**k for k in range(6)]
    norms = [(1.0, 0.0, 1e3)] + [(1.0, y, f) for y, f in zip(updates, residuals, strict=True)]
    assert feed(problem, frozen(), norms) == (5, STEP)
    lagged = dataclasses.replace(DEFAULT, jacobian="lagged")
    assert feed(problem, lagged, norms) == (5, STEP)
    assert feed(problem, full(), norms) == (6, STEP)


def test_estimate_needs_a_second_iteration(problem):
    """ρ_1 is not guessed: at iteration 1 only the update test applies, even with a reused
    Jacobian and even right after a solve whose last updates were tiny (the running norms of
    the previous solve must not stand in for ρ_1). ‖δU_1‖ = 2 tol: not stopped."""
    previous = [(1.0, 0.0, 1.0), (1.0, 1e-3, 1e-2), (1.0, 1e-9, 1e-8)]
    assert feed(problem, frozen(), previous) == (2, STEP)
    norms = [(1.0, 0.0, 1.0), (1.0, 2 * TOL, 1e-3)]
    assert feed(problem, frozen(), norms) == (2, ITERATING)


@pytest.mark.parametrize(
    ("updates", "residuals", "stop"),
    [
        # Update ratio 8e-5 (the update ratio alone: η‖δU‖ = 6.4e-4 tol, a stop), residual
        # ratio 0.2: η = 0.25, η‖δU_2‖ = 2 tol, not stopped; at 3, ρ = 0.2, 0.4 tol: stopped.
        ((1e-3, 8 * TOL, 1.6 * TOL), (1.0, 0.2, 0.04), 3),
        # The mirror: residual ratio 1e-6, update ratio 0.5: η = 1, ‖δU_2‖ = 1.5 tol, not
        # stopped; at 3, ‖δU_3‖ = 0.75 tol passes the update test itself (the residuals stay
        # above rtol ‖F_0‖ = 1e-7).
        ((3 * TOL, 1.5 * TOL, 0.75 * TOL), (1e2, 1e-4, 5e-5), 3),
    ],
    ids=["residual-ratio-0.2", "update-ratio-0.5"],
)
def test_contraction_is_the_larger_ratio(problem, updates, residuals, stop):
    """ρ is the larger of the update and residual ratios (module docstring: the update ratio
    alone read 1.5e-4 where the residual fell by 0.2 an iteration, and let the energy drift)."""
    norms = [(1.0, 0.0, 1e3)] + [(1.0, y, f) for y, f in zip(updates, residuals, strict=True)]
    assert feed(problem, frozen(), norms) == (stop, STEP)
    # Not earlier: the sequence cut after iteration 2 keeps iterating.
    assert feed(problem, frozen(), norms[:3]) == (3, ITERATING)


def test_no_estimate_when_not_contracting(problem):
    """ρ ≥ 1 (the updates grow by 1.5): η = ρ/(1 − ρ) would be negative and "stop" any
    sequence; the rule requires ρ < 1, so only the update test can end it."""
    norms = [(1.0, 0.0, 1.0), (1.0, 2 * TOL, 0.5), (1.0, 3 * TOL, 0.4), (1.0, 4.5 * TOL, 0.3)]
    assert feed(problem, frozen(), norms) == (4, ITERATING)


def test_absolute_and_relative_residual_tests(problem):
    """atol at iteration 0 (the initial guess solves it: no iteration at all) and later
    (whatever the update); rtol relative to ‖F_0‖ of this solve; just above either: not."""
    st = full()
    assert feed(problem, st, [(1.0, 0.0, st.atol)]) == (0, ABS)
    assert feed(problem, st, [(1.0, 0.0, 2 * st.atol)]) == (1, ITERATING)
    assert feed(problem, st, [(1.0, 0.0, 1.0), (1.0, 0.5, st.atol)]) == (1, ABS)
    f0 = 1e3  # rtol ‖F_0‖ = 1e-7
    assert feed(problem, st, [(1.0, 0.0, f0), (1.0, 0.5, 1e-7)]) == (1, REL)
    assert feed(problem, st, [(1.0, 0.0, f0), (1.0, 0.5, 1.01e-7)]) == (2, ITERATING)
    # A new solve starts from its own ‖F_0‖ (1e-3 now): 1e-7 is no longer small enough.
    assert feed(problem, st, [(1.0, 0.0, 1e-3), (1.0, 0.5, 1e-7)]) == (2, ITERATING)


def test_absolute_update_part_for_tiny_states(problem):
    """xatol: at ‖U‖ = 0 an update of xatol stops, 2 xatol does not; at ‖U‖ = 1.6e-8 (the
    module docstring's thin rod) an update at the round-off floor, 3e-16, is 2e-8 of ‖U‖ and
    would never meet stol ‖U‖ = 1.6e-16: with xatol = 0 the solve runs to max_iterations."""
    st = full()
    assert feed(problem, st, [(0.0, 0.0, 1.0), (0.0, st.xatol, 0.5)]) == (1, STEP)
    assert feed(problem, st, [(0.0, 0.0, 1.0), (0.0, 2 * st.xatol, 0.5)]) == (2, ITERATING)
    stall = [(1.6e-8, 0.0, 1.0)] + [(1.6e-8, 3e-16, 1e-9)] * st.max_iterations
    assert feed(problem, st, stall) == (1, STEP)
    assert feed(problem, full(xatol=0.0), stall) == (st.max_iterations, MAX_IT)


def test_nan_and_iteration_limit(problem):
    """A NaN norm (‖F‖ or ‖δU‖) is DIVERGED_FNORM_NAN at once, at iteration 0 too; at
    max_iterations the solve is DIVERGED_MAX_IT, one before it still iterates."""
    nan = math.nan
    assert feed(problem, full(), [(1.0, 0.0, nan)]) == (0, NAN)
    assert feed(problem, full(), [(1.0, 0.0, 1.0), (1.0, nan, 0.5)]) == (1, NAN)
    assert feed(problem, frozen(), [(1.0, 0.0, 1.0), (1.0, 0.1, nan)]) == (1, NAN)
    slow = [(1.0, 0.0, 1.0)] + [(1.0, 0.5, 0.9)] * 5
    assert feed(problem, full(max_iterations=5), slow) == (5, MAX_IT)
    assert feed(problem, full(max_iterations=6), slow) == (6, ITERATING)


# --------------------------------------------------------------------------- real solves
def documented_rule(norms, st: NewtonSettings) -> int:
    """The iteration at which the module docstring's rule stops, written out from it."""
    f0 = norms[0][2]
    if f0 <= st.atol:
        return 0
    for k in range(1, len(norms)):
        x, y, f = norms[k]
        tol = st.stol * x + st.xatol
        if f <= st.atol or f <= st.rtol * f0 or y <= tol:
            return k
        if k >= 2 and st.jacobian != "full":
            rho = max(y / norms[k - 1][1], f / norms[k - 1][2])
            if rho < 1 and rho / (1 - rho) * y <= tol:
                return k
    return -1


def recorded_solve(problem: Squares, start) -> list[tuple[int, tuple, np.ndarray, int]]:
    """Solve from ``start``, recording (it, norms, iterate, reason) of every call of the rule
    (through the solver's iteration hook; Newton calls the rule after evaluating F at the new
    iterate, which U then holds)."""
    solver, calls = problem.solver, []

    def recording(it, norms, reason):
        calls.append((it, tuple(norms), problem.U.x.array.copy(), reason))

    solver.iteration_hook = recording
    try:
        problem.U.x.array[:] = start
        solver.solve()
    finally:
        solver.iteration_hook = None
    return calls


def test_newton_hands_the_norms_in_the_documented_order():
    """Full Newton on U² = (4, 9) from (1, 1): at iteration k ≥ 1 the norms are (‖U_k‖,
    ‖U_k − U_{k−1}‖, ‖U_k² − g‖) to round-off (1e-12 relative: norms of 2-vectors of O(1)
    entries, the update read as a difference of iterates); at iteration 0 the loop passes
    (0, 0, ‖F_0‖), as SNES did. Measured: updates 4.3, 1.7, 0.38, 2.3e-2, 9.2e-5, 1.4e-9
    (quadratic); the last iterate is the root (2, 3) to ε, with ‖F‖ = 0 (so atol, tested
    first, ends it)."""
    problem = Squares(NewtonSettings())
    try:
        calls = recorded_solve(problem, [1.0, 1.0])
    finally:
        problem.solver.destroy()
    g = np.array([4.0, 9.0])
    assert calls[0][0] == 0 and calls[0][1][2] == pytest.approx(np.linalg.norm(1.0 - g), rel=1e-14)
    for (it, (x, y, f), u, _), (_, _, u_before, _) in zip(calls[1:], calls[:-1], strict=True):
        assert it >= 1
        assert x == pytest.approx(np.linalg.norm(u), rel=1e-12)
        assert y == pytest.approx(np.linalg.norm(u - u_before), rel=1e-12, abs=1e-15)
        assert f == pytest.approx(np.linalg.norm(u * u - g), rel=1e-12, abs=1e-14)
    assert calls[-1][3] > 0 and all(c[3] == ITERATING for c in calls[:-1])
    assert documented_rule([c[1] for c in calls], NewtonSettings()) == calls[-1][0]
    np.testing.assert_allclose(problem.U.x.array, [2.0, 3.0], rtol=0, atol=4e-16 * 3)


def test_frozen_jacobian_solve_stops_by_the_estimate():
    """Modified Newton: the Jacobian of a first solve from (1.9, 2.9) (diag(3.8, 5.8)) is
    reused, so iterations contract linearly, towards ρ = max |1 − 2u*/J| = 0.0526 (1 − 4/3.8;
    the other unknown's 0.0345 fades; measured 0.023, 0.049, 0.050, 0.052); the
    solve must stop at the first iteration the documented rule allows, which is before the
    update test alone would (that is what the estimate is for), and the result must be within
    the estimated error η ‖δU‖ ≤ stol ‖U‖ + xatol of the root (checked with 2x margin: η
    bounds the remaining error only asymptotically)."""
    st = frozen()
    problem = Squares(st)
    try:
        calls = recorded_solve(problem, [1.9, 2.9])
    finally:
        problem.solver.destroy()
    norms = [c[1] for c in calls]
    stop = calls[-1][0]
    assert calls[-1][3] == STEP
    assert documented_rule(norms, st) == stop
    assert stop >= 2
    assert documented_rule(norms, full()) == -1  # the update test alone: not yet
    ratios = [norms[k][1] / norms[k - 1][1] for k in range(2, len(norms))]
    assert all(r < 0.06 for r in ratios) and abs(ratios[-1] - 0.2 / 3.8) < 0.005, ratios
    error = np.linalg.norm(problem.U.x.array - [2.0, 3.0])
    assert error <= 2 * (st.stol * np.linalg.norm([2.0, 3.0]) + st.xatol)


# ------------------------------------------------------------------ exceptions in callbacks
class Boom(Exception):
    """Raised by a callback of cf_solve in the tests below."""


@pytest.mark.parametrize("where", ["residual", "hook"])
def test_a_callbacks_exception_comes_out_of_the_solve(where):
    """An exception cannot cross C: cf_solve's callback (DOLFINx's residual, with
    ``solver.loop = "python"``, or an observer's hook) stores it and answers a status, C leaves
    the solve at once, and ``solve`` raises the very exception. Raised at the third call: the
    solve is then mid-way (after iteration 1), and what comes out is the exception, not a
    NewtonFailure or a PETSc error. The solver works again afterwards: the next solve from
    (1.9, 2.9) converges to the root (2, 3) within the update test's tolerance, stol ‖U‖ +
    xatol (its last update is that small, and full Newton's error after it smaller still)."""
    problem = Squares(dataclasses.replace(DEFAULT, loop="python"))
    solver, calls = problem.solver, {"n": 0}
    assert solver.loop == "python"

    def third(real):
        def call(*args):
            calls["n"] += 1
            if calls["n"] == 3:
                raise Boom(where)
            return real(*args)

        return call

    try:
        if where == "residual":
            solver._residual = third(solver._residual)
        else:
            solver.iteration_hook = third(lambda it, norms, reason: None)
        problem.U.x.array[:] = [1.0, 1.0]
        with pytest.raises(Boom, match=where):
            solver.solve()
        assert calls["n"] == 3
        problem.U.x.array[:] = [1.9, 2.9]
        assert solver.solve() > 0
        tolerance = DEFAULT.stol * math.sqrt(13.0) + DEFAULT.xatol
        np.testing.assert_allclose(problem.U.x.array, [2.0, 3.0], rtol=0, atol=tolerance)
    finally:
        solver.destroy()


def test_settings_are_frozen_and_a_replacement_reaches_c():
    """NewtonSettings is frozen: the C solve keeps its own copy (``cf_settings``), written when
    a solver's ``settings`` is set, so a field assigned in place would reach Python and not C
    (before: ``settings.max_iterations = 1`` changed what Python read and left C at 25).
    Assignment raises; settings derived with ``dataclasses.replace`` and given to the solver
    reach C's copy (its max_iterations, its policy flags)."""
    settings = NewtonSettings()
    with pytest.raises(dataclasses.FrozenInstanceError):
        settings.max_iterations = 1  # type: ignore[misc]
    problem = Squares(settings)
    try:
        solver = problem.solver
        solver.settings = dataclasses.replace(settings, max_iterations=3, jacobian="lagged")
        assert (solver._cs.max_iterations, solver._cs.lagged, solver._cs.full) == (3, 1, 0)
    finally:
        problem.solver.destroy()


def test_settings_of_a_table_own_their_petsc_options():
    """:meth:`NewtonSettings.of` copies the table's ``petsc`` dict: an option added to the
    table afterwards does not reach settings already made (before: the one dict was shared,
    so a frozen settings' options changed under it)."""
    table = types.SimpleNamespace(rtol=1e-9, petsc={"snes_type": "newtonls"})
    settings = NewtonSettings.of(table)
    table.petsc["snes_linesearch_type"] = "bt"
    assert settings.petsc == {"snes_type": "newtonls"} and settings.rtol == 1e-9


def test_an_active_set_that_changed_holds_the_solve(problem):
    """``hold`` (a contact's active set changed at this iterate, cosserat_fem/nls/contact.py):
    a sequence the rule stops at iteration 1 by the residual test goes on while it is set,
    and ends at the iteration limit (DIVERGED_MAX_IT) if it stays set; cleared, it stops."""
    state = problem.solver._state
    norms = [(1.0, 0.0, 1.0), (1.0, 1e-3, 1e-12)]
    try:
        state.hold = 1
        assert feed(problem, full(), norms) == (2, ITERATING)
        assert feed(problem, full(max_iterations=1), norms) == (1, MAX_IT)
        state.hold = 0
        assert feed(problem, full(), norms) == (1, ABS)
    finally:
        state.hold = 0


def test_the_guard_refuses_a_drift_the_update_test_would_take(problem):
    """``guard`` (set with contact): the update test stops a solve only if ‖F‖ ≤ ‖F_0‖. A
    mechanism's drift (U growing 1e6×, updates relatively small, ‖F‖ growing) stops by the
    update test without it, not with it; a residual at or below ‖F_0‖ still stops."""
    state = problem.solver._state
    drift = [(1.0, 0.0, 6.5), (1e24, 1e15, 7e27)]
    settled = [(1.0, 0.0, 6.5), (1.0, 1e-9, 6.5)]
    try:
        assert feed(problem, full(), drift) == (1, STEP)
        state.guard = 1
        assert feed(problem, full(), drift) == (2, ITERATING)
        assert feed(problem, full(), settled) == (1, STEP)
    finally:
        state.guard = 0
