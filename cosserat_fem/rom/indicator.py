"""The reduced model's own error: an indicator from the full residual of the reduced state, and
the flags of a run outside its training (issue 28 item 3; docs/rom.md §10).

**The residual.** Each implicit stage i of a step solves the integrator's full stage residual
F(U) = 0 (for SDIRK: the model's residual with the rate K_i = (U − Z_i)/(γh)); the reduced run
solves only its projection (D V)ᵀ F(U_ref + V q) = 0 (docs/rom.md (5)). At the converged reduced
stage value U_i, F_i = F(U_i) is what the reduced state leaves unbalanced: one full assembly a
stage of every m-th step. The step's defect is

    R_n = Σ_i b_i F_i                                                             (10.1)

(b the integrator's weights; the last stage's F for one-stage schemes), the rate of the state
the reduced step misses: U_{n+1} = U_n + h Σ b_i K_i. Its rows of p (ṗ − q) vanish (the same
modes for p and its rate: docs/rom.md (4)); its rows of q are the balance laws divided by their
inertia ((48), (65)), R_q = D⁻¹ r_sym with r_sym the force the reduced state leaves out.

**Its size: the static response.** Measured in the norm dual to W, ‖R‖_{W*}² = Σ_j (D_j R_j)²/W_j
(the lumped rate defect's W-norm), the residual is dominated by the axial rows, whose error is
quasi-static (stiff) and small; accumulated in time, ∫‖R‖_{W*} dτ overestimates the error
110-2700 times, a factor that varies 24-fold over the checks (docs/rom.md §10). The part of the
error a residual makes at once is the rod's response to it: below the missing modes'
frequencies, the static one,

    e_p = K⁻¹ R_q,                                                                (10.2)

K = D⁻¹ K_sym the linear stiffness about the straight rod (cosserat_fem/analysis/modal.py, the
rows divided by their inertia as F's; factored once), which weighs each missing mode's force by
1/ω_j² and the stiff rows by their stiffness. Left in the state, e_p also drives the modes of the
basis (through the mass and the nonlinear terms, at their frequencies ~ ω0): the error they
accumulate grows as ∫ ‖e_p‖ dτ, τ = ω0 t (ω0 the first bending frequency of the scene's
scaling, (47)). The indicator takes that accumulated static response,

    ξ(t) = ∫₀ᵗ ‖e_p‖_W dτ,                                                          (10.3)

sampled every m-th step and integrated by the rectangle rule, ξ_j = ξ_{j−1} + ‖e_p,j‖_W
(τ_j − τ_{j−1}), and as docs/rom.md §7's error measure (a relative L² over the output times),

    E_j = C (Σ_{i≤j} ξ_i²)^{1/2} / (Σ_{i≤j} ‖u_p,i‖_W²)^{1/2},                        (10.4)

u_p the reduced state's p − p_ref, C = :data:`CONSTANT` calibrated on the checks (measured
E/error with C = 1: 0.31-2.29 on the paper's scene over 0.006 s, docs/rom.md §10). The run's
estimate is E at its end (``final``); ``max`` is the largest E after the first quarter of the
samples (before, E divides by a state still near rest). A run whose ``max`` exceeds the
tolerance says so (a warning line, summary.json's ``rom.indicator.exceeded``).

**Out of training.** The basis's provenance records the range of the reduced coordinates
c = Vᵀ W (U − U_ref) over its snapshots (per coordinate, min and max, and the largest W-norm of a
snapshot: basis.py) and the loads of the scenes it was trained on. A run is flagged when a
coordinate leaves its range by more than ``margin`` times the training's largest coordinate
(of p, or of its rate), when the state's W-norm exceeds (1 + ``margin``) times the largest
snapshot's ("amplitude"), or when the scene's loads are none of the training scenes' ("load"):
one warning line naming what and when (the first time of each), and an entry in summary.json's
``rom.outside_training``.

:class:`ErrorIndicator` is the observer (cosserat_fem/timestepping/events.py) that a reduced run
(cosserat_fem/rom/runs.py ``run``, cf.rom.run) adds; its
:meth:`~ErrorIndicator.summary_entries` go into the run's summary
(cosserat_fem/analysis/observers.py, RunSummary). It also puts the time into a refusal of the
reduced run that has none (the chart's move, galerkin.ReducedSolver.set_form,
raised where the solver does not know the time).
"""

from __future__ import annotations

import json
import math
import time
from dataclasses import dataclass

import numpy as np

from cosserat_fem.common.errors import SceneError, SolverError
from cosserat_fem.common.log import LOGGER
from cosserat_fem.timestepping.events import Observer

#: C of (10.4): the measured E/error with C = 1 on the paper's scene over 0.006 s, trained on
#: its own run and on other loads (k = 4, 8, 12), lies in [0.306, 2.289]; C = 1.2 is near the
#: middle of [1/(3 · 0.306), 3/2.289] = [1.09, 1.31], which puts them all within a factor 3.
CONSTANT = 1.2


@dataclass(frozen=True)
class IndicatorSettings:
    """``every``: the residual is assembled at every ``every``-th step (m of (10.3));
    ``tolerance``: the estimated relative error E (10.4) above which the run says so;
    ``constant``: C of (10.4); ``margin``: how far the coordinates may leave the training's
    range (a fraction of the largest coordinate's amplitude, and of the largest snapshot's
    W-norm) before the run is flagged."""

    every: int = 10
    tolerance: float = 1e-2
    constant: float = CONSTANT
    margin: float = 0.25

    def __post_init__(self) -> None:
        if isinstance(self.every, bool) or not isinstance(self.every, int) or self.every < 1:
            raise SceneError(f"indicator.every: must be a whole number >= 1, got {self.every!r}")
        for name in ("tolerance", "constant", "margin"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, float | int) or not value > 0:
                raise SceneError(f"indicator.{name}: must be a positive number, got {value!r}")
            if not math.isfinite(value):
                raise SceneError(f"indicator.{name}: must be a positive number, got {value!r}")


#: The settings a reduced run takes by default (cosserat_fem/rom/galerkin.py ``run``).
DEFAULT = IndicatorSettings()


def relative_estimate(errors2: float, norms2: float, constant: float) -> float:
    """E = C (Σ_j ξ_j²)^{1/2} / (Σ_j ‖u_p,j‖_W²)^{1/2} (10.4) from the two sums over the
    samples j; 0 while the state has not left its reference."""
    return constant * math.sqrt(errors2 / norms2) if norms2 > 0 else 0.0


class StaticResponse:
    """e_p = K⁻¹ R_q (10.2): the response of the rod's linear stiffness K about the straight
    state (cosserat_fem/analysis/modal.py: K = D⁻¹ K_sym, the balance rows divided by their
    inertia, as F's rows; supports as identity rows) to the rate rows R_q of a residual R of
    U's owned rows (``n`` of them), factored once (LU, ``lu_package``). ``p_rows``: U's rows
    of p, in the order of the returned e_p."""

    def __init__(self, model, t: float, lu_package: str, n: int):
        from petsc4py import PETSc

        from cosserat_fem.analysis.modal import ModalOperator
        from cosserat_fem.rom.basis import state_rows

        problem = ModalOperator(model, t).problem()
        self.K = problem.K
        problem.M.destroy()
        self.ksp = PETSc.KSP().create(model.msh.comm)
        self.ksp.setOperators(self.K)
        self.ksp.setType("preonly")
        self.ksp.getPC().setType("lu")
        self.ksp.getPC().setFactorSolverType(lu_package)
        self.x, self.y = self.K.createVecs()
        layout = model.layout
        self.p_rows, self.q_rows = state_rows(layout, n)
        # U's p-entry c of a node is entry c of the node's 6-block of K's space
        p_entries = np.asarray(layout.components[: layout.p_count])
        nodes = n // layout.size
        self.places = (np.arange(nodes)[:, None] * 6 + p_entries[None, :]).ravel()

    def response(self, R: np.ndarray) -> np.ndarray:
        """e_p on U's p rows (this rank's owned) for the residual R (U's owned rows)."""
        y = self.y.array
        y[:] = 0.0
        y[self.places] = R[self.q_rows]
        self.ksp.solve(self.y, self.x)
        return self.x.array[self.places].copy()

    def destroy(self) -> None:
        for item in (self.ksp, self.x, self.y, self.K):
            item.destroy()


def coordinate_ranges(coordinates: np.ndarray, norms: np.ndarray) -> dict:
    """The provenance entry of a basis's training range: ``coordinates`` (2k, T) the reduced
    coordinates c = Vᵀ W u_i of the T snapshots, ``norms`` (T,) their W-norms."""
    return {
        "min": [float(x) for x in coordinates.min(axis=1)],
        "max": [float(x) for x in coordinates.max(axis=1)],
        "largest_norm": float(np.max(norms)),
    }


def outside_range(c: np.ndarray, ranges: dict, modes: int, margin: float) -> list[int]:
    """The coordinates of c (2k: the basis's first ``modes`` of p, then of its rate) that leave
    the training range (``ranges`` of :func:`coordinate_ranges`, of 2K ≥ 2k coordinates) by
    more than ``margin`` times the largest amplitude of the training's p-coordinates."""
    lo, hi = np.asarray(ranges["min"], dtype=float), np.asarray(ranges["max"], dtype=float)
    K = len(lo) // 2
    kept = np.r_[0:modes, K : K + modes]
    lo, hi = lo[kept], hi[kept]
    amplitude = np.maximum(np.abs(lo), np.abs(hi))
    slack = np.empty_like(amplitude)
    slack[:modes] = margin * amplitude[:modes].max()
    slack[modes:] = margin * amplitude[modes:].max()
    beyond = np.maximum(c - hi, lo - c)
    return [int(j) for j in np.flatnonzero(beyond > slack)]


def _loads(scene) -> str:
    """The scene's loads as canonical json (for the comparison with the training's)."""
    return json.dumps(scene.to_dict().get("loads"), sort_keys=True)


class ErrorIndicator(Observer):
    """The reduced run's error indicator and out-of-training flags (module docstring): an
    observer of a run whose solver is a :class:`~cosserat_fem.rom.galerkin.ReducedSolver`.
    ``settings``: :class:`IndicatorSettings`. After the run: ``times`` [s] and ``values`` (E at
    each sampled step's output), ``outside`` (the flags), ``seconds`` (its own wall time)."""

    def __init__(self, settings: IndicatorSettings | None = None):
        self.settings = settings or IndicatorSettings()
        self.times: list[float] = []
        self.values: list[float] = []
        self.outside: list[dict] = []
        self.seconds = 0.0  # its wall time [s], the set-up included
        self.setup_seconds = 0.0  # of which the set-up's (K assembled and factored)
        self._flagged: set[str] = set()
        self._xi = 0.0  # ξ of (10.3) at the last sample
        self._xi2 = 0.0  # Σ ξ_j² over the samples
        self._norms2 = 0.0  # Σ ‖u_p,j‖_W²
        self._tau = 0.0  # τ of the last sample
        self._stages: list[np.ndarray] = []
        self._sampling = False
        self.static: StaticResponse | None = None

    # -- set-up --------------------------------------------------------------------------
    def started(self, loop) -> None:
        t0 = time.perf_counter()
        solver, model = loop.solver, loop.model
        self.solver, self.basis = solver, solver.basis
        self.comm = model.msh.comm
        n = len(self.basis.weights)
        self.WV = self.basis.weights[:, None] * self.basis.V
        weights = getattr(loop.integrator, "b", None)
        self.stage_weights = None if weights is None else np.asarray(weights, dtype=float)
        self.omega0 = model.omega0
        self._tau = loop.state.t * self.omega0
        self.static = StaticResponse(model, loop.state.t, solver.lu_package, n)
        self.setup_seconds = time.perf_counter() - t0
        provenance = self.basis.provenance
        trained = [run.get("loads") for run in provenance.get("runs", []) if "loads" in run]
        known = [json.dumps(x, sort_keys=True) for x in trained]
        if trained and _loads(model.scene) not in known:
            self._flag("load", loop.state.t, "the scene's loads are none of the training scenes'")
        self.seconds += time.perf_counter() - t0

    def _flag(self, what: str, t: float, why: str, **extra) -> None:
        """One warning line and one summary entry per kind of flag (its first time)."""
        if what in self._flagged:
            return
        self._flagged.add(what)
        self.outside.append({"what": what, "time": float(t), "reason": why, **extra})
        LOGGER.warning("reduced run outside its training at t = %.6g s: %s (%s)", t, what, why)

    # -- the residual of the sampled steps --------------------------------------------------
    def step_attempted(self, loop, t_new: float) -> None:
        self._sampling = loop.state.accepted % self.settings.every == 0
        self._stages = []

    def solve_done(self, loop, iterations: int) -> None:
        if not self._sampling:
            return
        t0 = time.perf_counter()
        solver = self.solver
        if solver._assembler is not None:
            solver._assembler.residual()
        else:
            solver._residual()
        self._stages.append(solver.b.array.copy())
        self.seconds += time.perf_counter() - t0

    def step_rejected(self, loop, cause) -> None:
        self._stages = []

    def step_accepted(self, loop) -> None:
        """At a sampled step: its defect R (10.1), the static response e_p = K⁻¹ R_q (10.2),
        ξ (10.3) and the estimate E (10.4), and the training's range."""
        if not (self._sampling and self._stages):
            return
        t0 = time.perf_counter()
        b, basis, s = self.stage_weights, self.basis, self.settings
        if b is not None and len(b) == len(self._stages):
            R = sum(w * F for w, F in zip(b, self._stages, strict=True))
        else:  # one-stage schemes (or a count the weights do not match): the last stage's
            R = self._stages[-1]
        self._stages = []
        u = loop.model.U.x.array[: len(basis.weights)] - basis.reference
        assert self.static is not None, "started comes first"
        e = self.static.response(R)
        p, w = self.static.p_rows, basis.weights
        local = np.concatenate([self.WV.T @ u, [e @ (w[p] * e), u[p] @ (w[p] * u[p]), u @ (w * u)]])
        both = self.comm.allreduce(local) if self.comm.size > 1 else local
        t = loop.state.t
        tau = t * self.omega0
        self._xi += math.sqrt(max(float(both[-3]), 0.0)) * (tau - self._tau)
        self._tau = tau
        self._xi2 += self._xi**2
        self._norms2 += max(float(both[-2]), 0.0)
        self.times.append(float(t))
        self.values.append(relative_estimate(self._xi2, self._norms2, s.constant))
        self._check_range(both[:-3], math.sqrt(max(float(both[-1]), 0.0)), t)
        self.seconds += time.perf_counter() - t0

    def _check_range(self, c: np.ndarray, norm: float, t: float) -> None:
        """Flags a state outside the training's range (module docstring)."""
        ranges, margin = self.basis.provenance.get("coordinates"), self.settings.margin
        if not ranges:
            return
        largest = float(ranges["largest_norm"])
        if norm > (1.0 + margin) * largest:
            self._flag(
                "amplitude",
                t,
                f"the state's W-norm {norm:.3g} exceeds the training's largest {largest:.3g}",
                norm=norm,
                largest=largest,
            )
        beyond = outside_range(c, ranges, self.basis.modes, margin)
        if beyond:
            self._flag(
                "coordinates",
                t,
                f"reduced coordinate(s) {beyond[:4]} leave the training's range",
                coordinates=beyond,
            )

    # -- the end -----------------------------------------------------------------------------
    @property
    def final(self) -> float:
        return self.values[-1] if self.values else 0.0

    @property
    def largest(self) -> float:
        """The largest E after the first quarter of the samples (module docstring)."""
        settled = self.values[len(self.values) // 4 :]
        return max(settled) if settled else 0.0

    def ended(self, loop, failure) -> None:
        s = self.settings
        if self.static is not None:
            self.static.destroy()
            self.static = None
        if isinstance(failure, SolverError) and failure.time is None and self.times:
            failure.time = loop.state.t  # the step it stopped at (the chart's move)
            failure.message = failure._compose()
            failure.args = (failure.message,)
        if self.largest > s.tolerance:
            start = len(self.values) // 4
            at = self.times[start + int(np.argmax(self.values[start:]))]
            LOGGER.warning(
                "reduced run: estimated relative error %.3g exceeds the tolerance %.3g (t = "
                "%.6g s; docs/rom.md §10)",
                self.largest,
                s.tolerance,
                at,
            )

    def summary_entries(self) -> dict:
        """summary.json's ``rom`` entry (observers.py's RunSummary puts it in)."""
        s = self.settings
        return {
            "rom": {
                "indicator": {
                    "max": self.largest,
                    "final": self.final,
                    "tolerance": float(s.tolerance),
                    "exceeded": self.largest > s.tolerance,
                    "every": s.every,
                    "times": list(self.times),
                    "values": list(self.values),
                    "wall_time_s": self.seconds,
                    "setup_wall_time_s": self.setup_seconds,
                },
                "outside_training": list(self.outside),
            }
        }
