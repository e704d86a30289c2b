"""Checks of the second-order (axial z, twist φ) cantilever reference (no DOLFINx needed):
its torsion constant against published values and the solver's series, its pieces against
closed forms, and its paper-case solution against an independent method of lines.

Rod of Cao & Tucker (2008), section 6: ℓ = 1 m, a = 0.04 m, b = 0.06 m, E = 7.1e10 Pa,
ν = 0.32, κ = 0.833, ρ = 2730 kg/m³, f_x = f_y = 2e3 sin(πs) sin(8 ω0 t) N/m from rest.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.linalg as sl
from cosserat_fem.forms.section import rectangle_torsion_constant as solver_torsion_constant
from scipy.signal import lfilter
from scipy.special import zeta

from cosserat_fem.reference.second_order import (
    PAPER_OMEGA,
    PAPER_Q0,
    PAPER_ROD,
    RodData,
    axial_force_second_order,
    second_order_response,
    second_order_tip_response,
    static_axial_displacement,
    static_twist,
    torsion_forcing_second_order,
)
from cosserat_fem.reference.timoshenko import modal_loads, mode_shapes, static_deflection_sine_load
from cosserat_fem.reference.torsion import rectangle_torsion_constant, torsion_constant_bound

ROD = PAPER_ROD
EA = ROD.young * ROD.area
KGA = ROD.kappa * ROD.shear * ROD.area
T_PAPER = np.linspace(0.0, 0.06, 1501)


@pytest.fixture(scope="module")
def paper() -> dict[str, np.ndarray]:
    """The paper's case with the default truncation."""
    return {"coarse": second_order_response(ROD, PAPER_Q0, PAPER_OMEGA, T_PAPER)}


def _rel(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.linalg.norm(a - b) / np.linalg.norm(b))


# --------------------------------------------------------------------------------------------
# Section data
# --------------------------------------------------------------------------------------------
#: k of J = k b a³ (a the shorter side) for b/a = 1, 1.5, 2, 10, as published to four digits
#: (Timoshenko & Goodier, Theory of Elasticity, §109, tabulate 0.141, 0.196, 0.229, 0.312).
PUBLISHED_K = {1.0: 0.1406, 1.5: 0.1958, 2.0: 0.2287, 10.0: 0.3123}


@pytest.mark.parametrize("ratio", list(PUBLISHED_K))
def test_torsion_constant_against_published_values_and_the_solvers_series(ratio):
    """The references' c33 (cosserat_fem/reference/torsion.py: the double Fourier series of
    Prandtl's stress function, summed directly) is their own, not the solver's:

    * against the published k: within 5e-5, half a unit of the fourth digit given (measured
      0.140577, 0.195761, 0.228682, 0.312325);
    * against the solver's Saint-Venant single series in tanh (forms/section.py, summed to
      rounding): the double series truncated at m, n ≤ M falls short of J by a remainder
      0 ≤ T ≤ (a² + b²) π²/(48 M³) (torsion_constant_bound, 1.3e-11 to 3.3e-10 relative
      here), so the two must agree to that bound and the double series must be the smaller
      (measured 0.9 of the bound: it is nearly sharp). Both orders of the sides give the same J.
    """
    a, b = 1.0, ratio
    J = rectangle_torsion_constant(a, b)
    assert J / (b * a**3) == pytest.approx(PUBLISHED_K[ratio], abs=5e-5)
    series = solver_torsion_constant(b, a, "series")
    bound = torsion_constant_bound(a, b)
    assert bound < 1e-9
    assert -1e-15 <= 1.0 - J / series <= bound + 1e-15, (1.0 - J / series, bound)
    assert rectangle_torsion_constant(b, a) == pytest.approx(J, rel=1e-14)


def test_torsion_constant_of_the_paper_and_thin_strips():
    """The paper's 0.04 m × 0.06 m section: within 5e-3 of the approximate formula
    W H³/3 (1 − 0.63 (H/W)(1 − H⁴/(12 W⁴))) (good to ~0.5 % at W/H = 1.5) and below the polar
    moment c11 + c22. Thin strips, W/H = 10 and 100: Saint-Venant's series with tanh = 1 (its
    error is O(e^(−π W/H)), below 1e-13 here) sums in closed form to
    W H³/3 (1 − (192/π⁵)(31/32) ζ(5) H/W), which the double series must meet within its
    truncation bound (3.3e-10 and 3.2e-8; measured 0.8 of it)."""
    w, h = 0.06, 0.04
    approx = w * h**3 / 3 * (1 - 0.63 * h / w * (1 - h**4 / (12 * w**4)))
    assert ROD.c33 == pytest.approx(approx, rel=5e-3)
    assert ROD.c33 < ROD.c11 + ROD.c22
    assert ROD.c33 == rectangle_torsion_constant(ROD.a, ROD.b)  # the reference's own
    for ratio in (10.0, 100.0):
        strip = ratio / 3 * (1 - 192 / math.pi**5 * 31 / 32 * zeta(5) / ratio)
        J = rectangle_torsion_constant(1.0, ratio)
        assert 0.0 <= 1.0 - J / strip <= torsion_constant_bound(1.0, ratio), ratio


# --------------------------------------------------------------------------------------------
# Quadratic forcing on given fields
# --------------------------------------------------------------------------------------------
def test_static_euler_bernoulli_limit_tip_moves_inwards():
    """x' = ψ (no shear) and N = 0 give z' = −ψ²/2: the tip moves towards the clamp."""
    EI = ROD.young * ROD.c22
    P, ell = 5e3, ROD.length
    psi = lambda s: P * s * (2 * ell - s) / (2 * EI)  # noqa: E731 - EB tip-load rotation

    def n2(s):
        return axial_force_second_order(ROD, dx=psi(s), psi=psi(s))

    s = np.linspace(0.0, ell, 7)
    assert np.allclose(n2(s), 0.5 * EA * psi(s) ** 2, rtol=1e-14)
    z = static_axial_displacement(ROD, s, n2)
    assert z[0] == 0.0 and np.all(np.diff(z) < 0.0)
    # z(ℓ) = −½∫ψ² = −P²ℓ⁵/(15 E²I²), the classical foreshortening of a cantilever.
    assert z[-1] == pytest.approx(-(P**2) * ell**5 / (15 * EI**2), rel=1e-13)
    assert z[-1] < 0.0
    # Same in the y-plane (β = y'); planes add.
    EI1 = ROD.young * ROD.c11
    beta = lambda s: P * s * (2 * ell - s) / (2 * EI1)  # noqa: E731
    zy = static_axial_displacement(
        ROD, ell, lambda s: axial_force_second_order(ROD, psi(s), psi(s), beta(s), beta(s))
    )
    assert zy == pytest.approx(-(P**2) * ell**5 / 15 * (1 / EI**2 + 1 / EI1**2), rel=1e-13)


def test_static_timoshenko_end_force_matches_exact_kinematics():
    """End force P e1: n = P e1, so n·e3 = 0 exactly. Expanding v1 = P cosψ/κGA,
    v3 − 1 = P sinψ/EA and z' + 1 = v1 d13 + v3 d33 gives z' = −ψ²/2 − (1 − κG/E) ψ γ with
    γ = P/κGA: an independent check of N2's shear terms."""
    EI = ROD.young * ROD.c22
    P, ell = 5e3, ROD.length
    gam = P / KGA
    psi = lambda s: P * s * (2 * ell - s) / (2 * EI)  # noqa: E731
    s = np.linspace(0.0, ell, 5)
    n2 = axial_force_second_order(ROD, dx=psi(s) + gam, psi=psi(s))
    dz_exact = -0.5 * psi(s) ** 2 - (1 - ROD.kappa * ROD.shear / ROD.young) * psi(s) * gam
    assert np.allclose(-n2 / EA, dz_exact, rtol=1e-13, atol=0.0)


def test_static_twist_constant_curvatures():
    """Uniform curvatures ψ' = k2, θ' = k1 (β' = −k1): φ' = ψ'θ + T/(Gc33),
    T(s) = E(c22 − c11) k1 k2 (ℓ − s)."""
    k1, k2, ell = 2e-3, 3e-3, ROD.length
    Gc33 = ROD.shear * ROD.c33
    dc = ROD.c22 - ROD.c11

    def forcing(s):
        return torsion_forcing_second_order(ROD, dpsi=k2 + 0 * s, beta=-k1 * s, dbeta=-k1 + 0 * s)

    s = np.array([0.0, 0.3, ell])
    phi = static_twist(ROD, s, lambda x: forcing(x)[0], lambda x: forcing(x)[1])
    exact = k1 * k2 * s**2 / 2 + ROD.young * dc * k1 * k2 * (ell * s - s**2 / 2) / Gc33
    assert np.allclose(phi, exact, rtol=1e-13, atol=0.0)


# --------------------------------------------------------------------------------------------
# Modal solution
# --------------------------------------------------------------------------------------------
def test_quasi_static_limit_matches_static_fields():
    """For Ω ≪ ω1 the response at sin Ωt = 1 is the static solution driven by the exact static
    Timoshenko fields of the sine load (closed form, no modes): checks the modal quadratic forms,
    the Galerkin solution and the static correction end to end."""
    ell, q = ROD.length, 3e3
    k = math.pi / ell
    bx, by = ROD.beam_x, ROD.beam_y

    def fields(beam, s):
        _, rot = static_deflection_sine_load(beam, q, s)
        V = q / k * (1 + np.cos(k * s))
        M = q / k * (ell - s - np.sin(k * s) / k)
        return rot + V / beam.kGA, rot, M / beam.EI  # w', rotation, rotation'

    def n2(s):
        dx, psi, _ = fields(bx, s)
        dy, beta, _ = fields(by, s)
        return axial_force_second_order(ROD, dx, psi, dy, beta)

    def forcing(s):
        _, _, dpsi = fields(bx, s)
        _, beta, dbeta = fields(by, s)
        return torsion_forcing_second_order(ROD, dpsi=dpsi, beta=beta, dbeta=dbeta)

    z_st = static_axial_displacement(ROD, ell, n2)
    phi_st = static_twist(ROD, ell, lambda s: forcing(s)[0], lambda s: forcing(s)[1])
    assert z_st < 0.0

    Omega = 1e-4 * 207.0
    t = np.array([0.5 * math.pi / Omega])
    z, phi = second_order_tip_response(ROD, q, Omega, t, linear_modes=12, axial_modes=12)
    # Residual dynamics: free-vibration parts of η of relative size Ω/ω ~ 1e-4.
    assert z[0] == pytest.approx(float(z_st), rel=1e-3)
    assert phi[0] == pytest.approx(float(phi_st), rel=1e-3)


@pytest.mark.long
def test_closed_form_matches_dop853():
    """The exact-in-time modal solution equals a DOP853 integration of the same modal ODEs
    (forcing evaluated directly from η, η', η'' rather than by product-to-sum expansion)."""
    t = np.linspace(0.0, 0.004, 81)
    kw = dict(linear_modes=4, axial_modes=3, static_correction=False)
    a = second_order_response(ROD, PAPER_Q0, PAPER_OMEGA, t, **kw)
    b = second_order_response(ROD, PAPER_Q0, PAPER_OMEGA, t, method="ode", rtol=1e-11, **kw)
    assert np.max(np.abs(a.z - b.z)) < 1e-9 * np.max(np.abs(b.z))
    assert np.max(np.abs(a.phi - b.phi)) < 1e-9 * np.max(np.abs(b.phi))


@pytest.mark.long
def test_convergence_in_truncation(paper):
    """Default truncation (16 linear modes per plane, K = 16) vs (20, 24): < 1e-4 relative."""
    c = paper["coarse"]
    f = second_order_response(ROD, PAPER_Q0, PAPER_OMEGA, T_PAPER, linear_modes=20, axial_modes=24)
    assert _rel(c.z, f.z) < 1e-4
    assert _rel(c.phi, f.phi) < 1e-4
    small = second_order_response(
        ROD, PAPER_Q0, PAPER_OMEGA, T_PAPER, linear_modes=10, axial_modes=10
    )
    assert _rel(small.z, f.z) < 1e-4
    assert _rel(small.phi, f.phi) < 1e-4
    # Without the static correction the axial sum converges only like 1/K (N2(ℓ) ≠ 0).
    plain = second_order_response(
        ROD,
        PAPER_Q0,
        PAPER_OMEGA,
        T_PAPER,
        linear_modes=10,
        axial_modes=10,
        static_correction=False,
    )
    assert _rel(plain.z, f.z) > 1e-2


def test_quadratic_scaling():
    t = np.linspace(0.0, 0.01, 51)
    kw = dict(linear_modes=6, axial_modes=6)
    z1, p1 = second_order_tip_response(ROD, 1e3, PAPER_OMEGA, t, **kw)
    z2, p2 = second_order_tip_response(ROD, 2e3, PAPER_OMEGA, t, **kw)
    assert np.allclose(z2, 4 * z1, rtol=1e-12, atol=1e-14 * np.abs(z2).max())
    assert np.allclose(p2, 4 * p1, rtol=1e-12, atol=1e-14 * np.abs(p2).max())
    # z adds plane by plane; φ is bilinear in (q_x, q_y).
    zx, px = second_order_tip_response(ROD, (2e3, 0.0), PAPER_OMEGA, t, **kw)
    zy, py = second_order_tip_response(ROD, (0.0, 2e3), PAPER_OMEGA, t, **kw)
    zxy, pxy = second_order_tip_response(ROD, (2e3, -1e3), PAPER_OMEGA, t, **kw)
    assert np.allclose(zx + zy, z2, rtol=1e-12, atol=1e-14 * np.abs(z2).max())
    assert np.all(px == 0.0) and np.all(py == 0.0)
    assert np.allclose(pxy, -0.5 * p2, rtol=1e-12, atol=1e-14 * np.abs(p2).max())


def test_fields_along_s():
    """z and φ along s: zero at the clamp, zero at rest, and at s = ℓ the tip response of
    second_order_tip_response. Both sum the same modal terms, in other orders: they agree to
    the round-off of terms as large as the motion, ~1e-16 of the largest value, where the sum
    cancels (z(ℓ, 0) = 3e-22 and -2e-22 m on two machines' cosines); allowed 1e-12 relative
    and 1e-12 of the largest value."""
    t = np.linspace(0.0, 0.01, 41)
    s = np.array([0.0, 0.25, 0.5, 1.0])
    kw = dict(linear_modes=8, axial_modes=8)
    r = second_order_response(ROD, PAPER_Q0, PAPER_OMEGA, t, s=s, **kw)
    assert r.z.shape == (41, 4)
    assert np.all(r.z[:, 0] == 0.0) and np.all(r.phi[:, 0] == 0.0)
    # From rest (up to rounding in the cancelling sums of cosines at t = 0).
    assert np.all(np.abs(r.z[0]) < 1e-12 * np.abs(r.z).max())
    assert np.all(np.abs(r.phi[0]) < 1e-12 * np.abs(r.phi).max())
    z_tip, phi_tip = second_order_tip_response(ROD, PAPER_Q0, PAPER_OMEGA, t, **kw)
    assert np.allclose(r.z[:, -1], z_tip, rtol=1e-12, atol=1e-12 * np.abs(r.z).max())
    assert np.allclose(r.phi[:, -1], phi_tip, rtol=1e-12, atol=1e-12 * np.abs(r.phi).max())


def test_printed_torsion_inertia_changes_phi_only(paper):
    """I33 = ρ c33 (eq. (54) as printed) instead of ρ (c11 + c22): φ changes by ~34 % (L2)."""
    polar = paper["coarse"]
    printed = second_order_response(ROD, PAPER_Q0, PAPER_OMEGA, T_PAPER, torsion_inertia="printed")
    assert np.array_equal(printed.z, polar.z)
    change = _rel(printed.phi, polar.phi)
    print(
        f"\nprinted vs polar torsion inertia: relative L2 change of phi = {change:.3f}, "
        f"max |dphi| = {np.abs(printed.phi - polar.phi).max():.3e} rad; printed phi in "
        f"[{printed.phi.min():.3e}, {printed.phi.max():.3e}]"
    )
    assert 0.2 < change < 0.5
    with pytest.raises(ValueError):
        second_order_response(ROD, PAPER_Q0, PAPER_OMEGA, T_PAPER[:3], torsion_inertia="x")


# --------------------------------------------------------------------------------------------
# An independent solution of the same second-order equations: the method of lines
# --------------------------------------------------------------------------------------------
def _p2_line(length: float, elements: int, gauss: int = 4):
    """P2 Lagrange elements on [0, ℓ]: Gauss points, weights, and the basis functions and
    their s-derivatives at the points (points × nodes)."""
    x, w = np.polynomial.legendre.leggauss(gauss)
    h, xi = length / elements, 0.5 * (x + 1.0)
    shape = np.stack([2 * (xi - 0.5) * (xi - 1), -4 * xi * (xi - 1), 2 * xi * (xi - 0.5)], 1)
    slope = np.stack([4 * xi - 3, 4 - 8 * xi, 4 * xi - 1], axis=1) / h
    N = np.zeros((elements * gauss, 2 * elements + 1))
    dN = np.zeros_like(N)
    for e in range(elements):
        rows = slice(e * gauss, (e + 1) * gauss)
        N[rows, 2 * e : 2 * e + 3], dN[rows, 2 * e : 2 * e + 3] = shape, slope
    points = (np.arange(elements)[:, None] + xi[None, :]).ravel() * h
    return points, np.tile(0.5 * h * w, elements), N, dN


def _trapezoidal(omega: float, dt: float, load: np.ndarray) -> np.ndarray:
    """q'' + ω² q = f from rest by the trapezoidal rule (the bilinear map of 1/(s² + ω²)),
    f sampled at t_n = n Δt."""
    c = 0.25 * dt * dt
    den = np.array([1 + c * omega**2, -2 + 2 * c * omega**2, 1 + c * omega**2])
    return lfilter(c * np.array([1.0, 2.0, 1.0]), den, load)


def method_of_lines(rod: RodData, q0: float, Omega: float, end: float, dt: float, elements: int):
    """(t, z(ℓ,t), φ(ℓ,t)) of the module's axial and torsion equations solved another way: the
    weak forms ∫ ρA z_tt v + (EA z' + N2) v' = 0 and ∫ ρJ φ_tt v + G c33 (φ' − ψ'θ) v' − f v = 0
    on P2 elements (z = φ = 0 at s = 0; the free end natural), the sources N2, ψ'θ and f taken
    pointwise at the Gauss points from the same 16 linear Timoshenko modes per plane (η from
    rest in closed form), and the trapezoidal rule in time (each eigenvector of the discrete
    pencil stepped by :func:`_trapezoidal`: the same scheme, uncoupled). No sine modes, no
    quasi-static correction, no product-to-sum expansion."""
    t = np.arange(0.0, end + 0.5 * dt, dt)
    points, weights, N, dN = _p2_line(rod.length, elements)
    N, dN = N[:, 1:], dN[:, 1:]  # the clamped node removed
    mass, stiff = N.T @ (weights[:, None] * N), dN.T @ (weights[:, None] * dN)
    planes = []
    for beam in (rod.beam_x, rod.beam_y):
        modes = mode_shapes(beam, 16)
        om = np.array([m.omega for m in modes])
        A = modal_loads(beam, q0, None, modes) / (om**2 - Omega**2)
        B = -(Omega / om) * A
        sin_f, sin_m = np.sin(Omega * t)[:, None], np.sin(np.outer(t, om))
        eta = A * sin_f + B * sin_m
        rate = A * Omega * np.cos(Omega * t)[:, None] + B * om * np.cos(np.outer(t, om))
        acceleration = -A * Omega**2 * sin_f - B * om**2 * sin_m
        shapes = (
            np.array([m.W(points, 1) for m in modes]),
            np.array([m.Psi(points) for m in modes]),
            np.array([m.Psi(points, 1) for m in modes]),
        )
        planes.append((eta, rate, acceleration, shapes))
    (ex, rx, ax, (dWx, Px, dPx)), (ey, ry, _, (dWy, Py, dPy)) = planes
    Gc33, J = rod.shear * rod.c33, rod.torsion_inertia("polar")
    tips = []
    for m_coef, k_coef in ((rod.density * rod.area, rod.young * rod.area), (rod.density * J, Gc33)):
        lam, vec = sl.eigh(k_coef * stiff, m_coef * mass)
        loads = np.empty((t.size, lam.size))
        for start in range(0, t.size, 2000):
            rows = slice(start, start + 2000)
            psi, beta = ex[rows] @ Px, ey[rows] @ Py
            if not tips:  # axial: −∫ N2 v'
                n2 = axial_force_second_order(rod, ex[rows] @ dWx, psi, ey[rows] @ dWy, beta)
                F = -(n2 * weights) @ dN
            else:  # torsion: ∫ G c33 ψ'θ v' + f v
                pre, f = torsion_forcing_second_order(
                    rod,
                    ex[rows] @ dPx,
                    beta,
                    ey[rows] @ dPy,
                    rx[rows] @ Px,
                    ax[rows] @ Px,
                    ry[rows] @ Py,
                )
                F = (Gc33 * pre * weights) @ dN + (f * weights) @ N
            loads[rows] = F @ vec
        q = np.column_stack([_trapezoidal(w, dt, loads[:, k]) for k, w in enumerate(np.sqrt(lam))])
        tips.append(q @ vec[-1])  # the last node is the free end
    return t, tips[0], tips[1]


def test_paper_case_against_the_method_of_lines(paper):
    """0 ≤ t ≤ 0.06 s, the paper's case. The modal closed form (sine modes with the
    quasi-static correction, exact in time) against :func:`method_of_lines` (P2 × 16, the
    trapezoidal rule at Δt = 4 and 2 μs), which shares only the pointwise source formulas
    (checked on their own above) and the linear Timoshenko modes.

    The method of lines errs by the trapezoidal rule's phase error, (ωΔt)²/12 a radian: second
    order, so its difference from the closed form must fall 4x per halving of Δt (measured
    3.90 for z, 4.02 for φ; required 4 ± 0.3, which the closed form being wrong at the 1e-5
    level would break), and the Richardson extrapolation (4 u(Δt/2) − u(Δt))/3 removes it,
    leaving O(Δt⁴), P2 × 16's spatial error (4e-7 in φ: 32 elements change it by that) and
    the closed form's own truncation (16 linear, 16 axial and torsional modes: ~1e-6). The
    extrapolated histories must agree with the closed form within 5e-6 (relative L2; measured
    9.8e-7 for z, 1.2e-6 for φ), and so must the extremes (measured 7.0e-7, 8e-8, 4.7e-7):
    z(ℓ,t) ∈ [−4.137e-6, 0] m, never outwards (the quasi-static foreshortening dominates;
    the paper's Fig. 4, indicative only, shows about [−6e-6, 2e-6] m) and
    φ(ℓ,t) ∈ [−4.506e-5, 2.383e-5] rad (Fig. 4: about [−4e-5, 2e-5] rad), the figures the
    docs quote, held here to their rounding. Compared at the 1501 times of the fixture; ~0.5 s."""
    t, z1, p1 = method_of_lines(ROD, PAPER_Q0, PAPER_OMEGA, 0.06, 4e-6, 16)
    _, z2, p2 = method_of_lines(ROD, PAPER_Q0, PAPER_OMEGA, 0.06, 2e-6, 16)
    # Compared on the fixture's 1501 times, every 10th step at 4 μs and 20th at 2 μs.
    z1, p1, z2, p2 = z1[::10], p1[::10], z2[::20], p2[::20]
    assert np.allclose(t[::10], T_PAPER, rtol=0.0, atol=1e-15)
    r = paper["coarse"]  # the default truncation
    for coarse, fine, ref in ((z1, z2, r.z), (p1, p2, r.phi)):
        ratio = _rel(coarse, ref) / _rel(fine, ref)
        assert ratio == pytest.approx(4.0, abs=0.3), ratio
        extrapolated = (4.0 * fine - coarse) / 3.0
        assert _rel(extrapolated, ref) < 5e-6, _rel(extrapolated, ref)
        assert ref.min() == pytest.approx(extrapolated.min(), rel=5e-6)
        assert ref.max() == pytest.approx(extrapolated.max(), rel=5e-6, abs=5e-6 * abs(ref.min()))
    # The figures the docs quote, to their rounding (their value is held by the method of
    # lines above, not by these lines).
    quoted = "the quoted extreme, rounded; the method of lines holds its value"
    assert r.z.min() == pytest.approx(-4.137e-6, rel=2e-4), quoted
    assert r.z.max() < 1e-6 * abs(r.z.min())
    assert r.phi.min() == pytest.approx(-4.506e-5, rel=2e-4), quoted
    assert r.phi.max() == pytest.approx(2.383e-5, rel=2e-4), quoted


def test_resonance_rejected():
    omega1 = second_order_response(ROD, 1.0, 1.0, [0.0], linear_modes=2, axial_modes=2).omega_x[0]
    with pytest.raises(ValueError, match="resonance"):
        second_order_response(ROD, 1.0, omega1, [0.0], linear_modes=2, axial_modes=2)
