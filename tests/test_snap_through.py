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
(5.8e-4) is pre-asymptotic, 80 P3 and 40 P4 agree to 1.7e-8 relative. P₂: −0.940874 (20 P3),
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
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import ROOT

import cosserat_fem as cf

LEE = ROOT / "scenes" / "lee_frame.toml"
#: The converged limit loads of Lee's frame (module docstring: 80 P3 and 40 P4).
P1, P2 = 1.854453, -0.939249
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
    each other and of the converged values (measured 1.7e-8 and 5e-7); the braced frame (c11,
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
