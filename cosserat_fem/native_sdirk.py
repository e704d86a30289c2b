"""A whole SDIRK time step in one call into C (newton_loop.c ``cf_sdirk_step``), for serial runs.

:class:`~cosserat_fem.integrators.SDIRK` takes a step as a dozen NumPy calls per stage (the
stage value Z_i, the predictor's extrapolation, U, the stage rate K_i) around a Newton solve
(:meth:`NewtonSolver.solve`: one call of ``cf_solve``), and its
accept as a few copies: on the paper's scene those cost about as much as the solves' C work
(docs/decisions.md, "The compiled inner loop"). :class:`NativeSDIRK` does the same in C: per
stage the same IEEE operations, element by element and in the same order, as the NumPy calls
of ``SDIRK.step``, ``SDIRK._rate_guess`` and ``SDIRK.accept``, and per stage the solve that
``NewtonSolver.solve`` makes (``cf_solve``: the policy, the iterations, the retry), calling
Python back only to assemble a Jacobian. So a run's states and counters are bitwise those of
the Python step (tests/test_native_newton.py).

It applies when the Newton solver runs its C loop (serial, no point load, ``solver.loop =
"auto"``) with a reused Jacobian, no observer watches Newton's iterations or solves and no
support moves (a moving support's values go into each stage's guess from Python). Loads given
by data (tables, callables: cosserat_fem/load_coefficients.py) are evaluated before the step
at its stage times, as the Python step's solves would evaluate them (the same τ = τ_n + c_i h,
the same numbers), and the C code puts each stage's values into the packed constants and the
Constant (a load of t) or the quadrature Function (of t and s) as it sets τ; each step
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
from dolfinx import cpp, fem

from .integrators import SDIRK, Integrator, time_view
from .newton import _REASONS, NewtonFailure


class NativeSDIRK:
    """``step`` and ``accept`` of an SDIRK integrator in C where they apply (module docstring),
    else the integrator's own. Build it with :func:`stepper`."""

    def __init__(self, integrator: SDIRK, solver, data=None):
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
        self.sd = sd
        self._native = None  # the solver's C loop that sd's constants belong to
        self.steps = 0  # steps attempted in C
        self.data = data  # the model's DataLoads (load_coefficients.py), or None
        self._data: list = []  # (t ↦ values, size) of each load given by data, in sd's order
        self._data_values = np.zeros((len(it.b), 0))

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
        if not self._bind_data(form, native):
            return False
        sd = self.sd
        sd.constants = self.ffi.cast("double*", native.constants.ctypes.data)
        sd.time_slot = int(slots[0]) if slots.size else -1
        self._native = native
        return True

    def _bind_data(self, form, native) -> bool:
        """Where each load given by data goes in C (sd's data_targets): a Constant's slot in the
        packed constants (found by packing two values of it) and its own storage, a Function's
        own array; False if a Constant's place is unclear."""
        entries = self.data.entries(self.integrator.time_eval) if self.data else []
        targets, sizes, self._data = [], [], []
        ffi = self.ffi
        for coefficient, values in entries:
            if isinstance(coefficient, fem.Constant):
                kept = np.array(coefficient.value)
                packed = []
                for probe in (1.0, 2.0):
                    coefficient.value = probe
                    packed.append(cpp.fem.pack_constants(form))
                coefficient.value = kept
                slots = np.flatnonzero(packed[0] != packed[1])
                if slots.size != 1:
                    return False
                # the packed slot the residual reads, and the Constant's own storage, which a
                # Jacobian assembled between stages reads (a torque's term depends on U)
                own = time_view(coefficient)
                self._keep.append(own)
                targets += [ffi.cast("double*", native.constants.ctypes.data) + int(slots[0]),
                            ffi.cast("double*", own.ctypes.data)]  # fmt: skip
                sizes += [1, 1]
                self._data.append((values, 2))
            else:
                array = coefficient.x.array
                targets.append(ffi.cast("double*", array.ctypes.data))
                sizes.append(array.size)
                self._data.append((values, array.size))
        self._targets = ffi.new("double*[]", targets or [ffi.NULL])
        self._sizes = np.array(sizes or [0], dtype=np.int32)
        self._data_values = np.zeros((len(self.integrator.b), max(sum(sizes), 1)))
        sd = self.sd
        sd.n_data, sd.data_stride = len(targets), sum(sizes)
        sd.data_targets = self._targets
        sd.data_sizes = ffi.cast("int32_t*", self._sizes.ctypes.data)
        sd.data_values = ffi.cast("double*", self._data_values.ctypes.data)
        return True

    def _stage_data(self, h: float) -> None:
        """The loads given by data at this step's stage times τ_n + c_i h (the τ the Python step
        gives its time Constant, t = τ/ω0 as DataLoads.sync computes it), into sd's values;
        the Python side's coefficients then hold no τ's values (forgotten)."""
        it, omega0 = self.integrator, self.data.omega0
        for i, c in enumerate(it._c_list):
            t = (it.time + c * h) / omega0
            row, offset = self._data_values[i], 0
            for values, size in self._data:
                row[offset : offset + size] = values(t)
                offset += size
        self.data.forget(it.time_eval)

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
        if self._data:
            self._stage_data(h)
        native.refresh(dirichlet=False)  # fixed Dirichlet values (no moving support)
        sd.h, sd.time, sd.stored = h, it.time, it._stored
        self.steps += 1
        status = self.lib.cf_sdirk_step(solver._sv, solver._cs, solver._state, sd)
        it.unknown_time = sd.unknown_time
        solver._finish(status, f"the C time step, stage {sd.stage + 1}, its unknown at "
                               f"τ = ω0 t = {sd.unknown_time:.10g}")  # fmt: skip
        if sd.reason <= 0:
            raise NewtonFailure(_REASONS.get(sd.reason, str(sd.reason)), solver._state.iterations)
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
    solver runs Newton's C loop, with no moving support and no observer of Newton's solves or
    iterations; else the integrator itself."""
    if (
        not isinstance(integrator, SDIRK)
        or solver.loop != "c"
        or model.motions
        or events.listens("solve_done")
        or events.listens("newton_iteration")
        or len(integrator.b) > 8
    ):
        return integrator
    return NativeSDIRK(integrator, solver, model.data)
