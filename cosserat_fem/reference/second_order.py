r"""Second-order (weakly nonlinear) reference for the axial motion and twist of the cantilever.

Pure numpy/scipy; this module must never import DOLFINx. It is an independent check of the
two purely nonlinear free-end responses of the Cao & Tucker (2008) example, the axial
displacement z(ℓ, t) and the twist φ(ℓ, t), which vanish in linear theory and are driven by
products of the first-order (linear Timoshenko) bending fields.

Problem
-------
Cantilever clamped at s = 0, free at s = ℓ; rectangular section a (along d1) × b (along d2):
A = ab, c11 = a b³/12, c22 = b a³/12, c33 the Saint-Venant torsion constant (:mod:`.torsion`:
the double Fourier series of Prandtl's stress function, not the solver's single series),
G = E/(2(1+ν)); transverse loads f_x = q_x sin(πs/ℓ) sin Ωt, f_y = q_y sin(πs/ℓ) sin Ωt in
fixed directions, from rest.

First order (decoupled linear Timoshenko planes, :mod:`.timoshenko`):

* x-plane: deflection x, rotation ψ, I = c22; shear strain γ1 = x' − ψ;
* y-plane: deflection y, rotation β, I = c11; shear strain γ2 = y' − β. The Cosserat Euler
  angle is θ = −β (so y' ≈ −θ).

Second order. Expanding the directors, d3 ≈ (ψ, −θ, 1 − (ψ² + θ²)/2), d13 ≈ −ψ, d23 ≈ θ,
and the strains, v1 ≈ γ1, v2 ≈ y' + θ = γ2, v3 − 1 ≈ z' + x'ψ − y'θ − (θ² + ψ²)/2,
u1 ≈ θ', u2 ≈ ψ', u3 = φ' − ψ' sin θ ≈ φ' − ψ'θ, w1 ≈ θ_t, w2 ≈ ψ_t, w3 ≈ φ_t − ψ_tθ, the
e3-component of the force balance and the d3-component of the moment balance give

.. math::

    \rho A\, z_{tt} &= \partial_s N, \qquad N = EA\, z' + N_2, \\
    N_2 &= EA\,\bigl(x'\psi + y'\beta - \tfrac12(\psi^2 + \beta^2)\bigr)
           - \kappa G A\,(\psi\gamma_1 + \beta\gamma_2), \\
    \rho I_{33}\,\bigl(\phi_{tt} - \partial_t(\psi_t\theta)\bigr)
        + \rho (c_{22} - c_{11})\,\theta_t\psi_t
      &= \partial_s\bigl(G c_{33}\,(\phi' - \psi'\theta)\bigr)
        + E (c_{22} - c_{11})\,\theta'\psi',

with z(0) = φ(0) = 0, N(ℓ) = 0 and G c33 (φ' − ψ'θ)(ℓ) = 0. I33 = ρJ with J = c11 + c22
(``torsion_inertia="polar"``, the physically consistent rotary inertia) or J = c33
(``"printed"``, as printed in the paper's eq. (54)).

Method
------
Galerkin projection on the clamped-free modes χ_k(s) = sin(λ_k s), λ_k = (2k−1)π/(2ℓ),
k = 1..K, with the natural end conditions built into the weak forms

.. math::

    \rho A\,\tfrac{\ell}{2}\, a_k'' + EA\,\lambda_k^2\tfrac{\ell}{2}\, a_k
        &= -\int_0^\ell N_2\,\chi_k'\,ds, \\
    \rho J\,\tfrac{\ell}{2}\, b_k'' + G c_{33}\lambda_k^2\tfrac{\ell}{2}\, b_k
        &= \int_0^\ell \Bigl[G c_{33}\,\psi'\theta\,\chi_k'
          + \bigl(\rho J\,\partial_t(\psi_t\theta) - \rho(c_{22}-c_{11})\,\theta_t\psi_t
          + E(c_{22}-c_{11})\,\theta'\psi'\bigr)\chi_k\Bigr] ds,

from rest. The first-order fields are finite modal sums (N mass-normalised Timoshenko modes
per plane) with the closed-form Duhamel coordinates
η_i = A_i sin Ωt + B_i sin ω_i t, A_i = Q_i/(ω_i² − Ω²), B_i = −(Ω/ω_i) A_i, so
η_i'' = −ω_i² η_i + Q_i sin Ωt exactly. Every right-hand side is therefore a quadratic form
F_k(t) = Σ_ij C_ijk η_i^(a)(t) η_j^(b)(t) whose spatial coefficients C_ijk are integrals of
mode-shape products, evaluated to rounding by composite Gauss-Legendre quadrature. Expanding
the products of sinusoids, F_k is a finite sum of cos νt and sin νt (ν = ν_f ± ν_g over the
frequencies {Ω, ω_1, ..., ω_N} of the two planes), and each modal oscillator is solved from rest
in closed form (``method="closed-form"``, default; resonance-safe sinc forms) or, as a
cross-check, by scipy's DOP853 (``method="ode"``).

Static correction (mode acceleration). Because N_2(ℓ) ≠ 0, EA z'(ℓ) = −N_2(ℓ) ≠ 0 while every
χ_k'(ℓ) = 0, so the plain modal sum for z(ℓ) converges only like 1/K. With
``static_correction=True`` (default) the quasi-static part is taken in closed form instead,

.. math::

    z(s,t) = z_{qs}(s,t) + \sum_{k\le K} \bigl(a_k(t) - F_k(t)/k_k\bigr)\chi_k(s), \qquad
    z_{qs}(s,t) = -\frac{1}{EA}\int_0^s N_2\,d\sigma,

and likewise φ_qs(s) = ∫_0^s ψ'θ dσ + (1/(G c33)) ∫_0^ℓ min(s, σ) f(σ) dσ with f the
distributed torsional forcing in parentheses above (the exact static solution of the torsion
problem with f treated as a load). The remaining dynamic sum converges like K⁻⁴ or faster.

Validation (paper case, 0 ≤ t ≤ 0.06 s; tests/test_second_order_reference.py)
-------------------------------------------------------------------------------
z(ℓ, t) ∈ [−4.137e-6, 0] m and φ(ℓ, t) ∈ [−4.506e-5, 2.383e-5] rad (``"printed"``:
φ ∈ [−3.42e-5, 1.31e-5] rad, 34 % relative L2 change). The default truncation (16 linear modes
per plane, K = 16) agrees with (20, 24) to ~1e-6 relative. Against the nonlinear FE solver
(24 P3 cells, generalized-α, 0 ≤ t ≤ 0.02 s) the relative L2 differences are 1.7e-4 (z) and
2.9e-4 (φ) at Δt = 5e-6 s, 0.8e-4 and 1.5e-4 at Δt = 1.25e-6 s; the remainder scales like q0²,
i.e. it is the next (fourth-order) term of the expansion, not a discretisation error.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.integrate import solve_ivp

from cosserat_fem.reference.timoshenko import (
    TimoshenkoBeam,
    TimoshenkoMode,
    modal_loads,
    mode_shapes,
)
from cosserat_fem.reference.torsion import rectangle_torsion_constant

__all__ = [
    "PAPER_ROD",
    "PAPER_Q0",
    "PAPER_OMEGA",
    "RodData",
    "SecondOrderResponse",
    "axial_force_second_order",
    "rectangle_torsion_constant",
    "second_order_response",
    "second_order_tip_response",
    "static_axial_displacement",
    "static_twist",
    "torsion_forcing_second_order",
]

FloatArray = NDArray[np.float64]
TorsionInertia = Literal["polar", "printed"]
Method = Literal["closed-form", "ode"]

_NODES = 24  # Gauss-Legendre points per panel


# --------------------------------------------------------------------------------------------
# Rod data
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class RodData:
    """Uniform rectangular rod, SI units: extent ``a`` along d1, ``b`` along d2.

    Attributes:
        length: ℓ [m]; a, b: section sides [m]; young: E [Pa]; poisson: ν [-];
        kappa: shear correction factor κ [-]; density: ρ [kg/m³].
    """

    length: float
    a: float
    b: float
    young: float
    poisson: float
    kappa: float
    density: float

    @property
    def area(self) -> float:
        """A = a b."""
        return self.a * self.b

    @property
    def c11(self) -> float:
        """c11 = a b³/12 (bending about d1: y-plane)."""
        return self.a * self.b**3 / 12.0

    @property
    def c22(self) -> float:
        """c22 = b a³/12 (bending about d2: x-plane)."""
        return self.b * self.a**3 / 12.0

    @property
    def c33(self) -> float:
        """Saint-Venant torsion constant, the reference's own (:mod:`.torsion`; within
        1.5e-11 of forms/section.py's series for the paper's section)."""
        return rectangle_torsion_constant(self.a, self.b)

    @property
    def shear(self) -> float:
        """G = E/(2(1+ν))."""
        return self.young / (2.0 * (1.0 + self.poisson))

    def torsion_inertia(self, rule: TorsionInertia = "polar") -> float:
        """J in I33 = ρJ: c11 + c22 (``"polar"``) or c33 (``"printed"``, eq. (54))."""
        if rule == "polar":
            return self.c11 + self.c22
        if rule == "printed":
            return self.c33
        raise ValueError(f"unknown torsion_inertia {rule!r}; expected 'polar' or 'printed'")

    @property
    def beam_x(self) -> TimoshenkoBeam:
        """x-plane (deflection x, rotation ψ): depth a, I = c22."""
        return TimoshenkoBeam.rectangular(
            self.length, self.a, self.b, self.young, self.poisson, self.kappa, self.density
        )

    @classmethod
    def from_scene(cls, scene) -> RodData:
        """The rod of a scene (rectangular section; ν from E and G when G was given)."""
        rod, mat = scene.rod, scene.rod.material
        return cls(
            length=rod.length,
            a=rod.section.a,
            b=rod.section.b,
            young=mat.young_modulus,
            poisson=mat.young_modulus / (2.0 * mat.shear_modulus) - 1.0,
            kappa=rod.section.shear_coefficient,
            density=mat.density,
        )

    @property
    def beam_y(self) -> TimoshenkoBeam:
        """y-plane (deflection y, rotation β = −θ): depth b, I = c11."""
        return TimoshenkoBeam.rectangular(
            self.length, self.b, self.a, self.young, self.poisson, self.kappa, self.density
        )


#: The paper's rod (section 6), its load amplitude [N/m] and forcing frequency 8 ω0 [rad/s].
PAPER_ROD = RodData(
    length=1.0, a=0.04, b=0.06, young=7.1e10, poisson=0.32, kappa=0.833, density=2730.0
)
PAPER_Q0 = 2.0e3
PAPER_OMEGA = 8.0 * 207.0236


# --------------------------------------------------------------------------------------------
# Second-order forcing on given fields
# --------------------------------------------------------------------------------------------
def axial_force_second_order(
    rod: RodData,
    dx: ArrayLike,
    psi: ArrayLike,
    dy: ArrayLike = 0.0,
    beta: ArrayLike = 0.0,
) -> FloatArray:
    """N2 = EA (x'ψ + y'β − (ψ² + β²)/2) − κGA (ψ γ1 + β γ2), γ1 = x' − ψ, γ2 = y' − β.

    The quadratic part of the axial force N = EA z' + N2 (elementwise on given fields).
    """
    dx, psi, dy, beta = (np.asarray(v, dtype=float) for v in (dx, psi, dy, beta))
    EA = rod.young * rod.area
    kGA = rod.kappa * rod.shear * rod.area
    return EA * (dx * psi + dy * beta - 0.5 * (psi**2 + beta**2)) - kGA * (
        psi * (dx - psi) + beta * (dy - beta)
    )


def torsion_forcing_second_order(
    rod: RodData,
    dpsi: ArrayLike,
    beta: ArrayLike,
    dbeta: ArrayLike,
    psi_t: ArrayLike = 0.0,
    psi_tt: ArrayLike = 0.0,
    beta_t: ArrayLike = 0.0,
    torsion_inertia: TorsionInertia = "polar",
) -> tuple[FloatArray, FloatArray]:
    """(pre-twist ψ'θ, distributed torque f) of the second-order torsion problem, θ = −β.

    The twist obeys ρJ φ_tt = ∂s(G c33 (φ' − ψ'θ)) + f with
    f = ρJ ∂t(ψ_t θ) − ρ(c22 − c11) θ_t ψ_t + E(c22 − c11) θ'ψ',
    ∂t(ψ_tθ) = ψ_tt θ + ψ_t θ_t (elementwise on given fields and rates).
    """
    dpsi, beta, dbeta, psi_t, psi_tt, beta_t = (
        np.asarray(v, dtype=float) for v in (dpsi, beta, dbeta, psi_t, psi_tt, beta_t)
    )
    theta, dtheta, theta_t = -beta, -dbeta, -beta_t
    rho, dc = rod.density, rod.c22 - rod.c11
    J = rod.torsion_inertia(torsion_inertia)
    f = (
        rho * J * (psi_tt * theta + psi_t * theta_t)
        - rho * dc * theta_t * psi_t
        + rod.young * dc * dtheta * dpsi
    )
    return dpsi * theta, f


# --------------------------------------------------------------------------------------------
# Quadrature
# --------------------------------------------------------------------------------------------
def _gauss(a: float, b: float, panels: int, nodes: int = _NODES) -> tuple[FloatArray, FloatArray]:
    """Composite Gauss-Legendre rule on [a, b]: (points, weights)."""
    x, wq = np.polynomial.legendre.leggauss(nodes)
    edges = np.linspace(a, b, panels + 1)
    half = 0.5 * np.diff(edges)
    mid = 0.5 * (edges[1:] + edges[:-1])
    return (mid[:, None] + half[:, None] * x[None, :]).ravel(), (half[:, None] * wq).ravel()


@dataclass(frozen=True)
class _StationRule:
    """Nodes on [0, ℓ] split at the station s, with the weights of ∫_0^s g and ∫ min(s,σ) g."""

    points: FloatArray
    w_cumulative: FloatArray
    w_green: FloatArray


def _station_rule(s: float, length: float, wavenumber: float) -> _StationRule:
    """Rules for ∫_0^s g dσ and ∫_0^ℓ min(s, σ) g(σ) dσ, exact for smooth g (split at s)."""
    parts_p, parts_c, parts_g = [], [], []
    if s > 0.0:
        p, w = _gauss(0.0, s, max(2, math.ceil(wavenumber * s / 4.0)))
        parts_p.append(p)
        parts_c.append(w)
        parts_g.append(w * p)
    if s < length:
        p, w = _gauss(s, length, max(2, math.ceil(wavenumber * (length - s) / 4.0)))
        parts_p.append(p)
        parts_c.append(np.zeros_like(w))
        parts_g.append(w * s)
    return _StationRule(np.concatenate(parts_p), np.concatenate(parts_c), np.concatenate(parts_g))


def static_axial_displacement(
    rod: RodData, s: ArrayLike, n2: Callable[[FloatArray], ArrayLike]
) -> FloatArray:
    """Static axial displacement z(s) = −(1/EA) ∫_0^s N2 dσ (so that N = EA z' + N2 = 0).

    ``n2`` is a vectorised callable σ ↦ N2(σ), e.g. built with
    :func:`axial_force_second_order` from given first-order fields.
    """
    s = np.asarray(s, dtype=float)
    EA = rod.young * rod.area
    out = []
    for si in s.ravel():
        r = _station_rule(float(si), rod.length, 64.0 / rod.length)
        vals = np.broadcast_to(np.asarray(n2(r.points), dtype=float), r.points.shape)
        out.append(-float(np.sum(r.w_cumulative * vals)) / EA)
    return np.asarray(out).reshape(s.shape)


def static_twist(
    rod: RodData,
    s: ArrayLike,
    pretwist: Callable[[FloatArray], ArrayLike],
    torque: Callable[[FloatArray], ArrayLike],
) -> FloatArray:
    """Static twist φ(s) = ∫_0^s ψ'θ dσ + (1/(G c33)) ∫_0^ℓ min(s, σ) f(σ) dσ.

    The solution of ∂s(G c33 (φ' − ψ'θ)) + f = 0, φ(0) = 0, G c33 (φ' − ψ'θ)(ℓ) = 0 for a
    pre-twist σ ↦ ψ'θ and a distributed torque σ ↦ f (see :func:`torsion_forcing_second_order`).
    """
    s = np.asarray(s, dtype=float)
    Gc33 = rod.shear * rod.c33
    out = []
    for si in s.ravel():
        r = _station_rule(float(si), rod.length, 64.0 / rod.length)
        k0 = np.broadcast_to(np.asarray(pretwist(r.points), dtype=float), r.points.shape)
        f = np.broadcast_to(np.asarray(torque(r.points), dtype=float), r.points.shape)
        out.append(float(np.sum(r.w_cumulative * k0) + np.sum(r.w_green * f) / Gc33))
    return np.asarray(out).reshape(s.shape)


# --------------------------------------------------------------------------------------------
# First-order modal coordinates
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class _Plane:
    """Modal data of one linear plane: η_i = A_i sin Ωt + B_i sin ω_i t (from rest)."""

    modes: tuple[TimoshenkoMode, ...]
    omega: FloatArray
    Q: FloatArray
    A: FloatArray
    B: FloatArray
    Omega: float

    @classmethod
    def build(cls, beam: TimoshenkoBeam, q: float, Omega: float, count: int) -> _Plane:
        modes = tuple(mode_shapes(beam, count))
        omega = np.array([m.omega for m in modes])
        close = np.abs(omega - Omega) < 1e-9 * omega
        if np.any(close):
            raise ValueError(
                f"forcing frequency {Omega} rad/s coincides with a bending frequency "
                f"{omega[close][0]} rad/s (exact resonance is not supported)"
            )
        Q = modal_loads(beam, q, None, modes)
        A = Q / (omega**2 - Omega**2)
        return cls(modes, omega, Q, A, -(Omega / omega) * A, float(Omega))

    @property
    def frequencies(self) -> FloatArray:
        """ν = (Ω, ω_1, ..., ω_N)."""
        return np.concatenate(([self.Omega], self.omega))

    def spectral(self, order: int) -> tuple[FloatArray, str]:
        """(E, kind): d^order η_i/dt^order = Σ_f E[i, f] kind(ν_f t), kind 'sin' or 'cos'."""
        n = self.omega.size
        E = np.zeros((n, n + 1))
        E[:, 0] = self.A
        E[np.arange(n), np.arange(1, n + 1)] = self.B
        nu = self.frequencies
        factor, kind = {0: (1.0, "sin"), 1: (1.0, "cos"), 2: (-1.0, "sin")}[order]
        return factor * E * nu[None, :] ** order, kind

    def eta(self, t: FloatArray, order: int) -> FloatArray:
        """d^order η/dt^order at times t (1-D), shape (T, N); η'' = −ω²η + Q sin Ωt."""
        t = t[:, None]
        sO, sw = np.sin(self.Omega * t), np.sin(self.omega * t)
        if order == 0:
            return self.A * sO + self.B * sw
        if order == 1:
            return self.A * self.Omega * np.cos(self.Omega * t) + self.B * self.omega * np.cos(
                self.omega * t
            )
        if order == 2:
            return -(self.omega**2) * (self.A * sO + self.B * sw) + self.Q * sO
        raise ValueError(f"order must be 0, 1 or 2, got {order}")

    def shapes(self, s: FloatArray) -> dict[str, FloatArray]:
        """Mode-shape arrays (N, len(s)): W', Ψ, Ψ'."""
        return {
            "dW": np.array([m.W(s, derivative=1) for m in self.modes]),
            "Psi": np.array([m.Psi(s) for m in self.modes]),
            "dPsi": np.array([m.Psi(s, derivative=1) for m in self.modes]),
        }


@dataclass(frozen=True)
class _Term:
    """C[i, j, k] η_p,i^(a) η_q,j^(b): a quadratic form in the modal coordinates."""

    p: str
    a: int
    q: str
    b: int
    C: FloatArray


@dataclass
class _Spectrum:
    """Σ_m amp[m, k] kind(ν_m t) for kind in cos/sin (ν ≥ 0), per output column k."""

    cos_nu: FloatArray
    cos_amp: FloatArray
    sin_nu: FloatArray
    sin_amp: FloatArray

    def evaluate(self, t: FloatArray) -> FloatArray:
        return (
            np.cos(np.outer(t, self.cos_nu)) @ self.cos_amp
            + np.sin(np.outer(t, self.sin_nu)) @ self.sin_amp
        )


def _merge(nu: FloatArray, amp: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Add the amplitudes of equal frequencies (exact duplicates such as |ν_f − ν_g|)."""
    uniq, inv = np.unique(nu, return_inverse=True)
    out = np.zeros((uniq.size, amp.shape[1]))
    np.add.at(out, inv, amp)
    return uniq, out


def _spectrum(terms: Sequence[_Term], planes: dict[str, _Plane]) -> _Spectrum:
    """Expand Σ_terms C_ijk η^(a) η^(b) into cosines and sines (product-to-sum formulas)."""
    cos_nu, cos_amp, sin_nu, sin_amp = [], [], [], []
    for term in terms:
        Ea, ka = planes[term.p].spectral(term.a)
        Eb, kb = planes[term.q].spectral(term.b)
        H = np.einsum("if,jg,ijk->fgk", Ea, Eb, term.C, optimize=True)
        nf, ng = planes[term.p].frequencies, planes[term.q].frequencies
        plus = (nf[:, None] + ng[None, :]).ravel()
        minus = (nf[:, None] - ng[None, :]).ravel()
        H = 0.5 * H.reshape(-1, H.shape[-1])
        if ka == "sin" and kb == "sin":  # sin a sin b = [cos(a−b) − cos(a+b)]/2
            cos_nu += [np.abs(minus), plus]
            cos_amp += [H, -H]
        elif ka == "cos" and kb == "cos":  # cos a cos b = [cos(a−b) + cos(a+b)]/2
            cos_nu += [np.abs(minus), plus]
            cos_amp += [H, H]
        else:  # sin a cos b = [sin(a+b) + sin(a−b)]/2; cos a sin b = [sin(a+b) − sin(a−b)]/2
            sgn = 1.0 if ka == "sin" else -1.0
            sin_nu += [plus, np.abs(minus)]
            sin_amp += [H, sgn * np.sign(minus)[:, None] * H]
    empty = (np.zeros(0), np.zeros((0, terms[0].C.shape[-1])))
    c = _merge(np.concatenate(cos_nu), np.concatenate(cos_amp)) if cos_nu else empty
    s = _merge(np.concatenate(sin_nu), np.concatenate(sin_amp)) if sin_nu else empty
    return _Spectrum(c[0], c[1], s[0], s[1])


def _direct(terms: Sequence[_Term], planes: dict[str, _Plane], t: FloatArray) -> FloatArray:
    """Σ_terms C_ijk η^(a)(t) η^(b)(t) evaluated directly, shape (T, K)."""
    out = 0.0
    for term in terms:
        ea = planes[term.p].eta(t, term.a)
        eb = planes[term.q].eta(t, term.b)
        out = out + np.einsum("ti,tj,ijk->tk", ea, eb, term.C, optimize=True)
    return np.asarray(out)


# --------------------------------------------------------------------------------------------
# Modal oscillators from rest
# --------------------------------------------------------------------------------------------
def _sinc(x: FloatArray) -> FloatArray:
    """sin x / x, 1 at x = 0."""
    zero = x == 0.0
    return np.where(zero, 1.0, np.sin(x) / np.where(zero, 1.0, x))


class _HalfAngles:
    """cos(νt/2), sin(νt/2) of every line ν at every time t, shape (T, M): computed once for
    all the modal oscillators, whose phases (ω ± ν)t/2 follow by the addition theorems."""

    def __init__(self, nu: FloatArray, t: FloatArray):
        self.nu, self.t = nu, t[:, None]
        self.cos, self.sin = np.cos(0.5 * nu * self.t), np.sin(0.5 * nu * self.t)

    def full(self) -> tuple[FloatArray, FloatArray]:
        """cos νt, sin νt (the double angles)."""
        return self.cos**2 - self.sin**2, 2.0 * self.cos * self.sin


def _response_cos(lines: _HalfAngles, omega: float) -> FloatArray:
    """x'' + ω² x = cos νt from rest: (cos νt − cos ωt)/(ω² − ν²)
    = t sin((ω+ν)t/2) sinc((ω−ν)t/2)/(ω+ν), resonance-safe; (T, M)."""
    tt, nu = lines.t, lines.nu
    sw, cw = np.sin(0.5 * omega * tt), np.cos(0.5 * omega * tt)
    return tt * (sw * lines.cos + cw * lines.sin) * _sinc(0.5 * (omega - nu) * tt) / (omega + nu)


def _response_sin(lines: _HalfAngles, omega: float) -> FloatArray:
    """x'' + ω² x = sin νt from rest: (sin νt − (ν/ω) sin ωt)/(ω² − ν²)
    = (sin ωt/ω − t cos((ω+ν)t/2) sinc((ν−ω)t/2))/(ω+ν), resonance-safe; (T, M)."""
    tt, nu = lines.t, lines.nu
    sw, cw = np.sin(0.5 * omega * tt), np.cos(0.5 * omega * tt)
    return (
        np.sin(omega * tt) / omega
        - tt * (cw * lines.cos - sw * lines.sin) * _sinc(0.5 * (nu - omega) * tt)
    ) / (omega + nu)


@dataclass(frozen=True)
class _ModalProblem:
    """(mass ℓ/2) a_k'' + (stiffness λ_k² ℓ/2) a_k = F_k(t) on χ_k = sin λ_k s.

    ``galerkin`` holds the quadratic forms of F_k, ``stations`` those of the quasi-static
    solution at the output stations.
    """

    mass: float  # ρA or ρJ
    stiffness: float  # EA or G c33
    lam: FloatArray
    galerkin: list[_Term]
    stations: list[_Term]

    @property
    def omega(self) -> FloatArray:
        return self.lam * math.sqrt(self.stiffness / self.mass)

    def modal_stiffness(self, length: float) -> FloatArray:
        return self.stiffness * self.lam**2 * 0.5 * length


def _solve_closed_form(
    prob: _ModalProblem, planes: dict[str, _Plane], t: FloatArray, length: float, correct: bool
) -> FloatArray:
    """Modal coordinates a_k(t) (or a_k − F_k/k_k if ``correct``), shape (T, K)."""
    spec = _spectrum(prob.galerkin, planes)
    m = prob.mass * 0.5 * length
    cos_lines, sin_lines = _HalfAngles(spec.cos_nu, t), _HalfAngles(spec.sin_nu, t)
    out = np.empty((t.size, prob.lam.size))
    for k, om in enumerate(prob.omega):
        rc = _response_cos(cos_lines, om)
        rs = _response_sin(sin_lines, om)
        out[:, k] = (rc @ spec.cos_amp[:, k] + rs @ spec.sin_amp[:, k]) / m
    if correct:  # the quasi-static part F_k(t)/(m ω_k²), the same lines for every mode
        forcing = cos_lines.full()[0] @ spec.cos_amp + sin_lines.full()[1] @ spec.sin_amp
        out -= forcing / (m * prob.omega**2)
    return out


def _solve_ode(
    prob: _ModalProblem,
    planes: dict[str, _Plane],
    t: FloatArray,
    length: float,
    correct: bool,
    rtol: float,
) -> FloatArray:
    """As :func:`_solve_closed_form`, by DOP853 with the forcing evaluated directly."""
    m = prob.mass * 0.5 * length
    om2 = prob.omega**2
    K = om2.size
    kk = prob.modal_stiffness(length)
    scale = float(np.max(np.abs(_direct(prob.galerkin, planes, t)) / kk)) if t.size else 1.0

    def rhs(tau: float, y: FloatArray) -> FloatArray:
        F = _direct(prob.galerkin, planes, np.array([tau]))[0]
        return np.concatenate((y[K:], F / m - om2 * y[:K]))

    order = np.argsort(t)
    ts = t[order]
    sol = solve_ivp(
        rhs,
        (0.0, float(ts[-1]) if ts.size else 0.0),
        np.zeros(2 * K),
        method="DOP853",
        t_eval=ts,
        rtol=rtol,
        atol=1e-6 * rtol * max(scale, 1e-300),
    )
    if not sol.success:
        raise RuntimeError(f"DOP853 failed: {sol.message}")
    a = np.empty((t.size, K))
    a[order] = sol.y[:K].T
    if correct:
        a = a - _direct(prob.galerkin, planes, t) / kk
    return a


# --------------------------------------------------------------------------------------------
# Assembly of the quadratic forms
# --------------------------------------------------------------------------------------------
def _problems(
    rod: RodData,
    planes: dict[str, _Plane],
    s: FloatArray,
    axial_modes: int,
    torsion_modes: int,
    torsion_inertia: TorsionInertia,
) -> tuple[_ModalProblem, _ModalProblem]:
    ell = rod.length
    E, G, rho = rod.young, rod.shear, rod.density
    EA, kGA = E * rod.area, rod.kappa * G * rod.area
    Gc33, dc = G * rod.c33, rod.c22 - rod.c11
    J = rod.torsion_inertia(torsion_inertia)
    lam_a = (2 * np.arange(1, axial_modes + 1) - 1) * math.pi / (2.0 * ell)
    lam_t = (2 * np.arange(1, torsion_modes + 1) - 1) * math.pi / (2.0 * ell)
    beta_max = max(m.beta for pl in planes.values() for m in pl.modes)
    wavenumber = 2.0 * beta_max + max(lam_a[-1], lam_t[-1])

    # Galerkin integrals on [0, ℓ].
    pts, wts = _gauss(0.0, ell, max(8, math.ceil(wavenumber * ell / 4.0)))
    sx, sy = planes["x"].shapes(pts), planes["y"].shapes(pts)

    def gal(f: FloatArray, g: FloatArray, chi: FloatArray) -> FloatArray:
        return np.einsum("n,in,jn,kn->ijk", wts, f, g, chi, optimize=True)

    axial: list[_Term] = []
    chi, dchi = np.sin(np.outer(lam_a, pts)), lam_a[:, None] * np.cos(np.outer(lam_a, pts))
    for name, sh in (("x", sx), ("y", sy)):
        # n_ij = (EA − κGA) W_i' Ψ_j − (EA/2 − κGA) Ψ_i Ψ_j ;  F_k = −∫ N2 χ_k'
        C = -(EA - kGA) * gal(sh["dW"], sh["Psi"], dchi) + (0.5 * EA - kGA) * gal(
            sh["Psi"], sh["Psi"], dchi
        )
        axial.append(_Term(name, 0, name, 0, C))
    chi, dchi = np.sin(np.outer(lam_t, pts)), lam_t[:, None] * np.cos(np.outer(lam_t, pts))
    P = gal(sx["Psi"], sy["Psi"], chi)
    torsion = [  # θ = −β
        _Term(
            "x",
            0,
            "y",
            0,
            -Gc33 * gal(sx["dPsi"], sy["Psi"], dchi) - E * dc * gal(sx["dPsi"], sy["dPsi"], chi),
        ),
        _Term("x", 2, "y", 0, -rho * J * P),
        _Term("x", 1, "y", 1, -rho * (J - dc) * P),
    ]

    # Quasi-static parts at the stations (columns = stations).
    n = {name: pl.omega.size for name, pl in planes.items()}
    ax_xx, ax_yy = np.zeros((n["x"], n["x"], s.size)), np.zeros((n["y"], n["y"], s.size))
    t00, t20, t11 = (np.zeros((n["x"], n["y"], s.size)) for _ in range(3))
    for m, si in enumerate(s):
        r = _station_rule(float(si), ell, wavenumber)
        rx, ry = planes["x"].shapes(r.points), planes["y"].shapes(r.points)
        wc, wg = r.w_cumulative, r.w_green

        def q(w: FloatArray, f: FloatArray, g: FloatArray) -> FloatArray:
            return np.einsum("n,in,jn->ij", w, f, g, optimize=True)

        for out, sh in ((ax_xx, rx), (ax_yy, ry)):
            out[:, :, m] = (
                -(
                    (EA - kGA) * q(wc, sh["dW"], sh["Psi"])
                    - (0.5 * EA - kGA) * q(wc, sh["Psi"], sh["Psi"])
                )
                / EA
            )
        Pg = q(wg, rx["Psi"], ry["Psi"]) / Gc33
        t00[:, :, m] = -q(wc, rx["dPsi"], ry["Psi"]) - E * dc / Gc33 * q(wg, rx["dPsi"], ry["dPsi"])
        t20[:, :, m] = -rho * J * Pg
        t11[:, :, m] = -rho * (J - dc) * Pg
    ax_st = [_Term("x", 0, "x", 0, ax_xx), _Term("y", 0, "y", 0, ax_yy)]
    tor_st = [_Term("x", 0, "y", 0, t00), _Term("x", 2, "y", 0, t20), _Term("x", 1, "y", 1, t11)]
    return (
        _ModalProblem(rho * rod.area, EA, lam_a, axial, ax_st),
        _ModalProblem(rho * J, Gc33, lam_t, torsion, tor_st),
    )


# --------------------------------------------------------------------------------------------
# Public driver
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class SecondOrderResponse:
    """Result of :func:`second_order_response`; unpacks as ``z, phi``.

    Attributes:
        z, phi: axial displacement [m] and twist [rad], shape ``times.shape + s.shape``.
        z_quasi_static, phi_quasi_static: their quasi-static parts z_qs, φ_qs (zero arrays if
            ``static_correction=False``).
        z_last_mode, phi_last_mode: max over time of the last retained axial / torsional
            modal term at the stations (a truncation indicator), shape ``s.shape``.
        axial_frequencies, torsion_frequencies: ω_k of the Galerkin modes [rad/s].
        omega_x, omega_y: the linear bending frequencies used [rad/s].
    """

    z: FloatArray
    phi: FloatArray
    z_quasi_static: FloatArray
    phi_quasi_static: FloatArray
    z_last_mode: FloatArray
    phi_last_mode: FloatArray
    axial_frequencies: FloatArray
    torsion_frequencies: FloatArray
    omega_x: FloatArray
    omega_y: FloatArray
    info: dict[str, object] = field(default_factory=dict)

    def __iter__(self):
        return iter((self.z, self.phi))


def second_order_response(
    rod: RodData,
    q0: float | tuple[float, float],
    Omega: float,
    times: ArrayLike,
    s: ArrayLike | None = None,
    torsion_inertia: TorsionInertia = "polar",
    linear_modes: int | tuple[int, int] = 16,
    axial_modes: int = 16,
    torsion_modes: int | None = None,
    static_correction: bool = True,
    method: Method = "closed-form",
    rtol: float = 1e-10,
) -> SecondOrderResponse:
    r"""Second-order z(s, t) and φ(s, t) of the cantilever under f_x, f_y = q sin(πs/ℓ) sin Ωt.

    See the module docstring for the equations and the method.

    Args:
        rod: section and material data.
        q0: load amplitude [N/m] in both planes, or ``(q_x, q_y)``.
        Omega: forcing frequency Ω [rad/s] (must not equal a bending frequency exactly).
        times: evaluation times [s] (any shape, ≥ 0); the motion starts from rest at t = 0.
        s: stations [m] (any shape); default the free end s = ℓ.
        torsion_inertia: ``"polar"`` (I33 = ρ(c11 + c22)) or ``"printed"`` (I33 = ρ c33).
        linear_modes: Timoshenko modes per plane, or ``(N_x, N_y)`` (all below the cut-off).
        axial_modes: K, the number of axial Galerkin modes χ_k.
        torsion_modes: number of torsional modes (default ``axial_modes``).
        static_correction: use the mode-acceleration form z = z_qs + Σ(a_k − F_k/k_k)χ_k
            (recommended: without it z(ℓ) converges only like 1/K).
        method: ``"closed-form"`` (exact in time) or ``"ode"`` (DOP853, tolerance ``rtol``;
            slow for many modes, meant as a cross-check).

    Returns:
        :class:`SecondOrderResponse`.
    """
    t_in = np.asarray(times, dtype=float)
    t = t_in.ravel()
    if np.any(t < 0.0):
        raise ValueError("times must be >= 0 (the motion starts from rest at t = 0)")
    s_arr = np.asarray(rod.length if s is None else s, dtype=float)
    st = s_arr.ravel()
    qx, qy = q0 if isinstance(q0, tuple | list | np.ndarray) else (q0, q0)
    nx, ny = (linear_modes, linear_modes) if isinstance(linear_modes, int) else linear_modes
    planes = {
        "x": _Plane.build(rod.beam_x, float(qx), Omega, nx),
        "y": _Plane.build(rod.beam_y, float(qy), Omega, ny),
    }
    kt = axial_modes if torsion_modes is None else torsion_modes
    axial, torsion = _problems(rod, planes, st, axial_modes, kt, torsion_inertia)

    results = []
    for prob in (axial, torsion):
        if method == "closed-form":
            a = _solve_closed_form(prob, planes, t, rod.length, static_correction)
        elif method == "ode":
            a = _solve_ode(prob, planes, t, rod.length, static_correction, rtol)
        else:
            raise ValueError(f"unknown method {method!r}")
        chi = np.sin(np.outer(prob.lam, st))  # (K, S)
        dyn = a @ chi
        if static_correction:
            spec = _spectrum(prob.stations, planes)
            qs = spec.evaluate(t)
        else:
            qs = np.zeros_like(dyn)
        last = np.max(np.abs(a[:, -1:] * chi[-1][None, :]), axis=0) if t.size else np.zeros(st.size)
        results.append((dyn + qs, qs, last))

    shape = t_in.shape + s_arr.shape
    (z, zqs, zl), (phi, pqs, pl) = results
    return SecondOrderResponse(
        z=z.reshape(shape),
        phi=phi.reshape(shape),
        z_quasi_static=zqs.reshape(shape),
        phi_quasi_static=pqs.reshape(shape),
        z_last_mode=zl.reshape(s_arr.shape),
        phi_last_mode=pl.reshape(s_arr.shape),
        axial_frequencies=axial.omega,
        torsion_frequencies=torsion.omega,
        omega_x=planes["x"].omega,
        omega_y=planes["y"].omega,
        info={"linear_modes": (nx, ny), "axial_modes": axial_modes, "torsion_modes": kt},
    )


def second_order_tip_response(
    params: RodData,
    q0: float | tuple[float, float],
    Omega: float,
    times: ArrayLike,
    torsion_inertia: TorsionInertia = "polar",
    linear_modes: int | tuple[int, int] = 16,
    axial_modes: int = 16,
    **kwargs: object,
) -> tuple[FloatArray, FloatArray]:
    """(z(ℓ, t), φ(ℓ, t)) at ``times`` (shape of ``times``); see :func:`second_order_response`.

    Further keyword arguments (``torsion_modes``, ``static_correction``, ``method``,
    ``rtol``) are passed on.
    """
    res = second_order_response(
        params,
        q0,
        Omega,
        times,
        None,
        torsion_inertia=torsion_inertia,
        linear_modes=linear_modes,
        axial_modes=axial_modes,
        **kwargs,  # type: ignore[arg-type]
    )
    return res.z, res.phi
