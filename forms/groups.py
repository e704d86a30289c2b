"""Scalings (47) and dimensionless groups (48) of Cao & Tucker (2008).

Dimensionless variables (47): σ = s/ℓ, p1..p3 = (x, y, z)/ℓ, p4..p6 = (θ, ψ, φ), τ = ω0 t.

Each balance law of (39) is divided by a reference so that its acceleration term has unit
coefficient: the force balance by ρ A ω0² ℓ (so g0 = 1/(ρ A ω0² ℓ)), the moment balance about
d_i by ρ I_ii ω0² (so g_i = 1/(ρ I_ii ω0²)), with the rotary inertias (46)
I11 = ρ c11, I22 = ρ c22, I33 = ρ (c11 + c22).

The torsion row is where the paper is inconsistent (see docs/errata.md, erratum 1): eq. (54)
as printed, with ν31 = G/(ρ ℓ² ω0²), ν32 = E (c22 − c11)/(ρ ℓ² c33 ω0²),
ν33 = (c22 − c11)/c33 and g3 = 1/(ρ c33 ω0²), is the moment balance about d3 divided by
ρ c33 ω0², i.e. it carries the rotary inertia ρ c33 instead of the I33 = ρ (c11 + c22) of (46)
that (52)-(53) use. Here the torsion row is divided by ρ I3 ω0² with I3 chosen by
``torsion_inertia``:

* ``"polar"`` (default, consistent with (46) and (52)-(53)): I3 = c11 + c22, so
  ν31 = G c33/(ρ ℓ² ω0² (c11 + c22)), ν32 = E (c22 − c11)/(ρ ℓ² ω0² (c11 + c22)),
  ν33 = (c22 − c11)/(c11 + c22), g3 = 1/(ρ (c11 + c22) ω0²);
* ``"printed"``: I3 = c33, which reproduces (48) and (54) exactly as printed.

Rotary inertias given apart from the section (``RodConstants.inertia``: I11, I22, I33 per unit
length, e.g. Simo & Vu-Quoc's benchmarks, whose mass is not that of a solid section) divide the
rows instead, and the gyroscopic coefficients of rows 4 and 5, (I33 − I22)/I11 and
(I11 − I33)/I22 (1 and −1 for (46)), become ``gamma1``, ``gamma2``; row 6's is ν33 =
(I22 − I11)/I33. The bending and torsion stiffnesses E c11, E c22, G c33 stay the section's.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

from .section import Section, SectionLaw


@dataclass(frozen=True)
class RodConstants:
    """Physical constants of a uniform straight rod, SI units.

    length ℓ [m]; section (A, c11, c22, c33, κ); density ρ [kg/m³]; Young's modulus E [Pa];
    shear modulus G [Pa]; reference frequency ω0 [rad/s] of the time scaling (47).
    """

    length: float
    section: Section
    density: float
    young_modulus: float
    shear_modulus: float
    omega0: float
    torsion_inertia: str = "polar"
    #: (I11, I22, I33) [kg m] per unit length given apart from the section, or None: (46).
    inertia: tuple[float, float, float] | None = None
    #: A general section law (forms/section.py), or None: the paper's diagonal (13) of
    #: ``section``. With one, ``section``, ρ and the inertias above are the references of the
    #: scaling (47)-(48) only (ω0, the rows' divisors); the law's K, μ and I act in the balance.
    law: SectionLaw | None = None

    def __repr__(self) -> str:
        """The dataclass's repr, without ``law`` when there is none (the repr of the rods
        before the law existed, which tests/unit/scene/test_keys.py compares)."""
        shown = [f for f in fields(self) if not (f.name == "law" and self.law is None)]
        text = ", ".join(f"{f.name}={getattr(self, f.name)!r}" for f in shown)
        return f"{type(self).__name__}({text})"

    @property
    def rotary_inertias(self) -> tuple[float, float, float]:
        """I11/ρ, I22/ρ, I33/ρ [m⁴]: c11, c22 (46) and the torsion row's I3 (module
        docstring), or the given ones over ρ: the one source for the equations, the energy and
        the modes."""
        if self.inertia is not None:
            i1, i2, i3 = self.inertia
            return i1 / self.density, i2 / self.density, i3 / self.density
        return self.section.c11, self.section.c22, self.torsion_row_inertia

    @property
    def mass_inertias(self) -> tuple[float, float, float]:
        """(I11, I22, I33) [kg m] per unit length of the balance laws (6): given, or
        ρ (c11, c22, c11 + c22) (46), whatever divides the torsion row."""
        if self.inertia is not None:
            return self.inertia
        s = self.section
        return self.density * s.c11, self.density * s.c22, self.density * (s.c11 + s.c22)

    @property
    def torsion_row_inertia(self) -> float:
        """I3 / ρ [m⁴] that divides the torsion row (see the module docstring)."""
        s = self.section
        if self.inertia is not None:
            return self.inertia[2] / self.density
        if self.torsion_inertia == "polar":
            return s.c11 + s.c22
        if self.torsion_inertia == "printed":
            return s.c33
        raise ValueError(f"unknown torsion_inertia {self.torsion_inertia!r}")


def euler_bernoulli_omega0(length: float, section: Section, density: float, young: float) -> float:
    """The paper's reference frequency (section 6): ω0 = 1.875²/ℓ² · sqrt(E c22/(ρ A)).

    (1.875 is the paper's rounding of β1 ℓ = 1.87510407, the first root of cos β cosh β = −1.)
    """
    return 1.875**2 / length**2 * math.sqrt(young * section.c22 / (density * section.area))


@dataclass(frozen=True)
class Groups:
    """The dimensionless groups of (48), with the torsion row generalised (module docstring).

    ``length`` is kept because the free-end data (62) is scaled by g0/ℓ and g_i/ℓ.
    """

    length: float
    g0: float
    nu01: float
    nu02: float
    g1: float
    g2: float
    g3: float
    nu11: float
    nu12: float
    nu13: float
    nu14: float
    nu21: float
    nu22: float
    nu23: float
    nu24: float
    nu31: float
    nu32: float
    nu33: float
    gamma1: float = 1.0
    gamma2: float = -1.0

    def as_dict(self) -> dict[str, float]:
        return dict(self.__dict__)


def dimensionless_groups(rod: RodConstants) -> Groups:
    """Eq. (48), with I3 = ``rod.torsion_row_inertia`` in the torsion row."""
    s = rod.section
    rho, E, G, ell, w0 = rod.density, rod.young_modulus, rod.shear_modulus, rod.length, rod.omega0
    A, c11, c22, c33, kappa = s.area, s.c11, s.c22, s.c33, s.shear_coefficient
    i1, i2, i3 = rod.rotary_inertias
    g0 = 1.0 / (rho * A * w0**2 * ell)
    g1 = 1.0 / (rho * i1 * w0**2)
    g2 = 1.0 / (rho * i2 * w0**2)
    g3 = 1.0 / (rho * i3 * w0**2)
    scale = rho * ell**2 * w0**2
    gyro = {}
    if rod.inertia is not None:  # else exactly 1 and −1 (module docstring)
        gyro = {"gamma1": (i3 - i2) / i1, "gamma2": (i1 - i3) / i2}
    return Groups(
        length=ell,
        g0=g0,
        nu01=kappa * G * A * g0 / ell,
        nu02=E * A * g0 / ell,
        g1=g1,
        g2=g2,
        g3=g3,
        nu11=E * (c11 / i1) / scale,
        nu12=(G * c33 - E * c22) / (scale * i1),
        nu13=kappa * G * A * g1,
        nu14=E * A * g1,
        nu21=E * (c22 / i2) / scale,
        nu22=(G * c33 - E * c11) / (scale * i2),
        nu23=kappa * G * A * g2,
        nu24=E * A * g2,
        nu31=G * c33 / (scale * i3),
        nu32=E * (c22 - c11) / (scale * i3),
        nu33=(i2 - i1) / i3,
        **gyro,
    )
