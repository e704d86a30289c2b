"""A general 6×6 section law and sections that vary along s (issue 29, items 3-4;
docs/sections.md): n = K₁ Γ + K₁₂ κ, m = K₂₁ Γ + K₂ κ in the directors, K, μ and I
functions of σ = s/ℓ.

Checks, each against an independent derivation:

* the diagonal law K = diag(κGA, κGA, EA, E c11, E c22, G c33) with μ = ρ A and the rod's
  inertias is the paper's (13): the same residual vectors as the form without a law;
* a coupled, varying law in the general form (65) equals the director form (6), term by term;
* extension–twist coupling K36: a cantilever under an end force F along its axis has the
  closed-form strains ε = F K66/(K33 K66 − K36²), κ3 = −F K36/(K33 K66 − K36²);
* a stepped shaft (two pieces) under an end load against the sum of the pieces' closed forms;
* a linearly tapered cantilever's first bending frequency against a Rayleigh–Ritz series;
* bad 6×6 input: one line naming the key.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import scipy.linalg
import scipy.sparse.linalg
import ufl
from cosserat_fem.forms.director_form import director_residual_terms
from cosserat_fem.forms.energy import kinetic_energy_density, strain_energy_density
from cosserat_fem.forms.general_form import (
    DistributedLoads,
    EndLoads,
    KelvinVoigtDamping,
    residual_terms,
)
from cosserat_fem.forms.groups import RodConstants, dimensionless_groups
from cosserat_fem.forms.resultants import resultants, scaled_law
from cosserat_fem.forms.section import SectionLaw, check_stiffness, rectangle
from dolfinx import fem, mesh
from dolfinx.fem.petsc import NonlinearProblem, assemble_matrix, assemble_vector
from dolfinx.nls.petsc import NewtonSolver
from mpi4py import MPI
from petsc4py import PETSc

from cosserat_fem.api import modes, run
from cosserat_fem.common.errors import SceneError
from cosserat_fem.rod.model import build_model
from cosserat_fem.scene.build import load_scene

E, G, RHO = 2.1e11, 8.1e10, 7800.0
#: Six unequal retardation times μ_1..μ_6 [s] (shear 1, shear 2, extension, bending 1,
#: bending 2, torsion), spread by a factor 12.
TIMES = (2.5e-4, 1.0e-4, 4.0e-4, 3.0e-4, 0.5e-4, 6.0e-4)


def _rod(length=1.7, law=None, a=0.03, b=0.07) -> RodConstants:
    sec = rectangle(a, b, 0.85)
    return RodConstants(length, sec, RHO, E, G, 150.0, law=law)


def _diagonal(rod: RodConstants) -> tuple[float, ...]:
    s = rod.section
    kga = s.shear_coefficient * G * s.area
    return (kga, kga, E * s.area, E * s.c11, E * s.c22, G * s.c33)


def _assemble(form) -> np.ndarray:
    vec = assemble_vector(fem.form(form))
    vec.ghostUpdate()
    return vec.array.copy()


def _random_state(degree: int, seed: int, cells: int = 5):
    msh = mesh.create_unit_interval(MPI.COMM_WORLD, cells)
    V = fem.VectorFunctionSpace(msh, ("Lagrange", degree), dim=12)
    U, Udot = fem.Function(V), fem.Function(V)
    rng = np.random.default_rng(seed)
    U.x.array[:] = 0.5 * rng.standard_normal(U.x.array.size)
    Udot.x.array[:] = 0.5 * rng.standard_normal(U.x.array.size)
    dx = ufl.Measure("dx", domain=msh, metadata={"quadrature_degree": 8})
    return msh, V, U, Udot, dx


def _ends(msh):
    """The boundary measure with the end σ = 1 tagged 2 (the only end loaded here)."""
    end = mesh.locate_entities_boundary(msh, 0, lambda X: np.isclose(X[0], 1.0))
    tags = mesh.meshtags(msh, 0, end.astype(np.int32), np.full(len(end), 2, dtype=np.int32))
    return ufl.Measure("ds", domain=msh, subdomain_data=tags)


def _assert_terms_equal(a: dict, b: dict) -> None:
    """The same terms, each assembled vector non-zero and equal to 1e-12 of its largest entry."""
    assert set(a) == set(b)
    for name in a:
        va, vb = _assemble(a[name]), _assemble(b[name])
        scale = np.abs(va).max()
        assert scale > 0, name
        assert np.abs(va - vb).max() <= 1e-12 * scale, name


def _general(rod, U, Udot, V, dx, ds, **kw):
    x = ufl.SpatialCoordinate(V.mesh)[0]
    loads = DistributedLoads(
        ufl.as_vector([2e3 * x, -1e3, 500.0]), ufl.as_vector([30 * x, 20.0, -15.0])
    )
    ends = (
        EndLoads(ds(2), ufl.as_vector([100.0, -200.0, 300.0]), ufl.as_vector([10.0, 20.0, -30.0])),
    )
    law = scaled_law(rod) if rod.law is not None else None
    terms = residual_terms(
        U, Udot, ufl.TestFunction(V), dimensionless_groups(rod), dx, loads, ends, law=law, **kw
    )
    return terms.as_dict()


@pytest.mark.parametrize("degree", [1, 2])
def test_the_diagonal_law_is_the_papers_law(degree):
    """The 6×6 law diag(κGA, κGA, EA, E c11, E c22, G c33), μ = ρ A and I = ρ (c11, c22,
    c11 + c22) against no law (the flux (63) and source (67) of the groups (48)), at random
    states with loads and Kelvin–Voigt damping, term by term. The two are algebraically equal
    (the law's path is that of the straight reference, tested equal to (65) in
    tests/test_forms.py) and differ by the order of a few hundred products in the sums of the
    assembly: 1e-12 of the largest entry is ~1e4 ulp of headroom (observed ~1e-16)."""
    msh, V, U, Udot, dx = _random_state(degree, seed=7 + degree)
    ds = _ends(msh)
    paper = _rod()
    k = _diagonal(paper)
    law = SectionLaw(
        tuple(tuple(k[i] if i == j else 0.0 for j in range(6)) for i in range(6)),
        RHO * paper.section.area,
        paper.mass_inertias,
    )
    diag = _rod(law=law)
    kv = KelvinVoigtDamping(1e-3, paper.omega0)
    a = _general(paper, U, Udot, V, dx, ds, kelvin_voigt=kv)
    b = _general(diag, U, Udot, V, dx, ds, kelvin_voigt=kv)
    _assert_terms_equal(a, b)
    # the output's resultants (forms/resultants.py) alike, tested against P1 functions
    ra, rb = resultants(U, paper, 1e-3), resultants(U, diag, 1e-3)
    w = ufl.TestFunction(fem.FunctionSpace(msh, ("Lagrange", 1)))
    for name in ("n", "m"):
        weights = ufl.as_vector([1.0, 2.0, 3.0])
        fa = _assemble(ufl.inner(getattr(ra, name), weights) * w * dx)
        fb = _assemble(ufl.inner(getattr(rb, name), weights) * w * dx)
        assert np.abs(fa - fb).max() <= 1e-12 * np.abs(fa).max(), name
    # and the energies (forms/energy.py): ½ (Γ·n + κ·m) and ½ (μ |ṙ|² + Σ I_i w_i²)
    for density in (strain_energy_density, kinetic_energy_density):
        ea = fem.assemble_scalar(fem.form(density(U, paper) * dx))
        eb = fem.assemble_scalar(fem.form(density(U, diag) * dx))
        assert abs(ea - eb) <= 1e-12 * abs(ea), density.__name__


def _coupled_varying_law(rod: RodConstants, x) -> SectionLaw:
    """A full symmetric positive definite K(σ) = S(σ) (D + C) S(σ): the diagonal D of the rod,
    every coupling C_ij = 0.3 sqrt(D_ii D_jj) (i ≠ j; D + C is then D^½ (0.7 I + 0.3 11ᵀ) D^½,
    positive definite) and a taper S = 1 − 0.4 σ; μ and I tapered too."""
    k = _diagonal(rod)
    taper = 1.0 - 0.4 * x
    K = tuple(
        tuple(taper * (k[i] if i == j else 0.3 * math.sqrt(k[i] * k[j])) for j in range(6))
        for i in range(6)
    )
    inertia = tuple(taper * i for i in rod.mass_inertias)
    return SectionLaw(K, taper * RHO * rod.section.area, inertia)


@pytest.mark.parametrize("degree", [1, 3])
def test_a_coupled_varying_law_in_the_general_form_equals_the_director_form(degree):
    """The general form with a coupled, tapered law (every K_ij ≠ 0, K, μ, I linear in σ)
    against the director form (directors by UFL's chain rule, n and m in the fixed basis),
    term by term with Kelvin–Voigt damping of six unequal retardation times (BeamDyn's
    diag(μ) K, where every coupling of K meets unequal μ); the same round-off bound as above."""
    msh, V, U, Udot, dx = _random_state(degree, seed=3 * degree)
    ds = _ends(msh)
    x = ufl.SpatialCoordinate(msh)[0]
    rod = _rod()
    rod = _rod(law=_coupled_varying_law(rod, x))
    kv = KelvinVoigtDamping(TIMES, rod.omega0)
    general = _general(rod, U, Udot, V, dx, ds, kelvin_voigt=kv)
    director = director_residual_terms(
        U,
        Udot,
        ufl.TestFunction(V),
        rod,
        dx,
        ufl.as_vector([2e3 * x, -1e3, 500.0]),
        ufl.as_vector([30 * x, 20.0, -15.0]),
        ((ds(2), ufl.as_vector([100.0, -200.0, 300.0]), ufl.as_vector([10.0, 20.0, -30.0])),),
        retardation_time=TIMES,
    )
    _assert_terms_equal(general, director)


def test_the_viscous_law_is_beamdyns_diag_mu_times_k():
    """BeamDyn's f_d = μ C ε̇ with μ diagonal (OpenFAST theory.rst, "Damping Forces"; BeamDyn.f90
    Calc_Stif_betaC: betaC = diag(beta) Stif): row i of K ε̇ times μ_i. With a coupled K (all
    K_ij ≠ 0) and six unequal μ_i, the output's viscous resultants (forms/resultants.py
    kelvin_voigt_parts) at a random state equal diag(μ) K ε̇ formed here from the 6×6 product
    in numpy and the parts' own rates ε̇, to 1e-12 of the largest (round-off of six-term sums),
    and differ from K diag(μ) ε̇ by more than 0.1 of it: the two orders are told apart."""
    from cosserat_fem.forms.resultants import kelvin_voigt_parts

    msh, _, U, _, dx = _random_state(2, seed=41)
    rod = _rod()
    K = np.array(_coupled_varying_law(rod, 0.0).stiffness, dtype=float)
    rod = _rod(law=_coupled_varying_law(rod, 0.0))
    parts = kelvin_voigt_parts(U, rod, TIMES)
    rates = ufl.as_vector([parts.v_rate[i] for i in range(3)] + [parts.u_rate[i] for i in range(3)])
    got = ufl.as_vector([parts.n[i] for i in range(3)] + [parts.m[i] for i in range(3)])
    mu = np.diag(TIMES)
    w = ufl.TestFunction(fem.VectorFunctionSpace(msh, ("Lagrange", 1), dim=6))
    vectors = {
        name: _assemble(ufl.inner(ufl.as_matrix(matrix.tolist()) * rates, w) * dx)
        for name, matrix in (("beamdyn", mu @ K), ("other", K @ mu))
    }
    ours = _assemble(ufl.inner(got, w) * dx)
    scale = np.abs(ours).max()
    assert np.abs(ours - vectors["beamdyn"]).max() <= 1e-12 * scale
    assert np.abs(ours - vectors["other"]).max() > 0.1 * scale


def _static_tip(rod: RodConstants, force, cells: int, degree: int = 2, taper=None) -> np.ndarray:
    """The cantilever (clamped at σ = 0, p = q = 0) under the end force ``force`` [N] (fixed
    basis) at σ = 1, static (q̇ = 0; the kinematic rows then give q = 0): the tip's p."""
    msh = mesh.create_unit_interval(MPI.COMM_WORLD, cells)
    V = fem.VectorFunctionSpace(msh, ("Lagrange", degree), dim=12)
    U = fem.Function(V)
    ds = _ends(msh)
    dx = ufl.Measure("dx", domain=msh, metadata={"quadrature_degree": 2 * degree + 2})
    x = ufl.SpatialCoordinate(msh)[0]
    if taper is not None:
        rod = RodConstants(rod.length, rod.section, RHO, E, G, rod.omega0, law=taper(x))
    law = scaled_law(rod) if rod.law is not None else None
    F = residual_terms(
        U,
        ufl.zero(12),
        ufl.TestFunction(V),
        dimensionless_groups(rod),
        dx,
        end_loads=(EndLoads(ds(2), ufl.as_vector(force)),),
        law=law,
    ).total()
    start = mesh.locate_entities_boundary(msh, 0, lambda X: np.isclose(X[0], 0.0))
    bc = fem.dirichletbc(
        np.zeros(12, dtype=PETSc.ScalarType), fem.locate_dofs_topological(V, 0, start), V
    )
    problem = NonlinearProblem(F, U, bcs=[bc])
    solver = NewtonSolver(MPI.COMM_WORLD, problem)
    solver.rtol, solver.atol, solver.max_it = 1e-14, 1e-14, 30
    solver.convergence_criterion = "incremental"
    ksp = solver.krylov_solver
    ksp.setType("preonly")
    ksp.getPC().setType("lu")
    solver.solve(U)
    points = V.tabulate_dof_coordinates()[:, 0]
    tip = int(np.argmax(points))
    return U.x.array.reshape(-1, 12)[tip, :6].copy()


def test_extension_twist_coupling_has_the_closed_form_response():
    """An end force F e3 on a cantilever whose law couples extension and twist (K36 ≠ 0):
    the resultants are n = (0, 0, F), m = 0 in the directors all along (free end, no other load,
    and a rod that only stretches and twists keeps d3 = e3), so K33 ε + K36 κ3 = F,
    K36 ε + K66 κ3 = 0:

        ε = F K66/(K33 K66 − K36²),   κ3 = −F K36/(K33 K66 − K36²)

    (derivation in docs/sections.md), at any load: a twisted, stretched straight rod has
    v = (0, 0, 1 + p3'), u3 = φ'/ℓ exactly. The strains are constant, in the finite element
    space of any degree: the discretisation error is zero and the tip's z/ℓ = ε and φ = κ3 ℓ
    hold to the Newton tolerance, 1e-9 relative (the increment's 1e-14 times a condition
    number ~1e4 of the clamped operator at these stiffnesses)."""
    rod = _rod()
    k = list(_diagonal(rod))
    K36 = 0.5 * math.sqrt(k[2] * k[5])  # |K36|² < K33 K66: positive definite
    K = [[k[i] if i == j else 0.0 for j in range(6)] for i in range(6)]
    K[2][5] = K[5][2] = K36
    check_stiffness(K, "rod.section.stiffness")
    law = SectionLaw(tuple(tuple(r) for r in K))
    force = 1e-4 * k[2]  # ε ~ 1e-4
    tip = _static_tip(_rod(law=law), [0.0, 0.0, force], cells=4, degree=1)
    det = k[2] * k[5] - K36**2
    eps, kappa3 = force * k[5] / det, -force * K36 / det
    assert abs(tip[2] - eps) <= 1e-9 * abs(eps)
    assert abs(tip[5] - kappa3 * rod.length) <= 1e-9 * abs(kappa3 * rod.length)
    assert abs(eps - force / k[2]) > 0.2 * eps  # K36² = K33 K66/4: ε is 4/3 of F/K33
    assert np.abs(tip[[0, 1, 3, 4]]).max() <= 1e-12


def _stepped(rod: RodConstants, thin: RodConstants):
    """The law of a shaft of ``rod``'s section on σ < ½ and ``thin``'s on σ > ½."""

    def law(x):
        k1, k2 = _diagonal(rod), _diagonal(thin)
        first = ufl.lt(x, 0.5)
        K = tuple(
            tuple(ufl.conditional(first, k1[i], k2[i]) if i == j else 0.0 for j in range(6))
            for i in range(6)
        )
        return SectionLaw(K)

    return law


def _stepped_tip_errors(cells_list):
    rod, thin = _rod(), _rod(a=0.02, b=0.05)
    k1, k2 = _diagonal(rod), _diagonal(thin)
    ell = rod.length
    P = 1e-5 * 3 * k1[4] / ell**2  # tip deflection ~ 1e-5 ℓ: linear to ~1e-9
    half = 0.5 * ell
    exact = P * (
        (ell**3 - (ell - half) ** 3) / (3 * k1[4])
        + (ell - half) ** 3 / (3 * k2[4])
        + half / k1[0]
        + half / k2[0]
    )
    errors = []
    for cells in cells_list:
        tip = _static_tip(rod, [P, 0.0, 0.0], cells, degree=2, taper=_stepped(rod, thin))
        errors.append((exact - tip[0] * ell) / exact)  # signed: positive if too stiff
    return exact, errors


def test_a_stepped_shaft_is_the_sum_of_its_pieces():
    """A cantilever of two pieces (a 30×70 mm and a 20×50 mm rectangle, the step at ℓ/2, the
    law a UFL conditional of σ) under an end force P e1: the tip deflection of Timoshenko's
    beam, the sum of the pieces' closed forms, δ = P Σ_k ∫_k [(ℓ − s)²/(E c22)_k + 1/(κGA)_k] ds
    (bending about d2, shear along d1), at δ/ℓ ~ 1e-5 where the geometric nonlinearity is
    ~ (P ℓ²/EI)² ~ 1e-9. With the step at a node, quadratic elements' nodal values converge
    at order 4 once the shear locking of a rod ℓ/a ~ 60 is resolved (relative errors 2.9e-2,
    6.6e-3, 1.2e-3, 1.4e-4, 1.1e-5, 7.6e-7 on 4 ... 128 cells, orders 2.2, 2.5, 3.1, 3.6,
    3.9): on 32, 64, 128 cells the orders must lie in [3.3, 4.3] and the error on 128 cells
    below 1.5e-6, with the FE tip too stiff (the error's sign of a displacement method)."""
    exact, errors = _stepped_tip_errors([32, 64, 128])
    orders = [math.log2(errors[i] / errors[i + 1]) for i in range(2)]
    assert all(3.3 <= o <= 4.3 for o in orders), orders
    assert 0.0 < errors[-1] <= 1.5e-6, errors


def _tapered_law(rod: RodConstants, taper: float):
    """Every stiffness, μ and I times (1 − taper σ): a rectangle whose width b tapers
    linearly, for its bending about d2 (E c22 = E b a³/12, κGA, ρ A = ρ a b, ρ c22 all ∝ b)."""
    k = _diagonal(rod)

    def law(x):
        s = 1.0 - taper * x
        K = tuple(tuple(s * k[i] if i == j else 0.0 for j in range(6)) for i in range(6))
        inertia = tuple(s * i for i in rod.mass_inertias)
        return SectionLaw(K, s * RHO * rod.section.area, inertia)

    return law


def _first_bending_frequency(
    rod: RodConstants, law, cells: int, near: float, degree: int = 2
) -> float:
    """ω1 [rad/s] of the linearised clamped-free rod: A x + λ B x = 0 with A = ∂F/∂U and
    B = ∂F/∂U̇ of the residual (65) at the straight rod at rest (dense, the clamped end's dofs
    removed), ω = ω0 |Im λ|, the smallest of the bending-about-d2 (x) modes among the six
    eigenvalues λ nearest σ = i ``near``/ω0 [rad/s]: shift-invert, (A + σB)⁻¹ B x =
    x/(σ − λ), by ARPACK on a dense LU (B's null space, the λ = ∞, maps to 0), instead of
    every eigenpair of the dense pencil (O(n³): 4.7 s of 5 on 32 cells). The first bending
    mode lies within 1e-2 of ``near`` = the Ritz frequency; the nearest other modes, the
    first about d1 (c11 > c22) and the second about d2, lie 1.5 and 6 times higher."""
    msh = mesh.create_unit_interval(MPI.COMM_WORLD, cells)
    V = fem.VectorFunctionSpace(msh, ("Lagrange", degree), dim=12)
    U, Udot = fem.Function(V), fem.Function(V)
    dx = ufl.Measure("dx", domain=msh, metadata={"quadrature_degree": 2 * degree + 2})
    x = ufl.SpatialCoordinate(msh)[0]
    rod = RodConstants(rod.length, rod.section, RHO, E, G, rod.omega0, law=law(x))
    F = residual_terms(
        U, Udot, ufl.TestFunction(V), dimensionless_groups(rod), dx, law=scaled_law(rod)
    ).total()
    du = ufl.TrialFunction(V)
    mats = []
    for var in (U, Udot):
        A = assemble_matrix(fem.form(ufl.derivative(F, var, du)))
        A.assemble()
        mats.append(A.convert("dense").getDenseArray().copy())
    points = V.tabulate_dof_coordinates()[:, 0]
    free = np.repeat(~np.isclose(points, 0.0), 12)  # the blocks' dofs, 12 a node
    A, B = (M[np.ix_(free, free)] for M in mats)
    sigma = 1j * near / rod.omega0
    lu = scipy.linalg.lu_factor(A + sigma * B)
    op = scipy.sparse.linalg.LinearOperator(
        A.shape, matvec=lambda v: scipy.linalg.lu_solve(lu, B @ v), dtype=complex
    )
    nu, vecs = scipy.sparse.linalg.eigs(op, k=6, v0=np.ones(A.shape[0], dtype=complex))
    lam = sigma - 1.0 / nu
    best = math.inf
    for value, vec in zip(lam, vecs.T, strict=True):
        comps = np.abs(vec.reshape(-1, 12))
        if comps[:, 0].max() > 10 * comps[:, 1].max():  # bending in x (about d2)
            best = min(best, abs(value.imag))
    return best * rod.omega0


def _ritz_frequency(
    EI: float, kGA: float, mu: float, rhoI: float, ell: float, taper: float, terms: int
) -> float:
    """Rayleigh–Ritz for Timoshenko's cantilever (clamped at ξ = s/ℓ = 0) whose EI, κGA, μ,
    ρI are the given ones times (1 − taper ξ): deflection w = Σ_k c_k ξ P_k(2ξ − 1), rotation
    ψ = Σ_k d_k ξ P_k(2ξ − 1) (Legendre P_k, k < terms; w(0) = ψ(0) = 0), ω1² the smallest
    eigenvalue of K c = ω² M c with the energies ∫ [EI ψ_s² + κGA (w_s − ψ)²] ds and
    ∫ [μ w² + ρI ψ²] ds, integrated exactly by Gauss–Legendre (polynomials of degree
    ≤ 2 terms + 1). κGA → ∞, ρI → 0 is Euler–Bernoulli's beam."""
    xi, wq = np.polynomial.legendre.leggauss(terms + 3)
    xi, wq = 0.5 * (xi + 1.0), 0.5 * wq * ell
    leg = np.polynomial.legendre
    t = 2.0 * xi - 1.0
    eye = np.eye(terms)
    P = np.stack([leg.legval(t, eye[k]) for k in range(terms)], axis=1)
    dP = np.stack([2.0 * leg.legval(t, leg.legder(eye[k])) for k in range(terms)], axis=1)
    phi = xi[:, None] * P
    dphi = (P + xi[:, None] * dP) / ell
    zero = np.zeros_like(phi)
    w, ws = np.hstack([phi, zero]), np.hstack([dphi, zero])
    psi, psis = np.hstack([zero, phi]), np.hstack([zero, dphi])
    shape = (1.0 - taper * xi) * wq

    def gram(a, b, coef):
        return (a * (coef * shape)[:, None]).T @ b

    shear = ws - psi
    K = gram(psis, psis, EI) + gram(shear, shear, kGA)
    M = gram(w, w, mu) + gram(psi, psi, rhoI)
    return math.sqrt(scipy.linalg.eigh(K, M, eigvals_only=True)[0])


def test_a_tapered_cantilevers_first_frequency():
    """A cantilever whose width tapers linearly to half (EI, κGA, μ and ρI ∝ 1 − σ/2): its
    first bending frequency against Timoshenko's beam by Rayleigh–Ritz
    (:func:`_ritz_frequency`, computed here independently of the forms), converged: 10 and
    12 terms agree to 1e-9 (observed 8e-12). The series' own check: the uniform rod with
    κGA × 100 and ρI / 100, near Euler–Bernoulli's, gives (β1 ℓ)² = 1.87510407²
    (cos β cosh β = −1) to 1e-5 (observed 3.0e-6, Timoshenko's correction 2.4e-4 / 100;
    further the equal-degree series locks). The FE frequency converges from
    above (a displacement method): on 8, 16 and 32 quadratic cells the error must be
    positive, fall by a factor ≥ 4 each time (order ≥ 2 in ω; observed 1.6e-3, 2.3e-4, 2.2e-5, the
    pre-asymptotic range of a slender rod's shear locking) and be below 5e-5 on 32 cells. The
    FE frequency is the eigenvalue nearest the reference by shift-invert
    (:func:`_first_bending_frequency`): it agrees with every eigenpair of the dense pencil
    (scipy.linalg.eig, 4.7 s) to 5e-8 relative on 8 and 32 cells (measured), 400 times below
    the finest error, in 0.5 s."""
    rod = _rod()
    ell, EI, mu = rod.length, E * rod.section.c22, RHO * rod.section.area
    kGA, rhoI = _diagonal(rod)[0], rod.mass_inertias[1]
    uniform = _ritz_frequency(EI, 1e2 * kGA, mu, 1e-2 * rhoI, ell, 0.0, 12)
    assert abs(uniform * ell**2 * math.sqrt(mu / EI) - 1.87510407**2) <= 1e-5 * 1.87510407**2
    taper = 0.5
    reference = _ritz_frequency(EI, kGA, mu, rhoI, ell, taper, 12)
    assert abs(_ritz_frequency(EI, kGA, mu, rhoI, ell, taper, 10) - reference) <= 1e-9 * reference
    law = _tapered_law(rod, taper)
    errors = [
        (_first_bending_frequency(rod, law, n, reference) - reference) / reference
        for n in (8, 16, 32)
    ]
    print(reference, errors)
    assert all(e > 0.0 for e in errors), errors
    assert errors[1] <= errors[0] / 4 and errors[2] <= errors[1] / 4, errors
    assert errors[2] <= 5e-5, errors


@pytest.mark.parametrize(
    ("matrix", "message"),
    [
        (np.eye(5), "must be a 6×6 matrix, got shape (5, 5)"),
        ([[1.0] * 6] * 5 + [[1.0] * 5], "must be a 6×6 matrix of numbers"),
        (np.eye(6) + 1e-9 * np.triu(np.ones((6, 6)), 1), "not symmetric"),
        (np.diag([1.0, 1.0, 1.0, 1.0, 1.0, -1.0]), "not positive definite"),
        (np.ones((6, 6)), "not positive definite"),
        (np.diag([1.0, 1.0, math.nan, 1.0, 1.0, 1.0]), "entries must be finite"),
    ],
)
def test_bad_stiffness_is_one_line_naming_the_key(matrix, message):
    """A matrix that is not 6×6, not symmetric to 1e-12 relative (here 1e-9), not positive
    definite (an eigenvalue −1; the singular all-ones matrix) or not finite: one line that
    starts with the key. A symmetric matrix off by 1e-13 relative passes."""
    with pytest.raises(ValueError) as err:
        check_stiffness(matrix, "rod.section.stiffness")
    text = str(err.value)
    assert text.startswith("rod.section.stiffness: ") and message in text and "\n" not in text
    ok = np.diag([2.0, 2.0, 3.0, 1.0, 1.0, 0.5]) + 1e-13 * np.triu(np.ones((6, 6)), 1)
    assert check_stiffness(ok, "k").shape == (6, 6)


def _diagonal_scene_pair(extra: tuple[str, ...] = ()):
    """The paper's scene (scenes/cao_tucker_2008.toml) and the same with
    rod.section.stiffness = diag(κGA, κGA, EA, E c11, E c22, G c33) of its section."""
    path = Path(__file__).parents[1] / "scenes" / "cao_tucker_2008.toml"
    paper = load_scene(path, list(extra))
    k = _diagonal_of(paper.rod_constants())
    rows = [[k[i] if i == j else 0.0 for j in range(6)] for i in range(6)]
    diag = load_scene(path, [*extra, f"rod.section.stiffness={rows!r}"])
    return paper, diag


def _diagonal_of(rod: RodConstants) -> tuple[float, ...]:
    s = rod.section
    kga = s.shear_coefficient * rod.shear_modulus * s.area
    E_, G_ = rod.young_modulus, rod.shear_modulus
    return (kga, kga, E_ * s.area, E_ * s.c11, E_ * s.c22, G_ * s.c33)


def test_a_diagonal_stiffness_key_is_the_papers_scene():
    """[rod.section] stiffness = the diagonal of (13) in the paper's scene: the model's
    residual (the scene's loads at t = 1 ms, every term) at a random state equals the scene's
    without the key to 1e-12 of its largest entry (round-off of the sums, as above), and a
    short dynamic run (20 steps of sdirk3) gives the same probe to 1e-7 of its largest
    displacement: the residuals differ at round-off, so the Newton iterates do; the bound is
    the solver's stol = 1e-7, what one iteration more or less could change."""
    paper, diag = _diagonal_scene_pair(('discretisation.planar="off"',))
    assert paper.rod_constants().law is None and diag.rod_constants().law is not None
    vectors = []
    for scene in (paper, diag):
        model = build_model(scene, MPI.COMM_SELF, planar=False)
        U, Udot = fem.Function(model.V), fem.Function(model.V)
        rng = np.random.default_rng(11)
        U.x.array[:] = 0.3 * rng.standard_normal(U.x.array.size)
        Udot.x.array[:] = 0.3 * rng.standard_normal(U.x.array.size)
        tau = fem.Constant(model.msh, PETSc.ScalarType(1e-3 * model.omega0))
        model.sync_loads(tau)
        vectors.append(_assemble(model.residual(U, Udot, tau)))
    assert np.abs(vectors[0] - vectors[1]).max() <= 1e-12 * np.abs(vectors[0]).max()
    end = ("time.end=6e-4", "output.xdmf=false", "output.checkpoint=false")
    runs = [run(scene, record=True).probes for scene in _diagonal_scene_pair(end)]
    assert runs[0].shape == runs[1].shape and runs[0].shape[0] >= 2
    scale = np.abs(runs[0][:, 1:4]).max()
    assert scale > 0
    assert np.abs(runs[0][:, 1:] - runs[1][:, 1:]).max() <= 1e-7 * scale


@pytest.mark.parametrize(
    ("value", "message"),
    [
        ("[[1, 0], [0, 1]]", "rod.section.stiffness: must be a 6×6 symmetric positive definite"),
        ('"diag"', "rod.section.stiffness: must be a 6×6"),
        ("[" + ", ".join(["[1, 1, 1, 1, 1, 1]"] * 5 + ["[1, 1, 1]"]) + "]", "stiffness[5]: must"),
        ("[" + ", ".join(["[1, 2, 0, 0, 0, 0]"] * 6) + "]", "not symmetric"),
        ("[" + ", ".join(["[1, 1, 1, 1, 1, 1]"] * 6) + "]", "not positive definite"),
        ("[[1, 0, 0, 0, 0, true]" + ", [0, 1, 0, 0, 0, 0]" * 5 + "]", "stiffness[0][5]: must be"),
        ('[[1, 0, 0, 0, 0, "s"]' + ", [0, 1, 0, 0, 0, 0]" * 5 + "]", "not symmetric: [0][5]"),
    ],
)
def test_a_bad_stiffness_key_is_one_line(value, message):
    """The scene key rod.section.stiffness: not a list of 6 rows of 6 numbers, not symmetric,
    not positive definite: a SceneError of one line naming the key (the command line prints it
    and exits 2, cosserat_fem/cli.py)."""
    path = Path(__file__).parents[1] / "scenes" / "cao_tucker_2008.toml"
    with pytest.raises(SceneError) as err:
        load_scene(path, [f"rod.section.stiffness={value}"])
    text = str(err.value)
    assert message in text and "\n" not in text and text.startswith("rod.section.stiffness")


def test_a_coupled_law_is_never_solved_in_a_plane():
    """The paper's scene with its load in the x-z plane only is solved in that plane; with a
    diagonal stiffness still, with an extension–twist coupling K36 not (an axial force would
    twist the rod out of the plane, which the planar unknowns cannot hold)."""
    inplane = ('loads.force_density=["2e3*sin(pi*s/L)*sin(8*omega0*t)", 0, 0]',)
    paper, diag = _diagonal_scene_pair(inplane)
    assert paper.plane() == diag.plane() == "x-z"
    k = _diagonal_of(paper.rod_constants())
    rows = [[k[i] if i == j else 0.0 for j in range(6)] for i in range(6)]
    rows[2][5] = rows[5][2] = 0.5 * math.sqrt(k[2] * k[5])
    path = Path(__file__).parents[1] / "scenes" / "cao_tucker_2008.toml"
    coupled = load_scene(path, [*inplane, f"rod.section.stiffness={rows!r}"])
    assert coupled.plane() is None


def _tapered_scene(elements: int, extra: tuple[str, ...] = ()):
    """The paper's cantilever (scenes/cao_tucker_2008.toml) with its width tapering linearly
    to half, given by expressions of s: K, μ and I all times (1 − s/(2L))."""
    path = Path(__file__).parents[1] / "scenes" / "cao_tucker_2008.toml"
    rod = load_scene(path).rod_constants()
    k = _diagonal_of(rod)
    taper = "*(1 - 0.5*s/L)"
    rows = [[f"{k[i]!r}{taper}" if i == j else 0.0 for j in range(6)] for i in range(6)]
    mu = rod.density * rod.section.area
    inertia = [f"{i!r}{taper}" for i in rod.mass_inertias]
    sets = [
        f"rod.section.stiffness={rows!r}".replace("'", '"'),
        f'rod.section.mass_per_length="{mu!r}{taper}"',
        f"rod.section.inertia={inertia!r}".replace("'", '"'),
        f"discretisation.elements={elements}",
        *extra,
    ]
    return rod, load_scene(path, sets)


def test_a_tapered_scene_by_expressions_of_s():
    """[rod.section] stiffness, mass_per_length and inertia as expressions of s: the paper's
    cantilever tapered to half its width (EI, κGA, μ, ρI ∝ 1 − s/(2L)); its first bending
    mode about d2 (``modes``, the scene's P3 elements) against Timoshenko's Rayleigh–Ritz
    (:func:`_ritz_frequency`, 12 terms, converged to 1e-9): on 4 and 8 cells the error must
    be positive (a displacement method) and fall by ≥ 8 (P3: order ≥ 3), below 1e-5 on 8."""
    errors = []
    for elements in (4, 8):
        rod, scene = _tapered_scene(elements)
        E_, mu = rod.young_modulus, rod.density * rod.section.area
        kGA = _diagonal_of(rod)[0]
        reference = _ritz_frequency(
            E_ * rod.section.c22, kGA, mu, rod.mass_inertias[1], rod.length, 0.5, 12
        )
        found = [m.omega for m in modes(scene, count=4) if m.kind == "bending-x"]
        errors.append((found[0] - reference) / reference)
    print(errors)
    assert all(e > 0.0 for e in errors), errors
    assert errors[1] <= errors[0] / 8 and errors[1] <= 1e-5, errors


def _law_sets(rows, *extra: str) -> list[str]:
    return [f"rod.section.stiffness={rows!r}".replace("'", '"'), *extra]


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ((0, 0, "1e8*(1 - 2*s/L)"), "rod.section.stiffness: not positive definite at s = 0.5 m"),
        ((0, 0, "1e8*(1 + q*s)"), "rod.section.stiffness[0][0]: "),
        ((0, 0, "1e8*log(0.5 - s/L)"), "rod.section.stiffness[0][0]: must be finite"),
        ((2, 5, "1e3*s"), "rod.section.stiffness: not symmetric: [2][5] = "),
    ],
)
def test_a_bad_law_along_s_is_one_line(change, message):
    """A law by expressions of s checked at 401 stations along the rod: not positive definite
    past s = L/2 (the first station where K11 ≤ 0 is s = 0.5 m on the 1 m rod), an unknown
    name, not finite (log of a negative number past L/2), an entry not mirrored: one line
    naming the key (and the station)."""
    path = Path(__file__).parents[1] / "scenes" / "cao_tucker_2008.toml"
    rows: list[list] = [[1e8 if i == j else 0.0 for j in range(6)] for i in range(6)]
    i, j, value = change
    rows[i][j] = value
    with pytest.raises(SceneError) as err:
        load_scene(path, _law_sets(rows))
    text = str(err.value)
    assert text.startswith(message) and "\n" not in text, text


@pytest.mark.parametrize(
    ("sets", "message"),
    [
        (['rod.section.mass_per_length="6.5*(1 - 2*s/L)"'], "rod.section.mass_per_length: must"),
        (["rod.section.inertia=[1, 1, -1]"], "rod.section.inertia[2]: must be > 0"),
        (["rod.rotary_inertia=[1, 1, 1]", "rod.section.inertia=[1, 1, 1]"], "give the inertias"),
    ],
)
def test_a_bad_mass_along_s_is_one_line(sets, message):
    """μ ≤ 0 past L/2, a negative inertia, the inertias given twice: one line naming the key;
    and μ without a stiffness: refused (μ and I belong to the 6×6 law)."""
    path = Path(__file__).parents[1] / "scenes" / "cao_tucker_2008.toml"
    rows = [[1e8 if i == j else 0.0 for j in range(6)] for i in range(6)]
    with pytest.raises(SceneError) as err:
        load_scene(path, _law_sets(rows, *sets))
    assert message in str(err.value) and "\n" not in str(err.value), str(err.value)
    with pytest.raises(SceneError, match=r"^rod.section.mass_per_length: only with"):
        load_scene(path, ["rod.section.mass_per_length=6.5"])


def test_gravity_weighs_the_laws_mass_per_length():
    """[loads] gravity on a rod with a general law whose mass_per_length μ is twice the
    shape's ρ A (the paper's section, its diagonal law): the weight μ g, not ρ A g (before:
    the shape's, half of it; found reading BeamDyn's blades, whose μ is the law's). Gravity
    0.01 m/s² across the cantilever: the static tip deflection against the linear Timoshenko
    beam's q L⁴/(8 EI) + q L²/(2 κGA), q = μ g. Measured 4e-13 relative at the 8 cubic cells:
    the element is exact at its nodes for this load (as the Timoshenko element is for
    polynomial loads of its degree or less), so what remains is the geometric nonlinearity,
    (w/L)² ~ 1e-12, and Newton's last correction; 1e-9 bounds both. ρ A g would be 50% off."""
    paper, diag = _diagonal_scene_pair()
    rod = paper.rod_constants()
    mu = 2.0 * rod.density * rod.section.area
    path = Path(__file__).parents[1] / "scenes" / "cao_tucker_2008.toml"
    k = _diagonal_of(rod)
    rows = [[k[i] if i == j else 0.0 for j in range(6)] for i in range(6)]
    settings = [
        f"rod.section.stiffness={rows!r}",
        f"rod.section.mass_per_length={mu!r}",
        "loads.force_density=[0, 0, 0]",
        "loads.gravity=[0.01, 0, 0]",
    ]
    from cosserat_fem.api import static

    tip = float(static(load_scene(path, settings)).probes[-1, 1])
    q, L = mu * 0.01, rod.length
    expected = q * L**4 / (8 * k[4]) + q * L**2 / (2 * k[0])
    assert tip == pytest.approx(expected, rel=1e-9)
