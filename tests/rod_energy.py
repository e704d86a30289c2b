"""Energy bookkeeping of a run, for tests and benchmarks/verify.py: E = T + V of the rod and
the power P of its loads and its damping [SI] (:class:`EnergyMonitor`), and an observer that
records them at every output time (:class:`EnergyRecorder`).

The integrands are those of :mod:`cosserat_fem.forms.energy`; the forms are compiled once and
evaluated on the current state (collectively under MPI). The load power is evaluated at a given
time τ, so that the work of the loads can be integrated in time alongside the run.
"""

from __future__ import annotations

from cosserat_fem.forms.energy import (
    damping_power,
    kinetic_energy_density,
    load_power,
    strain_energy_density,
)
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from cosserat_fem.rod.model import RodModel
from cosserat_fem.timestepping.events import Observer


class EnergyMonitor:
    """T, V [J] of ``model.U`` and the power P [W] of the scene's loads and damping; once the
    model's chart has moved (cosserat_fem/rod/charts.py) the forms measure the angles in it
    (recompiled then)."""

    def __init__(self, model: RodModel):
        self.model = model
        self.tau = fem.Constant(model.msh, PETSc.ScalarType(0.0))
        self._compile()

    def _compile(self) -> None:
        model = self.model
        self._charted = model.chart_moved
        chart = model.chart_form() if model.chart_moved else None
        U, rod, dx = model.layout.full(model.U), model.rod, model.dx
        reference = model.reference_form()
        kinetic = kinetic_energy_density(U, rod, reference) * dx
        body = model.scene.loads.body
        if body is not None:  # a rigid body at an end: its T_B (forms/rigid_body.py)
            from cosserat_fem.forms import rigid_body
            from cosserat_fem.forms.general_form import LoadContext

            from cosserat_fem.rod.model import END_TAG, START_TAG

            tag = START_TAG if body.end == "start" else END_TAG
            context = LoadContext(
                U=U, V=None, groups=model.groups, convention=None, chart=chart,
                reference=reference, ds={}, vector=None, omega0=model.omega0,
            )  # fmt: skip
            kinetic = kinetic + rigid_body.kinetic_energy(body, context) * model.ds(tag)
        self._T = fem.form(kinetic)
        self._V = fem.form(strain_energy_density(U, rod, chart, reference) * dx)
        distributed, ends = model.load_vectors(self.tau)
        power = None
        if distributed.force is not None or distributed.torque is not None:
            density = load_power(U, rod, distributed.force, distributed.torque, chart)
            power = rod.length * density * dx
        for end in ends:
            if end.force is not None or end.torque is not None:
                power_at = load_power(U, rod, end.force, end.torque, chart)
                term = (power_at("+") if end.interior else power_at) * end.ds
                power = term if power is None else power + term
        d = model.scene.damping
        if d.active:
            density = damping_power(
                U, rod, d.translational, d.rotational, d.retardation_time, chart, reference
            )
            term = rod.length * density * dx
            power = term if power is None else power + term
        self._P = fem.form(power) if power is not None else None

    def _current(self) -> None:
        if self._charted != self.model.chart_moved:
            self._compile()

    def _sum(self, form) -> float:
        return self.model.msh.comm.allreduce(fem.assemble_scalar(form), op=MPI.SUM)

    def energies(self) -> tuple[float, float]:
        """(kinetic, strain) energy [J]."""
        self._current()
        return self._sum(self._T), self._sum(self._V)

    def power(self, t: float) -> float:
        """Power of the loads and the damping at time t [s] on the current state [W]."""
        self._current()
        if self._P is None:
            return 0.0
        self.tau.value = t * self.model.omega0
        self.model.sync_loads(self.tau)
        return self._sum(self._P)


class EnergyRecorder(Observer):
    """Observer (cosserat_fem/timestepping/events.py): at every output time t [s], the rod's energy
    E = T + V [J] and the power P [W] of its loads and damping: lists ``t``, ``E``, ``P``."""

    def __init__(self):
        self.monitor: EnergyMonitor | None = None
        self.t: list[float] = []
        self.E: list[float] = []
        self.P: list[float] = []

    def output(self, loop, k: int, t: float) -> None:
        """Appends t [s], E = T + V [J] and P [W]; the monitor is built at the first output."""
        if self.monitor is None:
            self.monitor = EnergyMonitor(loop.model)
        self.t.append(t)
        self.E.append(sum(self.monitor.energies()))
        self.P.append(self.monitor.power(t))
