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

import numpy as np
import pytest
from conftest import ROOT, inject_newton_failures

from cosserat_fem.scene import load_scene
from cosserat_fem.simulation import run

SCENE = ROOT / "scenes" / "cao_tucker_2008.toml"
OVERRIDES = ["output.xdmf=false"]


def probes(out):
    return np.loadtxt(out / "probes.csv", delimiter=",", skiprows=1)


@pytest.fixture(scope="module")
def undisturbed(tmp_path_factory):
    out = tmp_path_factory.mktemp("undisturbed")
    run(load_scene(SCENE, OVERRIDES), out)
    return probes(out)


def test_injected_newton_failures_are_recovered(tmp_path, monkeypatch, undisturbed):
    # Solve calls, counting from 1: two a step (SDIRK3). Call 199 is the first of step 100; it
    # and its retry shift later steps by 2 calls: 1200 is the first of step 599, 1201 the first
    # of its first half.
    fail_at = {2 * 99 + 1, 2 * 599 + 2, 2 * 599 + 3}
    inject_newton_failures(monkeypatch, fail_at.__contains__)
    summary = run(load_scene(SCENE, OVERRIDES), tmp_path).summary
    assert summary["status"] == "completed"
    assert summary["steps"] == 2000
    assert summary["rejected_steps"] == 3
    assert summary["smallest_step_s"] == pytest.approx(3e-5 / 4)
    # A fresh Jacobian after each change of the step that reaches Newton: 1 + 2 (step 100:
    # half, then nominal) + 2 (step 599: the injected failure of the half step comes before
    # any assembly, then a quarter, then nominal).
    assert summary["newton"]["jacobian_assemblies"] == 5
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
        run(load_scene(SCENE, OVERRIDES + ["time.max_halvings=3"]), tmp_path)
    message = str(info.value)
    assert "injected" in message and "rejected 3 times" in message and "3.75e-06 s" in message
    assert "at t = 0.00147375 s" in message  # the first sub-step of step 50: 49 Δt + Δt/8
    data = probes(tmp_path)
    assert data.shape[0] == 50  # t = 0 and 49 steps
    np.testing.assert_array_equal(data, undisturbed[:50])
