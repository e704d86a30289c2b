"""Guards on the cost of the default scene, without timing (timings live in benchmarks/).

The paper's scene at its default settings (8 cubic elements, generalized-α ρ∞ = 0.8,
Δt = 10 μs, frozen Jacobian): one Jacobian assembly and LU factorisation for the whole run (the
frozen policy refreshes only when a step needs more than 4 iterations, which this small-amplitude
motion never does), no retried steps, and on average at most 3.2 Newton iterations a step
(measured 2.96 with the second-order predictor; 3.59 with the first-order one, so a lost
predictor fails this test). Quick to run: the full 6000 steps take about 1.2 s.
"""

from __future__ import annotations

from conftest import ROOT

from cosserat_fem.scene import load_scene
from cosserat_fem.simulation import run

SCENE = ROOT / "scenes" / "cao_tucker_2008.toml"


def test_default_scene_cost(tmp_path):
    summary = run(load_scene(SCENE, ["output.xdmf=false"]), tmp_path).summary
    newton = summary["newton"]
    assert summary["steps"] == 6000
    assert newton["jacobian_assemblies"] == 1
    assert newton["retries"] == 0
    assert newton["iterations"] / summary["steps"] <= 3.2
    assert newton["max_iterations_in_a_solve"] <= 4
