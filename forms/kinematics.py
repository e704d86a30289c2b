"""Kinematics of the Cao & Tucker (2008) rod in the Euler-angle chart, eqs. (14)-(29), (66).

The unknown is p = (p1, ..., p6) = (x/ℓ, y/ℓ, z/ℓ, θ, ψ, φ) (47), q = dp/dτ; a prime is
d/dσ. All functions take and return UFL expressions.
"""

from __future__ import annotations

import ufl


def rotation_matrix(theta, psi, phi) -> ufl.core.expr.Expr:
    """D = Dφ Dθ Dψ of eq. (18): row i holds the director d_i in the fixed basis e_j.

    ψ rotates about e2 (15), then θ about the new e1 (16), then φ about d3 (17).
    """
    cth, sth = ufl.cos(theta), ufl.sin(theta)
    cps, sps = ufl.cos(psi), ufl.sin(psi)
    cph, sph = ufl.cos(phi), ufl.sin(phi)
    return ufl.as_matrix(
        [
            [cph * cps + sph * sth * sps, sph * cth, -cph * sps + sph * sth * cps],
            [-sph * cps + cph * sth * sps, cph * cth, sph * sps + cph * sth * cps],
            [cth * sps, -sth, cth * cps],
        ]
    )


def angular_map(theta, phi) -> ufl.core.expr.Expr:
    """Mm of eq. (66): maps (θ', ψ', φ') to u (25) and (θ̇, ψ̇, φ̇) to w (26).

    det Mm = cos θ: the Euler-angle chart is singular at θ = ±π/2.
    """
    cth, sth = ufl.cos(theta), ufl.sin(theta)
    cph, sph = ufl.cos(phi), ufl.sin(phi)
    return ufl.as_matrix([[cph, sph * cth, 0.0], [-sph, cph * cth, 0.0], [0.0, -sth, 1.0]])


def angular_map_rate(theta, phi, theta_dot, phi_dot) -> ufl.core.expr.Expr:
    """dMm/dτ = ∂Mm/∂θ θ̇ + ∂Mm/∂φ φ̇ (the velocity-product terms of (64))."""
    cth, sth = ufl.cos(theta), ufl.sin(theta)
    cph, sph = ufl.cos(phi), ufl.sin(phi)
    return ufl.as_matrix(
        [
            [-sph * phi_dot, cph * cth * phi_dot - sph * sth * theta_dot, 0.0],
            [-cph * phi_dot, -sph * cth * phi_dot - cph * sth * theta_dot, 0.0],
            [0.0, -cth * theta_dot, 0.0],
        ]
    )


#: Names of the components of p (47), in order (probes, summaries, output tables).
P_NAMES = ("x", "y", "z", "theta", "psi", "phi")


def split(vec12):
    """(p, q) from the 12-component unknown U = (p, q)."""
    return (
        ufl.as_vector([vec12[i] for i in range(6)]),
        ufl.as_vector([vec12[i] for i in range(6, 12)]),
    )


def sigma_derivatives(U) -> tuple[ufl.core.expr.Expr, ufl.core.expr.Expr]:
    """(p', q') = d/dσ of the two halves of the 12-component U = (p, q)."""
    dU = U.dx(0)
    return split(ufl.as_vector([dU[i] for i in range(12)]))


def translations(p6):
    """(p1, p2, p3) of a 6-vector."""
    return ufl.as_vector([p6[0], p6[1], p6[2]])


def angles(p6):
    """(p4, p5, p6) = (θ, ψ, φ) of a 6-vector."""
    return ufl.as_vector([p6[3], p6[4], p6[5]])


def stretch_shear_strain(p, dp) -> ufl.core.expr.Expr:
    """v_i = d_i · ∂r/∂s, eq. (29), dimensionless: r' = (p1', p2', 1 + p3') by (14), (27)."""
    D = rotation_matrix(p[3], p[4], p[5])
    r_prime = ufl.as_vector([dp[0], dp[1], 1.0 + dp[2]])
    return D * r_prime


def curvature(p, dp) -> ufl.core.expr.Expr:
    """û = ℓ u, components in the director basis, eq. (25): û = Mm (θ', ψ', φ')."""
    return angular_map(p[3], p[5]) * angles(dp)


def angular_velocity(p, q) -> ufl.core.expr.Expr:
    """ŵ = w/ω0, components in the director basis, eq. (26): ŵ = Mm (θ̇, ψ̇, φ̇)."""
    return angular_map(p[3], p[5]) * angles(q)


def strain_rates(p, dp, q, dq) -> tuple[ufl.core.expr.Expr, ufl.core.expr.Expr]:
    """τ-derivatives of the director components of v (29) and û (25), the objective strain
    rates of a Kelvin–Voigt law.

    v_i = d_i · r' with ḋ_i = w × d_i (4) gives v̇ = D (q1', q2', q3') + v × ŵ (the second
    term vanishes for a rigid rotation, where r' turns with the directors); û = Mm (θ', ψ', φ')
    gives û̇ = (dMm/dτ) (θ', ψ', φ') + Mm (θ̇', ψ̇', φ̇'), with q' = dq/dσ."""
    D = rotation_matrix(p[3], p[4], p[5])
    v = stretch_shear_strain(p, dp)
    w = angular_velocity(p, q)
    v_dot = D * translations(dq) + ufl.cross(v, w)
    mdot = angular_map_rate(p[3], p[5], q[3], q[5])
    u_dot = mdot * angles(dp) + angular_map(p[3], p[5]) * angles(dq)
    return v_dot, u_dot
