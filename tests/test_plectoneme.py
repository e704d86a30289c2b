"""A clamped rod twisted past Greenhill's buckling twist towards a plectoneme, without contact
(issue 30; benchmarks/plectoneme_path.py, docs/plectoneme.md).

The rod of tests/test_greenhill.py (L = 1 m, circle d = 2 mm, E = 1e9 Pa, ν = 0.3), clamped
at A and held at B by a sliding support turned about e3 by the twist Φ, under a dead tension
T = 100 EI/L² along e3 at B, and a lateral gravity g_x (ρ A g_x e1 [N/m]) as the imperfection
that pins the buckled shape's orientation (a round rod's buckled states are a circle of
them). The path is continued in Φ by the arclength engine (cosserat_fem/nls/arclength.py)
on the static residual with the turn as its parameter (benchmarks/plectoneme_path.py,
``TwistPath``): with g_x = 1 m/s² from Φ = 0 over the fold to a B shortened by 5 cm, then
with g_x = 1e-2 m/s² on, Φ decreasing, to the first self-contact of the tube (radius r).

**The buckling twist.** The straight rod under T buckles at M_c, the first root of the
clamped-clamped determinant of EI w⁗ − i M w‴ − T w″ = 0 (``buckling_torque``): M_c L/EI =
20.9835 (1.0492 times the infinite rod's 2 √(EI T)), Φ_c = M_c L/GJ = 27.27855 rad; as T → 0
it tends to Greenhill's 2 x1 = 8.98682 of tests/test_greenhill.py. The bifurcation is
subcritical (unstable-symmetric): the imperfect path turns back at a fold Φ_max < Φ_c, and
Koiter's law for that kind, Φ_c − Φ_max = C ε^(2/3) + O(ε^(4/3)), relates the folds of two
imperfections ε (J. W. Hutchinson & W. T. Koiter, Postbuckling theory, Appl. Mech. Rev. 23
(1970) 1353; the 2/3 power from the cubic normal form λ = λ_c − a w² − ε b/w at its maximum).

**The contact onset.** Past the fold the torque falls with Φ while the loop grows and B comes
in (the descending, unstable branch: under twist control the rod would snap here); the two
strands that cross at the loop's neck come within 2r at Φ_onset = 6.4816 rad (M = 0.14 mN m,
0.86 % of M_c; B 40 cm in). The node-to-cell gap there is still +2.4 r on 32 cells: the strands
meet between the nodes (docs/plectoneme.md). The gap is the least distance of the cells'
curves (contact_search's closest points from 8k + 1 points of each cell, refined), located
as the engine's test function to 1e-9 in arclength.
"""

from __future__ import annotations

import functools
import math
import subprocess
import sys
import time

import numpy as np
import pytest
from conftest import PYTHON, ROOT, stop_tree, subprocess_env

sys.path.insert(0, str(ROOT / "benchmarks"))
from plectoneme_path import (  # noqa: E402
    DIAMETER,
    EI,
    LENGTH,
    NU,
    TENSION,
    buckling_torque,
    greenhill_twist,
    trace,
)

GJ = EI / (1 + NU)  # a circle: J = 2 I, G = E/(2 (1 + ν)) [N m²]


@functools.cache
def path(cells: int, first: float = 1.0, second: float | None = 1e-2):
    """The traced path (``trace``) on ``cells`` P3 cells, imperfections ``first`` and
    ``second`` [m/s²]; ``second`` None: the first stage alone."""
    return trace(cells, imperfections=(first, second or 0.0), second_stage=second is not None)


def test_the_buckling_torque_with_tension():
    """``buckling_torque``: as T → 0 the root tends to Greenhill's M_c L/EI = 2 x1 (at
    T = 1e-6 EI/L² it differs by 1.5e-7, the tension's first-order term, within 1e-6); at
    T = 100 EI/L² it is 20.98350 EI/L (a root of the determinant, Brent to 1e-14: held to
    1e-9); and it tends to the infinite rod's 2 √(EI T) from above as T L²/EI grows (the
    clamps' excess M_c/(2 √(EI T)) − 1 falls: 4.9e-2 at 100, below 1e-2 at 1e4)."""
    x2 = greenhill_twist() / (1 + NU)
    assert abs(buckling_torque(1e-6 * EI) * LENGTH / EI - x2) < 1e-6
    assert buckling_torque(TENSION) * LENGTH / EI == pytest.approx(20.98350083, abs=1e-7)
    excess = [
        buckling_torque(t * EI / LENGTH**2) / (2 * math.sqrt(EI * t * EI / LENGTH**2)) - 1
        for t in (100.0, 1e4)
    ]
    assert 0 < excess[1] < 1e-2 < excess[0] < 5e-2


@pytest.mark.long
def test_the_path_turns_back_below_the_buckling_twist_as_koiter_says():
    """The imperfect path (32 P3 cells; stage one alone, 30-50 s): (1) on its straight part,
    Φ ≤ Φ_c/2, the end torque grows as GJ/L (the secant from Φ_c/4 to Φ_c/2 within 1e-4:
    the imperfection's lateral sag, w/L = 3e-3, changes it at second order, (w/L)² ~ 1e-5;
    measured −6.6e-6);
    (2) it turns back at a fold Φ_max below Φ_c for both imperfections ε = 1 and 1/4 m/s²
    (subcritical: a stable, supercritical branch would have no fold), B shortening past it;
    (3) the deficits scale as ε^(2/3): their ratio 4^(2/3) = 2.520 within 0.03 (measured
    2.527; the O(ε^(4/3)) term and the FE's error in Φ_c, 1.5e-5 of it, below that); (4) the
    buckling twist extrapolated from the two folds by that law, (4^(2/3) Φ_max(1/4) −
    Φ_max(1))/(4^(2/3) − 1), is the linear analysis' Φ_c within 1e-4 of it (measured
    −1.9e-5; on 16 cells +2.6e-4, the P3 error falling as h⁴)."""
    phi_c = buckling_torque(TENSION) * LENGTH / GJ
    big, small = path(32, 1.0, None), path(32, 0.25, None)
    straight = [p for p in big.points if phi_c / 4 <= p.phi <= phi_c / 2 and p.shift > -1e-3]
    a, b = straight[0], straight[-1]
    slope = (b.torque - a.torque) / (b.phi - a.phi)
    assert abs(slope / (GJ / LENGTH) - 1) < 1e-4, slope
    for traced in (big, small):
        assert traced.fold < phi_c
        assert traced.points[-1].phi < traced.fold and traced.points[-1].shift < -0.05 * LENGTH
    ratio = (phi_c - big.fold) / (phi_c - small.fold)
    assert abs(ratio - 4 ** (2 / 3)) < 0.03, ratio
    a = 4 ** (2 / 3)
    extrapolated = (a * small.fold - big.fold) / (a - 1)
    assert abs(extrapolated / phi_c - 1) < 1e-4, extrapolated


@pytest.mark.long
def test_the_contact_onset_twist_converges_under_refinement():
    """The contact onset Φ_onset on 16, 32 and 64 P3 cells (2 min): 6.483009, 6.481680,
    6.481631 rad (measured); the differences fall from 1.3e-3 to 4.9e-5 rad, by 27 (P3
    positions converge as h⁴, 16: asserted > 8); the finest two within 2e-4 rad. Along the
    way: the torque at the onset is a small part of M_c (the loop nearly planar, the strands
    crossing at its neck: measured 0.14 mN m = 0.86 % of M_c, asserted < 5 %), past the fold
    (Φ_onset < Φ_max), and the node-to-cell gap there still positive on 16 and 32 cells (the
    strands meet between the nodes: +2.4 r on 32 cells)."""
    onsets = []
    for cells in (16, 32, 64):
        traced = path(cells)
        assert traced.onset is not None, traced.reasons
        at = traced.onset_point
        assert at is not None and abs(at.gap) < 1e-6 * at.radius
        assert 0 < at.torque < 0.05 * buckling_torque(TENSION)
        assert at.phi < traced.fold
        if cells < 64:
            assert at.node_gap > 0
        onsets.append(traced.onset)
    first, second = abs(onsets[0] - onsets[1]), abs(onsets[1] - onsets[2])
    assert first / second > 8, onsets
    assert second < 2e-4, onsets
    assert DIAMETER == 0.002  # the figures above are this rod's


def _sliding(contact: dict) -> dict:
    """The twisted rod of tests/test_greenhill.py on 8 P3 cells, B sliding along e3, with the
    [contact] table ``contact``."""
    return {
        "rod": {
            "section": {"shape": "circle", "diameter": 0.02},
            "material": {"density": 1000.0, "young_modulus": 1e9, "poisson_ratio": NU},
        },
        "structure": {
            "nodes": [{"name": "A", "position": [0, 0, 0]}, {"name": "B", "position": [0, 0, 1]}],
            "members": [{"name": "AB", "from": "A", "to": "B", "elements": 8}],
            "supports": [
                {"node": "A", "kind": "clamped"},
                {"node": "B", "kind": "sliding", "rotation": "t", "rotation_axis": [0, 0, 1]},
            ],
        },
        "time": {"end": 1.0, "step": 0.1, "integrator": "bdf2"},
        "discretisation": {"degree": 3},
        "contact": contact,
    }


def test_a_sliding_end_takes_self_contact_and_its_cells_are_pressed_on():
    """A `sliding` support with self contact alone is taken, with an obstacle still refused by
    name. B's node holds x and y but not z, the clamp A all three; B's last cell is its held
    cell and its nodes are no slaves (rod/self_contact.py). A mid-span node bent over beside
    that cell, 0.5 r into it, is the slave of a pair on it (against the rule "the later node
    is the slave", which B's nodes would win), and none of B's cell's nodes is a slave. Two
    held cells (A's first, were A sliding too) brought into contact are refused in one line
    with the place (PartlyHeld): neither side has a slave; apart (at rest, or 0.01 r apart)
    they pass; at a scene's start the refusal is a SceneError."""
    from mpi4py import MPI

    from cosserat_fem.common.errors import SceneError
    from cosserat_fem.nls.pair_contact import PartlyHeld
    from cosserat_fem.rod.model import build_model
    from cosserat_fem.rod.obstacles import _check_self_start, contact_rows
    from cosserat_fem.rod.self_contact import SelfContactGeometry
    from cosserat_fem.scene.build import scene_from_dict

    plane = {"kind": "plane", "point": [-1.0, 0, 0], "normal": [1.0, 0, 0]}
    with pytest.raises(SceneError, match=r"^structure\.supports\[1\]\.kind: a sliding node"):
        scene_from_dict(_sliding({"self_contact": True, "obstacles": [plane]}))
    model = build_model(scene_from_dict(_sliding({"self_contact": True})), MPI.COMM_SELF)
    pairs = contact_rows(model).pairs
    geometry, places, r = pairs.geometry, pairs.places_all, 0.01
    b, a = int(np.argmax(places)), int(np.argmin(places))
    assert pairs.held_slots_all[b].tolist() == [True, True, False]
    assert pairs.held_slots_all[a].all() and pairs.held_all.sum() == 2
    (cell,) = geometry.dofs[geometry.held_cells]
    assert b in cell and set(np.flatnonzero(geometry.never_slaves)) == set(cell.tolist())
    x = pairs.everywhere(model.U.x.array)
    middle = int(np.argmin(np.abs(places - 0.5)))
    x[middle] = [1.5 * r, 0.0, x[cell, 2].mean()]
    found = geometry(x)
    (k,) = np.flatnonzero(found.slave == middle)
    assert b in found.partner[k] and abs(found.gap[k] + 0.5 * r) < 1e-9 * r  # a straight cell
    assert not geometry.never_slaves[found.slave].any()
    partly = np.zeros(len(places), dtype=bool)
    partly[[a, b]] = True
    both = SelfContactGeometry(geometry.dofs, places, r, 2 * r, partly=partly)
    (first,) = both.dofs[both.held_cells & np.isin(both.dofs, a).any(axis=1)]
    x = pairs.everywhere(model.U.x.array)
    both(x)  # at rest: no pair between the two held cells, nothing refused
    x[first, 0] += 2.01 * r  # beside B's cell, 0.01 r apart: not touching
    x[first, 2] += x[cell, 2].mean() - x[first, 2].mean()
    both(x)
    x[first, 0] -= 0.51 * r  # 0.5 r into it
    with pytest.raises(PartlyHeld, match=r"^contact: the cells of two supports .* touch at") as e:
        both(x)
    assert "\n" not in str(e.value)

    class Start:  # at a scene's start the same is the scene's fault: a SceneError
        ell, geometry = 1.0, both

        def everywhere(self, u):
            return x

    with pytest.raises(SceneError, match=r"^contact\.self_contact: at the start, the cells of"):
        _check_self_start(Start(), model.U.x.array)


#: where the runs in time end [s]: Φ = 33 rad, past the strands' meeting (32.34 rad); the
#: scene's 45 s would now run on past B's touching (no longer a stop: a sliding support's
#: cells are pressed on) into the slow steps after the contact
IN_TIME_END = 33.0


@functools.cache
def in_time(cells: int):
    """scenes/plectoneme.toml on ``cells`` P3 cells (benchmarks/plectoneme_run.py ``run``) to
    t = IN_TIME_END: its rows, wall time and closed forms."""
    from plectoneme_run import run

    return run(cells, (f"time.end={IN_TIME_END}",))


@pytest.mark.long
def test_the_twisted_rod_in_time_snaps_until_its_strands_meet_without_passing_through():
    """scenes/plectoneme.toml (r = L/100, T = 100 EI/L², twist control at 1 rad/s, a drag,
    no damping in torsion) on 64 and 96 P3 cells (~2 min since the chains of contacts: the
    96 cells' run goes on to Φ = 33.0 rad, 103 s), docs/plectoneme.md "With self contact":

    (1) straight, Φ in [Φ_c/4, Φ_c/2]: the torque at the clamp grows as GJ/L (the secant
    within 1e-4: the gravity's sag changes it at (w/L)² ~ 1e-5; measured −4e-6; the drag is
    translational and torsion undamped, so no viscous torque) and B has moved out by the
    stretch T L/EA within 2 % (the sag's shortening, (π w/L)² L/4 ~ 1.3e-5 m, is 0.5 % of
    it; measured 6.6e-3 on both meshes);
    (2) past the fold the rod snaps: B comes in by more than 0.2 m before the strands meet
    (0.282 m on 64 cells at Φ = 32.3427 rad: the loop of the descending branch,
    docs/plectoneme.md);
    (3) the path up to the contact is converged in space: the torque's maximum (~1.11 M_c
    at this rate, the snap's delay) on 64 and 96 cells within 1e-4 relative (measured
    1.3e-6) and the twist where the strands first meet, bracketed on 96 cells by its last
    accepted and its failing step (32.3423, 32.3481 rad), within 1e-2 rad of the 64 cells'
    (the adaptive steps' tolerance 1e-3 sets the steps there, of 1e-3 rad);
    (4) no interpenetration at any accepted state: the pairs' node gaps ≥ −1e-9 r (the rows
    hold them to the Newton tolerance) and the least gap between the nodes ≥ −1e-2 r (the
    guard's bound, which rejects deeper states; measured −1.0e-2 r on 64 cells, its last
    state before the guard stops it, and −9.5e-3 r on 96);
    (5) a run that stops does so in one line naming the place s (64 cells: the guard at
    Φ = 32.630 rad; 96 cells: it reaches IN_TIME_END, where B's sliding node touched
    the ply before B's cells were pressed on)."""
    rows, _, forms = in_time(64)
    r, GJ, phi_c = 0.5 * forms["diameter"], forms["GJ"], forms["phi_c"]
    t, phi, M, dz, w, pairs, node_gap, between = rows.T
    straight = (phi >= phi_c / 4) & (phi <= phi_c / 2)
    slope = np.polyfit(phi[straight], M[straight], 1)[0]
    assert abs(slope / GJ - 1) < 1e-4, slope / GJ - 1
    EA = 4e6 * math.pi * r**2
    assert abs(dz[straight] / (forms["T"] / EA) - 1).max() < 2e-2
    touching = np.flatnonzero(pairs > 0)
    assert touching.size, forms.get("failure")
    onset = phi[touching[0]]
    assert dz[touching[0]] < -0.2
    assert node_gap[touching].min() >= -1e-9 * r
    assert between.min() >= -1e-2 * r
    fine, _, finer = in_time(96)
    assert abs(fine[:, 2].max() / M.max() - 1) < 1e-4
    if (fine[:, 5] > 0).any():
        low = high = fine[np.argmax(fine[:, 5] > 0), 1]
    else:
        low, high = fine[-1, 1], finer["failed_at"] * float(finer["rate"])
    assert low - 1e-2 <= onset <= high + 1e-2, (onset, low, high)
    for failure in (forms.get("failure"), finer.get("failure")):
        assert failure is None or ("\n" not in failure and "s = " in failure)


def test_the_plateau_scene_twists_its_straight_rod_as_gj_over_l(tmp_path):
    """scenes/plectoneme_plateau.toml (r = L/200, T = 300 EI/L², the twist 2 rad/s up to t1,
    a point imperfection at mid-span; docs/plectoneme.md "Towards the plateau") on 16 P3
    cells for its first 2 s (~1 s of wall): the torque at the clamp against the twist
    Φ(t) of benchmarks/plectoneme_plateau.py ``twist`` grows as GJ/L, the secant over Φ in
    [1, 4] rad within 1e-4 (the straight rod: M = GJ Φ/L; the imperfection's lateral sag,
    w/L ~ 5e-3, changes it at (w/L)² ~ 3e-5; measured −2.4e-5), so the benchmark's Φ(t) is
    the scene's turn of B (a wrong rate or t1 would move it by its own relative error); and
    the torque's plateau over a window the run did not reach is nan (``plateau``). The
    benchmark's ``--out``/``--restart``: a run to 1 s kept in a folder and continued from its
    checkpoint to 2 s ends with the uninterrupted run's torque at 2 s within 1e-4 (both the
    straight rod's GJ Φ/L to 3e-5; the steps differ, the first run's last one cut at 1 s),
    and its rows are the first run's (kept in its checkpoint, whatever the folder's rows.npy
    holds: here a file cut short, as a run killed between two writes leaves it) and then its
    own, in time."""
    from plectoneme_plateau import plateau, run

    rows, _, forms = run(16, end=2.0)
    first, _, _ = run(16, end=1.0, out=tmp_path)
    assert np.array_equal(np.load(tmp_path / "rows.npy"), first)
    np.save(tmp_path / "rows.npy", first[:3])
    later, _, _ = run(0, end=2.0, restart=tmp_path)
    assert np.array_equal(later[: len(first)], first)
    assert np.all(np.diff(later[:, 0]) > 0)
    assert first[-1, 0] == 1.0 < later[len(first), 0] < later[-1, 0] == rows[-1, 0] == 2.0
    assert np.array_equal(np.load(tmp_path / "rows.npy"), later)
    assert abs(later[-1, 2] / rows[-1, 2] - 1) < 1e-4, later[-1, 2] / rows[-1, 2] - 1
    phi, M = rows[:, 1], rows[:, 2]
    straight = (phi >= 1.0) & (phi <= 4.0)
    slope = np.polyfit(phi[straight], M[straight], 1)[0]
    assert abs(slope / forms["GJ"] - 1) < 1e-4, slope / forms["GJ"] - 1
    assert forms["phi_c"] == pytest.approx(45.78112494284397, rel=1e-9)
    assert math.isnan(plateau(rows, forms, (3.0, 5.0))["mean"])


def test_the_contact_plys_torque_meets_the_strands_equilibrium():
    """benchmarks/plectoneme_plateau.py ``contact_ply``, the minimum (Y.1) of the energy
    balance, against the ply's equilibrium by the Kirchhoff equations of a helical strand
    with a frictionless line contact and no resultant across the ply (docs/plectoneme.md,
    "The contact ply's torque"): M_p r/EI = 2 sin³θ cos θ / cos 2θ and T r²/EI =
    sin⁴θ (1 + 2 cos²θ) / (2 cos 2θ), within 1e-6 (at a flat minimum a minimiser finds θ to
    ~√ε θ ~ 1e-8 rad only, which moves these by ~3 δθ/θ ~ 1e-7; measured ≤ 1.5e-8): being
    (Y.1)'s stationarity, they hold the implementation and the minimiser, not the physics
    (docs/plectoneme.md derives both);
    for r → 0 its leading order M_p = (4/3) (3/2)^¼ √(EI T) √ρ, ρ = r √(T/EI) (within 1e-3
    at ρ = 1e-4: the next order is the sines' θ² ~ 0.8 ρ; measured 4.1e-5); and the plateau
    scene's figures the docs quote, θ_p = 15.04°, M_p = 0.318 √(2 EI T)."""
    from plectoneme_plateau import contact_ply

    EI, T = 7.853981633974483e-3, 2.356194490192345
    for r in (1e-3, 5e-3, 2e-2):
        theta, M = contact_ply(r, T, EI)
        s, c, c2 = math.sin(theta), math.cos(theta), math.cos(2 * theta)
        assert M * r / EI == pytest.approx(2 * s**3 * c / c2, rel=1e-6)
        assert T * r**2 / EI == pytest.approx(s**4 * (1 + 2 * c**2) / (2 * c2), rel=1e-6)
    rho = 1e-4
    _, M = contact_ply(rho * math.sqrt(EI / T), T, EI)
    leading = 4 / 3 * 1.5**0.25 * math.sqrt(EI * T * rho)
    assert abs(M / leading - 1) < 1e-3, M / leading - 1
    theta, M = contact_ply(5e-3, T, EI)
    assert math.degrees(theta) == pytest.approx(15.04, abs=5e-3)
    assert M / math.sqrt(2 * EI * T) == pytest.approx(0.318, abs=5e-4)


#: the plateau runs' end [s] (Φ = 60 rad) and the window of twist [rad] of the plateau
#: (benchmarks/plectoneme_plateau.py; t = 59 to 65 s)
PLATEAU_END, PLATEAU_WINDOW = 66.0, (56.5, 59.5)
#: how long [s] the two plateau runs may take before the test calls them hung (measured
#: 14:51 for the two at once on this machine's 2 cores)
PLATEAU_HUNG = 3600.0


@pytest.mark.long
def test_the_torque_plateau_after_the_snap_converges_under_refinement(tmp_path):
    """scenes/plectoneme_plateau.toml (r = L/200, T = 300 EI/L², twisted at 0.5 rad/s after
    t1; docs/plectoneme.md, "The plateau in the long set") on 240 and 300 P3 cells to
    t = 66 s (Φ = 60 rad), each run serially, the two at once (~15 min on 2 cores): the
    rod snaps past Φ_c, its strands meet and wind into a ply that takes most of the rod, and
    the clamp's torque levels off. Over Φ in [56.5, 59.5] rad:

    * **the two meshes agree** within the error of what both hold approximately: the
      contact is held at the nodes and the parts may pass through each other between them
      by g_b (each run's least gap between the nodes over the window, ≥ −1e-2 r by the
      sampled check), which brings the strands' axes g_b closer, the ply's helix radius (half
      their distance) by g_b/2, and so M_p by ∂M_p/∂r g_b/2, ∂M_p/∂r = (2T − EI
      sin⁴θ_p/r²)/sin 2θ_p = 0.537 M_p/r (the envelope theorem on (Y.1), θ_p interior); and
      the time steps' error, allowed time.rtol M_p (3e-3 M_p: a local tolerance, not a
      bound on the global error, 13 times the error measured against a run at rtol 3e-4 and
      steps ≤ 0.01 s, 2.3e-4 M_p: docs/decisions.md, "Landings in an overdamped ply"):
      |M̄_300 − M̄_240| ≤ (0.537 (|g_b,240| + |g_b,300|)/(2r) + rtol) M_p (measured: 1.05447
      and 1.05415 M_p, 3.2e-4 M_p apart against a bound of 3.5e-3 M_p, g_b = −1.3e-3 and
      −4.5e-4 r);
    * **the plateau is the contact ply's** (Y.1), M_p = 0.061221 N m, not the snap's
      √(2 EI T) = 3.14 M_p or a free loop's 0.9 √(2 EI T): within 10 % (the drag on what
      moves raises it by an estimated 3-5 % at this rate, the lateral point load lowers it
      by ~1 %: docs/plectoneme.md, "The contact ply's torque"; measured +5.4 %).

    Both runs reach the end (a contact that cannot be resolved would stop them). Measured
    (2026-12-06, this machine): 14:51 for the two, 1780 and 1832 steps."""
    from plectoneme_plateau import closed_form, plateau

    from cosserat_fem import api

    logs = {cells: tmp_path / f"{cells}.log" for cells in (240, 300)}
    procs = {}
    try:
        for cells, log in logs.items():
            with open(log, "w") as out:
                procs[cells] = subprocess.Popen(
                    [
                        PYTHON,
                        str(ROOT / "benchmarks/plectoneme_plateau.py"),
                        str(cells),
                        "--end",
                        str(PLATEAU_END),
                        "--out",
                        str(tmp_path),
                    ],
                    cwd=ROOT,
                    stdout=out,
                    stderr=subprocess.STDOUT,
                    env={**subprocess_env(), "OMP_NUM_THREADS": "1"},
                )
        start = time.monotonic()
        for cells, proc in procs.items():
            try:
                proc.wait(timeout=max(1.0, PLATEAU_HUNG - (time.monotonic() - start)))
            except subprocess.TimeoutExpired:
                pytest.fail(
                    f"the {cells}-cell plateau run hung (> {PLATEAU_HUNG:.0f} s): "
                    + logs[cells].read_text()[-2000:]
                )
    finally:
        for proc in procs.values():
            if proc.poll() is None:
                stop_tree(proc)
    scene = api.load(ROOT / "scenes/plectoneme_plateau.toml")
    forms = closed_form(scene)
    r, M_p, theta = forms["r"], forms["M_p"], forms["theta_p"]
    dM_dr = (2 * forms["T"] - forms["EI"] * math.sin(theta) ** 4 / r**2) / math.sin(2 * theta)
    assert dM_dr * r / M_p == pytest.approx(0.537, abs=1e-3)
    found = {}
    for cells, log in logs.items():
        text = log.read_text()[-2000:]
        assert procs[cells].returncode == 0, text
        rows = np.load(tmp_path / str(cells) / "rows.npy")
        assert rows[-1, 0] == pytest.approx(PLATEAU_END, abs=1e-9), text
        found[cells] = plateau(rows, forms, PLATEAU_WINDOW)
    means = {cells: found[cells]["mean"] / M_p for cells in found}
    between = sum(abs(found[cells]["between/r"]) for cells in found)
    bound = dM_dr * r / M_p * between / 2 + scene.time.rtol
    assert abs(means[300] - means[240]) <= bound, (means, bound)
    for cells in found:
        assert abs(means[cells] - 1) <= 0.1, means
