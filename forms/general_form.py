"""The general form (65) of Cao & Tucker (2008) in UFL, with the errata of docs/errata.md.

With p = (x/ℓ, y/ℓ, z/ℓ, θ, ψ, φ) and q = dp/dτ, eq. (65) reads

    ṗ = q,        Ma(p) q̇ + b(p, p')' = g(p, p', q),

on σ ∈ [0, 1], with Ma = diag(I₃, Mm) (66), the flux b (63), the source g (67). A clamped end
is p = q = 0 (55); a free end carries the natural condition a_m b = −g_b (section 5), a_m = +1
at σ = 1 and −1 at σ = 0, with the free-end data (62) corrected as

    g_b = ( (g0/ℓ) f^b ,  (g1/ℓ) l^b_1, (g2/ℓ) l^b_2, (g3/ℓ) l^b_3 ),

where f^b [N] and l^b [N m] are the end force and torque in fixed directions (42) and
l^b_i = d_i · l^b (43). Multiplying by a test function V = (v_p, v_q) and integrating b' by
parts gives the weak form

    F = ∫ (ṗ − q)·v_p dσ + ∫ (Ma q̇ − g)·v_q − b·v_q' dσ − Σ_free ends g_b·v_q = 0.

Each row is a balance law of (6)/(39) divided by its reference (see :mod:`.groups`): rows 1-3
the force balance (49)-(51) by ρ A ω0² ℓ, rows 4-6 the moment balance about d1, d2, d3
(52)-(54) by ρ c11 ω0², ρ c22 ω0², ρ I3 ω0².

The source g (67) is split by origin so that tests can compare term by term:
``inertial`` (the velocity products of (64) and the gyroscopic terms), ``elastic`` (contact
force and torque terms), ``load`` (distributed force and torque).

**A reference configuration** (forms/reference.py: tangent t0, frame D0; a rod curved or
twisted at rest). The unknowns are the displacement (r − r0)/ℓ and the angles of the rotation
R = D A (chart A, forms/kinematics.py) that carries the reference directors, whose matrix is
D0 R. Rows 4-6 are then the moment balance (6) in the components of the rows λ_j of R (a frame
that turns with the rod and does not jump where D0 does), each divided by the rotary inertia
of the rows (Î_j), i.e. the virtual work of (6) with δϑ = Σ_j v_{9+j} λ_j/Î_j: with
ŵ = Mm (θ̇, ψ̇, φ̇) and κ_R the angular velocity and curvature of R in those components, the
contact force and torque N̂, M̂ of the strains D0 (R r' − t0) and D0 κ_R (director
components, dimensionless as in :func:`kelvin_voigt_terms`) and N = D0ᵀ N̂, M = D0ᵀ M̂,

    Ma = diag(I₃, Î⁻¹ I_λ Mm),   I_λ = D0ᵀ diag(Î) D0,
    b = −(Rᵀ N, M_j/Î_j),   g = (0, Î⁻¹ (κ_R × M + v_R × N − I_λ Ṁm q_a − ŵ × I_λ ŵ)) + loads,

with v_R = R r', loads and damping as without a reference with R for the directors. With
t0 = e3, D0 = I this is (65) itself (tests/test_forms.py: the same residual to round-off).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import ufl

from .conventions import END_LOAD_SIGNS
from .groups import Groups
from .kinematics import (
    Chart,
    angles,
    angular_map,
    angular_map_rate,
    angular_velocity,
    curvature,
    directors,
    sigma_derivatives,
    split,
    strain_rates,
    stretch_shear_strain,
    translations,
)
from .reference import Reference, straight


@dataclass(frozen=True)
class EndLoadConvention:
    """How the free-end data g_b is formed (docs/errata.md, errata 2 and 3).

    sign:    ``"balance"`` (default): n(ℓ) = f^b, m(ℓ) = l^b, i.e. a_m b = −g_b as in section 5;
             ``"printed"``: eqs. (41), (44)-(45), (56)-(61), a_m n + f^b = 0, which makes the
             free end move against the applied load.
    scaling: ``"balance"`` (default): g_b = ((g0/ℓ) f^b, (g_i/ℓ) l^b_i), dimensionless;
             ``"printed"``: eq. (62), g_b = g0 (f^b, l^b_i).
    """

    sign: str = "balance"
    scaling: str = "balance"


@dataclass
class DistributedLoads:
    """Force density f [N/m] and torque density l [N m/m] in the fixed basis (36).

    UFL 3-vectors of σ and t, or ``None`` when absent (an absent load adds no term).
    """

    force: ufl.core.expr.Expr | None = None
    torque: ufl.core.expr.Expr | None = None


@dataclass
class EndLoads:
    """End force f^b [N] and torque l^b [N m] in fixed directions (42) on one free end.

    ``ds`` is the boundary measure restricted to that end. With ``interior`` the load acts at
    a node inside the rod (a point load): ``ds`` is then the interior-facet measure dS of that
    node, the term the same as an end's, −g_b · v_q there, with the balance sign (the fields
    are continuous: it is evaluated on one side of the node)."""

    ds: ufl.Measure
    force: ufl.core.expr.Expr | None = None
    torque: ufl.core.expr.Expr | None = None
    interior: bool = False


@dataclass(frozen=True)
class LoadContext:
    """What the form of a load declared with its physics is given (``residual(load, context)``
    of its module in forms/; cosserat_fem/scene/resolved.py FormLoad): the state ``U`` = (p, q) and
    the test function ``V`` (12 components each), the ``groups``, the end-load ``convention``,
    the ``chart`` (None: the fixed basis), the rest configuration ``reference`` (None: the
    straight rod, forms/reference.py), the boundary measure of each end by name ("start",
    "end"), and ``vector``, which makes a load vector of the scene (expressions of t, data)
    a UFL 3-vector times the load factor, or None when it is zero; ``Udot`` the state's
    τ-derivative, ``omega0`` ω0 [rad/s] of τ = ω0 t (47) and ``gravity`` g [m/s²] times the
    load factor (a UFL 3-vector, None without gravity), for loads that carry inertia or
    weight (forms/rigid_body.py)."""

    U: ufl.core.expr.Expr
    V: ufl.core.expr.Expr
    groups: Groups
    convention: EndLoadConvention
    chart: Chart | None
    reference: Reference | None
    ds: dict[str, ufl.Measure]
    vector: Callable[[tuple], ufl.core.expr.Expr | None]
    Udot: ufl.core.expr.Expr | None = None
    omega0: float = 1.0
    gravity: ufl.core.expr.Expr | None = None


@dataclass(frozen=True)
class ViscousDamping:
    """Viscous damping densities in SI units: force f_d = −c_t ṙ [N/m] (``translational`` c_t
    [N s/m²]) and torque l_d = −c_r ω [N m/m] (``rotational`` c_r [N s]), ω = ω0 ŵ the angular
    velocity (26); ``omega0`` [rad/s] converts the rates: ṙ = ℓ ω0 (q1, q2, q3)."""

    translational: float
    rotational: float
    omega0: float


#: The six strain components of a section law, in its order (docs/sections.md §1).
STRAIN_COMPONENTS = 6


def retardation_times(value) -> tuple[float, ...]:
    """The six retardation times μ_1..μ_6 [s] of ``value``: one number τ_d (every component
    alike, μ_i = τ_d) or six, in the section's strain order (shear 1, shear 2, extension,
    bending 1, bending 2, torsion)."""
    if isinstance(value, int | float):
        return (float(value),) * STRAIN_COMPONENTS
    times = tuple(float(x) for x in value)
    if len(times) != STRAIN_COMPONENTS:
        raise ValueError(f"retardation times: one number or {STRAIN_COMPONENTS}, got {value!r}")
    return times


def per_component(times, n, m) -> tuple[ufl.core.expr.Expr, ufl.core.expr.Expr]:
    """diag(μ) (n, m): the contact force and torque of the strain rates (director components)
    with row i times μ_i, the Kelvin–Voigt law of :class:`KelvinVoigtDamping`."""
    return (
        ufl.as_vector([times[i] * n[i] for i in range(3)]),
        ufl.as_vector([times[3 + i] * m[i] for i in range(3)]),
    )


@dataclass(frozen=True)
class KelvinVoigtDamping:
    """Kelvin–Voigt damping of the section: the contact force and torque (9)-(13), or the
    section law (S1) of docs/sections.md, (n, m) = K ε, become

        (n, m) = K ε + diag(μ) K ε̇,    ε = (Γ, κ) = (v − v0, u − u0),

    with the director-component rates ε̇ of :func:`.kinematics.strain_rates` (objective rates)
    and ``retardation_time`` μ [s]: one number τ_d (μ_i = τ_d: a material whose E and G both
    carry (1 + τ_d ∂t)) or six, μ_1..μ_6 in the strain order (shear 1, shear 2, extension,
    bending 1, bending 2, torsion). diag(μ) K, row i of K ε̇ times μ_i, is BeamDyn's
    stiffness-proportional damping f_d = μ C ε̇ (OpenFAST docs/source/user/beamdyn/theory.rst,
    "Damping Forces and Linearization", μ "a user-defined damping-coefficient diagonal
    matrix"; modules/beamdyn/src/BeamDyn.f90, Calc_Stif_betaC: betaC = diag(beta) Stif in
    the section's frame, then ffd = betaC eed); it differs from K diag(μ) only where K
    couples components of unequal μ. For a diagonal K, component i of a mode linearised about
    the straight rod decays at μ_i ω_n²/2 (ζ_n = μ_i ω_n/2: every mode alike for one τ_d).
    ``omega0`` [rad/s] converts the rates."""

    retardation_time: float | tuple[float, ...]
    omega0: float

    @property
    def eta(self) -> tuple[float, ...]:
        """η_i = ω0 μ_i: the six retardation times in units of 1/ω0 (47)."""
        return tuple(self.omega0 * t for t in retardation_times(self.retardation_time))


@dataclass(frozen=True)
class ScaledLaw:
    """A general section law (forms/section.py ``SectionLaw``, docs/sections.md) in the scaling
    of the rows (:func:`kelvin_voigt_terms`; built by forms/resultants.py ``scaled_law``):
    ``stiffness`` K̂ (6×6 rows, numbers or UFL expressions of σ) with (N̂, M̂) = K̂ (Γ, û);
    ``mass`` μ̂(σ) = μ/(ρ A) and ``inertia`` Î_i(σ) = I_ii/(ρ A ℓ²), ρ A the reference's;
    ``apply`` the law (forms/resultants.py ``section_law``). With one, the form is that of a
    reference (module docstring; the straight one if none), with the rows 1-3 of Ma times μ̂
    and I_λ = D0ᵀ diag(Î(σ)) D0, the rows still divided by the constant references."""

    stiffness: list
    mass: object
    inertia: tuple
    apply: Callable


@dataclass
class Source:
    """The source g of (67), split by origin; each part is a UFL 6-vector."""

    inertial: ufl.core.expr.Expr
    elastic: ufl.core.expr.Expr
    load: ufl.core.expr.Expr | None = None


@dataclass
class ResidualTerms:
    """The weak residual F of (65) as named UFL forms (absent terms are ``None``)."""

    kinematic: ufl.Form
    inertia: ufl.Form
    elastic: ufl.Form
    distributed_load: ufl.Form | None = None
    end_load: ufl.Form | None = None
    extra: dict[str, ufl.Form] = field(default_factory=dict)

    def as_dict(self) -> dict[str, ufl.Form]:
        terms = {
            "kinematic": self.kinematic,
            "inertia": self.inertia,
            "elastic": self.elastic,
            "distributed_load": self.distributed_load,
            "end_load": self.end_load,
        }
        terms.update(self.extra)
        return {k: v for k, v in terms.items() if v is not None}

    def total(self) -> ufl.Form:
        forms = list(self.as_dict().values())
        total = forms[0]
        for f in forms[1:]:
            total = total + f
        return total


def mass_matrix(p) -> ufl.core.expr.Expr:
    """Ma of eq. (66): the 6×6 block diagonal diag(I₃, Mm(θ, φ)) acting on q̇."""
    mm = angular_map(p[3], p[5])
    rows = [[1.0 if i == j else 0.0 for j in range(6)] for i in range(3)]
    rows += [[0.0, 0.0, 0.0, mm[i, 0], mm[i, 1], mm[i, 2]] for i in range(3)]
    return ufl.as_matrix(rows)


def flux(p, dp, groups: Groups, chart: Chart | None = None) -> ufl.core.expr.Expr:
    """The flux b of eq. (63).

    Rows 1-3: b = −(g0/ℓ) n, the contact force (32) in the fixed basis, written as in (63):
    b = −ν01 r' + ((ν01 − ν02) v3 + ν02) d3, with r' = (p1', p2', 1 + p3') and v3 of (29).
    Rows 4-6: b = −(ν11 û1, ν21 û2, ν31 û3), the contact torque components m_i = J_ii u_i (13).
    In a ``chart`` the directors and strains are those of forms/kinematics.py's charts.
    """
    D = directors(p, chart)
    v = stretch_shear_strain(p, dp, chart)
    u = curvature(p, dp, chart)
    r_prime = ufl.as_vector([dp[0], dp[1], 1.0 + dp[2]])
    axial = (groups.nu01 - groups.nu02) * v[2] + groups.nu02
    b_force = [-groups.nu01 * r_prime[j] + axial * D[2, j] for j in range(3)]
    b_torque = [-groups.nu11 * u[0], -groups.nu21 * u[1], -groups.nu31 * u[2]]
    return ufl.as_vector(b_force + b_torque)


def source(
    p, dp, q, groups: Groups, loads: DistributedLoads | None = None, chart: Chart | None = None
) -> Source:
    """The source g of eq. (67), split into inertial, elastic and load parts.

    inertial (rows 4-6), from (52)-(54) with (64): g = −(dMm/dτ) q_ang − (ŵ2 ŵ3, −ŵ3 ŵ1, ν33 ŵ1 ŵ2);
      the gyroscopic coefficients of rows 4-5 are (I33 − I22)/I11 = 1 and (I11 − I33)/I22 = −1
      for I33 = ρ (c11 + c22) (46), ``groups.gamma1``, ``gamma2`` for rotary inertias given
      apart from the section.
    elastic: row 4: ν12 û2 û3 − ((ν13 − ν14) v3 + ν14) v2,
             row 5: −ν22 û1 û3 + ((ν23 − ν24) v3 + ν24) v1,
             row 6: ν32 û1 û2    (the v × n terms vanish in row 6 since K11 = K22).
    load:    (g0 f, g1 l1, g2 l2, g3 l3) with l_i = d_i · l (38).
    In a ``chart``, v, û and the directors are those of forms/kinematics.py's charts.
    """
    v = stretch_shear_strain(p, dp, chart)
    u = curvature(p, dp, chart)
    w = angular_velocity(p, q)
    qa = angles(q)
    mdot_q = angular_map_rate(p[3], p[5], q[3], q[5]) * qa
    # Gyroscopic coefficients (I33 − I22)/I11 = 1 and (I11 − I33)/I22 = −1 for (46), or those
    # of rotary inertias given apart from the section (forms/groups.py).
    g1, g2 = groups.gamma1, groups.gamma2
    gyro = ufl.as_vector(
        [
            w[1] * w[2] if g1 == 1.0 else g1 * w[1] * w[2],
            -w[2] * w[0] if g2 == -1.0 else g2 * w[2] * w[0],
            groups.nu33 * w[0] * w[1],
        ]
    )
    inertial = ufl.as_vector([0.0, 0.0, 0.0] + [-mdot_q[i] - gyro[i] for i in range(3)])
    elastic = ufl.as_vector(
        [
            0.0,
            0.0,
            0.0,
            groups.nu12 * u[1] * u[2] - ((groups.nu13 - groups.nu14) * v[2] + groups.nu14) * v[1],
            -groups.nu22 * u[0] * u[2] + ((groups.nu23 - groups.nu24) * v[2] + groups.nu24) * v[0],
            groups.nu32 * u[0] * u[1],
        ]
    )
    load = None
    if loads is not None and (loads.force is not None or loads.torque is not None):
        zero3 = ufl.as_vector([0.0, 0.0, 0.0])
        f = loads.force if loads.force is not None else zero3
        if loads.torque is not None:
            l_d = directors(p, chart) * loads.torque
        else:
            l_d = zero3
        scale = (groups.g1, groups.g2, groups.g3)
        force = [groups.g0 * f[i] for i in range(3)]
        load = ufl.as_vector(force + [scale[i] * l_d[i] for i in range(3)])
    return Source(inertial=inertial, elastic=elastic, load=load)


def damping_source(p, q, groups: Groups, damping: ViscousDamping) -> ufl.core.expr.Expr:
    """The damping densities as rows of g (67), like the loads: (g0 f_d, g_i l_d,i) with
    f_d = −c_t ℓ ω0 (q1, q2, q3) in the fixed basis and l_d,i = −c_r ω0 ŵ_i in the directors
    (a torque density enters row 3 + i through d_i · l, (38)). The power they take,
    −∫ (c_t |ṙ|² + c_r |ω|²) ds ≤ 0, is the energy's loss rate."""
    w = angular_velocity(p, q)
    ct = damping.translational * groups.length * damping.omega0 * groups.g0
    cr = damping.rotational * damping.omega0
    return ufl.as_vector(
        [
            -ct * q[0],
            -ct * q[1],
            -ct * q[2],
            -cr * groups.g1 * w[0],
            -cr * groups.g2 * w[1],
            -cr * groups.g3 * w[2],
        ]
    )


def kelvin_voigt_terms(
    p,
    dp,
    q,
    dq,
    groups: Groups,
    damping: KelvinVoigtDamping,
    chart: Chart | None = None,
    reference: Reference | None = None,
    law: ScaledLaw | None = None,
) -> tuple[ufl.core.expr.Expr, ufl.core.expr.Expr]:
    """The viscous parts (b_v, g_v) of the flux b (63) and the source g (67).

    In the scaling of the rows (:mod:`.groups`), with F* = ρ A ℓ² ω0² = ℓ/g0, the dimensionless
    contact force N̂ = n/F* and torque M̂ = m/(F* ℓ) (director components) and the rotary
    inertias Î_i = I_ii/(ρ A ℓ²) = g0/(ℓ g_i), the elastic flux (63) is b = −(Dᵀ N̂, M̂_i/Î_i)
    and the elastic source of the moment rows (67) is ((û × M̂) + (v × N̂))_i/Î_i, which is the
    moment balance (6) in director components, m' + u × m + v × n. The viscous parts are the
    same expressions of (N̂_v, M̂_v) = diag(η) K̂ (v̇, û̇), η_i = ω0 μ_i
    (:class:`KelvinVoigtDamping`; without a law K̂ (v̇, û̇) = (ν01 v̇1, ν01 v̇2, ν02 v̇3,
    ν11 Î1 û̇1, ν21 Î2 û̇2, ν31 Î3 û̇3)), and enter the free-end condition a_m b = −g_b with
    the elastic flux: n(ℓ) = f^b holds for the whole contact force. With a ``reference`` the
    rates are those of D0 (R r' − t0) and D0 κ_R, the director components, and
    N = D0ᵀ N̂_v, M = D0ᵀ M̂_v as for the elastic part (module docstring)."""
    eta = damping.eta
    if reference is None:
        v_dot, u_dot = strain_rates(p, dp, q, dq, chart)
        n_v, m_v = per_component(eta, *scaled_resultants(v_dot, u_dot, groups, law))
        return contact_terms(p, dp, groups, n_v, m_v, chart)
    v_dot, u_dot = strain_rates(p, dp, q, dq, chart, reference.tangent)
    D0 = reference.frame
    n_v, m_v = per_component(eta, *scaled_resultants(D0 * v_dot, D0 * u_dot, groups, law))
    return contact_terms(p, dp, groups, D0.T * n_v, D0.T * m_v, chart, reference.tangent)


def row_inertias(groups: Groups) -> tuple[float, float, float]:
    """Î_i = g0/(ℓ g_i) = I_ii/(ρ A ℓ²), the dimensionless rotary inertias that divide rows 4-6."""
    g0, ell = groups.g0, groups.length
    return g0 / (ell * groups.g1), g0 / (ell * groups.g2), g0 / (ell * groups.g3)


def scaled_resultants(v_strain, u_strain, groups: Groups, law: ScaledLaw | None = None):
    """(N̂, M̂) of strains (director components) of stretch-shear and curvature, in the scaling of
    :func:`kelvin_voigt_terms`: N̂ = (ν01 e1, ν01 e2, ν02 e3), M̂_i = ν_i1 Î_i k_i; with a
    ``law``, (N̂, M̂) = K̂ (e, k)."""
    if law is not None:
        return law.apply(v_strain, u_strain, law.stiffness)
    inertia = row_inertias(groups)
    axial = (groups.nu01, groups.nu01, groups.nu02)
    stiff = (groups.nu11, groups.nu21, groups.nu31)
    n = ufl.as_vector([axial[i] * v_strain[i] for i in range(3)])
    m = ufl.as_vector([stiff[i] * inertia[i] * u_strain[i] for i in range(3)])
    return n, m


def contact_terms(p, dp, groups: Groups, n, m, chart: Chart | None = None, reference_tangent=None):
    """The flux and source of a contact force N̂ = ``n`` and torque M̂ = ``m`` (components along
    the rows of D A; scaling of :func:`kelvin_voigt_terms`): b = −(Dᵀ N̂, M̂_i/Î_i) and
    g = (0, ((û × M̂) + (v × N̂))_i/Î_i), the moment balance (6) m' + u × m + v × n."""
    inertia = row_inertias(groups)
    D = directors(p, chart)
    v = stretch_shear_strain(p, dp, chart, reference_tangent)
    u = curvature(p, dp, chart)
    force = D.T * n
    moment = ufl.cross(u, m) + ufl.cross(v, n)
    flux_c = ufl.as_vector([-force[i] for i in range(3)] + [-m[i] / inertia[i] for i in range(3)])
    source_c = ufl.as_vector([0.0, 0.0, 0.0] + [moment[i] / inertia[i] for i in range(3)])
    return flux_c, source_c


def reference_strains(
    p, dp, reference: Reference, chart: Chart | None = None
) -> tuple[ufl.core.expr.Expr, ufl.core.expr.Expr]:
    """(v − v0, û − û0) = (D0 (R r' − t0), D0 κ_R), director components (module docstring)."""
    v_rel = stretch_shear_strain(p, dp, chart, reference.tangent) - reference.tangent
    return reference.frame * v_rel, reference.frame * curvature(p, dp, chart)


def reference_inertia(
    groups: Groups, reference: Reference, law: ScaledLaw | None = None
) -> ufl.core.expr.Expr:
    """I_λ = D0ᵀ diag(Î) D0: the rotary inertia in the components of the rows of R (Î those
    of a ``law`` if given)."""
    inertias = row_inertias(groups) if law is None else law.inertia
    return reference.frame.T * ufl.diag(ufl.as_vector(inertias)) * reference.frame


def reference_inertial_terms(
    p, q, groups: Groups, reference: Reference, law: ScaledLaw | None = None
):
    """(Ma, g_inertial) of the module docstring: Ma = diag(I₃, Î⁻¹ I_λ Mm) and
    g = (0, −Î⁻¹ (I_λ Ṁm q_a + ŵ × I_λ ŵ)); with a ``law`` diag(μ̂ I₃, ...) and its Î(σ)
    in I_λ (:class:`ScaledLaw`)."""
    inertia = row_inertias(groups)
    I_l = reference_inertia(groups, reference, law)
    mm = I_l * angular_map(p[3], p[5])
    mass = 1.0 if law is None else law.mass
    rows = [[mass if i == j else 0.0 for j in range(6)] for i in range(3)]
    rows += [[0.0, 0.0, 0.0, *(mm[i, j] / inertia[i] for j in range(3))] for i in range(3)]
    w = angular_velocity(p, q)
    rate = I_l * (angular_map_rate(p[3], p[5], q[3], q[5]) * angles(q)) + ufl.cross(w, I_l * w)
    source_i = ufl.as_vector([0.0, 0.0, 0.0] + [-rate[i] / inertia[i] for i in range(3)])
    return ufl.as_matrix(rows), source_i


def reference_contact_terms(
    p,
    dp,
    groups: Groups,
    reference: Reference,
    v_strain,
    u_strain,
    chart: Chart | None = None,
    law: ScaledLaw | None = None,
):
    """Flux and source of the contact force and torque of director-component strains with a
    reference: N = D0ᵀ N̂, M = D0ᵀ M̂ in the rows of R (module docstring)."""
    n, m = scaled_resultants(v_strain, u_strain, groups, law)
    D0 = reference.frame
    return contact_terms(p, dp, groups, D0.T * n, D0.T * m, chart, reference.tangent)


def end_data(
    p, groups: Groups, end: EndLoads, convention: EndLoadConvention, chart: Chart | None = None
) -> ufl.core.expr.Expr:
    """Free-end data g_b of (62), corrected (module docstring); l^b_i = d_i · l^b by (43)."""
    sign = END_LOAD_SIGNS[convention.sign]
    if convention.scaling == "balance":
        ell = groups.length
        scales = [groups.g0 / ell] * 3 + [g / ell for g in (groups.g1, groups.g2, groups.g3)]
    elif convention.scaling == "printed":
        scales = [groups.g0] * 6
    else:
        raise ValueError(f"unknown end-load scaling {convention.scaling!r}")
    zero3 = ufl.as_vector([0.0, 0.0, 0.0])
    fb = end.force if end.force is not None else zero3
    lb = directors(p, chart) * end.torque if end.torque is not None else zero3
    comps = [fb[0], fb[1], fb[2], lb[0], lb[1], lb[2]]
    return ufl.as_vector([sign * scales[i] * comps[i] for i in range(6)])


def residual_terms(
    U,
    Udot,
    V,
    groups: Groups,
    dx: ufl.Measure,
    loads: DistributedLoads | None = None,
    end_loads: tuple[EndLoads, ...] = (),
    convention: EndLoadConvention = EndLoadConvention(),
    damping: ViscousDamping | None = None,
    kelvin_voigt: KelvinVoigtDamping | None = None,
    chart: Chart | None = None,
    reference: Reference | None = None,
    law: ScaledLaw | None = None,
) -> ResidualTerms:
    """The weak residual of (65) (module docstring), term by term.

    U, Udot: the 12-component state (p, q) and its τ-derivative, as UFL expressions (the
    time integrator decides what they are); V: the test function; ``chart``: the frame the
    angles are measured from (forms/kinematics.py; None: the fixed basis, as in the paper);
    ``reference``: the rest configuration (module docstring; None: the straight rod of (65));
    ``law``: a general section law (:class:`ScaledLaw`; None: the paper's (13) of ``groups``).
    """
    if law is not None and reference is None:
        reference = straight()
    p, q = split(U)
    pdot, qdot = split(Udot)
    vp, vq = split(V)
    dp, dq = sigma_derivatives(U)
    dvq = sigma_derivatives(V)[1]

    g = source(p, dp, q, groups, loads, chart)
    kinematic = ufl.inner(pdot - q, vp) * dx
    if reference is None:
        inertia = ufl.inner(mass_matrix(p) * qdot - g.inertial, vq) * dx
        elastic = (-ufl.inner(flux(p, dp, groups, chart), dvq) - ufl.inner(g.elastic, vq)) * dx
    else:
        Ma, g_inertial = reference_inertial_terms(p, q, groups, reference, law)
        inertia = ufl.inner(Ma * qdot - g_inertial, vq) * dx
        strains = reference_strains(p, dp, reference, chart)
        b_e, g_e = reference_contact_terms(p, dp, groups, reference, *strains, chart, law)
        elastic = (-ufl.inner(b_e, dvq) - ufl.inner(g_e, vq)) * dx
    distributed = -ufl.inner(g.load, vq) * dx if g.load is not None else None
    end_form = None
    for end in end_loads:
        if end.force is None and end.torque is None:
            continue
        if end.interior:
            data = end_data(p, groups, end, EndLoadConvention(scaling=convention.scaling), chart)
            term = (-ufl.inner(data, vq))("+") * end.ds
        else:
            term = -ufl.inner(end_data(p, groups, end, convention, chart), vq) * end.ds
        end_form = term if end_form is None else end_form + term
    extra = {}
    if damping is not None:
        extra["damping"] = -ufl.inner(damping_source(p, q, groups, damping), vq) * dx
    if kelvin_voigt is not None:
        b_v, g_v = kelvin_voigt_terms(p, dp, q, dq, groups, kelvin_voigt, chart, reference, law)
        extra["kelvin_voigt"] = (-ufl.inner(b_v, dvq) - ufl.inner(g_v, vq)) * dx
    return ResidualTerms(
        kinematic=kinematic,
        inertia=inertia,
        elastic=elastic,
        distributed_load=distributed,
        end_load=end_form,
        extra=extra,
    )


__all__ = [
    "DistributedLoads",
    "EndLoadConvention",
    "EndLoads",
    "KelvinVoigtDamping",
    "LoadContext",
    "Reference",
    "ResidualTerms",
    "ScaledLaw",
    "Source",
    "ViscousDamping",
    "damping_source",
    "end_data",
    "flux",
    "kelvin_voigt_terms",
    "mass_matrix",
    "per_component",
    "residual_terms",
    "retardation_times",
    "source",
    "translations",
]
