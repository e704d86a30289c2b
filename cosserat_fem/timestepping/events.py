"""The events of a run, and the observers that act on them.

A time loop (cosserat_fem/timestepping/loop.py) or a load-stepping loop
(cosserat_fem/analysis/statics.py) is a source of events; everything else a run does besides
stepping is an observer of them: probes, XDMF frames, checkpoints, the progress bar, the wall-time
limit, in-memory records for the Python API, a benchmark's timers
(cosserat_fem/analysis/observers.py). An observer overrides the hooks it needs; the others cost
nothing (:class:`Events` calls only overridden hooks).

Hooks, in the order a step meets them (``loop`` is the source: its ``state`` (t, counters),
``model``, ``integrator``, ``solver``):

* ``started(loop)``: set up, before the first step (also of a restart: ``loop.restarted``);
* ``step_attempted(loop, t_new)``: a step (or load increment) to t_new is about to be taken;
* ``newton_iteration(loop, it, norms, reason)``: a Newton iteration's convergence test ran;
  ``norms`` = (‖U‖, ‖δU‖, ‖F‖), ``reason`` a PETSc SNES converged reason (0: iterating;
  cosserat_fem/nls/newton.py);
* ``solve_done(loop, iterations)``: a nonlinear solve (one stage) converged;
* ``step_rejected(loop, cause)``: the step failed (``cause``: the SolverError) or its error
  estimate was too large (``cause`` None); it will be retried smaller;
* ``step_accepted(loop)``: the new state is kept (``loop.state.t`` is its time);
* ``output(loop, k, t)``: output time t_k = start + k time.step [s] (the load factor in
  statics) reached; ``loop.model.U`` holds the state at t_k (interpolated for adaptive
  steps) while the observers run;
* ``step_finished(loop)``: a nominal step and its outputs are done and the loop's state is
  whole: a checkpoint taken now continues exactly;
* ``ended(loop, failure)``: the run ended (``failure`` None) or stopped (the exception);
  the state is the last accepted one. Observers close their files here.

An observer may raise a CosseratError (an output that cannot be written, a limit reached):
the run then stops as after a failure.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable
from typing import Any

HOOKS = (
    "started",
    "step_attempted",
    "newton_iteration",
    "solve_done",
    "step_rejected",
    "step_accepted",
    "output",
    "step_finished",
    "ended",
)


class Observer:
    """Base class: every hook does nothing (see the module docstring for when each runs)."""

    def started(self, loop) -> None:
        pass

    def step_attempted(self, loop, t_new: float) -> None:
        pass

    def newton_iteration(self, loop, it: int, norms: tuple[float, float, float], reason) -> None:
        pass

    def solve_done(self, loop, iterations: int) -> None:
        pass

    def step_rejected(self, loop, cause) -> None:
        pass

    def step_accepted(self, loop) -> None:
        pass

    def output(self, loop, k: int, t: float) -> None:
        pass

    def step_finished(self, loop) -> None:
        pass

    def ended(self, loop, failure: BaseException | None) -> None:
        pass


class OutputCallback(Observer):
    """An observer from a function ``f(k, t, model)`` called at every output time."""

    def __init__(self, function: Callable[[int, float, Any], None]):
        self.function = function

    def output(self, loop, k: int, t: float) -> None:
        self.function(k, t, loop.model)


def as_observer(item: Observer | Callable) -> Observer:
    """An Observer as given, or a function f(k, t, model) wrapped as one; SceneError naming
    ``observers`` for anything else (before the run: it failed at the first output time)."""
    if isinstance(item, Observer):
        return item
    if not callable(item):
        from cosserat_fem.common.errors import SceneError

        raise SceneError(
            "observers: each must be an Observer "
            "(cosserat_fem/timestepping/events.py) or a "
            f"function f(k, t, model), got {type(item).__name__}"
        )
    return OutputCallback(item)


class Events:
    """Calls the hooks of a list of observers, in their order; only hooks that an observer
    overrides are called. The wall time spent in ``output`` is summed (``output_time``)."""

    def __init__(self, observers: Iterable[Observer | Callable] = ()):
        self.observers = [as_observer(o) for o in observers]
        self._hooks = {name: self._bound(name) for name in HOOKS}
        self.output_time = 0.0

    def _bound(self, name: str) -> list[Callable]:
        """The bound ``name`` hooks of the observers that override it, in the observers' order."""
        base = getattr(Observer, name)
        return [
            getattr(o, name) for o in self.observers if getattr(type(o), name, base) is not base
        ]

    def listens(self, name: str) -> bool:
        """Whether any observer overrides hook ``name``."""
        return bool(self._hooks[name])

    def started(self, loop) -> None:
        for hook in self._hooks["started"]:
            hook(loop)

    def step_attempted(self, loop, t_new: float) -> None:
        for hook in self._hooks["step_attempted"]:
            hook(loop, t_new)

    def newton_iteration(self, loop, it: int, norms, reason) -> None:
        for hook in self._hooks["newton_iteration"]:
            hook(loop, it, norms, reason)

    def solve_done(self, loop, iterations: int) -> None:
        for hook in self._hooks["solve_done"]:
            hook(loop, iterations)

    def step_rejected(self, loop, cause) -> None:
        for hook in self._hooks["step_rejected"]:
            hook(loop, cause)

    def step_accepted(self, loop) -> None:
        for hook in self._hooks["step_accepted"]:
            hook(loop)

    def output(self, loop, k: int, t: float) -> None:
        t0 = time.perf_counter()
        for hook in self._hooks["output"]:
            hook(loop, k, t)
        self.output_time += time.perf_counter() - t0

    def step_finished(self, loop) -> None:
        for hook in self._hooks["step_finished"]:
            hook(loop)

    def ended(self, loop, failure: BaseException | None) -> BaseException | None:
        """Every observer's ``ended``, even after one of them raised a CosseratError: the
        first such error is returned if there was no failure before (files must close)."""
        from cosserat_fem.common.errors import CosseratError

        for hook in self._hooks["ended"]:
            try:
                hook(loop, failure)
            except CosseratError as exc:
                failure = failure or exc
        return failure
