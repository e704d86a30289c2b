"""The continuation engine (cosserat_fem/nls/arclength.py) on algebraic problems with closed
forms: a fold, a pitchfork and a transcritical bifurcation.

Tolerances: the engine locates a special point to |s − s*| ≤ locate_tolerance = 1e-9 in
arclength, and |dp/ds| ≤ 1, so p* is found to 1e-9 (a 2e-9 bound leaves room for the
corrector's own error, ‖δx‖ ≤ 1e-10 at its last iteration, quadratically less after it). Points
on a branch satisfy its closed form to the corrector's tolerance (1e-10, the update's size,
the residual then O(1e-20)); 1e-9 is asserted.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from cosserat_fem.nls.arclength import Continuation, ContinuationSettings


class Dense:
    """R(u, p) given with its derivatives, dense LU by numpy (slogdet for the sign)."""

    def __init__(self, R, R_u, R_p):
        self.R, self.R_u, self.R_p = R, R_u, R_p
        self.J: np.ndarray | None = None

    def residual(self, u, p):
        return np.asarray(self.R(u, p), dtype=float)

    def linearise(self, u, p):
        self.J = np.asarray(self.R_u(u, p), dtype=float)

    def solve(self, rhs):
        assert self.J is not None
        try:
            return np.linalg.solve(self.J, rhs)
        except np.linalg.LinAlgError as exc:  # the engine's contract: an ArithmeticError
            raise ZeroDivisionError(str(exc)) from None

    def dparameter(self, u, p):
        return np.asarray(self.R_p(u, p), dtype=float)

    def dot(self, a, b):
        return float(a @ b)

    def determinant(self):
        assert self.J is not None
        sign, log = np.linalg.slogdet(self.J)
        return float(sign), float(log)


SETTINGS = ContinuationSettings(step=0.1, max_step=0.2, locate_tolerance=1e-9, max_points=100)


def fold():
    """u0² + p − 1 = 0, u1 − u0 = 0: a fold at p = 1, u = 0 (dp/ds = 0 there)."""
    return Dense(
        lambda u, p: [u[0] ** 2 + p - 1, u[1] - u[0]],
        lambda u, p: [[2 * u[0], 0], [-1, 1]],
        lambda u, p: [1, 0],
    )


def pitchfork():
    """(p − 1) u0 − u0³ = 0, 2 u1 − p = 0: the branch u0 = 0 and u0² = p − 1 meet at p = 1,
    where det R_u = 2 (p − 1 − 3u0²) changes sign on the trivial branch while dp/ds does not."""
    return Dense(
        lambda u, p: [(p - 1) * u[0] - u[0] ** 3, 2 * u[1] - p],
        lambda u, p: [[p - 1 - 3 * u[0] ** 2, 0], [0, 2]],
        lambda u, p: [u[0], -1],
    )


def transcritical():
    """(p − 1) u0 − u0² = 0, u1 − p u0 = 0: u0 = 0 and u0 = p − 1 cross at p = 1."""
    return Dense(
        lambda u, p: [(p - 1) * u[0] - u[0] ** 2, u[1] - p * u[0]],
        lambda u, p: [[p - 1 - 2 * u[0], 0], [-p, 1]],
        lambda u, p: [u[0], -u[0]],
    )


def test_fold_is_passed_and_located():
    """From (u0, p) = (1, 0) towards larger p: the path turns at the fold p = 1 and comes back
    on u0 < 0 (every point on u0² = 1 − p), the fold located at p = 1, u0 = 0."""
    engine = Continuation(fold(), SETTINGS, stop=lambda q: "back" if q.u[0] < -1.0 else None)
    start = engine.start_point(np.array([1.0, 1.0]), 0.0)
    branch = engine.trace(start, 1)
    assert branch.reason == "back"
    assert [q.kind for q in branch.special] == ["limit"]
    limit = branch.special[0]
    assert abs(limit.p - 1.0) < 2e-9 and abs(limit.u[0]) < 1e-4  # u0 ~ sqrt(1 − p)
    assert abs(limit.t_p) < 1e-4
    for q in branch.points:
        assert abs(q.u[0] ** 2 + q.p - 1) < 1e-9 and abs(q.u[1] - q.u[0]) < 1e-9
    assert min(q.u[0] for q in branch.points) < -1.0  # went around


def test_pitchfork_located_and_switched():
    """On the trivial branch u0 = 0 from p = 0: the bifurcation at p = 1 (to 2e-9), no fold;
    the switched branch traced both ways lies on u0² = p − 1, one way u0 > 0 and the other
    u0 < 0, and p grows both ways (a supercritical pitchfork)."""
    settings = ContinuationSettings(step=0.1, max_step=0.2, p_max=2.0, max_points=100)
    engine = Continuation(pitchfork(), settings)
    start = engine.start_point(np.array([0.0, 0.0]), 0.0)
    branch = engine.trace(start, 1)
    assert branch.reason == "p reached 2"
    assert [q.kind for q in branch.special] == ["bifurcation"]
    bif = branch.special[0]
    assert abs(bif.p - 1.0) < 2e-9 and abs(bif.u[0]) < 1e-12
    up, down = engine.switch(bif)
    signs = []
    for new in (up, down):
        assert new.points[-1].p == 2.0 and new.special == []  # ends at the bound
        for q in new.points[1:]:
            assert abs(q.u[0] ** 2 - (q.p - 1)) < 1e-9 and abs(2 * q.u[1] - q.p) < 1e-9
        signs.append(np.sign(new.points[-1].u[0]))
    assert sorted(signs) == [-1.0, 1.0]


def test_transcritical_switched_both_ways():
    """Trivial branch from p = 0: the crossing at p = 1 located; the other branch u0 = p − 1
    traced both ways from it reaches p = 0 one way and p = 2 the other (the bounds)."""
    settings = ContinuationSettings(step=0.1, max_step=0.2, p_min=0.0, p_max=2.0)
    engine = Continuation(transcritical(), settings)
    branch = engine.trace(engine.start_point(np.zeros(2), 0.0), 1)
    (bif,) = branch.special
    assert bif.kind == "bifurcation" and abs(bif.p - 1.0) < 2e-9
    ends = []
    for new in engine.switch(bif):
        for q in new.points[1:]:
            assert abs(q.u[0] - (q.p - 1)) < 1e-9 and abs(q.u[1] - q.p * q.u[0]) < 1e-9
        ends.append(new.points[-1].p)
    assert sorted(ends) == [0.0, 2.0]


def test_step_collapse_keeps_the_branch():
    """A problem that fails beyond p = 0.5 (the residual raises): the step halves down to
    min_step and the branch ends with the reason, its points kept (all p ≤ 0.5)."""

    def R(u, p):
        if p > 0.5:
            raise ArithmeticError("no solution here")
        return [u[0] - p]

    engine = Continuation(
        Dense(R, lambda u, p: [[1.0]], lambda u, p: [-1.0]),
        ContinuationSettings(step=0.1, min_step=1e-3),
    )
    branch = engine.trace(engine.start_point(np.zeros(1), 0.0), 1)
    assert "min_step" in branch.reason and "no solution here" in branch.reason
    assert len(branch.points) > 3 and all(q.p <= 0.5 for q in branch.points)
    assert branch.points[-1].p > 0.5 - 2e-3 * math.sqrt(2)


@pytest.mark.parametrize("direction", [1, -1])
def test_both_directions_from_a_start(direction):
    """From (1, 0) on u0² = 1 − p with its tangent oriented by ``direction``: p decreasing
    (−1) stays on u0 = +√(1 − p) down to p = −3; p increasing (+1) passes the fold and goes
    down to p = −3 on u0 = −√(1 − p), where the branch ends (a point at the bound p_min
    itself). both_ways gives the two."""
    settings = ContinuationSettings(step=0.1, max_step=0.3, p_min=-3.0)
    engine = Continuation(fold(), settings)
    start = engine.start_point(np.array([1.0, 1.0]), 0.0, direction)
    branch = engine.trace(start, 1)
    end = branch.points[-1]
    assert end.p == -3.0 and end.kind == "end"
    assert abs(end.u[0] + direction * math.sqrt(1 - end.p)) < 1e-9
    assert len(branch.special) == (1 if direction == 1 else 0)
    ways = engine.both_ways(start)
    assert [len(w.special) for w in ways] == ([1, 0] if direction == 1 else [0, 1])


class Projected(Dense):
    """u0 = p, u1 = sin(u0) (R = [u0 − p, u1 − sin u0]); refine_prediction sets u1 = sin(u0),
    the problem's own exact refinement, as the rod's positions for its angles."""

    def __init__(self):
        super().__init__(
            lambda u, p: [u[0] - p, u[1] - math.sin(u[0])],
            lambda u, p: [[1.0, 0.0], [-math.cos(u[0]), 1.0]],
            lambda u, p: [-1.0, 0.0],
        )
        self.refined = 0

    def refine_prediction(self, u, p):
        self.refined += 1
        return np.array([u[0], math.sin(u[0])])


@pytest.mark.parametrize("refine", [True, False])
def test_refined_prediction_lets_the_steps_grow(refine):
    """u0 is linear in p, so the tangent predicts it exactly, and the refinement gives u1
    exactly: every corrector converges at its first iteration (an update of 0 in exact
    arithmetic, round-off below the 1e-10 tolerance) and each step grows by max_grow = 4.
    The arclength to p = 20 is ∫ √(2 + cos²p) dp ≈ 20 · 1.58 = 31.7; steps 0.01 · 4^k sum past
    it after 7 (0.01 (4^7 − 1)/3 = 54.6 > 31.7 > 13.6), and the last, past p = 20, is followed by
    the point at the bound: at most 8 points after the start. Without the refinement the
    corrector needs 2 or more iterations on the curved u1, the steps grow slower: more."""
    problem = Projected()
    settings = ContinuationSettings(
        step=0.01, max_step=100.0, p_min=-1.0, p_max=20.0, refine=refine
    )
    engine = Continuation(problem, settings)
    branch = engine.trace(engine.start_point(np.zeros(2), 0.0), 1)
    assert branch.points[-1].p == 20.0
    for q in branch.points:
        assert abs(q.u[1] - math.sin(q.p)) < 1e-9
    if refine:
        assert len(branch.points) - 1 <= 8 and problem.refined >= len(branch.points) - 2
        assert all(q.iterations == 1 for q in branch.points[1:])
    else:
        assert len(branch.points) - 1 > 8 and problem.refined == 0


def test_overshoot_ends_at_the_bound_on_the_branch():
    """u0 = p², u1 = p from p = 0 with p_max = 1 and steps of 0.3 (grown by 1.5 each): the
    step that would pass p = 1 is not kept; the branch's last point is at p = 1 exactly,
    corrected there (u0 = 1 to the corrector's 1e-10, the linear interpolation of the two
    points around it is off by O(Δp²) ≈ 0.1), and no point lies outside [p_min, p_max]."""
    problem = Dense(
        lambda u, p: [u[0] - p**2, u[1] - p],
        lambda u, p: [[1.0, 0.0], [0.0, 1.0]],
        lambda u, p: [-2.0 * p, -1.0],
    )
    settings = ContinuationSettings(step=0.3, max_step=0.6, p_min=-1.0, p_max=1.0)
    engine = Continuation(problem, settings)
    branch = engine.trace(engine.start_point(np.zeros(2), 0.0), 1)
    assert branch.reason == "p reached 1"
    assert all(-1.0 <= q.p <= 1.0 for q in branch.points)
    last = branch.points[-1]
    assert last.p == 1.0 and last.kind == "end"
    assert abs(last.u[0] - 1.0) < 1e-9 and abs(last.u[1] - 1.0) < 1e-9
    assert branch.points[-2].p < 1.0 and len(branch.points) >= 3


def cubic():
    """u³ − u − p = 0: an S, folds at u = ∓1/√3, p = ±2/(3√3) = ±0.3849."""
    return Dense(
        lambda u, p: [u[0] ** 3 - u[0] - p],
        lambda u, p: [[3 * u[0] ** 2 - 1]],
        lambda u, p: [-1.0],
    )


@pytest.mark.parametrize("max_turn", [math.pi, math.pi / 3])
def test_a_step_that_turns_too_far_is_halved(max_turn):
    """The S u³ − u = p from (u, p) = (−2, −6) upwards in steps of 3 (not grown): on the lower
    branch the step from u = −1.04 predicts past the first fold, and the corrector there
    converges onto the upper branch at u = 0.92, skipping both folds and the middle branch;
    that step's chord is at 67.5° to the tangent. With the turn unchecked (max_turn = π) no
    fold is found; with the default 60° the step is rejected and halved, and both folds are
    located, p = +2/(3√3) then −2/(3√3) to 2e-9 (module docstring's tolerance)."""
    settings = ContinuationSettings(
        step=3.0, max_step=3.0, max_grow=1.0, p_min=-10.0, p_max=10.0, max_turn=max_turn
    )
    assert ContinuationSettings().max_turn == math.pi / 3  # the documented default
    engine = Continuation(cubic(), settings)
    branch = engine.trace(engine.start_point(np.array([-2.0]), -6.0), 1)
    fold = 2 / (3 * math.sqrt(3))
    if max_turn == math.pi:
        assert branch.special == []
        assert (
            max(
                engine.turn(a, b)
                for a, b in zip(branch.points[:-1], branch.points[1:], strict=True)
            )
            > 1.1
        )
    else:
        assert [q.kind for q in branch.special] == ["limit", "limit"]
        assert abs(branch.special[0].p - fold) < 2e-9
        assert abs(branch.special[1].p + fold) < 2e-9
        assert all(
            engine.turn(a, b) <= max_turn
            for a, b in zip(branch.points[:-1], branch.points[1:], strict=True)
        )
        assert branch.steps_rejected >= 1


class Failing(Dense):
    """The fold problem, whose ``linearise`` raises (as a failing factorisation) once armed
    and ``allowed`` more calls have been made."""

    def __init__(self, allowed: int):
        problem = fold()
        super().__init__(problem.R, problem.R_u, problem.R_p)
        self.allowed = allowed
        self.armed = False

    def linearise(self, u, p):
        if self.armed:
            if self.allowed <= 0:
                raise ZeroDivisionError("failing on purpose")
            self.allowed -= 1
        super().linearise(u, p)


@pytest.mark.parametrize("allowed", [0, 12])
def test_locating_failure_keeps_an_approximate_point(allowed):
    """The fold of test_fold_is_passed_and_located with the corrector failing while the fold
    is located (the problem fails once the engine locates; ``allowed`` factorisations first:
    0, no point in the bracket, or 12, a few of Illinois' points): the branch still goes
    around (its reason the stop's), and the fold is kept as the bracket's best estimate,
    kind "limit", its note "approximate". It is a corrected point of the branch (on
    u0² = 1 − p to 1e-9), within the step's bracket: |p − 1| ≤ (Δs ≤ 0.2)² (p = 1 − u0²,
    |u0| ≤ Δs) = 0.04; with points evaluated inside it, nearer."""
    problem = Failing(allowed)
    engine = Continuation(problem, SETTINGS, stop=lambda q: "back" if q.u[0] < -1.0 else None)
    special = engine._special

    def armed(*args):
        problem.armed = True
        try:
            special(*args)
        finally:
            problem.armed = False

    engine._special = armed  # type: ignore[method-assign]
    start = engine.start_point(np.array([1.0, 1.0]), 0.0)
    branch = engine.trace(start, 1)
    assert branch.reason == "back"
    (limit,) = branch.special
    assert limit.kind == "limit" and limit.note.startswith("approximate")
    assert abs(limit.u[0] ** 2 + limit.p - 1) < 1e-9 and abs(limit.p - 1) <= 0.04
    if allowed:
        assert abs(limit.p - 1) < 1e-3


class Charted:
    """The line α = p in a chart that moves: the unknown is v = k (α − c) (chart (c, k)),
    R = c + v/k − p, so R_v = 1/k, det R_v of the sign of k. The chart moves when |v| > 1,
    onto c = α and k = −2 (from k = 1) or −k: each move reverses the orientation (det R_v
    changes sign with the chart alone), the first one also doubles the scale (J = −2);
    a point with |v| > 1.5 is inadmissible."""

    def __init__(self):
        self.chart: tuple[float, float] = (0.0, 1.0)
        self.moves = 0

    def alpha(self, v) -> float:
        c, k = self.chart
        return c + float(v[0]) / k

    def residual(self, u, p):
        return np.array([self.alpha(u) - p])

    def linearise(self, u, p):
        pass

    def solve(self, rhs):
        return np.asarray(rhs) * self.chart[1]

    def dparameter(self, u, p):
        return np.array([-1.0])

    def dot(self, a, b):
        return float(a @ b)

    def determinant(self):
        k = self.chart[1]
        return math.copysign(1.0, k), -math.log(abs(k))

    def use_chart(self, chart):
        self.chart = chart

    def inadmissible(self, u):
        return "past 1.5" if abs(u[0]) > 1.5 else None

    def chart_move(self, u):
        if abs(u[0]) <= 1.0:
            return None
        c, k = self.chart
        c_new, k_new = self.alpha(u), (-2.0 if k == 1.0 else -k)
        self.chart = (c_new, k_new)
        self.moves += 1
        return lambda v: k_new * (c + v / k - c_new)


def test_chart_moves_keep_the_path_and_its_steps():
    """The engine's charts (module docstring, "Charts") on :class:`Charted`: with the step
    held (grow = max_grow = 1), each step advances p by Δs/√(1 + k²) in the chart of scale k
    (the unit tangent (k, 1)/√(1 + k²)); the move's step scale ‖(J t_v, t_p)‖ keeps it, so
    all steps advance p equally, Δs/√2, across the moves (measured 3e-11 after 4 moves: the
    central difference is exact for a linear map but for round-off, ε_mach ‖φ(u)‖/ε ≈ 3e-10
    relative to the scale per move; asserted 1e-9). No bifurcation is reported though
    det R_v changes sign at every move (it is compared within one chart only), every point
    satisfies α = p (1e-12), and each point's α is computed in its own chart."""
    problem = Charted()
    settings = ContinuationSettings(
        step=0.3, max_step=10.0, grow=1.0, max_grow=1.0, max_points=100, p_min=-1.0, p_max=4.0
    )
    engine = Continuation(problem, settings)
    start = engine.start_point(np.zeros(1), 0.0)
    branch = engine.trace(start, 1)
    assert branch.reason == "p reached 4" and branch.charts_moved == problem.moves >= 3
    assert not branch.special and branch.steps_rejected == 0
    increments = np.diff([q.p for q in branch.points[:-1]])  # the last ends at the bound
    assert np.max(np.abs(increments - 0.3 / math.sqrt(2.0))) < 1e-9
    for q in branch.points:
        c, k = q.chart
        assert abs(c + q.u[0] / k - q.p) < 1e-12
    assert len({q.chart for q in branch.points}) == problem.moves + 1
