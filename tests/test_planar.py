"""Planar scenes solve 6 of the 12 unknowns, and get the same answer.

When no load, support motion or initial state leaves the x-z plane, y = θ = φ = 0 (and their
rates) is an invariant set of (65): with θ = φ = 0 the directors are d1 = (cos ψ, 0, −sin ψ),
d2 = e2, d3 = (sin ψ, 0, cos ψ), the curvature is û = (0, ψ', 0), v2 = y' = 0, so every
right-hand side of the y, θ and φ rows (the ν12 û2 û3, v2, ν32 û1 û2 and gyroscopic products)
vanishes. The reduced model solves (x, z, ψ) and their rates, testing the same residual with
the in-plane test functions only: the same equations, assembled with the out-of-plane terms
known to be zero, so the answers agree to round-off (the tests ask for 1e-12 of the largest
motion; measured 8e-16 m against 3e-3), in dynamics and in statics (the roll-up to a full circle).
The XDMF output of a reduced run (all four fields, embedded in the 12 components) equals the
full run's likewise.

Likewise x = ψ = φ = 0 in the y-z plane: with ψ = φ = 0, d1 = e1, d2 = (0, cos θ, sin θ),
d3 = (0, −sin θ, cos θ), û = (θ', 0, 0), ŵ = (θ̇, 0, 0), v1 = x' = 0, and the x, ψ, φ rows
vanish (their sources hold û2, û3, v1, n1 or a product with ŵ2, ŵ3; dMm/dτ q_ang has only
−sin θ θ̇ ψ̇ and −cos θ θ̇² ψ-column terms, zero with ψ̇ = 0). The reduced model solves
(y, z, θ); θ carries the bending, so the chart check still guards |θ| < π/2.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import ROOT
from cosserat_fem.forms.resultants import section_stiffnesses
from xdmf_files import read_arrays

from cosserat_fem.analysis.simulation import run_scene
from cosserat_fem.analysis.statics import static_path
from cosserat_fem.output.fields import PointProbe
from cosserat_fem.rod.model import rod_constants
from cosserat_fem.scene.build import load_scene

PAPER = ROOT / "scenes" / "cao_tucker_2008.toml"


def probes(out):
    return np.loadtxt(out / "probes.csv", delimiter=",", skiprows=1)


#: By plane: the in-plane load (the paper's in x or y, an axial ramp), the unknowns solved,
#: the skipped ones, the probe columns (t, x, y, z, θ, ψ, φ) that move and that stay zero.
PLANES = {
    "x-z": (
        'loads.force_density=["2e3*sin(pi*s/L)*sin(8*omega0*t)", 0, "1e3*s/L"]',
        ["x", "z", "psi", "dx/dtau", "dz/dtau", "dpsi/dtau"],
        "out-of-plane unknowns y, theta, phi",
        [1, 3, 5],
        [2, 4, 6],
    ),
    "y-z": (
        'loads.force_density=[0, "2e3*sin(pi*s/L)*sin(8*omega0*t)", "1e3*s/L"]',
        ["y", "z", "theta", "dy/dtau", "dz/dtau", "dtheta/dtau"],
        "out-of-plane unknowns x, psi, phi",
        [2, 3, 4],
        [1, 5, 6],
    ),
}


@pytest.mark.parametrize("plane, adaptive", [("x-z", False), ("x-z", True), ("y-z", False)])
def test_planar_dynamics_equal_the_full_run(tmp_path, plane, adaptive):
    load, unknowns, skipped, moving, still = PLANES[plane]
    runs = {}
    for planar in ("auto", "off"):
        sets = [
            load,
            'output.fields=["displacement", "angles", "strains", "forces"]',
            "time.end=0.006",
            f"discretisation.planar={planar!r}",
            f"time.adaptive={str(adaptive).lower()}",
        ]
        scene = load_scene(PAPER, sets)
        assert scene.plane() == (plane if planar == "auto" else None)
        result = run_scene(scene, tmp_path / planar)
        runs[planar] = (result.summary, probes(tmp_path / planar))
    reduced, full = runs["auto"], runs["off"]
    assert reduced[0]["solved_unknowns"] == unknowns
    assert len(full[0]["solved_unknowns"]) == 12
    assert reduced[0]["dofs"] * 2 == full[0]["dofs"]
    assert skipped in reduced[0]["skipped_terms"]
    assert reduced[0]["accepted_steps"] == full[0]["accepted_steps"]
    scale = np.abs(full[1][:, 1:]).max(axis=0)
    assert scale[moving[0] - 1] > 1e-4 and scale[moving[1] - 1] > 1e-7  # bending and z move
    assert scale[moving[2] - 1] > 1e-4  # the bending angle
    assert np.abs(reduced[1] - full[1]).max() <= 1e-12 * scale.max()
    assert np.all(reduced[1][:, still] == 0.0)  # the out-of-plane ones are exactly zero
    # The XDMF arrays too (a reduced U embedded twice once put z into ψ and dropped z).
    # Displacement and angles to 1e-12 like the probes. The strains are derivatives of
    # fields that agree to ~1e-17: their round-off is that of O(1) sums (v3 ≈ 1), a few ulp,
    # amplified by k²/h ~ 100 on this mesh; allowed 1e-13 (measured ≤ 1.1e-15 for v,
    # 8.2e-15 1/m for u), and the resultants n = K (v − e3), m = J u that times the largest
    # stiffness (measured 1.9e-7 N against EA · 1e-13 = 1.7e-5 N).
    _, times_r, arrays_r = read_arrays(tmp_path / "auto" / "solution.xdmf")
    _, times_f, arrays_f = read_arrays(tmp_path / "off" / "solution.xdmf")
    np.testing.assert_array_equal(times_r, times_f)
    K, J = section_stiffnesses(rod_constants(scene))
    tolerance = {"strain_v": 1e-13, "curvature_u": 1e-13}
    tolerance.update(force_n=1e-13 * max(K), torque_m=1e-13 * max(J))
    assert set(arrays_r) == set(arrays_f) == {"displacement", "angles", *tolerance}
    for name, values in arrays_f.items():
        assert np.abs(values).max() > 0.0, name
        allowed = tolerance.get(name, 1e-12 * np.abs(values).max())
        assert np.abs(arrays_r[name] - values).max() <= allowed, name


def test_out_of_plane_scenes_are_not_reduced(tmp_path):
    assert load_scene(PAPER).plane() is None  # f1 and f2 ≠ 0
    torque = load_scene(PAPER, ["loads.force_density=[0, 0, 0]", "loads.end.torque=[0, 0, 5]"])
    assert torque.plane() is None  # a twisting end torque
    assert (
        load_scene(PAPER, ["loads.force_density=[1, 0, 0]", "loads.end.torque=[0, 5, 0]"]).plane()
        == "x-z"
    )
    in_yz = ["loads.force_density=[0, 1, 0]", "loads.end.torque=[5, 0, 0]"]
    assert load_scene(PAPER, in_yz).plane() == "y-z"
    assert load_scene(PAPER, [*in_yz, "loads.gravity=[-9.81, 0, 0]"]).plane() is None
    assert load_scene(PAPER, [*in_yz, "loads.end.torque=[5, 1, 0]"]).plane() is None
    assert load_scene(PAPER, [*in_yz, "initial.angle_rates=[0, 0, 's'] "]).plane() is None
    assert load_scene(PAPER, ["loads.force_density=[0, 0, 1]"]).plane() == "x-z"  # both: x-z
    # a given initial state that leaves the plane keeps the twelve unknowns
    unloaded = load_scene(PAPER, ["loads.force_density=[0, 0, 0]", "output.xdmf=false"])
    assert unloaded.plane() == "x-z"
    bent = load_scene(PAPER, ["loads.force_density=[0, 0, 0]", "loads.end.force=[0, 1e3, 0]"])
    static = static_path(bent, write_outputs=False).model
    assert static.scene.plane() == "y-z"  # solved in y-z, handed over in all 12 components
    state = static.layout.full_array(static.U.x.array).ravel().copy()
    sets = ["loads.force_density=[0, 0, 0]", "output.xdmf=false", "time.end=3e-4"]
    summary = run_scene(load_scene(PAPER, sets), tmp_path, initial_state=state).summary
    assert len(summary["solved_unknowns"]) == 12
    assert abs(probes(tmp_path)[0, 2]) > 1e-6  # it started from the out-of-plane state


def test_planar_statics_equal_the_full_solve():
    """The roll-up of scenes/rollup.toml (an end torque about e2: a full circle, x-z), and the
    paper's cantilever under a large end force along e2 (y-z; tip y = 0.30 ℓ, θ = −0.45 rad)."""
    cases = [
        (ROOT / "scenes" / "rollup.toml", [], 4, 2 * np.pi),
        (PAPER, ["loads.force_density=[0, 0, 0]", "loads.end.force=[0, 5e4, 0]"], 3, None),
    ]
    for path, sets, angle, expected in cases:
        tips = {}
        for planar in ("auto", "off"):
            scene = load_scene(path, [*sets, f"discretisation.planar={planar!r}"])
            result = static_path(scene, write_outputs=False)
            assert result.model.layout.reduced == (planar == "auto")
            tips[planar] = PointProbe(result.model, 1.0).values()
        assert np.abs(tips["auto"] - tips["off"]).max() <= 1e-12 * np.abs(tips["off"]).max()
        if expected is not None:
            assert tips["auto"][angle] == pytest.approx(expected, rel=1e-6)  # ψ(ℓ) = 2π
        else:
            assert abs(tips["auto"][angle]) > 0.1  # a large rotation, carried by θ
