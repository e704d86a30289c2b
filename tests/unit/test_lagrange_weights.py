"""Unit tests of Lagrange interpolation in cosserat_fem.timestepping.adaptive: lagrange_weights and
StateHistory.polynomial (the local error estimate's predictor, the dense output, SDIRK's
stage-rate predictor).

The polynomial through n nodes reproduces every polynomial of degree < n exactly, inside and
outside the nodes' span; for t^n it misses by the nodal polynomial ω(t) = Π_j (t − t_j)
(t^n − ω(t) has degree < n and agrees at the nodes). In floating point each weight
w_j = Π_{k≠j} (t − t_k)/(t_j − t_k) is a product of n − 1 factors, each a rounded
subtraction over a rounded subtraction, rounded by the division and the product: relative
error ≤ 4(n − 1) ε to first order; the sum Σ w_j u_j adds n roundings. So
|Σ w_j u_j − p(t)| ≤ 5 n ε Σ_j |w_j| |u_j| ≤ 5 n ε Λ(t) max_j |u_j|, with Λ(t) = Σ |w_j| the
Lebesgue function (≥ 1; 1.1 to 17.5 inside the nodes' span below, 194 and 1053 for the
extrapolations), plus the rounding of the exact value p(t) itself.
"""

from __future__ import annotations

import numpy as np
import pytest

from cosserat_fem.timestepping.adaptive import StateHistory, lagrange_weights

pytestmark = pytest.mark.unit

EPS = np.finfo(float).eps
NODES = np.array([0.0, 0.13, 0.5, 0.61, 1.37])  # uneven, as accepted adaptive steps are
POINTS = [0.07, 0.3, 0.55, 1.0, 1.37 + 0.4, 1.37 + 0.9]  # inside, and extrapolated


def bound(weights: np.ndarray, values: np.ndarray, exact: float) -> float:
    n = len(weights)
    return 5 * n * EPS * float(np.abs(weights) @ np.abs(values)) + EPS * abs(exact)


@pytest.mark.parametrize("t", POINTS)
def test_polynomials_below_the_degree_are_reproduced(t):
    """Monomials (t − 0.4)^k, k < n = 5, and a random polynomial of degree 4, at interior and
    extrapolated points, to the round-off bound of the module docstring."""
    w = lagrange_weights(NODES, t)
    rng = np.random.default_rng(7)
    coefficients = [np.eye(5)[k] for k in range(5)] + [rng.normal(size=5)]
    for c in coefficients:
        values = np.polynomial.polynomial.polyval(NODES - 0.4, c)
        exact = float(np.polynomial.polynomial.polyval(t - 0.4, c))
        assert abs(w @ values - exact) <= bound(w, values, exact), (t, c)
    assert abs(w.sum() - 1.0) <= bound(w, np.ones(5), 1.0)


@pytest.mark.parametrize("t", POINTS)
def test_degree_n_misses_by_the_nodal_polynomial(t):
    """For u = t^n the interpolant is t^n − ω(t): the error formula, to the same bound (and
    ω(t) is not small at these points, so the weights do not reproduce degree n)."""
    w = lagrange_weights(NODES, t)
    values = NODES**5
    omega = float(np.prod(t - NODES))
    assert abs(w @ values - (t**5 - omega)) <= bound(w, values, t**5)
    assert abs(omega) > 1e-4


def test_weights_at_the_nodes_are_exact():
    """At a node t_j every factor of w_j is a/a = 1 and every other weight has the factor
    (t_j − t_j) = 0: the Kronecker delta with no rounding at all."""
    for j, t in enumerate(NODES):
        np.testing.assert_array_equal(lagrange_weights(NODES, t), np.eye(len(NODES))[j])


def test_lebesgue_function_at_the_points():
    """The bound's Λ(t) at the points used, so that the tolerance's size is on record: 1.33,
    2.31, 1.10, 17.5 inside the nodes' span (t = 1 lies in the long last interval), 194 and
    1053 for the extrapolations by 0.4 and 0.9 beyond it (the error estimate extrapolates by
    one step, the dense output only interpolates). Measured errors: at most 1.35 ε Σ|w_j||u_j|
    against the bound's 25 ε Σ|w_j||u_j|."""
    lebesgue = [np.abs(lagrange_weights(NODES, t)).sum() for t in POINTS]
    expected = [1.3348, 2.3070, 1.0958, 17.493, 194.35, 1052.6]
    np.testing.assert_allclose(lebesgue, expected, rtol=1e-4)


def test_two_node_weights_by_hand():
    """Linear interpolation/extrapolation: w = ((t − t1)/(t0 − t1), (t − t0)/(t1 − t0))."""
    np.testing.assert_allclose(lagrange_weights([1.0, 3.0], 4.0), [-0.5, 1.5], rtol=0, atol=EPS)
    np.testing.assert_allclose(lagrange_weights([1.0, 3.0], 2.5), [0.25, 0.75], rtol=0, atol=EPS)
    np.testing.assert_array_equal(lagrange_weights([2.0], 5.0), [1.0])


def vector_polynomial(t: float) -> np.ndarray:
    """Three components of degrees 3, 2 and 0 (what a state array of a smooth run is, locally)."""
    return np.array([2.0 - t + 0.5 * t**2 - 0.25 * t**3, 3.0 * t**2 - 1.0, 7.0])


def test_state_history_polynomial():
    """Capacity 6, eight states pushed at uneven times (the first two are garbage, not on the
    polynomial: they must have left the history); the newest 4 reproduce the cubic at an
    interior time and at the next step's time, the newest 6 likewise; the same bound as the
    weights (Λ ≤ 87 here, values ≤ 7: 5·6·ε·87·7 ≈ 4e-12, asserted 1e-11)."""
    times = [0.0, 0.2, 0.35, 0.4, 0.62, 0.7, 0.95, 1.03]
    history = StateHistory(capacity=6)
    for k, t in enumerate(times):
        state = np.full(3, 1e6) if k < 2 else vector_polynomial(t)
        history.push(t, state)
    assert len(history) == 6
    assert history.newest[0] == 1.03
    np.testing.assert_array_equal(history.newest[1], vector_polynomial(1.03))
    for points in (4, 6):
        for t in (0.9, 1.2):
            np.testing.assert_allclose(
                history.polynomial(t, points), vector_polynomial(t), rtol=0, atol=1e-11
            )
    # The newest 3 points reproduce degree 2 but not the cubic component.
    quadratic = history.polynomial(1.2, 3)
    np.testing.assert_allclose(quadratic[1:], vector_polynomial(1.2)[1:], rtol=0, atol=1e-11)
    assert abs(quadratic[0] - vector_polynomial(1.2)[0]) > 1e-3


def test_state_history_copies_and_round_trip():
    """push copies the array (the caller's U changes afterwards); state_dict/load_state_dict
    give the same polynomial bit for bit, and respect the capacity."""
    history = StateHistory(capacity=4)
    u = np.zeros(3)
    for t in (0.0, 0.3, 0.5, 0.9, 1.4):
        u[:] = vector_polynomial(t)
        history.push(t, u)
    u[:] = -1.0
    np.testing.assert_array_equal(history.newest[1], vector_polynomial(1.4))
    state = history.state_dict()
    assert list(state["times"]) == [0.3, 0.5, 0.9, 1.4] and state["states"].shape == (4, 3)
    again = StateHistory(capacity=4)
    again.push(-5.0, np.ones(3))  # replaced by the load
    again.load_state_dict(state)
    assert len(again) == 4
    np.testing.assert_array_equal(again.polynomial(1.7, 4), history.polynomial(1.7, 4))
    state["states"][:] = 0.0  # the loaded history holds copies
    np.testing.assert_array_equal(again.newest[1], vector_polynomial(1.4))
