"""Small static loads against the closed forms of Timoshenko beam theory.

The paper's cantilever (clamped at s = 0, free at s = ℓ) under an end force, an end torque or a
uniform load. Loads are small (tip deflection ~1e-5 ℓ), so the nonlinear rod agrees with the
linear closed forms up to its geometric nonlinearity, relative O((δ/ℓ)²) ~ 1e-10; this is
checked, not assumed (``test_deviation_is_the_geometric_nonlinearity``). Lagrange elements of
degree ≥ 3 contain the exact end-load solution (cubic deflection, quadratic rotation) and
degree ≥ 4 the uniform-load one (quartic), and the quadrature (2k) integrates the linearised
forms exactly, so there is no discretisation error: tolerances are set by the nonlinearity
(1e-10) and the Newton tolerance (stol = 1e-8 on the update, error ~1e-16 after a quadratic
step), with a margin of 100: 1e-8.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from cosserat_fem.analysis.statics import solve_static
from cosserat_fem.output.fields import PointProbe
from cosserat_fem.reference import timoshenko as tb
from cosserat_fem.reference.rod_planes import bending_planes
from cosserat_fem.rod.model import rod_constants
from cosserat_fem.scene.build import load_scene

SCENE = Path(__file__).resolve().parents[1] / "scenes" / "cao_tucker_2008.toml"
BASE = [
    "loads.force_density=[0,0,0]",
    "discretisation.elements=4",
    "discretisation.degree=3",
    "solver.stol=1e-8",  # the tolerance the docstring argues from
]
TOL = 1e-8


def tip(overrides: list[str]) -> np.ndarray:
    """(x, y, z, θ, ψ, φ) at s = ℓ, SI units."""
    model, _ = solve_static(load_scene(SCENE, BASE + overrides))
    return PointProbe(model, 1.0).values()


@pytest.fixture(scope="module")
def beams():
    """Timoshenko beams of the two bending planes: x bends about d2 (I = c22), y about d1."""
    scene = load_scene(SCENE)
    return (*bending_planes(scene), rod_constants(scene))


def test_end_force_in_x(beams):
    bx, _, _ = beams
    P = 5.0  # N: δ ≈ 5e-6 ℓ
    u = tip([f"loads.end.force=[{P},0,0]"])
    assert u[0] == pytest.approx(tb.tip_deflection_end_force(bx, P), rel=TOL)
    assert u[4] == pytest.approx(tb.tip_rotation_end_force(bx, P), rel=TOL)  # ψ ≈ x'
    assert u[0] > 0  # the tip moves with the load


def test_end_force_in_y(beams):
    _, by, _ = beams
    P = -5.0
    u = tip([f"loads.end.force=[0,{P},0]"])
    assert u[1] == pytest.approx(tb.tip_deflection_end_force(by, P), rel=TOL)
    assert -u[3] == pytest.approx(tb.tip_rotation_end_force(by, P), rel=TOL)  # θ ≈ −y'
    assert u[1] < 0


def test_end_force_along_the_axis(beams):
    *_, rod = beams
    P = 1e3
    u = tip([f"loads.end.force=[0,0,{P}]", "discretisation.degree=1"])
    assert u[2] == pytest.approx(P * rod.length / (rod.young_modulus * rod.section.area), rel=TOL)


def test_uniform_load(beams):
    bx, by, _ = beams
    q = 10.0  # N/m
    u = tip([f"loads.force_density=[{q},{q},0]", "discretisation.degree=4"])
    assert u[0] == pytest.approx(tb.tip_deflection_uniform_load(bx, q), rel=TOL)
    assert u[1] == pytest.approx(tb.tip_deflection_uniform_load(by, q), rel=TOL)
    assert u[4] == pytest.approx(tb.tip_rotation_uniform_load(bx, q), rel=TOL)


@pytest.mark.parametrize("axis", [0, 1, 2])
def test_end_torque(beams, axis):
    """Bending rotation Mℓ/(E c) about e1 (θ) and e2 (ψ), twist Tℓ/(G c33) about e3 (φ)."""
    *_, rod = beams
    s, E, G, ell = rod.section, rod.young_modulus, rod.shear_modulus, rod.length
    M = 2.0  # N m
    torque = [0, 0, 0]
    torque[axis] = M
    u = tip([f"loads.end.torque={torque}"])
    if axis == 0:
        assert u[3] == pytest.approx(M * ell / (E * s.c11), rel=TOL)
        assert u[1] == pytest.approx(-M * ell**2 / (2 * E * s.c11), rel=TOL)
    elif axis == 1:
        assert u[4] == pytest.approx(M * ell / (E * s.c22), rel=TOL)
        assert u[0] == pytest.approx(M * ell**2 / (2 * E * s.c22), rel=TOL)
    else:
        assert u[5] == pytest.approx(M * ell / (G * s.c33), rel=TOL)
    assert u[3 + axis] > 0  # the section turns with the torque


def test_deviation_is_the_geometric_nonlinearity(beams):
    """At 10x and 100x the load the deviation from linear theory grows like the load squared:
    it is the rod's geometric nonlinearity, not a discretisation or solver error."""
    bx, _, _ = beams
    devs = []
    for P in (50.0, 500.0):
        u = tip([f"loads.end.force=[{P},0,0]"])
        devs.append(abs(u[0] / tb.tip_deflection_end_force(bx, P) - 1.0))
    assert 70 < devs[1] / devs[0] < 130


def test_printed_sign_moves_the_tip_against_the_load(beams):
    """Erratum 2: with the free-end condition as printed in (41)/(56)-(61) the tip moves against
    the applied force by exactly the linear deflection (mirror image)."""
    bx, _, _ = beams
    u = tip(["loads.end.force=[5,0,0]", "model.end_load_sign=printed"])
    assert u[0] == pytest.approx(-tb.tip_deflection_end_force(bx, 5.0), rel=TOL)


def test_printed_scaling_is_off_by_the_length():
    """Erratum 3: g_b = g0 f^b as printed in (62) instead of (g0/ℓ) f^b: for ℓ = 2 m the end
    force acts twice as strongly (for ℓ = 1 m, as in the paper, both coincide)."""
    common = ["rod.length=2", "loads.end.force=[0.05,0,0]"]  # δ ≈ 1e-5 ℓ
    balance = tip(common)
    printed = tip(common + ["model.end_load_scaling=printed"])
    assert printed[0] == pytest.approx(2.0 * balance[0], rel=1e-8)


@pytest.mark.parametrize("axis", [0, 1, 2])
def test_uniform_torque_density(beams, axis):
    """A uniform torque density m [N m/m] about e_axis: the internal moment m (ℓ − s) gives the
    tip rotation m ℓ²/(2 E c) in bending and the tip twist m ℓ²/(2 G c33) in torsion (quadratic
    in s, exact for cubic elements)."""
    *_, rod = beams
    s, E, G, ell = rod.section, rod.young_modulus, rod.shear_modulus, rod.length
    m = 2.0
    density = [0, 0, 0]
    density[axis] = m
    u = tip([f"loads.torque_density={density}"])
    stiffness = (E * s.c11, E * s.c22, G * s.c33)[axis]
    assert u[3 + axis] == pytest.approx(m * ell**2 / (2 * stiffness), rel=TOL)


def test_slender_rod_under_a_small_axial_force():
    """Regression: a thin rod (a = 4 mm) under a tiny axial tip force, ‖U‖ ~ 1e-8. The Newton
    update's round-off floor is absolute (~3e-16), so a purely relative step test never
    converged; the absolute part xatol ends the solve. z(ℓ) = Pℓ/(EA) exactly (linear)."""
    P = -5e-3
    u = tip(
        [
            f"loads.end.force=[0,0,{P}]",
            "rod.section.a=0.004",
            "rod.section.b=0.006",
            "model.reference_frequency=auto",
        ]
    )
    assert u[2] == pytest.approx(P * 1.0 / (7.1e10 * 0.004 * 0.006), rel=TOL)
