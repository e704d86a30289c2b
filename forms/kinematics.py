"""Kinematics of the Cao & Tucker (2008) rod in the Euler-angle chart, eqs. (14)-(29), (66).

The unknown is p = (p1, ..., p6) = (x/ℓ, y/ℓ, z/ℓ, θ, ψ, φ) (47), q = dp/dτ; a prime is
d/dσ. All functions take and return UFL expressions.

**Charts.** The paper measures the angles from the fixed basis e_j: the directors are
d_i = Σ_j D_ij e_j with D of (18). Measured instead from a reference frame a_j(σ) that does
not move in time (a :class:`Chart`, row j of A holding a_j in the fixed basis),
d_i = Σ_j D_ij a_j, so the directors' matrix is D A. The strains follow from (3), (4) and (29)
with the frame's own curvature κ, a_j' = κ × a_j (components κ_j = κ · a_j):

* v = D A r' (29);
* û = Mm (θ', ψ', φ') + D κ (25): the curvature of the directors relative to the frame plus
  the frame's, in director components (d_i · κ = (D κ)_i);
* ŵ = Mm (θ̇, ψ̇, φ̇) (26), unchanged: the frame does not move;
* the rate of D κ is (D κ) × ŵ (κ is fixed in space, ḋ_i = w × d_i (4)).

With A = I (κ = 0) these are the paper's. The balance laws (6) and everything built on v, û,
ŵ and the directors are unchanged, so the general form (65) keeps Ma = diag(I₃, Mm) (66) and
its singularity, det Mm = cos θ, now at θ = ±π/2 *relative to the frame*: the time loop moves
the frame to the rod's rotation before θ gets there (cosserat_fem/rod/charts.py).
"""

from __future__ import annotations

from dataclasses import dataclass

import ufl


def d_sigma(f) -> ufl.core.expr.Expr:
    """f' = df/dσ, σ = s/ℓ (47): ``f.dx(0)`` on the rod's own mesh (the interval [0, 1],
    geometric dimension 1, the paper's), and on a structure's mesh (straight members embedded
    in 3D, coordinates r0/ℓ, docs/structures.md) the tangential derivative grad f · t with
    t = J[:, 0]/|J[:, 0]|, J the cell's Jacobian (t points from the cell's first vertex to its
    second; the member's rest frame is oriented cell by cell to match, cosserat_fem/rod/
    structure.py). For a 1D mesh the expression is the one the forms always had, so the single
    rod's compiled kernels are unchanged."""
    domain = ufl.domain.extract_unique_domain(f)
    if domain is None or domain.geometric_dimension() == 1:
        return f.dx(0)
    J = ufl.Jacobian(domain)
    t = ufl.as_vector([J[i, 0] for i in range(3)])
    return ufl.dot(ufl.grad(f), t / ufl.sqrt(ufl.dot(t, t)))


@dataclass(frozen=True)
class Chart:
    """A reference frame of the Euler angles (module docstring): ``frame`` A (3×3, row j the
    frame vector a_j in the fixed basis, orthonormal) and ``curvature`` κ̂ = ℓ κ, the frame's
    curvature in its own components (a_j' = κ̂ × a_j with ' = d/dσ)."""

    frame: ufl.core.expr.Expr
    curvature: ufl.core.expr.Expr


def quaternion_frame(Q) -> ufl.core.expr.Expr:
    """A of a quaternion Q = (q0, q1, q2, q3) of any nonzero length: A = R(Q)ᵀ, with R(Q) the
    rotation taking e_j to a_j,

        R = I + 2 (q0 [v]× + [v]×²)/|Q|²,   v = (q1, q2, q3),

    an exact rotation for every Q ≠ 0, so that an interpolated, unnormalised field of
    quaternions gives an orthonormal frame at every point."""
    q0, v = Q[0], ufl.as_vector([Q[1], Q[2], Q[3]])
    hat = ufl.as_matrix([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])
    R = ufl.Identity(3) + 2.0 / ufl.dot(Q, Q) * (q0 * hat + hat * hat)
    return R.T


def quaternion_chart(Q) -> Chart:
    """The :class:`Chart` of a field of quaternions Q(σ) (:func:`quaternion_frame`), with
    κ̂ from the skew matrix A' Aᵀ: a_j' = Σ_l (A' Aᵀ)_jl a_l = κ̂ × a_j, so
    (A' Aᵀ)_jl = (κ̂ × a_j) · a_l = ε_jlm κ̂_m."""
    A = quaternion_frame(Q)
    W = d_sigma(A) * A.T
    return Chart(A, ufl.as_vector([W[1, 2], W[2, 0], W[0, 1]]))


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
    dU = d_sigma(U)
    return split(ufl.as_vector([dU[i] for i in range(12)]))


def translations(p6):
    """(p1, p2, p3) of a 6-vector."""
    return ufl.as_vector([p6[0], p6[1], p6[2]])


def angles(p6):
    """(p4, p5, p6) = (θ, ψ, φ) of a 6-vector."""
    return ufl.as_vector([p6[3], p6[4], p6[5]])


def directors(p, chart: Chart | None = None) -> ufl.core.expr.Expr:
    """The directors' matrix, row i holding d_i in the fixed basis: D of (18), or D A in a
    chart (module docstring)."""
    D = rotation_matrix(p[3], p[4], p[5])
    return D if chart is None else D * chart.frame


def tangent(dp, reference_tangent=None) -> ufl.core.expr.Expr:
    """r' = ∂r/∂s: (p1', p2', 1 + p3') by (14), (27), or t0 + (p1', p2', p3') from a reference
    curve of tangent t0 (forms/reference.py)."""
    if reference_tangent is None:
        return ufl.as_vector([dp[0], dp[1], 1.0 + dp[2]])
    return reference_tangent + ufl.as_vector([dp[0], dp[1], dp[2]])


def stretch_shear_strain(p, dp, chart: Chart | None = None, reference_tangent=None):
    """v_i = d_i · ∂r/∂s, eq. (29), dimensionless, r' of :func:`tangent`; with a reference
    tangent, the components along the rows of D A (forms/reference.py)."""
    return directors(p, chart) * tangent(dp, reference_tangent)


def frame_curvature(p, chart: Chart | None) -> ufl.core.expr.Expr | None:
    """D κ̂: the curvature of a chart's frame in director components (None without one)."""
    return None if chart is None else rotation_matrix(p[3], p[4], p[5]) * chart.curvature


def curvature(p, dp, chart: Chart | None = None) -> ufl.core.expr.Expr:
    """û = ℓ u, components in the director basis, eq. (25): û = Mm (θ', ψ', φ'), plus D κ̂ in
    a chart (module docstring)."""
    u = angular_map(p[3], p[5]) * angles(dp)
    return u if chart is None else u + frame_curvature(p, chart)


def angular_velocity(p, q) -> ufl.core.expr.Expr:
    """ŵ = w/ω0, components in the director basis, eq. (26): ŵ = Mm (θ̇, ψ̇, φ̇)."""
    return angular_map(p[3], p[5]) * angles(q)


def strain_rates(
    p, dp, q, dq, chart: Chart | None = None, reference_tangent=None
) -> tuple[ufl.core.expr.Expr, ufl.core.expr.Expr]:
    """τ-derivatives of the director components of v (29) and û (25), the objective strain
    rates of a Kelvin–Voigt law.

    v_i = d_i · r' with ḋ_i = w × d_i (4) gives v̇ = D (q1', q2', q3') + v × ŵ (the second
    term vanishes for a rigid rotation, where r' turns with the directors); û = Mm (θ', ψ', φ')
    gives û̇ = (dMm/dτ) (θ', ψ', φ') + Mm (θ̇', ψ̇', φ̇'), with q' = dq/dσ, plus (D κ̂) × ŵ in
    a chart (module docstring); with a reference tangent (forms/reference.py), the same rates
    of v along the rows of D A."""
    D = directors(p, chart)
    v = stretch_shear_strain(p, dp, chart, reference_tangent)
    w = angular_velocity(p, q)
    v_dot = D * translations(dq) + ufl.cross(v, w)
    mdot = angular_map_rate(p[3], p[5], q[3], q[5])
    u_dot = mdot * angles(dp) + angular_map(p[3], p[5]) * angles(dq)
    if chart is not None:
        u_dot = u_dot + ufl.cross(frame_curvature(p, chart), w)
    return v_dot, u_dot
