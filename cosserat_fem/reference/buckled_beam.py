"""A pinned–pinned beam buckled by end shortening and forced transversely, and its one-mode
reduction: the double-well Duffing oscillator of Holmes (1979, Phil. Trans. R. Soc. A 292:419)
and Moon & Holmes (1979, J. Sound Vib. 65:275), whose Poincaré sections and Floquet
multipliers are computed here (scipy, DOP853).

**The reduction.** A beam of length ℓ, E, ρ, section A and second moment I, both ends pinned,
one end moved towards the other by D (held), loaded by f0 sin(πs/ℓ) cos Ωt [N/m] across its
axis and damped by c [N s/m²]. With w(s, t) = a(t) sin(πs/ℓ) (the first mode, which the
pinned ends allow exactly) and the axial force uniform (axial inertia neglected: the first
axial frequency π√(E/ρ)/ℓ is ~100 times Ω here),

    N = EA (−D/ℓ + a² π²/(4ℓ²)),     ρA ẅ + c ẇ + EI w'''' − N w'' = f,

projected on sin(πs/ℓ) (× 2/(ρAℓ)):

    ä + (c/ρA) ȧ − k a + β a³ = (f0/ρA) cos Ωt,
    k = ω_b² (D/D_cr − 1),  ω_b² = EI π⁴/(ρA ℓ⁴),  D_cr = I π²/(A ℓ),  β = E π⁴/(4ρ ℓ⁴).

D_cr is Euler's load π²EI/ℓ² as a shortening (P ℓ/(EA)). For D > D_cr the straight beam is
unstable and the buckled states a = ±a_s, a_s = √(k/β) = (2/π) √(ℓ (D − D_cr)), are the two
wells. With a = a_s x and τ = √k t:

    x'' + δ x' − x + x³ = γ cos ωτ,   δ = c/(ρA √k),  ω = Ω/√k,  γ = f0/(ρA a_s k).

Nothing else is dropped for this beam model: with N uniform every term of the
(Woinowsky-Krieger) beam equation is ∝ sin(πs/ℓ), so the one-mode motion is an exact solution
of it. The rod differs from it by the geometrically exact terms, O((π a_s/ℓ)²), shear and the
section's rotary inertia, O((π r/ℓ)²) (r the radius of gyration), and the axial inertia,
O((Ω/ω_axial)²).

**The published route** (δ = 0.3, ω = 1.2; Guckenheimer & Holmes 1983, Nonlinear Oscillations,
§2.2; the textbook sequence): γ = 0.20 a period-1 orbit in one well, 0.28 period 2, 0.29
period 4, 0.37 period 5, 0.50 chaos. :func:`period_doubling` gives the first doubling:
γ = 0.2655 (the multiplier of the period-1 orbit crossing −1).
Tests: tests/unit/reference/test_buckled_beam.py; the rod against it: tests/test_chaos.py.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import brentq, fsolve

#: The published route's damping and forcing frequency (module docstring).
HOLMES_DELTA, HOLMES_OMEGA = 0.3, 1.2
#: Its forcing amplitudes and the periods of their attractors (0: chaos).
HOLMES_ROUTE = {0.20: 1, 0.28: 2, 0.29: 4, 0.37: 5, 0.50: 0}


@dataclass(frozen=True)
class BuckledBeam:
    """The beam of the module docstring, SI units: ``length`` ℓ [m], ``young_modulus`` E
    [Pa], ``density`` ρ [kg/m³], ``area`` A [m²], ``inertia`` I [m⁴] (about the axis of
    bending), ``shortening`` D [m]."""

    length: float
    young_modulus: float
    density: float
    area: float
    inertia: float
    shortening: float

    @property
    def critical_shortening(self) -> float:
        """D_cr = I π²/(A ℓ) [m]."""
        return self.inertia * math.pi**2 / (self.area * self.length)

    @property
    def omega_b(self) -> float:
        """The straight beam's first bending frequency without axial force [rad/s]."""
        E, rho, A, I, L = self.young_modulus, self.density, self.area, self.inertia, self.length
        return math.pi**2 * math.sqrt(E * I / (rho * A * L**4))

    @property
    def k(self) -> float:
        """ω_b² (D/D_cr − 1) [1/s²]: the negative stiffness of the straight state."""
        return self.omega_b**2 * (self.shortening / self.critical_shortening - 1.0)

    @property
    def amplitude(self) -> float:
        """a_s = (2/π) √(ℓ (D − D_cr)) [m]: the buckled states' mid-span deflection."""
        return 2.0 / math.pi * math.sqrt(self.length * (self.shortening - self.critical_shortening))

    def damping(self, delta: float) -> float:
        """c = δ ρA √k [N s/m²] for the oscillator's δ."""
        return delta * self.density * self.area * math.sqrt(self.k)

    def frequency(self, omega: float) -> float:
        """Ω = ω √k [rad/s] for the oscillator's ω."""
        return omega * math.sqrt(self.k)

    def force(self, gamma: float) -> float:
        """f0 = γ ρA a_s k [N/m] for the oscillator's γ."""
        return gamma * self.density * self.area * self.amplitude * self.k


def duffing_flow(gamma: float, delta: float, omega: float, start, n: int, rtol: float = 1e-12):
    """The oscillator's state (x, x') after n periods 2π/ω from ``start`` at τ = 0, and the
    matrix of the variational equation over them (the monodromy, for a periodic start)."""

    def f(t, y):
        x, v = y[0], y[1]
        J = np.array([[0.0, 1.0], [1.0 - 3.0 * x * x, -delta]])
        P = y[2:].reshape(2, 2)
        rhs = [v, -delta * v + x - x**3 + gamma * math.cos(omega * t)]
        return np.concatenate([rhs, (J @ P).ravel()])

    T = 2.0 * math.pi / omega
    y0 = np.concatenate([np.asarray(start, dtype=float), np.eye(2).ravel()])
    sol = solve_ivp(f, (0.0, n * T), y0, method="DOP853", rtol=rtol, atol=rtol * 1e-2)
    return sol.y[:2, -1], sol.y[2:, -1].reshape(2, 2)


def duffing_section(
    gamma: float,
    periods: int,
    start=(1.0, 0.0),
    delta: float = HOLMES_DELTA,
    omega: float = HOLMES_OMEGA,
    rtol: float = 1e-10,
) -> np.ndarray:
    """The Poincaré section (x, x') at τ = j 2π/ω, j = 0 ... ``periods``, from ``start``:
    (periods + 1, 2)."""
    T = 2.0 * math.pi / omega

    def f(t, y):
        return [y[1], -delta * y[1] + y[0] - y[0] ** 3 + gamma * math.cos(omega * t)]

    times = np.arange(periods + 1) * T
    sol = solve_ivp(
        f, (0.0, times[-1]), start, method="DOP853", t_eval=times, rtol=rtol, atol=rtol * 1e-2
    )
    return sol.y.T


def duffing_orbit(
    gamma: float,
    guess,
    n: int = 1,
    delta: float = HOLMES_DELTA,
    omega: float = HOLMES_OMEGA,
) -> tuple[np.ndarray, np.ndarray]:
    """A periodic orbit of period n 2π/ω: its section point (x, x') at τ = 0 (Newton from
    ``guess``) and its Floquet multipliers (the monodromy's eigenvalues; their product is
    e^{−δ n 2π/ω}, Liouville)."""
    point = fsolve(
        lambda y: duffing_flow(gamma, delta, omega, y, n, 1e-12)[0] - y,
        guess,
        xtol=1e-13,
        full_output=1,
    )[0]
    return point, np.linalg.eigvals(duffing_flow(gamma, delta, omega, point, n, 1e-12)[1])


def period_doubling(
    low: float = 0.25,
    high: float = 0.27,
    guess=(0.43, 0.34),
    delta: float = HOLMES_DELTA,
    omega: float = HOLMES_OMEGA,
) -> float:
    """The forcing γ in [low, high] where the period-1 orbit in the right well (found from
    ``guess`` at ``low``, followed to each γ) has a multiplier −1: the first period doubling
    (0.2655 at the published δ, ω)."""
    state = {"point": np.asarray(guess, dtype=float)}

    def crossing(gamma: float) -> float:
        point, multipliers = duffing_orbit(gamma, state["point"], 1, delta, omega)
        state["point"] = point
        return float(np.min(multipliers.real)) + 1.0 if np.isreal(multipliers).all() else 1.0

    return brentq(crossing, low, high, xtol=1e-8)
