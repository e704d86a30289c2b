"""Stability of a static equilibrium, and the critical load factor where it is lost; the
modes about the straight rod or a static state (:func:`compute_modes`, ``cf.modes``).

A load factor f multiplies every load of the scene (the load stepping's λ of
cosserat_fem/analysis/statics.py: ``model.load_factor``). At each f the static state U(f) is found
by load stepping from the nearest state already found, and the rod's motions about it are those
of cosserat_fem/analysis/modal.py: M p̈ + K(f) p = 0, with K the tangent of the static residual, load
stiffness included (the stress stiffening, torques in fixed directions, the non-symmetric
part of a follower end load, forms/follower.py). Modes e^{iωt} φ solve K φ = λ M φ (λ in units
of ω0², ω = ω0 √λ), and the state is

* **stable** when every λ found is real and positive (every mode oscillates);
* **divergence** (static instability, buckling) when a λ is real and negative: the mode grows
  like e^{ω0 √−λ t};
* **flutter** when a pair of λ is complex: two frequencies met and left the real axis, and the
  mode grows like e^{ω0 Im √λ t} while it oscillates

(:func:`cosserat_fem.analysis.modal.eigenvalue_kind` separates these from round-off). Only the
``count`` eigenvalues nearest to 0 are computed (shift-and-invert about 0): the ones that cross
0, or collide, first.

**Critical factor.** The factors of a grid are visited in increasing order up to the first
unstable state (those beyond are not solved); the first interval [a, b] with a stable state
at a and an unstable one at b brackets the loss of stability. In it
a continuous function of f that changes sign there is driven to 0 by Brent's method (bisection
safeguarding inverse quadratic interpolation; scipy.optimize.brentq) to |Δf| ≤ ``tolerance``
(1 + |f|):

* divergence: λ_min(f), the lowest real eigenvalue, which crosses 0 linearly (a simple root);
* flutter: the discriminant of the colliding pair, d(f) = (λ2 − λ1)² as a real number: two
  real eigenvalues of the same kind of motion (bending-x, ...) next to each other, or the
  complex pair λr ± i λi, for which d = −4 λi². Near the collision λ1,2 = a ± √(c (f* − f)),
  so d = 4 c (f* − f) is smooth and changes sign at f*, where the square root of λ1 − λ2 would
  not (its derivative is infinite there). The pair is the one whose real part is nearest the
  complex pair found at b; the same kind is asked so that a second plane of bending with the
  same frequencies (a square section) is not taken for a collision.

When both functions change sign over [a, b], the smaller root is the critical factor. The
tolerance is that of the root finder: the critical factor's error is the discretisation's
(eigenvalues of degree-k elements converge as h^(2k)), which the checks bound
(tests/test_stability.py, docs/equilibrium-stability.md).

The static states are solved in 3D (the modes leave a plane of loading), without the moving
chart of large rotations (cosserat_fem/rod/charts.py): the rod's angle θ must stay away from π/2
along the path, which load stepping checks (a SolverError otherwise). A factor beyond a limit
point (a fold, where the static path turns back) has no state to step to: load stepping
fails there with its reason; follow such paths with the continuation of issue 27 item 2.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from mpi4py import MPI

from cosserat_fem.analysis import budget
from cosserat_fem.analysis.modal import (
    ModalOperator,
    Mode,
    assemble_modal_problem,
    check_count,
    eigenvalue_kind,
    solve_eigenproblem,
    write_modes,
)
from cosserat_fem.analysis.observers import summary_start
from cosserat_fem.analysis.statics import StaticLoop, check_static_scene, static_solver
from cosserat_fem.common.errors import SceneError, SolverError
from cosserat_fem.common.parallel import ranks_on_node
from cosserat_fem.io.folder_lock import holding_folders
from cosserat_fem.io.run_folder import prepare_output_dir, write_summary
from cosserat_fem.rod.model import RodModel, build_model
from cosserat_fem.scene.build import Scene
from cosserat_fem.timestepping.events import Events

#: The kinds of state, in the order a state with both instabilities reports them.
STATUSES = ("stable", "flutter", "divergence")


@dataclass
class StabilityPoint:
    """The state at load factor ``factor``: the eigenvalues λ of K φ = λ M φ nearest 0
    (dimensionless, units of ω0², sorted by real part), the kind of motion of each mode
    (cosserat_fem/analysis/modal.py KINDS), and ``status``: "stable", "divergence" or "flutter" (the
    module docstring; flutter first when a state has both)."""

    factor: float
    eigenvalues: np.ndarray
    kinds: list[str]
    status: str

    @classmethod
    def of(cls, factor: float, modes: Sequence[Mode]) -> StabilityPoint:
        lams = np.array([m.eigenvalue for m in modes], dtype=complex)
        scale = float(np.abs(lams).max()) if lams.size else 1.0
        found = {eigenvalue_kind(complex(lam), scale) for lam in lams}
        status = next((s for s in STATUSES[1:] if s in found), "stable")
        return cls(factor, lams, [m.kind for m in modes], status)

    @property
    def stable(self) -> bool:
        return self.status == "stable"

    @property
    def diverges(self) -> bool:
        """Whether a real eigenvalue is negative beyond round-off
        (:func:`~cosserat_fem.analysis.modal.eigenvalue_kind`)."""
        scale = float(np.abs(self.eigenvalues).max())
        return any(eigenvalue_kind(lam, scale) == "divergence" for lam in self.eigenvalues)

    def lowest_real(self) -> float:
        """λ_min: the lowest real part among the real eigenvalues (divergence's function)."""
        scale = float(np.abs(self.eigenvalues).max())
        real = [lam.real for lam in self.eigenvalues if eigenvalue_kind(lam, scale) != "flutter"]
        return min(real) if real else math.inf

    def complex_pair(self) -> tuple[float, str] | None:
        """(real part, kind) of the complex pair nearest 0, None if there is none."""
        scale = float(np.abs(self.eigenvalues).max())
        pairs = [
            (abs(lam), lam.real, kind)
            for lam, kind in zip(self.eigenvalues, self.kinds, strict=True)
            if eigenvalue_kind(lam, scale) == "flutter"
        ]
        return min(pairs)[1:] if pairs else None

    def discriminant(self, near: float, kind: str) -> float | None:
        """d = (λ2 − λ1)² of the pair whose real part is nearest ``near`` (flutter's function,
        module docstring): a complex pair's −4 λi², or two neighbouring real eigenvalues of
        the kind of motion ``kind``; None if there is no such pair."""
        scale = float(np.abs(self.eigenvalues).max())
        candidates = []  # (distance of the pair's middle to near, d)
        real = []
        for lam, k in zip(self.eigenvalues, self.kinds, strict=True):
            if eigenvalue_kind(lam, scale) == "flutter":
                candidates.append((abs(lam.real - near), -4.0 * lam.imag**2))
            elif k == kind:
                real.append(lam.real)
        real.sort()
        for low, high in zip(real, real[1:], strict=False):
            candidates.append((abs(0.5 * (low + high) - near), (high - low) ** 2))
        return min(candidates)[1] if candidates else None

    def as_dict(self) -> dict:
        return {
            "factor": self.factor,
            "status": self.status,
            "eigenvalues": [[lam.real, lam.imag] for lam in self.eigenvalues],
            "kinds": self.kinds,
        }


@dataclass
class StabilityResult:
    """The states visited (``points``, by factor: the grid's and the root finder's), and the
    critical load factor ``critical`` where stability is lost (None if it is not lost in the
    range, or already lost at its start: ``reason`` says which), its ``kind`` ("divergence" or
    "flutter"), the ``bracket`` [a, b] it was found in, the root finder's ``tolerance`` and
    ``evaluations`` (its function evaluations), and the scene's loads at factor 1
    (``loads``: the critical loads are critical × these)."""

    points: list[StabilityPoint]
    critical: float | None = None
    kind: str | None = None
    bracket: tuple[float, float] | None = None
    tolerance: float = 0.0
    evaluations: int = 0
    reason: str = ""
    loads: dict = field(default_factory=dict)

    def as_dict(self) -> dict:
        return {
            "critical_factor": self.critical,
            "instability": self.kind,
            "bracket": list(self.bracket) if self.bracket else None,
            "tolerance": self.tolerance,
            "root_evaluations": self.evaluations,
            "reason": self.reason,
            "loads_at_factor_1": self.loads,
            "points": [p.as_dict() for p in sorted(self.points, key=lambda p: p.factor)],
        }


class Equilibria:
    """Static states of one scene at load factors, and the modes and eigenvalues about each.

    One 3D model, one Newton solver and one :class:`~cosserat_fem.analysis.modal.ModalOperator`
    serve every factor (the load factor is a Constant of the forms: nothing is compiled
    again); each state is stepped to from the nearest one found so far (the straight rod at
    f = 0), in increments of 1/static.load_steps of the factor, the loads at static.time.

    The request is checked first (a SceneError naming the key: a scene without static
    states, ``count``, the memory budget); then ``folder``, if given, is made and locked for
    the writer ``command`` ("stability" or "modes") in the enclosing
    :func:`~cosserat_fem.io.folder_lock.holding_folders` call; then the model is built."""

    def __init__(
        self,
        scene: Scene,
        count: int = 6,
        comm: MPI.Comm = MPI.COMM_WORLD,
        folder: Path | None = None,
        command: str = "stability",
    ):
        check_static_scene(scene, command)
        check_count(scene, count)
        budget.check(scene, "modes", None, ranks_on_node(comm), comm.size, modes=count, comm=comm)
        if folder is not None:
            prepare_output_dir(folder, comm, lock=command)
        self.scene, self.count = scene, count
        self.model = build_model(scene, comm, planar=False)  # the modes leave the plane too
        self.solver = static_solver(scene, self.model)
        self.operator = ModalOperator(self.model, scene.static.time)
        self.states: dict[float, np.ndarray] = {0.0: self.model.U.x.array.copy()}
        self.points: dict[float, StabilityPoint] = {}

    def state(self, factor: float) -> np.ndarray:
        """U at ``factor`` (a copy), by load stepping from the nearest state found."""
        if factor in self.states:
            return self.states[factor].copy()
        start = min(self.states, key=lambda f: (abs(f - factor), f))
        steps = max(1, math.ceil(abs(factor - start) * self.scene.static.load_steps - 1e-9))
        self.model.U.x.array[:] = self.states[start]
        self.model.load_factor.value = start
        loop = StaticLoop(self.model, self.solver, self.scene, Events(), start, factor, steps)
        try:
            loop.run()
        finally:
            loop.back_to_accepted()
        self.states[factor] = self.model.U.x.array.copy()
        return self.states[factor].copy()

    def modes(self, factor: float) -> list[Mode]:
        """The ``count`` modes nearest 0 about the state at ``factor`` (its loads × factor)."""
        base = self.state(factor)
        self.model.load_factor.value = factor
        problem = self.operator.problem(base)
        try:
            return solve_eigenproblem(problem, self.count)
        finally:
            problem.destroy()

    def at(self, factor: float) -> StabilityPoint:
        """The state at ``factor`` and the ``count`` eigenvalues nearest 0 about it."""
        if factor not in self.points:
            self.points[factor] = StabilityPoint.of(factor, self.modes(factor))
        return self.points[factor]

    def close(self) -> None:
        self.solver.destroy()


#: What the modes are about: the straight rod, or the static state under the scene's loads.
ABOUT = ("undeformed", "static")


@holding_folders
def compute_modes(
    scene: Scene,
    count: int,
    about: str = "undeformed",
    comm: MPI.Comm = MPI.COMM_WORLD,
    out: Path | None = None,
) -> tuple[RodModel, list[Mode]]:
    """The scene's ``count`` lowest modes about the straight rod (their loads at time.start)
    or about its static state under the scene's loads (load factor 1, loads at static.time:
    :meth:`Equilibria.modes`, the one path to modes about a
    static state). A mechanism (scene.Supports.mechanism) has rigid-body modes, ω = 0 (six
    for a free rod), before its flexible ones; it has modes about the straight rod only (its
    static state is not determined: a SceneError). With ``out``: the folder is checked and
    locked for this writer after the request is checked and before anything is computed,
    and the modes are written there (:func:`write_modes`)."""
    if about not in ABOUT:
        raise SceneError(f"about (--about): must be 'undeformed' or 'static', got {about!r}")
    if scene.structure is not None and scene.mechanism and about == "static":
        raise SceneError(
            "structure.supports: modes about the static state of a mechanism: it has none; "
            "use --about undeformed"
        )
    if scene.supports.mechanism and scene.structure is None and about == "static":
        raise SceneError(
            f"supports: modes about the static state of a mechanism (start = "
            f'"{scene.supports.start}", end = "{scene.supports.end}"): it has none, its '
            "rigid-body motions leave it undetermined; use --about undeformed"
        )
    if about == "static":
        equilibria = Equilibria(scene, count, comm, folder=out, command="modes")
        try:
            model, modes = equilibria.model, equilibria.modes(1.0)
        finally:
            equilibria.close()
    else:
        check_count(scene, count)
        budget.check(scene, "modes", None, ranks_on_node(comm), comm.size, modes=count, comm=comm)
        if out is not None:
            prepare_output_dir(out, comm, lock="modes")
        model = build_model(scene, comm, planar=False)  # the modes leave the plane too
        problem = assemble_modal_problem(model)
        try:
            modes = solve_eigenproblem(problem, count)
        finally:
            problem.destroy()
    if out is not None:
        write_modes(out, model, modes, about)
    return model, modes


def _root(function, a: float, b: float, tolerance: float) -> tuple[float, int]:
    """Brent's root of ``function`` in [a, b] (opposite signs at the ends) to |Δf| ≤
    tolerance (1 + max |a|, |b|); (root, function evaluations)."""
    from scipy.optimize import brentq

    xtol = tolerance * (1.0 + max(abs(a), abs(b)))
    root, info = brentq(function, a, b, xtol=xtol, rtol=4 * np.finfo(float).eps, full_output=True)
    return float(root), int(info.function_calls)


def critical_factor(
    equilibria: Equilibria, factors: Sequence[float], tolerance: float = 1e-8
) -> StabilityResult:
    """Visit ``factors`` (increasing) until a state is unstable, and locate the loss of
    stability in that first interval (module docstring); the factors beyond it are not
    solved."""
    result = StabilityResult(points=[], tolerance=tolerance)
    a = equilibria.at(factors[0])
    if not a.stable:
        result.reason = f"unstable ({a.status}) already at the first factor {a.factor}"
    else:
        for factor in factors[1:]:
            b = equilibria.at(factor)
            if not b.stable:
                result.critical, result.evaluations, result.kind = _locate(
                    equilibria, a, b, tolerance
                )
                result.bracket = (a.factor, b.factor)
                break
            a = b
        else:
            result.reason = f"stable over [{factors[0]}, {factors[-1]}]"
    result.points = sorted(equilibria.points.values(), key=lambda p: p.factor)
    return result


def _locate(
    equilibria: Equilibria, a: StabilityPoint, b: StabilityPoint, tolerance: float
) -> tuple[float, int, str]:
    """(critical factor, evaluations, kind) in [a, b], a stable and b not: the smaller root
    of divergence's and flutter's functions where each changes sign (module docstring)."""
    roots = []
    if b.diverges:
        if a.lowest_real() <= 0.0:  # λ_min at a is 0 to round-off: a is the critical state
            roots.append((a.factor, 0, "divergence"))
        else:
            root = _root(lambda f: equilibria.at(f).lowest_real(), a.factor, b.factor, tolerance)
            roots.append((*root, "divergence"))
    pair = b.complex_pair()
    if pair is not None:
        near, kind = pair
        d_a = a.discriminant(near, kind)
        if d_a is None or d_a <= 0.0:  # Brent needs the sign change: two real λ at a
            raise SolverError(
                f"flutter between load factors {a.factor} and {b.factor}: the two "
                f"{kind} eigenvalues that collide are not both among the {equilibria.count} "
                "nearest 0 at the stable end",
                where="stability",
                suggestion="ask for more eigenvalues (--count)",
            )

        def discriminant(f: float) -> float:
            d = equilibria.at(f).discriminant(near, kind)
            if d is None:
                raise SolverError(
                    f"flutter: no {kind} pair at load factor {f}",
                    where="stability",
                    suggestion="raise --count",
                )
            return d

        roots.append((*_root(discriminant, a.factor, b.factor, tolerance), "flutter"))
    return min(roots)


def scene_loads(scene: Scene) -> dict:
    """The scene's load components at factor 1 that are not zero, by dotted key (their
    expressions as given: the critical loads are the critical factor times these)."""
    return {
        key: str(value)
        for key, value in scene.load_components()
        if not getattr(value, "is_zero", False)
    }


#: Bounds that keep a stability analysis finite: the grid's states, and the load steps from 0
#: to the range's top (static.load_steps a unit of the factor; each a Newton solve).
MAX_SAMPLES = 1000
MAX_LOAD_STEPS = 100_000


def check_factors(
    low: float, high: float, samples: int, tolerance: float, load_steps: int = 1
) -> list[float]:
    """The grid of load factors, or a SceneError naming the option: a range whose top needs
    more than :data:`MAX_LOAD_STEPS` load steps (``load_steps`` a unit of the factor), or more
    than :data:`MAX_SAMPLES` samples, would run without practical end."""
    if not all(math.isfinite(v) for v in (low, high)) or low < 0.0 or high <= low:
        raise SceneError(
            f"--range: must be two finite load factors 0 <= LOW < HIGH, got {low!r} {high!r}"
        )
    if isinstance(samples, bool) or not isinstance(samples, int | np.integer) or samples < 2:
        raise SceneError(f"--samples: must be a whole number >= 2, got {samples!r}")
    if samples > MAX_SAMPLES:
        raise SceneError(f"--samples: at most {MAX_SAMPLES}, got {samples}")
    if not (isinstance(tolerance, float | int) and 0.0 < tolerance < 0.1):
        raise SceneError(f"--tolerance: must lie in (0, 0.1), got {tolerance!r}")
    if high * load_steps > MAX_LOAD_STEPS:
        raise SceneError(
            f"--range: HIGH = {high:g} needs {high * load_steps:.3g} load steps "
            f"(static.load_steps = {load_steps} a unit of the factor), more than "
            f"{MAX_LOAD_STEPS}; scale the scene's loads instead"
        )
    return [float(f) for f in np.linspace(low, high, samples)]


@holding_folders
def stability(
    scene: Scene,
    low: float = 0.0,
    high: float = 1.0,
    samples: int = 5,
    tolerance: float = 1e-8,
    count: int = 6,
    out: Path | None = None,
    comm: MPI.Comm = MPI.COMM_WORLD,
) -> StabilityResult:
    """Stability of the scene's static states for load factors in [low, high] (``samples``
    equally spaced, visited up to the first unstable one, then the root finder's) and the
    critical factor (:func:`critical_factor`). The request is checked before anything else
    (one SceneError naming the option); with ``out``: that folder is then made and locked
    (one writer a folder), and stability.json is written there."""
    factors = check_factors(low, high, samples, tolerance, scene.static.load_steps)
    equilibria = Equilibria(scene, count, comm, folder=out)
    try:
        result = critical_factor(equilibria, factors, tolerance)
    finally:
        equilibria.close()
    result.loads = scene_loads(scene)
    if out is not None:
        summary = summary_start("stability", scene, comm, equilibria.model, **result.as_dict())
        summary["status"] = "completed"
        write_summary(Path(out) / "stability.json", summary, comm)
    return result


def stability_at(
    scene: Scene, factor: float = 1.0, count: int = 6, comm: MPI.Comm = MPI.COMM_WORLD
) -> StabilityPoint:
    """Whether the static state at load factor ``factor`` (1: the scene's loads) is stable,
    with the ``count`` eigenvalues nearest 0 about it."""
    if isinstance(factor, bool) or not (isinstance(factor, float | int) and math.isfinite(factor)):
        raise SceneError(f"factor: must be a finite number, got {factor!r}")
    equilibria = Equilibria(scene, count, comm)
    try:
        return equilibria.at(float(factor))
    finally:
        equilibria.close()
