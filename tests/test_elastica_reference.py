"""Self-checks of the large-deflection cantilever references (no DOLFINx needed).

Euler's elastica under a dead tip force (closed form vs collocation, Mattiasson's 1981 table,
small-load expansion) and the extensible, shearable Reissner rod (elastica limit, linear
Timoshenko limit, circular arc under a pure end moment, equilibrium of the returned fields).
"""

from __future__ import annotations

import math
from functools import cache

import numpy as np
import pytest

from cosserat_fem.reference.elastica import (
    ELASTICA_TIP_TABLE,
    MATTIASSON_1981,
    MATTIASSON_ALPHAS,
    ElasticaSolution,
    ReissnerSolution,
    elastica_tip_load,
    reissner_tip_load,
    small_load_expansion,
)
from cosserat_fem.reference.timoshenko import TimoshenkoBeam, tip_deflection_end_force

ALPHAS = (0.5, 1.0, 2.0, 5.0, 10.0, 20.0)

# Cao & Tucker (2008) rod, x-plane: a = 0.04 m (bending direction) by b = 0.06 m.
CAO_TUCKER = TimoshenkoBeam.rectangular(1.0, 0.04, 0.06, 7.1e10, 0.32, 0.833, 2730.0)
EA_CT = CAO_TUCKER.young * CAO_TUCKER.area
# A stubby, soft rod on which shear and extension are O(1) effects: ℓ = 1.5 m, EI = 2 N m².
STUBBY = {"length": 1.5, "EA": 40.0, "GAk": 15.0, "EI": 2.0}


@cache
def _elastica(alpha: float, method: str) -> ElasticaSolution:
    return elastica_tip_load(alpha, method)  # type: ignore[arg-type]


def _d1(fun, s, h):
    """4th-order central first derivative."""
    return (-fun(s + 2 * h) + 8 * fun(s + h) - 8 * fun(s - h) + fun(s - 2 * h)) / (12 * h)


def _d2(fun, s, h):
    """4th-order central second derivative."""
    return (-fun(s + 2 * h) + 16 * fun(s + h) - 30 * fun(s) + 16 * fun(s - h) - fun(s - 2 * h)) / (
        12 * h * h
    )


# --------------------------------------------------------------------------------------------
# Elastica
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("alpha", ALPHAS)
def test_elliptic_and_collocation_agree(alpha: float) -> None:
    ell = _elastica(alpha, "elliptic")
    bvp = _elastica(alpha, "bvp")
    assert bvp.tol <= 1e-11
    for a, b in zip(ell.tip, bvp.tip, strict=True):
        assert abs(a - b) < 1e-9
    s = np.linspace(0.0, 1.0, 401)
    np.testing.assert_allclose(ell.fields(s), bvp.fields(s), rtol=0.0, atol=1e-9)
    # Stored stations are consistent with the callables, and the tip with the fields.
    np.testing.assert_allclose(ell.psi(ell.s), ell.psi_values, rtol=0, atol=1e-15)
    np.testing.assert_allclose(bvp.x(bvp.s), bvp.x_values, rtol=0, atol=1e-15)
    assert ell.x(1.0) == pytest.approx(ell.tip_deflection, abs=1e-14)
    assert 1.0 - ell.z(1.0) == pytest.approx(ell.shortening, abs=1e-14)
    assert ell.psi(1.0) == pytest.approx(ell.tip_angle, abs=1e-14)
    assert ell.modulus == pytest.approx(math.sin(0.25 * math.pi + 0.5 * ell.tip_angle), abs=1e-15)


def test_elliptic_root_equation() -> None:
    """√α = K(k) − F(φ1, k), sin φ1 = 1/(√2 k), evaluated directly (no addition theorem)."""
    from scipy.special import ellipe, ellipeinc, ellipk, ellipkinc

    for alpha in ALPHAS:
        sol = _elastica(alpha, "elliptic")
        k = sol.modulus
        phi1 = math.asin(1.0 / (math.sqrt(2.0) * k))
        m = k * k
        assert ellipk(m) - ellipkinc(phi1, m) == pytest.approx(math.sqrt(alpha), rel=1e-13)
        w = 1.0 - 2.0 * (ellipe(m) - ellipeinc(phi1, m)) / math.sqrt(alpha)
        assert w == pytest.approx(sol.tip_deflection, abs=1e-13)
        assert 2.0 * k * math.cos(phi1) / math.sqrt(alpha) == pytest.approx(
            1.0 - sol.shortening, abs=1e-13
        )


def test_small_load_limit() -> None:
    """w/ℓ = α/3 − 4α³/105 + O(α⁵): the linear limit and the cubic correction."""
    alphas = 0.2 / 2.0 ** np.arange(6)
    sols = [_elastica(float(a), "elliptic") for a in alphas]
    w = np.array([s.tip_deflection for s in sols])
    u = np.array([s.shortening for s in sols])
    psi = np.array([s.tip_angle for s in sols])
    # Linear theory: w/(α/3) -> 1 with relative error ~ (4/35) α².
    rel = w / (alphas / 3.0) - 1.0
    np.testing.assert_allclose(rel / alphas**2, -4.0 / 35.0, rtol=0.03)
    # The cubic coefficient, with an O(α²) error (ratio of successive errors -> 4).
    c3 = (w - alphas / 3.0) / alphas**3
    err = c3 + 4.0 / 105.0
    assert np.all(np.abs(err) < 0.02 * alphas**2)
    np.testing.assert_allclose(err[:-2] / err[1:-1], 4.0, rtol=0.02)
    # Shortening and tip angle: u = α²/15 − 4α⁴/315, ψ_t = α/2 − 11α³/240.
    np.testing.assert_allclose((u - alphas**2 / 15.0) / alphas**4, -4.0 / 315.0, rtol=0.03)
    np.testing.assert_allclose((psi - alphas / 2.0) / alphas**3, -11.0 / 240.0, rtol=0.03)
    # Full two-term series: remainder O(α⁵) (w, ψ) and O(α⁶) (u), resolved for α ≥ 0.025
    # (below, the ~1e-14 absolute round-off of the closed form dominates α⁶).
    for a, sol in zip(alphas[:4], sols[:4], strict=True):
        series = small_load_expansion(float(a))
        assert abs(sol.tip_deflection - series.deflection) < 0.01 * a**5
        assert abs(sol.shortening - series.shortening) < 0.004 * a**6
        assert abs(sol.tip_angle - series.angle) < 0.01 * a**5


@pytest.mark.parametrize("alpha", MATTIASSON_ALPHAS)
def test_mattiasson_table(alpha: float) -> None:
    sol = _elastica(alpha, "elliptic")
    published = MATTIASSON_1981[alpha]
    # The printed 5 digits, ±1 in the last digit (in fact all agree exactly after rounding).
    assert abs(sol.shortening - published.u) <= 1.0001e-5
    assert abs(sol.tip_deflection - published.w) <= 1.0001e-5
    assert round(sol.shortening, 5) == pytest.approx(published.u, abs=1e-12)
    assert round(sol.tip_deflection, 5) == pytest.approx(published.w, abs=1e-12)
    # The module's own 12-digit table, from both methods.
    table = ELASTICA_TIP_TABLE[alpha]
    for method in ("elliptic", "bvp"):
        tip = _elastica(alpha, method).tip
        np.testing.assert_allclose(tip, table, rtol=2e-12, atol=0)


def test_negative_and_zero_load() -> None:
    pos, neg = _elastica(2.0, "elliptic"), elastica_tip_load(-2.0)
    assert neg.tip_deflection == -pos.tip_deflection
    assert neg.tip_angle == -pos.tip_angle
    assert neg.shortening == pos.shortening
    s = np.linspace(0, 1, 11)
    np.testing.assert_array_equal(neg.fields(s), pos.fields(s) * np.array([-1, -1, -1, 1])[:, None])
    zero = elastica_tip_load(0.0, "bvp")
    assert zero.tip == (0.0, 0.0, 0.0)
    np.testing.assert_array_equal(zero.z(s), s)
    with pytest.raises(ValueError, match="method"):
        elastica_tip_load(1.0, "shooting")  # type: ignore[arg-type]


@pytest.mark.parametrize("method", ["elliptic", "bvp"])
@pytest.mark.parametrize("alpha", [1.0, 10.0])
def test_elastica_equilibrium_finite_differences(alpha: float, method: str) -> None:
    """ψ'' + α cos ψ = 0, ψ' = κ, x' = sin ψ, z' = cos ψ, the BCs and the first integral."""
    sol = _elastica(alpha, method)
    h = 1e-3
    s = np.linspace(2 * h, 1.0 - 2 * h, 97)
    psi = sol.psi(s)
    d2 = _d2(sol.psi, s, h)
    assert np.max(np.abs(d2 + alpha * np.cos(psi))) < 1e-6 * alpha
    np.testing.assert_allclose(_d1(sol.psi, s, h), sol.curvature(s), rtol=0, atol=1e-8 * alpha)
    np.testing.assert_allclose(_d1(sol.x, s, h), np.sin(psi), rtol=0, atol=1e-9)
    np.testing.assert_allclose(_d1(sol.z, s, h), np.cos(psi), rtol=0, atol=1e-9)
    y0, y1 = sol.fields(0.0), sol.fields(1.0)
    assert abs(y0[0]) < 1e-12 and abs(y0[2]) < 1e-12 and abs(y0[3]) < 1e-12
    assert abs(y1[1]) < 1e-10 * alpha
    # ½κ² + α sin ψ = α sin ψ_t, and the clamp moment EI ψ'(0) = P z(ℓ).
    t = np.linspace(0.0, 1.0, 201)
    first = 0.5 * sol.curvature(t) ** 2 + alpha * np.sin(sol.psi(t))
    np.testing.assert_allclose(first, alpha * math.sin(sol.tip_angle), rtol=1e-11)
    assert y0[1] == pytest.approx(alpha * (1.0 - sol.shortening), rel=1e-11)


# --------------------------------------------------------------------------------------------
# Reissner rod
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("stiff", [math.inf, 1e14])
@pytest.mark.parametrize("alpha", [1.0, 5.0, 10.0])
def test_reissner_inextensible_limit_is_the_elastica(alpha: float, stiff: float) -> None:
    length, EI = 2.0, 3.0
    P = alpha * EI / length**2
    rod = reissner_tip_load(length, stiff, stiff, EI, P)
    ref = _elastica(alpha, "elliptic")
    assert rod.tip_x / length == pytest.approx(ref.tip_deflection, abs=1e-9)
    assert 1.0 - rod.tip_z / length == pytest.approx(ref.shortening, abs=1e-9)
    assert rod.tip_angle == pytest.approx(ref.tip_angle, abs=1e-9)
    s = np.linspace(0.0, length, 101)
    got = rod.fields(s) * np.array([1.0, length, 1.0 / length, 1.0 / length])[:, None]
    np.testing.assert_allclose(got, ref.fields(s / length), rtol=0, atol=1e-9 * max(1.0, alpha))


@pytest.mark.parametrize(
    "params",
    [
        {"length": 1.0, "EA": EA_CT, "GAk": CAO_TUCKER.kGA, "EI": CAO_TUCKER.EI},
        STUBBY,
    ],
    ids=["cao-tucker", "stubby"],
)
def test_reissner_small_load_is_timoshenko(params: dict[str, float]) -> None:
    """|x(ℓ)/δ_lin − 1| = O((δ/ℓ)²) for the tip force P, δ_lin = Pℓ³/(3EI) + Pℓ/(κGA)."""
    length, EI, GAk = params["length"], params["EI"], params["GAk"]
    beam = TimoshenkoBeam(length, 1.0, EI, 1.0, GAk, 1.0, 1.0)  # EI = I·E, κGA = κ·G·A
    ratios = []
    for target in (0.02, 0.01, 0.005):
        P = target * length / (length**3 / (3.0 * EI) + length / GAk)
        rod = reissner_tip_load(P=P, **params)
        delta = tip_deflection_end_force(beam, P)
        assert delta == pytest.approx(target * length, rel=1e-14)
        rel = rod.tip_x / delta - 1.0
        assert abs(rel) <= 2.0 * (delta / length) ** 2
        ratios.append(rel / (delta / length) ** 2)
        assert rod.tip_angle == pytest.approx(P * length**2 / (2.0 * EI), rel=3 * target**2)
    # The relative correction is genuinely quadratic: rel/(δ/ℓ)² converges to a constant.
    assert abs(ratios[0]) > 0.1
    assert abs(ratios[1] / ratios[2] - 1.0) < 0.01
    assert abs(ratios[0] / ratios[1] - 1.0) < 0.02


@pytest.mark.parametrize("theta", [0.5, 1.0, math.pi, 1.5 * math.pi, 2.0 * math.pi])
def test_reissner_pure_moment_is_a_circular_arc(theta: float) -> None:
    """ψ = Ms/EI, x = (EI/M)(1 − cos(Ms/EI)), z = (EI/M) sin(Ms/EI), for any EA and κGA."""
    p = STUBBY
    M = theta * p["EI"] / p["length"]
    rod = reissner_tip_load(P=0.0, M=M, **p)
    radius = p["EI"] / M
    s = np.linspace(0.0, p["length"], 201)
    np.testing.assert_allclose(rod.psi(s), s / radius, rtol=0, atol=1e-10)
    np.testing.assert_allclose(rod.curvature(s), 1.0 / radius, rtol=0, atol=1e-10)
    np.testing.assert_allclose(rod.x(s), radius * (1.0 - np.cos(s / radius)), rtol=0, atol=1e-10)
    np.testing.assert_allclose(rod.z(s), radius * np.sin(s / radius), rtol=0, atol=1e-10)
    assert rod.tip_angle == pytest.approx(theta, abs=1e-10)
    if theta == 2.0 * math.pi:  # the closed circle: the tip is back at the clamp
        assert abs(rod.tip_x) < 1e-10 and abs(rod.tip_z) < 1e-10
    np.testing.assert_array_equal(rod.normal_force(s), 0.0)
    np.testing.assert_array_equal(rod.shear_force(s), 0.0)


def test_reissner_pure_tension() -> None:
    p = STUBBY
    rod = reissner_tip_load(P=0.0, Pz=5.0, **p)
    assert rod.tip_angle == 0.0 and rod.tip_x == 0.0
    assert rod.tip_z == pytest.approx(p["length"] * (1.0 + 5.0 / p["EA"]), abs=1e-12)


def _check_reissner_equilibrium(rod: ReissnerSolution) -> None:
    ell, EI = rod.length, rod.EI
    h = 1e-3 * ell
    s = np.linspace(2 * h, ell - 2 * h, 97)
    psi = rod.psi(s)
    V, N = rod.shear_force(s), rod.normal_force(s)
    eps, gamma = rod.axial_strain(s), rod.shear_strain(s)
    np.testing.assert_allclose(eps, N / rod.EA, rtol=1e-15)
    scale = abs(rod.P) + abs(rod.Pz) + abs(rod.M) / ell
    # EI ψ'' + (1 + ε) V − γ N = 0 (moment balance m' + r' × n = 0).
    balance = EI * _d2(rod.psi, s, h) + (1.0 + eps) * V - gamma * N
    assert np.max(np.abs(balance)) < 1e-6 * scale
    np.testing.assert_allclose(_d1(rod.psi, s, h), rod.curvature(s), rtol=0, atol=1e-8)
    # Kinematics r' = (1 + ε) d3 + γ d1.
    dx = (1.0 + eps) * np.sin(psi) + gamma * np.cos(psi)
    dz = (1.0 + eps) * np.cos(psi) - gamma * np.sin(psi)
    np.testing.assert_allclose(_d1(rod.x, s, h), dx, rtol=0, atol=1e-9)
    np.testing.assert_allclose(_d1(rod.z, s, h), dz, rtol=0, atol=1e-9)
    # Boundary conditions.
    y0, y1 = rod.fields(0.0), rod.fields(ell)
    assert np.all(np.abs(y0[[0, 2, 3]]) < 1e-12)
    assert EI * y1[1] == pytest.approx(rod.M, abs=1e-9 * scale * ell)
    # First integral ½EIψ'² + N + ½(1/EA − 1/κGA)N² and global moment balance at the clamp.
    t = np.linspace(0.0, ell, 201)
    Nt = rod.normal_force(t)
    first = 0.5 * EI * rod.curvature(t) ** 2 + Nt + 0.5 * (1 / rod.EA - 1 / rod.GAk) * Nt**2
    assert np.ptp(first) < 1e-10 * scale * (1.0 + scale * ell**2 / EI)
    clamp = rod.M + rod.P * rod.tip_z - rod.Pz * rod.tip_x
    assert EI * y0[1] == pytest.approx(clamp, abs=1e-10 * scale * ell)


@pytest.mark.parametrize(
    ("P", "Pz", "M"),
    [(6.0, 0.0, 0.0), (4.0, 3.0, 0.0), (3.0, -1.0, 2.0), (-5.0, 2.0, -3.0)],
)
def test_reissner_equilibrium_finite_differences(P: float, Pz: float, M: float) -> None:
    rod = reissner_tip_load(P=P, Pz=Pz, M=M, **STUBBY)
    assert rod.tol <= 1e-11
    _check_reissner_equilibrium(rod)
    # Shear and extension matter here: the tip differs from the inextensible rod at O(1).
    stiff = reissner_tip_load(STUBBY["length"], math.inf, math.inf, STUBBY["EI"], P, Pz, M)
    assert abs(rod.tip_x - stiff.tip_x) > 1e-2


@pytest.mark.parametrize(("P", "Pz", "M"), [(6.0, 0.0, 0.0), (3.0, -1.0, 2.0)])
def test_reissner_energy_is_stationary(P: float, Pz: float, M: float) -> None:
    """Independent of the sign algebra of the ODE: δΠ = 0 for the total potential energy

    Π(ψ, ε, γ) = ∫ ½(EI ψ'² + EA ε² + κGA γ²) ds − n·r(ℓ) − M ψ(ℓ),
    r(ℓ) = ∫ ((1 + ε) d3 + γ d1) ds, for variations of ψ vanishing at the clamp.
    """
    p = STUBBY
    rod = reissner_tip_load(P=P, Pz=Pz, M=M, **p)
    ell = p["length"]
    x, wq = np.polynomial.legendre.leggauss(20)
    edges = np.linspace(0.0, ell, 41)
    half = 0.5 * np.diff(edges)[:, None]
    s = (0.5 * (edges[1:] + edges[:-1])[:, None] + half * x).ravel()
    w = (half * wq).ravel()
    eps, gamma = rod.axial_strain(s), rod.shear_strain(s)

    def energy(psi, dpsi, psi_tip):
        strain = 0.5 * (p["EI"] * dpsi**2 + p["EA"] * eps**2 + p["GAk"] * gamma**2)
        rx = (1.0 + eps) * np.sin(psi) + gamma * np.cos(psi)
        rz = (1.0 + eps) * np.cos(psi) - gamma * np.sin(psi)
        return np.sum(w * (strain - P * rx - Pz * rz)) - M * psi_tip

    psi, dpsi = rod.psi(s), rod.curvature(s)
    for mode in (1, 2, 3):
        k = (mode - 0.5) * math.pi / ell
        var, dvar, var_tip = np.sin(k * s), k * np.cos(k * s), math.sin(k * ell)
        h = 1e-4
        plus = energy(psi + h * var, dpsi + h * dvar, rod.tip_angle + h * var_tip)
        minus = energy(psi - h * var, dpsi - h * dvar, rod.tip_angle - h * var_tip)
        first_variation = (plus - minus) / (2 * h)
        bending = np.sum(w * p["EI"] * dpsi * dvar)  # one of the O(1) terms that cancel
        assert abs(first_variation) < 1e-8 * max(1.0, abs(bending))
        # A wrong sign of the coupling term (1+ε)V − γN would break this: its size is
        # ∫ 2γN var, far above the tolerance.
        coupling = np.sum(w * 2.0 * gamma * rod.normal_force(s) * var)
        assert abs(coupling) > 1e-3


def test_tighter_tolerance_on_request() -> None:
    """tol < 1e-11 is kept where it converges (α = 1) and falls back to 1e-11 otherwise."""
    tight = elastica_tip_load(1.0, "bvp", tol=1e-12)
    assert tight.tol == 1e-12
    np.testing.assert_allclose(tight.tip, ELASTICA_TIP_TABLE[1.0], rtol=1e-13)
    hard = elastica_tip_load(10.0, "bvp", tol=1e-13)
    assert hard.tol in (1e-13, 1e-11)
    np.testing.assert_allclose(hard.tip, ELASTICA_TIP_TABLE[10.0], rtol=1e-12)
