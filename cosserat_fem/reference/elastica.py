r"""Large static deflections of a tip-loaded cantilever: Euler's elastica and the Reissner rod.

Pure numpy/scipy; this module must never import DOLFINx. It is an independent, high-accuracy
reference for the *nonlinear* statics of the Cosserat rod solver.

Geometry and conventions (one bending plane, the e1-e3 plane)
--------------------------------------------------------------
Cantilever of length ℓ, clamped at s = 0 with its tangent along e3 (the rod axis), free at
s = ℓ. The section rotates about e2 by the angle ψ(s), measured from e3 towards e1, so the
directors are

.. math::

    d_3 = (\sin\psi, 0, \cos\psi), \qquad d_1 = (\cos\psi, 0, -\sin\psi), \qquad d_2 = e_2,

(d1 × d2 = d3). The section force n(s) (exerted by the part (s, ℓ] on [0, s]) obeys n' = 0
without distributed load, so n ≡ (P_x, 0, P_z) is the dead end force; the section moment
m = EI ψ' e2 obeys m' + r' × n = 0 and m(ℓ) = M e2.

1. Euler's elastica (inextensible, unshearable: r' = d3)
-------------------------------------------------------
With a dead tip force P e1 (perpendicular to the undeformed rod) and no end moment,
(r' × n)·e2 = P cos ψ and

.. math::

    EI\,\psi'' + P\cos\psi = 0, \qquad \psi(0) = 0, \qquad \psi'(\ell) = 0,
    \qquad x' = \sin\psi, \quad z' = \cos\psi, \quad x(0) = z(0) = 0.

Everything depends on the load only through α = Pℓ²/(EI). The functions below work in
dimensionless form (ℓ = 1, arc length ŝ = s/ℓ ∈ [0, 1]); for a rod of length ℓ and bending
stiffness EI under P, use α = Pℓ²/EI and scale back as

.. math::

    \psi(s) = \hat\psi(s/\ell), \quad \psi'(s) = \hat\kappa(s/\ell)/\ell, \quad
    x(s) = \ell\,\hat x(s/\ell), \quad z(s) = \ell\,\hat z(s/\ell).

In Mattiasson's (1981) notation the tip deflection along the load is w/ℓ = x̂(1) and the axial
tip displacement (shortening) is u/ℓ = 1 − ẑ(1).

**Closed form (elliptic integrals).** The first integral with ψ'(1) = 0 is
½ψ'² = α(sin ψ_t − sin ψ), ψ_t = ψ(1), and ψ increases monotonically from 0 to ψ_t < π/2.
Substituting

.. math::

    1 + \sin\psi = 2k^2\sin^2\phi, \qquad k = \sin\Bigl(\frac{\pi/2 + \psi_t}{2}\Bigr),
    \qquad k' = \sqrt{1-k^2} = \cos\Bigl(\frac{\pi/2 + \psi_t}{2}\Bigr),

(φ runs from φ1, sin φ1 = 1/(√2 k), at the clamp to π/2 at the tip) gives
ψ' = 2k√α cos φ, cos ψ = 2k sin φ Δ(φ), Δ(φ) = √(1 − k² sin²φ), and
√α ds = dφ/Δ(φ), hence with F, E the incomplete integrals of the first and second kind,

.. math::

    \sqrt\alpha &= K(k) - F(\phi_1, k), \\
    x(1) &= 1 - \frac{2}{\sqrt\alpha}\bigl(E(k) - E(\phi_1, k)\bigr), \qquad
    z(1) = \frac{2k\cos\phi_1}{\sqrt\alpha} = \frac{\psi'(0)}{\alpha},

(√α dx = (1/Δ − 2Δ) dφ, √α dz = 2k sin φ dφ). To avoid the cancellation K − F(φ1) for small
loads, Legendre's addition theorem (F(φ1) + F(φ2) = K and
E(φ1) + E(φ2) = E + k² sin φ1 sin φ2 when tan φ1 tan φ2 = 1/k') is used:

.. math::

    \sqrt\alpha = F(\phi_2, k), \quad \tan\phi_2 = \frac{\cot\phi_1}{k'}, \qquad
    x(1) = 1 - \frac{2\,g(\phi_2)}{\sqrt\alpha}, \quad
    g(\chi) = E(\chi, k) - \frac{k^2\sin\chi\cos\chi}{\Delta(\chi)}.

The tip angle is the root (brentq) of F(φ2(ψ_t), k(ψ_t)) = √α. Along the rod, measuring from
the tip, χ(s) = am(√α(1 − s), k) (Jacobi amplitude; scipy's ``ellipj`` polished by Newton on
F(χ) = √α(1 − s)), and with sn = sin χ, cn = cos χ, dn = Δ(χ) = √(cn² + k'² sn²):

.. math::

    \sin\psi &= \frac{2k^2\,cn^2}{dn^2} - 1, \quad \cos\psi = \frac{2kk'\,cn}{dn^2}, \quad
    \psi' = 2kk'\sqrt\alpha\,\frac{sn}{dn}, \\
    x(s) &= s - \frac{2}{\sqrt\alpha}\bigl(g(\phi_2) - g(\chi)\bigr), \qquad
    z(s) = \frac{2kk'}{\sqrt\alpha}\Bigl(\frac{\sin\phi_2}{\Delta(\phi_2)} - \frac{sn}{dn}\Bigr).

**Collocation.** Independently, ``scipy.integrate.solve_bvp`` on y = (ψ, κ, x, z),
y' = (κ, −α cos ψ, sin ψ, cos ψ), ψ(0) = x(0) = z(0) = κ(1) = 0, with analytic Jacobians and
tolerance 1e-11 (1e-12 on request, where round-off lets it converge), by continuation in α
from the linear solution ψ = α(s − s²/2) at a small load. The two methods agree to ~1e-14.

Small loads (perturbation in α, the nonlinearity is odd in α):
w/ℓ = α/3 − 4α³/105 + O(α⁵), u/ℓ = α²/15 − 4α⁴/315 + O(α⁶), ψ_t = α/2 − 11α³/240 + O(α⁵).

2. The extensible, shearable (Reissner / Cosserat) rod
-----------------------------------------------------
The model of the finite-element code in statics: strains in the section frame, shear
γ = r'·d1 and axial ε = r'·d3 − 1, bending ψ'; linear constitutive law

.. math::

    V = n\cdot d_1 = P_x\cos\psi - P_z\sin\psi = \kappa GA\,\gamma, \qquad
    N = n\cdot d_3 = P_x\sin\psi + P_z\cos\psi = EA\,\varepsilon, \qquad
    m = EI\,\psi'\,e_2,

kinematics r' = (1 + ε) d3 + γ d1. Since r' × n = ((1+ε)V − γN) d3 × d1 and d3 × d1 = d2,
the moment balance m' + r' × n = 0 reads

.. math::

    EI\,\psi'' + (1+\varepsilon)V - \gamma N
      = EI\,\psi'' + V\Bigl[1 + N\Bigl(\frac{1}{EA} - \frac{1}{\kappa GA}\Bigr)\Bigr] = 0,

with ψ(0) = 0, x(0) = z(0) = 0, EI ψ'(ℓ) = M and

.. math::

    x' = (1+\varepsilon)\sin\psi + \gamma\cos\psi, \qquad
    z' = (1+\varepsilon)\cos\psi - \gamma\sin\psi.

Check: for small P = P_x (P_z = M = 0), EI ψ'' ≈ −P, so ψ = P(ℓs − s²/2)/EI and
x(ℓ) ≈ Pℓ³/(3EI) + Pℓ/(κGA), the linear Timoshenko cantilever. With EA = κGA = ∞ the
elastica is recovered; for P_x = P_z = 0 the rod bends into the circular arc ψ = Ms/EI,
x = (EI/M)(1 − cos(Ms/EI)), z = (EI/M) sin(Ms/EI) (N = V = 0, so extensibility plays no
role). The equation is autonomous, with the first integral

.. math::

    \tfrac12 EI\,\psi'^2 + N(\psi) + \tfrac12\Bigl(\frac{1}{EA} - \frac{1}{\kappa GA}\Bigr)
    N(\psi)^2 = \text{const},

(dN/dψ = V), and global equilibrium gives EI ψ'(0) = M + P_x z(ℓ) − P_z x(ℓ).
Solved by ``solve_bvp`` in the scaled variable s/ℓ, with continuation in the load factor.
Compressive P_z beyond the buckling load may converge to any equilibrium branch.
Tests: tests/test_elastica_reference.py.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Literal, NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.integrate import solve_bvp
from scipy.optimize import brentq
from scipy.special import ellipeinc, ellipj, ellipkinc

__all__ = [
    "ELASTICA_TIP_TABLE",
    "MATTIASSON_1981",
    "MATTIASSON_ALPHAS",
    "ElasticaSolution",
    "MattiassonEntry",
    "ReissnerSolution",
    "TipValues",
    "elastica_tip_load",
    "reissner_tip_load",
    "small_load_expansion",
]

FloatArray = NDArray[np.float64]
Fields = Callable[[FloatArray], FloatArray]

#: Default and robust collocation tolerance. Tighter requests are attempted from the 1e-11
#: solution and kept only if they converge: round-off puts a floor ≈ ε·N·max|y| on the
#: residual with N nodes, so 1e-12 (N ≈ 2000-10000) stalls for most loads beyond α ≈ 1.
_BVP_TOL = 1e-11
_MAX_NODES = 50_000
#: Largest change of ψ [rad] accepted in one continuation step (keeps to the stable branch).
_MAX_DPSI = 0.5


# --------------------------------------------------------------------------------------------
# Tables
# --------------------------------------------------------------------------------------------
class TipValues(NamedTuple):
    """Tip of the elastica: w/ℓ = x(ℓ)/ℓ, u/ℓ = 1 − z(ℓ)/ℓ, and the tip angle ψ(ℓ) [rad]."""

    deflection: float
    shortening: float
    angle: float


class MattiassonEntry(NamedTuple):
    """One row of Mattiasson's (1981) table: axial displacement u/ℓ, deflection w/ℓ."""

    u: float
    w: float


#: Load levels α = Pℓ²/EI of the benchmark table.
MATTIASSON_ALPHAS: tuple[float, ...] = (1.0, 2.0, 5.0, 10.0)

#: Mattiasson (1981), IJNME 17:145-153, as widely reproduced (5 digits): α -> (u/ℓ, w/ℓ).
#: All eight printed values equal the exact ones of :data:`ELASTICA_TIP_TABLE` rounded to 5
#: decimals (no last-digit discrepancy).
MATTIASSON_1981: dict[float, MattiassonEntry] = {
    1.0: MattiassonEntry(u=0.05643, w=0.30172),
    2.0: MattiassonEntry(u=0.16064, w=0.49346),
    5.0: MattiassonEntry(u=0.38763, w=0.71379),
    10.0: MattiassonEntry(u=0.55500, w=0.81061),
}

#: Computed here (elliptic integrals; the collocation solution agrees to ~1e-15):
#: α -> (w/ℓ, u/ℓ, ψ_tip), 15 significant digits.
ELASTICA_TIP_TABLE: dict[float, TipValues] = {
    1.0: TipValues(0.301720773799814, 0.0564332362833768, 0.461351949711879),
    2.0: TipValues(0.493457480396711, 0.160641720825167, 0.781749831556543),
    5.0: TipValues(0.713791523611913, 0.387628360724430, 1.21536811761168),
    10.0: TipValues(0.810609024880296, 0.554995597753751, 1.43028553880386),
}


def small_load_expansion(alpha: float) -> TipValues:
    """Perturbation series of the elastica tip about α = 0 (error O(α⁵), O(α⁶), O(α⁵)).

    w/ℓ = α/3 − 4α³/105, u/ℓ = α²/15 − 4α⁴/315, ψ_t = α/2 − 11α³/240; from
    ψ = αψ₁ + α³ψ₃ with ψ₁ = s − s²/2, ψ₃'' = ψ₁²/2, ψ₃(0) = ψ₃'(1) = 0, and
    x = ∫(ψ − ψ³/6), 1 − z = ∫(ψ²/2 − ψ⁴/24).
    """
    a = alpha
    return TipValues(
        deflection=a / 3.0 - 4.0 * a**3 / 105.0,
        shortening=a**2 / 15.0 - 4.0 * a**4 / 315.0,
        angle=a / 2.0 - 11.0 * a**3 / 240.0,
    )


# --------------------------------------------------------------------------------------------
# Elastica
# --------------------------------------------------------------------------------------------
class _PlanarFields:
    """The fields of a planar solution (:class:`ElasticaSolution`: dimensionless, s ∈ [0, 1],
    lengths over ℓ; :class:`ReissnerSolution`: s ∈ [0, ℓ] [m], lengths [m]) from its
    interpolant ``_fields``: (ψ, ψ', x, z) at the stations s."""

    _fields: Fields

    def fields(self, s: ArrayLike) -> FloatArray:
        """Array (4,) + s.shape of (ψ, ψ', x, z) at the stations s."""
        s = np.asarray(s, dtype=float)
        return self._fields(s.ravel()).reshape((4, *s.shape))

    def psi(self, s: ArrayLike) -> FloatArray:
        """The section's (the tangent's, unshearable) angle ψ(s) [rad]."""
        return self.fields(s)[0]

    def curvature(self, s: ArrayLike) -> FloatArray:
        """The bending strain ψ'(s); the moment is EI ψ' (dimensionless: times ℓ)."""
        return self.fields(s)[1]

    def x(self, s: ArrayLike) -> FloatArray:
        """x(s), along the load."""
        return self.fields(s)[2]

    def z(self, s: ArrayLike) -> FloatArray:
        """z(s), along the undeformed axis."""
        return self.fields(s)[3]


@dataclass(frozen=True)
class ElasticaSolution(_PlanarFields):
    """Dimensionless elastica (ℓ = 1, load α = Pℓ²/EI); see the module docstring for scaling.

    Attributes:
        alpha: α = Pℓ²/EI.
        method: ``"elliptic"`` or ``"bvp"``.
        tip_angle: ψ(ℓ) [rad].
        tip_deflection: w/ℓ = x(ℓ)/ℓ, along the load.
        shortening: u/ℓ = 1 − z(ℓ)/ℓ, axial tip displacement.
        modulus: elliptic modulus k = sin((π/2 + ψ_t)/2).
        s, psi_values, x_values, z_values: the fields at stations s ∈ [0, 1] (the collocation
            mesh for ``"bvp"``, equispaced for ``"elliptic"``).
        tol: collocation tolerance reached (0 for the closed form).
    """

    alpha: float
    method: str
    tip_angle: float
    tip_deflection: float
    shortening: float
    modulus: float
    s: FloatArray
    psi_values: FloatArray
    x_values: FloatArray
    z_values: FloatArray
    tol: float
    _fields: Fields = field(repr=False, compare=False)

    @property
    def tip(self) -> TipValues:
        """(w/ℓ, u/ℓ, ψ_tip)."""
        return TipValues(self.tip_deflection, self.shortening, self.tip_angle)


def _elliptic_parts(beta: float) -> tuple[float, float, float, float]:
    """(k, k', m = k², φ2) for the tip angle ψ_t = π/2 − β (β ∈ (0, π/2]).

    k = cos(β/2), k' = sin(β/2); sin φ1 = 1/(√2 k), cos φ1 = √(sin ψ_t/(1 + sin ψ_t)),
    tan φ2 = cot φ1/k'.
    """
    k, kp = math.cos(0.5 * beta), math.sin(0.5 * beta)
    sin_t = math.cos(beta)
    s1 = 1.0 / (math.sqrt(2.0) * k)
    c1 = math.sqrt(sin_t / (1.0 + sin_t))
    return k, kp, k * k, math.atan2(c1, kp * s1)


def _amplitude(u: FloatArray, m: float) -> FloatArray:
    """Jacobi amplitude χ = am(u, m), i.e. F(χ, m) = u, polished by Newton (dF/dχ = 1/Δ)."""
    chi = np.asarray(ellipj(u, m)[3], dtype=float)
    for _ in range(3):
        chi = chi - (ellipkinc(chi, m) - u) * np.sqrt(1.0 - m * np.sin(chi) ** 2)
    return chi


def _g(chi: FloatArray | float, k: float, kp: float) -> FloatArray:
    """g(χ) = E(χ, k) − k² sin χ cos χ / Δ(χ)."""
    sn, cn = np.sin(chi), np.cos(chi)
    dn = np.hypot(cn, kp * sn)
    return ellipeinc(chi, k * k) - k * k * sn * cn / dn


def _elastica_elliptic(alpha: float, stations: int) -> ElasticaSolution:
    sa = math.sqrt(alpha)

    def residual(beta: float) -> float:
        k, kp, m, phi2 = _elliptic_parts(beta)
        return float(ellipkinc(phi2, m)) - sa

    hi = 0.5 * math.pi  # ψ_t = 0: residual = −√α < 0
    lo = 0.25 * math.pi
    while residual(lo) <= 0.0:
        lo *= 1.0 / 16.0
        if lo < 1e-250:
            raise ValueError(f"alpha = {alpha:g} too large for the elliptic solution")
    beta = brentq(residual, lo, hi, xtol=1e-300, rtol=4.0 * np.finfo(float).eps, maxiter=500)
    k, kp, m, phi2 = _elliptic_parts(beta)
    tip_angle = 0.5 * math.pi - beta
    g2 = float(_g(phi2, k, kp))
    sin2, d2 = math.sin(phi2), math.hypot(math.cos(phi2), kp * math.sin(phi2))

    def fields(s: FloatArray) -> FloatArray:
        chi = _amplitude(sa * (1.0 - s), m)
        sn, cn = np.sin(chi), np.cos(chi)
        dn2 = cn**2 + (kp * sn) ** 2
        dn = np.sqrt(dn2)
        psi = np.arctan2(2.0 * m * cn**2 / dn2 - 1.0, 2.0 * k * kp * cn / dn2)
        kappa = 2.0 * k * kp * sa * sn / dn
        x = s - 2.0 * (g2 - _g(chi, k, kp)) / sa
        z = 2.0 * k * kp * (sin2 / d2 - sn / dn) / sa
        return np.vstack([psi, kappa, x, z])

    x_tip = 1.0 - 2.0 * g2 / sa
    z_tip = 2.0 * k * kp * sin2 / d2 / sa
    s = np.linspace(0.0, 1.0, stations)
    y = fields(s)
    return ElasticaSolution(
        alpha=alpha,
        method="elliptic",
        tip_angle=tip_angle,
        tip_deflection=x_tip,
        shortening=1.0 - z_tip,
        modulus=k,
        s=s,
        psi_values=y[0],
        x_values=y[2],
        z_values=y[3],
        tol=0.0,
        _fields=fields,
    )


# --------------------------------------------------------------------------------------------
# Collocation with load continuation (shared by both models)
# --------------------------------------------------------------------------------------------
FunFactory = Callable[[float], tuple[Callable, Callable]]
BC = Callable[[FloatArray, FloatArray], FloatArray]
BCJac = Callable[[FloatArray, FloatArray], tuple[FloatArray, FloatArray]]


@dataclass
class _BVPResult:
    """A converged ``solve_bvp`` result and the tolerance it reached."""

    sol: Any
    tol: float


def _bvp_tight(
    fun_jac: tuple[Callable, Callable],
    bc: BC,
    bc_jac: BCJac,
    mesh: FloatArray,
    y: FloatArray,
    tol: float,
) -> _BVPResult:
    """Solve at max(tol, 1e-11); if tol is tighter, try it from there (kept if converged)."""
    fun, jac = fun_jac
    first = max(tol, _BVP_TOL)
    sol = solve_bvp(fun, bc, mesh, y, fun_jac=jac, bc_jac=bc_jac, tol=first, max_nodes=_MAX_NODES)
    if sol.status != 0:
        raise RuntimeError(f"solve_bvp failed at tol {first:g}: {sol.message}")
    if tol < first:
        tight = solve_bvp(
            fun,
            bc,
            sol.x,
            sol.y,
            fun_jac=jac,
            bc_jac=bc_jac,
            tol=tol,
            max_nodes=min(_MAX_NODES, 5 * sol.x.size // 2),
        )
        if tight.status == 0:
            return _BVPResult(tight, tol)
    return _BVPResult(sol, first)


def _solve_continued(
    factory: FunFactory,
    bc_factory: Callable[[float], tuple[BC, BCJac]],
    guess: Callable[[float, FloatArray], FloatArray],
    tol: float,
    nodes: int = 101,
) -> _BVPResult:
    r"""Solve the BVP at load factor λ = 1 by continuation in λ from the linear solution.

    ``factory(λ)`` returns (fun, fun_jac), ``bc_factory(λ)`` (bc, bc_jac) and
    ``guess(λ, s)`` the linear-theory solution (row 0 = ψ), which starts the path at the
    largest λ ≤ 1 where it is small (max |ψ| ≤ 0.5 rad). Each step is solved at tol 1e-6
    from the previous solution and accepted only if ψ changed by at most 0.5 rad (so the
    path stays on the branch connected to the straight rod: at large loads the elastica has
    other, looped equilibria that a distant initial guess can converge to); the step grows
    ×1.5 on success and halves on failure. The full load is finally solved by
    :func:`_bvp_tight` at ``tol``.
    """
    mesh = np.linspace(0.0, 1.0, nodes)
    amplitude = float(np.max(np.abs(guess(1.0, mesh)[0])))
    lam = min(1.0, 0.5 / amplitude) if amplitude > 0.0 else 1.0
    fun, jac = factory(lam)
    bc, bc_jac = bc_factory(lam)
    sol = solve_bvp(fun, bc, mesh, guess(lam, mesh), fun_jac=jac, bc_jac=bc_jac, tol=1e-6)
    if sol.status != 0:
        raise RuntimeError(f"solve_bvp failed from the linear solution: {sol.message}")
    step = lam
    while lam < 1.0:
        trial = min(1.0, lam + step)
        fun, jac = factory(trial)
        bc, bc_jac = bc_factory(trial)
        new = solve_bvp(fun, bc, sol.x, sol.y, fun_jac=jac, bc_jac=bc_jac, tol=1e-6)
        if new.status == 0 and np.max(np.abs(new.y[0] - sol.sol(new.x)[0])) <= _MAX_DPSI:
            lam, sol = trial, new
            step *= 1.5
        else:
            step *= 0.5
            if step < 1e-6:
                raise RuntimeError(f"load continuation stalled at load factor {lam:.6g}")
    return _bvp_tight(factory(1.0), *bc_factory(1.0), sol.x, sol.y, tol)


def _elastica_bvp(alpha: float, tol: float) -> ElasticaSolution:
    """y = (ψ, κ, x, z), y' = (κ, −α cos ψ, sin ψ, cos ψ)."""

    def factory(lam: float) -> tuple[Callable, Callable]:
        a = lam * alpha

        def fun(s: FloatArray, y: FloatArray) -> FloatArray:
            c, sn = np.cos(y[0]), np.sin(y[0])
            return np.vstack([y[1], -a * c, sn, c])

        def jac(s: FloatArray, y: FloatArray) -> FloatArray:
            J = np.zeros((4, 4, s.size))
            c, sn = np.cos(y[0]), np.sin(y[0])
            J[0, 1] = 1.0
            J[1, 0] = a * sn
            J[2, 0] = c
            J[3, 0] = -sn
            return J

        return fun, jac

    def bc_factory(lam: float) -> tuple[BC, BCJac]:
        def bc(ya: FloatArray, yb: FloatArray) -> FloatArray:
            return np.array([ya[0], ya[2], ya[3], yb[1]])

        def bc_jac(ya: FloatArray, yb: FloatArray) -> tuple[FloatArray, FloatArray]:
            A, B = np.zeros((4, 4)), np.zeros((4, 4))
            A[0, 0] = A[1, 2] = A[2, 3] = B[3, 1] = 1.0
            return A, B

        return bc, bc_jac

    def guess(lam: float, s: FloatArray) -> FloatArray:
        a = lam * alpha
        return np.vstack([a * (s - 0.5 * s**2), a * (1.0 - s), a * (0.5 * s**2 - s**3 / 6), s])

    res = _solve_continued(factory, bc_factory, guess, tol)
    sol = res.sol

    def fields(s: FloatArray) -> FloatArray:
        return np.asarray(sol.sol(s), dtype=float)

    psi_t = float(sol.y[0, -1])
    return ElasticaSolution(
        alpha=alpha,
        method="bvp",
        tip_angle=psi_t,
        tip_deflection=float(sol.y[2, -1]),
        shortening=1.0 - float(sol.y[3, -1]),
        modulus=math.sin(0.25 * math.pi + 0.5 * psi_t),
        s=np.asarray(sol.x, dtype=float),
        psi_values=np.asarray(sol.y[0], dtype=float),
        x_values=np.asarray(sol.y[2], dtype=float),
        z_values=np.asarray(sol.y[3], dtype=float),
        tol=res.tol,
        _fields=fields,
    )


def elastica_tip_load(
    alpha: float,
    method: Literal["elliptic", "bvp"] = "elliptic",
    stations: int = 201,
    tol: float = _BVP_TOL,
) -> ElasticaSolution:
    r"""Euler's elastica cantilever under a dead tip force perpendicular to the rod.

    Solves EI ψ'' + P cos ψ = 0, ψ(0) = 0, ψ'(ℓ) = 0 in dimensionless form (ℓ = 1,
    α = Pℓ²/EI) by the elliptic-integral closed form or by collocation (see the module
    docstring for both and for the scaling to a dimensional rod). Negative α mirrors the
    solution (ψ, x → −ψ, −x).

    Args:
        alpha: α = Pℓ²/EI. The closed form is accurate up to α ~ 10³ (ψ_t → π/2, k' → 0).
        method: ``"elliptic"`` (default) or ``"bvp"``.
        stations: number of equispaced stations stored for ``"elliptic"``.
        tol: ``solve_bvp`` tolerance for ``"bvp"``; requests below 1e-11 are attempted from
            the 1e-11 solution and kept only if they converge (the reached value is
            ``.tol``). At 1e-11 the two methods agree to ~1e-14 for α ≤ 20.
    """
    alpha = float(alpha)
    if method not in ("elliptic", "bvp"):
        raise ValueError(f"method must be 'elliptic' or 'bvp', got {method!r}")
    if alpha < 0.0:
        sol = elastica_tip_load(-alpha, method, stations, tol)
        flip = np.array([-1.0, -1.0, -1.0, 1.0])[:, None]
        inner = sol._fields
        return ElasticaSolution(
            alpha=alpha,
            method=sol.method,
            tip_angle=-sol.tip_angle,
            tip_deflection=-sol.tip_deflection,
            shortening=sol.shortening,
            modulus=sol.modulus,
            s=sol.s,
            psi_values=-sol.psi_values,
            x_values=-sol.x_values,
            z_values=sol.z_values,
            tol=sol.tol,
            _fields=lambda s: flip * inner(s),
        )
    if alpha == 0.0:
        s = np.linspace(0.0, 1.0, stations)
        zero = np.zeros_like(s)

        def straight(t: FloatArray) -> FloatArray:
            return np.vstack([0.0 * t, 0.0 * t, 0.0 * t, t])

        return ElasticaSolution(
            0.0, method, 0.0, 0.0, 0.0, math.sqrt(0.5), s, zero, zero, s.copy(), 0.0, straight
        )
    if method == "elliptic":
        return _elastica_elliptic(alpha, stations)
    return _elastica_bvp(alpha, tol)


# --------------------------------------------------------------------------------------------
# Reissner rod
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class ReissnerSolution(_PlanarFields):
    """Static planar extensible, shearable rod under a dead end force and an end moment.

    Attributes:
        length, EA, GAk, EI: ℓ [m], axial EA [N], shear κGA [N], bending EI [N m²].
        P, Pz, M: end force components along e1 and e3 [N] and end moment about e2 [N m].
        tip_x, tip_z: tip position x(ℓ), z(ℓ) [m]; tip_angle: ψ(ℓ) [rad].
        s: collocation mesh [m]; tol: solve_bvp tolerance reached.
    """

    length: float
    EA: float
    GAk: float
    EI: float
    P: float
    Pz: float
    M: float
    tip_x: float
    tip_z: float
    tip_angle: float
    s: FloatArray
    tol: float
    _fields: Fields = field(repr=False, compare=False)

    def normal_force(self, s: ArrayLike) -> FloatArray:
        """N = n·d3 = P sin ψ + P_z cos ψ [N]."""
        psi = self.psi(s)
        return self.P * np.sin(psi) + self.Pz * np.cos(psi)

    def shear_force(self, s: ArrayLike) -> FloatArray:
        """V = n·d1 = P cos ψ − P_z sin ψ [N]."""
        psi = self.psi(s)
        return self.P * np.cos(psi) - self.Pz * np.sin(psi)

    def axial_strain(self, s: ArrayLike) -> FloatArray:
        """ε = N/EA."""
        return self.normal_force(s) / self.EA

    def shear_strain(self, s: ArrayLike) -> FloatArray:
        """γ = V/(κGA)."""
        return self.shear_force(s) / self.GAk


def reissner_tip_load(
    length: float,
    EA: float,
    GAk: float,
    EI: float,
    P: float,
    Pz: float = 0.0,
    M: float = 0.0,
    tol: float = _BVP_TOL,
) -> ReissnerSolution:
    r"""Planar Reissner (Cosserat) cantilever under a dead end force (P, 0, Pz) and moment M.

    Solves, in t = s/ℓ with y = (ψ, μ = dψ/dt, ξ = x/ℓ, ζ = z/ℓ),

    .. math::

        \psi_t = \mu, \quad
        \mu_t = -\frac{\ell^2}{EI}\,V\bigl[1 + N(1/EA - 1/\kappa GA)\bigr], \quad
        \xi_t = (1+N/EA)\sin\psi + \frac{V}{\kappa GA}\cos\psi, \quad
        \zeta_t = (1+N/EA)\cos\psi - \frac{V}{\kappa GA}\sin\psi,

    ψ(0) = ξ(0) = ζ(0) = 0, μ(1) = Mℓ/EI (derivation in the module docstring), by
    ``solve_bvp`` with continuation in the load factor, at ``tol`` (default 1e-11; tighter
    requests are kept only if they converge, see :func:`elastica_tip_load`). ``EA`` and
    ``GAk`` may be ``math.inf`` (inextensible / unshearable).
    """
    ell = float(length)
    cE = 0.0 if math.isinf(EA) else 1.0 / EA
    cG = 0.0 if math.isinf(GAk) else 1.0 / GAk
    c = cE - cG
    scale = ell * ell / EI

    def factory(lam: float) -> tuple[Callable, Callable]:
        px, pz = lam * P, lam * Pz

        def parts(y: FloatArray) -> tuple[FloatArray, ...]:
            cs, sn = np.cos(y[0]), np.sin(y[0])
            V = px * cs - pz * sn
            N = px * sn + pz * cs
            return cs, sn, V, N

        def fun(t: FloatArray, y: FloatArray) -> FloatArray:
            cs, sn, V, N = parts(y)
            stretch, gamma = 1.0 + cE * N, cG * V
            return np.vstack(
                [
                    y[1],
                    -scale * V * (1.0 + c * N),
                    stretch * sn + gamma * cs,
                    stretch * cs - gamma * sn,
                ]
            )

        def jac(t: FloatArray, y: FloatArray) -> FloatArray:
            cs, sn, V, N = parts(y)
            stretch, gamma = 1.0 + cE * N, cG * V
            J = np.zeros((4, 4, t.size))
            J[0, 1] = 1.0
            J[1, 0] = -scale * (-N + c * (V * V - N * N))  # dV/dψ = −N, dN/dψ = V
            J[2, 0] = cE * V * sn + stretch * cs - cG * N * cs - gamma * sn
            J[3, 0] = cE * V * cs - stretch * sn + cG * N * sn - gamma * cs
            return J

        return fun, jac

    def bc_factory(lam: float) -> tuple[BC, BCJac]:
        mu_tip = lam * M * ell / EI

        def bc(ya: FloatArray, yb: FloatArray) -> FloatArray:
            return np.array([ya[0], ya[2], ya[3], yb[1] - mu_tip])

        def bc_jac(ya: FloatArray, yb: FloatArray) -> tuple[FloatArray, FloatArray]:
            A, B = np.zeros((4, 4)), np.zeros((4, 4))
            A[0, 0] = A[1, 2] = A[2, 3] = B[3, 1] = 1.0
            return A, B

        return bc, bc_jac

    def guess(lam: float, t: FloatArray) -> FloatArray:
        """Linear bending ψ with the exact position integrals of that ψ (trapezoidal)."""
        a, b = lam * P * scale, lam * M * ell / EI
        psi = a * (t - 0.5 * t**2) + b * t
        mu = a * (1.0 - t) + b
        dt = np.diff(t)
        xi = np.concatenate([[0.0], np.cumsum(0.5 * dt * (np.sin(psi[1:]) + np.sin(psi[:-1])))])
        zeta = np.concatenate([[0.0], np.cumsum(0.5 * dt * (np.cos(psi[1:]) + np.cos(psi[:-1])))])
        return np.vstack([psi, mu, xi, zeta])

    res = _solve_continued(factory, bc_factory, guess, tol)
    sol = res.sol
    units = np.array([1.0, 1.0 / ell, ell, ell])[:, None]

    def fields(s: FloatArray) -> FloatArray:
        return units * np.asarray(sol.sol(s / ell), dtype=float)

    return ReissnerSolution(
        length=ell,
        EA=float(EA),
        GAk=float(GAk),
        EI=float(EI),
        P=float(P),
        Pz=float(Pz),
        M=float(M),
        tip_x=ell * float(sol.y[2, -1]),
        tip_z=ell * float(sol.y[3, -1]),
        tip_angle=float(sol.y[0, -1]),
        s=ell * np.asarray(sol.x, dtype=float),
        tol=res.tol,
        _fields=fields,
    )


def buckled_column_load(
    alpha: float, length: float, EI: float, EA: float = math.inf, GAk: float = math.inf
) -> float:
    r"""The dead axial end load P [N] under which a clamped-free column of the Reissner rod
    (section 2 of the module docstring) buckles into the post-buckled state whose free end
    has turned by ``alpha`` [rad] (0 < |α| < π), on its first buckled branch.

    With n = −P e3: V = P sin ψ, N = −P cos ψ, and the moment balance reads
    EI ψ'' + P sin ψ (1 + aP cos ψ) = 0, a = 1/κGA − 1/EA, ψ(0) = 0, ψ'(ℓ) = 0, ψ(ℓ) = α.
    Its first integral ½EI ψ'² = F(α) − F(ψ), F(ψ) = P(1 − cos ψ) + ½aP² sin²ψ, factors as
    F(α) − F(ψ) = P (cos ψ − cos α) [1 + ½aP (cos ψ + cos α)], and with
    sin(ψ/2) = k sin φ, k = sin(α/2) (ψ from 0 to α as φ from 0 to π/2),

    .. math::

        \ell = \sqrt{EI/P}\int_0^{\pi/2}
            \frac{d\varphi}{\sqrt{1 - k^2\sin^2\varphi}\,
                  \sqrt{1 + \tfrac12 aP(\cos\psi + \cos\alpha)}},
        \qquad \cos\psi = 1 - 2k^2\sin^2\varphi,

    solved for P by Brent's method (the integral by Gauss–Legendre, 64 points: the integrand
    is analytic on the closed interval, the error below 1e-14 relative). For EA = κGA = ∞ it
    is the elastica's closed form P = (EI/ℓ²) K(k)², i.e. P/P_E = (2K(k)/π)² with
    P_E = π² EI/(4ℓ²), K the complete elliptic integral of the first kind."""
    k = math.sin(abs(alpha) / 2.0)
    a = (0.0 if math.isinf(GAk) else 1.0 / GAk) - (0.0 if math.isinf(EA) else 1.0 / EA)
    nodes, weights = np.polynomial.legendre.leggauss(64)
    phi = 0.25 * math.pi * (nodes + 1.0)
    weights = 0.25 * math.pi * weights
    s2 = np.sin(phi) ** 2
    cos_psi = 1.0 - 2.0 * k * k * s2
    delta = np.sqrt(1.0 - k * k * s2)

    def mismatch(P: float) -> float:
        factor = np.sqrt(1.0 + 0.5 * a * P * (cos_psi + math.cos(alpha)))
        return math.sqrt(EI / P) * float(weights @ (1.0 / (delta * factor))) - length

    P_E = math.pi**2 * EI / (4.0 * length**2)
    return float(brentq(mismatch, 0.5 * P_E, 50.0 * P_E, xtol=1e-15 * P_E, rtol=1e-15))
