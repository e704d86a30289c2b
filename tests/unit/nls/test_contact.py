"""cosserat_fem/nls/contact.py: the tangent bases of the contact rows.

The rows' values and Jacobian are checked on a model in tests/test_contact.py (central
differences of the rows on a tilted cylinder, slip in 3D). Here: each basis T is orthonormal
and orthogonal to its normal, in 2D and 3D, and ∂T/∂n is the derivative of the map n ↦ T
(central differences along directions tangent to the unit sphere and along n, error O(ε²):
bound 1e-8 at ε = 1e-6).
"""

from __future__ import annotations

import numpy as np
import pytest

from cosserat_fem.nls.contact import tangent_bases

pytestmark = pytest.mark.unit


@pytest.mark.parametrize("m", [2, 3])
def test_tangent_bases_are_orthonormal_complements(m):
    rng = np.random.default_rng(m)
    n = rng.normal(size=(20, m))
    n /= np.linalg.norm(n, axis=1)[:, None]
    T, _ = tangent_bases(n)
    assert T.shape == (20, m - 1, m)
    full = np.concatenate([n[:, None, :], T], axis=1)
    assert np.abs(full @ full.transpose(0, 2, 1) - np.eye(m)).max() < 1e-14


@pytest.mark.parametrize("m", [2, 3])
def test_the_bases_derivative_is_the_derivative(m):
    rng = np.random.default_rng(10 + m)
    n = rng.normal(size=(8, m))
    n /= np.linalg.norm(n, axis=1)[:, None]
    _, dT = tangent_bases(n)
    eps = 1e-6
    for k in range(m):
        step = np.zeros(m)
        step[k] = eps
        plus, _ = tangent_bases(n + step)
        minus, _ = tangent_bases(n - step)
        assert np.abs((plus - minus) / (2 * eps) - dT[..., k]).max() < 1e-8
