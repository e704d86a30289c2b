"""Energy of the rod and power of its loads, in SI units, as UFL integrands per unit σ.

With (9)-(13), (25), (26), (29), (46) and the scalings (47) (x = ℓ p1, t = τ/ω0, so
∂t r = ℓ ω0 q_trans, w = ω0 ŵ, u = û/ℓ):

    kinetic  T = ½ ∫₀^ℓ [ρA |∂t r|² + ρ (c11 w1² + c22 w2² + I3 w3²)] ds,
    strain   V = ½ ∫₀^ℓ [κGA (v1² + v2²) + EA (v3 − 1)² + E c11 u1² + E c22 u2² + G c33 u3²] ds,

and the power of the loads (36), (42) in fixed directions is

    P = ∫₀^ℓ (f · ∂t r + l · w) ds + Σ_free ends (f^b · ∂t r + l^b · w),

with l · w = Σ_i l_i w_i, l_i = d_i · l (38). For the rod of (6) with the consistent rotary
inertia (docs/errata.md, erratum 1), dE/dt = P with E = T + V. Damping adds its power

    P_d = −∫₀^ℓ [c_t |∂t r|² + c_r |w|² + ε̇ · diag(μ) K ε̇] ds,   ε̇ = (v̇, u̇),

(viscous densities −c_t ∂t r, −c_r w; Kelvin–Voigt parts (n_v, m_v) = diag(μ) K ε̇ of n and m,
forms/general_form.py KelvinVoigtDamping, whose power against the strain rates is what the
elastic parts' is against V). P_d ≤ 0 when diag(μ) K + K diag(μ) is positive semi-definite:
always for one τ_d (μ_i = τ_d, K positive definite) and for a diagonal K; BeamDyn's law with
unequal μ_i and a K that couples their components may, for some rates, not dissipate.
Integrands are per unit σ (ds = ℓ dσ): integrate them with ``* dx`` over the interval mesh
σ ∈ [0, 1].
"""

from __future__ import annotations

import ufl

from .general_form import retardation_times
from .groups import RodConstants
from .kinematics import (
    Chart,
    angular_velocity,
    curvature,
    directors,
    sigma_derivatives,
    split,
    stretch_shear_strain,
)
from .reference import Reference
from .resultants import kelvin_voigt_parts, relative_strains, section_law, stiffness_matrix


def _rates(U, rod: RodConstants, reference: Reference | None = None):
    p, q = split(U)
    ell, w0 = rod.length, rod.omega0
    r_dot = ell * w0 * ufl.as_vector([q[0], q[1], q[2]])
    w = w0 * angular_velocity(p, q)  # director components (of R's rows with a reference)
    if reference is not None:
        w = reference.frame * w
    return p, r_dot, w


def kinetic_energy_density(U, rod: RodConstants, reference: Reference | None = None):
    """ℓ × the kinetic energy per unit length [J per unit σ]; the rotary inertias along the
    directors, D0 R with a ``reference`` (forms/reference.py)."""
    _, r_dot, w = _rates(U, rod, reference)
    s = rod.section
    law = rod.law
    if law is not None:  # a general section law's μ(σ) and I(σ) (forms/section.py)
        mu = law.mass_per_length if law.mass_per_length is not None else rod.density * s.area
        inertia = law.inertia if law.inertia is not None else rod.mass_inertias
        rot = sum(inertia[i] * w[i] ** 2 for i in range(3))
        return 0.5 * rod.length * (mu * ufl.dot(r_dot, r_dot) + rot)
    inertia = rod.rotary_inertias
    rot = sum(inertia[i] * w[i] ** 2 for i in range(3))
    return 0.5 * rod.length * rod.density * (s.area * ufl.dot(r_dot, r_dot) + rot)


def strain_energy_density(
    U, rod: RodConstants, chart: Chart | None = None, reference: Reference | None = None
):
    """ℓ × the strain energy per unit length [J per unit σ] (angles measured in ``chart``;
    strains measured from a ``reference``, forms/resultants.py :func:`relative_strains`)."""
    p, _ = split(U)
    dp, _ = sigma_derivatives(U)
    if rod.law is not None:  # ½ (Γ·n + κ·m) of a general section law, K = Kᵀ
        gamma, kappa = relative_strains(p, dp, rod.length, chart, reference)
        n, m = section_law(gamma, kappa, stiffness_matrix(rod))
        return 0.5 * rod.length * (ufl.dot(gamma, n) + ufl.dot(kappa, m))
    s, E, G = rod.section, rod.young_modulus, rod.shear_modulus
    kGA = s.shear_coefficient * G * s.area
    if reference is None:
        v = stretch_shear_strain(p, dp, chart)
        u = curvature(p, dp, chart) / rod.length
        stretch = kGA * (v[0] ** 2 + v[1] ** 2) + E * s.area * (v[2] - 1.0) ** 2
    else:
        v, u = relative_strains(p, dp, rod.length, chart, reference)
        stretch = kGA * (v[0] ** 2 + v[1] ** 2) + E * s.area * v[2] ** 2
    bend = E * s.c11 * u[0] ** 2 + E * s.c22 * u[1] ** 2 + G * s.c33 * u[2] ** 2
    return 0.5 * rod.length * (stretch + bend)


def load_power(U, rod: RodConstants, force=None, torque=None, chart: Chart | None = None):
    """f · ∂t r + l · w for loads in fixed directions, force and torque UFL 3-vectors or None.

    For densities (f [N/m], l [N m/m]) this is the power per unit length, to be multiplied by
    ℓ and integrated with ``dx``; for end loads (f^b [N], l^b [N m]) the power at that end,
    to be integrated with the end's ``ds``.
    """
    # With a reference, ŵ and R l are both along the rows of R: l · w is the same.
    p, r_dot, w = _rates(U, rod)
    power = 0
    if force is not None:
        power = power + ufl.dot(force, r_dot)
    if torque is not None:
        power = power + ufl.dot(directors(p, chart) * torque, w)
    return power


def damping_power(
    U,
    rod: RodConstants,
    translational=0.0,
    rotational=0.0,
    retardation_time: float | tuple[float, ...] = 0.0,
    chart: Chart | None = None,
    reference: Reference | None = None,
) -> ufl.core.expr.Expr:
    """P_d per unit length [W/m] (module docstring), to be multiplied by ℓ and integrated with
    ``dx``: c_t [N s/m²], c_r [N s], τ_d [s] or six μ_i [s]."""
    _, r_dot, w = _rates(U, rod)
    power = -translational * ufl.dot(r_dot, r_dot) - rotational * ufl.dot(w, w)
    if any(retardation_times(retardation_time)):  # −(n_v · ∂t v + m_v · ∂t u)
        kv = kelvin_voigt_parts(U, rod, retardation_time, chart, reference)
        power = power - ufl.dot(kv.n, kv.v_rate) - ufl.dot(kv.m, kv.u_rate)
    return power
