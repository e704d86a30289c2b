"""The Jacobian policies give the same answer and do what they say.

Full Newton assembles a Jacobian at every iteration; "lagged" once every ``lag`` steps;
"frozen" once, and again only when a step needs more than ``refresh_iterations`` iterations.
All three solve the same equations to the Newton tolerance (stol = 1e-8: full Newton stops at
an update of 1e-8 ‖U‖, after which its error is ~1e-16 ‖U‖; the modified-Newton policies stop
when the update or the estimated error ρ/(1 − ρ)·‖δU‖ is below 1e-8 ‖U‖), so the free-end
histories agree to 1e-7 relative, for a one-stage (generalized-α) and a two-stage (SDIRK3)
integrator, whose stages share one frozen matrix.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import ROOT

from cosserat_fem.analysis.simulation import run_scene
from cosserat_fem.scene.build import load_scene

SCENE = ROOT / "scenes" / "cao_tucker_2008.toml"
COMMON = ["time.end=0.003", "time.step=1e-5", "output.xdmf=false", "solver.stol=1e-8"]


@pytest.fixture(scope="module", params=["generalized-alpha", "sdirk3"])
def runs(tmp_path_factory, request):
    results = {}
    for policy in ("full", "lagged", "frozen"):
        out = tmp_path_factory.mktemp(policy)
        over = [f"solver.jacobian={policy}", "solver.lag=25", f"time.integrator={request.param}"]
        scene = load_scene(SCENE, COMMON + over)
        summary = run_scene(scene, out).summary
        results[policy] = (np.loadtxt(out / "probes.csv", delimiter=",", skiprows=1), summary)
    return results


def test_same_answer(runs):
    ref = runs["full"][0]
    for policy in ("lagged", "frozen"):
        data = runs[policy][0]
        for j in range(1, 7):
            assert np.abs(data[:, j] - ref[:, j]).max() <= 1e-7 * np.abs(ref[:, j]).max()


def test_counters(runs):
    steps = 300
    full, lagged, frozen = (runs[p][1]["newton"] for p in ("full", "lagged", "frozen"))
    assert full["jacobian_assemblies"] == full["iterations"] >= steps
    # lagged: every 25th solve; SDIRK3 solves twice a step
    assert lagged["jacobian_assemblies"] == lagged["solves"] // 25
    assert frozen["jacobian_assemblies"] <= 3
    assert frozen["retries"] == lagged["retries"] == 0


def test_frozen_jacobian_is_refreshed_when_convergence_slows(tmp_path):
    """A large tip force bends the rod by a sizeable rotation: the frozen Jacobian of the straight
    rod no longer contracts fast, steps need more iterations, and the policy refreshes it."""
    scene = load_scene(
        SCENE,
        [
            "loads.force_density=[0,0,0]",
            "loads.end.force=[2e4,0,0]",
            "time.end=0.004",
            "time.step=1e-5",
            "time.integrator=generalized-alpha",
            "output.xdmf=false",
            "solver.jacobian=frozen",
            "solver.refresh_iterations=4",
        ],
    )
    newton = run_scene(scene, tmp_path).summary["newton"]
    assert newton["jacobian_assemblies"] > 1
    assert newton["jacobian_assemblies"] < newton["solves"] / 4
