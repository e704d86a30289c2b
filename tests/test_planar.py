"""Planar scenes solve 6 of the 12 unknowns, and get the same answer.

When no load, support motion or initial state leaves the x-z plane, y = θ = φ = 0 (and their
rates) is an invariant set of (65): with θ = φ = 0 the directors are d1 = (cos ψ, 0, −sin ψ),
d2 = e2, d3 = (sin ψ, 0, cos ψ), the curvature is û = (0, ψ', 0), v2 = y' = 0, so every
right-hand side of the y, θ and φ rows (the ν12 û2 û3, v2, ν32 û1 û2 and gyroscopic products)
vanishes. The reduced model solves (x, z, ψ) and their rates, testing the same residual with
the in-plane test functions only: the same equations, assembled with the out-of-plane terms
known to be zero, so the answers agree to round-off (the tests ask for 1e-12 of the largest
motion; measured 8e-16 m against 3e-3), in dynamics and in statics (the roll-up to a full circle).
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import ROOT

from cosserat_fem.output import PointProbe
from cosserat_fem.scene import load_scene
from cosserat_fem.simulation import run
from cosserat_fem.statics import static_path

PAPER = ROOT / "scenes" / "cao_tucker_2008.toml"
IN_PLANE = [
    'loads.force_density=["2e3*sin(pi*s/L)*sin(8*omega0*t)", 0, "1e3*s/L"]',
    "output.xdmf=false",
    "time.end=0.006",
]


def probes(out):
    return np.loadtxt(out / "probes.csv", delimiter=",", skiprows=1)


@pytest.mark.parametrize("adaptive", [False, True])
def test_planar_dynamics_equal_the_full_run(tmp_path, adaptive):
    runs = {}
    for planar in ("auto", "off"):
        sets = [
            *IN_PLANE,
            f"discretisation.planar={planar!r}",
            f"time.adaptive={str(adaptive).lower()}",
        ]
        result = run(load_scene(PAPER, sets), tmp_path / planar)
        runs[planar] = (result.summary, probes(tmp_path / planar))
    reduced, full = runs["auto"], runs["off"]
    assert reduced[0]["solved_unknowns"] == ["x", "z", "psi", "dx/dtau", "dz/dtau", "dpsi/dtau"]
    assert len(full[0]["solved_unknowns"]) == 12
    assert reduced[0]["dofs"] * 2 == full[0]["dofs"]
    assert "out-of-plane unknowns y, theta, phi" in reduced[0]["skipped_terms"]
    assert reduced[0]["accepted_steps"] == full[0]["accepted_steps"]
    scale = np.abs(full[1][:, 1:]).max(axis=0)
    assert scale[0] > 1e-4 and scale[2] > 1e-7  # x and z move
    assert np.abs(reduced[1] - full[1]).max() <= 1e-12 * scale.max()
    assert np.all(reduced[1][:, [2, 4, 6]] == 0.0)  # y, θ, φ are exactly zero


def test_out_of_plane_scenes_are_not_reduced(tmp_path):
    paper = load_scene(PAPER)  # f2 ≠ 0
    assert not paper.planar_xz()
    torque = load_scene(PAPER, ["loads.force_density=[0, 0, 0]", "loads.end.torque=[0, 0, 5]"])
    assert not torque.planar_xz()  # a twisting end torque
    assert load_scene(
        PAPER, ["loads.force_density=[1, 0, 0]", "loads.end.torque=[0, 5, 0]"]
    ).planar_xz()
    # a given initial state that leaves the plane keeps the twelve unknowns
    unloaded = load_scene(PAPER, ["loads.force_density=[0, 0, 0]", "output.xdmf=false"])
    assert unloaded.planar_xz()
    bent = load_scene(PAPER, ["loads.force_density=[0, 0, 0]", "loads.end.force=[0, 1e3, 0]"])
    state = static_path(bent, write_outputs=False).model.U.x.array.copy()
    sets = ["loads.force_density=[0, 0, 0]", "output.xdmf=false", "time.end=3e-4"]
    summary = run(load_scene(PAPER, sets), tmp_path, initial_state=state).summary
    assert len(summary["solved_unknowns"]) == 12
    assert abs(probes(tmp_path)[0, 2]) > 1e-6  # it started from the out-of-plane state


def test_planar_statics_equal_the_full_solve():
    """The roll-up of scenes/rollup.toml (an end torque about e2: a full circle)."""
    tips = {}
    for planar in ("auto", "off"):
        scene = load_scene(ROOT / "scenes" / "rollup.toml", [f"discretisation.planar={planar!r}"])
        result = static_path(scene, write_outputs=False)
        assert result.model.reduced == (planar == "auto")
        tips[planar] = PointProbe(result.model.U, 1.0, result.model.length).values()
    assert np.abs(tips["auto"] - tips["off"]).max() <= 1e-12
    assert tips["auto"][4] == pytest.approx(2 * np.pi, rel=1e-6)  # ψ(ℓ) = 2π: rolled up
