"""Guards on the cost of the default scene, without timing (timings live in benchmarks/).

The paper's scene at its default settings (8 cubic elements, SDIRK3 at Δt = 30 μs, frozen
Jacobian): one Jacobian assembly and LU factorisation for the whole run (the frozen policy
refreshes only when a solve needs more than 4 iterations, which this small-amplitude motion
never does), no retried solves, and, at the scene's stol = 1e-7, at most 4.5 Newton iterations
a step over its two stages (measured 4.11; 4 is the least: two a solve). At stol = 1e-8, at
most 5.5: measured 5.28 with the stage predictor that extrapolates the last two stage rates
linearly and the error-estimate stop of cosserat_fem.nls.newton, whose contraction is the larger of
the update and residual ratios; with a predictor of another degree 7.32 (0: the last stage
rate), 5.74 (2: the predictor it replaced), 6.22 (3), 6.53 (4), so each fails this test
(docs/decisions.md, "The stage predictor"); with the update test alone 7.35 (the quadratic
predictor), so a lost estimate stop fails it too. Quick to run: the 2000 steps take about a second.
"""

from __future__ import annotations

import sys
from pathlib import Path

import pytest
from conftest import ROOT
from petsc4py import PETSc

from cosserat_fem.analysis.simulation import run_scene
from cosserat_fem.scene.build import load_scene

SCENE = ROOT / "scenes" / "cao_tucker_2008.toml"


@pytest.mark.parametrize(("stol", "per_step"), [("scene", 4.5), ("1e-8", 5.5)])
def test_default_scene_cost(tmp_path, stol, per_step):
    extra = [] if stol == "scene" else [f"solver.stol={stol}"]
    summary = run_scene(load_scene(SCENE, ["output.xdmf=false", *extra]), tmp_path).summary
    newton = summary["newton"]
    assert summary["integrator"] == "sdirk3"
    assert summary["steps"] == 2000
    assert newton["solves"] == 2 * summary["steps"]
    assert newton["jacobian_assemblies"] == 1
    assert newton["retries"] == 0
    assert newton["iterations"] / summary["steps"] <= per_step
    assert newton["max_iterations_in_a_solve"] <= 4


def test_runs_leave_no_petsc_options(tmp_path):
    """PETSc 3.18 holds at most 512 options; a run that left some behind would make a long
    session (a benchmark of ~170 runs) fail with error 55 (found that way)."""
    options = PETSc.Options()
    before = len(options.getAll())
    for integrator in ("generalized-alpha", "sdirk3", "bdf2"):
        over = ["output.xdmf=false", "time.end=1e-4", "time.step=1e-5"]
        run_scene(load_scene(SCENE, over + [f"time.integrator={integrator}"]), tmp_path)
    assert len(options.getAll()) == before


def test_a_step_allocates_little(tmp_path):
    """Python and numpy allocations in a step of the default scene (tracemalloc: the peak of a
    step above the memory held at its start), after 5 steps of warm-up: the lean Newton loop,
    and the integrator's kept buffers allocate no state-sized arrays
    per iteration. Measured 5.5 kB a step, 2.3 times the state U (300 values, 2.4 kB: what
    remains is DOLFINx's packing of coefficients, a few hundred bytes a residual, and small
    Python objects); allowed 4 times U, which one more state-sized temporary per Newton
    iteration (5.74 a step) would exceed, as would any matrix-sized one (the Jacobian holds
    ~140 kB: 8 cells of 48 x 48 entries)."""
    import tracemalloc

    import numpy as np

    from cosserat_fem.timestepping.events import Observer

    class StepMemory(Observer):
        def __init__(self):
            self.transient: list[int] = []
            self.start = 0

        def step_accepted(self, loop):
            current, peak = tracemalloc.get_traced_memory()
            self.transient.append(peak - self.start)
            tracemalloc.reset_peak()
            self.start = tracemalloc.get_traced_memory()[0]

    scene = load_scene(SCENE, ["output.xdmf=false", "time.end=0.006"])
    run_scene(scene, write_outputs=False)  # compiled forms in memory
    memory = StepMemory()
    tracemalloc.start()
    try:
        result = run_scene(scene, write_outputs=False, observers=[memory])
    finally:
        tracemalloc.stop()
    state_bytes = result.model.U.x.array.nbytes
    assert state_bytes == 2400
    assert np.median(memory.transient[5:]) <= 4 * state_bytes


def _package_calls_per_step(overrides: list[str]) -> dict[int, float]:
    """{Newton iterations of a step: the median calls of the package's own Python functions in
    the steps of that many iterations} over 100 steps after 10 of warm-up, for the paper's
    scene with ``overrides`` (200 steps); the groups of 5 steps or more. A call is
    sys.setprofile's "call" event of a code object in cosserat_fem/, comprehensions and
    generator expressions left out (an interpreter's choice: Python 3.12 inlines
    comprehensions)."""
    import numpy as np

    import cosserat_fem
    from cosserat_fem.timestepping.events import Observer

    package = str(Path(cosserat_fem.__file__).parent)

    class Calls(Observer):
        def __init__(self):
            self.finished = 0
            self.calls = 0
            self.per_step: list[tuple[int, int]] = []
            self.iterations = 0

        def count(self, frame, event, arg):
            code = frame.f_code
            if (
                event == "call"
                and code.co_filename.startswith(package)
                and (not code.co_name.startswith("<"))
            ):
                self.calls += 1

        def step_finished(self, loop):
            self.finished += 1
            calls = self.calls
            iterations = loop.solver.stats.iterations  # counted, then forgotten (below)
            if 10 < self.finished <= 110:
                self.per_step.append((iterations - self.iterations, calls))
            self.iterations = iterations
            self.calls = 0
            if self.finished == 10:
                sys.setprofile(self.count)
            elif self.finished == 110:
                sys.setprofile(None)

    scene = load_scene(SCENE, ["output.xdmf=false", "time.end=0.006", *overrides])
    calls = Calls()
    try:
        run_scene(scene, write_outputs=False, observers=[calls])
    finally:
        sys.setprofile(None)
    assert calls.finished == 200 and len(calls.per_step) == 100
    groups: dict[int, list[int]] = {}
    for iterations, count in calls.per_step:
        groups.setdefault(iterations, []).append(count)
    return {k: float(np.median(v)) for k, v in sorted(groups.items()) if len(v) >= 5}


def test_a_step_makes_o1_python_calls():
    """The design of the one step: Python composes it (integrators.py ``SDIRK.step``: per
    stage a C kernel, the loop's solve and Newton's ``cf_solve``, which iterates in C), so a
    step makes O(1) calls into Python, independent of the number of elements (the assembly is
    C's) and of Newton's iterations (the loop is C's). Asserted as that invariance, not as a
    count of the interpreter's profile events (which differ between Python versions: C calls,
    comprehensions): the calls of the package's own functions in a step
    (:func:`_package_calls_per_step`: medians, since a few observers act on the clock, e.g.
    the interrupt check every ~0.1 s) are the same in steps of 4 and of 5 Newton iterations
    (stol = 1e-8 takes both), and the same with 8 and 32 elements. Measured 24 a step (the
    step, 2 x 2 solves, the time loop, the state check, the observers); with the residual
    assembled through a Python callback (solver.loop = "python"), 42 and 45 in steps of 4 and
    5 iterations, which fails this test. Bounded by 30 besides: 24 and less than one call more
    per stage and iteration (8 a step)."""
    base = _package_calls_per_step([])
    more_elements = _package_calls_per_step(["discretisation.elements=32"])
    tighter = _package_calls_per_step(["solver.stol=1e-8"])
    assert len(tighter) >= 2, tighter  # steps of two iteration counts: the invariance is tested
    counts = {*base.values(), *more_elements.values(), *tighter.values()}
    assert len(counts) == 1, (base, more_elements, tighter)
    assert counts.pop() <= 30
