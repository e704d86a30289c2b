"""Unit checks of cosserat_fem/rom/hyper.py's ECSW selection without a rod: the greedy
non-negative least squares (Lawson & Hanson stopped at a tolerance, docs/rom.md (11)) on
synthetic problems whose sparse solutions are known exactly, and the training system's
scaling."""

from __future__ import annotations

import numpy as np
import pytest

from cosserat_fem.common.errors import SceneError
from cosserat_fem.rom.hyper import nnls_select, training_system

pytestmark = pytest.mark.unit


def test_nnls_recovers_a_known_sparse_solution():
    """d = C ξ* with ξ* ≥ 0 nonzero on 4 of 30 columns of a Gaussian C (80 rows, full column
    rank): the NNLS problem's minimiser is unique and is ξ*, so the selection stopped at
    ‖C ξ − d‖ ≤ 1e-12 ‖d‖ has ‖ξ − ξ*‖ ≤ 1e-12 ‖d‖ / σ_min(C) (here ≈ 4e-12): the weights on
    ξ*'s support equal it to that bound, any other column's weight is below it."""
    rng = np.random.default_rng(7)
    C = rng.standard_normal((80, 30))
    truth = np.zeros(30)
    support = np.array([3, 11, 17, 28])
    truth[support] = [0.5, 2.0, 1.25, 3.0]
    d = C @ truth
    chosen, weights, error = nnls_select(C, d, 1e-12)
    found = np.zeros(30)
    found[chosen] = weights
    bound = 1e-12 * np.linalg.norm(d) / np.linalg.svd(C, compute_uv=False)[-1]
    assert error <= 1e-12
    assert np.abs(found - truth).max() <= bound
    assert set(support) <= set(chosen.tolist())


def test_tolerance_stops_at_the_closed_form_count():
    """Orthonormal columns Q (60 × 12) and d = Q ξ*, ξ*_j = 2^-j: the gradient Qᵀ r picks the
    columns in the order of ξ*, each fit is exact on its column, and after p columns the
    relative residual is √(Σ_{j≥p} 4^-j / Σ_j 4^-j). With τ = 1e-2 the selection stops at
    the first p whose tail is ≤ τ (p = 7: 7.8e-3; p = 6: 1.6e-2), weights ξ*_j to round-off."""
    rng = np.random.default_rng(3)
    Q = np.linalg.qr(rng.standard_normal((60, 12)))[0]
    truth = 2.0 ** -np.arange(12)
    tails = np.sqrt(np.cumsum((truth**2)[::-1])[::-1] / np.sum(truth**2))
    expected = int(np.argmax(np.append(tails[1:], 0.0) <= 1e-2)) + 1
    chosen, weights, error = nnls_select(Q, Q @ truth, 1e-2)
    assert expected == 7
    assert sorted(chosen.tolist()) == list(range(expected))
    assert np.allclose(weights, truth[chosen], rtol=0, atol=1e-13)
    assert error == pytest.approx(tails[expected], rel=1e-10)


def test_max_elements_bounds_the_set_and_bad_tolerance_is_refused():
    """``max_elements`` = 3 on the problem above stops at 3 columns (residual tail[3] = 0.125
    > τ, reported); a tolerance outside [0, 1) is one SceneError naming the key."""
    rng = np.random.default_rng(3)
    Q = np.linalg.qr(rng.standard_normal((60, 12)))[0]
    truth = 2.0 ** -np.arange(12)
    chosen, _, error = nnls_select(Q, Q @ truth, 1e-6, max_elements=3)
    assert chosen.size == 3 and error > 0.12
    with pytest.raises(SceneError, match="tolerance"):
        nnls_select(Q, Q @ truth, 1.5)


def test_training_system_scales_each_state_and_sums_to_d():
    """Blocks (cells, m) of two states, one 1e6 times the other: each enters C with unit
    Frobenius norm, a zero block is left out, and d = C 1 (ξ = 1 fits exactly)."""
    rng = np.random.default_rng(5)
    a = rng.standard_normal((5, 4))
    C, d = training_system([a, 1e6 * a, np.zeros((5, 4))])
    assert C.shape == (8, 5)
    assert np.linalg.norm(C[:4]) == pytest.approx(1.0) and np.allclose(C[:4], C[4:])
    assert np.allclose(d, C @ np.ones(5))
    with pytest.raises(SceneError, match="ecsw"):
        training_system([np.zeros((5, 4))])
