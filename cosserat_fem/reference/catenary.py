"""The heavy cable hanging onto a frictionless seabed: the elastic catenary with a grounded
length (a riser's or mooring line's touchdown; docs/contact-design.md, "Riser touchdown
(catenary)"; tests/test_riser.py).

Pure numpy/scipy; this module must never import DOLFINx.

A cable of unstretched length L, weight w [N/m] per unstretched length, axial stiffness EA [N]
(Hooke: the tension T = EA ε, ε the stretch minus one), no bending stiffness, lies from its
anchor (s = 0) along a frictionless horizontal seabed and hangs from its top end (s = L),
held at height h above the seabed and horizontal distance X_top from the anchor. The seabed
carries no horizontal force, so the horizontal tension H is uniform, the grounded part is
straight with tension H, and the suspended part meets the seabed tangentially at the
touchdown point (the catenary's vertex). With s0 the unstretched arc length from the
touchdown point and S0 the suspended part's, its tension is T(s0) = sqrt(H² + (w s0)²) and
(Irvine 1981, "Cable structures", §2.2, with the origin at the vertex)

    x(s0) = (H/w) asinh(w s0/H) + H s0/EA,
    z(s0) = (H/w) (sqrt(1 + (w s0/H)²) − 1) + w s0²/(2 EA),                      (K.1)

and the top is at

    h = z(S0),   X_top = (L − S0)(1 + H/EA) + x(S0).                               (K.2)

Eliminating s0 from z: w z = T − H + (T² − H²)/(2 EA), so at the top

    T_top + T_top²/(2 EA) = H + H²/(2 EA) + w h,                                     (K.3)

a quadratic in T_top (EA → ∞: T_top = H + w h, docs/contact-design.md (C.2)), whence
S0 = sqrt(T_top² − H²)/w (with bending stiffness: (K.4) below).
Given the top's position, X_top(H) of (K.2) with S0(H) from (K.3) increases with H (a tauter
cable hangs from further away), so H is the root of one monotone equation (brentq on a
bracket grown by factors of 2). Given the top's force (H, V) instead, S0 = V/w directly.

The touchdown point is at s = L − S0 (unstretched, from the anchor) and at the horizontal
distance (L − S0)(1 + H/EA) from it.

**Bending stiffness** EI (a rod, its top free to turn: no moment there), by matched
asymptotics in λ = sqrt(EI/H) ≪ a = H/w (θ the tangent's angle to the seabed; above the
touchdown the internal force is n(s) = F − w (L − s) e_z, F = (H, V) the top's force, of angle
θ_n, and the moment balance is EI θ'' = T (θ − θ_n) to first order):

* at the touchdown (the beam-column EI y'''' − H y'' = −w on a rigid seabed, y = y' = y'' = 0
  there) the seabed's point reaction is w λ, so the touchdown point moves to
  s = L − S0 − λ, S0 = V/w, and the outer catenary's vertex is λ²/(2a) above the seabed;
* along the suspended part θ − θ_n = (EI/T) θ_n''; at the top a layer of length sqrt(EI/T_top)
  turns the tangent by −κ_t sqrt(EI/T_top) (κ_t = w H/T_top² the catenary's curvature there),
  and its shear force is Q_t = κ_t sqrt(EI T_top).

For the top's force (H, V) given, the top moves by, to O(λ²) (θ_t = atan(V/H)),

    δX_top = (λ²/a) (θ_t/4 − sin 4θ_t/16 + cos³θ_t sin θ_t),
    δh = −(λ²/(2a)) cos⁴θ_t,                                                          (K.4)

and (K.3) holds for the top's axial force N_t = sqrt(T_top² − Q_t²) (T + T²/(2EA) + EI κ²/2
− w z is a first integral of the unshearable rod under gravity; the seabed's reactions act
where the tangent is horizontal): the same δh, w δh = −Q_t²/(2 T_top) to O(λ²).
Units: SI (any consistent set).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq


@dataclass(frozen=True)
class Catenary:
    """The solved cable: horizontal tension H [N], the suspended part's unstretched length
    S0 [m], the top's tension T_top [N], height h [m] and horizontal distance X_top [m], and
    the touchdown point at the unstretched arc length ``touchdown_s`` [m] from the anchor,
    the horizontal distance ``touchdown_x`` [m]."""

    weight: float
    stiffness: float
    length: float
    H: float
    S0: float
    T_top: float
    h: float
    X_top: float

    @property
    def touchdown_s(self) -> float:
        return self.length - self.S0

    @property
    def touchdown_x(self) -> float:
        return (self.length - self.S0) * (1.0 + self.H / self.stiffness)

    def shape(self, s0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(K.1): the suspended part's points (x, z) [m] at unstretched arc lengths ``s0``
        (0 ≤ s0 ≤ S0) from the touchdown point, x from the anchor."""
        s0 = np.asarray(s0, dtype=float)
        w, EA, H = self.weight, self.stiffness, self.H
        x = self.touchdown_x + (H / w) * np.arcsinh(w * s0 / H) + H * s0 / EA
        z = (H / w) * (np.sqrt(1.0 + (w * s0 / H) ** 2) - 1.0) + w * s0**2 / (2.0 * EA)
        return x, z


def top_tension(weight: float, stiffness: float, H: float, h: float) -> float:
    """(K.3) solved for T_top [N]: the positive root of T²/(2EA) + T − c = 0 with
    c = H + H²/(2EA) + w h, written without cancellation (2c / (1 + sqrt(1 + 2c/EA)))."""
    c = H + H**2 / (2.0 * stiffness) + weight * h
    return 2.0 * c / (1.0 + math.sqrt(1.0 + 2.0 * c / stiffness))


def _top(weight: float, stiffness: float, length: float, H: float, S0: float) -> Catenary:
    """(K.1)-(K.2) at the top s0 = S0 for the horizontal tension H."""
    w, EA = weight, stiffness
    T = math.hypot(H, w * S0)
    h = (T - H) / w + (T**2 - H**2) / (2.0 * EA * w)  # z(S0), (K.1) without cancellation
    x = (H / w) * math.asinh(w * S0 / H) + H * S0 / EA
    X_top = (length - S0) * (1.0 + H / EA) + x
    return Catenary(w, EA, length, H, S0, T, h, X_top)


def from_top_force(weight: float, stiffness: float, length: float, H: float, V: float) -> Catenary:
    """The cable whose top end carries the force (H, V) [N] (horizontal away from the anchor,
    vertical up): the suspended part is the weight V holds, S0 = V/w; ValueError unless
    0 < V < w L (a grounded part left) and H > 0."""
    if not (H > 0.0 and 0.0 < V < weight * length):
        raise ValueError(f"top force ({H}, {V}): needs H > 0 and 0 < V < w L = {weight * length}")
    return _top(weight, stiffness, length, H, V / weight)


def from_top_position(
    weight: float, stiffness: float, length: float, h: float, X_top: float
) -> Catenary:
    """The cable whose top is held at height h and horizontal distance X_top [m] from the
    anchor: H the root of X_top(H) (K.2) with S0(H) from (K.3) (module docstring).
    ValueError if no cable of this length reaches the top with a grounded part (X_top ≤ L − h:
    too slack to be a catenary from a vertex, it would be slack on the seabed; or S0 > L)."""
    w, EA, L = weight, stiffness, length
    if not (h > 0.0 and X_top > L - h):
        raise ValueError(f"top at h = {h}, X_top = {X_top}: needs h > 0 and X_top > L − h")

    def cable(H: float) -> Catenary:
        T = top_tension(w, EA, H, h)
        return _top(w, EA, L, H, math.sqrt(max(T**2 - H**2, 0.0)) / w)

    def excess(H: float) -> float:
        return cable(H).X_top - X_top

    low = high = w * h
    while excess(low) > 0.0:
        low /= 2.0
        if low < 1e-12 * w * h:
            raise ValueError(f"top at h = {h}, X_top = {X_top}: no slack cable reaches it")
    while excess(high) < 0.0:  # (K.2) continued past S0 = L (a negative grounded part)
        high *= 2.0
        if high > 1e12 * w * h:
            raise ValueError(f"top at h = {h}, X_top = {X_top}: no cable of L = {L} reaches it")
    H = brentq(excess, low, high, xtol=1e-15 * high, rtol=4 * np.finfo(float).eps)
    result = cable(H)
    if result.S0 > L:
        raise ValueError(f"top at h = {h}, X_top = {X_top}: the cable (L = {L}) leaves the seabed")
    return result


def bending_shift(weight: float, H: float, V: float, EI: float) -> tuple[float, float]:
    """(K.4): the top's horizontal and vertical moves (δX_top, δh) [m] by the bending
    stiffness EI [N m²] of a cable whose top carries the force (H, V) [N], to O(λ²)."""
    theta, a, lam2 = math.atan2(V, H), H / weight, EI / H
    dX = lam2 / a * (theta / 4 - math.sin(4 * theta) / 16 + math.cos(theta) ** 3 * math.sin(theta))
    return dX, -lam2 / (2 * a) * math.cos(theta) ** 4
