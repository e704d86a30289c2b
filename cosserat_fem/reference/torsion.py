r"""Saint-Venant torsion constant of a rectangle, independently of the solver's section code.

The solver (forms/section.py) sums Saint-Venant's single series in tanh. The references need
c33 too (the torsional frequencies of :mod:`.rod_planes`, the twist of :mod:`.second_order`),
and take it from here: Prandtl's stress function of the a × b rectangle expanded in a double
Fourier sine series (a Galerkin solution that is exact term by term), summed directly.

With Gθ = 1 the stress function Φ solves ∇²Φ = −2 in [0, a] × [0, b], Φ = 0 on the boundary,
and J = 2 ∫ Φ dA. Expanding −2 = −2 Σ 16/(π² m n) sin(mπx/a) sin(nπy/b) (m, n odd) gives
Φ = Σ A_mn sin(mπx/a) sin(nπy/b) with A_mn = 32/(π⁴ m n (m²/a² + n²/b²)), hence

.. math::

    J = \frac{256\, a b}{\pi^6} \sum_{m, n\ \mathrm{odd}} \frac{1}{m^2 n^2 (m^2/a^2 + n^2/b^2)}.

Truncated at m, n ≤ M the remainder T is bounded, since Σ_n 1/(n² (m²/a² + n²/b²)) ≤
(a²/m²) Σ_n n⁻² = (a²/m²) π²/8 and Σ_{m > M odd} m⁻⁴ ≤ ½ ∫_M^∞ x⁻⁴ dx = 1/(6M³), by

.. math::

    0 \le T \le \frac{(a^2 + b^2)\, \pi^2}{48 M^3},

which :func:`torsion_constant_bound` returns as a bound on the relative error of J (the sum
is at least its first term, a²b²/(a² + b²)). With the default 2000 odd indices per direction
(M = 3999) it is 1.3e-11 for the square, 1.5e-11 for the paper's 2:3 section and 3.3e-10 for
a 1:10 strip (the sums fall short of forms/section.py's series by 0.9 of it: the bound is
nearly sharp). Pure numpy; no DOLFINx, no UFL. Tests: tests/test_second_order_reference.py
::test_torsion_constant_against_published_values_and_the_solvers_series,
::test_torsion_constant_of_the_paper_and_thin_strips.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

__all__ = ["TORSION_TERMS", "rectangle_torsion_constant", "torsion_constant_bound"]

#: Odd indices summed per direction (M = 2 TORSION_TERMS − 1).
TORSION_TERMS = 2000


# RodData.c33 is a property: cached (why: docs/decisions.md, "The references' torsion constant").
@lru_cache(maxsize=64)
def rectangle_torsion_constant(a: float, b: float, terms: int = TORSION_TERMS) -> float:
    """J [m⁴] of the a × b rectangle by the double Fourier series of Prandtl's stress
    function (module docstring), m, n = 1, 3, ..., 2 terms − 1."""
    if not (a > 0.0 and b > 0.0):
        raise ValueError(f"rectangle sides must be positive, got {a!r} x {b!r}")
    odd = np.arange(1, 2 * terms, 2, dtype=float)
    m2, n2 = (odd / a) ** 2, (odd / b) ** 2
    weight_m, weight_n = 1.0 / odd**2, 1.0 / odd**2
    total = 0.0
    for start in range(0, odd.size, 256):  # rows of m, to bound the memory
        rows = slice(start, start + 256)
        block = weight_m[rows, None] * weight_n[None, :] / (m2[rows, None] + n2[None, :])
        total += float(np.sum(block))
    return 256.0 * a * b / math.pi**6 * total


def torsion_constant_bound(a: float, b: float, terms: int = TORSION_TERMS) -> float:
    """An upper bound on the relative truncation error of :func:`rectangle_torsion_constant`:
    (a² + b²) π² / (48 M³) over the first term a²b²/(a² + b²), M = 2 terms − 1."""
    M = 2 * terms - 1
    return (a * a + b * b) ** 2 * math.pi**2 / (48.0 * M**3 * a * a * b * b)
