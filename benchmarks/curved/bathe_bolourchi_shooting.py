"""Bathe & Bolourchi's 45° bend solved without finite elements, by shooting: the reference for
tests/test_curved.py and docs/verification.md.

    .venv/bin/python benchmarks/curved/bathe_bolourchi_shooting.py     # about 20 s

A circular arc of radius 100 in over 45° (length 25π in), clamped at s = 0 where it runs along
t = e3 and bends towards n = +e1 (the centre at (100, 0, 0) in), a 1 in × 1 in section,
E = 1e7 psi, ν = 0, GA = 5e6 lb (no shear correction), GJ = G (I2 + I3) = 8.333e5 lb in², a
dead tip force P along z = e2. The rod's equilibrium (6) with a dead end load is integrated
from the clamp: n(s) = P (the force is constant), m(s) = (r_tip − r(s)) × P, the strains from
the linear laws (10)-(13) about the arc, u = u0 + J⁻¹ m and v = e3 + K⁻¹ n in the directors'
components, r' = Σ v_i d_i, d_i' = u × d_i; the unknown tip position r_tip is found by Newton
(scipy fsolve) so that the integrated tip equals it, continued in load from 0. DOP853 at
rtol = atol = 1e-12. Prints the tip displacement (Δn, Δz, Δt) [in] every 60 lb, to 7 digits.
(The method is the research note's for issue 16; the circle, not BeamDyn's parabola.)
"""

from __future__ import annotations

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import fsolve

E, A, I = 1e7, 1.0, 1.0 / 12.0
GA, GJ = 5e6, 5e6 * 2.0 / 12.0
R = 100.0
L = R * np.pi / 4.0


def hat(w):
    return np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])


def tip(P: float, guess: np.ndarray) -> np.ndarray:
    """The tip position [in] under the force P [lb] along e2 (module docstring)."""
    F = np.array([0.0, P, 0.0])
    # Columns of Rm: the directors, d3 the tangent, d2 = e2 at rest, d1 = d2 × d3 (e1, towards
    # the centre, at s = 0), as the arc of [reference] shape = "arc".
    K, C = np.array([E * I, E * I, GJ]), np.array([GA, GA, E * A])
    u0 = np.array([0.0, 1.0 / R, 0.0])

    def rhs(s, y, r_tip):
        r, Rm = y[:3], y[3:].reshape(3, 3)  # Rm columns: d1, d2, d3 in the fixed basis
        m = np.cross(r_tip - r, F)
        u = u0 + Rm.T @ m / K
        v = np.array([0.0, 0.0, 1.0]) + Rm.T @ F / C
        return np.concatenate([Rm @ v, (Rm @ hat(u)).ravel()])

    y0 = np.concatenate([np.zeros(3), np.eye(3).ravel()])

    def residual(r_tip):
        sol = solve_ivp(rhs, (0.0, L), y0, args=(r_tip,), rtol=1e-12, atol=1e-12, method="DOP853")
        return sol.y[:3, -1] - r_tip

    return fsolve(residual, guess, xtol=1e-13)


def main() -> None:
    start = np.array([R * (1 - np.cos(np.pi / 4)), 0.0, R * np.sin(np.pi / 4)])
    r = tip(0.0, start)
    print(f"tip at rest: {r} (exact {start})")
    for P in np.arange(10.0, 601.0, 10.0):
        r = tip(P, r)
        if P % 60 == 0:
            d = r - start
            print(f"P = {P:5.0f} lb: dn = {d[0]:.7f}  dz = {d[1]:.7f}  dt = {d[2]:.7f} in")


if __name__ == "__main__":
    main()
