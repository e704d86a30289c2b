"""The general form (65) against the balance laws (6) written independently in director form.

Both residuals are assembled at random states (angles of order 0.5 rad, arbitrary strains,
velocities and accelerations) with every load present: distributed force and torque, and end
force and torque at both ends. They are algebraically identical, so the assembled vectors must
agree to round-off, term by term: the tolerance 1e-12 relative to the largest entry allows for
summation-order differences of a few hundred terms at machine precision (observed: < 1e-15).
"""

from __future__ import annotations

import numpy as np
import pytest
import ufl
from cosserat_fem.forms.director_form import director_residual_terms
from cosserat_fem.forms.general_form import (
    DistributedLoads,
    EndLoadConvention,
    EndLoads,
    KelvinVoigtDamping,
    ViscousDamping,
    residual_terms,
)
from cosserat_fem.forms.groups import RodConstants, dimensionless_groups
from cosserat_fem.forms.kinematics import quaternion_chart
from cosserat_fem.forms.section import rectangle, rectangle_torsion_constant
from dolfinx import fem, mesh
from dolfinx.fem.petsc import assemble_vector
from mpi4py import MPI

TERMS = ("kinematic", "inertia", "elastic", "distributed_load", "end_load")
#: Six unequal retardation times μ_1..μ_6 [s] (strain order: shear 1, shear 2, extension,
#: bending 1, bending 2, torsion), spread by a factor 12 so that a component given another's μ
#: changes the viscous term by O(1).
TIMES = (2.5e-4, 1.0e-4, 4.0e-4, 3.0e-4, 0.5e-4, 6.0e-4)


def _assemble(form) -> np.ndarray:
    vec = assemble_vector(fem.form(form))
    vec.ghostUpdate()
    return vec.array.copy()


@pytest.fixture(scope="module")
def rod() -> RodConstants:
    # Not the paper's numbers on purpose: l != 1 and unequal sides exercise every scaling.
    sec = rectangle(0.03, 0.07, 0.85)
    return RodConstants(1.7, sec, 7800.0, 2.1e11, 8.1e10, 150.0)


def _setup(degree: int, seed: int):
    msh = mesh.create_unit_interval(MPI.COMM_WORLD, 5)
    V = fem.VectorFunctionSpace(msh, ("Lagrange", degree), dim=12)
    U, Udot = fem.Function(V), fem.Function(V)
    rng = np.random.default_rng(seed)
    U.x.array[:] = 0.5 * rng.standard_normal(U.x.array.size)
    Udot.x.array[:] = 0.5 * rng.standard_normal(U.x.array.size)
    x = ufl.SpatialCoordinate(msh)[0]
    ends = [
        mesh.locate_entities_boundary(msh, 0, lambda X, c=c: np.isclose(X[0], c))
        for c in (0.0, 1.0)
    ]
    facets = np.concatenate(ends).astype(np.int32)
    values = np.array([1] * len(ends[0]) + [2] * len(ends[1]), dtype=np.int32)
    order = np.argsort(facets)
    tags = mesh.meshtags(msh, 0, facets[order], values[order])
    ds = ufl.Measure("ds", domain=msh, subdomain_data=tags)
    # FFCx 0.5 takes the quadrature degree from the measure's metadata only (a
    # form_compiler_params entry is ignored), so both forms must get it here.
    dx = ufl.Measure("dx", domain=msh, metadata={"quadrature_degree": 8})
    loads = {
        "f": ufl.as_vector([2e3 * ufl.sin(3 * x), -1e3 * x, 500.0]),
        "l": ufl.as_vector([30 * x, 20.0, -15 * ufl.cos(x)]),
        "ends": [
            (ds(1), ufl.as_vector([-40.0, 70.0, 10.0]), ufl.as_vector([3.0, -2.0, 5.0])),
            (ds(2), ufl.as_vector([100.0, -200.0, 300.0]), ufl.as_vector([10.0, 20.0, -30.0])),
        ],
    }
    return msh, V, U, Udot, dx, loads


def _general(rod, U, Udot, V, dx, loads, convention=EndLoadConvention(), **terms):
    """The general form's terms with every load of ``loads``; ``terms``: more keyword
    arguments of residual_terms (damping, chart)."""
    ends = tuple(EndLoads(ds, f, t) for ds, f, t in loads["ends"])
    v = ufl.TestFunction(V)
    return residual_terms(
        U,
        Udot,
        v,
        dimensionless_groups(rod),
        dx,
        DistributedLoads(loads["f"], loads["l"]),
        ends,
        convention,
        **terms,
    ).as_dict()


@pytest.mark.parametrize("degree", [1, 2, 3])
def test_general_form_equals_director_form_term_by_term(rod, degree):
    msh, V, U, Udot, dx, loads = _setup(degree, seed=degree)
    general = _general(rod, U, Udot, V, dx, loads)
    director = director_residual_terms(
        U, Udot, ufl.TestFunction(V), rod, dx, loads["f"], loads["l"], tuple(loads["ends"])
    )
    assert set(general) == set(director) == set(TERMS)
    for name in TERMS:
        a, b = _assemble(general[name]), _assemble(director[name])
        scale = np.abs(a).max()
        assert scale > 0, name
        assert np.abs(a - b).max() <= 1e-12 * scale, name


@pytest.mark.parametrize("tau", [2.5e-4, TIMES], ids=["one", "six"])
@pytest.mark.parametrize("torsion_inertia", ["polar", "printed"])
@pytest.mark.parametrize("degree", [1, 3])
def test_damping_terms_equal_the_director_form(rod, degree, torsion_inertia, tau):
    """Viscous damping and Kelvin–Voigt damping at random states: the general form's rows
    (``damping_source``; ``kelvin_voigt_terms`` with the strain rates of
    ``kinematics.strain_rates``) against the director form's (∂t d_i by UFL's chain rule,
    ∂t u from (3), n_v and m_v in the fixed basis), with one retardation time and with six
    unequal ones per strain component. Same round-off bound as above. With the
    printed torsion inertia the torsion row (12) is the director form's times
    (c11 + c22)/c33, like every other term of that row (erratum 1): the viscous torsion row
    is scaled by the row's own reference."""
    from dataclasses import replace

    rod = replace(rod, torsion_inertia=torsion_inertia)
    msh, V, U, Udot, dx, loads = _setup(degree, seed=10 + degree)
    viscous = (3.0e2, 0.7)
    general = residual_terms(
        U,
        Udot,
        ufl.TestFunction(V),
        dimensionless_groups(rod),
        dx,
        damping=ViscousDamping(*viscous, rod.omega0),
        kelvin_voigt=KelvinVoigtDamping(tau, rod.omega0),
    ).as_dict()
    director = director_residual_terms(
        U, Udot, ufl.TestFunction(V), rod, dx, viscous_damping=viscous, retardation_time=tau
    )
    factor = 1.0
    if torsion_inertia == "printed":
        factor = (rod.section.c11 + rod.section.c22) / rod.section.c33
    for name in ("damping", "kelvin_voigt"):
        a, b = _assemble(general[name]), _assemble(director[name])
        b.reshape(-1, 12)[:, 11] *= factor
        scale = np.abs(a).max()
        assert scale > 0, name
        assert np.abs(a - b).max() <= 1e-12 * scale, name
    # The viscous flux is of the elastic's size times η = ω0 τ_d ~ 0.04 at these rates: it is
    # not a negligible addition that would pass any comparison.
    ratio = np.abs(_assemble(general["kelvin_voigt"])).max()
    assert ratio > 1e-3 * np.abs(_assemble(general["elastic"])).max()


def test_six_equal_retardation_times_are_the_one_time(rod):
    """μ_1 = ... = μ_6 = τ_d is the scalar law exactly: the general form's Kelvin–Voigt term,
    straight and with a reference (arc) and a chart, the output's viscous resultants and the
    dissipated power, assembled at random states, equal the scalar's to round-off (the same
    products in another order: 1e-13 of the largest entry, observed ~1e-16); the six unequal
    TIMES give another term (by O(1): > 0.1 of the largest entry), so the check can fail."""
    from cosserat_fem.forms.energy import damping_power
    from cosserat_fem.forms.resultants import kelvin_voigt_parts

    msh, V, U, Udot, dx, loads = _setup(1, seed=17)
    Q = _chart_quaternion(msh, 1, seed=18)
    arc = _references(msh, rod.length)["arc"]
    tau = 2.5e-4
    for reference in (None, arc):
        terms = {}
        for name, times in (("one", tau), ("six", (tau,) * 6), ("unequal", TIMES)):
            kv = KelvinVoigtDamping(times, rod.omega0)
            extra = dict(kelvin_voigt=kv, chart=quaternion_chart(Q), reference=reference)
            terms[name] = _assemble(_general(rod, U, Udot, V, dx, loads, **extra)["kelvin_voigt"])
        scale = np.abs(terms["one"]).max()
        assert np.abs(terms["six"] - terms["one"]).max() <= 1e-13 * scale, reference
        assert np.abs(terms["unequal"] - terms["one"]).max() > 0.1 * scale, reference
    w = ufl.TestFunction(fem.FunctionSpace(msh, ("Lagrange", 1)))
    weights = ufl.as_vector([1.0, 2.0, 3.0])
    for name in ("n", "m"):
        one = _assemble(ufl.inner(getattr(kelvin_voigt_parts(U, rod, tau), name), weights) * w * dx)
        six = kelvin_voigt_parts(U, rod, (tau,) * 6)
        six = _assemble(ufl.inner(getattr(six, name), weights) * w * dx)
        assert np.abs(six - one).max() <= 1e-13 * np.abs(one).max(), name
    one = _assemble(damping_power(U, rod, retardation_time=tau) * w * dx)
    six = _assemble(damping_power(U, rod, retardation_time=(tau,) * 6) * w * dx)
    assert np.abs(six - one).max() <= 1e-13 * np.abs(one).max()


def _row_ratio(rod_a, rod_b, name, convention_b=EndLoadConvention()):
    """Assembled term ``name`` for two settings; returns (a, b) reshaped to (nodes, 12)."""
    msh, V, U, Udot, dx, loads = _setup(2, seed=7)
    a = _assemble(_general(rod_a, U, Udot, V, dx, loads)[name]).reshape(-1, 12)
    b = _assemble(_general(rod_b, U, Udot, V, dx, loads, convention_b)[name]).reshape(-1, 12)
    return a, b


def test_printed_torsion_inertia_rescales_only_the_torsion_row(rod):
    """Eq. (54) as printed = the d3 moment balance divided by ρ c33 ω0² instead of ρ (c11+c22) ω0²
    (docs/errata.md, erratum 1): its rows differ from the consistent ones by exactly the factor
    (c11 + c22)/c33 in every term except the inertia of row 12, which keeps unit coefficient."""
    from dataclasses import replace

    printed = replace(rod, torsion_inertia="printed")
    factor = (rod.section.c11 + rod.section.c22) / rod.section.c33
    for name in ("elastic", "distributed_load", "end_load"):
        a, b = _row_ratio(rod, printed, name)
        np.testing.assert_allclose(b[:, :11], a[:, :11], rtol=0, atol=1e-13 * np.abs(a).max())
        np.testing.assert_allclose(
            b[:, 11], factor * a[:, 11], rtol=1e-12, atol=1e-13 * np.abs(a).max()
        )


def test_printed_end_load_conventions(rod):
    """Printed sign (41)/(56)-(61) flips the end load; printed scaling (62) uses g0 for all six
    entries instead of (g0/ℓ, g1/ℓ, g2/ℓ, g3/ℓ) (errata 2 and 3)."""
    a, b = _row_ratio(rod, rod, "end_load", EndLoadConvention(sign="printed"))
    np.testing.assert_allclose(b, -a, rtol=0, atol=1e-15 * np.abs(a).max())
    a, b = _row_ratio(rod, rod, "end_load", EndLoadConvention(scaling="printed"))
    groups = dimensionless_groups(rod)
    rotations = (groups.g1, groups.g2, groups.g3)
    expected = [rod.length] * 3 + [groups.g0 * rod.length / g for g in rotations]
    for j, factor in enumerate(expected):
        np.testing.assert_allclose(
            b[:, 6 + j], factor * a[:, 6 + j], rtol=1e-12, atol=1e-14 * np.abs(a).max()
        )


def test_section_constants():
    """c11, c22 of eq. (46); c33 series against the paper's approximate formula (within its
    stated accuracy of a few 0.1 %) and the limits: square 0.1406 a⁴, thin strip W H³/3."""
    sec = rectangle(0.04, 0.06, 0.833)
    assert sec.c11 == pytest.approx(0.04 * 0.06**3 / 12, rel=1e-15)
    assert sec.c22 == pytest.approx(0.06 * 0.04**3 / 12, rel=1e-15)
    approx = rectangle_torsion_constant(0.04, 0.06, "approximate")
    assert sec.c33 == pytest.approx(approx, rel=5e-3)
    assert rectangle_torsion_constant(1.0, 1.0) == pytest.approx(0.140577, rel=1e-5)
    assert rectangle_torsion_constant(1.0, 1e-3) == pytest.approx(1e-9 / 3, rel=1e-3)


def test_paper_reference_frequency_and_groups():
    """ω0 = 1.875²/ℓ² sqrt(E c22/(ρA)) = 207.0236 rad/s (section 6) and (48) spot checks."""
    from cosserat_fem.forms.groups import euler_bernoulli_omega0

    sec = rectangle(0.04, 0.06, 0.833)
    w0 = euler_bernoulli_omega0(1.0, sec, 2730.0, 7.1e10)
    assert w0 == pytest.approx(207.0236, rel=2e-6)
    groups = dimensionless_groups(RodConstants(1.0, sec, 2730.0, 7.1e10, 7.1e10 / 2.64, 207.0236))
    assert groups.nu11 == groups.nu21 == pytest.approx(7.1e10 / (2730.0 * 207.0236**2), rel=1e-14)
    assert groups.nu02 == pytest.approx(groups.nu11, rel=1e-14)  # EA g0/ℓ = E/(ρ ℓ² ω0²)
    assert groups.nu33 == pytest.approx((sec.c22 - sec.c11) / (sec.c11 + sec.c22), rel=1e-14)


def _chart_quaternion(msh, degree: int, seed: int) -> fem.Function:
    """A field of quaternions Q(σ) far from any rotation's identity and far from Q = 0
    (|Q| ≥ 0.5 at the nodes; the interpolant stays away from 0 as well)."""
    Q = fem.Function(fem.VectorFunctionSpace(msh, ("Lagrange", degree), dim=4))
    rng = np.random.default_rng(seed)
    values = rng.standard_normal((Q.x.array.size // 4, 4))
    values[:, 0] += 1.5
    Q.x.array[:] = values.ravel()
    return Q


@pytest.mark.parametrize("degree", [1, 3])
def test_charted_general_form_equals_the_director_form(rod, degree):
    """Angles measured from a frame A(σ) of quaternions (forms/kinematics.py, "Charts"): the
    general form with v = D A r', û = Mm θ' + D κ̂ against the director form whose directors
    are the rows of the elementary rotations times the Euler–Rodrigues frame of Q/|Q|, u and
    w by UFL's chain rule. Every term, damping included, to the round-off bound of the module
    docstring; the frame turns the directors by O(1), so a missing frame or κ̂ term fails."""
    msh, V, U, Udot, dx, loads = _setup(degree, seed=20 + degree)
    Q = _chart_quaternion(msh, degree, seed=30 + degree)
    viscous, tau = (3.0e2, 0.7), TIMES
    general = _general(
        rod,
        U,
        Udot,
        V,
        dx,
        loads,
        damping=ViscousDamping(*viscous, rod.omega0),
        kelvin_voigt=KelvinVoigtDamping(tau, rod.omega0),
        chart=quaternion_chart(Q),
    )
    director = director_residual_terms(
        U,
        Udot,
        ufl.TestFunction(V),
        rod,
        dx,
        loads["f"],
        loads["l"],
        tuple(loads["ends"]),
        viscous_damping=viscous,
        retardation_time=tau,
        chart_quaternion=Q,
    )
    plain = _general(rod, U, Udot, V, dx, loads)
    _agree_and_differ(general, director, plain, ("elastic", "distributed_load", "end_load"))


def _agree_and_differ(general: dict, director: dict, other: dict, differing: tuple) -> None:
    """Every term of ``general`` equals ``director``'s to the round-off bound of the module
    docstring, damping included, and the ``differing`` ones differ from ``other``'s by O(1)
    (so that the comparison could fail)."""
    assert set(general) == set(director) == {*TERMS, "damping", "kelvin_voigt"}
    for name in general:
        a, b = _assemble(general[name]), _assemble(director[name])
        scale = np.abs(a).max()
        assert scale > 0, name
        assert np.abs(a - b).max() <= 1e-12 * scale, name
        if name in differing:
            assert np.abs(a - _assemble(other[name])).max() > 1e-2 * scale, name


def test_identity_chart_equals_the_paper_chart(rod):
    """Q ≡ (1, 0, 0, 0): A = I and κ̂ = 0 exactly, so every term equals the chart-free form's
    to round-off (the products with exact ones and zeros differ only in summation order)."""
    msh, V, U, Udot, dx, loads = _setup(2, seed=41)
    Q = fem.Function(fem.VectorFunctionSpace(msh, ("Lagrange", 2), dim=4))
    Q.x.array.reshape(-1, 4)[:, 0] = 1.0
    charted = _general(rod, U, Udot, V, dx, loads, chart=quaternion_chart(Q))
    plain = _general(rod, U, Udot, V, dx, loads)
    for name in TERMS:
        a, b = _assemble(charted[name]), _assemble(plain[name])
        assert np.abs(a - b).max() <= 1e-14 * np.abs(b).max(), name


def test_rotary_inertias_given_apart_from_the_section(rod):
    """Rotary inertias not those of the section (I11, I22, I33 per unit length, here unequal
    and unrelated to c11, c22: Simo & Vu-Quoc's benchmarks give them so): the general form,
    whose rows are divided by them and whose gyroscopic coefficients become (I33 − I22)/I11,
    (I11 − I33)/I22, (I22 − I11)/I33 (forms/groups.py), against the director form with
    h = Σ I_ii (w · d_i) d_i; every term, with a chart, to the round-off bound of the module
    docstring. The inertia term must differ from the section's (a test that could not fail
    otherwise)."""
    from dataclasses import replace

    given = replace(rod, inertia=(0.31, 0.77, 1.93))
    msh, V, U, Udot, dx, loads = _setup(2, seed=51)
    Q = _chart_quaternion(msh, 2, seed=52)
    general = _general(given, U, Udot, V, dx, loads, chart=quaternion_chart(Q))
    director = director_residual_terms(
        U,
        Udot,
        ufl.TestFunction(V),
        given,
        dx,
        loads["f"],
        loads["l"],
        tuple(loads["ends"]),
        chart_quaternion=Q,
    )
    for name in TERMS:
        a, b = _assemble(general[name]), _assemble(director[name])
        assert np.abs(a - b).max() <= 1e-12 * np.abs(a).max(), name
    section = _general(rod, U, Udot, V, dx, loads, chart=quaternion_chart(Q))
    inertia = _assemble(general["inertia"])
    assert np.abs(inertia - _assemble(section["inertia"])).max() > 1e-2 * np.abs(inertia).max()


def _references(msh, length: float):
    """A circular arc and a helix (forms/reference.py), turned off the coordinate planes so that
    no component is trivially zero."""
    from cosserat_fem.forms.reference import circular_arc, helix, placed

    sigma = ufl.SpatialCoordinate(msh)[0]
    c, s = np.cos(0.7), np.sin(0.7)
    turn = [[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]]
    turn = np.array(turn) @ np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])
    return {
        "arc": placed(circular_arc(sigma, length, 0.9), turn.tolist()),
        "helix": helix(sigma, length, 0.35, 0.4),
    }


@pytest.mark.parametrize("shape", ["arc", "helix"])
@pytest.mark.parametrize("degree", [1, 3])
def test_general_form_with_a_reference_equals_the_director_form(rod, degree, shape):
    """A rod curved at rest (forms/general_form.py, "A reference configuration"): the general
    form, with strains D0 (R r' − t0) and D0 κ_R and rows 4-6 in the frame of R, against the
    director form built the other way, with directors D0 D A by UFL's chain rule and strains
    measured from the reference's own u0 = ½ Σ d0_i × d0_i' (derivative of D0 by UFL): every
    term, damping and a chart included, to the round-off bound of the module docstring. The
    elastic and inertia terms must differ from the straight rod's by O(1)."""
    msh, V, U, Udot, dx, loads = _setup(degree, seed=60 + degree)
    Q = _chart_quaternion(msh, degree, seed=70 + degree)
    reference = _references(msh, rod.length)[shape]
    viscous, tau = (3.0e2, 0.7), TIMES
    extra = dict(
        damping=ViscousDamping(*viscous, rod.omega0),
        kelvin_voigt=KelvinVoigtDamping(tau, rod.omega0),
        chart=quaternion_chart(Q),
    )
    general = _general(rod, U, Udot, V, dx, loads, reference=reference, **extra)
    director = director_residual_terms(
        U,
        Udot,
        ufl.TestFunction(V),
        rod,
        dx,
        loads["f"],
        loads["l"],
        tuple(loads["ends"]),
        viscous_damping=viscous,
        retardation_time=tau,
        chart_quaternion=Q,
        reference=reference,
    )
    straight = _general(rod, U, Udot, V, dx, loads, **extra)
    _agree_and_differ(general, director, straight, ("inertia", "elastic", "kelvin_voigt"))


def test_straight_reference_equals_the_paper_form(rod):
    """t0 = e3, D0 = I through the reference path (rows in the frame of R, I_λ = diag(Î),
    contact terms from N̂, M̂) equals (65) as the paper writes it, term by term to round-off,
    with a chart and damping: the reference path is the general form, not a variant of it."""
    from cosserat_fem.forms.reference import straight

    msh, V, U, Udot, dx, loads = _setup(3, seed=81)
    Q = _chart_quaternion(msh, 3, seed=82)
    extra = dict(
        damping=ViscousDamping(3.0e2, 0.7, rod.omega0),
        kelvin_voigt=KelvinVoigtDamping(2.5e-4, rod.omega0),
        chart=quaternion_chart(Q),
    )
    through = _general(rod, U, Udot, V, dx, loads, reference=straight(), **extra)
    paper = _general(rod, U, Udot, V, dx, loads, **extra)
    for name in paper:
        a, b = _assemble(through[name]), _assemble(paper[name])
        assert np.abs(a - b).max() <= 1e-13 * np.abs(b).max(), name


@pytest.mark.parametrize("shape", ["arc", "helix", "corner"])
def test_a_rod_at_rest_in_its_reference_has_zero_residual(rod, shape):
    """U = 0 (the reference itself, at rest) with no load: every term of the residual vanishes
    to round-off for an arc, a helix and a polyline whose frame jumps by 50° at the node
    σ = 0.4 (the strains D0 (R r' − t0) and D0 κ_R vanish there identically; no D0' is
    formed). Held against the elastic term of a small deflection, 1e-3 rad, whose size is
    about 1e-3 of the stiffness: the rest residual is below 1e-13 of it."""
    msh, V, U, Udot, dx, _ = _setup(3, seed=91)
    if shape == "corner":
        from cosserat_fem.forms.reference import Reference

        sigma = ufl.SpatialCoordinate(msh)[0]
        c, s = np.cos(np.radians(50.0)), np.sin(np.radians(50.0))
        before, after = np.eye(3), np.array([[c, 0.0, -s], [0.0, 1.0, 0.0], [s, 0.0, c]])
        frame = ufl.conditional(
            ufl.lt(sigma, 0.4), ufl.as_matrix(before.tolist()), ufl.as_matrix(after.tolist())
        )
        reference = Reference(frame[2, :], frame)
    else:
        reference = _references(msh, rod.length)[shape]
    U.x.array[:] = 0.0
    Udot.x.array[:] = 0.0
    Q = fem.Function(fem.VectorFunctionSpace(msh, ("Lagrange", 3), dim=4))
    Q.x.array.reshape(-1, 4)[:, 0] = 1.0
    terms = residual_terms(
        U,
        Udot,
        ufl.TestFunction(V),
        dimensionless_groups(rod),
        dx,
        chart=quaternion_chart(Q),
        reference=reference,
    ).as_dict()
    rest = {name: np.abs(_assemble(form)).max() for name, form in terms.items()}
    U.x.array.reshape(-1, 12)[:, 4] = 1e-3 * V.tabulate_dof_coordinates()[:, 0]  # ψ = 1e-3 σ
    bent = np.abs(
        _assemble(
            residual_terms(
                U,
                Udot,
                ufl.TestFunction(V),
                dimensionless_groups(rod),
                dx,
                chart=quaternion_chart(Q),
                reference=reference,
            ).elastic
        )
    ).max()
    assert bent > 0
    for name, value in rest.items():
        assert value <= 1e-13 * bent, (name, value, bent)


def test_a_curve_from_its_tangent_and_director_is_the_helix():
    """forms/reference.py ``curve`` (D0 from t0 and d0_1, u0 from their derivatives) given the
    helix's tangent, principal normal and their derivatives in s equals ``helix``'s closed-form
    frame and curvature, u0 = (0, cos²α/R, sin α cos α/R): ∫ |ΔD0|² + |Δu0|² R² dσ is zero to
    round-off (1e-28 of the frame's O(1) entries squared)."""
    from cosserat_fem.forms.reference import curve, helix

    msh = mesh.create_unit_interval(MPI.COMM_WORLD, 5)
    sigma = ufl.SpatialCoordinate(msh)[0]
    length, R, alpha = 1.3, 0.35, 0.4
    k, ca, sa = np.cos(alpha) / R, np.cos(alpha), np.sin(alpha)
    a = k * length * sigma
    c, s = ufl.cos(a), ufl.sin(a)
    written = curve(
        ufl.as_vector([-s * ca, c * ca, sa]),
        ufl.as_vector([-k * c * ca, -k * s * ca, 0.0]),
        ufl.as_vector([-c, -s, 0.0]),
        ufl.as_vector([k * s, -k * c, 0.0]),
    )
    named = helix(sigma, length, R, alpha)
    gap = (
        ufl.inner(written.frame - named.frame, written.frame - named.frame)
        + R**2 * ufl.inner(written.curvature - named.curvature, written.curvature - named.curvature)
    ) * ufl.dx(msh)
    assert abs(fem.assemble_scalar(fem.form(gap))) <= 1e-28
    size = R**2 * ufl.inner(named.curvature, named.curvature) * ufl.dx(msh)
    assert fem.assemble_scalar(fem.form(size)) > 0.5  # |u0| R = cos α: a real comparison
