"""Self-checks of the second-order (axial z, twist φ) cantilever reference (no DOLFINx needed).

Rod of Cao & Tucker (2008), section 6: ℓ = 1 m, a = 0.04 m, b = 0.06 m, E = 7.1e10 Pa,
ν = 0.32, κ = 0.833, ρ = 2730 kg/m³, f_x = f_y = 2e3 sin(πs) sin(8 ω0 t) N/m from rest.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from cosserat_fem.reference.second_order import (
    PAPER_OMEGA,
    PAPER_Q0,
    PAPER_ROD,
    axial_force_second_order,
    rectangle_torsion_constant,
    second_order_response,
    second_order_tip_response,
    static_axial_displacement,
    static_twist,
    torsion_forcing_second_order,
)
from cosserat_fem.reference.timoshenko import static_deflection_sine_load

ROD = PAPER_ROD
EA = ROD.young * ROD.area
KGA = ROD.kappa * ROD.shear * ROD.area
T_PAPER = np.linspace(0.0, 0.06, 1501)


@pytest.fixture(scope="module")
def paper() -> dict[str, np.ndarray]:
    """The paper's case with the default truncation and a much finer one."""
    coarse = second_order_response(ROD, PAPER_Q0, PAPER_OMEGA, T_PAPER)
    fine = second_order_response(
        ROD, PAPER_Q0, PAPER_OMEGA, T_PAPER, linear_modes=20, axial_modes=24
    )
    return {"coarse": coarse, "fine": fine}


def _rel(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.linalg.norm(a - b) / np.linalg.norm(b))


# --------------------------------------------------------------------------------------------
# Section data
# --------------------------------------------------------------------------------------------
def test_torsion_constant():
    # Square: c33 = 0.1406 a^4 (classical table value 2.25 a^4 / 16); very thin strip: W H^3/3.
    assert rectangle_torsion_constant(1.0, 1.0) == pytest.approx(0.140577, rel=1e-5)
    assert rectangle_torsion_constant(1e3, 1.0) == pytest.approx(1e3 / 3 * (1 - 0.630 / 1e3), 1e-4)
    # Paper: lies between the approximate formula's neighbourhood and below the polar moment.
    w, h = 0.06, 0.04
    approx = w * h**3 / 3 * (1 - 0.63 * h / w * (1 - h**4 / (12 * w**4)))
    assert ROD.c33 == pytest.approx(approx, rel=5e-3)
    assert ROD.c33 < ROD.c11 + ROD.c22


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


def test_closed_form_matches_dop853():
    """The exact-in-time modal solution equals a DOP853 integration of the same modal ODEs
    (forcing evaluated directly from η, η', η'' rather than by product-to-sum expansion)."""
    t = np.linspace(0.0, 0.004, 81)
    kw = dict(linear_modes=4, axial_modes=3, static_correction=False)
    a = second_order_response(ROD, PAPER_Q0, PAPER_OMEGA, t, **kw)
    b = second_order_response(ROD, PAPER_Q0, PAPER_OMEGA, t, method="ode", rtol=1e-11, **kw)
    assert np.max(np.abs(a.z - b.z)) < 1e-9 * np.max(np.abs(b.z))
    assert np.max(np.abs(a.phi - b.phi)) < 1e-9 * np.max(np.abs(b.phi))


def test_convergence_in_truncation(paper):
    """Default truncation (16 linear modes per plane, K = 16) vs (20, 24): < 1e-4 relative."""
    c, f = paper["coarse"], paper["fine"]
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
    assert np.allclose(r.z[:, -1], z_tip, rtol=1e-12, atol=1e-22)
    assert np.allclose(r.phi[:, -1], phi_tip, rtol=1e-12, atol=1e-20)


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


def test_paper_case_extremes(paper):
    """0 ≤ t ≤ 0.06 s. Paper's Fig. 4 (indicative only): z(1,t) in about [−6e-6, 2e-6] m,
    φ(1,t) in about [−4e-5, 2e-5] rad. Second-order theory: z in [−4.14e-6, 0] m (the tip
    never moves outwards: the response is dominated by the quasi-static foreshortening),
    φ in [−4.51e-5, 2.38e-5] rad."""
    r = paper["fine"]
    print(
        f"\nz(l,t) in [{r.z.min():.4e}, {r.z.max():.4e}] m, "
        f"phi(l,t) in [{r.phi.min():.4e}, {r.phi.max():.4e}] rad"
    )
    assert r.z.min() == pytest.approx(-4.137e-6, rel=2e-3)
    assert r.z.max() < 1e-6 * abs(r.z.min())
    assert r.phi.min() == pytest.approx(-4.506e-5, rel=2e-3)
    assert r.phi.max() == pytest.approx(2.383e-5, rel=2e-3)


def test_resonance_rejected():
    omega1 = second_order_response(ROD, 1.0, 1.0, [0.0], linear_modes=2, axial_modes=2).omega_x[0]
    with pytest.raises(ValueError, match="resonance"):
        second_order_response(ROD, 1.0, omega1, [0.0], linear_modes=2, axial_modes=2)
