"""Unit tests of the charts' nodal algebra, cosserat_fem/rod/charts.py.

Each function is checked against an independent construction: D of (18) against the product
Dφ Dθ Dψ of the elementary rotations (15)-(17); Mm (66) against the angular velocity of a
finite-differenced D; the quaternion frame against Rodrigues' formula for an axis and angle;
Shepperd's inverse by the round trip through random rotations, near every branch of the
method. A reset must leave the nodal directors and ŵ as they were (to round-off, 1e-14 on
entries of size 1). Random states: angles of order 1 rad and up to θ = ±1.5.
"""

from __future__ import annotations

import numpy as np
import pytest

from cosserat_fem.rod.charts import (
    angular_map,
    change_chart,
    change_chart_rate,
    chart_of,
    euler_angles,
    euler_matrix,
    quaternion_frame,
    quaternion_of_frame,
)

pytestmark = pytest.mark.unit
RNG = np.random.default_rng(2026)


def _elementary(theta, psi, phi):
    c, s = np.cos, np.sin
    d_psi = np.array([[c(psi), 0, -s(psi)], [0, 1, 0], [s(psi), 0, c(psi)]])
    d_theta = np.array([[1, 0, 0], [0, c(theta), s(theta)], [0, -s(theta), c(theta)]])
    d_phi = np.array([[c(phi), s(phi), 0], [-s(phi), c(phi), 0], [0, 0, 1]])
    return d_phi @ d_theta @ d_psi


def _angles(n):
    a = RNG.uniform(-3.0, 3.0, (n, 3))
    a[:, 0] = RNG.uniform(-1.5, 1.5, n)
    return a


def test_euler_matrix_is_the_product_of_the_elementary_rotations():
    a = _angles(50)
    D = euler_matrix(a[:, 0], a[:, 1], a[:, 2])
    for k in range(50):
        assert np.abs(D[k] - _elementary(*a[k])).max() < 1e-15


def test_angular_map_gives_the_angular_velocity():
    """ŵ = Mm (θ̇, ψ̇, φ̇) (26), the director components of w with ḋ_i = w × d_i (4), checked by
    central differences of D along a straight path in angle space (error ~1e-10)."""
    a, rate = _angles(20), RNG.standard_normal((20, 3))
    h = 1e-5
    Dp = euler_matrix(*(a + h * rate).T)
    Dm = euler_matrix(*(a - h * rate).T)
    D = euler_matrix(*a.T)
    Ddot = (Dp - Dm) / (2 * h)
    W = Ddot @ np.swapaxes(D, 1, 2)  # ḋ_i = w × d_i: W_il = ḋ_i · d_l = ε_ilm ŵ_m
    w = np.stack([W[:, 1, 2], W[:, 2, 0], W[:, 0, 1]], -1)
    Mm = angular_map(a[:, 0], a[:, 2])
    assert np.abs(w - np.einsum("nij,nj->ni", Mm, rate)).max() < 1e-9


def test_quaternion_frame_is_rodrigues_rotation():
    axis = RNG.standard_normal((30, 3))
    axis /= np.linalg.norm(axis, axis=1)[:, None]
    angle = RNG.uniform(-7.0, 7.0, 30)
    scale = RNG.uniform(0.3, 3.0, 30)  # any length: R(Q) is exact for every Q ≠ 0
    Q = scale[:, None] * np.concatenate(
        [np.cos(angle / 2)[:, None], np.sin(angle / 2)[:, None] * axis], 1
    )
    A = quaternion_frame(Q)
    for k in range(30):
        x, y, z = axis[k]
        K = np.array([[0, -z, y], [z, 0, -x], [-y, x, 0]])
        R = np.eye(3) + np.sin(angle[k]) * K + (1 - np.cos(angle[k])) * K @ K
        assert np.abs(A[k] - R.T).max() < 1e-14


@pytest.mark.parametrize("branch", range(4))
def test_quaternion_of_frame_inverts_the_frame(branch):
    """Rotations whose largest of (1 + tr, 1 + 2 R_ii − tr) is the branch's: the round trip
    Q → A → Q returns the unit quaternion with q0 ≥ 0."""
    Q = RNG.standard_normal((40, 4)) * 0.2
    Q[:, branch] += 2.0
    Q /= np.linalg.norm(Q, axis=1)[:, None]
    Q[Q[:, 0] < 0] *= -1
    assert np.abs(quaternion_of_frame(quaternion_frame(Q)) - Q).max() < 1e-14


def test_euler_angles_invert_and_continue():
    a = _angles(40)
    D = euler_matrix(*a.T)
    principal = euler_angles(D)
    assert np.abs(euler_matrix(*principal.T) - D).max() < 1e-14
    assert np.all(np.abs(principal[:, 0]) <= np.pi / 2)
    # Continued from a nearby triple on the other branch, two turns up: that one comes back.
    other = np.stack([np.pi - a[:, 0], a[:, 1] + np.pi, a[:, 2] + np.pi], -1) + 4 * np.pi
    near = other + RNG.uniform(-0.3, 0.3, other.shape)
    assert np.abs(euler_angles(D, near) - other).max() < 1e-12


def test_reset_keeps_the_nodal_directors_and_angular_velocity():
    n = 25
    full = RNG.standard_normal((n, 12))
    full[:, 3:6] = _angles(n)
    Q = RNG.standard_normal((n, 4))
    Q /= np.linalg.norm(Q, axis=1)[:, None]
    Q_new = chart_of(full, Q)
    new = change_chart(full, Q, Q_new)
    before = euler_matrix(*full[:, 3:6].T) @ quaternion_frame(Q)
    after = euler_matrix(*new[:, 3:6].T) @ quaternion_frame(Q_new)
    assert np.abs(after - before).max() < 1e-14
    assert np.abs(new[:, 3:6]).max() < 1e-15
    w_before = np.einsum("nij,nj->ni", angular_map(full[:, 3], full[:, 5]), full[:, 9:12])
    assert np.abs(new[:, 9:12] - w_before).max() < 1e-14
    assert np.array_equal(new[:, :3], full[:, :3]) and np.array_equal(new[:, 6:9], full[:, 6:9])
    assert np.all(np.einsum("ij,ij->i", Q_new, Q) >= 0.0)  # signed like the old ones


def _random_quaternions(n):
    Q = RNG.standard_normal((n, 4))
    return Q / np.linalg.norm(Q, axis=1)[:, None]


def test_change_of_chart_keeps_the_motion():
    """A state moved to another chart has the same directors and ŵ, and moved back it is the
    state it was (the charts' frames within ~1 rad of the rod's rotation, as after a reset)."""
    n = 25
    full = RNG.standard_normal((n, 12))
    full[:, 3:6] = 0.5 * _angles(n)
    Q_old = _random_quaternions(n)
    Q_new = Q_old + 0.3 * RNG.standard_normal((n, 4))
    new = change_chart(full, Q_old, Q_new)
    before = euler_matrix(*full[:, 3:6].T) @ quaternion_frame(Q_old)
    assert np.abs(euler_matrix(*new[:, 3:6].T) @ quaternion_frame(Q_new) - before).max() < 1e-14
    back = change_chart(new, Q_new, Q_old)
    assert np.abs(back - full).max() < 1e-12


def test_change_of_chart_of_a_rate_is_the_derivative_of_the_moved_states():
    """Along a motion U(τ) (angles and rates polynomials of τ), the rate in the new chart is
    d/dτ of the moved states (central differences, error ~1e-9). The charts are a few tenths
    of a radian apart, as at a reset, so that the new angles stay off the branch cuts of ψ and
    φ at ±π (where the differences of the principal triple would jump by 2π)."""
    n = 20
    c0, c1, c2 = (RNG.standard_normal((n, 12)) for _ in range(3))
    c0[:, 3:6] = RNG.uniform(-0.4, 0.4, (n, 3))

    def state(t):
        return c0 + t * c1 + t * t * c2

    rate = c1  # dU/dτ at τ = 0
    Q_old = _random_quaternions(n)
    Q_new = Q_old + 0.1 * RNG.standard_normal((n, 4))
    h = 1e-5
    fd = (change_chart(state(h), Q_old, Q_new) - change_chart(state(-h), Q_old, Q_new)) / (2 * h)
    mapped = change_chart_rate(state(0.0), rate, Q_old, Q_new)
    assert np.abs(mapped[:, 3:6] - fd[:, 3:6]).max() < 1e-8
    assert np.abs(mapped[:, 9:12] - fd[:, 9:12]).max() < 1e-8
    assert np.array_equal(mapped[:, :3], rate[:, :3])
