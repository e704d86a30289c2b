"""Pseudo-arclength continuation of the solutions of R(u, p) = 0, with limit and bifurcation
points located and branches switched (Keller 1977; Seydel, "Practical Bifurcation and
Stability Analysis", 3rd ed., ch. 4-5). It knows nothing of rods: u is a numpy array of the
owned entries of a distributed vector, p a float, and everything else comes from the problem.

**The problem** (:class:`ContinuationProblem`): ``residual(u, p)`` = R, ``linearise(u, p)``
assembles and factors R_u there (a singular matrix or non-finite values raise an
ArithmeticError or a RuntimeError, e.g. PETSc's: the step fails), ``solve(rhs)`` = R_u⁻¹ rhs
with those factors, ``dparameter(u, p)`` = R_p, ``dot(a, b)`` the inner product of two
u-vectors (MPI-summed: it is the metric of the u-part, scaled as the problem chooses) and
``determinant()`` = (sign, ln |det R_u|) of the last factors. Optional:
``refine_prediction(u, p)``, a problem's own improvement of a predicted u before the corrector
(the rod's: its positions solved for the predicted angles, cosserat_fem/analysis/paths.py),
used while ``refine`` is set. The metric of a point x = (u, p) is
‖x‖² = dot(u, u) + p², and the arclength s is measured in it.

**A step** from the point x_k with unit tangent t_k and step length Δs: the predictor
x̂ = x_k + Δs t_k (``predictor = "tangent"``, the default), or (``"quadratic"``, from the
third point of a branch on) the quadratic through x_{k−2}, x_{k−1}, x_k in the chord abscissa
(chords measured in the metric) at Δs beyond x_k, whose error is O(Δs³) instead of O(Δs²)
(Seydel, 4.4); then the problem's ``refine_prediction``, if any. Measured on the rod, the
quadratic does no better than the tangent; the refinement (the positions solved for the
predicted angles) is what lets the steps grow (docs/continuation.md). Then Newton on the
bordered system

    R(u, p) = 0,   ⟨t_k, x − x̂⟩ = 0,

each iteration by Keller's bordering: with R_u factored once, a = R_u⁻¹ R and b = R_u⁻¹ R_p
(two solves), δp = (⟨c_u, a⟩ − g)/(c_p − ⟨c_u, b⟩) (g the constraint's value, c its normal),
δu = −a − b δp; x ← x + δx. The corrector converges when ‖δx‖ ≤ ``tolerance`` (full Newton:
the error left is then of order ‖δx‖², far below it). The tangent at the converged point x
solves [R_u R_p; t_kᵀ] t = [0; 1] (b again: t_p = 1/(t_k,p − ⟨t_k,u, b⟩), t_u = −b t_p),
normalised: it keeps the orientation of t_k through a limit point, where t_p changes sign.

**Step length.** A step that converges in k ≤ ``easy_iterations`` iterations grows the next
by max(``grow``, ``easy_iterations``/k), at most ``max_grow`` (and up to ``max_step``); one
that fails (no convergence in ``max_iterations``, a non-finite residual, or an exception of
the problem: :class:`StepFailure`) is retried with half the step, down to ``min_step``; below
it the branch ends with ``reason`` and keeps every point found. A step that turns by more
than ``max_turn`` (default 60°) fails too: the angle, in the metric, of its new tangent or of
its chord x_{k+1} − x_k to the tangent t_k. On a smooth path of curvature κ the tangent
turns by about κΔs and the chord by κΔs/2, so the check bounds the step by the path's own
curvature; a corrector that converged far off the predictor (onto another branch, or back
along this one: the chord's angle is arctan(‖x_{k+1} − x̂‖/Δs)) turns by more. The tangent's
angle is below 90° by its orientation, the chord's is not. A step long enough to land on
another part of the path as straight as where it left (no turn to see) is not caught. The
first step of a branch switched onto is not checked (its start's direction is only
orthogonal to the old branch's). A step that takes p out of [``p_min``, ``p_max``] is not
kept: the branch ends with a last point at the bound itself (Newton at fixed p from the
interpolation of the two points, refined, kind "end"; if that fails, the step is halved),
and the special points between the two beyond the bound are dropped.

**Special points** between two consecutive points x_k, x_{k+1} of a branch:

* a **limit point** (fold) where t_p changes sign: located as the root of t_p(s) over the
  arclength s ∈ (0, Δs) measured from x_k along t_k (each evaluation a corrected point), by
  the Illinois variant of regula falsi;
* a **bifurcation point** where the sign of det R_u changes while t_p does not (a simple
  eigenvalue of R_u crosses 0 and the parameter keeps its direction): located as the root of
  det R_u(s)/|det R_u(x_k)| (continuous, computed from the logarithms), the same way.

* a problem's own **test functions** (``tests``, optional: a name → f(point), e.g. the
  Floquet multipliers' of a periodic orbit, cosserat_fem/analysis/periodic.py): where f
  changes sign, a special point of that name, located as the root of f(s) the same way.

All are located to |s − s*| ≤ ``locate_tolerance`` (Illinois' bracket), so p* to
|dp/ds| ``locate_tolerance`` ≤ ``locate_tolerance``. If the corrector fails inside the
bracket, the bracket's best estimate is kept instead, its ``note`` "approximate (...)".
The branch continues from x_{k+1}.

**Charts.** A problem's unknowns may be coordinates in a chart that must move along the path
(the rod's Euler angles, singular at θ = ±π/2: cosserat_fem/rod/charts.py). Such a problem
has ``chart`` (its current chart, an object the engine only compares by identity and stores
in each Point), ``use_chart(chart)`` (go back to a point's chart: a branch traced from a point
of an earlier one) and ``chart_move(u)``: None, or — having moved its chart — the map φ taking
a state of the old chart to the new one. Before each step the engine asks it at the last point
x_k = (u_k, p_k) with unit tangent t_k. On a move:

* the path x(s) = (u(s), p(s)) becomes (φ(u(s)), p(s)), whose tangent at x_k is
  (J t_u, t_p), J = Dφ(u_k) (computed as the central difference
  (φ(u_k + ε t_u) − φ(u_k − ε t_u))/2ε, ε = :data:`CHART_EPS`: error about 1e-10). The
  old predictor x_k + Δs t_k maps to φ(x_k) + Δs (J t_u, t_p) + O(Δs²): so the new unit
  tangent is t' = (J t_u, t_p)/m and the step Δs' = m Δs, m = ‖(J t_u, t_p)‖ in the metric,
  is the same step on the path. The arclength is then measured in the new chart's metric:
  the step's length on the path does not jump, its number in the two metrics differs by m
  (so the step after a move is m Δs even above ``max_step``, which bounds the steps grown
  in a chart's own metric);
* the discretised problem in the new chart is not exactly the old one (the rod's frame
  between the nodes is interpolated from the new chart's: charts.py), so φ(u_k) solves it to
  that difference only: the point is corrected on the hyperplane through φ(x_k) normal to
  t' (Newton, the constraint ⟨t', x − (φ(u_k), p_k)⟩ = 0: well posed at a fold too, where
  a correction at fixed p = p_k may land on another state of the same p: Lee's frame's
  switched branch, before, 0.47 of its 120 sideways), its tangent computed there (the
  bordered system, oriented along t') and its det R_u anew. It is the base of the next
  step; the branch keeps x_k as it was accepted (its outputs, its restart data: a point's
  rows and frames are written as it comes, path_restart.py), so x_k and its re-charted
  image differ by the change of the discretisation, O(h^(k+1)) (if the correction fails
  the move is undone and asked again at the next point);
* sign changes of det R_u and of t_p, and the tests, are looked for between two points of
  one chart only: across a move det R'_u' = det(R_u) times the determinants of the chart's
  Jacobian on the unknowns and on the test functions, whose sign the move alone may change
  (not a bifurcation). Every segment is searched: [x_{k−1}, x_k] in the old chart before
  the move, [x'_k, x_{k+1}] in the new one after it;
* the quadratic predictor's history: only through three points of one chart (else the
  tangent predictor, for the three steps after a move);
* a chart is itself singular somewhere (the Euler angles at θ = ±π/2, where det R_u changes
  sign by the chart alone): a problem's ``inadmissible(u)`` names why a corrected point lies
  too near it, and the step is then halved (a StepFailure), so that a step does not carry
  the state across the singularity between two moves.

``Branch.charts_moved`` counts the moves. A problem without ``chart_move`` has none.

**Branch switching** at a bifurcation point x*: the null vector φ of R_u(x*) by inverse
iteration with its factors (``null_iterations`` solves from a fixed pseudo-random start), the
direction d = (φ, 0) − ⟨(φ, 0), t*⟩ t* orthogonal to the old branch's tangent t* (exact for a
symmetric pitchfork, where the new branch's tangent is (φ, 0); for a transcritical point the
hyperplane ⟨d, x − x*⟩ = ±Δs still cuts the new branch at a distance O(Δs)), and the new
branch traced from x* in both directions ±d. The first segment of a branch that starts at a
special point is not searched for special points (its start is one).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np


class ContinuationProblem(Protocol):
    """R(u, p) = 0 for the engine (module docstring). u: the owned entries (numpy)."""

    def residual(self, u: np.ndarray, p: float) -> np.ndarray: ...

    def linearise(self, u: np.ndarray, p: float) -> None: ...

    def solve(self, rhs: np.ndarray) -> np.ndarray: ...

    def dparameter(self, u: np.ndarray, p: float) -> np.ndarray: ...

    def dot(self, a: np.ndarray, b: np.ndarray) -> float: ...

    def determinant(self) -> tuple[float, float]: ...


#: The central difference's step for the chart's Jacobian J t (module docstring, "Charts"):
#: its truncation error O(ε²) is 1e-12 and its round-off ε_mach ‖φ(u)‖/ε about 1e-10
#: relative; J t only orients the new tangent (then computed exactly) and scales the step.
CHART_EPS = 1e-6


class StepFailure(RuntimeError):
    """A corrector that did not converge (the step is halved)."""


@dataclass(frozen=True)
class ContinuationSettings:
    """Step lengths (arclength in the problem's metric), the corrector's stop rule, the
    locating tolerance and the ends of a branch (module docstring)."""

    step: float = 0.05
    min_step: float = 1e-6
    max_step: float = 0.5
    grow: float = 1.5
    max_grow: float = 4.0
    easy_iterations: int = 6
    max_iterations: int = 12
    tolerance: float = 1e-10
    locate_tolerance: float = 1e-9
    max_points: int = 200
    p_min: float = -math.inf
    p_max: float = math.inf
    null_iterations: int = 8
    predictor: str = "tangent"  # or "quadratic"
    refine: bool = True  # the problem's refine_prediction, if it has one
    #: the largest angle [rad] a step may turn by (its new tangent's, or its chord's, to the
    #: last tangent, in the metric); a step that turns more is rejected and halved
    max_turn: float = math.pi / 3


@dataclass
class Point:
    """A solution x = (u, p) on a branch, its unit tangent (t_u, t_p), the sign and ln of
    |det R_u| there, the corrector's iterations, and ``kind``: "regular", "start", "end" (at
    a bound of p), "limit", "bifurcation" or a test function's name (a located special
    point)."""

    u: np.ndarray
    p: float
    t_u: np.ndarray
    t_p: float
    det_sign: float
    log_det: float
    iterations: int = 0
    kind: str = "regular"
    #: why a located special point is only approximate ("" if located to
    #: ``locate_tolerance``): the corrector failed inside the bracket, which was then left
    #: with its best estimate (:meth:`Continuation._locate`)
    note: str = ""
    #: the chart u is a coordinate of (the problem's ``chart``, opaque to the engine; None
    #: for a problem without charts: module docstring, "Charts")
    chart: object = None


@dataclass
class Branch:
    """The points of one branch in the order traced, the special points located on it (not
    among ``points``), the direction it was traced in (+1/−1 of its first tangent), and why
    it ended."""

    points: list[Point] = field(default_factory=list)
    special: list[Point] = field(default_factory=list)
    direction: int = 1
    reason: str = ""
    steps_rejected: int = 0
    #: the step the next point would have taken (kept by :meth:`Continuation.trace`)
    step: float = 0.0
    #: the index along the branch of ``points[0]`` (> 0 for a branch resumed from its last
    #: points: :meth:`Continuation.resume`)
    first_index: int = 0
    #: the chart's moves made on it (module docstring, "Charts")
    charts_moved: int = 0


class Continuation:
    """The engine on one problem (module docstring)."""

    def __init__(
        self,
        problem: ContinuationProblem,
        settings: ContinuationSettings | None = None,
        stop: Callable[[Point], str | None] | None = None,
        tests: Mapping[str, Callable[[Point], float]] | None = None,
    ):
        """``stop(point)``: a reason to end the branch at ``point`` (kept), or None;
        ``tests``: kind → a continuous test function of a point, whose sign changes are
        located as special points of that kind (module docstring)."""
        self.problem = problem
        self.settings = settings or ContinuationSettings()
        self.stop = stop
        self.tests = dict(tests or {})
        self.corrector_solves = 0  # factorisations of R_u by the correctors
        #: the branch being traced (``stop`` may save it as it grows: path_restart.py)
        self.branch: Branch | None = None

    # -- the metric ------------------------------------------------------------------------
    def _dot(self, a_u: np.ndarray, a_p: float, b_u: np.ndarray, b_p: float) -> float:
        return self.problem.dot(a_u, b_u) + a_p * b_p

    # -- charts --------------------------------------------------------------------------
    def _chart(self) -> object:
        """The problem's current chart (None without charts)."""
        return getattr(self.problem, "chart", None)

    def _use_chart(self, point: Point) -> None:
        """Put the problem in the chart of ``point`` (a branch traced from a point of an
        earlier chart: the other direction, a switch)."""
        use = getattr(self.problem, "use_chart", None)
        if use is not None and point.chart is not self._chart():
            use(point.chart)

    def _move_chart(self, point: Point) -> tuple[Point, float] | None:
        """The point re-charted and the step's scale |J t| if the problem's ``chart_move``
        moves its chart at ``point`` (module docstring, "Charts"), else None. A move whose
        re-correction fails is undone (tried again at the next point)."""
        move = getattr(self.problem, "chart_move", None)
        if move is None:
            return None
        old = self._chart()
        to_new = move(point.u)
        if to_new is None:
            return None
        eps = CHART_EPS
        J_t = (to_new(point.u + eps * point.t_u) - to_new(point.u - eps * point.t_u)) / (2 * eps)
        scale = math.sqrt(self._dot(J_t, point.t_p, J_t, point.t_p))
        mapped, n_u, n_p = to_new(point.u), J_t / scale, point.t_p / scale
        try:  # on the hyperplane through the mapped point normal to the mapped tangent
            value = self._dot(n_u, n_p, mapped, point.p)
            u, p, its = self.correct(mapped, point.p, n_u, n_p, value)
            t_u, t_p, sign, log_det = self._tangent_and_det(u, p, n_u, n_p)
        except (StepFailure, ArithmeticError, RuntimeError):
            self._use_chart(Point(point.u, point.p, point.t_u, point.t_p, 1.0, 0.0, chart=old))
            return None
        moved = Point(u, p, t_u, t_p, sign, log_det, its, point.kind, chart=self._chart())
        return moved, scale

    def _admissible(self, u: np.ndarray) -> None:
        """StepFailure if the problem's ``inadmissible(u)`` gives a reason (a point too near
        its chart's singularity: module docstring, "Charts")."""
        check = getattr(self.problem, "inadmissible", None)
        reason = None if check is None else check(u)
        if reason:
            raise StepFailure(reason)

    # -- one corrected point -------------------------------------------------------------
    def _tangent_and_det(self, u: np.ndarray, p: float, t_u: np.ndarray, t_p: float):
        """(t_u, t_p, sign, ln|det|) at (u, p) with R_u factored there; the tangent oriented
        along (t_u, t_p) (module docstring)."""
        pb = self.problem
        pb.linearise(u, p)
        sign, log_det = pb.determinant()
        b = pb.solve(pb.dparameter(u, p))
        n_p = 1.0 / (t_p - pb.dot(t_u, b))
        n_u = -b * n_p
        norm = math.sqrt(self._dot(n_u, n_p, n_u, n_p))
        return n_u / norm, n_p / norm, sign, log_det

    def correct(
        self,
        u: np.ndarray,
        p: float,
        c_u: np.ndarray,
        c_p: float,
        value: float,
    ) -> tuple[np.ndarray, float, int]:
        """Newton on R = 0, ⟨c_u, u⟩ + c_p p = ``value`` from the guess (u, p), by Keller's
        bordering; (u, p, iterations), or StepFailure."""
        pb, st = self.problem, self.settings
        u = u.copy()
        for it in range(1, st.max_iterations + 1):
            try:
                R = pb.residual(u, p)
                g = pb.dot(c_u, u) + c_p * p - value
                pb.linearise(u, p)
                self.corrector_solves += 1
                a = pb.solve(R)
                b = pb.solve(pb.dparameter(u, p))
            except (ArithmeticError, RuntimeError) as exc:
                raise StepFailure(f"{type(exc).__name__}: {exc}") from None
            d_p = (pb.dot(c_u, a) - g) / (c_p - pb.dot(c_u, b))
            d_u = -a - b * d_p
            u = u + d_u
            p = p + d_p
            size = math.sqrt(self._dot(d_u, d_p, d_u, d_p))
            if not math.isfinite(size):
                raise StepFailure("the corrector's update is not finite")
            if size <= st.tolerance:
                return u, p, it
        raise StepFailure(f"the corrector did not converge in {st.max_iterations} iterations")

    def _point_at(
        self,
        base: Point,
        s: float,
        kind: str = "regular",
        history: tuple[Point, Point] | None = None,
    ) -> Point:
        """The corrected point at arclength ``s`` from ``base`` along its tangent; with
        ``history`` (the two points before ``base``) the predictor is the quadratic through
        the three (module docstring)."""
        if history is None:
            u0 = base.u + s * base.t_u
            p0 = base.p + s * base.t_p
        else:
            u0, p0 = self._quadratic(history[0], history[1], base, s)
        u0 = self._refined(u0, p0)
        value = self._dot(base.t_u, base.t_p, u0, p0)
        u, p, its = self.correct(u0, p0, base.t_u, base.t_p, value)
        self._admissible(u)
        try:
            t_u, t_p, sign, log_det = self._tangent_and_det(u, p, base.t_u, base.t_p)
        except (ArithmeticError, RuntimeError) as exc:
            raise StepFailure(f"{type(exc).__name__}: {exc}") from None
        return Point(u, p, t_u, t_p, sign, log_det, its, kind, chart=self._chart())

    def _refined(self, u: np.ndarray, p: float) -> np.ndarray:
        """The problem's ``refine_prediction(u, p)`` of a predicted u, if it has one and
        ``refine`` is set (StepFailure if it fails)."""
        refine = getattr(self.problem, "refine_prediction", None)
        if refine is None or not self.settings.refine:
            return u
        try:
            return refine(u, p)
        except (ArithmeticError, RuntimeError) as exc:
            raise StepFailure(f"{type(exc).__name__}: {exc}") from None

    def _chord(self, a: Point, b: Point) -> float:
        d_u, d_p = b.u - a.u, b.p - a.p
        return math.sqrt(self._dot(d_u, d_p, d_u, d_p))

    def _quadratic(self, x0: Point, x1: Point, x2: Point, s: float) -> tuple[np.ndarray, float]:
        """The quadratic through x0, x1, x2 at chord abscissae −h1−h2, −h2, 0 (h the chords
        in the metric), evaluated at s: Lagrange's weights."""
        h2 = self._chord(x1, x2)
        h1 = self._chord(x0, x1)
        a0, a1, a2 = -h1 - h2, -h2, 0.0
        w0 = (s - a1) * (s - a2) / ((a0 - a1) * (a0 - a2))
        w1 = (s - a0) * (s - a2) / ((a1 - a0) * (a1 - a2))
        w2 = (s - a0) * (s - a1) / ((a2 - a0) * (a2 - a1))
        return w0 * x0.u + w1 * x1.u + w2 * x2.u, w0 * x0.p + w1 * x1.p + w2 * x2.p

    def _at_parameter(self, prev: Point, cur: Point, value: float) -> Point:
        """The point at p = ``value`` (between prev.p and cur.p), Newton at fixed p from the
        linear interpolation of the two; StepFailure if that fails (the step is halved)."""
        w = (value - prev.p) / (cur.p - prev.p)
        guess = (1.0 - w) * prev.u + w * cur.u
        guess = self._refined(guess, value)
        u, p, its = self.correct(guess, value, np.zeros_like(guess), 1.0, value)
        try:
            t_u, t_p, sign, log_det = self._tangent_and_det(u, p, cur.t_u, cur.t_p)
        except (ArithmeticError, RuntimeError) as exc:
            raise StepFailure(f"{type(exc).__name__}: {exc}") from None
        return Point(u, p, t_u, t_p, sign, log_det, its, "end", chart=self._chart())

    def turn(self, prev: Point, cur: Point) -> float:
        """The angle [rad] a step from ``prev`` to ``cur`` turns by: the larger of the
        angles, in the metric, of the new tangent and of the chord x_cur − x_prev to the
        tangent t_prev (module docstring, "Step length")."""
        cos_t = self._dot(prev.t_u, prev.t_p, cur.t_u, cur.t_p)
        c_u, c_p = cur.u - prev.u, cur.p - prev.p
        chord = math.sqrt(self._dot(c_u, c_p, c_u, c_p))
        cos_c = self._dot(prev.t_u, prev.t_p, c_u, c_p) / chord if chord > 0 else 1.0
        return max(math.acos(min(1.0, max(-1.0, c))) for c in (cos_t, cos_c))

    def start_point(self, u: np.ndarray, p: float, direction: int = 1) -> Point:
        """The solution near (u, p) at fixed p (Newton with the constraint p = p), its
        tangent oriented so that p grows along it for ``direction`` = +1."""
        zero = np.zeros_like(u)
        u, p, its = self.correct(u, p, zero, 1.0, p)
        t_u, t_p, sign, log_det = self._tangent_and_det(u, p, zero, float(direction))
        return Point(u, p, t_u, t_p, sign, log_det, its, "start", chart=self._chart())

    # -- locating ------------------------------------------------------------------------
    def _locate(
        self,
        base: Point,
        step: float,
        f0: float,
        f1: float,
        function,
        kind: str,
        end: Point | None = None,
    ):
        """The point at the root of ``function(point)`` for s in (0, step) from ``base``
        (f(0) = f0, f(step) = f1 of opposite signs; ``end`` the point at s = step, if known),
        Illinois' regula falsi. If the corrector fails inside the bracket (also just beside
        the failing s), the bracket's best estimate is kept (:meth:`_estimate`), its ``note``
        saying so."""
        st = self.settings
        a, b, fa, fb = 0.0, step, f0, f1
        side = 0
        best = None
        for _ in range(200):
            s = (a * fb - b * fa) / (fb - fa)
            if not (a < s < b):
                s = 0.5 * (a + b)
            try:
                try:
                    point = self._point_at(base, s, kind)
                except StepFailure:  # R_u exactly singular at s: the root, within tolerance
                    s = min(s + 0.25 * st.locate_tolerance, 0.5 * (s + b))
                    point = self._point_at(base, s, kind)
            except StepFailure as exc:
                return self._estimate(best, base, end, fa, fb, kind, b - a, exc)
            fs = function(point)
            best = point
            if fs == 0.0:
                break
            if (fs > 0) == (fb > 0):
                b, fb = s, fs
                if side == -1:
                    fa *= 0.5
                side = -1
            else:
                a, fa = s, fs
                if side == 1:
                    fb *= 0.5
                side = 1
            if b - a <= st.locate_tolerance:
                break
        assert best is not None
        return best

    @staticmethod
    def _estimate(best, base, end, fa, fb, kind, width, exc) -> Point:
        """The bracket's best estimate when locating failed (:meth:`_locate`): the last
        point evaluated (an end of the narrowed bracket), else the bracket's end of least |f|
        (``base`` or ``end``); marked by its ``note``."""
        if best is None:
            best = end if end is not None and abs(fb) < abs(fa) else base
        note = f"approximate (bracket {width:.3g} wide: {exc})"
        names = ("u", "p", "t_u", "t_p", "det_sign", "log_det", "chart")
        fields = {k: getattr(best, k) for k in names}
        return Point(**fields, iterations=best.iterations, kind=kind, note=note)

    def _special(self, branch: Branch, prev: Point, cur: Point, step: float) -> None:
        """Locate a limit or a bifurcation point between prev and cur, and the roots of the
        ``tests`` (module docstring)."""
        if (prev.t_p > 0) != (cur.t_p > 0):
            point = self._locate(prev, step, prev.t_p, cur.t_p, lambda q: q.t_p, "limit", cur)
            branch.special.append(point)
        elif prev.det_sign != cur.det_sign:
            ref = prev.log_det

            def det(q: Point) -> float:
                return q.det_sign * math.exp(min(q.log_det - ref, 700.0))

            point = self._locate(prev, step, det(prev), det(cur), det, "bifurcation", cur)
            branch.special.append(point)
        for kind, test in self.tests.items():  # the problem's own test functions
            f0, f1 = test(prev), test(cur)
            if (f0 > 0) != (f1 > 0):
                branch.special.append(self._locate(prev, step, f0, f1, test, kind, cur))

    # -- a branch ------------------------------------------------------------------------
    def trace(self, start: Point, direction: int = 1, search_first: bool = True) -> Branch:
        """The branch from ``start`` along ``direction`` × its tangent, until p leaves
        [p_min, p_max], ``max_points``, ``stop`` or a step collapse (module docstring)."""
        st = self.settings
        first = Point(
            start.u,
            start.p,
            direction * start.t_u,
            direction * start.t_p,
            start.det_sign,
            start.log_det,
            start.iterations,
            start.kind,
            chart=start.chart,
        )
        branch = Branch(points=[first], direction=direction)
        return self._extend(branch, st.step, search_first)

    def resume(self, branch: Branch) -> Branch:
        """``branch`` (its last points, at least the last three for the quadratic predictor,
        ``first_index``, ``step`` and ``steps_rejected`` as a trace left them) traced on from
        its last point: the same operations as the uninterrupted trace, so the same points
        (path_restart.py)."""
        return self._extend(branch, branch.step, True)

    def _extend(self, branch: Branch, step: float, search_first: bool) -> Branch:
        st = self.settings
        branch.reason = ""
        self.branch = branch
        self._use_chart(branch.points[-1])
        prev = branch.points[-1]  # the step's base: the last point, or it re-charted
        while True:
            count = branch.first_index + len(branch.points)
            if count >= st.max_points:  # before a move: the step kept is the last point's
                branch.step = step
                branch.reason = f"{st.max_points} points (max_points)"
                return branch
            moved = self._move_chart(prev)
            if moved is not None:
                prev, scale = moved
                step *= scale  # the same step on the path (not capped: module docstring)
                branch.charts_moved += 1
            branch.step = step
            checked = count > 1 or search_first
            try:
                history = None
                if st.predictor == "quadratic" and count >= 3 and len(branch.points) >= 3:
                    if branch.points[-3].chart is prev.chart:  # one chart: module docstring
                        history = (branch.points[-3], branch.points[-2])
                cur = self._point_at(prev, step, history=history)
                turn = self.turn(prev, cur)
                if checked and turn > st.max_turn:
                    raise StepFailure(
                        f"the step turned by {math.degrees(turn):.3g} degrees "
                        f"(max_turn {math.degrees(st.max_turn):.3g})"
                    )
                outside = not st.p_min <= cur.p <= st.p_max
                if outside:
                    bound = st.p_max if cur.p > st.p_max else st.p_min
                    end = self._at_parameter(prev, cur, bound)
            except StepFailure as exc:
                branch.steps_rejected += 1
                step *= 0.5
                if step < st.min_step:
                    branch.reason = (
                        f"step below min_step {st.min_step:g} at p = {prev.p:.9g}: {exc}"
                    )
                    return branch
                continue
            if checked:
                found = len(branch.special)
                self._special(branch, prev, cur, step)
                if outside:  # those beyond the bound are not on the branch kept
                    inside = [q for q in branch.special[found:] if st.p_min <= q.p <= st.p_max]
                    branch.special[found:] = inside
            if outside:
                branch.points.append(end)
                branch.reason = f"p reached {bound:g}"
                return branch
            branch.points.append(cur)
            prev = cur
            if cur.iterations <= st.easy_iterations:
                factor = max(st.grow, st.easy_iterations / max(cur.iterations, 1))
                step = min(step * min(factor, st.max_grow), st.max_step)
            branch.step = step
            reason = self.stop(cur) if self.stop is not None else None
            if reason:
                branch.reason = reason
                return branch

    def both_ways(self, start: Point, search_first: bool = True) -> list[Branch]:
        """The branch through ``start`` traced along its tangent and against it."""
        return [self.trace(start, d, search_first) for d in (1, -1)]

    # -- branch switching ----------------------------------------------------------------
    def null_vector(self, point: Point) -> np.ndarray:
        """φ, ⟨φ, φ⟩ = 1: inverse iteration with the factors of R_u at ``point``."""
        pb = self.problem
        self._use_chart(point)
        pb.linearise(point.u, point.p)
        v = np.random.default_rng(12345).standard_normal(point.u.shape)
        for _ in range(self.settings.null_iterations):
            v = pb.solve(v)
            v = v / math.sqrt(pb.dot(v, v))
        return v

    def switch(self, point: Point) -> list[Branch]:
        """The other branch through the bifurcation point ``point``, both ways (module
        docstring)."""
        return self.both_ways(self.switch_start(point), search_first=False)

    def switch_start(self, point: Point) -> Point:
        """The start of the other branch through the bifurcation point ``point``: ``point``
        with the direction d of the module docstring as its tangent (:meth:`switch` traces
        it along ±d; a caller that ends each branch before the next traces it alike)."""
        phi = self.null_vector(point)
        along = self._dot(phi, 0.0, point.t_u, point.t_p)
        d_u, d_p = phi - along * point.t_u, -along * point.t_p
        norm = math.sqrt(self._dot(d_u, d_p, d_u, d_p))
        start = Point(
            point.u,
            point.p,
            d_u / norm,
            d_p / norm,
            point.det_sign,
            point.log_det,
            0,
            "bifurcation",
            chart=point.chart,
        )
        return start
