"""Backbone curves and forced responses of a rod's first bending mode, by perturbation: the
references of tests/test_backbone.py and docs/verification.md (section 7). No DOLFINx.

A rod of length ℓ [m], bending stiffness EI [N m²], axial stiffness EA [N] and mass ρA [kg/m]
vibrating in one plane with w(s, t) its transverse displacement. Its first linear mode φ(s)
(Euler–Bernoulli) and one coordinate q(t) carry the motion; the nonlinear terms are cubic, so
that a one-mode reduction gives the backbone exactly to its first order in the amplitude
(other modes are driven at O(q³) and act back at O(q⁵)).

**Cantilever** (clamped at s = 0, free at s = ℓ), inextensible, unshearable: with the section's
rotation ψ = q φ'(s), x' = sin ψ and z' = cos ψ, the strain energy V = ½ EI q² ∫ φ''² ds is
exactly quadratic and the nonlinearity is the inertia of the foreshortening,

    T = ½ ρA q̇² ∫ [(φ − q² G/2)² + q² H²] ds,   G(s) = ∫₀^s φ'³,  H(s) = ∫₀^s φ'²,

so T = ½ m q̇² (1 + β q²), β = (∫ H² − ∫ φ G) / ∫ φ², and the Lagrange equation
m (1 + β q²) q̈ + m β q q̇² + k q = 0 has, by harmonic balance with q = A cos ωt,
ω² = ω1² / (1 + β A²/2): ω = ω1 (1 + κ a²) with a = A φ(ℓ) the free end's amplitude [m] and
κ = −β / (4 φ(ℓ)²) [1/m²] (β < 0: the first mode hardens, κ ℓ² = 0.01938).

**Clamped at both ends** (immovable): bending stretches the axis, and the axial force, quasi-
static (the axial modes are far above), is uniform, N = EA/(2ℓ) ∫ w'² ds (Woinowsky-Krieger).
With w = q φ(s), φ(ℓ/2) = 1, the Duffing equation

    q̈ + 2ζω q̇ + ω² q + α q³ = f sin Ωt,   α = EA (∫ φ'²)² / (2 ℓ ρA ∫ φ²),

f = ∫ g φ ds / (ρA ∫ φ²) for a load density g(s) sin Ωt [N/m], q the mid-span displacement.
Its backbone is ω (1 + κ a²), κ = 3α/(8ω²), and the harmonic balance of its forced response
gives the amplitudes a of q ≈ a sin(Ωt + phase) as the positive roots of

    a² [(ω² + ¾ α a² − Ω²)² + (2ζωΩ)²] = f²,

three of them (two stable, one not) where the response is multivalued: between the
frequencies where an upward sweep jumps down and a downward one jumps up. Near resonance, with
σ = Ω/ω − 1, it reads u [(σ − κu)² + ζ²] = (f/2ω²)², u = a²: a cubic in u with three real
roots only where σ > √3 ζ, so the curve bends over once the peak amplitude a_p = f/(2ζω²)
has κ a_p² > 8/(3√3) ζ ≈ 1.54 ζ.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: β1 ℓ and β1 ℓ of the first modes (cantilever: cos βℓ cosh βℓ = −1; clamped: = +1).
CANTILEVER_BETA = 1.875104068711961
CLAMPED_BETA = 4.730040744862704
_FINE = 20001  # points of the quadratures (trapezoidal rule on smooth integrands: ~1e-9)


def _cumulative(f: np.ndarray, s: np.ndarray) -> np.ndarray:
    return np.concatenate([[0.0], np.cumsum(0.5 * np.diff(s) * (f[1:] + f[:-1]))])


def _integral(f: np.ndarray, s: np.ndarray) -> float:
    return float(np.sum(0.5 * np.diff(s) * (f[1:] + f[:-1])))


def _beam_mode(beta: float, sigma: float, s: np.ndarray, length: float):
    """φ = cosh βs − cos βs − σ (sinh βs − sin βs) and φ' [1/m] at s [m], β = ``beta``/ℓ: the
    first mode of a beam clamped at s = 0 (both end conditions there hold for any σ)."""
    b = beta / length
    x = b * np.asarray(s, dtype=float)
    phi = np.cosh(x) - np.cos(x) - sigma * (np.sinh(x) - np.sin(x))
    return phi, b * (np.sinh(x) + np.sin(x) - sigma * (np.cosh(x) - np.cos(x)))


def cantilever_mode(s: np.ndarray, length: float) -> tuple[np.ndarray, np.ndarray]:
    """φ and φ' [1/m] of the cantilever's first mode at s [m], φ(ℓ) = 2 (the usual scaling:
    ∫ φ² ds = ℓ; σ from φ''(ℓ) = 0)."""
    b = CANTILEVER_BETA
    sigma = (math.cosh(b) + math.cos(b)) / (math.sinh(b) + math.sin(b))
    return _beam_mode(b, sigma, s, length)


def clamped_mode(s: np.ndarray, length: float) -> tuple[np.ndarray, np.ndarray]:
    """φ and φ' [1/m] of the clamped–clamped beam's first mode at s [m], φ(ℓ/2) = 1 (σ from
    φ(ℓ) = 0)."""
    b = CLAMPED_BETA
    sigma = (math.cosh(b) - math.cos(b)) / (math.sinh(b) - math.sin(b))
    middle = _beam_mode(b, sigma, np.array([0.5 * length]), length)[0][0]
    phi, dphi = _beam_mode(b, sigma, s, length)
    return phi / middle, dphi / middle


def cantilever_hardening(length: float) -> float:
    """κ [1/m²] of the cantilever's backbone ω = ω1 (1 + κ a²), a the free end's amplitude
    (module docstring)."""
    s = np.linspace(0.0, length, _FINE)
    phi, dphi = cantilever_mode(s, length)
    G, H = _cumulative(dphi**3, s), _cumulative(dphi**2, s)
    beta = (_integral(H**2, s) - _integral(phi * G, s)) / _integral(phi**2, s)
    return -beta / (4.0 * phi[-1] ** 2)


def hardening_fit(shifts: dict[float, float]) -> float:
    """κ [1/m²] of ω/ω1 − 1 = κ a² + μ a⁴ through the relative frequency shifts measured at
    two amplitudes a [m] (``{a1: shift1, a2: shift2}``): the first order, the next removed."""
    (a1, s1), (a2, s2) = sorted(shifts.items())
    mu = (s2 / a2**2 - s1 / a1**2) / (a2**2 - a1**2)
    return s1 / a1**2 - mu * a1**2


def cantilever_shape(amplitude: float, length: float, s: np.ndarray):
    """The inextensible, unshearable shape ψ = q φ'(s) whose free end is displaced by
    ``amplitude`` [m] in x: the displacements x(s), z(s) − s [m] and ψ(s) [rad] at s."""
    fine = np.linspace(0.0, length, _FINE)
    dphi = cantilever_mode(fine, length)[1]

    def tip(q):
        return _integral(np.sin(q * dphi), fine)

    low, high = 0.0, amplitude / tip(1.0) * 2.0  # tip(q) ≈ 2q: bracket, then bisect
    for _ in range(200):
        middle = 0.5 * (low + high)
        low, high = (middle, high) if tip(middle) < amplitude else (low, middle)
    psi = 0.5 * (low + high) * dphi
    x, z = _cumulative(np.sin(psi), fine), _cumulative(np.cos(psi) - 1.0, fine)
    return tuple(np.interp(s, fine, f) for f in (x, z, psi))


@dataclass(frozen=True)
class Duffing:
    """The clamped–clamped rod's first mode as a Duffing oscillator (module docstring):
    ``omega`` [rad/s] its linear frequency (Euler–Bernoulli, or as measured), ``alpha``
    [1/(m² s²)], ``zeta`` the damping ratio."""

    omega: float
    alpha: float
    zeta: float = 0.0

    @classmethod
    def clamped(
        cls,
        length: float,
        EA: float,
        EI: float,
        rho_A: float,
        zeta: float = 0.0,
        omega: float | None = None,
    ) -> Duffing:
        s = np.linspace(0.0, length, _FINE)
        phi, dphi = clamped_mode(s, length)
        mass = _integral(phi**2, s)
        alpha = EA * _integral(dphi**2, s) ** 2 / (2.0 * length * rho_A * mass)
        if omega is None:
            omega = CLAMPED_BETA**2 / length**2 * math.sqrt(EI / rho_A)
        return cls(omega, alpha, zeta)

    @classmethod
    def of_clamped_scene(cls, scene, omega: float) -> Duffing:
        """The Duffing model of a scene's rectangular rod clamped at both ends, bending in x
        (about d2: EI = E b a³/12), its first frequency ``omega`` [rad/s] (the rod's own, e.g.
        from cosserat-fem modes) and ζ = c_t / (2ρAω) of its viscous damping.translational."""
        rod = scene.rod
        a, b, E = rod.section.a, rod.section.b, rod.material.young_modulus
        rho_A = rod.material.density * a * b
        zeta = scene.damping.translational / (2.0 * rho_A * omega)
        return cls.clamped(rod.length, E * a * b, E * b * a**3 / 12, rho_A, zeta, omega=omega)

    @property
    def hardening(self) -> float:
        """κ [1/m²]: the backbone ω (1 + κ a²)."""
        return 3.0 * self.alpha / (8.0 * self.omega**2)

    def backbone(self, a: np.ndarray) -> np.ndarray:
        """The frequency [rad/s] of free vibration at amplitude a [m], √(ω² + ¾ α a²)."""
        return np.sqrt(self.omega**2 + 0.75 * self.alpha * np.asarray(a) ** 2)

    def amplitudes(self, f: float, Omega: float) -> list[float]:
        """The steady amplitudes [m] under f sin Ωt (f [m/s²], Ω [rad/s]): the positive roots
        of the harmonic balance (module docstring), ascending; one or three."""
        c = 0.75 * self.alpha
        d = self.omega**2 - Omega**2
        damping = (2.0 * self.zeta * self.omega * Omega) ** 2
        roots = np.roots([c * c, 2.0 * c * d, d * d + damping, -f * f])
        found = [math.sqrt(r.real) for r in roots if abs(r.imag) <= 1e-9 * abs(r) and r.real > 0]
        return sorted(found)


def clamped_modal_force(load: np.ndarray, s: np.ndarray, length: float, rho_A: float) -> float:
    """f [m/s²] of a load density ``load`` (g(s) [N/m] at s [m]) on the clamped rod's first
    mode: ∫ g φ ds / (ρA ∫ φ² ds)."""
    phi = clamped_mode(s, length)[0]
    return _integral(load * phi, s) / (rho_A * _integral(phi**2, s))


def clamped_shape(amplitude: float, length: float, s: np.ndarray):
    """The first mode's shape with mid-span displacement ``amplitude`` [m], the axis stretched
    uniformly (z' = ε − w'²/2 with ε = ∫ w'²/(2ℓ), so that z(ℓ) = 0: the quasi-static state of
    the Duffing model) and unsheared (ψ = atan(w'/(1 + z'))): x(s), z(s) − s [m], ψ(s) [rad]."""
    fine = np.linspace(0.0, length, _FINE)
    phi, dphi = clamped_mode(fine, length)
    w, dw = amplitude * phi, amplitude * dphi
    dz = _integral(dw**2, fine) / (2.0 * length) - 0.5 * dw**2
    z = _cumulative(dz, fine)
    psi = np.arctan2(dw, 1.0 + dz)
    return tuple(np.interp(s, fine, f) for f in (w, z, psi))
