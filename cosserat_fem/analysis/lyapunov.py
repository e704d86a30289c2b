"""The largest Lyapunov exponent of a periodically forced rod, by Benettin's method, with its
Poincaré section (``cf.lyapunov``; issue 27 item 4).

**Method** (Benettin, Galgani, Giorgilli & Strelcyn 1980, Meccanica 15:9). Two trajectories of
the same discrete system: the reference, from the scene's initial state, and a perturbed one,
from the reference's state plus δ0. They are integrated alike, interval by interval, each
interval ``every`` forcing periods T long (kT, k = ``every``), with the same fixed steps
(time.step must divide kT): the perturbed state is the reference's plus a vector that the
*discrete* flow carries, so no step-size control or interpolation enters the difference. At
the end of interval j the distance d_j = ‖U_pert − U_ref‖ is measured and the perturbation
rescaled back to d0 along its own direction (every array of the integrator's state, U and its
history: U_pert ← U_ref + (d0/d_j)(U_pert − U_ref)). The stretch of interval j is
s_j = ln(d_j/d0), and the running estimate after n intervals, those before ``discard``
left out (while the perturbation turns towards the most unstable direction),

    λ_n = Σ_{j=discard}^{n−1} s_j / ((n − discard) k T)    [1/s].

The tangent map was not chosen: the integrators step U through Newton solves of their own
stages (timestepping/integrators.py), and carrying a tangent through them would mean
differentiating every scheme's stage equations and history; two trajectories need nothing
from the integrators but their state_dict (the restart's), one TimeLoop and one compiled
form, at twice the cost of one run. With a linear system, the two give the same numbers.

**Norm.** d = the root mean square of the entries of U = (p, q) over the rod's degrees of
freedom, in the solver's units: lengths in ℓ, angles in rad, rates d/dτ with τ = ω0 t
(rod/model.py ``initial_state``): dimensionless, and independent of the mesh's size for a
smooth perturbation. The limit λ does not depend on the norm (all norms of a finite
dimensional space are equivalent; the ratio of two enters λ_n as ln(ratio)/(n k T)).

**Perturbation size** d0 = ``perturbation`` (default 1e3 × solver.stol, 1e-5 at the default
stol 1e-8). Two bounds: (i) linear range: the perturbation grows at most by e^{λ k T} within
an interval before it is rescaled, so the terms of second order that the linearisation drops
stay a fraction ~d0 e^{λ k T} of it (the state's nonlinear scale is 1 in these units: a
deflection of ℓ, a rotation of a radian); (ii) above the solver's noise: Newton stops when its
update is below stol ‖U‖, so each trajectory carries an error of that order per step, which
must stay well below d0: 1e3 × stol keeps it at 1e-3 of d0 for ‖U‖'s RMS of order 1. Its
direction: normal random numbers (seeded by ``seed``) at the degrees of freedom that no
support holds (a held value would be reset by the first step).

**Poincaré section**: :class:`~cosserat_fem.analysis.observers.PoincareSection` on the
reference trajectory, at the forcing's phase ``phase``; poincare.csv with ``out``.

Limits: fixed steps only (time.adaptive would let the two trajectories take different steps,
whose error estimates, not the flow, would then part them); a run whose Euler-angle chart
moves (rod/charts.py) differently in the two trajectories stops with a SolverError (their
states would not be comparable). The scene's time.end is not used: the run spans ``periods``
periods from time.start. Tests: tests/test_chaos.py.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from mpi4py import MPI

from cosserat_fem.analysis.observers import PoincareSection
from cosserat_fem.analysis.simulation import _discretise, _initial_array, drive
from cosserat_fem.common.errors import SceneError, SolverError
from cosserat_fem.common.parallel import agree
from cosserat_fem.io.poincare import POINCARE
from cosserat_fem.scene.build import Scene, refuse_closed, refuse_contact
from cosserat_fem.timestepping.events import Events, Observer, as_observer
from cosserat_fem.timestepping.loop import TimeLoop

#: The parts of a loop's state_dict that hold the trajectory (the others: the solver's and
#: the loop's counters, the chart, are the perturbed trajectory's own).
TRAJECTORY_PARTS = ("state", "integrator")
#: The integrator's arrays that are states (not rates) at the start: perturbed like U.
STATE_ARRAYS = ("U_n", "U_nm1")


@dataclass
class LyapunovResult:
    """``exponent`` [1/s]: the running estimate at the end (NaN if no interval was averaged);
    per interval j: ``times`` [s] its end, ``stretches`` s_j = ln(d_j/d0), ``running`` λ after
    it [1/s] (NaN while j < discard); ``poincare`` the section's rows (``columns``: period
    index, t [s], the probe's values, state_rms); ``perturbation`` d0, ``period`` T [s],
    ``every`` k, ``discard``; ``files`` written."""

    exponent: float
    times: np.ndarray
    stretches: np.ndarray
    running: np.ndarray
    poincare: np.ndarray
    columns: tuple[str, ...]
    perturbation: float
    period: float
    every: int
    discard: int
    files: list[Path] = field(default_factory=list)


def running_estimate(stretches: np.ndarray, interval: float, discard: int) -> np.ndarray:
    """λ_n [1/s] after each interval n = 1, 2, ... (module docstring); NaN for n ≤ discard."""
    s = np.asarray(stretches, dtype=float)
    n = np.arange(1, s.size + 1)
    averaged = np.cumsum(np.where(n > discard, s, 0.0))
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(n > discard, averaged / ((n - discard) * interval), np.nan)


def _whole(value, name: str, low: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < low:
        raise SceneError(f"{name}: must be a whole number >= {low}, got {value!r}")
    return int(value)


def check_request(
    scene: Scene, period, periods, every, discard, perturbation
) -> tuple[int, int, float]:
    """The request checked before any work (a closed rod refused too): (intervals, steps an
    interval, d0)."""
    refuse_closed(scene, "lyapunov")
    refuse_contact(scene, "lyapunov")
    if isinstance(period, bool) or not isinstance(period, int | float) or not period > 0.0:
        raise SceneError(f"period: must be the forcing period, a positive time [s], got {period!r}")
    if not math.isfinite(period):
        raise SceneError(f"period: must be finite, got {period!r}")
    periods, every = _whole(periods, "periods", 1), _whole(every, "every", 1)
    discard = _whole(discard, "discard", 0)
    if periods % every:
        raise SceneError(f"periods: {periods} is not a whole number of intervals every = {every}")
    intervals = periods // every
    if discard >= intervals:
        raise SceneError(f"discard: {discard} leaves none of the {intervals} intervals to average")
    if scene.time.adaptive:
        raise SceneError(
            "time.adaptive: the Lyapunov exponent needs fixed steps (both trajectories must take "
            "the same steps); set time.adaptive = false"
        )
    steps = every * period / scene.time.step
    if abs(steps - round(steps)) > 1e-6 * steps:
        fitting = every * period / max(1, round(steps))
        raise SceneError(
            f"time.step: {scene.time.step!r} s does not divide the interval of {every} forcing "
            f"period(s) {every * period:.9g} s; use e.g. {fitting:.9g}"
        )
    if perturbation is None:
        perturbation = 1e3 * scene.solver.stol
    if isinstance(perturbation, bool) or not isinstance(perturbation, int | float):
        raise SceneError(f"perturbation: must be a number, got {type(perturbation).__name__}")
    if not 0.0 < perturbation <= 1e-2:
        raise SceneError(f"perturbation: must lie in (0, 1e-2] (RMS of U), got {perturbation!r}")
    return intervals, round(steps), float(perturbation)


class _Benettin:
    """The source of events that :func:`~cosserat_fem.analysis.simulation.drive` runs: the two
    trajectories in one TimeLoop, interval by interval; the reference's events go to
    ``events`` (the section, the caller's observers), the perturbed one's to none."""

    def __init__(
        self,
        loop: TimeLoop,
        intervals: int,
        steps: int,
        d0: float,
        seed: int,
        told: Callable[[float, float], None] | None = None,
    ):
        self.loop, self.intervals, self.steps, self.d0, self.seed = loop, intervals, steps, d0, seed
        self.told = told  # told(t, stretch) after each interval
        self.events, self.solver = loop.events, loop.solver
        self.model, self.integrator = loop.model, loop.integrator
        self.quiet = Events([])
        V = self.model.V
        self.owned = V.dofmap.index_map.size_local * V.dofmap.index_map_bs
        self.comm = self.model.msh.comm
        self.entries = self.comm.allreduce(self.owned)
        self.stretches: list[float] = []
        self.times: list[float] = []

    # What drive() and the observers read of a loop.
    @property
    def state(self):
        return self.loop.state

    @property
    def completed(self) -> bool:
        return len(self.stretches) == self.intervals

    @property
    def restarted(self) -> bool:
        return False

    @property
    def end_reason(self):
        return self.loop.end_reason

    def back_to_accepted(self) -> None:
        self.loop.back_to_accepted()

    def distance(self, a: np.ndarray, b: np.ndarray) -> float:
        """RMS of (a − b) over the owned entries (collective)."""
        d = (a - b)[: self.owned]
        return math.sqrt(self.comm.allreduce(float(d @ d)) / self.entries)

    def direction(self) -> np.ndarray:
        """A random vector of RMS d0, zero at the held degrees of freedom, ghosts updated."""
        from dolfinx import fem

        rng = np.random.default_rng([self.seed, self.comm.rank])
        held = np.full(self.model.U.x.array.shape, np.nan)
        fem.set_bc(held, self.model.bcs)  # the held entries get their (finite) values
        vector = fem.Function(self.model.V)
        free = ~np.isfinite(held[: self.owned])
        vector.x.array[: self.owned] = np.where(free, rng.standard_normal(self.owned), 0.0)
        vector.x.scatter_forward()
        u = vector.x.array
        return u * (self.d0 / self.distance(u, 0.0 * u))

    def perturbed_start(self, reference: dict) -> dict:
        delta = self.direction()
        parts = {k: dict(v) for k, v in reference.items()}
        parts["state"]["U"] = reference["state"]["U"] + delta
        for name in STATE_ARRAYS:
            if name in parts["integrator"]:
                parts["integrator"][name] = reference["integrator"][name] + delta
        return parts

    def rescaled(self, reference: dict, perturbed: dict, factor: float) -> dict:
        """The perturbed parts with U_ref + factor (U_pert − U_ref) in every trajectory array."""
        parts = {k: dict(v) for k, v in perturbed.items()}
        for part in TRAJECTORY_PARTS:
            for key, value in perturbed[part].items():
                ref = reference[part].get(key)
                if isinstance(value, np.ndarray) and value.dtype.kind == "f" and value.size:
                    assert ref is not None and ref.shape == value.shape, "same integrator"
                    parts[part][key] = ref + factor * (value - ref)
        return parts

    def _same_chart(self, reference: dict, perturbed: dict) -> None:
        a, b = reference.get("chart"), perturbed.get("chart")
        same = (a is None and b is None) or (
            a is not None
            and b is not None
            and np.array_equal(a["Q"], b["Q"])
            and a["active"] == b["active"]
        )
        if not self.comm.allreduce(bool(same), op=MPI.LAND):
            raise SolverError(
                time=self.loop.state.t,
                where=None,
                reason="the Euler-angle chart moved differently in the perturbed trajectory",
                suggestion="use a smaller perturbation, or a shorter interval (every)",
            )

    def _run_to(self, parts: dict, events: Events, n_steps: int) -> dict:
        loop = self.loop
        loop.load_state_dict(parts)
        loop.events = events
        loop.tspan = dataclasses.replace(
            loop.tspan, end=loop.tspan.start + n_steps * loop.tspan.step
        )
        loop.run_fixed()
        return loop.state_dict()

    def run(self) -> None:
        loop = self.loop
        loop.events.started(loop)
        reference = loop.state_dict()
        perturbed = self.perturbed_start(reference)
        for j in range(self.intervals):
            n_steps = (j + 1) * self.steps
            reference = self._run_to(reference, self.events, n_steps)
            if loop.end_reason is not None:
                break
            perturbed = self._run_to(perturbed, self.quiet, n_steps)
            self._same_chart(reference, perturbed)
            d = self.distance(perturbed["state"]["U"], reference["state"]["U"])
            if not (d > 0.0 and math.isfinite(d)):
                raise SolverError(
                    time=loop.state.t,
                    where=None,
                    reason=f"the two trajectories' distance is {d!r}",
                    suggestion="a larger perturbation (it fell below round-off)",
                )
            self.stretches.append(math.log(d / self.d0))
            self.times.append(loop.state.t)
            if self.told is not None:
                self.told(self.times[-1], self.stretches[-1])
            perturbed = self.rescaled(reference, perturbed, self.d0 / d)
        loop.events = self.events
        loop.load_state_dict(reference)  # the observers end on the reference's last state


def largest_exponent(
    scene: Scene,
    period: float,
    *,
    periods: int,
    every: int = 1,
    discard: int = 0,
    phase: float = 0.0,
    perturbation: float | None = None,
    seed: int = 0,
    observers=(),
    out: str | Path | None = None,
    initial_state: np.ndarray | None = None,
    comm: MPI.Comm = MPI.COMM_WORLD,
    stopped: Callable[[LyapunovResult, BaseException], None] | None = None,
    interval: Callable[[float, float], None] | None = None,
) -> LyapunovResult:
    """The largest Lyapunov exponent of the scene forced with period ``period`` T [s] over
    ``periods`` periods from time.start, and the Poincaré section at the forcing's phase
    ``phase`` [rad] (module docstring): a :class:`LyapunovResult`. ``every``: periods between
    renormalisations; ``discard``: intervals left out of the average; ``perturbation`` d0;
    ``seed``: its direction's; ``observers``: the reference trajectory's; with ``out``,
    poincare.csv there; ``initial_state``: the reference's start, as ``cf.run``'s (e.g. a
    static solution: a buckled beam in one of its wells); ``stopped(result so far, why)``
    when the run stops early (a CosseratError: limits.wall_time, a failed solve; or
    KeyboardInterrupt: Ctrl-C, SIGTERM), before that is raised: the intervals done, their
    stretches and the running estimate (NaN if none was averaged), so that nothing computed
    is lost; ``interval(t [s], stretch)`` after each interval (every rank). Bad input: a
    SceneError naming the argument or key, before any work."""
    intervals, steps, d0 = check_request(scene, period, periods, every, discard, perturbation)
    observers = [as_observer(o) for o in observers]
    initial_state = _initial_array(initial_state, comm)
    path = None
    if out is not None:
        folder = Path(out)
        problem = None
        if comm.rank == 0:
            try:
                folder.mkdir(parents=True, exist_ok=True)
            except OSError as exc:
                problem = SceneError(f"out: cannot make {str(folder)!r} ({exc})")
        agree(comm, problem)
        path = folder / POINCARE
    section = PoincareSection(period, phase, path)
    model, integrator, solver = _discretise(scene, comm, initial_state, None)
    chain: list[Observer] = [section, *observers]
    loop = TimeLoop(model, integrator, solver, scene.time, Events(chain))
    source = _Benettin(loop, intervals, steps, d0, seed, interval)

    def result() -> LyapunovResult:
        """What the intervals run so far give (all of them once the run ended)."""
        stretches = np.array(source.stretches)
        running = running_estimate(stretches, every * period, discard)
        rows = section.rows  # set when the run ended (drive ends it, stopped or not)
        assert rows is not None, "set when the run ended"
        return LyapunovResult(
            exponent=float(running[-1]) if running.size else math.nan,
            times=np.array(source.times),
            stretches=stretches,
            running=running,
            poincare=rows,
            columns=section.columns,
            perturbation=d0,
            period=float(period),
            every=every,
            discard=discard,
            files=[path] if path is not None else [],
        )

    try:
        failure = drive(source)
    except KeyboardInterrupt as exc:  # Ctrl-C, or SIGTERM (cli.py): every rank alike
        if stopped is not None:
            stopped(result(), exc)
        raise
    if failure:
        if stopped is not None:
            stopped(result(), failure)
        raise failure
    return result()
