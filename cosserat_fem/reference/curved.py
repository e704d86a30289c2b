"""Reference figures for rods curved at rest (tests/test_curved.py, benchmarks/verify.py).

* :data:`BATHE_BOLOURCHI_SHOOTING`: the tip displacement [in] of Bathe & Bolourchi's 45° bend
  (scenes/bathe_bolourchi_bend.toml) at 60, 120 and 600 lbf, from the shooting solution of
  benchmarks/curved/bathe_bolourchi_shooting.py (no finite elements; ODEs at 1e-12), as
  (towards the arc's centre, out of its plane, along the clamp's tangent).
* :data:`SIMO_VU_QUOC_RIGHT_ANGLE`: the extrema of the out-of-plane displacement of Simo &
  Vu-Quoc's (1988) right-angle cantilever (scenes/simo_vuquoc_right_angle.toml) in their
  published figure, digitised in AeroBeams (test/referenceData/elbowFrame, u3_elbow.txt and
  u3_tip.txt): (time, value) of the first maximum, the minimum and the maximum after t = 20,
  of the elbow and of the tip. Two digitisations of the figure differ by up to 0.4 in value
  and 1 in time.
* :func:`thin_ring_frequency`: the natural frequencies of a free circular ring, inextensible,
  without shear or rotary inertia (Love, sections 293-294; NAFEMS's free thin ring).
"""

from __future__ import annotations

BATHE_BOLOURCHI_SHOOTING = {
    60: (-0.4882970, 11.0391662, -0.8142055),
    120: (-1.7713363, 20.8555532, -2.9616345),
    600: (-13.6045213, 53.4748588, -23.5602395),
}

SIMO_VU_QUOC_RIGHT_ANGLE = {
    "elbow": ((3.05, 5.50), (10.8, -3.87), (25.2, 6.11)),
    "tip": ((7.67, 8.29), (16.0, -9.67), (26.1, 6.98)),
}


def right_angle_extrema(t, u, point: str) -> list[tuple[float, float]]:
    """The extrema of a history u(t) of ``point`` ("elbow" or "tip") that
    :data:`SIMO_VU_QUOC_RIGHT_ANGLE` lists: the first maximum (before t = 6 at the elbow,
    12 at the tip), the minimum, the maximum after t = 20; (time, value) each."""
    import numpy as np

    t, u = np.asarray(t), np.asarray(u)
    first = t < (12.0 if point == "tip" else 6.0)
    out = []
    for window, pick in ((first, np.argmax), (t == t, np.argmin), (t > 20.0, np.argmax)):
        k = np.flatnonzero(window)[pick(u[window])]
        out.append((float(t[k]), float(u[k])))
    return out


def thin_ring_frequency(n: int, plane: str, EI: float, GJ: float, rho_A: float, R: float) -> float:
    """ω [rad/s] of the mode of n waves round a free thin ring of radius R [m] (bending
    stiffness EI [N m²] in and out of its plane alike, torsion GJ [N m²], mass per length
    ρA [kg/m]), in its plane (``plane="in"``) or out of it (``"out"``):

        in:   ω² = EI n² (n² − 1)² / (ρA R⁴ (n² + 1)),
        out:  ω² = EI n² (n² − 1)² / (ρA R⁴ (n² + EI/GJ)).

    Inextensible centreline, no shear strain, no rotary inertia: the limit of a slender ring.
    For R = 1 m, d = 0.1 m, E = 200 GPa, ν = 0.3, ρ = 8000 kg/m³ and n = 2, 3, 4: 53.38,
    151.0, 289.5 Hz in plane and 51.85, 148.8, 287.0 Hz out of it (NAFEMS's values)."""
    import math

    ratio = {"in": 1.0, "out": EI / GJ}[plane]
    return math.sqrt(EI * n**2 * (n**2 - 1) ** 2 / (rho_A * R**4 * (n**2 + ratio)))
