"""Unit tests of cosserat_fem/analysis/periodic.py: the classification of multipliers, the
refusals before any solve, the period expression, and the location of period doubling and
torus bifurcations (the test functions :func:`floquet_tests` on the engine's branch of the
fixed points of maps with closed-form multipliers). The shooting itself and the monodromy
matrix: tests/test_periodic.py; a rod's period doubling: tests/test_chaos.py."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cosserat_fem import api
from cosserat_fem.analysis.periodic import Shooting, classify
from cosserat_fem.common.errors import SceneError
from unit.nls.test_arclength import Dense

CLAMPED = {
    "supports.end": "clamped",
    "loads.force_density": ["F*sin(pi*s/L)*sin(r*w1*t)", 0, 0],
    "parameters.F": 1.0,
    "parameters.w1": 1302.92,
    "parameters.r": 1.07,
    "output.xdmf": False,
    "output.checkpoint": False,
    "discretisation.elements": 2,
}


def _scene(**more):
    from conftest import ROOT

    return api.load(ROOT / "scenes" / "cao_tucker_2008.toml", {**CLAMPED, **more})


@pytest.mark.parametrize(
    ("multipliers", "kind"),
    [
        ([0.9, -0.5, 0.3 + 0.4j, 0.3 - 0.4j], "stable"),
        ([1.2, 0.9, 0.1], "fold"),  # a real multiplier beyond +1: the middle branch
        ([-1.1, 0.9], "period-doubling"),
        ([0.8 + 0.7j, 0.8 - 0.7j, 0.5], "torus"),  # |μ| = 1.063, a complex pair
        ([], "stable"),
    ],
)
def test_classify_names_how_stability_is_lost(multipliers, kind):
    """The largest |μ| decides: inside the unit circle stable, else by where it left it
    (+1 fold, −1 period doubling, a complex pair a torus)."""
    assert classify(np.array(multipliers, dtype=complex)) == kind


def test_a_multiplier_on_the_circle_is_not_yet_unstable():
    """|μ| = 1 − 1e-12 is within UNIT_CIRCLE (1e-9) of the circle: not called stable, because
    round-off cannot tell it from a crossing; 1 − 1e-6 is stable."""
    assert classify(np.array([1.0 - 1e-12])) == "fold"
    assert classify(np.array([1.0 - 1e-6])) == "stable"


@pytest.mark.parametrize(
    ("overrides", "key"),
    [
        ({"time.integrator": "bdf2"}, "time.integrator"),
        ({"time.integrator": "generalized-alpha"}, "time.integrator"),
        ({"time.adaptive": True}, "time.adaptive"),
    ],
)
def test_a_multistep_or_adaptive_scene_is_refused_naming_the_key(overrides, key):
    """The period map's state is U alone only for a one-step method with fixed steps: the
    others are refused before anything is built, naming the key."""
    with pytest.raises(SceneError, match=key):
        Shooting(_scene(**overrides), "2*pi/(r*w1)")


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"steps_per_period": 0}, "steps_per_period"),
        ({"steps_per_period": 2.5}, "steps_per_period"),
        ({"settle": -1}, "settle"),
        ({"max_iterations": 0}, "max_iterations"),
        ({"tolerance": 0.0}, "tolerance"),
    ],
)
def test_periodic_orbit_refuses_bad_arguments_naming_them(kwargs, name):
    with pytest.raises(SceneError, match=name):
        api.periodic_orbit(_scene(), "2*pi/(r*w1)", **kwargs)


def test_the_period_expression_and_a_guess_of_the_wrong_size():
    """The period expression in the scene's constants, 2π/(r w1) [s], and again at another
    value of the parameter r; a guess of the wrong size is refused naming ``guess``."""
    shooting = Shooting(_scene(), "2*pi/(r*w1)", steps_per_period=4, parameter="r")
    try:
        assert shooting.period == pytest.approx(2 * math.pi / (1.07 * 1302.92), rel=1e-15)
        shooting.set_parameter(1.1)
        assert shooting.period == pytest.approx(2 * math.pi / (1.1 * 1302.92), rel=1e-15)
        assert shooting.model.parameter_value("r") == 1.1
        with pytest.raises(SceneError, match="guess"):
            shooting.check_state(np.zeros(shooting.n_local + 1))
        with pytest.raises(SceneError, match="period"):
            Shooting(_scene(), "-1.0")
    finally:
        shooting.destroy()


def test_a_monodromy_too_large_for_memory_is_refused_naming_the_key():
    """600 cubic elements, planar: n = 6 × 1801 = 10806 dofs, whose dense columns (X, two
    stage rates, PETSc's two dense matrices, a copy: 6 n² doubles) need 5.2 GiB > 2 GiB."""
    with pytest.raises(SceneError, match=r"discretisation.elements: .* 5\.2 GiB"):
        Shooting(_scene(**{"discretisation.elements": 600}), "2*pi/(r*w1)")


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"end": 1.0}, "end"),
        ({"step": 0.02, "max_step": 0.01}, "step"),
        ({"step": -0.01}, "step"),
        ({"max_step": float("nan")}, "max_step"),
        ({"scale": 0.0}, "scale"),
        ({"settle": -1}, "settle"),
        ({"max_points": 1}, "max_points"),
        ({"start": "one"}, "start"),
    ],
)
def test_periodic_branch_refuses_bad_arguments_naming_them(kwargs, name):
    """Refused before anything is built, one line naming the argument."""
    arguments = {"start": 1.0, "end": 1.1, **kwargs}
    with pytest.raises(SceneError, match=f"^{name}: "):
        api.periodic_branch(_scene(), "2*pi/(r*w1)", "r", **arguments)


def test_the_determinant_is_the_product_of_the_multipliers_less_one():
    """Shooting.determinant from the LU of M − I: sign × exp(ln|det|) = Π(μ − 1) over the free
    dofs × (−1)^(held dofs) (M − I is −I there), on a 2-element rod at rest over 4 steps;
    the same matrix, so to round-off (1e-10 relative on ~50 factors)."""
    shooting = Shooting(_scene(), "2*pi/(r*w1)", steps_per_period=4, parameter="r")
    try:
        shooting.linearise(shooting.rest(), 1.07)
        sign, log_det = shooting.determinant()
        assert shooting.linearised is not None
        mu = shooting.multipliers(shooting.linearised)
        product = np.prod(mu - 1.0) * (-1.0) ** (shooting.n - mu.size)
    finally:
        shooting.destroy()
    assert abs(product.imag) <= 1e-10 * abs(product)
    assert sign * math.exp(log_det) == pytest.approx(product.real, rel=1e-10)


class FixedPoints(Dense):
    """The fixed points of a map u ↦ F(u, p) of R^n as a ContinuationProblem of the engine
    (cosserat_fem/nls/arclength.py), as a branch of orbits is (R = F − u, R_u = M − I, M =
    ∂F/∂u the "monodromy"; the engine unit tests' dense problem). ``multipliers(point)`` =
    eig M there."""

    def __init__(self, F, M, F_p):
        super().__init__(
            lambda u, p: np.asarray(F(u, p)) - u,
            lambda u, p: np.asarray(M(u, p)) - np.eye(u.size),
            F_p,
        )
        self.M = M

    def multipliers(self, point) -> np.ndarray:
        return np.linalg.eigvals(np.asarray(self.M(point.u, point.p), dtype=float))


def _centred(c, linear, nonlinear, dnonlinear):
    """F(u, p) = c(p) + A(p) v + g(v), v = u − c(p) (g(0) = 0, g'(0) = 0): the branch of fixed
    points u = c(p), whose multipliers are A(p)'s eigenvalues."""

    def F(u, p):
        v = u - c(p)
        return c(p) + linear(p) @ v + nonlinear(v)

    def M(u, p):
        return linear(p) + dnonlinear(u - c(p))

    def F_p(u, p):
        # h = 1e-7: F_p is only the engine's tangent and Newton direction (the corrector
        # converges on R itself); its error moves no located point
        h = 1e-7
        return (F(u, p + h) - F(u, p - h)) / (2 * h)

    return FixedPoints(F, M, F_p)


def _trace(problem: FixedPoints, start: float, end: float):
    """The branch from p = start to end by the engine with :func:`floquet_tests` (locate
    tolerance 1e-9 in arclength, the corrector's 1e-10)."""
    from cosserat_fem.analysis.periodic import floquet_tests
    from cosserat_fem.nls.arclength import Continuation, ContinuationSettings

    settings = ContinuationSettings(
        step=0.1, max_step=0.2, locate_tolerance=1e-9, p_min=start, p_max=end
    )
    engine = Continuation(problem, settings, tests=floquet_tests(problem.multipliers))
    guess = problem.residual(np.zeros(3), start) * 0.0
    branch = engine.trace(engine.start_point(guess, start, 1), 1)
    assert branch.reason == f"p reached {end:g}"
    return branch


def _located(problem: FixedPoints, start: float, end: float, kind: str, p_star: float):
    """The one special point of the branch from start to end: of ``kind``, at p* within 2e-9
    (module tests' tolerance)."""
    branch = _trace(problem, start, end)
    assert [q.kind for q in branch.special] == [kind]
    (point,) = branch.special
    assert abs(point.p - p_star) <= 2e-9, point.p
    return point


def _quadratic(v):
    return 0.3 * np.array([v[0] ** 2, v[0] * v[1], 0.0])


def _dquadratic(v):
    return 0.3 * np.array([[2 * v[0], 0, 0], [v[1], v[0], 0], [0, 0, 0]])


def test_a_period_doubling_of_a_map_is_located_where_a_real_multiplier_is_minus_one():
    """The closed form: F = c(p) + A(p)(u − c) + quadratic terms, A(p) = [[0, 1, 0], [−¼, −p,
    0], [0, 0, 0.3]]: multipliers μ² + pμ + ¼ = 0 (product ¼) and 0.3. For p < 1 a complex
    pair of modulus ½, meeting on the negative real axis at p = 1 and splitting into two reals,
    one reaching −1 where 1 − p + ¼ = 0: p* = 5/4, the period doubling. On the way from 0.2 to
    2 the engine finds exactly one special point, "period-doubling": the pair's meeting is no
    torus (the bialternate factor μ1 μ2 − 1 = −¾ throughout, which a product over the complex
    pairs alone, switching from |μ|² − 1 < 0 to nothing at p = 1, would not be). Located to
    |p − p*| ≤ 2e-9 (the locate tolerance 1e-9 in arclength, |dp/ds| ≤ 1, plus the
    corrector's 1e-10), so a multiplier within 2e-9 |dμ/dp| of −1, |dμ/dp| = |μ/(2μ + p)| =
    4/3 at p* (μ = −1): 3e-9 asserted; the point on the branch u = c(p*) to 1e-8."""

    def c(p):
        return np.array([math.sin(p), p**2, 0.5 * p])

    def A(p):
        return np.array([[0.0, 1.0, 0.0], [-0.25, -p, 0.0], [0.0, 0.0, 0.3]])

    problem = _centred(c, A, _quadratic, _dquadratic)
    point = _located(problem, 0.2, 2.0, "period-doubling", 1.25)
    mu = problem.multipliers(point)
    assert np.isreal(mu).all()
    assert np.min(np.abs(mu + 1.0)) <= 3e-9
    assert np.abs(point.u - c(point.p)).max() <= 1e-8


def test_a_torus_bifurcation_of_a_map_is_located_where_a_complex_pair_crosses_the_circle():
    """The closed form: A(p) = ρ(p) R(θ) ⊕ (−0.4), ρ(p) = 0.6 + 0.4 p, θ = 1.1 rad: the pair
    ρ e^{±iθ} crosses |μ| = 1 at p* = 1 (Neimark–Sacker), the real −0.4 stays inside; the
    engine on p from 0 to 2 finds one special point, "torus" (det(M + I) = |1 + ρe^{iθ}|² ×
    0.6 > 0 has no root), at |p − p*| ≤ 2e-9 (as above), where |μ| = ρ is within 0.4 × 2e-9
    of 1 (1e-9 asserted) and arg μ = ±θ to round-off; :func:`is_torus` holds there. A neutral
    saddle, A = diag(2, p, 0.1) (two real multipliers of product 2p = 1 at p = ½), is a root
    of the same test, which :func:`is_torus` rejects: located at ½ to 2e-9, no pair on the
    circle."""
    from cosserat_fem.analysis.periodic import is_torus

    theta = 1.1

    def c(p):
        return np.array([p, math.cos(p), p**3])

    def A(p):
        r = 0.6 + 0.4 * p
        block = r * np.array(
            [[math.cos(theta), -math.sin(theta)], [math.sin(theta), math.cos(theta)]]
        )
        return np.block([[block, np.zeros((2, 1))], [np.zeros((1, 2)), np.array([[-0.4]])]])

    problem = _centred(c, A, _quadratic, _dquadratic)
    point = _located(problem, 0.0, 2.0, "torus", 1.0)
    mu = problem.multipliers(point)
    pair = mu[np.abs(mu.imag) > 0]
    assert np.abs(np.abs(pair) - 1.0).max() <= 1e-9
    assert np.abs(np.abs(np.angle(pair)) - theta).max() <= 1e-12
    assert is_torus(mu)

    saddle = _centred(c, lambda p: np.diag([2.0, p, 0.1]), _quadratic, _dquadratic)
    assert not is_torus(saddle.multipliers(_located(saddle, 0.2, 0.8, "torus", 0.5)))
