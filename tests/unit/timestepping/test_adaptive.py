"""Unit tests of cosserat_fem/timestepping/adaptive.py: the step-size controller and Lagrange
interpolation.

The step-size controller, StepController.

The rules (module docstring of cosserat_fem/timestepping/adaptive.py): ‖est‖ = sqrt(mean((est_i /
(atol + rtol P_c(i)))²)) over the controlled entries, P_c the largest |value| field c has
reached so far (its peak, updated by accepted states only); the next step is h times
min(GROWTH, max(SHRINK, SAFETY ‖est‖^(−1/(p+1)))) with SAFETY = 0.8, GROWTH = 1.5,
SHRINK = 0.2; after a rejection at most 1; a ratio in [1, KEEP = 1.2] is not made (1 instead).
Serial (MPI.COMM_SELF): the reductions are then the local sums and maxima.

Lagrange interpolation, lagrange_weights and StateHistory.polynomial (the local error
estimate's predictor, the dense output, SDIRK's stage-rate predictor).

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

import math

import numpy as np
import pytest
from mpi4py import MPI

from cosserat_fem.timestepping import adaptive
from cosserat_fem.timestepping.adaptive import StateHistory, StepController, lagrange_weights

pytestmark = pytest.mark.unit

EPS = np.finfo(float).eps
RTOL, ATOL = 1e-3, 1e-6


def controller(order: int = 2, counted: int | None = None) -> StepController:
    """Blocks of 3 (fields a, b, c), the first two controlled, 2 blocks owned (6 entries);
    arrays carry 3 ghost entries after them."""
    return StepController(
        RTOL,
        ATOL,
        order,
        MPI.COMM_SELF,
        n_owned=6,
        block=3,
        controlled=slice(0, 2),
        counted=counted,
    )


STATE = np.array([1.0, -4.0, 100.0, -3.0, 2.0, -7.0, 50.0, 50.0, 50.0])  # peaks a 3, b 4
SMALL = 0.5 * STATE  # peaks a 1.5, b 2
TINY = 0.01 * STATE
EST = np.array([3e-3, -2e-3, 9.0, 1e-3, 4e-3, 9.0, 9.0, 9.0, 9.0])  # c and ghosts: ignored


def by_hand(est_ab: list[list[float]], peaks: list[float], count: int) -> float:
    """The weighted RMS norm written out: Σ over blocks and fields of (e / (atol + rtol P))²,
    divided by the number counted, square-rooted."""
    total = 0.0
    for block in est_ab:
        for e, peak in zip(block, peaks, strict=True):
            total += (e / (ATOL + RTOL * peak)) ** 2
    return math.sqrt(total / count)


EST_AB = [[3e-3, -2e-3], [1e-3, 4e-3]]


def test_constants_are_the_documented_ones():
    assert (adaptive.SAFETY, adaptive.GROWTH, adaptive.SHRINK, adaptive.KEEP) == (
        0.8,
        1.5,
        0.2,
        1.2,
    )


def test_error_norm_by_hand():
    """Peak-relative weights: scales atol + rtol (3, 4) = 3.001e-3, 4.001e-3 for fields a, b
    of STATE (the largest |value| over both blocks; field c, 100, and the ghost entries, 50,
    do not count), RMS over 2 blocks x 2 fields (or over 2 x 3 with counted = 3, a reduced
    model's share). Equal to a few ε relative (a sum of four squares, one sqrt)."""
    c = controller()
    assert c.error_norm(EST, STATE) == pytest.approx(by_hand(EST_AB, [3, 4], 4), rel=8 * EPS)
    c3 = controller(counted=3)
    assert c3.error_norm(EST, STATE) == pytest.approx(by_hand(EST_AB, [3, 4], 6), rel=8 * EPS)
    # Entry-wise weights would differ: the point of the peaks (block 2's a is 3, b is 2).
    entrywise = math.sqrt(
        sum(
            (e / (ATOL + RTOL * abs(u))) ** 2
            for e, u in zip([3e-3, -2e-3, 1e-3, 4e-3], [1.0, -4.0, -3.0, 2.0], strict=True)
        )
        / 4
    )
    assert abs(c.error_norm(EST, STATE) - entrywise) > 0.1


def test_peaks_follow_accepted_states_only():
    """A rejected candidate's magnitudes are forgotten; an accepted one's are kept as the
    peaks, which later smaller states do not lower; accept() without a preceding error_norm
    takes the state's magnitudes itself."""
    c = controller()
    c.error_norm(EST, STATE)
    c.reject()
    np.testing.assert_array_equal(c.peak, [0.0, 0.0])
    # Now SMALL is the candidate (STATE was rejected): its own peaks, 1.5 and 2.
    assert c.error_norm(EST, SMALL) == pytest.approx(by_hand(EST_AB, [1.5, 2], 4), rel=8 * EPS)
    c.accept(SMALL)
    np.testing.assert_array_equal(c.peak, [1.5, 2.0])
    # TINY after SMALL: the scale stays at SMALL's peaks.
    assert c.error_norm(EST, TINY) == pytest.approx(by_hand(EST_AB, [1.5, 2], 4), rel=8 * EPS)
    c.accept(TINY)
    np.testing.assert_array_equal(c.peak, [1.5, 2.0])
    c.accept(STATE)  # no error_norm before it
    np.testing.assert_array_equal(c.peak, [3.0, 4.0])


@pytest.mark.parametrize(
    ("order", "proposal", "rejected", "expected"),
    [
        (2, 1.3, False, 1.3),  # above KEEP: made
        (2, 1.1, False, 1.0),  # in [1, KEEP]: not made (a frozen Jacobian lives longer)
        (2, 1.19, False, 1.0),
        (2, 1.21, False, 1.21),
        (2, 0.9, False, 0.9),  # a decrease is always made
        (2, 0.5, False, 0.5),
        (2, 1000.0, False, 1.5),  # GROWTH
        (2, 0.01, False, 0.2),  # SHRINK
        (2, 0.7, True, 0.7),  # rejected: the proposal if below 1 ...
        (2, 1.3, True, 1.0),  # ... never above 1
        (2, 0.1, True, 0.2),
        (3, 1.3, False, 1.3),
        (3, 0.4, True, 0.4),
        (4, 0.6, False, 0.6),
    ],
)
def test_factor(order, proposal, rejected, expected):
    """The error that makes SAFETY err^(−1/(p+1)) equal to ``proposal`` is
    (SAFETY/proposal)^(p+1); the factor is then the clipped, hysteresis-filtered proposal, to
    a few ε (one power and one product, each rounded)."""
    c = controller(order=order)
    error = (0.8 / proposal) ** (order + 1)
    assert c.factor(error, rejected=rejected) == pytest.approx(expected, rel=8 * EPS)


def test_factor_edge_cases():
    """‖est‖ = 0 (or ≤ 0): GROWTH (1 after a rejection); NaN or ∞: SHRINK; exactly 1 is made
    by hysteresis as 1 (not 0.8^(...) rounding to 0.9999999999999999)."""
    c = controller()
    assert c.factor(0.0) == 1.5
    assert c.factor(-1.0) == 1.5
    assert c.factor(0.0, rejected=True) == 1.0
    assert c.factor(math.inf) == 0.2
    assert c.factor(math.nan) == 0.2
    assert c.factor(math.nan, rejected=True) == 0.2
    assert c.factor(0.512) == 1.0  # 0.8 · 0.512^(−1/3) = 1 up to rounding
    # The boundaries of the hysteresis band, by the proposal 0.8 err^(−1/3) itself.
    just_above = np.nextafter(1.2, 2.0)
    err = (0.8 / just_above) ** 3
    proposal = 0.8 * err ** (-1.0 / 3.0)
    assert c.factor(err) == (proposal if proposal > 1.2 else 1.0)


def test_state_dict_round_trip():
    """The peaks are the whole state: a controller loaded from another's state_dict gives the
    same norms bit for bit; the dict is a copy; a pending candidate does not survive a load;
    a list (e.g. read back from JSON) loads as float64."""
    a = controller()
    a.error_norm(EST, SMALL)
    a.accept(SMALL)
    state = a.state_dict()
    b = controller()
    b.error_norm(EST, 10 * STATE)  # a pending candidate with large peaks
    b.load_state_dict(state)
    for s in (TINY, SMALL, STATE):
        assert b.error_norm(EST, s) == a.error_norm(EST, s)
    b.reject()
    a.reject()
    b.accept(TINY)  # takes max(loaded peaks, TINY), not the stale 10 x STATE candidate
    np.testing.assert_array_equal(b.peak, [1.5, 2.0])
    state["peak"][:] = 99.0
    np.testing.assert_array_equal(a.peak, [1.5, 2.0])
    c = controller()
    c.load_state_dict({"peak": [1, 2]})
    assert c.peak.dtype == np.float64 and list(c.peak) == [1.0, 2.0]


# Lagrange interpolation: lagrange_weights and StateHistory.polynomial.

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
