"""Large static deflections: the roll-up into a circle and Euler's elastica.

* Roll-up (scenes/rollup.toml): an end moment M = turns · 2π E c22/ℓ about e2. The contact force
  vanishes, so the axis is a circle of radius E c22/M; at one turn the tip is back at the
  clamp. The finite-element error is the approximation of sin/cos of the linear angle field;
  the tip converges at about h^6 for cubic elements (nodal superconvergence), and quartic
  elements reach the round-off level.
* Elastica (scenes/tip_load_elastica.toml): a fixed-direction tip force P ⟂ rod with
  α = Pℓ²/(EI) = 1, 2, 5, 10 on a slender rod. The exact solution of the same extensible,
  shearable (Reissner) rod is computed by ``solve_bvp`` (reference/elastica.py): the FE tip
  agrees with it to 1e-9 (measured 6.5e-10 at α = 10, P4 × 32), which isolates the
  discretisation; the inextensible elastica (elliptic integrals) differs from the rod by its
  stretch and shear, α a²/(12 ℓ²) ~ 1e-6 (measured ≤ 4.8e-6), within the 1e-5 goal; and
  Mattiasson's five-digit table is reproduced.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import ROOT

from cosserat_fem.analysis.statics import static_path
from cosserat_fem.output.fields import PointProbe
from cosserat_fem.reference.elastica import MATTIASSON_1981, elastica_tip_load, reissner_tip_load
from cosserat_fem.rod.model import rod_constants
from cosserat_fem.scene.build import load_scene

ROLLUP = ROOT / "scenes" / "rollup.toml"
ELASTICA = ROOT / "scenes" / "tip_load_elastica.toml"


def tip_after(scene_path, overrides):
    scene = load_scene(scene_path, overrides)
    result = static_path(scene, write_outputs=False)
    assert result.load_factors[-1] == 1.0
    return scene, PointProbe(result.model, 1.0).values()


def rollup_gap(overrides, axis: str = "e2") -> tuple[float, float]:
    """(|r(ℓ) − r(0)|/ℓ, the tip's bending angle: ψ(ℓ) about e2, θ(ℓ) about e1)."""
    scene, tip = tip_after(ROLLUP, overrides)
    ell = scene.rod.length
    return math.hypot(tip[0], tip[1], ell + tip[2]) / ell, tip[4 if axis == "e2" else 3]


#: The roll-up about e1: the same rod turned a quarter turn about its axis (a ↔ b, so that
#: E c11 = EI) and the moment about e1, which bends it in the y-z plane, carried by θ.
ABOUT_E1 = [
    'loads.end.torque=["turns*2*pi*EI/L", 0, 0]',
    "rod.section.a=0.06",
    "rod.section.b=0.04",
]


@pytest.mark.parametrize("axis", ["e2", "e1"])
@pytest.mark.parametrize(("turns", "elements"), [(1, 24), (2, 40)])
def test_rollup_closes_the_circle(turns, elements, axis):
    """Goal: tip gap / ℓ ≤ 1e-8 at degree ≥ 3 (here 4); the tip angle = turns · 2π, about e2
    (ψ, the x-z plane) or about e1 (θ, the y-z plane: the solved block of Ma is 1 there, so θ
    passes ±π/2, cosserat_fem/rod/checks.py). The bending angle is linear in s, which the
    elements represent exactly; x and z (its sine and cosine) are not: the gap is their error,
    falling as h^8 at the tip (6.6e-11 at 32 elements, one turn), measured 6.5e-10 (one turn,
    24 elements) and 7.0e-10 (two, 40), about either axis; the angle within 1e-8 relative
    (measured 6.5e-10 and 7.0e-10)."""
    gap, angle = rollup_gap(
        [
            f"parameters.turns={turns}",
            f"discretisation.elements={elements}",
            f"static.load_steps={16 * turns}",
            *(ABOUT_E1 if axis == "e1" else []),
        ],
        axis,
    )
    assert gap < 1e-8
    assert angle == pytest.approx(turns * 2 * math.pi, rel=1e-8)


def test_rollup_convergence_with_cubic_elements():
    """Cubic elements: the gap falls like h^6 (measured 6.2e-6 → 1.0e-7 from 16 to 32)."""
    gaps = [
        rollup_gap(["discretisation.degree=3", f"discretisation.elements={n}"])[0] for n in (16, 32)
    ]
    order = math.log2(gaps[0] / gaps[1])
    assert 5.0 < order < 7.0, gaps


@pytest.mark.parametrize(("turns", "elements"), [(1, 24), (2, 40)])
def test_rollup_about_e1_in_3d_closes_the_circle(turns, elements):
    """Solved in 3D (discretisation.planar = "off"), bending about e1 is carried by θ in a
    block of Ma whose determinant is cos θ (66): the static path moves the chart onto the
    rod's rotation whenever |θ| > charts.RESET_THETA (cosserat_fem/rod/charts.py), and closes the
    circle as the planar solve does, gap / ℓ ≤ 1e-8 (measured 6.5e-10 and 7.0e-10, as in the
    y-z plane: the elements' error in x and z; the interpolated frame adds less than that).
    The probe's angles, continued through the resets, end at θ(ℓ) = turns · 2π."""
    scene = load_scene(
        ROLLUP,
        [
            f"parameters.turns={turns}",
            f"discretisation.elements={elements}",
            f"static.load_steps={16 * turns}",
            *ABOUT_E1,
            "discretisation.planar='off'",
        ],
    )
    result = static_path(scene, write_outputs=False, record=True)
    assert not result.model.layout.reduced
    assert result.summary["chart_resets"] >= 4 * turns  # θ passes 0.9 rad each 2.3 load steps
    tip = result.probes[-1]
    assert math.hypot(tip[1], tip[2], scene.rod.length + tip[3]) / scene.rod.length < 1e-8
    assert tip[4] == pytest.approx(turns * 2 * math.pi, rel=1e-8)
    assert abs(tip[5]) < 1e-8 and abs(tip[6]) < 1e-8
    # The tip angle grows with the load factor, continuously through every reset.
    assert np.all(np.diff(result.probes[:, 4]) > 0)


@pytest.fixture(scope="module")
def elastica_runs():
    runs = {}
    for alpha in (1.0, 2.0, 5.0, 10.0):
        scene, tip = tip_after(
            ELASTICA, [f"parameters.alpha={alpha}", "discretisation.elements=32"]
        )
        runs[alpha] = (scene, tip)
    return runs


def test_elastica_against_the_exact_rod_and_the_inextensible_limit(elastica_runs):
    for alpha, (scene, tip) in elastica_runs.items():
        rod = rod_constants(scene)
        s = rod.section
        EI = rod.young_modulus * s.c22
        exact = reissner_tip_load(
            rod.length,
            rod.young_modulus * s.area,
            s.shear_coefficient * rod.shear_modulus * s.area,
            EI,
            alpha * EI / rod.length**2,
        )
        assert abs(tip[0] - exact.tip_x) < 1e-9 * rod.length, alpha
        assert abs(rod.length + tip[2] - exact.tip_z) < 1e-9 * rod.length, alpha
        inextensible = elastica_tip_load(alpha)
        assert abs(tip[0] / rod.length - inextensible.tip_deflection) < 1e-5, alpha
        assert abs(-tip[2] / rod.length - inextensible.shortening) < 1e-5, alpha
        assert abs(tip[4] - inextensible.tip_angle) < 1e-5, alpha


def test_mattiasson_table(elastica_runs):
    """Mattiasson (1981): u/ℓ and w/ℓ to five digits (±1 in the last, the table's rounding,
    plus our 5e-6 model difference)."""
    for alpha, (u_table, w_table) in MATTIASSON_1981.items():
        scene, tip = elastica_runs[float(alpha)]
        assert abs(tip[0] / scene.rod.length - w_table) < 1.5e-5, alpha
        assert abs(-tip[2] / scene.rod.length - u_table) < 1.5e-5, alpha
