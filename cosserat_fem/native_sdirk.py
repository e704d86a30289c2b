"""A whole SDIRK time step in one call into C (newton_loop.c ``cf_sdirk_step``), for serial runs.

:class:`~cosserat_fem.integrators.SDIRK` takes a step as a dozen NumPy calls per stage (the
stage value Z_i, the predictor's extrapolation, U, the stage rate K_i) around a Newton solve
(:meth:`NewtonSolver.solve`: its Jacobian policy and counters, then ``cf_newton``), and its
accept as a few copies: on the paper's scene those cost about as much as the solves' C work
(docs/decisions.md, "The compiled inner loop"). :class:`NativeSDIRK` does the same in C: per
stage the same IEEE operations, element by element and in the same order, as the NumPy calls
of ``SDIRK.step``, ``SDIRK._rate_guess`` and ``SDIRK.accept``, the policy of
``NewtonSolver.solve`` (the lagged count, a retry from the same guess with a fresh Jacobian,
the frozen refresh) and ``cf_newton``; it returns to Python only to assemble a Jacobian. So
a run's states and counters are bitwise those of the Python step (tests/test_native_newton.py).

It applies when the Newton solver runs its C loop (serial, no point load, ``solver.loop =
"auto"``) with a reused Jacobian, no observer watches Newton's iterations or solves, no
support moves (a moving support's values go into each stage's guess from Python) and no load
is given by data (a table's or a callable's value at each stage is set from Python:
cosserat_fem/load_coefficients.py); each step
checks what can change during a run (a new form after a chart move: a new C loop) and
otherwise takes the Python step. Fixed supports' values are not written into each stage's
guess as the Python step writes them (``support_dofs_to``): the same bits whenever the state
holds them already, as every state the loop accepts does; an ``initial_state`` given through
the API that breaks a support is mended by the first Newton update instead, which converges
to the same solution in other bits.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from dolfinx import cpp

from .integrators import SDIRK, Integrator, time_view


class NativeSDIRK:
    """``step`` and ``accept`` of an SDIRK integrator in C where they apply (module docstring),
    else the integrator's own. Build it with :func:`stepper`."""

    def __init__(self, integrator: SDIRK, solver):
        from .native_newton import compiled

        module = compiled()
        self.ffi, self.lib = module.ffi, module.lib
        self.integrator, self.solver = integrator, solver
        ffi = self.ffi
        self._keep: list = []

        def pointer(array: np.ndarray):
            assert array.dtype == np.float64 and array.flags.c_contiguous
            self._keep.append(array)
            return ffi.cast("double*", array.ctypes.data)

        it = integrator
        self._tableau = [np.ascontiguousarray(x, dtype=np.float64) for x in (it.A, it.b, it.c)]
        sd = ffi.new("cf_sdirk*")
        sd.stages, sd.n, sd.gamma = len(it.b), it.U_n.size, float(it.gamma)
        sd.A, sd.b, sd.c = (pointer(x) for x in self._tableau)
        sd.u, sd.z, sd.u_n = pointer(it._u), pointer(it._z), pointer(it.U_n)
        sd.K, sd.taus = pointer(it.K), pointer(it._taus)
        sd.rates, sd.times = pointer(it._rates), pointer(it._times)
        sd.guess, sd.term = pointer(it._guess), pointer(it._term)
        sd.time_value = pointer(time_view(it.time_eval))
        sd.initial = ffi.cast("void*", solver._initial.handle)
        self.sd = sd
        self._native = None  # the solver's C loop that sd's constants belong to
        self.steps = 0  # steps attempted in C

    def _bind(self, native) -> bool:
        """sd's constants: those of the solver's current C loop, and the index of τ in them
        (found by packing two values of the time Constant); False if τ's place is unclear."""
        form, value = self.solver.F_form, time_view(self.integrator.time_eval)
        kept = float(value[()])
        packed = []
        for probe in (1.0, 2.0):
            value[()] = probe
            packed.append(cpp.fem.pack_constants(form))
        value[()] = kept
        slots = np.flatnonzero(packed[0] != packed[1])
        if slots.size > 1:
            return False
        sd = self.sd
        sd.constants = self.ffi.cast("double*", native.constants.ctypes.data)
        sd.time_slot = int(slots[0]) if slots.size else -1
        settings = self.solver.settings
        sd.lagged, sd.lag = settings.jacobian == "lagged", settings.lag
        sd.frozen = settings.jacobian == "frozen"
        sd.refresh_iterations = settings.refresh_iterations
        self._native = native
        return True

    def step(self, h: float, solve: Callable[[], int]) -> int:
        """:meth:`SDIRK.step` (``solve`` is used only by the Python step); the Newton
        iterations of its stages. NewtonFailure as the stage's solve raises it."""
        solver, it = self.solver, self.integrator
        native = solver._native
        if native is None or solver.iteration_hook or solver.settings.jacobian == "full":
            return it.step(h, solve)
        if native is not self._native and not self._bind(native):
            return it.step(h, solve)
        sd = self.sd
        it.prepare(h)
        native.refresh(dirichlet=False)  # fixed Dirichlet values (no moving support)
        sd.h, sd.time, sd.stored = h, it.time, it._stored
        sd.stage = sd.phase = sd.iterations = 0
        p, settings, state = native._p, native._settings, native.state
        step = self.lib.cf_sdirk_step
        self.steps += 1
        try:
            solver.solve_stages(sd, lambda: step(p, settings, state, sd))
        finally:
            it.unknown_time = sd.unknown_time
        return sd.iterations

    def accept(self, h: float) -> None:
        """:meth:`SDIRK.accept` (``cf_sdirk_accept``: the same copies)."""
        it, sd = self.integrator, self.sd
        sd.stored = it._stored
        self.lib.cf_sdirk_accept(sd)
        it._stored = sd.stored
        Integrator.accept(it, h)


def stepper(integrator: Integrator, solver, model, events):
    """What a time loop steps with: a :class:`NativeSDIRK` for an SDIRK integrator whose
    solver runs Newton's C loop, with no moving support, no load given by data and no
    observer of Newton's solves or iterations; else the integrator itself."""
    if (
        not isinstance(integrator, SDIRK)
        or solver.loop != "c"
        or model.motions
        or model.data.active
        or events.listens("solve_done")
        or events.listens("newton_iteration")
        or len(integrator.b) > 8
    ):
        return integrator
    return NativeSDIRK(integrator, solver)
