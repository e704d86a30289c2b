"""Stress cases 1 and 3 of docs/stability.md: the paper's load 10x, 100x and 1000x, and time
steps of half to 2.6 forcing periods. (Cases 2 and 4: tests/test_stress_dynamics.py, whose
analysis of the schemes, scheme_response and linear_system, is used here.)

The paper's scene: 8 cubic elements, SDIRK3 at Δt = 30 μs with the frozen Jacobian unless said
otherwise; the load f_x = f_y = F q0 sin(πs/ℓ) sin(8 ω0 t), q0 = 2 kN/m, scaled by F.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from conftest import ROOT
from test_stress_dynamics import INTEGRATORS, linear_system, scheme_response

from cosserat_fem.analysis.simulation import run_scene
from cosserat_fem.common.errors import SolverError
from cosserat_fem.reference.rod_planes import sine_load_tip_response
from cosserat_fem.reference.second_order import RodData, second_order_tip_response
from cosserat_fem.scene.build import load_scene

pytestmark = [pytest.mark.stress, pytest.mark.long]

SCENE = ROOT / "scenes" / "cao_tucker_2008.toml"
Q0 = 2e3  # N/m, the paper's load amplitude


def paper_load(factor: float) -> list[str]:
    load = f"{Q0 * factor:g}*sin(pi*s/L)*sin(8*omega0*t)"
    return [f'loads.force_density=["{load}","{load}",0]', "output.xdmf=false"]


def probes(out) -> np.ndarray:
    return np.loadtxt(out / "probes.csv", delimiter=",", skiprows=1, ndmin=2)


# ================================================================== case 1: large loads
FACTORS = (1.0, 5.0, 10.0)


@pytest.fixture(scope="module")
def scaled_runs(tmp_path_factory):
    """The whole 0.06 s at 1x, 5x and 10x the paper's load: {factor: (summary, probes)}."""
    runs = {}
    for factor in FACTORS:
        out = tmp_path_factory.mktemp(f"load{factor:g}")
        summary = run_scene(load_scene(SCENE, paper_load(factor)), out).summary
        runs[factor] = (summary, probes(out))
    return runs


def test_ten_times_the_load_departs_from_perturbation_theory_as_the_load_squared(scaled_runs):
    """Up to 10x the paper's load (tip 1.6 % of ℓ) the run completes with the nominal steps,
    and the rod departs from perturbation theory by the next order of the expansion.

    For the load F q0, x/F and y/F follow the linear Timoshenko response, z/F² and φ/F² the
    second-order theory (cosserat_fem/reference), up to D(F) = e + F² R + O(F⁴): e the
    discretisation error (of the linear and the second-order response; it scales with the
    response, so it is the same in D for every F), F² R the next order of the expansion.
    Hence (D(10) − D(1))/(D(5) − D(1)) = (100 − 1)/(25 − 1) = 4.125 in norm, with e cancelled
    exactly. Measured 4.135 (x), 4.142 (y), 4.134 (z), 4.137 (φ) over 0.06 s. The O(F⁴) term
    shifts the ratio by about the size of the remainder relative to the response at 10x,
    1.1e-2 (x) to 3.5e-2 (φ) (measured below); required 4.125 ± 0.15. A remainder of another
    order would give another ratio: F³, 8.06; F, 2.25. Each run: 2000 steps, none rejected."""
    for factor, (summary, _) in scaled_runs.items():
        assert summary["status"] == "completed", factor
        assert summary["steps"] == 2000 and summary["rejected_steps"] == 0, factor
    scene = load_scene(SCENE)
    t = scaled_runs[1.0][1][:, 0]
    omega = 8.0 * scene.omega0
    x_ref, y_ref = sine_load_tip_response(scene, t, q0=Q0, omega=omega)
    z_ref, phi_ref = second_order_tip_response(
        RodData.from_scene(scene), Q0, omega, t, torsion_inertia=scene.model.torsion_inertia
    )
    tip = np.hypot(*scaled_runs[10.0][1][:, 1:3].T).max()
    assert tip == pytest.approx(1.6e-2 * scene.rod.length, rel=0.05)
    for column, ref, power in ((1, x_ref, 1), (2, y_ref, 1), (3, z_ref, 2), (6, phi_ref, 2)):
        D = {f: data[:, column] / f**power - ref for f, (_, data) in scaled_runs.items()}
        remainder = np.linalg.norm(D[10.0] - D[1.0]) / np.linalg.norm(ref)
        assert 5e-3 < remainder < 5e-2, (column, remainder)  # measured 1.1e-2 to 3.5e-2
        ratio = np.linalg.norm(D[10.0] - D[1.0]) / np.linalg.norm(D[5.0] - D[1.0])
        assert ratio == pytest.approx(99.0 / 24.0, abs=0.15), (column, ratio)


def test_hundred_times_the_load_completes(tmp_path):
    """100x the paper's load: tip deflections of 0.2 ℓ and more, θ beyond 1 rad; the run
    completes with the nominal 30 μs steps (the frozen Jacobian refreshed at nearly every
    step). Required: completed, 2000 steps, the free end's |θ| above 0.9 rad at some time
    (the large-rotation regime is reached: measured 1.03) and below π/2 throughout (so the
    chart never moves: the paper's forms throughout). Its motion is resolved in time only
    for the first ~20 ms: past ~25 ms runs at 30 μs, 15 μs and adaptive steps part
    (docs/stability.md, case 1), so no later value is asserted. ~3 s."""
    summary = run_scene(load_scene(SCENE, paper_load(100.0)), tmp_path).summary
    assert summary["status"] == "completed"
    assert summary["steps"] == 2000
    theta = np.abs(probes(tmp_path)[:, 4])
    assert 0.9 < theta.max() < 0.5 * math.pi


@pytest.mark.parametrize("adaptive", [False, True], ids=["fixed", "adaptive"])
def test_thousand_times_the_load_passes_the_chart_singularity(tmp_path, adaptive):
    """1000x the paper's load drives θ(s = 0.25 m) to π/2 at 8.40 ms, where the Euler-angle
    chart is singular (det Ma = cos θ). Until the charts of cosserat_fem/rod/charts.py, both step
    sequences stopped there with that reason (measured 8.4047 ms fixed, 8.3991 ms adaptive).
    Now the chart moves onto the rod before θ gets there, and the run goes on through ever
    larger rotations: with fixed steps it completed (70 moves of the chart; 75 and 3 rejected
    steps at commit e6ffdb3), with adaptive steps (rtol = 1e-4) the steps shrank below 1e-13 s
    at 26.9 ms (379 moves). Those are one-off measurements, not held: past ~20 ms the motion
    is not resolved, and where a run of it ends is decided by the discretisation and by
    round-off (docs/stability.md case 1). Required: past 8.5 ms, at least one move of the
    chart, a stop (if any) whose reason is not the chart, and outputs kept: probes.csv has
    every output step before the stop."""
    extra = ["time.adaptive=true", "time.rtol=1e-4"] if adaptive else []
    try:
        run_scene(load_scene(SCENE, paper_load(1000.0) + extra), tmp_path)
        stopped_at = None
    except SolverError as error:
        assert "chart" not in str(error), str(error)
        stopped_at = error.time
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["time_reached_s"] > 8.5e-3
    assert summary["chart_resets"] >= 1
    data = probes(tmp_path)
    assert np.isfinite(data).all()
    if stopped_at is not None:
        assert summary["status"] == "failed"
        assert data[-1, 0] <= stopped_at and len(data) >= int(8.5e-3 / 3e-5)


# ================================================================== case 3: long steps
PAPER_SHAPE = 'loads.force_density=["2e3*sin(pi*s/L)","2e3*sin(pi*s/L)",0]'
LONG_STEPS = (2e-3, 1e-2)  # s: 0.53 and 2.6 forcing periods (2π/(8 ω0) = 3.79 ms)
SCHEMES = ("midpoint", "galpha-0.8", "bdf2", "sdirk3", "sdirk4")


@pytest.fixture(scope="module")
def linearised_paper_rod():
    """K, M, f of the rod linearised about the straight state, f the paper's load shape in
    both planes (cosserat_fem.analysis.modal, via test_stress_dynamics.linear_system); the index of
    x(ℓ)/ℓ (y(ℓ)/ℓ follows it: the dofs are blocked by node), ω0."""
    K, M, f, tip, omega0 = linear_system([PAPER_SHAPE])
    return K, M, f, tip, omega0


@pytest.mark.parametrize("h", LONG_STEPS, ids=["2ms", "10ms"])
@pytest.mark.parametrize("name", SCHEMES)
def test_steps_as_long_as_the_forcing_period(tmp_path, linearised_paper_rod, name, h):
    """Δt = 2 ms and 10 ms over 0.06 s (30 and 6 steps; the forcing period is 3.79 ms, the
    first mode's 30 ms). With full Newton every scheme completes without a rejected step,
    and its free-end history is that of the same scheme applied to the linearised rod,
    M p̈ + K p + f sin(8τ) = 0 (test_stress_dynamics.scheme_response: the same unknowns,
    stage and load times and start): none blows up, all five being A-stable, and what each
    gives is its own discrete response to the sampled load (tip amplitudes 0.6e-3 to
    1.4e-2 m, against 1.4e-3 m for the rod; the error of 2 steps a period or fewer, as
    expected). Required within 1e-3 of the maximum: what differs is the rod's nonlinearity,
    of the order of the tip slope squared (ψ ≲ 2e-2 rad: ≲ 5e-4), measured 6e-6 to 3.4e-4.

    With the scene's frozen Jacobian Newton fails on some of these steps (at 10 ms all five
    schemes, at 2 ms SDIRK4: 3 to 57 rejected, each retried with half the step), so the
    history is no fixed-step one and has no closed form; the run must still complete, finite
    and below 0.05 ℓ (a blow-up guard, not a measurement: the largest tip deflection of the
    frozen runs is 1.6e-2 ℓ, of the full-Newton ones 1.4e-2 ℓ, midpoint at 10 ms)."""
    K, M, f, tip, omega0 = linearised_paper_rod
    common = paper_load(1.0) + INTEGRATORS[name] + [f"time.step={h}"]
    full = load_scene(SCENE, common + ["solver.jacobian=full"])
    summary = run_scene(full, tmp_path / "full").summary
    assert summary["status"] == "completed" and summary["rejected_steps"] == 0
    data = probes(tmp_path / "full")
    steps = round(0.06 / h)
    assert len(data) == steps + 1
    y = scheme_response(K, M, f, lambda tau: math.sin(8.0 * tau), omega0 * h, steps, name)
    length = load_scene(SCENE).rod.length
    for column, index in ((1, tip), (2, tip + 1)):
        linear = length * y[:, index]
        scale = np.abs(linear).max()
        assert np.abs(data[:, column] - linear).max() <= 1e-3 * scale, (column, name, h)
    summary = run_scene(load_scene(SCENE, common), tmp_path / "frozen").summary
    assert summary["status"] == "completed"
    frozen = probes(tmp_path / "frozen")
    assert len(frozen) == steps + 1 and np.isfinite(frozen).all()
    assert np.hypot(frozen[:, 1], frozen[:, 2]).max() < 0.05 * length
