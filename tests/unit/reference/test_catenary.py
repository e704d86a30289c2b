"""Unit tests of cosserat_fem/reference/catenary.py: the elastic catenary with a grounded
length against independent forms.

* Direct quadrature: the suspended part integrated from the touchdown point as the cable's
  equilibrium, dx/ds0 = (1 + T/EA) H/T, dz/ds0 = (1 + T/EA) w s0/T, T = sqrt(H² + (w s0)²)
  (scipy.integrate.quad, rtol 1e-12), plus the grounded part (L − S0)(1 + H/EA), gives the
  top's (h, X_top) of (K.2) to 1e-10 relative (the quadrature's tolerance).
* Inextensible limit (EA = 1e30): S0 = sqrt(h² + 2 h H/w) and T_top = H + w h
  (docs/contact-design.md (C.2)) to round-off (1e-12).
* Round trip: the top position of from_top_force fed to from_top_position gives back H, S0 and
  T_top to 1e-10 (the root's tolerance amplified by the sensitivity dH/dX_top).
* h → 0 (a cable barely lifted, H fixed): the suspended part is the parabola's, S0 ≈ X ≈
  sqrt(2 a h) (a = H/w), and X_top → L (EA = ∞): S0/sqrt(2ah) − 1 = O(h/a), measured
  against the bound h/a at h/a = 1e-4.
* The bending's shift of the top (K.4) against its pieces, the suspended part's integral by
  quadrature in the arc length (1e-10), and its δh against the first integral's −Q_t²/(2 w T_top).
* Refusals: a top too low for a slack cable to reach with a vertex (X_top ≤ L − h), and a
  force lifting the whole cable (V ≥ w L): ValueError.
"""

from __future__ import annotations

import math

import pytest
from scipy.integrate import quad

from cosserat_fem.reference.catenary import (
    bending_shift,
    from_top_force,
    from_top_position,
    top_tension,
)

pytestmark = pytest.mark.unit

W, EA, L = 2.0, 500.0, 10.0  # N/m, N, m: the strain H/EA of 1-4 %, so the stretch matters


def test_the_top_is_the_quadrature_of_the_cable_s_equilibrium():
    cable = from_top_force(W, EA, L, H=6.0, V=9.0)
    H, S0 = cable.H, cable.S0

    def tension(s):
        return math.hypot(H, W * s)

    x = quad(lambda s: (1 + tension(s) / EA) * H / tension(s), 0, S0, epsabs=0, epsrel=1e-12)[0]
    z = quad(lambda s: (1 + tension(s) / EA) * W * s / tension(s), 0, S0, epsabs=0, epsrel=1e-12)
    assert S0 == pytest.approx(4.5, rel=1e-15)
    assert cable.h == pytest.approx(z[0], rel=1e-10)
    assert cable.X_top == pytest.approx((L - S0) * (1 + H / EA) + x, rel=1e-10)
    assert cable.T_top == pytest.approx(math.hypot(6.0, 9.0), rel=1e-14)
    assert top_tension(W, EA, H, cable.h) == pytest.approx(cable.T_top, rel=1e-12)
    xs, zs = cable.shape([0.0, S0])
    assert xs[0] == pytest.approx(cable.touchdown_x) and zs[0] == 0.0
    assert xs[1] == pytest.approx(cable.X_top, rel=1e-14)
    assert zs[1] == pytest.approx(cable.h, rel=1e-14)


def test_the_inextensible_limit_is_the_catenary_c2():
    h, X_top = 3.0, 8.0
    cable = from_top_position(W, 1e30, L, h, X_top)
    a = cable.H / W
    assert cable.S0 == pytest.approx(math.sqrt(h**2 + 2 * h * a), rel=1e-12)
    assert cable.T_top == pytest.approx(cable.H + W * h, rel=1e-12)
    X = a * math.acosh(1 + h / a)
    assert cable.touchdown_s + X == pytest.approx(X_top, rel=1e-12)


@pytest.mark.parametrize(("H", "V"), [(0.5, 3.0), (6.0, 9.0), (40.0, 19.0)])
def test_position_and_force_are_one_cable(H, V):
    by_force = from_top_force(W, EA, L, H, V)
    by_position = from_top_position(W, EA, L, by_force.h, by_force.X_top)
    assert by_position.H == pytest.approx(H, rel=1e-10)
    assert by_position.S0 == pytest.approx(by_force.S0, rel=1e-10)
    assert by_position.T_top == pytest.approx(by_force.T_top, rel=1e-10)
    assert by_position.touchdown_s == pytest.approx(by_force.touchdown_s, rel=1e-10)


def test_a_barely_lifted_cable_is_the_parabola():
    a, h = 2.0, 2e-4  # h/a = 1e-4
    cable = from_top_force(W, 1e30, L, a * W, W * math.sqrt(h**2 + 2 * h * a))
    assert cable.h == pytest.approx(h, rel=1e-10)
    parabola = math.sqrt(2 * a * h)
    assert abs(cable.S0 / parabola - 1) <= h / a
    assert abs((cable.X_top - cable.touchdown_s) / parabola - 1) <= h / a
    assert L - cable.X_top < 2 * parabola * h / a  # S0 − X = (2/3) S0 h/(2a) to first order


def test_unreachable_tops_are_refused():
    with pytest.raises(ValueError, match="X_top > L"):
        from_top_position(W, EA, L, 3.0, L - 3.0)
    with pytest.raises(ValueError, match="leaves the seabed"):
        from_top_position(W, EA, L, 3.0, 12.0)
    with pytest.raises(ValueError, match="0 < V < w L"):
        from_top_force(W, EA, L, 1.0, W * L)


@pytest.mark.parametrize(("H", "V"), [(6.0, 9.0), (2.0, 2.2), (10.0, 1.0)])
def test_the_bending_shift_is_its_pieces_integrated(H, V):
    """(K.4) against its pieces summed with the suspended part's integral done by quadrature
    in the arc length (θ_n = atan(w s/H); the integrand in s, not (K.4)'s substitution in θ):
    δX = −∫ (EI/T) θ_n'' sin θ_n ds + κ_t λ_t² sin θ_t and δh = λ²/(2a) +
    ∫ (EI/T) θ_n'' cos θ_n ds − κ_t λ_t² cos θ_t (the touchdown's and the top's layers,
    λ_t² = EI/T_top), to 1e-10; and w δh = −Q_t²/(2 T_top) (the first integral's form)."""
    EI = 0.01
    S0, T_top = V / W, math.hypot(H, V)

    def theta(s):
        return math.atan(W * s / H)

    def bend(s):
        u = W * s / H  # θ_n'' = d²/ds² atan(u) = −2 (w/H)² u/(1 + u²)²
        return EI * -2 * (W / H) ** 2 * u / (1 + u**2) ** 2 / math.hypot(H, W * s)

    def integral(f):
        return quad(f, 0, S0, epsabs=0, epsrel=1e-12, limit=200)[0]

    kappa, lam_t2 = W * H / T_top**2, EI / T_top
    theta_t = math.atan2(V, H)
    dX = -integral(lambda s: bend(s) * math.sin(theta(s))) + kappa * lam_t2 * math.sin(theta_t)
    dh = EI / H / (2 * H / W) + integral(lambda s: bend(s) * math.cos(theta(s)))
    dh -= kappa * lam_t2 * math.cos(theta_t)
    shift = bending_shift(W, H, V, EI)
    assert shift[0] == pytest.approx(dX, rel=1e-10)
    assert shift[1] == pytest.approx(dh, rel=1e-10)
    shear = kappa * math.sqrt(EI * T_top)
    assert W * shift[1] == pytest.approx(-(shear**2) / (2 * T_top), rel=1e-12)
