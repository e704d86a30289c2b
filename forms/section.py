"""Cross-section constants of Cao & Tucker (2008), eq. (46) and the text after it.

Shapes: the paper's rectangle (:func:`rectangle`), the circle and circular tube (:func:`tube`),
or the constants given explicitly (:class:`Section`). Rectangle conventions (paper, eqs. (11)
and (46)): the director d1 points across the dimension ``a``
(the thickness), d2 across ``b`` (the width). Then

* c11 = ∫ η² dA = a b³ / 12   (bending about d1: displacement y, angle θ),
* c22 = ∫ ξ² dA = b a³ / 12   (bending about d2: displacement x, angle ψ),
* c33 = Saint-Venant torsion constant (not the polar moment c11 + c22).

The paper's reference frequency ω0 = 1.875² / ℓ² · sqrt(E c22 / (ρ A)) uses c22 = b a³/12,
which fixes this orientation (a = 0.04 m, b = 0.06 m give ω0 = 207.0236 rad/s).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

TORSION_CONSTANT_RULES = ("series", "approximate")


@dataclass(frozen=True)
class Section:
    """Section constants in SI units: area A [m²], c11, c22, c33 [m⁴], shear coefficient κ."""

    area: float
    c11: float
    c22: float
    c33: float
    shear_coefficient: float


def rectangle_torsion_constant(width: float, height: float, rule: str = "series") -> float:
    """Saint-Venant torsion constant of a W × H rectangle, W ≥ H (paper, after eq. (46)).

    ``series``:      c33 = W H³/3 [1 − 192 H/(π⁵ W) Σ_{n≥1} tanh(π(2n−1)W/(2H)) / (2n−1)⁵]
    ``approximate``: c33 = W H³/3 [1 − 0.63 (H/W) (1 − H⁴/(12 W⁴))]

    The series is summed until its terms fall below 1e-17 of the sum (a few terms suffice:
    they decay like (2n−1)⁻⁵).
    """
    w, h = max(width, height), min(width, height)
    if rule == "series":
        total, n = 0.0, 1
        while True:
            k = 2 * n - 1
            term = math.tanh(math.pi * k * w / (2.0 * h)) / k**5
            total += term
            if term < 1e-17 * total:
                break
            n += 1
        return w * h**3 / 3.0 * (1.0 - 192.0 * h / (math.pi**5 * w) * total)
    if rule == "approximate":
        return w * h**3 / 3.0 * (1.0 - 0.63 * h / w * (1.0 - h**4 / (12.0 * w**4)))
    raise ValueError(
        f"unknown torsion-constant rule {rule!r}; expected one of {TORSION_CONSTANT_RULES}"
    )


def rectangle(
    a: float, b: float, shear_coefficient: float, torsion_rule: str = "series"
) -> Section:
    """Rectangle with extent ``a`` along d1 and ``b`` along d2 (eq. (46))."""
    return Section(
        area=a * b,
        c11=a * b**3 / 12.0,
        c22=b * a**3 / 12.0,
        c33=rectangle_torsion_constant(a, b, torsion_rule),
        shear_coefficient=shear_coefficient,
    )


def cowper_circle(poisson_ratio: float, ratio: float = 0.0) -> float:
    """Cowper's (1966) shear coefficient of a circular tube with inner/outer diameter ratio
    m (m = 0: the solid circle, 6(1+ν)/(7+6ν)):
    κ = 6 (1+ν)(1+m²)² / [(7+6ν)(1+m²)² + (20+12ν) m²]."""
    nu, m2 = poisson_ratio, ratio * ratio
    numerator = 6.0 * (1.0 + nu) * (1.0 + m2) ** 2
    return numerator / ((7.0 + 6.0 * nu) * (1.0 + m2) ** 2 + (20.0 + 12.0 * nu) * m2)


def tube(outer_diameter: float, inner_diameter: float, shear_coefficient: float) -> Section:
    """Circular tube (inner diameter 0: the solid circle): A = π (D² − d²)/4,
    c11 = c22 = π (D⁴ − d⁴)/64, and the torsion constant of a circular section is its polar
    moment, c33 = c11 + c22 = π (D⁴ − d⁴)/32 (no warping)."""
    D, d = outer_diameter, inner_diameter
    second_moment = math.pi * (D**4 - d**4) / 64.0
    return Section(
        area=math.pi * (D * D - d * d) / 4.0,
        c11=second_moment,
        c22=second_moment,
        c33=2.0 * second_moment,
        shear_coefficient=shear_coefficient,
    )


#: The order of a 6×6 section law's rows and columns: the strains (Γ1, Γ2, Γ3, κ1, κ2, κ3) =
#: (shear 1, shear 2, extension, bending 1, bending 2, torsion), director components. It is
#: BeamDyn's order (axis 3 along the beam); GXBeam's (axis 1 along the beam) is taken to it
#: by the permutation :data:`GXBEAM_TO_LAW` of rows and columns.
LAW_ORDER = ("shear 1", "shear 2", "extension", "bending 1", "bending 2", "torsion")

#: K_law[i][j] = K_gxbeam[P[i]][P[j]]: GXBeam's (extension, shear 2, shear 3, torsion,
#: bending 2, bending 3) to :data:`LAW_ORDER` (GXBeam gives compliances: invert first).
GXBEAM_TO_LAW = (1, 2, 0, 4, 5, 3)


@dataclass(frozen=True)
class SectionLaw:
    """A general section law (docs/sections.md): contact force and torque in the directors,

        n = K₁ Γ + K₁₂ κ,   m = K₂₁ Γ + K₂ κ,   K = [[K₁, K₁₂], [K₂₁, K₂]] = Kᵀ > 0,

    Γ = v − v0 [-], κ = u − u0 [1/m], in the order :data:`LAW_ORDER`; ``stiffness`` K, rows of
    6 entries [N | N m; N m | N m²], each a number or a UFL expression of the reference
    coordinate σ = s/ℓ (a section that varies along s). ``mass_per_length`` μ [kg/m] and
    ``inertia`` (I11, I22, I33) [kg m] likewise; None: ρ A and the rod's rotary inertias. The
    paper's (13) is K = diag(κGA, κGA, EA, E c11, E c22, G c33)."""

    stiffness: tuple[tuple[Any, ...], ...]
    mass_per_length: Any = None
    inertia: tuple[Any, Any, Any] | None = None


def check_stiffness(matrix: Any, key: str, rtol: float = 1e-12) -> np.ndarray:
    """The 6×6 ``matrix`` as an array if it is symmetric (|K − Kᵀ| ≤ rtol max|K|) and
    positive definite (Cholesky); else ValueError, one line naming ``key``."""
    try:
        K = np.array(matrix, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{key}: must be a 6×6 matrix of numbers") from None
    if K.shape != (6, 6):
        raise ValueError(f"{key}: must be a 6×6 matrix, got shape {K.shape}")
    if not np.all(np.isfinite(K)):
        raise ValueError(f"{key}: entries must be finite numbers")
    asym = float(np.abs(K - K.T).max())
    if asym > rtol * float(np.abs(K).max()):
        raise ValueError(f"{key}: not symmetric (max |K - K^T| = {asym:.3g})")
    try:
        np.linalg.cholesky(K)
    except np.linalg.LinAlgError:
        smallest = float(np.linalg.eigvalsh(0.5 * (K + K.T)).min())
        raise ValueError(
            f"{key}: not positive definite (smallest eigenvalue {smallest:.3g})"
        ) from None
    return K
