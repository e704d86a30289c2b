"""Strains and contact force and torque of the rod in SI units, as UFL expressions.

For the output (cosserat_fem/output/fields.py): the quantities that the general form (65) carries,
unscaled. With p = (x/ℓ, y/ℓ, z/ℓ, θ, ψ, φ) and a prime d/dσ (σ = s/ℓ), all components in the
director basis (d1, d2, d3) of (18) (``X_i = d_i · X``):

* v_i = d_i · ∂r/∂s, eq. (29), dimensionless (:func:`.kinematics.stretch_shear_strain`);
* u_i, the curvature (3) in the director basis, eq. (25), [1/m]: u = û/ℓ
  (:func:`.kinematics.curvature`);
* n = Σ K_ii (v_i − δ_i3) d_i, the contact force (9)-(10) [N], K = diag(κGA, κGA, EA);
* m = Σ J_ii u_i d_i, the contact torque (13) [N m], J = diag(E c11, E c22, G c33);
* or, with a general section law (forms/section.py ``SectionLaw``, docs/sections.md), the
  6×6 K of :func:`stiffness_matrix`: n = K₁ Γ + K₁₂ κ, m = K₂₁ Γ + K₂ κ (:func:`section_law`,
  the one place the law is written; the general and director forms use it too);
* with Kelvin–Voigt damping (retardation times μ_1..μ_6 [s], one τ_d or six,
  :class:`.general_form.KelvinVoigtDamping`) n and m include their viscous parts
  diag(μ) K (v̇, u̇) (rates of :func:`.kinematics.strain_rates`; τ_d K v̇ and τ_d J u̇ for one
  τ_d), the whole contact force and torque.

The reference configuration is the straight rod along e3 (r' = (p1', p2', 1 + p3'), (14),
(27)): there v = (0, 0, 1), u = n = m = 0. n(s) and m(s) are the force and torque that the
part (s, ℓ] exerts on [0, s] (docs/errata.md, erratum 2), so at a free end s = ℓ they equal the
applied end force and torque, n(ℓ) = f^b, m(ℓ) = l^b. The flux (63) of the general form is
these resultants scaled by the references of its rows (see :mod:`.groups`),

    b = −( (g0/ℓ) Dᵀ n,  (g1/ℓ) m1, (g2/ℓ) m2, (g3/ℓ) m3 ),

with Dᵀ n the contact force in the fixed basis (tests/test_visualisation.py checks this
identity against :func:`.general_form.flux`).
"""

from __future__ import annotations

from dataclasses import dataclass

import ufl

from .general_form import ScaledLaw, per_component, reference_strains, retardation_times
from .groups import RodConstants
from .kinematics import (
    Chart,
    curvature,
    d_sigma,
    sigma_derivatives,
    split,
    strain_rates,
    stretch_shear_strain,
)
from .reference import Reference


def section_stiffnesses(rod: RodConstants) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """(K11, K22, K33) = (κGA, κGA, EA) [N] and (J11, J22, J33) = (E c11, E c22, G c33)
    [N m²], the constitutive tensors K = Σ K_ii d_i ⊗ d_i, J = Σ J_ii d_i ⊗ d_i of (10)-(13)."""
    s, E, G = rod.section, rod.young_modulus, rod.shear_modulus
    kga = s.shear_coefficient * G * s.area
    return (kga, kga, E * s.area), (E * s.c11, E * s.c22, G * s.c33)


def strains(
    p, dp, length: float, chart: Chart | None = None, reference: Reference | None = None
) -> tuple[ufl.core.expr.Expr, ufl.core.expr.Expr]:
    """(v, u): the stretch-shear strain (29) [-] and the curvature (25) [1/m], director basis
    (angles measured in ``chart``, forms/kinematics.py); with a ``reference`` (forms/reference.py)
    v = D0 R r' and u = u0 + D0 κ_R/ℓ (its closed-form curvature u0 needed)."""
    if reference is None:
        return stretch_shear_strain(p, dp, chart), curvature(p, dp, chart) / length
    D0 = reference.frame
    v = D0 * stretch_shear_strain(p, dp, chart, reference.tangent)
    return v, reference.curvature + D0 * curvature(p, dp, chart) / length


def relative_strains(
    p, dp, length: float, chart: Chart | None = None, reference: Reference | None = None
) -> tuple[ufl.core.expr.Expr, ufl.core.expr.Expr]:
    """(v − v0 [-], u − u0 [1/m]), director basis: the strains the laws (10)-(13) act on,
    v0 = (0, 0, 1) and u0 = 0 for the straight rod, D0 t0 and the reference's for a
    ``reference`` (forms/general_form.py :func:`reference_strains`)."""
    if reference is None:
        v, u = strains(p, dp, length, chart)
        return v - ufl.as_vector([0.0, 0.0, 1.0]), u
    v_rel, u_rel = reference_strains(p, dp, reference, chart)
    return v_rel, u_rel / length


def stiffness_matrix(rod: RodConstants) -> list[list]:
    """The 6×6 section stiffness K of :class:`.section.SectionLaw` (order
    :data:`.section.LAW_ORDER`; entries numbers or UFL expressions of σ): the rod's law, or
    the paper's diagonal (13) diag(κGA, κGA, EA, E c11, E c22, G c33)."""
    if rod.law is not None:
        return [list(row) for row in rod.law.stiffness]
    K, J = section_stiffnesses(rod)
    diagonal = (*K, *J)
    return [[diagonal[i] if i == j else 0.0 for j in range(6)] for i in range(6)]


def section_law(gamma, kappa, K) -> tuple[ufl.core.expr.Expr, ufl.core.expr.Expr]:
    """The section law, written once: n = K₁ Γ + K₁₂ κ, m = K₂₁ Γ + K₂ κ (director
    components) of the 6×6 ``K`` (list of rows) and the strains Γ = v − v0, κ = u − u0; zero
    entries add no term. Units are K's: [N], [N m] for :func:`stiffness_matrix` and SI
    strains; the general form passes its scaled K̂ (:func:`scaled_law`)."""
    strain = [gamma[i] for i in range(3)] + [kappa[i] for i in range(3)]

    def row(i):
        terms = [K[i][j] * strain[j] for j in range(6) if not _is_zero(K[i][j])]
        return sum(terms[1:], terms[0]) if terms else 0.0

    return ufl.as_vector([row(i) for i in range(3)]), ufl.as_vector([row(i) for i in range(3, 6)])


def _is_zero(entry) -> bool:
    return isinstance(entry, int | float) and entry == 0.0


def scaled_law(rod: RodConstants) -> ScaledLaw:
    """The rod's section law in the scaling of the general form (:func:`.general_form.
    kelvin_voigt_terms`): with F* = ρ A ℓ² ω0² (the reference section's ρ A) and û = ℓ u,
    N̂ = n/F*, M̂ = m/(F* ℓ) are K̂ (Γ, û) with K̂_ij = K_ij / (F* ℓ^(a_i + a_j)), a = 0 for
    the force rows and 1 for the torque rows; μ̂ = μ/(ρ A) and Î_i = I_ii/(ρ A ℓ²)."""
    ell, w0 = rod.length, rod.omega0
    mu0 = rod.density * rod.section.area
    fstar = mu0 * ell**2 * w0**2
    K = stiffness_matrix(rod)
    hat = [[K[i][j] / (fstar * ell ** ((i >= 3) + (j >= 3))) for j in range(6)] for i in range(6)]
    law = rod.law
    mu = law.mass_per_length if law is not None and law.mass_per_length is not None else mu0
    given = law.inertia if law is not None and law.inertia is not None else rod.mass_inertias
    return ScaledLaw(
        stiffness=hat,
        mass=mu / mu0,
        inertia=tuple(i / (mu0 * ell**2) for i in given),
        apply=section_law,
    )


def contact_force(v, rod: RodConstants, relative: bool = False) -> ufl.core.expr.Expr:
    """n_i = K_ii (v_i − δ_i3) [N], director components, from the strain v of (29); or
    K_ii v_i from ``relative`` strains v − v0 (the paper's diagonal law; a general law:
    :func:`section_law`)."""
    K, _ = section_stiffnesses(rod)
    if relative:
        return ufl.as_vector([K[i] * v[i] for i in range(3)])
    return ufl.as_vector([K[0] * v[0], K[1] * v[1], K[2] * (v[2] - 1.0)])


def contact_torque(u, rod: RodConstants) -> ufl.core.expr.Expr:
    """m_i = J_ii u_i [N m], director components, from the curvature u [1/m] (or u − u0)."""
    _, J = section_stiffnesses(rod)
    return ufl.as_vector([J[i] * u[i] for i in range(3)])


@dataclass
class Resultants:
    """v [-], u [1/m], n [N], m [N m]: UFL 3-vectors, director components."""

    v: ufl.core.expr.Expr
    u: ufl.core.expr.Expr
    n: ufl.core.expr.Expr
    m: ufl.core.expr.Expr


@dataclass
class KelvinVoigtParts:
    """The strain rates ∂t v [1/s], ∂t u [1/(m s)] and the viscous contact force n_v [N] and
    torque m_v [N m], (n_v, m_v) = diag(μ) K (∂t v, ∂t u): UFL 3-vectors, director components
    (:class:`.general_form.KelvinVoigtDamping`)."""

    v_rate: ufl.core.expr.Expr
    u_rate: ufl.core.expr.Expr
    n: ufl.core.expr.Expr
    m: ufl.core.expr.Expr


def kelvin_voigt_parts(
    U,
    rod: RodConstants,
    retardation_time,
    chart: Chart | None = None,
    reference: Reference | None = None,
) -> KelvinVoigtParts:
    """The Kelvin–Voigt parts of the 12-component state U = (p, q), retardation time τ_d [s]
    or six μ_1..μ_6 [s] (:func:`.general_form.retardation_times`); the rates of
    :func:`.kinematics.strain_rates` are per unit τ = ω0 t, hence the ω0 (with a
    ``reference``, turned into the directors' components by D0)."""
    p, q = split(U)
    dp, dq = sigma_derivatives(U)
    if reference is None:
        v_dot, u_dot = strain_rates(p, dp, q, dq, chart)
    else:
        v_dot, u_dot = strain_rates(p, dp, q, dq, chart, reference.tangent)
        v_dot, u_dot = reference.frame * v_dot, reference.frame * u_dot
    v_rate = rod.omega0 * v_dot
    u_rate = rod.omega0 / rod.length * u_dot
    times = retardation_times(retardation_time)
    n, m = per_component(times, *section_law(v_rate, u_rate, stiffness_matrix(rod)))
    return KelvinVoigtParts(v_rate=v_rate, u_rate=u_rate, n=n, m=m)


def resultants(
    U,
    rod: RodConstants,
    retardation_time: float | tuple[float, ...] = 0.0,
    chart: Chart | None = None,
    reference: Reference | None = None,
) -> Resultants:
    """v, u, n, m of the state U = (p, q) (12 components, or p alone with 6) on σ ∈ [0, 1];
    a ``retardation_time`` τ_d > 0 (or six μ_i, one > 0) adds the Kelvin–Voigt parts to n and
    m (needs q); angles measured in ``chart`` (forms/kinematics.py), the rod at rest a
    ``reference``'s (forms/reference.py; v and u total, n and m from the strains relative to
    it)."""
    p = split(U)[0] if U.ufl_shape == (12,) else U
    dU = d_sigma(U)
    dp = ufl.as_vector([dU[i] for i in range(6)])
    v, u = strains(p, dp, rod.length, chart, reference)
    if reference is None and rod.law is None:
        n, m = contact_force(v, rod), contact_torque(u, rod)
    else:
        v_rel, u_rel = relative_strains(p, dp, rod.length, chart, reference)
        n, m = section_law(v_rel, u_rel, stiffness_matrix(rod))
    if any(retardation_times(retardation_time)):
        viscous = kelvin_voigt_parts(U, rod, retardation_time, chart, reference)
        n, m = n + viscous.n, m + viscous.m
    return Resultants(v=v, u=u, n=n, m=m)
