"""Charts of the Euler angles: the reference frame they are measured from, and its resets.

The paper's angles (θ, ψ, φ) are singular at θ = ±π/2, det Ma = cos θ (66). Measured from a
frame A(σ) of quaternions instead of the fixed basis (forms/kinematics.py, "Charts"), the
directors are D(θ, ψ, φ) A, and moving the frame onto the rod's rotation brings the angles back
to zero. :func:`chart_of` and :func:`change_chart` do that at the Lagrange nodes, where it
changes nothing of the state: the directors, the position and the angular velocity ŵ are the
same before and after (the nodal values of A become those of the old D A; the angles become 0
and their rates Mm (θ̇, ψ̇, φ̇) = ŵ, since Mm = I at zero angles). Between the nodes the frame is the
normalised interpolant of the nodal quaternions, so a reset moves the interpolated rotation
by the interpolation error of the rotation field, O(h^(k+1)) for elements of degree k: the
discrete state changes by that much at a reset (docs/decisions.md, "Charts").

Why quaternions, not a rotation vector or a new set of Euler angles: docs/decisions.md,
"Charts". The numpy functions here mirror the UFL ones of forms/kinematics.py at the nodes
(tests/unit/rod/test_charts.py checks them against each other).
"""

from __future__ import annotations

import numpy as np

from cosserat_fem.common.rotations import quaternion_of_frame  # noqa: F401 (re-exported)

#: A reset moves the frame when |θ| exceeds this at some node [rad]: far enough from π/2 that a
#: step of up to ~0.5 rad of θ stays regular (|cos θ| ≥ 0.1 until θ = 1.47).
RESET_THETA = 0.9


def euler_matrix(theta, psi, phi) -> np.ndarray:
    """D of eq. (18) for arrays of angles: (..., 3, 3), row i the director d_i."""
    cth, sth = np.cos(theta), np.sin(theta)
    cps, sps = np.cos(psi), np.sin(psi)
    cph, sph = np.cos(phi), np.sin(phi)
    return np.stack(
        [
            np.stack([cph * cps + sph * sth * sps, sph * cth, -cph * sps + sph * sth * cps], -1),
            np.stack([-sph * cps + cph * sth * sps, cph * cth, sph * sps + cph * sth * cps], -1),
            np.stack([cth * sps, -sth, cth * cps], -1),
        ],
        -2,
    )


def angular_map(theta, phi) -> np.ndarray:
    """Mm of eq. (66) for arrays of angles: (..., 3, 3)."""
    cth, sth = np.cos(theta), np.sin(theta)
    cph, sph = np.cos(phi), np.sin(phi)
    zero, one = np.zeros_like(cth), np.ones_like(cth)
    return np.stack(
        [
            np.stack([cph, sph * cth, zero], -1),
            np.stack([-sph, cph * cth, zero], -1),
            np.stack([zero, -sth, one], -1),
        ],
        -2,
    )


def quaternion_frame(Q: np.ndarray) -> np.ndarray:
    """A = R(Q)ᵀ of (..., 4) quaternions of any nonzero length: (..., 3, 3), row j the frame
    vector a_j (forms/kinematics.quaternion_frame)."""
    Q = np.asarray(Q, dtype=float)
    q0, v = Q[..., 0], Q[..., 1:]
    hat = np.zeros((*Q.shape[:-1], 3, 3))
    hat[..., 0, 1], hat[..., 0, 2] = -v[..., 2], v[..., 1]
    hat[..., 1, 0], hat[..., 1, 2] = v[..., 2], -v[..., 0]
    hat[..., 2, 0], hat[..., 2, 1] = -v[..., 1], v[..., 0]
    scale = (2.0 / np.einsum("...i,...i", Q, Q))[..., None, None]
    R = np.eye(3) + scale * (q0[..., None, None] * hat + hat @ hat)
    return np.swapaxes(R, -1, -2)


def euler_angles(D: np.ndarray, near: np.ndarray | None = None) -> np.ndarray:
    """Angles (θ, ψ, φ) of (18) with D(θ, ψ, φ) = D, for (..., 3, 3) matrices: (..., 3).

    D[2, 1] = −sin θ, (D[2, 0], D[2, 2]) = cos θ (sin ψ, cos ψ), (D[0, 1], D[1, 1]) =
    cos θ (sin φ, cos φ). Two triples give each D, (θ, ψ, φ) and (π − θ, ψ + π, φ + π), each
    up to turns of 2π; without ``near`` the one with |θ| ≤ π/2 and ψ, φ in (−π, π], else the
    one nearest ``near`` (a continued output, e.g. the previous row). At θ = ±π/2 only ψ ∓ φ
    is defined (the chart's singularity): that is where a continued triple may jump."""
    D = np.asarray(D, dtype=float)
    theta = np.arcsin(np.clip(-D[..., 2, 1], -1.0, 1.0))
    psi = np.arctan2(D[..., 2, 0], D[..., 2, 2])
    phi = np.arctan2(D[..., 0, 1], D[..., 1, 1])
    first = np.stack([theta, psi, phi], -1)
    if near is None:
        return first
    second = np.stack([np.pi - theta, psi + np.pi, phi + np.pi], -1)
    one, two = (c + 2.0 * np.pi * np.round((near - c) / (2.0 * np.pi)) for c in (first, second))
    take = np.sum((two - near) ** 2, axis=-1) < np.sum((one - near) ** 2, axis=-1)
    return np.where(take[..., None], two, one)


def angular_map_rate(theta, phi, theta_dot, phi_dot) -> np.ndarray:
    """dMm/dτ = ∂Mm/∂θ θ̇ + ∂Mm/∂φ φ̇ for arrays: (..., 3, 3) (kinematics.angular_map_rate)."""
    cth, sth = np.cos(theta), np.sin(theta)
    cph, sph = np.cos(phi), np.sin(phi)
    zero = np.zeros_like(cth)
    return np.stack(
        [
            np.stack([-sph * phi_dot, cph * cth * phi_dot - sph * sth * theta_dot, zero], -1),
            np.stack([-cph * phi_dot, -sph * cth * phi_dot - cph * sth * theta_dot, zero], -1),
            np.stack([zero, -cth * theta_dot, zero], -1),
        ],
        -2,
    )


def _apply(M: np.ndarray, x: np.ndarray) -> np.ndarray:
    return np.einsum("nij,nj->ni", M, x)


def change_chart(full: np.ndarray, Q_old: np.ndarray, Q_new: np.ndarray) -> np.ndarray:
    """The nodal states ``full`` (nodes, 12) of U = (p, q) with angles measured from the frame
    of ``Q_old`` (nodes, 4), measured from that of ``Q_new`` instead: the same directors
    D(θ, ψ, φ) A(Q_old) = D(θ', ψ', φ') A(Q_new) (the triple with |θ'| ≤ π/2) and the same
    ŵ = Mm (θ̇, ψ̇, φ̇) (26). Positions and their rates are unchanged. A new array."""
    a, qa = full[:, 3:6], full[:, 9:12]
    D = euler_matrix(*a.T) @ quaternion_frame(Q_old)
    a_new = euler_angles(D @ np.swapaxes(quaternion_frame(Q_new), -1, -2))
    out = full.copy()
    out[:, 3:6] = a_new
    w = _apply(angular_map(a[:, 0], a[:, 2]), qa)
    out[:, 9:12] = np.linalg.solve(angular_map(a_new[:, 0], a_new[:, 2]), w[..., None])[..., 0]
    return out


def change_chart_rate(
    full: np.ndarray, rate: np.ndarray, Q_old: np.ndarray, Q_new: np.ndarray
) -> np.ndarray:
    """The rate U̇ = (ṗ, q̇) (nodes, 12) at the state ``full`` in the chart of ``Q_old``, in
    the chart of ``Q_new`` (:func:`change_chart`): the angular velocity implied by the angles'
    rate, Mm ṗ_a, and the angular acceleration d(Mm q_a)/dτ = Mm q̇_a + (dMm/dτ) q_a, with dMm/dτ
    along ṗ_a, are the same in both. A new array."""
    new = change_chart(full, Q_old, Q_new)
    a, qa, a2, qa2 = full[:, 3:6], full[:, 9:12], new[:, 3:6], new[:, 9:12]
    Mm, Mm2 = angular_map(a[:, 0], a[:, 2]), angular_map(a2[:, 0], a2[:, 2])
    pa = rate[:, 3:6]
    out = rate.copy()
    pa2 = np.linalg.solve(Mm2, _apply(Mm, pa)[..., None])[..., 0]
    out[:, 3:6] = pa2
    wdot = _apply(Mm, rate[:, 9:12]) + _apply(
        angular_map_rate(a[:, 0], a[:, 2], pa[:, 0], pa[:, 2]), qa
    )
    rest = wdot - _apply(angular_map_rate(a2[:, 0], a2[:, 2], pa2[:, 0], pa2[:, 2]), qa2)
    out[:, 9:12] = np.linalg.solve(Mm2, rest[..., None])[..., 0]
    return out


def chart_of(full: np.ndarray, Q: np.ndarray) -> np.ndarray:
    """The quaternions (nodes, 4) of the rods' own rotation D(θ, ψ, φ) A(Q) at the nodes,
    signed like ``Q`` (the field stays continuous: a reset turns a node's frame by less
    than π)."""
    D = euler_matrix(full[:, 3], full[:, 4], full[:, 5]) @ quaternion_frame(Q)
    Q_new = quaternion_of_frame(D)
    flip = np.einsum("ij,ij->i", Q_new, Q) < 0.0
    Q_new[flip] *= -1.0
    return Q_new
