"""A failed step is rejected and retried with half the step (at most time.max_halvings times),
and the run goes on at the nominal step; outputs stay on the nominal time grid.

Newton failures are injected on purpose into the paper's scene (SDIRK3, Δt = 30 μs): the first
solve of step 100 fails once (one halving), and later the first solve of a step fails and so
does the first solve of its first half (two halvings). The run completes, with the rejected
steps and the smallest sub-step in its summary, and its free-end history differs from an
undisturbed run only by the local error of the three sub-stepped steps: the run's global error
(5.6e-4) is the sum of 2000 local errors of about 3e-7 each, so three steps taken differently
change x(ℓ,t), y(ℓ,t) by about 1e-6 of their maxima (measured 2.4e-7 and 5.2e-7); the test
allows 1e-5.
"""

from __future__ import annotations

import logging

import numpy as np
import pytest
from conftest import ROOT, inject_newton_failures

from cosserat_fem.analysis.simulation import run_scene
from cosserat_fem.scene.build import load_scene

SCENE = ROOT / "scenes" / "cao_tucker_2008.toml"
OVERRIDES = ["output.xdmf=false"]


def probes(out):
    return np.loadtxt(out / "probes.csv", delimiter=",", skiprows=1)


@pytest.fixture(scope="module")
def undisturbed(tmp_path_factory):
    out = tmp_path_factory.mktemp("undisturbed")
    run_scene(load_scene(SCENE, OVERRIDES), out)
    return probes(out)


def recovered(summary: dict, rejected: int, smallest: float, jacobians: int) -> None:
    """A run that completed its 2000 steps after ``rejected`` rejections, its smallest step
    ``smallest`` [s], with ``jacobians`` Jacobian assemblies."""
    assert summary["status"] == "completed"
    assert summary["steps"] == 2000
    assert summary["rejected_steps"] == rejected
    assert summary["smallest_step_s"] == pytest.approx(smallest)
    assert summary["newton"]["jacobian_assemblies"] == jacobians


def test_injected_newton_failures_are_recovered(tmp_path, monkeypatch, undisturbed):
    # Solve calls, counting from 1: two a step (SDIRK3). Call 199 is the first of step 100; it
    # and its retry shift later steps by 2 calls: 1200 is the first of step 599, 1201 the first
    # of its first half.
    fail_at = {2 * 99 + 1, 2 * 599 + 2, 2 * 599 + 3}
    inject_newton_failures(monkeypatch, fail_at.__contains__)
    summary = run_scene(load_scene(SCENE, OVERRIDES), tmp_path).summary
    # A fresh Jacobian after each change of the step that reaches Newton: 1 + 2 (step 100:
    # half, then nominal) + 2 (step 599: the injected failure of the half step comes before
    # any assembly, then a quarter, then nominal).
    recovered(summary, rejected=3, smallest=3e-5 / 4, jacobians=5)
    data = probes(tmp_path)
    np.testing.assert_allclose(data[:, 0], undisturbed[:, 0], rtol=0, atol=1e-15)
    for j in (1, 2):
        scale = np.abs(undisturbed[:, j]).max()
        assert np.abs(data[:, j] - undisturbed[:, j]).max() <= 1e-5 * scale


def test_failure_after_max_halvings_keeps_the_outputs(tmp_path, monkeypatch, undisturbed):
    """Every solve from step 50 on fails: the step is halved max_halvings = 3 times, then the
    run stops with the reason and the time, and probes.csv holds the 49 good steps."""
    inject_newton_failures(monkeypatch, lambda n: n > 2 * 49)
    with pytest.raises(Exception) as info:
        run_scene(load_scene(SCENE, OVERRIDES + ["time.max_halvings=3"]), tmp_path)
    message = str(info.value)
    assert "injected" in message and "rejected 3 times" in message and "3.75e-06 s" in message
    assert "at t = 0.00147375 s" in message  # the first sub-step of step 50: 49 Δt + Δt/8
    data = probes(tmp_path)
    assert data.shape[0] == 50  # t = 0 and 49 steps
    np.testing.assert_array_equal(data, undisturbed[:50])


def corrupt_after_step(monkeypatch, attempt: int, corrupt) -> None:
    """Apply ``corrupt`` to the state array U that step attempt number ``attempt`` (counting
    from 1, retries included) of the integrator (SDIRK3, the scene's) leaves, before the
    run's state checks see it: as if the step itself had produced that state (SDIRK.step,
    the one step every run takes)."""
    from cosserat_fem.timestepping.integrators import SDIRK

    real_step = SDIRK.step
    calls = {"n": 0}

    def step(self, h, solve):
        iterations = real_step(self, h, solve)
        calls["n"] += 1
        if calls["n"] == attempt:
            blocks = self.U.function_space.dofmap.index_map_bs
            corrupt(self.U.x.array.reshape(-1, blocks))
        return iterations

    monkeypatch.setattr(SDIRK, "step", step)


def nan_in_one_value(U: np.ndarray) -> None:
    U[-1, 0] = np.nan  # one x value (of whichever node the dof map puts last)


def over_the_chart(U: np.ndarray) -> None:
    """θ + π at every node: cos θ changes sign everywhere, |cos θ| stays ≈ 1, so only the sign
    test can see it (a jump over θ = ±π/2, through which no continuous motion passes)."""
    assert U.shape[1] == 12  # θ is the fourth of (x, y, z, θ, ψ, φ) and their rates
    U[:, 3] += np.pi


@pytest.mark.parametrize(
    ("corrupt", "reason"),
    [
        (nan_in_one_value, "the solution became non-finite (NaN/inf)"),
        (over_the_chart, "θ crossed ±π/2 within the step"),
    ],
    ids=["nan", "chart-jump"],
)
def test_a_state_that_fails_the_checks_is_rejected_and_retried(
    tmp_path, monkeypatch, caplog, undisturbed, corrupt, reason
):
    """Step 100 (attempt 100) ends in a state that is not finite, or that jumped over the
    chart singularity: the step is rejected with that reason (logged), retried as two half
    steps, and the run completes as in test_injected_newton_failures_are_recovered: one
    rejected step, a smallest step of Δt/2, 1 + 2 Jacobian assemblies (the half steps, then
    the nominal step again), and a free-end history that differs from the undisturbed run
    only by the local error of the one step taken in two halves, ~3e-7 of the maxima (the
    module docstring's estimate; measured 1.1e-7 and 1.8e-7 for x and y, the same in both
    cases, as the retry does not depend on the reason); required within 1e-5."""
    corrupt_after_step(monkeypatch, 100, corrupt)
    with caplog.at_level(logging.INFO, logger="cosserat_fem"):
        summary = run_scene(load_scene(SCENE, OVERRIDES), tmp_path).summary
    rejections = [r.getMessage() for r in caplog.records if "rejected" in r.getMessage()]
    assert len(rejections) == 1 and reason in rejections[0], rejections
    assert "t = 0.003 s" in rejections[0], rejections  # step 100 of 30 μs
    recovered(summary, rejected=1, smallest=3e-5 / 2, jacobians=3)
    data = probes(tmp_path)
    np.testing.assert_allclose(data[:, 0], undisturbed[:, 0], rtol=0, atol=1e-15)
    assert np.isfinite(data).all()
    np.testing.assert_array_equal(data[:100], undisturbed[:100])  # before the step: bitwise
    for j in (1, 2):
        scale = np.abs(undisturbed[:, j]).max()
        assert np.abs(data[:, j] - undisturbed[:, j]).max() <= 1e-5 * scale


def test_a_failed_check_names_the_first_place_along_the_rod():
    """A check that fails names the first node along the rod where its rule is broken, the
    same on every CPU and partition. θ = π/2 − 1e-3 + 1e-12 σ at every node (σ = s/ℓ): |cos θ|
    ≈ 1e-3 < CHART_COS_MIN everywhere, smallest at the free end by ~1e-12, the size of the
    round-off that a CPU decides in θ of a rigid rotation: the chart check names s = 0 m (it
    named the place of the smallest |cos θ|, here s = 1 m). A NaN at σ = 0.5 and σ = 1 names
    s = 0.5 m."""
    from cosserat_fem.common.errors import SolverError
    from cosserat_fem.rod.checks import check_state
    from cosserat_fem.rod.model import build_model

    model = build_model(load_scene(SCENE, ["discretisation.planar=off"]), planar=False)
    sigma = model.V.tabulate_dof_coordinates()[:, 0]
    blocks = model.U.x.array.reshape(len(sigma), -1)
    blocks[:, model.layout.index(3)] = 0.5 * np.pi - 1e-3 + 1e-12 * sigma
    with pytest.raises(SolverError, match="chart singular") as caught:
        check_state(model, 0.001)
    assert caught.value.where == "s = 0 m", caught.value.where
    blocks[:] = 0.0
    blocks[np.isclose(sigma, 0.5) | np.isclose(sigma, 1.0), 0] = np.nan
    with pytest.raises(SolverError, match="non-finite") as caught:
        check_state(model, 0.001)
    assert caught.value.where == f"s = {0.5 * model.length:.4g} m", caught.value.where
