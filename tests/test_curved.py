"""Rods curved or twisted at rest ([reference], forms/reference.py): the scene, the rest state,
Bathe & Bolourchi's 45° bend against an independent solution, and the arc against the
straight rod rolled up into it.

The 45° bend's reference is benchmarks/curved/bathe_bolourchi_shooting.py: the same rod
(GA = 5e6 lb, GJ = G (I2 + I3)) integrated from the clamp as an ODE in s (DOP853, 1e-12)
with the tip position found by Newton, continued in load; no finite elements. Its tip
displacements (Δn, Δz, Δt) [in] at 300 and 600 lb are held here to 7 digits.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import ROOT
from xdmf_files import read_arrays

from cosserat_fem import api
from cosserat_fem.errors import SceneError
from cosserat_fem.schema import read_toml

#: Tip displacement (along e1 = towards the centre, e2 = the load, e3 = the clamp's tangent)
#: [in] of the shooting solution at 60, 120 and 600 lb.
SHOOTING = {
    60: (-0.4882970, 11.0391662, -0.8142055),
    120: (-1.7713363, 20.8555532, -2.9616345),
    600: (-13.6045213, 53.4748588, -23.5602395),
}


BEND = ROOT / "scenes" / "bathe_bolourchi_bend.toml"
INCH = 0.0254  # m


def bend_tip(overrides: list[str]) -> dict[int, np.ndarray]:
    """{load [lbf]: tip displacement [in]} of the bend scene's static path with ``overrides``."""
    scene = api.load(BEND, overrides)
    result = api.static(scene)
    return {round(600 * row[0]): row[1:4] / INCH for row in result.probes}


def test_bathe_bolourchi_45_degree_bend():
    """scenes/bathe_bolourchi_bend.toml (SI units; quartic elements, 8 of them, 10 load steps):
    the tip at 60, 120 and 600 lb within 2e-5 in of
    the shooting solution (3e-7 of the 63 in it moves). Measured 1.0e-5 in with 8 elements,
    7e-8 in with 16 (the spatial error falls 140x per halving), 1.3e-2 in with cubic × 8:
    the bound is P4 × 8's discretisation error with a margin of 2, and a strain measured
    wrongly from the arc (the rest residual, an O(h) frame) misses it by orders."""
    tips = bend_tip([])  # the scene's 8 quartic elements, 10 load steps
    for load, expected in SHOOTING.items():
        np.testing.assert_allclose(tips[load], expected, rtol=0, atol=2e-5, err_msg=f"{load} lb")


def test_arc_at_rest_stays_at_rest_and_is_written_as_the_reference(tmp_path):
    """An arc and a helix with no load, in time: the residual at rest is zero (the strains of
    forms/general_form.py vanish identically), so every Newton solve converges at its guess
    and U stays exactly 0 over 70 steps. The XDMF mesh is the reference curve r0(s) at the
    output points and the probes' angles and directors at the tip those of D0(ℓ): for the arc
    ψ = ℓ/R about e2."""
    shapes = {"arc": ["reference.radius=0.8"],
              "helix": ["reference.radius=0.1", "reference.pitch_angle=0.2"]}  # fmt: skip
    for shape, extra in shapes.items():
        scene = api.load("scenes/cao_tucker_2008.toml", [
            f"reference.shape={shape}", *extra, "time.end=0.0021", "loads.end.force=[0,0,0]",
            "loads.force_density=[0,0,0]", "output.probe_fields=['directors']",
        ])  # fmt: skip
        result = api.run(scene, tmp_path / shape)
        assert np.abs(result.model.U.x.array).max() == 0.0, shape
        points, _, arrays = read_arrays(tmp_path / shape / "solution.xdmf")
        ell = scene.rod.length
        s = np.linspace(0.0, ell, len(points))  # uniform cells, k points each, sorted by z
        np.testing.assert_allclose(points, scene.reference.positions(s), rtol=0, atol=1e-15)
        assert not arrays["displacement"].any()
        tip = scene.reference.frames(np.array([ell]))[0]
        header = (tmp_path / shape / "probes.csv").read_text().splitlines()[0].split(",")
        last = np.array((tmp_path / shape / "probes.csv").read_text().splitlines()[-1]
                        .split(","), dtype=float)  # fmt: skip
        directors = last[header.index("d1_x"):header.index("d3_z") + 1].reshape(3, 3)
        np.testing.assert_allclose(directors, tip, rtol=0, atol=1e-14)
        if shape == "arc":
            np.testing.assert_allclose(last[4:7], [0.0, ell / 0.8, 0.0], rtol=0, atol=1e-14)


def test_arc_equals_the_straight_rod_rolled_up_into_it(elements=8):
    """A straight rod under the end moment EI/R about e2 is rolled up into the 45° arc of
    radius R exactly (u2 = m2/EI = 1/R, v = e3). With an in-plane tip force F added to both,
    the arc's equilibrium, m = J (u − u0), n = K (v − v0), and the rolled-up rod's, m = J u
    with the moment carried through, obey the same equations (d2 = e2 stays in-plane), so the
    tips must coincide: here the paper's straight model (65), through the general form, and
    the reference path of forms/general_form.py, through other strains and rows, against each
    other. A force of 15 EI/ℓ² moves the tip by 84 in. Quartic elements: the two tips differ
    by 5.8e-6, 7.3e-8 and 3.4e-10 in with 4, 8 and 16 elements (each tip's own discretisation
    error with 8 is 2e-4 in: the two discretisations err alike), so 8 elements and 1e-6 in, the
    4-element difference's sixth."""
    force = '["-2000*lbf", 0, "1000*lbf"]'
    EI = 1e7 * 6894.757293168361 * INCH**4 / 12  # N m^2
    rolling = f"[0, {EI / (100 * INCH)!r}, 0]"  # EI/R about e2 [N m]
    straight = read_toml(BEND)
    straight["reference"] = {"shape": "straight"}
    tips = {}
    cases = (("arc", BEND, []), ("straight", straight, [f"loads.end.torque={rolling}"]))
    for name, source, extra in cases:
        scene = api.load(source, [f"loads.end.force={force}", *extra])
        tip = api.static(scene).probes[-1][1:4]
        tips[name] = (tip + scene.reference.positions(np.array([scene.rod.length]))[0]) / INCH
    rest = api.load(BEND).reference.positions(np.array([25 * math.pi * INCH]))[0] / INCH
    assert np.abs(tips["arc"] - rest).max() > 80.0
    np.testing.assert_allclose(tips["arc"], tips["straight"], rtol=0, atol=1e-6)


@pytest.mark.parametrize(
    ("overrides", "message"),
    [
        (["reference.shape=arc"], "reference.radius: required for shape 'arc'"),
        (["reference.radius=1"], "reference.radius: not a key of shape 'straight'"),
        (["reference.shape=helix", "reference.radius=1"], "reference.pitch_angle: required"),
        (["reference.shape=arc", "reference.radius=1", "reference.pitch_angle=0.1"],
         "reference.pitch_angle: not a key of shape 'arc', which takes radius"),
        (["reference.shape=arc", "reference.radius=0"], "reference.radius: must be > 0"),
        (["reference.shape=helix", "reference.radius=1", "reference.pitch_angle=2"],
         "reference.pitch_angle: must lie in"),
        (["reference.shape=ring"], "reference.shape: must be one of"),
        (["reference.shape=arc", "reference.radius=1", "supports.end=pinned"],
         "supports.end: 'pinned' is not supported with reference.shape = 'arc'"),
        (["reference.shape=arc", "reference.radius=1", "model.torsion_inertia=printed"],
         "model.torsion_inertia: 'printed'"),
    ],
)
def test_a_malformed_reference_is_refused_by_its_key(overrides, message):
    with pytest.raises(SceneError) as caught:
        api.load("scenes/cao_tucker_2008.toml", overrides)
    assert str(caught.value).startswith(message), str(caught.value)
    assert "\n" not in str(caught.value)
