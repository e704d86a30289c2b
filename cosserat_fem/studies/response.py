"""The steady response of a rod to periodic forcing: settled periods and amplitudes.

A run forced with period T [s] (the forcing's, e.g. 2π/Ω for a load ∝ sin Ωt) is cut into
periods P_j = [t0 + jT, t0 + (j+1)T] from its start t0. For each period and each column c of
the probe (x, y, z [m] and θ, ψ, φ [rad] at the probe point), with c(t) the piecewise-linear
interpolant of the probe's values at the output times:

    mean            m_j = (1/T) ∫_{P_j} c dt,
    half range      A_j = (max_{P_j} c − min_{P_j} c) / 2,
    first harmonic  H_j = (2/T) ∫_{P_j} c (sin Ωt + i cos Ωt) dt,   Ω = 2π/T

(H = h1 e^{i phase} for c = h1 sin(Ωt + phase): its phase as well as its size).

**Settled.** The change from one period to the next, relative to the size of the motion,

    δ_j = max_c max(|A_j − A_{j−1}|, |m_j − m_{j−1}|, |H_j − H_{j−1}|) / S_g(c),

S_g the size of the motion in c's unit, S = max(max_{x,y,z} A_j / ℓ, max_{θ,ψ,φ} A_j): the
largest half range of period j, lengths in units of the rod's length ℓ (S_g = ℓ S for the
displacements, S for the angles; so that a column that hardly moves, ψ at the mid-span of a
symmetric mode, is not measured against its own round-off), must stay ≤ ``tolerance`` for
``settled_periods`` periods in a row. Then the run ends
(:meth:`~cosserat_fem.timestepping.loop.TimeLoop.request_end`). What the criterion leaves: a
transient e^{−ζωt} (ζ the damping ratio of the mode it rings in, ω its frequency) that changes by δ
over one period is still δ / (1 − e^{−ζωT}) of the motion (H's change catches a transient
at the forcing's frequency that turns the phase and hardly changes A); a tolerance bounds
the error of the amplitudes only together with the damping (docs/sweeps.md, "Frequency
responses").

**Measured** over the last ``measure_periods`` whole periods W = [b − nT, b]: per column its
half range ``amp``, its mean ``mean`` and its first harmonic, c ≈ mean + h1 sin(Ωt + phase),
from H over W: h1 = |H|, phase = arg H, t the run's own (absolute) time, so that for a load
∝ sin Ωt ``phase`` is the response's phase against the load's. The integrals are the
trapezoidal rule over the output times (exact for the interpolant's mean, O((Ω Δt)²) for
the harmonic); the half range of samples every Δt misses a peak by at most 1 − cos(πΔt/T)
of the amplitude, which :func:`check_sampling` holds below a tenth of the tolerance: it
varies from period to period with the phase of the samples, unless ``steps_per_period``
makes T a whole number of steps, when every period is sampled alike and the change δ is
the response's own down to round-off; the half range ``amp`` then stays biased low by up to
1 − cos(π/N), N = steps_per_period (5.5e-5 at N = 300), the same in every period, while
``h1`` is exact for the interpolant. A run that has not settled by its end is measured over
its last whole periods, and flagged (``settled`` false).

The decision is taken on the rank that owns the probe point and broadcast, once a period, so
that every rank ends the run at the same step.
Tests: tests/test_response.py.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from cosserat_fem.common.errors import SceneError
from cosserat_fem.io.probes import PROBE_COLUMNS
from cosserat_fem.timestepping.events import Observer

#: The columns the response is measured on: the probe's (x, y, z [m], θ, ψ, φ [rad]).
COLUMNS = PROBE_COLUMNS[1:]
#: The quantities measured per column (module docstring), in the table's order.
MEASURES = ("amp", "mean", "h1", "phase")
DIRECTIONS = ("up", "down", "both")


@dataclass(frozen=True)
class ResponseSettings:
    """How a forced member runs and is measured (module docstring): ``period`` [s] is an
    expression of the scene's constants (L, omega0, the parameters); ``continuation``, the
    varied key stepped along a chain of members, each starting from the previous one's final
    state (None: every member from the scene's initial state); ``direction``: the order of a
    chain, by increasing ("up") or decreasing ("down") values of that key, or both chains;
    ``steps_per_period``: each member's time.step is T divided by it, so that every period
    is sampled at the same phases (None: the scene's time.step, checked by
    :func:`check_sampling`)."""

    period: str
    continuation: str | None = None
    direction: str = "up"
    tolerance: float = 1e-3
    settled_periods: int = 3
    measure_periods: int = 2
    max_periods: int = 200
    steps_per_period: int | None = None  # time.step = T / this: every period sampled alike


def period_of(
    settings, constants: dict[str, float], where: str, key: str = "sweep.response.period"
) -> float:
    """The forcing period [s] of ``settings.period`` (a ResponseSettings', or a Poincaré
    section's: sweep_spec.SectionSettings) at the scene's ``constants``; SceneError naming
    ``key`` unless it is finite and positive."""
    from cosserat_fem.scene.build import _finite_value
    from cosserat_fem.scene.expressions import Expression

    expression = Expression.parse(settings.period, set(constants), key=key)
    value = _finite_value(expression, key, where, **constants)
    if not value > 0.0:
        raise SceneError(
            f"{key}: {settings.period!r} = {value!r} s at {where}; must be a positive time"
        )
    return value


def check_sampling(settings: ResponseSettings, period: float, step: float, where: str) -> None:
    """Refuse output times too coarse for the period: a half range of samples every ``step``
    misses a peak by up to 1 − cos(π step / T) of it, and by a different amount in each period
    (the samples' phase moves): that jitter enters the change δ, so it must stay below a tenth
    of the tolerance, for δ to measure the response and not the sampling, to 10 %
    (SceneError naming time.step)."""
    miss = 1.0 - math.cos(math.pi * min(step / period, 1.0))
    if miss > 0.1 * settings.tolerance:
        most = period * math.acos(1.0 - 0.1 * settings.tolerance) / math.pi
        raise SceneError(
            f"time.step: {step!r} s samples the forcing period {period:.6g} s too coarsely for "
            f"sweep.response.tolerance = {settings.tolerance:g} at {where} (a peak missed by "
            f"{miss:.2g}); use time.step <= {most:.3g} s"
        )


def continued_start(end: float, period_before: float, period: float) -> float:
    """The start time [s] of a member that continues a run ended at ``end`` under a forcing of
    period ``period_before``: the time in [0, ``period``) at which a forcing of ``period``
    has the phase the last one had at ``end`` (the load is continuous across the switch)."""
    cycles = end / period_before
    return (cycles - math.floor(cycles)) * period


def _window(times: np.ndarray, values: np.ndarray, a: float, b: float):
    """The samples in [a, b] with the interpolant's values at a and b added."""
    inside = (times > a) & (times < b)
    ends = np.array(
        [[np.interp(x, times, values[:, c]) for c in range(values.shape[1])] for x in (a, b)]
    )
    return (
        np.concatenate([[a], times[inside], [b]]),
        np.concatenate([ends[:1], values[inside], ends[1:]]),
    )


def _integral(t: np.ndarray, f: np.ndarray) -> np.ndarray:
    """∫ f dt by the trapezoidal rule along axis 0."""
    dt = np.diff(t)[:, None]
    return (0.5 * dt * (f[1:] + f[:-1])).sum(axis=0)


def _harmonic(t: np.ndarray, f: np.ndarray, period: float) -> np.ndarray:
    """H = (2/(t_end − t_0)) ∫ f (sin Ωt + i cos Ωt) dt per column, Ω = 2π/period (module
    docstring: f = h1 sin(Ωt + phase) gives h1 e^{i phase})."""
    omega_t = 2.0 * math.pi / period * t
    weight = (np.sin(omega_t) + 1j * np.cos(omega_t))[:, None]
    return 2.0 * _integral(t, f * weight) / (t[-1] - t[0])


class Probe(Protocol):
    """What :class:`PeriodicResponse` measures (fields.PointProbe): the values at the point
    (a row of probes.csv's columns after t) on the owning rank, None elsewhere."""

    owner: int

    @property
    def is_owner(self) -> bool: ...

    def values(self) -> np.ndarray | None: ...


class PeriodicResponse(Observer):
    """Measures the forced response at the probe point σ = ``sigma`` over periods of
    ``period`` [s] (module docstring) and ends the run once it has settled; ``result`` (on
    every rank once the run has ended) holds the measurement."""

    def __init__(self, settings: ResponseSettings, period: float, sigma: float):
        self.settings, self.period, self.sigma = settings, period, sigma
        self.result: dict | None = None
        self.probe: Probe | None = None  # attached when the run starts
        self.closed = 0  # periods closed
        self._times: list[float] = []
        self._values: list[np.ndarray] = []
        self._previous: tuple[np.ndarray, np.ndarray, np.ndarray] | None = (
            None  # the last period's (half range, mean, harmonic)
        )
        self._in_a_row = 0
        self._change = math.nan

    @property
    def settled(self) -> bool:
        return self._in_a_row >= self.settings.settled_periods

    # -- hooks ----------------------------------------------------------------------------
    def started(self, loop) -> None:
        from cosserat_fem.output.fields import PointProbe

        comm = loop.model.U.function_space.mesh.comm
        self.attach(PointProbe(loop.model, self.sigma), comm, loop.state.t, loop.model.length)

    def attach(self, probe: Probe, comm, t0: float, length: float) -> None:
        """Measure ``probe`` (a fields.PointProbe: ``values()``, ``is_owner``, ``owner``) on
        ``comm`` from the start time ``t0`` [s] (its first sample); ``length`` [m]: ℓ."""
        self.probe, self.comm, self.t0, self.length = probe, comm, t0, length
        self._sample(t0)

    def output(self, loop, k: int, t: float) -> None:
        self._sample(t)
        boundary = self.t0 + (self.closed + 1) * self.period
        # The boundary reached to round-off: t and the boundary are sums of up to ~1e6 steps
        # or periods, exact to ~1e6 ε ≈ 2e-10 of them.
        if t < boundary - 1e-9 * self.period:
            return
        self.closed += 1
        self._change, self._in_a_row = self._from_owner(lambda: self._close(boundary))
        if self.settled:
            loop.request_end(
                f"the response settled after {self.closed} periods (change "
                f"{self._change:.3g} <= {self.settings.tolerance:g} for "
                f"{self._in_a_row} periods in a row)"
            )

    def ended(self, loop, failure) -> None:
        if self.probe is None:  # the run failed before it started: nothing measured
            return
        measured = self._from_owner(self._measure)
        self.result = {
            "periods": self.closed,
            "settled": self.settled,
            "change": self._change,
            "start_s": self.t0,
            "end_s": loop.state.t,
            **measured,
        }

    # -- the owner's work -------------------------------------------------------------------
    def _from_owner(self, compute):
        """``compute()`` on the probe's rank, its value on every rank; a failure there raised
        on every rank alike (the others would wait in the broadcast otherwise)."""
        value, problem = None, None
        assert self.probe is not None, "attached when the run started"
        if self.probe.is_owner:
            try:
                value = compute()
            except Exception as exc:  # noqa: BLE001 - carried to every rank, then raised
                problem = f"{type(exc).__name__}: {exc}"
        if self.comm.size > 1:
            value, problem = self.comm.bcast((value, problem), root=self.probe.owner)
        if problem:
            raise RuntimeError(f"the forced response's measurement failed: {problem}")
        return value

    def _sample(self, t: float) -> None:
        assert self.probe is not None, "attached when the run started"
        values = self.probe.values()
        if values is not None:
            self._times.append(t)
            self._values.append(values[: len(COLUMNS)])

    def _close(self, b: float) -> tuple[float, int]:
        """Period statistics of [b − T, b]; the change δ and the settled periods in a row."""
        times, values = np.array(self._times), np.array(self._values)
        tt, vv = _window(times, values, b - self.period, b)
        half = 0.5 * (vv.max(axis=0) - vv.min(axis=0))
        mean = _integral(tt, vv) / self.period
        harmonic = _harmonic(tt, vv, self.period)
        previous, self._previous = self._previous, (half, mean, harmonic)
        keep = self.settings.measure_periods + 1  # periods of samples the measurement needs
        first = np.searchsorted(times, b - keep * self.period) - 1
        if first > 0:
            del self._times[:first], self._values[:first]
        if previous is None:
            return math.nan, 0
        half0, mean0, harmonic0 = previous
        change = np.maximum.reduce(
            [np.abs(half - half0), np.abs(mean - mean0), np.abs(harmonic - harmonic0)]
        )
        size = max(half[:3].max() / self.length, half[3:].max(), np.finfo(float).tiny)
        scale = np.repeat([self.length * size, size], 3)
        delta = float((change / scale).max())
        in_a_row = self._in_a_row + 1 if delta <= self.settings.tolerance else 0
        return delta, in_a_row

    def _measure(self) -> dict[str, float]:
        """The half range, mean and first harmonic of each column over the last whole periods
        (at most ``measure_periods``; NaN without a whole period)."""
        n = min(self.settings.measure_periods, self.closed)
        out = {}
        if n == 0:
            return {f"{m}_{c}": math.nan for c in COLUMNS for m in MEASURES}
        b = self.t0 + self.closed * self.period
        a = b - n * self.period
        tt, vv = _window(np.array(self._times), np.array(self._values), a, b)
        mean = _integral(tt, vv) / (b - a)
        harmonic = _harmonic(tt, vv, self.period)
        half = 0.5 * (vv.max(axis=0) - vv.min(axis=0))
        for i, name in enumerate(COLUMNS):
            out[f"amp_{name}"] = float(half[i])
            out[f"mean_{name}"] = float(mean[i])
            out[f"h1_{name}"] = float(abs(harmonic[i]))
            out[f"phase_{name}"] = float(np.angle(harmonic[i]))
        return out
