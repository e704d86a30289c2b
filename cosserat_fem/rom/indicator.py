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

**The error it makes: transported in the linear modes.** The error e = U_full − U_red obeys,
linearised about the straight rod, M ë + K e = −R_q − δ (τ = ω0 t, (47)), M, K = D⁻¹ M_sym,
D⁻¹ K_sym of cosserat_fem/analysis/modal.py (the rows over their inertia, as F's), and δ the
part of the force of e beyond K (below). In the first N normal modes of (K, M), e = Σ_j η_j φ_j,
φ_jᵀ D M φ_j = 1, each mode is an oscillator

    η̈_j + λ_j η_j = g_j,   g_j = −φ_jᵀ D (R_q + δ),                              (10.5)

forced by the residual sampled every m-th step (N dot products), the forcing taken linear
between samples, and carried between samples exactly (:func:`oscillator_step`),

    η(s) = y(s) + (a + b s)/λ,  y = free oscillation from η(0) − a/λ, η̇(0) − b/λ.      (10.6)

A resonant residual adds up coherently and a non-resonant one does not: a running sum of the
residual cannot tell them apart (it overestimated 3.5-10 times over the paper's 0.06 s). The
modes the basis spans get little forcing (Galerkin), those it misses the most. The estimate is
the relative L² free-end error of docs/rom.md §7 itself, over the sampled times,

    E_j = C (Σ_{i≤j} |ℓ e_end,i|²)^{1/2} / (Σ_{i≤j} |ℓ u_end,i|²)^{1/2},                  (10.7)

e_end, u_end the (x, y, z)/ℓ rows of e and of the reduced displacement at the free end (where
the end at σ = 1 is held: the W-norms of e_p and u_p over the rod instead); C = 1
(:data:`CONSTANT`, nothing calibrated). Reported as min(E, 1) (:data:`SATURATED`).

**The coupling.** Linear about the straight rod, (10.5) with δ = 0 holds for small
motions (measured 0.65-0.98 at a hundredth of the paper's load), but at the paper's load the
reduced state's deflection couples the error's modes (the tangent stiffness K_T(u) ≠ K: a
bending error forces axial and torsional ones and back), and the error in the basis's own
modes, which the residual hardly forces, grows through it: without δ, E/error fell to
0.07-0.5 over 0.06 s. At the last stage of a sampled step, with e of (10.6),

    δ = F_q(p + e_p, q) − F_q(p, q) − K e_p                                          (10.8)

(one more assembly of F at the stage value with p moved by e_p; φ_jᵀ D K e = λ_j η_j); it
forces only the modes the sampling resolves (:data:`RESOLVED`). Between two samples the
coupling's forcing c is taken linear, as the residual's, from c_n at the last sample to
c_{n+1} at the new one (a predictor-corrector: η of (10.6) with c held at c_n, c_{n+1} at that
η, then η again with c linear between them):

    g(s) = g_R,n + c_n + s [(g_R,n+1 − g_R,n) + (c_{n+1} − c_n)]/Δτ,               (10.10)

c_{n+1} kept for the next interval (no second assembly). Held at c_n instead, the coupling (a
stiffness: δ ≈ (K_T(u) − K) e) lags the error by half an interval, a delayed restoring
force that feeds the mode: near the first resonance, where the deflection and so K_T − K
are largest, the transport grew 13-16 times past the error (docs/rom.md §10 "At resonance").

**Out of training.** The basis's provenance records the range of the reduced coordinates
c = Vᵀ W (U − U_ref) over its snapshots (per coordinate, min and max, and the largest W-norm of a
snapshot: basis.py) and the loads of the scenes it was trained on. A run is flagged when a
coordinate leaves its range by more than ``margin`` times the training's largest coordinate
(of p, or of its rate), when the state's W-norm exceeds (1 + ``margin``) times the largest
snapshot's ("amplitude"), or when the scene's loads are not what the training ran ("load":
another form of the expressions, or a number in them or a [parameters] value outside the
trained range, :func:`outside_loads`): one warning line naming what and when (the first time
of each), and an entry in summary.json's ``rom.outside_training``.

:class:`ErrorIndicator` is the observer (cosserat_fem/timestepping/events.py) that a reduced run
(cosserat_fem/rom/runs.py ``run``, cf.rom.run) adds; its
:meth:`~ErrorIndicator.summary_entries` go into the run's summary
(cosserat_fem/analysis/observers.py, RunSummary). It also puts the time into a refusal of the
reduced run that has none (the chart's move, galerkin.ReducedSolver.set_form,
raised where the solver does not know the time).
"""

from __future__ import annotations

import hashlib
import json
import math
import re
import time
from collections import OrderedDict
from dataclasses import dataclass

import numpy as np

# SLEPc (the modes' solver) loaded by every rank that loads this module, used or not: loaded on
# some ranks of the world only, it hangs the exit (PETSc's clean-up at exit waits in an
# MPI_Comm_dup on those ranks while the others are in MPI_Finalize; measured with a basis
# trained on rank 0 alone, a hyper-reduced sweep's under mpirun -n 2, whose members then read
# the modes from its file).
from slepc4py import SLEPc  # noqa: F401

from cosserat_fem.common.errors import SceneError, SolverError
from cosserat_fem.common.log import LOGGER
from cosserat_fem.timestepping.events import Observer

#: C of (10.7): 1, nothing calibrated (measured E/error 0.41-2.43 over the checks of
#: docs/rom.md §10); a larger C makes the estimate more conservative.
CONSTANT = 1.0


@dataclass(frozen=True)
class IndicatorSettings:
    """``every``: the residual is assembled at every ``every``-th step (m of (10.5));
    ``tolerance``: the estimated relative error E (10.7) above which the run says so;
    ``constant``: C of (10.7); ``modes``: N of (10.5), the normal modes the error is carried
    in (at most the discretisation's); ``coupling``: δ of (10.8) (False: δ = 0, the linear
    transport about the straight rod); ``margin``: how far the coordinates may leave the training's
    range (a fraction of the largest coordinate's amplitude, and of the largest snapshot's
    W-norm) before the run is flagged. A hyper-reduced run's forcing is the full residual's
    too (the forcing from ECSW's sampled elements alone was measured and removed: docs/rom.md
    §10 "Cost")."""

    every: int = 10
    tolerance: float = 1e-2
    constant: float = CONSTANT
    margin: float = 0.25
    modes: int = 30
    coupling: bool = True

    def __post_init__(self) -> None:
        if not isinstance(self.coupling, bool):
            raise SceneError("indicator.coupling: must be true or false")
        if isinstance(self.every, bool) or not isinstance(self.every, int) or self.every < 1:
            raise SceneError(f"indicator.every: must be a whole number >= 1, got {self.every!r}")
        if isinstance(self.modes, bool) or not isinstance(self.modes, int) or self.modes < 1:
            raise SceneError(f"indicator.modes: must be a whole number >= 1, got {self.modes!r}")
        for name in ("tolerance", "constant", "margin"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, float | int) or not value > 0:
                raise SceneError(f"indicator.{name}: must be a positive number, got {value!r}")
            if not math.isfinite(value):
                raise SceneError(f"indicator.{name}: must be a positive number, got {value!r}")


#: E's ceiling: an error estimated as large as the motion itself (the linearisation of (10.5)
#: no longer holds). Reported values are min(E, 1); when E passes :data:`BLOWN` (or is not
#: finite: the explicit coupling (10.8) of a state far from the straight rod diverges), the modes
#: are no longer carried and E stays 1 to the run's end.
SATURATED = 1.0
#: The coupling (10.8) forces the modes the sampling resolves, ω_j Δτ ≤ RESOLVED (Δτ the
#: interval between samples): held explicit over Δτ, it would make the stiff modes diverge where
#: the state is far from the straight rod (a pendulum at 65°); the coupling that matters is in
#: the lowest modes (measured over the paper's 0.06 s: all modes or ω_j Δτ ≤ 1 or 3 give the
#: same E within 3%).
RESOLVED = 1.0
BLOWN = 1e3

#: The settings a reduced run takes by default (cosserat_fem/rom/galerkin.py ``run``).
DEFAULT = IndicatorSettings()


def relative_estimate(errors2: float, norms2: float, constant: float) -> float:
    """E = C (Σ_j |e_j|²)^{1/2} / (Σ_j |u_j|²)^{1/2} (10.7) from the two sums over the
    samples j; 0 while the state has not left its reference."""
    return constant * math.sqrt(errors2 / norms2) if norms2 > 0 else 0.0


def oscillator_step(
    eta: np.ndarray, rate: np.ndarray, lam: np.ndarray, dt: float, a: np.ndarray, b: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The exact step (10.6) of η̈ + λ η = g(s), g = a + b s over s ∈ [0, dt] (τ units), for
    each mode (arrays of the N modes, λ > 0): η − g/λ is a free oscillation, so with
    y = η − a/λ, ẏ = η̇ − b/λ at s = 0, y(dt) = y cos ω dt + ẏ/ω sin ω dt, ω = √λ, and
    η(dt) = y(dt) + (a + b dt)/λ, η̇(dt) = ẏ(dt) + b/λ. Returns (η, η̇) at dt."""
    omega = np.sqrt(lam)
    y, ydot = eta - a / lam, rate - b / lam
    c, s = np.cos(omega * dt), np.sin(omega * dt)
    return y * c + ydot / omega * s + (a + b * dt) / lam, ydot * c - y * omega * s + b / lam


def full_residual(solver, rows: np.ndarray | None = None, shift=None) -> np.ndarray:
    """F(U) of the full model at the solver's U (its owned rows, a copy): the solver's own
    assembly (the C assembler where the reduced solver has one, else DOLFINx's); with
    ``shift``, at U + ``shift`` in U's owned ``rows``, U and the solver's F vector restored after.
    The one place the indicator reads the solver's internals (cosserat_fem/rom/galerkin.py)."""
    U = solver._u_owned
    if shift is not None:
        kept_U, kept_b = U.copy(), solver.b.array.copy()
        U[rows] += shift
    if solver._assembler is not None:
        solver._assembler.residual()
    else:
        solver._residual()
    F = solver.b.array.copy()
    if shift is not None:
        U[:] = kept_U
        solver.b.array[:] = kept_b
        if solver.comm.size > 1:
            solver.U.x.scatter_forward()
    return F


#: The modes of (10.5) of this process's last runs (λ, Φ), by what determines them
#: (:func:`modes_key`): a sweep's members on one rod share one set-up. At most :data:`KEPT`
#: (a riser of 10⁴ elements: 43 MB a set of 30 modes).
_MODES: OrderedDict[str, tuple[np.ndarray, np.ndarray]] = OrderedDict()
KEPT = 2
#: How many times this process has solved for the modes (SLEPc): the set-ups not cached.
SOLVES = [0]


def rod_key(model, t: float) -> dict:
    """What K and M about the straight rod (ModalOperator at ``t``) depend on: the rod
    (length, section, material), its reference, model constants (ω0, the inertia), supports,
    damping, the discretisation and the components U holds; and the loads whose virtual work
    is not linear in the state (torques, end and point loads, which give K a load stiffness:
    cosserat_fem/analysis/modal.py), with the parameters and t when there are any. Force
    densities and gravity, in fixed directions, do no work that is not linear in the
    displacement: a sweep over their amplitude or frequency shares the modes."""
    d = model.scene.to_dict()
    loads = {
        k: v for k, v in (d.get("loads") or {}).items() if k not in ("force_density", "gravity")
    }
    torque = loads.get("torque_density")
    if isinstance(torque, list) and all(str(x).strip() in ("0", "0.0") for x in torque):
        loads.pop("torque_density")
    stiff = bool(loads)
    return {
        **{k: d.get(k) for k in ("rod", "reference", "model", "supports", "damping")},
        "discretisation": d.get("discretisation"),
        "components": [int(c) for c in model.layout.components],
        "loads": loads,
        "parameters": d.get("parameters") if stiff else None,
        "t": float(t) if stiff else None,
    }


def stored_key(model, t: float) -> str:
    """The SHA-256 of :func:`rod_key`, kept in a basis file beside the modes it stores
    (basis.py): a run on another rod solves its own."""
    text = json.dumps(rod_key(model, t), sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()


def modes_key(model, t: float, count: int, lu_package: str, n: int) -> str:
    """The process cache's key (:data:`_MODES`): :func:`rod_key`, the modes asked for, the LU
    package, this rank's rows and the ranks."""
    comm = model.msh.comm
    extra = {"count": count, "lu": lu_package, "rows": [n, comm.rank, comm.size]}
    return json.dumps({**rod_key(model, t), **extra}, sort_keys=True, default=str)


class ErrorModes:
    """The first ``count`` normal modes of the rod about the straight state (10.5): K φ = λ M φ
    with K, M = D⁻¹ K_sym, D⁻¹ M_sym of cosserat_fem/analysis/modal.py (the balance rows over
    their inertia, as F's rows; supports as K's identity rows and M's zero rows, their λ
    infinite), solved by SLEPc (shift-and-invert about 0, about −1 for a mechanism, whose
    rigid-body modes are then left out; a closed rod's shapes S φ as modal.join_ends's), each
    φ_j scaled to φ_jᵀ D M φ_j = 1 (D = diag of the kinetic weights: D M = M_sym symmetric, so
    φ_jᵀ D K φ_l = λ_j δ_jl); ``stored``: (λ, Φ on U's owned rows) of a basis file
    (``source`` "basis", :func:`stored_modes`: K and M are not even assembled), else solved once a
    process for a rod (:func:`modes_key`: a run that finds them
    has ``source`` "cached"; every rank of the communicator must find them, else all solve).
    ``n``: U's owned rows; ``places``: where U's p rows sit in the 6-component space of K;
    ``ends``: the local 6-space rows of the free end's x/ℓ, y/ℓ, z/ℓ (empty on the ranks
    without it). Planar runs: the modes out of the plane get no forcing."""

    def __init__(self, model, t: float, count: int, lu_package: str, n: int, stored=None):
        from mpi4py import MPI

        from cosserat_fem.analysis.modal import _kinetic_weights
        from cosserat_fem.rom.basis import state_rows

        self.comm = model.msh.comm
        layout = model.layout
        self.p_rows, self.q_rows = state_rows(layout, n)
        p_entries = np.asarray(layout.components[: layout.p_count])
        nodes = n // layout.size
        self.places = (np.arange(nodes)[:, None] * 6 + p_entries[None, :]).ravel()
        self.D = np.tile(_kinetic_weights(model), nodes)  # D on this rank's 6-space rows
        # the 6- and 12-component spaces share their node numbering (modal.ModalOperator)
        sigma = model.V.tabulate_dof_coordinates()[:nodes, 0]
        tip = np.flatnonzero(np.isclose(sigma, 1.0))
        self.ends = (6 * tip[:1, None] + np.arange(3)[None, :]).ravel()
        key = modes_key(model, t, count, lu_package, n)
        found = _MODES.get(key)
        hit = found is not None
        if self.comm.size > 1:
            hit = bool(self.comm.allreduce(int(hit), op=MPI.MIN))
        self.source = "cached" if hit else "solved"
        if stored is not None:  # (λ, Φ on U's rows) of a basis file, this rank's rows
            lam, on_rows = stored
            self.lam = np.asarray(lam, dtype=float)[:count]
            self.Phi = np.zeros((len(self.D), len(self.lam)))
            self.Phi[self.places] = on_rows[self.p_rows, : len(self.lam)]
            self.source = "basis"
        elif hit and found is not None:
            _MODES.move_to_end(key)
            self.lam, self.Phi = found
        else:
            self.lam, self.Phi = self._solve(model, t, count, lu_package)
            SOLVES[0] += 1
            _MODES[key] = (self.lam, self.Phi)
            while len(_MODES) > KEPT:
                _MODES.popitem(last=False)
        self.DPhi = (self.D[:, None] * self.Phi)[self.places]  # on U's p rows' places

    def on_rows(self, n: int) -> np.ndarray:
        """Φ on U's n owned rows (p's rows; zero on q's): what a basis file stores."""
        out = np.zeros((n, len(self.lam)))
        out[self.p_rows] = self.Phi[self.places]
        return out

    def _solve(self, model, t: float, count: int, lu_package: str):
        """(λ, Φ) of the class docstring, by SLEPc (collective)."""
        from cosserat_fem.analysis.modal import ModalOperator, max_modes, shift_invert

        problem = ModalOperator(model, t).problem()
        K, M, joint = problem.K, problem.M, problem.joint
        most = max_modes(model.scene)
        count = min(count, most)
        eps = shift_invert(problem, count, min(max(2 * count + 10, 30), most), 1e-10, lu_package)
        vr, vi = K.createVecs()
        Mv, shape = vr.duplicate(), vr.duplicate()
        pairs = []
        for i in range(min(eps.getConverged(), count)):
            lam = eps.getEigenpair(i, vr, vi)
            M.mult(vr, Mv)  # φᵀ D M φ in the (joined, for a ring) space of the eigenproblem
            scale = self._sum(np.array([vr.array @ (self.D[: len(vr.array)] * Mv.array)]))[0]
            if joint is not None:  # a closed rod's shape is S φ (modal.join_ends)
                joint.mult(vr, shape)
            else:
                vr.copy(shape)
            pairs.append((complex(lam).real, shape.array / math.sqrt(abs(scale))))
        eps.destroy()
        for item in (vr, vi, Mv, shape):
            item.destroy()
        problem.destroy()
        # the rigid-body modes of a mechanism (λ = 0 to round-off, of either sign) not carried
        rigid = model.scene.supports.rigid_body_modes()
        pairs = [p for p in sorted(pairs, key=lambda p: p[0])[rigid:] if p[0] > 0]
        if not pairs:
            raise SolverError("no normal mode found for the error indicator", where="indicator")
        return np.array([pair[0] for pair in pairs]), np.column_stack([pair[1] for pair in pairs])

    def _sum(self, local: np.ndarray) -> np.ndarray:
        return self.comm.allreduce(local) if self.comm.size > 1 else local

    def forcing(self, Rq: np.ndarray) -> np.ndarray:
        """g = −Φᵀ D R (10.5) of the rate rows R of U (their order that of U's p rows); the
        modes' forcing, summed over the ranks."""
        return -self._sum(self.DPhi.T @ Rq)

    def shape(self, eta: np.ndarray) -> np.ndarray:
        """e = Σ_j η_j φ_j on this rank's 6-space rows."""
        return self.Phi @ eta


def basis_modes(model, n: int, count: int | None = None) -> tuple[np.ndarray, np.ndarray, dict]:
    """The modes of (10.5) for a basis file (cosserat_fem/rom/basis.py ``pod_basis``): λ, Φ on
    U's n owned rows, and the provenance entry {"key": :func:`stored_key`, "modes": N} that a
    run checks before it uses them (the training's start time; collective)."""
    from cosserat_fem.nls.newton import NewtonSolver

    t = model.scene.time.start
    count = DEFAULT.modes if count is None else count
    lu = NewtonSolver._lu_package(model.msh.comm, "auto")
    modes = ErrorModes(model, t, count, lu, n)
    entry = {"key": stored_key(model, t), "asked": count, "modes": len(modes.lam)}
    return modes.lam, modes.on_rows(n), entry


def stored_modes(basis, model, t: float, count: int):
    """(λ, Φ on U's rows) of ``basis`` if it stores the first ``count`` modes (it asked for as
    many or more) of this rod (:func:`stored_key` at ``t``), else None: solved at run time."""
    entry = basis.provenance.get("error_modes")
    if basis.error_modes is None or basis.error_lambda is None or not isinstance(entry, dict):
        return None
    if entry.get("key") != stored_key(model, t) or count > int(entry.get("asked", 0)):
        return None
    return basis.error_lambda, basis.error_modes


def coordinate_ranges(coordinates: np.ndarray, norms: np.ndarray) -> dict:
    """The provenance entry of a basis's training range: ``coordinates`` (2k, T) the reduced
    coordinates c = Vᵀ W u_i of the T snapshots, ``norms`` (T,) their W-norms."""
    return {
        "min": [float(x) for x in coordinates.min(axis=1)],
        "max": [float(x) for x in coordinates.max(axis=1)],
        "largest_norm": float(np.max(norms)),
    }


def range_limits(ranges: dict, modes: int, margin: float):
    """(lo, hi, slack) of :func:`outside_range`: the training's range of the basis's first
    ``modes`` coordinates of p and of its rate and how far each may leave it (computed once a
    run)."""
    lo, hi = np.asarray(ranges["min"], dtype=float), np.asarray(ranges["max"], dtype=float)
    K = len(lo) // 2
    kept = np.r_[0:modes, K : K + modes]
    lo, hi = lo[kept], hi[kept]
    amplitude = np.maximum(np.abs(lo), np.abs(hi))
    slack = np.empty_like(amplitude)
    slack[:modes] = margin * amplitude[:modes].max()
    slack[modes:] = margin * amplitude[modes:].max()
    return lo, hi, slack


def outside_range(c: np.ndarray, ranges: dict, modes: int, margin: float) -> list[int]:
    """The coordinates of c (2k: the basis's first ``modes`` of p, then of its rate) that leave
    the training range (``ranges`` of :func:`coordinate_ranges`, of 2K ≥ 2k coordinates) by
    more than ``margin`` times the largest amplitude of the training's p-coordinates."""
    return _beyond(c, *range_limits(ranges, modes, margin))


def _beyond(c: np.ndarray, lo: np.ndarray, hi: np.ndarray, slack: np.ndarray) -> list[int]:
    return [int(j) for j in np.flatnonzero(np.maximum(c - hi, lo - c) > slack)]


def _loads(scene) -> str:
    """The scene's loads as canonical json (for the comparison with the training's)."""
    return json.dumps(scene.to_dict().get("loads"), sort_keys=True)


#: A number written in an expression (not a digit of a name: omega0, f2).
_NUMBER = re.compile(r"(?<![A-Za-z_0-9.])(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?(?![A-Za-z_0-9])")


def load_values(scene) -> dict:
    """What a run's loads are, for a basis's provenance (each training run's ``load_values``)
    and the comparison with it (:func:`outside_loads`): ``form``, the loads with every number
    written in them replaced by "#" (canonical JSON: the expressions' shape), and ``values``,
    those numbers by name ("loads.force_density[0]#1": the first number of that
    component's expression, e.g. its amplitude 2e3; "#2" the next, e.g. the 8 of
    sin(8*omega0*t)) and the scene's [parameters] ("parameters.r"), all as floats."""
    d = scene.to_dict()
    values: dict[str, float] = {}

    def form(x, path: str):
        if isinstance(x, bool) or x is None:
            return x
        if isinstance(x, int | float):
            values[path] = float(x)
            return "#"
        if isinstance(x, str):
            for i, match in enumerate(_NUMBER.finditer(x)):
                values[f"{path}#{i + 1}"] = float(match.group())
            return _NUMBER.sub("#", x)
        if isinstance(x, list | tuple):
            return [form(v, f"{path}[{i}]") for i, v in enumerate(x)]
        if isinstance(x, dict):
            return {k: form(v, f"{path}.{k}") for k, v in sorted(x.items())}
        return str(x)

    shape = form(d.get("loads"), "loads")
    for name, value in sorted((d.get("parameters") or {}).items()):
        values[f"parameters.{name}"] = float(value)
    return {"form": json.dumps(shape, sort_keys=True), "values": values}


def outside_loads(mine: dict, trained: list[dict], margin: float) -> str | None:
    """Why a run's loads (:func:`load_values`) are outside those of the training runs
    (``trained``: theirs), or None. Outside: a form none of them has (another expression:
    a load added, removed or written otherwise), or a value beyond the range [lo, hi] the
    runs of that form trained on by more than ``margin`` (hi − lo) (+ 1e-12 max(|lo|, |hi|)
    for round-off), or a parameter they did not have. A range trained on one value (hi = lo)
    admits that value only: any other amplitude or frequency was not trained, as the text
    comparison of the loads said before. A range trained on several admits a quarter of its
    width beyond it (``margin`` 0.25, the coordinates' own, :func:`range_limits`): a sweep's
    members interpolate, and a step of a quarter of the spacing of the training's ends is
    what the coordinates' range admits of the states."""
    same = [run["values"] for run in trained if run.get("form") == mine["form"]]
    if not same:
        return "the scene's loads are none of the training scenes' (another expression)"
    for name, value in mine["values"].items():
        seen = [v[name] for v in same if name in v]
        if not seen:
            return f"{name} = {value:g} was not a parameter of the training"
        lo, hi = min(seen), max(seen)
        slack = margin * (hi - lo) + 1e-12 * max(abs(lo), abs(hi))
        if value < lo - slack or value > hi + slack:
            return (
                f"{name} = {value:g} outside the trained range [{lo:g}, {hi:g}] "
                f"(by more than {margin:g} of its width)"
            )
    return None


class ErrorIndicator(Observer):
    """The reduced run's error indicator and out-of-training flags (module docstring): an
    observer of a run whose solver is a :class:`~cosserat_fem.rom.galerkin.ReducedSolver`.
    ``settings``: :class:`IndicatorSettings`. After the run: ``times`` [s] and ``values`` (E at
    each sampled step's output), ``outside`` (the flags), ``seconds`` (its own wall time).
    In reduced coordinates (cosserat_fem/timestepping/loop.py) it asks for the full state at
    its sampled steps only (``loop.lift()``), not at every event."""

    #: The time loop lifts U in full before this observer's hooks only when it asks.
    needs_full_state = False

    def __init__(
        self,
        settings: IndicatorSettings | None = None,
        previous: dict | None = None,
        state: dict | None = None,
    ):
        """``previous``: the ``rom`` entry of the summary of the run this one continues (a
        restart): its samples, flags and restarts are kept before this part's. ``state``: the
        checkpoint's ``indicator`` part (:meth:`checkpoint_parts`), the modes' η, η̇ and the
        sums of (10.7) at the checkpoint: carried on from there (``carried``), so that the
        restarted run's E is the straight run's; without it (a checkpoint written before the
        indicator kept its state, or one of other settings) the modes start from zero again."""
        self.settings = settings or IndicatorSettings()
        self.previous = previous if isinstance(previous, dict) else {}
        self.state = state if isinstance(state, dict) else None
        self.carried = False  # the checkpoint's modal state was restored (``state``)
        self.restarted_at: float | None = None
        self.times: list[float] = []
        self.values: list[float] = []
        self.outside: list[dict] = []
        self.seconds = 0.0  # its wall time [s], the set-up included
        self.setup_seconds = 0.0  # of which the set-up's (K, M assembled, the modes solved)
        self._flagged: set[str] = set()
        self._errors2 = 0.0  # Σ_j |e_end,j|² over the samples (10.7)
        self._norms2 = 0.0  # Σ_j |u_end,j|²
        self._rod_errors2 = self._rod_norms2 = 0.0  # the same in W-norms over the rod
        self._eta = self._rate = np.zeros(0)  # the modes' η, η̇ at the last sample
        self._tau = 0.0  # τ of the last sample
        self._g = np.zeros(0)  # the forcing of R at the last sample, and of the coupling:
        self._coupling = np.zeros(0)  # g of (10.5)'s two parts
        self._pending: tuple | None = None  # a sampled step's new values, until it is accepted
        self._stages: list[np.ndarray] = []
        self._sampling = False
        self._saturated = False  # the transport blew up (:data:`BLOWN`)
        self._t_new = 0.0
        self.modes: ErrorModes | None = None
        self.modes_from = ""  # the modes "solved" (SLEPc), "cached" (this process's), or "basis"

    # -- set-up --------------------------------------------------------------------------
    def started(self, loop) -> None:
        t0 = time.perf_counter()
        if self.previous:
            self.restarted_at = float(loop.state.t)
        solver, model = loop.solver, loop.model
        self.solver, self.basis = solver, solver.basis
        self.comm = model.msh.comm
        self.length = model.rod.length
        n = len(self.basis.weights)
        self.WV = self.basis.weights[:, None] * self.basis.V
        weights = getattr(loop.integrator, "b", None)
        self.stage_weights = None if weights is None else np.asarray(weights, dtype=float)
        self.omega0 = model.omega0
        self._tau = loop.state.t * self.omega0
        t, count = loop.state.t, self.settings.modes
        stored = stored_modes(self.basis, model, t, count)
        self.modes = ErrorModes(model, t, count, solver.lu_package, n, stored)
        self.modes_from = self.modes.source
        m = self.modes  # V's rows of the free end's x/ℓ, y/ℓ, z/ℓ (of U's p rows)
        self._tip_V = self.basis.V[m.p_rows[np.isin(m.places, m.ends)]]
        count = len(self.modes.lam)
        self._eta, self._rate = np.zeros(count), np.zeros(count)
        self._g, self._coupling = np.zeros(count), np.zeros(count)
        self._first = True
        self._flagged = {str(x.get("what")) for x in self.previous.get("outside_training") or []}
        if self.state is not None:
            self._restore(self.state)
        self.setup_seconds = time.perf_counter() - t0
        provenance = self.basis.provenance
        ranges = provenance.get("coordinates")  # as arrays once (outside_range takes either)
        self._ranges = ranges and {
            "min": np.asarray(ranges["min"], dtype=float),
            "max": np.asarray(ranges["max"], dtype=float),
            "largest_norm": float(ranges["largest_norm"]),
        }
        self._limits = self._ranges and range_limits(
            self._ranges, self.basis.modes, self.settings.margin
        )
        runs = [run for run in provenance.get("runs", []) if "loads" in run]
        if runs and all("load_values" in run for run in runs):  # the numbers trained on
            why = outside_loads(
                load_values(model.scene),
                [run["load_values"] for run in runs],
                self.settings.margin,
            )
            if why is not None:
                self._flag("load", loop.state.t, why)
        elif runs:  # a basis of before the numbers: the loads' text
            known = [json.dumps(run.get("loads"), sort_keys=True) for run in runs]
            if _loads(model.scene) not in known:
                why = "the scene's loads are none of the training scenes'"
                self._flag("load", loop.state.t, why)
        self.seconds += time.perf_counter() - t0

    # -- checkpoint/restart -----------------------------------------------------------------
    #: The part of a checkpoint that holds the indicator's state (TimeLoop.state_dict).
    PART = "indicator"

    def checkpoint_parts(self) -> dict:
        """{"indicator": its state at the checkpoint}: η, η̇, τ and the forcings g_R, c of the
        last sample (10.6, 10.10), the sums of (10.7), whether the first sample is still to
        come or the transport has saturated, and the settings they depend on (``every``,
        ``modes``, ``coupling``: a restart with other settings starts from zero). Written at
        the end of a step, where no sampled step is pending."""
        s = self.settings
        sums = [self._errors2, self._norms2, self._rod_errors2, self._rod_norms2]
        return {
            self.PART: {
                "eta": self._eta.copy(),
                "rate": self._rate.copy(),
                "g": self._g.copy(),
                "coupling": self._coupling.copy(),
                "tau": self._tau,
                "sums": np.array(sums),
                "first": float(self._first),
                "saturated": float(self._saturated),
                "settings": np.array([s.every, s.modes, float(s.coupling)], dtype=float),
            }
        }

    def _restore(self, state: dict) -> None:
        """The inverse of :meth:`checkpoint_parts` (at :meth:`started`, the modes known), when
        the settings and the modes' count are those of the checkpoint; the earlier parts'
        samples become this run's first ones (E's running sums continue: ``carried``)."""
        s = self.settings
        settings = np.array([s.every, s.modes, float(s.coupling)], dtype=float)
        eta = np.asarray(state.get("eta", ()), dtype=float)
        if not (
            np.array_equal(np.asarray(state.get("settings", ())), settings)
            and eta.shape == self._eta.shape
        ):
            LOGGER.warning(
                "reduced run: the indicator's state in the checkpoint is of other settings or "
                "modes; its modes start from zero at the restart"
            )
            return
        self._eta, self._rate = eta.copy(), np.asarray(state["rate"], dtype=float).copy()
        self._g = np.asarray(state["g"], dtype=float).copy()
        self._coupling = np.asarray(state["coupling"], dtype=float).copy()
        self._tau = float(state["tau"])
        sums = [float(x) for x in np.asarray(state["sums"])]
        self._errors2, self._norms2, self._rod_errors2, self._rod_norms2 = sums
        self._first, self._saturated = bool(state["first"]), bool(state["saturated"])
        before = self.previous.get("indicator") if self.previous else None
        before = before if isinstance(before, dict) else {}
        self.times = [float(x) for x in before.get("times", [])]
        self.values = [float(x) for x in before.get("values", [])]
        self.carried = True

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
        self._pending = None
        self._t_new = t_new

    def solve_done(self, loop, iterations: int) -> None:
        """At each stage of a sampled step: F_i (10.1); at its last, the step's defect R, the
        modes carried to the step's end (10.6) and the coupling at the new error (10.8)."""
        if not self._sampling or self._saturated:
            return
        t0 = time.perf_counter()
        loop.lift()  # U and the stage's Z in full (nothing to do on full vectors)
        self._stages.append(full_residual(self.solver))
        b = self.stage_weights
        if b is None or len(self._stages) == len(b):
            self._advance(loop)
        self.seconds += time.perf_counter() - t0

    def _advance(self, loop) -> None:
        """The sampled step's new η, η̇ (kept in ``_pending`` until the step is accepted): the
        forcing of R linear between the samples (10.6), the coupling's too (10.10): predicted
        with c_n held, corrected with c linear from c_n to c_{n+1} at the predicted η (from the
        start, c_0 = 0 with e = 0, the first interval is the prediction's)."""
        modes, b = self.modes, self.stage_weights
        assert modes is not None, "started comes first"
        if b is not None and len(b) == len(self._stages):
            R = sum(w * F for w, F in zip(b, self._stages, strict=True))
        else:  # one-stage schemes: the last stage's
            R = self._stages[-1]
        g = modes.forcing(R[modes.q_rows])
        if self._first:  # the forcing held from the start to the first sample
            self._g = g
        tau = self._t_new * self.omega0
        dt = tau - self._tau
        a = self._g + self._coupling
        slope = (g - self._g) / dt if dt > 0 else np.zeros_like(g)
        eta, rate = oscillator_step(self._eta, self._rate, modes.lam, dt, a, slope)
        coupling = self._coupling
        if self.settings.coupling:  # −Φᵀ D δ of (10.8): φ_jᵀ D K φ_l = λ_j δ_jl, so K e is Λ η
            coupling = modes.forcing(self._difference(modes.shape(eta))) + modes.lam * eta
            coupling = np.where(np.sqrt(modes.lam) * dt <= RESOLVED, coupling, 0.0)
            if dt > 0 and not self._first:  # (10.10): the coupling linear over the interval
                turn = slope + (coupling - self._coupling) / dt
                eta, rate = oscillator_step(self._eta, self._rate, modes.lam, dt, a, turn)
        e = modes.shape(eta)
        self._pending = (eta, rate, tau, g, coupling, e)

    def _difference(self, e: np.ndarray) -> np.ndarray:
        """F_q(p + e_p, q) − F_q(p, q) at the last stage's state, of which δ (10.8) is the part
        beyond the linear stiffness about the straight rod (the geometric coupling of the
        error's modes through the reduced state); one assembly."""
        modes = self.modes
        assert modes is not None, "started comes first"
        shifted = full_residual(self.solver, modes.p_rows, e[modes.places])
        q = modes.q_rows
        return shifted[q] - self._stages[-1][q]

    def step_rejected(self, loop, cause) -> None:
        self._stages = []
        self._pending = None

    def step_accepted(self, loop) -> None:
        """At a sampled step: the new η, η̇ and the estimate E (10.7), and the training's
        range."""
        saturated = self._saturated
        if not (self._sampling and (self._pending is not None or saturated)):
            return
        t0 = time.perf_counter()
        self._stages = []
        assert self.modes is not None, "started comes first"
        if saturated:  # the modes are no longer carried (:data:`SATURATED`)
            e = np.zeros(len(self.modes.D))
        else:
            assert self._pending is not None
            eta, rate, tau, g, coupling, e = self._pending
            self._eta, self._rate, self._tau, self._g = eta, rate, tau, g
            self._coupling, self._first = coupling, False
        self._pending = None
        if self.solver.basis is not self.basis:
            self._follow_chart(self.solver.basis)
        basis, space = self.basis, loop.space
        with np.errstate(over="ignore", invalid="ignore"):
            if space.reduced:  # U = U_ref + V c: its sums from c, nothing lifted
                local = self._sums_reduced(e, space.values(loop.model.U))
            else:
                u = loop.model.U.x.array[: len(basis.weights)] - basis.reference
                u6 = np.zeros(len(self.modes.D))
                u6[self.modes.places] = u[self.modes.p_rows]
                local = self._sums(e, u, u6)
        both = self.comm.allreduce(local) if self.comm.size > 1 else local
        self._errors2 += max(float(both[-5]), 0.0)
        self._norms2 += max(float(both[-4]), 0.0)
        self._rod_errors2 += max(float(both[-3]), 0.0)
        self._rod_norms2 += max(float(both[-2]), 0.0)
        t = loop.state.t
        self.times.append(float(t))
        if self._norms2 > 1e-20 * self._rod_norms2:
            E = relative_estimate(self._errors2, self._norms2, self.settings.constant)
        else:  # the end at σ = 1 held: the rod's W-norms instead
            E = relative_estimate(self._rod_errors2, self._rod_norms2, self.settings.constant)
        self._saturated = saturated or not E < BLOWN
        self.values.append(SATURATED if self._saturated else min(E, SATURATED))
        self._check_range(both[:-5], math.sqrt(max(float(both[-1]), 0.0)), t)
        self.seconds += time.perf_counter() - t0

    def _follow_chart(self, basis) -> None:
        """The solver's basis of a new chart (galerkin.ReducedSolver.follow_chart, docs/rom.md
        §9): the coordinates' W V, the free end's rows and the training's range are its own
        from now on; the modes' state η, η̇ is carried on (the error's positions do not
        depend on the chart; its angles change with it by a rotation near the rod's)."""
        m = self.modes
        assert m is not None, "started comes first"
        self.basis = basis
        self.WV = basis.weights[:, None] * basis.V
        self._tip_V = basis.V[m.p_rows[np.isin(m.places, m.ends)]]
        ranges = basis.provenance.get("coordinates")
        self._ranges = ranges and {
            "min": np.asarray(ranges["min"], dtype=float),
            "max": np.asarray(ranges["max"], dtype=float),
            "largest_norm": float(ranges["largest_norm"]),
        }
        self._limits = self._ranges and range_limits(
            self._ranges, basis.modes, self.settings.margin
        )

    def _sums(self, e: np.ndarray, u: np.ndarray, u6: np.ndarray) -> np.ndarray:
        """This rank's c = Vᵀ W u, |ℓ e_end|², |ℓ u_end|², ‖e_p‖_W², ‖u_p‖_W², ‖u‖_W²."""
        modes, ell, w = self.modes, self.length, self.basis.weights
        assert modes is not None, "started comes first"
        ends, places, p = modes.ends, modes.places, modes.p_rows
        return np.concatenate(
            [
                self.WV.T @ u,
                [
                    float(np.sum((ell * e[ends]) ** 2)),
                    float(np.sum((ell * u6[ends]) ** 2)),
                    float(e[places] @ (w[p] * e[places])),
                    float(u[p] @ (w[p] * u[p])),
                    u @ (w * u),
                ],
            ]
        )

    def _sums_reduced(self, e: np.ndarray, c: np.ndarray) -> np.ndarray:
        """:meth:`_sums` of U = U_ref + V c in reduced coordinates (serial), O(k) but for e's:
        c itself, u_end = V_end c, and the W-norms ‖u_p‖_W² = Σ_{j≤k} c_j², ‖u‖_W² = Σ c_j²
        (Vᵀ W V = I), equal to the lifted state's to round-off."""
        modes, ell, w, k = self.modes, self.length, self.basis.weights, self.basis.modes
        assert modes is not None, "started comes first"
        ends, places, p = modes.ends, modes.places, modes.p_rows
        ep = e[places]
        u_end = self._tip_V @ c
        return np.concatenate(
            [
                c,
                [
                    float(np.sum((ell * e[ends]) ** 2)),
                    float(np.sum((ell * u_end) ** 2)),
                    float(ep @ (w[p] * ep)),
                    float(c[:k] @ c[:k]),
                    float(c @ c),
                ],
            ]
        )

    def _check_range(self, c: np.ndarray, norm: float, t: float) -> None:
        """Flags a state outside the training's range (module docstring)."""
        ranges, margin = self._ranges, self.settings.margin
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
        beyond = _beyond(c, *self._limits)
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
    def _settled(self) -> int:
        """The first sample counted: after the first quarter of them, and never the first of
        several (E there divides by a state still near rest: 1.0 in a run of 3 samples)."""
        n = len(self.values)
        return max(1, n // 4) if n > 1 else 0

    @property
    def largest(self) -> float:
        """The largest E after the first quarter of the samples (module docstring)."""
        settled = self.values[self._settled :]
        return max(settled) if settled else 0.0

    def ended(self, loop, failure) -> None:
        s = self.settings
        self.modes = None
        if isinstance(failure, SolverError) and failure.time is None and self.times:
            failure.time = loop.state.t  # the step it stopped at (the chart's move)
            failure.message = failure._compose()
            failure.args = (failure.message,)
        if self.largest > s.tolerance:
            start = self._settled
            at = self.times[start + int(np.argmax(self.values[start:]))]
            LOGGER.warning(
                "reduced run: estimated relative error %.3g exceeds the tolerance %.3g (t = "
                "%.6g s; docs/rom.md §10)",
                self.largest,
                s.tolerance,
                at,
            )

    def summary_entries(self) -> dict:
        """summary.json's ``rom`` entry (observers.py's RunSummary puts it in). A restarted
        run's keeps the earlier parts' samples, largest E and flags before its own, and lists
        the times it was restarted at (``restarts``). Its modes' state carried on from the
        checkpoint (``carried``, :meth:`checkpoint_parts`), E is the straight run's; else
        (an older checkpoint) the part carried the error from zero again, and its E does not
        count the error made before it."""
        s = self.settings
        before = self.previous.get("indicator") if self.previous else None
        before = before if isinstance(before, dict) else {}
        if self.carried:  # the earlier samples are this run's own (_restore)
            before = {"restarts": before.get("restarts", [])}
        largest = max(self.largest, float(before.get("max", 0.0) or 0.0))
        restarts = list(before.get("restarts", []))
        if self.restarted_at is not None:
            restarts.append(self.restarted_at)
        outside = list(self.previous.get("outside_training", []) or []) if self.previous else []
        return {
            "rom": {
                "indicator": {
                    "max": largest,
                    "final": self.final,
                    "tolerance": float(s.tolerance),
                    "exceeded": largest > s.tolerance,
                    "every": s.every,
                    "times": [*before.get("times", []), *self.times],
                    "values": [*before.get("values", []), *self.values],
                    "restarts": restarts,
                    "carried": self.carried,
                    "wall_time_s": self.seconds,
                    "setup_wall_time_s": self.setup_seconds,
                    "modes_from": self.modes_from,
                },
                "outside_training": [*outside, *self.outside],
            }
        }
