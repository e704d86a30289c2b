"""Limit points on the rod's equilibrium path, passed and located by continuation
(cosserat_fem/analysis/paths.py, issue 27 item 2): Lee's frame, snap-through and snap-back.

**Lee's frame** (scenes/lee_frame.toml: Lee, Manuel & Rossow 1968; two members of L = 120
at a right angle, hinged at both ends, EI = 1440, EA = 4320, a vertical load P at 24 from
the corner). The reference load is set to P = 10 so that λ = P/10: the arclength weighs the
state's RMS (x/ℓ, rad) against λ², and with P = 1 the path is nearly all λ, so its folds
are sharp in that metric and a step of the corrector jumps across the turn (measured: at the
lower limit, 10 P3 with steps up to 0.02); with λ = P/10 the two weigh alike and each fold
is passed in a few steps. The path of the load point's downward deflection w (the probe at
s = 144): P rises to a maximum P₁ (snap-through under load control), falls through zero to
a minimum P₂ < 0, and rises again; between the two limit points w itself turns back twice
(snap-back under displacement control: w grows to ~61, falls to ~51, grows again).

*Convergence.* The limit loads are extrema of the load along the discrete path, so they
converge like energies, h^(2k): P₁ on k = 3 elements: 1.8550447 (20), 1.8544634 (40),
1.8544529 (80), and 1.8544527 on 40 P4; the 40 → 80 P3 change (1.05e-5) against 20 → 40
(5.8e-4) is pre-asymptotic, 80 P3 and 40 P4 agree to 9e-8 relative. P₂: −0.940874 (20 P3),
−0.9392803 (40 P3), −0.9392495 (80 P3), −0.9392490 (40 P4): 5e-7 relative. Converged:

    P₁ = 1.854453 (P₁ L²/EI = 18.5445),   P₂ = −0.939249 (P₂ L²/EI = −9.3925).

*Against the literature.* The arc-length literature (Schweizerhof & Wriggers 1986, Simo &
Vu-Quoc 1986 and after) quotes P₁ ≈ 1.85 (P L²/EI ≈ 18.5) for the inextensible, shear-rigid
frame; no copy of the papers was readable here (2026-12-04), so the figure is not asserted.
The independent figures: this rod's own load stepping (another algorithm on the same
equations) converges at P = 1.8545 and not at 1.8555 on 20 P3 (scenes/lee_frame.toml), which
brackets the 20 P3 limit 1.85504 found here; and the same frame with EA and κGA × 1000 (the
shear-rigid, inextensible limit, 40 P3) has P₁ = 1.85797 (18.580) and P₂ = −0.94614.

**The rod in 3D.** A curved rod is solved in 3D, and this 3 × 2 section (out-of-plane
bending 2.25 × the in-plane, torsion 0.9 × in-plane bending) has a lateral (out-of-plane)
bifurcation on the planar path before the in-plane limit: det R_u changes sign at
P = 1.69299 (20 P3), where dλ/ds does not. It is out of the plane: with the out-of-plane
stiffnesses c11, c33 × 100 it is gone, and the in-plane path and limits are the same to
round-off (θ = φ = 0 on it: the in-plane equations do not see c11, c33). The literature's
frame is planar (braced out of its plane), so the limit loads are those of the planar path.

**A shallow arch** (scenes/shallow_arch.toml): a circular arc of span L ≈ 1 m, rise
e = 6 mm = 3 r (r = 2 mm the section's radius of gyration, EI = 38.4 N m², EA = 9.6e6 N),
pinned at both ends, under a dead load q0 sin(πz/L) per unit span. The shallow-arch
theory (Marguerre's equations, as in Timoshenko & Gere, Theory of Elastic Stability): the
rest shape y0 = Σ e_n sin(nπz/L) (its sine coefficients, by quadrature) and the shape
y = Σ A_n sin(nπz/L) under the thrust H, the bending equations of the modes

    EI k_n⁴ (A_n − e_n) − H k_n² A_n + q0 δ_n1 = 0,   k_n = nπ/L,

and the extension H/EA = Σ k_n² (e_n² − A_n²)/4 (Marguerre's strain u' + (y'² − y0'²)/2,
averaged: the ends do not move). Given A_1 these fix H (a monotone root) and every A_n,
n ≥ 3, and q0 = EI k_1⁴ (e_1 − A_1) + H k_1² A_1: the path q0(A_1), whose maximum and
minimum are the limit loads (:func:`shallow_arch_limits`; 41 modes, the coefficients fall as
n⁻³). For this arch the thrust stays below the antisymmetric mode's H_2 = 4 EI k_1²
(0.48 H_2 at both limits), so it snaps symmetrically through a limit point (rises
2 r < e < 4.69 r for a sine arch): det R_u changes sign only where dλ/ds does.

The rod differs from that theory by what the theory drops, each bounded by the arch's end
slope β/2 = 0.024: the geometry's cosines, 1 − cos φ ≤ (β/2)²/2 = 2.9e-4 relative; the
load's and the thrust's components along the rod's tangent, relative φ q0 L/H ≤ 0.024 × 33/720
= 1.1e-3; shear, EI k_1²/κGA = 1.2e-4: 1.5e-3 in all, asserted. Measured (16 P3): −2.8e-4 at
the maximum (λ = 1.08250e-3 against 1.08280e-3, q0 = 32.475 N/m), −4.8e-4 at the minimum
(4.61681e-4 against 4.61905e-4). The discretisation error is far below: 8 P3 differs from
32 P3 by 4e-5 at the maximum, 3e-6 at the minimum.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import ROOT
from scipy.integrate import quad
from scipy.optimize import brentq, minimize_scalar

import cosserat_fem as cf

LEE = ROOT / "scenes" / "lee_frame.toml"
#: The converged limit loads of Lee's frame (module docstring: 80 P3 and 40 P4).
P1, P2 = 1.8544528, -0.9392493
#: The reference load: λ = P/10.
P_REF = 10.0


def lee_path(elements: int, degree: int = 3, braced: bool = False):
    """The primary path of Lee's frame, λ growing, from P = 0 until the load point has come
    down by 95 (past both limit points), the load point probed; ``braced``: out-of-plane
    bending and torsion stiffnesses × 100."""
    overrides = {
        "parameters.P": P_REF,
        "discretisation.elements": elements,
        "discretisation.degree": degree,
    }
    if braced:
        overrides |= {"rod.section.c11": 450.0, "rod.section.c33": 470.0}
    result = cf.continuation(
        cf.load(LEE, overrides),
        -1.0,
        1.0,
        step=0.05,
        max_step=0.05,
        max_points=400,
        switch=0,
        directions=(1,),
        probe=144.0,
        stop=lambda q: "down by 95" if -q.tip[2] > 95.0 else None,
    )
    (branch,) = result.branches
    return branch


def turns(values) -> int:
    """How many times a sequence turns back (sign changes of its differences)."""
    d = np.diff(np.asarray(values))
    d = d[d != 0.0]
    return int(np.sum(np.sign(d[1:]) != np.sign(d[:-1])))


def limit_loads(branch) -> tuple[float, float]:
    limits = [q for q in branch.special if q.kind == "limit"]
    assert len(limits) == 2
    return limits[0].factor * P_REF, limits[1].factor * P_REF


def test_lee_frame_snap_through_and_back():
    """20 P3 elements, the frame as given (module docstring): the branch ends by the stop
    (not a step collapse); the special points are the lateral bifurcation, then two limit
    points, the maximum P₁ > 0 and the minimum P₂ < 0, where dλ/ds changes sign; the load
    turns back twice and so does the deflection w (snap-through and snap-back); each located
    limit is beyond the traced points' local extremum of the load next to it. P₁, P₂ are the
    converged values to 20 P3's discretisation error, measured 3.2e-4 and 1.7e-3 relative
    (from the refinement): 1e-3 and 3e-3 asserted.
    The bifurcation, P = 1.69299, lies before P₁ and at a smaller deflection."""
    branch = lee_path(20)
    assert branch.reason == "down by 95"
    assert [q.kind for q in branch.special] == ["bifurcation", "limit", "limit"]
    loads = [q.factor * P_REF for q in branch.points]
    deflection = [-q.tip[2] for q in branch.points]
    assert turns(loads) == 2 and turns(deflection) == 2
    p1, p2 = limit_loads(branch)
    top = int(np.argmax(np.diff(loads) < 0))  # the first point after which the load falls
    bottom = top + int(np.argmax(np.diff(loads[top:]) > 0))  # then rises again
    assert p1 >= loads[top] - 1e-9 and p2 <= loads[bottom] + 1e-9
    assert abs(p1 / P1 - 1) < 1e-3 and abs(p2 / P2 - 1) < 3e-3
    one, two = (q for q in branch.special if q.kind == "limit")
    assert one.dfactor == pytest.approx(0.0, abs=1e-6) and two.dfactor == pytest.approx(0, abs=1e-6)
    lateral = branch.special[0].factor * P_REF
    assert 1.6 < lateral < p1 and -branch.special[0].tip[2] < -one.tip[2]


@pytest.mark.long
def test_lee_frame_limit_loads_converge():
    """Refinement (module docstring): 80 P3 and 40 P4 give P₁ and P₂ within 1e-6 relative of
    each other and of the converged values (measured 9e-8 and 5e-7 apart); the braced frame (c11,
    c33 × 100) has no bifurcation and the same limit loads to 1e-9 (the in-plane equations do
    not see c11, c33; θ = φ = 0 on the path, so only round-off and the corrector's 1e-10 in
    the update differ)."""
    fine, p4 = lee_path(80), lee_path(40, degree=4)
    for branch in (fine, p4):
        p1, p2 = limit_loads(branch)
        assert abs(p1 / P1 - 1) < 1e-6 and abs(p2 / P2 - 1) < 1e-6
    braced, free = lee_path(20, braced=True), lee_path(20)
    assert [q.kind for q in braced.special] == ["limit", "limit"]
    assert np.allclose(limit_loads(braced), limit_loads(free), rtol=0, atol=1e-9)


ARCH = ROOT / "scenes" / "shallow_arch.toml"


def shallow_arch_limits(R, beta, EI, EA, modes=41) -> tuple[float, float]:
    """The limit loads (q0 at the maximum and the minimum of the symmetric path) of the
    shallow-arch theory for the circular arch of radius R [m] and opening β [rad] under
    q0 sin(πz/L) (module docstring), from its first ``modes`` sine modes."""
    L = 2 * R * math.sin(beta / 2)

    def rest(z: float) -> float:
        return math.sqrt(R * R - (z - L / 2) ** 2) - R * math.cos(beta / 2)

    n = np.arange(1, modes + 1)
    e = np.array(
        [2 / L * quad(lambda z, m=m: rest(z) * math.sin(m * math.pi * z / L), 0, L)[0] for m in n]
    )
    k = np.pi * n / L
    Hn = EI * k**2

    def load(A1: float) -> float:
        def extension(H: float) -> float:
            A = e / (1 - H / Hn)
            A[0] = A1
            return H / EA - float(np.sum(k**2 * (e**2 - A**2))) / 4

        H = brentq(extension, -50 * Hn[0], Hn[2] * (1 - 1e-9), xtol=1e-16, rtol=1e-15)
        return EI * k[0] ** 4 * (e[0] - A1) + H * k[0] ** 2 * A1

    options = {"xatol": 1e-14}
    top = minimize_scalar(lambda a: -load(a), bounds=(0, e[0]), options=options)
    bottom = minimize_scalar(load, bounds=(-e[0], 0), options=options)
    return -top.fun, bottom.fun


def arch_path(elements: int):
    scene = cf.load(ARCH, {"discretisation.elements": elements, "parameters.Q": 30000.0})
    result = cf.continuation(
        scene,
        -0.01,
        0.01,
        step=5e-4,
        max_step=5e-4,
        switch=0,
        directions=(1,),
        stop=lambda q: "through" if q.tip[0] < -0.012 else None,
    )
    (branch,) = result.branches
    return scene, branch


def test_shallow_arch_snaps_through():
    """8 P3 elements (module docstring): the crown (the probe at mid-span) goes down by 12 mm,
    2 e, through two limit points and nothing else (no bifurcation: the snap is symmetric);
    the limit loads are the shallow-arch theory's to 1.5e-3 (its neglected terms; measured
    2.8e-4 and 4.8e-4); the load turns back twice, the crown's deflection never (a
    snap-through, no snap-back)."""
    scene, branch = arch_path(8)
    assert branch.reason == "through"
    assert [q.kind for q in branch.special] == ["limit", "limit"]
    rod = scene.rod_constants()
    EI, EA = rod.young_modulus * rod.section.c22, rod.young_modulus * rod.section.area
    p = scene.parameters
    top, bottom = shallow_arch_limits(p["R"], p["beta"], EI, EA)
    Q = p["Q"]
    one, two = (q.factor * Q for q in branch.special)
    assert abs(one / top - 1) < 1.5e-3 and abs(two / bottom - 1) < 1.5e-3
    assert turns([q.factor for q in branch.points]) == 2
    assert turns([q.tip[0] for q in branch.points]) == 0
