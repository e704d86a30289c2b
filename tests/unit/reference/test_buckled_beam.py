"""Unit tests of cosserat_fem/reference/buckled_beam.py: the one-mode reduction's constants
against their independent forms, and the double-well oscillator's orbits.

* D_cr is Euler's load π²EI/ℓ² as a shortening P ℓ/(EA); the buckled amplitude a_s solves
  the static equation −k a + β a³ = 0, and the axial force there, EA(−D/ℓ + a_s²π²/(4ℓ²)),
  is Euler's load (a buckled pinned beam carries its critical load). Round-off only (1e-12).
* The forcing, damping and frequency round-trip through δ, ω, γ exactly (1e-12).
* A period-n orbit's Floquet multipliers multiply to e^{−δ n 2π/ω} (Liouville: the trace of
  the Jacobian is −δ), to the integrator's tolerance (rtol 1e-12, over a product of order 1:
  1e-8). The period-1 orbit at γ = 0.20 is stable (|μ| < 1) and is the section's limit; the
  period-2 point at γ = 0.28 is not a period-1 point (its image after one period is another
  point, by more than 0.1), and is stable.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from cosserat_fem.reference.buckled_beam import (
    HOLMES_DELTA,
    HOLMES_OMEGA,
    BuckledBeam,
    duffing_flow,
    duffing_orbit,
    duffing_section,
)

pytestmark = pytest.mark.unit

BEAM = BuckledBeam(1.0, 7.1e10, 2730.0, 2e-4, 0.02 * 0.01**3 / 12, 2 * 8.2247e-5)


def test_the_reduction_s_constants_are_euler_s():
    E, A, I, L = BEAM.young_modulus, BEAM.area, BEAM.inertia, BEAM.length
    euler = math.pi**2 * E * I / L**2
    assert BEAM.critical_shortening == pytest.approx(euler * L / (E * A), rel=1e-12)
    a = BEAM.amplitude
    beta = E * math.pi**4 / (4 * BEAM.density * L**4)
    assert -BEAM.k * a + beta * a**3 == pytest.approx(0.0, abs=1e-12 * BEAM.k * a)
    axial = E * A * (-BEAM.shortening / L + a**2 * math.pi**2 / (4 * L**2))
    assert -axial == pytest.approx(euler, rel=1e-10)


def test_the_oscillator_s_parameters_round_trip():
    rhoA, sk = BEAM.density * BEAM.area, math.sqrt(BEAM.k)
    assert BEAM.damping(0.3) / (rhoA * sk) == pytest.approx(0.3, rel=1e-12)
    assert BEAM.frequency(1.2) / sk == pytest.approx(1.2, rel=1e-12)
    assert BEAM.force(0.28) / (rhoA * BEAM.amplitude * BEAM.k) == pytest.approx(0.28, rel=1e-12)


@pytest.mark.parametrize("gamma, guess, n", [(0.20, (0.57, 0.41), 1), (0.28, (0.246, 0.237), 2)])
def test_orbits_and_their_multipliers(gamma, guess, n):
    point, multipliers = duffing_orbit(gamma, guess, n)
    T = 2 * math.pi / HOLMES_OMEGA
    assert np.prod(multipliers).real == pytest.approx(math.exp(-HOLMES_DELTA * n * T), rel=1e-8)
    assert np.abs(multipliers).max() < 1.0
    image = duffing_flow(gamma, HOLMES_DELTA, HOLMES_OMEGA, point, 1, 1e-12)[0]
    if n == 1:
        section = duffing_section(gamma, 40, start=(1.0, 0.0), rtol=1e-9)
        assert section[-1] == pytest.approx(point, abs=1e-6)
    else:
        assert np.abs(image - point).max() > 0.1
