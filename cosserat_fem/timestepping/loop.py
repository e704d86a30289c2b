"""The time loop: steps of an integrator, checked, retried, and announced as events.

Time runs in τ = ω0 t (47) inside the integrator; the loop speaks seconds. Each attempted step
is one ``Integrator.step`` (one Newton solve per stage) followed by the state checks of
cosserat_fem/rod/checks.py (a finite state, a regular Euler-angle chart). A step that fails is
rejected and retried smaller:

* fixed steps (:meth:`TimeLoop.run_fixed`): halved, at most ``time.max_halvings`` times; the
  next nominal step is whole again; outputs at t_k = start + k time.step;
* adaptive steps (:meth:`TimeLoop.run_adaptive`): chosen by the local error estimate of
  cosserat_fem/timestepping/adaptive.py; outputs on the same grid by interpolation.

**Impacts.** With contact rows (cosserat_fem/nls/contact.py) and a ``multistep`` integrator
(BDF2, generalized-α at ρ∞ < 1: cosserat_fem/timestepping/integrators.py, "One-step steps
around a jump"), a step in which nodes come into contact is solved again by the implicit
midpoint rule, and so are the steps after it until two in a row leave the contact set as it
was (``ONE_STEP_AFTER``); then the method restarts (``Integrator.restart``). An impact makes
the velocity jump within a step: the midpoint rule changes the kinetic energy by the work of
the contact force exactly there (NodeContact.accept), while BDF2's last two states and
generalized-α's rate recurrence would carry the jump into the next steps, which then change
the energy by O(Δvᵀ M Δv) that no force did. Why two: a node that lands moving into the
obstacle has its normal velocity reversed by the next midpoint step (it stays, the velocity
flips) and leaves at the one after; with one, BDF2's history would span that flip. An
adaptive run forgets its error estimate's history at a landing (the states' kink), as at its
start. ``LoopState.redone`` counts the steps solved again.

Trouble that no smaller step can mend (a load that is not finite) or that persists stops the
loop with a SolverError or a SceneError naming the time, the place and the reason. The loop
knows nothing of files: probes, frames, checkpoints, progress and limits are observers of its
events (cosserat_fem/timestepping/events.py, cosserat_fem/analysis/observers.py).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, fields

import numpy as np

from cosserat_fem.common.errors import SceneError, SolverError
from cosserat_fem.common.log import LOGGER
from cosserat_fem.nls.newton import NewtonFailure, NewtonSolver
from cosserat_fem.rod.checks import StateCheck, cos_theta, worst_place
from cosserat_fem.rod.model import RodModel
from cosserat_fem.timestepping.adaptive import SHRINK, StateHistory, StepController
from cosserat_fem.timestepping.events import Events, Observer

#: The events before which a run in reduced coordinates lifts U (and the integrator's
#: Functions) in full, if an observer of it reads the state (TimeLoop._reads_state).
LIFTED = (
    "step_attempted",
    "solve_done",
    "step_rejected",
    "step_accepted",
    "output",
    "step_finished",
)

#: Rejections in a row after which an adaptive run stops.
MAX_CONSECUTIVE_REJECTIONS = 12

#: Midpoint steps in a row without a change of the contact set after which a multistep
#: integrator takes its own steps again (module docstring, "Impacts").
ONE_STEP_AFTER = 2


@dataclass
class LoopState:
    """Where a time loop is: ``t`` [s] of the last accepted state; counts of accepted and
    rejected steps and of output steps; the smallest and largest accepted step [s]; for
    fixed steps the halving level and the part of the nominal step done, for adaptive ones
    the next step size ``h`` [s] (NaN when not chosen); ``one_step`` the midpoint steps
    still to take after an impact, ``redone`` the steps solved again by the midpoint rule
    (module docstring, "Impacts")."""

    t: float
    accepted: int = 0
    rejected: int = 0
    outputs: int = 0
    smallest: float | None = None
    largest: float | None = None
    level: int = 0
    done: float = 0.0
    h: float = math.nan
    chart_resets: int = 0
    one_step: int = 0
    redone: int = 0

    _INTEGERS = ("accepted", "rejected", "outputs", "level", "chart_resets", "one_step", "redone")

    def state_dict(self) -> dict[str, float]:
        """Numbers only (None as NaN), for a checkpoint."""
        values = {f.name: getattr(self, f.name) for f in fields(self)}
        return {k: math.nan if v is None else v for k, v in values.items()}

    def load_state_dict(self, state: dict) -> None:
        """The inverse of :meth:`state_dict` (NaN back to None); keys not in ``state`` keep their
        values."""
        for f in fields(self):
            if f.name not in state:
                continue
            value = float(state[f.name])
            if f.name in self._INTEGERS:
                setattr(self, f.name, int(value))
            elif f.name in ("smallest", "largest"):
                setattr(self, f.name, None if math.isnan(value) else value)
            else:
                setattr(self, f.name, value)

    def counts(self) -> dict:
        """The counters as summary.json reports them."""
        return {
            "steps": self.outputs,
            "time_reached_s": self.t,
            "accepted_steps": self.accepted,
            "rejected_steps": self.rejected,
            "smallest_step_s": self.smallest,
            "largest_step_s": self.largest,
            "chart_resets": self.chart_resets,
            "impact_steps_redone": self.redone,
        }


def activate_chart(model: RodModel, integrator, solver: NewtonSolver) -> None:
    """The residual carries the model's chart from now on: its forms are compiled (once, the
    first time the chart moves; until then the paper's forms cost less)."""
    model.use_chart(active=True)
    solver.set_form(integrator.residual_form())


def watch_chart(
    model: RodModel,
    integrator,
    solver: NewtonSolver,
    history: StateHistory | None = None,
    cos: np.ndarray | None = None,
) -> float | None:
    """Between steps: if the chart nears its singularity at some node, |cos θ| < cos
    charts.RESET_THETA (θ within 0.67 rad of ±π/2), move it onto the rod's rotation
    (cosserat_fem/rod/charts.py), mapping the integrator's states and rates (and those of an
    adaptive ``history``) into it (Integrator.change_variables). ``cos``: cos θ at the owned
    nodes if known (checks.cos_theta). Returns the angle |θ| the test found (the one of the
    smallest |cos θ|) if the chart moved, else None. Collective."""
    if model.chart is None:
        return None
    largest = model.chart_move_due(cos_theta(model, model.U.x.array) if cos is None else cos)
    if largest is None:
        return None
    Q_new = model.new_chart()
    state_map, rate_map = model.chart_maps(Q_new)
    integrator.change_variables(state_map, rate_map)
    if history is not None:
        history.map_states(state_map)
    model.set_chart(Q_new)
    follow = getattr(solver, "follow_chart", None)  # a reduced run's basis per chart
    if follow is not None:
        follow(model, integrator)
    if model.chart_active:
        solver.request_jacobian()  # the matrix of the old chart's angles
    else:
        activate_chart(model, integrator, solver)
    return largest


class TimeLoop:
    """Integrates ``model`` over the span ``tspan`` (the scene's ``time``) with ``integrator``
    and ``solver``, announcing each step to ``events``.

    ``restart``: a checkpoint's parts (cosserat_fem/io/checkpoint.py) to continue from; the
    loop's own are :meth:`state_dict`. After :meth:`run` returns or raises, the model holds
    the last accepted state."""

    def __init__(
        self,
        model: RodModel,
        integrator,
        solver: NewtonSolver,
        tspan,
        events: Events,
        restart: dict | None = None,
    ):
        self.model, self.integrator, self.solver = model, integrator, solver
        self.tspan, self.events = tspan, events
        self.omega0 = model.omega0
        self.state = LoopState(t=integrator.time / self.omega0)
        self.restarted = restart is not None
        self.pending = False  # a step was attempted and neither accepted nor rejected
        self.end_reason: str | None = None  # set by request_end: the run ends early
        self.stepping_since: float | None = None
        self.stepping_until: float | None = None
        self.history: StateHistory | None = None
        self.control: StepController | None = None
        self._one_step = False  # the integrator takes midpoint steps (module docstring)
        self.landing = False  # the last accepted step brought nodes into contact
        if tspan.adaptive:
            self._adaptive_parts()
        if restart is not None:
            self.load_state_dict(restart)
        # The integrator's state in reduced coordinates (docs/rom.md §8): U's full values are
        # lifted only for what reads them (lift: outputs, checkpoints, observers, the end).
        self.space = integrator.space
        self._reduced = bool(self.space.reduced)
        self._check = self.space.state_check(model) if self._reduced else StateCheck(model)
        self._lifts = {hook: self._reads_state(hook) for hook in LIFTED}
        self._cos_accepted = self._check.cos_theta()  # the chart-crossing check
        self._cos_candidate = self._cos_accepted
        # Fixed supports: their Dirichlet values are not read again before each solve.
        solver.supports_move = bool(model.motions)
        self._watch_solves = events.listens("solve_done")
        if events.listens("newton_iteration"):
            solver.iteration_hook = lambda it, norms, reason: events.newton_iteration(
                self, it, norms, reason
            )

    # -- state ----------------------------------------------------------------------------
    def _reads_state(self, hook: str) -> bool:
        """Whether, in reduced coordinates, an observer of ``hook`` reads the full state: every
        one that does not say otherwise (``needs_full_state = False``: it reads none, or asks
        for it by :meth:`lift`)."""
        if not self._reduced:
            return False
        base = getattr(Observer, hook)
        return any(
            getattr(type(o), hook, base) is not base and getattr(o, "needs_full_state", True)
            for o in self.events.observers
        )

    def lift(self, rows: np.ndarray | None = None) -> None:
        """The model's U and the integrator's Functions (SDIRK's Z) written in full from the
        reduced coordinates (O(n m)), or U's entries ``rows`` only (int32; a probe's:
        observers.probe_rows); nothing in a full run, whose arrays are the values. For an
        observer with ``needs_full_state = False`` that reads them at some events only (a
        reduced run's error indicator at its sampled steps)."""
        if not self._reduced:
            return
        if rows is None:
            self.space.lift()
        else:
            space = self.space
            space.lift_rows(self.model.U.x.array, space.values(self.model.U), 1.0, rows)

    def _adaptive_parts(self) -> None:
        """For adaptive steps: the step controller (the error of p only) and the history of the
        last order + 2 accepted states (cosserat_fem/timestepping/adaptive.py)."""
        layout, order = self.model.layout, self.integrator.order
        n_owned = self.model.V.dofmap.index_map.size_local * layout.size
        # The error of p (the first entries of each block) is controlled, not that of the
        # rates q (cosserat_fem.timestepping.adaptive).
        self.control = StepController(
            self.tspan.rtol,
            self.tspan.atol,
            order,
            self.model.msh.comm,
            n_owned,
            block=layout.size,
            controlled=slice(0, layout.p_count),
            counted=6,  # the six fields of p, also when a planar model solves three of them
        )
        self.history = StateHistory(capacity=order + 2)

    def state_dict(self) -> dict[str, dict]:
        """Everything the remaining steps depend on, by part (cosserat_fem/io/checkpoint.py),
        and the parts of the observers that keep a state across a restart (their
        ``checkpoint_parts()``: {part: {key: array}}, read back by the observer itself from
        the checkpoint: a reduced run's error indicator, cosserat_fem/rom/indicator.py)."""
        model = self.model
        self.lift()
        parts = {
            "state": {"U": model.U.x.array.copy()},
            "integrator": self.integrator.state_dict(),
            "newton": self.solver.state_dict(),
            "loop": self.state.state_dict(),
        }
        if model.chart is not None:
            parts["chart"] = {
                "Q": model.chart.x.array.copy(),
                "active": float(model.chart_active),
                "moved": float(model.chart_moved),
            }
        if self.history is not None:
            assert self.control is not None, "set with the history (_adaptive_parts)"
            parts.update(history=self.history.state_dict(), control=self.control.state_dict())
        for observer in self.events.observers:  # an observer's own state (rom's indicator)
            kept = getattr(observer, "checkpoint_parts", None)
            if kept is not None:
                parts.update(kept())
        return parts

    def load_state_dict(self, parts: dict) -> None:
        """The inverse of :meth:`state_dict`: U, integrator, Newton solver, loop and, for
        adaptive steps, history and controller."""
        model = self.model
        model.U.x.array[:] = parts["state"]["U"]
        self.integrator.load_state_dict(parts["integrator"])
        chart = parts.get("chart")
        if chart is not None and model.chart is not None:
            model.chart.x.array[:] = chart["Q"]
            model.chart_moved = bool(chart["moved"])
            if chart["active"] and not model.chart_active:
                self._activate_chart()
        self.solver.load_state_dict(parts["newton"])
        self.state.load_state_dict(parts["loop"])
        if self.state.one_step:  # stopped among the midpoint steps after an impact
            self._use_one_step(True)
        if self.history is not None:
            assert self.control is not None, "set with the history (_adaptive_parts)"
            self.history.load_state_dict(parts["history"])
            self.control.load_state_dict(parts["control"])

    @property
    def completed(self) -> bool:
        """The span is done: its last output time reached, or an observer ended it early."""
        return self.state.outputs == self.tspan.n_steps or self.end_reason is not None

    def request_end(self, reason: str) -> None:
        """End the run after the current nominal step, as if its span ended there (an
        observer's call, e.g. once a forced response has settled: cosserat_fem/studies/response.py);
        ``reason`` goes to summary.json. Every rank must call it alike."""
        self.end_reason = reason

    # -- the chart of the angles ------------------------------------------------------------
    def _activate_chart(self) -> None:
        """The residual carries the chart from now on (a restart of a run whose chart moved)."""
        activate_chart(self.model, self.integrator, self.solver)

    def _watch_chart(self, t: float) -> None:
        """After an accepted step to t [s]: :func:`watch_chart`, and the chart-crossing check
        starts again from the new chart's angles."""
        model = self.model
        if self._reduced:
            if getattr(self._check, "quiet", False):
                return  # the bound (8.1) keeps every node away from the chart's limit
            self.lift()
        try:
            largest = watch_chart(
                model, self.integrator, self.solver, self.history, self._cos_accepted
            )
        except SolverError as exc:  # a reduced run's refusal of the move: say when
            if exc.time is None:
                exc.time = t
                exc.message = exc._compose()
                exc.args = (exc.message,)
            raise
        if largest is None:
            return
        self._cos_accepted = self._cos_candidate = self._check.cos_theta()
        self.state.chart_resets += 1
        LOGGER.info("t = %.6g s: chart moved onto the rod (|θ| reached %.3f rad)", t, largest)

    # -- one step ---------------------------------------------------------------------------
    def _solve(self) -> int:
        """One Newton solve, with moving supports at the time of the unknown: their values
        are put into the initial guess too (the Jacobian's rows and columns of held dofs are
        those of the identity; docs/decisions.md, "Dirichlet values in the guess")."""
        model = self.model
        if model.motions:
            model.support_dofs_to(model.U.x.array, self.integrator.unknown_time)
        if model.data is not None and model.data.bound:  # loads given by data, at the stage
            model.data.sync(self.integrator.time_eval)
        iterations = self.solver.solve()
        if self._watch_solves:
            if self._lifts["solve_done"]:
                self.space.lift()
            self.events.solve_done(self, iterations)
        return iterations

    def attempt(self, t_new: float) -> SolverError | None:
        """Take a step to t_new [s]; None if it converged and the state is fine, else the
        retryable SolverError (U is then left as the integrator made it: reject or accept).
        A step of a multistep integrator in which nodes came into contact is solved again by
        the midpoint rule (module docstring, "Impacts")."""
        if self._lifts["step_attempted"]:
            self.space.lift()
        self.events.step_attempted(self, t_new)
        self.pending = True
        cause = self._advance(t_new)
        if cause is None and self._landed():
            self.integrator.reject()
            self._use_one_step(True)
            self.state.redone += 1
            cause = self._advance(t_new)
        return cause

    def _use_one_step(self, on: bool) -> None:
        """The integrator's midpoint steps on, or off with its restart at the new state."""
        self._one_step = on
        self.integrator.use_one_step(on)
        if not on:
            self.integrator.restart(self.model, self.solver.lu_package)
        self.solver.request_jacobian()  # the residual's coefficients changed

    def _impacts(self):
        """The contact rows whose impacts take midpoint steps (module docstring, "Impacts"), or
        None: none, an integrator without history to spoil, a scene that asks for none
        (``time.impact_steps`` false), or rows that do not tell their transitions."""
        contact = getattr(self.solver, "contact", None)
        if contact is None or not self.integrator.multistep or not self.tspan.impact_steps:
            return None
        return contact if hasattr(contact, "transitions") else None

    def _landed(self) -> bool:
        """Whether the step just solved, by the integrator's own rule, brought nodes into
        contact (collective)."""
        contact = self._impacts()
        if contact is None or self._one_step:
            return False
        return contact.transitions()[0] > 0

    def _advance(self, t_new: float) -> SolverError | None:
        """One try of the step to t_new [s] (:meth:`attempt`)."""
        try:
            self.integrator.step((t_new - self.state.t) * self.omega0, self._solve)
            # A method whose new state is not its last stage (SDIRK3/4) meets a moving
            # support's values only to its order: put them in exactly.
            if self.model.motions:
                self.model.support_dofs_to(self.model.U.x.array, t_new * self.omega0)
            self._cos_candidate = self._check(t_new, before=self._cos_accepted)
            contact = getattr(self.solver, "contact", None)
            changes = None if contact is None else contact.step_changes()
            if changes is not None:  # an impact front crossing too many nodes at once
                where, reason = changes
                return SolverError(time=t_new, where=where, reason=reason, retry=True)
        except NewtonFailure as exc:
            self._blame_loads(t_new)
            blocks = self.model.layout.size
            residual = np.abs(self.solver.b.array.reshape(-1, blocks)).max(axis=1)
            s, _ = worst_place(self.model, residual)
            reason = f"Newton did not converge ({exc.reason}, {exc.iterations} iterations)"
            suggestion = "reduce time.step, or use solver.jacobian = 'full'"
            contact = getattr(self.solver, "contact", None)
            unsettled = "" if contact is None else contact.unsettled()
            if unsettled:
                reason += f": {unsettled}"
                suggestion = "reduce time.step (an impact or a slip front crossing many nodes)"
            elif contact is not None:  # its Jacobian is full already
                suggestion = "reduce time.step"
            if exc.reason == "DIVERGED_FNORM_NAN" and exc.iterations == 0:
                # Not finite before any iteration: the loads and the state are finite (checked
                # above), so their products with the groups (48) leave double precision.
                reason += ": the residual is not finite at the start of the step"
                suggestion = "check the magnitude of the loads"
            return SolverError(
                time=t_new,
                where=f"s = {s:.4g} m (largest residual)",
                reason=reason,
                suggestion=suggestion,
                retry=True,
            )
        except SolverError as exc:
            if not exc.retry:
                raise
            self._blame_loads(t_new)
            return exc
        return None

    def _blame_loads(self, t_new: float) -> None:
        """A SceneError naming the load that is not finite during the step to t_new [s], if
        one is: then no smaller step can help (collective)."""
        t, stage = self.state.t, self.integrator.unknown_time / self.omega0
        problem = self.model.nonfinite_load([t, 0.5 * (t + t_new), stage, t_new])
        if problem:
            raise SceneError(f"{problem}: the load is not finite there")

    def accept(self, t_new: float) -> None:
        """Keep the step to t_new [s]: the integrator's history, the counters and the smallest
        and largest step [s]; then the step_accepted event."""
        st = self.state
        h = t_new - st.t
        self.integrator.accept(h * self.omega0)
        impacts = self._impacts()
        came, left = (0, 0) if impacts is None else impacts.transitions()
        contact = getattr(self.solver, "contact", None)
        if contact is not None:  # the friction's history: the accepted state (nls/contact.py)
            contact.accept(self.model.U.x.array)
        self.landing = came > 0
        if self._one_step:  # the midpoint steps of an impact
            st.one_step = ONE_STEP_AFTER if came or left else st.one_step - 1
            if st.one_step <= 0:
                st.one_step = 0
                self._use_one_step(False)
        self.pending = False
        self._cos_accepted = self._cos_candidate
        st.t = t_new
        st.accepted += 1
        st.smallest = h if st.smallest is None else min(st.smallest, h)
        st.largest = h if st.largest is None else max(st.largest, h)
        self._watch_chart(t_new)
        if self._lifts["step_accepted"]:
            self.space.lift()
        self.events.step_accepted(self)

    def reject(self, cause: SolverError | None) -> None:
        self.integrator.reject()
        self.pending = False
        self.state.rejected += 1
        if self._lifts["step_rejected"]:
            self.space.lift()
        self.events.step_rejected(self, cause)

    def back_to_accepted(self) -> None:
        """U back to the last accepted state if a step is pending (a run that stops)."""
        if self.pending:
            self.integrator.reject()
            self.pending = False
        self.lift()

    def _output(self, k: int, t: float, state: np.ndarray | None = None) -> None:
        """The output event of t_k; ``state``, when given, is the (interpolated) state at
        t_k, put into the model's U while the observers run."""
        if self._lifts["output"]:
            self.space.lift()
        u = self.model.U.x.array
        kept = None
        if state is not None:
            kept = u.copy()
            u[:] = state
        try:
            self.events.output(self, k, t)
        finally:
            if kept is not None:
                u[:] = kept

    # -- the loops --------------------------------------------------------------------------
    def run(self) -> None:
        """The steps from the state's time to the span's end (see the module docstring).
        ``stepping_since``, ``stepping_until``: the time.perf_counter() values when the first
        step began and the last one ended."""
        self._watch_chart(self.state.t)  # an initial state may be near the singularity
        self.events.started(self)
        self.stepping_since = time.perf_counter()
        try:
            if self.tspan.adaptive:
                self.run_adaptive()
            else:
                self.run_fixed()
        finally:
            self.stepping_until = time.perf_counter()
            self.lift()

    def run_fixed(self) -> None:
        """Steps of time.step; a failed step is retried with half of it, at most
        time.max_halvings times, and the next nominal step is full again. The state holds
        the halving level and the part of the nominal step done."""
        tspan, st, solver = self.tspan, self.state, self.solver
        halvings = tspan.max_halvings
        whole = 2**halvings  # a nominal step in units of the smallest allowed sub-step
        # Halving level; progress into the nominal step, in those units.
        level = min(int(st.level), halvings)
        done = float(st.done) * whole
        if done != int(done):
            raise SceneError(
                f"time.max_halvings: the checkpoint stopped {done / whole:g} into a step, "
                f"which steps of 2^-{halvings} cannot reach; use at least the first run's value"
            )
        done = int(done)
        while st.outputs < tspan.n_steps and self.end_reason is None:
            st.level, st.done = level, done / whole
            units = whole >> level
            t_new = tspan.start + (st.outputs + (done + units) / whole) * tspan.step
            cause = self.attempt(t_new)
            if cause is not None:
                self.reject(cause)
                LOGGER.info(
                    "step to t = %.6g s rejected (%s), level %d", t_new, cause.reason, level
                )
                if level >= halvings:
                    raise SolverError(
                        time=cause.time,
                        where=cause.where,
                        reason=f"{cause.reason}; the step was rejected {level} times, down to "
                        f"{tspan.step / 2**level:.3g} s (time.max_halvings = {halvings})",
                        suggestion=cause.suggestion,
                    )
                level += 1
                solver.request_jacobian()  # the Jacobian depends on the step size
                continue
            self.accept(t_new)
            done += units
            if done < whole:
                continue
            st.outputs, done = st.outputs + 1, 0
            if level:
                level = 0
                solver.request_jacobian()
            self._output(st.outputs, st.t)
            st.level, st.done = 0, 0.0
            if self._lifts["step_finished"]:
                self.space.lift()
            self.events.step_finished(self)

    def run_adaptive(self) -> None:
        """Steps chosen by the local error estimate (cosserat_fem/timestepping/adaptive.py); outputs
        on
        the grid start + k time.step by interpolation."""
        tspan, st, solver, model = self.tspan, self.state, self.solver, self.model
        history, control = self.history, self.control
        assert history is not None and control is not None, "set for adaptive steps (__init__)"
        order = self.integrator.order
        span = tspan.end - tspan.start
        h_max = tspan.max_step or span
        h_min = 1e-12 * span
        if self.restarted:
            h = float(st.h)
        else:
            history.push(st.t, model.U.x.array)
            h = min(tspan.step, h_max)
        consecutive = 0
        while st.t < tspan.end - 1e-12 * span and self.end_reason is None:
            st.h = h
            h = min(h, tspan.end - st.t)
            t_new = st.t + h
            cause = self.attempt(t_new)
            error = None
            if cause is None and len(history) == order + 2:
                u = model.U.x.array
                error = control.error_norm(u - history.polynomial(t_new, order + 2), u)
            if cause is not None or (error is not None and error > 1.0):
                self.reject(cause)
                LOGGER.info(
                    "step to t = %.6g s rejected: %s",
                    t_new,
                    cause.reason if cause else f"error estimate {error:.3g} > 1",
                )
                control.reject()
                consecutive += 1
                # (error is None exactly when a cause rejected the step)
                h *= control.factor(error, rejected=True) if error is not None else SHRINK
                if consecutive > MAX_CONSECUTIVE_REJECTIONS or h < h_min:
                    reason = cause.reason if cause else f"local error estimate {error:.3g} > 1"
                    raise SolverError(
                        time=t_new,
                        where=cause.where if cause else None,
                        reason=f"{reason}; {consecutive} steps rejected in a row, the last "
                        f"{h:.3g} s (time.rtol = {tspan.rtol:g})",
                        suggestion=cause.suggestion if cause else "loosen time.rtol/time.atol",
                    )
                solver.request_jacobian()  # the Jacobian depends on the step size
                st.h = h
                continue
            consecutive = 0
            self.accept(t_new)
            if self.landing:  # the states' kink: the estimate starts again (module docstring)
                history.load_state_dict({"times": [t_new], "states": [model.U.x.array]})
            else:
                history.push(t_new, model.U.x.array)
            control.accept(model.U.x.array)
            while st.outputs < tspan.n_steps:
                t_k = tspan.start + (st.outputs + 1) * tspan.step
                if t_k > t_new + 1e-9 * tspan.step:
                    break
                st.outputs += 1
                exact = abs(t_k - t_new) <= 1e-9 * tspan.step
                self._output(st.outputs, t_k, None if exact else history.polynomial(t_k, 4))
            if error is not None:
                h_next = min(h * control.factor(error), h_max)
                if h_next != h:
                    # A new Jacobian for the new step: one kept across a change of ±25 % made
                    # modified Newton contract 4x per iteration only, and the frozen policy
                    # then refreshed it anyway (measured: fewer iterations, the same run time).
                    solver.request_jacobian()
                h = h_next
            st.h = h
            self.events.step_finished(self)
