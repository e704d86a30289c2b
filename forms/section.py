"""Cross-section constants of Cao & Tucker (2008), eq. (46) and the text after it.

Conventions (paper, eqs. (11) and (46)): the director d1 points across the dimension ``a``
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
