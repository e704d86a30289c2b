r"""Closed-form reference for the *linear* Timoshenko cantilever (pure numpy/scipy).

This module is an independent check of the nonlinear Cosserat rod solver in its
small-amplitude limit. It must never import DOLFINx.

Model (one bending plane, SI units)
-----------------------------------
Clamped at :math:`s=0`, free at :math:`s=\ell`; deflection :math:`w(s,t)`, section rotation
:math:`\psi(s,t)`, shear strain :math:`\gamma = w' - \psi`:

.. math::

    \rho A\, w_{tt} &= \bigl(\kappa G A\,(w' - \psi)\bigr)' + f(s,t), \\
    \rho I\, \psi_{tt} &= (E I\, \psi')' + \kappa G A\,(w' - \psi),

with :math:`w(0)=\psi(0)=0`, :math:`EI\,\psi'(\ell) = M` (end moment) and
:math:`\kappa GA\,(w'(\ell)-\psi(\ell)) = P` (end force). Shear force
:math:`V = \kappa GA\,\gamma` and bending moment :math:`\mathcal M = EI\,\psi'` obey
:math:`V' = -f`, :math:`\mathcal M' = -V` in statics.

Contents
--------
* static closed forms for an end force, an end moment, a uniform load and a sine load, and
  :func:`static_response` for an arbitrary smooth load (Green's function quadrature);
* :func:`natural_frequencies` / :func:`mode_shapes`: the exact Timoshenko spectrum below the
  cut-off frequency :math:`\omega_c = \sqrt{\kappa GA/(\rho I)}`, mass-normalised modes;
* :func:`forced_response`: exact modal superposition (Duhamel integral in closed form) for
  :math:`f(s,t) = q_0\,S(s)\sin\Omega t` starting from rest;
* :func:`static_modal_sum`: :math:`\sum_k W_k Q_k/\omega_k^2`, which converges to the static
  solution (a strong self-check of the modes);
* :func:`euler_bernoulli_frequencies`: the classical slender-beam limit.

Tests: tests/test_timoshenko_reference.py.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, replace
from functools import lru_cache

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import brentq

__all__ = [
    "EULER_BERNOULLI_BETA_L",
    "ForcedResponse",
    "TimoshenkoBeam",
    "TimoshenkoMode",
    "euler_bernoulli_frequencies",
    "forced_response",
    "mass_matrix",
    "mode_shapes",
    "modal_loads",
    "natural_frequencies",
    "static_deflection_sine_load",
    "static_modal_sum",
    "static_response",
    "tip_deflection_end_force",
    "tip_deflection_end_moment",
    "tip_deflection_uniform_load",
    "tip_rotation_end_force",
    "tip_rotation_end_moment",
    "tip_rotation_uniform_load",
]

FloatArray = NDArray[np.float64]
Shape = Callable[[FloatArray], ArrayLike]

#: First roots of the Euler-Bernoulli cantilever equation ``1 + cos(x) cosh(x) = 0``.
EULER_BERNOULLI_BETA_L: tuple[float, ...] = (1.875104069, 4.694091133, 7.854757438, 10.99554073)


# --------------------------------------------------------------------------------------------
# Beam data
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class TimoshenkoBeam:
    """Uniform Timoshenko beam bending in one plane (SI units).

    Attributes:
        length: ℓ [m].
        area: cross-section area A [m²].
        inertia: second moment of area I of the bending plane [m⁴].
        young: Young's modulus E [Pa].
        shear: shear modulus G [Pa].
        kappa: shear correction factor κ [-].
        density: mass density ρ [kg/m³].
    """

    length: float
    area: float
    inertia: float
    young: float
    shear: float
    kappa: float
    density: float

    @classmethod
    def rectangular(
        cls,
        length: float,
        depth: float,
        width: float,
        young: float,
        poisson: float,
        kappa: float,
        density: float,
    ) -> TimoshenkoBeam:
        """Rectangular section ``depth`` (in the bending direction) × ``width``.

        A = depth·width, I = width·depth³/12, G = E/(2(1+ν)).
        """
        return cls(
            length=length,
            area=depth * width,
            inertia=width * depth**3 / 12.0,
            young=young,
            shear=young / (2.0 * (1.0 + poisson)),
            kappa=kappa,
            density=density,
        )

    @property
    def EI(self) -> float:
        """Bending stiffness E·I [N m²]."""
        return self.young * self.inertia

    @property
    def kGA(self) -> float:
        """Shear stiffness κ·G·A [N]."""
        return self.kappa * self.shear * self.area

    @property
    def rhoA(self) -> float:
        """Mass per unit length ρ·A [kg/m]."""
        return self.density * self.area

    @property
    def rhoI(self) -> float:
        """Rotary inertia per unit length ρ·I [kg m]."""
        return self.density * self.inertia

    @property
    def cutoff_frequency(self) -> float:
        """ω_c = sqrt(κGA/(ρI)) [rad/s]; only modes below it are handled here."""
        return math.sqrt(self.kGA / self.rhoI)


# --------------------------------------------------------------------------------------------
# Statics
# --------------------------------------------------------------------------------------------
def tip_deflection_end_force(beam: TimoshenkoBeam, P: float) -> float:
    """w(ℓ) = Pℓ³/(3EI) + Pℓ/(κGA) for an end force P."""
    ell = beam.length
    return P * ell**3 / (3.0 * beam.EI) + P * ell / beam.kGA


def tip_rotation_end_force(beam: TimoshenkoBeam, P: float) -> float:
    """ψ(ℓ) = Pℓ²/(2EI) for an end force P."""
    return P * beam.length**2 / (2.0 * beam.EI)


def tip_deflection_uniform_load(beam: TimoshenkoBeam, q: float) -> float:
    """w(ℓ) = qℓ⁴/(8EI) + qℓ²/(2κGA) for a uniform load q [N/m]."""
    ell = beam.length
    return q * ell**4 / (8.0 * beam.EI) + q * ell**2 / (2.0 * beam.kGA)


def tip_rotation_uniform_load(beam: TimoshenkoBeam, q: float) -> float:
    """ψ(ℓ) = qℓ³/(6EI) for a uniform load q [N/m]."""
    return q * beam.length**3 / (6.0 * beam.EI)


def tip_deflection_end_moment(beam: TimoshenkoBeam, M: float) -> float:
    """w(ℓ) = Mℓ²/(2EI) for an end moment M (no shear: V ≡ 0)."""
    return M * beam.length**2 / (2.0 * beam.EI)


def tip_rotation_end_moment(beam: TimoshenkoBeam, M: float) -> float:
    """ψ(ℓ) = Mℓ/(EI) for an end moment M."""
    return M * beam.length / beam.EI


def static_deflection_sine_load(
    beam: TimoshenkoBeam, q0: float, s: ArrayLike
) -> tuple[FloatArray, FloatArray]:
    r"""Exact static (w, ψ) for the load f(s) = q0 sin(πs/ℓ), no end force or moment.

    With k = π/ℓ, integrating V' = -f, 𝓜' = -V from the free end (V(ℓ) = 𝓜(ℓ) = 0):

    .. math::

        V(s) &= \frac{q_0}{k}\,(1 + \cos ks), \qquad
        \mathcal M(s) = \frac{q_0}{k}\Bigl(\ell - s - \frac{\sin ks}{k}\Bigr), \\
        \psi(s) &= \frac{1}{EI}\int_0^s \mathcal M
                 = \frac{q_0}{k\,EI}\Bigl(\ell s - \frac{s^2}{2} + \frac{\cos ks - 1}{k^2}\Bigr), \\
        w(s) &= \int_0^s \Bigl(\psi + \frac{V}{\kappa GA}\Bigr)
              = \frac{q_0}{k\,EI}\Bigl(\frac{\ell s^2}{2} - \frac{s^3}{6}
                + \frac{\sin ks - ks}{k^3}\Bigr)
              + \frac{q_0}{k\,\kappa GA}\Bigl(s + \frac{\sin ks}{k}\Bigr).

    At the tip, w(ℓ) = q0 ℓ⁴ (1/3 - 1/π²)/(π EI) + q0 ℓ²/(π κGA).
    Vectorised over ``s``; returns arrays of the shape of ``s``.
    """
    s = np.asarray(s, dtype=float)
    ell = beam.length
    k = math.pi / ell
    ks = k * s
    sin_ks, cos_ks = np.sin(ks), np.cos(ks)
    c_b = q0 / (k * beam.EI)
    psi = c_b * (ell * s - 0.5 * s**2 + (cos_ks - 1.0) / k**2)
    w = c_b * (0.5 * ell * s**2 - s**3 / 6.0 + (sin_ks - ks) / k**3)
    w = w + q0 / (k * beam.kGA) * (s + sin_ks / k)
    return w, psi


def _gauss_legendre(a: float, b: float, panels: int, nodes: int) -> tuple[FloatArray, FloatArray]:
    """Composite Gauss-Legendre rule on [a, b]: (points, weights)."""
    x, wq = np.polynomial.legendre.leggauss(nodes)
    edges = np.linspace(a, b, panels + 1)
    half = 0.5 * np.diff(edges)
    mid = 0.5 * (edges[1:] + edges[:-1])
    pts = (mid[:, None] + half[:, None] * x[None, :]).ravel()
    wts = (half[:, None] * wq[None, :]).ravel()
    return pts, wts


def _eval_shape(shape: Shape, x: FloatArray) -> FloatArray:
    """Evaluate a (vectorised) load shape; scalar results such as ``lambda s: 1.0`` broadcast."""
    return np.broadcast_to(np.asarray(shape(x), dtype=float), x.shape)


def _sine_shape(beam: TimoshenkoBeam) -> Shape:
    ell = beam.length
    return lambda x: np.sin(math.pi * np.asarray(x) / ell)


def static_response(
    beam: TimoshenkoBeam,
    s: ArrayLike,
    *,
    q0: float = 0.0,
    shape: Shape | None = None,
    force: float = 0.0,
    moment: float = 0.0,
    nodes: int = 64,
) -> tuple[FloatArray, FloatArray]:
    r"""Exact static (w, ψ) for a distributed load q0·S(s) plus an end force and end moment.

    Integrating V' = -f, 𝓜' = -V, EIψ' = 𝓜, w' = ψ + V/(κGA) from the clamp gives the
    Green's-function form

    .. math::

        w(s) &= \int_0^\ell \Bigl[\frac{G(s,\sigma)}{EI} + \frac{\min(s,\sigma)}{\kappa GA}\Bigr]
                f(\sigma)\,d\sigma
              + P\Bigl(\frac{s^2(3\ell-s)}{6EI} + \frac{s}{\kappa GA}\Bigr)
              + \frac{M s^2}{2EI}, \\
        \psi(s) &= \frac{1}{EI}\int_0^\ell \partial_s G(s,\sigma)\,f(\sigma)\,d\sigma
              + \frac{P s(2\ell - s)}{2EI} + \frac{M s}{EI},

    with G(s,σ) = σ²(3s-σ)/6 for σ ≤ s and s²(3σ-s)/6 for σ ≥ s. The integrals are evaluated
    by ``nodes``-point Gauss-Legendre on [0, s] and [s, ℓ] separately (the kernel has a kink at
    σ = s), which is exact to rounding for smooth S (default S(s) = sin(πs/ℓ)).
    """
    s = np.asarray(s, dtype=float)
    ell, EI, kGA = beam.length, beam.EI, beam.kGA
    w = force * (s**2 * (3.0 * ell - s) / (6.0 * EI) + s / kGA) + moment * s**2 / (2.0 * EI)
    psi = force * s * (2.0 * ell - s) / (2.0 * EI) + moment * s / EI
    if q0 != 0.0:
        if shape is None:
            shape = _sine_shape(beam)
        x, wq = np.polynomial.legendre.leggauss(nodes)
        sf = s.reshape(-1, 1)
        t = 0.5 * (1.0 + x)[None, :]
        # sigma <= s
        sig = sf * t
        f = q0 * _eval_shape(shape, sig)
        jac = 0.5 * sf * wq[None, :]
        w_lo = np.sum(jac * f * (sig**2 * (3.0 * sf - sig) / (6.0 * EI) + sig / kGA), axis=1)
        psi_lo = np.sum(jac * f * sig**2 / (2.0 * EI), axis=1)
        # sigma >= s
        sig = sf + (ell - sf) * t
        f = q0 * _eval_shape(shape, sig)
        jac = 0.5 * (ell - sf) * wq[None, :]
        w_hi = np.sum(jac * f * (sf**2 * (3.0 * sig - sf) / (6.0 * EI) + sf / kGA), axis=1)
        psi_hi = np.sum(jac * f * sf * (2.0 * sig - sf) / (2.0 * EI), axis=1)
        w = w + (w_lo + w_hi).reshape(s.shape)
        psi = psi + (psi_lo + psi_hi).reshape(s.shape)
    return np.asarray(w, dtype=float), np.asarray(psi, dtype=float)


# --------------------------------------------------------------------------------------------
# Free vibration
# --------------------------------------------------------------------------------------------
def euler_bernoulli_frequencies(beam: TimoshenkoBeam, count: int) -> FloatArray:
    """First ``count`` Euler-Bernoulli cantilever frequencies ω_k = (β_kℓ)² sqrt(EI/(ρAℓ⁴)).

    β_kℓ are the roots of 1 + cos x cosh x = 0, found as roots of cos x + 1/cosh x on
    [(k-1)π, kπ] (one root per interval).
    """
    roots = [
        brentq(
            lambda x: math.cos(x) + 1.0 / math.cosh(x),
            (k - 1) * math.pi,
            k * math.pi,
            xtol=1e-15,
            rtol=4 * np.finfo(float).eps,
        )
        for k in range(1, count + 1)
    ]
    x = np.asarray(roots)
    return x**2 * math.sqrt(beam.EI / (beam.rhoA * beam.length**4))


def _omega_sq_from_beta(beam: TimoshenkoBeam, beta: FloatArray) -> FloatArray:
    r"""Lower branch ω²(β) of the dispersion relation with λ² = -β².

    Substituting λ² = -β² in the characteristic equation gives a quadratic in ω²:
    ρAρI ω⁴ - (ρA κGA + β²(κGA ρI + ρA EI)) ω² + κGA EI β⁴ = 0. The lower root, written
    in the cancellation-free form 2C/(B + sqrt(B² - 4AC)), is the branch that reaches ω_c at
    β_c (the upper root is at least 4× larger there, by AM-GM).
    """
    a = beam.rhoA * beam.rhoI
    b = beam.rhoA * beam.kGA + beta**2 * (beam.kGA * beam.rhoI + beam.rhoA * beam.EI)
    c = beam.kGA * beam.EI * beta**4
    return 2.0 * c / (b + np.sqrt(b * b - 4.0 * a * c))


def _cutoff_beta(beam: TimoshenkoBeam) -> float:
    """β at ω = ω_c (α = 0): β_c² = ω_c² (ρI/EI + ρA/κGA)."""
    wc2 = beam.kGA / beam.rhoI
    return math.sqrt(wc2 * (beam.rhoI / beam.EI + beam.rhoA / beam.kGA))


@dataclass(frozen=True)
class _Wave:
    """Wavenumbers and amplitude ratios at one frequency (all arrays of the same shape)."""

    omega: FloatArray
    alpha: FloatArray
    beta: FloatArray
    r: FloatArray  # Ψ/W for e^{-α(ℓ-s)} (and -r for e^{-αs})
    c: FloatArray  # W = cos βs -> Ψ = c sin βs;  W = sin βs -> Ψ = -c cos βs
    ga: FloatArray  # ρAω²/(κGA α) = r - α  (shear strain per unit W, exponential part)
    gb: FloatArray  # ρAω²/(κGA β) = β + c  (shear strain per unit W, oscillatory part)


def _waves(beam: TimoshenkoBeam, beta: FloatArray) -> _Wave:
    r"""Wave data for the oscillatory wavenumber β (below cut-off).

    The characteristic equation κGA·EI λ⁴ + ω²(κGA ρI + ρA EI) λ² + ρAω²(ρIω² - κGA) = 0 has
    roots λ² = α² > 0 and λ² = -β² < 0 for ω < ω_c. From the product of the roots,
    α² = ρAω²(κGA - ρIω²)/(κGA EI β²). The first field equation gives, for w = W e^{λs},
    ψ = Ψ e^{λs}: Ψ/W = (κGA λ² + ρAω²)/(κGA λ), i.e. r = α + ρAω²/(κGA α) and
    c = -β + ρAω²/(κGA β) for the real forms listed in :class:`_Wave`.
    """
    beta = np.asarray(beta, dtype=float)
    om2 = _omega_sq_from_beta(beam, beta)
    alpha = np.sqrt(beam.rhoA * om2 * (beam.kGA - beam.rhoI * om2) / (beam.kGA * beam.EI * beta**2))
    ga = beam.rhoA * om2 / (beam.kGA * alpha)
    gb = beam.rhoA * om2 / (beam.kGA * beta)
    return _Wave(np.sqrt(om2), alpha, beta, alpha + ga, gb - beta, ga, gb)


def _bc_matrix(beam: TimoshenkoBeam, wave: _Wave) -> FloatArray:
    r"""4×4 boundary-condition matrix (batched over the shape of ``wave.beta``).

    Basis (columns): e^{-αs}, e^{-α(ℓ-s)}, cos βs, sin βs for W, with
    Ψ = -r e^{-αs}, r e^{-α(ℓ-s)}, c sin βs, -c cos βs. Rows: W(0) = 0, Ψ(0) = 0,
    Ψ'(ℓ) = 0 (no end moment) and W'(ℓ) - Ψ(ℓ) = 0 (no end shear); in the last row
    the differences r - α and β + c are formed analytically (ga, gb) to avoid cancellation.
    """
    ell = beam.length
    a, b, r, c, ga, gb = wave.alpha, wave.beta, wave.r, wave.c, wave.ga, wave.gb
    e = np.exp(-a * ell)
    cb, sb = np.cos(b * ell), np.sin(b * ell)
    one, zero = np.ones_like(a), np.zeros_like(a)
    rows = [
        [one, e, one, zero],
        [-r, r * e, zero, -c],
        [a * r * e, a * r, c * b * cb, c * b * sb],
        [ga * e, -ga, -gb * sb, gb * cb],
    ]
    return np.moveaxis(np.array(rows, dtype=float), (0, 1), (-2, -1))


def _balanced(mat: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Row- then column-normalise (2-norms). Returns (balanced matrix, column scales).

    Both scalings are positive and continuous in ω, so the sign of the determinant and its
    zeros are unchanged, while its magnitude becomes O(1) (smallest singular value ~ 0 only at
    a genuine eigenfrequency).
    """
    mat = mat / np.linalg.norm(mat, axis=-1, keepdims=True)
    col = 1.0 / np.linalg.norm(mat, axis=-2, keepdims=True)
    return mat * col, col[..., 0, :]


def _det(beam: TimoshenkoBeam, beta: FloatArray) -> FloatArray:
    return np.linalg.det(_balanced(_bc_matrix(beam, _waves(beam, beta)))[0])


@dataclass(frozen=True)
class TimoshenkoMode:
    r"""One mass-normalised cantilever mode (W_k, Ψ_k) with angular frequency ``omega``.

    W(s) = C₀ e^{-αs} + C₁ e^{-α(ℓ-s)} + C₂ cos βs + C₃ sin βs,
    Ψ(s) = -r C₀ e^{-αs} + r C₁ e^{-α(ℓ-s)} + c C₂ sin βs - c C₃ cos βs,

    normalised so that ∫₀^ℓ (ρA W² + ρI Ψ²) ds = 1 and W(ℓ) > 0. Calling the mode returns
    ``(W(s), Ψ(s))``.
    """

    beam: TimoshenkoBeam
    omega: float
    alpha: float
    beta: float
    r: float
    c: float
    coefficients: tuple[float, float, float, float]

    def _parts(self, s: ArrayLike, n: int) -> tuple[FloatArray, ...]:
        s = np.asarray(s, dtype=float)
        a, b, ell = self.alpha, self.beta, self.beam.length
        e0 = (-a) ** n * np.exp(-a * s)
        e1 = a**n * np.exp(-a * (ell - s))
        cs = b**n * np.cos(b * s + 0.5 * n * math.pi)
        sn = b**n * np.sin(b * s + 0.5 * n * math.pi)
        return e0, e1, cs, sn

    def W(self, s: ArrayLike, derivative: int = 0) -> FloatArray:
        """Deflection shape W(s) (or its ``derivative``-th s-derivative) [m/sqrt(kg)]."""
        e0, e1, cs, sn = self._parts(s, derivative)
        c0, c1, c2, c3 = self.coefficients
        return c0 * e0 + c1 * e1 + c2 * cs + c3 * sn

    def Psi(self, s: ArrayLike, derivative: int = 0) -> FloatArray:
        """Rotation shape Ψ(s) (or its ``derivative``-th s-derivative) [1/sqrt(kg)]."""
        e0, e1, cs, sn = self._parts(s, derivative)
        c0, c1, c2, c3 = self.coefficients
        return self.r * (-c0 * e0 + c1 * e1) + self.c * (c2 * sn - c3 * cs)

    def __call__(self, s: ArrayLike) -> tuple[FloatArray, FloatArray]:
        return self.W(s), self.Psi(s)


def _quadrature(beam: TimoshenkoBeam, beta_max: float) -> tuple[FloatArray, FloatArray]:
    """Gauss-Legendre rule resolving products of modes up to wavenumber β_max (≤ 4 rad/panel)."""
    panels = max(8, int(math.ceil(2.0 * beta_max * beam.length / 4.0)))
    return _gauss_legendre(0.0, beam.length, panels, 24)


def _mass_product(
    beam: TimoshenkoBeam, m1: TimoshenkoMode, m2: TimoshenkoMode, pts: FloatArray, wts: FloatArray
) -> float:
    return float(
        np.sum(wts * (beam.rhoA * m1.W(pts) * m2.W(pts) + beam.rhoI * m1.Psi(pts) * m2.Psi(pts)))
    )


@lru_cache(maxsize=64)
def _modes(beam: TimoshenkoBeam, count: int) -> tuple[TimoshenkoMode, ...]:
    """Scan the balanced BC determinant in β, bracket sign changes, refine with brentq."""
    if count < 1:
        raise ValueError(f"count must be >= 1, got {count}")
    ell = beam.length
    beta_c = _cutoff_beta(beam)
    beta_stop = beta_c * (1.0 - 1e-9)
    step = math.pi / (32.0 * ell)  # modes are ~π/ℓ apart in β
    lo = 0.05 / ell
    betas: list[float] = []
    while len(betas) < count and lo < beta_stop:
        grid = lo + step * np.arange(257)
        grid = grid[grid <= beta_stop]
        if grid.size < 2:
            break
        d = _det(beam, grid)
        for i in np.nonzero(np.sign(d[:-1]) * np.sign(d[1:]) < 0)[0]:
            root = brentq(
                lambda x: float(_det(beam, np.array([x]))[0]),
                grid[i],
                grid[i + 1],
                xtol=1e-15 * grid[i + 1],
                rtol=4 * np.finfo(float).eps,
                maxiter=200,
            )
            bal, _ = _balanced(_bc_matrix(beam, _waves(beam, np.array([root]))))
            # Reject spurious sign changes (e.g. the basis degenerating at the cut-off α -> 0):
            # at a genuine eigenfrequency the balanced matrix is singular.
            if np.linalg.svd(bal[0], compute_uv=False)[-1] < 1e-7:
                betas.append(root)
            if len(betas) == count:
                break
        lo = float(grid[-1])
    if len(betas) < count:
        raise ValueError(
            f"only {len(betas)} Timoshenko modes lie below the cut-off frequency "
            f"omega_c = sqrt(kappa G A/(rho I)) = {beam.cutoff_frequency:.6g} rad/s; "
            f"{count} were requested (modes above the cut-off are not implemented)"
        )

    beta_arr = np.asarray(betas)
    waves = _waves(beam, beta_arr)
    mats = _bc_matrix(beam, waves)
    bal, col = _balanced(mats)
    pts, wts = _quadrature(beam, float(beta_arr.max()))
    modes: list[TimoshenkoMode] = []
    for k in range(count):
        null = np.linalg.svd(bal[k])[2][-1] * col[k]
        c0, c1, c2, c3 = (float(x) for x in null)
        mode = TimoshenkoMode(
            beam,
            float(waves.omega[k]),
            float(waves.alpha[k]),
            float(waves.beta[k]),
            float(waves.r[k]),
            float(waves.c[k]),
            (c0, c1, c2, c3),
        )
        scale = 1.0 / math.sqrt(_mass_product(beam, mode, mode, pts, wts))
        if mode.W(ell) < 0.0:
            scale = -scale
        coeffs = (scale * c0, scale * c1, scale * c2, scale * c3)
        modes.append(replace(mode, coefficients=coeffs))
    return tuple(modes)


def natural_frequencies(beam: TimoshenkoBeam, count: int) -> FloatArray:
    r"""First ``count`` angular frequencies ω_k [rad/s] of the clamped-free Timoshenko beam.

    Derivation: with w = W e^{λs}, ψ = Ψ e^{λs} e^{iωt} the field equations give the
    biquadratic κGA·EI λ⁴ + ω²(κGA ρI + ρA EI) λ² + ρAω²(ρIω² - κGA) = 0, whose roots below
    ω_c = sqrt(κGA/(ρI)) are λ² = α² > 0 and -β² < 0. In the numerically stable basis
    e^{-αs}, e^{-α(ℓ-s)}, cos βs, sin βs (with matching Ψ, see :class:`TimoshenkoMode`)
    the conditions W(0) = Ψ(0) = Ψ'(ℓ) = W'(ℓ) - Ψ(ℓ) = 0 form a 4×4 homogeneous system.
    The frequencies are the zeros of its (row/column balanced) determinant, scanned on a
    β-grid of step π/(32ℓ) (ω(β) is monotone below the cut-off), bracketed, refined with
    brentq and accepted only where the smallest singular value vanishes.

    Raises:
        ValueError: if fewer than ``count`` modes lie below the cut-off ω_c.
    """
    return np.array([m.omega for m in _modes(beam, count)])


def mode_shapes(beam: TimoshenkoBeam, count: int) -> list[TimoshenkoMode]:
    """First ``count`` mass-normalised modes: ∫₀^ℓ (ρA W_j W_k + ρI Ψ_j Ψ_k) ds = δ_jk.

    Each mode is callable, ``W, Psi = mode(s)``, and has ``.W(s, derivative)``,
    ``.Psi(s, derivative)`` and ``.omega``. Sign convention: W_k(ℓ) > 0.
    """
    return list(_modes(beam, count))


def mass_matrix(beam: TimoshenkoBeam, modes: Sequence[TimoshenkoMode]) -> FloatArray:
    """Modal mass matrix ∫ (ρA W_j W_k + ρI Ψ_j Ψ_k) ds (identity up to rounding)."""
    pts, wts = _quadrature(beam, max(m.beta for m in modes))
    Ws = np.array([m.W(pts) for m in modes])
    Ps = np.array([m.Psi(pts) for m in modes])
    return beam.rhoA * (Ws * wts) @ Ws.T + beam.rhoI * (Ps * wts) @ Ps.T


# --------------------------------------------------------------------------------------------
# Forced response
# --------------------------------------------------------------------------------------------
def modal_loads(
    beam: TimoshenkoBeam, q0: float, shape: Shape | None, modes: Sequence[TimoshenkoMode]
) -> FloatArray:
    """Generalised forces Q_k = ∫₀^ℓ q0 S(s) W_k(s) ds (composite Gauss-Legendre)."""
    if shape is None:
        shape = _sine_shape(beam)
    pts, wts = _quadrature(beam, max(m.beta for m in modes))
    f = q0 * _eval_shape(shape, pts)
    return np.array([float(np.sum(wts * f * m.W(pts))) for m in modes])


def static_modal_sum(
    beam: TimoshenkoBeam,
    q0: float,
    shape: Shape | None,
    s: ArrayLike,
    modes: int,
) -> tuple[FloatArray, FloatArray]:
    """Truncated modal static solution (Σ_k W_k Q_k/ω_k², Σ_k Ψ_k Q_k/ω_k²), k = 1..modes.

    ``shape=None`` means S(s) = sin(πs/ℓ). Converges to :func:`static_response` as
    ``modes`` grows (limited to the modes below the cut-off).
    """
    ms = _modes(beam, modes)
    s = np.asarray(s, dtype=float)
    amp = modal_loads(beam, q0, shape, ms) / np.array([m.omega for m in ms]) ** 2
    w = sum(a * m.W(s) for a, m in zip(amp, ms, strict=True))
    psi = sum(a * m.Psi(s) for a, m in zip(amp, ms, strict=True))
    return np.asarray(w, dtype=float), np.asarray(psi, dtype=float)


def _duhamel_sine(Q: FloatArray, omega: FloatArray, Omega: float, t: FloatArray) -> FloatArray:
    r"""η(t) solving η'' + ω²η = Q sin Ωt, η(0) = η'(0) = 0 (broadcast over Q/ω and t).

    η = Q/(ω² - Ω²) (sin Ωt - (Ω/ω) sin ωt), rewritten without the 0/0 at resonance as
    η = Q/(ω + Ω) [sin(ωt)/ω - t cos((ω+Ω)t/2) sinc((Ω-ω)t/2)]  (sinc x = sin x / x),
    which equals Q/(2ω²)(sin ωt - ωt cos ωt) at Ω = ω.
    """
    x = 0.5 * (Omega - omega) * t
    return (
        Q
        / (omega + Omega)
        * (np.sin(omega * t) / omega - t * np.cos(0.5 * (omega + Omega) * t) * np.sinc(x / math.pi))
    )


@dataclass(frozen=True)
class ForcedResponse:
    """Result of :func:`forced_response`. Unpacks as ``w, psi = forced_response(...)``.

    Attributes:
        w, psi: deflection and rotation, shape ``times.shape + s.shape``.
        eta: modal coordinates η_k(t), shape ``times.shape + (modes,)``.
        omega: the ω_k used; Q: the modal loads Q_k.
        static_remainder_w, static_remainder_psi: exact quasi-static truncation remainder
            w_static(s) - Σ_{k≤N} W_k Q_k/ω_k² (and likewise ψ), shape ``s.shape``.
        truncation_w, truncation_psi: estimated bound on the neglected modal tail,
            |static remainder| · (1 + Ω/ω_N)/(1 - Ω²/ω_N²) (inf if Ω ≥ ω_N), shape ``s.shape``.
            With ``static_correction=True`` the remaining error is smaller still, roughly by a
            further factor (Ω/ω_N).
        last_mode_w: max over ``times`` of |W_N(s) η_N(t)|, the size of the last retained term.
    """

    w: FloatArray
    psi: FloatArray
    eta: FloatArray
    omega: FloatArray
    Q: FloatArray
    static_remainder_w: FloatArray
    static_remainder_psi: FloatArray
    truncation_w: FloatArray
    truncation_psi: FloatArray
    last_mode_w: FloatArray

    def __iter__(self) -> Iterator[FloatArray]:
        return iter((self.w, self.psi))


def forced_response(
    beam: TimoshenkoBeam,
    q0: float,
    Omega: float,
    times: ArrayLike,
    s: ArrayLike | None = None,
    modes: int = 20,
    shape: Shape | None = None,
    static_correction: bool = False,
) -> ForcedResponse:
    r"""Response from rest to f(s,t) = q0 S(s) sin(Ωt) by exact modal superposition.

    With mass-normalised modes (W_k, Ψ_k) and Q_k = ∫₀^ℓ q0 S W_k ds, each modal coordinate
    solves η_k'' + ω_k² η_k = Q_k sin Ωt from rest, whose Duhamel integral is

    .. math:: \eta_k(t) = \frac{Q_k}{\omega_k^2 - \Omega^2}
              \Bigl(\sin\Omega t - \frac{\Omega}{\omega_k}\sin\omega_k t\Bigr)

    (evaluated in a form that stays exact at resonance); then w = Σ_k W_k η_k and
    ψ = Σ_k Ψ_k η_k, k = 1..``modes``.

    Args:
        beam: the beam.
        q0: load amplitude [N/m].
        Omega: forcing angular frequency Ω [rad/s].
        times: evaluation times (any shape).
        s: stations (any shape); default the tip s = ℓ.
        modes: number of modes N (all below the cut-off).
        shape: vectorised S(s); default sin(πs/ℓ).
        static_correction: add the quasi-static remainder (w_static - Σ W_k Q_k/ω_k²)·sin Ωt
            of the neglected modes (mode-acceleration method). The uncorrected sum is the
            exact solution of the N-mode truncated problem; the corrected one is closer to the
            full continuum solution when Ω ≪ ω_N.

    Returns:
        :class:`ForcedResponse` (unpacks as ``w, psi``) with truncation-error estimates.
    """
    if s is None:
        s = beam.length
    t = np.asarray(times, dtype=float)
    s = np.asarray(s, dtype=float)
    ms = _modes(beam, modes)
    omega = np.array([m.omega for m in ms])
    Q = modal_loads(beam, q0, shape, ms)
    eta = _duhamel_sine(Q, omega, Omega, t[..., None])  # times.shape + (N,)
    Wk = np.array([m.W(s) for m in ms])  # (N,) + s.shape
    Pk = np.array([m.Psi(s) for m in ms])
    w = np.tensordot(eta, Wk, axes=(-1, 0))
    psi = np.tensordot(eta, Pk, axes=(-1, 0))

    w_st, psi_st = static_response(
        beam, s, q0=q0, shape=shape if shape is not None else _sine_shape(beam)
    )
    amp = Q / omega**2
    rem_w = w_st - np.tensordot(amp, Wk, axes=(0, 0))
    rem_psi = psi_st - np.tensordot(amp, Pk, axes=(0, 0))
    if static_correction:
        sin_t = np.sin(Omega * t)[(...,) + (None,) * s.ndim]
        w = w + sin_t * rem_w
        psi = psi + sin_t * rem_psi
    ratio = Omega / omega[-1]
    factor = (1.0 + ratio) / (1.0 - ratio**2) if ratio < 1.0 else math.inf
    last = np.abs(eta[..., -1])
    last_max = float(np.max(last)) if last.size else 0.0
    return ForcedResponse(
        w=np.asarray(w, dtype=float),
        psi=np.asarray(psi, dtype=float),
        eta=eta,
        omega=omega,
        Q=Q,
        static_remainder_w=np.asarray(rem_w, dtype=float),
        static_remainder_psi=np.asarray(rem_psi, dtype=float),
        truncation_w=np.abs(rem_w) * factor,
        truncation_psi=np.abs(rem_psi) * factor,
        last_mode_w=np.abs(Wk[-1]) * last_max,
    )
