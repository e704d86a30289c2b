"""Greenhill's twisted shaft: the critical combination of axial force and torque
(issue 27 item 1), with the semitangential end torque of forms/semitangential.py.

**The shaft.** A round cantilever (clamped at s = 0, free at s = ℓ) under a dead compressive
end force P along −e3 and an end torque T about e3 that is semitangential (Ziegler): when the
end turns by a small rotation θ the torque turns by θ/2, M = T (e3 + ½ θ × e3). Linearised
about the straight, twisted state (axial force −P, twisting moment T along d3), with β the
lateral tilt of d3 (a complex number βx + i βy), w the lateral displacement and z the axis:

* the moment of the part [z, ℓ] about the section, m_lat = T β + EI e3 × β' (twisting moment
  along the tilted d3, bending), equals the end torque's lateral part ½ T β(ℓ) plus the moment
  of the dead force P (w(ℓ) − w(z)) × e3;
* the lateral slope w' = (1 − P/EA) β + P β/(κGA) = c β (extension and shear, as for the Euler
  column of tests/test_stability.py).

Differentiating the first and eliminating w: EI β'' − i T β' + P c β = 0, so β = A (e^{i k1 z}
− e^{i k2 z}) (β(0) = 0) with EI k² − T k − P c = 0, k1 − k2 = D/EI, D = √(T² + 4 EI P c).
The free end's condition i EI β'(ℓ) + ½ T β(ℓ) = 0 gives e1 (½T − EI k1) = e2 (½T − EI k2),
with ½T − EI k1,2 = ∓ D/2: e^{i (k1 − k2) ℓ} = −1, the first root (k1 − k2) ℓ = π:

    (T / T_c)² + P c / P_E = 1,   T_c = π EI/ℓ,  P_E = π² EI/(4ℓ²),  c = 1 + P/(κGA) − P/(EA),

Greenhill's formula for the effective length 2ℓ (his pinned shaft: (T/(2π EI/ℓ))² + P/(π²
EI/ℓ²) = 1; A. G. Greenhill, Proc. Inst. Mech. Eng. (1883) 182; Timoshenko & Gere, Theory of
Elastic Stability (1961), on shafts under compression and torsion; the kind of torque
after H. Ziegler, Principles of Structural Stability (1968), read here through the derivation
above, not against the book). Shear and extension enter with P only; the torque's term is
unchanged. With a dead torque (M = T e3) the end's condition is i EI β' + T β = 0 and the same
steps give e^{i (k1 − k2) ℓ} = (T + D)/(T − D), of modulus ≠ 1 for T ≠ 0: no adjacent
equilibrium at any torque (the static criterion finds nothing), the classical case where the
dead torque is not conservative. Its tangent has a circulatory part ½ T (θ_y δθ_x − θ_x δθ_y)
at the end (the dead torque minus the semitangential one), which splits the double eigenvalue
λ0 of the two equal bending planes into λ0 ± i c1 T to first order in T (the perturbation of a
semisimple double eigenvalue by an antisymmetric 2 × 2 block): a complex pair from the smallest
torque, Im λ linear in T.

**The pinned shaft.** Greenhill's own shaft, pinned at both ends, needs a support that holds
the twist at one end: pinned and roller ends hold φ by dropping the residual's row of the
moment along d3, so their reaction torque is along d3 (a tangential, non-conservative
torque), and that shaft is not conservative either (a complex pair again; see
docs/equilibrium-stability.md). The cantilever is the conservative Greenhill problem the
scene can pose today.

**And by `stability()`.** The critical factor is located here from the lowest real part of
the eigenvalues at two factors 1e-4 either side of the closed form (the secant through them,
whose error is (Δf)² λ''/λ' ≈ 1e-8 · O(1)), and by :func:`stability` (Brent on the lowest
real eigenvalue) for the pure torque within 1e-6. The two bending planes of a round shaft are
a double eigenvalue, and near λ = 0 its round-off imaginary part (1.3e-10 to 1.8e-10 at a
largest |λ| of 24, measured) is above 1e-8 |λ|: modal.eigenvalue_kind bounds round-off by
1e-10 of the largest |λ| too; with the relative bound alone Brent's function skipped the
pair and found 1.0055 (1.030 on a slender shaft) instead of 1.000.
"""

from __future__ import annotations

import math

import pytest
from conftest import ROOT
from mpi4py import MPI
from scipy.optimize import brentq

from cosserat_fem.analysis.equilibria import Equilibria, stability, stability_at
from cosserat_fem.common.errors import SceneError
from cosserat_fem.scene.build import load_scene, scene_from_dict
from cosserat_fem.scene.schema import UNSET

ROLLUP = ROOT / "scenes" / "rollup.toml"
#: A stocky round cantilever (ℓ/d = 5, ℓ/r = 20), 8 P4 elements: P c/P_E − 1 = 1.2e-2 at P_E.
SHAFT = {
    "loads.end": UNSET,
    "rod.section.shape": "circle",
    "rod.section.a": UNSET,
    "rod.section.b": UNSET,
    "rod.section.diameter": 0.1,
    "rod.section.shear_coefficient": "auto",
    "rod.length": 0.5,
    "discretisation.elements": 8,
    "discretisation.degree": 4,
    "static.load_steps": 4,  # a quarter of T_c a step: the twist reaches π (1 + ν) at T_c
}


def shaft_constants(scene) -> tuple[float, float, float, float, float]:
    """(EI, EA, κGA, GJ, ℓ) of the scene's round rod (N m², N, N, N m², m)."""
    rod = scene.rod_constants()
    s = rod.section
    EI = rod.young_modulus * s.c22
    GJ = rod.shear_modulus * s.c33
    return (
        EI,
        rod.young_modulus * s.area,
        s.shear_coefficient * rod.shear_modulus * s.area,
        GJ,
        rod.length,
    )


def loads(p: float, t: float, torque: str = "loads.semitangential.torque") -> tuple[dict, float]:
    """The scene's loads P = p P_E, T = t T_c, and the critical factor f* of (p, t): the root
    of (f t)² + f p (1 + a f p) = 1, a = P_E (1/κGA − 1/EA) (module docstring)."""
    EI, EA, kGA, _, ell = shaft_constants(load_scene(ROLLUP, SHAFT))
    P_E, T_c = math.pi**2 * EI / (4 * ell**2), math.pi * EI / ell
    over = {}
    if p:
        over["loads.end.force"] = [0, 0, -p * P_E]
    if t:
        over[torque] = [0, 0, t * T_c]
    quadratic = P_E * (1 / kGA - 1 / EA) * p**2 + t**2
    return over, (-p + math.sqrt(p**2 + 4 * quadratic)) / (2 * quadratic)


def located(scene, near: float, half_width: float = 1e-4) -> float:
    """The factor where the lowest real part of the eigenvalues crosses 0: the secant through
    near (1 ∓ half_width) (module docstring)."""
    equilibria = Equilibria(scene, count=4)
    try:
        fs = [near * (1 - half_width), near * (1 + half_width)]
        lams = [min(equilibria.at(f).eigenvalues.real) for f in fs]
    finally:
        equilibria.close()
    assert lams[0] > 0 > lams[1], lams  # it does cross 0 between them
    return fs[0] - lams[0] * (fs[1] - fs[0]) / (lams[1] - lams[0])


@pytest.mark.parametrize(
    ("p", "t"),
    [
        (0.0, 1.0),  # pure torque: T_c = π EI/ℓ, no shear correction
        (1.0, 1.0),  # mixed: f* = 0.61597, Euler–Bernoulli's (√5 − 1)/2 = 0.61803
        pytest.param(1.0, 0.0, marks=pytest.mark.long),  # pure force: Haringx's P (1 + a P)
        pytest.param(0.5, 1.0, marks=pytest.mark.long),  # mixed, torque dominant
    ],
)
def test_greenhill_cantilever_critical_combination(p, t):
    """The stocky shaft under P = p P_E and a semitangential T = t T_c loses stability at
    the factor f* of (f t)² + f p c(f p P_E) = 1 (module docstring) within 1e-7: measured
    −9.5e-9 (pure torque), −3.1e-9 (mixed), −1.1e-9 (pure force), −5.4e-9 (0.5, 1), the
    secant's (Δf)² term and the eigenvalue's h^8 error (8 and 16 elements agree to 5e-11)
    well below. Where P acts, the shear and extension correction moves f* by 9e-4 to
    1.2e-2, more than 5e3 times that: dropping it fails."""
    over, expected = loads(p, t)
    found = located(load_scene(ROLLUP, {**SHAFT, **over}), expected)
    assert abs(found - expected) < 1e-7, (found, expected)
    if p:
        euler_bernoulli = (-p + math.sqrt(p**2 + 4 * t**2)) / (2 * t**2) if t else 1 / p
        assert abs(euler_bernoulli - expected) > 5e-4


def test_a_semitangential_torque_twists_the_shaft_and_stays_axial():
    """Under T = 0.9 T_c alone the shaft stays straight (x, y, θ, ψ zero to round-off, 1e-12)
    and twists uniformly, φ(ℓ) = T ℓ/GJ within 1e-10 (a P4 field holds the linear φ exactly;
    the Newton tolerance is 1e-10 relative): the end's rotation, 3.73 rad, is past π, where
    the torque's first quaternion multiple vanishes and its second is taken
    (forms/semitangential.py)."""
    over, _ = loads(0.0, 0.9)
    scene = load_scene(ROLLUP, {**SHAFT, **over})
    _, _, _, GJ, ell = shaft_constants(scene)
    equilibria = Equilibria(scene, count=4)
    try:
        U = equilibria.state(1.0).reshape(-1, 12)
    finally:
        equilibria.close()
    twist = 0.9 * math.pi * shaft_constants(scene)[0] / ell * ell / GJ
    assert twist > math.pi
    assert abs(U[:, :5]).max() < 1e-12
    assert abs(U[:, 5].max() - twist) < 1e-10 * twist


@pytest.mark.long
def test_a_dead_torque_makes_a_complex_pair_from_the_smallest_torque():
    """A small torque (T = 0.01, 0.02 T_c) on the shaft: dead (loads.end.torque), the two
    bending planes form a complex pair whose imaginary part is linear in T (first-order
    perturbation of the double eigenvalue, module docstring: ratio 2 within 1e-3, the O(T²)
    remainder measured 2.2e-6 relative); semitangential, every λ real (|Im λ| < 1e-8 |λ|,
    the classifier's round-off bound) and the state stable."""
    imaginary = []
    for t in (0.01, 0.02):
        dead, _ = loads(0.0, t, "loads.end.torque")
        point = stability_at(load_scene(ROLLUP, {**SHAFT, **dead, "static.load_steps": 1}), 1.0, 4)
        assert point.status == "flutter"
        imaginary.append(max(abs(point.eigenvalues.imag)))
        semi, _ = loads(0.0, t)
        point = stability_at(load_scene(ROLLUP, {**SHAFT, **semi, "static.load_steps": 1}), 1.0, 4)
        assert point.stable
        assert all(abs(lam.imag) <= 1e-8 * abs(lam) for lam in point.eigenvalues)
    assert imaginary[0] > 1e-3
    assert abs(imaginary[1] / imaginary[0] - 2.0) < 1e-3


@pytest.mark.long
def test_stability_locates_greenhill():
    """:func:`stability` finds the pure torque's critical factor 1 within 1e-6."""
    over, _ = loads(0.0, 1.0)
    result = stability(load_scene(ROLLUP, {**SHAFT, **over}), 0.95, 1.15, 3, 1e-10, count=4)
    assert result.kind == "divergence" and abs(result.critical - 1.0) < 1e-6


def test_semitangential_scene_checks():
    """A clamped or sliding end refuses it, a pinned or roller end its torque about e3 (the
    message names the key); its plane is that of a fixed torque; to_dict reads back."""
    with pytest.raises(SceneError, match=r"^loads\.semitangential\.end: a semitangential"):
        load_scene(
            ROLLUP, {"loads.semitangential.end": "start", "loads.semitangential.torque": [1, 0, 0]}
        )
    with pytest.raises(SceneError, match=r"^loads\.semitangential\.torque\[2\]: a roller end"):
        load_scene(
            ROLLUP,
            {
                "loads.end": UNSET,
                "supports.end": "roller",
                "loads.semitangential.torque": [0, 0, 1],
            },
        )
    scene = load_scene(ROLLUP, {"loads.end": UNSET, "loads.semitangential.torque": [0, 2, 0]})
    assert scene.plane() == "x-z"
    assert (
        load_scene(ROLLUP, {"loads.end": UNSET, "loads.semitangential.torque": [0, 0, 2]}).plane()
        is None
    )
    assert scene_from_dict(scene.to_dict()) == scene


@pytest.mark.long
def test_a_semitangential_torque_on_a_kinked_rod_is_the_dead_torque_of_a_rotation_in_its_axis():
    """Argyris's frame (scenes/argyris_frame.toml, a polyline whose rest frame at the tip is
    turned by 90° about e2) under an end torque about e1, the free leg's axis: the clamped leg
    bends about e1 (its weak axis) and the free leg twists, so every rotation is about e1, the
    torque's own axis; the semitangential torque then stays M0 and the state is the dead
    torque's (the tip turns by about 0.8 rad: 80 N mm over E I_weak/240 mm = 160 N mm and
    GJ/240 mm = 245 N mm). Equal within 1e-10 of the largest component (Newton's tolerance);
    the torque computed from the rotation from the fixed basis instead of from the rest frame
    (R = (D0 D)ᵀ instead of Dᵀ, forms/semitangential.py) leaves the frame nearly straight, a
    difference of 0.83 rad (measured with that temporary change)."""
    frame = ROOT / "scenes" / "argyris_frame.toml"
    states = []
    for key in ("loads.end.torque", "loads.semitangential.torque"):
        over = {"loads.end": UNSET, key: [80.0, 0, 0], "static.load_steps": 8}
        equilibria = Equilibria(load_scene(frame, over), count=4)
        try:
            states.append(equilibria.state(1.0).reshape(-1, 12))
        finally:
            equilibria.close()
    assert abs(states[0][:, 3]).max() > 0.5  # θ: it does turn about e1
    assert abs(states[0] - states[1]).max() < 1e-10 * abs(states[0]).max()


# ---------------------------------------------------------------------------------------
# Twisted, not torqued: a rod clamped at both ends, one end turned (issue 30's plectoneme,
# its buckling). A straight rod (L = 1 m, circle d = 2 mm, E = 1e9 Pa, ν = 0.3) clamped at
# s = 0 and, at s = L, held by a sliding support (its lateral position and its rotation
# held, free to slide along the rod: no axial force) that turns it about the rod's axis by
# Φ (a one-member structure, docs/structures.md, the support's `rotation`): the turn is
# prescribed, so no question of the torque's conservativeness arises. The straight twisted
# rod carries M = GJ Φ/L. Linearised about it, w = u + i v obeys EI w'''' − i M w''' = 0 (no
# axial force), so w = c0 + c1 s + c2 s² + c3 e^{iαs/L}, α = M L/EI; w = w' = 0 at both ends
# makes the determinant
#
#     (e^{iα} − 1)(iα − 2) + 2iα = 0   ⇔   e^{iα} = (2 + iα)/(2 − iα) = e^{2i atan(α/2)},
#
# so α/2 = atan(α/2) + kπ: tan x = x, x = α/2, whose first positive root x1 = 4.4934 gives
# M_c L/EI = 2 x1 = 8.98682 (Love's 8.99). The buckling twist Φ_c = M_c L/GJ = 2 x1 EI/GJ,
# EI/GJ = 1 + ν for a circle: 11.6829 rad. The rod's shear changes it by a factor
# 1 + O(EI/(κGA L²)) = 1 + O((r/L)²) = 1 + O(1e-6) here, below what is asserted.
NU, PHI = 0.3, 12.0  # the turn at load factor 1 [rad], past the buckling twist


def twisted(elements: int) -> dict:
    """The twisted rod above, its end turned by λ Φ at load factor λ."""
    return {
        "title": "Greenhill: a clamped rod twisted until it buckles",
        "rod": {
            "section": {"shape": "circle", "diameter": 0.002},
            "material": {"density": 1000.0, "young_modulus": 1e9, "poisson_ratio": NU},
        },
        "structure": {
            "nodes": [{"name": "A", "position": [0, 0, 0]}, {"name": "B", "position": [0, 0, 1]}],
            "members": [{"name": "AB", "from": "A", "to": "B", "elements": elements}],
            "supports": [
                {"node": "A", "kind": "clamped"},
                {
                    "node": "B",
                    "kind": "sliding",
                    "axis": [0, 0, 1],
                    "rotation": PHI,
                    "rotation_axis": [0, 0, 1],
                },
            ],
        },
        "static": {"load_steps": 8},
        "time": {"end": 1.0, "step": 1.0},
        "discretisation": {"degree": 3},
    }


def buckling_twist(elements: int) -> float:
    """Φ_c [rad]: the twist where the tangent's lowest eigenvalue (the modes about the static
    state, analysis/equilibria.py) crosses zero, bisected in the load factor to 2e-6 of Φ."""
    equilibria = Equilibria(scene_from_dict(twisted(elements)), 2, MPI.COMM_SELF)
    try:
        lo, hi = 0.9, 1.0
        assert min(e.real for e in equilibria.at(lo).eigenvalues) > 0
        assert min(e.real for e in equilibria.at(hi).eigenvalues) < 0
        while hi - lo > 2e-6:
            mid = 0.5 * (lo + hi)
            if min(e.real for e in equilibria.at(mid).eigenvalues) > 0:
                lo = mid
            else:
                hi = mid
        return 0.5 * (lo + hi) * PHI
    finally:
        equilibria.close()


@pytest.mark.long
def test_a_twisted_clamped_rod_buckles_at_greenhills_twist():
    """Φ_c within 0.2 % of 2 x1 (1 + ν) (the issue's bound) on 16 cubic cells (measured
    1.3e-4), converging under refinement (8 → 16 cells: the error falls by more than 8,
    measured 14; the bisection's 2e-6 is below both). ~15 s."""
    x1 = brentq(lambda x: math.tan(x) - x, math.pi + 1e-9, 1.5 * math.pi - 1e-9)
    assert 2 * x1 == pytest.approx(8.98682, abs=1e-5)  # Love's 8.99
    exact = 2 * x1 * (1 + NU)
    errors = [abs(buckling_twist(cells) / exact - 1) for cells in (8, 16)]
    assert errors[1] < 2e-3
    assert errors[0] / errors[1] > 8
