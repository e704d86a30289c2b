"""Every scene under scenes/ is valid and runs (scikit-fem's test_examples, for scenes).

Static scenes (those whose header comment says ``cosserat-fem static``) are solved with their
own settings, and their answer is the one their comment states, against its closed form or
published value (:data:`STATIC_ANSWERS`); modal ones (``cosserat-fem modes``) give their first
modes; dynamic ones run their first 50 steps. Each must complete with finite probes that moved
(or finite, positive frequencies), so a scene broken by a change of the schema or the solver
fails here, and so does one whose settings no longer give what it says.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import ROOT

from cosserat_fem import api
from cosserat_fem.analysis.simulation import run_scene
from cosserat_fem.analysis.statics import static_path
from cosserat_fem.io.probes import probe_columns
from cosserat_fem.reference.curved import BATHE_BOLOURCHI_SHOOTING
from cosserat_fem.reference.elastica import MATTIASSON_1981
from cosserat_fem.scene.build import load_scene

SCENES = sorted((ROOT / "scenes").glob("*.toml"))
STATIC = [p for p in SCENES if f"cosserat-fem static scenes/{p.name}" in p.read_text()]


def static_tip(out) -> np.ndarray:
    """The last row of a static path's probes.csv: (λ = 1, x, y, z, θ, ψ, φ) of the free end."""
    rows = np.loadtxt(out / "probes.csv", delimiter=",", skiprows=1, ndmin=2)
    assert rows[-1, 0] == 1.0  # the whole load
    return rows[-1]


def rollup_gap(scene, tip: np.ndarray) -> float:
    """|r(ℓ) − r(0)| / ℓ: the tip's distance from the clamp it must return to."""
    ell = scene.rod.length
    return math.hypot(tip[1], tip[2], ell + tip[3]) / ell


def rollup(scene, tip: np.ndarray) -> None:
    """scenes/rollup.toml: the end moment M = turns · 2π E c22/ℓ closes the rod into a circle
    (its comment): the tip back at the clamp within 1e-8 ℓ and ψ(ℓ) = turns · 2π. The bending
    angle is linear in s, which quartic elements hold; what is left is their error in x and z
    (sin and cos of that angle), falling as h^8 at the tip (docs/verification.md, section 2):
    measured 1.1e-11 ℓ (ψ: 6.9e-11 rad) with the scene's 40 elements, 1.6e-8 ℓ with 16. ψ(ℓ)
    within 1e-8 relative, as the gap."""
    turns = scene.parameters["turns"]
    assert rollup_gap(scene, tip) < 1e-8, rollup_gap(scene, tip)
    assert tip[5] == pytest.approx(turns * 2 * math.pi, rel=1e-8)


def elastica(scene, tip: np.ndarray) -> None:
    """scenes/tip_load_elastica.toml (α = P ℓ²/EI = 10): the tip deflection w/ℓ and shortening
    u/ℓ of its comment's table (Mattiasson 1981, five digits). The rod is not the inextensible
    elastica: its stretch and shear move the tip by α a²/(12 ℓ²) = 3.3e-6 here; the table's
    rounding is 5e-6; the scene's discretisation error (16 quartic elements) is 1.1e-7 (the
    difference to 32 elements, whose own error is 6.5e-10: tests/test_large_deflection.py).
    Required within 1e-5 (their sum, 8.4e-6, rounded up); measured 3.7e-6 and 3.6e-6."""
    alpha, ell = scene.parameters["alpha"], scene.rod.length
    table = MATTIASSON_1981[alpha]
    assert tip[1] / ell == pytest.approx(table.w, abs=1e-5)
    assert -tip[3] / ell == pytest.approx(table.u, abs=1e-5)


def bend(scene, tip: np.ndarray) -> None:
    """scenes/bathe_bolourchi_bend.toml: the tip at 600 lbf within 2e-5 in of the shooting
    solution of the same rod, the scene's discretisation error with a margin of 2 (the
    argument of tests/test_curved.py::test_bathe_bolourchi_45_degree_bend, which holds the
    path at 60 and 120 lbf too)."""
    inch = 0.0254
    np.testing.assert_allclose(tip[1:4] / inch, BATHE_BOLOURCHI_SHOOTING[600], rtol=0, atol=2e-5)


def lee(scene, tip: np.ndarray) -> None:
    """scenes/lee_frame.toml at its small reference load P = 1e-6: the probe (mid-span, the
    corner) moves as the linear frame of its comment, the stiffness method of
    tests/test_curved_supports.py::lee_linear, within 2e-3 of each of (x, z) (that test's
    bound: the corner's sway, 2.0e-12, is the smallest and the nonlinearity's 8.5e-4 of it)."""
    from test_curved_supports import lee_linear

    material, sec = scene.rod.material, scene.rod.section
    EA, EI = material.young_modulus * sec.area, material.young_modulus * sec.c22
    GA = sec.shear_coefficient * material.shear_modulus * sec.area
    corner = lee_linear(scene.parameters["P"], EA, EI, GA)[0]
    np.testing.assert_allclose(tip[[1, 3]], corner, rtol=2e-3, atol=0)


def portal(scene, tip: np.ndarray) -> None:
    """scenes/portal_frame.toml at its small reference load F = 1e-3: the probe (B, the loaded
    corner) sways as the linear frame (tests/test_structures.py::frame_linear, the stiffness
    method with exact Timoshenko members), within 1e-4 of it (P3 holds those members' fields
    exactly; what is left is the geometric nonlinearity, of the order of the rotations, 3.6e-4:
    measured 3.2e-8 at F = 1e-6, so 3.2e-5 here)."""
    from test_structures import frame_linear, stiffnesses

    nodes = {"A": (0, 0), "B": (0, 120), "C": (120, 120), "D": (120, 0)}
    members = [("A", "B"), ("B", "C"), ("D", "C")]
    F = scene.parameters["F"]
    sway = frame_linear(nodes, members, {"A", "D"}, {"B": (F, 0.0)}, *stiffnesses())["B"][0]
    assert tip[1] == pytest.approx(sway, rel=1e-4)


def joined_wing(scene, tip: np.ndarray) -> None:
    """scenes/joined_wing.toml (its 16 P3 cells, 140 load steps): the joint's rise at 70 kN
    as GXBeam's figure, 6.648282 m, within 1e-3, GXBeam's own discretisation error bounding
    it (tests/test_joined_wing.py, which converges ours; measured 1.7e-4)."""
    assert tip[3] == pytest.approx(6.648282, rel=1e-3)


def goto(scene, tip: np.ndarray) -> None:
    """scenes/goto_ring.toml (32 members, 64 load steps): the turned node B moves by −4R/3
    along AB, to the folded ring's −R/3 (docs/goto-ring.md (2)), within 6e-3 R, the 32
    members' discretisation error (measured 4.3e-3; tests/test_goto_ring.py converges it)."""
    assert tip[1] == pytest.approx(-4.0 / 3.0, abs=6e-3)


#: The answer each static scene's comment states, checked on its own settings' result.
def riser(scene, tip: np.ndarray) -> None:
    """scenes/riser.toml: the top (probe x = h, z = X_top − L) where the elastic catenary for
    its force puts it (cosserat_fem/reference/catenary.py), moved by the bending's (K.4)
    (δX_top = 0.18 mm, δh = −41 µm): h within 1e-4 relative (measured −3.5e-5, the
    discretisation's: the contact at the nodes), X_top within 5e-5 m ((K.4)'s next order
    O(λ³/a) ~ 1e-5 m; measured −1.4e-6 m)."""
    from cosserat_fem.reference.catenary import bending_shift, from_top_force

    w, ell = scene.parameters["w"], scene.rod.length
    H, V = scene.parameters["span"] * w, scene.parameters["hanging"] * w
    E, d = scene.rod.material.young_modulus, scene.rod.section.diameter
    EA, EI = E * math.pi * d**2 / 4, E * math.pi * d**4 / 64
    cable = from_top_force(w, EA, ell, H, V)
    dX, dh = bending_shift(w, H, V, EI)
    assert tip[1] == pytest.approx(cable.h + dh, rel=1e-4)
    assert abs(ell + tip[3] - cable.X_top - dX) <= 5e-5


STATIC_ANSWERS = {
    "rollup": rollup,
    "tip_load_elastica": elastica,
    "bathe_bolourchi_bend": bend,
    "lee_frame": lee,
    "portal_frame": portal,
    "joined_wing": joined_wing,
    "goto_ring": goto,
    "riser": riser,
}


def ring(scene, modes) -> None:
    """scenes/free_ring.toml (its own 32 quartic elements): six rigid-body modes, then the
    lowest pair, n = 2 out of the plane, of equal frequencies (1e-9), below the thin-ring
    closed form (51.85 Hz, its comment) by the leading Timoshenko correction
    −½ (1 + E/κG)(n r_g/R)² = −0.49 % within 10 % of it (the ring's own 1/n² terms:
    tests/test_ring.py's bound). Measured 51.608 Hz, −0.47 %."""
    from test_ring import KAPPA, NU, R, closed_form

    # The six rigid-body motions are in the discrete space (the reference curve is its own
    # interpolant), so their λ are zero up to the round-off of the shift-invert solve (eps times
    # K's condition): measured |λ| ≤ 1.3e-8 against λ7 = 848.6, 1.5e-11 of it; 1e-6 leaves the
    # round-off room and fails on a seventh mode of λ ≈ 0 or a missing sixth.
    flexible = modes[6].eigenvalue.real
    assert flexible > 0.0
    assert all(abs(m.eigenvalue) < 1e-6 * flexible for m in modes[:6]), modes[:7]
    assert modes[5].note.startswith("rigid-body") and not modes[6].note
    pair = np.array([m.omega for m in modes[6:8]])
    np.testing.assert_allclose(pair[0], pair[1], rtol=1e-9, atol=0)
    diameter = scene.rod.section.diameter
    estimate = -0.5 * (1 + 2 * (1 + NU) / KAPPA) * (2 * diameter / 4 / R) ** 2
    deviation = pair[0] / closed_form(diameter, "out")[0] - 1.0
    assert deviation == pytest.approx(estimate, rel=0.1), (deviation, estimate)


#: The answer each modal scene's comment states.
MODAL_ANSWERS = {"free_ring": ring}


def test_every_static_and_modal_scene_has_its_answer_checked():
    assert sorted(p.stem for p in STATIC) == sorted(STATIC_ANSWERS)
    modal = [p.stem for p in SCENES if f"cosserat-fem modes scenes/{p.name}" in p.read_text()]
    assert sorted(modal) == sorted(MODAL_ANSWERS)


def test_the_rollup_scene_rolls_two_turns_as_its_comment_says(tmp_path):
    """``--set parameters.turns=2`` (its comment): two loops, the tip back at the clamp within
    1e-8 ℓ with the scene's mesh and load steps (measured 7.0e-10 ℓ; 16 elements left 9.6e-7:
    the elements' error grows with the angle each spans, as (κ h)^8)."""
    path = ROOT / "scenes" / "rollup.toml"
    scene = load_scene(path, ["parameters.turns=2"])
    assert static_path(scene, tmp_path).summary["status"] == "completed"
    rollup(scene, static_tip(tmp_path))


@pytest.mark.parametrize("path", SCENES, ids=[p.stem for p in SCENES])
def test_scene_runs(tmp_path, path):
    scene = load_scene(path)
    if f"cosserat-fem modes scenes/{path.name}" in path.read_text():
        modes = api.modes(scene, count=8)
        assert all(np.isfinite(m.omega) for m in modes) and modes[-1].omega > 0.0
        MODAL_ANSWERS[path.stem](scene, modes)
        return
    if f"cosserat-fem static scenes/{path.name}" in path.read_text():
        result = static_path(scene, tmp_path)
        assert result.summary["status"] == "completed"
        STATIC_ANSWERS[path.stem](scene, static_tip(tmp_path))
        return
    end = scene.time.start + 50 * scene.time.step
    short = load_scene(path, [f"time.end={end!r}", "output.xdmf=false"])
    result = run_scene(short, tmp_path)
    assert result.summary["status"] == "completed" and result.summary["steps"] == 50
    probes = np.loadtxt(tmp_path / "probes.csv", delimiter=",", skiprows=1)
    columns = probe_columns(short.output.probe_fields)
    assert probes.shape == (51, len(columns)) and np.isfinite(probes).all()
    assert np.abs(probes[-1, 1:4] - probes[0, 1:4]).max() > 0.0  # something moved
